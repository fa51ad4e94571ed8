"""Trade study across strategies (issues 6, 17): accuracy against cost of each coupling strategy
and of its knobs, on the BFEMP scenes and one scene of each explicit paper.

``python -m benchmarks tradeoff [--quick | --full] [--out DIR]`` with the options of
``OPTIONS`` (scenes, strategies, knobs, workers or a Dask scheduler, cost axis, resume), also
``bfemp sweep``; replay one point with ``--replay tradeoff.json --id ID`` or ``--point '<record
as JSON>'``.

Where each part lives: the scenes and what each point's error is against
(``_tradeoff_scenes.SCENES``); the knobs and their ladders (``_tradeoff_knobs``; one knob at a
time, points with equal settings run once); one point per fresh process, locally or on a Dask
cluster (``_tradeoff_point`` running ``_tradeoff_runs.run_point``); the points kept for
``--resume`` (``_tradeoff_cache``); the fronts, winners, knob effects, feasibility (issue 40)
and the report (``_tradeoff_report``). Before the timed points a few steps of each scene and
strategy fill numba's on-disk cache. A later run of some scenes merges into a record with
``merge(record, rerun)``.

Outputs in ``--out`` (default ``results/``): ``tradeoff.json`` (every point's record, the
fronts, winners, crossovers, knob effects, infeasible points), ``tradeoff_<scene>.png`` (error
against cost, log-log) and ``tradeoff.md``. Modes: ``quick`` (coarse settings, seconds to a
minute per point) and ``full`` (around the papers' settings, hours of CPU per point for the
rings and hertz: meant for a Dask cluster).

A point's record holds everything to run it again (``scene``, ``settings``, ``mode``,
``threads``, the ``reference`` metrics its error is taken against, the ``commit``); the runs are
deterministic, so at the same commit replaying a record reproduces its error exactly (the wall
time is not).
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import math
import os
import shlex
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks._penetration import KEYS as PENETRATION_KEYS
from benchmarks._tradeoff_cache import FOLDER as CACHE_FOLDER
from benchmarks._tradeoff_cache import PointCache
from benchmarks._tradeoff_knobs import (
    finer_key,
    ladder,
    option_defaults,
    option_knobs,
    strategy_knobs,
)
from benchmarks._tradeoff_point import check_scheduler, execute_dask, execute_local, execute_point
from benchmarks._tradeoff_report import (
    COSTS,
    best_knob,
    crossovers,
    infeasible,
    knob_effect,
    markdown,
    pareto_front,
    plot_scene,
    winners,
)
from benchmarks._tradeoff_scenes import SCENE_FINER, SCENES
from benchmarks.common import git_commit
from benchmarks.runner import Benchmark, register

log = logging.getLogger(__name__)

NAME = "tradeoff"
MODES = ("quick", "full")
CONNECT_TIMEOUT_S = 10.0  # s, to reach a Dask scheduler
RUNS_MODULE = "benchmarks._tradeoff_runs"


# ----------------------------------------------------------------------------- planning
def _short(value: object) -> str:
    """A compact label of a knob value: 2e-3, 0.5, 0.333, 4, auto, none."""
    if value is None:
        return "none"
    if isinstance(value, str) or isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    value = float(value)
    if value == 0.0:
        return "0"
    exponent = math.floor(math.log10(abs(value)))
    if -1 <= exponent < 3:
        return format(value, ".3g")
    return f"{format(value / 10.0**exponent, '.3g')}e{exponent}"


def _names(value: str | list[str] | tuple[str, ...] | None, what: str, allowed: tuple) -> list:
    """Validated names from a comma-separated string or a list; None: every allowed one."""
    if value is None:
        return list(allowed)
    names = value.split(",") if isinstance(value, str) else list(value)
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise ValueError(f"--{what}s: give at least one {what}; available: {', '.join(allowed)}")
    for name in names:
        if name not in allowed:
            raise ValueError(f"unknown {what} {name!r}; available: {', '.join(allowed)}")
    return list(dict.fromkeys(names))


def _registry() -> tuple[str, ...]:
    """The library's strategy names (``bfemp.steppers.STRATEGIES``)."""
    return tuple(importlib.import_module("bfemp.steppers").STRATEGIES)


def all_knobs() -> tuple[str, ...]:
    """Every knob name: dt, the scenes' knobs and every strategy's declared option knobs."""
    names = ["dt", *SCENE_FINER, *(k for s in _registry() for k in option_knobs(s))]
    return tuple(dict.fromkeys(names))


def _check_value(where: str, knob: str, value: object, spec: dict | None) -> None:
    if value is None and spec is not None and "first" in spec:
        return  # "off": a knob swept from None (xpic_order)
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or value < 0 or (value == 0 and knob != "iterations"):
        raise ValueError(f"{where}: knob {knob} must be a positive number, got {value!r}")


def strategy_base(scene: str, strategy: str, mode: str) -> dict:
    """The settings of one strategy's base point on ``scene`` (what ``run_point`` takes, but
    ``scene``): the scene's base, ``strategy``, ``dt``, ``options`` and ``transfer`` if any."""
    spec = SCENES[scene]["strategies"][strategy]
    base = {"strategy": strategy, "dt": spec["dt"][mode], "options": dict(spec["options"])}
    if "transfer" in spec:
        base["transfer"] = spec["transfer"]
    return {**base, **SCENES[scene]["modes"][mode]["base"]}


