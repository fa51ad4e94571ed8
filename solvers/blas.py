"""Which BLAS CHOLMOD runs on, and how many threads it uses.

CHOLMOD's supernodal factorisation spends nearly all its time in dense BLAS/LAPACK kernels of
whatever ``libblas.so.3`` the dynamic loader resolves (Debian: ``update-alternatives``).  The
reference BLAS that ``libsuitesparse-dev`` pulls in is 1.4x to 6.5x slower on our matrices than
OpenBLAS (issue 13), so the library reports at start-up which one CHOLMOD got.

Detection reads ``/proc/self/maps`` (Linux) after importing ``sksparse.cholmod``: the BLAS
mapped from outside the wheels of numpy/scipy (which bundle their own OpenBLAS, unused by
CHOLMOD) is the one CHOLMOD links.  Thread counts come from ``threadpoolctl`` where installed.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "BlasInfo",
    "REFERENCE_BLAS_HINT",
    "cholmod_blas",
    "classify_blas",
    "report_cholmod_blas_once",
    "serial_wheel_blas",
    "set_blas_threads",
]

logger = logging.getLogger(__name__)

REFERENCE_BLAS_HINT = (
    "CHOLMOD runs on the reference BLAS ({path}), several times slower than an optimised one; "
    "install OpenBLAS (`apt-get install libopenblas0-pthread`, or `make setup` as root)"
)

# The start-up report, made once per process (see report_cholmod_blas_once).
_reported: BlasInfo | None = None

#: (substring of the library file name, BLAS name); the first match wins
_KNOWN = (
    ("mkl", "mkl"),
    ("openblas", "openblas"),
    ("blis", "blis"),
    ("atlas", "atlas"),
    ("/blas/libblas", "reference"),
    ("libblas.so", "reference"),
)

#: directories of libraries bundled inside Python wheels: not the BLAS CHOLMOD links
_WHEEL_DIRS = ("numpy.libs", "scipy.libs", "site-packages/numpy", "site-packages/scipy")


@dataclass(frozen=True)
class BlasInfo:
    """The BLAS CHOLMOD got.

    Attributes:
        name: ``"openblas"``, ``"mkl"``, ``"blis"``, ``"atlas"``, ``"reference"``, or
            ``"unknown"`` (no CHOLMOD, or not on Linux).
        path: the resolved file of the library (``""`` when unknown).
        threads: its thread count from threadpoolctl, or None (reference BLAS: 1 by nature).
    """

    name: str
    path: str
    threads: int | None

    @property
    def optimised(self) -> bool:
        """Whether this is a tuned, multi-threaded BLAS (not the reference one)."""
        return self.name in ("openblas", "mkl", "blis", "atlas")

    def describe(self) -> str:
        """One line, e.g. ``openblas (/usr/lib/.../libopenblasp-r0.3.21.so, 2 threads)``."""
        if self.name == "unknown":
            return "unknown (CHOLMOD not loaded or no /proc/self/maps)"
        threads = "" if self.threads is None else f", {self.threads} threads"
        return f"{self.name} ({self.path}{threads})"


def classify_blas(path: str) -> str | None:
    """The BLAS name of a shared-library path, or None if it is no BLAS."""
    low = path.lower()
    if any(d in low for d in _WHEEL_DIRS) or "lapack" in Path(low).name:
        return None
    for key, name in _KNOWN:
        if key in low:
            return name
    return None


def _mapped_blas(maps_text: str) -> tuple[str, str] | None:
    """(name, path) of the system BLAS in a ``/proc/self/maps`` text.

    The library mapped under the soname's file name ``libblas.so*`` is the one the loader
    resolved for CHOLMOD (Debian's OpenBLAS and reference BLAS both install one); only without
    it do other BLAS libraries count, MKL last (``pypardiso`` maps its own MKL, which CHOLMOD
    does not use).
    """
    found: dict[str, str] = {}
    for line in maps_text.splitlines():
        parts = line.split()
        if len(parts) < 6 or not parts[-1].startswith("/"):
            continue
        name = classify_blas(parts[-1])
        if name is None:
            continue
        if Path(parts[-1]).name.startswith("libblas.so"):
            return name, os.path.realpath(parts[-1])
        found.setdefault(name, os.path.realpath(parts[-1]))
    for name in ("openblas", "blis", "atlas", "reference", "mkl"):
        if name in found:
            return name, found[name]
    return None


def _threads(path: str) -> int | None:
    try:
        # threadpoolctl: the maintained way to read and set BLAS/OpenMP thread pools.
        from threadpoolctl import threadpool_info
    except ImportError:
        return None
    real = Path(os.path.realpath(path))
    for pool in threadpool_info():
        lib = Path(os.path.realpath(pool.get("filepath", "")))
        # the libblas.so.3 shim of Debian's OpenBLAS loads libopenblas*.so from its directory
        if lib == real or (pool.get("user_api") == "blas" and lib.parent == real.parent):
            return int(pool["num_threads"])
    return None


def cholmod_blas(maps_path: str = "/proc/self/maps") -> BlasInfo:
    """The BLAS ``sksparse.cholmod`` is linked against in this process.

    Args:
        maps_path: the memory-map listing to read (tests pass a file of their own).

    Returns:
        :class:`BlasInfo`; ``name == "unknown"`` when CHOLMOD does not import or the listing
        cannot be read.
    """
    try:
        from sksparse import cholmod  # noqa: F401  (loads libcholmod and its BLAS)

        text = Path(maps_path).read_text()
    except (ImportError, OSError):
        return BlasInfo("unknown", "", None)
    hit = _mapped_blas(text)
    if hit is None:
        return BlasInfo("unknown", "", None)
    name, path = hit
    return BlasInfo(name, path, _threads(path))


def report_cholmod_blas_once() -> BlasInfo:
    """Log once per process which BLAS CHOLMOD got: INFO if optimised, a WARNING if not."""
    global _reported
    if _reported is None:
        _reported = info = cholmod_blas()
        if info.name == "reference":
            logger.warning(REFERENCE_BLAS_HINT.format(path=info.path))
        else:
            logger.info("CHOLMOD BLAS: %s", info.describe())
    return _reported


def set_blas_threads(n: int) -> bool:
    """Limit the BLAS thread pools of this process to ``n`` threads; False without threadpoolctl.

    Raises:
        ValueError: n is not an integer >= 1.
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"BLAS threads must be an integer >= 1, got {n!r}")
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return False
    threadpool_limits(limits=n, user_api="blas")
    return True


