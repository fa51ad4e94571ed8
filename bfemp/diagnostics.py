"""Physical diagnostics of a state: energies, linear and angular momentum (FEM + MPM).

2D quantities are per unit thickness (J/m, kg m/s/m). With APIC each particle carries, besides
1/2 m_p |v_p|^2, the kinetic energy of its affine velocity 1/2 m_p tr(C_p D_p C_p^T), and its spin
m_p eps : (C_p D_p)^T adds to the angular momentum (D_p = dx^2/4 I for quadratic B-splines): these
are the quantities APIC transfers conserve.

Per body (:func:`per_body_energies`, :func:`per_body_momenta`) the same sums are split by the
body that owns each node, cell or particle; they add up to the totals. Contact forces between
bodies (:func:`contact_forces_between_bodies`) are the barrier's per-pair point forces summed by
the bodies on either side of each pair, so that the force on a from b is minus that on b from a
(each pair's forces sum to zero).
"""

from __future__ import annotations

import math

import numpy as np

from bfemp.model import Model
from bfemp.state import State
from bfemp.terms.elasticity import fem_elastic_groups, stencil_energy

__all__ = [
    "angular_momentum",
    "body_metrics",
    "contact_forces_between_bodies",
    "energy_columns",
    "fem_elastic_energy",
    "gravity_energy",
    "kinetic_energy",
    "linear_momentum",
    "load_energy",
    "momentum_columns",
    "mpm_body_elastic_energies",
    "mpm_elastic_energy",
    "per_body_energies",
    "per_body_momenta",
    "report_columns",
]


def _sq(v: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", v, v)


def kinetic_energy(model: Model, state: State, transfer: str = "apic") -> float:
    """1/2 sum m |v|^2 in J over FEM nodes and particles (+ the APIC affine part)."""
    total = np.dot(model.fem_mass, _sq(state.fem_v)) + np.dot(model.mpm_mass, _sq(state.mpm_v))
    if model.n_particles and transfer == "apic":
        c2 = np.einsum("pij,pij->p", state.mpm_C, state.mpm_C)
        total += model.grid.dx**2 / 4.0 * np.dot(model.mpm_mass, c2)
    return 0.5 * float(total)


def energy_columns(
    model: Model,
    state: State,
    transfer: str = "apic",
    groups: list | None = None,
    contact: float | None = None,
    mpm_elastic: list[float] | None = None,
) -> dict[str, float]:
    """``energy_kinetic``, ``_elastic``, ``_gravity`` (``_load`` where loaded, ``_contact``
    where ``contact`` is given) and ``_total`` in J (J/m in 2D) of ``state``, as
    ``Simulation.energies`` reports them; a NaN contact energy (a strategy without one) is
    left out of the total. ``groups``: as in :func:`fem_elastic_energy`; ``mpm_elastic``:
    :func:`mpm_body_elastic_energies` where the caller has them."""
    elastic = fem_elastic_energy(model, state, groups)
    if model.n_particles:
        elastic += mpm_elastic_energy(model, state, mpm_elastic)
    out = {
        "energy_kinetic": kinetic_energy(model, state, transfer),
        "energy_elastic": float(elastic),
        "energy_gravity": gravity_energy(model, state),
    }
    if model.has_load:
        out["energy_load"] = load_energy(model, state)
    if contact is not None:
        out["energy_contact"] = contact
    out["energy_total"] = sum(v for v in out.values() if not math.isnan(v))
    return out


def gravity_energy(model: Model, state: State) -> float:
    """-sum m g . x in J over FEM nodes and particles (zero reference at the origin)."""
    return -float(
        np.dot(model.fem_mass, state.fem_x @ model.gravity)
        + np.dot(model.mpm_mass, state.mpm_x @ model.gravity)
    )


def load_energy(model: Model, state: State) -> float:
    """-sum_i f_i . x_i in J for the constant external nodal forces."""
    return -float(np.sum(model.fem_load * state.fem_x))


def fem_elastic_energy(model: Model, state: State, groups: list | None = None) -> float:
    """sum_e V_e psi(F_e) in J (J/m in 2D) over the FEM cells that can deform.

    Cells whose every node is scripted are left out (scripted motions are rigid: no energy).
    ``groups``: ``bfemp.terms.fem_elastic_groups(model)``, computed here when None (pass it to
    evaluate many states of one model).
    """
    groups = fem_elastic_groups(model) if groups is None else groups
    return float(sum(stencil_energy(law, st, state.fem_x) for law, st in groups))


def mpm_elastic_energy(model: Model, state: State, per_body: list[float] | None = None) -> float:
    """sum_p V_p^0 psi(F_p) in J over the particles (``per_body``: the bodies' shares from
    :func:`mpm_body_elastic_energies`, computed here when None)."""
    return sum(mpm_body_elastic_energies(model, state) if per_body is None else per_body, 0.0)


def mpm_body_elastic_energies(model: Model, state: State) -> list[float]:
    """sum_p V_p^0 psi(F_p) in J over each MPM body's particles, in body order."""
    out = []
    for body in model.mpm_bodies:  # a few bodies; vectorised over particles
        sl = body.particles
        n = body.n_particles
        mat = body.material
        psi = mat.law.energy_density(state.mpm_F[sl], np.full(n, mat.mu), np.full(n, mat.lam))
        out.append(float(np.dot(model.mpm_volume[sl], psi)))
    return out


def linear_momentum(model: Model, state: State) -> np.ndarray:
    """sum m v ``(d,)`` in kg m/s over FEM nodes and particles."""
    return model.fem_mass @ state.fem_v + model.mpm_mass @ state.mpm_v


def _cross(x: np.ndarray, v: np.ndarray, m: np.ndarray) -> np.ndarray:
    if x.shape[1] == 2:
        return np.array([float(np.dot(m, x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]))])
    return m @ np.cross(x, v)


