"""Bound the OpenMP threads of CHOLMOD's own parallel loops while CHOLMOD runs.

SuiteSparse 5 builds CHOLMOD with OpenMP loops that ask for a thread count fixed when it was
compiled (``num_threads(CHOLMOD_OMP_NUM_THREADS)``, 4 by default), whatever the machine has:
the loops that zero each supernode of ``L`` before it is assembled, clear the row map, and so
on. ``OMP_NUM_THREADS`` does not reach an explicit ``num_threads`` clause, so on 2 cores every
supernode of a factorisation started 3 extra threads, and with ``OMP_WAIT_POLICY=PASSIVE`` (set
by ``solvers/__init__.py`` for numba) each start is a futex wake-up and a sleep again
(measured: ``docs/guide/performance.md``). The dense BLAS work, where two cores pay, runs on
OpenBLAS's own threads, untouched by this.

:func:`bounded_openmp` bounds the OpenMP regions started by the calling thread with the runtime
calls ``omp_set_dynamic(1)`` and ``omp_set_num_threads(n)`` (dynamic adjustment caps even an
explicit ``num_threads`` at ``n``), and gives the previous values back on exit, so numba's own
parallel regions keep their threads. ``BFEMP_CHOLMOD_OPENMP_THREADS`` sets ``n`` (default 1;
``0`` leaves CHOLMOD's compiled-in count alone, the control). Where CHOLMOD links no OpenMP
runtime this does nothing and :func:`openmp_report` says so.
"""

from __future__ import annotations

import ctypes
import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = [
    "ENV_VARIABLE",
    "bounded_openmp",
    "cholmod_openmp_threads",
    "format_openmp",
    "openmp_report",
]

log = logging.getLogger(__name__)

ENV_VARIABLE = "BFEMP_CHOLMOD_OPENMP_THREADS"

#: OpenMP runtimes CHOLMOD may link (GNU, LLVM, Intel), by a substring of the mapped file name
_RUNTIMES = ("libgomp", "libomp", "libiomp")

#: the loaded runtime: None before the first look, False when there is none
_runtime: ctypes.CDLL | bool | None = None
_runtime_path = ""


def cholmod_openmp_threads() -> int:
    """Threads CHOLMOD's OpenMP loops are bounded to (``BFEMP_CHOLMOD_OPENMP_THREADS``, default
    1); 0: not bounded.

    Raises:
        ValueError: the variable is not an integer >= 0.
    """
    raw = os.environ.get(ENV_VARIABLE, "1").strip()
    try:
        n = int(raw)
    except ValueError:
        n = -1
    if n < 0:
        raise ValueError(f"{ENV_VARIABLE} must be an integer >= 0, got {raw!r}")
    return n


def _mapped_runtime(maps_path: str = "/proc/self/maps") -> str:
    """The file of the OpenMP runtime mapped into this process, or ``""``."""
    try:
        with open(maps_path) as maps:
            for line in maps:
                path = line.split()[-1] if line.strip() else ""
                name = os.path.basename(path)
                if path.startswith("/") and any(name.startswith(r) for r in _RUNTIMES):
                    return path
    except OSError:
        pass
    return ""


def _load_runtime() -> ctypes.CDLL | None:
    """The OpenMP runtime already in the process (CHOLMOD's), or None; looked up once."""
    global _runtime, _runtime_path
    if _runtime is None:
        _runtime = False
        try:
            import sksparse.cholmod  # noqa: F401  (maps CHOLMOD's runtime, if it links one)
        except ImportError:
            pass
        path = _mapped_runtime()
        if path:
            try:
                lib = ctypes.CDLL(path)  # already mapped: the same library, not a second copy
                for name in ("omp_set_dynamic", "omp_set_num_threads"):
                    getattr(lib, name).argtypes, getattr(lib, name).restype = [ctypes.c_int], None
                for name in ("omp_get_dynamic", "omp_get_max_threads"):
                    getattr(lib, name).argtypes, getattr(lib, name).restype = [], ctypes.c_int
            except (OSError, AttributeError) as err:
                log.debug("OpenMP runtime %s not usable: %s", path, err)
            else:
                _runtime, _runtime_path = lib, path
    return _runtime or None


@contextmanager
def bounded_openmp(threads: int | None = None) -> Iterator[None]:
    """Inside the block, OpenMP regions started by this thread use at most ``threads`` threads.

    Args:
        threads: the bound (None: :func:`cholmod_openmp_threads`); 0 leaves the runtime alone.

    Costs four foreign calls, about 2 us; without an OpenMP runtime it does nothing.
    """
    n = cholmod_openmp_threads() if threads is None else threads
    lib = _load_runtime() if n > 0 else None
    if lib is None:
        yield
        return
    dynamic, max_threads = lib.omp_get_dynamic(), lib.omp_get_max_threads()
    lib.omp_set_dynamic(1)
    lib.omp_set_num_threads(n)
    try:
        yield
    finally:
        lib.omp_set_num_threads(max_threads)
        lib.omp_set_dynamic(dynamic)


def openmp_report() -> dict:
    """``{"runtime": path or "", "cholmod_openmp_threads": n}`` for benchmark records: the
    OpenMP runtime in the process and the bound (0: not bounded, or no runtime to bound)."""
    n = cholmod_openmp_threads()
    lib = _load_runtime()
    return {
        "runtime": _runtime_path if lib is not None else "",
        "cholmod_openmp_threads": n if lib is not None else 0,
    }


def format_openmp() -> str:
    """One console line: how many OpenMP threads CHOLMOD's own loops get."""
    report = openmp_report()
    if report["cholmod_openmp_threads"]:
        n = report["cholmod_openmp_threads"]
        return f"CHOLMOD OpenMP loops: {n} thread{'s' if n > 1 else ''} ({report['runtime']})"
    if cholmod_openmp_threads() == 0:
        return f"CHOLMOD OpenMP loops: as compiled ({ENV_VARIABLE}=0)"
    return "CHOLMOD OpenMP loops: no OpenMP runtime in the process"
