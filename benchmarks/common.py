"""Shared helpers of the benchmarks: environment record, JSON output."""

from __future__ import annotations

import json
import logging
import math
import os
import platform
import resource
import subprocess
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from solvers.allocator import allocator_report
from solvers.choice import linear_algebra
from solvers.numba_threads import numba_threads_report
from solvers.openmp import openmp_report


def git_commit() -> str:
    """The current git commit, or "unknown" outside a checkout."""
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parent,
        )
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def environment() -> dict:
    """Machine and library versions for the record."""
    import numba
    import scipy

    try:
        import sksparse

        sks = getattr(sksparse, "__version__", "installed")
    except ImportError:
        sks = None
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "scikit_sparse": sks,
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
        "commit": git_commit(),
        # the BLAS under CHOLMOD and the linear solvers installed (issue 13)
        "linear_algebra": linear_algebra(),
        "allocator": allocator_report(),
        # CHOLMOD's own OpenMP loops bounded (solvers.openmp)
        "openmp": openmp_report(),
        # numba's threading layer: TBB where the wheel is installed (solvers.numba_threads)
        "numba_threads": numba_threads_report(),
        "load_average_1min": os.getloadavg()[0],
    }


def json_ready(value: object) -> object:
    """``value`` with numpy scalars as Python numbers and NaN and infinities as None, through
    dicts (keys as strings), lists and tuples: what strict JSON holds."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, str):  # numpy scalar
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def peak_memory_mb() -> float:
    """Peak resident memory of this process in MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def figure(figsize: tuple[float, float], *grid, layout: str | None = None, **subplots):
    """A matplotlib figure drawn without a display (Agg canvas) and its axes
    ``fig.subplots(*grid, **subplots)``: ``(fig, axes)``; ``figsize`` in inches."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout=layout)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(*grid, **subplots)


def save(fig, path: str | Path, axes=(), title: str | None = None, legend: str = "small") -> None:
    """Grid and legend (font size ``legend``) on each of ``axes``, ``title`` above, then the
    figure saved to ``path`` at 110 dpi."""
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=legend)
    if title is not None:
        fig.suptitle(title)
    fig.savefig(path, dpi=110)


def table_head(*columns: str) -> list[str]:
    """The header row and the separator row of a Markdown table of ``columns``."""
    return [f"| {' | '.join(columns)} |", "|" + "---|" * len(columns)]


def write_json(out: str | Path, name: str, payload: dict) -> Path:
    """Write ``out/name.json`` (indented) and return its path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.json"
    path.write_text(json.dumps(payload, indent=2, default=float))
    return path


def cases_by_mu(
    records: list[str | Path], attach: Callable[[Path, dict], dict] | None = None
) -> tuple[str, list[dict], list[dict]]:
    """Read records of one mode whose cases (one per friction coefficient ``mu``) ran in
    separate processes: ``(mode, records, cases sorted by mu)``; a later record's case replaces
    an earlier one of the same mu. ``attach(path, case)`` returns the case with data kept
    beside its record (e.g. arrays in an ``.npz``)."""
    loaded = [json.loads(Path(p).read_text()) for p in records]
    modes = {r["mode"] for r in loaded}
    if len(modes) != 1:
        raise ValueError(f"merge: records of one mode expected, got modes {sorted(modes)}")
    by_mu = {}
    for path, record in zip(records, loaded, strict=True):
        for case in record["cases"]:
            by_mu[case["mu"]] = case if attach is None else attach(Path(path), case)
    return modes.pop(), loaded, [by_mu[mu] for mu in sorted(by_mu)]


def note_merge(payload: dict, records: list[str | Path], loaded: list[dict]) -> dict:
    """Add to a merged ``payload`` where its cases came from (``merged_from``: path, mus and
    wall time of each record) and the largest peak memory of those runs; returns it."""
    payload["merged_from"] = [
        {"path": str(p), "mus": [c["mu"] for c in r["cases"]], "wall_s": r["wall_s"]}
        for p, r in zip(records, loaded, strict=True)
    ]
    payload["peak_memory_mb"] = max(r["peak_memory_mb"] for r in loaded)
    return payload


def log_row(logger: logging.Logger, label: str, row: Mapping, keys: str) -> None:
    """Log ``label: key=value ...`` of the space-separated ``keys`` of ``row`` (floats to 6
    significant digits): the progress line of a step or a finished case."""
    text = (
        f"{k}={row[k]:.6g}" if isinstance(row[k], float) else f"{k}={row[k]}" for k in keys.split()
    )
    logger.info("%s: %s", label, " ".join(text))
