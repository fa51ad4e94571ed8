"""The demos: colliding rings (the main one, coupled MPM-FEM) and a cantilever (FEM only).

``run_demo`` (``make demo``, ``bfemp demo``): the BFEMP paper's colliding rings (section 6.1)
at a coarse resolution: an MPM ring and a FEM ring (Neo-Hookean, E = 1e8 Pa, nu = 0.2, inner and
outer radii 3 and 4 m) fly at each other at 40 m/s each, meet through the barrier (dhat = 1e-2 m,
kappa = 1e7 Pa) and bounce apart; Newmark with implicit contact, APIC, dt = 2e-3 s (the paper:
2e-4 s, dx = 0.1 m, see ``python -m benchmarks rings``). Writes VTK frames (``mpm_ring.pvd``,
``fem_ring.pvd``), ``metrics.csv``/``metrics.png``, ``demo.png`` (energies, momentum drift,
closest approach), ``snapshots.png`` (the rings at six times, coloured by von Mises stress),
``scene.toml`` (the scene, to rerun with ``bfemp run``) and ``demo.json`` with the rings
benchmark's headline metrics. A demo replaces the outputs of an earlier run in ``out``.

``run_cantilever_demo`` (``bfemp demo --case cantilever``): a 2D Neo-Hookean cantilever, left end
clamped, swinging under gravity under Newmark; frames ``beam.pvd``, ``demo.png`` (energies) and
``tip.png`` (tip deflection).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import bfemp
from bfemp.io.metrics import MetricsLog
from bfemp.plotting import plot_series

__all__ = ["cantilever_scene", "colliding_rings_scene", "run_cantilever_demo", "run_demo"]


def cantilever_scene(*, length: float = 4.0, height: float = 0.5, h: float = 0.125) -> bfemp.Scene:
    """A beam ``length x height`` m clamped at x = 0, E 5e7 Pa, nu 0.3, rho 1000, g = 9.81."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (length, height), h=h)
    clamped = mesh.points[:, 0] <= 1e-9
    scene.add_fem(
        mesh,
        material=bfemp.NeoHookean(E=5e7, nu=0.3, density=1000.0),
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=clamped,
        name="beam",
    )
    return scene


def run_cantilever_demo(
    out: str | Path = "results/demo", *, t_end: float = 2.0, dt: float = 1e-2, progress: bool = True
) -> dict:
    """Run the cantilever demo and write its outputs to ``out``; returns a summary dict."""
    out = Path(out)
    scene = cantilever_scene()
    sim = bfemp.Simulation(scene, integrator="newmark", dt=dt, tol=1e-6)
    tip = int(np.argmax(sim.state.fem_x[:, 0] + 1e-3 * sim.state.fem_x[:, 1]))
    tip_y0 = float(sim.state.fem_x[tip, 1])
    times, deflection = [0.0], [0.0]

    def record_tip(s: bfemp.Simulation) -> None:
        times.append(s.state.t)
        deflection.append(float(s.state.fem_x[tip, 1]) - tip_y0)

    metrics = sim.run(
        t_end, out=out, every=5, progress=progress, callback=record_tip, overwrite=True
    )
    plot_series(
        metrics.column("t"),
        {
            k: metrics.column(k)
            for k in ("energy_kinetic", "energy_elastic", "energy_gravity", "energy_total")
        },
        out / "demo.png",
        xlabel="t (s)",
        ylabel="energy (J/m)",
        title="Cantilever under gravity (Newmark)",
    )
    plot_series(
        np.array(times),
        {"tip deflection": np.array(deflection)},
        out / "tip.png",
        xlabel="t (s)",
        ylabel="deflection (m)",
        title="Cantilever tip deflection",
    )
    summary = {
        "steps": int(round(t_end / dt)),
        "newton_iterations_total": int(np.nansum(metrics.column("iterations_newton"))),
        "min_tip_deflection_m": float(min(deflection)),
        "energy_total_first": float(metrics.column("energy_total")[0]),
        "energy_total_last": float(metrics.column("energy_total")[-1]),
        "outputs": {
            "frames": str(out / "beam.pvd"),
            "metrics": str(out / "metrics.csv"),
            "plots": [
                str(out / name) for name in ("demo.png", "tip.png", "metrics.png", "snapshots.png")
            ],
            "scene": str(out / "scene.toml"),
        },
    }
    (out / "demo.json").write_text(json.dumps(summary, indent=2))
    return summary


#: Colliding rings (paper section 6.1): geometry in m, speed in m/s, material in SI (2D).
RING_RADII = (3.0, 4.0)
RING_GAP = 2.0
RING_SPEED = 40.0
RING_MATERIAL = dict(E=1e8, nu=0.2, density=1000.0)


