"""The user-facing way to describe a coupled problem and build a ``Model``.

Every input is validated where it enters; errors name the body and the field, for example
``fem body 'floor': prescribed_nodes must have 120 entries, got 100``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import meshio
import numpy as np

from bfemp.materials import LinearElastic, NeoHookean
from bfemp.model import FemBody, Model, simplex_shape_gradients
from bfemp.motion import Motion
from geometry.mesh import TetMesh, TriMesh, from_meshio, mesh_from_arrays

__all__ = ["Scene"]

Material = NeoHookean | LinearElastic


@dataclass(frozen=True)
class _FemSpec:
    name: str
    mesh: TriMesh | TetMesh
    material: Material
    velocity: np.ndarray  # (n, d)
    motion: Motion | None
    prescribed: np.ndarray  # (n,) bool


class Scene:
    """A coupled scene under construction.

    Args:
        dim: 2 (plane strain, per unit thickness) or 3.
        gravity: gravitational acceleration ``(d,)`` in m/s^2; default zero.
    """

    def __init__(self, dim: int, gravity: tuple[float, ...] | None = None) -> None:
        if dim not in (2, 3):
            raise ValueError(f"Scene.dim must be 2 or 3, got {dim!r}")
        self.dim = int(dim)
        g = np.zeros(dim) if gravity is None else np.asarray(gravity, dtype=np.float64)
        if g.shape != (dim,) or not np.all(np.isfinite(g)):
            raise ValueError(f"Scene.gravity must be {dim} finite numbers, got {gravity!r}")
        self.gravity = g
        self._fem: list[_FemSpec] = []
        self._loads: list[tuple[int, np.ndarray, np.ndarray]] = []

    # ------------------------------------------------------------------ FEM bodies
    def add_fem(
        self,
        points: np.ndarray | TriMesh | TetMesh | meshio.Mesh,
        cells: np.ndarray | None = None,
        *,
        material: Material,
        velocity: tuple[float, ...] | np.ndarray | None = None,
        prescribed: Motion | None = None,
        prescribed_nodes: np.ndarray | None = None,
        name: str | None = None,
    ) -> int:
        """Add a FEM body (triangles in 2D, tetrahedra in 3D) and return its index.

        Args:
            points: node positions ``(n, d)`` in m, or a ``TriMesh``/``TetMesh``/``meshio.Mesh``.
            cells: vertex indices ``(m, d + 1)`` when ``points`` is an array.
            material: ``NeoHookean`` or ``LinearElastic``.
            velocity: initial velocity ``(d,)`` or ``(n, d)`` in m/s; default zero.
            prescribed: a ``bfemp.motion`` Motion scripting some or all nodes.
            prescribed_nodes: bool mask ``(n,)`` or index array of the scripted nodes; default all
                nodes when ``prescribed`` is given.
            name: body name used in messages and output files; default ``fem{index}``.

        Returns:
            The body index; ``Model.fem_bodies[index]`` is its handle.
        """
        index = len(self._fem)
        name = f"fem{index}" if name is None else str(name)
        if any(spec.name == name for spec in self._fem):
            raise ValueError(f"fem body '{name}': name is already used by another body")
        where = f"fem body '{name}'"
        mesh = self._as_mesh(points, cells, where)
        mesh.check_quality(name=where)
        if not isinstance(material, NeoHookean | LinearElastic):
            raise ValueError(
                f"{where}: material must be bfemp.NeoHookean or bfemp.LinearElastic, "
                f"got {type(material).__name__}"
            )
        n = mesh.points.shape[0]
        vel = self._velocity(velocity, n, where)
        prescribed_mask = self._prescribed_mask(prescribed, prescribed_nodes, n, where)
        self._fem.append(_FemSpec(name, mesh, material, vel, prescribed, prescribed_mask))
        return index

    def add_load(
        self, body: int, force: tuple[float, ...] | np.ndarray, nodes: np.ndarray | None = None
    ) -> None:
        """Apply constant nodal forces to a FEM body (dead load).

        Args:
            body: index returned by ``add_fem``.
            force: force per selected node in N (N/m in 2D), ``(d,)`` or ``(k, d)``.
            nodes: bool mask ``(n,)`` or indices ``(k,)`` of the body's nodes; default all.
        """
        if not (isinstance(body, int | np.integer) and 0 <= body < len(self._fem)):
            raise ValueError(f"add_load: body must be an index returned by add_fem, got {body!r}")
        spec = self._fem[body]
        where = f"fem body '{spec.name}'"
        n, d = spec.mesh.points.shape
        if nodes is None:
            idx = np.arange(n)
        else:
            nodes = np.asarray(nodes)
            if nodes.dtype == bool:
                if nodes.shape != (n,):
                    raise ValueError(f"{where}: load nodes mask must have {n} entries")
                idx = np.flatnonzero(nodes)
            else:
                idx = nodes.astype(np.int64).ravel()
                if idx.size and (idx.min() < 0 or idx.max() >= n):
                    raise ValueError(f"{where}: load node indices must lie in [0, {n})")
        f = np.asarray(force, dtype=np.float64)
        if f.shape == (d,):
            f = np.broadcast_to(f, (idx.size, d))
        if f.shape != (idx.size, d) or not np.all(np.isfinite(f)):
            raise ValueError(
                f"{where}: load force must have shape ({d},) or ({idx.size}, {d}) and be finite, "
                f"got {f.shape}"
            )
        self._loads.append((body, idx, np.array(f)))

    def _as_mesh(self, points: object, cells: np.ndarray | None, where: str) -> TriMesh | TetMesh:
        if isinstance(points, TriMesh | TetMesh):
            mesh = points
        elif isinstance(points, meshio.Mesh):
            mesh = from_meshio(points)
        else:
            if cells is None:
                raise ValueError(f"{where}: cells are required when points is an array")
            try:
                mesh = mesh_from_arrays(np.asarray(points), np.asarray(cells))
            except ValueError as err:
                raise ValueError(f"{where}: {err}") from None
        if mesh.dim != self.dim:
            raise ValueError(f"{where}: points are {mesh.dim}D but the scene is {self.dim}D")
        return mesh

    def _velocity(self, velocity: object, n: int, where: str) -> np.ndarray:
        d = self.dim
        if velocity is None:
            return np.zeros((n, d))
        v = np.asarray(velocity, dtype=np.float64)
        if v.shape == (d,):
            v = np.broadcast_to(v, (n, d))
        if v.shape != (n, d):
            raise ValueError(
                f"{where}: velocity must have shape ({d},) or ({n}, {d}), got {v.shape}"
            )
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{where}: velocity holds NaN or inf")
        return np.ascontiguousarray(v, dtype=np.float64).copy()

    @staticmethod
    def _prescribed_mask(
        motion: Motion | None, nodes: np.ndarray | None, n: int, where: str
    ) -> np.ndarray:
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
        nodes = np.asarray(nodes)
        if nodes.dtype == bool:
            if nodes.shape != (n,):
                raise ValueError(
                    f"{where}: prescribed_nodes mask must have {n} entries, got {nodes.shape}"
                )
            return nodes.copy()
        if nodes.ndim != 1 or not np.issubdtype(nodes.dtype, np.integer):
            raise ValueError(f"{where}: prescribed_nodes must be a bool mask or integer indices")
        if nodes.size and (nodes.min() < 0 or nodes.max() >= n):
            raise ValueError(f"{where}: prescribed_nodes indices must lie in [0, {n})")
        mask = np.zeros(n, dtype=bool)
        mask[nodes] = True
        return mask

    # ------------------------------------------------------------------ build
    def build(self) -> Model:
        """Concatenate the bodies into a ``Model`` (masses lumped, shape gradients precomputed)."""
        d = self.dim
        if not self._fem:
            raise ValueError("Scene has no bodies: add one with add_fem")
        points, cells, velocity, prescribed, cell_body, bodies = [], [], [], [], [], []
        node_offset = cell_offset = 0
        for index, spec in enumerate(self._fem):
            n, m = spec.mesh.points.shape[0], spec.mesh.cells.shape[0]
            points.append(spec.mesh.points)
            cells.append(spec.mesh.cells + node_offset)
            velocity.append(spec.velocity)
            prescribed.append(spec.prescribed)
            cell_body.append(np.full(m, index, dtype=np.int64))
            boundary = spec.mesh.boundary_edges if d == 2 else spec.mesh.boundary_faces
            bodies.append(
                FemBody(
                    name=spec.name,
                    index=index,
                    material=spec.material,
                    nodes=slice(node_offset, node_offset + n),
                    cells=slice(cell_offset, cell_offset + m),
                    prescribed_motion=spec.motion,
                    boundary=np.ascontiguousarray(boundary + node_offset, dtype=np.int64),
                )
            )
            node_offset += n
            cell_offset += m
        fem_X = np.ascontiguousarray(np.concatenate(points), dtype=np.float64)
        fem_cells = np.ascontiguousarray(np.concatenate(cells), dtype=np.int64)
        fem_cell_body = np.concatenate(cell_body)
        grad, volume = simplex_shape_gradients(fem_X, fem_cells)
        density = np.array([spec.material.density for spec in self._fem])[fem_cell_body]
        mass = np.zeros(fem_X.shape[0])
        # Lumped mass: each cell gives rho V / (d + 1) to each of its vertices.
        np.add.at(mass, fem_cells.ravel(), np.repeat(density * volume / (d + 1), d + 1))
        fem_prescribed = np.concatenate(prescribed)
        load = np.zeros_like(fem_X)
        for body, idx, f in self._loads:
            np.add.at(load, bodies[body].nodes.start + idx, f)
        model = Model(
            dim=d,
            gravity=self.gravity.copy(),
            fem_X=fem_X,
            fem_v0=np.concatenate(velocity),
            fem_mass=mass,
            fem_cells=fem_cells,
            fem_cell_volume=volume,
            fem_cell_grad=grad,
            fem_cell_body=fem_cell_body,
            fem_prescribed=fem_prescribed,
            fem_bodies=tuple(bodies),
            fem_load=load,
        )
        # Scripted nodes start with their scripted velocity.
        v0 = model.prescribed_velocities(0.0)
        model.fem_v0[fem_prescribed] = v0[fem_prescribed]
        if not math.isfinite(float(mass.sum())):
            raise ValueError("Scene: non-finite total mass")
        return model
