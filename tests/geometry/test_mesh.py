"""Tests of geometry.mesh: validation, volumes, quality, boundary extraction and meshio I/O."""

import logging

import meshio
import numpy as np
import pytest

from geometry.mesh import TetMesh, TriMesh, from_meshio, mesh_from_arrays, read_mesh

SQUARE_PTS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
SQUARE_TRI = np.array([[0, 1, 2], [0, 2, 3]])
CUBE_PTS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
# Six right-handed tetrahedra around the diagonal 0-6.
CUBE_TET = np.array(
    [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]]
)
CUBE_TET_MIXED = CUBE_TET.copy()
CUBE_TET_MIXED[[1, 4]] = CUBE_TET[[1, 4]][:, [1, 0, 2, 3]]  # two left-handed cells


def grid_mesh(n=4):
    """Unit square, n x n quads, each cut into two counter-clockwise triangles."""
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    pts = np.stack([x.ravel(), y.ravel()], 1)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = (j * (n + 1) + i).ravel()
    tri = np.concatenate(
        [np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)]
    )
    return TriMesh(pts, tri)


def regular_tet():
    return np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)


# --------------------------------------------------------------------------- construction
def test_arrays_are_float64_int64_contiguous_readonly_copies():
    pts = SQUARE_PTS.astype(np.float32)
    cells = SQUARE_TRI.astype(np.int32)
    mesh = TriMesh(pts, cells)
    assert mesh.points.dtype == np.float64 and mesh.cells.dtype == np.int64
    assert mesh.points.flags.c_contiguous and mesh.cells.flags.c_contiguous
    assert (mesh.dim, mesh.n_points, mesh.n_cells) == (2, 4, 2)
    with pytest.raises(ValueError):
        mesh.points[0, 0] = 5.0
    pts[0, 0] = 7.0  # the mesh holds a copy
    assert mesh.points[0, 0] == 0.0


@pytest.mark.parametrize(
    ("points", "cells", "match"),
    [
        (np.zeros((4, 3)), SQUARE_TRI, r"points must have shape \(n, 2\)"),
        (SQUARE_PTS[:2], SQUARE_TRI, r"points needs at least 3 points"),
        (SQUARE_PTS, SQUARE_TRI[:, :2], r"cells must have shape \(m >= 1, 3\)"),
        (
            np.array([[0, 0], [1, np.nan], [1, 1], [0, 1.0]]),
            SQUARE_TRI,
            r"points.*non-finite.*\[1\]",
        ),
        (SQUARE_PTS, np.array([[0, 1, 2], [0, 2, 4]]), r"cells \[1\] reference points outside"),
        (SQUARE_PTS, np.array([[0, 1, 2], [0, -1, 3]]), r"cells \[1\] reference"),
        (SQUARE_PTS, np.array([[0, 1, 1], [0, 2, 3]]), r"cells \[0\] repeat a vertex"),
        (SQUARE_PTS, SQUARE_TRI.astype(float), r"cells must be an integer array"),
        (SQUARE_PTS, np.zeros((0, 3), dtype=int), r"cells must have shape"),
    ],
)
def test_bad_arrays_raise_naming_field(points, cells, match):
    with pytest.raises(ValueError, match=match):
        TriMesh(points, cells)


def test_mesh_from_arrays_picks_class_by_shape():
    assert isinstance(mesh_from_arrays(SQUARE_PTS, SQUARE_TRI), TriMesh)
    tet = mesh_from_arrays(CUBE_PTS, CUBE_TET)
    assert isinstance(tet, TetMesh) and tet.dim == 3
    with pytest.raises(ValueError, match="cells must have shape"):
        mesh_from_arrays(SQUARE_PTS, np.array([[0, 1]]))
    with pytest.raises(ValueError, match=r"TetMesh.points must have shape \(n, 3\)"):
        mesh_from_arrays(SQUARE_PTS, np.array([[0, 1, 2, 3]]))


