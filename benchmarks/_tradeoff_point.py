"""Running the points of the trade study (``benchmarks.tradeoff``), each in a fresh process.

``execute_point(point)`` is the pure function that both executors run (``execute_local``, a pool
of local processes, and ``execute_dask``, a Dask cluster): it starts ``python -m
benchmarks._tradeoff_point SPEC RESULT`` with the point's settings in ``SPEC`` and reads the
measurement back from ``RESULT``. A fresh process makes the peak resident memory the point's own
and fixes the numba and BLAS thread counts (``THREAD_VARIABLES``) to the point's ``threads``
wherever it runs.

The measurement (JSON): ``metrics`` (what the scene's ``run_point`` returns), ``wall_s`` and
``cpu_s`` (s, the ``run_point`` call: scene build and time loop; the CPU time of all the
process's threads), ``process_wall_s`` (s, the whole child process, measured by the parent),
``peak_memory_mb`` (MiB) and ``failure`` (None, or why the child produced no metrics: an
exception, a crash, a timeout).
"""

from __future__ import annotations

import importlib
import json
import logging
import os
import re
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from concurrent.futures import Executor, ThreadPoolExecutor, as_completed
from pathlib import Path

from benchmarks._shared import python_child
from benchmarks.common import json_ready, peak_memory_mb

log = logging.getLogger(__name__)

#: ``on_done(k, measurement)``: job ``k`` of a batch has finished
OnDone = Callable[[int, dict], None]

#: environment variables that fix the thread count of a point's process
THREAD_VARIABLES = (
    "NUMBA_NUM_THREADS",
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
)
_STDERR_TAIL = 2000  # characters of a failed child's stderr kept in ``failure``


def execute_point(point: dict) -> dict:
    """Run one point in a fresh Python process and return its measurement (see module doc).

    Args:
        point: at least ``module`` (the scene's benchmark module, exposing ``run_point``),
            ``settings`` (what ``run_point`` takes), ``threads`` (threads of the child) and
            ``timeout_s`` (s, None for none).

    Returns:
        the measurement dict; never raises for a failing point (``failure`` says why).
    """
    env = {**os.environ, **{name: str(int(point["threads"])) for name in THREAD_VARIABLES}}
    with tempfile.TemporaryDirectory(prefix="bfemp-tradeoff-") as tmp:
        spec, result = Path(tmp) / "point.json", Path(tmp) / "result.json"
        spec.write_text(json.dumps({"module": point["module"], "settings": point["settings"]}))
        started = time.perf_counter()
        try:
            args = ["-m", __name__, str(spec), str(result)]
            proc = python_child(args, env=env, timeout=point.get("timeout_s"))
        except subprocess.TimeoutExpired:
            return _failed(f"timed out after {point['timeout_s']} s", started)
        if proc.returncode != 0 or not result.exists():
            tail = proc.stderr[-_STDERR_TAIL:].strip()
            return _failed(f"point process exited with status {proc.returncode}: {tail}", started)
        measurement = json.loads(result.read_text())
    measurement["process_wall_s"] = time.perf_counter() - started
    return measurement


def _execute(ids: list[str], jobs: list[dict], executor: Executor, on_done: OnDone | None) -> list:
    """``execute_point`` of every job on ``executor`` (shut down at the end); ``(n,)``
    measurements in the order of ``jobs``, ``on_done(k, measurement)`` called as job ``k``
    finishes and each logged by its id."""
    results: list[dict | None] = [None] * len(jobs)
    with executor:
        futures = {executor.submit(execute_point, job): k for k, job in enumerate(jobs)}
        for future in as_completed(futures):
            k = futures[future]
            results[k] = measurement = future.result()
            log.info(
                "%s: %.1f s, %s iterations%s",
                ids[k],
                measurement.get("wall_s") or float("nan"),
                (measurement.get("metrics") or {}).get("iterations"),
                f", FAILED: {measurement['failure']}" if measurement.get("failure") else "",
            )
            if on_done is not None:
                on_done(k, measurement)
    return results


