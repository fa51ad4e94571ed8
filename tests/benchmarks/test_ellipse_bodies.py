"""The classes of an ellipse packing as MPM bodies (lr_ellipses' scene)."""

import numpy as np
import pytest

import bfemp
from benchmarks.lr_ellipses import add_ellipse_classes
from geometry.ellipse_classes import EllipseParticles, colour_ellipses, sample_ellipses
from geometry.ellipses import pack_ellipses

MM = 1e-3
ALUMINIUM = bfemp.BulkShearHyperelastic(K=78.09e9, G=27.6e9, density=2780.0)  # LR §4.2


def test_one_body_per_class_holding_its_ellipses_particles_and_it_runs():
    dx = MM / 35
    packing = pack_ellipses((0.0, 0.0), (MM, MM), min_semi_axis=0.08 * MM, rng=0)
    parts = sample_ellipses(packing, dx, 4)
    classes = colour_ellipses(packing, 2 * dx, 6)
    scene = bfemp.Scene(dim=2)
    scene.set_grid(dx=dx)
    bodies = add_ellipse_classes(scene, parts, classes, ALUMINIUM, velocity=(0.0, -1.0))
    model = scene.build()
    assert len(bodies) == classes.max() + 1 == len(model.mpm_bodies)
    assert model.n_particles == parts.x.shape[0]
    for k, body in enumerate(model.mpm_bodies):
        assert body.name == f"class{k}" and body.material is ALUMINIUM
        mine = np.isin(parts.ellipse, np.flatnonzero(classes == k))
        assert np.array_equal(model.mpm_X[body.particles], parts.x[mine])
    assert np.allclose(model.mpm_volume.sum(), parts.volume.sum(), rtol=1e-14)
    # a few explicit steps of the free packing: uniform motion, no deformation
    sim = bfemp.Simulation(scene, strategy="single_field", dt="auto")
    for _ in range(3):
        sim.step()
    assert np.allclose(sim.state.mpm_v, [0.0, -1.0], atol=1e-9)
    assert np.allclose(np.linalg.det(sim.state.mpm_F), 1.0, atol=1e-12)


def test_a_class_without_particles_is_refused_by_name():
    packing = pack_ellipses((0.0, 0.0), (MM, MM), min_semi_axis=0.08 * MM, rng=0)
    parts = sample_ellipses(packing, MM / 35, 4)
    empty = EllipseParticles(parts.x[:0], parts.volume[:0], parts.ellipse[:0], parts.n_ellipses)
    scene = bfemp.Scene(dim=2)
    with pytest.raises(ValueError, match="class 0 has no particle"):
        add_ellipse_classes(scene, empty, np.zeros(packing.n_ellipses, int), ALUMINIUM)