# --------------------------------------------------------------------------- volumes, quality
def test_signed_volumes_match_determinants_and_orientation():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(30, 3))
    cells = np.array([rng.choice(30, 4, replace=False) for _ in range(40)])
    vol = TetMesh(pts, cells).signed_volumes()
    e = pts[cells[:, 1:]] - pts[cells[:, :1]]
    np.testing.assert_allclose(vol, np.linalg.det(e.transpose(0, 2, 1)) / 6.0, rtol=1e-12)
    tri = TriMesh(SQUARE_PTS, np.array([[0, 1, 2], [0, 3, 2]]))
    np.testing.assert_allclose(tri.signed_volumes(), [0.5, -0.5])
    tet = TetMesh(np.vstack([np.zeros(3), np.eye(3)]), np.array([[0, 1, 2, 3], [0, 2, 1, 3]]))
    np.testing.assert_allclose(tet.signed_volumes(), [1 / 6, -1 / 6])


def test_quality_is_one_for_equilateral_and_matches_radius_ratio():
    eq = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]])
    assert TriMesh(eq, np.array([[0, 1, 2]])).cell_quality()[0] == pytest.approx(1.0)
    assert TetMesh(regular_tet(), np.array([[0, 1, 2, 3]])).cell_quality()[0] == pytest.approx(1)
    # Independent radius ratio of random triangles: r = A / s, R = abc / (4A).
    rng = np.random.default_rng(1)
    pts = rng.random((20, 2))
    cells = np.array([rng.choice(20, 3, replace=False) for _ in range(30)])
    q = TriMesh(pts, cells).cell_quality()
    x = pts[cells]
    a, b, c = (np.linalg.norm(x[:, i] - x[:, (i + 1) % 3], axis=1) for i in range(3))
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    np.testing.assert_allclose(q, 2 * (area / ((a + b + c) / 2)) / (a * b * c / (4 * area)))
    # Independent tet radius ratio: circumcentre from a linear solve, r = 3V / S.
    pts3 = rng.random((20, 3))
    cells3 = np.array([rng.choice(20, 4, replace=False) for _ in range(30)])
    q3 = TetMesh(pts3, cells3).cell_quality()
    for cell, qi in zip(cells3[:5], q3[:5], strict=True):
        x = pts3[cell]
        centre = np.linalg.solve(2 * (x[1:] - x[0]), (x[1:] ** 2).sum(1) - (x[0] ** 2).sum())
        big_r = np.linalg.norm(centre - x[0])
        vol = abs(np.linalg.det(x[1:] - x[0])) / 6
        faces = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
        s = sum(0.5 * np.linalg.norm(np.cross(x[f[1]] - x[f[0]], x[f[2]] - x[f[0]])) for f in faces)
        assert qi == pytest.approx(3 * (3 * vol / s) / big_r, rel=1e-9)


def test_quality_decreases_as_triangle_flattens():
    heights = [0.9, 0.3, 0.1, 0.01]
    q = [
        TriMesh(np.array([[0, 0], [1, 0], [0.5, t]]), np.array([[0, 1, 2]])).cell_quality()[0]
        for t in heights
    ]
    assert np.all(np.diff(q) < 0) and q[-1] < 0.05


def test_min_angles_of_right_triangle():
    mesh = TriMesh(np.array([[0, 0], [2, 0], [0, 1.0]]), np.array([[0, 1, 2]]))
    assert mesh.min_angles()[0] == pytest.approx(np.arctan(0.5))


def test_good_mesh_passes_check_quality():
    mesh = grid_mesh()
    report = mesh.check_quality("grid")
    assert report.ok and report.min_quality == pytest.approx(mesh.cell_quality().min())
    assert report.mean_edge_length == pytest.approx(np.mean(mesh.edge_lengths()))


def test_inverted_cells_detected_with_indices():
    mesh = grid_mesh()
    cells = mesh.cells.copy()
    cells[[3, 11]] = cells[[3, 11]][:, [0, 2, 1]]
    bad = TriMesh(mesh.points, cells)
    report = bad.quality_report()
    np.testing.assert_array_equal(report.inverted_cells, [3, 11])
    assert report.degenerate_cells.size == 0
    with pytest.raises(ValueError, match=r"beam: 2 inverted cell\(s\).*\[3, 11\]"):
        bad.check_quality("beam")
    fixed = bad.oriented()
    assert np.all(fixed.signed_volumes() > 0)
    np.testing.assert_allclose(np.abs(fixed.signed_volumes()), np.abs(bad.signed_volumes()))
    fixed.check_quality()


