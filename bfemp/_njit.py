"""One loop, two numba builds: a gather over points runs serially below a size and in parallel
from it on, where the thread start-up of a parallel loop costs less than the loop."""

from __future__ import annotations

import functools
import types
from collections.abc import Callable

from numba import njit

__all__ = ["compile_parallel_builds", "serial_or_parallel"]

_BUILT: list[Callable] = []  # every serial_or_parallel function


def serial_or_parallel(min_rows: int) -> Callable[[Callable], Callable]:
    """Decorator: the function compiled twice, ``njit(cache=True)`` and ``njit(cache=True,
    parallel=True)`` (its ``prange`` loops run as plain ranges in the serial build, with the
    same arithmetic: each iteration writes only its own rows), called with positional
    arguments and running the parallel build when the first has ``min_rows`` rows or more.
    The builds are the attributes ``serial`` and ``parallel`` of the decorated function.

    The parallel build compiles a twin of the function named ``NAME_parallel``: numba's disk
    cache files a build under its module, qualified name and line, not its flags, so two
    builds of one function share one entry and a process loads whichever was saved first for
    both (the parallel build then ran serially from a warm cache)."""

    def build(func: Callable) -> Callable:
        serial = njit(cache=True)(func)
        twin = types.FunctionType(
            func.__code__, func.__globals__, f"{func.__name__}_parallel", func.__defaults__
        )
        twin.__qualname__ = f"{func.__qualname__}_parallel"
        parallel = njit(cache=True, parallel=True)(twin)

        @functools.wraps(func)
        def run(*args: object) -> object:
            return (parallel if args[0].shape[0] >= min_rows else serial)(*args)

        run.serial, run.parallel = serial, parallel
        _BUILT.append(run)
        return run

    return build


def compile_parallel_builds(functions: list[Callable] | None = None) -> int:
    """Compile and cache the parallel builds of ``functions`` (default: every one) for the
    signatures their serial builds met in this process (``bfemp warmup``'s small scenes reach
    only the serial ones); the number compiled."""
    compiled = 0
    for run in _BUILT if functions is None else functions:
        for signature in run.serial.signatures:
            if signature not in run.parallel.signatures:
                run.parallel.compile(signature)
                compiled += 1
    return compiled
