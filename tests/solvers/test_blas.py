"""Which BLAS CHOLMOD got: classification of library paths, the maps reader, the report."""

import logging

import numpy as np
import pytest

from solvers import blas, linear


@pytest.mark.parametrize(
    ("path", "name"),
    [
        ("/usr/lib/x86_64-linux-gnu/openblas-pthread/libopenblasp-r0.3.21.so", "openblas"),
        ("/usr/lib/x86_64-linux-gnu/openblas-pthread/libblas.so.3", "openblas"),
        ("/usr/lib/x86_64-linux-gnu/blas/libblas.so.3.11.0", "reference"),
        ("/opt/intel/mkl/lib/libmkl_rt.so.2", "mkl"),
        ("/usr/lib/x86_64-linux-gnu/blis-openmp/libblas.so.3", "blis"),
        ("/usr/lib/x86_64-linux-gnu/lapack/liblapack.so.3", None),
        ("/venv/lib/python3.11/site-packages/numpy.libs/libscipy_openblas64_-ab.so", None),
        ("/usr/lib/x86_64-linux-gnu/libc.so.6", None),
    ],
)
def test_classify_blas(path, name):
    assert blas.classify_blas(path) == name


def _maps(tmp_path, *paths):
    lines = [f"7f00-7f01 r-xp 00000000 08:01 1 {p}" for p in paths]
    f = tmp_path / "maps"
    f.write_text("\n".join(["7f00-7f01 rw-p 00000000 00:00 0 ", *lines]) + "\n")
    return str(f)


@pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")
def test_cholmod_blas_reads_the_mapped_system_blas(tmp_path):
    ref = "/usr/lib/x86_64-linux-gnu/blas/libblas.so.3.11.0"
    wheel = "/v/site-packages/numpy.libs/libscipy_openblas64_-x.so"
    info = blas.cholmod_blas(_maps(tmp_path, wheel, ref))
    assert info.name == "reference" and not info.optimised
    assert "reference" in info.describe()
    # numpy's bundled OpenBLAS is not what CHOLMOD runs on
    assert blas.cholmod_blas(_maps(tmp_path, wheel)).name == "unknown"
    opb = "/usr/lib/x86_64-linux-gnu/openblas-pthread/libopenblasp-r0.3.21.so"
    assert blas.cholmod_blas(_maps(tmp_path, wheel, opb)).optimised


@pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")
def test_this_process_names_a_blas():
    info = blas.cholmod_blas()
    assert info.name in ("openblas", "mkl", "blis", "atlas", "reference")
    assert info.path.startswith("/")


def test_reference_blas_is_reported_once_as_a_warning(monkeypatch, caplog):
    ref = blas.BlasInfo("reference", "/usr/lib/x86_64-linux-gnu/blas/libblas.so.3", None)
    monkeypatch.setattr(blas, "cholmod_blas", lambda: ref)
    monkeypatch.setattr(blas, "_reported", None)
    with caplog.at_level(logging.INFO, logger="solvers.blas"):
        assert blas.report_cholmod_blas_once() is ref
        assert blas.report_cholmod_blas_once() is ref
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert "reference BLAS" in warnings[0].getMessage()
    assert "libopenblas0-pthread" in warnings[0].getMessage()


def test_set_blas_threads_rejects_bad_counts():
    with pytest.raises(ValueError, match="BLAS threads"):
        blas.set_blas_threads(0)


@pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")
def test_the_libblas_soname_wins_over_an_mkl_mapped_by_pypardiso(tmp_path):
    shim = "/usr/lib/x86_64-linux-gnu/openblas-pthread/libblas.so.3"
    mkl = "/venv/lib/libmkl_rt.so.2"
    assert blas.cholmod_blas(_maps(tmp_path, mkl, shim)).name == "openblas"
    ref = "/usr/lib/x86_64-linux-gnu/blas/libblas.so.3.11.0"
    assert blas.cholmod_blas(_maps(tmp_path, mkl, ref)).name == "reference"


def _wheel_blas_threads():
    threadpoolctl = pytest.importorskip("threadpoolctl")
    counts = [
        pool["num_threads"]
        for pool in threadpoolctl.threadpool_info()
        if pool["user_api"] == "blas" and any(d in pool["filepath"] for d in blas._WHEEL_DIRS)
    ]
    return counts


def test_newton_runs_the_wheel_blas_on_one_thread_and_gives_the_pools_back():
    # numpy's own OpenBLAS spun beside CHOLMOD's and made back-solves 8x slower (issue 13)
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from solvers.newton import minimize
    from tests.solvers.test_newton import Quadratic

    if not _wheel_blas_threads():
        pytest.skip("no BLAS bundled in the numpy/scipy wheels in this process")
    seen = []

    class Recording(Quadratic):
        def value(self, x):
            seen.append(_wheel_blas_threads())
            return super().value(x)

    A = np.diag([2.0, 3.0, 4.0])
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        before = _wheel_blas_threads()
        assert set(before) == {2}  # the control: outside Newton the pools keep their size
        res = minimize(Recording(A, np.ones(3)), np.zeros(3))
        after = _wheel_blas_threads()
    assert res.success
    assert seen and all(set(counts) == {1} for counts in seen)
    assert after == before
