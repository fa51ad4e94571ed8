"""Barrier and CCD throughput against the ipctk library, and a Newton-iteration breakdown (rings).

``python -m benchmarks perf_contact``. Three parts (method notes: ``records/perf_contact.md``):

1. **Barrier** (value + gradient + PSD-projected Hessian) on one particle-segment (2D) and one
   particle-triangle (3D) configuration, through bfemp's ``BarrierTerm`` and ipctk's
   ``BarrierPotential`` on the same collision points. A prescribed FEM body (2D: disk of radius
   1 m, h = 0.05 m, 120 boundary segments; 3D: unit box, h = 0.1 m, 1200 boundary triangles) and
   MPM particles at distances uniform in [0.05, 0.95] dhat (dhat = 1e-3 m) above facet interiors,
   at least 2 dhat from their edges: one facet-interior pair per particle in both libraries.
   Pairs: 50k (full) / 5k (quick); MPM grid dx 0.05 m (2D) / 0.1 m (3D); particle volume
   (dx / 2)^d. ipctk's collision mesh takes bfemp's collision points and its affine collision
   map (the particles' B-spline weights, BFEMP eq. 29) as ``displacement_map``. Levels timed:
   ``kernel`` (bfemp's pointwise kernels on the pair arrays: no pair search, chain rule or
   scatter), ``collision`` (ipctk, w.r.t. the collision vertices, assembled) and ``dofs`` (both,
   w.r.t. the simulation unknowns, assembled); ``barrier_pairs_per_s`` = active pairs / ``dofs``
   time. The pair search is timed apart and also added (``*_with_pair_search``). ``agreement``:
   the same active pairs; ipctk's energy equals ``stiffness * sum -(d^2 - dhat^2)^2 ln(d^2 /
   dhat^2)`` over bfemp's pair distances; ipctk's vertex gradient equals bfemp's point force
   times ``stiffness b_ipc'(d^2) 2 d / (omega b'(d))``.

2. **CCD**: every grid node translated by 3 dhat along -x (2D) / -z (3D): bfemp
   ``max_step_size`` against ipctk ``compute_collision_free_stepsize``, each with its broad phase;
   both must not exceed the exact first time of impact (brute force over every particle and
   facet).

3. **Rings breakdown**: the ``rings`` scene at its quick / full resolution, Newmark, dt = 2e-4 s,
   APIC, tol 1e-6 m/s, stepped to 5 steps after the first active contact pair (t ~ 0.025 s);
   there one step's phases (``report.timings``, the fastest of ``repeats`` runs, a fresh linear
   solver each), the per-iteration assembly and CHOLMOD phases (``benchmarks._phases``), the
   broad phase, the pair search and the CCD step bound along the inertial predictor.

Every operation is called once, then ``repeats`` times in a row; its time (s) is the fastest call.
Parts 1 and 2 run both libraries on ``COMPARE_THREADS`` threads (per-core throughput), part 3 on
the default threads. ipctk is optional (``pip install .[bench]``); without it its columns are
``null``.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp

import bfemp
from benchmarks import catalogue
from benchmarks._phases import barrier_stepper, newton_phases, wall_times
from benchmarks.common import figure
from benchmarks.runner import Benchmark, name_unless, register
from bfemp.contact._barrier_kernels import _barrier_gradients, _barrier_hessians
from bfemp.contact.barrier import barrier, barrier_derivative, barrier_second_derivative
from bfemp.contact.evaluation import KERNEL_KIND
from bfemp.contact.pairs import _distance, candidate_pairs
from solvers.assembly import TripletAssembler
from solvers.linear import default_linear_solver

try:  # optional benchmark dependency
    import ipctk
except ImportError:  # pragma: no cover - exercised where ipctk is absent
    ipctk = None

log = logging.getLogger(__name__)

NAME = "perf_contact"
DHAT, KAPPA = 1e-3, 1e7  # m, Pa (bfemp); ipctk's stiffness is KAPPA too (a plain factor there)
MATERIAL = dict(E=1e7, nu=0.3, density=1000.0)
MOTION = 3.0  # CCD translation in units of dhat
MODES = {
    "full": dict(pairs=50_000, repeats=7, rings="full"),
    "quick": dict(pairs=5_000, repeats=3, rings="quick"),
}
GEOMETRY = {2: dict(radius=1.0, h=0.05, dx=0.05), 3: dict(side=1.0, h=0.1, dx=0.1)}
RINGS_DT = 2e-4  # s
APPROACH_T = 0.02  # s: free flight with 10 dt up to here (contact at 0.025 s)
CONTACT_STEPS = 5  # steps of dt after the first step with a contact pair, before timing
#: Threads of both libraries in the barrier and CCD comparisons (numba and ipctk's TBB).
COMPARE_THREADS = 1


# --------------------------------------------------------------------------- configurations
def _sample_on_facets(
    points: np.ndarray, facets: np.ndarray, n: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points (m) on facet interiors, 2 dhat or more from the facet's edges; their facets."""
    dim = points.shape[1]
    out, owner, have = [], [], 0
    while have < n:
        f = rng.integers(0, facets.shape[0], 2 * n)
        c = points[facets[f]]  # (m, d, d)
        if dim == 2:
            s = rng.uniform(0.0, 1.0, f.size)
            x = c[:, 0] + s[:, None] * (c[:, 1] - c[:, 0])
            length = np.linalg.norm(c[:, 1] - c[:, 0], axis=1)
            ok = np.minimum(s, 1.0 - s) * length > 2.0 * DHAT
        else:
            w = rng.dirichlet(np.ones(3), f.size)
            x = np.einsum("mk,mkd->md", w, c)
            # in-plane distance to the edge opposite vertex k: w_k times the height 2 A / |e_k|
            area2 = np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
            edge = np.stack(
                [np.linalg.norm(c[:, (k + 2) % 3] - c[:, (k + 1) % 3], axis=1) for k in range(3)],
                axis=1,
            )
            ok = np.all(w * (area2[:, None] / edge) > 2.0 * DHAT, axis=1)
        out.append(x[ok])
        owner.append(f[ok])
        have += int(ok.sum())
    return np.concatenate(out)[:n], np.concatenate(owner)[:n]


