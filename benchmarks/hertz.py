"""Brazilian disk test (BFEMP paper, section 6.3, figure 10): contact force against contact width.

A 2D elastic MPM disk (R = 1 m, E = 1e10 Pa, nu = 0.3, rho = 100 kg/m^2, plane strain) lies
between two FEM plates (4 vertices, 2 triangles each): the bottom one fixed d-hat below the
disk, the top one d-hat above it moving down at 0.1 m/s. Barrier contact with dhat = 1e-4 m,
kappa = 1e4 Pa, mu = 1; backward Euler, dt = 1e-2 s; no gravity; APIC. Both
``bfemp.LinearElastic`` and ``bfemp.NeoHookean``.

Metric. After every step: the force F on the bottom plate (N per unit thickness: minus the
y-sum of ``sim.contact_forces()`` over its nodes) and the contact half-width a, half the
horizontal range of the particles within d-hat of the plate (paper, after its ref. [85]).
Plane Hertz contact of a cylinder on a rigid flat (eq. 39): ``F = C_hertz a^2`` with
``C_hertz = pi E / (4 (1 - nu^2) R)``. ``C_fit`` is the least-squares ``F = C a^2`` over the
samples with ``2 dx <= a <= 0.15 R``, ``rel_error = |C_fit / C_hertz - 1|`` (JSON
``materials.<name>``; the (F, a) samples under ``samples``). The range: Hertz is a small-strain
half-space theory (contact strain ~ a / 2R, 7.5 % at a = 0.15 R); below two cells per
half-width the contact is shaped by the grid's quadratic B-splines, not by the elasticity (the
a^4 weight of a sample in the fit makes the small-a end matter little anyway).
``C_fit_interpolated`` uses a to sub-particle resolution instead (on the rim, the x where the gap
crosses d-hat, interpolated between the last particle within d-hat and the first beyond): it
separates the particles' quantisation of a from the error of the simulation.

Full mode adds a grid sweep (``grid_convergence``: linear disk, dx in ``SWEEP_DX``, quick
settings with dt = ``SWEEP_DT``) and extrapolates C_fit / C_hertz to dx = 0 along a straight
line. Measured results, what limits the accuracy and why each choice below was made:
``benchmarks/records/hertz.md``.

Choices where the paper is silent or the library forces a change (recorded in the JSON):

- Particles: concentric rings (``_disk_particles``), not the sub-cell lattice of
  ``bfemp.sample`` (a flat punch). Interior rings have spacing s radially and along the arc
  (full mode: s = sqrt(pi R^2 / 42920), the paper's count; 45939 particles in all); the rim is
  ``boundary_refine`` = 4 times finer both ways (isotropic particles keep the barrier weight
  2 sqrt(V / pi) per unit length), so the contact surface is at R - s / 8 and a steps by s / 4.
  Ring areas are exact: the volumes sum to pi R^2.
- The disk centre is a quarter cell right of a grid node (``grid_offset_cells``): centred on a
  node, both edges pass the knots at once and a jumps by a cell; staggered, the edges jump in
  turn (same mean, half the scatter).
- Top plate (the paper's is fully scripted, a rigid plate): only the plate's
  top face (2 of its 4 vertices) is scripted; its contact face is made of the 2 free vertices
  (unknowns, CCD-checked) and the plate is linear elastic with 1000 x the disk's E (it shortens
  ~1e-6 m under the largest load). The bottom plate is fixed and fully scripted.
- Plates 2.4 m x 0.2 m; initial gaps d-hat (1 + 1e-6) (at exactly d-hat the initial-state
  validation finds the nearest particle within d-hat by round-off); eps_v = 1e-5 m/s.
- Newton tolerance 1e-6 m/s (1e-4 d-hat per step), not the paper's 1e-8 m/s (a round-off
  stall).
- Full mode at the paper's grid (t_end 0.6 s: a/R up to ~0.14). Quick mode and the sweep take
  coarser steps and looser tolerances (``_FAST``): the compression is quasi-static (waves cross
  the disk in 2e-4 s). mu stays 1 (frictionless plates leave the disk a neutral, rolling mode).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks import catalogue
from benchmarks._penetration import penetration_summary
from benchmarks._shared import check_settings
from benchmarks.common import figure, log_row, save
from benchmarks.runner import Benchmark, register

log = logging.getLogger(__name__)

NAME = "hertz"
RADIUS = 1.0  # m
E, NU, RHO = 1e10, 0.3, 100.0  # Pa, -, kg/m^2 (2D)
DHAT, KAPPA, MU, EPS_V = 1e-4, 1e4, 1.0, 1e-5  # m, Pa, -, m/s
SPEED = 0.1  # m/s, top plate downwards
PLATE_HALF_WIDTH, PLATE_THICKNESS = 1.2, 0.2  # m
PLATE_STIFFNESS_RATIO = 1e3  # top plate E / disk E
GAP_FACTOR = 1.0 + 1e-6  # initial plate gaps: dhat * GAP_FACTOR
FIT_MAX_A_OVER_R = 0.15
FIT_MIN_CELLS = 2.0
TARGET_REL_ERROR = 0.15
PAPER = {
    "particles": 42920,
    "dx": 0.025,
    "dt": 1e-2,
    "tol_m_s": 1e-8,
    "result": "qualitative match with Hertz in the small-deformation range (figure 10)",
}
MATERIALS = {"linear": bfemp.LinearElastic, "neo_hookean": bfemp.NeoHookean}

#: Quick-mode settings (and, with dt = 3e-2, those of the full mode's grid sweep): coarse
#: steps and a loose Newton tolerance for a quasi-static compression (see the module docstring).
_FAST = dict(
    boundary_refine=4,
    dt=6e-2,
    t_end=0.6,
    tol=1e-4,
    max_newton_iterations=500,
    mu=MU,
    eps_v=1e-3,
    grid_offset_cells=0.25,
)
MODES = {
    "full": dict(
        _FAST,
        dx=0.025,
        spacing=math.sqrt(math.pi * RADIUS**2 / PAPER["particles"]),
        dt=1e-2,
        tol=1e-6,
        max_newton_iterations=1000,
        eps_v=EPS_V,
    ),
    "quick": dict(dx=0.02, spacing=0.01, **_FAST),
}
#: One grid step finer than the paper's: the full settings at dx = 0.02 m, particle spacing
#: scaled with dx. Written to ``hertz_refined.json``; ``full`` stays the paper's grid.
MODES["refined"] = {**MODES["full"], "dx": 0.02, "spacing": MODES["full"]["spacing"] * 0.8}
#: The softened disk of the trade study (``benchmarks.tradeoff``, scene ``hertz_soft``: the
#: explicit strategies beside barrier): E = 1e5 Pa (an explicit stable step of 5.4e-4 s at
#: dx = 0.05 m), kappa scaled with E; the top plate as stiff as the disk, 16 x denser and
#: starting at the push velocity; the fixed plate 1e4 x denser (its nodes weigh in augury's and
#: lr's velocity mixing); a from the particles the bottom plate pushes (``width_from="force"``).
#: Why each, and what was measured: ``benchmarks/records/hertz.md``.
SOFT_E = 1e5  # Pa
SOFT = dict(
    E_Pa=SOFT_E,
    kappa_Pa=KAPPA * SOFT_E / E,
    plate_stiffness_ratio=1.0,
    plate_density_factor=16.0,
    plate_moving_start=True,
    bottom_density_factor=1e4,
    width_from="force",
)
#: ``width_from="force"``: a particle is pushed by the bottom plate when its upward contact force
#: exceeds this fraction of the largest (the rest is round-off)
PUSHED_FRACTION = 1e-9
#: Grid sweep of the full mode: linear material, ``_FAST`` settings with dt = 3e-2, spacing dx/2.
SWEEP_DX = (0.05, 0.04, 1.0 / 30.0, 0.025)
SWEEP_DT = 3e-2


def hertz_constant(radius: float = RADIUS, E: float = E, nu: float = NU) -> float:
    """C of plane Hertz contact ``F = C a^2`` (paper eq. 39) in N/m^3 (F in N/m, a in m)."""
    return math.pi * E / (4.0 * (1.0 - nu**2) * radius)


def _disk_particles(
    radius: float, spacing: float, boundary_refine: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Particles of a disk about the origin on concentric rings (see the module docstring).

    Args:
        radius: disk radius in m.
        spacing: radial and arc spacing of the interior rings in m.
        boundary_refine: the outermost ring is this many times finer (radially and along the arc).

    Returns:
        ``(x (P, 2) in m, volume (P,) in m^2, outer (K,))``: ``outer`` are the indices of the
        outermost ring in order of angle, starting at the bottom particle (x = 0) and going
        counter-clockwise.
    """
    t_b = spacing / boundary_refine
    inner = radius - t_b  # radius of the disk left for the interior rings
    n_rings = max(int(round(inner / spacing)), 1)
    # Ring edges: [R, R - t_b], then n_rings rings of width ~s down to the centre (the last one
    # is the central disk, sampled by 3 particles at half its radius).
    edges = np.concatenate([[radius], inner * (1.0 - np.arange(n_rings + 1) / n_rings)])
    r_out, r_in = edges[:-1], edges[1:]
    r_mid = 0.5 * (r_out + r_in)
    width = r_out - r_in
    counts = np.maximum(np.rint(2.0 * np.pi * r_mid / width), 3).astype(np.int64)
    areas = np.pi * (r_out**2 - r_in**2)
    ring = np.repeat(np.arange(r_mid.size), counts)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    j = np.arange(ring.size) - start[ring]
    # Alternate rings are rotated by half a step; ring 0 has a particle at the bottom (x = 0).
    theta = -0.5 * np.pi + (j + 0.5 * (ring % 2)) * (2.0 * np.pi / counts[ring])
    x = np.stack([r_mid[ring] * np.cos(theta), r_mid[ring] * np.sin(theta)], axis=1)
    volume = (areas / counts)[ring]
    outer = np.arange(counts[0])
    return np.ascontiguousarray(x), volume, outer


