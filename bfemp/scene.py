"""The user-facing way to describe a coupled problem and build a ``Model``.

Every input is validated where it enters; errors name the body and the field, for example
``fem body 'floor': prescribed_nodes must have 120 entries, got 100``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import meshio
import numpy as np

from bfemp._scene_inputs import (
    as_mesh,
    check_fem_mesh,
    check_material,
    check_translation,
    initial_velocity,
    node_selection,
    prescribed_mask,
)
from bfemp.contact.pair_friction import body_code
from bfemp.contact.parameters import ContactParameters
from bfemp.materials import Material
from bfemp.model import BOUNDARY_KINDS, Boundary, FemBody, Model, MpmBody, simplex_shape_gradients
from bfemp.motion import Motion
from geometry._checks import points as _points
from geometry._checks import vector
from geometry.grid import Grid, particles_per_cell
from geometry.mesh import SourceNumbering, TetMesh, TriMesh

__all__ = ["Scene", "check_fem_mesh"]


@dataclass(frozen=True)
class _MpmSpec:
    name: str
    x: np.ndarray  # (p, d)
    volume: np.ndarray  # (p,)
    material: Material
    velocity: np.ndarray  # (p, d)


@dataclass(frozen=True)
class _FemSpec:
    name: str
    mesh: TriMesh | TetMesh
    material: Material
    velocity: np.ndarray  # (n, d)
    motion: Motion | None
    prescribed: np.ndarray  # (n,) bool
    numbering: SourceNumbering | None  # the mesh file's numbering (node indices of the user)


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
        self.gravity = np.zeros(dim) if gravity is None else vector("Scene.gravity", gravity, dim)
        self._fem: list[_FemSpec] = []
        self._loads: list[tuple[int, np.ndarray, np.ndarray]] = []
        self._mpm: list[_MpmSpec] = []
        self._grid: Grid | None = None
        self._boundaries: list[Boundary] = []
        self._contact: ContactParameters | None = None
        # (name a, name b) -> mu of that pair of bodies (set_friction)
        self._pair_mu: dict[tuple[str, str], float] = {}
        # (body name, field) -> how a scene file described it (mesh shape or file, node
        # selection, material name), so that bfemp.scenefile.save() writes it back the same way.
        self._sources: dict[tuple[str, str], object] = {}

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
    ) -> FemBody:
        """Add a FEM body (triangles in 2D, tetrahedra in 3D) and return its handle.

        Args:
            points: node positions ``(n, d)`` in m, or a ``TriMesh``/``TetMesh``/``meshio.Mesh``.
                A mesh whose cells are all clockwise (2D) / left-handed (3D) is flipped; see
                :func:`check_fem_mesh` for what is refused.
            cells: vertex indices ``(m, d + 1)`` when ``points`` is an array.
            material: ``NeoHookean``, ``LinearElastic`` or ``BulkShearHyperelastic``.
            velocity: initial velocity ``(d,)`` or ``(n, d)`` in m/s; default zero.
            prescribed: a ``bfemp.motion`` Motion scripting some or all nodes.
            prescribed_nodes: bool mask ``(n,)`` or index array of the scripted nodes (at least
                one); default all nodes when ``prescribed`` is given.
            name: body name used in messages and output files; default ``fem{index}``.

        Node numbering: a ``meshio.Mesh`` (or a mesh read from a file) may hold points that no
        cell uses; they are pruned and the nodes renumbered. Node indices are then taken in the
        numbering of the file, the one the user sees, and translated; indices of pruned points
        are refused. Masks and per-node velocities may have one entry per point of the file
        (translated) or per node of the pruned mesh (``mesh.points``, taken as they are).

        Returns:
            The body's handle (``body.x(sim.state)``: its node positions); it is also its index
            (``Model.fem_bodies[body]``) wherever an integer is expected.
        """
        index = len(self._fem)
        name = f"fem{index}" if name is None else str(name)
        if any(spec.name == name for spec in self._fem):
            raise ValueError(f"fem body '{name}': name is already used by another body")
        where = f"fem body '{name}'"
        mesh = as_mesh(points, cells, self.dim, where)
        numbering = mesh.source if mesh.source is not None and mesh.source.pruned else None
        n = mesh.points.shape[0]
        mask = prescribed_mask(prescribed, prescribed_nodes, n, where, numbering)
        mesh = check_fem_mesh(mesh, where, rigid=bool(mask.all()))
        check_material(material, where)
        vel = initial_velocity(velocity, self.dim, n, where, numbering)
        self._fem.append(_FemSpec(name, mesh, material, vel, prescribed, mask, numbering))
        return self._fem_body(index)

    def _fem_body(self, index: int) -> FemBody:
        """The handle of FEM body ``index``: its slices of the concatenated node and cell arrays
        and its boundary facets in the global node numbering."""
        spec = self._fem[index]
        nodes = sum(s.mesh.points.shape[0] for s in self._fem[:index])
        cells = sum(s.mesh.cells.shape[0] for s in self._fem[:index])
        boundary = spec.mesh.boundary_edges if self.dim == 2 else spec.mesh.boundary_faces
        return FemBody(
            name=spec.name,
            index=index,
            material=spec.material,
            nodes=slice(nodes, nodes + spec.mesh.points.shape[0]),
            cells=slice(cells, cells + spec.mesh.cells.shape[0]),
            prescribed_motion=spec.motion,
            boundary=np.ascontiguousarray(boundary + nodes, dtype=np.int64),
        )

    # ------------------------------------------------------------------ MPM bodies
    def add_mpm(
        self,
        particles: np.ndarray,
        volumes: np.ndarray,
        *,
        material: Material,
        velocity: tuple[float, ...] | np.ndarray | None = None,
        name: str | None = None,
    ) -> MpmBody:
        """Add an MPM body (particles on the shared background grid) and return its handle.

        Args:
            particles: positions ``(p, d)`` in m (e.g. from ``bfemp.sample``).
            volumes: particle volumes ``(p,)`` in m^d (per unit thickness in 2D).
            material: ``NeoHookean``, ``LinearElastic`` or ``BulkShearHyperelastic``.
            velocity: initial velocity ``(d,)`` or ``(p, d)`` in m/s; default zero.
            name: body name used in messages and output files; default ``mpm{index}``.
        """
        index = len(self._mpm)
        name = f"mpm{index}" if name is None else str(name)
        if any(spec.name == name for spec in (*self._mpm, *self._fem)):
            raise ValueError(f"mpm body '{name}': name is already used by another body")
        where = f"mpm body '{name}'"
        x = _points(f"{where}: particles", particles, self.dim, "p")
        if x.shape[0] == 0:
            raise ValueError(f"{where}: no particles (shape {x.shape})")
        vol = np.asarray(volumes, dtype=np.float64)
        if vol.shape != (x.shape[0],):
            raise ValueError(f"{where}: volumes must have shape ({x.shape[0]},), got {vol.shape}")
        bad = np.flatnonzero(~(np.isfinite(vol) & (vol > 0.0)))
        if bad.size:
            raise ValueError(
                f"{where}: volumes must be positive and finite; bad at rows {bad[:10].tolist()}"
            )
        check_material(material, where)
        vel = initial_velocity(velocity, self.dim, x.shape[0], where)
        self._mpm.append(_MpmSpec(name, np.ascontiguousarray(x), vol.copy(), material, vel))
        start = sum(spec.x.shape[0] for spec in self._mpm[:-1])
        return MpmBody(name, index, material, slice(start, start + x.shape[0]))

    def set_grid(self, dx: float, origin: tuple[float, ...] | None = None) -> None:
        """The MPM background grid: cell size ``dx`` in m, node ``origin (d,)`` (default 0)."""
        if not (isinstance(dx, int | float) and math.isfinite(dx) and dx > 0):
            raise ValueError(f"set_grid: dx must be a positive length in m, got {dx!r}")
        try:
            self._grid = Grid.make(float(dx), self.dim, origin)
        except ValueError as err:
            raise ValueError(f"set_grid: {err}") from None

    def set_contact(
        self,
        dhat: float,
        kappa: float | str = 1e7,
        mu: float = 0.0,
        eps_v: float = 1e-5,
        friction_iterations: int = 20,
    ) -> None:
        """Barrier contact between MPM particles and FEM boundaries (and between FEM bodies).

        Args:
            dhat: activation distance in m.
            kappa: barrier stiffness in Pa, or ``"auto"``.
            mu: friction coefficient (0 builds no friction term).
            eps_v: static friction velocity threshold in m/s.
            friction_iterations: cap of the lagged-friction loop.
        """
        self._contact = ContactParameters(
            dhat=dhat, kappa=kappa, mu=mu, eps_v=eps_v, friction_iterations=friction_iterations
        )

    def set_friction(self, body_a: str, body_b: str, mu: float) -> None:
        """The friction coefficient of one pair of bodies, instead of ``set_contact``'s ``mu``.

        ``barrier`` and ``two_stage`` take a contact's bodies from its point (a particle or a
        FEM boundary node) and the FEM boundary feature it is closest to; they have no MPM-MPM
        contact (one grid velocity), so an MPM-MPM pair only warns there. ``lr`` takes the two
        materials of each contact node (at nodes of three or more, the mass-weighted mean of
        the pairs). ``augury`` refuses a scene with pairs by name. Setting a pair again
        replaces its value.

        Args:
            body_a, body_b: names of two bodies already added, in either order.
            mu: Coulomb coefficient of that pair, finite and >= 0 (0: frictionless).

        Raises:
            ValueError: an unknown name, the same body twice, or a bad mu.
        """
        kinds = {spec.name: "fem" for spec in self._fem} | {spec.name: "mpm" for spec in self._mpm}
        for name in (body_a, body_b):
            if name not in kinds:
                known = ", ".join(repr(k) for k in kinds) or "none"
                raise ValueError(f"set_friction: no body named {name!r} (bodies: {known})")
        if body_a == body_b:
            raise ValueError(f"set_friction: body {body_a!r} given twice; name two bodies")
        if (
            isinstance(mu, bool)
            or not isinstance(mu, int | float)
            or not (math.isfinite(mu) and mu >= 0.0)
        ):
            raise ValueError(
                f"set_friction: mu of ({body_a!r}, {body_b!r}) must be a finite number >= 0, "
                f"got {mu!r}"
            )
        self._pair_mu.pop((body_b, body_a), None)
        self._pair_mu[(body_a, body_b)] = float(mu)

    def _contact_with_pairs(self) -> ContactParameters | None:
        """``set_contact``'s parameters with the ``set_friction`` pairs as body codes."""
        if not self._pair_mu:
            return self._contact
        if self._contact is None:
            pairs = ", ".join(f"({a!r}, {b!r})" for a, b in self._pair_mu)
            raise ValueError(
                f"set_friction {pairs} without contact: call scene.set_contact(dhat=...) too"
            )
        code = {spec.name: body_code("fem", k) for k, spec in enumerate(self._fem)}
        code |= {spec.name: body_code("mpm", k) for k, spec in enumerate(self._mpm)}
        pairs = tuple((code[a], code[b], mu) for (a, b), mu in self._pair_mu.items())
        return dataclasses.replace(self._contact, pair_mu=pairs)

    def add_boundary(
        self, levelset: object, kind: str = "slip", motion: Motion | None = None
    ) -> None:
        """A level-set boundary acting on the MPM grid nodes inside it (``value <= 0``).

        Bodies resting on it stop about one grid cell above it (the dx gap, ``bfemp.levelset``);
        a prescribed FEM body is a boundary without that gap.

        Args:
            levelset: e.g. ``bfemp.levelset.HalfPlane(point=..., normal=...)``.
            kind: ``"sticky"``, ``"slip"`` or ``"separate"``.
            motion: optional translation of the boundary (``bfemp.motion.Linear`` or a
                ``Sequence`` of them); static when None.
        """
        if kind not in BOUNDARY_KINDS:
            raise ValueError(f"add_boundary: kind must be one of {BOUNDARY_KINDS}, got {kind!r}")
        if not (
            callable(getattr(levelset, "value", None))
            and callable(getattr(levelset, "normal", None))
        ):
            raise ValueError("add_boundary: levelset must have value(x) and normal(x) methods")
        ls_dim = getattr(levelset, "dim", None)
        if ls_dim is not None and ls_dim != self.dim:
            raise ValueError(f"add_boundary: levelset is {ls_dim}D but the scene is {self.dim}D")
        if motion is not None:
            check_translation(motion)
        self._boundaries.append(Boundary(levelset=levelset, kind=kind, motion=motion))

    def add_load(
        self,
        body: str | int | FemBody,
        force: tuple[float, ...] | np.ndarray,
        nodes: np.ndarray | None = None,
    ) -> None:
        """Apply constant nodal forces to a FEM body (dead load).

        Args:
            body: the body's name (as ``set_friction`` and scene files take it), or the handle
                (or index) returned by ``add_fem``; loads act on FEM bodies only.
            force: force per selected node in N (N/m in 2D), ``(d,)`` or ``(k, d)``.
            nodes: bool mask ``(n,)`` or indices ``(k,)`` of the body's nodes (in the mesh
                file's numbering, as for ``add_fem``'s ``prescribed_nodes``); default all.
        """
        if isinstance(body, str):
            body = self._fem_by_name(body, "add_load")
        if isinstance(body, MpmBody):
            raise ValueError(
                f"add_load: loads act on FEM bodies only, and '{body.name}' is an MPM body; "
                "MPM bodies feel body forces through the scene's gravity"
            )
        if isinstance(body, FemBody):
            body = body.index
        if not (isinstance(body, int | np.integer) and 0 <= body < len(self._fem)):
            raise ValueError(f"add_load: body must be a body returned by add_fem, got {body!r}")
        spec = self._fem[body]
        where = f"fem body '{spec.name}'"
        n, d = spec.mesh.points.shape
        field = f"{where}: load nodes"
        idx = np.arange(n) if nodes is None else node_selection(nodes, n, field, spec.numbering)
        f = np.asarray(force, dtype=np.float64)
        if f.shape == (d,):
            f = np.broadcast_to(f, (idx.size, d))
        if f.shape != (idx.size, d) or not np.all(np.isfinite(f)):
            raise ValueError(
                f"{where}: load force must have shape ({d},) or ({idx.size}, {d}) and be finite, "
                f"got {f.shape}"
            )
        self._loads.append((body, idx, np.array(f)))

    def _fem_by_name(self, name: str, where: str) -> int | MpmBody:
        """The index of the FEM body called ``name`` (an MPM body's handle, for the caller's
        message); ``ValueError`` naming the bodies there are when no body has that name."""
        for index, spec in enumerate(self._fem):
            if spec.name == name:
                return index
        for index, spec in enumerate(self._mpm):
            if spec.name == name:
                return MpmBody(spec.name, index, spec.material, slice(0, 0))
        known = ", ".join(repr(spec.name) for spec in self._fem) or "none"
        raise ValueError(f"{where}: no FEM body named {name!r} (FEM bodies: {known})")

    def _record_source(self, name: str, field: str, value: object) -> None:
        """Remember how a scene file described ``field`` of body ``name`` (None: nothing)."""
        if value is not None:
            self._sources[(name, field)] = value

    # ------------------------------------------------------------------ build
    def build(self) -> Model:
        """Concatenate the bodies into a ``Model`` (masses lumped, shape gradients precomputed)."""
        d = self.dim
        if not self._fem and not self._mpm:
            raise ValueError("Scene has no bodies: add one with add_fem or add_mpm")
        if self._mpm and self._grid is None:
            raise ValueError("Scene has MPM bodies but no grid: call scene.set_grid(dx=...)")
        bodies = [self._fem_body(index) for index in range(len(self._fem))]
        points = [spec.mesh.points for spec in self._fem]
        cells = [spec.mesh.cells + b.nodes.start for spec, b in zip(self._fem, bodies, strict=True)]
        velocity = [spec.velocity for spec in self._fem]
        prescribed = [spec.prescribed for spec in self._fem]
        cell_body = [
            np.full(spec.mesh.cells.shape[0], b.index, dtype=np.int64)
            for spec, b in zip(self._fem, bodies, strict=True)
        ]
        fem_X = np.ascontiguousarray(np.concatenate([np.zeros((0, d)), *points]), dtype=np.float64)
        fem_cells = np.ascontiguousarray(
            np.concatenate([np.zeros((0, d + 1), dtype=np.int64), *cells]), dtype=np.int64
        )
        fem_cell_body = np.concatenate([np.zeros(0, dtype=np.int64), *cell_body])
        grad, volume = simplex_shape_gradients(fem_X, fem_cells)
        density = np.array([spec.material.density for spec in self._fem])[fem_cell_body]
        mass = np.zeros(fem_X.shape[0])
        # Lumped mass: each cell gives rho V / (d + 1) to each of its vertices.
        np.add.at(mass, fem_cells.ravel(), np.repeat(density * volume / (d + 1), d + 1))
        fem_prescribed = np.concatenate([np.zeros(0, dtype=bool), *prescribed])
        load = np.zeros_like(fem_X)
        for body, idx, f in self._loads:
            np.add.at(load, bodies[body].nodes.start + idx, f)
        model = Model(
            dim=d,
            gravity=self.gravity.copy(),
            fem_X=fem_X,
            fem_v0=np.concatenate([np.zeros((0, d)), *velocity]),
            fem_mass=mass,
            fem_cells=fem_cells,
            fem_cell_volume=volume,
            fem_cell_grad=grad,
            fem_cell_body=fem_cell_body,
            fem_prescribed=fem_prescribed,
            fem_bodies=tuple(bodies),
            fem_load=load,
            contact=self._contact_with_pairs(),
            **self._build_mpm(),
        )
        # Scripted nodes start with their scripted velocity.
        v0 = model.prescribed_velocities(0.0)
        model.fem_v0[fem_prescribed] = v0[fem_prescribed]
        if not math.isfinite(float(mass.sum())):
            raise ValueError("Scene: non-finite total mass")
        return model

    def _build_mpm(self) -> dict:
        """MPM fields of the Model (empty arrays without particles; no grid without particles)."""
        d = self.dim
        xs, vols, vels, masses, owner, bodies = [], [], [], [], [], []
        offset = 0
        for index, spec in enumerate(self._mpm):
            n = spec.x.shape[0]
            if self._grid is not None:
                ppc = particles_per_cell(self._grid, spec.x, spec.volume)
                if ppc < 1.0:
                    raise ValueError(
                        f"mpm body '{spec.name}': {ppc:.3g} particles per grid cell (< 1): the "
                        f"grid dx = {self._grid.dx:g} m is finer than the particle spacing; "
                        f"sample with a larger ppc or use a coarser grid"
                    )
            xs.append(spec.x)
            vols.append(spec.volume)
            vels.append(spec.velocity)
            masses.append(spec.material.density * spec.volume)
            owner.append(np.full(n, index, dtype=np.int64))
            bodies.append(MpmBody(spec.name, index, spec.material, slice(offset, offset + n)))
            offset += n

        def cat(parts: list[np.ndarray], shape: tuple[int, ...], dtype: type = np.float64):
            return np.ascontiguousarray(np.concatenate([np.zeros(shape, dtype=dtype), *parts]))

        return dict(
            mpm_X=cat(xs, (0, d)),
            mpm_v0=cat(vels, (0, d)),
            mpm_volume=cat(vols, (0,)),
            mpm_mass=cat(masses, (0,)),
            mpm_particle_body=cat(owner, (0,), np.int64),
            mpm_bodies=tuple(bodies),
            grid=self._grid if self._mpm else None,
            boundaries=tuple(self._boundaries) if self._mpm else (),
        )
