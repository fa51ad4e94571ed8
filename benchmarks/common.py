"""Shared helpers of the benchmarks: environment record, JSON output."""

from __future__ import annotations

import json
import os
import platform
import resource
import subprocess
from pathlib import Path

import numpy as np

from solvers.blas import linear_algebra


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
        "load_average_1min": os.getloadavg()[0],
    }


def peak_memory_mb() -> float:
    """Peak resident memory of this process in MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def write_json(out: str | Path, name: str, payload: dict) -> Path:
    """Write ``out/name.json`` (indented) and return its path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.json"
    path.write_text(json.dumps(payload, indent=2, default=float))
    return path
