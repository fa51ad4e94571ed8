"""The grid detectors LR compares its logistic regression with (``bfemp.contact.lr``): the mass
gradient and "average gradient" (AG) normals (LR eqs. 11, 13) and the "contact position" (CP)
separation with a constant offset (LR eq. 16), from per-material grid mass moments.
"""

from __future__ import annotations

import numpy as np

from bfemp.contact._lr_args import contact_rows, dimension, float_array, grid_args
from bfemp.contact._lr_grid_kernels import mass_gradients
from bfemp.mpm._multimaterial_kernels import mass_moments

__all__ = [
    "CP_OFFSET_CELLS",
    "ag_normals",
    "cp_separation",
    "mass_gradient_normals",
    "material_mass_moments",
]

CP_OFFSET_CELLS = 0.8  # LR section 2.3: delta_c = 0.8 cells (calibrated for GIMP, L-P3)


def mass_gradient_normals(
    nodes: np.ndarray,
    grads: np.ndarray,
    mass: np.ndarray,
    material: np.ndarray,
    n_nodes: int,
    n_materials: int,
) -> np.ndarray:
    """Per-material grid mass gradients grad m_i^alpha = sum_{p in alpha} m_p grad w_ip
    ``(n_materials, n_nodes, d)`` in kg/m (LR eq. 11 with m_p for V_p: pass particle volumes as
    ``mass`` for the paper's volume gradient, areas for its 2D area gradient). For one material
    it points out of the material (LR after LR eq. 12: ||g|| n^alpha = g, n^alpha outward).

    Args:
        nodes: stencil node indices ``(P, S)`` int, -1 = none.
        grads: weight gradients grad w_ip ``(P, S, d)`` in 1/m.
        mass: particle masses ``(P,)`` in kg (or volumes, areas).
        material: material of each particle ``(P,)`` int in [0, n_materials).
        n_nodes, n_materials: sizes of the output.
    """
    mass = float_array("mass", mass, (None,))
    n_p = mass.shape[0]
    nodes, material = grid_args(nodes, n_nodes, material, n_materials, n_p)
    grads = float_array("grads", grads, (n_p, nodes.shape[1], None))
    dimension("grads", grads)
    return mass_gradients(nodes, grads, mass, material, int(n_nodes), int(n_materials))


def material_mass_moments(
    nodes: np.ndarray,
    weights: np.ndarray,
    mass: np.ndarray,
    x: np.ndarray,
    material: np.ndarray,
    n_nodes: int,
    n_materials: int,
) -> np.ndarray:
    """Per-material first mass moments sum_{p in alpha} w_ip m_p x_p ``(n_materials, n_nodes,
    d)`` in kg m; divided by m_i^alpha they are the extrapolated positions x^alpha = S^+alpha X
    of LR eq. 11 that ``cp_separation`` uses.

    Args:
        nodes: stencil node indices ``(P, S)`` int, -1 = none.
        weights: w_ip ``(P, S)``.
        mass: particle masses ``(P,)`` in kg.
        x: particle positions ``(P, d)`` in m.
        material: ``(P,)`` int in [0, n_materials).
        n_nodes, n_materials: sizes of the output.
    """
    mass = float_array("mass", mass, (None,))
    n_p = mass.shape[0]
    nodes, material = grid_args(nodes, n_nodes, material, n_materials, n_p)
    weights = float_array("weights", weights, nodes.shape)
    x = float_array("x", x, (n_p, None))
    dimension("x", x)
    return mass_moments(nodes, weights, mass, x, material, int(n_nodes), int(n_materials))


