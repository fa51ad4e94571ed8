"""The ``extremes`` table as markdown and as a figure (one column per strategy)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from benchmarks.common import figure, table_head

#: colour per kind of outcome
_COLOURS = {"pass": "tab:green", "named": "tab:orange", "na": "0.8", "UNEXPLAINED": "tab:red"}


def _fmt(value: object, spec: str = ".3g") -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return format(value, spec)
    return str(value)


def _kind(status: str) -> str:
    if status in ("pass", "UNEXPLAINED"):
        return status
    return "na" if status == "NOT_APPLICABLE" else "named"


def short_outcome(row: dict) -> str:
    """The status of a row, with the bound of a dt refusal and the auto run's status."""
    text = row["status"]
    if row["status"] == "REFUSED" and "auto" in row:
        auto_dt = row["auto"]["dt"]
        auto_dt = f"{auto_dt:.2g} s" if isinstance(auto_dt, float) else str(auto_dt)
        text += f" (dt {row['config']['dt']:g} s); auto dt {auto_dt}: "
        text += row["auto"]["status"]
    return text


def _values(run: dict) -> str:
    """min distance, penetrations, min J and energy growth of a run that stepped."""
    if not run.get("steps"):
        return ""
    d = run.get("min_distance")
    if d is None:
        d = run.get("min_distance_geometric")
    return (
        f"d {_fmt(d)} · pen {_fmt(run.get('penetrations'))} · J {_fmt(run.get('min_J'), '.3g')}"
        f" · ΔE {_fmt(run.get('energy_growth_max'), '.1e')}"
    )


def _cell(row: dict) -> str:
    run = row.get("auto", row)
    values = _values(run)
    return short_outcome(row) + (f"<br>{values}" if values else "")


def _by_case(payload: dict) -> dict[str, dict[str, dict]]:
    table: dict[str, dict[str, dict]] = {}
    for r in payload["cases"]:
        table.setdefault(r["name"], {})[r["strategy"]] = r
    return table


def markdown_table(payload: dict) -> str:
    """One row per case, one column per strategy; then a detailed table per strategy."""
    strategies = payload["strategies"]
    lines = [
        f"# extremes ({payload['mode']} mode)",
        "",
        f"{payload['n_cases']} cases under {len(strategies)} strategies: {payload['n_pass']} pass, "
        f"{payload['n_named_failures']} named failures, {payload['n_not_applicable']} not "
        f"applicable, {payload['n_unexplained']} unexplained ({payload['n_auto_runs']} extra "
        f"runs at dt = 'auto', {payload['n_auto_pass']} pass). Wall time "
        f"{payload['wall_s']:.1f} s, commit `{payload['environment']['commit'][:10]}`.",
        "",
        "Per strategy: "
        + "; ".join(
            f"{s} {c['n_pass']} pass / {c['n_named_failures']} named / "
            f"{c['n_not_applicable']} n.a. / {c['n_unexplained']} unexplained, {c['wall_s']:.1f} s"
            for s, c in payload["by_strategy"].items()
        )
        + ".",
        "",
        "Each cell: outcome (a refused dt: the refusal, then the run at the stable step), then "
        "d: smallest active contact distance of the step reports (strategies without one: the "
        "independent particle-to-boundary distance) in m, pen: most particles inside the FEM "
        "body at once, J: min J of cells and particles, ΔE: max_t (E(t) - E(0)) / E_ref.",
        "",
        *table_head("case", "knob", *strategies),
    ]
    for name, per in _by_case(payload).items():
        first = next(iter(per.values()))
        cells = [name, first["knob"]] + [_cell(per[s]) if s in per else "-" for s in strategies]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    for s in strategies:
        lines += ["", f"## {s}", ""] + _strategy_table(
            [r for r in payload["cases"] if r["strategy"] == s]
        )
    return "\n".join(lines) + "\n"


