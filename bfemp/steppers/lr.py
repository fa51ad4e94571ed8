"""``"lr"``: multimaterial MPM with logistic-regression contact and multimaterial XPIC(m).

Paper: Nairn et al., logistic-regression multimaterial MPM contact ("LR"). Every MPM body is one
material with its own velocity field on the shared grid (``bfemp.mpm.transfer``'s
multimaterial kernels). One USL step, the explicit engine's step (``bfemp.steppers.explicit``)
with M fields and these phases: P2G (step 1), ``after_p2g`` (2-3), ``resolve`` (4), the
engine's constraints (5), ``g2p`` (6):

1. Stencils at X_p^n; P2G per material (LR eq. 5): m^a, p^a0, f^a0 (LR eq. 29, gravity included).
   Level-set boundaries act on every field (``bfemp.mpm.boundaries``).
2. Contact nodes: nodes where two or more materials have mass, however little (LR section 3.1: nodes
   that "see" two or more materials; NairnMPM activates a material's field wherever one of its
   particles contributes). ``mass_fraction`` > 0 (Uintah's 1e-8) leaves out a material whose mass
   there is below that fraction of the node's total: an option, not LR's rule. At a node with two
   materials one pair (a, b), a the lower index; at a node with three or more, one pair per material
   a against the lumped others (LR eq. 50). Each pair's point cloud is every particle whose stencil
   weight at the node is positive; one logistic-regression fit per pair and step gives the normal n
   (from a to b) and the separation d_LR with the deformed particle radius (LR eqs. 19-25,
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

Penetration: none below a fixed FEM plate's top beyond about one step's travel (measured, issue
40: design note ``measurements``, lr); against deformable FEM bodies nothing is guaranteed.

Transfers: ``"flip"`` (the default) and ``"pic"`` (= XPIC(1)); ``xpic_order`` m >= 1 selects
XPIC(m). APIC is refused: LR's corrections and XPIC are written for FLIP-type updates. FEM bodies
take part as one material each (bfemp's design; LR has no FEM): their boundary nodes are the
material's points in P2G (mass m_n, velocity v_n^n, force m_n a_n^mech; the internal force stays on
the mesh), and the point cloud holds the boundary nodes plus facet samples at spacing <= dx / 2, all
of radius 0 (they lie on the surface). The boundary nodes then move like FLIP particles, v_n^{n+1} =
v_n^n + dt a_n^mech + sum_i w_in dp_i^{F+} / m_i^F, which conserves momentum since m_i^F = sum_n
w_in m_n; interior nodes take the mechanical update. Scripted nodes enter with their mass and
velocity, and with the force that takes them to their script at t^{n+1}; they keep their script.
Where a FEM material's grid mass at a node comes from scripted nodes alone, that field is rigid in
the contact law (infinite mass, NairnMPM's rigid materials; LR has none): the other material takes
its velocity along the normal (``_kinematic_fields`` says why: with its finite grid mass a fixed
plate let bodies through). The momentum such a field takes is the support's reaction, not applied
and not conserved among the bodies; it is reported per step as
``StepReport.extra["scripted_impulse"]`` (|sum|, kg m/s) and in the contact view's FEM forces. A
grid finer than twice the FEM boundary edge is warned about (the FEM material's grid mass then has
holes between its nodes).
"""

from __future__ import annotations

import logging
import math
import time
from typing import ClassVar

import numpy as np

from bfemp.mpm.boundaries import material_constraints
from bfemp.mpm.transfer import (
    g2p_field,
    g2p_update,
    p2g_field,
    p2g_materials,
    p2g_nodal,
)
from bfemp.mpm.xpic import xpic_grid_velocity
from bfemp.state import State
from bfemp.steppers._lr_contact import PairContact
from bfemp.steppers._lr_options import (
    FIRST_CORRECTION_RATIO,
    FIRST_CORRECTION_WINDOW,
    LR_PENETRATION_CELLS,
    LR_PENETRATION_NOTE,
    TRANSFERS,
    LROptions,
)
from bfemp.steppers._lr_points import FemPoints, Pairs, Points
from bfemp.steppers.base import ContactView
from bfemp.steppers.capabilities import Capabilities
from bfemp.steppers.explicit import ExplicitStepper, GridStep, Motion, _inverse

