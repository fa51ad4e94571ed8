"""Linear simplex meshes: :class:`TriMesh` (2D triangles) and :class:`TetMesh` (3D tetrahedra).

A mesh holds ``points`` (n, d) float64 in metres and ``cells`` (m, d+1) int64, both C-contiguous
and read-only (meshes are immutable; derived data such as the boundary is cached lazily).
Construction validates shapes, finiteness, index range and repeated indices and raises
``ValueError`` naming the field. Geometric quality (degenerate / inverted cells) is *not* enforced
at construction: it is reported by :meth:`quality_report` and enforced by :meth:`check_quality`,
because the caller decides whether an inverted input is an error or should be :meth:`oriented`.

Conventions (chosen here, relied upon by contact code):

- Positive cells: counter-clockwise triangles, right-handed tetrahedra (``signed_volumes > 0``).
- 2D boundary edges are directed with the body on the left, outward normal ``(dy, -dx) / L``.
  3D boundary faces have outward right-hand-rule normals. Boundary extraction uses the cells with
  negative ones flipped, so the boundary is outward even for clockwise-ordered imported meshes.
- Quality is the normalised radius ratio ``d r_in / r_circ`` in [0, 1] (1 = equilateral).
- A cell is degenerate when ``|V| <= volume_tol * h^d`` (h = mean cell edge length) or its
  quality is below ``quality_tol``; it is inverted when ``V < -volume_tol * h^d``.
- Files go through meshio. 2D meshes are written with a zero z column (VTK and Gmsh store 3D
  points) and a zero z column is dropped again on reading. Points not referenced by any cell
  (e.g. Gmsh arc centres) are pruned on import, with a log message; the mesh keeps the map to
  the file's numbering in :attr:`~TriMesh.source` (:class:`SourceNumbering`), so that node
  indices given in the file's numbering can be translated (and those of pruned points refused).
- Orientation is not changed here; ``bfemp.Scene.add_fem`` flips a mesh whose cells are all
  clockwise (2D) / left-handed (3D), as some generators write them, and refuses mixed ones.
"""

from __future__ import annotations

import contextlib
import io
import logging
from functools import cached_property
from os import PathLike
from pathlib import Path

import meshio
import numpy as np

from geometry import _meshing_metrics as mm
from geometry._checks import points as check_points
from geometry._mesh_source import SourceNumbering
from geometry._meshing_report import MeshQualityReport, format_indices

__all__ = [
    "MeshQualityReport",
    "SourceNumbering",
    "TetMesh",
    "TriMesh",
    "from_meshio",
    "mesh_from_arrays",
    "read_mesh",
]

logger = logging.getLogger(__name__)

_MESHIO_TYPE = {2: "triangle", 3: "tetra"}


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


