"""Fuzzing the no-crossing promise (issue 44): thousands of random scenes under every strategy
that claims no crossing, judged by an independent oracle; a record of outcomes per class.

``python -m benchmarks fuzz [--quick | --full] [--workers N] [--resume] [--out DIR]``

Strategies: every registered strategy whose capabilities state a penetration bound of 0
(``bfemp.steppers.STRATEGIES``; today ``barrier`` and ``two_stage``). Scenes:
``benchmarks._fuzz_scenes`` (thin bars, sliver meshes, thin 3D plates, blocks; FEM or MPM
projectiles at free or fixed FEM targets; 2D and 3D; spins; d-hat above half a body's
thickness). The implicit strategy runs ``IMPLICIT_STEPS`` steps at dt log-uniform in
[1e-4, 2] s with a random integrator; the explicit one at its stable step times random CFL
fractions, the projectile placed d-hat plus 0.5 to 6 steps of closing speed away, for the steps
to contact plus ``EXPLICIT_EXTRA_STEPS`` (at most ``EXPLICIT_MAX_STEPS``).

Each case ends one way (``OUTCOMES``):

- ``clean``: every step converged and the oracle (``benchmarks._crossing_oracle``) found
  nothing: no point inside another body at the end or along the straight-line motion (beyond a
  corner cut, counted apart), no cell or particle with J <= 0;
- ``failed``: a step raised ``StepError`` with a named status (``TUNNELED``, ``INTERSECTION``,
  ``INVERTED``, ``MAX_ITERATIONS``, ``CFL_VIOLATED``, ...): the promise kept by refusing;
- ``refused``: the scene or simulation was refused at construction with a message;
- ``silent_crossing``, ``converged_inversion``, ``crash`` (an exception other than the above,
  or an unnamed status): the defects. The issue's target is zero of the first two.

The record (``fuzz.json`` and ``fuzz.md``; ``fuzz_quick.*`` for the quick mode) counts outcomes
and failure statuses per class x strategy and per pair kind, the steps judged, the smallest J
seen, the corner cuts and their deepest, the steps whose sampling was capped, and lists every
defect case in full (a case dict replays with ``run_case``). Each case is appended to
``<out>/fuzz_cases_<mode>.jsonl`` as it finishes, keyed by the code's digest
(``_tradeoff_cache.code_version``): ``--resume`` keeps the cases of the same code and runs the
rest, so a full run can take several sessions.
"""

from __future__ import annotations

import argparse
import collections
import json
import logging
import math
import multiprocessing
import re
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

from benchmarks import _fuzz_scenes as scenes
from benchmarks._crossing_oracle import MAX_SAMPLES, Bodies, judge_step
from benchmarks._tradeoff_cache import code_version
from benchmarks.common import git_commit
from benchmarks.runner import Benchmark, name_unless, register
from bfemp.steppers import STRATEGIES

log = logging.getLogger(__name__)

#: cases per class and strategy
CASES = {"quick": 3, "full": 300}
IMPLICIT_STEPS = 3
EXPLICIT_EXTRA_STEPS = 6
EXPLICIT_MAX_STEPS = 80
NEWTON_CAP = 200
OUTCOMES = ("clean", "failed", "refused", "silent_crossing", "converged_inversion", "crash")
DEFECTS = ("silent_crossing", "converged_inversion", "crash")
_STATUS = re.compile(r"[A-Z][A-Z0-9_]+")


def no_crossing_strategies() -> list[str]:
    """The registered strategies whose capabilities state a penetration bound of 0."""
    return [
        name
        for name, cls in STRATEGIES.items()
        if getattr(cls.capabilities, "penetration_bound_cells", None) == 0
    ]


def cases(mode: str) -> list[dict]:
    """Every case of ``mode``: ``CASES[mode]`` seeds per class and strategy."""
    if mode not in CASES:
        raise ValueError(f"unknown mode '{mode}'; modes: {', '.join(CASES)}")
    return [
        scenes.draw_case(cls, seed, strategy)
        for cls in scenes.CLASSES
        for strategy in no_crossing_strategies()
        for seed in range(CASES[mode])
    ]


