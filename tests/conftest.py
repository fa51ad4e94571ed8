"""Test-session set-up shared by every test file.

Under pytest-xdist (``make test``: one worker per core) each worker gets its share of the cores
for its thread pools: numba's, OpenBLAS's (CHOLMOD's dense work, numpy's) and OpenMP's. Left at
their defaults, every worker starts as many threads as the machine has cores, so two workers on
2 cores ran 4 threads in every parallel kernel and factorisation and lost the difference to
spinning and wake-ups: 360 s against 302 s for the parallel part of the suite, 97 s against 21 s
of system time (2 cores, 2026-12-07). The variables are read when numba and the BLAS load,
which is after this file; a value set by the caller is kept. The tests that compare wall times
(marked ``serial``) run in one process, without xdist, on every core.
"""

import os

_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
_POOLS = ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
if _WORKERS:
    _THREADS = str(max(1, (os.cpu_count() or 1) // _WORKERS))
    for _name in _POOLS:
        os.environ.setdefault(_name, _THREADS)


def pytest_collection_modifyitems(items: list) -> None:
    """Files with a test marked ``slow`` run first, in their collected order, the rest after:
    the workers share out the long files first and end together on short ones (the docs build
    came last in collection order, and one worker ran it alone at the end)."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)
