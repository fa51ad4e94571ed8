"""Time integrators as parameters of one incremental potential (BFEMP eqs. 10-12, 21-22).

The Newmark family with the paper's extra alpha::

    x^{n+1} = x^n + dt v^n + alpha dt^2 ((1 - 2 beta) a^n + 2 beta a^{n+1})      (21)
    v^{n+1} = v^n + dt ((1 - gamma) a^n + gamma a^{n+1})                          (21)

x^{n+1} is the minimiser of 1/2 ||x - x_hat||_M^2 + 2 alpha beta dt^2 Psi(x) (22)
with x_hat = x^n + dt v^n + alpha (1 - 2 beta) dt^2 a^n. After the solve a^{n+1} = -M^-1 dPsi/dx
at x^{n+1} (Algorithm 2, line 14), and the velocity follows (21).

Backward Euler: alpha = 1, beta = 1/2, gamma = 1. Mid-point Newmark (trapezoidal, energy
conserving for linear problems): alpha = 1/2, beta = 1/4, gamma = 1/2.

Damped Newmark (``"newmark_damped"``, not in the paper): alpha = 1/2, gamma = 0.55,
beta = (gamma + 1/2)^2 / 4, Newmark's own dissipative member (unconditionally stable for linear
problems, damps modes with omega dt >> 1, first order in dt). Why: the trapezoidal rule is not
energy-stable for nonlinear problems, and a stiff barrier that switches on within a step pumps
energy into the contact zone's unresolved modes. It curbs the growth, it does not rule it out
(measured on colliding rings and a block hitting a plate: ``docs/guide/scenes.md``).

Newmark with implicit contact (``"newmark_implicit_contact"``, not in the paper): mid-point
Newmark for everything but contact; the barrier and friction forces enter as Newmark's
beta = 1/2, gamma = 1 member, i.e. with no memory: they are left out of a^n (so out of x_hat and
of the (1 - gamma) a^n velocity term) and weighted alpha dt^2 in BFEMP eq. 22 instead of
2 alpha beta dt^2. The step is still one minimisation,

    E(x) = 1/2 ||x - x_hat||_M^2 + 2 alpha beta dt^2 Psi(x) + alpha dt^2 (B(x) + D(x)),

and v^{n+1} = v^n + dt ((1 - gamma) a_e^n + gamma a_e^{n+1}) + dt a_c^{n+1}, with a_e the
elastic (and body-force) acceleration and a_c = -M^-1 grad(B + D). As gamma = 2 beta,
x^{n+1} - x^n = dt (v^n + v^{n+1}) / 2 still holds for every node, so the friction sliding map
and the trapezoidal kinematics are those of mid-point Newmark. The idea is that of the
contact-implicit and contact-stabilised Newmark schemes of the dynamic-contact literature
(Kane et al. 1999; Deuflhard, Krause and Ertel 2008): the trapezoidal rule carries a
contact force from one step into the next through a^n, and a stiff barrier that is on at t^n and
off at t^{n+1} (or the reverse) then pumps energy into the contact nodes' chatter at the
Nyquist frequency. Without that memory the contact impulse is implicit and dissipative (at
impact the contact nodes lose their normal approach speed, a share of the energy expected to
shrink with the boundary nodes' mass as the mesh is refined) while elastic waves keep the
trapezoidal rule's energy conservation (measured: ``docs/guide/scenes.md``).

Symplectic Euler (``"symplectic_euler"``, explicit strategies only): the explicit Newmark member
beta = 0, gamma = 1/2 (central differences, AUG eq. 32) written with half-step velocities,

    v^{n+1/2} = v^{n-1/2} + dt a(x^n),    x^{n+1} = x^n + dt v^{n+1/2},

the usual explicit USL step of MPM. The state's velocity is the half-step one (the positions
are those of central differences; kinetic energy from it is off by O(dt)). It is not an
``Integrator``: beta = 0 gives BFEMP eq. 22 a zero potential weight, so an implicit stepper handed
it would minimise inertia alone. It is an ``ExplicitIntegrator`` whose ``explicit`` is True;
implicit steppers refuse every integrator whose ``explicit`` is True, explicit ones refuse the
rest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

__all__ = [
    "BACKWARD_EULER",
    "INTEGRATOR_NAMES",
    "NEWMARK",
    "NEWMARK_DAMPED",
    "NEWMARK_IMPLICIT_CONTACT",
    "SYMPLECTIC_EULER",
    "ExplicitIntegrator",
    "Integrator",
    "integrator_from_name",
]


@dataclass(frozen=True, kw_only=True)
class Integrator:
    """Parameters ``alpha``, ``beta``, ``gamma`` of BFEMP eqs. 21-22.

    ``implicit_contact``: barrier and friction forces enter with beta = 1/2, gamma = 1 (no
    memory, weight ``alpha dt^2``; see the module docstring); needs gamma = 2 beta.
    """

    #: implicit (the solve of BFEMP eq. 22); see ``ExplicitIntegrator``
    explicit: ClassVar[bool] = False

    name: str
    alpha: float
    beta: float
    gamma: float
    implicit_contact: bool = False

    def __post_init__(self) -> None:
        if self.implicit_contact and not np.isclose(self.gamma, 2.0 * self.beta):
            raise ValueError(
                f"integrator {self.name!r}: implicit_contact needs gamma = 2 beta (so that the "
                f"contact and the elastic parts share x^{{n+1}} - x^n = dt (v^n + v^{{n+1}}) / 2), "
                f"got gamma = {self.gamma}, beta = {self.beta}"
            )

    def weight(self, dt: float) -> float:
        """The potential weight 2 alpha beta dt^2 in s^2 (BFEMP eq. 22)."""
        return 2.0 * self.alpha * self.beta * dt * dt

    def contact_weight(self, dt: float) -> float:
        """The weight in s^2 of the contact terms (barrier, friction): ``alpha dt^2`` with
        ``implicit_contact`` (beta = 1/2), else ``weight(dt)``."""
        return self.alpha * dt * dt if self.implicit_contact else self.weight(dt)

    @property
    def uses_acceleration(self) -> bool:
        """Whether a^n enters the step (x_hat or the velocity update)."""
        return self.alpha * (1.0 - 2.0 * self.beta) != 0.0 or self.gamma != 1.0

    def predict(self, x: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float) -> np.ndarray:
        """x_hat = x + dt v + alpha (1 - 2 beta) dt^2 a, same shape as ``x`` (m)."""
        return x + dt * v + self.alpha * (1.0 - 2.0 * self.beta) * dt * dt * a

    def velocity(
        self, v: np.ndarray, a_old: np.ndarray, a_new: np.ndarray, dt: float
    ) -> np.ndarray:
        """v^{n+1} = v^n + dt ((1 - gamma) a^n + gamma a^{n+1}) in m/s (BFEMP eq. 21)."""
        return v + dt * ((1.0 - self.gamma) * a_old + self.gamma * a_new)

    def acceleration(self, x_new: np.ndarray, x_hat: np.ndarray, dt: float) -> np.ndarray:
        """a^{n+1} = (x^{n+1} - x_hat) / (2 alpha beta dt^2) in m/s^2: BFEMP eq. 21 solved for
        a^{n+1}.

        The step's acceleration from its solved positions, not from the forces there: the two
        agree at the exact minimiser of BFEMP eq. 22, but Newton stops on a small increment, and
        where the Hessian is stiff (static friction: mu lambda / (eps_v dt) per contact) a small
        increment leaves a force residual r, which -M^-1 dPsi/dx would turn into a velocity
        error dt r / m with no motion behind it (a block resting on a floor with mu = 0.3,
        dt = 5e-3 s: corner particles reported 1e-3 m/s while moving at 5e-6 m/s). From the
        positions, x^{n+1} - x^n = dt v^{n+1} holds exactly under backward Euler and
        x^{n+1} - x^n = dt (v^n + v^{n+1}) / 2 under mid-point Newmark.
        """
        return (x_new - x_hat) / self.weight(dt)

    def contact_acceleration(
        self, x_new: np.ndarray, x_hat: np.ndarray, a_new: np.ndarray, dt: float
    ) -> np.ndarray:
        """With ``implicit_contact``: a_c^{n+1} = (x^{n+1} - x_hat - 2 alpha beta dt^2 a_e^{n+1})
        / (alpha dt^2) in m/s^2, the contact part of the motion given the elastic (and
        body-force) acceleration ``a_new`` from the forces: the solved positions and the
        velocity update agree exactly, as with ``acceleration``."""
        return (x_new - x_hat - self.weight(dt) * a_new) / (self.alpha * dt * dt)

    def contact_velocity(self, v: np.ndarray, a_contact: np.ndarray, dt: float) -> np.ndarray:
        """Add the implicit contact impulse: v + dt a_c^{n+1} in m/s (gamma = 1, no memory)."""
        return v + dt * a_contact


@dataclass(frozen=True, kw_only=True)
class ExplicitIntegrator:
    """An explicit time integrator (see the module docstring): no solve, a stable-step bound.

    ``beta`` and ``gamma`` name the Newmark member whose positions it reproduces.
    """

    #: explicit: only explicit strategies accept it
    explicit: ClassVar[bool] = True

    name: str
    beta: float = 0.0
    gamma: float = 0.5

    def velocity(self, v: np.ndarray, a: np.ndarray, dt: float) -> np.ndarray:
        """v^{n+1/2} = v^{n-1/2} + dt a(x^n) in m/s."""
        return v + dt * a

    def position(self, x: np.ndarray, v_half: np.ndarray, dt: float) -> np.ndarray:
        """x^{n+1} = x^n + dt v^{n+1/2} in m."""
        return x + dt * v_half


BACKWARD_EULER = Integrator(name="backward_euler", alpha=1.0, beta=0.5, gamma=1.0)
NEWMARK = Integrator(name="newmark", alpha=0.5, beta=0.25, gamma=0.5)
NEWMARK_DAMPED = Integrator(name="newmark_damped", alpha=0.5, beta=0.25 * 1.05**2, gamma=0.55)
NEWMARK_IMPLICIT_CONTACT = Integrator(
    name="newmark_implicit_contact", alpha=0.5, beta=0.25, gamma=0.5, implicit_contact=True
)

SYMPLECTIC_EULER = ExplicitIntegrator(name="symplectic_euler")

_BY_NAME = {
    i.name: i
    for i in (BACKWARD_EULER, NEWMARK, NEWMARK_DAMPED, NEWMARK_IMPLICIT_CONTACT, SYMPLECTIC_EULER)
}
#: the names ``integrator_from_name`` (and the scene file's ``integrator``) accept
INTEGRATOR_NAMES = tuple(_BY_NAME)


def integrator_from_name(
    name: str | Integrator | ExplicitIntegrator,
) -> Integrator | ExplicitIntegrator:
    """``"backward_euler"``, ``"newmark"``, ``"newmark_damped"``,
    ``"newmark_implicit_contact"``, ``"symplectic_euler"`` (explicit strategies only), or an
    ``Integrator`` / ``ExplicitIntegrator``."""
    if isinstance(name, Integrator | ExplicitIntegrator):
        return name
    try:
        return _BY_NAME[name]
    except KeyError:
        raise ValueError(f"integrator must be one of {sorted(_BY_NAME)}, got {name!r}") from None
