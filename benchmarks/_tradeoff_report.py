"""Analysis and reporting of the trade study (``benchmarks.tradeoff``): the Pareto front, what
each knob buys per second, the Pareto plots and the markdown summary."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: a log-log slope needs the time to change by at least this factor along the sweep
MIN_TIME_RATIO = 1.05
#: refining a knob counts as a gain when the error drops by at least this factor
MIN_ERROR_RATIO = 1.02
#: the cost axes: record key -> words
COSTS = {"wall_s": "wall time", "cpu_s": "CPU time"}


def pareto_front(cost: np.ndarray, error: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated points when both ``cost`` and ``error`` are minimised.

    A point is dominated when another one is no worse in both and better in one. Points with a
    non-finite cost or error take no part; of identical points only the first is returned.

    Args:
        cost: ``(n,)`` costs (wall time in s).
        error: ``(n,)`` errors (dimensionless).

    Returns:
        ``(k,)`` int indices into the inputs, by increasing cost (hence decreasing error).
    """
    cost = np.asarray(cost, dtype=np.float64)
    error = np.asarray(error, dtype=np.float64)
    if cost.shape != error.shape or cost.ndim != 1:
        raise ValueError(
            f"cost and error must have one shape (n,), got {cost.shape}, {error.shape}"
        )
    valid = np.flatnonzero(np.isfinite(cost) & np.isfinite(error))
    order = valid[np.lexsort((error[valid], cost[valid]))]  # by cost, ties by error
    sorted_error = error[order]
    # non-dominated: strictly better error than every point at most as costly before it
    best_before = np.r_[np.inf, np.minimum.accumulate(sorted_error)[:-1]]
    return order[sorted_error < best_before]


def knob_effect(points: list[dict], direction: int) -> dict:
    """What refining one knob buys along its one-at-a-time sweep.

    Args:
        points: the knob's sweep (base included): dicts with ``value``, ``time_s`` (s, the cost) and
            ``error`` (None for a failed point, which is skipped).
        direction: +1 when a larger value is finer (ppc), -1 when a smaller one is (dt, dx, ...).

    Returns:
        ``coarse`` and ``fine``: the end points (value, error, time_s) of the sweep;
        ``loglog_slope`` = ``d log(error) / d log(time)`` between them (None when the time
        changes by less than ``MIN_TIME_RATIO`` or an error is 0); ``reaches_zero``: the fine
        end is the reference run itself (error 0, an unbounded slope); ``error_drop_per_s`` =
        ``(error_coarse - error_fine) / (time_fine - time_coarse)`` (None when the time does
        not change); ``verdict``: ``"buys accuracy"`` (finer: lower error, more time),
        ``"free"`` (lower error, no more time), ``"no gain"`` (the error drops by less than
        ``MIN_ERROR_RATIO``) or
        ``"n/a"`` (fewer than two usable points).
    """
    usable = [p for p in points if p["error"] is not None and p["time_s"]]
    usable.sort(key=lambda p: direction * p["value"])
    out = {"points": len(usable), "coarse": None, "fine": None, "loglog_slope": None}
    out.update(reaches_zero=False, error_drop_per_s=None)
    if len(usable) < 2:
        return {**out, "verdict": "n/a"}
    coarse, fine = usable[0], usable[-1]
    out["coarse"], out["fine"] = (
        {key: p[key] for key in ("value", "error", "time_s")} for p in (coarse, fine)
    )
    error_drop = coarse["error"] - fine["error"]
    extra_time = fine["time_s"] - coarse["time_s"]
    time_changes = abs(math.log(fine["time_s"] / coarse["time_s"])) >= math.log(MIN_TIME_RATIO)
    if time_changes:
        out["error_drop_per_s"] = error_drop / extra_time
        if coarse["error"] > 0 and fine["error"] > 0:
            out["loglog_slope"] = math.log(fine["error"] / coarse["error"]) / math.log(
                fine["time_s"] / coarse["time_s"]
            )
    out["reaches_zero"] = fine["error"] == 0 < coarse["error"]
    if not (out["reaches_zero"] or coarse["error"] >= MIN_ERROR_RATIO * fine["error"] > 0):
        verdict = "no gain"
    elif not time_changes or extra_time <= 0:
        verdict = "free"
    else:
        verdict = "buys accuracy"
    return {**out, "verdict": verdict}