__all__ = ["LROptions", "LRStepper"]

log = logging.getLogger(__name__)


class LRStepper(ExplicitStepper):
    """The ``"lr"`` strategy (module docstring)."""

    name: ClassVar[str] = "lr"
    Options: ClassVar[type[LROptions]] = LROptions
    #: one velocity field per body (LR sec. 2); FEM bodies take part through their surface
    #: nodes (bfemp's design, module docstring), against MPM bodies only: in the conformance
    #: catalogue's stack a free FEM block on a fixed FEM plate sank 2.2 cells into it
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs={"mpm-mpm": "contact", "mpm-fem": "contact", "mpm-prescribed": "contact"},
        needs_contact_settings=False,
        penetration_bound_cells=LR_PENETRATION_CELLS,
        penetration_note=LR_PENETRATION_NOTE,
        needs_mpm_body=True,
    )
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
        scene_mu = float(getattr(model.contact, "mu", 0.0) or 0.0)
        self.mu = opts.mu if opts.mu is not None else scene_mu
        self.material = np.ascontiguousarray(model.mpm_particle_body, dtype=np.int64)
        self.n_materials = len(model.mpm_bodies) + len(model.fem_bodies)
        self._law = PairContact(model, opts, self.mu, self.n_materials)
        self.mu_table, self._pair_mu = self._law.mu_table, self._law.pair_mu
        d = model.dim
        # undeformed particle semi-axes R0 (P, d): half the side of the particle's cube
        self.radius0 = np.repeat((0.5 * model.mpm_volume ** (1.0 / d))[:, None], d, axis=1)
        self._fem = FemPoints(model, self.radius0, self.material)
        self.xpic_order = (
            opts.xpic_order if opts.xpic_order is not None else (1 if transfer == "pic" else None)
        )
        if opts.contact_force == "c0" and self.xpic_order is not None:
            raise ValueError(
                "lr: contact_force='c0' is a FLIP rule; XPIC(m) (xpic_order or transfer='pic') "
                "takes the first correction through v* (LR eq. 37): use contact_force='c1'"
            )
        self.contact_force = opts.contact_force
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

    # ------------------------------------------------------------------ FEM as a material
    def _pairs(self, pts: Points, grid_x: np.ndarray, mass: np.ndarray) -> Pairs:
        """This step's contact pairs and planes (``PairContact.pairs``; a subclass may watch)."""
        return self._law.pairs(pts, grid_x, mass)

    def _correct(self, planes: Pairs, *args: np.ndarray | None) -> tuple:
        """One contact correction (``PairContact.correct``; a subclass may watch)."""
        return self._law.correct(planes, *args)

    # ------------------------------------------------------------------ the step's phases
    def particles_to_grid(self, state: State) -> GridStep:
        """Phase P2G (docstring step 1): per material (LR eq. 5) m^a, p^a0, f^a0 with gravity,
        FEM boundary nodes as points; the constraints decided and applied on v^a0."""
        model, dt = self.model, self.dt
        t0 = time.perf_counter()
        piola = self.mpm_stresses(state)
        pts = self._fem.points(state)
        st = pts.stencils
        n_p = model.n_particles
        nodes, weights, grads = st.nodes[:n_p], st.weights[:n_p], st.grads[:n_p]
        grid_x = st.active_x
        mass, mom0, force = p2g_materials(
            nodes,
            weights,
            grads,
            self.material,
            model.mpm_mass,
            state.mpm_v,
            piola,
            state.mpm_F,
            model.mpm_volume,
            self.n_materials,
            grid_x.shape[0],
        )
        force += mass[..., None] * model.gravity
        fem_force = np.zeros((0, model.dim))
        if self._fem.n_nodes:
            fem_force = self.fem_forces(state)  # internal + gravity + loads, on the mesh
            rows = slice(n_p, n_p + self._fem.n_nodes)
            b = self._fem.nodes
            p2g_nodal(
                st.nodes[rows],
                st.weights[rows],
                self._fem.node_material,
                model.fem_mass[b],
                state.fem_v[b],
                self._fem.scripted_force(state, fem_force, dt),
                mass,
                mom0,
                force,
            )
        inv_mass = _inverse(mass)
        v0 = mom0 * inv_mass[..., None]
        t_next = state.t + dt
        cons = material_constraints(model.boundaries, grid_x, v0, t_next, dt)
        v0 = cons.apply(v0, dt)
        work = {"pts": pts, "inv_mass": inv_mass, "kinematic": self._fem.kinematic_fields(st, mass)}
        return GridStep(
            state=state,
            t_next=t_next,
            dt=dt,
            grid_x=grid_x,
            mass=mass,
            velocity=v0,
            force=force,
            fem_force=fem_force,
            constraints=cons,
            message="explicit step (lr)",
            timings={"fem_forces": 0.0, "p2g": time.perf_counter() - t0},
            work=work,
            _grid=model.grid,
        )

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
                self.xpic_order,
                self.options.xpic_variant,
                v,
                step.velocity,
                dv,
                apply_A,
                step.constraints.project,
            )
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
                    unconverged,
                    opts.lr_max_iterations,
                    new_step,
                )
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
        an impact) is removed from the grid again every step. Over each window of
        ``FIRST_CORRECTION_WINDOW`` steps with contact, the note is given when sum ``|dp^a|`` of
        the first correction exceeds ``FIRST_CORRECTION_RATIO`` times that of the second:
        measured, that flags the c1 runs that lose their physics and not those that keep it;
        with c0 or PIC the physics holds (design note ``measurements``, lr).
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
                FIRST_CORRECTION_WINDOW,
                step,
                ratio,
            )
        return [f"LR_FIRST_CORRECTION: first/second correction impulse ratio {ratio:.3g}"]

    def _fem_velocities(self, step: GridStep, dp: np.ndarray, inv_mass: np.ndarray) -> np.ndarray:
        """FEM velocities at t^{n+1} ``(N, d)`` m/s (section 2.6 of the spec): the mechanical
        update, plus on the boundary nodes the G2P of the contact velocity change ``dp / m``
        ``(M, G, d)`` (the engine then gives scripted nodes their script and moves the nodes)."""
        model, dt, state = self.model, self.dt, step.state
        fem_v = state.fem_v + dt * step.fem_force * self._fem_inv_mass[:, None]
        if self._fem.n_nodes:
            st = step.work["pts"].stencils
            rows = slice(model.n_particles, model.n_particles + self._fem.n_nodes)
            kick = g2p_field(
                st.nodes[rows], st.weights[rows], self._fem.node_material, dp * inv_mass[..., None]
            )
            free = self._fem.node_free
            fem_v[self._fem.nodes[free]] += kick[free]
        return fem_v

    def _store_contact(
        self, planes: Pairs, dp2: np.ndarray, pts: Points, inv_mass: np.ndarray
    ) -> None:
        """The contact view: the f^{C,1} grid forces dp^+/dt shared out to the particles and FEM
        boundary nodes in proportion to their mass weight at each node (sums to the grid's)."""
        model, st, dt = self.model, pts.stencils, self.dt
        share = g2p_field(st.nodes, st.weights, pts.material, dp2 * inv_mass[..., None])
        force = share * (pts.mass / dt)[:, None]
        n_p = model.n_particles
        fem_forces = np.zeros((model.n_fem_nodes, model.dim))
        if self._fem.n_nodes:
            fem_forces[self._fem.nodes] = force[n_p : n_p + self._fem.n_nodes]
        sep = planes.separation[np.isfinite(planes.separation)]
        self._last_contact = ContactView(
            fem_forces=fem_forces,
            particle_forces=force[:n_p],
            min_distance=float(sep.min()) if sep.size else float("nan"),
            pairs=int(np.unique(planes.node).size),
        )
