"""``augury_probes``: the 2D probes behind issue 14's diagnosis of ``augury_ramp`` (AUG sec. 3.3).

Three cheap 2D scenes that isolate what the 3D ramp mixes (the kernels work in any dimension):

- ``flat``: a soft block (0.5 x 0.5 m, E 1e6, rho 1000, h 0.1) sliding at 1 m/s over a free slab
  at zero gap, no gravity, mu = 0, grid_dx 0.05 m, dt 1e-4 s, 200 steps: the block's mean
  velocity (x must stay 1 m/s, y 0) per (normals, N).
- ``settled``: the ramp's bodies (block 1 x 1 m, plate 4 x 0.25 m with a fixed bottom, rho 1e6,
  E 1e10, grid 0.5 h, dt 2.5e-5 h) with the grid aligned to the plate: settled under the normal
  part of gravity (100 cos30 m/s^2; velocities and B damped by 1 % a step for ``settle`` s),
  then the downhill part (100 sin30) switched on. The slip (mean downhill displacement of the
  block's bottom nodes minus the plate's top nodes under it) after ``t_end``; sticking needs
  mu > tan30 = 0.577 and a slip near zero. ``zero_B`` zeroes the carried APIC B after every
  step (a probe, not an option: it gives up the exact angular momentum).
- ``energy``: the same scene without settling; the generalised kinetic energy the correction
  adds (sum over steps of max(0, E(V^) - E(V-bar))) with and without the energy guard.

Quick records ``benchmarks/records/augury_probes.json``; the numbers are quoted in
``bfemp.contact.augury``.
"""

from __future__ import annotations

import logging

import numpy as np

import bfemp
import bfemp.steppers.augury as augury_module
from benchmarks.runner import Benchmark, register
from bfemp.steppers.augury import AuguryOptions, AuguryStepper

log = logging.getLogger(__name__)

NAME = "augury_probes"
G = 100.0
THETA = np.deg2rad(30.0)
MODES = {
    "quick": {
        "flat": [(n, k) for n in ("own", "facing") for k in (1, 10, 30)],
        "settled": [
            {"mu": 0.7, "iterations": 1, "normals": "own", "zero_B": False},
            {"mu": 0.7, "iterations": 1, "normals": "own", "zero_B": True},
            {"mu": 0.7, "iterations": 30, "normals": "facing", "zero_B": False},
            {"mu": 0.0, "iterations": 30, "normals": "facing", "zero_B": False},
        ],
        "energy": [(10, False), (10, True), (1, False)],
        "h": 0.5,
        "settle": 0.05,
        "t_end": 0.05,
    },
    # what tests/benchmarks/test_augury_probes.py runs (seconds)
    "smoke": {
        "flat": [("own", 1), ("facing", 30)],
        "settled": [{"mu": 0.7, "iterations": 1, "normals": "own", "zero_B": False}],
        "energy": [(10, False), (10, True)],
        "h": 1.0,
        "settle": 0.01,
        "t_end": 0.01,
    },
}


def flat(normals: str, iterations: int) -> dict:
    """The ``flat`` probe: the block's mean velocity (m/s) and contact pairs after 200 steps."""
    soft = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
    scene = bfemp.Scene(dim=2)
    scene.add_fem(bfemp.shapes.rectangle((0, -0.2), (2, 0), h=0.1), material=soft)
    scene.add_fem(
        bfemp.shapes.rectangle((0.3, 0.0), (0.8, 0.5), h=0.1), material=soft, velocity=(1.0, 0)
    )
    model = scene.build()
    opts = AuguryOptions(
        mu=0.0, grid_dx=0.05, normals=normals, iterations=iterations, penetration_check_every=0
    )
    stepper = AuguryStepper(model, dt=1e-4, options=opts)
    state = stepper.initialize(model.initial_state())
    for _ in range(200):
        state, report = stepper.step(state)
    block = model.fem_bodies[1]
    m = model.fem_mass[block.nodes]
    v = m @ state.fem_v[block.nodes] / m.sum()
    probe = {"normals": normals, "iterations": iterations, "vx": float(v[0]), "vy": float(v[1])}
    return probe | {"contact_pairs": int(report.contact_pairs)}


def plate_model(h: float, gravity: tuple[float, float]) -> bfemp.Model:
    """Plate (fixed bottom) and block of the ramp, grid-aligned, at mesh size ``h`` m."""
    mat = bfemp.NeoHookean(E=1e10, nu=0.3, density=1e6)
    scene = bfemp.Scene(dim=2, gravity=gravity)
    plate = bfemp.shapes.rectangle((0.0, -0.25), (4.0, 0.0), h=min(h, 0.25))
    bottom = np.isclose(np.asarray(plate.points)[:, 1], -0.25)
    scene.add_fem(plate, material=mat, prescribed=bfemp.motion.Fixed(), prescribed_nodes=bottom)
    scene.add_fem(bfemp.shapes.rectangle((0.25, 0.0), (1.25, 1.0), h=h), material=mat)
    return scene.build()