class _SimplexMesh:
    """Shared implementation of :class:`TriMesh` and :class:`TetMesh`; ``_DIM`` is 2 or 3."""

    _DIM: int = 0

    def __init__(
        self, points: np.ndarray, cells: np.ndarray, *, source: SourceNumbering | None = None
    ) -> None:
        d, cls = self._DIM, type(self).__name__
        pts = np.array(check_points(f"{cls}.points", points, d), copy=True)  # owned, read-only
        if pts.shape[0] < d + 1:
            raise ValueError(f"{cls}.points needs at least {d + 1} points, got {pts.shape[0]}")
        raw = np.asarray(cells)
        if raw.dtype.kind not in "iu":
            raise ValueError(f"{cls}.cells must be an integer array, got dtype {raw.dtype}")
        cel = np.array(raw, dtype=np.int64, order="C", copy=True)
        if cel.ndim != 2 or cel.shape[1] != d + 1 or cel.shape[0] == 0:
            raise ValueError(f"{cls}.cells must have shape (m >= 1, {d + 1}), got {cel.shape}")
        bad = np.flatnonzero(((cel < 0) | (cel >= pts.shape[0])).any(axis=1))
        if bad.size:
            raise ValueError(
                f"{cls}.cells {format_indices(bad)} reference points outside [0, {pts.shape[0]})"
            )
        srt = np.sort(cel, axis=1)
        bad = np.flatnonzero((srt[:, 1:] == srt[:, :-1]).any(axis=1))
        if bad.size:
            raise ValueError(f"{cls}.cells {format_indices(bad)} repeat a vertex index")
        if source is not None and source.index.shape != (pts.shape[0],):
            raise ValueError(
                f"{cls}: source numbering has {source.index.size} nodes, the mesh {pts.shape[0]}"
            )
        self._points = _readonly(pts)
        self._cells = _readonly(cel)
        self._source = source

    # -- basic data -------------------------------------------------------------------------
    @property
    def points(self) -> np.ndarray:
        """Node coordinates, shape (n, d), metres (read-only)."""
        return self._points

    @property
    def cells(self) -> np.ndarray:
        """Vertex indices of each cell, shape (m, d+1), int64 (read-only)."""
        return self._cells

    @property
    def source(self) -> SourceNumbering | None:
        """The numbering of the file this mesh was read from (None when built from arrays)."""
        return self._source

    @property
    def dim(self) -> int:
        """Spatial dimension d (2 or 3)."""
        return self._DIM

    @property
    def n_points(self) -> int:
        """Number of nodes n."""
        return int(self._points.shape[0])

    @property
    def n_cells(self) -> int:
        """Number of cells m."""
        return int(self._cells.shape[0])

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n_points={self.n_points}, n_cells={self.n_cells})"

    # -- geometry and quality ---------------------------------------------------------------
    @cached_property
    def _volumes(self) -> np.ndarray:
        return _readonly(mm.signed_measures(self._points, self._cells))

    def signed_volumes(self) -> np.ndarray:
        """Signed area (m^2, 2D) or volume (m^3, 3D) of each cell, shape (m,); > 0 = positive."""
        return self._volumes

    def total_volume(self) -> float:
        """Sum of the absolute cell volumes (m^2 in 2D, m^3 in 3D)."""
        return float(np.abs(self._volumes).sum())

    def cell_quality(self) -> np.ndarray:
        """Normalised radius ratio ``d r_in / r_circ`` of each cell, shape (m,), in [0, 1]."""
        return mm.radius_ratio(self._points, self._cells)

    def edge_lengths(self) -> np.ndarray:
        """Edge lengths of each cell, shape (m, 3) in 2D or (m, 6) in 3D, metres."""
        return mm.edge_lengths(self._points, self._cells)

    def quality_report(
        self, *, volume_tol: float = 1e-10, quality_tol: float = 1e-3
    ) -> MeshQualityReport:
        """Find degenerate and inverted cells, unused points and non-manifold facets.

        Args:
            volume_tol: a cell with ``|V| <= volume_tol * h^d`` is degenerate (h = mean edge
                length in metres); one with ``V < -volume_tol * h^d`` is inverted.
            quality_tol: a cell with radius-ratio quality below this is degenerate (a sliver:
                aspect ratio ``1 / quality`` above ``1 / quality_tol``); 0 checks no shapes.
        """
        if not volume_tol >= 0.0:
            raise ValueError(f"volume_tol must be >= 0, got {volume_tol}")
        if not 0.0 <= quality_tol <= 1.0:
            raise ValueError(f"quality_tol must be in [0, 1], got {quality_tol}")
        vol = self._volumes
        quality = self.cell_quality()
        h = float(self.edge_lengths().mean())
        tiny = volume_tol * h**self._DIM
        used = np.zeros(self.n_points, dtype=bool)
        used[self._cells.ravel()] = True
        directed, inverse, counts = mm.facets(self._cells)
        over = counts[inverse] > 2
        nonmanifold = mm.unique_rows(np.sort(directed[over], axis=1))[0]
        zero = np.abs(vol) <= tiny
        sliver = ~zero & (quality < quality_tol)
        return MeshQualityReport(
            cell_volumes=vol,
            cell_quality=quality,
            mean_edge_length=h,
            degenerate_cells=np.flatnonzero(zero | sliver),
            inverted_cells=np.flatnonzero(vol < -tiny),
            unused_points=np.flatnonzero(~used),
            nonmanifold_facets=nonmanifold,
            zero_volume_cells=np.flatnonzero(zero),
            sliver_cells=np.flatnonzero(sliver),
            quality_tol=float(quality_tol),
        )

    def check_quality(
        self, name: str = "mesh", *, volume_tol: float = 1e-10, quality_tol: float = 1e-3
    ) -> MeshQualityReport:
        """Like :meth:`quality_report`, but raise ``ValueError`` naming ``name`` on any problem.

        The message lists the offending cell indices (first 10 and the count).
        """
        report = self.quality_report(volume_tol=volume_tol, quality_tol=quality_tol)
        if not report.ok:
            raise ValueError(f"{name}: " + "; ".join(report.problems()))
        return report

    def oriented(self) -> _SimplexMesh:
        """Copy with every cell of negative signed volume flipped (last two vertices swapped):
        counter-clockwise triangles, right-handed tetrahedra."""
        return type(self)(
            self._points, mm.oriented_cells(self._cells, self._volumes), source=self._source
        )

    # -- boundary ---------------------------------------------------------------------------
    @cached_property
    def boundary_facets(self) -> np.ndarray:
        """Outward-oriented boundary facets, shape (k, d): edges (2D) or triangles (3D).

        Every facet used by exactly one cell; computed on the oriented cells.
        """
        oriented = mm.oriented_cells(self._cells, self._volumes)
        return _readonly(mm.boundary_facets(oriented))

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        """Sorted unique indices of the nodes on the boundary, shape (b,), int64."""
        return _readonly(np.unique(self.boundary_facets))

    def boundary_normals(self) -> np.ndarray:
        """Outward unit normals of the boundary facets, shape (k, d)."""
        return mm.facet_normals(self._points, self.boundary_facets)[0]

    def boundary_measures(self) -> np.ndarray:
        """Length (m, 2D) or area (m^2, 3D) of each boundary facet, shape (k,)."""
        return mm.facet_normals(self._points, self.boundary_facets)[1]

    # -- I/O --------------------------------------------------------------------------------
    def to_meshio(
        self,
        *,
        point_data: dict[str, np.ndarray] | None = None,
        cell_data: dict[str, np.ndarray] | None = None,
    ) -> meshio.Mesh:
        """Convert to a ``meshio.Mesh`` with one ``triangle`` / ``tetra`` cell block; 2D points
        are stored as (n, 3) with z = 0 (what VTK and Gmsh expect).

        Args:
            point_data: arrays with leading dimension n to attach to the nodes.
            cell_data: arrays with leading dimension m to attach to the cells.
        """
        pts = self._points
        if self._DIM == 2:
            pts = np.hstack([pts, np.zeros((self.n_points, 1))])
        checks = (("point_data", point_data, self.n_points), ("cell_data", cell_data, self.n_cells))
        for label, data, size in checks:
            for key, arr in (data or {}).items():
                if np.shape(arr)[:1] != (size,):
                    raise ValueError(f"{label}[{key!r}] must have leading dimension {size}")
        return meshio.Mesh(
            np.array(pts),
            [(_MESHIO_TYPE[self._DIM], np.array(self._cells))],
            point_data=dict(point_data or {}),
            cell_data={k: [np.asarray(v)] for k, v in (cell_data or {}).items()},
        )

    def write(
        self,
        path: str | PathLike,
        *,
        point_data: dict[str, np.ndarray] | None = None,
        cell_data: dict[str, np.ndarray] | None = None,
        file_format: str | None = None,
    ) -> None:
        """Write the mesh with meshio (format from the extension unless ``file_format`` is given).

        Raises ``ValueError`` naming ``path`` when meshio cannot write that format.
        """
        path = Path(path)
        mesh = self.to_meshio(point_data=point_data, cell_data=cell_data)
        try:
            meshio.write(path, mesh, file_format=file_format)
        except (meshio.ReadError, meshio.WriteError, KeyError, ValueError) as exc:
            raise ValueError(f"cannot write mesh file {path}: {exc}") from exc


