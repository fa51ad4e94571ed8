"""Tests of geometry.levelset: analytic distances, unit normals = FD gradients, combinators."""

import numpy as np
import pytest

from geometry.levelset import Box, Disk, HalfPlane, Inverted, LevelSet, Union


def fd_gradient(ls, x, h=1e-6):
    grad = np.empty_like(x)
    for a in range(x.shape[1]):  # loop over the axes only
        e = np.zeros(x.shape[1])
        e[a] = h
        grad[:, a] = (ls.value(x + e) - ls.value(x - e)) / (2 * h)
    return grad


def box_distance(lower, upper, x):
    """Reference signed distance of a box: Euclidean outside, minus nearest-face inside."""
    lower, upper = np.asarray(lower), np.asarray(upper)
    outside = np.linalg.norm(np.clip(x, lower, upper) - x, axis=1)
    inside = np.minimum(x - lower, upper - x).min(axis=1)
    return np.where(outside > 0, outside, -inside)


def check_normals(ls, x):
    n = ls.normal(x)
    assert n.shape == x.shape
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(n, fd_gradient(ls, x), atol=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_half_plane(dim):
    point = np.arange(1.0, dim + 1.0)
    normal = np.zeros(dim)
    normal[-1], normal[0] = 3.0, 4.0
    ls = HalfPlane(point=tuple(point), normal=tuple(normal))
    assert ls.dim == dim and isinstance(ls, LevelSet)
    np.testing.assert_allclose(np.linalg.norm(ls.unit_normal), 1.0)
    x = np.random.default_rng(0).normal(size=(50, dim))
    np.testing.assert_allclose(ls.value(x), (x - point) @ normal / 5.0, atol=1e-14)
    check_normals(ls, x)
    # The obstacle is on the side opposite to the normal.
    assert ls.value(point[None] - normal[None]) < 0 < ls.value(point[None] + normal[None])


@pytest.mark.parametrize("dim", [2, 3])
def test_box_distance_and_normals(dim):
    lower, upper = (-0.5, 0.0, 1.0)[:dim], (1.0, 0.4, 1.5)[:dim]
    ls = Box(lower=lower, upper=upper)
    x = np.random.default_rng(1).uniform(-1.5, 2.5, size=(400, dim))
    np.testing.assert_allclose(ls.value(x), box_distance(lower, upper, x), atol=1e-14)
    # Normals: away from the medial set, where the nearest face is unique by a margin.
    q = np.abs(x - 0.5 * (np.add(lower, upper))) - 0.5 * np.subtract(upper, lower)
    top2 = np.sort(q, axis=1)[:, -2:]
    smooth = (q.max(axis=1) > 0) | (top2[:, 1] - top2[:, 0] > 1e-3)
    check_normals(ls, x[smooth])
    # Hand-picked points: face, edge/corner, inside.
    c = np.array([2.0, 1.4, 2.5][:dim])
    assert ls.value(c[None])[0] == pytest.approx(np.linalg.norm(c - upper))
    inner = np.array([0.9, 0.2, 1.25][:dim])
    assert ls.value(inner[None])[0] == pytest.approx(-0.1)
    np.testing.assert_allclose(ls.normal(inner[None])[0], np.eye(dim)[0])


@pytest.mark.parametrize("dim", [2, 3])
def test_disk_distance_and_normals(dim):
    center = np.array([0.3, -0.2, 0.1][:dim])
    ls = Disk(center=tuple(center), radius=0.7)
    x = np.random.default_rng(2).uniform(-2, 2, size=(300, dim))
    np.testing.assert_allclose(ls.value(x), np.linalg.norm(x - center, axis=1) - 0.7, atol=1e-14)
    check_normals(ls, x[np.linalg.norm(x - center, axis=1) > 1e-3])
    n0 = ls.normal(center[None])
    np.testing.assert_allclose(np.linalg.norm(n0, axis=1), 1.0)


def test_union_is_min_with_the_minimising_normal():
    a = Disk(center=(0.0, 0.0), radius=0.5)
    b = HalfPlane(point=(0.0, -1.0), normal=(0.0, 1.0))
    c = Box(lower=(1.0, 1.0), upper=(2.0, 2.0))
    u = Union(a, b, c)
    assert u.dim == 2
    x = np.random.default_rng(3).uniform(-3, 3, size=(500, 2))
    vals = np.stack([a.value(x), b.value(x), c.value(x)])
    np.testing.assert_allclose(u.value(x), vals.min(axis=0))
    which = vals.argmin(axis=0)
    normals = np.stack([a.normal(x), b.normal(x), c.normal(x)])
    np.testing.assert_allclose(u.normal(x), normals[which, np.arange(len(x))])
    gap = np.sort(vals, axis=0)
    smooth = (gap[1] - gap[0] > 1e-3) & (np.linalg.norm(x, axis=1) > 1e-3)
    q = np.abs(x - 1.5) - 0.5
    smooth &= (which != 2) | (q.max(axis=1) > 0) | (np.abs(q[:, 0] - q[:, 1]) > 1e-3)
    check_normals(u, x[smooth])


def test_inverted_box_is_a_container():
    box = Box(lower=(0.0, 0.0, 0.0), upper=(1.0, 2.0, 1.0))
    cont = Inverted(box)
    assert cont.dim == 3
    x = np.random.default_rng(4).uniform(-1, 3, size=(200, 3))
    np.testing.assert_allclose(cont.value(x), -box.value(x))
    np.testing.assert_allclose(cont.normal(x), -box.normal(x))
    inside = np.all((x > 0) & (x < (1.0, 2.0, 1.0)), axis=1)
    assert np.all(cont.value(x[inside]) > 0) and np.all(cont.value(x[~inside]) < 0)
    # Near the floor of the container the normal points up, into the kept region.
    np.testing.assert_allclose(cont.normal(np.array([[0.5, 1.0, 0.1]])), [[0.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: HalfPlane(point=(0, 0), normal=(0, 0)), "normal"),
        (lambda: HalfPlane(point=(0, 0), normal=(0, 1, 0)), "normal"),
        (lambda: HalfPlane(point=(0,), normal=(1,)), "point"),
        (lambda: Box(lower=(0, 0), upper=(1, 0)), "upper"),
        (lambda: Box(lower=(0, 0), upper=(1, 1, 1)), "upper"),
        (lambda: Disk(center=(0, 0), radius=0.0), "radius"),
        (lambda: Disk(center=(0, np.nan), radius=1.0), "center"),
        (lambda: Union(), "parts"),
        (lambda: Union(Disk(center=(0, 0), radius=1), Disk(center=(0, 0, 0), radius=1)), "dim"),
        (lambda: Union(Disk(center=(0, 0), radius=1), 3.0), "parts"),
        (lambda: Inverted("box"), "levelset"),
    ],
)
def test_validation_names_the_field(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_wrong_point_dimension_is_rejected():
    with pytest.raises(ValueError, match=r"Disk: x must have shape \(n, 2\)"):
        Disk(center=(0, 0), radius=1.0).value(np.zeros((3, 3)))
