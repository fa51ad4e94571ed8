"""Energy terms of the incremental potential; each implements the contract of ``base.Term``."""

from bfemp.terms.base import StepContext, Term, block_pattern
from bfemp.terms.elasticity import (
    ElasticityTerm,
    ElasticStencils,
    fem_cell_stencils,
    fem_elastic_groups,
    stencil_energy,
)
from bfemp.terms.external import ExternalForceTerm
from bfemp.terms.gravity import GravityTerm
from bfemp.terms.inertia import InertiaTerm

__all__ = [
    "StepContext",
    "Term",
    "block_pattern",
    "ElasticityTerm",
    "ElasticStencils",
    "fem_cell_stencils",
    "fem_elastic_groups",
    "stencil_energy",
    "ExternalForceTerm",
    "GravityTerm",
    "InertiaTerm",
]
