"""bfemp warmup: the scenes it runs cover every strategy in 2D and 3D, and a run fills an empty
numba cache with the kernels the scenes call."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

from bfemp import regress
from bfemp.warmup import FIRST, warm_up, warmup_jobs

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def test_jobs_are_every_reference_and_the_quick_examples_3d_and_2d_first():
    jobs = warmup_jobs()
    names = [j.name for j in jobs]
    refs = {r.name for r in regress.find_references(ROOT / "references")}
    assert refs <= set(names) and {"cube_on_plate_3d", "rings"} <= set(names)
    assert names[: len(FIRST)] == list(FIRST)
    scenes = [tomllib.loads(Path(j.scene_file).read_text()) for j in jobs]
    strategies = {s["simulation"].get("strategy", "barrier") for s in scenes}
    assert {"barrier", "augury", "lr", "two_stage", "single_field"} <= strategies
    # every explicit strategy in 3D too, on the 3D example
    explicit_3d = {j.strategy for j in jobs if j.name.startswith("cube_on_plate_3d:")}
    assert explicit_3d == {"augury", "lr", "two_stage"}


def test_bad_process_count_and_empty_folder_are_named(tmp_path):
    with pytest.raises(ValueError, match="processes must be an integer >= 1"):
        warm_up(processes=0)
    with pytest.raises(Exception, match="no scene to warm up with"):
        warm_up(tmp_path)


def test_warmup_fills_an_empty_kernel_cache(tmp_path):
    refs = tmp_path / "references"
    refs.mkdir()
    for suffix in (".toml", ".npz", ".json"):
        shutil.copy(ROOT / "references" / f"single_field_2d{suffix}", refs)
    cache = tmp_path / "cache"
    env = {"NUMBA_CACHE_DIR": str(cache), "PATH": "/usr/bin:/bin"}
    done = subprocess.run(
        [sys.executable, "-m", "bfemp", "warmup", "--dir", str(refs), "--processes", "1"],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "1 scenes" in done.stdout and str(cache) in done.stdout
    assert len(list(cache.rglob("*.nbi"))) >= 5  # the explicit MPM kernels, compiled and kept


_MISSES = """
import gc, sys
from numba.core.dispatcher import Dispatcher
from bfemp.warmup import WarmupJob, _run_job
_run_job(WarmupJob("probe", sys.argv[1], 2))
for obj in gc.get_objects():
    if isinstance(obj, Dispatcher) and obj.stats.cache_misses:
        module = obj.py_func.__module__
        if module.split(".")[0] in ("bfemp", "geometry", "solvers"):
            print(module, obj.py_func.__qualname__)
"""


def test_a_second_process_finds_every_kernel_it_calls_in_the_cache():
    """The kernels of an MPM-on-FEM barrier step with friction (MPM and FEM Hessians, barrier,
    friction, CCD) compile in the first process at most, never again in the next one. Fails
    when a kernel's cache entry cannot be found again: a closure over another kernel (numba
    keys it by the pickled closure cells, which differ in every process) compiled anew in
    every process (``_hessian_kernels`` until 2026-12-07, 3 s in 2D and 8 s in 3D)."""
    scene = str(ROOT / "references" / "barrier_friction_2d.toml")
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-c", _MISSES, scene],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=600,
        )
        assert done.returncode == 0, done.stderr
    assert done.stdout == "", f"compiled again in a second process:\n{done.stdout}"
