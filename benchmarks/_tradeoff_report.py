"""Analysis and reporting of the trade study (``benchmarks.tradeoff``): the Pareto front, what
each knob buys per second, the Pareto plots and the markdown summary.

Feasibility (issue 40, ``benchmarks._penetration``): an infeasible point (:func:`infeasible`)
is drawn as a cross, named in the report with its depth against its bound, and kept off every
Pareto front and out of every winner of an error range, however cheap and accurate it is.
"""

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
#: two strategies' costs closer than this fraction are a close call, not a firm lead: about the
#: spread of one point's wall time between runs of the same work (4.7 % in the full rings sweep)
CLOSE_COST_FRACTION = 0.05
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


def infeasible(point: dict) -> bool:
    """Whether ``point`` went deeper inside a FEM body than its strategy's stated bound.

    Args:
        point: a point record with ``max_penetration_m`` and ``penetration_bound_m`` (m; either
            missing or None: not judged, feasible).

    Returns:
        ``max_penetration_m > penetration_bound_m`` (strictly: a bound of 0 m admits no depth
        at all, a depth equal to the bound is within it).
    """
    depth, bound = point.get("max_penetration_m"), point.get("penetration_bound_m")
    return depth is not None and bound is not None and depth > bound


def winners(points: list[dict], cost: str = "wall_s") -> list[dict]:
    """Which strategy reaches each error target at the least cost.

    For an error target E, a strategy's cost is that of its cheapest point with error <= E; the
    winner is the strategy with the least such cost (ties: the first name in sorted order). The
    winner changes only at the errors of the points, so the targets split into ranges.

    Args:
        points: dicts with ``strategy``, ``error`` (dimensionless; None for a failed point, which
            takes no part) and the cost (``cost``, s); an infeasible point (:func:`infeasible`)
            takes no part either.
        cost: the key of the cost.

    Returns:
        the ranges, from large errors to small: ``error_from`` <= E < ``error_to`` (inf for the
        loosest range), ``winner``, ``cost_s`` (its cost there), ``runner_up`` and
        ``runner_up_cost_s`` (the next cheapest strategy reaching E, or None), adjacent ranges
        with one winner merged (the runner-up and costs are those at the range's tightest
        target). No range below the smallest error any point reached.
    """
    done = [p for p in points if _finite(p.get("error")) and _finite(p.get(cost))]
    done = [p for p in done if not infeasible(p)]
    levels = sorted({p["error"] for p in done})
    ranges: list[dict] = []
    for level, upper in zip(levels, [*levels[1:], math.inf], strict=False):
        best: dict[str, float] = {}
        for p in done:
            if p["error"] <= level:
                best[p["strategy"]] = min(best.get(p["strategy"], math.inf), p[cost])
        winner, runner_up = [*sorted(best, key=lambda s: (best[s], s)), None][:2]
        ranges.append(
            {
                "error_from": level,
                "error_to": upper,
                "winner": winner,
                "cost_s": best[winner],
                "runner_up": runner_up,
                "runner_up_cost_s": best.get(runner_up),
            }
        )
    merged: list[dict] = []
    for r in ranges:  # tight to loose; merge upward, keeping the tightest target's numbers
        if merged and merged[-1]["winner"] == r["winner"]:
            merged[-1]["error_to"] = r["error_to"]
        else:
            merged.append(dict(r))
    return merged[::-1]


def _finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


def crossovers(ranges: list[dict]) -> list[dict]:
    """The errors where the winner changes: ``error`` (the boundary), ``above`` (the winner
    for targets at or above it) and ``below`` (the winner for tighter targets)."""
    return [
        {"error": loose["error_from"], "above": loose["winner"], "below": tight["winner"]}
        for loose, tight in zip(ranges, ranges[1:], strict=False)
    ]


def close_call(r: dict) -> bool:
    """Whether range ``r`` of ``winners`` has a runner-up within ``CLOSE_COST_FRACTION`` of the
    winner's cost at the range's tightest target."""
    return bool(r["runner_up"]) and r["runner_up_cost_s"] <= r["cost_s"] * (
        1.0 + CLOSE_COST_FRACTION
    )