def _strategy_table(rows: list[dict]) -> list[str]:
    lines = [
        "| case | dt [s] | steps | min d [m] | min d / dhat | geometric d [m] | penetrations "
        "| min J (FEM) | min J (MPM) | max energy growth | Newton sum / max | wall [s] | cpu [s] "
        "| outcome |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        for run, label in ((row, row["name"]), (row.get("auto"), f"{row['name']} (auto dt)")):
            if run is None:
                continue
            steps = f"{run.get('steps', 0)} / {run['steps_planned']}"
            newton = f"{run.get('newton_iterations', 0)} / {run.get('newton_iterations_max', 0)}"
            outcome = str(run["outcome"])
            if run.get("drift_m") is not None:
                outcome += f" (drift {run['drift_m']:.2e} m)"
            cells = [
                label,
                _fmt(run.get("dt", row["config"]["dt"]), ".3g"),
                steps,
                _fmt(run.get("min_distance")),
                _fmt(run.get("min_distance_over_dhat")),
                _fmt(run.get("min_distance_geometric")),
                _fmt(run.get("penetrations")),
                _fmt(run.get("min_J_fem"), ".4g"),
                _fmt(run.get("min_J_mpm"), ".4g"),
                _fmt(run.get("energy_growth_max"), ".2e"),
                newton,
                _fmt(run.get("wall_s"), ".2f"),
                _fmt(run.get("cpu_s"), ".2f"),
                outcome,
            ]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return lines


def plot_cases(payload: dict, path: Path, title: str) -> None:
    """Left: the outcome grid (case x strategy; green pass, orange named failure, grey not
    applicable, red unexplained; a refused dt is coloured by its auto run). Right: min J and
    max energy growth per case, one marker per strategy."""
    from matplotlib.patches import Rectangle

    strategies = payload["strategies"]
    table = _by_case(payload)
    names = list(table)
    fig, axes = figure(
        (16.0, 0.4 * len(names) + 2.5),
        1,
        3,
        gridspec_kw={"width_ratios": [2.2, 1.0, 1.0]},
        layout="constrained",
    )
    grid, y = axes[0], np.arange(len(names))
    for j, s in enumerate(strategies):
        for i, name in enumerate(names):
            row = table[name].get(s)
            if row is None:
                continue
            run = row.get("auto", row)
            colour = _COLOURS[_kind(run["status"])]
            grid.add_patch(Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, color=colour, alpha=0.6))
            label = row["status"] if "auto" not in row else f"REFUSED\nauto: {run['status']}"
            grid.text(j, i, label.replace("_", " "), ha="center", va="center", fontsize=6)
    grid.set_xlim(-0.5, len(strategies) - 0.5)
    grid.set_ylim(len(names) - 0.5, -0.5)
    grid.set_xticks(range(len(strategies)), strategies)
    grid.set_yticks(y, names, fontsize="small")
    grid.set_title("outcome")
    markers = "osD^v<>"
    for ax, key, label, scale in (
        (axes[1], "min_J", "min J", "symlog"),
        (axes[2], "energy_growth_max", "max (E - E0) / E_ref", "symlog"),
    ):
        for j, s in enumerate(strategies):
            vals = []
            for name in names:
                row = table[name].get(s)
                run = None if row is None else row.get("auto", row)
                value = None if run is None else run.get(key)
                vals.append(np.nan if value is None else value)
            ax.plot(vals, y, markers[j % len(markers)], label=s, alpha=0.8, ls="none")
        ax.set_xscale(scale, linthresh=1e-3 if key == "min_J" else 1e-4)
        if key == "min_J":
            ax.axvline(0.0, color="k", ls="--", lw=0.8)  # left of it: inverted
        ax.set_ylim(len(names) - 0.5, -0.5)
        ax.set_yticks(y, [])
        ax.set_xlabel(label)
        ax.grid(True, axis="x", alpha=0.3)
    axes[2].legend(fontsize="small")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
