"""The conformance catalogue's scenes: small canonical scenes every strategy is run on.

Each case builds a ``bfemp.Scene`` for a mode (``"quick"``: what the tests run; ``"full"``:
longer, for the record) and names the checks that judge it (``benchmarks.conformance``). All
bodies are Neo-Hookean; the soft bodies (E = 100 kPa, 1000 kg/m^3, c ~ 10 m/s) keep the explicit
stable step near 1e-3 s at the 2 cm grid. Fixed plates are fully scripted FEM bodies meshed at
half a grid cell (``lr`` asks for FEM boundary edges <= dx / 2:
docs/design/explicit_strategies.md, sec. 2.6).

- ``drop_2d_mu0``, ``drop_2d_mu0.3``: an MPM disk (r 0.1 m) thrown at (1, -1) m/s onto a fixed
  plate (top y = 0); ``drop_3d_mu0``, ``drop_3d_mu0.3``: an MPM cube (0.2 m) at (0.5, 0, -1) m/s.
  Checks: held (the body stays on the plate), penetration within the strategy's bound.
- ``incline_mpm_*``, ``incline_fem_*``: a 0.1 m block (MPM, or FEM) released from rest 2 mm above
  a fixed plate under gravity tilted by theta = atan(0.5) (the same as a plate inclined by theta,
  with simpler geometry). Coulomb: a = g (sin theta - mu cos theta) for mu < tan theta, else it
  sticks. mu = 0, 0.5 tan theta (a = g sin theta / 2) and 1.5 tan theta (sticks).
- ``impact_*``: two disks of r 0.1 m at 1 m/s each, head-on and oblique (offset 0.1 m), no
  gravity: MPM-MPM, MPM-FEM and FEM-FEM. Checks: linear (and, oblique, angular) momentum, the
  rebound (bodies that a strategy couples by contact separate; by a shared grid, stick).
- ``stack``: a FEM block (0.3 x 0.1 m) 2 mm above a fixed plate and an MPM block (0.1 m) 2 mm
  above it, under gravity. Checks: stacked, penetration, drift (the upper block's speed late).
- ``thin_plate``: an MPM disk (r 0.05 m) at 10 m/s against a fixed plate half a cell thick
  (1 cm), no gravity. Checks: nothing passes the plate, penetration.

The numbers (sizes, speeds, durations) are this catalogue's choices, not from a paper.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

import bfemp

SOFT = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)
STIFF = bfemp.NeoHookean(E=1e7, nu=0.3, density=1000.0)
#: MPM grid spacing of the 2D and 3D cases in m
DX_2D, DX_3D = 0.02, 0.05
DHAT = 1e-3  # m: the barrier's d-hat (barrier and two_stage); every gap starts at >= 2 dhat
KAPPA = 1e5  # Pa
G = 9.81
THETA = math.atan(0.5)  # the incline's angle (tan theta = 0.5)


@dataclass(frozen=True)
class Case:
    """One conformance case.

    Attributes:
        name: case name (``drop_2d_mu0.3``).
        scene: scene family (``drop``, ``incline``, ``impact``, ``stack``, ``thin_plate``).
        dim: 2 or 3.
        t_end: simulated time per mode in s.
        barrier_dt: the implicit strategy's time step in s (explicit ones take ``"auto"``).
        dx: the MPM grid spacing in m (penetration bounds are given in its cells).
        checks: names of the checks that judge this case (``benchmarks.conformance``).
        params: what the checks need (the mover's name, the analytic acceleration, ...).
    """

    name: str
    scene: str
    dim: int
    t_end: dict
    barrier_dt: float
    dx: float
    checks: tuple[str, ...]
    params: dict = field(default_factory=dict)

    def build(self, mode: str) -> bfemp.Scene:
        """The case's scene (the mode changes only the duration)."""
        del mode
        return _BUILDERS[self.scene](self)


def _plate(scene: bfemp.Scene, lower, upper, h: float, name: str = "plate") -> None:
    mesh = (bfemp.shapes.rectangle if len(lower) == 2 else bfemp.shapes.box)(lower, upper, h=h)
    scene.add_fem(mesh, material=STIFF, prescribed=bfemp.motion.Fixed(), name=name)


def _contact(scene: bfemp.Scene, mu: float) -> None:
    scene.set_contact(dhat=DHAT, kappa=KAPPA, mu=mu)


def _drop(case: Case) -> bfemp.Scene:
    mu = case.params["mu"]
    if case.dim == 2:
        scene = bfemp.Scene(dim=2, gravity=(0.0, -G))
        _plate(scene, (-0.4, -0.05), (0.8, 0.0), h=DX_2D / 2)
        disk = bfemp.shapes.disk((0.0, 0.1 + 2 * DX_2D), 0.1, h=DX_2D)
        x, vol = bfemp.sample.mesh(disk, dx=DX_2D, ppc=4)
        scene.add_mpm(x, vol, material=SOFT, velocity=(1.0, -1.0), name="body")
        scene.set_grid(dx=DX_2D)
    else:
        scene = bfemp.Scene(dim=3, gravity=(0.0, 0.0, -G))
        _plate(scene, (-0.3, -0.3, -0.05), (0.6, 0.3, 0.0), h=DX_3D / 2)
        lo, hi = (-0.1, -0.1, 2 * DX_3D / 5), (0.1, 0.1, 0.2 + 2 * DX_3D / 5)
        x, vol = bfemp.sample.box(lo, hi, dx=DX_3D, ppc=8)
        scene.add_mpm(x, vol, material=SOFT, velocity=(0.5, 0.0, -1.0), name="body")
        scene.set_grid(dx=DX_3D)
    _contact(scene, mu)
    return scene


def _incline(case: Case) -> bfemp.Scene:
    mu = case.params["mu"]
    scene = bfemp.Scene(dim=2, gravity=(G * math.sin(THETA), -G * math.cos(THETA)))
    _plate(scene, (-0.2, -0.05), (0.8, 0.0), h=DX_2D / 2)
    lo, hi = (-0.05, 2 * DHAT + 1e-3), (0.05, 0.1 + 2 * DHAT + 1e-3)
    if case.params["body"] == "mpm":
        x, vol = bfemp.sample.box(lo, hi, dx=DX_2D, ppc=4)
        scene.add_mpm(x, vol, material=SOFT, name="body")
        scene.set_grid(dx=DX_2D)
    else:
        block = bfemp.shapes.rectangle(lo, hi, h=DX_2D)
        scene.add_fem(block, material=SOFT, name="body")
    _contact(scene, mu)
    return scene


def _impact(case: Case) -> bfemp.Scene:
    kinds, offset = case.params["kinds"], case.params["offset"]
    scene = bfemp.Scene(dim=2)
    centers = ((-0.12, -offset / 2), (0.12, offset / 2))
    for name, kind, c, v in zip(("a", "b"), kinds, centers, (1.0, -1.0), strict=True):
        disk = bfemp.shapes.disk(c, 0.1, h=DX_2D)
        if kind == "mpm":
            x, vol = bfemp.sample.mesh(disk, dx=DX_2D, ppc=4)
            scene.add_mpm(x, vol, material=SOFT, velocity=(v, 0.0), name=name)
        else:
            scene.add_fem(disk, material=SOFT, velocity=(v, 0.0), name=name)
    if "mpm" in kinds:
        scene.set_grid(dx=DX_2D)
    _contact(scene, 0.0)
    return scene


def _stack(case: Case) -> bfemp.Scene:
    del case
    scene = bfemp.Scene(dim=2, gravity=(0.0, -G))
    _plate(scene, (-0.3, -0.05), (0.3, 0.0), h=DX_2D / 2)
    gap = 2 * DHAT + 1e-3
    lower = bfemp.shapes.rectangle((-0.15, gap), (0.15, 0.1 + gap), h=DX_2D / 2)
    scene.add_fem(lower, material=SOFT, name="lower")
    x, vol = bfemp.sample.box((-0.05, 0.1 + 2 * gap), (0.05, 0.2 + 2 * gap), dx=DX_2D, ppc=4)
    scene.add_mpm(x, vol, material=SOFT, name="body")
    scene.set_grid(dx=DX_2D)
    _contact(scene, 0.3)
    return scene


def _thin_plate(case: Case) -> bfemp.Scene:
    del case
    scene = bfemp.Scene(dim=2)
    _plate(scene, (-0.3, -DX_2D / 2), (0.3, 0.0), h=DX_2D / 4)
    disk = bfemp.shapes.disk((0.0, 0.05 + DX_2D), 0.05, h=DX_2D / 2)
    x, vol = bfemp.sample.mesh(disk, dx=DX_2D, ppc=4)
    scene.add_mpm(x, vol, material=SOFT, velocity=(0.0, -10.0), name="body")
    scene.set_grid(dx=DX_2D)
    _contact(scene, 0.0)
    return scene


_BUILDERS = {
    "drop": _drop,
    "incline": _incline,
    "impact": _impact,
    "stack": _stack,
    "thin_plate": _thin_plate,
}


def _all_cases() -> tuple[Case, ...]:
    out = []
    for dim, dx, t_end, dt in ((2, DX_2D, (0.1, 0.4), 2e-3), (3, DX_3D, (0.06, 0.3), 4e-3)):
        for mu in (0.0, 0.3):
            params = {"mu": mu, "up": dim - 1, "plate_top": 0.0}
            out.append(
                Case(
                    f"drop_{dim}d_mu{mu:g}",
                    "drop",
                    dim,
                    _modes(*t_end),
                    dt,
                    dx,
                    ("held", "penetration"),
                    params,
                )
            )
    a_free = G * math.sin(THETA)
    for body in ("mpm", "fem"):
        for label, mu in (("mu0", 0.0), ("mu0.5tan", 0.25), ("mu1.5tan", 0.75)):
            sticks = mu >= math.tan(THETA)
            exact = 0.0 if sticks else G * (math.sin(THETA) - mu * math.cos(THETA))
            checks = ("held", "penetration", "sticks" if sticks else "acceleration")
            # the block lands within 25 ms; the fit skips the landing's ringing
            params = {
                "mu": mu,
                "body": body,
                "up": 1,
                "plate_top": 0.0,
                "a_exact": exact,
                "a_free": a_free,
                "fit_from": _modes(0.06, 0.1),
            }
            out.append(
                Case(
                    f"incline_{body}_{label}",
                    "incline",
                    2,
                    _modes(0.15, 0.5),
                    2e-3,
                    DX_2D,
                    checks,
                    params,
                )
            )
    for kinds in (("mpm", "mpm"), ("mpm", "fem"), ("fem", "fem")):
        for label, offset in (("head_on", 0.0), ("oblique", 0.1)):
            checks = ("momentum", "rebound", "penetration") + (("angular_momentum",) * bool(offset))
            out.append(
                Case(
                    f"impact_{kinds[0]}_{kinds[1]}_{label}",
                    "impact",
                    2,
                    _modes(0.1, 0.25),
                    1e-3,
                    DX_2D,
                    checks,
                    {"kinds": kinds, "offset": offset},
                )
            )
    out.append(
        Case(
            "stack",
            "stack",
            2,
            _modes(0.15, 0.5),
            2e-3,
            DX_2D,
            ("stacked", "penetration", "drift"),
            {"up": 1, "plate_top": 0.0},
        )
    )
    out.append(
        Case(
            "thin_plate",
            "thin_plate",
            2,
            _modes(0.02, 0.04),
            1e-3,
            DX_2D,
            ("no_pass", "penetration"),
            {"up": 1, "plate_bottom": -DX_2D / 2},
        )
    )
    return tuple(out)


def _modes(quick: float, full: float) -> dict:
    return {"quick": quick, "full": full}


#: every case of the catalogue, in table order
CASES: tuple[Case, ...] = _all_cases()


def cases(names: list[str] | None = None) -> list[Case]:
    """The cases named (all when None); an unknown name is refused with the known ones."""
    if not names:
        return list(CASES)
    known = {c.name: c for c in CASES}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"unknown conformance case(s) {unknown}; known: {sorted(known)}")
    return [known[n] for n in names]


def body_positions(model: bfemp.Model, state: bfemp.State) -> dict[str, np.ndarray]:
    """Positions ``(n, d)`` of each body's FEM nodes or particles, in m."""
    out = {b.name: state.fem_x[b.nodes] for b in model.fem_bodies}
    out.update({b.name: state.mpm_x[b.particles] for b in model.mpm_bodies})
    return out


def body_mass_arrays(model: bfemp.Model) -> dict[str, np.ndarray]:
    """Masses ``(n,)`` of each body's FEM nodes or particles, in kg (per m in 2D)."""
    out = {b.name: model.fem_mass[b.nodes] for b in model.fem_bodies}
    out.update({b.name: model.mpm_mass[b.particles] for b in model.mpm_bodies})
    return out
