"""The inputs of a ``Scene``, checked and turned into arrays; errors name the body and field."""

from __future__ import annotations

import logging

import meshio
import numpy as np

from bfemp.materials import Material
from bfemp.motion import Fixed, Linear, Motion, Sequence
from geometry.mesh import SourceNumbering, TetMesh, TriMesh, from_meshio, mesh_from_arrays

__all__ = [
    "as_mesh",
    "check_fem_mesh",
    "check_material",
    "check_translation",
    "initial_velocity",
    "node_selection",
    "prescribed_mask",
]

log = logging.getLogger("bfemp.scene")


def check_material(material: object, where: str) -> None:
    """``ValueError`` naming ``where`` unless ``material`` is one of bfemp's materials."""
    if not isinstance(material, Material):
        raise ValueError(
            f"{where}: material must be bfemp.NeoHookean, bfemp.LinearElastic or "
            f"bfemp.BulkShearHyperelastic, got {type(material).__name__}"
        )


def check_fem_mesh(mesh: TriMesh | TetMesh, where: str, *, rigid: bool) -> TriMesh | TetMesh:
    """The mesh of a FEM body, oriented and checked; ``ValueError`` naming ``where`` if bad.

    A mesh whose cells are all clockwise (2D) / left-handed (3D), as some generators write
    them, is flipped (logged at INFO); one with both orientations is refused (its negative
    cells may be folded over). Cells of (near) zero area/volume are refused. Slivers (aspect
    ratio above 1e3) are refused for deformable bodies only: a ``rigid`` body (every node
    prescribed) never deforms, so the shape of its cells does not matter.
    """
    volumes = mesh.signed_volumes()
    if np.all(volumes < 0.0):
        log.info(
            "%s: all %d cells are %s; flipped to the positive orientation",
            where,
            mesh.n_cells,
            "clockwise" if mesh.dim == 2 else "left-handed",
        )
        mesh = mesh.oriented()
    mesh.check_quality(name=where, quality_tol=0.0 if rigid else 1e-3)
    return mesh


def check_translation(motion: object) -> None:
    """Moving level sets translate: Linear, Fixed, or Sequences of them."""
    if isinstance(motion, Sequence):
        for _, part in motion.segments:
            check_translation(part)
    elif not isinstance(motion, Linear | Fixed):
        raise ValueError(
            "add_boundary: motion must translate the level set (bfemp.motion.Linear, Fixed or a "
            f"Sequence of them), got {type(motion).__name__}"
        )


def as_mesh(points: object, cells: np.ndarray | None, dim: int, where: str) -> TriMesh | TetMesh:
    """A FEM body's mesh from a mesh, a meshio mesh or ``points (n, d)`` and ``cells (m, d + 1)``
    arrays (m), in a ``dim``-D scene; ``ValueError`` naming ``where`` if it does not fit."""
    if isinstance(points, TriMesh | TetMesh):
        mesh = points
    elif isinstance(points, meshio.Mesh):
        try:
            mesh = from_meshio(points, name="the meshio mesh")
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from None
    else:
        if cells is None:
            raise ValueError(f"{where}: cells are required when points is an array")
        shape = np.shape(cells)
        if len(shape) == 2 and shape[1] in (3, 4) and shape[1] != dim + 1:
            given = "tetrahedra" if shape[1] == 4 else "triangles"
            kind = "triangles" if dim == 2 else "tetrahedra"
            raise ValueError(
                f"{where}: cells of shape {shape} are {given}, a {shape[1] - 1}D mesh, but "
                f"the scene is {dim}D: cells must have shape (m, {dim + 1}) ({kind})"
            )
        try:
            mesh = mesh_from_arrays(np.asarray(points), np.asarray(cells))
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from None
    if mesh.dim != dim:
        raise ValueError(f"{where}: points are {mesh.dim}D but the scene is {dim}D")
    return mesh


def initial_velocity(
    velocity: object, dim: int, n: int, where: str, numbering: SourceNumbering | None = None
) -> np.ndarray:
    """Initial velocities ``(n, d)`` in m/s from None (rest), one ``(d,)`` vector, one row per
    point, or (``numbering``) one row per point of the mesh file."""
    d = dim
    if velocity is None:
        return np.zeros((n, d))
    v = np.asarray(velocity, dtype=np.float64)
    if v.shape == (d,):
        v = np.broadcast_to(v, (n, d))
    elif numbering is not None and v.shape == (numbering.n_source, d):
        v = v[numbering.index]  # one row per point of the file
    if v.shape != (n, d):
        raise ValueError(f"{where}: velocity must have shape ({d},) or ({n}, {d}), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{where}: velocity holds NaN or inf")
    return np.ascontiguousarray(v, dtype=np.float64).copy()


def prescribed_mask(
    motion: Motion | None,
    nodes: np.ndarray | None,
    n: int,
    where: str,
    numbering: SourceNumbering | None = None,
) -> np.ndarray:
    """The ``(n,)`` bool mask of the nodes a prescribed ``motion`` drives: all of them, or
    ``nodes`` (a mask or indices, in the mesh file's numbering when given)."""
    if motion is None:
        if nodes is not None:
            raise ValueError(f"{where}: prescribed_nodes given without a prescribed motion")
        return np.zeros(n, dtype=bool)
    if not isinstance(motion, Motion):
        raise ValueError(
            f"{where}: prescribed must be a bfemp.motion Motion, got {type(motion).__name__}"
        )
    if nodes is None:
        return np.ones(n, dtype=bool)
    field = f"{where}: prescribed_nodes"
    mask = np.zeros(n, dtype=bool)
    mask[node_selection(nodes, n, field, numbering)] = True
    if not mask.any():
        raise ValueError(
            f"{field} selects no node (a mask with no True entry or no indices): "
            "select at least one node, or leave out prescribed for a free body"
        )
    return mask


def node_selection(
    nodes: object, n: int, field: str, numbering: SourceNumbering | None = None
) -> np.ndarray:
    """The node indices ``(k,)`` int64 that ``nodes`` selects of a mesh of ``n`` nodes: a bool
    mask ``(n,)``, or integer indices ``(k,)`` (order and repeats kept); with ``numbering``,
    masks and indices may be in the numbering of the mesh file. ``ValueError`` naming ``field``.
    """
    nodes = np.asarray(nodes)
    if nodes.dtype == bool:
        if numbering is not None and nodes.shape == (numbering.n_source,):
            nodes = numbering.mask(nodes, f"{field} mask")
        if nodes.shape != (n,):
            raise ValueError(f"{field} mask must have {n} entries, got {nodes.shape}")
        return np.flatnonzero(nodes)
    if nodes.size == 0:
        return np.zeros(0, dtype=np.int64)
    if nodes.ndim != 1 or not np.issubdtype(nodes.dtype, np.integer):
        raise ValueError(f"{field} must be a bool mask or integer indices")
    if numbering is not None:
        return numbering.nodes(nodes, f"{field} indices")
    bad = nodes[(nodes < 0) | (nodes >= n)]
    if bad.size:
        raise ValueError(f"{field} indices must lie in [0, {n}), got {bad[:10].tolist()}")
    return nodes.astype(np.int64)
