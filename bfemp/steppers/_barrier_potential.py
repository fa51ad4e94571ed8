"""The incremental potential of the ``barrier`` strategy: the terms a model needs, and no more.

A scene pays only for what it has (ARCHITECTURE.md): no elasticity term for cells whose every node
is scripted, no gravity or load term without gravity or loads, no barrier without a possible contact
pair (FEM facets against particles or another FEM body), no friction term when mu = 0.
"""

from __future__ import annotations

import numpy as np

from bfemp.contact.friction import FrictionTerm
from bfemp.contact.parameters import warn_mpm_pairs
from bfemp.contact.term import BarrierTerm
from bfemp.diagnostics import contact_forces_between_bodies
from bfemp.model import Model
from bfemp.mpm.elasticity import MpmElasticityTerm
from bfemp.potential import IncrementalPotential
from bfemp.steppers.base import ContactView, finite_or_nan
from bfemp.terms import (
    ElasticityTerm,
    ExternalForceTerm,
    GravityTerm,
    InertiaTerm,
    fem_elastic_groups,
)

__all__ = ["build_potential", "contact_view", "has_contact"]


def build_potential(model: Model) -> IncrementalPotential:
    """The terms this model needs, and nothing else (a scene pays only for what it has)."""
    potentials = [
        ElasticityTerm(law, stencils, name=f"elasticity[{law.name}]")
        for law, stencils in fem_elastic_groups(model)
    ]
    for law in {id(b.material.law): b.material.law for b in model.mpm_bodies}.values():
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
            warn_mpm_pairs(c, "barrier", [b.name for b in model.mpm_bodies])
            potentials.append(FrictionTerm(c.friction, c.eps_v, barrier))
    return IncrementalPotential(InertiaTerm(), potentials)


def has_contact(model: Model) -> bool:
    """Contact is on and some pair can exist: FEM facets against particles or another FEM body."""
    if model.contact is None or not model.fem_bodies:
        return False
    return model.n_particles > 0 or len(model.fem_bodies) > 1


def contact_view(model: Model, barrier: BarrierTerm | None) -> ContactView:
    """What ``barrier`` knows at its current iterate (the end of the last step).

    Forces in N (N/m in 2D): on every FEM node (zero off the boundary) and every particle, and
    per pair of bodies; all zero (and energy 0) before the first step; energy NaN without a
    barrier.
    """
    kwargs = {"parameters": {"kappa": float(barrier.kappa)}} if barrier is not None else {}
    view = ContactView.empty(model.n_fem_nodes, model.n_particles, model.dim, **kwargs)
    if barrier is None or barrier.pairs is None:
        energy = 0.0 if barrier is not None else np.nan
        return ContactView(**{**view.__dict__, "energy": energy})
    cs = barrier.collisions
    pair_forces = barrier.pair_point_forces()
    forces = np.zeros((cs.n_points, model.dim))
    for pts, f in pair_forces.values():
        np.add.at(forces, pts.reshape(-1), f.reshape(-1, model.dim))
    nf = cs.n_fem_points
    np.add.at(view.fem_forces, cs.nodes[:nf, 0], forces[:nf])
    view.particle_forces[cs.particle_index[nf:]] = forces[nf:]
    return ContactView(
        view.fem_forces,
        view.particle_forces,
        min_distance=finite_or_nan(barrier.min_distance()),
        pairs=int(barrier.pairs.n_pairs),
        energy=float(barrier.value(None)),
        parameters={"kappa": float(barrier.kappa)},
        body_forces=contact_forces_between_bodies(model, cs.point_body, pair_forces),
    )
