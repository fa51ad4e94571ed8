"""PNG plots of run metrics and benchmark series.

Figures are built with ``matplotlib.figure.Figure`` on an Agg canvas: importing this module or
plotting never selects a pyplot backend or touches pyplot's global figure registry, so it works
headless and inside applications that use another backend. Files are written atomically.

Groups of metrics columns are lists of names or ``fnmatch`` patterns (``"energy_*"``). The default
groups are: energies (``energy_*``), momenta (``momentum_*``), iterations (``iterations_*``:
Newton, friction, ... per step), closest distance, contact forces per body pair
(``contact_force.*``), per-body energies and momenta (``body.*``) and timings (``time_*``, log
scale). A group none of whose columns is in the log is skipped; the ``x`` column itself is never
plotted as a series. A column NaN in every row is not computed by the run (:func:`undefined_column`:
``energy_contact`` of a strategy without a contact energy, ``min_distance`` of an explicit one):
its legend entry says so, and a panel none of whose columns is computed says so in its middle.

Readable at a glance: every panel's y axis names its quantity and unit (:data:`GROUP_UNITS`), the
x axis ``t [s]``; every curve of a panel has its own colour (tab10, tab20, then line styles:
:func:`curve_styles`); legends sit outside the axes, right of the curves.
"""

from __future__ import annotations

import fnmatch
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bfemp.errors import warn_user
from bfemp.io.metrics import MetricsLog, undefined_column
from bfemp.io.vtk import atomic_path

logger = logging.getLogger(__name__)

#: group name -> (column patterns, y-axis label: quantity [unit]); 2D quantities are per unit
#: thickness
_GROUPS = {
    "energies": (("energy_*",), "energy [J] (2D: J/m)"),
    "momenta": (("momentum_*",), "momentum [kg m/s] (2D: per m)"),
    "iterations": (("iterations_*",), "iterations per step"),
    "min_distance": (("min_distance",), "distance [m]"),
    "contact_forces": (("contact_force.*",), "force [N] (2D: N/m)"),
    "body_energies": (("body.*.energy_*",), "energy [J] (2D: J/m)"),
    "body_momenta": (("body.*.momentum_*",), "momentum [kg m/s] (2D: per m)"),
    "timings": (("time_*",), "wall time per step [s]"),
}
DEFAULT_GROUPS: Mapping[str, tuple[str, ...]] = {k: v[0] for k, v in _GROUPS.items()}
#: y-axis label of a group
GROUP_UNITS: Mapping[str, str] = {k: v[1] for k, v in _GROUPS.items()}
#: x-axis label of a known abscissa column
X_UNITS: Mapping[str, str] = {"t": "t [s]", "step": "step"}
#: groups drawn on a logarithmic y axis (values spanning decades)
LOG_GROUPS = frozenset({"timings"})
_LINESTYLES = ("-", "--", ":", "-.")

_DPI = 110


def _resolve_groups(
    columns: Sequence[str], groups: Mapping[str, Sequence[str]], x: str | None
) -> dict[str, list[str]]:
    """Expand the patterns of each group against ``columns``; drop empty groups."""
    if not isinstance(groups, Mapping):
        raise ValueError("groups must be a mapping group name -> list of columns/patterns")
    resolved: dict[str, list[str]] = {}
    for group, patterns in groups.items():
        if isinstance(patterns, str) or not isinstance(patterns, Sequence) or not patterns:
            raise ValueError(f"groups[{group!r}] must be a non-empty list of column names")
        names: list[str] = []
        for pattern in patterns:
            if not isinstance(pattern, str):
                raise ValueError(f"groups[{group!r}] holds {pattern!r}, not a column name")
            names += [c for c in columns if fnmatch.fnmatchcase(c, pattern) and c not in names]
        names = [c for c in names if c != x]
        if names:
            resolved[str(group)] = names
        else:
            logger.debug("metrics plot: group %r has no columns in the log, skipped", group)
    return resolved


def _save_png(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI)
    return path


def _finish(
    fig: Figure, ax: object, path: str | Path, ylabel: str, title: str | None, logy: bool, **grid
) -> Path:
    """Label, grid (``ax.grid`` options ``grid``), legend and write the one-axes figure."""
    if logy:
        ax.set_yscale("log")
    ax.set(ylabel=ylabel, title=title or "")
    ax.grid(True, alpha=0.3, **grid)
    ax.legend(fontsize="small")
    return _save_png(fig, path)