def angular_momentum(model: Model, state: State, transfer: str = "apic") -> np.ndarray:
    """sum m x x v about the origin, ``(1,)`` (z) in 2D or ``(3,)`` in 3D, kg m^2/s.

    With APIC the particles' spin m_p eps : (C_p D_p)^T is included; the augury matrices
    ``state.carried["aug_B"]`` (FEM nodes) and ``["aug_Bp"]`` (particles), where present, add
    their spin m eps : B^T whatever ``transfer`` (AUG eq. 36: the quantity H_APIC conserves).
    """
    total = _cross(state.fem_x, state.fem_v, model.fem_mass)
    for name, m in (("aug_B", model.fem_mass), ("aug_Bp", model.mpm_mass)):
        B = state.carried.get(name, np.zeros((0, 2, 2)))
        if B.shape[0] and B.shape[0] == m.shape[0]:
            total = total + _spin(B, m)
    if model.n_particles:
        total = total + _cross(state.mpm_x, state.mpm_v, model.mpm_mass)
        if transfer == "apic":
            B = state.mpm_C * (model.grid.dx**2 / 4.0)  # C D with D = dx^2/4 I
            total = total + _spin(B, model.mpm_mass)
    return total


def _spin(B: np.ndarray, m: np.ndarray) -> np.ndarray:
    """sum_p m_p eps : B_p^T, ``(1,)`` in 2D or ``(3,)`` in 3D (B = C D in m^2/s)."""
    if B.shape[1] == 2:
        return np.array([float(m @ (B[:, 1, 0] - B[:, 0, 1]))])
    spin = np.stack(
        [B[:, 2, 1] - B[:, 1, 2], B[:, 0, 2] - B[:, 2, 0], B[:, 1, 0] - B[:, 0, 1]], axis=1
    )
    return m @ spin


def body_names(model: Model) -> list[str]:
    """Body names in the order used here: FEM bodies, then MPM bodies."""
    return [b.name for b in model.fem_bodies] + [b.name for b in model.mpm_bodies]


def per_body_energies(
    model: Model, state: State, transfer: str = "apic", mpm_elastic: list[float] | None = None
) -> dict[str, dict[str, float]]:
    """Kinetic, elastic and gravitational energy of each body, in J (J/m in 2D).

    Returns ``{body name: {"kinetic": ..., "elastic": ..., "gravity": ...}}``; summed over the
    bodies these are :func:`kinetic_energy`, the elastic energy (FEM cells + particles) and
    :func:`gravity_energy`. ``mpm_elastic``: :func:`mpm_body_elastic_energies` of ``state``
    where the caller has them (a metrics row: the particles' energy is then evaluated once).
    """
    if mpm_elastic is None:
        mpm_elastic = mpm_body_elastic_energies(model, state)
    out: dict[str, dict[str, float]] = {}
    if model.fem_bodies:
        x = state.fem_x[model.fem_cells]  # (M, d+1, d)
        F = np.einsum("mai,maj->mij", x, model.fem_cell_grad)
        kin = 0.5 * model.fem_mass * _sq(state.fem_v)
        grav = -model.fem_mass * (state.fem_x @ model.gravity)
    for body in model.fem_bodies:  # a few bodies; vectorised over nodes and cells
        mat, cells = body.material, body.cells
        m = cells.stop - cells.start
        psi = mat.law.energy_density(F[cells], np.full(m, mat.mu), np.full(m, mat.lam))
        out[body.name] = {
            "kinetic": float(kin[body.nodes].sum()),
            "elastic": float(np.dot(model.fem_cell_volume[cells], psi)),
            "gravity": float(grav[body.nodes].sum()),
        }
    if model.mpm_bodies:
        kin = 0.5 * model.mpm_mass * _sq(state.mpm_v)
        if transfer == "apic":
            c2 = np.einsum("pij,pij->p", state.mpm_C, state.mpm_C)
            kin = kin + 0.5 * model.grid.dx**2 / 4.0 * model.mpm_mass * c2
        grav = -model.mpm_mass * (state.mpm_x @ model.gravity)
    for body, elastic in zip(model.mpm_bodies, mpm_elastic, strict=True):
        sl = body.particles
        out[body.name] = {
            "kinetic": float(kin[sl].sum()),
            "elastic": elastic,
            "gravity": float(grav[sl].sum()),
        }
    return out