def _ratio(effect: dict) -> float:
    """Error ratio coarse / fine of a knob (inf when the fine end has no error)."""
    fine = effect["fine"]["error"]
    return effect["coarse"]["error"] / fine if fine > 0 else math.inf


def best_knob(effects: dict[str, dict]) -> str | None:
    """The knob that buys the most accuracy per second.

    A ``"free"`` knob wins first (the largest error ratio coarse / fine); otherwise the most
    negative log-log slope among the knobs that buy accuracy (a knob whose fine end is the
    reference run, error 0, counts as an unbounded slope). None when no knob lowers the error.
    """
    free = {k: e for k, e in effects.items() if e["verdict"] == "free"}
    if free:
        return max(free, key=lambda k: _ratio(free[k]))
    buying = {k: e for k, e in effects.items() if e["verdict"] == "buys accuracy"}

    def slope(k: str) -> float:
        e = buying[k]
        return -math.inf if e["reaches_zero"] else e["loglog_slope"]

    return min(buying, key=slope) if buying else None


def plot_scene(
    records: list[dict], path: Path, title: str, error_label: str, cost: str = "wall_s"
) -> Path:
    """Error against cost (log-log): every point labelled by its settings, the
    one-at-a-time sweeps as thin lines, the Pareto front as a dashed staircase.

    Args:
        records: the scene's point records (``label``, ``role``, ``knob``, ``sweeps``, ``value``,
            ``error``, ``pareto`` and the cost); failed points are left out. An error of exactly 0
            (the point is the reference run) is drawn at a tenth of the smallest positive error.
        path: the PNG file.
        title, error_label: the title and the error axis label.
        cost: the record key of the cost in s (``COSTS``).
    """
    fig = Figure(figsize=(8.0, 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    done = [r for r in records if r["error"] is not None and r[cost]]
    positive = [r["error"] for r in done if r["error"] > 0]
    floor = 0.1 * min(positive) if positive else 1e-16

    def shown(r: dict) -> float:
        return r["error"] if r["error"] > 0 else floor

    # knobs with at least two finished points (a one-value sweep, e.g. one strategy, is the base)
    knobs = sorted({k for r in done for k in r["sweeps"] if r["role"] == "sweep"})
    colors = {knob: f"C{i}" for i, knob in enumerate(knobs)}
    for knob in knobs:
        # along the knob's values: the path that refining it takes
        sweep = sorted((r for r in done if knob in r["sweeps"]), key=lambda r: r["settings"][knob])
        if len(sweep) > 1:
            t, e = [r[cost] for r in sweep], [shown(r) for r in sweep]
            ax.plot(t, e, "-", color=colors[knob], lw=0.8, alpha=0.6)
    for r in done:
        if r["role"] == "base":
            style = {"marker": "s", "color": "k"}
        elif r["role"] == "reference":
            style = {"marker": "*", "color": "k", "markersize": 11}
        else:
            style = {"marker": "o", "color": colors[r["knob"]]}
        ax.plot(r[cost], shown(r), linestyle="none", **style)
        text = r["label"] + (" (error 0)" if r["error"] == 0 else "")
        ax.annotate(
            text, (r[cost], shown(r)), xytext=(4, 3), textcoords="offset points", fontsize=7
        )
    front = sorted((r for r in done if r["pareto"]), key=lambda r: r[cost])
    if front:
        t = [r[cost] for r in front]
        e = [shown(r) for r in front]
        ax.step(t, e, where="post", color="0.3", ls="--", lw=1.2, label="Pareto front")
    for knob in knobs:
        ax.plot([], [], "o-", color=colors[knob], label=f"sweep of {knob}")
    ax.plot([], [], "ks", label="base")
    if any(r["role"] == "reference" for r in done):
        ax.plot([], [], "k*", markersize=11, label="reference run")
    ax.set(xscale="log", yscale="log", xlabel=f"{COSTS[cost]} of the point [s]", ylabel=error_label)
    ax.set_title(title, fontsize="medium")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    fig.savefig(path, dpi=110)
    return path


def _num(value: float | None, fmt: str = ".3g") -> str:
    return "-" if value is None else format(value, fmt)


def markdown(payload: dict) -> str:
    """The trade study's summary: per scene, what each knob buys per second, the best knob,
    the Pareto front, and every point."""
    ex = payload["executor"]
    cost, words = payload["cost"], COSTS[payload["cost"]]
    where = f"Dask scheduler {ex['scheduler']}" if ex["kind"] == "dask" else f"{ex['workers']}"
    lines = [
        f"# Trade study ({payload['mode']} mode)",
        "",
        f"{len(payload['points'])} points on {where} "
        f"{'' if ex['kind'] == 'dask' else 'local worker processes '}"
        f"({ex['threads_per_point']} thread(s) per point); elapsed {payload['wall_s']:.1f} s, "
        f"sum of point wall times {payload['point_wall_s_total']:.1f} s, "
        f"commit `{payload['environment']['commit'][:10]}`.",
        "",
        "Wall and CPU time: the point's `run_point` call (scene build and time loop) in its own "
        f"process; memory: that process's peak resident set. Cost axis: {words}. Replay any "
        "point with "
        "`python -m benchmarks tradeoff --replay tradeoff.json --id ID`.",
    ]
    for scene in payload["scenes"]:
        records = [r for r in payload["points"] if r["scene"] == scene]
        effects = payload["knob_effects"][scene]
        best = payload["best_knob"][scene]
        lines += ["", f"## {scene}", "", f"Error: {payload['errors'][scene]}", ""]
        base = next(r for r in records if r["role"] == "base")
        settings = ", ".join(f"{k}={v}" for k, v in base["settings"].items())
        lines += [f"Base: {settings}.", ""]
        lines += [
            f"| knob | coarse -> fine | error | {words} [s] | d log(error) / d log(time) "
            "| error drop per extra s | verdict |",
            "|---|---|---|---|---|---|---|",
        ]
        for knob, e in effects.items():
            if e["coarse"] is None:
                lines.append(f"| {knob} | - | - | - | - | - | {e['verdict']} |")
                continue
            c, f = e["coarse"], e["fine"]
            lines.append(
                f"| {knob} | {c['value']:g} -> {f['value']:g} | {c['error']:.3g} -> "
                f"{f['error']:.3g} | {c['time_s']:.2f} -> {f['time_s']:.2f} | "
                f"{'-inf (error 0)' if e['reaches_zero'] else _num(e['loglog_slope'], '.2f')} | "
                f"{_num(e['error_drop_per_s'])} | "
                f"{e['verdict']} |"
            )
        if best is None:
            lines += ["", "No knob lowered the error along its sweep."]
        else:
            e = effects[best]
            if e["verdict"] == "free":
                why = "refining it lowered the error without costing time"
            elif e["reaches_zero"]:
                why = "its finest value is the reference run"
            else:
                why = f"d log(error) / d log(time) = {e['loglog_slope']:.2f}"
            lines += ["", f"**Most accuracy per second: {best}** ({why})."]
        front = [r for r in records if r["pareto"]]
        front.sort(key=lambda r: r[cost])
        lines += [
            "",
            f"Pareto front (error against {words}): "
            + ", ".join(f"{r['label']} ({r['error']:.3g}, {r[cost]:.2f} s)" for r in front)
            + ".",
            "",
            "| point | error | wall [s] | CPU [s] | Newton iterations | peak memory [MiB] | "
            "failure |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in records:
            failure = (r["failure"] or "").replace("|", "\\|")[:120]
            mark = " (front)" if r["pareto"] else ""
            lines.append(
                f"| {r['label']}{mark} | {_num(r['error'])} | {_num(r['wall_s'], '.2f')} | "
                f"{_num(r['cpu_s'], '.2f')} | "
                f"{_num(r['newton_iterations'], 'd')} | {_num(r['peak_memory_mb'], '.0f')} | "
                f"{failure} |"
            )
    return "\n".join(lines) + "\n"
