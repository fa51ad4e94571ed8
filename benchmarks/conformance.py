"""``python -m benchmarks conformance``: every strategy on the catalogue's canonical scenes.

Each case of :mod:`benchmarks._conformance_scenes` runs under every registered strategy with its
defaults (``dt="auto"`` for the explicit ones, the case's ``barrier_dt`` for ``barrier``). A
strategy whose capabilities (``bfemp strategies``) do not cover a pair of the scene is refused by
``Simulation`` by name: the cell reads ``REFUSED``. A step that fails raises a named ``StepError``
(``TUNNELED``, ``CFL_VIOLATED``, ...): ``NAMED_FAILURE``, never a silent wrong answer. A run that
finishes is judged by the case's checks:

Guarantees (what ``Capabilities`` declares; the tests assert them on the quick mode):

- ``penetration``: the largest ``penetration_depth`` (the shared point-in-body check,
  ``bfemp.contact.penetration``) over the run, within the strategy's bound
  (``penetration_bound_cells`` x the grid's dx; 0 for barrier and two_stage).
- ``held``: the falling body stays on the plate: its centre of mass ends at least half its
  half-height above the plate top.
- ``stacked``: the upper block's centre of mass ends above the lower block's top, and the lower
  block's above the plate.
- ``no_pass``: no particle ends beyond the far side of the thin plate.
- ``rebound``: the bodies separate after the impact (normal relative velocity reversed:
  restitution > 0.05), whether a strategy couples them by contact or by a shared grid (MPM's
  native coupling: no slip while the bodies share grid nodes, and they part once they do not).
- ``friction`` (mu = 1.5 tan theta, strategies that declare friction): friction acts: the block
  slides less than half the frictionless distance over the fit window.

Accuracy (measured and recorded; not a declared guarantee, so a miss is a finding, not a bug):

- ``acceleration``: the block's acceleration along the incline (linear fit of the centre-of-mass
  velocity after landing) against g (sin theta - mu cos theta): error / (g sin theta) <= 0.1.
- ``sticks`` (mu = 1.5 tan theta): the block slides less than 5 % of the frictionless distance
  over the fit window (it sticks).
- ``momentum``: linear momentum of the free bodies, max |p(t) - p(0)| / sum m |v0| <= 1e-6.
- ``angular_momentum``: max |L(t) - L(0)| / sum m |x0 x v0| <= 1e-2 (oblique impacts).
- ``drift``: the upper block's rms speed over the run's second half <= 0.05 m/s.

The tolerances are this catalogue's choices (no paper gives them). Outputs: ``conformance.json``
(every cell: outcome, checks with value and limit, notes counted, wall time), ``conformance.md``
(the strategy x case table and the findings) and ``conformance.png`` (the table in colour).
"""

from __future__ import annotations

import logging
import math
import time
import warnings
from pathlib import Path

import numpy as np

import bfemp
from benchmarks._conformance_scenes import CASES, Case, body_mass_arrays, body_positions
from benchmarks.common import figure, table_head
from benchmarks.runner import Benchmark, name_unless, register
from bfemp.steppers import STRATEGIES, StepError
from bfemp.steppers.capabilities import scene_pairs

__all__ = ["GUARANTEES", "check_case", "run", "run_cell"]

log = logging.getLogger(__name__)

#: checks that test what a strategy's capabilities declare (the rest measure accuracy)
GUARANTEES = frozenset({"penetration", "held", "stacked", "no_pass", "rebound", "friction"})
#: accuracy limits (module docstring)
LIMITS = {
    "acceleration": 0.1,
    "momentum": 1e-6,
    "angular_momentum": 1e-2,
    "drift": 0.05,
    "sticks": 0.05,
    "friction": 0.5,
    "rebound_restitution": 0.05,
}