def per_body_momenta(model: Model, state: State) -> dict[str, np.ndarray]:
    """Linear momentum ``(d,)`` in kg m/s (per m in 2D) of each body; they sum to
    :func:`linear_momentum`."""
    out = {b.name: model.fem_mass[b.nodes] @ state.fem_v[b.nodes] for b in model.fem_bodies}
    for b in model.mpm_bodies:
        out[b.name] = model.mpm_mass[b.particles] @ state.mpm_v[b.particles]
    return out


def contact_forces_between_bodies(
    model: Model,
    point_body: np.ndarray,
    pair_forces: dict[str, tuple[np.ndarray, np.ndarray]],
) -> np.ndarray:
    """Total contact force ``(B, B, d)`` in N (N/m in 2D): ``[a, b]`` on body a from body b.

    Args:
        model: the model (B = FEM bodies + MPM bodies, in :func:`body_names` order).
        point_body: owning body of each collision point ``(C,)``: FEM bodies 0.., MPM bodies
            -1 - index (``CollisionSet.point_body``).
        pair_forces: kind -> ``(points (n, m), forces (n, m, d))`` of the active pairs
            (``ContactTerm.pair_point_forces()``): the point side is point 0 (point-point,
            point-edge, point-triangle) or points 0, 1 (edge-edge); the other side the rest.
    """
    nf = len(model.fem_bodies)
    n_bodies = nf + len(model.mpm_bodies)
    point_body = np.asarray(point_body)
    body = np.where(point_body >= 0, point_body, nf - 1 - point_body)
    out = np.zeros((n_bodies, n_bodies, model.dim))
    for kind, (pts, forces) in pair_forces.items():
        split = 2 if kind == "ee" else 1  # points of the first side
        a, b = body[pts[:, 0]], body[pts[:, -1]]
        np.add.at(out, (a, b), forces[:, :split].sum(axis=1))
        np.add.at(out, (b, a), forces[:, split:].sum(axis=1))
    return out


def body_metrics(
    model: Model,
    state: State,
    transfer: str = "apic",
    body_forces: np.ndarray | None = None,
    mpm_elastic: list[float] | None = None,
) -> dict[str, float]:
    """Metrics columns per body and per pair of bodies (see the README for the names).

    ``body.NAME.energy_kinetic`` / ``_elastic`` / ``_gravity`` (J), ``body.NAME.momentum_x``
    ... (kg m/s), and in a scene with contact ``contact_force.A.B_x`` ... (N): the force on
    body A from body B, for every ordered pair with a FEM body in it (particles never touch
    particles), from ``body_forces (B, B, d)`` (``ContactView.body_forces``; None: zeros).
    2D values are per unit thickness. ``mpm_elastic``: as in :func:`per_body_energies`.
    """
    axes = "xyz"[: model.dim]
    row: dict[str, float] = {}
    for name, e in per_body_energies(model, state, transfer, mpm_elastic).items():
        for key, value in e.items():
            row[f"body.{name}.energy_{key}"] = value
    for name, p in per_body_momenta(model, state).items():
        for k, c in enumerate(axes):
            row[f"body.{name}.momentum_{c}"] = float(p[k])
    if model.contact is None:
        return row
    names = body_names(model)
    nf = len(model.fem_bodies)
    forces = np.zeros((len(names), len(names), model.dim)) if body_forces is None else body_forces
    for a, name_a in enumerate(names):
        for b, name_b in enumerate(names):
            if a != b and (a < nf or b < nf):
                for k, c in enumerate(axes):
                    row[f"contact_force.{name_a}.{name_b}_{c}"] = float(forces[a, b, k])
    return row


def momentum_columns(model: Model, state: State, transfer: str = "apic") -> dict[str, float]:
    """Metrics columns ``momentum_x``... (kg m/s) and ``angular_momentum_z`` (2D) or
    ``angular_momentum_x``... (3D) in kg m^2/s, of the whole scene."""
    axes = "xyz"
    row = {f"momentum_{axes[k]}": float(p) for k, p in enumerate(linear_momentum(model, state))}
    angular = angular_momentum(model, state, transfer)
    for k, value in enumerate(angular):
        row[f"angular_momentum_{'z' if angular.size == 1 else axes[k]}"] = float(value)
    return row


def report_columns(report: object, contact: object | None) -> dict[str, float]:
    """Metrics columns of a step's ``StepReport``: iterations, residual, phase seconds, and
    with ``contact`` (the stepper's ``ContactView``, None without contact) the contact ones."""
    row = {f"iterations_{name}": count for name, count in report.iterations.items()}
    row["residual"] = report.residual
    if contact is not None:
        row["min_distance"] = report.min_distance
        row["contact_pairs"] = report.contact_pairs
        row.update(contact.parameters)
    row.update({f"time_{phase}": seconds for phase, seconds in report.timings.items()})
    return row