def colliding_rings_scene(
    *, dx: float = 1.0 / 3.0, ppc: int = 4, fem_h: float = 1.0 / 3.0
) -> bfemp.Scene:
    """MPM ring (centre (-5, 0)) and FEM ring (centre (5, 0)) 2 m apart, closing at 80 m/s.

    Args:
        dx: MPM grid spacing in m (the paper: 0.1).
        ppc: particles per cell (a square number; the paper's count matches 9 at dx = 0.1).
        fem_h: FEM ring edge length in m (the paper's mesh: about 0.13).

    The grid is shifted by a quarter particle spacing off the sampling lattice, so that no
    particle sits on a half-integer grid coordinate (where the outermost quadratic B-spline
    weight vanishes and rim nodes get no mass).
    """
    r_in, r_out = RING_RADII
    centre = r_out + 0.5 * RING_GAP
    material = bfemp.NeoHookean(**RING_MATERIAL)
    scene = bfemp.Scene(dim=2)
    # the sampling mesh only decides which sub-cell centres lie in the ring: make it fine
    shape = bfemp.shapes.ring((-centre, 0.0), r_in, r_out, h=0.25 * dx)
    particles, volumes = bfemp.sample.mesh(shape, dx=dx, ppc=ppc)
    scene.add_mpm(
        particles, volumes, material=material, velocity=(RING_SPEED, 0.0), name="mpm_ring"
    )
    mesh = bfemp.shapes.ring((centre, 0.0), r_in, r_out, h=fem_h)
    scene.add_fem(mesh, material=material, velocity=(-RING_SPEED, 0.0), name="fem_ring")
    shift = dx / (4.0 * round(ppc**0.5))
    scene.set_grid(dx=dx, origin=(shift, shift))
    scene.set_contact(dhat=1e-2, kappa=1e7)
    return scene


def run_demo(
    out: str | Path = "results/demo", *, t_end: float = 0.3, dt: float = 2e-3, progress: bool = True
) -> dict:
    """Run the colliding-rings demo and write its outputs to ``out``; returns a summary dict.

    The summary (also ``out/demo.json``) holds the rings benchmark's metrics at this resolution:
    ``momentum_drift_rel`` (max |P(t) - P(0)| over the sum of the rings' |P(0)|),
    ``min_distance`` (m, closest particle-boundary distance at any step), ``energy_loss_pct``
    (kinetic + elastic, from first contact to the end), ``contact_window_s``, ``steps``,
    ``newton_iterations_total``, ``wall_s`` and the output paths.
    """
    out = Path(out)
    sim = bfemp.Simulation(
        colliding_rings_scene(),
        integrator="newmark_implicit_contact",
        transfer="apic",
        dt=dt,
        tol=1e-6,
    )
    model = sim.model
    started = time.perf_counter()
    metrics = sim.run(t_end, out=out, every=5, progress=progress, overwrite=True)
    wall = time.perf_counter() - started
    t = metrics.column("t")
    momentum = np.stack([metrics.column("momentum_x"), metrics.column("momentum_y")], axis=1)
    scale = float(
        np.linalg.norm(model.fem_mass @ model.fem_v0)
        + np.linalg.norm(model.mpm_mass @ model.mpm_v0)
    )
    drift = np.linalg.norm(momentum - momentum[0], axis=1) / scale
    energy = metrics.column("energy_kinetic") + metrics.column("energy_elastic")
    pairs = metrics.column("contact_pairs")
    touching = np.flatnonzero(np.nan_to_num(pairs) > 0)
    first = max(int(touching[0]) - 1, 0) if touching.size else 0
    dist = metrics.column("min_distance")
    _plot_rings(t, metrics, drift, out / "demo.png")
    summary = {
        "steps": int(len(t) - 1),
        "newton_iterations_total": int(np.nansum(metrics.column("iterations_newton"))),
        "momentum_drift_rel": float(drift.max()),
        "min_distance": float(np.nanmin(dist)) if np.isfinite(dist).any() else float("nan"),
        "contact_window_s": [float(t[touching[0]]), float(t[touching[-1]])]
        if touching.size
        else None,
        "energy_loss_pct": float(100.0 * (energy[first] - energy[-1]) / energy[first]),
        "wall_s": wall,
        "outputs": {
            "frames": [str(out / "mpm_ring.pvd"), str(out / "fem_ring.pvd")],
            "metrics": str(out / "metrics.csv"),
            "plots": [str(out / "demo.png"), str(out / "metrics.png"), str(out / "snapshots.png")],
            "summary": str(out / "demo.json"),
            "scene": str(out / "scene.toml"),
        },
    }
    (out / "demo.json").write_text(json.dumps(summary, indent=2))
    return summary


def _plot_rings(t: np.ndarray, metrics: MetricsLog, drift: np.ndarray, path: Path) -> None:
    """Energies, momentum drift and closest approach of the rings demo in one PNG."""
    fig = Figure(figsize=(8.0, 9.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_e, ax_p, ax_d = fig.subplots(3, 1, sharex=True)
    for key in ("energy_kinetic", "energy_elastic", "energy_contact"):
        if key in metrics.columns:
            ax_e.plot(t, metrics.column(key) / 1e6, label=key.removeprefix("energy_"))
    total = metrics.column("energy_kinetic") + metrics.column("energy_elastic")
    ax_e.plot(t, total / 1e6, "k-", label="kinetic + elastic")
    ax_e.set_ylabel("energy [MJ/m]")
    ax_p.semilogy(t, np.maximum(drift, 1e-18))
    ax_p.set_ylabel("|P(t) - P(0)| / sum |P_ring(0)|")
    ax_d.semilogy(t, metrics.column("min_distance"), ".", ms=3)
    ax_d.axhline(1e-2, color="0.5", ls=":", label="dhat")
    ax_d.set(xlabel="t [s]", ylabel="closest particle-boundary distance [m]")
    for ax in (ax_e, ax_p, ax_d):
        ax.grid(True, alpha=0.3)
    ax_e.legend(fontsize="small")
    ax_d.legend(fontsize="small")
    fig.suptitle("Colliding rings: MPM (left) and FEM (right), BFEMP barrier coupling")
    fig.savefig(path, dpi=110)
