"""numba runs on TBB's pool where the wheel is installed (solvers.numba_threads), the user's
``NUMBA_THREADING_LAYER`` wins, and the layers give the same results bit for bit: explicit
``augury`` steps and implicit ``barrier`` steps of the colliding rings, whose kernels
would differ in the last bits if a reduction's split followed the scheduler."""

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

#: the layer numba ran on and a digest of the end states of both strategies
_PROBE = """
import hashlib, json
import numba
import bfemp
from bfemp.demo import colliding_rings_scene
from solvers.numba_threads import numba_threads_report

digest = hashlib.sha256()
for strategy, dt, steps in (("augury", "auto", 6), ("barrier", 2e-3, 1)):
    sim = bfemp.Simulation(colliding_rings_scene(), strategy=strategy, dt=dt)
    for _ in range(steps):
        sim.step()
    for array in (sim.state.mpm_x, sim.state.mpm_v, sim.state.mpm_F, sim.state.fem_x):
        digest.update(array.tobytes())
print(json.dumps({"report": numba_threads_report(), "digest": digest.hexdigest()}))
"""

#: where the tbb wheel is a dependency (pyproject.toml), so installed with bfemp
TBB_PLATFORM = sys.platform.startswith("linux") and platform.machine() == "x86_64"


def _probe(layer: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    if layer is not None:
        env["NUMBA_THREADING_LAYER"] = layer
    env["NUMBA_NUM_THREADS"] = "2"  # two threads split the work, on any machine
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not TBB_PLATFORM, reason="tbb is a dependency on x86-64 Linux only")
def test_tbb_by_default_omp_on_request_and_the_same_results():
    default = _probe(None)
    assert default["report"]["layer"] == "tbb"
    assert default["report"]["tbb_library"] == str(Path(sys.prefix) / "lib" / "libtbb.so.12")
    omp = _probe("omp")
    assert omp["report"]["layer"] == "omp"
    assert omp["report"]["why_not_tbb"] == "NUMBA_THREADING_LAYER=omp"
    assert default["digest"] == omp["digest"]


def test_report_names_the_layer_without_a_kernel_run():
    code = (
        "import json, solvers; from solvers.numba_threads import numba_threads_report;"
        "print(json.dumps(numba_threads_report()))"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    report = json.loads(out.stdout)
    assert report["layer"] in (("tbb",) if TBB_PLATFORM else ("tbb", "omp", "workqueue"))
    assert report["threads"] >= 1
