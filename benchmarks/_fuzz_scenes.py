"""Random scenes of the fuzz benchmark (``benchmarks.fuzz``, issue 44), one family per class.

A case is a plain dict (JSON; it replays the scene exactly): its ``cls``, its ``seed``, the
``strategy`` and the parameters drawn by the class's ``draw`` from
``numpy.random.default_rng((class index, seed))``. ``build(case)`` makes the ``bfemp.Scene``.
Every class throws a projectile (a FEM or MPM body) at a target FEM body that is free or fixed
(``prescribed=Fixed()``), so that every pair kind a no-crossing strategy couples appears:
FEM-FEM, MPM-deformable FEM, MPM-prescribed FEM, FEM-prescribed FEM. Speeds to 60 m/s, spins
to 60 rad/s, E 1e4 to 1e9 Pa, d-hat 1e-4 to 0.12 m (bodies thinner than 2 d-hat included).

Classes (``CLASSES``):

- ``thin_bar_2d``: a disk at a bar 0.74 m long and 5 mm to 0.1 m thick (issue 44 defect 1).
- ``sliver_2d``: a fan-meshed polygon (12 to 48 triangles meeting at its centre: apex angles
  7.5 to 30 degrees) at a bar meshed by two triangles (aspect ratio 7 to 150).
- ``blocks_2d``: a disk or square at a disk or square, head-on or oblique (issue 12's family).
- ``thin_plate_3d``: a cube at a plate 0.6 x 0.6 m, 10 to 60 mm thick, meshed at 0.1 m (flat
  tetrahedra).
- ``blocks_3d``: a cube at a cube, head-on or oblique.

Sizes are small (tens to hundreds of cells) so that thousands of cases fit in an hour on two
cores.
"""

from __future__ import annotations

import numpy as np

import bfemp
from geometry.mesh import TriMesh

#: the projectile starts d-hat plus this far (m) from the target's near side, for the implicit
#: strategy; explicit strategies start d-hat plus ``EXPLICIT_GAP_STEPS`` steps of closing speed
#: away (``benchmarks.fuzz.run_case``)
GAP_RANGE = (0.02, 0.3)
EXPLICIT_GAP_STEPS = (0.5, 6.0)


def _common(rng: np.random.Generator, dim: int) -> dict:
    """Parameters every class draws: materials, d-hat, speed, direction, spin, what is MPM and
    what is fixed."""
    angle = rng.uniform(-0.6, 0.6, size=dim - 1)  # rad off the straight approach
    return dict(
        dim=dim,
        mpm=bool(rng.random() < 0.5),
        target_fixed=bool(rng.random() < 0.3),
        target_moving=float(rng.uniform(0.0, 20.0)) * float(rng.random() < 0.3),
        dhat=float(10 ** rng.uniform(-4, np.log10(0.12))),
        speed=float(10 ** rng.uniform(np.log10(2.0), np.log10(60.0))),
        angle=[float(a) for a in angle],
        spin=float(rng.uniform(-60.0, 60.0)) * float(rng.random() < 0.4),
        gap=float(rng.uniform(*GAP_RANGE)),  # beyond d-hat (build)
        E=[float(10 ** rng.uniform(4, 9)) for _ in range(2)],
        nu=[float(rng.uniform(0.0, 0.45)) for _ in range(2)],
    )


def _draw_thin_bar_2d(rng):
    c = _common(rng, 2)
    c.update(thickness=float(rng.uniform(0.005, 0.1)), radius=float(rng.uniform(0.05, 0.1)))
    c.update(offset=float(rng.uniform(-0.3, 0.3)))
    return c


def _draw_sliver_2d(rng):
    c = _draw_thin_bar_2d(rng)
    c.update(fan=int(rng.integers(12, 49)))
    return c


def _draw_blocks(dim):
    def draw(rng):
        c = _common(rng, dim)
        c.update(
            size=[float(rng.uniform(0.1, 0.4)) for _ in range(2)],
            round=[bool(rng.random() < 0.5) for _ in range(2)] if dim == 2 else [False, False],
            lateral=[float(v) for v in rng.uniform(-0.8, 0.8, size=dim - 1)]
            if rng.random() < 0.5
            else [0.0] * (dim - 1),
        )
        return c

    return draw


def _draw_thin_plate_3d(rng):
    c = _common(rng, 3)
    c.update(thickness=float(rng.uniform(0.01, 0.06)), size=float(rng.uniform(0.06, 0.15)))
    c.update(offset=[float(v) for v in rng.uniform(-0.2, 0.2, size=2)])
    return c


CLASSES = {
    "thin_bar_2d": _draw_thin_bar_2d,
    "sliver_2d": _draw_sliver_2d,
    "blocks_2d": _draw_blocks(2),
    "thin_plate_3d": _draw_thin_plate_3d,
    "blocks_3d": _draw_blocks(3),
}


def draw_case(cls: str, seed: int, strategy: str) -> dict:
    """The case of class ``cls`` drawn from ``seed`` for ``strategy`` (a JSON-able dict)."""
    if cls not in CLASSES:
        raise ValueError(f"unknown fuzz class '{cls}'; classes: {', '.join(CLASSES)}")
    rng = np.random.default_rng([list(CLASSES).index(cls), seed])  # classes draw apart
    case = CLASSES[cls](rng)
    case.update(cls=cls, seed=int(seed), strategy=strategy)
    # the step: implicit dt log-uniform 1e-4 .. 2 s and an integrator; explicit: CFL fractions
    case["dt"] = float(10 ** rng.uniform(-4, np.log10(2.0)))
    case["integrator"] = str(
        rng.choice(["backward_euler", "newmark", "newmark_damped", "newmark_implicit_contact"])
    )
    case["cfl"] = [float(rng.uniform(0.2, 1.0)) for _ in range(2)]  # FEM, MPM safety
    case["gap_steps"] = float(rng.uniform(*EXPLICIT_GAP_STEPS))
    return case


