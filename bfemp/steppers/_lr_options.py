"""Options of the ``"lr"`` strategy (LR) and its stated penetration bound."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from bfemp.mpm.xpic import XPIC_VARIANTS
from bfemp.steppers.explicit import ExplicitOptions

__all__ = ["LROptions"]


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
            correction's; with 1 it is zero). 1 by default: under c1 the first correction reaches
            neither particles nor FEM nodes (LR eq. 33), so a lasting contact keeps approaching
            (measured, issue 40: design note ``measurements``, lr).
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
            choice (1e-8), an option, not LR's: it leaves nearly massless fields uncorrected
            (measured, issue 40: design note ``measurements``, lr). ``interface="perfect"``
            always counts every material with mass.
        penalty: LR penalty on the normal components, times dx^2 (LR: 1e-7).
        lr_tol: LR stop criterion 1 - n_new . n_old (LR: 1e-5).
        lr_max_iterations: cap of the Gauss-Newton iterations (LR: 15).
        thin_cloud: in cells; the LR normal loses its components along directions in which the
            node's whole point cloud is thinner than this (standard deviation), 0 disables
            (bfemp's, ``bfemp.contact.lr.lr_planes``: one particle column per block gave sideways
            normals on ``lr_compression``; design note ``measurements``, lr).
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
        self.check_choices(
            law=LAWS,
            interface=INTERFACES,
            detector=DETECTORS,
            lump=LUMPS,
            xpic_variant=XPIC_VARIANTS,
            contact_force=CONTACT_FORCES,
        )
        if self.corrections not in (1, 2) or isinstance(self.corrections, bool):
            raise ValueError(f"{name}.corrections must be 1 or 2, got {self.corrections!r}")
        self.check_integers("lr_max_iterations", low=1)
        if self.xpic_order is not None:
            self.check_integers("xpic_order", low=1)
        self.check_numbers("mu", strict=False, none=True)
        self.check_numbers("cp_offset", "mass_fraction", "penalty", "thin_cloud", strict=False)
        self.check_numbers("lr_tol")
        if self.mass_fraction >= 0.5:
            raise ValueError(f"{name}.mass_fraction must be below 0.5, got {self.mass_fraction}")
