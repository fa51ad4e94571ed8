"""Contact normals, separations and the contact law of logistic-regression (LR) multimaterial MPM
(Nairn et al., "LR"), physics only: the ``"lr"`` stepper builds the per-material grid and the
point clouds and calls these. The LR plane, normal and separation (``lr_planes``, LR eqs. 19-25,
App. eqs. 53-57) and the contact law (``contact_momentum``, LR eqs. 7-10, 14-15, 24) are here;
the grid detectors LR compares against (AG normals, LR eqs. 11, 13; CP separation, LR eq. 16)
are re-exported from ``bfemp.contact._lr_detectors``. Units: SI throughout (m, kg, kg m/s).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from bfemp.contact._lr_args import (
    check_clouds,
    check_F_R0,
    check_fit_options,
    contact_rows,
    dimension,
    float_array,
    grid_args,
    int_array,
)
from bfemp.contact._lr_detectors import (
    CP_OFFSET_CELLS,
    ag_normals,
    cp_separation,
    mass_gradient_normals,
    material_mass_moments,
)
from bfemp.contact._lr_grid_kernels import point_clouds
from bfemp.contact._lr_kernels import DEGENERATE, ONE_CLASS, deformed_radii, lr_planes_kernel

__all__ = [
    "CP_OFFSET_CELLS",
    "DETECTORS",
    "LAWS",
    "LRPlanes",
    "ag_normals",
    "contact_momentum",
    "contact_point_clouds",
    "cp_separation",
    "deformed_radius",
    "lr_planes",
    "mass_gradient_normals",
    "material_mass_moments",
]

log = logging.getLogger(__name__)

LAWS = ("frictionless", "coulomb", "perfect")
DETECTORS = ("lr", "cp", "velocity")


@dataclass(frozen=True)
class LRPlanes:
    """The LR solve at C contact nodes (``lr_planes``).

    Attributes:
        normal: unit normals ``(C, d)`` from material alpha (side -1) to beta (side +1).
        separation: d_LR ``(C,)`` in m (LR eq. 24); negative = overlapping, 0 = touching.
        iterations: Gauss-Newton (logistic) iterations taken ``(C,)`` int, after the
            linear-regression start.
        converged: ``(C,)`` bool, 1 - n^(k+1) . n^(k) < tol met within ``max_iterations``.
        fallback: ``(C,)`` bool, a Gauss-Newton iterate was NaN, singular or had a zero normal,
            and the linear-regression normal was used.
        phi: the final model parameters ``(C, d + 1)`` (LR eq. 19), positions relative to the node:
            (X - x_i, 1) . phi = 0 on the plane; the normal part in 1/m, the offset
            dimensionless. In a fallback, the linear start.
    """

    normal: np.ndarray
    separation: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    fallback: np.ndarray
    phi: np.ndarray


def deformed_radius(F: np.ndarray, R0: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Distance R_p ``(Q,)`` in m from each particle's centre to its deformed edge along the unit
    ``normal (Q, d)`` (LR eq. 25): n0 = F_p^-1 n, 1/R_p = sqrt(sum_k n0_k^2 / R0_k^2), i.e. along n
    to the boundary of the ellipse (ellipsoid) of semi-axes R0 inscribed in the undeformed
    particle and mapped by F_p (NairnMPM ``GetDeformedRadius``).

    Args:
        F: deformation gradients ``(Q, d, d)``, det F > 0.
        R0: undeformed semi-axes ``(Q, d)`` in m (2 x 2 PPC: dx/4); a row of zeros is a surface
            sample (FEM boundary) with R_p = 0.
        normal: unit directions ``(Q, d)``.
    """
    normal = float_array("normal", normal, (None, None))
    q, d = normal.shape
    dimension("normal", normal)
    F = float_array("F", F, (q, d, d))
    R0 = float_array("R0", R0, (q, d))
    check_F_R0(F, R0, "deformed_radius")
    length = np.linalg.norm(normal, axis=1)
    if np.any(np.abs(length - 1.0) > 1e-8):
        raise ValueError("deformed_radius: normal rows must be unit vectors")
    return deformed_radii(F, R0, normal)