#: threadpoolctl's controller of the BLAS libraries bundled in wheels; False: none to control
_wheel_blas_pools = None


def _wheel_blas_controller():  # noqa: ANN202  (a threadpoolctl.ThreadpoolController or None)
    global _wheel_blas_pools
    if _wheel_blas_pools is None:
        _wheel_blas_pools = False
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:
            return None
        import scipy.linalg  # noqa: F401  (maps scipy's own OpenBLAS, so that it is controlled)

        controller = ThreadpoolController()
        wheel = [
            lib
            for lib in controller.lib_controllers
            if lib.user_api == "blas"
            and any(d in os.path.realpath(lib.filepath).lower() for d in _WHEEL_DIRS)
        ]
        if wheel:
            controller.lib_controllers = wheel
            _wheel_blas_pools = controller
    return _wheel_blas_pools or None


@contextmanager
def serial_wheel_blas() -> Iterator[None]:
    """Run numpy's and scipy's bundled BLAS (not CHOLMOD's) on one thread inside the block.

    Newton's vector work (``np.dot``, ``np.linalg.norm`` on 1e4-1e5 entries) goes through the
    OpenBLAS inside the numpy/scipy wheels, whose worker threads then spin for about 0.1 s
    (OpenBLAS's thread timeout) on the same cores as CHOLMOD's own OpenBLAS; ``Simulation.step``
    runs inside it too (its per-step energies are dot products of that size). One thread loses
    nothing on vectors of that size (measured: ``docs/guide/performance.md``).
    The previous thread counts come back on exit; without threadpoolctl, or without wheel BLAS
    loaded, this does nothing. Costs about 10 us.
    """
    controller = _wheel_blas_controller()
    if controller is None:
        yield
        return
    with controller.limit(limits=1):
        yield
