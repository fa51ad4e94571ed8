"""Tests of geometry.shapes: measure, closed outward boundaries, exact boundary nodes, quality,
conformity and input validation of every generator."""

import numpy as np
import pytest

from geometry import _meshing_build as mb
from geometry import shapes
from geometry.mesh import TetMesh, TriMesh

C2 = np.array([0.3, -0.2])
C3 = np.array([0.1, 0.2, -0.3])
SINE = dict(x_range=(-0.5, 0.5), y_base=0.2, thickness=0.05, amplitude=1 / 40, wavelength=0.1)


def facet_counts(mesh):
    """Independent facet sharing counts via np.unique on sorted facets."""
    c = mesh.cells
    if mesh.dim == 2:
        f = c[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2)
    else:
        f = c[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3)
    return np.unique(np.sort(f, axis=1), axis=0, return_counts=True)


def n_edges(mesh):
    c = mesh.cells
    pairs = (
        [[0, 1], [1, 2], [2, 0]] if mesh.dim == 2 else [[i, j] for i in range(4) for j in range(i)]
    )
    return len(np.unique(np.sort(c[:, pairs].reshape(-1, 2), axis=1), axis=0))


def euler_characteristic(mesh):
    _, counts = facet_counts(mesh)
    if mesh.dim == 2:
        return mesh.n_points - n_edges(mesh) + mesh.n_cells
    return mesh.n_points - n_edges(mesh) + len(counts) - mesh.n_cells


def divergence_flux(mesh):
    """Sum over boundary facets of (x . n) |facet| with x at the facet centroid (exact for x)."""
    x = mesh.points[mesh.boundary_facets].mean(axis=1)
    return np.sum(np.einsum("ij,ij->i", x, mesh.boundary_normals()) * mesh.boundary_measures())


# name: (generator, exact measure, Euler characteristic, relative tolerance on the measure)
CASES = {
    "rectangle": (lambda: shapes.rectangle((-1.0, 0.5), (1.0, 1.5), 0.1), 2.0, 1, 1e-12),
    "rectangle_crossed": (
        lambda: shapes.rectangle((-1.0, 0.5), (1.0, 1.5), 0.1, diagonals="crossed"),
        2.0,
        1,
        1e-12,
    ),
    "box": (lambda: shapes.box((0, 0, 0), (1.0, 0.5, 0.3), 0.1), 0.15, 1, 1e-12),
    "disk": (lambda: shapes.disk(C2, 1.0, 0.1), np.pi, 1, 2e-3),
    "ring": (lambda: shapes.ring(C2, 3.0, 4.0, 0.15), 7 * np.pi, 0, 1e-4),
    "semicircular_ring": (
        lambda: shapes.semicircular_ring(C2, 12.0, 14.0, 0.25),
        0.5 * np.pi * (14**2 - 12**2),
        1,
        1e-4,
    ),
    "spherical_shell": (
        lambda: shapes.spherical_shell(C3, 0.45, 0.5, 0.05),
        4 / 3 * np.pi * (0.5**3 - 0.45**3),
        2,
        5e-3,
    ),
    "thick_shell": (
        lambda: shapes.spherical_shell(C3, 0.3, 1.0, 0.15),
        4 / 3 * np.pi * (1.0 - 0.3**3),
        2,
        1.2e-2,
    ),
    "sine_strip": (lambda: shapes.sine_strip(**SINE, h=0.01), 0.05, 1, 1e-12),
    "sine_strip_top_flat": (
        lambda: shapes.sine_strip(**SINE, h=0.01, profile="top", other_side="flat"),
        1.0 * (1 / 40 + 0.05),
        1,
        1e-3,
    ),
}
_CACHE = {}


def generated(name):
    if name not in _CACHE:
        _CACHE[name] = CASES[name][0]()
    return _CACHE[name]


