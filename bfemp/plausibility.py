"""Warnings for implausible discretisations and for runs that lose most of their energy.

``Simulation`` calls :func:`discretisation_notes` when it is built and :class:`EnergyLossCheck`
after every step. Neither refuses anything: a discretisation outside the ranges below may be
what the user wants (a coarse look, a quasi-static solve), so they are named notes
(``bfemp.PlausibilityWarning``, kept in ``Simulation.diagnostics``), each naming the ratio, the
body and the threshold. The thresholds are our choices (the papers give working values, not
limits); each constant's comment says why it is where it is.

Ratios checked at construction:

- particles per grid cell of each MPM body (``geometry.grid.particles_per_cell``, by volume),
  as particle spacings per cell edge ``k = ppc^(1/d)``: above :data:`MAX_PARTICLES_PER_CELL_EDGE`;
- grid cells across each MPM body's thinnest axis-aligned extent (bounding box of its particles
  plus one particle spacing): below :data:`MIN_GRID_CELLS_ACROSS_BODY`;
- the time step against each deformable body's wave period ``T = 2 L / c_p`` (``L`` the largest
  extent of its rest shape, ``c_p = material.p_wave_speed``): ``dt / T`` above
  :data:`MAX_DT_OVER_WAVE_PERIOD`.
"""

from __future__ import annotations

import math

import numpy as np

from bfemp.model import Model
from geometry.grid import particles_per_cell

__all__ = [
    "ENERGY_LOSS_RUN_FRACTION",
    "ENERGY_LOSS_STEP_FRACTION",
    "ENERGY_NOISE_REL",
    "MAX_DT_OVER_WAVE_PERIOD",
    "MAX_PARTICLES_PER_CELL_EDGE",
    "MIN_GRID_CELLS_ACROSS_BODY",
    "EnergyLossCheck",
    "damps_by_design",
    "discretisation_notes",
    "wave_periods",
]

#: Particle spacings per grid cell edge, ``ppc^(1/d)``, above which the grid is implausibly coarse
#: for the particles (64 particles per cell in 2D, 512 in 3D). The papers sample 2-4 per edge
#: (BFEMP sec. 6.5, Fig. 14: PPC 4, 9, 16 in 2D; LR: four per cell in 2D). At 8 per edge the
#: grid, not the particles, sets the resolution: it averages each stress over 8 particle
#: spacings, so the particles carry detail no grid node can represent, and each one costs a
#: transfer. (Our choice: twice the densest sampling the papers use.)
MAX_PARTICLES_PER_CELL_EDGE = 8.0

#: Grid cells across an MPM body's thinnest extent below which the body is implausibly small for
#: its grid. A body thinner than one cell has no grid node between its two faces: its bending and
#: its through-thickness stress are not resolved, and the quadratic B-spline stencil (3 cells
#: wide) spreads it over a region several times its size, so it feels contact and boundaries a
#: cell or more before it touches them. (Our choice: one cell, the least that gives a body a
#: node of its own: thin bodies of 1-2 cells are used on purpose.)
MIN_GRID_CELLS_ACROSS_BODY = 1.0

#: ``dt / T`` above which a time step is implausibly large for a deformable body, with
#: ``T = 2 L / c_p`` its wave period: the period of its fundamental axial vibration (a free-free
#: bar, f = c / 2 L) and the duration of an impact of two equal bars (St. Venant). A step longer
#: than ``T / 2`` cannot represent even that slowest axial vibration (fewer than two steps per
#: period, the Nyquist limit), and an impact lasts about two steps or less: implicit integrators
#: then dissipate (backward Euler) or misplace (Newmark) its energy (measured: design note
#: ``measurements``, plausibility). Quasi-static solves with backward Euler take such steps on
#: purpose (BFEMP sec. 6.5; the note says so). (Our choice: two steps per period, where the
#: measured loss jumps.)
MAX_DT_OVER_WAVE_PERIOD = 0.5

#: Fraction of the energy scale (below) lost since t = 0 above which a closed scene gets an
#: ``ENERGY_LOSS`` note. (Our choice: half, so that friction, backward Euler's damping of a
#: resolved vibration and the 5-20 % an implicit impact loses stay below it.)
ENERGY_LOSS_RUN_FRACTION = 0.5

#: Fraction of the energy scale lost in one step above which a closed scene gets an
#: ``ENERGY_LOSS`` note (a collision swallowed by one step). (Our choice.)
ENERGY_LOSS_STEP_FRACTION = 0.25

#: A loss is counted only above this fraction of the sum of the magnitudes of the energy terms
#: (kinetic, elastic, gravity, load, contact): below it, a body at rest high above gravity's
#: zero would be judged by the round-off and Newton tolerance of a total far larger than the
#: little energy in motion. (Our choice: well above round-off, below any loss worth a note.)
ENERGY_NOISE_REL = 1e-6


