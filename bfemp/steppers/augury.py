"""``"augury"``: APIC augury contact (AUG) on the explicit engine.

Foreground particles are the FEM boundary nodes (AUG) and, as bfemp's extension, the MPM
particles (section 1.4); they are transferred to their own Cartesian contact grid (spacing
``grid_dx``, origin 0) by the contact operator H (``bfemp.contact.augury.ContactOperator``: one
APIC or PIC P2G and one G2P at fixed positions). One step, after the engine's free flight
(``ExplicitStepper``: symplectic Euler, forces at x^n; MPM: the engine's USL step on the MPM
grid, which gives v_p^free and x_p^free):

1. a_p = (v_p^free - v_p^n) / dt (FEM: the mechanical acceleration of the node; MPM: the
   particle's); prediction (AUG eq. 27) v-bar = v^n + tau a (``predictor="symplectic"``) or
   v^n + (dt/2 + tau) a (``"paper"``, the velocity-Verlet reading of AUG eq. 32, pitfall A2);
   B-bar = B^n.
2. Stencils at x_p^n; V^_0 = H V-bar; N augury iterations remove the undesirable part
   (``bfemp.contact.augury.augury_correction``: AUG eq. 38 or AUG eqs. 40-46 with mu).
3. A^ = (V^_N - V-bar) / tau; v^{n+1} = v^free + dt a^, x^{n+1} = x^free + dt^2 a^,
   B^{n+1} = B^n + dt B-dot^ (so x^{n+1} = x^n + dt v^{n+1} for FEM nodes).

With tau = dt and N = 0 this gives v^{n+1} = H(v^n + dt a) on the foreground exactly (T9).

The augury pass is the engine's ``after_g2p`` phase: it corrects the free-flight end values
(after G2P, where the MPM foreground velocities exist) before the engine commits them, so a step
writes positions once. The FEM result is the same as a correction inside ``resolve`` (v and x
are linear in the correction), and the MPM particles get theirs after G2P as section 1.4
prescribes; F_p takes the correction's gradient (``contact_strain``, below).

Conservation: every H - I term has zero net linear momentum and, with APIC and B, zero net
angular momentum, so the correction conserves both for FEM-only scenes (angular momentum about
x^n: the B term of ``bfemp.diagnostics.angular_momentum`` is the one H_APIC keeps). PIC keeps
linear momentum only.

Scripted (prescribed) FEM boundary nodes are kinematic foreground by default
(``kinematic_foreground=True``): they enter H with their scripted velocity and infinite inertia
(``ContactOperator(kinematic=...)``: a contact node one of them touches takes their velocity
alone, so a fixed plate holds whatever its density) and their own correction is dropped. AUG has
no scripted bodies (its ramp's fixed face is 0.25 below the free top face in contact), so this
is a choice the paper leaves open; with their lumped mass instead (measured, issue 40) a fixed
plate only damps: the drop below sank at 0.08 m/s for as long as it ran. The cost in
conservation: the free bodies exchange momentum with the scripted nodes, which do not give it
back. Every step reports it, ``StepReport.extra["kinematic_impulse_x"|"_y"|"_z"]`` in N s (N s/m
in 2D): the impulse the scripted nodes deliver to the free foreground in the step (the free
particles' summed m dt a^; H conserves momentum among them), and a ``SCRIPTED_FOREGROUND`` note.
Measured on issue 40's drop (MPM disk r 0.1 m, 31.6 kg/m, E 1e5 Pa, thrown at (1, -1) m/s onto
a fixed FEM plate of edge 0.025 m, mu 0.3, MPM dx 0.02 m, dt "auto" = 6.1e-4 s, grid_dx 0.05 m,
0.3 s): the plate delivered (-30.8, 123.4) N s/m, up to 1.5 N s/m in one step, which is the
disk's momentum change less gravity's impulse to round-off; the lowest particle never went below
+0.050 m (1.0 grid_dx, 2.5 MPM cells above the plate top: augury stops a body about one contact
cell short of a scripted one, the nodes both stencils share) and the disk stopped sliding and
rolling (AUG's drag, ``bfemp.contact.augury``). 3D (a 0.2 m MPM cube at (1, 0, -1) m/s on a
plate of edge 0.05 m, MPM dx 0.04 m, grid_dx 0.114 m, 0.3 s): lowest particle +0.035 m (0.31
grid_dx). With ``False`` (the default before issue 40) scripted nodes are not in H and the body
falls through a fixed plate (the drop: lowest particle -0.69 m at 0.3 s; the cube -0.35 m at 0.2
s).

MPM particles' F (``contact_strain=True``, bfemp's): section 1.4 item 3 leaves F_p as the
engine's G2P made it from the free grid velocities, expecting contact to reach F through the
next P2G. It does not: the next P2G sees the corrected velocities, but the F increment of the
correction itself, dt grad(dt a^), is never applied, so under sustained contact the particles
crowd together while F stays near I (the drop's disk, resting on the plate, had lost 14 % of its
particle-cloud height at 0.3 s with mean det F 0.996). F_p^{n+1} += dt (sum_i dv_i grad w_ip^T)
F_p^n, dv_i the correction's mass-weighted field on the engine's MPM grid per body
(``_correction_gradient``): 5 % with it.

Named notes in every report where they apply: ``SCRIPTED_FOREGROUND``, ``AUGURY_REACH`` (tau
times the velocity spread at shared contact nodes above grid_dx / 3, AUG eq. 50),
``AUGURY_STEP_REACH`` (dt max |v| above grid_dx / 2) and ``INTERPENETRATION`` (foreground nodes
or particles strictly inside a cell of another FEM body at the end of the step; AUG admits the
method can let bodies through, pitfall A9). Cost: N + 1 H applications over the foreground set
(optionally only the particles sharing a contact node with another body, ``region="shared"``).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from bfemp.contact._augury_kernels import node_body_ranges, points_in_cells
from bfemp.contact.augury import (
    KERNELS,
    MODES,
    ContactOperator,
    ContactStencils,
    augury_correction,
    contact_stencils,
    facet_normals,
)
from bfemp.contact.parameters import refuse_pair_friction
from bfemp.errors import warn_user
from bfemp.model import Model
from bfemp.state import State
from bfemp.steppers.base import ContactView
from bfemp.steppers.capabilities import Capabilities
from bfemp.steppers.explicit import ExplicitOptions, ExplicitStepper, GridStep, Motion
from geometry.grid import particle_stencils

__all__ = ["AuguryOptions", "AuguryStepper"]

log = logging.getLogger(__name__)

#: the deepest penetration of a particle or FEM node into a FEM body stated for this strategy,
#: in grid cells (``Capabilities.penetration_bound_cells``), and how it was measured
AUGURY_PENETRATION_CELLS = 1.0
#: contact grid / MPM grid spacing above which the bound is not claimed (AUGURY_COARSE_GRID note)
COARSE_GRID_RATIO = 4.0
AUGURY_PENETRATION_NOTE = (
    "stated bound 1 MPM grid cell (AUG gives none and admits bodies can pass, pitfall A9); "
    "measured 0 in every case of the conformance catalogue (benchmarks/records/conformance*): "
    "with scripted nodes rigid in H a body stops about one contact cell short of a FEM body "
    "(2D drop: lowest particle 2.5 MPM cells above the plate); not claimed where the contact "
    "grid is over 4 MPM cells (AUGURY_COARSE_GRID note: 1.4 cells measured on the trade "
    "study's slope, contact grid 88 MPM cells)"
)

PREDICTORS = ("symplectic", "paper")
TRANSFERS = ("apic", "pic")
REGIONS = ("all", "shared")
NORMALS = ("own", "facing")


@dataclass(frozen=True, kw_only=True)
class AuguryOptions(ExplicitOptions):
    """Options of ``"augury"``.

    Attributes:
        tau: augury time scale tau in s; None: tau = dt (AUG's choice). tau < dt / 2 is refused
            (the correction v-bar + (dt/tau) G v-bar is unstable beyond).
        iterations: augury iterations N >= 0 (AUG: 1; N = 0 sticks). Measured (issue 14,
            ``bfemp.contact.augury``): N = 1 leaves a fixed fraction of the tangential drag
            every step, so a frictionless slide is held back whatever h; sliding needs
            ``normals="facing"`` and N of about 30 (2D ramp at t = 0.05 s, error 5.1 / 4.8 /
            3.8 % at h = 1 / 0.5 / 0.25 m; 3D ramp at 0.1 s: 9 / 15.5 % at h = 1 / 0.5),
            which then lets a block at mu = 0.7 creep (no setting tried does both).
        mode: ``"friction"`` (AUG eqs. 40-46, Coulomb with ``mu``; mu = 0 is frictionless) or
            ``"separate"`` (AUG eq. 38: only tensile corrections removed).
        mu: Coulomb coefficient; None takes ``scene.set_contact(mu=...)`` (0 without contact).
            Both given and different (a ``set_contact`` mu other than 0, its default) is
            refused: one scene, one friction coefficient.
        grid_dx: contact-grid spacing in m; None: 2 x the mean FEM boundary edge at rest, not
            below the MPM particle spacing (AUG: about twice the element edge).
        kernel: contact-grid kernel, ``"quadratic"`` (bfemp's B-spline, 3 nodes per axis),
            ``"aug_b2avg"`` (AUG App. B, 4 nodes) or ``"linear"`` (hats).
        predictor: ``"symplectic"`` (v-bar = v^n + tau a) or ``"paper"`` (v^n + (dt/2 + tau) a).
        contact_transfer: transfer of the contact operator H, ``"apic"`` or ``"pic"``.
        kinematic_foreground: scripted FEM nodes on the boundary enter H with their mass and
            scripted velocity (their correction is dropped: the momentum they deliver is
            reported per step in ``StepReport.extra["kinematic_impulse_*"]``, module docstring);
            default True since issue 40 (False: a fixed floor does not exist for augury).
        mpm_foreground: MPM particles are foreground particles (bfemp's extension).
        region: ``"all"`` (every foreground particle, AUG) or ``"shared"`` (only those whose
            stencil touches a contact node with mass from another body).
        penetration_check_every: check for interpenetration every this many steps (0: never).
        normals: FEM foreground normals, ``"own"`` (AUG section 2.3: the area-weighted normal
            of the node's facets) or ``"facing"`` (bfemp's option: of the node's facets, the one
            whose normal is most opposed to the other bodies' mean normal on the node's stencil;
            at corners and edges the averaged normal is tilted, so that the normal part of a
            sliding drag is kept as a push: measured, a block on a 30 degree ramp at mu = 0
            then barely slides).
        contact_strain: MPM particles' F takes the gradient of their contact correction (bfemp's;
            module docstring: without it a body resting on another crowds together while F
            stays near I).
        energy_guard: stop the augury iterations before an iterate with more generalised
            kinetic energy than the prediction V-bar (bfemp's; ``bfemp.contact.augury``: with
            friction and N > 1 the iterations were measured to inject energy, a block at
            mu = 0.7 then left a 30 degree incline; N = 1 was measured never to gain).
        cfl_safety_fem: safety factor on the FEM bound h_min / c_p, in (0, 1].
        cfl_safety_mpm: safety factor on the MPM bound ``dx / (c_p + |v_p|)``, in (0, 1].
    """

    strategy: ClassVar[str] = "augury"

    tau: float | None = field(default=None, metadata={"sweep": {"finer": -1, "factor": 2.0}})
    iterations: int = field(default=1, metadata={"sweep": {"finer": 1, "step": 1, "min": 0}})
    mode: str = "friction"
    mu: float | None = None
    grid_dx: float | None = None
    kernel: str = "quadratic"
    predictor: str = "symplectic"
    contact_transfer: str = "apic"
    kinematic_foreground: bool = True
    mpm_foreground: bool = True
    region: str = "all"
    penetration_check_every: int = 1
    normals: str = "own"
    energy_guard: bool = True
    contact_strain: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        name = type(self).__name__
        for field_name in ("tau", "mu", "grid_dx"):
            value = getattr(self, field_name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{name}.{field_name} must be a number or None, got {value!r}")
            low_ok = value >= 0.0 if field_name == "mu" else value > 0.0
            if not (math.isfinite(value) and low_ok):
                kind = ">= 0" if field_name == "mu" else "> 0"
                raise ValueError(f"{name}.{field_name} must be finite and {kind}, got {value!r}")
            object.__setattr__(self, field_name, float(value))
        for field_name in ("iterations", "penetration_check_every"):
            value = getattr(self, field_name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{name}.{field_name} must be an integer >= 0, got {value!r}")
        for field_name, allowed in (
            ("mode", MODES),
            ("kernel", tuple(KERNELS)),
            ("predictor", PREDICTORS),
            ("contact_transfer", TRANSFERS),
            ("region", REGIONS),
            ("normals", NORMALS),
        ):
            value = getattr(self, field_name)
            if value not in allowed:
                raise ValueError(f"{name}.{field_name} must be one of {allowed}, got {value!r}")
        for field_name in (
            "kinematic_foreground",
            "mpm_foreground",
            "energy_guard",
            "contact_strain",
        ):
            if not isinstance(getattr(self, field_name), bool):
                raise ValueError(f"{name}.{field_name} must be True or False")


class AuguryStepper(ExplicitStepper):
    """The ``"augury"`` strategy (module docstring)."""

    name: ClassVar[str] = "augury"
    Options: ClassVar[type[AuguryOptions]] = AuguryOptions
    explicit: ClassVar[bool] = True
    #: FEM boundary nodes and particles meet on the contact grid (AUG; particles: bfemp's
    #: extension, section 1.4); MPM bodies also share the engine's MPM grid velocity field
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs={"mpm-mpm": "grid", "mpm-fem": "contact", "mpm-prescribed": "contact",
               "fem-fem": "contact"},
        friction=True,
        needs_contact_settings=False,
        penetration_bound_cells=AUGURY_PENETRATION_CELLS,
        penetration_note=AUGURY_PENETRATION_NOTE,
    )  # fmt: skip

    def _setup(self) -> None:
        """The strategy's own construction, after the engine's (module docstring)."""
        model = self.model
        opts = self.options
        self.tau = self.dt if opts.tau is None else opts.tau
        if self.tau < 0.5 * self.dt:
            raise ValueError(
                f"augury: tau = {self.tau:.6g} s is below dt / 2 = {0.5 * self.dt:.6g} s "
                "(the augury correction is unstable there); take tau >= dt / 2 or tau=None"
            )
        refuse_pair_friction(model.contact, "augury")
        self.mu = _friction_coefficient(opts.mu, model.contact)
        self.apic = opts.contact_transfer == "apic"
        self._tau_predict = self.tau + (0.5 * self.dt if opts.predictor == "paper" else 0.0)
        self._setup_foreground()
        self._last_contact = None
        self._steps = 0
        #: steps whose foreground shared a contact node between bodies
        self.steps_with_contact = 0
        #: largest INTERPENETRATION depth seen so far, in m (distance of a point inside a cell
        #: of another body to that cell's nearest face; 0 while none was found)
        self.max_penetration_depth = 0.0

    # ------------------------------------------------------------------ construction
    def _setup_foreground(self) -> None:
        model, opts, d = self.model, self.options, self.model.dim
        n = model.n_fem_nodes
        facets, opposite, owners = [], [], []
        cell_keys, cell_opp = _cell_faces(model.fem_cells, n, d)
        for body in model.fem_bodies:
            f = np.asarray(body.boundary, dtype=np.int64).reshape(-1, d)
            if f.size == 0:
                continue
            key = _face_key(np.sort(f, axis=1), n)
            pos = np.searchsorted(cell_keys, key)
            pos = np.minimum(pos, cell_keys.size - 1)
            if not np.all(cell_keys[pos] == key):
                raise ValueError(
                    f"augury: fem body {body.name!r}: boundary facets not on any of its cells"
                )
            facets.append(f)
            opposite.append(cell_opp[pos])
            owners.append(np.full(f.shape[0], body.index))
        self._facets = np.concatenate(facets) if facets else np.zeros((0, d), np.int64)
        self._facet_opp = np.concatenate(opposite) if opposite else np.zeros(0, np.int64)
        on_boundary = np.zeros(n, dtype=bool)
        on_boundary[self._facets.reshape(-1)] = True
        on_boundary &= model.fem_mass > 0.0
        scripted = model.fem_prescribed.astype(bool)
        kin = on_boundary & scripted if opts.kinematic_foreground else np.zeros(n, bool)
        self._fem_fg = np.flatnonzero((on_boundary & ~scripted) | kin)
        self._fem_fg_movable = ~scripted[self._fem_fg]
        self._n_kinematic = int(kin.sum())
        fem_node_body = np.zeros(n, dtype=np.int64)
        for body in model.fem_bodies:
            fem_node_body[body.nodes] = body.index
        self._fem_node_body = fem_node_body
        self._mpm_fg = bool(opts.mpm_foreground and model.n_particles)
        n_fem_bodies = len(model.fem_bodies)
        self._mpm_body = (
            model.mpm_particle_body + n_fem_bodies if model.n_particles else np.zeros(0, np.int64)
        )
        # contact-grid spacing (section 1.5 item 4, A8)
        edges = _facet_edge_lengths(model.fem_X, self._facets)
        mean_edge = float(edges.mean()) if edges.size else 0.0
        spacing = 0.0
        if self._mpm_fg:
            spacing = float(np.mean(model.mpm_volume) ** (1.0 / d))
        if opts.grid_dx is not None:
            self.grid_dx = opts.grid_dx
        else:
            self.grid_dx = max(2.0 * mean_edge, spacing)
            if self.grid_dx <= 0.0:
                raise ValueError("augury: no FEM boundary and no MPM foreground to set grid_dx")
        if edges.size and edges.max() > 1.5 * self.grid_dx:
            warn_user(
                f"AUGURY_LONG_EDGES: FEM boundary edges up to {edges.max():.4g} m exceed 1.5 "
                f"grid_dx = {1.5 * self.grid_dx:.4g} m: particles of a body may pass each "
                "other's contact nodes (AUG: grid_dx about 2 x the edge)",
                logger=log,
            )
        self._cell_body = np.asarray(model.fem_cell_body, dtype=np.int64)
        #: the AUGURY_COARSE_GRID note of every step, or None (``_coarse_grid_note``)
        self._coarse_note = self._coarse_grid_note(model)

    def _coarse_grid_note(self, model: Model) -> str | None:
        """A note when particles meet FEM bodies on a contact grid much coarser than the MPM
        grid: the stated penetration bound (``AUGURY_PENETRATION_CELLS`` MPM cells) is not
        kept there. Measured (issue 40, the trade study's quick slope: FEM slope edge 0.22 m,
        grid_dx 0.44 m = 88 MPM cells of 5 mm): the box went 6.9 mm (1.4 MPM cells) into the
        slope; in the conformance catalogue (grid_dx 1-2.5 MPM cells) nothing went in."""
        if not (self._mpm_fg and model.fem_bodies and model.grid is not None):
            return None
        ratio = self.grid_dx / model.grid.dx
        if ratio <= COARSE_GRID_RATIO:
            return None
        return (
            f"AUGURY_COARSE_GRID: the contact grid ({self.grid_dx:.4g} m, 2 x the mean FEM "
            f"boundary edge) is {ratio:.3g} MPM cells: particles may go deeper into FEM bodies "
            f"than the stated bound of {AUGURY_PENETRATION_CELLS:g} MPM cell (refine the FEM "
            "boundary or set AuguryOptions.grid_dx)"
        )

    def initialize(self, state: State) -> State:
        """A copy of ``state`` with ``aug_B (N, d, d)`` and ``aug_Bp (P, d, d)`` (zeros when
        absent or of another size)."""
        out = state.copy()
        d = self.model.dim
        if out.aug_B.shape != (self.model.n_fem_nodes, d, d):
            out.aug_B = np.zeros((self.model.n_fem_nodes, d, d))
        if out.aug_Bp.shape != (self.model.n_particles, d, d):
            out.aug_Bp = np.zeros((self.model.n_particles, d, d))
        return out

    # ------------------------------------------------------------------ geometry per step
    def fem_normals(self, x: np.ndarray) -> np.ndarray:
        """Outward unit normals ``(N, d)`` of the FEM boundary nodes at positions ``x`` (area-
        weighted facet normals, AUG section 2.3; zero off the boundary)."""
        n_f = facet_normals(x, self._facets, self._facet_opp)
        n = x.shape[0]
        flat = self._facets.reshape(-1)  # d corners per facet
        normals = np.stack(
            [
                np.bincount(flat, np.repeat(n_f[:, a], self._facets.shape[1]), n)
                for a in range(x.shape[1])
            ],
            axis=1,
        )
        return _normalize(normals)

    def _facing_normals(
        self,
        x: np.ndarray,
        st: ContactStencils,
        m: np.ndarray,
        body: np.ndarray,
        normals: np.ndarray,
    ) -> np.ndarray:
        """``"facing"`` normals of the FEM foreground ``(n_fem, d)`` (option ``normals``).

        n-bar_other(p) = sum_i N_ip sum_{q not in body(p)} N_iq m_q n_q (a P2G of m n per body);
        where it is non-zero the node takes, of its facets' unit normals, the one with the
        smallest n_f . n-bar_other; elsewhere its own averaged normal.
        """
        n_fem = self._fem_fg.size
        weights = st.weights
        total = np.zeros((st.n_nodes, x.shape[1]))
        per_body = {}
        for b in np.unique(body):
            sel = body == b
            field = np.zeros_like(total)
            flat = st.nodes[sel].reshape(-1)
            contrib = (weights[sel] * m[sel, None])[:, :, None] * normals[sel][:, None, :]
            for a in range(x.shape[1]):
                field[:, a] = np.bincount(flat, contrib[..., a].reshape(-1), st.n_nodes)
            per_body[b] = field
            total += field
        other = np.zeros((n_fem, x.shape[1]))
        for b, field in per_body.items():
            sel = np.flatnonzero(body[:n_fem] == b)
            if sel.size:
                rest = total - field
                other[sel] = np.einsum("pk,pkd->pd", weights[sel], rest[st.nodes[sel]])
        n_f = _normalize(facet_normals(x, self._facets, self._facet_opp))
        fg_pos = np.full(self.model.n_fem_nodes, -1)
        fg_pos[self._fem_fg] = np.arange(n_fem)
        best = np.full(n_fem, np.inf)
        choice = normals[:n_fem].copy()
        for j in range(self._facets.shape[1]):
            p = fg_pos[self._facets[:, j]]
            ok = p >= 0
            score = np.einsum("kd,kd->k", n_f[ok], other[p[ok]])
            order = np.argsort(score)[::-1]  # the last write per node is its smallest score
            pk, sk, nk = p[ok][order], score[order], n_f[ok][order]
            better = sk < best[pk]
            # several facets per node: resolve with a stable minimum per node
            uniq, first = np.unique(pk[::-1], return_index=True)
            idx = len(pk) - 1 - first
            win = better[idx]
            best[uniq[win]] = sk[idx][win]
            choice[uniq[win]] = nk[idx][win]
        has_other = np.einsum("pd,pd->p", other, other) > 0.0
        return np.where(has_other[:, None], choice, normals[:n_fem])

    def _mpm_normals(
        self, stencils: ContactStencils, first: int, mass: np.ndarray, body: np.ndarray
    ) -> np.ndarray:
        """Outward unit normals ``(P, d)`` of the MPM foreground: n_p = normalize(sum_i N_ip
        g_i), g_i = sum_{q in body} m_q grad N_iq (bfemp's MPM foreground).

        grad N_iq is the gradient of node i's kernel at x_q (``contact_stencils``), which points
        from x_q toward node i, so g_i points away from the body's mass: outward. Section 1.4
        writes -sum N_ip g_i, the sign for the gradient taken at the node; with this
        convention it gave inward normals (issue 40: on a disk every rim particle had
        cos(n_p, radial) = -1), which turned compressive corrections into "tensile" ones that
        the augury iteration removes, and an MPM body sank through a fixed plate.
        """
        rows = np.arange(first, first + mass.size)
        nodes = stencils.nodes[rows]
        grads = stencils.grads[rows]
        w = stencils.weights[rows]
        out = np.zeros((mass.size, self.model.dim))
        for b in np.unique(body):
            sel = np.flatnonzero(body == b)
            g = np.zeros((stencils.n_nodes, self.model.dim))
            np.add.at(
                g,
                nodes[sel].reshape(-1),
                (mass[sel, None, None] * grads[sel]).reshape(-1, g.shape[1]),
            )
            out[sel] = np.einsum("pk,pkd->pd", w[sel], g[nodes[sel]])  # outward (docstring)
        return _normalize(out)

    def _correction_gradient(self, x: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """Gradient ``(P, d, d)`` in 1/s of the MPM velocity correction ``dv (P, d)`` (m/s) on the
        engine's MPM grid at x^n ``(P, d)``: per MPM body, the mass-weighted nodal field
        dv_i = sum_p w_ip m_p dv_p / sum_p w_ip m_p, then sum_i dv_i grad w_ip^T (the G2P
        velocity gradient the engine's F update uses)."""
        model = self.model
        st = particle_stencils(model.grid, x)
        d = model.dim
        m = model.mpm_mass
        out = np.zeros((x.shape[0], d, d))
        body = model.mpm_particle_body
        for b in np.unique(body):
            sel = np.flatnonzero(body == b)
            nodes = st.nodes[sel]
            wm = st.weights[sel] * m[sel, None]
            flat = nodes.reshape(-1)
            mass = np.bincount(flat, wm.reshape(-1), st.n_nodes)
            field = np.zeros((st.n_nodes, d))
            for a in range(d):
                field[:, a] = np.bincount(flat, (wm * dv[sel, a, None]).reshape(-1), st.n_nodes)
            np.divide(field, mass[:, None], out=field, where=mass[:, None] > 0.0)
            out[sel] = np.einsum("pka,pkc->pac", field[nodes], st.grads[sel])
        return out

    # ------------------------------------------------------------------ the step
    def after_g2p(self, step: GridStep, motion: Motion) -> None:
        """The augury correction of the engine's free-flight end values (module docstring)."""
        started = time.perf_counter()
        model, d, state = self.model, self.model.dim, step.state
        B_fem, B_mpm = state.aug_B, state.aug_Bp
        if B_fem.shape != (model.n_fem_nodes, d, d) or B_mpm.shape != (model.n_particles, d, d):
            start = self.initialize(state)
            B_fem, B_mpm = start.aug_B, start.aug_Bp
        motion.carried.update(aug_B=B_fem, aug_Bp=B_mpm)
        if self._coarse_note is not None:
            step.notes.append(self._coarse_note)
        fg = self._fem_fg
        n_fem = fg.size
        n_mpm = model.n_particles if self._mpm_fg else 0
        a_hat = np.zeros((n_fem + n_mpm, d))
        shared_count, h_applications, kinematic_impulse = 0, 0, None
        stats = {"iterations": 0}
        if n_fem + n_mpm:
            points = self._foreground(state, motion, B_fem, B_mpm, n_mpm)
            a_hat, B_new, shared_count, h_applications, kinematic_impulse = self._correction(
                step, points, stats
            )
            self._correct_motion(step, motion, a_hat, B_new, n_fem, n_mpm)
            if kinematic_impulse is not None:
                step.notes.append(
                    f"SCRIPTED_FOREGROUND: {self._n_kinematic} scripted nodes in H delivered an "
                    f"impulse of {np.linalg.norm(kinematic_impulse):.6g} N s to the free bodies "
                    "(their dropped correction: momentum not conserved)"
                )
        if self._n_kinematic:
            impulse = np.zeros(d) if kinematic_impulse is None else kinematic_impulse
            step.extra.update(
                {f"kinematic_impulse_{'xyz'[a]}": float(impulse[a]) for a in range(d)}
            )
        self._steps += 1
        self.steps_with_contact += shared_count > 0
        every = self.options.penetration_check_every
        if every and self._steps % every == 0:
            t0 = time.perf_counter()
            step.notes.extend(self._penetration_notes(motion))
            step.timings["augury_penetration"] = time.perf_counter() - t0
        self._store_contact(a_hat, shared_count, n_fem)
        step.timings["augury"] = time.perf_counter() - started
        step.message = "explicit step with augury contact"
        step.iterations.update(
            augury=self.options.iterations,
            augury_taken=stats["iterations"],
            h_applications=h_applications,
        )
        step.outcome["contact_pairs"] = shared_count

    def _foreground(
        self, state: State, motion: Motion, B_fem: np.ndarray, B_mpm: np.ndarray, n_mpm: int
    ) -> dict[str, np.ndarray]:
        """The foreground's start positions x ``(n, d)`` m, masses m ``(n,)`` kg, velocities
        v_n and v_free ``(n, d)`` m/s, matrices B ``(n, d, d)``, bodies ``(n,)`` and FEM normals,
        FEM boundary nodes first, then the particles."""
        model, fg = self.model, self._fem_fg
        keys = ("x", "m", "v_n", "v_free", "B", "body")
        parts: list[tuple[np.ndarray, ...]] = []
        fem_normals = None
        if fg.size:
            fem = (state.fem_x, model.fem_mass, state.fem_v, motion.fem_v, B_fem)
            parts.append((*(value[fg] for value in fem), self._fem_node_body[fg]))
            fem_normals = self.fem_normals(state.fem_x)[fg]
        if n_mpm:
            parts.append(
                (state.mpm_x, model.mpm_mass, state.mpm_v, motion.mpm_v, B_mpm, self._mpm_body)
            )
        points = {k: np.concatenate(v) for k, v in zip(keys, zip(*parts, strict=True), strict=True)}
        points["fem_normals"] = fem_normals
        points["fem_x"] = state.fem_x
        return points

    def _correction(
        self, step: GridStep, points: dict[str, np.ndarray], stats: dict[str, int]
    ) -> tuple[np.ndarray, np.ndarray, int, int, np.ndarray | None]:
        """The augury pass on the foreground ``points`` (module docstring, steps 1-2): the
        accelerations a^ ``(n, d)`` m/s^2, B^{n+1} ``(n, d, d)``, the number of particles sharing
        a contact node with another body, H applications, the kinematic impulse (or None)."""
        dt, tau, timings = self.dt, self.tau, step.timings
        x, m, body = points["x"], points["m"], points["body"]
        v_n, v_free, B_bar = points["v_n"], points["v_free"], points["B"]
        n_fem = self._fem_fg.size
        n_all = x.shape[0]
        movable = np.ones(n_all, dtype=bool)
        movable[:n_fem] = self._fem_fg_movable
        accel = (v_free - v_n) / dt
        v_bar = v_n + self._tau_predict * accel  # AUG eq. 27
        # kinematic nodes move with their scripted velocity
        v_bar[~movable] = v_free[~movable]
        t0 = time.perf_counter()
        st = contact_stencils(x, self.grid_dx, self.options.kernel)
        normals = np.zeros((n_all, x.shape[1]))
        if n_fem:
            normals[:n_fem] = points["fem_normals"]
            if self.options.normals == "facing":
                normals[:n_fem] = self._facing_normals(points["fem_x"], st, m, body, normals)
        if n_all > n_fem:
            normals[n_fem:] = self._mpm_normals(st, n_fem, m[n_fem:], body[n_fem:])
        node_shared, v_lo, v_hi = node_body_ranges(st.nodes, st.weights, body, v_bar, st.n_nodes)
        shared = (node_shared[st.nodes] & (st.weights > 0.0)).any(axis=1)
        timings["augury_stencils"] = time.perf_counter() - t0
        step.notes.extend(self._reach_notes(node_shared, v_lo, v_hi, v_bar))
        sel = np.arange(n_all) if self.options.region == "all" else np.flatnonzero(shared)
        if not self.apic:
            B_bar = np.zeros_like(B_bar)
        v_hat = v_bar.copy()
        B_hat = B_bar.copy()
        h_applications = 0
        if sel.size:
            t0 = time.perf_counter()
            sub = st if sel.size == n_all else _subset(st, sel)
            op = ContactOperator(sub, x[sel], m[sel], apic=self.apic, kinematic=~movable[sel])
            v_hat[sel], B_hat[sel] = augury_correction(
                op,
                v_bar[sel],
                B_bar[sel],
                normals[sel],
                self.options.iterations,
                self.options.mode,
                self.mu,
                movable[sel],
                energy_guard=self.options.energy_guard,
                stats=stats,
            )
            h_applications = op.applications
            timings["augury_H"] = time.perf_counter() - t0
        a_hat = (v_hat - v_bar) / tau
        Bdot = (B_hat - B_bar) / tau
        # impulse (N s; N s/m in 2D) the kinematic nodes deliver to the free foreground this
        # step: H conserves momentum among the free particles, so it is the free particles'
        # whole correction
        kinematic_impulse = dt * (m[movable] @ a_hat[movable]) if (~movable).any() else None
        a_hat[~movable] = 0.0
        Bdot[~movable] = 0.0
        return a_hat, B_bar + dt * Bdot, int(shared.sum()), h_applications, kinematic_impulse

    def _correct_motion(
        self,
        step: GridStep,
        motion: Motion,
        a_hat: np.ndarray,
        B_new: np.ndarray,
        n_fem: int,
        n_mpm: int,
    ) -> None:
        """v^{n+1} = v^free + dt a^, x^{n+1} = x^free + dt^2 a^, B^{n+1} (module docstring step
        3) on the end values, before the engine commits them."""
        dt, state = self.dt, step.state
        if n_fem:
            fg, mov = self._fem_fg, self._fem_fg_movable
            idx = fg[mov]
            motion.fem_v[idx] += dt * a_hat[:n_fem][mov]
            motion.fem_x[idx] += dt * dt * a_hat[:n_fem][mov]
            B_fem = motion.carried["aug_B"].copy()
            B_fem[fg] = B_new[:n_fem]
            motion.carried["aug_B"] = B_fem
        if n_mpm:
            motion.mpm_v = motion.mpm_v + dt * a_hat[n_fem:]
            motion.mpm_x = motion.mpm_x + dt * dt * a_hat[n_fem:]
            motion.carried["aug_Bp"] = B_new[n_fem:]
            if self.options.contact_strain:
                motion.mpm_F = motion.mpm_F + dt * np.einsum(
                    "pab,pbc->pac",
                    self._correction_gradient(state.mpm_x, dt * a_hat[n_fem:]),
                    state.mpm_F,
                )

    def _reach_notes(
        self, node_shared: np.ndarray, v_lo: np.ndarray, v_hi: np.ndarray, v_bar: np.ndarray
    ) -> list[str]:
        """AUGURY_REACH / AUGURY_STEP_REACH (section 1.5 item 2); v_rel is the spread of the
        predicted velocities at the contact nodes shared by two bodies (an upper bound)."""
        notes = []
        dx = self.grid_dx
        v_max = float(np.sqrt(np.einsum("pd,pd->p", v_bar, v_bar)).max()) if v_bar.size else 0.0
        if self.dt * v_max > 0.5 * dx:
            notes.append(
                f"AUGURY_STEP_REACH: dt max|v| = {self.dt * v_max:.4g} m exceeds grid_dx / 2 = "
                f"{0.5 * dx:.4g} m"
            )
        if node_shared.any():
            spread = v_hi[node_shared] - v_lo[node_shared]
            v_rel = float(np.sqrt((spread**2).sum(axis=1)).max())
            if self.tau * v_rel > dx / 3.0:
                notes.append(
                    f"AUGURY_REACH: tau |v_rel| = {self.tau * v_rel:.4g} m exceeds grid_dx / 3 = "
                    f"{dx / 3.0:.4g} m (AUG eq. 50: bodies may stop short or overshoot)"
                )
        return notes

    def _penetration_notes(self, new: Motion) -> list[str]:
        """INTERPENETRATION (pitfall A9): foreground points strictly inside another FEM body."""
        model = self.model
        if len(model.fem_bodies) + (len(model.mpm_bodies) if self._mpm_fg else 0) < 2:
            return []
        if not model.fem_cells.shape[0]:
            return []
        pts = [new.fem_x[self._fem_fg]]
        owner = [self._fem_node_body[self._fem_fg]]
        if self._mpm_fg:
            pts.append(new.mpm_x)
            owner.append(self._mpm_body)
        cells = new.fem_x[model.fem_cells]
        found, depth = points_in_cells(
            np.ascontiguousarray(np.concatenate(pts)),
            np.ascontiguousarray(np.concatenate(owner)),
            np.ascontiguousarray(cells),
            self._cell_body,
            1e-9,
        )
        inside = found >= 0
        if not inside.any():
            return []
        depth_m = float(_depth_in_cell(np.concatenate(pts)[inside], cells[found[inside]]).max())
        self.max_penetration_depth = max(self.max_penetration_depth, depth_m)
        return [
            f"INTERPENETRATION: {int(inside.sum())} foreground points strictly inside a cell of "
            f"another body (deepest barycentric depth {float(depth.max()):.3g}, "
            f"{depth_m:.3g} m from that cell's nearest face)"
        ]

    def _store_contact(self, a_hat: np.ndarray, shared_count: int, n_fem: int) -> None:
        model = self.model
        fem_f = np.zeros((model.n_fem_nodes, model.dim))
        part_f = np.zeros((model.n_particles, model.dim))
        if n_fem:
            fem_f[self._fem_fg] = model.fem_mass[self._fem_fg, None] * a_hat[:n_fem]
        if self._mpm_fg and model.n_particles:
            part_f[:] = model.mpm_mass[:, None] * a_hat[n_fem:]
        largest = float(np.sqrt(np.einsum("pd,pd->p", a_hat, a_hat)).max()) if a_hat.size else 0.0
        self._last_contact = ContactView(
            fem_f,
            part_f,
            pairs=shared_count,
            parameters={"augury_max_correction": largest},
        )

    def contact(self) -> ContactView:
        """Augury forces m a^ of the last step on the foreground (no distance, no energy)."""
        if self._last_contact is None:
            m = self.model
            self._last_contact = ContactView.empty(
                m.n_fem_nodes, m.n_particles, m.dim, parameters={"augury_max_correction": 0.0}
            )
        return self._last_contact


# ---------------------------------------------------------------------- helpers
def _friction_coefficient(option: float | None, contact: object) -> float:
    """The Coulomb coefficient augury uses: ``AuguryOptions.mu``, else the scene's
    ``set_contact(mu=...)`` (0 without contact settings).

    Raises:
        ValueError: both are given and differ (a contact mu of 0, ``set_contact``'s default, is
            taken as not given, so ``AuguryOptions(mu=...)`` alone sets friction).
    """
    scene_mu = float(getattr(contact, "mu", 0.0) or 0.0)
    if option is None:
        return scene_mu
    if scene_mu != 0.0 and float(option) != scene_mu:
        raise ValueError(
            f"augury: AuguryOptions.mu = {option:g} and scene.set_contact(mu={scene_mu:g}) give "
            "two friction coefficients; give mu in one place (AuguryOptions.mu=None takes the "
            "scene's)"
        )
    return float(option)


def _normalize(v: np.ndarray) -> np.ndarray:
    norm = np.sqrt(np.einsum("pd,pd->p", v, v))
    out = np.zeros_like(v)
    np.divide(v, norm[:, None], out=out, where=norm[:, None] > 0.0)
    return out


def _depth_in_cell(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Distance in m of each point ``(Q, d)`` inside its simplex ``(Q, d + 1, d)`` to the
    simplex's nearest face: min_j lambda_j / |grad lambda_j| (barycentric lambda)."""
    inv = np.linalg.inv(np.swapaxes(cells[:, 1:] - cells[:, :1], 1, 2))  # rows: grad lambda_1..d
    lam = np.einsum("qab,qb->qa", inv, points - cells[:, 0])
    grads = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)  # (Q, d + 1, d)
    lam = np.concatenate([1.0 - lam.sum(axis=1, keepdims=True), lam], axis=1)
    return (lam / np.linalg.norm(grads, axis=2)).min(axis=1)


def _face_key(faces_sorted: np.ndarray, n: int) -> np.ndarray:
    """One int64 per sorted facet (n^d < 2^63: n < 2e6 nodes in 3D)."""
    key = np.zeros(faces_sorted.shape[0], dtype=np.int64)
    for j in range(faces_sorted.shape[1]):
        key = key * np.int64(n) + faces_sorted[:, j]
    return key


def _cell_faces(cells: np.ndarray, n: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Sorted keys of every cell face and the vertex opposite each (``(M (d+1),)`` each)."""
    cells = np.asarray(cells, dtype=np.int64)
    keys, opp = [], []
    for j in range(d + 1):
        face = np.delete(cells, j, axis=1)
        keys.append(_face_key(np.sort(face, axis=1), n))
        opp.append(cells[:, j])
    keys = np.concatenate(keys) if keys else np.zeros(0, np.int64)
    opp = np.concatenate(opp) if opp else np.zeros(0, np.int64)
    order = np.argsort(keys, kind="stable")
    return keys[order], opp[order]


def _facet_edge_lengths(x: np.ndarray, facets: np.ndarray) -> np.ndarray:
    if facets.size == 0:
        return np.zeros(0)
    p = x[facets]
    k = facets.shape[1]
    lengths = [
        np.linalg.norm(p[:, (j + 1) % k] - p[:, j], axis=1) for j in range(k if k > 2 else 1)
    ]
    return np.concatenate(lengths)


def _subset(st: ContactStencils, sel: np.ndarray) -> ContactStencils:
    """The stencils of the particles ``sel`` (node indices unchanged)."""
    return replace(
        st,
        nodes=np.ascontiguousarray(st.nodes[sel]),
        weights=np.ascontiguousarray(st.weights[sel]),
        grads=st.grads[sel],
        D=st.D[sel],
    )