def winner_sentences(scene: str, ranges: list[dict], cost_words: str = "wall time") -> list[str]:
    """The ranges and crossovers in words (one sentence each); a close call (``close_call``)
    says that the lead is within the timing noise."""
    if not ranges:
        return [f"{scene}: no point has an error, no winner."]
    close = f"within {CLOSE_COST_FRACTION:.0%} in cost, about the spread of one point's time"
    lines = []
    for r in ranges:
        span = (
            f"error targets at or above {r['error_from']:.3g}"
            if math.isinf(r["error_to"])
            else f"error targets in [{r['error_from']:.3g}, {r['error_to']:.3g})"
        )
        at = f"{r['error_from']:.3g}"
        other = (
            f"; next at {at}: {r['runner_up']}, {r['runner_up_cost_s']:.3g} s"
            if r["runner_up"]
            else f"; no other strategy reaches {at}"
        )
        lines.append(
            f"For {span}, **{r['winner']}** is the cheapest ({r['cost_s']:.3g} s of "
            f"{cost_words} at {at}{other})"
            + (f": a close call ({close} between runs), not a firm lead." if close_call(r) else ".")
        )
    for loose, c in zip(ranges, crossovers(ranges), strict=False):
        lines.append(
            f"Crossover at error {c['error']:.3g}: below it {c['below']} is faster than "
            f"{c['above']} on {scene} (at or above it, {c['above']} wins"
            + (f"; a close call at {c['error']:.3g}: {close})." if close_call(loose) else ").")
        )
    lowest = ranges[-1]
    if lowest["error_from"] > 0:
        lines.append(f"No strategy reached an error below {lowest['error_from']:.3g} on {scene}.")
    else:
        lines.append(f"Error 0 is the reference run itself ({lowest['winner']}).")
    return lines


def bound_words(point: dict) -> str:
    """A point's penetration bound in words: metres, and the cells and grid it came from."""
    bound = point["penetration_bound_m"]
    cells, dx = point.get("penetration_bound_cells"), point.get("penetration_grid_dx_m")
    if bound == 0.0:
        return "0 m (its strategy lets nothing end inside a FEM body)"
    if cells is not None and dx is not None:
        which = {
            point.get("penetration_mpm_grid_dx_m"): "MPM grid",
            point.get("penetration_contact_grid_dx_m"): "contact grid",
        }.get(dx, "grid")
        return f"{bound:.3g} m ({cells:g} cell(s) of the {dx:.3g} m {which})"
    return f"{bound:.3g} m"


def infeasible_sentences(scene: str, records: list[dict]) -> list[str]:
    """The scene's infeasible points (:func:`infeasible`) in words, one sentence each: scene,
    strategy, knob value (the point's label), depth against bound; or one sentence saying that
    every point judged kept within its bound (and how many could be judged)."""
    judged = [
        r
        for r in records
        if r.get("max_penetration_m") is not None and r.get("penetration_bound_m") is not None
    ]
    bad = [r for r in records if infeasible(r)]
    if not bad:
        if not judged:
            return [
                f"No point on {scene} has both a penetration depth and a bound to judge it by "
                "(no FEM body in the scene, or a record from before the measurement)."
            ]
        return [
            f"Every point judged on {scene} ({len(judged)} of {len(records)}) kept within its "
            "strategy's penetration bound."
        ]
    lines = []
    for r in bad:
        error = "" if r.get("error") is None else f" (error {r['error']:.3g})"
        line = (
            f"**Infeasible**: {scene}, **{r['strategy']}** at {r['label']}{error} went "
            f"{r['max_penetration_m']:.3g} m inside a FEM body, beyond its bound of "
            f"{bound_words(r)}: drawn as a cross, never on the front, never a winner."
        )
        if r.get("is_reference"):
            line += (
                " It is the scene's reference run: the other points' errors are their "
                "difference from a run that penetrates."
            )
        lines.append(line)
    return lines


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


#: one colour per strategy (the registry's names), fixed so that every plot agrees
STRATEGY_COLORS = {
    "barrier": "C0",
    "two_stage": "C1",
    "augury": "C2",
    "lr": "C3",
    "single_field": "C4",
}


