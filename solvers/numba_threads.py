"""numba's parallel kernels on Intel TBB's thread pool where the ``tbb`` wheel is installed.

numba runs ``prange`` loops on the first threading layer it can load: TBB, OpenMP, workqueue.
On OpenMP the package's ``OMP_WAIT_POLICY=PASSIVE`` (``solvers/__init__``; spinning threads
starved other processes on the same cores) makes every parallel region wake its threads from
sleep, about 45 us against 2-10 us on TBB, whose workers spin briefly and then yield: an
explicit MPM step starts four regions (measured: ``docs/guide/performance.md``).

pip puts the wheel's ``libtbb.so.12`` in ``<prefix>/lib``, where the dynamic loader does not
look, so numba's TBB layer does not load from a virtual environment (numba issues 6108, 7148,
9740). :func:`prefer_tbb` loads that file by its path before numba starts its threads; numba's
own lookup by name then finds it. ``NUMBA_THREADING_LAYER`` set by the user is left alone. The
layers give the same results: every kernel splits its work into chunks fixed by the thread
count, never by the scheduler.
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

__all__ = ["format_numba_threads", "numba_threads_report", "prefer_tbb"]


_LIBTBB = "libtbb.so.12"  # the soname numba's TBB layer links and looks up (Linux)

_state: dict = {"tbb_library": "", "why_not": "prefer_tbb() not called"}


def prefer_tbb(prefix: str = sys.prefix) -> bool:
    """Load the ``tbb`` wheel's library from ``<prefix>/lib`` so that numba picks its TBB
    layer (module docstring); whether it was loaded. Idempotent; does nothing where
    ``NUMBA_THREADING_LAYER`` is set, off Linux, or without the wheel (the reason is kept for
    :func:`numba_threads_report`)."""
    if _state["tbb_library"]:
        return True
    if os.environ.get("NUMBA_THREADING_LAYER", "default") != "default":
        _state["why_not"] = f"NUMBA_THREADING_LAYER={os.environ['NUMBA_THREADING_LAYER']}"
        return False
    if not sys.platform.startswith("linux"):
        _state["why_not"] = f"not Linux ({sys.platform}): numba's own lookup"
        return False
    path = Path(prefix) / "lib" / _LIBTBB
    if not path.is_file():
        _state["why_not"] = f"no {path} (the tbb wheel is not installed)"
        return False
    try:
        ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
    except OSError as err:
        _state["why_not"] = f"{path} did not load: {err}"
        return False
    _state["tbb_library"] = str(path)
    return True


def numba_threads_report() -> dict:
    """``{"layer": "tbb" | "omp" | "workqueue", "threads": n, "tbb_library": path or "",
    "why_not_tbb": reason or ""}`` for benchmark records; starts numba's threads if no
    parallel kernel has yet (a few ms)."""
    import numba
    from numba.np.ufunc import parallel

    try:
        layer = numba.threading_layer()
    except ValueError:  # no parallel kernel has run: start the pool as the first one would
        parallel._launch_threads()
        layer = numba.threading_layer()
    return {
        "layer": layer,
        "threads": numba.get_num_threads(),
        "tbb_library": _state["tbb_library"],
        "why_not_tbb": "" if _state["tbb_library"] else _state["why_not"],
    }


def format_numba_threads() -> str:
    """One console line: numba's threading layer and thread count."""
    report = numba_threads_report()
    why = f" ({report['why_not_tbb']})" if report["layer"] != "tbb" else ""
    return f"numba threads: {report['threads']} on the {report['layer']} layer{why}"
