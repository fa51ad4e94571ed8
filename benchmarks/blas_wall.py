"""Wall time of whole benchmarks on the reference BLAS and on the optimised one (issue 13).

The issue asks for the rings and hertz full wall times before and after the optimised BLAS
under CHOLMOD. "Before" and "after" are taken in one run, on one machine and one commit: each
benchmark runs twice as a child process (``python -m benchmarks NAME --MODE``), once with the
loader pointed at Debian's reference BLAS and LAPACK (:func:`benchmarks._blas_switch.
reference_blas_env`) and once on the system default (OpenBLAS after ``make setup``). The two
runs are sequential, so they do not share the cores.

Modes:
    ``full``: hertz and rings in full mode (rings full alone is 35-60 min on OpenBLAS);
    ``hertz``: hertz in full mode only; ``rings``: rings in full mode only;
    ``rings_transfers``: rings in full mode without its compared integrator (the APIC and FLIP
    runs the record is about, half the time);
    ``quick``: slope in quick mode (seconds; what the tests run).

Recorded per benchmark and BLAS: the child's wall time (s, interpreter start and numba cache
loads included), the benchmark's own ``wall_s`` from its JSON, and the BLAS CHOLMOD ran on as
that JSON names it; then reference / optimised for both times. ``--blas reference`` (or
``optimised``) runs one half, and ``--merge`` a later run's record with the other half's.

Measured results, with the commits they ran on: ``benchmarks/records/blas_wall.md``.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import subprocess
from pathlib import Path

from benchmarks._blas_switch import reference_blas_env
from benchmarks._phases import timed
from benchmarks._shared import ROOT, python_child
from benchmarks.runner import Benchmark, register

log = logging.getLogger(__name__)

#: mode -> (benchmark, its mode, extra command-line options) run under each BLAS
MODES = {
    "full": (("hertz", "full", ()), ("rings", "full", ())),
    "hertz": (("hertz", "full", ()),),
    "rings": (("rings", "full", ()),),
    "rings_transfers": (("rings", "full", ("--no-compare",)),),
    "quick": (("slope", "quick", ()),),
}


def _run_child(
    name: str, mode: str, options: tuple[str, ...], out: Path, env: dict, timeout: float
) -> dict:
    """Run benchmark ``name`` in ``mode`` in a child process with ``env``; its wall and record."""
    command = ["-m", "benchmarks", name, f"--{mode}", *options, "--out", str(out)]
    try:
        done, wall = timed(lambda: python_child(command, env, timeout, cwd=ROOT))
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:.0f} s"}
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
        return {"error": f"exit status {done.returncode}: {' | '.join(tail)}", "wall_s": wall}
    record = json.loads(next(out.glob("*.json")).read_text())
    la = record.get("environment", {}).get("linear_algebra", {})
    runs = record.get("runs")
    per_run = {}
    if isinstance(runs, dict):  # rings: one run per transfer, each with its own wall time
        per_run = {k: r["wall_s"] for k, r in runs.items() if isinstance(r, dict) and "wall_s" in r}
    return {
        "command": " ".join(command),
        "wall_s": wall,
        "benchmark_wall_s": record.get("wall_s"),
        "run_wall_s": per_run,
        "blas": la.get("cholmod_blas"),
        "blas_threads": la.get("blas_threads"),
    }


#: the BLAS a run may be limited to (``--blas``)
BLAS_CHOICES = ("both", "reference", "optimised")


def _arguments(group: argparse._ActionsContainer) -> None:
    """``--blas {both,reference,optimised}`` (one half only; default both) and ``--merge J``."""
    group.add_argument(
        "--blas",
        choices=BLAS_CHOICES,
        help="run on both BLAS (default) or on one (the other half of a record measured apart)",
    )
    group.add_argument(
        "--merge",
        metavar="BLAS_WALL_JSON",
        help="take the halves this run does not make from that record of the same mode",
    )


def _read_merge(path: str | Path, mode: str) -> dict:
    """The ``blas_wall.json`` at ``path``; ValueError naming what does not fit ``mode``."""
    try:
        record = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ValueError(f"merge: cannot read {path}: {err}") from None
    if record.get("benchmark") != "blas_wall" or record.get("mode") != mode:
        raise ValueError(
            f"merge: {path} is not a blas_wall record of mode {mode!r} "
            f"(benchmark {record.get('benchmark')!r}, mode {record.get('mode')!r})"
        )
    return record


def measure(
    mode: str,
    cfg: tuple,
    out: Path,
    timeout_s: float = 4 * 3600.0,
    blas: str = "both",
    merge: str | Path | None = None,
) -> dict:
    """Run each benchmark of ``cfg`` (``MODES[mode]``) on both BLAS.

    Args:
        mode, cfg: a key of :data:`MODES` and its value.
        out: output folder; the children's own records go under ``out/blas_wall/``.
        timeout_s: wall limit of one child (s); a child past it is recorded as an error.
        blas: ``"both"``, or the one half to run (the other is then absent from the record).
        merge: a ``blas_wall.json`` of the same mode made by another run (``blas`` the other
            half, same machine): its halves that this run does not make are copied in, and
            ``merged_from`` names it (its commit, BLAS and load).

    Returns:
        The payload; ``payload["runs"][name]`` holds ``reference`` and ``optimised`` (each as
        :func:`_run_child` returns) and ``speedup`` (reference / optimised wall) where both ran.
    """
    if blas not in BLAS_CHOICES:
        raise ValueError(f"blas must be one of {BLAS_CHOICES}, got {blas!r}")
    reference = reference_blas_env()
    halves = [("reference", reference), ("optimised", dict(os.environ))]
    halves = [(label, env) for label, env in halves if blas in ("both", label)]
    merged = _read_merge(merge, mode) if merge is not None else None
    runs: dict[str, dict] = {}
    for name, bench_mode, options in cfg:
        row: dict = {"mode": bench_mode, "options": list(options)}
        for label, env in halves:
            if env is None:
                row[label] = {"error": "the reference BLAS (libblas3, liblapack3) is not installed"}
                continue
            folder = Path(out) / "blas_wall" / f"{name}_{label}"
            folder.mkdir(parents=True, exist_ok=True)
            for old in folder.glob("*.json"):
                old.unlink()
            log.info("blas_wall: %s --%s on the %s BLAS", name, bench_mode, label)
            row[label] = _run_child(name, bench_mode, options, folder, env, timeout_s)
            log.info("blas_wall: %s on the %s BLAS: %s", name, label, row[label])
        for label in ("reference", "optimised"):
            if label not in row and merged is not None and label in merged["runs"].get(name, {}):
                row[label] = {**merged["runs"][name][label], "merged": True}
        ref, opt = row.get("reference"), row.get("optimised")
        if ref and opt and "error" not in ref and "error" not in opt:
            row["speedup"] = ref["wall_s"] / max(opt["wall_s"], 1e-12)
            if ref["benchmark_wall_s"] and opt["benchmark_wall_s"]:
                row["benchmark_speedup"] = ref["benchmark_wall_s"] / opt["benchmark_wall_s"]
        runs[name] = row
    payload = {
        "blas": blas,
        "runs": runs,
        "machine_note": "2 shared cores; the two runs of a benchmark are sequential",
    }
    if merged is not None:
        env = merged.get("environment", {})
        payload["merged_from"] = {
            "path": str(merge),
            "blas": merged.get("blas", "both"),
            "commit": env.get("commit"),
            "load_average_1min": env.get("load_average_1min"),
        }
    return payload


BENCHMARK = register(
    Benchmark("blas_wall", __doc__, MODES, measure, arguments=_arguments, needs_out=True)
)
run = BENCHMARK.run
