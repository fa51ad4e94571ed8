"""Contact broad phase: numba spatial hash vs python-fcl BVH vs brute force (issue C3).

Cases (full mode; quick mode has 10x fewer points and simplices):
- ``2d``: 100k points uniform in the unit square vs 5k segments, the boundaries of 50 circles
  (radius 0.02-0.05 m, 100 segments each);
- ``3d``: 100k points uniform in the unit cube vs 20k triangles, the surfaces of 20 UV spheres
  (radius 0.05-0.12 m, 1000 triangles each).

Each case runs two queries: ``barrier`` (static, inflation = dhat = 1e-3 m) and ``ccd`` (points
and vertices moved by a random displacement of up to 2e-3 m per axis, swept boxes, no inflation).
Recorded per query: candidate pairs, seconds of ``hash`` (median and minimum of 5 after a warm-up
call that loads the numba kernels; the 2-core test machine is shared, hence the minimum) and
``fcl`` (one call: building the trees, collide, callback), and brute force on the first
``brute_points`` points with its extrapolation to all points; the pair
sets are checked equal (fcl vs hash in full, brute vs hash on the subset). The faster of hash and
fcl is recorded as ``auto_choice``; ``geometry.broadphase`` uses it for ``method="auto"``.
"""

from __future__ import annotations

import statistics
from pathlib import Path

import numpy as np

from benchmarks._phases import timed, wall_times
from benchmarks.runner import Benchmark, register
from bfemp.plotting import plot_bars
from geometry.broadphase import point_simplex_candidates

CASES = {
    "full": {
        "2d": dict(points=100_000, bodies=50, resolution=(100,)),
        "3d": dict(points=100_000, bodies=20, resolution=(20, 25)),
    },
    "quick": {
        "2d": dict(points=10_000, bodies=50, resolution=(10,)),
        "3d": dict(points=10_000, bodies=20, resolution=(5, 10)),
    },
}
DHAT = 1e-3
MOTION = 2e-3
BRUTE_POINTS = 2000


def _circles(rng: np.random.Generator, bodies: int, n_seg: int) -> tuple[np.ndarray, np.ndarray]:
    centre = rng.uniform(0.1, 0.9, (bodies, 1, 2))
    radius = rng.uniform(0.02, 0.05, (bodies, 1, 1))
    theta = np.linspace(0.0, 2.0 * np.pi, n_seg, endpoint=False)[None, :, None]
    ring = np.concatenate([np.cos(theta), np.sin(theta)], axis=2)
    vertices = (centre + radius * ring).reshape(-1, 2)
    local = np.stack([np.arange(n_seg), (np.arange(n_seg) + 1) % n_seg], axis=1)
    segments = (local[None] + n_seg * np.arange(bodies)[:, None, None]).reshape(-1, 2)
    return vertices, segments


def _spheres(
    rng: np.random.Generator, bodies: int, n_theta: int, n_phi: int
) -> tuple[np.ndarray, np.ndarray]:
    theta = np.linspace(0.0, np.pi, n_theta + 1)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, n_phi, endpoint=False)[None, :]
    unit = np.stack(
        np.broadcast_arrays(
            np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)
        ),
        axis=-1,
    ).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_theta), np.arange(n_phi), indexing="ij")
    v00, v01 = i * n_phi + j, i * n_phi + (j + 1) % n_phi
    v10, v11 = v00 + n_phi, v01 + n_phi
    local = np.concatenate(
        [np.stack([v00, v10, v11], -1).reshape(-1, 3), np.stack([v00, v11, v01], -1).reshape(-1, 3)]
    )
    centre = rng.uniform(0.15, 0.85, (bodies, 1, 3))
    radius = rng.uniform(0.05, 0.12, (bodies, 1, 1))
    vertices = (centre + radius * unit[None]).reshape(-1, 3)
    n_vert = unit.shape[0]
    triangles = (local[None] + n_vert * np.arange(bodies)[:, None, None]).reshape(-1, 3)
    return vertices, triangles