def pair_args(
    name: str, node: object, alpha: object, beta: object, n_materials: int, n_nodes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    node, alpha, beta = contact_rows(name, node, alpha, beta, n_nodes)
    if node.size:
        for label, a in (("alpha", alpha), ("beta", beta)):
            if a.min() < 0 or a.max() >= n_materials:
                raise ValueError(f"{name}: {label} must be in [0, {n_materials})")
        if np.any(alpha == beta):
            raise ValueError(
                f"{name}: alpha and beta must differ (row {int(np.argmax(alpha == beta))})"
            )
    return node, alpha, beta


def ag_normals(
    mass_gradients: np.ndarray, node: np.ndarray, alpha: np.ndarray, beta: np.ndarray
) -> np.ndarray:
    """The "average gradient" (AG) normals ``(C, d)`` from alpha to beta (LR eq. 13):
    n = (g^alpha - g^beta) / ||g^alpha - g^beta|| at the contact nodes ``node (C,)``, g from
    ``mass_gradient_normals`` ``(M, G, d)`` (each g points out of its material, so -g^beta
    points into beta). A node where the difference vanishes gets a zero row (``contact_momentum``
    then finds no approach, d_n = 0, and applies no correction).
    """
    g = float_array("mass_gradients", mass_gradients, (None, None, None))
    dimension("mass_gradients", g)
    node, alpha, beta = pair_args("ag_normals", node, alpha, beta, g.shape[0], g.shape[1])
    n = g[alpha, node] - g[beta, node]
    length = np.linalg.norm(n, axis=1)
    out = np.zeros_like(n)
    ok = length > 0.0
    out[ok] = n[ok] / length[ok, None]
    return out


def cp_separation(
    node_x: np.ndarray,
    node: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    mass: np.ndarray,
    moments: np.ndarray,
    normal: np.ndarray,
    offset_cells: float,
    dx: float,
) -> np.ndarray:
    """The "contact position" separation ``(C,)`` in m with a constant offset (LR eq. 16):
    ((x^beta - x_i) - (x^alpha - x_i)) . n - offset_cells dx, x^alpha = moments / m^alpha the
    extrapolated centre of mass of alpha's particles at the node (LR eq. 11, S^+alpha X). Contact
    by LR eq. 16 is ``cp_separation < 0`` (``contact_momentum(..., detector="cp")``); LR's
    "CP = 0.8" is ``offset_cells = CP_OFFSET_CELLS`` (0.8, calibrated for GIMP with 2 PPC: L-P3).

    Why centre-of-mass positions: LR eq. 16 is stated in the extrapolated particle positions
    x^alpha = S^+alpha X (LR eq. 11); these need the first mass moments, which the grid momenta
    and masses alone do not give (``material_mass_moments``).

    Args:
        node_x: positions of the C contact nodes ``(C, d)`` in m.
        node: their grid indices ``(C,)`` int into the G grid nodes.
        alpha, beta: the two materials at each node ``(C,)`` int.
        mass: per-material grid masses m_i^alpha ``(M, G)`` in kg (> 0 at the pairs).
        moments: ``material_mass_moments`` ``(M, G, d)`` in kg m.
        normal: unit normals ``(C, d)`` from alpha to beta.
        offset_cells: delta_c in cells.
        dx: grid spacing in m.
    """
    node_x = float_array("node_x", node_x, (None, None))
    n_c, d = node_x.shape
    dimension("node_x", node_x)
    mass = float_array("mass", mass, (None, None))
    moments = float_array("moments", moments, (mass.shape[0], mass.shape[1], d))
    normal = float_array("normal", normal, (n_c, d))
    node, alpha, beta = pair_args("cp_separation", node, alpha, beta, *mass.shape)
    if node.shape != (n_c,):
        raise ValueError(f"cp_separation: node must have shape ({n_c},), got {node.shape}")
    if not (np.isfinite(dx) and dx > 0.0):
        raise ValueError(f"cp_separation: dx must be > 0, got {dx}")
    if not np.isfinite(offset_cells):
        raise ValueError(f"cp_separation: offset_cells must be finite, got {offset_cells}")
    m_a = mass[alpha, node]
    m_b = mass[beta, node]
    if np.any(m_a <= 0.0) or np.any(m_b <= 0.0):
        bad = np.flatnonzero((m_a <= 0.0) | (m_b <= 0.0))
        raise ValueError(
            f"cp_separation: a material has no mass at contact rows {bad[:10].tolist()}"
        )
    x_a = moments[alpha, node] / m_a[:, None] - node_x
    x_b = moments[beta, node] / m_b[:, None] - node_x
    return np.einsum("cd,cd->c", x_b - x_a, normal) - float(offset_cells) * float(dx)