class _Recorder:
    """Per step: every body's centre of mass, its velocity and its extent along each axis."""

    KEYS = ("com", "vel", "lo", "hi")

    def __init__(self, sim: bfemp.Simulation) -> None:
        self.masses = body_mass_arrays(sim.model)
        self.t: list[float] = []
        self.series = {key: {n: [] for n in self.masses} for key in self.KEYS}
        self(sim)

    def __call__(self, sim: bfemp.Simulation) -> None:
        state = sim.state
        velocities = {b.name: state.fem_v[b.nodes] for b in sim.model.fem_bodies}
        velocities.update({b.name: state.mpm_v[b.particles] for b in sim.model.mpm_bodies})
        self.t.append(state.t)
        for name, x in body_positions(sim.model, state).items():
            m = self.masses[name]
            com, vel = m @ x / m.sum(), m @ velocities[name] / m.sum()
            for key, value in zip(self.KEYS, (com, vel, x.min(axis=0), x.max(axis=0)), strict=True):
                self.series[key][name].append(value)

    def arrays(self) -> dict:
        """``t (T,)`` in s and, per key of ``KEYS`` and body, ``(T, d)`` (m or m/s)."""
        out = {key: {n: np.array(v) for n, v in by.items()} for key, by in self.series.items()}
        return {"t": np.array(self.t), **out}


def _result(value: float, limit: float, passed: bool, text: str) -> dict:
    return {"value": float(value), "limit": float(limit), "passed": bool(passed), "text": text}


def _within(check: str, value: float, text: str) -> dict:
    """The result of an accuracy check: ``value`` at most its limit ``LIMITS[check]``."""
    return _result(value, LIMITS[check], value <= LIMITS[check], text)


def check_case(case: Case, strategy: str, sim: bfemp.Simulation, rec: dict, mode: str) -> dict:
    """Evaluate ``case.checks`` on a finished run; returns ``{check: result}``."""
    caps = STRATEGIES[strategy].capabilities
    t, com, vel, lo, hi = rec["t"], rec["com"], rec["vel"], rec["lo"], rec["hi"]
    p = case.params
    out = {}
    for name in case.checks:
        if name == "penetration":
            if "penetration_depth" not in sim.metrics.columns:
                continue  # no FEM body in the scene: nothing to penetrate
            depth = float(np.nanmax(sim.metrics.column("penetration_depth")))
            bound = caps.penetration_bound_cells
            limit = 0.0 if bound is None else bound * case.dx
            out[name] = _result(
                depth,
                limit,
                depth <= limit,
                f"deepest {depth:.3g} m ({depth / case.dx:.2f} cells), bound {limit:.3g} m",
            )
        elif name == "held":
            up = p["up"]
            half = 0.5 * (hi["body"][0, up] - lo["body"][0, up])
            height = (com["body"][-1, up] - p["plate_top"]) / half
            out[name] = _result(
                height, 0.5, height >= 0.5, f"centre of mass ends {height:.2f} half-heights up"
            )
        elif name == "stacked":
            up = p["up"]
            above = com["body"][-1, up] - hi["lower"][-1, up]
            lower_up = com["lower"][-1, up] - p["plate_top"]
            out[name] = _result(
                above,
                0.0,
                above > 0.0 and lower_up > 0.0,
                f"upper centre {above:.3g} m above the lower top; lower centre {lower_up:.3g} m "
                "above the plate",
            )
        elif name == "no_pass":
            beyond = float(p["plate_bottom"] - lo["body"][-1, p["up"]])
            out[name] = _result(
                beyond, 0.0, beyond <= 0.0, f"lowest particle {beyond:.3g} m beyond the plate"
            )
        elif name == "rebound":
            out[name] = _rebound(case, caps, com, vel)
        elif name in ("acceleration", "sticks"):
            t_from = p["fit_from"][mode]
            late = t >= t_from
            if name == "acceleration":
                a_fit = float(np.polyfit(t[late], vel["body"][late, 0], 1)[0])
                err = abs(a_fit - p["a_exact"]) / p["a_free"]
                text = f"a = {a_fit:.3f} m/s^2 against {p['a_exact']:.3f} (error {err:.3f} g sin)"
                out[name] = _within(name, err, text)
            else:
                slip = abs(com["body"][-1, 0] - com["body"][late][0, 0])
                free = 0.5 * p["a_free"] * (t[-1] - t[late][0]) ** 2
                text = f"slid {slip:.3g} m, {100 * slip / free:.1f} % of frictionless {free:.3g} m"
                for check in ("friction", "sticks"):
                    out[check] = _within(check, slip / free, text)
        elif name in ("momentum", "angular_momentum"):
            out[name] = _conservation(name, sim, com, vel, rec)
        elif name == "drift":
            half = t >= 0.5 * t[-1]
            rms = float(np.sqrt(np.mean(np.sum(vel["body"][half] ** 2, axis=1))))
            out[name] = _within(name, rms, f"upper block rms speed {rms:.3g} m/s")
        else:
            raise ValueError(f"unknown check {name!r}")
    return out


