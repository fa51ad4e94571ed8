"""Cases of the ``extremes`` benchmark: one base scene and one knob varied per case.

Base scene (2D, plane strain, no gravity, no friction): a free FEM slab ``[-0.3, 0.7] x [-0.2, 0]``
m at rest and an MPM block ``[0, 0.4] x [0, 0.2]`` m (``ppc = 4``) above it, falling at 40 m/s. The
lowest particle starts ``2 dhat + 1 mm`` above the slab (more than dhat: no barrier at t = 0). Both
bodies Neo-Hookean, E = 1e8 Pa, nu = 0.3, rho = 1000 kg/m^3; barrier contact dhat = 1e-3 m (1e-3
of the scene size L = 1 m, the slab width), kappa = 1e7 Pa; backward Euler, APIC, dt = 1e-4 s,
Newton tolerance 1e-6 m/s, at most 200 Newton iterations per step. Quick mode: grid dx = FEM h =
0.05 m (128 particles, 160 triangles), 2 ms (20 steps at the base dt, at least 3 steps); full
mode: dx = h = 0.025 m (512 particles, 640 triangles), 10 ms (100 steps at the base dt, at least
10 steps). The block touches the slab in the first step and leaves it after about 1.4 ms.

Each case changes one knob of the base (see ``CASES``); choices where the issue is silent:

- mass ratios change both densities at a fixed geometric mean of 1000 kg/m^3:
  rho_mpm = 1000 sqrt(r), rho_fem = 1000 / sqrt(r);
- grazing: the block starts at x = -0.2 m and moves at 40 m/s, 3 degrees below the horizontal,
  for 4 ms (quick) / 20 ms (full); the friction variant uses mu = 0.5, eps_v = 1e-3 m/s;
- corner first: the MPM block rotated by 45 degrees (its corner hits the slab's face), or the FEM
  body replaced by a free 0.4 m square rotated by 45 degrees, its corner hitting the block's face;
- vertex: the slab moves by dx/4 so that every other particle column lies exactly (bit for bit)
  above a top vertex of the slab;
- cell_centre: the block moves by -dx/4 so that its particle columns lie on grid lines and on
  grid-cell centres, where a quadratic B-spline stencil holds nodes of weight exactly 0;
- kappa far too small: 1 Pa (stopping the block would need d / dhat below the smallest double);
  far too large: 1e16 Pa (1e8 times E);
- newmark_coarse: Newmark at dx = h = 0.05 m in both modes; implicit_contact and
  implicit_contact_coarse: the same two with ``"newmark_implicit_contact"``;
- resting: the slab fixed, gravity 9.81 m/s^2, the block at rest, dt = 5e-3 s, 0.5 s (quick) /
  5 s (full) = 100 / 1000 steps.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

import bfemp

SCENE_SIZE = 1.0  # m: the slab width, the length d-hat is measured against
SPEED = 40.0  # m/s
GRAZING_ANGLE = 3.0  # degrees between the block's velocity and the slab's top face
GRAVITY = 9.81  # m/s^2 (resting case only)

#: per mode: grid dx = FEM h in m, the least number of steps of any case, duration factor
MODES = {
    "quick": dict(dx=0.05, min_steps=3, duration_factor=1.0),
    "full": dict(dx=0.025, min_steps=10, duration_factor=5.0),
}

GEOMETRIES = ("drop", "grazing", "corner_mpm", "corner_fem", "vertex", "cell_centre", "resting")


@dataclass(frozen=True, kw_only=True)
class CaseConfig:
    """The knobs of one case (SI units).

    Attributes:
        E: Young's modulus of both bodies in Pa.
        nu: Poisson ratio of both bodies.
        density_ratio: rho_mpm / rho_fem at a geometric mean density of 1000 kg/m^3.
        dt: time step in s.
        dhat_rel: d-hat as a fraction of the scene size (1 m).
        kappa: barrier stiffness in Pa, or ``"auto"``.
        mu: friction coefficient (0: no friction term).
        eps_v: static friction velocity threshold in m/s.
        geometry: one of ``GEOMETRIES``.
        integrator: ``"backward_euler"``, ``"newmark"`` or ``"newmark_implicit_contact"``.
        duration: simulated time in quick mode in s.
        duration_full: simulated time in full mode in s (None: ``duration`` times the mode's
            ``duration_factor``).
        tol: Newton tolerance on ``||p||_inf / dt`` in m/s.
        max_newton_iterations: Newton cap per step.
        dx: grid cell size = FEM edge length in m (None: the mode's).
    """

    E: float = 1e8
    nu: float = 0.3
    density_ratio: float = 1.0
    dt: float = 1e-4
    dhat_rel: float = 1e-3
    kappa: float | str = 1e7
    mu: float = 0.0
    eps_v: float = 1e-3
    geometry: str = "drop"
    integrator: str = "backward_euler"
    duration: float = 2e-3
    duration_full: float | None = None
    tol: float = 1e-6
    max_newton_iterations: int = 200
    dx: float | None = None

    def __post_init__(self) -> None:
        if self.geometry not in GEOMETRIES:
            raise ValueError(f"CaseConfig.geometry must be one of {GEOMETRIES}")

    @property
    def dhat(self) -> float:
        """d-hat in m."""
        return self.dhat_rel * SCENE_SIZE

    def as_dict(self) -> dict:
        """The knobs, JSON-ready."""
        return asdict(self)


@dataclass(frozen=True, kw_only=True)
class Case:
    """One row of the table.

    Attributes:
        name: short identifier.
        group: the knob family (``"stiffness"``, ``"dt"``, ...).
        knob: what differs from the base, in words.
        config: the knobs.
        quick: whether the case is in the quick subset (run by the tests).
        expect: the quick-mode outcome the tests assert: ``"pass"`` or the solver's status name.
    """

    name: str
    group: str
    knob: str
    config: CaseConfig = field(default_factory=CaseConfig)
    quick: bool = False
    expect: str = "pass"


def _case(name: str, group: str, knob: str, quick: bool = False, expect: str = "pass", **kw):
    return Case(
        name=name, group=group, knob=knob, config=CaseConfig(**kw), quick=quick, expect=expect
    )


# fmt: off
CASES: tuple[Case, ...] = (
    _case("base", "base", "the base scene", quick=True),
    _case("E_1e3", "stiffness", "E = 1e3 Pa", quick=True, E=1e3),
    _case("E_1e5", "stiffness", "E = 1e5 Pa", E=1e5),
    _case("E_1e10", "stiffness", "E = 1e10 Pa", E=1e10),
    _case("E_1e12", "stiffness", "E = 1e12 Pa", quick=True, E=1e12),
    _case("nu_0.45", "poisson", "nu = 0.45", nu=0.45),
    _case("nu_0.49", "poisson", "nu = 0.49", nu=0.49),
    _case("nu_0.499", "poisson", "nu = 0.499", quick=True, nu=0.499),
    _case("dt_1e-5", "dt", "dt = 1e-5 s", dt=1e-5),
    _case("dt_1e-3", "dt", "dt = 1e-3 s", dt=1e-3),
    _case("dt_1e-2", "dt", "dt = 1e-2 s", dt=1e-2),
    _case("dt_1e-1", "dt", "dt = 1e-1 s", quick=True, dt=1e-1),
    _case("dhat_1e-2", "dhat", "dhat = 1e-2 L", dhat_rel=1e-2),
    _case("dhat_1e-4", "dhat", "dhat = 1e-4 L", dhat_rel=1e-4),
    _case("dhat_1e-5", "dhat", "dhat = 1e-5 L", dhat_rel=1e-5),
    _case("dhat_1e-6", "dhat", "dhat = 1e-6 L", quick=True, dhat_rel=1e-6),
    _case("mass_1e-4", "mass ratio", "rho_mpm / rho_fem = 1e-4", density_ratio=1e-4),
    _case("mass_1e-2", "mass ratio", "rho_mpm / rho_fem = 1e-2", density_ratio=1e-2),
    _case("mass_1e2", "mass ratio", "rho_mpm / rho_fem = 1e2", density_ratio=1e2),
    _case("mass_1e4", "mass ratio", "rho_mpm / rho_fem = 1e4", quick=True, density_ratio=1e4),
    _case("grazing", "geometry", "velocity 3 deg off the face", geometry="grazing", duration=4e-3),
    _case("corner_mpm", "geometry", "MPM block corner first (45 deg)", geometry="corner_mpm"),
    _case("corner_fem", "geometry", "FEM square corner first (45 deg)", geometry="corner_fem"),
    _case("vertex", "geometry", "particles exactly over FEM vertices", quick=True,
          geometry="vertex"),
    _case("cell_centre", "geometry", "particle columns on grid-cell centres (zero B-spline "
          "weights)", geometry="cell_centre"),
    _case("kappa_1e0", "kappa", "kappa = 1 Pa (far too small)", quick=True,
          expect="MAX_ITERATIONS", kappa=1.0),
    _case("kappa_1e16", "kappa", "kappa = 1e16 Pa (far too large)", quick=True, kappa=1e16),
    _case("kappa_auto", "kappa", 'kappa = "auto"', kappa="auto"),
    _case("resting", "drift", "block resting on a fixed slab under gravity, dt = 5e-3 s",
          quick=True, geometry="resting", dt=5e-3, duration=0.5, duration_full=5.0),
    _case("newmark", "integrator", "Newmark (average acceleration)", integrator="newmark"),
    _case("newmark_coarse", "integrator", "Newmark, dx = h = 0.05 m (the quick resolution) in "
          "every mode", integrator="newmark", dx=0.05),
    _case("implicit_contact", "integrator", "Newmark with implicit contact (memory-free contact "
          "forces)", integrator="newmark_implicit_contact"),
    _case("implicit_contact_coarse", "integrator", "Newmark with implicit contact, dx = h = 0.05 "
          "m in every mode (newmark_coarse's setting)", integrator="newmark_implicit_contact",
          dx=0.05),
    _case("grazing_friction", "friction", "grazing with mu = 0.5", geometry="grazing", mu=0.5,
          duration=4e-3),
)
# fmt: on


def quick_cases() -> tuple[Case, ...]:
    """The quick subset."""
    return tuple(c for c in CASES if c.quick)


def n_steps(
    config: CaseConfig, mode: str, *, dt: float | None = None, duration: float | None = None
) -> int:
    """Steps of a case in a mode: the duration over dt, at least the mode's ``min_steps``.

    ``dt`` (s) replaces the case's (an explicit strategy's stable step), ``duration`` (s) the
    mode's duration of the case.
    """
    m = MODES[mode]
    if duration is None:
        duration = config.duration * m["duration_factor"]
        if mode == "full" and config.duration_full is not None:
            duration = config.duration_full
    dt = config.dt if dt is None else dt
    return max(m["min_steps"], math.ceil(duration / dt - 1e-9))


def _rotate(points: np.ndarray, center: np.ndarray, angle: float) -> np.ndarray:
    """Points ``(n, 2)`` rotated by ``angle`` rad about ``center (2,)``."""
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    return (points - center) @ rot.T + center


def build_scene(config: CaseConfig, mode: str) -> tuple[bfemp.Scene, dict]:
    """The scene of a case and a description of its geometry (for the record).

    Returns ``(scene, info)``; ``info`` holds ``energy_ref_J`` for the resting case (the block's
    weight times its height, J/m) and the sizes.
    """
    dx = MODES[mode]["dx"] if config.dx is None else config.dx
    dhat = config.dhat
    geometry = config.geometry
    resting = geometry == "resting"
    rho_mpm = 1000.0 * math.sqrt(config.density_ratio)
    rho_fem = 1000.0 / math.sqrt(config.density_ratio)
    mat_mpm = bfemp.NeoHookean(E=config.E, nu=config.nu, density=rho_mpm)
    mat_fem = bfemp.NeoHookean(E=config.E, nu=config.nu, density=rho_fem)
    scene = bfemp.Scene(dim=2, gravity=(0.0, -GRAVITY) if resting else None)

    if geometry == "corner_fem":
        square = bfemp.shapes.rectangle((-0.2, -0.2), (0.2, 0.2), h=dx)
        pts = _rotate(square.points, np.zeros(2), math.pi / 4.0)
        pts = pts + np.array([0.2, -pts[:, 1].max()])  # top corner at (0.2, 0)
        fem_points, fem_cells = pts, square.cells
    else:
        # vertex, cell_centre: the slab moves by dx/4 so that its top vertices lie under every
        # other particle column of the base block (vertex), or under none (cell_centre)
        shift = 0.25 * dx if geometry in ("vertex", "cell_centre") else 0.0
        slab = bfemp.shapes.rectangle((-0.3 + shift, -0.2), (0.7 + shift, 0.0), h=dx)
        fem_points, fem_cells = slab.points, slab.cells
    fem_kw = dict(prescribed=bfemp.motion.Fixed()) if resting else {}
    scene.add_fem(fem_points, fem_cells, material=mat_fem, name="fem", **fem_kw)

    x0 = -0.2 if geometry.startswith("grazing") else 0.0
    x, vol = bfemp.sample.box((x0, 0.0), (x0 + 0.4, 0.2), dx=dx, ppc=4)
    if geometry == "cell_centre":
        # particle columns on grid lines and on grid-cell centres (x = k dx / 2, grid origin 0):
        # a quadratic B-spline stencil then holds nodes at exactly 1.5 dx, of weight exactly 0
        x[:, 0] -= 0.25 * dx
    if geometry == "corner_mpm":
        x = _rotate(x, np.array([x0 + 0.2, 0.1]), math.pi / 4.0)
    snap = np.zeros(x.shape[0], dtype=bool)
    if geometry == "vertex":
        # snap the columns over top vertices to the vertices' x exactly (no round-off offset)
        top = np.sort(fem_points[np.abs(fem_points[:, 1]) < 1e-12, 0])
        right = np.clip(np.searchsorted(top, x[:, 0]), 1, top.size - 1)
        left_closer = x[:, 0] - top[right - 1] < top[right] - x[:, 0]
        nearest = np.where(left_closer, top[right - 1], top[right])
        snap = np.abs(nearest - x[:, 0]) < 1e-9
        x[snap, 0] = nearest[snap]
    top_y = float(fem_points[:, 1].max())
    x[:, 1] += top_y + 2.0 * dhat + 1e-3 - x[:, 1].min()
    if geometry.startswith("grazing"):
        a = math.radians(GRAZING_ANGLE)
        velocity = (SPEED * math.cos(a), -SPEED * math.sin(a))
    elif resting:
        velocity = (0.0, 0.0)
    else:
        velocity = (0.0, -SPEED)
    scene.add_mpm(x, vol, material=mat_mpm, velocity=velocity, name="block")
    scene.set_grid(dx=dx)
    scene.set_contact(dhat=dhat, kappa=config.kappa, mu=config.mu, eps_v=config.eps_v)
    info = {
        "dx": dx,
        "particles": int(x.shape[0]),
        "fem_nodes": int(fem_points.shape[0]),
        "fem_triangles": int(fem_cells.shape[0]),
        "rho_mpm": rho_mpm,
        "rho_fem": rho_fem,
        "velocity": list(velocity),
        "vertex_aligned_particles": int(snap.sum()),
        "energy_ref_J": float(rho_mpm * vol.sum() * GRAVITY * 0.2) if resting else None,
    }
    return scene, info
