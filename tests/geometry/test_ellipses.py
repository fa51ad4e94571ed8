"""Ellipse packings for lr_ellipses: certified overlap test, packing, particles, colouring and
the interpenetration counter."""

import math

import numpy as np
import pytest

from geometry.ellipse_classes import (
    class_particles,
    colour_ellipses,
    interpenetrating,
    sample_ellipses,
)
from geometry.ellipses import (
    EllipsePacking,
    certified_apart,
    ellipse_polygons,
    inside_ellipse,
    pack_ellipses,
)

MM = 1e-3
FULL = dict(lower=(0.0, 0.0), upper=(1 * MM, 2 * MM))  # LR's box, semi-axes 0.05-0.2 mm
QUICK = dict(lower=(0.0, 0.0), upper=(1 * MM, 1 * MM), min_semi_axis=0.08 * MM)


def _boundary(centers, semi_axes, angles, n=2000):
    """(E, n, 2) points on the ellipses' boundaries."""
    t = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    u = np.stack([np.cos(t), np.sin(t)], axis=1)[None] * semi_axes[:, None, :]
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return (
        np.stack([c * u[..., 0] - s * u[..., 1], s * u[..., 0] + c * u[..., 1]], axis=2)
        + centers[:, None]
    )


def _overlapping(packing, n=2000):
    """(E, E) True where a sampled boundary point of one ellipse lies inside another."""
    pts = _boundary(packing.centers, packing.semi_axes, packing.angles, n)
    E = packing.n_ellipses
    out = np.zeros((E, E), dtype=bool)
    flat = pts.reshape(-1, 2)
    for j in range(E):  # ellipses; vectorised over all boundary points
        hit = inside_ellipse(flat, packing.centers[j], packing.semi_axes[j], packing.angles[j])
        out[:, j] = hit.reshape(E, n).any(axis=1)
    np.fill_diagonal(out, False)
    return out | out.T


def _sampled_gaps(packing, n=720, reach=0.2e-3):
    """(E, E) smallest distance between sampled boundary points (>= the true gap) for the pairs
    whose bounding circles are closer than ``reach`` (m); inf for the others."""
    pts = _boundary(packing.centers, packing.semi_axes, packing.angles, n)
    E = packing.n_ellipses
    gaps = np.full((E, E), np.inf)
    d = np.linalg.norm(packing.centers[:, None] - packing.centers[None], axis=2)
    a = packing.semi_axes[:, 0]
    for i, j in zip(*np.nonzero(np.triu(d < a[:, None] + a[None] + reach, 1)), strict=True):
        g = np.sqrt(((pts[i][:, None] - pts[j][None]) ** 2).sum(axis=2).min())
        gaps[i, j] = gaps[j, i] = g
    return gaps


# ---------------------------------------------------------------------------- overlap test
def test_certified_apart_is_conservative_and_tight_for_two_circles():
    one = np.ones(1)
    poly = ellipse_polygons(np.array([[0.0, 0.0], [2.5, 0.0]]), np.ones((2, 2)), np.zeros(2))
    a, b = poly[:1], poly[1:]
    # true gap 0.5; the circumscribed 24-gons are 0.86 % larger
    assert certified_apart(a, b, 0.48)[0]
    assert not certified_apart(a, b, 0.5)[0]
    overlapping = ellipse_polygons(np.array([[1.9, 0.0]]), one[None].repeat(2, 1), np.zeros(1))
    assert not certified_apart(a, overlapping, 0.0)[0]


def test_certified_apart_never_passes_an_overlapping_pair():
    rng = np.random.default_rng(3)
    n = 400
    centers = rng.uniform(-1.0, 1.0, (n, 2, 2))
    b = rng.uniform(0.1, 0.5, (n, 2))
    axes = np.stack([b * rng.uniform(1.0, 2.5, (n, 2)), b], axis=2)
    angles = rng.uniform(0.0, math.pi, (n, 2))
    pa = ellipse_polygons(centers[:, 0], axes[:, 0], angles[:, 0])
    pb = ellipse_polygons(centers[:, 1], axes[:, 1], angles[:, 1])
    apart = certified_apart(pa, pb, 0.0)
    pts = _boundary(centers[:, 0], axes[:, 0], angles[:, 0], 720)
    for k in range(n):
        overlap = inside_ellipse(pts[k], centers[k, 1], axes[k, 1], angles[k, 1]).any()
        overlap |= inside_ellipse(centers[k, 1][None], centers[k, 0], axes[k, 0], angles[k, 0])[0]
        assert not (apart[k] and overlap)
    assert 0.2 < apart.mean() < 0.95  # both outcomes occur in this sample