def _query(points, vertices, simplices, kwargs: dict) -> dict:
    def call(method: str, pts=points) -> np.ndarray:
        return point_simplex_candidates(pts, vertices, simplices, method=method, **kwargs)

    pairs = call("hash")  # warm-up: loads (or compiles) the numba kernels
    t_hash = wall_times(lambda: call("hash"), 5)
    pairs_fcl, t_fcl = timed(lambda: call("fcl"))
    n_sub = min(BRUTE_POINTS, points.shape[0])
    sub_kwargs = {k: v[:n_sub] if k == "points_end" else v for k, v in kwargs.items()}
    brute = point_simplex_candidates  # on the first n_sub points
    pairs_brute, t_brute = timed(
        lambda: brute(points[:n_sub], vertices, simplices, method="brute", **sub_kwargs)
    )
    return {
        "pairs": int(pairs.shape[0]),
        "hash_s": statistics.median(t_hash),
        "hash_min_s": min(t_hash),
        "fcl_s": t_fcl,
        "fcl_over_hash": t_fcl / statistics.median(t_hash),
        "brute_points": n_sub,
        "brute_subset_s": t_brute,
        "brute_estimated_full_s": t_brute * points.shape[0] / n_sub,
        "fcl_equals_hash": bool(np.array_equal(pairs, pairs_fcl)),
        "brute_equals_hash_on_subset": bool(
            np.array_equal(pairs[pairs[:, 0] < n_sub], pairs_brute)
        ),
    }


def _measure(dim: int, points: int, bodies: int, resolution: tuple[int, ...]) -> dict:
    rng = np.random.default_rng(2024 + dim)
    if dim == 2:
        vertices, simplices = _circles(rng, bodies, *resolution)
    else:
        vertices, simplices = _spheres(rng, bodies, *resolution)
    pts = rng.random((points, dim))
    static = {"inflation": DHAT}
    swept = {
        "points_end": pts + rng.uniform(-MOTION, MOTION, pts.shape),
        "vertices_end": vertices + rng.uniform(-MOTION, MOTION, vertices.shape),
    }
    return {
        "dim": dim,
        "points": points,
        "simplices": int(simplices.shape[0]),
        "dhat_m": DHAT,
        "motion_m": MOTION,
        "barrier": _query(pts, vertices, simplices, static),
        "ccd": _query(pts, vertices, simplices, swept),
    }


def measure(mode: str, cases: dict) -> dict:
    """Both cases of ``mode``: candidates and times of every method, and the auto choice."""
    cases = {name: _measure(2 if name == "2d" else 3, **cfg) for name, cfg in cases.items()}
    queries = [q for case in cases.values() for q in (case["barrier"], case["ccd"])]
    hash_total = sum(q["hash_s"] for q in queries)
    fcl_total = sum(q["fcl_s"] for q in queries)
    return {
        "cases": cases,
        "auto_choice": "hash" if hash_total <= fcl_total else "fcl",
        "all_methods_agree": all(
            q["fcl_equals_hash"] and q["brute_equals_hash_on_subset"] for q in queries
        ),
    }


def plot(payload: dict, png: Path) -> None:
    """Seconds per query and method (log scale)."""
    labels, groups = [], {"hash": [], "fcl": [], "brute (extrapolated)": []}
    for name, case in payload["cases"].items():
        for query in ("barrier", "ccd"):
            q = case[query]
            labels.append(f"{name} {query}\n{case['simplices']} simpl.")
            groups["hash"].append(q["hash_s"])
            groups["fcl"].append(q["fcl_s"])
            groups["brute (extrapolated)"].append(q["brute_estimated_full_s"])
    plot_bars(
        labels,
        groups,
        png,
        ylabel="seconds",
        title="Broad phase: spatial hash vs fcl BVH vs brute force",
        logy=True,
    )


BENCHMARK = register(Benchmark("perf_broadphase", __doc__, CASES, measure, plot=plot))
run = BENCHMARK.run