def _knob_base(settings: dict, knob: str, strategy: str) -> object:
    if knob == "dt" or knob in SCENE_FINER:
        return settings[knob]
    return settings["options"].get(knob, option_defaults(strategy).get(knob))


def _with(settings: dict, knob: str, value: object) -> dict:
    """``settings`` with one knob changed (a scene knob, dt, or an option; an option at its
    current value, its default included, leaves ``settings`` as they are)."""
    if _knob_base(settings, knob, settings["strategy"]) == value:
        return settings
    if knob == "dt" or knob in SCENE_FINER:
        return {**settings, knob: value}
    return {**settings, "options": {**settings["options"], knob: value}}


def knob_table(scene: str, strategy: str, mode: str, sweeps: dict | None = None) -> dict:
    """Knob -> ``{"finer": +-1, "values": (...), "spec": ...}`` of one strategy on one scene.

    The scene's knobs (less the strategy's ``no_knobs``) take the mode's values; dt (at a fixed
    dt) or the CFL fractions (at ``dt="auto"``) and the strategy's option knobs take
    ``ladder`` values around the base. ``sweeps`` (``{knob: values}`` for every strategy of the
    scene, ``{strategy: {knob: values}}`` for one) replaces values; a knob swept from None
    starts at its declared ``first``.
    """
    decl = SCENES[scene]
    sdecl = decl["strategies"][strategy]
    base = strategy_base(scene, strategy, mode)
    table: dict[str, dict] = {}
    skip = sdecl.get("no_knobs", {})
    for knob in decl["scene_knobs"]:
        if knob not in skip:
            values = decl["modes"][mode]["sweeps"].get(knob, (base[knob],))
            table[knob] = {"finer": SCENE_FINER[knob], "values": tuple(values), "spec": None}
    for knob, spec in strategy_knobs(strategy, base["dt"]).items():
        spec = {**spec, **sdecl.get("spec", {}).get(knob, {})}
        values = () if knob in skip else ladder(spec, _knob_base(base, knob, strategy), mode)
        if values:
            table[knob] = {"finer": spec["finer"], "values": values, "spec": spec}
    overrides = dict((sweeps or {}).get(scene, {}))
    mine = overrides.pop(strategy, {}) if isinstance(overrides.get(strategy), dict) else {}
    overrides = {k: v for k, v in overrides.items() if k not in _registry()}
    for knob, values in {**overrides, **mine}.items():
        if knob not in table:
            continue  # a scene-wide override of a knob this strategy does not have
        values = tuple(values) if isinstance(values, list | tuple) else (values,)
        if not values:
            raise ValueError(f"sweeps[{scene!r}][{knob!r}] is empty")
        table[knob] = {**table[knob], "values": values}
    for knob, entry in table.items():
        for value in entry["values"]:
            _check_value(f"{scene}/{strategy}", knob, value, entry["spec"])
    return table


def _check_sweeps(sweeps: dict | None) -> None:
    known = all_knobs()
    for scene, by_knob in (sweeps or {}).items():
        if scene not in SCENES:
            raise ValueError(f"sweeps: unknown scene {scene!r}; available: {sorted(SCENES)}")
        for key, value in by_knob.items():
            if key in _registry() and key not in SCENES[scene]["strategies"]:
                raise ValueError(f"sweeps[{scene!r}]: strategy {key!r} does not run {scene}")
            unknown = [k for k in (value if key in _registry() else [key]) if k not in known]
            if unknown:
                raise ValueError(
                    f"sweeps[{scene!r}]: unknown knob {unknown[0]!r}; knobs: {', '.join(known)}"
                )


def run_order(records: list[dict], todo: list[int]) -> list[int]:
    """The indices ``todo`` of ``records`` in the order they are submitted: each scene's
    reference run first (every error of its scene waits for it, and it is the longest, so a
    sweep stopped early has it kept), then the plan's order."""
    return sorted(todo, key=lambda k: not records[k]["is_reference"])


