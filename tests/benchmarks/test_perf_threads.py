"""perf_threads: every thread combination runs in its own process with the pools it was given."""

import os

from benchmarks import perf_threads


def test_each_combination_runs_with_its_own_pool_sizes(tmp_path):
    rec = perf_threads.run("smoke", tmp_path)
    cores = os.cpu_count() or 1
    assert (tmp_path / "perf_threads_smoke.json").exists()
    for name, row in rec["rows"].items():
        assert set(row["step_s"]) == {"mpm3d", "fem3d"}
        assert all(t > 0.0 for t in row["step_s"].values())
        if name != "default":
            numba_threads = int(name.split("numba")[1])
            assert row["numba_threads"] == numba_threads
            if row["blas_threads"] is not None:  # None: the reference BLAS, one thread by nature
                assert row["blas_threads"] == int(name[4 : name.index("_")])
    # the default leaves both pools at the core count
    assert rec["rows"]["default"]["numba_threads"] == cores
    assert set(rec["fastest"]) == {"mpm3d", "fem3d"}
    assert all(r >= 1.0 for r in rec["default_over_fastest"].values())