def test_many_inverted_cells_list_first_ten_and_count():
    mesh = grid_mesh(5)
    flipped = TriMesh(mesh.points, mesh.cells[:, [0, 2, 1]])
    with pytest.raises(ValueError, match=r"50 inverted.*\[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, \.\.\.\] "):
        flipped.check_quality()


def test_degenerate_cells_detected_2d_and_3d():
    pts = np.vstack([SQUARE_PTS, [[2.0, 0.0]], [[3.0, 1e-9]]])
    mesh = TriMesh(pts, np.array([[0, 1, 2], [0, 2, 3], [1, 4, 5]]))  # last one nearly collinear
    report = mesh.quality_report()
    np.testing.assert_array_equal(report.degenerate_cells, [2])
    with pytest.raises(ValueError, match=r"plate: 1 degenerate cell\(s\).*\[2\]"):
        mesh.check_quality("plate")
    # A flat tetrahedron (four coplanar points) next to a good one.
    pts3 = np.vstack([regular_tet(), [[0.3, 0.2, -1.0]], [[0.5, 0.5, -1.0]]])
    cells3 = np.array([[0, 1, 2, 3], [1, 2, 4, 5]])
    tet = TetMesh(pts3, cells3)
    np.testing.assert_array_equal(tet.quality_report().degenerate_cells, [1])
    with pytest.raises(ValueError, match=r"shell: .*degenerate.*\[1\]"):
        tet.check_quality("shell")


def test_unused_points_and_nonmanifold_facets_reported():
    pts = np.vstack([SQUARE_PTS, [[5.0, 5.0]]])
    with pytest.raises(ValueError, match=r"1 point\(s\) used by no cell.*\[4\]"):
        TriMesh(pts, SQUARE_TRI).check_quality()
    fan = np.array([[0, 0], [1, 0], [0.5, 1], [0.5, -1], [0.5, 2]])
    mesh = TriMesh(fan, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))  # edge 0-1 used three times
    report = mesh.quality_report()
    np.testing.assert_array_equal(report.nonmanifold_facets, [[0, 1]])
    with pytest.raises(ValueError, match=r"shared by >2 cells: \[0, 1\]"):
        mesh.check_quality()


def test_quality_report_rejects_bad_tolerances():
    with pytest.raises(ValueError, match="quality_tol"):
        grid_mesh().quality_report(quality_tol=2.0)
    with pytest.raises(ValueError, match="volume_tol"):
        grid_mesh().quality_report(volume_tol=-1.0)


# --------------------------------------------------------------------------- boundary
def test_square_boundary_edges_have_body_on_the_left():
    for cells in (SQUARE_TRI, SQUARE_TRI[:, ::-1]):  # counter-clockwise and clockwise input
        mesh = TriMesh(SQUARE_PTS, cells)
        edges = mesh.boundary_edges
        assert edges.shape == (4, 2)
        mid = mesh.points[edges].mean(axis=1)
        n = mesh.boundary_normals()
        np.testing.assert_allclose(n, np.round(2 * (mid - 0.5)), atol=1e-14)
        d = mesh.points[edges[:, 1]] - mesh.points[edges[:, 0]]
        np.testing.assert_allclose(n, np.stack([d[:, 1], -d[:, 0]], 1) / 1.0)
        np.testing.assert_array_equal(mesh.boundary_vertices, [0, 1, 2, 3])


def test_grid_boundary_is_closed_and_outward():
    mesh = grid_mesh(6)
    edges = mesh.boundary_edges
    assert len(edges) == 24
    # Every boundary vertex starts exactly one edge and ends exactly one edge.
    np.testing.assert_array_equal(np.bincount(edges[:, 0]), np.bincount(edges[:, 1]))
    assert set(np.unique(edges)) == set(mesh.boundary_vertices)
    x = mesh.points[edges].mean(axis=1)
    flux = np.sum(np.einsum("ij,ij->i", x, mesh.boundary_normals()) * mesh.boundary_measures())
    assert flux == pytest.approx(2 * mesh.total_volume())