def execute_local(
    ids: list[str], jobs: list[dict], workers: int, on_done: OnDone | None = None
) -> list[dict]:
    """``execute_point`` of every job, ``workers`` point processes at once.

    Args:
        ids: ``(n,)`` point ids (for the log); jobs: ``(n,)`` arguments of ``execute_point``;
        workers: processes at once (>= 1); on_done: called with ``(k, measurement)`` as job
            ``k`` finishes (in the order they finish).

    Returns:
        ``(n,)`` measurements, in the order of ``jobs``.
    """
    return _execute(ids, jobs, ThreadPoolExecutor(max_workers=workers), on_done)


_ADDRESS = re.compile(r"(tcp|tls|ws|wss|ucx)://(\[[0-9a-fA-F:.]+\]|[^\s:/\[\]]+):(\d{1,5})")


def check_scheduler(address: str) -> str:
    """``address`` (stripped) if it reads like a Dask scheduler address (``tcp://host:port``)."""
    match = _ADDRESS.fullmatch(address.strip())
    if match is None or not 0 < int(match.group(3)) < 65536:
        raise ValueError(
            f"--scheduler must be a Dask scheduler address like tcp://host:8786, got {address!r}"
        )
    return address.strip()


def execute_dask(
    ids: list[str], jobs: list[dict], address: str, timeout_s: float, on_done: OnDone | None = None
) -> list[dict]:
    """``execute_point`` of every job on the Dask cluster of the scheduler at ``address``
    (``tcp://host:port``; ``timeout_s``: seconds to wait for the connection); ``ids``, ``jobs``,
    ``on_done`` and the result as for ``execute_local``.

    Raises:
        ValueError: a malformed address, no ``distributed`` package, or no scheduler reached.
    """
    address = check_scheduler(address)
    try:
        import distributed
    except ImportError:
        raise ValueError(
            "--scheduler needs the Dask 'distributed' package (pip install distributed)"
        ) from None
    try:
        client = distributed.Client(address, timeout=timeout_s)
    except (OSError, TimeoutError) as err:
        raise ValueError(f"cannot reach the Dask scheduler at {address}: {err}") from None
    with client:  # pure=False: a replayed or repeated point runs again, no result reused
        return _execute(ids, jobs, client.get_executor(pure=False), on_done)


def _failed(why: str, started: float) -> dict:
    return {
        "metrics": None,
        "wall_s": None,
        "cpu_s": None,
        "peak_memory_mb": None,
        "process_wall_s": time.perf_counter() - started,
        "failure": why,
    }


def measure(module: str, settings: dict) -> dict:
    """In this process: ``module.run_point(settings)``, its wall time and the peak memory."""
    run_point = importlib.import_module(module).run_point
    started, cpu_started = time.perf_counter(), time.process_time()
    try:
        metrics = run_point(settings)
    except Exception as err:  # recorded as the point's failure; the sweep goes on
        log.error("%s.run_point failed:\n%s", module, traceback.format_exc())
        metrics, failure = None, f"{type(err).__name__}: {err}"
    else:
        failure = metrics.get("failure")
    return {
        "metrics": metrics,
        "wall_s": time.perf_counter() - started,
        "cpu_s": time.process_time() - cpu_started,
        "peak_memory_mb": peak_memory_mb(),
        "failure": failure,
    }


def main(argv: list[str]) -> int:
    """``python -m benchmarks._tradeoff_point SPEC RESULT``: measure the point in ``SPEC``."""
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    spec_path, result_path = argv
    spec = json.loads(Path(spec_path).read_text())
    measurement = measure(spec["module"], spec["settings"])
    # NaN is not JSON: the parent reads it back as None
    Path(result_path).write_text(json.dumps(json_ready(measurement)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