def _stepper(model: bfemp.Model, h: float, mu: float, iterations: int, normals: str, **kw):
    opts = AuguryOptions(
        mu=mu,
        iterations=iterations,
        normals=normals,
        grid_dx=0.5 * h,
        penetration_check_every=0,
        # the plate's fixed bottom row stays out of H, as when these probes were recorded
        # (issue 40 made scripted nodes kinematic foreground by default)
        kinematic_foreground=False,
        **kw,
    )
    return AuguryStepper(model, dt=2.5e-5 * h, options=opts)


def settled(
    h: float, settle: float, t_end: float, mu: float, iterations: int, normals: str, zero_B: bool
) -> dict:
    """The ``settled`` probe: slip at five times over ``t_end`` after the settling."""
    gn, gt = G * np.cos(THETA), G * np.sin(THETA)
    a = plate_model(h, (0.0, -gn))
    st = _stepper(a, h, mu, iterations, normals)
    state = st.initialize(a.initial_state())
    for _ in range(int(round(settle / st.dt))):
        state, _ = st.step(state)
        state.fem_v *= 0.99
        state.carried["aug_B"] *= 0.99
    b = plate_model(h, (gt, -gn))
    st = _stepper(b, h, mu, iterations, normals)
    state = st.initialize(state)
    X = b.fem_X
    start = b.fem_bodies[1].nodes.start
    on = np.flatnonzero(np.abs(X[:, 1]) < 1e-9)
    bottom = on[on >= start]
    top = on[(on < start) & (X[on, 0] > 0.25 - h) & (X[on, 0] < 1.25 + h)]
    x0 = state.fem_x.copy()
    steps = int(round(t_end / st.dt))
    t, slip, b_max = [], [], []
    for k in range(1, steps + 1):
        state, _ = st.step(state)
        if zero_B:
            state.carried["aug_B"][:] = 0.0
        if k % max(1, steps // 5) == 0 or k == steps:
            d = state.fem_x[:, 0] - x0[:, 0]
            t.append(k * st.dt)
            slip.append(float(d[bottom].mean() - d[top].mean()))
            b_max.append(float(np.abs(state.carried["aug_B"]).max()))
    return {
        "h": h,
        "mu": mu,
        "iterations": iterations,
        "normals": normals,
        "zero_B": zero_B,
        "t": t,
        "slip": slip,
        "B_max": b_max,
        "slip_rigid_frictionless": 0.5 * gt * t_end**2,
    }


def energy(h: float, t_end: float, iterations: int, guard: bool, mu: float = 0.7) -> dict:
    """The ``energy`` probe: kinetic energy added by the correction over ``t_end``."""
    model = plate_model(h, (G * np.sin(THETA), -G * np.cos(THETA)))
    st = _stepper(model, h, mu, iterations, "facing", energy_guard=guard)
    state = st.initialize(model.initial_state())
    gains = []
    original = augury_module.augury_correction

    def recording(op, v_bar, B_bar, *args, **kwargs):
        v, B = original(op, v_bar, B_bar, *args, **kwargs)
        gains.append(op.kinetic_energy(v, B) - op.kinetic_energy(v_bar, B_bar))
        return v, B

    augury_module.augury_correction = recording
    try:
        steps = int(round(t_end / st.dt))
        for _ in range(steps):
            state, _ = st.step(state)
    finally:
        augury_module.augury_correction = original
    g = np.array(gains)
    block = model.fem_bodies[1]
    m = model.fem_mass[block.nodes]
    return {
        "h": h,
        "mu": mu,
        "iterations": iterations,
        "energy_guard": guard,
        "steps": steps,
        "steps_gaining": int((g > 0.0).sum()),
        "energy_gained_J": float(g[g > 0.0].sum()),
        "energy_lost_J": float(-g[g < 0.0].sum()),
        "block_normal_displacement": float(
            m @ (state.fem_x[block.nodes, 1] - model.fem_X[block.nodes, 1]) / m.sum()
        ),
    }


def measure(mode: str, cfg) -> dict:
    """Every probe of ``mode``."""
    flats = [flat(n, k) for n, k in cfg["flat"]]
    for f in flats:
        log.info("augury_probes flat %(normals)s N=%(iterations)d: v = %(vx).4f, %(vy).4f", f)
    settles = [settled(cfg["h"], cfg["settle"], cfg["t_end"], **c) for c in cfg["settled"]]
    for s in settles:
        log.info(
            "augury_probes settled %s: slip %s", {k: s[k] for k in cfg["settled"][0]}, s["slip"]
        )
    energies = [energy(cfg["h"], cfg["t_end"], k, g) for k, g in cfg["energy"]]
    payload = {
        "flat": flats,
        "settled": settles,
        "energy": energies,
        "parameters": {k: v for k, v in cfg.items() if k in ("h", "settle", "t_end")},
    }
    return payload


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, measure))
run = BENCHMARK.run