def _rebound(case: Case, caps: object, com: dict, vel: dict) -> dict:
    kinds = case.params["kinds"]
    pair = "mpm-fem" if kinds[0] != kinds[1] else f"{kinds[0]}-{kinds[1]}"
    # the contact normal: the line of centres at their closest approach
    gaps = com["b"] - com["a"]
    normal = gaps[np.argmin(np.linalg.norm(gaps, axis=1))]
    normal = normal / np.linalg.norm(normal)
    v0 = vel["a"][0] - vel["b"][0]
    v1 = vel["a"][-1] - vel["b"][-1]
    approach = float(v0 @ normal)
    e = -float(v1 @ normal) / approach
    lim = LIMITS["rebound_restitution"]
    how = caps.couples(pair)
    return _result(e, lim, e > lim, f"{how}: restitution {e:.3f} along the contact normal")


def _conservation(name: str, sim: bfemp.Simulation, com: dict, vel: dict, rec: dict) -> dict:
    masses = {n: float(m.sum()) for n, m in rec["masses"].items()}
    if name == "momentum":
        cols = [c for c in sim.metrics.columns if c.startswith("momentum_")]
        p = np.stack([sim.metrics.column(c) for c in cols], axis=1)
        scale = sum(masses[n] * float(np.linalg.norm(vel[n][0])) for n in masses)
        err = float(np.max(np.linalg.norm(p - p[0], axis=1))) / scale
        text = f"max |p - p0| / sum m|v0| = {err:.2e}"
    else:
        L = sim.metrics.column("angular_momentum_z")
        cross = {n: com[n][0][0] * vel[n][0][1] - com[n][0][1] * vel[n][0][0] for n in masses}
        scale = sum(masses[n] * abs(float(cross[n])) for n in masses)
        err = float(np.max(np.abs(L - L[0]))) / scale
        text = f"max |L - L0| / sum m|x0 x v0| = {err:.2e}"
    return _within(name, err, text)