@pytest.mark.parametrize("name", list(CASES))
def test_generated_mesh_is_valid_conforming_and_closed(name):
    mesh = generated(name)
    _, exact, chi, rtol = CASES[name]
    vol = mesh.signed_volumes()
    assert np.all(vol > 0)
    mesh.check_quality(name)
    # Measure within discretisation error (polygonal approximation of curved boundaries).
    assert vol.sum() == pytest.approx(exact, rel=rtol)
    # Conformity: no facet is shared by more than two cells, and the topology is right.
    _, counts = facet_counts(mesh)
    assert counts.max() == 2
    assert len(mesh.boundary_facets) == np.sum(counts == 1)
    assert euler_characteristic(mesh) == chi
    # Outward orientation: divergence theorem, sum of x . n dA = d * volume.
    assert divergence_flux(mesh) == pytest.approx(mesh.dim * vol.sum(), rel=1e-10)
    # Closed boundary.
    facets = mesh.boundary_facets
    if mesh.dim == 2:
        np.testing.assert_array_equal(np.bincount(facets[:, 0]), np.bincount(facets[:, 1]))
        assert np.all(np.bincount(facets.ravel())[mesh.boundary_vertices] % 2 == 0)
    else:
        directed = facets[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2)
        _, edge_use = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
        assert np.all(edge_use == 2)
        assert len(edge_use) == len(mesh.boundary_edges)
        # Consistent orientation: every directed edge meets its reverse.
        fwd = {tuple(e) for e in directed}
        assert all((b, a) in fwd for a, b in directed)


@pytest.mark.parametrize("name", list(CASES))
def test_quality_thresholds(name):
    mesh = generated(name)
    if mesh.dim == 2:
        assert np.degrees(mesh.min_angles().min()) > 25.0
    else:
        assert mesh.cell_quality().min() > 0.1


def test_boundary_vertices_on_analytic_boundary():
    tol = 1e-12
    disk = generated("disk")
    r = np.linalg.norm(disk.points[disk.boundary_vertices] - C2, axis=1)
    np.testing.assert_allclose(r, 1.0, rtol=tol)
    assert np.all(np.linalg.norm(disk.points - C2, axis=1) <= 1.0 + tol)

    ring = generated("ring")
    r = np.linalg.norm(ring.points[ring.boundary_vertices] - C2, axis=1)
    assert np.all(np.isclose(r, 3.0, rtol=tol) | np.isclose(r, 4.0, rtol=tol))
    assert np.sum(np.isclose(r, 3.0)) > 100 and np.sum(np.isclose(r, 4.0)) > 100

    semi = generated("semicircular_ring")
    x = semi.points[semi.boundary_vertices] - C2
    r = np.linalg.norm(x, axis=1)
    on_arc = np.isclose(r, 12.0, rtol=tol) | np.isclose(r, 14.0, rtol=tol)
    on_feet = (np.abs(x[:, 1]) < tol) & (r > 12.0 - tol) & (r < 14.0 + tol)
    assert np.all(on_arc | on_feet) and np.all(semi.points[:, 1] >= C2[1] - tol)
    # The feet are flat: their boundary edges lie on y = center_y with normal (0, -1).
    feet = np.all(np.abs(semi.points[semi.boundary_edges][..., 1] - C2[1]) < tol, axis=1)
    assert feet.sum() == 2 * 10  # 2 feet, ceil(2 / (0.25 sqrt(3) / 2)) = 10 radial layers
    np.testing.assert_allclose(semi.boundary_normals()[feet], [[0.0, -1.0]] * 20, atol=tol)

    shell = generated("spherical_shell")
    r = np.linalg.norm(shell.points[shell.boundary_vertices] - C3, axis=1)
    assert np.all(np.isclose(r, 0.45, rtol=tol) | np.isclose(r, 0.5, rtol=tol))
    assert len(shell.boundary_vertices) == shell.n_points  # one radial layer: all on the surface

    rect = generated("rectangle")
    x = rect.points[rect.boundary_vertices]
    on_side = np.isclose(x[:, 0], -1) | np.isclose(x[:, 0], 1)
    assert np.all(on_side | np.isclose(x[:, 1], 0.5) | np.isclose(x[:, 1], 1.5))

    strip = generated("sine_strip")
    x = strip.points[strip.boundary_vertices]
    wave = 0.2 + np.cos(2 * np.pi * x[:, 0] / 0.1) / 40
    on_curve = np.isclose(x[:, 1], wave, atol=tol) | np.isclose(x[:, 1], wave + 0.05, atol=tol)
    assert np.all(on_curve | np.isclose(np.abs(x[:, 0]), 0.5))
    # The wavy side faces down (body above it): its normals have negative y.
    bottom = np.all(
        np.isclose(
            strip.points[strip.boundary_edges][..., 1],
            0.2 + np.cos(2 * np.pi * strip.points[strip.boundary_edges][..., 0] / 0.1) / 40,
            atol=tol,
        ),
        axis=1,
    )
    assert bottom.sum() > 100 and np.all(strip.boundary_normals()[bottom][:, 1] < 0)