class TriMesh(_SimplexMesh):
    """2D linear triangle mesh: ``points`` (n, 2) in metres, ``cells`` (m, 3) int64."""

    _DIM = 2

    @property
    def boundary_edges(self) -> np.ndarray:
        """Boundary edges (k, 2), directed with the body on the left (outward ``(dy, -dx)``)."""
        return self.boundary_facets

    def min_angles(self) -> np.ndarray:
        """Smallest interior angle of each triangle, shape (m,), radians."""
        return mm.triangle_angles(self._points, self._cells).min(axis=1)


class TetMesh(_SimplexMesh):
    """3D linear tetrahedron mesh: ``points`` (n, 3) in metres, ``cells`` (m, 4) int64."""

    _DIM = 3

    @property
    def boundary_faces(self) -> np.ndarray:
        """Boundary triangles (k, 3) with outward right-hand-rule normals."""
        return self.boundary_facets

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Unique edges of the boundary faces, shape (e, 2), each sorted ``a < b``."""
        tri = self.boundary_facets
        edges = np.sort(tri[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
        return _readonly(mm.unique_rows(edges)[0])


def mesh_from_arrays(
    points: np.ndarray, cells: np.ndarray, *, source: SourceNumbering | None = None
) -> TriMesh | TetMesh:
    """Build a :class:`TriMesh` (points (n, 2), cells (m, 3)) or :class:`TetMesh` ((n, 3), (m, 4)).

    The class is chosen from ``cells.shape[1]``; ``points`` must match (metres).
    """
    shape = np.shape(cells)
    if len(shape) != 2 or shape[1] not in (3, 4):
        raise ValueError(f"cells must have shape (m, 3) or (m, 4), got {shape}")
    cls = TriMesh if shape[1] == 3 else TetMesh
    return cls(points, cells, source=source)


def from_meshio(
    mesh: meshio.Mesh, *, name: str = "mesh", prune_unused: bool = True
) -> TriMesh | TetMesh:
    """Build a mesh from the ``tetra`` (preferred) or ``triangle`` cell blocks of a meshio mesh.

    All blocks of the chosen type are concatenated. For triangles stored with a z column of
    zeros the column is dropped; triangles with non-zero z (a surface in 3D) are rejected.
    With ``prune_unused`` points referenced by no cell are removed and the cells renumbered;
    the result's :attr:`~TriMesh.source` maps its nodes to the points of ``mesh``.

    Args:
        mesh: the meshio mesh; points in metres.
        name: used in error messages (e.g. the file path).
        prune_unused: remove unreferenced points (logged at INFO).
    """
    types = [block.type for block in mesh.cells]
    blocks = [np.asarray(b.data) for b in mesh.cells if b.type == "tetra"]
    dim = 3
    if not blocks:
        blocks = [np.asarray(b.data) for b in mesh.cells if b.type == "triangle"]
        dim = 2
    if not blocks:
        raise ValueError(f"{name}: no 'tetra' or 'triangle' cell block (found {types})")
    cells = np.concatenate(blocks, axis=0)
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{name}: points must have shape (n, 2) or (n, 3), got {points.shape}")
    if dim == 2 and points.shape[1] == 3:
        if np.any(points[:, 2] != 0.0):
            raise ValueError(
                f"{name}: triangle mesh has non-zero z coordinates (a surface mesh in 3D, "
                "not a planar body)"
            )
        points = points[:, :2]
    if dim == 3 and points.shape[1] != 3:
        raise ValueError(f"{name}: tetra mesh needs 3D points, got shape {points.shape}")
    try:
        out = mesh_from_arrays(points, cells)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from exc
    used = np.ones(out.n_points, dtype=bool)
    if prune_unused:
        used[:] = False
        used[out.cells.ravel()] = True
    source = SourceNumbering(name=name, index=np.flatnonzero(used), n_source=out.n_points)
    if not used.all():
        logger.info(
            "%s: pruning %d unreferenced point(s) %s; node indices in the file's numbering are "
            "translated",
            name,
            int((~used).sum()),
            format_indices(np.flatnonzero(~used)),
        )
        new_index = np.cumsum(used) - 1
        return mesh_from_arrays(out.points[used], new_index[out.cells], source=source)
    return mesh_from_arrays(out.points, out.cells, source=source)


def read_mesh(path: str | PathLike, *, prune_unused: bool = True) -> TriMesh | TetMesh:
    """Read a triangle or tetrahedron mesh from any file meshio understands (.vtu, .msh, ...).

    Raises ``ValueError`` naming ``path`` when the file is missing, unreadable or has no
    ``triangle`` / ``tetra`` block. See :func:`from_meshio` for the conversion rules.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"mesh file not found: {path}")
    # meshio prints its parse errors and may call sys.exit on a malformed file: capture both.
    chatter = io.StringIO()
    try:
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            mesh = meshio.read(path)
    except (Exception, SystemExit) as exc:
        detail = " ".join(chatter.getvalue().split()) or repr(exc)
        raise ValueError(f"cannot read mesh file {path}: {detail}") from exc
    return from_meshio(mesh, name=str(path), prune_unused=prune_unused)
