"""The quality report of :meth:`geometry.mesh.TriMesh.quality_report` (re-exported there)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def format_indices(idx: np.ndarray, limit: int = 10) -> str:
    """'[i0, i1, ...]' of the first ``limit`` indices plus the total count when longer."""
    head = ", ".join(str(int(i)) for i in idx[:limit])
    return f"[{head}]" if idx.size <= limit else f"[{head}, ...] ({idx.size} in total)"


@dataclass(frozen=True, kw_only=True)
class MeshQualityReport:
    """Result of :meth:`TriMesh.quality_report` / :meth:`TetMesh.quality_report`.

    Attributes:
        cell_volumes: (m,) signed area (m^2, 2D) or volume (m^3, 3D) of each cell.
        cell_quality: (m,) normalised radius ratio in [0, 1], 1 = equilateral.
        mean_edge_length: mean length of the cells' edges h (m), the scale of the tolerances.
        degenerate_cells: sorted indices of cells with ``|V| <= volume_tol h^d`` or quality below
            ``quality_tol`` (the union of ``zero_volume_cells`` and ``sliver_cells``).
        inverted_cells: sorted indices of cells with ``V < -volume_tol h^d``.
        unused_points: sorted indices of points referenced by no cell (zero mass in FEM).
        nonmanifold_facets: (k, d) sorted vertex indices of facets shared by more than two cells.
        zero_volume_cells: sorted indices of cells with ``|V| <= volume_tol h^d``.
        sliver_cells: sorted indices of the other degenerate cells: a volume above the tolerance
            but a quality below ``quality_tol``, i.e. an aspect ratio ``1 / quality`` (= R / (d r),
            circumradius over d times the inradius; 1 for the equilateral simplex) above
            ``1 / quality_tol``: the shape, not the size, is the problem.
        quality_tol: the quality limit used (0: shapes were not checked).
    """

    cell_volumes: np.ndarray
    cell_quality: np.ndarray
    mean_edge_length: float
    degenerate_cells: np.ndarray
    inverted_cells: np.ndarray
    unused_points: np.ndarray
    nonmanifold_facets: np.ndarray
    zero_volume_cells: np.ndarray
    sliver_cells: np.ndarray
    quality_tol: float

    @property
    def min_quality(self) -> float:
        """Smallest cell quality (dimensionless)."""
        return float(self.cell_quality.min())

    @property
    def ok(self) -> bool:
        """True when there is no degenerate or inverted cell, unused point or non-manifold facet."""
        return not (
            self.degenerate_cells.size
            or self.inverted_cells.size
            or self.unused_points.size
            or self.nonmanifold_facets.size
        )

    def problems(self) -> list[str]:
        """Human-readable description of each problem found (empty when :attr:`ok`)."""
        out = [
            f"{found.size} {what} at indices {format_indices(found)}"
            for found, what in (
                (self.inverted_cells, "inverted cell(s) (negative signed volume)"),
                (self.zero_volume_cells, "degenerate cell(s) (zero or near-zero area/volume)"),
            )
            if found.size
        ]
        if self.sliver_cells.size:
            aspect = 1.0 / np.maximum(self.cell_quality[self.sliver_cells], 1e-300)
            worst = int(self.sliver_cells[int(np.argmax(aspect))])
            out.append(
                f"{self.sliver_cells.size} degenerate cell(s) (slivers: the shape, not the "
                f"area, is the problem: aspect ratio up to {aspect.max():.3g} at cell {worst}, "
                f"limit {1.0 / self.quality_tol:.3g}; aspect ratio = circumradius / (d x "
                f"inradius), 1 for an equilateral cell) at indices "
                f"{format_indices(self.sliver_cells)}"
            )
        if self.unused_points.size:
            found = self.unused_points
            out.append(f"{found.size} point(s) used by no cell at indices {format_indices(found)}")
        if self.nonmanifold_facets.size:
            rows = "; ".join(str(r.tolist()) for r in self.nonmanifold_facets[:10])
            out.append(f"{len(self.nonmanifold_facets)} facet(s) shared by >2 cells: {rows}")
        return out
