"""Tests of geometry.sampling: sub-cell lattice, volumes, jitter, point location in meshes."""

import numpy as np
import pytest

from geometry import shapes
from geometry.levelset import Box, Disk, Inverted
from geometry.sampling import (
    locate_points,
    points_in_mesh,
    sample_box,
    sample_inside,
    sample_levelset,
    sample_mesh,
)


def brute_force_locate(mesh, x, tol=1e-12):
    """Reference: barycentric coordinates of every point in every cell (small inputs only)."""
    verts = mesh.points[mesh.cells]
    v0 = verts[:, 0]
    dm = np.transpose(verts[:, 1:] - v0[:, None], (0, 2, 1))
    lam = np.einsum("cij,pcj->pci", np.linalg.inv(dm), x[:, None, :] - v0[None])
    inside = (lam >= -tol).all(axis=2) & (1.0 - lam.sum(axis=2) >= -tol)
    return inside


# --------------------------------------------------------------------------- validation
@pytest.mark.parametrize(("dim", "ppc"), [(2, 2), (2, 8), (3, 4), (3, 9), (2, 0), (2, 4.0)])
def test_invalid_ppc_is_rejected_naming_ppc(dim, ppc):
    with pytest.raises(ValueError, match="ppc"):
        sample_box((0.0,) * dim, (1.0,) * dim, 0.1, ppc)


def test_bad_arguments_name_the_field():
    with pytest.raises(ValueError, match="dx"):
        sample_box((0.0, 0.0), (1.0, 1.0), 0.0, 4)
    with pytest.raises(ValueError, match="dx"):
        sample_box((0.0, 0.0), (1.0, 1.0), -0.1, 4)
    with pytest.raises(ValueError, match="upper"):
        sample_box((0.0, 0.0), (1.0, 0.0), 0.1, 4)
    with pytest.raises(ValueError, match="upper"):
        sample_box((0.0, 0.0), (1.0, 1.0, 1.0), 0.1, 4)
    with pytest.raises(ValueError, match="jitter"):
        sample_box((0.0, 0.0), (1.0, 1.0), 0.1, 4, jitter=1.5)
    with pytest.raises(ValueError, match="no particle inside"):
        sample_levelset(Disk(center=(0.5, 0.5), radius=0.01), (0, 0), (1, 1), 0.5, 1)
    with pytest.raises(ValueError, match="inside must return"):
        sample_inside(lambda y: np.ones(3, bool), (0, 0), (1, 1), 0.1, 1)
    with pytest.raises(ValueError, match="mesh"):
        sample_mesh("not a mesh", 0.1, 4)


# --------------------------------------------------------------------------- boxes
@pytest.mark.parametrize(("dim", "ppc"), [(2, 1), (2, 4), (2, 9), (3, 1), (3, 8), (3, 27)])
def test_aligned_box_has_exact_counts_volume_and_sub_centres(dim, ppc):
    dx = 0.125
    lower, upper = (0.25, -0.5, 0.0)[:dim], (1.0, 0.0, 0.375)[:dim]
    x, vol = sample_box(lower, upper, dx, ppc)
    n_cells = np.prod(np.round((np.subtract(upper, lower)) / dx))
    assert x.shape == (n_cells * ppc, dim) and x.flags.c_contiguous
    box_volume = np.prod(np.subtract(upper, lower))
    assert vol.sum() == pytest.approx(box_volume, rel=1e-13)
    k = round(ppc ** (1 / dim))
    s = dx / k
    np.testing.assert_allclose(vol, s**dim)
    m = x / s - 0.5  # sub-centres sit at (m + 1/2) s with integer m
    np.testing.assert_allclose(m, np.round(m), atol=1e-9)
    assert np.all(x >= lower) and np.all(x < upper)
    assert np.unique(np.round(m), axis=0).shape[0] == x.shape[0]
    # Every grid cell holds exactly ppc particles.
    _, counts = np.unique(np.floor(x / dx), axis=0, return_counts=True)
    assert np.all(counts == ppc)


def test_unaligned_box_stays_inside_and_volume_is_within_one_layer():
    lower, upper, dx = (0.03, 0.11), (0.97, 0.52), 0.1
    x, vol = sample_box(lower, upper, dx, 4)
    assert np.all(x >= lower) and np.all(x < upper)
    area, perimeter = 0.94 * 0.41, 2 * (0.94 + 0.41)
    assert abs(vol.sum() - area) <= perimeter * dx / 2


def test_origin_shifts_the_lattice():
    x0, _ = sample_box((0, 0), (1, 1), 0.1, 1)
    x1, _ = sample_box((0, 0), (1, 1), 0.1, 1, origin=(0.02, 0.0))
    frac = (x1[:, 0] - 0.02) / 0.1 - 0.5
    np.testing.assert_allclose(frac, np.round(frac), atol=1e-9)
    assert x1.shape[0] == x0.shape[0]


# --------------------------------------------------------------------------- level sets
def test_disk_and_ball_volumes_converge():
    for dx, tol in ((0.1, 0.03), (0.025, 0.008)):
        _, vol = sample_levelset(Disk(center=(0.1, -0.2), radius=0.5), (-1, -1), (1, 1), dx, 4)
        assert abs(vol.sum() / (np.pi * 0.25) - 1.0) < tol
    x, vol = sample_levelset(Disk(center=(0, 0, 0), radius=0.5), (-1,) * 3, (1,) * 3, 0.05, 8)
    assert abs(vol.sum() / (4 / 3 * np.pi * 0.125) - 1.0) < 0.01
    assert np.all(np.linalg.norm(x, axis=1) < 0.5)