def metrics_figure(
    log: MetricsLog,
    *,
    x: str | None = "t",
    groups: Mapping[str, Sequence[str]] | None = None,
    title: str | None = None,
) -> Figure:
    """Figure with one subplot per group of metrics columns, sharing the x axis.

    Args:
        log: the metrics table, at least one row.
        x: column for the abscissa (default time ``t`` [s]); ``None`` plots against the row index.
        groups: group title -> column names or ``fnmatch`` patterns; default :data:`DEFAULT_GROUPS`.
        title: figure title.

    Returns:
        the figure (Agg canvas attached), one axes per group that has columns in ``log``; each
        axes has a y label with the unit of its group (:data:`GROUP_UNITS`) and, with several
        curves, a legend outside the axes on the right; each curve of a panel has its own
        colour (and line style beyond 20 curves).
    """
    if not isinstance(log, MetricsLog):
        raise ValueError(f"log must be a MetricsLog, got {type(log).__name__}")
    if len(log) == 0:
        raise ValueError("log is empty: nothing to plot")
    if x is not None and x not in log:
        raise ValueError(f"x column {x!r} is not in the log; columns are {log.columns}")
    resolved = _resolve_groups(log.columns, DEFAULT_GROUPS if groups is None else groups, x)
    if not resolved:
        raise ValueError(f"no column of the log matches any group; columns are {log.columns}")
    x_values = np.arange(len(log)) if x is None else log.column(x)
    fig = Figure(figsize=(9.5, 2.4 * len(resolved) + 0.8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(resolved), 1, sharex=True, squeeze=False)[:, 0]
    marker = "." if len(log) <= 200 else None
    for ax, (group, names) in zip(axes, resolved.items(), strict=True):
        undefined = [n for n in names if undefined_column(log.column(n))]
        for name, style in zip(names, curve_styles(len(names)), strict=True):
            label = f"{name} ({UNDEFINED_TEXT})" if name in undefined else name
            ax.plot(x_values, log.column(name), marker=marker, label=label, **style)
        if len(undefined) == len(names):  # an empty panel says why
            ax.text(
                0.5,
                0.5,
                f"{', '.join(names)}: {UNDEFINED_TEXT}",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize="small",
                color="0.35",
            )
        ax.set_title(group.replace("_", " "), fontsize="medium")
        ax.set_ylabel(GROUP_UNITS.get(group, ""), fontsize="small")
        if group in LOG_GROUPS and np.any(np.concatenate([log.column(n) for n in names]) > 0):
            ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
        if len(names) > 1 or names[0] != group:
            # outside the axes, right of the curves: never over a curve or a tick label
            ax.legend(
                fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0
            )
    axes[-1].set_xlabel("step" if x is None else X_UNITS.get(x, x))
    if title:
        fig.suptitle(title)
    return fig


#: what the metrics plot says of a column that is NaN in every row
UNDEFINED_TEXT = "not computed in this run: NaN in every row"


def curve_styles(n: int) -> list[dict[str, object]]:
    """``n`` distinct (colour, line style) pairs: tab10 up to 10 curves, tab20 up to 20, then
    20 colours with a new line style for each further 20 curves."""
    from matplotlib import colormaps

    if n <= 10:
        return [{"color": colormaps["tab10"](i), "linestyle": "-"} for i in range(n)]
    tab20 = colormaps["tab20"]
    return [
        {"color": tab20(i % 20), "linestyle": _LINESTYLES[(i // 20) % len(_LINESTYLES)]}
        for i in range(n)
    ]


def plot_metrics(
    log: MetricsLog,
    path: str | Path,
    *,
    x: str | None = "t",
    groups: Mapping[str, Sequence[str]] | None = None,
    title: str | None = None,
) -> Path:
    """Write a PNG of the metrics (see :func:`metrics_figure` for the arguments).

    Returns:
        the path written.
    """
    return _save_png(metrics_figure(log, x=x, groups=groups, title=title), path)


def plot_series(
    x: np.ndarray,
    ys: Mapping[str, np.ndarray],
    path: str | Path,
    xlabel: str = "",
    ylabel: str = "",
    title: str | None = None,
    logy: bool = False,
    *,
    logx: bool = False,
) -> Path:
    """Write a PNG of several named curves over one abscissa (benchmark plots).

    Args:
        x: ``(N,)`` abscissa values (units per ``xlabel``).
        ys: label -> ``(N,)`` ordinate values; at least one series.
        path: the PNG file.
        xlabel, ylabel, title: axis labels and title.
        logy, logx: logarithmic axes; non-positive values are not drawn on a log axis.

    Returns:
        the path written.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"x must have shape (N,) with N >= 1, got {x.shape}")
    if not isinstance(ys, Mapping) or not ys:
        raise ValueError("ys must be a non-empty mapping label -> (N,) array")
    series = {}
    for label, y in ys.items():
        y = np.asarray(y, dtype=np.float64)
        if y.shape != x.shape:
            raise ValueError(f"ys[{label!r}] has shape {y.shape}, expected {x.shape} like x")
        if logy and np.any(y <= 0.0):
            warn_user(
                f"PLOT_HIDDEN_VALUES: plot_series: ys[{label!r}] has non-positive values, "
                "hidden on the log axis",
                logger=logger,
            )
        series[str(label)] = y
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    marker = "o" if x.size <= 50 else None
    for label, y in series.items():
        ax.plot(x, y, marker=marker, label=label)
    if logx:
        ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    return _finish(fig, ax, path, ylabel, title, logy, which="both")


def plot_bars(
    labels: Sequence[str],
    groups: Mapping[str, Sequence[float]],
    path: str | Path,
    *,
    ylabel: str = "",
    title: str | None = None,
    logy: bool = False,
) -> Path:
    """Write a PNG of grouped bars: one group per label, one bar per series (benchmark timings).

    Args:
        labels: ``(K,)`` category names.
        groups: series name -> ``(K,)`` values (NaN bars are left out).
        path: the PNG file.
    """
    if not labels or not groups:
        raise ValueError("plot_bars needs at least one label and one series")
    k = len(labels)
    for name, values in groups.items():
        if len(values) != k:
            raise ValueError(f"groups[{name!r}] has {len(values)} values, expected {k}")
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    width = 0.8 / len(groups)
    base = np.arange(k)
    for i, (name, values) in enumerate(groups.items()):
        ax.bar(base + i * width, np.asarray(values, dtype=np.float64), width, label=name)
    ax.set_xticks(base + 0.4 - width / 2, labels)
    return _finish(fig, ax, path, ylabel, title, logy, axis="y")