def pair_kind(case: dict) -> str:
    """The pair kind the case tests: ``mpm-fem``, ``mpm-prescribed``, ``fem-fem`` or
    ``fem-prescribed``."""
    return f"{'mpm' if case['mpm'] else 'fem'}-{'prescribed' if case['target_fixed'] else 'fem'}"


def _simulation(scene, case: dict):
    import bfemp

    if STRATEGIES[case["strategy"]].explicit:  # its own Newton cap (TwoStageOptions: 200)
        cfl = dict(zip(("cfl_safety_fem", "cfl_safety_mpm"), case["cfl"], strict=True))
        options = STRATEGIES[case["strategy"]].Options(**cfl)
        return bfemp.Simulation(scene, strategy=case["strategy"], dt="auto", options=options)
    return bfemp.Simulation(
        scene,
        strategy=case["strategy"],
        integrator=case["integrator"],
        dt=case["dt"],
        max_newton_iterations=NEWTON_CAP,
    )


def _closing_speed(case: dict) -> float:
    size = case.get("radius") or np.max(case.get("size", [0.1]))
    return case["speed"] + case["target_moving"] + abs(case["spin"]) * float(size)


def run_case(case: dict) -> dict:
    """Run one case and judge every converged step; returns the case with its ``outcome``,
    ``status`` (failure status, refusal or crash text), ``steps`` converged, ``iterations``
    (Newton, summed), ``min_J``, ``corner_cuts``, ``max_cut_depth_m``, ``samples`` (most in a
    step), ``capped`` steps, ``first`` (the oracle's first finding), ``dt`` used and
    ``wall_s``."""
    import bfemp

    t0 = time.perf_counter()
    out = dict(case, outcome="clean", status=None, steps=0, iterations=0, min_J=math.inf)
    out.update(corner_cuts=0, max_cut_depth_m=0.0, samples=0, capped=0, first=None)
    try:
        scene, min_feature = scenes.build(case)
        sim = _simulation(scene, case)
        n_steps = IMPLICIT_STEPS
        if STRATEGIES[case["strategy"]].explicit:  # explicit stage: place the body a few steps away
            dt = float(sim.dt)
            gap = case["gap_steps"] * _closing_speed(case) * dt
            scene, min_feature = scenes.build(case, gap=gap)
            sim = _simulation(scene, case)
            reach = case["gap_steps"] + 1.05 * case["dhat"] / (_closing_speed(case) * dt)
            n_steps = min(math.ceil(reach) + EXPLICIT_EXTRA_STEPS, EXPLICIT_MAX_STEPS)
        out["dt_used"] = float(sim.dt)
    except ValueError as err:  # SceneError is a ValueError
        out.update(outcome="refused", status=str(err)[:300])
        out["wall_s"] = time.perf_counter() - t0
        return out
    bodies = Bodies(sim.model)
    try:
        for _ in range(n_steps):
            start = sim.state.copy()
            try:
                report = sim.step()
            except bfemp.StepError as err:
                status = err.report.status
                named = bool(_STATUS.fullmatch(status)) and status != "CONVERGED"
                out.update(outcome="failed" if named else "crash", status=status)
                break
            out["steps"] += 1
            out["iterations"] += int(sum(dict(report.iterations or {}).values()))
            verdict = judge_step(bodies, start, sim.state, min_feature, case["dhat"])
            out["min_J"] = min(out["min_J"], verdict["min_J"])
            out["corner_cuts"] += verdict["corner_cuts"]
            out["max_cut_depth_m"] = max(out["max_cut_depth_m"], verdict["max_cut_depth_m"])
            out["samples"] = max(out["samples"], verdict["samples"])
            out["capped"] += int(verdict["capped"])
            if verdict["inverted"]:
                out.update(
                    outcome="converged_inversion", first=f"{verdict['inverted']} with J <= 0"
                )
                break
            if verdict["end_inside"] or verdict["passes"]:
                out.update(outcome="silent_crossing", first=verdict["first"])
                break
    except Exception as err:  # noqa: BLE001 - a crash is an outcome the record counts
        out.update(outcome="crash", status=f"{type(err).__name__}: {err}"[:300])
        out["traceback"] = traceback.format_exc()[-2000:]
    out["wall_s"] = time.perf_counter() - t0
    return out