def plan(
    mode: str,
    scenes: str | list[str] | None = None,
    knobs: str | list[str] | None = None,
    *,
    strategies: str | list[str] | None = None,
    sweeps: dict | None = None,
    threads: int = 1,
) -> list[dict]:
    """The points of a sweep (records without results), in run order.

    Args:
        mode: ``"quick"`` or ``"full"``.
        scenes: names or a comma-separated string (None: every scene).
        knobs: names or a comma-separated string (None: every knob of each strategy); the base
            point of each strategy always runs.
        strategies: registry names or a comma-separated string (None: every one), or
            ``{scene: names}`` (a scene not named there: every one); a strategy that does not
            apply to a scene is skipped there (logged with the reason); nothing left is an
            error.
        sweeps: value overrides, see :func:`knob_table`.
        threads: numba/BLAS threads of each point's process.

    Returns:
        one dict per distinct point: ``id`` (``scene/strategy/label``), ``scene``,
        ``strategy``, ``label``, ``role`` (``"base"``, ``"sweep"`` or ``"reference"``),
        ``knob`` and ``value`` (None for base and reference), ``sweeps`` (the knobs whose sweep
        holds the point), ``finer`` (knob -> direction, the strategy's knobs on the scene),
        ``is_reference``, ``settings``, ``mode``, ``threads``.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if not (isinstance(threads, int) and threads >= 1):
        raise ValueError(f"--threads-per-point must be an integer >= 1, got {threads!r}")
    scenes = _names(scenes, "scene", tuple(sorted(SCENES)))
    chosen_knobs = _names(knobs, "knob", all_knobs())
    per_scene = strategies if isinstance(strategies, dict) else {}
    for scene in per_scene:
        if scene not in SCENES:
            raise ValueError(f"strategies: unknown scene {scene!r}; available: {sorted(SCENES)}")
    everywhere = _names(None if per_scene else strategies, "strategy", _registry())
    _check_sweeps(sweeps)
    points = []
    for scene in scenes:
        chosen = everywhere
        if scene in per_scene:
            chosen = _names(per_scene[scene], "strategy", _registry())
        runs = [s for s in chosen if s in SCENES[scene]["strategies"]]
        for s in chosen:
            if s not in runs:
                why = SCENES[scene]["not_applicable"].get(s, "not declared for this scene")
                log.info("%s: %s does not run here: %s", scene, s, why)
        ref = SCENES[scene].get("reference_strategy")
        extra = [ref] if runs and ref and ref not in runs else []  # the others' errors need it
        for strategy in runs + extra:
            table = knob_table(scene, strategy, mode, sweeps)
            table = {k: v for k, v in table.items() if k in chosen_knobs}
            mine = _strategy_points(scene, strategy, mode, table, threads, strategy == ref)
            points += mine if strategy in runs else [p for p in mine if p["is_reference"]]
    if not points:
        raise ValueError(
            f"no scene among {', '.join(scenes)} runs any of the strategies "
            f"{', '.join(everywhere) if not per_scene else per_scene}; "
            + "; ".join(f"{s}: {', '.join(SCENES[s]['strategies'])}" for s in scenes)
        )
    return points


def _strategy_points(
    scene: str, strategy: str, mode: str, table: dict, threads: int, reference: bool
) -> list[dict]:
    base = strategy_base(scene, strategy, mode)
    by_settings: dict[str, dict] = {}
    finer = {k: v["finer"] for k, v in table.items()}

    def add(settings: dict, role: str, knob: str | None, label: str) -> dict:
        record = by_settings.setdefault(
            json.dumps(settings, sort_keys=True),
            {
                "id": f"{scene}/{strategy}/{label}",
                "scene": scene,
                "strategy": strategy,
                "label": label,
                "role": role,
                "knob": knob,
                "value": _knob_base(settings, knob, strategy) if knob else None,
                "sweeps": [],
                "finer": finer,
                "is_reference": False,
                "settings": settings,
                "mode": mode,
                "threads": threads,
            },
        )
        if knob and knob not in record["sweeps"]:
            record["sweeps"].append(knob)
        return record

    add(base, "base", None, "base")
    for knob, entry in table.items():
        for value in entry["values"]:
            add(_with(base, knob, value), "sweep", knob, f"{knob}={_short(value)}")
    if reference and "reference_keys" in SCENES[scene]:
        finest = dict(base)
        at_base = SCENES[scene]["modes"][mode].get("reference_at_base", {})
        for knob, entry in table.items():
            if knob not in at_base:  # declared with the reason (_tradeoff_scenes)
                value = max(entry["values"], key=lambda v, e=entry: finer_key(e, v))
                finest = _with(finest, knob, value)
        record = add(finest, "reference", None, "reference")  # or the sweep point it equals
        record["is_reference"], record["role"] = True, "reference"
    return list(by_settings.values())


# ----------------------------------------------------------------------------- running
def _job(record: dict, timeout_s: float | None) -> dict:
    """What ``execute_point`` runs for a record."""
    return {
        "module": RUNS_MODULE,
        "settings": {"scene": record["scene"], **record["settings"]},
        "threads": int(record.get("threads", 1)),
        "timeout_s": timeout_s,
    }


def _replay_line(record: str | Path, point_id: str) -> str:
    """The command that replays point ``point_id`` of the record file ``record``."""
    return (
        f"python -m benchmarks tradeoff --replay {shlex.quote(str(record))} "
        f"--id {shlex.quote(point_id)}"
    )


def point_error(scene: str, measurement: dict, reference: dict | None) -> tuple:
    """The point's error and its parts (``(None, {})`` for a failed point or reference).

    Args:
        scene: the scene name.
        measurement: ``execute_point``'s result.
        reference: for scenes without an analytic value, ``{"metrics": ...}`` of the reference
            run (None or no metrics: no error).
    """
    metrics = measurement.get("metrics")
    if measurement.get("failure") or not metrics:
        return None, {}
    spec = SCENES[scene]
    if "error_key" in spec:
        return metrics.get(spec["error_key"]), {}
    ref = (reference or {}).get("metrics")
    if not ref:
        return None, {}
    parts = {}
    for key in spec["reference_keys"]:
        value, target = metrics.get(key), ref.get(key)
        if value is None or not target:
            return None, {}
        parts[key] = abs(value - target) / abs(target)
    return max(parts.values()), parts


def _finish(record: dict, measurement: dict, reference: dict | None) -> dict:
    """A record with its measurement and error. A point whose metrics carry ``point_wall_s``
    and ``point_cpu_s`` (a run that also runs its own reference, lr_compression) costs those.
    The penetration and its bound (``PENETRATION_KEYS``) come up from the metrics, and
    ``infeasible`` says whether the depth exceeds the bound (``_tradeoff_report.infeasible``)."""
    error, parts = point_error(record["scene"], measurement, reference)
    metrics = measurement.get("metrics") or {}
    wall, cpu = measurement.get("wall_s"), measurement.get("cpu_s")
    if metrics.get("point_wall_s") is not None:
        wall, cpu = metrics["point_wall_s"], metrics.get("point_cpu_s")
    penetration = {key: metrics.get(key) for key in PENETRATION_KEYS}
    return {
        **record,
        **penetration,
        "infeasible": infeasible(penetration),
        "error": error,
        "error_parts": parts,
        "wall_s": wall,
        "cpu_s": cpu,
        "run_point_wall_s": measurement.get("wall_s"),
        "process_wall_s": measurement.get("process_wall_s"),
        "iterations": metrics.get("iterations"),
        "peak_memory_mb": measurement.get("peak_memory_mb"),
        "failure": measurement.get("failure"),
        "metrics": measurement.get("metrics"),
        "reference": reference,
    }


def _warmup_job(scene: str, strategy: str, threads: int) -> dict:
    """A few steps of the strategy's quick base on the scene (``SCENES[scene]["warmup"]``):
    fills numba's cache before the timed points (a cold cache would put compilation into the
    first points' times)."""
    settings = {**strategy_base(scene, strategy, "quick"), **SCENES[scene]["warmup"]}
    return _job({"scene": scene, "settings": settings, "threads": threads}, None)