def test_inverted_levelset_samples_the_complement():
    disk = Disk(center=(0.5, 0.5), radius=0.3)
    xa, va = sample_levelset(disk, (0, 0), (1, 1), 0.05, 4)
    xb, vb = sample_levelset(Inverted(disk), (0, 0), (1, 1), 0.05, 4)
    assert va.sum() + vb.sum() == pytest.approx(1.0)
    assert xa.shape[0] + xb.shape[0] == 20 * 20 * 4
    box = Inverted(Box(lower=(0.2, 0.2), upper=(0.6, 0.4)))
    xc, _ = sample_levelset(Inverted(box), (0, 0), (1, 1), 0.1, 4)
    assert xc.shape[0] == 4 * 2 * 4


def test_jitter_is_bounded_reproducible_and_keeps_particles_inside():
    disk = Disk(center=(0.0, 0.0), radius=0.4)
    x0, v0 = sample_levelset(disk, (-1, -1), (1, 1), 0.1, 4)
    xj, vj = sample_levelset(disk, (-1, -1), (1, 1), 0.1, 4, jitter=0.8, rng=7)
    xk, _ = sample_levelset(disk, (-1, -1), (1, 1), 0.1, 4, jitter=0.8, rng=7)
    xl, _ = sample_levelset(disk, (-1, -1), (1, 1), 0.1, 4, jitter=0.8, rng=8)
    np.testing.assert_array_equal(xj, xk)
    assert not np.array_equal(xj, xl)
    assert np.all(disk.value(xj) < 0.0)
    np.testing.assert_allclose(vj, 0.05**2)
    # Each particle stays within jitter * s / 2 of its own sub-centre.
    s = 0.05
    centre = (np.floor(xj / s) + 0.5) * s
    assert np.all(np.abs(xj - centre) <= 0.4 * s + 1e-15)
    assert np.any(np.abs(xj - centre) > 0.3 * s)


# --------------------------------------------------------------------------- meshes
def test_point_location_matches_brute_force_2d_nonconvex():
    mesh = shapes.ring((0.0, 0.0), 0.5, 1.0, 0.15)
    x = np.random.default_rng(0).uniform(-1.2, 1.2, size=(3000, 2))
    x = np.vstack([x, mesh.points])  # vertices: on the boundary of several cells
    cell = locate_points(mesh, x)
    ref = brute_force_locate(mesh, x)
    np.testing.assert_array_equal(cell >= 0, ref.any(axis=1))
    hit = cell >= 0
    assert np.all(ref[np.flatnonzero(hit), cell[hit]])  # the returned cell does contain it
    assert np.all(cell[-mesh.n_points :] >= 0)
    # Misses are in the polygonal hole (r <= 0.5) or outside the outer polygon.
    r = np.linalg.norm(x[~hit], axis=1)
    assert np.all((r <= 0.5 + 1e-12) | (r >= 0.98))


def test_point_location_matches_brute_force_3d():
    mesh = shapes.spherical_shell((0.0, 0.0, 0.0), 0.5, 1.0, 0.4)
    x = np.random.default_rng(1).uniform(-1.1, 1.1, size=(1000, 3))
    cell = locate_points(mesh, x)
    ref = brute_force_locate(mesh, x)
    np.testing.assert_array_equal(cell >= 0, ref.any(axis=1))
    hit = cell >= 0
    assert np.all(ref[np.flatnonzero(hit), cell[hit]])
    assert np.all(~points_in_mesh(mesh, np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])))
    with pytest.raises(ValueError, match=r"x must have shape \(P, 3\)"):
        locate_points(mesh, np.zeros((2, 2)))


def test_sample_mesh_box_is_exact_and_points_inside():
    mesh = shapes.box((0.0, 0.0, 0.0), (0.5, 0.25, 0.5), 0.25)
    x, vol = sample_mesh(mesh, 0.125, 8)
    assert x.shape[0] == 4 * 2 * 4 * 8
    assert vol.sum() == pytest.approx(mesh.total_volume(), rel=1e-13)
    assert np.all(points_in_mesh(mesh, x))
    x2, vol2 = sample_mesh(shapes.rectangle((0.0, 0.0), (1.0, 0.5), 0.2), 0.1, 9)
    assert x2.shape[0] == 10 * 5 * 9 and vol2.sum() == pytest.approx(0.5)


def test_sample_mesh_disk_and_ring_volumes_within_discretisation():
    disk = shapes.disk((0.0, 0.0), 1.0, 0.1)
    x, vol = sample_mesh(disk, 0.05, 4)
    assert np.all(np.linalg.norm(x, axis=1) <= 1.0)
    assert abs(vol.sum() - disk.total_volume()) < 2 * np.pi * 0.025
    ring = shapes.ring((0.2, 0.1), 0.6, 1.0, 0.1)
    x, vol = sample_mesh(ring, 0.05, 4, jitter=0.5, rng=3)
    r = np.linalg.norm(x - (0.2, 0.1), axis=1)
    assert np.all((r >= 0.59) & (r <= 1.0))  # nothing in the hole (chords sag < 0.01)
    assert abs(vol.sum() - ring.total_volume()) < 2 * np.pi * 1.6 * 0.025
    assert np.all(points_in_mesh(ring, x))