def _worker_init() -> None:
    logging.disable(logging.WARNING)  # the library's notes: counted by the oracle, not printed
    warnings.simplefilter("ignore")


def _run_all(todo: list[dict], workers: int, sink) -> None:
    if workers <= 1:
        _worker_init()
        for i, case in enumerate(todo):
            sink(run_case(case), i + 1, len(todo))
        logging.disable(logging.NOTSET)
        return
    ctx = multiprocessing.get_context("spawn")  # fresh interpreters: no forked numba state
    with ctx.Pool(workers, initializer=_worker_init, maxtasksperchild=200) as pool:
        for i, result in enumerate(pool.imap_unordered(run_case, todo, chunksize=1)):
            sink(result, i + 1, len(todo))


def summarise(results: list[dict]) -> dict:
    """Counts per class x strategy and per pair kind (module docstring)."""

    def block(rows):
        outcome = collections.Counter(r["outcome"] for r in rows)
        statuses = collections.Counter(r["status"] for r in rows if r["outcome"] == "failed")
        finite_J = [r["min_J"] for r in rows if math.isfinite(r["min_J"])]
        return {
            "cases": len(rows),
            "outcomes": {k: outcome.get(k, 0) for k in OUTCOMES},
            "failure_statuses": dict(statuses.most_common()),
            "steps_judged": int(sum(r["steps"] for r in rows)),
            "min_J": min(finite_J) if finite_J else None,
            "corner_cuts": int(sum(r["corner_cuts"] for r in rows)),
            "max_cut_depth_m": max((r["max_cut_depth_m"] for r in rows), default=0.0),
            "capped_steps": int(sum(r["capped"] for r in rows)),
            "wall_s": float(sum(r["wall_s"] for r in rows)),
        }

    by_class = collections.defaultdict(list)
    by_pair = collections.defaultdict(list)
    for r in results:
        by_class[f"{r['cls']}/{r['strategy']}"].append(r)
        by_pair[f"{pair_kind(r)}/{r['strategy']}"].append(r)
    return {
        "total": block(results),
        "by_class": {k: block(v) for k, v in sorted(by_class.items())},
        "by_pair_kind": {k: block(v) for k, v in sorted(by_pair.items())},
        "defect_cases": [r for r in results if r["outcome"] in DEFECTS],
    }


def markdown(payload: dict) -> str:
    """``fuzz.md``: the record's tables."""
    s = payload["summary"]
    lines = [
        f"# Fuzz record ({payload['mode']}): {s['total']['cases']} cases, "
        f"{s['total']['steps_judged']} steps judged",
        "",
        f"Commit {payload['commit']}; strategies {', '.join(payload['strategies'])}; "
        f"{payload['wall_s']:.0f} s on {payload['workers']} workers"
        + (
            f" (resumed: {payload['resumed']} cases from earlier runs)"
            if payload["resumed"]
            else ""
        ),
        "",
        f"Silent crossings: **{s['total']['outcomes']['silent_crossing']}**; converged "
        f"inversions: **{s['total']['outcomes']['converged_inversion']}**; crashes: "
        f"**{s['total']['outcomes']['crash']}**.",
        "",
        f"Corner cuts (shallow chords of a sliding point, not crossings: "
        f"`benchmarks/_crossing_oracle.py`): {s['total']['corner_cuts']}, deepest "
        f"{s['total']['max_cut_depth_m']:.3g} m. Steps whose motion needed more than "
        f"{MAX_SAMPLES} oracle samples (judged at {MAX_SAMPLES}): {s['total']['capped_steps']}.",
        "",
    ]
    for title, key in (("class", "by_class"), ("pair kind", "by_pair_kind")):
        lines += [
            f"## By {title}",
            "",
            f"| {title} / strategy | cases | "
            + " | ".join(OUTCOMES)
            + " | steps | min J | corner cuts (deepest, m) | failure statuses |",
            "|---" * (len(OUTCOMES) + 6) + "|",
        ]
        for name, b in s[key].items():
            o = b["outcomes"]
            statuses = ", ".join(f"{k} {v}" for k, v in b["failure_statuses"].items())
            min_j = "-" if b["min_J"] is None else f"{b['min_J']:.3g}"
            lines.append(
                f"| {name} | {b['cases']} | "
                + " | ".join(str(o[k]) for k in OUTCOMES)
                + f" | {b['steps_judged']} | {min_j} | {b['corner_cuts']} "
                f"({b['max_cut_depth_m']:.2g}) | {statuses} |"
            )
        lines.append("")
    lines += ["## Defect cases", ""]
    if not s["defect_cases"]:
        lines.append("None.")
    for r in s["defect_cases"]:
        lines.append(
            f"- {r['cls']} seed {r['seed']} {r['strategy']}: {r['outcome']}: "
            f"{r['first'] or r['status']}"
        )
    return "\n".join(lines) + "\n"


