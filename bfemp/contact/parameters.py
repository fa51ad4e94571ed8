"""Contact and friction parameters of a scene (``scene.set_contact``)."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from bfemp.contact.pair_friction import PairFriction
from bfemp.errors import warn_user

__all__ = ["ContactParameters", "refuse_pair_friction", "warn_mpm_pairs"]

log = logging.getLogger(__name__)


def _positive(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"set_contact: {name} must be a number, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"set_contact: {name} must be positive and finite, got {value!r}")
    return value


@dataclass(frozen=True, kw_only=True)
class ContactParameters:
    """Barrier and friction settings (paper section 5: all have a physical meaning).

    Attributes:
        dhat: contact activation distance d-hat in m (BFEMP eq. 27).
        kappa: barrier stiffness in Pa, or ``"auto"`` for an adaptive stiffness chosen from the
            elasticity and the masses (in the manner of IPC's adaptive kappa).
        mu: friction coefficient (0: no friction term is built).
        eps_v: static/sliding velocity threshold in m/s (BFEMP eq. 36).
        friction_iterations: cap of the outer lagged-friction loop (Algorithm 1); reaching it is
            reported, not silent.
        pair_mu: friction coefficients of pairs of bodies that differ from ``mu``,
            ``((code_a, code_b, mu), ...)`` in the collision set's body codes
            (``bfemp.contact.pair_friction.body_code``); ``scene.set_friction`` fills it.
    """

    dhat: float
    kappa: float | str = 1e7
    mu: float = 0.0
    eps_v: float = 1e-5
    friction_iterations: int = 20
    pair_mu: tuple[tuple[int, int, float], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "dhat", _positive("dhat", self.dhat))
        if isinstance(self.kappa, str) and self.kappa != "auto":
            raise ValueError(
                f"set_contact: kappa must be a positive barrier stiffness in Pa or the string "
                f"'auto' (adaptive), got {self.kappa!r}"
            )
        if self.kappa != "auto":
            object.__setattr__(self, "kappa", _positive("kappa", self.kappa))
        if (
            isinstance(self.mu, bool)
            or not isinstance(self.mu, int | float)
            or not (math.isfinite(self.mu) and self.mu >= 0.0)
        ):
            raise ValueError(f"set_contact: mu must be a finite number >= 0, got {self.mu!r}")
        object.__setattr__(self, "mu", float(self.mu))
        object.__setattr__(self, "eps_v", _positive("eps_v", self.eps_v))
        if (
            isinstance(self.friction_iterations, bool)
            or not isinstance(self.friction_iterations, int)
            or self.friction_iterations < 1
        ):
            raise ValueError(
                f"set_contact: friction_iterations must be an int >= 1, "
                f"got {self.friction_iterations!r}"
            )

    @property
    def adaptive_kappa(self) -> bool:
        """Whether kappa is chosen adaptively."""
        return self.kappa == "auto"

    @property
    def friction(self) -> float | PairFriction:
        """The friction coefficient: ``mu``, or a :class:`PairFriction` with per-pair values."""
        return PairFriction(self.mu, self.pair_mu) if self.pair_mu else self.mu

    @property
    def has_friction(self) -> bool:
        """Whether a friction term is needed (some pair has mu > 0)."""
        return self.mu > 0.0 or any(m > 0.0 for _, _, m in self.pair_mu)


def refuse_pair_friction(contact: ContactParameters | None, strategy: str) -> None:
    """Raise for a strategy with one friction coefficient when the scene sets pairs.

    Raises:
        ValueError: ``contact`` has ``scene.set_friction`` pairs, which ``strategy`` cannot
            honour (its own option ``mu`` is one coefficient for every contact).
    """
    if contact is not None and contact.pair_mu:
        raise ValueError(
            f"{strategy}: the scene sets friction per pair of bodies (scene.set_friction), and "
            f"{strategy} has one coefficient for every contact (its option mu); use the "
            f"'barrier' or 'two_stage' strategy, or one scene.set_contact(mu=...)"
        )


def warn_mpm_pairs(contact: ContactParameters | None, strategy: str, mpm_names: list) -> None:
    """Log a warning for ``scene.set_friction`` pairs of two MPM bodies, which ``strategy``
    (barrier contact, one grid velocity field for all particles) never brings into contact."""
    if contact is None:
        return
    unused = [(a, b) for a, b, _ in contact.pair_mu if a < 0 and b < 0]
    for a, b in unused:
        warn_user(
            f"FRICTION_UNUSED: {strategy}: the friction of MPM bodies {mpm_names[-1 - a]!r} and "
            f"{mpm_names[-1 - b]!r} (scene.set_friction) is not used: they share one grid "
            "velocity field and never meet through the barrier",
            logger=log,
        )