def test_cube_boundary_faces_outward_and_closed():
    mesh = TetMesh(CUBE_PTS, CUBE_TET_MIXED).oriented()
    assert np.all(mesh.signed_volumes() > 0)
    faces = mesh.boundary_faces
    assert faces.shape == (12, 3)
    np.testing.assert_array_equal(mesh.boundary_vertices, np.arange(8))
    assert mesh.boundary_edges.shape == (18, 2)  # 12 cube edges + 6 face diagonals
    assert np.all(mesh.boundary_edges[:, 0] < mesh.boundary_edges[:, 1])
    n = mesh.boundary_normals()
    centre = mesh.points[faces].mean(axis=1)
    expected = np.where(np.isclose(centre, 0.0), -1.0, 0.0) + np.where(np.isclose(centre, 1), 1, 0)
    np.testing.assert_allclose(n, expected, atol=1e-14)
    np.testing.assert_allclose(mesh.boundary_measures().sum(), 6.0)
    flux = np.sum(np.einsum("ij,ij->i", centre, n) * mesh.boundary_measures())
    assert flux == pytest.approx(3.0 * mesh.total_volume())


def test_boundary_of_mixed_orientation_tets_is_outward():
    mesh = TetMesh(CUBE_PTS, CUBE_TET_MIXED)
    np.testing.assert_array_equal(mesh.quality_report().inverted_cells, [1, 4])
    centre = mesh.points[mesh.boundary_faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", centre - 0.5, mesh.boundary_normals()) > 0)


def test_single_tet_faces_point_away_from_opposite_vertex():
    mesh = TetMesh(regular_tet(), np.array([[0, 1, 2, 3]]))
    centre = mesh.points[mesh.boundary_faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", centre, mesh.boundary_normals()) > 0)


# --------------------------------------------------------------------------- meshio
@pytest.mark.parametrize("suffix", [".vtu", ".msh", ".vtk"])
@pytest.mark.parametrize("dim", [2, 3])
def test_meshio_round_trip(tmp_path, suffix, dim):
    mesh = grid_mesh(3) if dim == 2 else TetMesh(CUBE_PTS, CUBE_TET).oriented()
    path = tmp_path / f"body{suffix}"
    mesh.write(path)
    back = read_mesh(path)
    assert type(back) is type(mesh) and back.points.shape == mesh.points.shape
    np.testing.assert_allclose(back.points, mesh.points)
    np.testing.assert_array_equal(back.cells, mesh.cells)


def test_point_and_cell_data_written(tmp_path):
    mesh = grid_mesh(2)
    temp = np.arange(mesh.n_points, dtype=float)
    path = tmp_path / "data.vtu"
    mesh.write(path, point_data={"T": temp}, cell_data={"id": np.arange(mesh.n_cells)})
    raw = meshio.read(path)
    np.testing.assert_allclose(raw.point_data["T"], temp)
    np.testing.assert_array_equal(raw.cell_data["id"][0], np.arange(mesh.n_cells))
    assert raw.points.shape[1] == 3 and np.all(raw.points[:, 2] == 0)
    with pytest.raises(ValueError, match=r"point_data\['T'\] must have leading dimension 9"):
        mesh.to_meshio(point_data={"T": temp[:3]})


def test_from_meshio_prefers_tetra_and_prunes_unused_points(caplog):
    pts = np.vstack([CUBE_PTS, [[9.0, 9.0, 9.0]]])  # last point unused (e.g. a Gmsh arc centre)
    raw = meshio.Mesh(pts[[8, *range(8)]], [("triangle", [[1, 2, 3]]), ("tetra", CUBE_TET + 1)])
    with caplog.at_level(logging.INFO, logger="geometry.mesh"):
        mesh = from_meshio(raw)
    assert "pruning 1 unreferenced" in caplog.text
    assert isinstance(mesh, TetMesh) and mesh.n_points == 8
    np.testing.assert_allclose(mesh.points, CUBE_PTS)
    np.testing.assert_array_equal(mesh.cells, CUBE_TET)
    kept = from_meshio(raw, prune_unused=False)
    assert kept.n_points == 9


def test_from_meshio_drops_zero_z_and_rejects_surfaces():
    pts3 = np.hstack([SQUARE_PTS, np.zeros((4, 1))])
    mesh = from_meshio(meshio.Mesh(pts3, [("triangle", SQUARE_TRI)]))
    assert isinstance(mesh, TriMesh) and mesh.points.shape == (4, 2)
    pts3[2, 2] = 0.5
    with pytest.raises(ValueError, match="surf.msh: triangle mesh has non-zero z"):
        from_meshio(meshio.Mesh(pts3, [("triangle", SQUARE_TRI)]), name="surf.msh")
    with pytest.raises(ValueError, match=r"lines: no 'tetra' or 'triangle' cell block.*'line'"):
        from_meshio(meshio.Mesh(pts3, [("line", [[0, 1]])]), name="lines")
    with pytest.raises(ValueError, match=r"bad: TriMesh.cells \[0\] reference points outside"):
        from_meshio(meshio.Mesh(SQUARE_PTS, [("triangle", [[0, 1, 7]])]), name="bad")


def test_file_errors_name_the_path(tmp_path):
    missing = tmp_path / "nothing.vtu"
    with pytest.raises(ValueError, match="mesh file not found: .*nothing.vtu"):
        read_mesh(missing)
    garbage = tmp_path / "garbage.vtu"
    garbage.write_text("not a mesh")
    with pytest.raises(ValueError, match="cannot read mesh file .*garbage.vtu"):
        read_mesh(garbage)
    lines = tmp_path / "lines.vtu"
    meshio.write(
        lines, meshio.Mesh(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], [("line", [[0, 1]])])
    )
    with pytest.raises(ValueError, match="lines.vtu: no 'tetra' or 'triangle'"):
        read_mesh(lines)
    with pytest.raises(ValueError, match="cannot write mesh file .*out.unknownext"):
        grid_mesh(2).write(tmp_path / "out.unknownext")


def test_from_meshio_keeps_the_numbering_of_the_file():
    pts = np.vstack([[[9.0, 9.0]], SQUARE_PTS[:2], [[8.0, 8.0]], SQUARE_PTS[2:]])  # 0, 3 unused
    raw = meshio.Mesh(np.hstack([pts, np.zeros((6, 1))]), [("triangle", [[1, 2, 4], [1, 4, 5]])])
    mesh = from_meshio(raw, name="sq.msh")
    np.testing.assert_allclose(mesh.points, SQUARE_PTS)
    source = mesh.source
    assert source.pruned and source.n_source == 6 and source.name == "sq.msh"
    np.testing.assert_array_equal(source.index, [1, 2, 4, 5])
    np.testing.assert_array_equal(source.nodes([5, 1, 4]), [3, 0, 2])
    np.testing.assert_array_equal(source.mask(np.array([0, 1, 0, 0, 0, 1], bool)), [1, 0, 0, 1])
    with pytest.raises(ValueError, match=r"picked \[0, 3\] in the numbering of sq.msh .*no cell"):
        source.nodes([1, 0, 3], "picked")
    with pytest.raises(ValueError, match=r"must lie in \[0, 6\) .*got \[6\]"):
        source.nodes([6])
    assert mesh.oriented().source is source  # the numbering survives re-orientation
    assert not from_meshio(raw, prune_unused=False).source.pruned
    assert mesh_from_arrays(SQUARE_PTS, SQUARE_TRI).source is None


def test_slivers_are_reported_by_aspect_ratio_not_area():
    # two triangles of 0.2 m^2 making a 40 m x 0.01 m plate: large area, bad shape
    plate = TriMesh(
        np.array([[0, 0], [40, 0], [40, 0.01], [0, 0.01]]), np.array([[0, 1, 2], [0, 2, 3]])
    )
    report = plate.quality_report()
    np.testing.assert_array_equal(report.sliver_cells, [0, 1])
    assert report.zero_volume_cells.size == 0
    aspect = 1.0 / plate.cell_quality()
    assert 1e3 < aspect.min()
    with pytest.raises(ValueError) as info:
        plate.check_quality("plate")
    message = str(info.value)
    assert message.startswith("plate: 2 degenerate cell(s) (slivers: the shape, not the area")
    assert f"aspect ratio up to {aspect.max():.3g} at cell" in message and "limit 1e+03" in message
    plate.check_quality("plate", quality_tol=0.0)  # shapes unchecked: only the area counts
