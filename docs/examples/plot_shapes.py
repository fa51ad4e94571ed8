"""
Meshes and particles
====================

FEM bodies are meshes from :mod:`bfemp.shapes` (or any meshio mesh); MPM bodies are particles
sampled from a shape with :mod:`bfemp.sample`. This scene puts one of each shape side by side
and draws the scene's first frame, the way a run's ``snapshots.png`` draws it: FEM cells
outlined, particles as dots, coloured by von Mises stress (round-off only, about 1e-8 Pa:
nothing has moved yet).
"""

import bfemp
from bfemp.io.snapshots import snapshot_figure, snapshot_from_blocks

rubber = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)  # Pa, -, kg/m^3
scene = bfemp.Scene(dim=2)

# %%
# Three FEM meshes: a rectangle, a disk and a ring (edge length ``h`` in m).
scene.add_fem(bfemp.shapes.rectangle((0.0, 0.0), (2.0, 0.5), h=0.1), material=rubber, name="bar")
scene.add_fem(bfemp.shapes.disk((3.0, 0.25), 0.5, h=0.1), material=rubber, name="disk")
scene.add_fem(bfemp.shapes.ring((5.0, 0.25), 0.3, 0.6, h=0.08), material=rubber, name="ring")

# %%
# Particles: a disk sampled with 4 particles per grid cell of ``dx`` = 0.1 m (``sample.box``
# and ``sample.levelset`` fill a box or a level set alike); each particle carries its volume
# (m^2 in 2D). The barrier couples every pair of bodies (``set_contact``).
x, vol = bfemp.sample.mesh(bfemp.shapes.disk((3.0, 1.75), 0.5, h=0.05), dx=0.1, ppc=4)
scene.add_mpm(x, vol, material=rubber, name="mpm_disk")
scene.set_grid(dx=0.1)
scene.set_contact(dhat=1e-3, kappa=1e5)
print(f"{len(vol)} particles in the disk, total area {vol.sum():.4f} m^2 (pi r^2 = 0.7854)")

# %%
# The simulation's frame blocks are what it writes to VTK; the snapshot sheet draws them.
sim = bfemp.Simulation(scene, dt=1e-3)
fig = snapshot_figure([snapshot_from_blocks(sim.state.t, sim.frame_blocks())], title="t = 0")