def _reference(records: list[dict], results: list[dict]) -> dict[str, dict]:
    """scene -> the reference run's id, settings and metrics (scenes with a reference only)."""
    out = {}
    for record, result in zip(records, results, strict=True):
        if record["is_reference"]:
            keys = SCENES[record["scene"]]["reference_keys"]
            ok = result.get("metrics") and not result.get("failure")
            out[record["scene"]] = {
                "id": record["id"],
                "settings": record["settings"],
                "metrics": {k: result["metrics"].get(k) for k in keys} if ok else None,
                "failure": result.get("failure"),
            }
    return out


# ----------------------------------------------------------------------------- analysis
def swept_knobs(records: list[dict], scene: str) -> dict[str, list[str]]:
    """strategy -> the knobs that took at least two values on ``scene`` (sorted)."""
    mine = [r for r in records if r["scene"] == scene]
    counts = {r["strategy"]: Counter() for r in mine}
    for r in mine:
        counts[r["strategy"]].update(r["sweeps"])
    return {s: sorted(k for k, n in c.items() if n >= 2) for s, c in counts.items()}


def _front(recs: list[dict], cost: str) -> set[int]:
    """Indices of ``recs`` on their non-dominated front; infeasible points take no part."""
    seconds = np.array([r[cost] if r[cost] else np.nan for r in recs], dtype=float)
    err = np.array(
        [np.nan if r["error"] is None or infeasible(r) else r["error"] for r in recs], dtype=float
    )
    return set(pareto_front(seconds, err).tolist())


def analyse(records: list[dict], scenes: list[str], cost: str = "wall_s") -> dict:
    """Mark the Pareto points; per scene the winners; per scene and strategy the knob effects.

    ``record["infeasible"]``: deeper inside a FEM body than its strategy's bound
    (``_tradeoff_report.infeasible``: never on a front, never a winner); ``record["pareto"]``:
    on the scene's front over every strategy; ``record["strategy_pareto"]``: on its strategy's
    own front. ``cost`` is the record key of the cost axis (``"wall_s"`` or ``"cpu_s"``).

    Returns:
        ``{"knob_effects": {scene: {strategy: {knob: effect}}}, "best_knob": {scene: {strategy:
        knob}}, "winners": {scene: ranges}, "crossovers": {scene: [...]}, "infeasible":
        {scene: [point ids]}}``.
    """
    keys = ("knob_effects", "best_knob", "winners", "crossovers", "infeasible")
    out: dict = {key: {} for key in keys}
    for scene in scenes:
        recs = [r for r in records if r["scene"] == scene]
        for r in recs:
            r["infeasible"] = infeasible(r)
        out["infeasible"][scene] = [r["id"] for r in recs if r["infeasible"]]
        front = _front(recs, cost)
        for k, r in enumerate(recs):
            r["pareto"] = k in front
        out["knob_effects"][scene], out["best_knob"][scene] = {}, {}
        for strategy in dict.fromkeys(r["strategy"] for r in recs):
            mine = [r for r in recs if r["strategy"] == strategy]
            own = _front(mine, cost)
            for k, r in enumerate(mine):
                r["strategy_pareto"] = k in own
            effects = {}
            for knob in dict.fromkeys(k for r in mine for k in r["sweeps"]):
                sweep = [r for r in mine if knob in r["sweeps"]]
                rows = [
                    {
                        "value": r["value"]
                        if r["knob"] == knob
                        else _knob_base(r["settings"], knob, strategy),
                        "error": r["error"],
                        "time_s": r[cost],
                    }
                    for r in sweep
                ]
                rows = [row for row in rows if row["value"] is not None]  # "off" is no number
                effects[knob] = knob_effect(rows, sweep[0]["finer"][knob])
            out["knob_effects"][scene][strategy] = effects
            out["best_knob"][scene][strategy] = best_knob(effects)
        out["winners"][scene] = winners(recs, cost)
        out["crossovers"][scene] = crossovers(out["winners"][scene])
    return out


