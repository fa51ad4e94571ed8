"""Isotropic hyperelastic materials: parameters (Young's modulus, Poisson ratio, density).

A material is a frozen keyword-only dataclass holding physical parameters in SI units. Its
``law`` is the pointwise law object (``psi(F)``, ``P(F)``, ``dP/dF`` on batches, see
``bfemp._material_kernels``), and ``mu``, ``lam`` are the Lame parameters

    lam = E nu / ((1 + nu)(1 - 2 nu)),    mu = E / (2 (1 + nu)).

2D is plane strain per unit thickness, so the same formulas hold in 2D and 3D.

``BulkShearHyperelastic(K=..., G=..., density=...)`` (LR eq. 18) is given by its bulk and shear
moduli instead; it exposes the same ``mu``, ``lam``, ``E``, ``nu``, ``p_wave_speed``, derived
from K and G (mu = G, lam = K - 2 G / 3).

Example::

    steel = NeoHookean(E=1e8, nu=0.2, density=1000.0)
    psi = steel.law.energy_density(F, steel.mu, steel.lam)   # F (S, d, d) -> psi (S,) in Pa
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from bfemp._bulk_shear_kernels import BULK_SHEAR
from bfemp._material_kernels import LINEAR_ELASTIC, NEO_HOOKEAN, MaterialLaw

__all__ = ["BulkShearHyperelastic", "LinearElastic", "Material", "NeoHookean"]


def _real_field(cls: str, field: str, value: object) -> float:
    """``value`` as a float; ``ValueError`` naming ``cls.field`` if it is not a real number."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{cls}.{field} must be a real number, got {value!r}")
    return float(value)


class _Law:
    """What every material shares: its pointwise law object ``law`` (energy density, first
    Piola stress and its derivative), set by each class, and what follows from it."""

    law: ClassVar[MaterialLaw]

    @property
    def name(self) -> str:
        """Registry name of the law ("neo_hookean", "linear", "bulk_shear")."""
        return self.law.name

    def cauchy_stress(self, F: np.ndarray) -> np.ndarray:
        """Cauchy stress (S, d, d) in Pa of deformation gradients F (S, d, d) (2D: in-plane)."""
        return self.law.cauchy_stress(F, self.mu, self.lam)


@dataclass(frozen=True, kw_only=True)
class _IsotropicElastic(_Law):
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
            # Store plain floats (numpy scalars in, Python floats out).
            object.__setattr__(self, field, _real_field(cls, field, getattr(self, field)))
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
    """Compressible Neo-Hookean material (BFEMP eq. 7).

    psi(F) = mu/2 (tr(F^T F) - d) - mu log J + lam/2 (log J)^2, J = det F, in J/m^3.

    Fields: E (Pa, > 0), nu (in (-1, 0.5)), density (kg/m^3, > 0).
    """

    law: ClassVar[MaterialLaw] = NEO_HOOKEAN


@dataclass(frozen=True, kw_only=True)
class LinearElastic(_IsotropicElastic):
    """Small-strain linear elasticity: psi = mu eps:eps + lam/2 tr(eps)^2, eps = sym(F) - I.

    Not rotation invariant: meant for small deformations and for comparisons.
    Fields: E (Pa, > 0), nu (in (-1, 0.5)), density (kg/m^3, > 0).
    """

    law: ClassVar[MaterialLaw] = LINEAR_ELASTIC


@dataclass(frozen=True, kw_only=True)
class BulkShearHyperelastic(_Law):
    """The hyperelastic law of LR eq. (18), given by its bulk and shear moduli.

    W(F) = G/2 (I1 J^{-2/3} - 3) + K/2 (1/2 (J^2 - 1) - ln J) in J/m^3, I1 = tr(F^T F), J = det F;
    Cauchy stress G J^{-5/3} dev(F F^T) + K/2 (J - 1/J) I. 2D is plane strain with the 3D
    invariants of diag(F, 1). At small strain it is linear elasticity with these K and G.

    Fields:
        K: bulk modulus in Pa, finite and > 0.
        G: shear modulus in Pa, finite and > 0.
        density: mass density in kg/m^3 (in 2D: per unit thickness), finite and > 0.

    The derived ``mu``, ``lam``, ``E``, ``nu`` are the 3D (and plane-strain) isotropic constants
    with the same small-strain response, so this material fits wherever the others do.
    """

    K: float
    G: float
    density: float

    def __post_init__(self) -> None:
        cls = type(self).__name__
        units = {"K": "Pa", "G": "Pa", "density": "kg/m^3"}
        for field, unit in units.items():
            value = _real_field(cls, field, getattr(self, field))
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{cls}.{field} must be finite and > 0 ({unit}), got {value}")
            object.__setattr__(self, field, value)

    law: ClassVar[MaterialLaw] = BULK_SHEAR

    @property
    def mu(self) -> float:
        """Shear modulus mu = G in Pa."""
        return self.G

    @property
    def lam(self) -> float:
        """First Lame parameter lam = K - 2 G / 3 in Pa (negative when nu < 0)."""
        return self.K - 2.0 * self.G / 3.0

    @property
    def E(self) -> float:
        """Young's modulus E = 9 K G / (3 K + G) in Pa."""
        return 9.0 * self.K * self.G / (3.0 * self.K + self.G)

    @property
    def nu(self) -> float:
        """Poisson ratio nu = (3 K - 2 G) / (2 (3 K + G)), in (-1, 0.5)."""
        return (3.0 * self.K - 2.0 * self.G) / (2.0 * (3.0 * self.K + self.G))

    @property
    def p_wave_speed(self) -> float:
        """Dilatational wave speed sqrt((K + 4 G / 3) / density) in m/s (for CFL estimates)."""
        return math.sqrt((self.K + 4.0 * self.G / 3.0) / self.density)

    @property
    def bulk_wave_speed(self) -> float:
        """Bulk sound speed sqrt(K / density) in m/s (LR's "wave speed", spec L-P2)."""
        return math.sqrt(self.K / self.density)


Material = NeoHookean | LinearElastic | BulkShearHyperelastic
"""Any material accepted by the model builder."""