def _plate(
    x0: float, x1: float, y0: float, y1: float, h: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A rectangle ``[x0, x1] x [y0, y1]`` (m): 4 vertices ``(4, 2)`` and 2 triangles, or with
    ``h`` (m) one row of ``n = ceil((x1 - x0) / h)`` columns, ``2 (n + 1)`` vertices and ``2 n``
    triangles (nodes every ``(x1 - x0) / n`` along both long faces)."""
    if h is None:
        points = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
        return points, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    n = max(int(math.ceil((x1 - x0) / h - 1e-9)), 1)
    xs = np.linspace(x0, x1, n + 1)
    points = np.concatenate(
        [np.column_stack([xs, np.full(n + 1, y0)]), np.column_stack([xs, np.full(n + 1, y1)])]
    )
    k = np.arange(n)
    lower = np.column_stack([k, k + 1, n + 2 + k])
    upper = np.column_stack([k, n + 2 + k, n + 1 + k])
    return np.ascontiguousarray(points), np.concatenate([lower, upper]).astype(np.int64)


def _scene(cfg: dict, material: str) -> tuple[bfemp.Scene, dict]:
    """The disk between the plates; returns the scene and geometry facts for the measurement.

    ``cfg`` may also set (``SOFT``; absent: the paper's scene) ``E_Pa`` and ``kappa_Pa`` (the
    disk's E and the barrier stiffness, Pa), ``plate_h`` (m, the plates' mesh along x; None:
    2 triangles each), ``plate_stiffness_ratio`` and ``plate_density_factor`` (the top plate's E
    and density over the disk's), ``plate_moving_start`` (the top plate starts at the push
    velocity) and ``bottom_density_factor`` (the fixed plate's density over the disk's).
    """
    x, volume, outer = _disk_particles(RADIUS, cfg["spacing"], cfg["boundary_refine"])
    # The disk centre sits a quarter cell right of a grid node (see the module docstring).
    x[:, 0] += cfg["grid_offset_cells"] * cfg["dx"]
    young = cfg.get("E_Pa", E)  # the softened variant's (SOFT) or the paper's
    disk = MATERIALS[material](E=young, nu=NU, density=RHO)
    scene = bfemp.Scene(dim=2)
    scene.add_mpm(x, volume, material=disk, name="disk")
    dhat = cfg.get("dhat", DHAT)
    gap = dhat * GAP_FACTOR
    y_bottom = float(x[:, 1].min()) - gap  # top face of the bottom plate
    y_top = float(x[:, 1].max()) + gap  # bottom face of the top plate
    w = PLATE_HALF_WIDTH
    plate_h = cfg.get("plate_h")
    points, cells = _plate(-w, w, y_bottom - PLATE_THICKNESS, y_bottom, plate_h)
    # the fixed plate's density only weighs its nodes in augury's and lr's velocity mixing
    heavy = RHO * cfg.get("bottom_density_factor", 1.0)
    rigid = bfemp.LinearElastic(E=young, nu=NU, density=heavy)
    bottom = scene.add_fem(
        points, cells, material=rigid, prescribed=bfemp.motion.Fixed(), name="bottom_plate"
    )
    points, cells = _plate(-w, w, y_top, y_top + PLATE_THICKNESS, plate_h)
    ratio = cfg.get("plate_stiffness_ratio", PLATE_STIFFNESS_RATIO)
    density = RHO * cfg.get("plate_density_factor", 1.0)
    stiff = bfemp.LinearElastic(E=ratio * young, nu=NU, density=density)
    # SOFT: the plate starts at the push velocity (no wave from a plate set moving at once)
    start = (0.0, -SPEED) if cfg.get("plate_moving_start", False) else (0.0, 0.0)
    top = scene.add_fem(
        points,
        cells,
        material=stiff,
        velocity=start,
        prescribed=bfemp.motion.Linear(velocity=(0.0, -SPEED)),
        prescribed_nodes=points[:, 1] > y_top + 0.5 * PLATE_THICKNESS,
        name="top_plate",
    )
    scene.set_grid(dx=cfg["dx"])
    kappa = cfg.get("kappa_Pa", KAPPA)
    scene.set_contact(dhat=dhat, kappa=kappa, mu=cfg["mu"], eps_v=cfg["eps_v"])
    geo = dict(y_bottom=y_bottom, y_top=y_top, outer=outer, bottom=bottom, top=top)
    geo.update(particles=x.shape[0], material=disk, volume=volume)
    return scene, geo


def contact_half_width(x: np.ndarray, y_plate: float, dhat: float) -> float:
    """Half the horizontal range in m of the particles ``x (P, 2)`` within ``dhat`` of the plate
    top face at height ``y_plate`` (0 with fewer than two such particles)."""
    near = x[:, 1] - y_plate < dhat
    if np.count_nonzero(near) < 2:
        return 0.0
    xs = x[near, 0]
    return 0.5 * float(xs.max() - xs.min())


def interpolated_half_width(ring_x: np.ndarray, y_plate: float, dhat: float) -> float:
    """Contact half-width in m from the outermost ring ``ring_x (K, 2)`` (ordered by angle from
    the bottom particle): on each side the x where the gap to the plate crosses ``dhat``,
    interpolated linearly between the last particle within dhat and the first one beyond."""
    gap = ring_x[:, 1] - y_plate
    if gap[0] >= dhat:
        return 0.0
    ends = []
    for order in (np.arange(ring_x.shape[0]), np.r_[0, ring_x.shape[0] - 1 : 0 : -1]):
        g, xs = gap[order], ring_x[order, 0]
        k = int(np.argmax(g >= dhat))  # first particle beyond dhat on this side (k >= 1)
        w = (dhat - g[k - 1]) / (g[k] - g[k - 1])
        ends.append(xs[k - 1] + w * (xs[k] - xs[k - 1]))
    return 0.5 * abs(ends[0] - ends[1])


def fit_constant(a: np.ndarray, force: np.ndarray, lo: float, hi: float) -> tuple[float, int]:
    """Least-squares ``C`` of ``F = C a^2`` over the samples with ``lo <= a <= hi``.

    Args:
        a: half-widths ``(n,)`` in m; force: forces ``(n,)`` in N/m; lo, hi: the fit range in m.

    Returns:
        ``(C in N/m^3, number of samples used)``; C is NaN with fewer than 3 samples.
    """
    sel = (a >= lo) & (a <= hi) & np.isfinite(force)
    if np.count_nonzero(sel) < 3:
        return float("nan"), int(np.count_nonzero(sel))
    a2 = a[sel] ** 2
    return float(np.dot(force[sel], a2) / np.dot(a2, a2)), int(np.count_nonzero(sel))


def stress_force(deformation: np.ndarray, geo: dict, t: float) -> float:
    """The force in N/m between the plates from the disk's stresses alone (any strategy): in
    static equilibrium the integral of the Cauchy stress over the disk equals the sum of
    x (outer) f over the contact forces (tensor virial), so with +F and -F at the bottom and top
    plates ``F = -sum_p sigma_yy,p V_p / (y_top(t) - y_bottom)``.

    Args:
        deformation: the particles' deformation gradients ``(P, 2, 2)``; geo: ``_scene``'s
            facts; t: time in s (the top face is at ``y_top - SPEED t``).
    """
    sigma = geo["material"].cauchy_stress(deformation)
    volume = geo["volume"] * np.linalg.det(deformation)
    gap = geo["y_top"] - SPEED * t - geo["y_bottom"]
    return -float(np.dot(sigma[:, 1, 1], volume)) / gap


#: the float series of ``run_material``'s samples (beside the counts n_contact, newton_iterations)
SAMPLE_KEYS = ("t", "F", "F_top", "F_particles", "lowest_gap", "F_stress", "a", "a_interpolated")


def run_material(cfg: dict, material: str) -> dict:
    """Compress the disk of one material; F and a after every step, and the fits.

    ``cfg["options"]`` (an options object; with ``strategy`` and ``integrator``) runs any
    strategy, else barrier by backward Euler with ``tol`` and ``max_newton_iterations``;
    ``cfg["width_from"] = "force"`` takes a from the particles the bottom plate pushes (``SOFT``).
    Besides F (the bottom plate's contact force) the samples hold ``F_particles`` (the lower
    half's particle contact forces), ``F_stress`` (``stress_force``) and ``lowest_gap`` (m, the
    lowest particle above the plate; < 0: inside it).
    """
    scene, geo = _scene(cfg, material)
    strategy = cfg.get("strategy", "barrier")
    sim = catalogue.simulation(
        scene, cfg, strategy, cfg.get("tol"), cfg.get("max_newton_iterations")
    )
    model = sim.model
    dhat = cfg.get("dhat", DHAT)
    bottom = model.fem_bodies[geo["bottom"]].nodes
    top = model.fem_bodies[geo["top"]].nodes
    lower = sim.state.mpm_x[:, 1] < 0.0  # the disk's lower half (its centre is at y = 0)
    x_mean0 = sim.state.mpm_x[:, 0].mean()
    n_steps = int(round(cfg["t_end"] / sim.dt))
    rows = {k: [] for k in (*SAMPLE_KEYS, "n_contact", "newton", "friction_iterations")}
    error = None
    start = time.perf_counter()
    for _ in range(n_steps):
        report, error = catalogue.step(sim, f"hertz/{material}")
        if error is not None:  # recorded; the samples so far are still fitted
            break
        fem_f, mpm_f = sim.contact_forces()
        x = sim.state.mpm_x
        rows["t"].append(sim.state.t)
        rows["F"].append(-float(fem_f[bottom, 1].sum()))
        rows["F_particles"].append(float(mpm_f[lower, 1].sum()))
        rows["lowest_gap"].append(float(x[:, 1].min() - geo["y_bottom"]))  # < 0: inside the plate
        rows["F_stress"].append(stress_force(sim.state.mpm_F, geo, sim.state.t))
        rows["F_top"].append(float(fem_f[top, 1].sum()))
        if cfg.get("width_from") == "force":  # any strategy: the particles the plate pushes
            pushed = lower & (mpm_f[:, 1] > PUSHED_FRACTION * max(float(mpm_f[:, 1].max()), 0.0))
            xs = x[pushed, 0]
            rows["a"].append(0.5 * float(xs.max() - xs.min()) if xs.size >= 2 else 0.0)
            rows["n_contact"].append(int(np.count_nonzero(pushed)))
        else:
            rows["a"].append(contact_half_width(x, geo["y_bottom"], dhat))
            rows["n_contact"].append(int(np.count_nonzero(x[:, 1] - geo["y_bottom"] < dhat)))
        rows["a_interpolated"].append(
            interpolated_half_width(x[geo["outer"]], geo["y_bottom"], dhat)
        )
        rows["newton"].append(report.newton_iterations)
        rows["friction_iterations"].append(report.friction_iterations)
        log_row(
            log,
            f"hertz/{material} t={sim.state.t:.3f}",
            {k: v[-1] for k, v in rows.items()},
            "F a a_interpolated newton",
        )
    wall = time.perf_counter() - start
    s = {k: np.asarray(v, dtype=np.float64) for k, v in rows.items()}
    c_h = hertz_constant(E=cfg.get("E_Pa", E))
    lo, hi = FIT_MIN_CELLS * cfg["dx"], FIT_MAX_A_OVER_R * RADIUS
    c_fit, n_fit = fit_constant(s["a"], s["F"], lo, hi)
    c_int, n_int = fit_constant(s["a_interpolated"], s["F"], lo, hi)
    dist = sim.metrics.column("min_distance")[1:]
    balance = np.abs(s["F"] - s["F_top"]) / np.maximum(np.abs(s["F"]), 1e-300)
    return {
        "C_fit": c_fit,
        "C_hertz": c_h,
        "rel_error": abs(c_fit / c_h - 1.0),
        "C_fit_over_C_hertz": c_fit / c_h,
        "fit_samples": n_fit,
        "C_fit_interpolated": c_int,
        "rel_error_interpolated": abs(c_int / c_h - 1.0),
        "fit_samples_interpolated": n_int,
        "a_max_over_R": float(s["a"].max() / RADIUS) if s["a"].size else 0.0,
        "force_balance_max": float(balance[s["F"] > 0].max()) if (s["F"] > 0).any() else 0.0,
        "min_distance": float(np.nanmin(dist)) if np.isfinite(dist).any() else float("nan"),
        "disk_drift_x_m": float(sim.state.mpm_x[:, 0].mean() - x_mean0),
        "error": error,
        "steps": int(s["t"].size),
        "wall_s": wall,
        "dt_s": float(sim.dt),
        "newton_iterations": int(s["newton"].sum()),
        "newton_iterations_max": int(s["newton"].max()) if s["newton"].size else 0,
        "friction_iterations": int(s["friction_iterations"].sum()),
        "particles": int(geo["particles"]),
        # the shared penetration_depth column's largest value and the strategy's bound (issue 40)
        **penetration_summary(sim),
        "samples": {
            **{k: s[k].tolist() for k in SAMPLE_KEYS},
            "n_contact": s["n_contact"].astype(int).tolist(),
            "newton_iterations": s["newton"].astype(int).tolist(),
        },
    }


#: the keys of a ``run_point`` settings dict (the trade study's knobs and fixed settings)
POINT_KEYS = tuple(
    "dx spacing dt dhat eps_v tol strategy material mu t_end max_newton_iterations "
    "boundary_refine grid_offset_cells".split()
)


def run_point(settings: dict) -> dict:
    """Compress the disk of one material at one setting of the discretisation knobs
    (``benchmarks.tradeoff``).

    Args:
        settings: every key of ``POINT_KEYS``: grid ``dx`` (m), particle ``spacing`` (m, interior
            rings), time step ``dt`` (s), barrier ``dhat`` (m; also the distance that defines
            the contact width), friction ``eps_v`` (m/s), Newton ``tol`` (m/s), the library's
            ``strategy`` name, ``material`` (a key of ``MATERIALS``), friction ``mu``, ``t_end``
            (s), ``max_newton_iterations``, ``boundary_refine`` and ``grid_offset_cells``.

    Returns:
        JSON-ready scalars of ``run_material`` (no samples): ``rel_error`` =
        ``|C_fit / C_hertz - 1|`` (NaN with fewer than 3 samples in the fit range),
        ``C_fit_over_C_hertz``, ``fit_samples``, ``steps``, ``newton_iterations``,
        ``particles``, and the ``StepError`` message in ``failure``.
    """
    check_settings("hertz.run_point", settings, POINT_KEYS)
    if settings["material"] not in MATERIALS:
        raise ValueError(
            f"hertz: settings.material must be one of {sorted(MATERIALS)}, "
            f"got {settings['material']!r}"
        )
    run = run_material(dict(settings), settings["material"])
    out = {k: v for k, v in run.items() if k not in ("samples", "error")}
    out["failure"] = run["error"]
    return out


def _grid_sweep() -> dict:
    """C_fit / C_hertz of the linear disk against the grid spacing (``_FAST``, dt = SWEEP_DT).

    Returns the per-dx results and the straight-line extrapolation of C_fit / C_hertz to dx = 0
    (the error is close to first order in dx: the contact edge is resolved to a fraction of a
    cell by the quadratic B-spline displacement field).
    """
    rows = []
    for dx in SWEEP_DX:
        r = run_material(dict(_FAST, dx=dx, spacing=0.5 * dx, dt=SWEEP_DT), "linear")
        keys = ("fit_samples", "particles", "steps", "newton_iterations", "wall_s", "error")
        rows.append(
            {
                "dx": dx,
                "C_fit_over_C_hertz": r["C_fit_over_C_hertz"],
                "C_fit_interpolated_over_C_hertz": r["C_fit_interpolated"] / r["C_hertz"],
                **{k: r[k] for k in keys},
            }
        )
    dx = np.array([row["dx"] for row in rows])
    ratio = np.array([row["C_fit_over_C_hertz"] for row in rows])
    ok = np.isfinite(ratio)
    slope, intercept = np.polyfit(dx[ok], ratio[ok], 1) if ok.sum() >= 2 else (np.nan, np.nan)
    return {
        "material": "linear",
        "settings": {**_FAST, "dt": SWEEP_DT, "spacing": "dx / 2"},
        "runs": rows,
        "linear_fit": {"intercept_dx0": float(intercept), "slope_per_m": float(slope)},
        "wall_s": float(sum(row["wall_s"] for row in rows)),
    }


def plot(payload: dict, path: Path) -> None:
    """Figure 10 style: F against a (both materials, Hertz, fits); F against the plate travel;
    with the full mode's grid sweep, C_fit / C_hertz against the grid spacing."""
    runs, cfg, sweep = payload["_runs"], MODES[payload["mode"]], payload["grid_convergence"]
    title = f"Brazilian disk (MPM) between FEM plates, {payload['mode']} mode"
    fig, axes = figure((16.0 if sweep else 11.0, 4.8), 1, 3 if sweep else 2, layout="constrained")
    c_h = hertz_constant()
    a_max = max(max(r["samples"]["a"], default=0.0) for r in runs.values())
    a_line = np.linspace(0.0, max(a_max, 1e-3) * 1.05, 200)
    axes[0].plot(a_line, c_h * a_line**2, "k-", lw=2, label="Hertz: pi E a^2 / (4 (1 - nu^2) R)")
    lo, hi = FIT_MIN_CELLS * cfg["dx"], FIT_MAX_A_OVER_R * RADIUS
    axes[0].axvspan(lo, hi, color="0.9", zorder=0, label="fit range")
    for k, (name, run) in enumerate(runs.items()):
        s = {key: np.asarray(v) for key, v in run["samples"].items()}
        fit = f"{name} fit: C = {run['C_fit_over_C_hertz']:.3f} C_hertz"
        axes[0].plot(s["a"], s["F"], "o", ms=4, color=f"C{k}", label=f"{name}, a of particles")
        axes[0].plot(s["a_interpolated"], s["F"], "x", ms=4, color=f"C{k}", alpha=0.6)
        axes[0].plot(a_line, run["C_fit"] * a_line**2, "--", color=f"C{k}", label=fit)
        axes[1].plot(SPEED * s["t"] * 1e3, s["F"], "-", color=f"C{k}", label=name)
        if sweep:
            axes[2].plot(cfg["dx"], run["C_fit_over_C_hertz"], "s", color=f"C{k}", label=name)
    labels = (
        ("contact half-width a [m] (x: interpolated)", "contact force F [N/m]", "F against a"),
        ("top plate travel [mm]", "force on the bottom plate F [N/m]", "compression"),
        ("grid spacing dx [m]", "C_fit / C_hertz", "grid convergence (linear disk)"),
    )
    if sweep:
        dx = np.array([row["dx"] for row in sweep["runs"]])
        ratio = [row["C_fit_over_C_hertz"] for row in sweep["runs"]]
        c0, slope = sweep["linear_fit"]["intercept_dx0"], sweep["linear_fit"]["slope_per_m"]
        line = np.linspace(0.0, dx.max() * 1.05, 50)
        axes[2].plot(dx, ratio, "o", color="C2", label=f"sweep, dt = {SWEEP_DT:g} s")
        axes[2].plot(line, c0 + slope * line, "C2:", label=f"straight line: {c0:.3f} at dx = 0")
        band = (1.0 - TARGET_REL_ERROR, 1.0 + TARGET_REL_ERROR)
        axes[2].axhspan(*band, color="0.9", zorder=0, label="target band")
        axes[2].axhline(1.0, color="k", lw=1)
        axes[2].set_xlim(left=0.0)
    for ax, (xlabel, ylabel, name) in zip(axes, labels, strict=False):
        ax.set(xlabel=xlabel, ylabel=ylabel)
        ax.set_title(name, fontsize="medium")
    save(fig, path, axes, title, legend="x-small")


def measure(mode: str, cfg: dict) -> dict:
    """Both materials: ``"full"`` (paper resolution, with the grid sweep), ``"refined"`` (the
    full settings at dx = 0.02 m, no sweep; recorded as ``hertz_refined``) or ``"quick"``
    (coarse steps on the refined grid, ~3 min)."""
    runs = {name: run_material(cfg, name) for name in MATERIALS}
    sweep = _grid_sweep() if mode == "full" else None
    materials = {name: {k: v for k, v in r.items() if k != "samples"} for name, r in runs.items()}
    log.info(
        "hertz: C_fit / C_hertz = %s",
        {k: round(r["C_fit_over_C_hertz"], 4) for k, r in runs.items()},
    )
    return {
        "materials": materials,
        "samples": {name: r["samples"] for name, r in runs.items()},
        "fit_range_m": [FIT_MIN_CELLS * cfg["dx"], FIT_MAX_A_OVER_R * RADIUS],
        "target": f"|C_fit / C_hertz - 1| < {TARGET_REL_ERROR} for both materials",
        "target_met": all(r["rel_error"] < TARGET_REL_ERROR for r in runs.values()),
        "grid_convergence": sweep,
        "steps": max(r["steps"] for r in runs.values()),
        "steps_total": sum(r["steps"] for r in runs.values()),
        "wall_s": sum(r["wall_s"] for r in runs.values()) + (sweep["wall_s"] if sweep else 0.0),
        "newton_iterations": sum(r["newton_iterations"] for r in runs.values()),
        "paper": PAPER,
        "parameters": {
            **cfg,
            "radius_m": RADIUS,
            "E_Pa": E,
            "nu": NU,
            "density_kg_m2": RHO,
            "dhat_m": DHAT,
            "kappa_Pa": KAPPA,
            "gravity": 0.0,
            "integrator": "backward_euler",
            "transfer": "apic",
            "plate_speed_m_s": SPEED,
            "plate_half_width_m": PLATE_HALF_WIDTH,
            "plate_thickness_m": PLATE_THICKNESS,
            "top_plate": "top face scripted, contact face free, E = "
            f"{PLATE_STIFFNESS_RATIO:g} x disk (library workaround, see docstring)",
            "initial_gap_m": DHAT * GAP_FACTOR,
            "sampling": "concentric rings, outermost ring boundary_refine x finer",
            "particles": next(iter(runs.values()))["particles"],
            "fit": "least squares F = C a^2 over fit_range_m",
        },
        "_runs": runs,
    }


BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        MODES,
        measure,
        plot=plot,
        record=lambda mode, options: f"{NAME}_refined" if mode == "refined" else NAME,
    )
)
run = BENCHMARK.run