def measure(
    mode: str, cfg: object, out: str | Path, workers: int | None = None, resume: bool = False
) -> dict:
    """The fuzz cases of ``mode``, each appended to ``out/fuzz_cases_<mode>.jsonl`` as it
    finishes (``resume``: keep those of the same code); ``workers`` processes (None: cores)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    todo = cases(mode)
    code = code_version(modules=("benchmarks.fuzz",))
    sink_path = out / f"fuzz_cases_{mode}.jsonl"
    done: dict[tuple, dict] = {}
    if resume and sink_path.exists():
        for line in sink_path.read_text().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:  # a line cut by a kill: run that case again
                continue
            if row.get("code") == code:
                done[(row["cls"], row["seed"], row["strategy"])] = row
    elif sink_path.exists():
        sink_path.unlink()
    resumed = len(done)
    todo = [c for c in todo if (c["cls"], c["seed"], c["strategy"]) not in done]
    log.info("fuzz (%s): %d cases, %d kept from an earlier run", mode, len(todo) + resumed, resumed)
    workers = workers or multiprocessing.cpu_count()
    commit = git_commit()
    t0 = time.perf_counter()
    results = list(done.values())
    with sink_path.open("a") as sink:

        def keep(result, i, n):
            result.update(code=code, commit=commit)
            sink.write(json.dumps(result, default=float) + "\n")
            sink.flush()
            results.append(result)
            if result["outcome"] in DEFECTS:
                which = (result[k] for k in ("cls", "seed", "strategy", "outcome"))
                log.warning("fuzz: %s seed %d %s: %s", *which)
            if i % 50 == 0 or i == n:
                log.info("fuzz: %d of %d cases (%.0f s)", i, n, time.perf_counter() - t0)

        _run_all(todo, workers, keep)
    return {
        "commit": commit,
        "code": code,
        "strategies": no_crossing_strategies(),
        "classes": list(scenes.CLASSES),
        "cases_per_class_and_strategy": CASES[mode],
        "implicit_steps": IMPLICIT_STEPS,
        "workers": workers,
        "resumed": resumed,
        "wall_s": time.perf_counter() - t0,
        "summary": summarise(results),
    }


def _arguments(parser: argparse._ActionsContainer) -> None:
    """``--workers`` and ``--resume`` (``python -m benchmarks fuzz``)."""
    parser.add_argument("--workers", type=int, help="processes at once (default: cores)")
    parser.add_argument(
        "--resume", action="store_true", help="keep the cases an earlier run of the same code kept"
    )


BENCHMARK = register(
    Benchmark(
        "fuzz",
        __doc__,
        dict.fromkeys(CASES, {}),
        measure,
        report=markdown,
        record=name_unless("full", "fuzz"),
        arguments=_arguments,
        needs_out=True,
        timings="^code$",  # the digest of the source: provenance, as the commit is
    )
)
run = BENCHMARK.run
