"""Isotropic hyperelastic materials: parameters (Young's modulus, Poisson ratio, density).

A material is a frozen keyword-only dataclass holding physical parameters in SI units. Its
``law`` is the pointwise law object (``psi(F)``, ``P(F)``, ``dP/dF`` on batches, see
``bfemp._material_kernels``), and ``mu``, ``lam`` are the Lame parameters

    lam = E nu / ((1 + nu)(1 - 2 nu)),    mu = E / (2 (1 + nu)).

2D is plane strain per unit thickness, so the same formulas hold in 2D and 3D.

Example::

    steel = NeoHookean(E=1e8, nu=0.2, density=1000.0)
    psi = steel.law.energy_density(F, steel.mu, steel.lam)   # F (S, d, d) -> psi (S,) in Pa
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from bfemp._material_kernels import LINEAR_ELASTIC, NEO_HOOKEAN, MaterialLaw

__all__ = ["LinearElastic", "Material", "NeoHookean"]


@dataclass(frozen=True, kw_only=True)
class _IsotropicElastic:
    """Shared parameters and validation of the isotropic elastic materials.

    Fields:
        E: Young's modulus in Pa, finite and > 0.
        nu: Poisson ratio (dimensionless), in (-1, 0.5).
        density: mass density in kg/m^3 (in 2D: per unit thickness), finite and > 0.
    """

    E: float
    nu: float
    density: float

    def __post_init__(self) -> None:
        cls = type(self).__name__
        for field in ("E", "nu", "density"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ValueError(f"{cls}.{field} must be a real number, got {value!r}")
            # Store plain floats (numpy scalars in, Python floats out).
            object.__setattr__(self, field, float(value))
        if not (math.isfinite(self.E) and self.E > 0.0):
            raise ValueError(f"{cls}.E must be finite and > 0 (Pa), got {self.E}")
        if not (-1.0 < self.nu < 0.5):
            raise ValueError(f"{cls}.nu must be in (-1, 0.5), got {self.nu}")
        if not (math.isfinite(self.density) and self.density > 0.0):
            raise ValueError(f"{cls}.density must be finite and > 0 (kg/m^3), got {self.density}")

    @property
    def mu(self) -> float:
        """Shear modulus (second Lame parameter) mu = E / (2 (1 + nu)) in Pa."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lam(self) -> float:
        """First Lame parameter lam = E nu / ((1 + nu)(1 - 2 nu)) in Pa."""
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    @property
    def p_wave_speed(self) -> float:
        """Dilatational wave speed sqrt((lam + 2 mu) / density) in m/s (for CFL estimates)."""
        return math.sqrt((self.lam + 2.0 * self.mu) / self.density)


@dataclass(frozen=True, kw_only=True)
class NeoHookean(_IsotropicElastic):
    """Compressible Neo-Hookean material (paper eq. 7).

    psi(F) = mu/2 (tr(F^T F) - d) - mu log J + lam/2 (log J)^2, J = det F, in J/m^3.

    Fields: E (Pa, > 0), nu (in (-1, 0.5)), density (kg/m^3, > 0).
    """

    @property
    def name(self) -> str:
        """Registry name of the law: "neo_hookean"."""
        return "neo_hookean"

    @property
    def law(self) -> MaterialLaw:
        """The pointwise law object (energy density, first Piola stress and its derivative)."""
        return NEO_HOOKEAN


@dataclass(frozen=True, kw_only=True)
class LinearElastic(_IsotropicElastic):
    """Small-strain linear elasticity: psi = mu eps:eps + lam/2 tr(eps)^2, eps = sym(F) - I.

    Not rotation invariant: meant for small deformations and for comparisons.
    Fields: E (Pa, > 0), nu (in (-1, 0.5)), density (kg/m^3, > 0).
    """

    @property
    def name(self) -> str:
        """Registry name of the law: "linear"."""
        return "linear"

    @property
    def law(self) -> MaterialLaw:
        """The pointwise law object (energy density, first Piola stress and its derivative)."""
        return LINEAR_ELASTIC


Material = NeoHookean | LinearElastic
"""Any material accepted by the model builder."""