def lr_planes(
    node_x: np.ndarray,
    cloud_ptr: np.ndarray,
    cloud_idx: np.ndarray,
    cloud_side: np.ndarray,
    points_x: np.ndarray,
    points_F: np.ndarray,
    points_R0: np.ndarray,
    dx: float,
    *,
    penalty: float = 1e-7,
    tol: float = 1e-5,
    max_iterations: int = 15,
    linear_scale: float = 2.0,
    normal_start: np.ndarray | None = None,
    thin: float = 0.0,
) -> LRPlanes:
    """The LR plane, normal and separation at C contact nodes (LR section 3.1 and Appendix).

    At node c the cloud is ``cloud_idx[cloud_ptr[c]:cloud_ptr[c+1]]`` (indices into the points)
    with classes ``cloud_side`` (-1 alpha, +1 beta). With x~_p = (X_p - x_i, 1) (relative to the
    node, as NairnMPM) and c_p the class, minimise (LR eq. 20)

        Omega = sum_p (f(x~_p . phi) - c_p)^2 + sum_j lambda_j phi_j^2,  f(s) = 2/(1+e^-s) - 1,

    with lambda = penalty dx^2 (1, .., 1, 0) (normal penalised, offset not; LR App.) by
    Gauss-Newton (LR eq. 21, App. eqs. 53-56, w_p = 1). Start: phi(0) = 0, whose first step is the
    linear-regression fit; as NairnMPM, phi(1) = linear_scale * phi_lin with
    (X~^T X~ + Lambda) phi_lin = X~^T c (the exact Gauss-Newton step from 0 is
    2 (X~^T X~ + 4 Lambda)^-1 X~^T c, the same up to the tiny penalty). Then logistic steps until
    1 - n^(k+1) . n^(k) < tol (LR eq. 57) or ``max_iterations`` steps (the last iterate is kept).
    A NaN, singular or zero-normal iterate falls back to the linear normal (``fallback``).

    The separation (LR eqs. 22-24): d_LR = min_beta((X_p - x_i).n - R_p) - max_alpha((X_p - x_i).n
    + R_p), with R_p of LR eq. 25 (``deformed_radius``); independent of x_i.

    Args:
        node_x: contact node positions ``(C, d)`` in m, d = 2 or 3.
        cloud_ptr: CSR row pointers ``(C + 1,)`` int into ``cloud_idx``.
        cloud_idx: point indices ``(K,)`` int into the points.
        cloud_side: classes ``(K,)`` int8, -1 (alpha) or +1 (beta).
        points_x: point positions ``(Q, d)`` in m.
        points_F: deformation gradients ``(Q, d, d)`` (det > 0; identity for surface samples).
        points_R0: undeformed semi-axes ``(Q, d)`` in m (0 rows: surface samples, R_p = 0).
        dx: grid spacing in m (> 0).
        penalty: lambda / dx^2 on the normal components (LR: 1e-7).
        tol: the stop tolerance on 1 - cos(dtheta) (LR: 1e-5, dtheta ~ 0.0044 rad).
        max_iterations: cap on the logistic steps (LR: 15); 0 returns the linear start.
        linear_scale: the factor on the linear-regression start (NairnMPM: 2).
        normal_start: optional warm start ``(C, d)`` (e.g. last step's normals); rows of zeros
            use the linear start. The start phi has that direction, the linear fit's magnitude
            and the least-squares offset of the scaled linear model.
        thin: in cells; > 0 removes from the normal its components along principal directions
            in which the whole cloud's standard deviation is below ``thin`` dx (a cloud of one
            particle column holds no information across it; bfemp's, see
            ``_lr_kernels._drop_thin_directions``), before the separation is measured. 0: off.

    Raises:
        ValueError: bad shapes or values (naming the argument), a cloud with one class only or
            a degenerate cloud (naming the node).
    """
    node_x = float_array("node_x", node_x, (None, None))
    n_c, d = node_x.shape
    dimension("node_x", node_x)
    cloud_ptr, cloud_idx, cloud_side = check_clouds(n_c, cloud_ptr, cloud_idx, cloud_side)
    points_x = float_array("points_x", points_x, (None, d))
    n_q = points_x.shape[0]
    points_F = float_array("points_F", points_F, (n_q, d, d))
    points_R0 = float_array("points_R0", points_R0, (n_q, d))
    if cloud_idx.size and (cloud_idx.min() < 0 or cloud_idx.max() >= n_q):
        raise ValueError(
            f"cloud_idx must index the {n_q} points, got range "
            f"[{cloud_idx.min()}, {cloud_idx.max()}]"
        )
    check_F_R0(points_F, points_R0, "lr_planes")
    check_fit_options(dx, penalty, tol, linear_scale, thin, max_iterations)
    start = np.zeros((n_c, d))  # rows of zeros: the linear start
    if normal_start is not None:
        start = float_array("normal_start", normal_start, (n_c, d))
    has_start = np.linalg.norm(start, axis=1) > 0.0

    normal, phi, sep, iters, conv, fb, code = lr_planes_kernel(
        node_x,
        cloud_ptr,
        cloud_idx,
        cloud_side,
        points_x,
        points_F,
        points_R0,
        float(penalty) * float(dx) ** 2,
        float(tol),
        int(max_iterations),
        float(linear_scale),
        (float(thin) * float(dx)) ** 2,
        start,
        has_start,
    )
    if np.any(code == ONE_CLASS):
        bad = np.flatnonzero(code == ONE_CLASS)
        raise ValueError(
            f"lr_planes: the point cloud of contact node {int(bad[0])} (of {bad.size} such "
            f"nodes: {bad[:10].tolist()}) lacks material alpha or beta; a contact node needs "
            "points of both classes"
        )
    if np.any(code == DEGENERATE):
        bad = np.flatnonzero(code == DEGENERATE)
        raise ValueError(
            f"lr_planes: the point cloud of contact node {int(bad[0])} (nodes "
            f"{bad[:10].tolist()}) is degenerate: the linear regression has no normal"
        )
    capped = ~conv & ~fb & (sep < 0.0)
    if max_iterations > 0 and np.any(capped):  # NairnMPM warns on these; the stepper counts them
        log.debug(
            "lr_planes: %d of %d touching contact nodes hit the cap of %d iterations",
            int(capped.sum()),
            n_c,
            max_iterations,
        )
    return LRPlanes(normal, sep, iters, conv, fb, phi)