def wave_periods(model: Model) -> list[tuple[str, float, float, float]]:
    """``(body description, T in s, L in m, c_p in m/s)`` of every deformable body.

    ``T = 2 L / c_p`` with ``L`` the largest extent of the body's rest shape (FEM nodes or MPM
    particles plus one particle spacing). FEM bodies whose every node is scripted are left out
    (nothing integrates them).
    """
    out = []
    prescribed = model.fem_prescribed
    for body in model.fem_bodies:
        if prescribed[body.nodes].all():
            continue
        length = float(np.ptp(model.fem_X[body.nodes], axis=0).max())
        c = float(body.material.p_wave_speed)
        if length > 0.0 and c > 0.0:
            out.append((f"fem body '{body.name}'", 2.0 * length / c, length, c))
    for body in model.mpm_bodies:
        sl = body.particles
        spacing = float(np.mean(model.mpm_volume[sl])) ** (1.0 / model.dim)
        length = float(np.ptp(model.mpm_X[sl], axis=0).max()) + spacing
        c = float(body.material.p_wave_speed)
        if c > 0.0:
            out.append((f"mpm body '{body.name}'", 2.0 * length / c, length, c))
    return out


def damps_by_design(integrator: object) -> bool:
    """Whether ``integrator`` damps unresolved vibrations on purpose: Newmark's gamma above 1/2
    (backward Euler, L-stable, the usual quasi-static and near-rigid choice, BFEMP secs. 6.4-6.5;
    damped Newmark). The mid-point members (gamma = 1/2) and symplectic Euler aim to keep the
    energy."""
    return float(getattr(integrator, "gamma", 0.5)) > 0.5


def discretisation_notes(model: Model, dt: float, integrator: object) -> list[str]:
    """The ``IMPLAUSIBLE_*`` notes of a scene at step ``dt`` (s), one per name (the findings of
    a name joined by "; "); empty when every ratio is within the thresholds of this module.

    ``integrator`` (a ``bfemp.Integrator`` or ``ExplicitIntegrator``) is named in the dt note,
    which is given only for scenes with contact settings (``scene.set_contact``: bodies that
    collide) and left out for an integrator that :func:`damps_by_design`: a step above the wave
    period is then the intended quasi-static (or near-rigid) use, whose vibrations the integrator
    removes. Without contact the mid-point rule is unconditionally stable and keeps the energy of
    the modes it does not resolve (measured: ``tests/bfemp/test_dynamics.py`` keeps a beam's
    energy within 1 % over ten periods at dt = 0.86 of its axial wave period); the harm is at
    impacts.
    """
    notes = []
    d = model.dim
    grid = model.grid
    for body in model.mpm_bodies if grid is not None else ():
        sl = body.particles
        x, vol = model.mpm_X[sl], model.mpm_volume[sl]
        ppc = particles_per_cell(grid, x, vol)
        per_edge = ppc ** (1.0 / d)
        if per_edge > MAX_PARTICLES_PER_CELL_EDGE:
            notes.append(
                f"IMPLAUSIBLE_GRID: mpm body '{body.name}' has {ppc:.4g} particles per grid cell "
                f"({per_edge:.3g} particle spacings per cell edge, above "
                f"{MAX_PARTICLES_PER_CELL_EDGE:g}): the grid dx = {grid.dx:g} m is much coarser "
                f"than the particles and sets the resolution; use a finer grid (dx about "
                f"{grid.dx * 2.0 / per_edge:.3g} m for 2 particles per edge) or fewer particles"
            )
        spacing = float(np.mean(vol)) ** (1.0 / d)
        across = (float(np.ptp(x, axis=0).min()) + spacing) / grid.dx
        if across < MIN_GRID_CELLS_ACROSS_BODY:
            notes.append(
                f"IMPLAUSIBLE_GRID: mpm body '{body.name}' is {across:.3g} grid cells across its "
                f"thinnest side (below {MIN_GRID_CELLS_ACROSS_BODY:g}; dx = {grid.dx:g} m): no "
                "more than one row of grid nodes lies inside it, so the grid cannot represent its "
                "deformation; use a grid dx smaller than the body"
            )
    impacts = model.contact is not None
    periods = wave_periods(model) if impacts and not damps_by_design(integrator) else []
    if periods:
        where, period, length, c = min(periods, key=lambda p: p[1])
        ratio = dt / period
        if ratio > MAX_DT_OVER_WAVE_PERIOD:
            notes.append(
                f"IMPLAUSIBLE_DT: dt = {dt:.4g} s is {ratio:.3g} times the wave period "
                f"T = 2 L / c_p = {period:.4g} s of {where} (L = {length:.4g} m, c_p = "
                f"{c:.4g} m/s; above {MAX_DT_OVER_WAVE_PERIOD:g}): not even the slowest axial "
                f"vibration of that body is resolved and an impact lasts two steps or less, so "
                f"{integrator.name} loses or misplaces its energy; take dt below "
                f"{MAX_DT_OVER_WAVE_PERIOD * period:.3g} s (or backward_euler for a "
                "quasi-static solve)"
            )
    return _one_per_name(notes)


