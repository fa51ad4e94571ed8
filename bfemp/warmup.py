"""Compile the numba kernels ahead of the first real run (``bfemp warmup``).

The kernels are ``njit(cache=True)`` (see :mod:`bfemp._numba_cache`): a run that finds no cached
kernel compiles every one it calls, which costs minutes on 2 cores (``bfemp demo``: 318 s with
an empty cache against 40 s with a warm one). Two processes that start on an empty cache at once
(the test workers, two runs side by side) both compile the same kernels. ``warm_up`` compiles
them once, in parallel over processes: it runs small scenes that between them call the kernels
of every strategy, with and without friction, FEM-FEM contact, in 2D and 3D:

- every regression reference of a folder (``references/``: barrier 2D and 3D, with friction,
  FEM-FEM, augury, lr, two_stage, single_field), for its stored number of steps;
- the example scenes ``cube_on_plate_3d`` (3D MPM on FEM, in contact) and ``rings`` (the demo), in
  their quick forms, and 3 steps of the first under each explicit strategy (references are 2D);
- after each scene, the parallel builds of the kernels it called (small scenes stay serial).

Nothing is compared or written but the kernel cache: the references are checked by ``bfemp
regress``. ``make setup`` runs it last, so ``make demo`` and ``make test`` find the cache warm.
"""

from __future__ import annotations

import logging
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

from bfemp.errors import SceneError

__all__ = ["WarmupJob", "warm_up", "warmup_jobs"]

log = logging.getLogger(__name__)

_ROOT = Path(__file__).resolve().parents[1]
#: the example scenes run in their quick forms, besides the references
EXAMPLES = ("cube_on_plate_3d", "rings")
#: started first, one per process: a 3D and a 2D scene share few kernels, so two processes on an
#: empty cache do not compile the same ones at once (the others find most of theirs cached)
FIRST = ("barrier_3d", "rings")
#: run on ``cube_on_plate_3d`` for 3 steps: their 3D kernels compiled in the first test worker
EXPLICIT_3D = ("augury", "lr", "two_stage")


@dataclass(frozen=True)
class WarmupJob:
    """One scene to run: a regression reference (``steps`` steps) or a quick example."""

    name: str
    scene_file: str
    #: steps to run; None: the scene's quick ``t_end``
    steps: int | None
    #: a strategy run instead of the file's, at ``dt="auto"`` and its default transfer
    strategy: str | None = None


def warmup_jobs(references: str | os.PathLike | None = None) -> list[WarmupJob]:
    """The scenes :func:`warm_up` runs: the references in ``references`` (default the checkout's
    ``references/``) and the quick :data:`EXAMPLES` found beside them in ``examples/``."""
    from bfemp import regress

    folder = Path(references) if references is not None else _ROOT / "references"
    jobs = [
        WarmupJob(ref.name, str(ref.scene_file), ref.steps)
        for ref in regress.find_references(folder)
    ]
    examples = folder.resolve().parent / "examples"
    jobs += [
        WarmupJob(name, str(examples / f"{name}.toml"), None)
        for name in EXAMPLES
        if (examples / f"{name}.toml").is_file()
    ]
    cube = examples / "cube_on_plate_3d.toml"
    jobs += [WarmupJob(f"{cube.stem}:{s}", str(cube), 3, s) for s in EXPLICIT_3D if cube.is_file()]
    if not jobs:
        raise SceneError(f"no scene to warm up with in {folder}", hint="give --dir DIR")
    rank = {name: k for k, name in enumerate(FIRST)}
    return sorted(jobs, key=lambda job: rank.get(job.name, len(FIRST)))


def _run_job(job: WarmupJob) -> float:
    """Run ``job`` here, then the parallel builds of the kernels it called; its wall time (s)."""
    from bfemp import scenefile
    from bfemp._njit import compile_parallel_builds
    from bfemp.simulation import Simulation

    start = time.perf_counter()
    sf = scenefile.load(job.scene_file)
    if job.strategy is None:
        sim = Simulation.from_file(sf)
    else:
        sim = Simulation(sf.build_model(), strategy=job.strategy, dt="auto")
    if job.steps is None:
        sim.run(sf.run_settings(quick=True)["t_end"], progress=False)
    else:
        for _ in range(job.steps):
            sim.step()
    compile_parallel_builds()
    return time.perf_counter() - start


def warm_up(
    references: str | os.PathLike | None = None, processes: int | None = None
) -> dict[str, float]:
    """Run :func:`warmup_jobs` in ``processes`` worker processes (default: the CPU count, at
    most the number of jobs) so that numba compiles and caches their kernels.

    Returns:
        job name -> its wall time (s), including the compilation it did.

    Raises:
        ValueError: ``processes`` below 1.
        SceneError: no scene found; a job that fails raises its own error.
    """
    if processes is None:
        processes = os.cpu_count() or 1
    if not isinstance(processes, int) or processes < 1:
        raise ValueError(f"processes must be an integer >= 1, got {processes!r}")
    jobs = warmup_jobs(references)
    processes = min(processes, len(jobs))
    walls: dict[str, float] = {}
    # spawn, not fork: a forked child would inherit this process's numba and OpenMP threads
    with ProcessPoolExecutor(processes, mp_context=get_context("spawn")) as pool:
        futures = {pool.submit(_run_job, job): job for job in jobs}
        for done, future in enumerate(as_completed(futures), 1):
            job = futures[future]
            walls[job.name] = future.result()
            log.info("warm-up %d/%d: %s in %.1f s", done, len(jobs), job.name, walls[job.name])
    return walls
