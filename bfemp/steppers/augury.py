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
is a choice the paper leaves open; with their lumped mass instead a fixed plate only damps
(measured, issue 40: design note ``measurements``, augury stepper). The cost in
conservation: the free bodies exchange momentum with the scripted nodes, which do not give it
back. Every step reports it, ``StepReport.extra["kinematic_impulse_x"|"_y"|"_z"]`` in N s (N s/m
in 2D): the impulse the scripted nodes deliver to the free foreground in the step (the free
particles' summed m dt a^; H conserves momentum among them), and a ``SCRIPTED_FOREGROUND`` note.
With ``False`` scripted nodes are not in H and a body falls through a fixed plate (measured on
issue 40's drop, with and without: design note ``measurements``, augury stepper).

MPM particles' F (``contact_strain=True``, bfemp's): section 1.4 item 3 leaves F_p as the
engine's G2P made it from the free grid velocities, expecting contact to reach F through the
next P2G. It does not: the next P2G sees the corrected velocities, but the F increment of the
correction itself, dt grad(dt a^), is never applied (measured: particles crowd together under
sustained contact while F stays near I; design note ``measurements``, augury stepper). F_p^{n+1}
+= dt (sum_i dv_i grad w_ip^T) F_p^n, dv_i the correction's mass-weighted field on the engine's
MPM grid per body (``bfemp.contact._augury_geometry.correction_gradient``).

Named notes in every report where they apply: ``SCRIPTED_FOREGROUND``, ``AUGURY_REACH`` (tau
times the velocity spread at shared contact nodes above grid_dx / 3, AUG eq. 50),
``AUGURY_STEP_REACH`` (dt max |v| above grid_dx / 2) and ``INTERPENETRATION`` (foreground nodes
or particles strictly inside a cell of another FEM body at the end of the step; AUG admits the
method can let bodies through, pitfall A9). Cost: N + 1 H applications over the foreground set
(optionally only the particles sharing a contact node with another body, ``region="shared"``).
"""

from __future__ import annotations

import logging
import time
from typing import ClassVar

import numpy as np

from bfemp.contact._augury_geometry import (
    cell_faces,
    correction_gradient,
    face_key,
    facing_normals,
    fem_normals,
    inside_other_cells,
    mpm_normals,
    reach_notes,
    subset,
)
from bfemp.contact._augury_kernels import node_body_ranges
from bfemp.contact.augury import (
    ContactOperator,
    augury_correction,
    contact_stencils,
)
from bfemp.contact.collision import facet_edge_lengths
from bfemp.contact.parameters import refuse_pair_friction
from bfemp.errors import warn_user
from bfemp.model import Model
from bfemp.state import State
from bfemp.steppers._augury_options import (
    AUGURY_PENETRATION_CELLS,
    AUGURY_PENETRATION_NOTE,
    COARSE_GRID_RATIO,
    AuguryOptions,
    friction_coefficient,
)
from bfemp.steppers.base import ContactView
from bfemp.steppers.capabilities import BARRIER_PAIRS, Capabilities
from bfemp.steppers.explicit import ExplicitStepper, GridStep, Motion

__all__ = ["AuguryOptions", "AuguryStepper"]

log = logging.getLogger(__name__)


class AuguryStepper(ExplicitStepper):
    """The ``"augury"`` strategy (module docstring)."""

    name: ClassVar[str] = "augury"
    Options: ClassVar[type[AuguryOptions]] = AuguryOptions
    #: FEM boundary nodes and particles meet on the contact grid (AUG; particles: bfemp's
    #: extension, section 1.4); MPM bodies also share the engine's MPM grid velocity field:
    #: the barrier's couplings, kind by kind
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs=BARRIER_PAIRS,
        needs_contact_settings=False,
        penetration_bound_cells=AUGURY_PENETRATION_CELLS,
        penetration_note=AUGURY_PENETRATION_NOTE,
    )

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
        self.mu = friction_coefficient(opts.mu, model.contact)
        self.apic = opts.contact_transfer == "apic"
        self._tau_predict = self.tau + (0.5 * self.dt if opts.predictor == "paper" else 0.0)
        self._setup_foreground()
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
        facets, opposite = [], []
        cell_keys, cell_opp = cell_faces(model.fem_cells, n, d)
        for body in model.fem_bodies:
            f = np.asarray(body.boundary, dtype=np.int64).reshape(-1, d)
            if f.size == 0:
                continue
            key = face_key(np.sort(f, axis=1), n)
            pos = np.searchsorted(cell_keys, key)
            pos = np.minimum(pos, cell_keys.size - 1)
            if not np.all(cell_keys[pos] == key):
                raise ValueError(
                    f"augury: fem body {body.name!r}: boundary facets not on any of its cells"
                )
            facets.append(f)
            opposite.append(cell_opp[pos])
        self._facets = np.concatenate(facets) if facets else np.zeros((0, d), np.int64)
        self._facet_opp = np.concatenate(opposite) if opposite else np.zeros(0, np.int64)
        on_boundary = np.zeros(n, dtype=bool)
        on_boundary[self._facets.reshape(-1)] = True
        on_boundary &= model.fem_mass > 0.0
        scripted = model.fem_prescribed.astype(bool)
        kin = on_boundary & scripted if opts.kinematic_foreground else np.zeros(n, bool)
        #: the FEM foreground: indices ``(n_fg,)`` of the FEM nodes on the contact grid (free
        #: boundary nodes, and scripted ones with ``kinematic_foreground``); read it only
        self.fem_foreground = np.flatnonzero((on_boundary & ~scripted) | kin)
        self._fem_movable = ~scripted[self.fem_foreground]
        self._n_kinematic = int(kin.sum())
        self._fem_node_body = np.zeros(n, dtype=np.int64)
        for body in model.fem_bodies:
            self._fem_node_body[body.nodes] = body.index
        self._mpm_fg = bool(opts.mpm_foreground and model.n_particles)
        n_fem_bodies = len(model.fem_bodies)
        self._mpm_body = (
            model.mpm_particle_body + n_fem_bodies if model.n_particles else np.zeros(0, np.int64)
        )
        # contact-grid spacing (section 1.5 item 4, A8)
        edges = facet_edge_lengths(model.fem_X, self._facets)
        mean_edge = float(edges.mean()) if edges.size else 0.0
        spacing = float(np.mean(model.mpm_volume) ** (1.0 / d)) if self._mpm_fg else 0.0
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
        kept there (measured: design note ``measurements``, augury stepper)."""
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
        """A copy of ``state`` carrying ``"aug_B" (N, d, d)`` and ``"aug_Bp" (P, d, d)`` (zeros
        when absent or of another size; ``State.carried``)."""
        out = state.copy()
        out.carried.update(self._carried_B(out))
        return out

    def _carried_B(self, state: State) -> dict[str, np.ndarray]:
        """``state.carried``'s ``"aug_B" (N, d, d)`` and ``"aug_Bp" (P, d, d)`` in m^2/s, zeros
        where absent or of another size (not copied)."""
        d, out = self.model.dim, {}
        for name, n in (("aug_B", self.model.n_fem_nodes), ("aug_Bp", self.model.n_particles)):
            B = state.carried.get(name)
            out[name] = B if B is not None and B.shape == (n, d, d) else np.zeros((n, d, d))
        return out

    # ------------------------------------------------------------------ geometry per step
    def fem_normals(self, x: np.ndarray) -> np.ndarray:
        """Outward unit normals ``(N, d)`` of the FEM boundary nodes at ``x (N, d)`` m (AUG
        section 2.3, ``bfemp.contact._augury_geometry.fem_normals``)."""
        return fem_normals(x, self._facets, self._facet_opp)

    # ------------------------------------------------------------------ the step
    def after_g2p(self, step: GridStep, motion: Motion) -> None:
        """The augury correction of the engine's free-flight end values (module docstring)."""
        started = time.perf_counter()
        model, d, state = self.model, self.model.dim, step.state
        motion.carried.update(self._carried_B(state))
        B_fem, B_mpm = motion.carried["aug_B"], motion.carried["aug_Bp"]
        if self._coarse_note is not None:
            step.notes.append(self._coarse_note)
        fg = self.fem_foreground
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
            self._correct_motion(step, motion, a_hat, B_new)
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
        model, fg = self.model, self.fem_foreground
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
        n_fem = self.fem_foreground.size
        n_all = x.shape[0]
        movable = np.ones(n_all, dtype=bool)
        movable[:n_fem] = self._fem_movable
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
                faces = (self.fem_foreground, self._facets, self._facet_opp)
                normals[:n_fem] = facing_normals(points["fem_x"], st, m, body, normals, *faces)
        if n_all > n_fem:
            normals[n_fem:] = mpm_normals(st, n_fem, m[n_fem:], body[n_fem:])
        node_shared, v_lo, v_hi = node_body_ranges(st.nodes, st.weights, body, v_bar, st.n_nodes)
        shared = (node_shared[st.nodes] & (st.weights > 0.0)).any(axis=1)
        timings["augury_stencils"] = time.perf_counter() - t0
        step.notes.extend(
            reach_notes(self.dt, self.tau, self.grid_dx, node_shared, v_lo, v_hi, v_bar)
        )
        sel = np.arange(n_all) if self.options.region == "all" else np.flatnonzero(shared)
        if not self.apic:
            B_bar = np.zeros_like(B_bar)
        v_hat = v_bar.copy()
        B_hat = B_bar.copy()
        h_applications = 0
        if sel.size:
            t0 = time.perf_counter()
            sub = st if sel.size == n_all else subset(st, sel)
            op = ContactOperator(sub, x[sel], m[sel], apic=self.apic, kinematic=~movable[sel])
            opts = self.options
            start = (v_bar[sel], B_bar[sel], normals[sel], opts.iterations, opts.mode, self.mu)
            v_hat[sel], B_hat[sel] = augury_correction(
                op, *start, movable[sel], energy_guard=opts.energy_guard, stats=stats
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
        self, step: GridStep, motion: Motion, a_hat: np.ndarray, B_new: np.ndarray
    ) -> None:
        """v^{n+1} = v^free + dt a^, x^{n+1} = x^free + dt^2 a^, B^{n+1} (module docstring step
        3) on the end values of the foreground (``a_hat``'s rows: FEM nodes, then particles),
        before the engine commits them."""
        dt, state, n_fem = self.dt, step.state, self.fem_foreground.size
        if n_fem:
            fg, mov = self.fem_foreground, self._fem_movable
            idx = fg[mov]
            motion.fem_v[idx] += dt * a_hat[:n_fem][mov]
            motion.fem_x[idx] += dt * dt * a_hat[:n_fem][mov]
            B_fem = motion.carried["aug_B"].copy()
            B_fem[fg] = B_new[:n_fem]
            motion.carried["aug_B"] = B_fem
        if a_hat.shape[0] > n_fem:  # the particles are foreground
            motion.mpm_v = motion.mpm_v + dt * a_hat[n_fem:]
            motion.mpm_x = motion.mpm_x + dt * dt * a_hat[n_fem:]
            motion.carried["aug_Bp"] = B_new[n_fem:]
            if self.options.contact_strain:
                motion.mpm_F = motion.mpm_F + dt * np.einsum(
                    "pab,pbc->pac",
                    correction_gradient(self.model, state.mpm_x, dt * a_hat[n_fem:]),
                    state.mpm_F,
                )

    def _penetration_notes(self, new: Motion) -> list[str]:
        """INTERPENETRATION (pitfall A9): foreground points strictly inside another FEM body."""
        model = self.model
        if len(model.fem_bodies) + (len(model.mpm_bodies) if self._mpm_fg else 0) < 2:
            return []
        if not model.fem_cells.shape[0]:
            return []
        pts = [new.fem_x[self.fem_foreground]]
        owner = [self._fem_node_body[self.fem_foreground]]
        if self._mpm_fg:
            pts.append(new.mpm_x)
            owner.append(self._mpm_body)
        inside, depth, depth_m = inside_other_cells(
            np.concatenate(pts), np.concatenate(owner), new.fem_x, model.fem_cells, self._cell_body
        )
        if not inside:
            return []
        self.max_penetration_depth = max(self.max_penetration_depth, depth_m)
        return [
            f"INTERPENETRATION: {inside} foreground points strictly inside a cell of "
            f"another body (deepest barycentric depth {depth:.3g}, "
            f"{depth_m:.3g} m from that cell's nearest face)"
        ]

    def _store_contact(self, a_hat: np.ndarray, shared_count: int, n_fem: int) -> None:
        model = self.model
        fem_f = np.zeros((model.n_fem_nodes, model.dim))
        part_f = np.zeros((model.n_particles, model.dim))
        if n_fem:
            fem_f[self.fem_foreground] = model.fem_mass[self.fem_foreground, None] * a_hat[:n_fem]
        if self._mpm_fg and model.n_particles:
            part_f[:] = model.mpm_mass[:, None] * a_hat[n_fem:]
        largest = float(np.sqrt(np.einsum("pd,pd->p", a_hat, a_hat)).max()) if a_hat.size else 0.0
        parameters = {"augury_max_correction": largest}
        self._last_contact = ContactView(fem_f, part_f, pairs=shared_count, parameters=parameters)

    def contact(self) -> ContactView:
        """Augury forces m a^ of the last step on the foreground (no distance, no energy)."""
        if self._last_contact is None:
            m = self.model
            self._last_contact = ContactView.empty(
                m.n_fem_nodes, m.n_particles, m.dim, parameters={"augury_max_correction": 0.0}
            )
        return self._last_contact