def _configuration(dim: int, n_pairs: int, seed: int = 7) -> dict:
    """Fixed FEM body and ``n_pairs`` particles each within dhat of exactly one facet interior."""
    rng = np.random.default_rng(seed)
    geo = GEOMETRY[dim]
    if dim == 2:
        mesh = bfemp.shapes.disk((0.0, 0.0), geo["radius"], h=geo["h"])
    else:
        mesh = bfemp.shapes.box((0.0,) * 3, (geo["side"],) * 3, h=geo["h"])
    facets, normals = mesh.boundary_facets, mesh.boundary_normals()  # outward unit normals
    base, owner = _sample_on_facets(mesh.points, facets, n_pairs, rng)
    gap = rng.uniform(0.05, 0.95, n_pairs) * DHAT
    particles = base + gap[:, None] * normals[owner]
    volumes = np.full(n_pairs, (0.5 * geo["dx"]) ** dim)
    material = bfemp.NeoHookean(**MATERIAL)
    scene = bfemp.Scene(dim=dim)
    scene.add_fem(mesh, material=material, prescribed=bfemp.motion.Fixed(), name="obstacle")
    scene.add_mpm(particles, volumes, material=material, name="particles")
    scene.set_grid(dx=geo["dx"])
    scene.set_contact(dhat=DHAT, kappa=KAPPA)
    stepper = barrier_stepper(scene.build(), dt=1e-3, tol=1e-6)
    phases = stepper.phases(stepper.model.initial_state())
    x, term = phases.x0, phases.barrier
    term.solution_changed(x)
    direction = np.zeros(dim)
    direction[0 if dim == 2 else 2] = -1.0
    p = np.tile(MOTION * DHAT * direction, x.size // dim)  # every grid node translated
    return dict(
        dim=dim,
        term=term,
        x=x,
        p=p,
        layout=phases.layout,
        particles=particles,
        n_facets=int(facets.shape[0]),
    )


# --------------------------------------------------------------------------- bfemp side
def _kernel(kind: str, pos: np.ndarray, pts: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Pointwise barrier of the pairs ``pts (n, m)`` at collision positions ``pos (C, d)``: sum
    b, (n, m d) gradients and PSD-projected (n, m d, m d) Hessians of b(d(x)) w.r.t. the pair's
    points (no weights), through bfemp's kernels."""
    d = _distance(kind, pos, pts)
    b1 = barrier_derivative(d, DHAT, KAPPA)
    b2 = barrier_second_derivative(d, DHAT, KAPPA)
    code = KERNEL_KIND[kind]
    return (
        float(barrier(d, DHAT, KAPPA).sum()),
        _barrier_gradients(pos, pts, code, b1),
        _barrier_hessians(pos, pts, code, b1, b2, True),
    )


def _bfemp(case: dict, repeats: int) -> dict:
    """bfemp's levels on one configuration, each ``_timed``: pair search, value, gradient,
    kernels, the projected Hessian chained to the unknowns (triplets) and its CSC assembly
    (pattern reused); their sums ``dofs_s`` and ``chain_rule_and_scatter_s``; facts about the
    configuration."""
    term, x = case["term"], case["x"]
    kind = "pe" if case["dim"] == 2 else "pt"
    term.solution_changed(x)
    pts = term.pairs.points[kind]
    pos = term.collision_positions(x)
    out = {
        "pairs": int(term.pairs.n_pairs),
        "pairs_by_kind": {k: int(v.shape[0]) for k, v in term.pairs.points.items()},
        "energy": float(term.value(x)),
    }
    assembler = TripletAssembler(x.size)
    triplets = term.hessian(x, psd=True)
    out["hessian_triplets"] = int(triplets.nnz)
    out["hessian_nnz"] = int(assembler.assemble(triplets).nnz)  # pattern built once
    ops = {
        "pair_search": lambda: term.solution_changed(x),
        "value": lambda: term.value(x),
        "gradient": lambda: term.gradient(x),
        "kernel": lambda: _kernel(kind, pos, pts),
        "hessian": lambda: term.hessian(x, psd=True),
        "assemble": lambda: assembler.assemble(triplets),
    }
    out.update(_timed(ops, repeats))
    evaluation = out["value_s"] + out["gradient_s"] + out["hessian_s"]
    out["dofs_s"] = evaluation + out["assemble_s"]
    out["chain_rule_and_scatter_s"] = max(evaluation - out["kernel_s"], 0.0)
    return out


def _collision_map(case: dict) -> sp.csc_matrix:
    """bfemp's affine collision map as a (C, n_all) sparse matrix (rows: B-spline weights)."""
    cs = case["term"].collisions
    n_all = case["layout"].n_all
    rows = np.repeat(np.arange(cs.n_points), cs.nodes.shape[1])
    keep = cs.weights.ravel() != 0.0
    return sp.csc_matrix(
        (cs.weights.ravel()[keep], (rows[keep], cs.nodes.ravel()[keep])), shape=(cs.n_points, n_all)
    )


# --------------------------------------------------------------------------- ipctk side
def _ipctk(case: dict, repeats: int) -> dict | None:
    """ipctk's levels on the same collision points, each ``_timed``: pair search, value,
    gradient, projected Hessian, ``to_full_dof`` (chain rule to the unknowns); their sums
    ``collision_s`` and ``dofs_s``; facts (its ``mesh`` and ``vertex_gradient`` too, for the
    CCD and the agreement). None without ipctk."""
    if ipctk is None:
        return None
    term, x = case["term"], case["x"]
    cs = term.collisions
    vertices = np.asfortranarray(term.collision_positions(x))
    facets = np.asfortranarray(cs.facets.astype(np.int32))
    empty = np.zeros((0, 2 if case["dim"] == 3 else 3), dtype=np.int32, order="F")
    edges, faces = (facets, empty) if case["dim"] == 2 else (empty, facets)
    if case["dim"] == 3:  # the faces' edges, as ipctk expects with faces
        edges = np.asfortranarray(cs.edges.astype(np.int32))
    mesh = ipctk.CollisionMesh(vertices, edges, faces, _collision_map(case))
    potential = ipctk.BarrierPotential(DHAT, KAPPA)
    collisions = ipctk.NormalCollisions()
    psd = ipctk.PSDProjectionMethod.CLAMP

    def build() -> None:
        # ipctk 1.6 proposes codimensional particle-particle candidates whatever the mesh's
        # can_collide filter says; bfemp never pairs particles, so they are dropped here
        candidates = ipctk.Candidates()
        candidates.build(mesh, vertices, DHAT)
        candidates.vv_candidates = []
        collisions.build(candidates, mesh, vertices, DHAT)

    build()
    grad = potential.gradient(collisions, mesh, vertices)
    hess = potential.hessian(collisions, mesh, vertices, psd)
    out = {
        "pairs": len(collisions),
        "energy": float(potential(collisions, mesh, vertices)),
        "vertex_gradient": np.asarray(grad).reshape(-1, case["dim"]),
        "mesh": mesh,
        "hessian_nnz_collision": int(hess.nnz),
        "hessian_nnz_full": int(mesh.to_full_dof(hess).nnz),
    }
    ops = {
        "pair_search": build,
        "value": lambda: potential(collisions, mesh, vertices),
        "gradient": lambda: potential.gradient(collisions, mesh, vertices),
        "hessian": lambda: potential.hessian(collisions, mesh, vertices, psd),
        "to_full_dof": lambda: (mesh.to_full_dof(grad), mesh.to_full_dof(hess)),
    }
    out.update(_timed(ops, repeats))
    out["collision_s"] = out["value_s"] + out["gradient_s"] + out["hessian_s"]
    out["dofs_s"] = out["collision_s"] + out["to_full_dof_s"]
    return out


def _timed(ops: dict, repeats: int) -> dict[str, float]:
    """``{name}_s``: for each op in turn, one warm-up call then the fastest of ``repeats``
    consecutive calls (a steady state: the allocator reuses the previous call's memory)."""
    out = {}
    for name, fn in ops.items():
        fn()
        out[f"{name}_s"] = min(wall_times(fn, repeats))
    return out


# --------------------------------------------------------------------------- agreement
def _ipc_barrier_d(dsq: np.ndarray, order: int) -> np.ndarray:
    """ipctk's clamped log barrier in squared distance (order 0) and its D-derivative (order 1)."""
    dh = DHAT * DHAT
    if order == 0:
        return -((dsq - dh) ** 2) * np.log(dsq / dh)
    return -2.0 * (dsq - dh) * np.log(dsq / dh) - (dsq - dh) ** 2 / dsq


def _agreement(case: dict, bf: dict, ip: dict) -> dict:
    """Same pairs, energies and particle gradients up to the known scaling of the two barriers."""
    term = case["term"]
    kind = "pe" if case["dim"] == 2 else "pt"
    d = term.pairs.distance[kind]
    point = term.pairs.points[kind][:, 0]
    expected = KAPPA * float(_ipc_barrier_d(d * d, 0).sum())
    # per particle: g_ipc = -F_bfemp * kappa_ipc b_ipc'(d^2) 2 d / (omega b'(d))
    force = term.point_forces()[point]
    omega = term.collisions.omega[point]
    ratio = (
        KAPPA * _ipc_barrier_d(d * d, 1) * 2.0 * d / (omega * barrier_derivative(d, DHAT, KAPPA))
    )
    predicted = -force * ratio[:, None]
    g_ipc = ip["vertex_gradient"][point]
    return {
        "same_pair_count": bool(bf["pairs"] == ip["pairs"]),
        "energy_rel_diff": abs(ip["energy"] - expected) / expected,
        "particle_gradient_rel_diff": float(np.abs(g_ipc - predicted).max() / np.abs(g_ipc).max()),
        "compared": "ipctk energy vs stiffness * sum b_ipc(d^2) over bfemp's pair distances; "
        "ipctk vertex gradient vs bfemp point force times the analytic per-pair derivative "
        "ratio (particles); norm-wise relative differences",
    }


# --------------------------------------------------------------------------- CCD
def _exact_toi(
    points: np.ndarray, verts: np.ndarray, facets: np.ndarray, motion: np.ndarray
) -> float:
    """First time in [0, 1] at which any point ``(n, d)`` moving by ``motion (d,)`` meets a fixed
    facet (brute force: crossing of the facet's line / plane inside the facet); 1 if none."""
    dim = verts.shape[1]
    c = verts[facets]
    e1, e2 = c[:, 1] - c[:, 0], c[:, -1] - c[:, 0]
    normal = np.stack([e1[:, 1], -e1[:, 0]], axis=1) if dim == 2 else np.cross(e1, e2)
    speed = normal @ motion  # (F,)
    best = 1.0
    for start in range(0, points.shape[0], 2000):  # chunks of 2000 points x all facets
        p = points[start : start + 2000]
        s0 = np.einsum("fd,nfd->nf", normal, p[:, None, :] - c[None, :, 0])
        moving = speed != 0.0  # facets parallel to the motion are never crossed
        t = np.where(moving, -s0 / np.where(moving, speed, 1.0), 2.0)
        q = p[:, None, :] + t[..., None] * motion - c[None, :, 0]  # (n, F, d) from corner 0
        if dim == 2:
            u = np.einsum("nfd,fd->nf", q, e1) / np.einsum("fd,fd->f", e1, e1)
            inside = (u >= 0.0) & (u <= 1.0)
        else:  # barycentric coordinates of the crossing in the triangle
            g11, g12, g22 = (np.einsum("fd,fd->f", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
            r1, r2 = np.einsum("nfd,fd->nf", q, e1), np.einsum("nfd,fd->nf", q, e2)
            det = g11 * g22 - g12 * g12
            b1, b2 = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
            inside = (b1 >= 0.0) & (b2 >= 0.0) & (b1 + b2 <= 1.0)
        hit = inside & (t >= 0.0) & (t <= 1.0)
        if hit.any():
            best = min(best, float(t[hit].min()))
    return best


def _ccd(case: dict, ip: dict | None, repeats: int) -> dict:
    """bfemp max_step_size vs ipctk compute_collision_free_stepsize on one translation."""
    term, x, p = case["term"], case["x"], case["p"]
    term.solution_changed(x)
    nf = term.collisions.n_fem_points
    start = term.collision_positions(x)
    end = term.collision_positions(x + p)
    motion = (end - start)[nf:].mean(axis=0)
    ops = {"bfemp": lambda: term.max_step_size(x, p)}
    if ip is not None:
        v0, v1, mesh = np.asfortranarray(start), np.asfortranarray(end), ip["mesh"]
        ops["ipctk"] = lambda: ipctk.compute_collision_free_stepsize(mesh, v0, v1)
    out = {
        "motion_m": float(np.linalg.norm(motion)),
        "exact_toi": _exact_toi(start[nf:], start[:nf], term.collisions.facets, motion),
        "bfemp_candidates": int(candidate_pairs(term.collisions, start, 0.0, end).shape[0]),
        "ipctk_step": None,
        "ipctk_s": None,
    }
    out.update(_timed(ops, repeats))
    out.update({f"{name}_step": float(fn()) for name, fn in ops.items()})
    steps = [s for s in (out["bfemp_step"], out["ipctk_step"]) if s is not None]
    out["conservative"] = bool(all(s <= out["exact_toi"] for s in steps))
    return out


# --------------------------------------------------------------------------- one case
def _measure_case(dim: int, n_pairs: int, repeats: int) -> dict:
    """Barrier levels, agreement and CCD of one configuration."""
    case = _configuration(dim, n_pairs)
    bf, ip = _bfemp(case, repeats), _ipctk(case, repeats)
    out = {
        "dim": dim,
        "pairs": bf["pairs"],
        "fem_facets": case["n_facets"],
        "particles": int(case["particles"].shape[0]),
        "unknowns": int(case["x"].size),
        "bfemp": bf,
        "ipctk": None,
        "agreement": None,
        "ccd": _ccd(case, ip, repeats),
    }
    if ip is not None:
        out["agreement"] = _agreement(case, bf, ip)
        out["ipctk"] = {k: v for k, v in ip.items() if k not in ("mesh", "vertex_gradient")}
    return out


# --------------------------------------------------------------------------- rings breakdown
def _rings_breakdown(resolution: str, repeats: int) -> dict:
    """Step the rings to first contact, then time one step's phases and the contact phases."""
    from benchmarks import rings

    cfg = dict(rings.MODES[resolution], dt=RINGS_DT)
    model = catalogue.rings_scene(cfg).build()

    def simulation(dt: float) -> bfemp.Simulation:
        return bfemp.Simulation(
            model, strategy="barrier", integrator="newmark", transfer="apic", dt=dt, tol=rings.TOL
        )

    start = time.perf_counter()
    # free flight (rigid translation, no contact) with 10 dt up to t = APPROACH_T, then dt
    fast = simulation(10.0 * RINGS_DT)
    while fast.state.t < APPROACH_T - 10.0 * RINGS_DT * (1.0 - 1e-9):
        fast.step()
    sim = simulation(RINGS_DT)
    sim.state = fast.state
    report = sim.step()
    while report.contact_pairs == 0 and sim.state.t < 0.05:  # contact expected at 0.025 s
        report = sim.step()
    first_contact_t = float(sim.state.t)
    for _ in range(CONTACT_STEPS):  # into the collision: a developed contact zone
        report = sim.step()
    approach_s = time.perf_counter() - start
    stepper, state = sim.stepper, sim.state
    out = {
        "resolution": resolution,
        "parameters": {k: cfg[k] for k in ("dx", "ppc", "fem_h", "dt")},
        "particles": int(sim.model.n_particles),
        "fem_nodes": int(sim.model.n_fem_nodes),
        "first_contact_t": first_contact_t,
        "t": float(state.t),
        "contact_step": int(state.step),
        "approach_steps": {"dt_10x": int(fast.state.step), "dt": int(state.step - fast.state.step)},
        "approach_wall_s": approach_s,
        "contact_pairs_at_t": int(report.contact_pairs),
    }
    out.update(newton_phases(stepper, state))
    # the step again, each phase the fastest of ``repeats`` runs; a fresh linear solver each
    # time, so that CHOLMOD analyses the pattern as it would on a new step
    best: dict[str, float] = {}
    for _ in range(repeats):
        stepper.linear_solver = default_linear_solver()
        _, report = stepper.step(state)
        for key, value in report.timings.items():
            best[key] = min(best.get(key, math.inf), value)
    out["newton_iterations"] = int(report.newton_iterations)
    out["step_phases_s"] = best
    nit = max(out["newton_iterations"], 1)
    out["step_phases_per_iteration_s"] = {
        k: v / nit for k, v in best.items() if k not in ("setup", "g2p", "intersection", "step")
    }
    phases = stepper.phases(state)
    x, term = phases.x0, phases.barrier
    term.solution_changed(x)
    pos = term.collision_positions(x)
    dhat = sim.model.contact.dhat
    out["barrier_pairs"] = int(term.pairs.n_pairs)
    out["broad_phase_candidates"] = int(candidate_pairs(term.collisions, pos, dhat).shape[0])
    p = phases.context.x_hat - x  # the inertial predictor: the size of a first Newton step
    out["ccd_step"] = float(term.max_step_size(x, p))
    ops = {
        "broad_phase": lambda: candidate_pairs(term.collisions, pos, dhat),
        "pair_search": lambda: term.solution_changed(x),
        "ccd": lambda: term.max_step_size(x, p),
    }
    out.update(_timed(ops, repeats))
    return out


# --------------------------------------------------------------------------- report
def _per_s(pairs: int, seconds: float | None) -> float | None:
    return None if seconds is None or seconds <= 0.0 else pairs / seconds


def _bars(ax, labels: list[str], series: dict, ylabel: str, title: str) -> None:
    """Grouped bars of ``series`` (name -> one value per label) on a log scale."""
    pos = np.arange(len(labels))
    for k, (name, vals) in enumerate(series.items()):
        ax.bar(pos + (k - 0.5) * 0.38, vals, 0.38, label=name)
    ax.set_xticks(pos, labels, fontsize="small")
    ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize="medium")
    ax.legend(fontsize="small")


def _plot(payload: dict, path: Path) -> None:
    """Pairs/s per level (2D, 3D), CCD times, and the rings step's phases per iteration."""
    fig, (ax_b, ax_c, ax_r) = figure(
        (13.0, 4.6), 1, 3, width_ratios=(2.2, 1.0, 1.6), layout="constrained"
    )
    labels, series = [], {"bfemp": [], "ipctk": []}
    for dim_key, case in payload["cases"].items():
        bf, ip = case["bfemp"], case["ipctk"] or {}
        for level, b_s, i_s in (
            ("bfemp kernel /\nipctk collision", bf["kernel_s"], ip.get("collision_s")),
            ("unknowns (dofs)", bf["dofs_s"], ip.get("dofs_s")),
        ):
            labels.append(f"{dim_key}\n{level}")
            series["bfemp"].append(_per_s(case["pairs"], b_s) or np.nan)
            series["ipctk"].append(_per_s(case["pairs"], i_s) or np.nan)
    _bars(ax_b, labels, series, "active pairs per second", "barrier value + gradient + PSD Hessian")
    ccd = {n: [c["ccd"][f"{n}_s"] or np.nan for c in payload["cases"].values()] for n in series}
    _bars(ax_c, list(payload["cases"]), ccd, "seconds (broad + narrow phase)", "CCD step bound")
    ring = payload["rings_breakdown"]
    parts = dict(ring["step_phases_per_iteration_s"])
    parts["broad phase\n(one call)"] = ring["broad_phase_s"]
    parts["CCD\n(one call)"] = ring["ccd_s"]
    keep = {k: v for k, v in parts.items() if v > 0.0 and k != "total"}
    ax_r.barh(list(keep), list(keep.values()), color="C2")
    ax_r.set_xlabel("seconds per Newton iteration")
    ax_r.set_title(
        f"rings at contact ({ring['particles']} particles, {ring['newton_iterations']} iterations)",
        fontsize="medium",
    )
    ax_r.tick_params(axis="y", labelsize="small")
    fig.suptitle(f"perf_contact ({payload['mode']} mode)")
    fig.savefig(path, dpi=110)


def measure(mode: str, cfg: dict) -> dict:
    """Both configurations and the rings breakdown of ``mode`` (``"full"``: 50k pairs, rings at
    full resolution; ``"quick"``: 5k, coarse rings)."""
    threads = numba.get_num_threads(), ipctk.get_num_threads() if ipctk is not None else None
    numba.set_num_threads(COMPARE_THREADS)  # per-core throughput: robust on a shared machine
    if ipctk is not None:
        ipctk.set_num_threads(COMPARE_THREADS)
    try:
        cases = {f"{d}d": _measure_case(d, cfg["pairs"], cfg["repeats"]) for d in (2, 3)}
    finally:
        numba.set_num_threads(threads[0])
        if ipctk is not None:
            ipctk.set_num_threads(threads[1])
    ring = _rings_breakdown(cfg["rings"], cfg["repeats"])
    pairs_per_s, ccd_s, ccd_step = {}, {}, {}
    for key, case in cases.items():
        bf, ip, n = case["bfemp"], case["ipctk"] or {}, case["pairs"]
        searched = ip["dofs_s"] + ip["pair_search_s"] if ip else None
        pairs_per_s[key] = {
            "bfemp": _per_s(n, bf["dofs_s"]),
            "ipctk": _per_s(ip.get("pairs", 0), ip.get("dofs_s")),
            "bfemp_kernel": _per_s(n, bf["kernel_s"]),
            "ipctk_collision": _per_s(ip.get("pairs", 0), ip.get("collision_s")),
            "bfemp_with_pair_search": _per_s(n, bf["dofs_s"] + bf["pair_search_s"]),
            "ipctk_with_pair_search": _per_s(ip.get("pairs", 0), searched),
        }
        c = case["ccd"]
        ccd_s[key] = {"bfemp": c["bfemp_s"], "ipctk": c["ipctk_s"]}
        ccd_step[key] = {
            "bfemp": c["bfemp_step"],
            "ipctk": c["ipctk_step"],
            "exact": c["exact_toi"],
        }
    has_ipctk = ipctk is not None
    targets_met = None
    if has_ipctk:
        targets_met = {
            key: {
                "barrier_pairs_per_s": bool(v["bfemp"] >= v["ipctk"]),
                "ccd_s": bool(ccd_s[key]["bfemp"] <= ccd_s[key]["ipctk"]),
            }
            for key, v in pairs_per_s.items()
        }
    payload = {
        "mode": mode,
        "barrier_pairs_per_s": pairs_per_s,
        "ccd_s": ccd_s,
        "ccd_step": ccd_step,
        "ccd_conservative": all(c["ccd"]["conservative"] for c in cases.values()),
        "agreement": {k: c["agreement"] for k, c in cases.items()},
        "rings_breakdown": ring,
        "targets": {
            "barrier_pairs_per_s": "bfemp >= ipctk (value + gradient + PSD Hessian, same unknowns)",
            "ccd_s": "bfemp <= ipctk",
            "ccd_step": "<= exact time of impact for both (conservative)",
        },
        "targets_met": targets_met,
        "ipctk_available": has_ipctk,
        "steps": sum(ring["approach_steps"].values()) + 1,
        "newton_iterations": ring["newton_iterations"],
        "parameters": {
            "pairs": cfg["pairs"],
            "repeats": cfg["repeats"],
            "dhat_m": DHAT,
            "kappa_Pa": KAPPA,
            "ipctk_stiffness": KAPPA,
            "gap_range_dhat": [0.05, 0.95],
            "ccd_translation_dhat": MOTION,
            "geometry": {f"{d}d": g for d, g in GEOMETRY.items()},
            "rings_resolution": cfg["rings"],
            "rings_dt_s": RINGS_DT,
            "compare_threads": COMPARE_THREADS,
            "rings_threads": {"numba": threads[0], "ipctk": threads[1]},
            "ipctk_version": getattr(ipctk, "__version__", None) if has_ipctk else None,
        },
        "cases": cases,
    }
    log.info("perf_contact: pairs/s %s; CCD s %s", pairs_per_s, ccd_s)
    return payload


# the committed records of modes other than full carry the mode in their names
BENCHMARK = register(
    Benchmark(NAME, __doc__, MODES, measure, plot=_plot, record=name_unless("full", NAME))
)
run = BENCHMARK.run
