"""The numbering of the file (or meshio mesh) a mesh was read from (re-exported by
:mod:`geometry.mesh`).

Reading a mesh prunes the points that no cell references (e.g. Gmsh arc centres) and renumbers
the rest, so node ``i`` of the mesh is point ``index[i]`` of the file. Users see the file's
numbering (in Gmsh, ParaView, the file itself), so node indices they give for such a mesh are
translated here; an index of a pruned point has no node and is refused, naming the index and the
file.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from geometry._meshing_report import format_indices

__all__ = ["SourceNumbering"]


@dataclass(frozen=True, eq=False)
class SourceNumbering:
    """Map between the nodes of a mesh and the points of its source.

    Attributes:
        name: the source, for messages (a file path, or e.g. ``"the meshio mesh"``).
        index: ``(n,)`` int64, increasing: the source point of each mesh node.
        n_source: number of points of the source (``>= n``).
    """

    name: str
    index: np.ndarray
    n_source: int

    def __post_init__(self) -> None:
        idx = np.asarray(self.index, dtype=np.int64)
        if idx.ndim != 1 or (idx.size and (idx.min() < 0 or idx.max() >= self.n_source)):
            raise ValueError(f"SourceNumbering.index must index [0, {self.n_source})")
        if np.any(np.diff(idx) <= 0):
            raise ValueError("SourceNumbering.index must be strictly increasing")
        idx.setflags(write=False)
        object.__setattr__(self, "index", idx)

    @property
    def pruned(self) -> bool:
        """Whether the source has points that are no mesh node."""
        return self.index.size != self.n_source

    @cached_property
    def node_of(self) -> np.ndarray:
        """``(n_source,)`` int64: the mesh node of each source point, -1 where pruned."""
        out = np.full(self.n_source, -1, dtype=np.int64)
        out[self.index] = np.arange(self.index.size)
        return out

    def _refuse_pruned(self, points: np.ndarray, what: str) -> None:
        if points.size:
            raise ValueError(
                f"{what} {format_indices(points)} in the numbering of {self.name} refer to "
                f"point(s) that no cell uses (pruned on import: the file has {self.n_source} "
                f"points, {self.index.size} of them in cells); select nodes of the body"
            )

    def nodes(self, indices: np.ndarray, what: str = "node indices") -> np.ndarray:
        """Mesh node indices ``(k,)`` of source point indices ``(k,)`` (order kept).

        Raises ``ValueError`` (starting with ``what``) for an index outside ``[0, n_source)``
        or of a pruned point.
        """
        idx = np.asarray(indices, dtype=np.int64).ravel()
        bad = idx[(idx < 0) | (idx >= self.n_source)]
        if bad.size:
            raise ValueError(
                f"{what} must lie in [0, {self.n_source}) (the numbering of {self.name}), got "
                f"{format_indices(bad)}"
            )
        nodes = self.node_of[idx]
        self._refuse_pruned(idx[nodes < 0], what)
        return nodes

    def mask(self, mask: np.ndarray, what: str = "node mask") -> np.ndarray:
        """Mesh node mask ``(n,)`` of a source point mask ``(n_source,)``; a True entry on a
        pruned point is refused."""
        mask = np.asarray(mask, dtype=bool)
        self._refuse_pruned(np.flatnonzero(mask & (self.node_of < 0)), f"{what} entries")
        return mask[self.index]