def _analysed(payload: dict) -> dict:
    """``payload`` (a trade study's record) with its analysis (``analyse``), each scene's swept
    knobs (``swept_knobs``) and Pareto point ids taken again from its points; returns it."""
    points, scenes = payload["points"], payload["scenes"]
    payload.update(analyse(points, scenes, payload["cost"]))
    payload["knobs"] = {s: swept_knobs(points, s) for s in scenes}
    payload["pareto"] = {
        s: [r["id"] for r in points if r["scene"] == s and r["pareto"]] for s in scenes
    }
    return payload


# ----------------------------------------------------------------------------- entry points
def sweep(mode: str = "quick", out: str | Path = "results", **options) -> dict:
    """Run the trade study and write ``tradeoff.json``, ``tradeoff.md``, ``tradeoff_<scene>.png``
    (``BENCHMARK.run``; ``options`` those of ``_measure``); returns ``{"json": path, "md": path,
    **record}``."""
    return BENCHMARK.run(mode, out, **options)


def _measure(
    mode: str,
    cfg: object,
    *,
    out: str | Path,
    scenes: str | list[str] | None = None,
    knobs: str | list[str] | None = None,
    strategies: str | list[str] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    threads: int = 1,
    timeout_s: float | None = None,
    sweeps: dict | None = None,
    cost: str = "wall",
    warmup: bool = True,
    resume: bool = False,
    points: str | Path | None = None,
    progress: bool = False,
) -> dict:
    """The trade study's payload; each point's measurement is also kept in the points folder
    as it arrives (``_tradeoff_cache``), so that a stopped sweep can be resumed.

    ``mode``, ``scenes``, ``knobs``, ``strategies``, ``sweeps``, ``threads``: see :func:`plan`;
    ``workers`` (default: the number of cores, ignored with ``scheduler``), ``scheduler``,
    ``timeout_s``, ``cost``, ``resume``, ``points``: the command-line options (``OPTIONS``; a
    resumed point keeps the times and ``commit`` of the run that measured it); ``warmup``: first
    run a few steps of each scene to fill numba's cache (untimed); ``progress``: a progress bar
    (points done, the last point's id) on stderr.
    """
    if scheduler is not None:
        check_scheduler(scheduler)
    if cost not in ("wall", "cpu"):
        raise ValueError(f"--cost must be 'wall' or 'cpu', got {cost!r}")
    workers = (os.cpu_count() or 1) if workers is None else workers
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"--workers must be an integer >= 1, got {workers!r}")
    records = plan(mode, scenes, knobs, strategies=strategies, sweeps=sweeps, threads=threads)
    scene_names = list(dict.fromkeys(r["scene"] for r in records))
    pairs = list(dict.fromkeys((r["scene"], r["strategy"]) for r in records))
    commit = git_commit()
    out = Path(out)
    jobs = [_job(r, timeout_s) for r in records]
    log.info("tradeoff (%s): %d points of %s", mode, len(jobs), ", ".join(scene_names))
    execute = _executor(scheduler, workers, progress)
    cache = PointCache(out / CACHE_FOLDER if points is None else Path(points), commit)
    entries = [cache.entry(job) if resume else None for job in jobs]
    results = [e and e["measurement"] for e in entries]  # None: to run
    todo = run_order(records, [k for k, m in enumerate(results) if m is None])
    # kept point id -> the commit that measured it
    measured_by = {records[k]["id"]: e.get("commit") for k, e in enumerate(entries) if e}
    if resume:
        log.info("tradeoff: %d of %d points kept in %s", len(measured_by), len(jobs), cache.folder)
    started = time.perf_counter()
    running = {(records[k]["scene"], records[k]["strategy"]) for k in todo}
    warm = [pair for pair in pairs if pair in running] if warmup else []
    warmed = execute(
        [f"{scene}/{strategy}/warmup" for scene, strategy in warm],
        [_warmup_job(scene, strategy, threads) for scene, strategy in warm],
        what="warm-up",
    )
    warmup_s = time.perf_counter() - started
    started = time.perf_counter()
    ran = execute(
        [records[k]["id"] for k in todo],
        [jobs[k] for k in todo],
        lambda j, measurement: cache.put(records[todo[j]]["id"], jobs[todo[j]], measurement),
    )
    for k, measurement in zip(todo, ran, strict=True):
        results[k] = measurement
    elapsed = time.perf_counter() - started
    references = _reference(records, results)
    finished = [
        _finish(record, result, references.get(record["scene"]))
        | {
            "resumed": record["id"] in measured_by,
            "commit": measured_by.get(record["id"], commit),
            "replay": _replay_line(out / f"{NAME}.json", record["id"]),
        }
        for record, result in zip(records, results, strict=True)
    ]

    mine = {s: [st for sc, st in pairs if sc == s] for s in scene_names}
    return _analysed(
        {
            "scenes": scene_names,
            "strategies": mine,
            "strategy_notes": {
                s: {st: SCENES[s]["strategies"][st].get("note") for st in mine[s]}
                for s in scene_names
            },
            "not_run": {s: _not_run(s, strategies, pairs) for s in scene_names},
            "errors": {s: SCENES[s]["error"] for s in scene_names},
            "executor": {
                "kind": "dask" if scheduler else "local",
                "workers": None if scheduler else workers,
                "scheduler": scheduler,
                "threads_per_point": threads,
                "timeout_s": timeout_s,
            },
            "cost": f"{cost}_s",
            "sweeps_override": sweeps,  # what replaced the mode's values (None: none)
            "strategies_chosen": strategies,
            "knobs_chosen": knobs,
            "warmup_s": warmup_s,
            "warmup_failures": [w["failure"] for w in warmed if w.get("failure")],
            "wall_s": elapsed,
            "resumed": list(measured_by),
            "point_wall_s_total": sum(r["wall_s"] or 0.0 for r in finished),
            "failed": [r["id"] for r in finished if r["failure"]],
            "references": references,
            "points": finished,
        }
    )