def run_cell(case: Case, strategy: str, mode: str) -> dict:
    """One case under one strategy: its outcome, checks, notes and cost."""
    scene = case.build(mode)
    cls = STRATEGIES[strategy]
    dt = "auto" if cls.explicit else case.barrier_dt
    row: dict = {"case": case.name, "strategy": strategy}
    wall = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bfemp.StepNoteWarning)  # counted in the row instead
        try:
            sim = bfemp.Simulation(scene, strategy=strategy, dt=dt)
        except ValueError as err:
            row.update(outcome="REFUSED", verdict="REFUSED", reason=str(err), wall_s=0.0)
            return row
        rec = _Recorder(sim)
        n_steps = max(1, math.ceil(case.t_end[mode] / sim.dt - 1e-9))
        try:
            for _ in range(n_steps):
                sim.step()
                rec(sim)
            row["outcome"] = "RAN"
        except StepError as err:
            row.update(outcome="NAMED_FAILURE", status=err.report.status, reason=str(err))
    row.update(
        wall_s=time.perf_counter() - wall,
        dt=sim.dt,
        steps=sim.state.step,
        t=sim.state.t,
        notes=dict(sim.note_counts),
        diagnostics=[d.split(":", 1)[0] for d in sim.diagnostics],
        pairs=[k for k, _, _ in scene_pairs(sim.model)],
    )
    if row["outcome"] == "RAN":
        arrays = rec.arrays()
        arrays["masses"] = rec.masses
        row["checks"] = check_case(case, strategy, sim, arrays, mode)
        failed = [k for k, v in row["checks"].items() if not v["passed"]]
        row["guarantees_failed"] = [k for k in failed if k in GUARANTEES]
        row["accuracy_failed"] = [k for k in failed if k not in GUARANTEES]
        row["verdict"] = "FAIL" if row["guarantees_failed"] else "PASS"
    else:
        row["verdict"] = row["outcome"]
    log.info("%s / %s: %s (%.1f s)", case.name, strategy, row["verdict"], row["wall_s"])
    return row


def measure(mode: str, cfg: object) -> dict:
    """Every case of ``mode`` under each registered strategy."""
    strategies = list(STRATEGIES)
    rows = [run_cell(c, s, mode) for c in CASES for s in strategies]
    capabilities = {s: STRATEGIES[s].capabilities for s in strategies}
    return {
        "strategies": strategies,
        "capabilities": {
            s: {
                "pairs": dict(c.pairs),
                "friction": c.friction,
                "penetration_bound_cells": c.penetration_bound_cells,
            }
            for s, c in capabilities.items()
        },
        "limits": LIMITS,
        "rows": rows,
        "n_fail": sum(r["verdict"] == "FAIL" for r in rows),
    }


def _cell_text(row: dict) -> str:
    verdict = row["verdict"]
    if verdict == "REFUSED":
        return "refused"
    if verdict == "NAMED_FAILURE":
        return f"named failure {row['status']}"
    text = verdict.lower()
    if row.get("accuracy_failed"):
        text += " (off: " + ", ".join(row["accuracy_failed"]) + ")"
    if row.get("guarantees_failed"):
        text = "FAIL: " + ", ".join(row["guarantees_failed"])
    return text


def report_markdown(payload: dict) -> str:
    """The record's table (strategy x case) and each cell's measured figures."""
    strategies = payload["strategies"]
    by = {(r["case"], r["strategy"]): r for r in payload["rows"]}
    names = list(dict.fromkeys(r["case"] for r in payload["rows"]))
    lines = [
        f"# Conformance ({payload['mode']})",
        "",
        "Generated by `python -m benchmarks conformance"
        + (" --full" if payload["mode"] == "full" else " --quick")
        + "` (`benchmarks/conformance.py` explains every check and limit). "
        "`pass`: every declared guarantee held; `(off: ...)`: an accuracy check missed its limit "
        "(a measurement, not a broken promise); `FAIL`: a declared guarantee broke; "
        "`refused`: the strategy does not couple a pair of the scene (refused by name); "
        "`named failure`: a step stopped with a named status.",
        "",
        *table_head("case", *strategies),
    ]
    for name in names:
        cells = [_cell_text(by[(name, s)]) for s in strategies]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", f"FAIL cells: {payload['n_fail']}. Wall time {payload['wall_s']:.0f} s.", ""]
    lines += ["## Measured", ""]
    for r in payload["rows"]:
        head = f"- **{r['case']} / {r['strategy']}**: {r['verdict']}"
        if r["verdict"] == "REFUSED":
            lines.append(head + f" ({r['reason'].split(';')[0]})")
            continue
        head += f", {r['steps']} steps of {r['dt']:.3g} s, {r['wall_s']:.1f} s"
        if r["verdict"] == "NAMED_FAILURE":
            head += f"; {r['reason']}"
        lines.append(head)
        for check, res in r.get("checks", {}).items():
            mark = "ok" if res["passed"] else "MISS"
            lines.append(f"  - {check} ({mark}): {res['text']}")
        if r["notes"]:
            lines.append(
                "  - notes: " + ", ".join(f"{k} x {v}" for k, v in sorted(r["notes"].items()))
            )
    return "\n".join(lines) + "\n"


