"""Keep freed memory in the process instead of handing it back to the kernel at every free.

Every Newton iteration allocates and frees arrays of tens to hundreds of MB: the per-particle
Hessian blocks, their masked and stacked triplet values, the rotated values, the CSC data.
glibc's malloc serves each request above its mmap threshold (32 MiB at most) with a fresh
``mmap`` and returns it with ``munmap`` on free, so every iteration writes to pages the process
has never touched. On a virtual machine whose balloon reports freed pages to the host
(virtio-balloon free page reporting, as on Firecracker and many cloud VMs), each such page then
costs a page fault on the host as well as in the guest (measured: ``docs/guide/performance.md``).

:func:`keep_freed_memory` sets glibc's ``M_MMAP_MAX`` to 0 (large blocks come from the heap and
go back to it when freed, to be reused by the next iteration's arrays of the same sizes) and
``M_TRIM_THRESHOLD`` to 2 GiB - 1 (the top of the heap is trimmed only past that). The price:
the process keeps its largest heap until it exits instead of shrinking after a peak.
Importing ``solvers`` (and so ``bfemp``) calls it; like the package's ``OMP_WAIT_POLICY`` this
is process-wide. The environment variable ``BFEMP_KEEP_FREED_MEMORY=0`` leaves glibc's
defaults alone. Elsewhere than glibc it does nothing
and says why in :func:`allocator_report`.
"""

from __future__ import annotations

import ctypes
import logging
import os
import platform

__all__ = ["ENV_VARIABLE", "allocator_report", "format_allocator", "keep_freed_memory"]

log = logging.getLogger(__name__)

ENV_VARIABLE = "BFEMP_KEEP_FREED_MEMORY"
_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4  # <malloc.h>
_TRIM_THRESHOLD = 2**31 - 1  # bytes, the largest value mallopt takes (an int)

_state: dict = {"keep_freed_memory": False, "why_not": "keep_freed_memory() not called"}


def keep_freed_memory() -> bool:
    """Make glibc keep freed blocks in the heap (see the module docstring); whether it does.

    Idempotent. Does nothing where ``BFEMP_KEEP_FREED_MEMORY`` is ``0``, ``false`` or ``no``,
    or where the C library is not glibc (the reason is kept for :func:`allocator_report`).
    """
    if _state["keep_freed_memory"]:
        return True
    if os.environ.get(ENV_VARIABLE, "1").strip().lower() in ("0", "false", "no", "off"):
        _state["why_not"] = f"{ENV_VARIABLE}={os.environ[ENV_VARIABLE]}"
        return False
    libc_name, _ = platform.libc_ver()
    if libc_name != "glibc":
        _state["why_not"] = f"the C library is not glibc ({libc_name or 'unknown'})"
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError) as err:
        _state["why_not"] = f"glibc's mallopt is not reachable: {err}"
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    if not (mallopt(_M_MMAP_MAX, 0) == 1 and mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD) == 1):
        _state["why_not"] = "mallopt refused M_MMAP_MAX = 0 or M_TRIM_THRESHOLD"
        return False
    _state.update(keep_freed_memory=True, why_not=None)
    log.debug("glibc malloc: M_MMAP_MAX = 0, M_TRIM_THRESHOLD = %d", _TRIM_THRESHOLD)
    return True


def allocator_report() -> dict:
    """``{"keep_freed_memory": bool, "why_not": str | None}`` for benchmark records."""
    return dict(_state)


def format_allocator() -> str:
    """One console line: whether freed memory is kept, or why not."""
    if _state["keep_freed_memory"]:
        return "malloc: freed memory kept in the process (glibc M_MMAP_MAX = 0)"
    return f"malloc: glibc defaults ({_state['why_not']})"