def _executor(scheduler: str | None, workers: int, progress: bool) -> Callable[..., list[dict]]:
    """``execute(ids, jobs, on_done=None, what="points")``: ``execute_point`` of every job on
    the Dask ``scheduler`` or ``workers`` local processes, a progress bar on stderr (points
    done, the last point's id) when ``progress``; the ``(n,)`` measurements in job order."""

    def execute(ids: list[str], jobs: list[dict], on_done=None, what="points") -> list[dict]:  # noqa: ANN001
        from tqdm.auto import tqdm

        bar = tqdm(total=len(ids), desc=f"tradeoff {what}", unit="point", disable=not progress)

        def done(j: int, measurement: dict) -> None:
            if on_done is not None:
                on_done(j, measurement)
            bar.update(1)
            bar.set_postfix_str(ids[j], refresh=False)

        try:
            if scheduler is not None:
                return execute_dask(ids, jobs, scheduler, CONNECT_TIMEOUT_S, done)
            return execute_local(ids, jobs, workers, done)
        finally:
            bar.close()

    return execute


def _not_run(scene: str, strategies: str | list | dict | None, pairs: list[tuple]) -> dict:
    """The chosen strategies that do not run ``scene`` (no (scene, strategy) in ``pairs``), each
    with why (``SCENES[scene]["not_applicable"]``)."""
    chosen = strategies.get(scene) if isinstance(strategies, dict) else strategies
    why = SCENES[scene]["not_applicable"]
    return {
        st: why.get(st, "not declared for this scene")
        for st in _names(chosen, "strategy", _registry())
        if (scene, st) not in pairs
    }


def _plot(payload: dict, png: Path) -> None:
    """One figure per scene, ``<stem>_<scene>.png`` beside ``png`` (error against cost)."""
    for scene in payload["scenes"]:
        kind = "reference run" if "reference_keys" in SCENES[scene] else "analytic"
        plot_scene(
            [r for r in payload["points"] if r["scene"] == scene],
            png.with_name(f"{png.stem}_{scene}.png"),
            f"{scene}: error against {COSTS[payload['cost']]} ({payload['mode']} mode)",
            f"error vs {kind}",
            payload["cost"],
        )


def rerender(path: str | Path) -> dict:
    """Write the report (``<stem>.md``) and the plots (``<stem>_<scene>.png``) again from a
    ``tradeoff.json`` (its points as recorded: the fronts, winners and knob effects are
    recomputed from them)."""
    path = Path(path)
    payload = _analysed(json.loads(path.read_text()))
    path.write_text(json.dumps(payload, indent=2, default=float))
    path.with_suffix(".md").write_text(markdown(payload))
    _plot(payload, path.with_suffix(".png"))
    return payload