def contact_point_clouds(
    nodes: np.ndarray,
    weights: np.ndarray,
    material: np.ndarray,
    node: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    n_nodes: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The point clouds of C contact rows in ``lr_planes``' CSR form (spec 2.1: every point whose
    stencil weight at the node is > 0; NairnMPM ``GetMaterialContactData``).

    Row r (grid node ``node[r]``) holds the points of material ``alpha[r]`` as side -1 and of
    ``beta[r]`` as side +1; ``beta[r] = -1`` takes every material other than alpha as +1 (the
    lumped partner of LR eq. 50, NairnMPM's b < 0). Points of other materials are left out. Within a
    cloud the points are in index order. FEM surface samples take part as points with their own
    stencils (spec 2.6).

    Args:
        nodes: stencil node indices ``(P, S)`` int (-1 = none).
        weights: w_ip ``(P, S)``.
        material: ``(P,)`` int >= 0.
        node: grid node of each contact row ``(C,)`` int in [0, n_nodes).
        alpha: ``(C,)`` int >= 0. beta: ``(C,)`` int, >= 0 and != alpha, or -1 (lumped).
        n_nodes: number of grid nodes.

    Returns:
        ``(cloud_ptr (C + 1,) int64, cloud_idx (K,) int64, cloud_side (K,) int8)``.
    """
    material = int_array("material", material, 1)
    n_p = material.shape[0]
    nodes, material = grid_args(
        nodes, n_nodes, material, max(1, int(material.max(initial=0)) + 1), n_p
    )
    weights = float_array("weights", weights, nodes.shape)
    node, alpha, beta = contact_rows("contact_point_clouds", node, alpha, beta, n_nodes)
    if np.any(alpha < 0) or np.any(beta < -1) or np.any(alpha == beta):
        raise ValueError("contact_point_clouds: alpha must be >= 0, beta >= 0 (or -1) and != alpha")
    return point_clouds(nodes, weights, material, node, alpha, beta, int(n_nodes))


def contact_momentum(
    m_a: np.ndarray,
    m_b: np.ndarray,
    p_a: np.ndarray,
    p_b: np.ndarray,
    normal: np.ndarray,
    separation: np.ndarray | None,
    *,
    mu: float | np.ndarray,
    law: str,
    detector: str = "lr",
    rigid_a: np.ndarray | None = None,
    rigid_b: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The momentum change of material a at C two-material contact nodes (LR eqs. 7-10, 14-15).

    Delta p(0) = m_a (v_cm - v_a) = m_red (v_b - v_a), m_red = m_a m_b / (m_a + m_b) (the change
    that moves both with the centre of mass), d_n = Delta p(0) . n. Contact iff d_n < 0
    (approaching, LR eq. 14) and separation < 0 (touching, LR eqs. 15/24) for the detectors ``"lr"``
    and ``"cp"``; ``"velocity"`` uses d_n < 0 alone (``separation`` may be None). Laws:

    - ``"frictionless"``: Delta p = d_n n.
    - ``"coulomb"``: t = Delta p(0) - d_n n; stick Delta p = Delta p(0) if ||t|| <= mu |d_n|,
      else slip Delta p = d_n n + mu |d_n| t / ||t|| (LR eqs. 8-10 with S_slide = mu N_c and
      N_c A_c dt = -d_n, so the area cancels; t/||t|| is the paper's t-hat with
      Delta p(0) . t-hat > 0 after its sign correction). The slip keeps the relative tangential
      velocity's direction and reduces its size by mu |d_n| / m_red: sliding loses relative
      tangential momentum, never reverses it.
    - ``"perfect"``: Delta p = Delta p(0) at every node (a bonded interface, NairnMPM
      ``IgnoreContact``); ``in_contact`` is then all True.

    Out of contact Delta p = 0. The caller adds Delta p to a and -Delta p to b (LR eq. 7). Every law
    removes kinetic energy of the pair or keeps it: Delta KE = (|Delta p|^2 -
    2 Delta p . Delta p(0)) / (2 m_red) <= 0.

    A rigid (kinematic) side has infinite mass: its velocity is scripted and no impulse
    changes it, so m_red is the other side's mass, Delta p(0) = m_a (v_b - v_a) where b is
    rigid and m_b (v_b - v_a) where a is (NairnMPM's rigid-material contact,
    ``CrackVelocityFieldMulti::RigidMaterialContactOnCVF``: delta p_i = m_i (v_rigid - v_i);
    LR itself has no rigid materials). The caller then leaves the rigid side's momentum as it
    is. Where both sides are rigid there is no contact.

    Args:
        m_a, m_b: grid masses ``(C,)`` in kg (> 0).
        p_a, p_b: grid momenta ``(C, d)`` in kg m/s.
        normal: unit normals ``(C, d)`` from a to b (a zero row: no contact unless "perfect").
        separation: ``(C,)`` in m (d_LR or ``cp_separation``), or None for "velocity".
        mu: Coulomb friction coefficient (>= 0; used by "coulomb" only), one for every contact
            or ``(C,)`` per contact (``scene.set_friction`` pairs).
        law: one of ``LAWS``. detector: one of ``DETECTORS``.
        rigid_a, rigid_b: ``(C,)`` bool, the side's field at the node is scripted (None: no
            node is).

    Returns:
        ``(dp (C, d) in kg m/s, in_contact (C,) bool)``.
    """
    if law not in LAWS:
        raise ValueError(f"contact_momentum: law must be one of {LAWS}, got {law!r}")
    if detector not in DETECTORS:
        raise ValueError(f"contact_momentum: detector must be one of {DETECTORS}, got {detector!r}")
    m_a = float_array("m_a", m_a, (None,))
    n_c = m_a.shape[0]
    m_b = float_array("m_b", m_b, (n_c,))
    p_a = float_array("p_a", p_a, (n_c, None))
    d = p_a.shape[1]
    p_b = float_array("p_b", p_b, (n_c, d))
    normal = float_array("normal", normal, (n_c, d))
    if np.any(m_a <= 0.0) or np.any(m_b <= 0.0):
        raise ValueError("contact_momentum: m_a and m_b must be > 0 at every contact node")
    length = np.linalg.norm(normal, axis=1)
    if np.any((np.abs(length - 1.0) > 1e-8) & (length != 0.0)):
        raise ValueError("contact_momentum: normal rows must be unit vectors (or zero)")
    mu = np.asarray(mu, dtype=np.float64)
    if mu.ndim not in (0, 1) or (mu.ndim == 1 and mu.shape != (n_c,)):
        raise ValueError(f"contact_momentum: mu must be a number or ({n_c},), got {mu.shape}")
    if law == "coulomb" and not np.all(np.isfinite(mu) & (mu >= 0.0)):
        raise ValueError(f"contact_momentum: mu must be finite and >= 0, got {mu}")
    if detector != "velocity" or separation is not None:
        if separation is None:
            raise ValueError(f"contact_momentum: detector {detector!r} needs a separation")
        separation = float_array("separation", separation, (n_c,))

    rigid = []
    for name, flag in (("rigid_a", rigid_a), ("rigid_b", rigid_b)):
        if flag is None:
            rigid.append(np.zeros(n_c, dtype=bool))
            continue
        flag = np.asarray(flag)
        if flag.dtype != bool or flag.shape != (n_c,):
            raise ValueError(f"contact_momentum: {name} must be a ({n_c},) bool array")
        rigid.append(flag)
    ra, rb = rigid

    total = m_a + m_b
    dp0 = (m_a[:, None] * p_b - m_b[:, None] * p_a) / total[:, None]  # m_red (v_b - v_a)
    if ra.any() or rb.any():  # an infinite mass: m_red is the other side's
        v_rel = p_b / m_b[:, None] - p_a / m_a[:, None]
        dp0[rb] = m_a[rb, None] * v_rel[rb]
        dp0[ra] = m_b[ra, None] * v_rel[ra]
        dp0[ra & rb] = 0.0
    if law == "perfect":
        return dp0, ~(ra & rb)
    d_n = np.einsum("cd,cd->c", dp0, normal)
    in_contact = d_n < 0.0  # approaching (LR eq. 14); never where both sides are rigid
    if detector != "velocity":
        in_contact &= separation < 0.0  # touching (LR eqs. 15, 24)
    dp = d_n[:, None] * normal
    if law == "coulomb":
        t = dp0 - dp
        t_len = np.linalg.norm(t, axis=1)
        cap = mu * np.abs(d_n)
        slip = t_len > cap
        stick = ~slip
        dp[stick] = dp0[stick]
        dp[slip] += (cap[slip] / t_len[slip])[:, None] * t[slip]
    dp[~in_contact] = 0.0
    return dp, in_contact