def plot_scene(
    records: list[dict], path: Path, title: str, error_label: str, cost: str = "wall_s"
) -> Path:
    """Error against cost (log-log), one colour per strategy: every point labelled by its knob
    (square: base, circle: sweep, star: reference run, cross: infeasible), each strategy's
    one-at-a-time sweeps as thin lines, the scene's non-dominated front as a dashed black
    staircase. Failed points are left out; an error of exactly 0 (the reference run itself) is
    drawn at a tenth of the smallest positive error; with no point left (the scene's reference
    run failed) the figure says so on linear axes.

    Args:
        records: the scene's point records (``strategy``, ``label``, ``role``, ``sweeps``,
            ``error``, ``pareto`` and the cost).
        path: the PNG file.
        title, error_label: the title and the error axis label.
        cost: the record key of the cost in s (``COSTS``).
    """
    fig = Figure(figsize=(8.5, 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    done = [r for r in records if r["error"] is not None and r[cost]]
    positive = [r["error"] for r in done if r["error"] > 0]
    floor = 0.1 * min(positive) if positive else 1e-16

    def shown(r: dict) -> float:
        return r["error"] if r["error"] > 0 else floor

    strategies = list(dict.fromkeys(r["strategy"] for r in records))
    extra = iter(f"C{i}" for i in range(5, 10))
    colors = {s: STRATEGY_COLORS.get(s) or next(extra) for s in strategies}
    for s in strategies:
        mine = [r for r in done if r["strategy"] == s]
        for knob in sorted({k for r in mine for k in r["sweeps"]}):
            sweep = sorted((r for r in mine if knob in r["sweeps"]), key=lambda r: r[cost])
            if len(sweep) > 1:
                x, y = [r[cost] for r in sweep], [shown(r) for r in sweep]
                ax.plot(x, y, "-", color=colors[s], lw=0.7, alpha=0.5)
        for r in mine:
            bad = infeasible(r)  # a cross: drawn, but never on the front nor a winner
            marker = "X" if bad else {"base": "s", "reference": "*"}.get(r["role"], "o")
            size = 9 if bad else 11 if r["role"] == "reference" else 6
            at = (r[cost], shown(r))
            ax.plot(*at, linestyle="none", marker=marker, color=colors[s], markersize=size)
            text = r["label"] + (" (error 0)" if r["error"] == 0 else "")
            text += " (infeasible)" if bad else ""
            ax.annotate(
                text, at, xytext=(4, 3), textcoords="offset points", fontsize=6, color=colors[s]
            )
        ax.plot([], [], "o", color=colors[s], label=s if mine else f"{s} (no finished point)")
    front = sorted((r for r in done if r["pareto"]), key=lambda r: r[cost])
    if front:
        t, e = [r[cost] for r in front], [shown(r) for r in front]
        ax.step(t, e, where="post", color="k", ls="--", lw=1.2, label="non-dominated front")
    ax.plot([], [], "ks", mfc="none", label="base (square), sweep (circle)")
    if any(r["role"] == "reference" for r in done):
        ax.plot([], [], "k*", markersize=11, label="reference run")
    if any(infeasible(r) for r in done):
        why = "infeasible: deeper inside a FEM body than its strategy's bound"
        ax.plot([], [], "kX", markersize=9, label=why)
    if done:
        ax.set(xscale="log", yscale="log")
    else:  # nothing to place on log axes (the reference run failed, or every point did)
        text = "no finished point with an error"
        ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)
    ax.set(xlabel=f"{COSTS[cost]} of the point [s]", ylabel=error_label)
    ax.set_title(title, fontsize="medium")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    fig.savefig(path, dpi=110)
    return path


def _num(value: float | None, fmt: str = ".3g") -> str:
    return "-" if value is None else format(value, fmt)


def _val(value: object) -> str:
    return "none" if value is None else format(value, "g")


def _executor_words(part: dict) -> str:
    """Where a merged run's points ran, in words (its ``executor``; older records: workers)."""
    ex = part.get("executor")
    if ex is not None and ex.get("kind") == "dask":
        return f"Dask scheduler {ex['scheduler']}"
    workers = ex["workers"] if ex is not None else part["workers"]
    return f"{workers} local worker process(es)"


def markdown(payload: dict) -> str:
    """The trade study's report: per scene, what the error is against, the strategies run and
    those that do not apply (why), the winner per error range and the crossovers (computed from
    the points by ``winners``), per strategy what each knob buys per second, and every point."""
    ex = payload["executor"]
    cost, words = payload["cost"], COSTS[payload["cost"]]
    merged = {scene for part in payload.get("merged", []) for scene in part["scenes"]}
    first = [r for r in payload["points"] if r["scene"] not in merged]
    lines = [
        f"# Trade study across strategies ({payload['mode']} mode)",
        "",
        f"{len(first)} points"
        + (
            f" (kept of the run's {payload['merged'][0]['first_run_points']})"
            if payload.get("merged") and "first_run_points" in payload["merged"][0]
            else ""
        )
        + f" on {_executor_words(payload)} "
        f"({ex['threads_per_point']} thread(s) per point); elapsed {payload['wall_s']:.1f} s, "
        f"sum of its point wall times {payload['point_wall_s_total']:.1f} s, "
        f"commit `{payload['environment']['commit'][:10]}`.",
        "",
        "Wall and CPU time: the point's run (scene build and time loop) in its own process; "
        f"memory: that process's peak resident set; iterations: Newton iterations summed over "
        f"the run (0 for the purely explicit strategies). Cost axis: {words}. Replay any point "
        "with `python -m benchmarks tradeoff --replay tradeoff.json --id ID`.",
        "",
        "Penetration: the deepest any FEM node or particle went inside another FEM body over "
        "the point's run (the shared `penetration_depth` check), against its strategy's stated "
        "bound (`penetration_bound_cells` of the strategy, read when the point ran, times the "
        "dx of the point's MPM grid, or of augury's contact grid in a scene without particles; "
        "0 for barrier and two_stage). A point beyond its bound is infeasible: drawn as a "
        "cross, named below, never on a front, never a winner.",
    ]
    for part in payload.get("merged", []):  # scenes rerun later and merged in (each point: commit)
        of_part = [r for r in payload["points"] if r["scene"] in part["scenes"]]
        resumed = sum(1 for r in of_part if r.get("resumed"))
        lines += [
            "",
            f"Scenes {', '.join(part['scenes'])}: run at commit `{part['commit'][:10]}` "
            f"({part['points']} points on {_executor_words(part)}, elapsed "
            f"{part['wall_s']:.1f} s"
            + (
                f"; {resumed} of them measured by an earlier, stopped run of the same code "
                "and resumed from their kept files"
                if resumed
                else ""
            )
            + f"; sum of the point wall times {sum(r['wall_s'] for r in of_part):.1f} s) and "
            "merged into this record; the figures above are those of the other scenes' run.",
        ]
    for scene in payload["scenes"]:
        records = [r for r in payload["points"] if r["scene"] == scene]
        lines += ["", f"## {scene}", "", f"Error: {payload['errors'][scene]}.", ""]
        for s, note in payload["strategy_notes"][scene].items():
            knobs = ", ".join(payload["knobs"][scene][s]) or "none"
            lines.append(f"- **{s}** ({note}); knobs swept: {knobs}.")
        for s, why in payload["not_run"][scene].items():
            lines.append(f"- {s}: not run: {why}.")
        lines += ["", "### Winner per error range", ""]
        lines += [f"- {line}" for line in winner_sentences(scene, payload["winners"][scene], words)]
        lines += ["", "### Penetration", ""]
        lines += [f"- {line}" for line in infeasible_sentences(scene, records)]
        front = sorted((r for r in records if r["pareto"]), key=lambda r: r[cost])
        lines += [
            "",
            f"Non-dominated front (error against {words}): "
            + ", ".join(
                f"{r['strategy']}/{r['label']} ({r['error']:.3g}, {r[cost]:.2f} s)" for r in front
            )
            + ".",
        ]
        for s, effects in payload["knob_effects"][scene].items():
            lines += [
                "",
                f"### {s}: what each knob buys",
                "",
                f"| knob | coarse -> fine | error | {words} [s] | d log(error) / d log(time) "
                "| error drop per extra s | verdict |",
                "|---|---|---|---|---|---|---|",
            ]
            for knob, e in effects.items():
                if e["coarse"] is None:
                    lines.append(f"| {knob} | - | - | - | - | - | {e['verdict']} |")
                    continue
                c, f = e["coarse"], e["fine"]
                slope = "-inf (error 0)" if e["reaches_zero"] else _num(e["loglog_slope"], ".2f")
                lines.append(
                    f"| {knob} | {_val(c['value'])} -> {_val(f['value'])} | {c['error']:.3g} -> "
                    f"{f['error']:.3g} | {c['time_s']:.2f} -> {f['time_s']:.2f} | {slope} | "
                    f"{_num(e['error_drop_per_s'])} | {e['verdict']} |"
                )
            best = payload["best_knob"][scene][s]
            lines += ["", f"Most accuracy per second ({s}): {best or 'no knob lowered the error'}."]
        lines += [
            "",
            "### Points",
            "",
            "| strategy | point | error | wall [s] | CPU [s] | iterations | peak memory [MiB] | "
            "penetration / bound [m] | failure |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in records:
            failure = (r["failure"] or "").replace("|", "\\|")[:120]
            mark = " (front)" if r["pareto"] else ""
            mark += " (infeasible)" if infeasible(r) else ""
            depth = f"{_num(r.get('max_penetration_m'))} / {_num(r.get('penetration_bound_m'))}"
            lines.append(
                f"| {r['strategy']} | {r['label']}{mark} | {_num(r['error'])} | "
                f"{_num(r['wall_s'], '.2f')} | {_num(r['cpu_s'], '.2f')} | "
                f"{_num(r['iterations'], 'd')} | {_num(r['peak_memory_mb'], '.0f')} | {depth} | "
                f"{failure} |"
            )
    return "\n".join(lines) + "\n"
