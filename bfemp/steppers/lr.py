"""``"lr"``: multimaterial MPM with logistic-regression contact and multimaterial XPIC(m).

Paper: Nairn et al., logistic-regression multimaterial MPM contact ("LR"). Every MPM body is one
material with its own velocity field on the shared grid (``bfemp.mpm.transfer``'s
multimaterial kernels). One USL step, the explicit engine's step (``bfemp.steppers.explicit``)
with M fields and these phases: P2G (step 1), ``after_p2g`` (2-3), ``resolve`` (4), the
engine's constraints (5), ``g2p`` (6):

1. Stencils at X_p^n; P2G per material (LR eq. 5): m^a, p^a0, f^a0 (LR eq. 29, gravity included).
   Level-set boundaries act on every field (``bfemp.mpm.boundaries``).
2. Contact nodes: nodes where two or more materials have mass, however little (LR section 3.1:
   nodes that "see" two or more materials; NairnMPM activates a material's field wherever one
   of its particles contributes). ``mass_fraction`` > 0 (Uintah's 1e-8) leaves out a material
   whose mass there is below that fraction of the node's total: an option, not LR's rule.
   At a node with two materials one pair (a, b), a the lower
   index; at a node with three or more, one pair per material a against the lumped others
   (LR eq. 50). Each pair's point cloud is every particle whose stencil weight at the node is
   positive; one logistic-regression fit per pair and step gives the normal n (from a to b)
   and the separation d_LR with the deformed particle radius (LR eqs. 19-25,
   ``bfemp.contact.lr.lr_planes``).
3. First correction (LR eqs. 7-10), with ``corrections=2`` (the paper's; the default is 1, "LR
   once", chosen by measurement: ``LROptions.corrections``): the contact law
   (``bfemp.contact.lr.contact_momentum``: contact iff approaching and touching) on p^a0
   gives dp^a; v^a = (p^a0 + dp^a) / m^a; dv^a = dp^a / m^a is kept for XPIC.
4. Provisional momenta p^a0+ = p^a + f^a0 dt (LR eq. 30); second correction with the same planes
   (LR eq. 31) gives p^a+, v^a+ = p^a+ / m^a, then the boundaries.
5. a^a = (v^a+ - v^a) / dt: the force f^{C,1} of LR eq. 34 (Uintah's form, boundaries included).
   ``contact_force="c0"`` (FLIP only) gives the particles and FEM boundary nodes f^{C,0} of
   LR eq. 33 instead: the first correction's dv^a as well.
6. Particles: FLIP (LR eq. 32) V^{n+1} = V^n + dt S a, X^{n+1} = X^n + dt S (v + dt a / 2);
   XPIC(m) (LR eqs. 35, 37; ``bfemp.mpm.xpic``) V^{n+1} = S v* + dt S a,
   X^{n+1} = X^n + dt (S v + (V^{n+1} - V^n) / 2); USL F^{n+1} = (I + dt S grad v+) F^n.

Two-material corrections conserve momentum (a gets dp, b gets -dp). Lumping at nodes with three
or more materials does not (the paper says so): its momentum change per step is reported in
``StepReport.extra["lump_momentum_drift"]`` (kg m/s); ``lump="conservative"`` (bfemp's) gives
-dp to the others in proportion to their masses. ``interface="perfect"`` takes dp = dp(0) at every
contact node: the multimaterial step then equals the single-material one (LR eq. 34, L1).

Penetration (measured for issue 40, defaults, an MPM disk, box or cube dropped at (1, -1) m/s
onto a fixed FEM plate, mu 0 and 0.3, dx 0.02 and 0.05 m, 2D and 3D, to 0.3 s): no particle
centre went below the plate's top (the lowest stayed 0.19-0.23 cells above, about one particle
radius: d_LR counts the deformed radius, LR eq. 25); a particle's undeformed extent (centre minus
half its spacing) went at most 0.057 cells (1.14 mm at dx = 0.02 m, mu 0, 3D) below the top,
about one step's travel at the impact speed (1.4 m/s x 0.6 ms). Against deformable FEM bodies
contact is met through their boundary nodes only and nothing is guaranteed.

Transfers: ``"flip"`` (the default) and ``"pic"`` (= XPIC(1)); ``xpic_order`` m >= 1 selects
XPIC(m). APIC is refused: LR's corrections and XPIC are written for FLIP-type updates.
FEM bodies take part as one material each (bfemp's design;
LR has no FEM): their boundary nodes are the material's points in P2G (mass m_n, velocity v_n^n,
force m_n a_n^mech; the internal force stays on the mesh), and the point cloud holds the boundary
nodes plus facet samples at spacing <= dx / 2, all of radius 0 (they lie on the surface). The
boundary nodes then move like FLIP particles, v_n^{n+1} = v_n^n + dt a_n^mech + sum_i w_in
dp_i^{F+} / m_i^F, which conserves momentum since m_i^F = sum_n w_in m_n; interior nodes take the
mechanical update. Scripted nodes enter with their mass and velocity, and with the force that
takes them to their script at t^{n+1}; they keep their script. Where a FEM material's grid mass
at a node comes from scripted nodes alone, that field is rigid in the contact law (infinite mass,
NairnMPM's rigid materials; LR has none): the other material takes its velocity along the normal
(``_kinematic_fields`` says why: with its finite grid mass a fixed plate let bodies through).
The momentum such a field takes is the support's reaction, not applied and not conserved among
the bodies; it is reported per step as ``StepReport.extra["scripted_impulse"]`` (|sum|, kg m/s)
and in the contact view's FEM forces. A grid finer than twice the FEM boundary edge is warned
about (the FEM material's grid mass then has holes between its nodes).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from bfemp.errors import warn_user
from bfemp.model import Model
from bfemp.mpm.boundaries import material_constraints
from bfemp.mpm.transfer import (
    g2p_field,
    g2p_update,
    p2g_field,
    p2g_materials,
    p2g_nodal,
)
from bfemp.mpm.xpic import XPIC_VARIANTS, xpic_grid_velocity
from bfemp.state import State
from bfemp.steppers.base import ContactView
from bfemp.steppers.capabilities import Capabilities
from bfemp.steppers.explicit import ExplicitOptions, ExplicitStepper, GridStep, Motion
from geometry.grid import ParticleStencils, particle_stencils

__all__ = ["LROptions", "LRStepper"]

log = logging.getLogger(__name__)

#: the deepest penetration of a particle or FEM node into a FEM body stated for this strategy,
#: in grid cells (``Capabilities.penetration_bound_cells``), and how it was measured
LR_PENETRATION_CELLS = 1.0
LR_PENETRATION_NOTE = (
    "stated bound 1 MPM grid cell (LR gives none: contact acts at grid nodes); measured 0 in "
    "every case of the conformance catalogue that lr runs (benchmarks/records/conformance*), "
    "and on issue 40's drop (disk, box, cube at 1.4 m/s on a fixed plate, dx 0.02 and 0.05 m) "
    "no particle centre went below the plate top, a particle's extent at most 0.057 cells; "
    "FEM-FEM pairs are not coupled (a free FEM block sank 2.2 cells into a fixed plate)"
)

#: per material, the level-set constraints of its field (None: no boundaries)

LAWS = ("coulomb", "frictionless")
INTERFACES = ("contact", "perfect")
DETECTORS = ("lr", "velocity", "cp")
LUMPS = ("lumped", "conservative")
TRANSFERS = ("flip", "pic")
CONTACT_FORCES = ("c1", "c0")
#: contact steps per window, and the first/second correction impulse ratio above which the
#: ``LR_FIRST_CORRECTION`` note is given (``LRStepper._watch_first_correction``)
FIRST_CORRECTION_WINDOW = 100
FIRST_CORRECTION_RATIO = 1.0


@dataclass(frozen=True, kw_only=True)
class LROptions(ExplicitOptions):
    """Options of ``"lr"``.

    Attributes:
        mu: Coulomb coefficient; None takes ``scene.set_contact(mu=...)`` (0 without contact).
        law: ``"coulomb"`` (stick or slip at mu; mu = 0 is frictionless) or ``"frictionless"``.
        interface: ``"contact"`` (the contact law) or ``"perfect"`` (dp = dp(0) at every
            contact node: the bodies stick as one, the single-material limit of LR eq. 34).
        detector: ``"lr"`` (LR normal and separation, LR eqs. 19-25), ``"velocity"`` (mass-gradient
            normals, contact when approaching alone) or ``"cp"`` (mass-gradient normals and the
            constant-offset separation of LR eq. 16, ``cp_offset`` cells), the paper's comparison.
        cp_offset: the constant offset of the ``"cp"`` detector in cells (LR: 0.8, calibrated
            for GIMP, pitfall L-P3).
        corrections: 1 ("LR once", LR Fig. 5: one correction, after the momentum update; the
            default) or 2 (the paper's: after P2G and after the momentum update). Set 2 for
            ``interface="perfect"`` (only then is the run exactly the single-material one, eq.
            34) and for the paper's multimaterial XPIC(m) (LR eq. 37's dv term is the first
            correction's; with 1 it is zero). Why 1 by default (measured for issue 40 under
            FLIP, mass_fraction 0, fixed FEM bodies rigid; "c1" is 2 with f^{C,1})::

                ============================  ========  ========  ========  ========
                scene                         once      c1        c0        PIC
                ============================  ========  ========  ========  ========
                landing: disk on a deformable 2D plate (bottom row fixed, E 1 MPa),
                lowest particle, cells        +0.025    -4.76     +0.048    +0.003
                landing: slope box, accel.
                error (lr_variants quick)     0.021     0.021     0.021     0.021
                impact: quick rings, error    0.69      4.16      0.71      1.70
                (particles inside FEM ring)   (0)       (214)     (0)       (7)
                compression at 0.05 % c_K
                (paper's rate) to 15 %        0.107 %   0.112 %   0.765 %   0.471 %
                ============================  ========  ========  ========  ========

            Under c1 neither the particles nor the FEM nodes ever receive the first correction
            (f^{C,1}, LR eq. 33), so in a lasting contact the pair keeps approaching at its
            centre-of-mass velocity: the disk sank through the deformable plate and ring
            particles ended inside the FEM ring. Once is as good as c1 where c1 is at its best
            (compression, the paper's Fig. 5 setting; LR reports its errors larger, which this
            grid does not reproduce) and the best or tied elsewhere; c0 loses the compression
            and PIC damps (the disk on a fixed plate stops rolling). XPIC(5) (with 2) sank
            1.1 cells into the deformable plate and left 91 particles inside the ring.
        contact_force: ``"c1"`` (the paper's f^{C,1}, LR eq. 33: only the second correction reaches
            the particles; exact for perfect interfaces, LR eq. 34) or ``"c0"`` (f^{C,0}: both
            corrections do; FLIP only). With one correction the two are the same. The
            ``LR_FIRST_CORRECTION`` note flags a run with two corrections and c1 under FLIP
            whose first correction keeps removing more than the second.
        lump: ``"lumped"`` (LR eq. 50: each material against the lumped others, dp to it alone;
            not momentum-conserving) or ``"conservative"`` (bfemp's: -dp spread over the
            others by mass) at nodes with three or more materials.
        xpic_order: None (the transfer alone) or the XPIC order m >= 1 (m = 1 is PIC).
        xpic_variant: ``"paper"`` (LR eq. 37), ``"uncorrected"`` or ``"corrected_velocity"``.
        mass_fraction: a material takes part at a node when its mass there exceeds this
            fraction of the node's total mass. 0 (the default) is LR's contact node (section
            3.1: a node that sees two or more materials) and NairnMPM's (a material's field
            is active wherever one of its particles has weight). A positive value is Uintah's
            choice (1e-8), kept as an option; it is not LR's. Why 0 (measured, issue 40, on
            ``lr_compression`` at the paper's loading rate 0.05 % c_K to 3.5 % strain,
            largest stress error against the single material): with 1e-8 a particle about
            1.5 cells from a node keeps its material's field there uncorrected and nearly
            massless, and the error steps near 2.8 % strain: LR-XPIC(5) 3.44 %, LR-FLIP
            1.06 %; with every material counted 0.046 % and 0.007 %. ``interface="perfect"`` always
            counts every material with mass (with the threshold the column drifted 8e-4 from
            the single-material run).
        penalty: LR penalty on the normal components, times dx^2 (LR: 1e-7).
        lr_tol: LR stop criterion 1 - n_new . n_old (LR: 1e-5).
        lr_max_iterations: cap of the Gauss-Newton iterations (LR: 15).
        thin_cloud: in cells; the LR normal loses its components along directions in which the
            node's whole point cloud is thinner than this (standard deviation), 0 disables
            (bfemp's, ``bfemp.contact.lr.lr_planes``: measured on ``lr_compression``, the nodes
            beside the column saw one particle column per block and took sideways normals; the
            column edges then interpenetrated and the stress error reached 1.1 % at 10 %).
        cfl_safety_fem, cfl_safety_mpm: as in ``ExplicitOptions``.
    """

    strategy: ClassVar[str] = "lr"

    mu: float | None = None
    law: str = "coulomb"
    interface: str = "contact"
    detector: str = "lr"
    cp_offset: float = 0.8
    corrections: int = field(
        default=1, metadata={"sweep": {"finer": 1, "step": 1, "min": 1, "max": 2}}
    )
    lump: str = "lumped"
    contact_force: str = "c1"
    xpic_order: int | None = field(
        default=None, metadata={"sweep": {"finer": 1, "step": 4, "min": 1, "first": 1}}
    )
    xpic_variant: str = "paper"
    mass_fraction: float = 0.0
    penalty: float = 1e-7
    lr_tol: float = 1e-5
    lr_max_iterations: int = 15
    thin_cloud: float = 0.05

    def __post_init__(self) -> None:
        super().__post_init__()
        name = type(self).__name__
        for field_name, allowed in (
            ("law", LAWS),
            ("interface", INTERFACES),
            ("detector", DETECTORS),
            ("lump", LUMPS),
            ("xpic_variant", XPIC_VARIANTS),
        ):
            value = getattr(self, field_name)
            if value not in allowed:
                raise ValueError(f"{name}.{field_name} must be one of {allowed}, got {value!r}")
        if self.contact_force not in CONTACT_FORCES:
            raise ValueError(
                f"{name}.contact_force must be one of {CONTACT_FORCES}, got {self.contact_force!r}"
            )
        if self.corrections not in (1, 2) or isinstance(self.corrections, bool):
            raise ValueError(f"{name}.corrections must be 1 or 2, got {self.corrections!r}")
        order = self.xpic_order
        if order is not None and (isinstance(order, bool) or not isinstance(order, int)):
            raise ValueError(f"{name}.xpic_order must be None or an integer >= 1, got {order!r}")
        if order is not None and order < 1:
            raise ValueError(f"{name}.xpic_order must be None or an integer >= 1, got {order!r}")
        it = self.lr_max_iterations
        if isinstance(it, bool) or not isinstance(it, int) or it < 1:
            raise ValueError(f"{name}.lr_max_iterations must be an integer >= 1, got {it!r}")
        for field_name, allow_none, low_open in (
            ("mu", True, False),
            ("cp_offset", False, False),
            ("mass_fraction", False, False),
            ("penalty", False, False),
            ("lr_tol", False, True),
            ("thin_cloud", False, False),
        ):
            value = getattr(self, field_name)
            if value is None and allow_none:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{name}.{field_name} must be a number, got {value!r}")
            ok = value > 0.0 if low_open else value >= 0.0
            if not (math.isfinite(value) and ok):
                kind = "> 0" if low_open else ">= 0"
                raise ValueError(f"{name}.{field_name} must be finite and {kind}, got {value!r}")
            object.__setattr__(self, field_name, float(value))
        if self.mass_fraction >= 0.5:
            raise ValueError(f"{name}.mass_fraction must be below 0.5, got {self.mass_fraction}")


@dataclass
class _Points:
    """Every point of a step: the P particles, then the FEM boundary nodes, then the facet
    samples. ``stencils`` on the shared active nodes, positions ``x (Q, d)`` m, ``F (Q, d, d)``,
    undeformed radii ``radius0 (Q, d)`` m (0 on FEM points), ``material (Q,)``, ``mass (Q,)`` kg
    (0 on samples)."""

    stencils: ParticleStencils
    x: np.ndarray
    F: np.ndarray
    radius0: np.ndarray
    material: np.ndarray
    mass: np.ndarray


@dataclass
class _Pairs:
    """Contact pairs of one step: ``node (K,)`` grid node, ``a (K,)`` material, ``b (K,)`` the
    partner material or -1 (the lumped others), ``ptr (K + 1,)``/``idx``/``side`` the CSR point
    clouds (particle indices; side -1 for a, +1 for the others), ``normal (K, d)`` from a to b,
    ``separation (K,)`` in m (NaN when the detector measures none)."""

    node: np.ndarray
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    separation: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    fallback: np.ndarray


class LRStepper(ExplicitStepper):
    """The ``"lr"`` strategy (module docstring)."""

    name: ClassVar[str] = "lr"
    Options: ClassVar[type[LROptions]] = LROptions
    explicit: ClassVar[bool] = True
    #: one velocity field per body (LR sec. 2); FEM bodies take part through their surface
    #: nodes (bfemp's design, module docstring), against MPM bodies only: in the conformance
    #: catalogue's stack a free FEM block on a fixed FEM plate sank 2.2 cells into it
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs={"mpm-mpm": "contact", "mpm-fem": "contact", "mpm-prescribed": "contact"},
        friction=True,
        needs_contact_settings=False,
        penetration_bound_cells=LR_PENETRATION_CELLS,
        penetration_note=LR_PENETRATION_NOTE,
        needs_mpm_body=True,
    )  # fmt: skip
    #: the transfer ``Simulation`` takes when none is given
    default_transfer: ClassVar[str] = "flip"
    transfers: ClassVar[tuple[str, ...]] = TRANSFERS

    #: why the other transfers are refused
    transfer_note: ClassVar[str] = (
        " (XPIC(m) by LROptions.xpic_order); APIC is not part of LR's multimaterial method"
    )

    def _setup(self) -> None:
        """The strategy's own construction, after the engine's (module docstring)."""
        model, opts, transfer = self.model, self.options, self.transfer
        if model.n_particles == 0:
            raise ValueError("lr: the scene has no MPM body (LR couples MPM materials)")
        if opts.mu is not None:
            self.mu = opts.mu
        else:
            self.mu = float(getattr(model.contact, "mu", 0.0) or 0.0)
        self.material = np.ascontiguousarray(model.mpm_particle_body, dtype=np.int64)
        self.n_materials = len(model.mpm_bodies) + len(model.fem_bodies)
        self.mu_table = self._friction_table(model)
        d = model.dim
        # undeformed particle semi-axes R0 (P, d): half the side of the particle's cube
        self.radius0 = np.repeat((0.5 * model.mpm_volume ** (1.0 / d))[:, None], d, axis=1)
        self._setup_fem_points()
        self.xpic_order = (
            opts.xpic_order if opts.xpic_order is not None else (1 if transfer == "pic" else None)
        )
        self.contact_force = self._resolve_contact_force(opts)
        if self.mu > 0.0 and opts.law == "frictionless":
            log.info("lr: law='frictionless' ignores mu = %g", self.mu)
        #: steps with at least one node in contact, and the LR fits that hit the cap
        self.steps_with_contact = 0
        self.unconverged_fits = 0
        self._warned_unconverged = False
        #: sum |dp| of the first and of the second correction over the current window of
        #: ``FIRST_CORRECTION_WINDOW`` steps with contact (``_watch_first_correction``)
        self._window = [0, 0.0, 0.0]
        self._warned_first_correction = False
        #: over the run's steps with contact: sum ``|dp^a|`` of the first and of the second
        #: correction (kg m/s), and the windows given the ``LR_FIRST_CORRECTION`` note
        self.first_correction_impulse = 0.0
        self.second_correction_impulse = 0.0
        self.first_correction_windows = 0

    def _resolve_contact_force(self, opts: LROptions) -> str:
        """``LROptions.contact_force``, refused where it does not apply (c0 under XPIC)."""
        if opts.contact_force == "c0" and self.xpic_order is not None:
            raise ValueError(
                "lr: contact_force='c0' is a FLIP rule; XPIC(m) (xpic_order or transfer='pic') "
                "takes the first correction through v* (LR eq. 37): use contact_force='c1'"
            )
        return opts.contact_force

    # ------------------------------------------------------------------ FEM as a material
    def _friction_table(self, model: Model) -> np.ndarray | None:
        """mu per pair of materials ``(M, M)`` from ``scene.set_friction``, or None (one mu).

        Materials are the MPM bodies, then the FEM bodies (``n_mpm + index``); pairs the scene
        does not name keep ``self.mu`` (``LROptions.mu`` or ``scene.set_contact(mu=...)``).
        """
        pairs = getattr(model.contact, "pair_mu", ())
        if not pairs:
            return None
        n_mpm = len(model.mpm_bodies)
        table = np.full((self.n_materials, self.n_materials), self.mu)
        for code_a, code_b, mu in pairs:
            a, b = (n_mpm + c if c >= 0 else -1 - c for c in (code_a, code_b))
            table[a, b] = table[b, a] = mu
        return table

    def _pair_mu(self, a: np.ndarray, b: np.ndarray, mass: np.ndarray) -> float | np.ndarray:
        """mu of each contact ``(C,)`` of material ``a`` against ``b`` (-1: the lumped others,
        then the mass-weighted mean of a's coefficients with them); ``mass (M, C)`` in kg."""
        if self.mu_table is None:
            return self.mu
        lumped = b < 0
        mu = self.mu_table[a, np.maximum(b, 0)]
        if lumped.any():
            la, m = a[lumped], mass[:, lumped].copy()
            m[la, np.arange(la.size)] = 0.0
            mu[lumped] = (self.mu_table[la].T * m).sum(axis=0) / m.sum(axis=0)
        return mu

    def _setup_fem_points(self) -> None:
        """Boundary nodes and facet samples of the FEM bodies (section 2.6 of the spec)."""
        model, d = self.model, self.model.dim
        n_mpm = len(model.mpm_bodies)
        nodes, node_mat, facets, facet_mat = [], [], [], []
        for body in model.fem_bodies:
            f = np.asarray(body.boundary, dtype=np.int64).reshape(-1, d)
            if f.size == 0:
                continue
            facets.append(f)
            facet_mat.append(np.full(f.shape[0], n_mpm + body.index, dtype=np.int64))
            b = np.unique(f)
            nodes.append(b)
            node_mat.append(np.full(b.size, n_mpm + body.index, dtype=np.int64))
        cat = np.concatenate
        self._fem_points = cat(nodes) if nodes else np.zeros(0, np.int64)
        self._fem_point_material = cat(node_mat) if node_mat else np.zeros(0, np.int64)
        self._fem_point_free = ~model.fem_prescribed[self._fem_points].astype(bool)
        facets_all = cat(facets) if facets else np.zeros((0, d), np.int64)
        facet_material = cat(facet_mat) if facet_mat else np.zeros(0, np.int64)
        dx = model.grid.dx
        if facets_all.shape[0]:
            ends = model.fem_X[facets_all]  # (F, d, d)
            edge = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
            if d == 3:
                edge = np.maximum(edge, np.linalg.norm(ends[:, 2] - ends[:, 1], axis=1))
                edge = np.maximum(edge, np.linalg.norm(ends[:, 0] - ends[:, 2], axis=1))
            if dx < 2.0 * edge.max() * (1.0 - 1e-9):
                warn_user(
                    f"LR_GRID_FINE: the MPM grid (dx = {dx:.4g} m) is finer than twice the FEM "
                    f"boundary edge (up to {edge.max():.4g} m): the FEM material's grid mass "
                    "has gaps between its nodes (spec section 2.6 asks for dx >= 2 x the edge)",
                    logger=log,
                )
            # facet samples at spacing <= dx / 2 (barycentric, the vertices left out)
            per_edge = np.maximum(1, np.ceil(edge / (0.5 * dx)).astype(np.int64))
            self._samples = _facet_samples(facets_all, facet_material, per_edge, d)
        else:
            self._samples = (np.zeros((0, d), np.int64), np.zeros((0, d)), np.zeros(0, np.int64))
        self._n_fem_points = self._fem_points.size
        self._n_samples = self._samples[0].shape[0]

    def _points(self, state: State) -> _Points:
        """Every point of the step (``_Points``), with stencils at their positions."""
        model, d = self.model, self.model.dim
        if self._n_fem_points == 0:
            st = particle_stencils(model.grid, state.mpm_x)
            return _Points(st, state.mpm_x, state.mpm_F, self.radius0, self.material,
                           model.mpm_mass)  # fmt: skip
        s_nodes, s_bary, s_mat = self._samples
        sample_x = np.einsum("sk,skd->sd", s_bary, state.fem_x[s_nodes])
        n_extra = self._n_fem_points + self._n_samples
        x = np.concatenate([state.mpm_x, state.fem_x[self._fem_points], sample_x])
        eye = np.broadcast_to(np.eye(d), (n_extra, d, d))
        F = np.concatenate([state.mpm_F, eye])
        R0 = np.concatenate([self.radius0, np.zeros((n_extra, d))])
        mat = np.concatenate([self.material, self._fem_point_material, s_mat])
        mass = np.concatenate(
            [model.mpm_mass, model.fem_mass[self._fem_points], np.zeros(self._n_samples)]
        )
        st = particle_stencils(model.grid, x)
        return _Points(st, x, F, R0, mat, mass)

    def _scripted_force(self, state: State, fem_force: np.ndarray) -> np.ndarray:
        """The forces ``(B, d)`` in N the FEM boundary nodes bring to P2G: the mechanical force
        on free nodes; on scripted nodes m_n (v_n^script(t^{n+1}) - v_n^n) / dt, so that their
        field reaches the script's velocity at t^{n+1} (their mechanical force, gravity
        included, never moves them: a fixed plate's field would otherwise fall at g)."""
        b = self._fem_points
        force = fem_force[b]
        scripted = ~self._fem_point_free
        if not scripted.any():
            return force
        nodes = b[scripted]
        v_next = self.model.prescribed_velocities(state.t + self.dt)[nodes]
        force = force.copy()
        force[scripted] = self.model.fem_mass[nodes, None] * (v_next - state.fem_v[nodes]) / self.dt
        return force

    def _kinematic_fields(self, st: ParticleStencils, mass: np.ndarray) -> np.ndarray | None:
        """``(M, G)`` bool: the fields whose whole grid mass at the node comes from scripted FEM
        nodes (None when no FEM node is scripted).

        Why (issue 40, measured on the drop of ``tests/bfemp/test_lr_drop.py``: a disk at 1.4 m/s on
        a fixed FEM plate): the plate's field holds only its boundary nodes' masses, so at the
        contact nodes the disk had 0.5-0.8 of the pair's mass. The centre-of-mass law (eqs.
        7-10) then took only m_b / (m_a + m_b) of the disk's approach velocity each step and
        gave the rest to a plate whose script undoes it: the momentum left, the disk kept
        moving down, and its lowest particle reached -0.53 m (the plate is 0.1 m thick).
        A scripted field is therefore infinitely heavy in the contact law (NairnMPM's rigid
        materials; LR has none), which stops the approach at once (``_correct``). A field
        mixing free and scripted nodes is left finite (its free nodes take the kick)."""
        if not self._n_fem_points or self._fem_point_free.all():
            return None
        n_p = self.model.n_particles
        scripted = ~self._fem_point_free
        rows = np.arange(n_p, n_p + self._n_fem_points)[scripted]
        nodes = st.nodes[rows]
        w = st.weights[rows] * self.model.fem_mass[self._fem_points[scripted], None]
        mat = np.broadcast_to(self._fem_point_material[scripted, None], nodes.shape)
        held = np.zeros_like(mass)
        np.add.at(held, (mat, nodes), w)
        return (mass > 0.0) & (held >= (1.0 - 1e-9) * mass)

    # ------------------------------------------------------------------ contact detection
    def _pairs(self, pts: _Points, grid_x: np.ndarray, mass: np.ndarray) -> _Pairs:
        """The contact pairs of this step with their planes (step 2 of the docstring)."""
        opts, d = self.options, self.model.dim
        total = mass.sum(axis=0)
        # a perfect interface joins every material with mass (so that it is exactly one body)
        fraction = 0.0 if opts.interface == "perfect" else opts.mass_fraction
        present = (mass > fraction * total[None, :]) & (mass > 0.0)
        count = present.sum(axis=0)
        two = np.flatnonzero(count == 2)
        many = np.flatnonzero(count >= 3)
        M = self.n_materials
        first = np.argmax(present[:, two], axis=0)
        last = M - 1 - np.argmax(present[::-1, two], axis=0)
        many_a, many_node = np.nonzero(present[:, many])
        node = np.concatenate([two, many[many_node]]).astype(np.int64)
        a = np.concatenate([first, many_a]).astype(np.int64)
        b = np.concatenate([last, np.full(many_a.size, -1)]).astype(np.int64)
        k = node.size
        planes = _Pairs(
            node=node,
            a=a,
            b=b,
            normal=np.zeros((k, d)),
            separation=np.full(k, np.nan),
            iterations=np.zeros(k, dtype=np.int64),
            converged=np.ones(k, dtype=bool),
            fallback=np.zeros(k, dtype=bool),
        )
        if k == 0 or opts.interface == "perfect":
            return planes
        from bfemp.contact import lr as lr_contact  # the LR kernels (numba)

        if opts.detector == "lr":
            st = pts.stencils
            ptr, idx, side = lr_contact.contact_point_clouds(
                st.nodes, st.weights, pts.material, node, a, b, grid_x.shape[0]
            )
            fit = lr_contact.lr_planes(
                grid_x[node],
                ptr,
                idx,
                side,
                pts.x,
                pts.F,
                pts.radius0,
                self.model.grid.dx,
                penalty=opts.penalty,
                tol=opts.lr_tol,
                max_iterations=opts.lr_max_iterations,
                thin=opts.thin_cloud,
            )
            planes.normal = fit.normal
            planes.separation = fit.separation
            planes.iterations = fit.iterations
            planes.converged = fit.converged
            planes.fallback = fit.fallback
            return planes
        # the grid detectors compare two materials: a lumped pair takes the heaviest other
        partner = b.copy()
        lumped = np.flatnonzero(b < 0)
        if lumped.size:
            others = mass[:, node[lumped]].copy()
            others[a[lumped], np.arange(lumped.size)] = -1.0
            partner[lumped] = np.argmax(others, axis=0)
        st = pts.stencils
        grads = lr_contact.mass_gradient_normals(
            st.nodes, st.grads, pts.mass, pts.material, grid_x.shape[0], M
        )
        planes.normal = lr_contact.ag_normals(grads, node, a, partner)
        if opts.detector == "cp":
            moments = lr_contact.material_mass_moments(
                st.nodes, st.weights, pts.mass, pts.x, pts.material, grid_x.shape[0], M
            )
            planes.separation = lr_contact.cp_separation(
                grid_x[node], node, a, partner, mass, moments, planes.normal,
                opts.cp_offset, self.model.grid.dx,
            )  # fmt: skip
        return planes

    # ------------------------------------------------------------------ the contact law
    def _correct(
        self, planes: _Pairs, mass: np.ndarray, mom: np.ndarray, kinematic: np.ndarray | None
    ) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
        """The contact law on momenta ``mom (M, G, d)``: the momentum changes ``(M, G, d)``
        applied, the number of pairs in contact, the net momentum change (lumping's drift)
        ``(d,)`` and the momentum ``(M, G, d)`` the scripted fields take and do not apply.

        ``kinematic (M, G)`` bool (``_kinematic_fields``; None: none) marks the scripted
        fields. A pair against one takes it as infinitely heavy (``contact_momentum``'s
        ``rigid_a``/``rigid_b``, NairnMPM's rigid-material contact); the scripted field's
        reaction -dp is returned in the last array, never applied (its velocity is the
        script). A lumped pair (LR eq. 50) whose others include a scripted field meets that field
        alone (the heaviest there, as NairnMPM picks one rigid material per node); a scripted
        a of a lumped pair is not corrected.
        """
        from bfemp.contact import lr as lr_contact  # the LR kernels (numba)

        opts = self.options
        delta = np.zeros_like(mom)
        absorbed = np.zeros_like(mom)
        node, a, b = planes.node, planes.a, planes.b
        if node.size == 0:
            return delta, 0, np.zeros(mom.shape[2]), absorbed
        m_a, p_a = mass[a, node], mom[a, node]
        lumped = b < 0
        partner = b.copy()  # the material that takes -dp; -1: the lumped others
        m_b = np.where(lumped, mass[:, node].sum(axis=0) - m_a, mass[np.maximum(b, 0), node])
        p_b = np.where(lumped[:, None], mom[:, node].sum(axis=0) - p_a, mom[np.maximum(b, 0), node])
        rigid_a = rigid_b = None
        if kinematic is not None:
            rigid_a = kinematic[a, node]
            rigid_b = kinematic[np.maximum(b, 0), node] & ~lumped
            rows = np.flatnonzero(lumped & ~rigid_a)
            if rows.size:  # lumped others holding a scripted field: that field alone
                kin_mass = np.where(kinematic[:, node[rows]], mass[:, node[rows]], 0.0)
                kin_mass[a[rows], np.arange(rows.size)] = 0.0
                heavy = np.argmax(kin_mass, axis=0)
                hit = kin_mass[heavy, np.arange(rows.size)] > 0.0
                rows, heavy = rows[hit], heavy[hit]
                m_b[rows], p_b[rows] = mass[heavy, node[rows]], mom[heavy, node[rows]]
                partner[rows] = heavy
                rigid_b[rows] = True
        if opts.interface == "perfect":
            dp, touching = lr_contact.contact_momentum(
                m_a, m_b, p_a, p_b, np.zeros_like(p_a), None, mu=0.0, law="perfect",
                detector="velocity", rigid_a=rigid_a, rigid_b=rigid_b,
            )  # fmt: skip
        else:
            most = self.mu if self.mu_table is None else float(self.mu_table.max())
            law = "frictionless" if opts.law == "frictionless" or most == 0.0 else "coulomb"
            sep = planes.separation
            if opts.detector == "velocity":  # no separation measured; the law ignores it
                sep = np.zeros_like(sep)
            dp, touching = lr_contact.contact_momentum(
                m_a, m_b, p_a, p_b, planes.normal, sep,
                mu=self._pair_mu(a, b, mass[:, node]), law=law, detector=opts.detector,
                rigid_a=rigid_a, rigid_b=rigid_b,
            )  # fmt: skip
        if rigid_a is not None:
            stays = lumped & rigid_a  # a scripted a keeps its script (LR eq. 50 corrects a alone)
            dp[stays] = 0.0
            touching = touching & ~stays
        lumped = partner < 0
        np.add.at(delta, (a, node), dp)
        pair = ~lumped
        np.add.at(delta, (partner[pair], node[pair]), -dp[pair])
        if opts.lump == "conservative" and lumped.any():
            ln, la, ldp = node[lumped], a[lumped], dp[lumped]
            share = mass[:, ln] / m_b[lumped][None, :]  # (M, L)
            share[la, np.arange(ln.size)] = 0.0
            mats = np.repeat(np.arange(self.n_materials), ln.size)
            nodes_rep = np.tile(ln, self.n_materials)
            spread = (share[..., None] * ldp[None]).reshape(-1, ldp.shape[1])
            np.add.at(delta, (mats, nodes_rep), -spread)
        drift = delta.sum(axis=(0, 1))
        if kinematic is not None:  # the scripted fields' reactions: reported, not applied
            absorbed = np.where(kinematic[..., None], delta, 0.0)
            delta = np.where(kinematic[..., None], 0.0, delta)
        return delta, int(touching.sum()), drift, absorbed

    # ------------------------------------------------------------------ the step's phases
    def particles_to_grid(self, state: State) -> GridStep:
        """Phase P2G (docstring step 1): per material (LR eq. 5) m^a, p^a0, f^a0 with gravity,
        FEM boundary nodes as points; the constraints decided and applied on v^a0."""
        model, dt = self.model, self.dt
        t0 = time.perf_counter()
        piola = self.mpm_stresses(state)
        pts = self._points(state)
        st = pts.stencils
        n_p = model.n_particles
        nodes, weights, grads = st.nodes[:n_p], st.weights[:n_p], st.grads[:n_p]
        grid_x = st.active_x
        mass, mom0, force = p2g_materials(
            nodes, weights, grads, self.material, model.mpm_mass, state.mpm_v,
            piola, state.mpm_F, model.mpm_volume, self.n_materials, grid_x.shape[0],
        )  # fmt: skip
        force += mass[..., None] * model.gravity
        fem_force = np.zeros((0, model.dim))
        if self._n_fem_points:
            fem_force = self.fem_forces(state)  # internal + gravity + loads, on the mesh
            rows = slice(n_p, n_p + self._n_fem_points)
            b = self._fem_points
            p2g_nodal(
                st.nodes[rows], st.weights[rows], self._fem_point_material,
                model.fem_mass[b], state.fem_v[b], self._scripted_force(state, fem_force),
                mass, mom0, force,
            )  # fmt: skip
        inv_mass = np.zeros_like(mass)
        np.divide(1.0, mass, out=inv_mass, where=mass > 0.0)
        v0 = mom0 * inv_mass[..., None]
        t_next = state.t + dt
        cons = material_constraints(model.boundaries, grid_x, v0, t_next, dt)
        v0 = cons.apply(v0, dt)
        work = {"pts": pts, "inv_mass": inv_mass, "kinematic": self._kinematic_fields(st, mass)}
        return GridStep(
            state=state, t_next=t_next, dt=dt, grid_x=grid_x, mass=mass, velocity=v0,
            force=force, fem_force=fem_force, constraints=cons, message="explicit step (lr)",
            timings={"fem_forces": 0.0, "p2g": time.perf_counter() - t0}, work=work,
            _grid=model.grid,
        )  # fmt: skip

    def after_p2g(self, step: GridStep) -> None:
        """The pairs and their planes (docstring step 2), the first correction (step 3)."""
        work, mass = step.work, step.mass
        t0 = time.perf_counter()
        work["planes"] = planes = self._pairs(work["pts"], step.grid_x, mass)
        step.timings["lr_fits"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        mom0 = step.velocity * mass[..., None]
        work["absorbed"] = np.zeros_like(mom0)  # momentum the scripted fields take (not applied)
        dp1 = np.zeros_like(mom0)
        if self.options.corrections == 2:
            dp1, _, _, absorbed1 = self._correct(planes, mass, mom0, work["kinematic"])
            if self.contact_force == "c0":
                work["absorbed"] += absorbed1
        work["dp1"], work["mom"] = dp1, mom0 + dp1
        step.timings["corrections"] = time.perf_counter() - t0

    def resolve(
        self, step: GridStep, grid_v: np.ndarray, fem_v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The second correction (docstring step 4): p^a0+ = p^a + dt f^a0 (LR eq. 30), v^a+ =
        (p^a0+ + dp^a) / m^a (LR eq. 31); the FEM velocities with the boundary nodes' kick.

        LR's update is in momenta, so the engine's v* = v + dt f / m (equal in exact arithmetic,
        rounded otherwise) is not used; nor its FEM v* (the kick is added to LR's own)."""
        work, dt = step.work, self.dt
        t0 = time.perf_counter()
        inv_mass = work["inv_mass"]
        mom_plus0 = work["mom"] + dt * step.force
        dp2, touching, drift, absorbed2 = self._correct(
            work["planes"], step.mass, mom_plus0, work["kinematic"]
        )
        work["absorbed"] += absorbed2
        # the contact momentum particles and FEM nodes receive (LR eq. 33): f^{C,1} dt or f^{C,0} dt
        work["dp_kick"] = dp2 + work["dp1"] if self.contact_force == "c0" else dp2
        work.update(dp2=dp2, touching=touching, drift=drift)
        step.timings["corrections"] += time.perf_counter() - t0
        if self.model.n_fem_nodes:
            fem_v = self._fem_velocities(step, work["dp_kick"], inv_mass)
        return (mom_plus0 + dp2) * inv_mass[..., None], fem_v

    def g2p(self, step: GridStep, grid_v: np.ndarray) -> tuple[np.ndarray, ...]:
        """Particles (docstring step 6): FLIP (LR eq. 32) or XPIC(m) (LR eqs. 35, 37) from the end
        velocities v^a+ ``(M, G, d)``, USL F; no APIC matrices."""
        model, dt, work, state = self.model, self.dt, step.work, step.state
        n_p = model.n_particles
        st = work["pts"].stencils
        nodes, weights, grads = st.nodes[:n_p], st.weights[:n_p], st.grads[:n_p]
        inv_mass = work["inv_mass"]
        v = work["mom"] * inv_mass[..., None]
        accel = (grid_v - v) / dt  # f^{C,1} of LR eq. 34 (boundaries included)
        sv, sv_plus, new_F = g2p_update(
            nodes, weights, grads, self.material, v, grid_v, dt, state.mpm_F
        )
        if self.xpic_order is None:  # FLIP (LR eq. 32)
            new_v = state.mpm_v + (sv_plus - sv)
            if self.contact_force == "c0":  # the first correction reaches the particles
                new_v += g2p_field(nodes, weights, self.material, work["dp1"] * inv_mass[..., None])
            new_x = state.mpm_x + dt * 0.5 * (sv + sv_plus)
        else:  # XPIC(m) (LR eqs. 35, 37)

            def apply_A(u: np.ndarray) -> np.ndarray:
                values = g2p_field(nodes, weights, self.material, u)
                return p2g_field(nodes, weights, self.material, model.mpm_mass, values, inv_mass)

            t1 = time.perf_counter()
            dv = work["dp1"] * inv_mass[..., None]
            v_star = xpic_grid_velocity(
                self.xpic_order, self.options.xpic_variant, v, step.velocity, dv, apply_A,
                step.constraints.project,
            )  # fmt: skip
            step.timings["xpic"] = time.perf_counter() - t1
            new_v = g2p_field(nodes, weights, self.material, v_star + dt * accel)
            new_x = state.mpm_x + dt * (sv + 0.5 * (new_v - state.mpm_v))
        return new_x, new_v, new_F, np.zeros_like(state.mpm_C)

    def after_g2p(self, step: GridStep, motion: Motion) -> None:
        """The step's notes, counters, report values and contact view (no correction)."""
        work, opts = step.work, self.options
        planes, touching = work["planes"], work["touching"]
        dp1, dp2, absorbed = work["dp1"], work["dp2"], work["absorbed"]
        if touching:
            self.steps_with_contact += 1
        impulse_1, impulse_2 = float(np.abs(dp1).sum()), float(np.abs(dp2).sum())
        new_step = step.state.step + 1
        step.notes += self._watch_first_correction(touching > 0, impulse_1, impulse_2, new_step)
        unconverged = int((~planes.converged).sum())
        self.unconverged_fits += unconverged
        if unconverged:
            step.notes.append(f"LR_UNCONVERGED: {unconverged} LR fits hit the iteration cap")
            if not self._warned_unconverged:  # once per run (spec L7); counted in every report
                self._warned_unconverged = True
                log.warning(
                    "lr: %d LR fits hit the cap of %d iterations at step %d (the last iterate "
                    "is used; counted in StepReport.extra['lr_unconverged'] from now on)",
                    unconverged, opts.lr_max_iterations, new_step,
                )  # fmt: skip
        self._store_contact(planes, work["dp_kick"] + absorbed, work["pts"], work["inv_mass"])
        step.extra.update(
            contact_nodes=float(np.unique(planes.node).size),
            nodes_3plus=float(np.unique(planes.node[planes.b < 0]).size),
            pairs_in_contact=float(touching),
            lr_iterations_max=float(planes.iterations.max()) if planes.node.size else 0.0,
            lr_unconverged=float(unconverged),
            lr_fallbacks=float(planes.fallback.sum()),
            lump_momentum_drift=float(np.linalg.norm(work["drift"])),
            scripted_impulse=float(np.linalg.norm(absorbed.sum(axis=(0, 1)))),
            first_correction_impulse=impulse_1,
            second_correction_impulse=impulse_2,
        )
        step.iterations["lr"] = int(planes.iterations.max()) if planes.node.size else 0
        step.outcome["contact_pairs"] = int(touching)

    def _watch_first_correction(
        self, touching: bool, impulse_1: float, impulse_2: float, step: int
    ) -> list[str]:
        """The ``LR_FIRST_CORRECTION`` note (and one warning per run) when, under FLIP with
        f^{C,1}, the first correction keeps removing momentum the particles never lose.

        Under f^{C,1} (LR eq. 33) the first correction's dp^a reaches neither V_p nor the FEM
        nodes, so an approach velocity the particles carry into a lasting contact (a landing,
        an impact) is removed from the grid again every step and is never lost by the
        particles. Over each window of ``FIRST_CORRECTION_WINDOW`` steps with contact, the
        note is given when sum ``|dp^a|`` of the first correction exceeds
        ``FIRST_CORRECTION_RATIO`` times that of the second. Measured under FLIP with c1
        (``benchmarks.lr_variants``, quick, ratio over the run): 0.011 on ``lr_compression``
        (stress within 0.13 % of the single material, never flagged), 7.3 while the slope box
        settles and 30 while it slides (friction lost) and 11 on the quick rings (213
        particles inside the FEM ring), all flagged. Where the particles do get the first
        correction (c0, PIC) a lasting contact gives 0.3-1.9 and the physics holds, so the note
        is for c1 only.
        """
        if touching:
            self.first_correction_impulse += impulse_1
            self.second_correction_impulse += impulse_2
        flip_c1 = self.xpic_order is None and self.contact_force == "c1"
        if not (flip_c1 and self.options.corrections == 2 and touching):
            return []
        window = self._window
        window[0] += 1
        window[1] += impulse_1
        window[2] += impulse_2
        if window[0] < FIRST_CORRECTION_WINDOW:
            return []
        ratio = window[1] / window[2] if window[2] > 0.0 else math.inf
        self._window = [0, 0.0, 0.0]
        if ratio <= FIRST_CORRECTION_RATIO:
            return []
        self.first_correction_windows += 1
        if not self._warned_first_correction:
            self._warned_first_correction = True
            log.warning(
                "lr: over the last %d contact steps (to step %d) the first correction removed "
                "%.3g times the momentum of the second: under FLIP with contact_force='c1' "
                "(LR eq. 33) the particles keep an approach velocity that contact removes from the "
                "grid every step (measured on a landing box: friction lost; on impacting rings: "
                "particles inside the FEM ring); corrections=1, transfer='pic' or "
                "contact_force='c0' remove it (benchmarks.lr_variants)",
                FIRST_CORRECTION_WINDOW, step, ratio,
            )  # fmt: skip
        return [f"LR_FIRST_CORRECTION: first/second correction impulse ratio {ratio:.3g}"]

    def _fem_velocities(self, step: GridStep, dp: np.ndarray, inv_mass: np.ndarray) -> np.ndarray:
        """FEM velocities at t^{n+1} ``(N, d)`` m/s (section 2.6 of the spec): the mechanical
        update, plus on the boundary nodes the G2P of the contact velocity change ``dp / m``
        ``(M, G, d)``; scripted nodes their script (the engine moves the nodes)."""
        model, dt, state = self.model, self.dt, step.state
        fem_v = state.fem_v + dt * step.fem_force * self._fem_inv_mass[:, None]
        if self._n_fem_points:
            st = step.work["pts"].stencils
            rows = slice(model.n_particles, model.n_particles + self._n_fem_points)
            kick = g2p_field(
                st.nodes[rows], st.weights[rows], self._fem_point_material, dp * inv_mass[..., None]
            )
            free = self._fem_point_free
            fem_v[self._fem_points[free]] += kick[free]
        scripted = ~self._fem_free
        fem_v[scripted] = model.prescribed_velocities(step.t_next)[scripted]
        return fem_v

    def _store_contact(
        self, planes: _Pairs, dp2: np.ndarray, pts: _Points, inv_mass: np.ndarray
    ) -> None:
        """The contact view: the f^{C,1} grid forces dp^+/dt shared out to the particles and FEM
        boundary nodes in proportion to their mass weight at each node (sums to the grid's)."""
        model, st, dt = self.model, pts.stencils, self.dt
        share = g2p_field(st.nodes, st.weights, pts.material, dp2 * inv_mass[..., None])
        force = share * (pts.mass / dt)[:, None]
        n_p = model.n_particles
        fem_forces = np.zeros((model.n_fem_nodes, model.dim))
        if self._n_fem_points:
            fem_forces[self._fem_points] = force[n_p : n_p + self._n_fem_points]
        sep = planes.separation[np.isfinite(planes.separation)]
        self._last_contact = ContactView(
            fem_forces=fem_forces,
            particle_forces=force[:n_p],
            min_distance=float(sep.min()) if sep.size else float("nan"),
            pairs=int(np.unique(planes.node).size),
        )

    def contact(self) -> ContactView:
        """The contact forces of the last step (zero before the first)."""
        if self._last_contact is None:
            return super().contact()
        return self._last_contact


def _facet_samples(
    facets: np.ndarray, material: np.ndarray, per_edge: np.ndarray, d: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample points on the facets at spacing facet edge / ``per_edge`` (vertices excluded, the
    nodes are points already): ``(facet nodes (S, d), barycentric weights (S, d), material (S,))``.

    2D: the n - 1 interior points of a segment cut into n; 3D: the barycentric lattice of order n
    of a triangle without its three vertices (points on shared edges appear once per facet).
    """
    out_nodes, out_bary, out_mat = [], [], []
    for n in np.unique(per_edge):  # a few distinct orders, vectorised over facets
        sel = np.flatnonzero(per_edge == n)
        if d == 2:
            t = np.arange(1, n) / n
            bary = np.stack([1.0 - t, t], axis=1)
        else:
            i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
            keep = (i + j <= n).ravel()
            i, j = i.ravel()[keep], j.ravel()[keep]
            k = n - i - j
            corner = (i == n) | (j == n) | (k == n)
            bary = np.stack([i, j, k], axis=1)[~corner] / n
        if bary.shape[0] == 0:
            continue
        out_nodes.append(np.repeat(facets[sel], bary.shape[0], axis=0))
        out_bary.append(np.tile(bary, (sel.size, 1)))
        out_mat.append(np.repeat(material[sel], bary.shape[0]))
    if not out_nodes:
        return np.zeros((0, d), np.int64), np.zeros((0, d)), np.zeros(0, np.int64)
    return np.concatenate(out_nodes), np.concatenate(out_bary), np.concatenate(out_mat)
