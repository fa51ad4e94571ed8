"""Step times of the explicit strategies against an earlier commit, in one run (issue 43).

Scene: rings at the BFEMP paper's resolution (``benchmarks.catalogue``: MPM grid dx = 0.1 m,
ppc = 9, 19,796 particles; FEM ring h = 0.13 m, 1,714 nodes), each strategy on the rings it
couples: ``augury``, ``lr`` and ``two_stage`` on the MPM ring and the FEM ring
(``rings_scene``), ``single_field`` on both rings as particles (``mpm_rings_scene``, 39,592
particles; it does not couple MPM with deformable FEM). ``bfemp.Simulation`` at ``dt="auto"``
(the explicit stable step), the strategies' defaults, so a step is what a user's script pays:
the strategy's step and the run's per-step diagnostics. The rings are 2 m apart at 40 m/s
each: the timed steps (after ``warmup`` steps) come before contact, where ``two_stage`` is its
stage 1 (the explicit elastic step) and ``augury`` applies its contact operator to every
particle (``region="all"``).

Before and after: the same measurement runs in subprocesses on two source trees, the working
tree and ``baseline`` (a git revision, unpacked once with ``git archive`` under ``results/``,
with its own numba cache), in alternating rounds; each keeps its best round per strategy.
``same_end_state``: the two trees' particle and FEM-node centres of mass after the timed steps
agree to the last bit (the speed work changes no physics). Timings are recorded, never asserted.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

from benchmarks.catalogue import RINGS_DISCRETISATION
from benchmarks.common import git_commit
from benchmarks.runner import Benchmark, name_unless, register

NAME = "perf_strategies"
ROOT = Path(__file__).resolve().parents[1]
STRATEGIES = ("single_field", "augury", "lr", "two_stage")
#: the commit before issue 43's work on the explicit engine
BASELINE = "554ac83"
MODES = {
    "full": dict(rings=RINGS_DISCRETISATION["full"], warmup=3, steps=30, rounds=3),
    "quick": dict(rings=RINGS_DISCRETISATION["quick"], warmup=1, steps=3, rounds=1),
}

#: what each subprocess runs: public API only, so that an older tree runs it as well
_SCRIPT = """
import json, sys, time, warnings
warnings.simplefilter("ignore")
import numpy as np
import bfemp
from benchmarks.catalogue import mpm_rings_scene, rings_scene
cfg = json.loads(sys.argv[1])
out = {}
for strategy in cfg["strategies"]:
    scene = (mpm_rings_scene if strategy == "single_field" else rings_scene)(cfg["rings"])
    sim = bfemp.Simulation(scene, strategy=strategy, dt="auto")
    for _ in range(cfg["warmup"]):
        sim.step()
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(cfg["steps"]):
        sim.step()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    m, x = sim.model, sim.state
    out[strategy] = {
        "s_per_step": wall / cfg["steps"],
        "cpu_s_per_step": cpu / cfg["steps"],
        "dt_s": sim.dt,
        "particles": int(m.n_particles),
        "fem_nodes": int(m.n_fem_nodes),
        "com_particles": (m.mpm_mass @ x.mpm_x / m.mpm_mass.sum()).tolist(),
        "com_fem": (m.fem_mass @ x.fem_x / m.fem_mass.sum()).tolist() if m.n_fem_nodes else [],
    }
print("RESULT " + json.dumps(out))
"""


def baseline_tree(revision: str) -> Path:
    """The source tree of ``revision`` in ``results/`` (unpacked once by ``git archive``)."""
    tree = ROOT / "results" / f"_tree_{revision}"
    if not (tree / "bfemp").is_dir():
        tree.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile() as archive:
            git = ["git", "-C", str(ROOT), "archive", revision]
            subprocess.run(git, stdout=archive, check=True)
            archive.seek(0)
            with tarfile.open(fileobj=archive) as tar:
                tar.extractall(tree, filter="data")
    return tree


def time_tree(tree: Path, cfg: dict) -> dict:
    """Run ``_SCRIPT`` on the source tree ``tree`` (its own numba cache); its result."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(tree / ".numba_cache")}
    job = subprocess.run(
        [sys.executable, "-c", _SCRIPT, json.dumps(cfg)],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    lines = [line for line in job.stdout.splitlines() if line.startswith("RESULT ")]
    if job.returncode != 0 or not lines:
        raise RuntimeError(f"{NAME}: the run on {tree} failed:\n{job.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT ") :])


def measure(mode: str, cfg: dict, baseline: str = BASELINE) -> dict:
    """Alternating rounds on the baseline tree and the working tree (module docstring)."""
    run_cfg = {**cfg, "strategies": list(STRATEGIES)}
    trees = {"before": baseline_tree(baseline), "after": ROOT}
    best: dict[str, dict] = {}
    for _ in range(cfg["rounds"]):
        for label, tree in trees.items():
            for strategy, row in time_tree(tree, run_cfg).items():
                kept = best.setdefault(label, {}).get(strategy)
                if kept is None or row["s_per_step"] < kept["s_per_step"]:
                    best[label][strategy] = row
    rows = {}
    for strategy in STRATEGIES:
        before, after = best["before"][strategy], best["after"][strategy]
        same = all(before[k] == after[k] for k in ("com_particles", "com_fem", "dt_s"))
        rows[strategy] = {
            "before": before,
            "after": after,
            "speedup": before["s_per_step"] / after["s_per_step"],
            "same_end_state": same,
        }
    return {
        "baseline": baseline,
        "after_commit": git_commit(),
        "strategies": rows,
        "same_end_state": all(r["same_end_state"] for r in rows.values()),
        "parameters": {**cfg, "numba_threads": os.environ.get("NUMBA_NUM_THREADS", "default")},
    }


_STEM = name_unless("full", NAME)
BENCHMARK = register(Benchmark(NAME, __doc__, MODES, measure, record=_STEM, timings="s_per_step"))
run = BENCHMARK.run
