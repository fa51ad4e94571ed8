"""The energy checks of a closed scene's run: ENERGY_GROWTH and ENERGY_LOSS.

A scene is closed when nothing external works on it (no moving scripted nodes, loads or moving
boundaries); then the total energy of each metrics row is watched: it must not grow beyond the
run's energy scale (:meth:`EnergyWatch._check_growth`), and it is noted when most of it is lost
where nothing dissipates by design (:class:`bfemp.plausibility.EnergyLossCheck`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np

from bfemp.errors import PlausibilityWarning, StepNoteWarning, warn_user
from bfemp.io.metrics import MetricsLog
from bfemp.model import Model
from bfemp.motion import Fixed
from bfemp.plausibility import EnergyLossCheck, damps_by_design

__all__ = ["EnergyWatch"]

log = logging.getLogger("bfemp.simulation")


class EnergyWatch:
    """The energy checks of one simulation's metrics rows.

    Args:
        model: the simulation's model.
        integrator: its integrator (named in the ENERGY_GROWTH warning).
        dissipation: what dissipates energy by design ("" for nothing; :func:`dissipation`).
        notice: the simulation's ``_notice(message, category, logger)`` for ENERGY_LOSS.
    """

    #: relative growth of the total energy of a closed scene that triggers ENERGY_GROWTH
    ENERGY_GROWTH_TOL = 1e-2
    #: the strain whose elastic energy mu V strain^2 floors the ENERGY_GROWTH scale
    ENERGY_FLOOR_STRAIN = 1e-6

    def __init__(
        self, model: Model, integrator: object, dissipation: str, notice: Callable[..., None]
    ) -> None:
        self.integrator, self.notice = integrator, notice
        self.closed = _is_closed(model)
        self._loss = EnergyLossCheck(dissipation)
        self._floor = self.ENERGY_FLOOR_STRAIN**2 * _shear_volume(model)
        self._log: MetricsLog | None = None
        self._peak = self._floor
        self._first: tuple[float, float] | None = None

    def check(self, row: dict[str, float], stepped: bool, metrics: MetricsLog, t: float) -> None:
        """Both checks on a metrics row at time t (s) of a closed scene (none on an open one);
        ``metrics``: the rows so far (a new log starts the scale anew)."""
        if self.closed:
            self._check_growth(row, stepped, metrics, t)
            if stepped:
                self._check_loss(row, metrics, t)

    def _check_growth(
        self, row: dict[str, float], stepped: bool, metrics: MetricsLog, t: float
    ) -> None:
        """Warn (once, counted) when a scene on which nothing external works gains energy.

        The growth E(t) - E(0) of the total energy is judged against the run's energy scale:
        the largest of |E(0)|, the kinetic and the elastic energy at any row so far, the change
        of the gravitational energy from t = 0 at any row so far, and a floor, the elastic
        energy of every body at a uniform strain of ``ENERGY_FLOOR_STRAIN`` (sum mu V e^2, J;
        J/m in 2D). The floor is this module's choice (no paper sets one): it keeps round-off
        of a scene at rest from reading as growth, and lies far below any energy a run resolves
        (design note ``measurements``, energy watch).

        Backward Euler only dissipates; Newmark's trapezoidal rule conserves energy for linear
        problems but can gain it when a stiff barrier switches on and off within steps (known for
        the trapezoidal rule with contact; design note ``measurements``, energy watch). The
        remedies are ``"newmark_implicit_contact"`` (contact forces without the trapezoidal
        rule's memory), a smaller dt (resolving the approach through dhat in a few steps),
        ``"newmark_damped"`` or backward Euler.

        Args:
            row: this row's energies (``energy_total``, ``energy_kinetic``, ...; J).
            stepped: a row after a step (False: the initial row, which only sets the scale).
        """
        if self._log is not metrics:  # a new run or a restored checkpoint
            self._log, self._peak, self._first = metrics, self._floor, None
            if len(metrics):
                first = metrics.rows[0]
                self._first = (first["energy_total"], first["energy_gravity"])
                for r in metrics.rows:
                    self._peak = max(self._peak, self._magnitude(r))
        if self._first is None:
            self._first = (row["energy_total"], row["energy_gravity"])
        self._peak = max(self._peak, self._magnitude(row))
        if not stepped:
            return
        change = row["energy_total"] - self._first[0]
        growth = change / self._peak if self._peak > 0.0 else 0.0
        if growth > self.ENERGY_GROWTH_TOL:
            warn_user(
                f"ENERGY_GROWTH: the total energy grew by {100 * growth:.3g} % of the run's "
                f"energy scale {self._peak:.3g} J (J/m in 2D) since t = 0, at t = "
                f"{t:.6g} s, although nothing external works on the scene "
                f"({self.integrator.name}); with contact, Newmark can gain energy: use "
                "integrator='newmark_implicit_contact', a smaller dt or "
                "integrator='backward_euler'",
                category=StepNoteWarning,
                logger=log,
            )

    def _magnitude(self, row: dict[str, float]) -> float:
        """The energy scale a row adds (:meth:`_check_growth`), in J."""
        values = (
            abs(self._first[0]),
            abs(row["energy_kinetic"]),
            abs(row["energy_elastic"]),
            abs(row["energy_gravity"] - self._first[1]),
        )
        return max((v for v in values if math.isfinite(v)), default=0.0)

    def _check_loss(self, row: dict[str, float], metrics: MetricsLog, t: float) -> None:
        """Note once when a closed scene loses most of its energy (``ENERGY_LOSS``; thresholds
        and how friction and damping are kept from false alarms: ``EnergyLossCheck``)."""
        parts = ("energy_kinetic", "energy_elastic", "energy_contact")
        check = self._loss
        if check.rows != len(metrics):  # the first step, or a run resumed from a checkpoint
            stored = sum(
                (np.nan_to_num(metrics.column(c)) for c in parts if c in metrics.columns),
                np.zeros(len(metrics)),
            )
            check.start(np.asarray(metrics.column("energy_total")), stored)
        stored = sum(float(np.nan_to_num(row.get(c, 0.0))) for c in parts)
        terms = ("energy_kinetic", "energy_elastic", "energy_gravity", "energy_load", *parts[2:])
        magnitude = sum(abs(float(np.nan_to_num(row.get(c, 0.0)))) for c in terms)
        note = check.check(row["energy_total"], stored, t, magnitude)
        if note is not None:
            self.notice(note, PlausibilityWarning, log)


def dissipation(sim: object) -> str:
    """What dissipates energy in a ``Simulation`` by design ("" for nothing; ``ENERGY_LOSS``
    is checked only then): a damping integrator (backward Euler, damped Newmark), friction,
    PIC, a contact that takes the approach velocity out (every strategy but ``barrier``, whose
    barrier stores the contact energy; MPM bodies meeting through the shared grid)."""
    parts = []
    if sim.strategy != "barrier":
        parts.append(f"the {sim.strategy} strategy's contact is inelastic")
    elif len(sim.model.mpm_bodies) > 1:
        parts.append("MPM bodies meet inelastically through the shared grid")
    if damps_by_design(sim.integrator):
        parts.append(f"the {sim.integrator.name} integrator damps")
    contact = sim.model.contact
    mus = [getattr(contact, "mu", 0.0) or 0.0, getattr(sim.options, "mu", 0.0) or 0.0]
    mus += [mu for *_, mu in (getattr(contact, "pair_mu", None) or ())]
    if max(mus) > 0.0:
        parts.append(f"friction, mu up to {max(mus):g}")
    if sim.transfer == "pic" and sim.model.n_particles:
        parts.append("the PIC transfer damps")
    return "; ".join(parts)


def _is_closed(model: Model) -> bool:
    """Nothing external works on the scene: no moving scripted nodes, loads or moving boundaries."""
    moving = any(
        b.prescribed_motion is not None and not isinstance(b.prescribed_motion, Fixed)
        for b in model.fem_bodies
    )
    moving_boundary = any(b.motion is not None for b in model.boundaries)
    return not (moving or moving_boundary or model.has_load)


def _shear_volume(model: Model) -> float:
    """sum mu V over the FEM cells and particles, in J (J/m in 2D): the bodies' elastic energy
    per unit squared strain (the scale of :meth:`EnergyWatch._check_growth`'s floor)."""
    total = 0.0
    for body in model.fem_bodies:  # a few bodies; vectorised over cells
        total += body.material.mu * float(model.fem_cell_volume[body.cells].sum())
    for body in model.mpm_bodies:
        total += body.material.mu * float(model.mpm_volume[body.particles].sum())
    return total