def _direction(case: dict) -> np.ndarray:
    """Unit approach direction: -y (2D) or -z (3D) turned by the case's angles."""
    d = np.zeros(case["dim"])
    d[-1] = -1.0
    d[: case["dim"] - 1] = np.sin(case["angle"])
    return d / np.linalg.norm(d)


def _velocity(points: np.ndarray, centre: np.ndarray, v: np.ndarray, spin: float) -> np.ndarray:
    """Velocities ``(n, d)`` of a rigid motion: ``v`` plus a spin (rad/s) about the axis normal to
    the plane of the first two coordinates through ``centre``."""
    out = np.tile(v, (points.shape[0], 1))
    r = points - centre
    out[:, 0] += -spin * r[:, 1]
    out[:, 1] += spin * r[:, 0]
    return out


def _fan(centre, radius, n):
    """A polygon of ``n`` sides meshed as a fan from its centre: ``n`` sliver triangles."""
    phi = 2.0 * np.pi * np.arange(n) / n
    rim = np.asarray(centre) + radius * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    points = np.vstack([centre, rim])
    cells = np.stack([np.zeros(n, int), 1 + np.arange(n), 1 + (np.arange(n) + 1) % n], axis=1)
    return TriMesh(points, cells)


def _shapes(case: dict):
    """(projectile mesh, its centre, target mesh, the thinnest feature in m)."""
    cls, dim = case["cls"], case["dim"]
    if cls in ("thin_bar_2d", "sliver_2d"):
        t, r = case["thickness"], case["radius"]
        centre = np.array([case["offset"], 0.5 * t + r + case["gap"]])
        if cls == "sliver_2d":
            projectile = _fan(centre, r, case["fan"])
            target = bfemp.shapes.rectangle((-0.37, -0.5 * t), (0.37, 0.5 * t), h=0.74)
        else:
            projectile = bfemp.shapes.disk(tuple(centre), r, h=0.5 * r)
            target = bfemp.shapes.rectangle((-0.37, -0.5 * t), (0.37, 0.5 * t), h=t)
        return projectile, centre, target, min(t, r)
    if cls == "thin_plate_3d":
        t, a = case["thickness"], case["size"]
        centre = np.array([*case["offset"], 0.5 * t + a + case["gap"]])
        projectile = bfemp.shapes.box(tuple(centre - a), tuple(centre + a), h=2.0 * a)
        target = bfemp.shapes.box((-0.3, -0.3, -0.5 * t), (0.3, 0.3, 0.5 * t), h=0.1)
        return projectile, centre, target, min(t, a)
    # blocks: projectile above the target along the last axis
    a, b = case["size"]
    centre = np.zeros(dim)
    centre[:-1] = np.asarray(case["lateral"]) * (a + b)
    centre[-1] = b + a + case["gap"]
    meshes = []
    for c, s, rnd in ((centre, a, case["round"][0]), (np.zeros(dim), b, case["round"][1])):
        if dim == 2 and rnd:
            meshes.append(bfemp.shapes.disk(tuple(c), s, h=0.6 * s))
        elif dim == 2:
            meshes.append(bfemp.shapes.rectangle(tuple(c - s), tuple(c + s), h=s))
        else:
            meshes.append(bfemp.shapes.box(tuple(c - s), tuple(c + s), h=2.0 * s))
    return meshes[0], centre, meshes[1], min(a, b)


def build(case: dict, gap: float | None = None) -> tuple[bfemp.Scene, float]:
    """The scene of ``case`` and the thinnest feature of its bodies in m (the oracle's sampling
    scale); the projectile starts 1.05 d-hat plus ``gap`` (default the case's) from the
    target."""
    if gap is not None:
        case = {**case, "gap": gap}
    case = {**case, "gap": 1.05 * case["dhat"] + case["gap"]}  # start outside contact
    dim = case["dim"]
    projectile, centre, target, min_feature = _shapes(case)
    scene = bfemp.Scene(dim=dim)
    mat = [bfemp.NeoHookean(E=case["E"][k], nu=case["nu"][k], density=1000.0) for k in range(2)]
    v = case["speed"] * _direction(case)
    if case["mpm"]:
        extent = float(np.ptp(projectile.points, axis=0).max())  # m
        dx = extent / 4.0 if dim == 2 else extent / 2.0  # a few cells across the body
        particles, volumes = bfemp.sample.mesh(projectile, dx=dx, ppc=2**dim)
        vel = _velocity(particles, centre, v, case["spin"])
        scene.add_mpm(particles, volumes, material=mat[0], velocity=vel, name="projectile")
        scene.set_grid(dx=dx, origin=tuple(np.full(dim, 0.13 * dx)))
    else:
        vel = _velocity(projectile.points, centre, v, case["spin"])
        scene.add_fem(projectile, material=mat[0], velocity=vel, name="projectile")
    if case["target_fixed"]:
        scene.add_fem(target, material=mat[1], prescribed=bfemp.motion.Fixed(), name="target")
    else:
        up = np.zeros(dim)
        up[-1] = case["target_moving"]
        scene.add_fem(target, material=mat[1], velocity=tuple(up), name="target")
    scene.set_contact(dhat=case["dhat"])
    return scene, float(min_feature)