def _one_per_name(notes: list[str]) -> list[str]:
    """Join notes of one name (``"NAME: text"``) into one ``"NAME: text; text"``: a simulation
    keeps and warns the first note of each name only (``bfemp.errors.warn_user``), and every
    finding of a scene's discretisation should reach the user."""
    joined: dict[str, str] = {}
    for note in notes:
        name, _, text = note.partition(": ")
        joined[name] = f"{joined[name]}; {text}" if name in joined else note
    return list(joined.values())


class EnergyLossCheck:
    """Names, once per run, a closed scene that loses most of its energy (``ENERGY_LOSS``).

    The scale of the loss is the largest kinetic + elastic + contact energy seen so far (the
    energy in motion and deformation; gravity and loads are left out because their zero is
    arbitrary), so a block that falls and comes to rest is measured against the kinetic energy
    it had, not against its height above the origin. A note is due when ``E_total(0) -
    E_total`` exceeds :data:`ENERGY_LOSS_RUN_FRACTION` of that scale, or one step loses more than
    :data:`ENERGY_LOSS_STEP_FRACTION` of it.

    False alarms: a scene that dissipates by design (``dissipation`` not empty: an integrator
    that :func:`damps_by_design`, friction, the PIC transfer, an inelastic contact: every
    strategy but ``barrier``, e.g. augury's sticking impacts that lose 51-53 % in its tests,
    and MPM bodies meeting on the shared grid) is not checked at all, because how much such a
    scene may lose has no bound we could state; nor is a scene on which something external
    works (loads, moving scripted nodes or boundaries: checked by ``Simulation``), whose energy
    may leave legitimately. What is left (``barrier`` with mid-point Newmark, with or without
    implicit contact, without friction) aims to keep the energy: an implicit impact loses 5-20 %
    there (measured: ``MAX_DT_OVER_WAVE_PERIOD``), well below the thresholds. The note is a
    note (``diagnostics``, a warning), never a failure.
    """

    def __init__(self, dissipation: str) -> None:
        #: what in this scene dissipates by design ("" for nothing: only then is it checked)
        self.dissipation = dissipation
        #: the note was given (once per run)
        self.done = False
        #: rows seen so far; the total energy of the first and of the latest; the scale
        self.rows = 0
        self._first = self._last = math.nan
        self._scale = 0.0

    def start(self, energies: np.ndarray, mechanical: np.ndarray) -> None:
        """Take the rows of a metrics log so far (a new run, or one resumed from a checkpoint).

        Args:
            energies: ``energy_total`` of every row ``(rows,)`` in J.
            mechanical: kinetic + elastic + contact energy of every row ``(rows,)`` in J.
        """
        self.rows = int(energies.size)
        if self.rows:
            self._first, self._last = float(energies[0]), float(energies[-1])
            self._scale = max(float(np.nanmax(mechanical)), 0.0) if mechanical.size else 0.0

    def check(
        self, total: float, mechanical: float, t: float, magnitude: float = 0.0
    ) -> str | None:
        """Take the next row; the note due after it, else None.

        Args:
            total: its ``energy_total`` in J.
            mechanical: its kinetic + elastic + contact energy in J.
            t: its time in s.
            magnitude: the sum of the magnitudes of its energy terms in J (the noise floor is
                :data:`ENERGY_NOISE_REL` of it).
        """
        previous = self._last
        if self.rows == 0:
            self._first = total
        self.rows += 1
        self._last = total
        if math.isfinite(mechanical):
            self._scale = max(self._scale, mechanical)
        scale = self._scale
        if self.dissipation or self.done or self.rows < 2 or not (scale > 0.0):
            return None
        floor = ENERGY_NOISE_REL * magnitude
        run_loss = (self._first - total) / scale if self._first - total > floor else 0.0
        step_loss = (previous - total) / scale if previous - total > floor else 0.0
        if not (run_loss > ENERGY_LOSS_RUN_FRACTION or step_loss > ENERGY_LOSS_STEP_FRACTION):
            return None
        self.done = True
        if step_loss > ENERGY_LOSS_STEP_FRACTION:
            what = (
                f"the last step lost {100 * step_loss:.0f} % (above "
                f"{100 * ENERGY_LOSS_STEP_FRACTION:g} %)"
            )
        else:
            what = (
                f"the run has lost {100 * run_loss:.0f} % since t = 0 (above "
                f"{100 * ENERGY_LOSS_RUN_FRACTION:g} %)"
            )
        return (
            f"ENERGY_LOSS: at t = {t:.6g} s {what} of the largest kinetic + elastic + contact "
            f"energy ({scale:.4g} J), although nothing external works on the scene and nothing "
            "in it dissipates by design (barrier contact, no friction, a mid-point integrator); "
            "a time step longer than the bodies' wave period loses impacts' energy: try a "
            "smaller dt (a note, not a failure)"
        )