def merge(record: str | Path, rerun: str | Path, keep_other_strategies: bool = False) -> dict:
    """Merge a later run of some scenes (``rerun``, a ``tradeoff.json``) into ``record`` (a
    ``tradeoff.json``, rewritten), then write its report and plots again (``rerender``).

    The rerun's scenes replace the record's points, references, knobs and errors of those scenes
    (new scenes join in ``SCENES``' order); the other scenes keep theirs, their not-run reasons and
    the rerun scenes' strategy notes as ``SCENES`` declares them now. ``record["merged"]`` lists
    each merged run (scenes, commit, points, workers, elapsed s, environment; the first merge also
    the first run's point count); every point keeps its own ``commit``.

    ``keep_other_strategies``: a rerun of some strategies of a scene (``--strategies augury,lr``)
    replaces only their points; the record's points of the scene's other strategies stay (not
    its old reference run: the rerun's replaces it), their errors taken again against the rerun's
    reference (``point_error`` on their kept metrics; ``error_against`` names that reference's
    commit), so that every error of a scene is against one reference run.
    """
    record, rerun = Path(record), Path(rerun)
    old, new = json.loads(record.read_text()), json.loads(rerun.read_text())
    scenes = new["scenes"]
    kept = _kept_points(old, new) if keep_other_strategies else []
    order = [s for s in SCENES if s in old["scenes"] or s in scenes]
    for key in ("strategies", "strategy_notes", "not_run", "knobs", "errors", "references"):
        merged = {s: (new if s in scenes else old)[key].get(s) for s in order}
        old[key] = {s: v for s, v in merged.items() if v is not None}
    for p in kept:  # the kept strategies are run strategies of their scene again
        scene, strategy = p["scene"], p["strategy"]
        if strategy not in old["strategies"][scene]:
            old["strategies"][scene].append(strategy)
        old["strategy_notes"][scene].setdefault(strategy, None)  # SCENES' note, below
        old["not_run"].get(scene, {}).pop(strategy, None)
    for s in order:
        if s in scenes:
            notes = old["strategy_notes"][s]
            old["strategy_notes"][s] = {st: SCENES[s]["strategies"][st].get("note") for st in notes}
        else:
            why = SCENES[s]["not_applicable"]
            old["not_run"][s] = {st: why.get(st, "not declared") for st in old["not_run"][s]}
    before = len(old["points"])
    points = [p for p in old["points"] if p["scene"] not in scenes] + kept + new["points"]
    for p in points:  # replay from the merged record, wherever each run was written
        p["replay"] = _replay_line(record, p["id"])
    old["points"] = sorted(points, key=lambda p: order.index(p["scene"]))
    old["scenes"] = order
    old["failed"] = [p["id"] for p in old["points"] if p["failure"]]
    part = {"scenes": scenes, "commit": new["environment"]["commit"], "points": len(new["points"])}
    part["workers"] = new["executor"]["workers"]
    part |= {key: new[key] for key in ("executor", "wall_s", "warmup_s", "environment")}
    if "merged" not in old:
        part["first_run_points"] = before
    old.setdefault("merged", []).append(part)
    record.write_text(json.dumps(old, indent=2, default=float))
    return rerender(record)


def _kept_points(old: dict, new: dict) -> list[dict]:
    """The record's points that a partial rerun keeps (``merge(keep_other_strategies=True)``):
    in the rerun's scenes, those of strategies the rerun has no point of (its reference aside),
    not the old reference; errors again against the rerun's reference."""
    kept = []
    against = f"reference run at {new['environment']['commit']}"
    for scene in new["scenes"]:
        rerun = {
            p["strategy"] for p in new["points"] if p["scene"] == scene and not p["is_reference"]
        }
        reference = new["references"].get(scene)
        for p in old["points"]:
            if p["scene"] == scene and p["strategy"] not in rerun and not p["is_reference"]:
                error, parts = point_error(scene, p, reference)
                kept.append(
                    {**p, "error": error, "error_parts": parts, "reference": reference}
                    | {"error_against": against if reference else None}
                )
    return kept


def load_record(
    path: str | Path | None = None, point_id: str | None = None, point: str | None = None
) -> dict:
    """The record to replay: from a JSON file (one record, or a ``tradeoff.json`` and an id) or
    from a JSON string."""
    where = "--point" if point is not None else "--replay"
    try:
        data = json.loads(point if point is not None else Path(path).read_text())
    except FileNotFoundError:
        raise ValueError(f"--replay: no file {path}") from None
    except json.JSONDecodeError as err:
        what = "" if point is not None else f": {path}"
        raise ValueError(f"{where}{what} is not valid JSON: {err}") from None
    if isinstance(data, dict) and "points" in data:
        ids = [p["id"] for p in data["points"]]
        if point_id is None:
            if len(ids) != 1:
                raise ValueError(
                    f"{path or '--point'} holds {len(ids)} points; choose one with --id "
                    f"(e.g. {', '.join(ids[:3])})"
                )
            point_id = ids[0]
        if point_id not in ids:
            raise ValueError(f"no point {point_id!r} in {path or '--point'}; ids: {', '.join(ids)}")
        data = data["points"][ids.index(point_id)]
    if not isinstance(data, dict) or "scene" not in data or "settings" not in data:
        raise ValueError("a point record needs at least 'scene' and 'settings'")
    if data["scene"] not in SCENES:
        raise ValueError(f"unknown scene {data['scene']!r}; available: {', '.join(sorted(SCENES))}")
    return data


def _check_settings(record: dict) -> None:
    """The record's strategy runs its scene and its knob values are valid."""
    scene, settings = record["scene"], record["settings"]
    strategy = settings.get("strategy")
    if strategy not in SCENES[scene]["strategies"]:
        raise ValueError(
            f"{scene}: strategy {strategy!r} does not run here; its strategies: "
            f"{', '.join(SCENES[scene]['strategies'])}"
        )
    if not isinstance(settings.get("options"), dict):
        raise ValueError(f"{scene} settings: 'options' must be a dict of the strategy's options")
    for knob, entry in knob_table(scene, strategy, record.get("mode", "quick")).items():
        base = _knob_base(settings, knob, strategy)
        _check_value(f"{scene}/{strategy}", knob, base, entry["spec"])