def _family(case_name: str) -> str:
    for prefix in ("drop_2d", "drop_3d", "incline_mpm", "incline_fem"):
        if case_name.startswith(prefix):
            return prefix
    return case_name.split("_")[0] if case_name.startswith("impact") else case_name


def readme_table(payload: dict) -> str:
    """The README's "which strategy handles what" table: per strategy and scene family, how
    many cases kept every declared guarantee (``pass``), and which were refused by name, ended
    in a named failure, broke a guarantee (FAIL) or missed an accuracy limit."""
    strategies = payload["strategies"]
    families = list(dict.fromkeys(_family(r["case"]) for r in payload["rows"]))
    lines = table_head("strategy", *(f.replace("_", " ") for f in families))
    for s in strategies:
        cells = []
        for fam in families:
            rows = [r for r in payload["rows"] if r["strategy"] == s and _family(r["case"]) == fam]
            verdicts = [r["verdict"] for r in rows]
            if all(v == "REFUSED" for v in verdicts):
                cells.append("refused")
                continue
            text = f"{verdicts.count('PASS')}/{len(rows)} pass"
            extra = [
                f"{verdicts.count(v)} {label}"
                for v, label in (
                    ("FAIL", "FAIL"),
                    ("NAMED_FAILURE", "named failure"),
                    ("REFUSED", "refused"),
                )
                if verdicts.count(v)
            ]
            off = sorted({k for r in rows for k in r.get("accuracy_failed", [])})
            if off:
                extra.append("off: " + ", ".join(off))
            cells.append(text + (f" ({'; '.join(extra)})" if extra else ""))
        lines.append(f"| {s} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_table(payload: dict, path: Path) -> None:
    """The strategy x case table in colour (green pass, yellow accuracy miss, red FAIL, blue
    named failure, grey refused)."""
    from matplotlib.patches import Rectangle

    strategies = payload["strategies"]
    names = list(dict.fromkeys(r["case"] for r in payload["rows"]))
    by = {(r["case"], r["strategy"]): r for r in payload["rows"]}
    colour = {
        "PASS": "#4caf50",
        "FAIL": "#e53935",
        "NAMED_FAILURE": "#42a5f5",
        "REFUSED": "#bdbdbd",
    }
    fig, ax = figure((2.0 + 1.6 * len(strategies), 0.9 + 0.32 * len(names)))
    for i, name in enumerate(names):
        for j, s in enumerate(strategies):
            r = by[(name, s)]
            c = colour[r["verdict"]]
            if r["verdict"] == "PASS" and r.get("accuracy_failed"):
                c = "#fdd835"
            ax.add_patch(Rectangle((j, i), 1, 1, color=c, ec="white"))
            ax.text(j + 0.5, i + 0.5, _cell_text(r)[:22], ha="center", va="center", fontsize=6)
    ax.set_xlim(0, len(strategies))
    ax.set_ylim(len(names), 0)
    ax.set_xticks(np.arange(len(strategies)) + 0.5, strategies, fontsize=8)
    ax.set_yticks(np.arange(len(names)) + 0.5, names, fontsize=7)
    ax.xaxis.tick_top()
    ax.set_title(f"conformance ({payload['mode']})", fontsize=9, pad=18)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


BENCHMARK = register(
    Benchmark(
        "conformance",
        __doc__,
        {"quick": {}, "full": {}},
        measure,
        plot_table,
        report_markdown,
        record=name_unless("full", "conformance"),
    )
)
run = BENCHMARK.run
