"""The incremental potential of the ``barrier`` strategy: the terms a model needs, and no more.

A scene pays only for what it has (DESIGN.md): no elasticity term for cells whose every node is
scripted, no gravity or load term without gravity or loads, no barrier without a possible contact
pair (FEM facets against particles or another FEM body), no friction term when mu = 0.
"""

from __future__ import annotations

import numpy as np

from bfemp.contact.friction import FrictionTerm
from bfemp.contact.term import BarrierTerm
from bfemp.model import Model
from bfemp.mpm.elasticity import MpmElasticityTerm
from bfemp.potential import IncrementalPotential
from bfemp.terms import (
    ElasticityTerm,
    ExternalForceTerm,
    GravityTerm,
    InertiaTerm,
    fem_elastic_groups,
)

__all__ = ["build_potential", "has_contact"]


def _laws(bodies: tuple) -> dict[int, object]:
    return {id(b.material.law): b.material.law for b in bodies}


def build_potential(model: Model) -> IncrementalPotential:
    """The terms this model needs, and nothing else (a scene pays only for what it has)."""
    potentials = [
        ElasticityTerm(law, stencils, name=f"elasticity[{law.name}]")
        for law, stencils in fem_elastic_groups(model)
    ]
    for law in _laws(model.mpm_bodies).values():
        bodies = [b for b in model.mpm_bodies if b.material.law is law]
        particles = np.concatenate([np.arange(b.particles.start, b.particles.stop) for b in bodies])
        owner = model.mpm_particle_body[particles]
        mu = np.array([b.material.mu for b in model.mpm_bodies])[owner]
        lam = np.array([b.material.lam for b in model.mpm_bodies])[owner]
        potentials.append(
            MpmElasticityTerm(law, particles, mu, lam, name=f"mpm_elasticity[{law.name}]")
        )
    if model.has_gravity:
        potentials.append(GravityTerm(model.gravity))
    if model.has_load:
        potentials.append(ExternalForceTerm(model.fem_load))
    if has_contact(model):
        c = model.contact
        barrier = BarrierTerm(c.dhat, 1.0 if c.adaptive_kappa else c.kappa)
        potentials.append(barrier)
        if c.has_friction:
            potentials.append(FrictionTerm(c.mu, c.eps_v, barrier))
    return IncrementalPotential(InertiaTerm(), potentials)


def has_contact(model: Model) -> bool:
    """Contact is on and some pair can exist: FEM facets against particles or another FEM body."""
    if model.contact is None or not model.fem_bodies:
        return False
    return model.n_particles > 0 or len(model.fem_bodies) > 1
