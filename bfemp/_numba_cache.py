"""Where numba keeps the compiled kernels, and the notice the command line gives on a first run.

The kernels of ``bfemp``, ``geometry`` and ``solvers`` are ``njit(cache=True)``: the first run
compiles them and writes them to numba's cache (index files ``*.nbi`` beside the ``*.nbc``
code), later runs load them. The location is numba's own rule, which bfemp does not override:
``NUMBA_CACHE_DIR`` when it is set, else a ``__pycache__`` folder beside each source file (numba
falls back to a per-user cache folder where that one is not writable). The Makefile sets
``NUMBA_CACHE_DIR`` to ``.numba_cache`` in the repository, so that ``make demo`` and ``make
test`` share one cache and ``make clean`` removes it. bfemp sets no default of its own: numba's
rule always finds a writable place that every later run of the same install finds again, and a
default inside the package would be an environment change made behind the user's back (and
unwritable for a system-wide install). The notice says "a minute or more", no exact figure
(measured: design note ``measurements``, numba cache).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["first_run_notice"]

_PACKAGES = ("bfemp", "geometry", "solvers")


def first_run_notice(cache_dir: str | None = None) -> str | None:
    """A one-line notice when no compiled kernel is cached yet (this run will compile them),
    naming where they will be kept; None when some are cached.

    Args:
        cache_dir: the cache folder to look in; default numba's ``NUMBA_CACHE_DIR``
            (``numba.config.CACHE_DIR``), and where that is unset the ``__pycache__`` folders
            of the packages (no notice when those are not writable: numba then uses a per-user
            folder this check does not look into).
    """
    if cache_dir is None:
        from numba.core import config

        cache_dir = config.CACHE_DIR
    if cache_dir:
        folder = Path(cache_dir)
        if folder.is_dir() and any(folder.rglob("*.nbi")):
            return None
        where = str(folder)
    else:
        root = Path(__file__).resolve().parents[1]
        folders = [root / name for name in _PACKAGES]
        if not all(os.access(f, os.W_OK) for f in folders):
            return None
        if any(any(f.rglob("__pycache__/*.nbi")) for f in folders):
            return None
        where = f"the __pycache__ folders under {root}"
    return f"compiling numba kernels on first run (a minute or more, once; cached in {where})"