def test_top_flat_sine_strip_has_wave_on_top():
    strip = generated("sine_strip_top_flat")
    x = strip.points[strip.boundary_edges]
    flat = np.all(np.isclose(x[..., 1], 0.2 - 1 / 40 - 0.05), axis=1)
    np.testing.assert_allclose(strip.boundary_normals()[flat], [[0.0, -1.0]] * flat.sum())
    assert strip.points[:, 1].max() == pytest.approx(0.2 + 1 / 40)


def polygon_deficits(mesh, center, radii):
    """Relative area missing from each inscribed boundary polygon (one per radius), and the
    exact area between them. Edge ab on the circle of radius R spans a triangle (c, a, b)."""
    x = mesh.points[mesh.boundary_edges] - center
    r = np.linalg.norm(x, axis=2)
    cross = x[:, 0, 0] * x[:, 1, 1] - x[:, 0, 1] * x[:, 1, 0]
    areas = []
    for radius in radii:
        on = np.all(np.isclose(r, radius), axis=1)
        areas.append(0.5 * abs(cross[on].sum()))
    return areas


@pytest.mark.parametrize(
    ("make", "arc"), [(shapes.ring, 2 * np.pi), (shapes.semicircular_ring, np.pi)]
)
def test_ring_area_converges_and_fills_region_between_polygons(make, arc):
    deficits, errors = [], []
    for h in (0.4, 0.2, 0.1, 0.05):
        mesh = make((0.0, 0.0), 1.0, 2.0, h)
        inner, outer = polygon_deficits(mesh, 0.0, (1.0, 2.0))
        # No gaps or overlaps: the mesh is exactly the region between the two polygons.
        assert mesh.total_volume() == pytest.approx(outer - inner, rel=1e-12)
        exact = 0.5 * arc * (4.0 - 1.0)
        errors.append(abs(mesh.total_volume() - exact) / exact)
        deficits.append([1 - inner / (0.5 * arc), 1 - outer / (0.5 * arc * 4.0)])
        assert errors[-1] < 0.5 * h**2  # the two O(h^2) polygon deficits partly cancel
    ratios = np.array(deficits[:-1]) / np.array(deficits[1:])
    assert np.all((ratios > 3.0) & (ratios < 5.5))  # second order in h
    assert errors[-1] < errors[0]


@pytest.mark.parametrize(
    ("make", "exact"),
    [
        (lambda h: shapes.disk((0, 0), 1.0, h), np.pi),
        (lambda h: shapes.spherical_shell((0, 0, 0), 0.45, 0.5, h), 4 / 3 * np.pi * 0.033875),
    ],
)
def test_measure_error_shrinks_second_order(make, exact):
    errors = np.array([abs(make(h).total_volume() - exact) / exact for h in (0.4, 0.2, 0.1)])
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 2.5) & (ratios < 5.5))


def test_structured_counts_and_single_cell_plate():
    rect = shapes.rectangle((0, 0), (2.0, 1.0), 0.25)
    assert (rect.n_points, rect.n_cells) == (9 * 5, 2 * 8 * 4)
    crossed = shapes.rectangle((0, 0), (2.0, 1.0), 0.25, diagonals="crossed")
    assert (crossed.n_points, crossed.n_cells) == (9 * 5 + 8 * 4, 4 * 8 * 4)
    plate = shapes.rectangle((-2, 0), (2, 0.1), 100.0)
    assert (plate.n_points, plate.n_cells) == (4, 2) and plate.total_volume() == pytest.approx(0.4)
    b = shapes.box((0, 0, 0), (1.0, 0.5, 0.25), 0.25)
    assert (b.n_points, b.n_cells) == (5 * 3 * 2, 6 * 4 * 2 * 1)
    assert isinstance(b, TetMesh) and isinstance(rect, TriMesh)