# ---------------------------------------------------------------------------- packing
@pytest.mark.parametrize("config", [FULL, QUICK], ids=["full", "quick"])
@pytest.mark.parametrize("seed", [0, 1])
def test_packing_has_no_overlap_and_the_target_fraction(config, seed):
    p = pack_ellipses(**config, rng=seed)
    assert p.fraction == pytest.approx(0.6, abs=0.01)
    s_min = config.get("min_semi_axis", 0.05 * MM)
    assert p.semi_axes.min() >= s_min * (1 - 1e-12) and p.semi_axes.max() <= 0.2 * MM
    ratio = p.semi_axes[:, 0] / p.semi_axes[:, 1]
    assert ratio.min() >= 1.0 - 1e-12 and ratio.max() <= 2.5 + 1e-9
    assert not _overlapping(p).any()
    for e in range(p.n_ellipses):  # no centre inside another ellipse (containment)
        others = np.delete(np.arange(p.n_ellipses), e)
        for j in others:
            assert not inside_ellipse(p.centers[e][None], p.centers[j], p.semi_axes[j], p.angles[j])
    pts = _boundary(p.centers, p.semi_axes, p.angles).reshape(-1, 2)
    assert (pts >= p.lower).all() and (pts <= p.upper).all()


def test_min_gap_is_kept_between_ellipses_and_to_the_walls():
    gap = 0.03 * MM
    p = pack_ellipses(**QUICK, min_gap=gap, fraction=0.5, rng=2)
    assert p.fraction == pytest.approx(0.5, abs=0.01)
    gaps = _sampled_gaps(p)
    assert (
        not _overlapping(p).any() and gaps.min() >= gap
    )  # sampled distances bound the true ones from above
    pts = _boundary(p.centers, p.semi_axes, p.angles).reshape(-1, 2)
    assert (pts >= p.lower + gap).all() and (pts <= p.upper - gap).all()


def test_packing_is_reproducible_by_seed():
    a = pack_ellipses(**QUICK, rng=5)
    b = pack_ellipses(**QUICK, rng=5)
    c = pack_ellipses(**QUICK, rng=6)
    for field in ("centers", "semi_axes", "angles"):
        assert np.array_equal(getattr(a, field), getattr(b, field))
    assert a.centers.shape != c.centers.shape or not np.array_equal(a.centers, c.centers)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(fraction=0.95), "fraction must be <= 0.9"),
        (dict(fraction=-0.1), "fraction must be finite and > 0"),
        (dict(max_aspect=0.5), "max_aspect must be >= 1"),
        (dict(min_semi_axis=0.1 * MM), r"min_semi_axis \* max_aspect"),
        (dict(max_semi_axis=math.nan), "max_semi_axis must be finite"),
        (dict(min_gap=-1.0), "min_gap must be finite and >= 0"),
        (dict(max_attempts=0), "max_attempts must be an integer >= 1"),
        (dict(upper=(1 * MM, -1.0)), "upper must exceed lower"),
    ],
)
def test_bad_arguments_are_named(kwargs, message):
    args = {**FULL, **kwargs}
    with pytest.raises(ValueError, match=message):
        pack_ellipses(**args)


# ---------------------------------------------------------------------------- particles
def test_particles_sit_on_the_sub_cell_lattice_inside_their_ellipse():
    p = pack_ellipses(**QUICK, rng=0)
    dx = MM / 35
    parts = sample_ellipses(p, dx, 4)
    s = dx / 2
    assert np.all(parts.volume == s * s)
    # sub-cell centres: (m + 1/2) s
    m = parts.x / s - 0.5
    assert np.abs(m - np.round(m)).max() < 1e-6
    for e, x in enumerate(parts.positions()):
        assert x.shape[0] > 0
        assert inside_ellipse(x, p.centers[e], p.semi_axes[e], p.angles[e]).all()
    # each ellipse holds its area in particles, to about one layer of its boundary
    perimeter = math.pi * p.semi_axes.sum(axis=1)
    err = np.abs(parts.counts() * s * s - p.areas)
    assert (err <= perimeter * s).all()
    # LR's quick case: about 2,900 particles (fraction 0.6 of a 70 x 70 lattice)
    assert parts.x.shape[0] == pytest.approx(0.6 * 70 * 70, rel=0.03)


# ---------------------------------------------------------------------------- colouring
@pytest.mark.parametrize(("config", "k"), [(FULL, 20), (QUICK, 6)], ids=["full", "quick"])
def test_colouring_separates_every_close_pair(config, k):
    p = pack_ellipses(**config, rng=0)
    dx = MM / 70 if config is FULL else MM / 35
    classes = colour_ellipses(p, 2 * dx, k)
    assert classes.shape == (p.n_ellipses,) and classes.min() >= 0 and classes.max() < k
    gaps = _sampled_gaps(p)
    close = gaps < 2 * dx  # the sampled gap bounds the true one from above
    i, j = np.nonzero(np.triu(close, 1))
    assert i.size > 0  # the packing is dense enough to have neighbours
    assert (classes[i] != classes[j]).all()


