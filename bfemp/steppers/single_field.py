"""``"single_field"``: explicit MPM with one shared grid velocity field, FEM meeting level sets.

All MPM bodies are transferred to one grid field (the P2G over all particles), so where their
stencils overlap they share node velocities: the classic MPM "contact" (no contact algorithm, no
normals). What that does, measured on soft Neo-Hookean blocks (E = 1e4 Pa, dx = 0.05 m, 4 PPC;
``tests/bfemp/test_explicit.py``):

- bodies stick tangentially (no slip): a block sliding at v0 over a resting one drags it along
  at once, both then vibrate about v0 / 2 (frictionless contact would keep 0 and v0);
- the normal approach is stopped when the stencils overlap, up to ~2 cells before the particles
  meet (contact at a distance);
- nothing holds bodies together in tension once their stencils part: blocks meeting head-on rebound
  (restitution 0.86 at 0.2 m/s each), and with a vertical offset the no-slip interface turns part of
  the motion into opposite vertical velocities.

FEM bodies interact with nothing but the level-set boundaries (and only through their scripted
motions or free flight: level sets act on grid nodes). It is the baseline of the trade study, what
a user gets with no contact algorithm; the engine is
:class:`bfemp.steppers.explicit.ExplicitStepper` unchanged.

Linear momentum of free bodies is conserved to round-off (every internal force sums to zero over
the shared grid), APIC also conserves angular momentum to round-off for laws with a symmetric
Kirchhoff stress (Neo-Hookean; not the small-strain linear law, which is not rotation invariant).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from bfemp.steppers.capabilities import Capabilities
from bfemp.steppers.explicit import ExplicitOptions, ExplicitStepper

__all__ = ["SingleFieldOptions", "SingleFieldStepper"]


@dataclass(frozen=True, kw_only=True)
class SingleFieldOptions(ExplicitOptions):
    """Options of ``"single_field"``.

    Attributes:
        cfl_safety_fem, cfl_safety_mpm: as in ``ExplicitOptions``.
    """

    strategy: ClassVar[str] = "single_field"


class SingleFieldStepper(ExplicitStepper):
    """The ``"single_field"`` strategy (module docstring): the explicit engine, no contact."""

    name: ClassVar[str] = "single_field"
    Options: ClassVar[type[SingleFieldOptions]] = SingleFieldOptions
    #: no contact algorithm: MPM bodies share the grid field, FEM bodies meet only level sets
    capabilities: ClassVar[Capabilities] = Capabilities(
        pairs={"mpm-mpm": "grid"},
        friction=False,
        needs_contact_settings=False,
        penetration_bound_cells=None,
        penetration_note="couples nothing with a FEM body (no contact algorithm)",
    )
