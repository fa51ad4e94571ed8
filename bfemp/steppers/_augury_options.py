"""Options of the ``"augury"`` strategy (AUG) and the friction coefficient it takes."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from bfemp.contact.augury import KERNELS, MODES
from bfemp.steppers.explicit import ExplicitOptions

__all__ = ["AuguryOptions", "friction_coefficient"]


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
        iterations: augury iterations N >= 0 (AUG: 1; N = 0 sticks). N = 1 holds a frictionless
            slide back whatever h; N of about 30 with ``normals="facing"`` lets a block at
            mu = 0.7 creep (issue 14: design note ``measurements``, augury).
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
            at corners and edges the averaged normal is tilted and keeps the normal part of a
            sliding drag as a push: a block on a 30 degree ramp at mu = 0 barely slid).
        contact_strain: MPM particles' F takes the gradient of their contact correction (bfemp's;
            module docstring: without it a body resting on another crowds together while F
            stays near I).
        energy_guard: stop the augury iterations before an iterate with more generalised
            kinetic energy than the prediction V-bar (bfemp's; ``bfemp.contact.augury``: with
            friction and N > 1 the iterations were measured to inject energy, N = 1 never).
        cfl_safety_fem, cfl_safety_mpm: as in ``ExplicitOptions``.
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
        self.check_numbers("tau", "grid_dx", none=True)
        self.check_numbers("mu", strict=False, none=True)
        self.check_integers("iterations", "penetration_check_every", low=0)
        self.check_choices(
            mode=MODES,
            kernel=tuple(KERNELS),
            predictor=PREDICTORS,
            contact_transfer=TRANSFERS,
            region=REGIONS,
            normals=NORMALS,
        )
        self.check_flags("kinematic_foreground", "mpm_foreground", "energy_guard", "contact_strain")


def friction_coefficient(option: float | None, contact: object) -> float:
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