def replay(record: dict, timeout_s: float | None = None) -> dict:
    """Run a recorded point again (fresh process) and recompute its error.

    For scenes with a reference run the error is taken against ``record["reference"]`` (the
    stored reference metrics). Returns the new record plus ``recorded_error`` and
    ``reproduced`` (the new error equals the recorded one to 1e-9, relative).
    """
    _check_settings(record)
    point = {
        "id": record.get("id", f"{record['scene']}/{record['settings']['strategy']}/point"),
        "scene": record["scene"],
        "label": record.get("label", "point"),
        "settings": record["settings"],
        "threads": int(record.get("threads", 1)),
    }
    measurement = execute_point(_job(point, timeout_s))
    done = _finish({**record, **point}, measurement, record.get("reference"))
    recorded, new = record.get("error"), done["error"]
    if recorded is None or new is None:
        same = recorded is None and new is None
    else:
        same = math.isclose(new, recorded, rel_tol=1e-9, abs_tol=1e-300)
    done["commit"] = git_commit()
    if record.get("commit") not in (None, done["commit"]):
        log.warning(
            "%s was recorded at commit %s, replayed at %s: the error may differ",
            point["id"],
            record["commit"],
            done["commit"],
        )
    return {**done, "recorded_error": recorded, "reproduced": same}


#: the sweep's command-line options: flag -> (keyword of ``sweep``, argparse settings)
OPTIONS = {
    "--scenes": ("scenes", dict(help=f"comma-separated scenes (default: {', '.join(SCENES)})")),
    "--knobs": ("knobs", dict(help="comma-separated knobs (default: every knob of each strategy)")),
    "--strategies": (
        "strategies",
        dict(help="comma-separated strategies (default: all that apply)"),
    ),
    "--workers": ("workers", dict(type=int, help="local point processes at once (default: cores)")),
    "--scheduler": ("scheduler", dict(help="run the points on a Dask scheduler (tcp://host:port)")),
    "--threads-per-point": ("threads", dict(type=int, default=1, help="threads of each point")),
    "--point-timeout": ("timeout_s", dict(type=float, help="wall-time limit of one point in s")),
    "--resume": ("resume", dict(action="store_true", help="take the points kept of the same code")),
    "--points": ("points", dict(metavar="DIR", help="kept points (default OUT/tradeoff_points/)")),
    "--cost": (
        "cost",
        dict(
            choices=("wall", "cpu"),
            default="wall",
            help="cost axis: the points' wall time (default) or CPU time (steadier when busy)",
        ),
    ),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The trade study's options (``python -m benchmarks tradeoff``; ``bfemp sweep`` repeats
    them, a test keeps the two in step): ``OPTIONS``, and the replay of one point."""
    group = parser.add_argument_group("trade study")
    for flag, (dest, settings) in OPTIONS.items():
        group.add_argument(flag, dest=dest, **settings)
    group.add_argument("--replay", metavar="JSON", help="re-run a recorded point (tradeoff.json)")
    group.add_argument("--id", help="with --replay: the point's id in tradeoff.json")
    group.add_argument("--point", metavar="JSON", help="re-run the point given as a JSON record")


def main_from_args(args: argparse.Namespace) -> int:
    """Run the sweep, or replay one point, from parsed command-line options; the exit status."""
    if args.replay is not None or args.point is not None:
        if args.replay is not None and args.point is not None:
            raise ValueError("give --replay or --point, not both")
        result = replay(load_record(args.replay, args.id, args.point), timeout_s=args.timeout_s)
        status = "reproduced" if result["reproduced"] else "NOT reproduced"
        print(
            f"{result['id']}: error {result['error']} (recorded {result['recorded_error']}): "
            f"{status}; wall {result['wall_s']} s, {result['iterations']} iterations, "
            f"peak {result['peak_memory_mb']} MiB"
            + (f"; failure: {result['failure']}" if result["failure"] else "")
        )
        return 0 if result["reproduced"] else 1
    if args.id is not None:
        raise ValueError("--id goes with --replay")
    options = {dest: getattr(args, dest) for dest, _ in OPTIONS.values()}
    progress = not getattr(args, "quiet", False)
    summary = sweep(args.mode or "full", args.out, **options, progress=progress)
    print(f"tradeoff: wrote {summary['json']}, {summary['md']}")
    for scene in summary["scenes"]:
        won = [f"{w['winner']} from {w['error_from']:.3g}" for w in summary["winners"][scene]]
        bad = ", ".join(summary["infeasible"][scene]) or "none"
        print(f"  {scene}: winners {', '.join(won) or '-'}; infeasible (past its bound): {bad}")
    return 0


#: the record's keys computed from the points' wall or CPU times (fronts, winners, crossovers,
#: knob effects) and the warm-up's time: left out by ``verify``, which compares every point's
#: settings, metrics and error
TIMINGS = r"^(pareto|strategy_pareto|winners|crossovers|knob_effects|best_knob|warmup_s)$"
BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        dict.fromkeys(MODES, {}),
        _measure,
        _plot,
        markdown,
        timings=TIMINGS,
        needs_out=True,
    )
)