def test_spread_colouring_uses_every_class_and_keeps_classes_apart():
    p = pack_ellipses(**FULL, rng=1)
    dx = MM / 70
    spread = colour_ellipses(p, 2 * dx, 20)
    fewest = colour_ellipses(p, 2 * dx, 20, spread=False)
    assert np.unique(spread).size == min(20, p.n_ellipses)
    assert np.unique(fewest).size < 6  # a planar-like contact graph needs few colours
    gaps = _sampled_gaps(p, reach=np.inf)

    def same_class_gap(classes):
        same = (classes[:, None] == classes[None]) & ~np.eye(p.n_ellipses, dtype=bool)
        return gaps[same].min()

    assert same_class_gap(fewest) >= 2 * dx and same_class_gap(spread) > 2 * same_class_gap(fewest)


def test_too_few_classes_is_a_clear_error():
    # three touching unit circles: a triangle in the contact graph
    c = np.array([[0.0, 0.0], [2.01, 0.0], [1.005, 1.75]])
    p = EllipsePacking(
        centers=c,
        semi_axes=np.ones((3, 2)),
        angles=np.zeros(3),
        lower=np.array([-2.0, -2.0]),
        upper=np.array([4.0, 4.0]),
    )
    assert sorted(colour_ellipses(p, 0.1, 3)) == [0, 1, 2]
    with pytest.raises(ValueError, match="2 classes are not enough: ellipse"):
        colour_ellipses(p, 0.1, 2)
    # far apart at this distance: one class suffices
    assert (colour_ellipses(p, 0.001, 1) == 0).all()


def test_class_particles_are_the_union_of_their_ellipses():
    p = pack_ellipses(**QUICK, rng=0)
    parts = sample_ellipses(p, MM / 35, 4)
    classes = colour_ellipses(p, 2 * MM / 35, 6)
    sets = class_particles(parts, classes)
    assert sum(x.shape[0] for x, _ in sets) == parts.x.shape[0]
    for k, (x, vol) in enumerate(sets):
        members = np.flatnonzero(classes == k)
        expected = np.concatenate([parts.positions()[e] for e in members])
        assert np.array_equal(x, expected) and vol.shape == (x.shape[0],)


# ---------------------------------------------------------------------------- counter
def test_interpenetration_counts_a_hand_made_overlap_and_not_a_clean_gap():
    s = 0.01
    x = np.array([[0.0, 0.0], [0.2 * s, 0.0], [5.0, 0.0], [5.0 + 0.6 * s, 0.0], [9.0, 9.0]])
    x = np.vstack([x, [[9.0 + 0.1 * s, 9.0]]])
    classes = np.array([0, 1, 0, 1, 2, 2])  # the last pair is close but of one class
    J = np.ones(6)
    hit = interpenetrating(x, classes, J, s)
    assert hit.tolist() == [True, True, False, False, False, False]
    # the radius grows with sqrt(J): at J = 4 the 0.6 s pair is within r = s
    J[2] = 4.0
    assert interpenetrating(x, classes, J, s).tolist() == [True, True, True, False, False, False]


def test_a_fresh_packing_has_no_interpenetration_and_a_shifted_one_has():
    p = pack_ellipses(**QUICK, rng=1)
    dx = MM / 35
    parts = sample_ellipses(p, dx, 4)
    classes = colour_ellipses(p, 2 * dx, 6)[parts.ellipse]
    J = np.ones(parts.x.shape[0])
    assert not interpenetrating(parts.x, classes, J, dx / 2).any()
    # push the particles of one ellipse a cell into its closest neighbour
    # (by a lattice vector plus a tenth of a spacing, so that particles nearly coincide)
    gaps = _sampled_gaps(p)
    i, j = np.unravel_index(np.argmin(gaps), gaps.shape)
    direction = (p.centers[j] - p.centers[i]) / np.linalg.norm(p.centers[j] - p.centers[i])
    s = dx / 2
    x = parts.x.copy()
    x[parts.ellipse == i] += np.round((gaps[i, j] + dx) * direction / s) * s + 0.1 * s
    moved = interpenetrating(x, classes, J, dx / 2)
    assert moved[parts.ellipse == i].any() and moved[parts.ellipse == j].any()
    # a brute-force reference of the same definition
    r = 0.5 * (dx / 2) * np.sqrt(J)
    d2 = ((x[:, None] - x[None]) ** 2).sum(axis=2)
    ref = ((d2 < r[:, None] ** 2) & (classes[:, None] != classes[None])).any(axis=1)
    assert np.array_equal(moved, ref)


def test_interpenetration_input_errors_are_named():
    x = np.zeros((2, 2))
    with pytest.raises(ValueError, match="J must be > 0"):
        interpenetrating(x, np.array([0, 1]), np.array([1.0, 0.0]), 0.1)
    with pytest.raises(ValueError, match="classes and J must have shape"):
        interpenetrating(x, np.array([0]), np.ones(2), 0.1)
    with pytest.raises(ValueError, match="spacing must be finite"):
        interpenetrating(x, np.array([0, 1]), np.ones(2), -1.0)
