"""
A cantilever under gravity
==========================

The first script of *Getting started*: a Neo-Hookean beam (4 m x 0.5 m, E = 50 MPa) clamped at
its left end swings down under gravity. Mid-point Newmark keeps its energy (no numerical
damping), so the beam keeps swinging.
"""

import bfemp
from bfemp.io.snapshots import snapshot_figure, snapshot_from_blocks
from bfemp.plotting import metrics_figure

scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
mesh = bfemp.shapes.rectangle((0.0, 0.0), (4.0, 0.5), h=0.125)
scene.add_fem(
    mesh,
    material=bfemp.NeoHookean(E=5e7, nu=0.3, density=1000.0),
    prescribed=bfemp.motion.Fixed(),
    prescribed_nodes=mesh.points[:, 0] < 1e-9,
    name="beam",
)
sim = bfemp.Simulation(scene, integrator="newmark", dt=1e-2, tol=1e-6)
print(sim.terms)

# %%
# Step for 0.6 s and keep six snapshots of the frames bfemp would write.
snapshots = [snapshot_from_blocks(sim.state.t, sim.frame_blocks())]
for step in range(60):
    sim.step()
    if (step + 1) % 12 == 0:
        snapshots.append(snapshot_from_blocks(sim.state.t, sim.frame_blocks()))
sheet = snapshot_figure(snapshots, title="cantilever under gravity")

# %%
# The metrics the run logged, one row per step (``sim.metrics``): energies, momenta, Newton
# iterations and timings. The total energy stays level: Newmark conserves it.
energy = sim.metrics.column("energy_total")
print(f"total energy: first step {energy[0]:.4g} J/m, last {energy[-1]:.4g} J/m")
groups = {"energies": ["energy_*"], "iterations": ["iterations_*"]}
panels = metrics_figure(sim.metrics, groups=groups)