def test_shell_seams_merged():
    h = 0.05
    shell = generated("spherical_shell")
    n = int(np.ceil(0.5 * np.pi * 0.5 / h))
    assert shell.n_points == 2 * (6 * n * n + 2)
    assert shell.n_cells == 6 * n * n * 6
    assert len(np.unique(np.round(shell.points, 9), axis=0)) == shell.n_points


def test_hex_split_conforms_under_any_numbering():
    # A 3 x 3 x 3 block of unit hexes with a random global numbering: the min-index rule must
    # still cut every shared face identically from both sides.
    rng = np.random.default_rng(3)
    n = 3
    grid = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    perm = rng.permutation(len(grid))
    points = np.empty_like(grid, dtype=float)
    points[perm] = grid
    index = perm.reshape(n + 1, n + 1, n + 1)
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(n)] * 3, indexing="ij"))
    hexes = np.stack([index[i + a, j + b, k + c] for a, b, c in mb.HEX_CORNERS], axis=1)
    mesh = TetMesh(points, mb.split_hexes(points, hexes))
    assert np.all(mesh.signed_volumes() > 0)
    assert mesh.total_volume() == pytest.approx(27.0)
    _, counts = facet_counts(mesh)
    assert counts.max() == 2
    assert np.sum(counts == 1) == 6 * 9 * 2  # the 54 boundary squares, two triangles each


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: shapes.rectangle((0, 0), (1, 1), 0.0), "h must be"),
        (lambda: shapes.rectangle((0, 0), (1, 1), float("nan")), "h must be"),
        (lambda: shapes.rectangle((0, 0), (0, 1), 0.1), "upper must exceed lower"),
        (lambda: shapes.rectangle((0, 0, 0), (1, 1), 0.1), "lower must be 2"),
        (lambda: shapes.rectangle((0, 0), (1, 1), 0.1, diagonals="x"), "diagonals must be"),
        (lambda: shapes.box((0, 0, 0), (1, 1), 0.1), "upper must be 3"),
        (lambda: shapes.box((0, 0, 0), (1, 1, -1), 0.1), "upper must exceed lower"),
        (lambda: shapes.disk((0, 0), -1.0, 0.1), "radius must be"),
        (lambda: shapes.disk((0, "a"), 1.0, 0.1), "center must be"),
        (lambda: shapes.ring((0, 0), 2.0, 1.0, 0.1), "r_outer must exceed r_inner"),
        (lambda: shapes.ring((0, 0), 0.0, 1.0, 0.1), "r_inner must be"),
        (lambda: shapes.semicircular_ring((0, 0), 1.0, None, 0.1), "r_outer must be"),
        (lambda: shapes.spherical_shell((0, 0), 1.0, 2.0, 0.1), "center must be 3"),
        (lambda: shapes.spherical_shell((0, 0, 0), 1.0, 1.0, 0.1), "r_outer must exceed"),
        (lambda: shapes.sine_strip(**{**SINE, "x_range": (1, 0)}, h=0.01), "x_range must be"),
        (lambda: shapes.sine_strip(**{**SINE, "thickness": 0}, h=0.01), "thickness must be"),
        (lambda: shapes.sine_strip(**{**SINE, "wavelength": -1}, h=0.01), "wavelength must be"),
        (lambda: shapes.sine_strip(**{**SINE, "amplitude": np.inf}, h=0.01), "amplitude must be"),
        (lambda: shapes.sine_strip(**SINE, h=0.01, profile="left"), "profile must be"),
        (lambda: shapes.sine_strip(**SINE, h=0.01, other_side="x"), "other_side must be"),
    ],
)
def test_bad_inputs_raise_naming_field(call, match):
    with pytest.raises(ValueError, match=match):
        call()
