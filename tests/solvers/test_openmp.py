"""CHOLMOD's own OpenMP loops are bounded (solvers.openmp): a factorisation inside the bound
starts no OpenMP threads and switches context a few times, where CHOLMOD's compiled-in count
(the control, ``BFEMP_CHOLMOD_OPENMP_THREADS=0``) starts its pool and switches thousands of
times; the thread settings of the caller come back after the block."""

import json
import os
import subprocess
import sys

import pytest

from solvers import linear, openmp

needs_cholmod = pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")

#: threads and context switches of the process around two CHOLMOD factorisations
_PROBE = """
import json, os, resource
import numpy as np, scipy.sparse as sp
from solvers.linear import CholmodSolver
from solvers.openmp import openmp_report

def threads():
    return len(os.listdir("/proc/self/task"))

def switches():
    # voluntary only: a thread that sleeps on a futex; preemption by other load is involuntary
    return resource.getrusage(resource.RUSAGE_SELF).ru_nvcsw

m = 160
t = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
eye = sp.identity(m)
A = sp.csc_matrix(sp.kron(t, eye) + sp.kron(eye, t) + 1e-3 * sp.identity(m * m))
A = sp.csc_matrix(sp.kron(A, np.array([[2.0, 0.5], [0.5, 2.0]])))
A.sort_indices()
solver = CholmodSolver(mode="supernodal")
b = np.ones(A.shape[0])
n0 = threads()
solver.solve(A, b)  # the symbolic analysis: outside the count of switches
s0 = switches()
x = solver.solve(A, b)
solver.solve(A, b)
n1, s1 = threads(), switches()
print(json.dumps({"new_threads": n1 - n0, "switches": s1 - s0, "residual":
    float(np.abs(A @ x - b).max()), "report": openmp_report()}))
"""


def _probe(threads: str) -> dict:
    env = {**os.environ, openmp.ENV_VARIABLE: threads, "OMP_WAIT_POLICY": "PASSIVE"}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@needs_cholmod
def test_bounded_factorisation_starts_no_openmp_threads_and_the_control_does():
    bounded, control = _probe("1"), _probe("0")
    if not bounded["report"]["runtime"]:
        pytest.skip("CHOLMOD links no OpenMP runtime here: nothing to bound")
    assert bounded["report"]["cholmod_openmp_threads"] == 1
    assert control["report"] == {
        "runtime": bounded["report"]["runtime"],
        "cholmod_openmp_threads": 0,
    }
    assert bounded["residual"] < 1e-8 and control["residual"] < 1e-8
    assert bounded["new_threads"] == 0
    # the control: CHOLMOD's compiled-in count starts OpenMP threads and wakes them per
    # supernode (measured: 3 threads, 28,000 switches in two factorisations, against 9 bounded)
    assert control["new_threads"] >= 1
    assert control["switches"] > 5 * max(bounded["switches"], 100)


def test_bound_gives_the_callers_settings_back():
    lib = openmp._load_runtime()
    if lib is None:
        pytest.skip("no OpenMP runtime in this process")
    original = lib.omp_get_max_threads()
    lib.omp_set_num_threads(3)
    try:
        before = (lib.omp_get_dynamic(), lib.omp_get_max_threads())
        with openmp.bounded_openmp(1):
            assert lib.omp_get_dynamic() == 1 and lib.omp_get_max_threads() == 1
        assert (lib.omp_get_dynamic(), lib.omp_get_max_threads()) == before
    finally:
        lib.omp_set_num_threads(original)


@pytest.mark.parametrize("raw", ["-1", "two", "1.5"])
def test_bad_thread_count_is_named(monkeypatch, raw):
    monkeypatch.setenv(openmp.ENV_VARIABLE, raw)
    with pytest.raises(ValueError, match=openmp.ENV_VARIABLE):
        openmp.cholmod_openmp_threads()


def test_thread_count_default_and_off(monkeypatch):
    monkeypatch.delenv(openmp.ENV_VARIABLE, raising=False)
    assert openmp.cholmod_openmp_threads() == 1
    monkeypatch.setenv(openmp.ENV_VARIABLE, "0")
    assert openmp.cholmod_openmp_threads() == 0
    assert "as compiled" in openmp.format_openmp()
