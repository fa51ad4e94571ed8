"""The scene catalogue of the benchmarks: public builders shared by the paper reproductions, the
per-strategy scene runs (``scenes``), the conformance scenes and the trade study.

- rings (BFEMP sec. 6.1): an MPM ring and a FEM ring, 2 m apart, approaching at 40 m/s each;
  ``rings_scene``, ``mpm_rings_scene`` (both rings as particles), ``RingsPenetration`` (the
  per-step count of particles inside the deformed FEM ring) and ``window_energies`` (the
  energy at the ends of the paper's collision window).
- slope (BFEMP sec. 6.4): a stiff MPM box on a fixed FEM slope, tan theta = 0.2;
  ``slope_scene``, ``slope_simulation``, ``settle_slope`` (frictionless settling against the slope
  and a stop plane), ``release_slope`` (the settled box without the plane at a friction coefficient,
  its acceleration fitted) and ``fit_acceleration``.
- blocks (the performance benchmarks and the solver tests): ``fem_block_scene`` and
  ``mpm_block_scene``.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import numpy as np

import bfemp

log = logging.getLogger(__name__)


def step(sim: bfemp.Simulation, label: str):
    """One step of ``sim``: ``(report, None)``, or ``(None, message)`` of a ``StepError``,
    logged as a warning under ``label`` (a failed step ends a benchmark's run, recorded)."""
    try:
        return sim.step(), None
    except bfemp.StepError as err:
        log.warning("%s: %s", label, err)
        return None, str(err)


def simulation(scene: bfemp.Scene, cfg: dict, strategy: str, tol: float, max_newton: int):
    """The paper's implicit solve, ``strategy`` (barrier) by backward Euler with Newton
    tolerance ``tol`` (m/s) and cap ``max_newton``, when ``cfg`` has no ``options``; else
    ``cfg``'s ``strategy``, ``integrator`` and ``options`` object (the trade study's explicit
    points). The step is ``cfg["dt"]`` (s)."""
    if cfg.get("options") is None:
        return bfemp.Simulation(
            scene,
            strategy=strategy,
            integrator="backward_euler",
            dt=cfg["dt"],
            tol=tol,
            max_newton_iterations=max_newton,
        )
    return bfemp.Simulation(
        scene,
        strategy=cfg["strategy"],
        integrator=cfg["integrator"],
        dt=cfg["dt"],
        options=cfg["options"],
    )


def paper_simulation(scene: bfemp.Scene, dt: float, tol: float, max_newton: int, **kwargs):
    """The papers' implicit setting: barrier by backward Euler with APIC, step ``dt`` (s),
    Newton tolerance ``tol`` (m/s) and cap ``max_newton``; ``kwargs`` go to
    ``bfemp.Simulation`` (``linear_solver``)."""
    return bfemp.Simulation(
        scene,
        integrator="backward_euler",
        transfer="apic",
        dt=dt,
        tol=tol,
        max_newton_iterations=max_newton,
        **kwargs,
    )


# ----------------------------------------------------------------------------- rings
R_INNER, R_OUTER = 3.0, 4.0  # m

GAP = 2.0  # m, between the outer surfaces

SPEED = 40.0  # m/s, each ring toward the other

MATERIAL = dict(E=1e8, nu=0.2, density=1000.0)  # Pa, -, kg/m^2 (2D)

DHAT, KAPPA = 1e-2, 1e7  # m, Pa

TOL = 1e-6  # m/s

WINDOW = (0.025, 0.293)  # s: the paper's collision window

#: the rings' MPM grid spacing ``dx`` (m), particles per cell ``ppc`` and FEM edge ``fem_h`` (m):
#: the paper's (full), the MPM grid coarsened 2x (partial: what a 2-core machine runs) and quick
RINGS_DISCRETISATION = {
    "full": dict(dx=0.1, ppc=9, fem_h=0.13),
    "partial": dict(dx=0.2, ppc=4, fem_h=0.13),
    "quick": dict(dx=1.0 / 3.0, ppc=4, fem_h=1.0 / 3.0),
}


def rings_grid_origin(cfg: dict) -> tuple[float, float]:
    """Grid origin shifted by a quarter of the particle spacing off the sampling lattice.

    With an odd number k of particles per cell and axis, the sub-cell centres fall on
    half-integer grid coordinates, where the quadratic B-spline weight (and its gradient) of the
    outermost stencil node vanishes; at the rim of a curved body some active nodes then have no
    mass and no stiffness at all and Newton cannot converge. The shift keeps every weight positive.
    """
    k = round(cfg["ppc"] ** 0.5)
    shift = cfg["dx"] / (4.0 * k)
    return (shift, shift)


def rings_scene(cfg: dict) -> bfemp.Scene:
    """Both rings, 2 m apart, approaching at 40 m/s each (MPM left, FEM right)."""
    centre = R_OUTER + 0.5 * GAP
    material = bfemp.NeoHookean(**MATERIAL)
    scene = bfemp.Scene(dim=2)
    # The sampling mesh only decides which sub-cell centres lie in the ring: make it fine.
    shape = bfemp.shapes.ring((-centre, 0.0), R_INNER, R_OUTER, h=0.25 * cfg["dx"])
    particles, volumes = bfemp.sample.mesh(shape, dx=cfg["dx"], ppc=cfg["ppc"])
    scene.add_mpm(particles, volumes, material=material, velocity=(SPEED, 0.0), name="mpm_ring")
    mesh = bfemp.shapes.ring((centre, 0.0), R_INNER, R_OUTER, h=cfg["fem_h"])
    scene.add_fem(mesh, material=material, velocity=(-SPEED, 0.0), name="fem_ring")
    scene.set_grid(dx=cfg["dx"], origin=rings_grid_origin(cfg))
    scene.set_contact(dhat=cfg.get("dhat", DHAT), kappa=KAPPA)
    return scene


def mpm_rings_scene(cfg: dict) -> bfemp.Scene:
    """Both rings as MPM bodies (the FEM ring of ``rings_scene`` sampled like the MPM one)."""
    scene = bfemp.Scene(dim=2)
    material = bfemp.NeoHookean(**MATERIAL)
    centre = R_OUTER + 0.5 * GAP
    for name, sign in (("left_ring", -1.0), ("right_ring", 1.0)):
        shape = bfemp.shapes.ring((sign * centre, 0.0), R_INNER, R_OUTER, h=0.25 * cfg["dx"])
        x, vol = bfemp.sample.mesh(shape, dx=cfg["dx"], ppc=cfg["ppc"])
        velocity = (-sign * SPEED, 0.0)
        scene.add_mpm(x, vol, material=material, velocity=velocity, name=name)
    scene.set_grid(dx=cfg["dx"], origin=rings_grid_origin(cfg))
    return scene


def inside_count(points: np.ndarray, edge_a: np.ndarray, edge_b: np.ndarray) -> int:
    """Number of points ``(n, 2)`` inside the region bounded by the segments ``a -> b`` ``(k, 2)``.

    Even-odd rule: a horizontal ray from the point crosses the boundary (outer and inner loop of
    the ring together) an odd number of times exactly when the point lies in the ring.
    """
    if points.shape[0] == 0:
        return 0
    py, px = points[:, 1:2], points[:, 0:1]
    ya, yb = edge_a[None, :, 1], edge_b[None, :, 1]
    straddles = (ya > py) != (yb > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = edge_a[None, :, 0] + (py - ya) * (edge_b[None, :, 0] - edge_a[None, :, 0]) / (
            yb - ya
        )
    crossings = np.count_nonzero(straddles & (px < x_cross), axis=1)
    return int(np.count_nonzero(crossings % 2 == 1))


class RingsPenetration:
    """Per-step callback: particles inside the deformed FEM ring (should stay 0)."""

    def __init__(self, sim: bfemp.Simulation) -> None:
        body = sim.model.fem_bodies[0]
        self.edges = body.boundary  # (k, 2) global FEM node indices
        self.worst = 0

    def __call__(self, sim: bfemp.Simulation) -> None:
        fem_x, mpm_x = sim.state.fem_x, sim.state.mpm_x
        a, b = fem_x[self.edges[:, 0]], fem_x[self.edges[:, 1]]
        lo, hi = np.minimum(a, b).min(axis=0), np.maximum(a, b).max(axis=0)
        near = np.all((mpm_x >= lo) & (mpm_x <= hi), axis=1)
        self.worst = max(self.worst, inside_count(mpm_x[near], a, b))
        if sim.state.step % 250 == 0:
            row = sim.metrics.last
            log.info(
                "t = %.4f s: E_kin %.4g J, E_el %.4g J, %d contact pairs",
                sim.state.t,
                row["energy_kinetic"],
                row["energy_elastic"],
                row.get("contact_pairs", 0),
            )


def window_energies(t: np.ndarray, energy: np.ndarray) -> tuple[float, float]:
    """Total energy (J/m) at the last step <= 0.025 s and at the first step >= 0.293 s."""
    eps = 1e-9
    before = np.flatnonzero(t <= WINDOW[0] + eps)
    after = np.flatnonzero(t >= WINDOW[1] - eps)
    e0 = float(energy[before[-1]]) if before.size else float("nan")
    e1 = float(energy[after[0]]) if after.size else float("nan")
    return e0, e1


# ----------------------------------------------------------------------------- slope

SLOPE_PHYSICS = {
    "box_size_m": (0.1, 0.02),
    "particle_lattice": (41, 9),
    "dx_m": 0.005,
    "density_kg_m2": 100.0,
    "E_Pa": 4e12,
    "nu": 0.2,
    "material": "neo_hookean",
    "tan_theta": 0.2,
    "g_m_s2": 5.10,
    "mus": (0.0, 0.1, 0.1999, 0.2),
    "dhat_m": 1e-3,
    "kappa_Pa": 1e6,
    "eps_v_m_s": 1e-5,
    "integrator": "backward_euler",
    "transfer": "apic",
    "dt_s": 1e-3,
    "tol_m_s": 1e-8,
    "friction_iterations_cap": 100,
    # the paper's Algorithm 2 line 14 (a^{n+1} from the forces): the default "positions" puts the
    # Newton tolerance of this very stiff box into every step's velocity (full mode, mu = 0.1999:
    # 4.0e-3 relative error against 3.4e-5; see BarrierOptions.velocity_update)
    "velocity_update": "forces",
    # the box starts this far from the slope and from the extra plane (dhat, plus a relative
    # 1e-6 so that rounding of the rotated lattice never starts a particle inside dhat)
    "initial_gap_m": 1e-3 * (1.0 + 1e-6),
    "slope_lower_upper_m": ((-0.8, -0.5), (0.2, 0.0)),
    "stop_plane_mesh": "rectangle 0.01 m x 0.037 m, from 3 dhat above the slope, h = 0.01 m",
}


#: the slope's settling, release and fit start (s after release) of the shortened runs (the
#: paper's are 0.1, 0.5 and 0.1 s)
SLOPE_TIMES = {
    "partial": dict(settle_s=0.1, release_s=0.2, fit_start_s=0.05),
    "quick": dict(settle_s=0.02, release_s=0.03, fit_start_s=0.01),
}

#: variant -> (frame, slope mesh size h in m)
SLOPE_VARIANTS = {
    "tilted_gravity": ("tilted_gravity", 1.0),
    "rotated_slope": ("rotated_slope", 1.0),
    "fine_slope": ("tilted_gravity", 0.1),
    # for strategies that see the FEM slope through its boundary nodes (lr): an edge of half a
    # grid cell; run with a thin slope (``scenes`` under lr sets slope_lower_upper_m)
    "dense_slope": ("tilted_gravity", 0.0025),
}

#: lr sees the FEM slope through its boundary nodes, so the slope is meshed at half a grid cell
#: (``SLOPE_VARIANTS["dense_slope"]``) and made 1 cm thick instead of 0.5 m (its elastic cells,
#: all scripted, are only a cost); measured with the default 1 m mesh, 18 contact nodes under
#: the 0.1 m box and the box sank through the slope
LR_SLOPE = ((-0.8, -0.01), (0.2, 0.0))


def slope_rotation(frame: str, theta: float) -> np.ndarray:
    """World-from-slope rotation ``(2, 2)``: identity, or a rotation by theta (rad)."""
    if frame == "tilted_gravity":
        return np.eye(2)
    if frame == "rotated_slope":
        c, s = math.cos(theta), math.sin(theta)
        return np.array([[c, -s], [s, c]])
    raise ValueError(f"frame must be 'tilted_gravity' or 'rotated_slope', got {frame!r}")


def slope_scene(variant: str, mu: float, with_stop: bool, p: dict = SLOPE_PHYSICS) -> bfemp.Scene:
    """Slope (+ the downhill stop plane) and the box dhat away from both, in world coordinates.

    ``p`` is ``SLOPE_PHYSICS`` or a copy with some entries changed (``slope.point_physics``).
    """
    frame, slope_h = SLOPE_VARIANTS[variant]
    theta = math.atan(p["tan_theta"])
    R = slope_rotation(frame, theta)
    # gravity in slope coordinates (tangent, normal), then into the world frame
    g_slope = p["g_m_s2"] * np.array([-math.sin(theta), -math.cos(theta)])
    scene = bfemp.Scene(dim=2, gravity=tuple(R @ g_slope))
    mat = bfemp.NeoHookean(E=p["E_Pa"], nu=p["nu"], density=p["density_kg_m2"])
    fixed = bfemp.motion.Fixed()
    gap, dhat = p["initial_gap_m"], p["dhat_m"]
    slope = bfemp.shapes.rectangle(*p["slope_lower_upper_m"], h=slope_h)
    scene.add_fem(slope.points @ R.T, slope.cells, material=mat, prescribed=fixed, name="slope")
    if with_stop:
        stop = bfemp.shapes.rectangle((-gap - 0.01, 3.0 * dhat), (-gap, 0.04), h=0.01)
        scene.add_fem(stop.points @ R.T, stop.cells, material=mat, prescribed=fixed, name="stop")
    (lx, ly), (nx, ny) = p["box_size_m"], p["particle_lattice"]
    xs, ys = np.meshgrid(np.linspace(0.0, lx, nx), np.linspace(0.0, ly, ny))
    particles = np.stack([xs.ravel(), ys.ravel() + gap], axis=1)
    volumes = np.full(particles.shape[0], lx * ly / particles.shape[0])
    scene.add_mpm(np.ascontiguousarray(particles @ R.T), volumes, material=mat, name="box")
    scene.set_grid(dx=p["dx_m"])
    scene.set_contact(
        dhat=dhat,
        kappa=p["kappa_Pa"],
        mu=mu,
        eps_v=p["eps_v_m_s"],
        friction_iterations=p["friction_iterations_cap"],
    )
    return scene


def slope_simulation(scene: bfemp.Scene, p: dict = SLOPE_PHYSICS) -> bfemp.Simulation:
    strategy = p.get("strategy", "barrier")
    options = p.get("options")  # another strategy's options (``scenes``)
    if strategy == "barrier":
        options = bfemp.BarrierOptions(
            tol=p["tol_m_s"], velocity_update=p.get("velocity_update", "positions")
        )
    return bfemp.Simulation(
        scene,
        strategy=strategy,
        integrator=p["integrator"],
        transfer=p["transfer"],
        dt=p["dt_s"],
        options=options,
    )


def slope_com(sim: bfemp.Simulation) -> tuple[np.ndarray, np.ndarray]:
    """Centre-of-mass position ``(2,)`` in m and velocity ``(2,)`` in m/s of the box."""
    m = sim.model.mpm_mass
    return m @ sim.state.mpm_x / m.sum(), m @ sim.state.mpm_v / m.sum()


def settle_slope(
    variant: str, steps: int, p: dict = SLOPE_PHYSICS, on_step: Callable | None = None
) -> tuple[bfemp.State, dict]:
    """Frictionless settling against the slope and the stop plane; the settled state.

    ``on_step(sim, report)`` is called after every step (``benchmarks.lr_variants``).
    """
    sim = slope_simulation(slope_scene(variant, 0.0, with_stop=True, p=p), p)
    started, newton = time.perf_counter(), 0
    for _ in range(steps):
        report = sim.step()
        newton += report.newton_iterations
        if on_step is not None:
            on_step(sim, report)
    _, v = slope_com(sim)
    info = {
        "steps": steps,
        "newton_iterations": newton,
        "wall_s": time.perf_counter() - started,
        "com_speed_at_release_m_s": float(np.linalg.norm(v)),
        "min_gap_at_release_m": float(slope_min_gap(sim, SLOPE_VARIANTS[variant][0])),
    }
    return sim.state.copy(), info


def slope_min_gap(sim: bfemp.Simulation, frame: str) -> float:
    """Smallest particle height above the slope line in m."""
    R = slope_rotation(frame, math.atan(SLOPE_PHYSICS["tan_theta"]))
    return float((sim.state.mpm_x @ R)[:, 1].min())


def fit_acceleration(tau: np.ndarray, s: np.ndarray, fit_start: float) -> dict:
    """Least-squares s = s0 + v0 tau + a tau^2 / 2 over tau >= fit_start; a in m/s^2."""
    window = tau >= fit_start - 1e-12
    if window.sum() < 4:
        return {"accel": float("nan"), "fit_window_s": None, "fit_rms_m": None}
    # shifted to the window's start for conditioning
    shifted, offset = tau[window] - tau[window][0], s[window] - s[window][0]
    coef = np.polynomial.polynomial.polyfit(shifted, offset, 2)
    residual = np.polynomial.polynomial.polyval(shifted, coef) - offset
    return {
        "accel": 2.0 * float(coef[2]),
        "fit_window_s": [float(tau[window][0]), float(tau[-1])],
        "fit_rms_m": float(np.sqrt(np.mean(residual**2))),
    }


def release_slope(
    variant: str,
    mu: float,
    settled: bfemp.State,
    steps: int,
    fit_start: float,
    p: dict = SLOPE_PHYSICS,
    on_step: Callable | None = None,
) -> dict:
    """Continue the settled box without the stop plane at friction ``mu``; fit its motion.

    A failed step (``StepError``) ends the case; it is recorded in ``error`` and the fit uses
    the steps completed before it. ``on_step(sim, report)`` is called after every step.
    """
    theta = math.atan(p["tan_theta"])
    downhill = slope_rotation(SLOPE_VARIANTS[variant][0], theta) @ np.array([-1.0, 0.0])
    sim = slope_simulation(slope_scene(variant, mu, with_stop=False, p=p), p)
    state = sim.state.copy()  # the release model's own (slope-only) FEM arrays
    state.t, state.step = settled.t, settled.step
    for key in ("mpm_x", "mpm_v", "mpm_F", "mpm_C", "mpm_a", "mpm_Ca"):
        setattr(state, key, getattr(settled, key).copy())
    sim.state = state
    tau, s, v_along, speed = [], [], [], []

    def record() -> None:
        x, v = slope_com(sim)
        tau.append(sim.state.t - settled.t)
        s.append(float(x @ downhill))
        v_along.append(float(v @ downhill))
        speed.append(float(np.linalg.norm(v)))

    record()
    newton, friction_max, friction_ok, min_d, error = 0, 0, True, math.inf, None
    started = time.perf_counter()
    for _ in range(steps):
        report, error = step(sim, f"{variant} mu={mu:g}")
        if error is not None:
            break
        newton += report.newton_iterations
        friction_max = max(friction_max, report.friction_iterations)
        friction_ok = friction_ok and report.friction_converged
        if np.isfinite(report.min_distance):
            min_d = min(min_d, report.min_distance)
        if on_step is not None:
            on_step(sim, report)
        record()
    wall = time.perf_counter() - started
    fit = fit_acceleration(np.array(tau), np.array(s), fit_start)
    g = p["g_m_s2"]
    analytic = g * (math.sin(theta) - mu * math.cos(theta)) if mu < p["tan_theta"] else 0.0
    accel = fit["accel"] if math.isfinite(fit["accel"]) else None  # None: too few steps
    return {
        "mu": mu,
        "accel": accel,
        "accel_analytic": analytic,
        "accel_rel_error": (
            abs(accel - analytic) / analytic if analytic > 0 and accel is not None else None
        ),
        "accel_abs_error": abs(accel - analytic) if accel is not None else None,
        "max_speed": float(max(speed[1:], default=float("nan"))),
        "final_speed": float(speed[-1]),
        "fit_window_s": fit["fit_window_s"],
        "fit_rms_m": fit["fit_rms_m"],
        "steps": len(tau) - 1,
        "error": error,
        "newton_iterations": newton,
        "friction_iterations_max": friction_max,
        "friction_converged": friction_ok,
        "min_distance_m": min_d if math.isfinite(min_d) else None,
        "wall_s": wall,
        "series": {"tau_s": tau, "speed_along_m_s": v_along},
    }


# ----------------------------------------------------------------------------- blocks
#: the blocks' material: E = 1e5 Pa, nu = 0.3, 1000 kg/m^dim
_BLOCK = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)


def fem_block_scene(dim: int, n: tuple[int, ...]) -> bfemp.Scene:
    """A Neo-Hookean FEM block (``_BLOCK``) of ``n`` cells per axis, h = 1 / n[-1] m, its x = 0
    face fixed, under gravity (``perf_fem``, the solver tests)."""
    h = 1.0 / n[-1]
    shape = bfemp.shapes.rectangle if dim == 2 else bfemp.shapes.box
    mesh = shape((0.0,) * dim, tuple(k * h for k in n), h=h)
    scene = bfemp.Scene(dim=dim, gravity=(0.0,) * (dim - 1) + (-9.81,))
    fixed = mesh.points[:, 0] < 1e-9
    scene.add_fem(
        mesh, material=_BLOCK, prescribed=bfemp.motion.Fixed(), prescribed_nodes=fixed, name="block"
    )
    return scene


def mpm_block_scene(dim: int, cells: tuple[int, ...], ppc: int) -> bfemp.Scene:
    """A Neo-Hookean MPM block (``_BLOCK``) of ``cells`` grid cells (dx = 1 / cells[0] m),
    ``ppc`` particles per cell, on a slip floor under gravity (``perf_mpm``)."""
    dx = 1.0 / cells[0]
    upper = tuple(c * dx for c in cells)
    x, vol = bfemp.sample.box((0.0,) * dim, upper, dx=dx, ppc=ppc)
    scene = bfemp.Scene(dim=dim, gravity=(0.0,) * (dim - 1) + (-9.81,))
    scene.add_mpm(x, vol, material=_BLOCK)
    scene.set_grid(dx=dx)
    normal = (0.0,) * (dim - 1) + (1.0,)
    scene.add_boundary(bfemp.levelset.HalfPlane(point=(0.0,) * dim, normal=normal), "slip")
    return scene
