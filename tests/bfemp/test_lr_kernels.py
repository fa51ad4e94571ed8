"""The logistic-regression (LR) contact kernels: planes, separations, radii and the contact law
(docs/design/explicit_strategies.md section 2.8, L5-L8; Nairn et al. LR eqs. 7-25, 53-57)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, least_squares, minimize_scalar
from scipy.spatial.transform import Rotation

from bfemp.contact import lr
from bfemp.contact.augury import contact_stencils

DX = 0.005  # 5 mm cells (LR section 4.1)


def lattice(lo, hi, dx=DX):
    """2 x 2 PPC particle centres (spacing dx/2, dx/4 from the faces) filling the box [lo, hi]."""
    axes = [np.arange(a + dx / 4, b - 1e-12 * dx, dx / 2) for a, b in zip(lo, hi, strict=True)]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in grid], axis=1)


def one_cloud(x_alpha, x_beta):
    """Points, classes and the CSR arrays of one contact node whose cloud is every point."""
    x = np.vstack([x_alpha, x_beta])
    side = np.r_[-np.ones(len(x_alpha)), np.ones(len(x_beta))].astype(np.int8)
    q = len(x)
    return x, side, np.array([0, q]), np.arange(q)


def solve(node, x, side, ptr, idx, F=None, R0=None, dx=DX, **kw):
    q, d = x.shape
    F = np.tile(np.eye(d), (q, 1, 1)) if F is None else F
    R0 = np.full((q, d), dx / 4) if R0 is None else R0
    return lr.lr_planes(np.atleast_2d(node), ptr, idx, side, x, F, R0, dx, **kw)


def tilt_deg(n):
    """Angle of the 2D unit normal n from the downward vertical (0, -1), degrees."""
    return np.degrees(np.arccos(np.clip(-n[1], -1.0, 1.0)))


# ---- L5: Fig. 3C -----------------------------------------------------------------------------


def fig3c(node):
    """LR Fig. 3C (our reconstruction, L-P5): in the node's B-spline stencil (1.5 cells each
    way), alpha fills only the quadrant x < x_i, y > y_i and beta the half y < y_i."""
    x0, y0 = node
    e = 1.5 * DX
    x_alpha = lattice((x0 - e, y0), (x0, y0 + e))
    x_beta = lattice((x0 - e, y0 - e), (x0 + e, y0))
    return x_alpha, x_beta


def test_fig3c_lr_is_horizontal_ag_tilts_and_node_position_drops_out():
    node = np.array([4 * DX, 6 * DX])
    x_alpha, x_beta = fig3c(node)
    x, side, ptr, idx = one_cloud(x_alpha, x_beta)
    res = solve(node, x, side, ptr, idx)
    assert res.converged[0] and not res.fallback[0]
    assert tilt_deg(res.normal[0]) < 1.0  # measured 0.97 degrees
    assert res.separation[0] < 0.0 < res.separation[0] + 0.05 * DX  # touching, d_LR ~ 0

    # AG (eq. 13) from the B-spline gradients of the same particles (mass weights = volumes)
    st_ = contact_stencils(x, DX)
    mat = (side > 0).astype(np.int64)
    g = lr.mass_gradient_normals(st_.nodes, st_.grads, np.ones(len(x)), mat, st_.n_nodes, 2)
    i = int(np.argmin(np.linalg.norm(st_.node_x - node, axis=1)))
    ag = lr.ag_normals(g, np.array([i]), np.array([0]), np.array([1]))
    assert tilt_deg(ag[0]) > 10.0  # LR reports about 18 degrees; measured 18.4

    for shift in ([0.3 * DX, -0.2 * DX], [-0.45 * DX, 0.4 * DX]):
        moved = solve(node + np.array(shift), x, side, ptr, idx)
        np.testing.assert_allclose(moved.normal, res.normal, rtol=0, atol=1e-12)
        np.testing.assert_allclose(moved.separation, res.separation, rtol=0, atol=1e-12 * DX)


# ---- L6: the deformed radius (eq. 25) --------------------------------------------------------


def rotation_2d(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def test_deformed_radius_stretch_and_rotation():
    R0 = np.array([[0.3, 0.7]])
    e1 = np.array([[1.0, 0.0]])
    F = np.diag([1.7, 0.4])[None]
    np.testing.assert_allclose(lr.deformed_radius(F, R0, e1), 1.7 * 0.3, rtol=1e-14)
    F3 = np.diag([0.6, 1.3, 2.0])[None]
    R03 = np.array([[0.2, 0.3, 0.5]])
    for k in range(3):
        n = np.eye(3)[k][None]
        np.testing.assert_allclose(lr.deformed_radius(F3, R03, n), F3[0, k, k] * R03[0, k])
    rng = np.random.default_rng(3)
    for _ in range(5):
        Q2 = rotation_2d(rng.uniform(0, 2 * np.pi))[None]
        n = rng.normal(size=(1, 2))
        n /= np.linalg.norm(n)
        rotated = lr.deformed_radius(Q2, R0, n @ Q2[0].T)
        np.testing.assert_allclose(rotated, lr.deformed_radius(np.eye(2)[None], R0, n), 1e-14)
        Q3 = Rotation.random(random_state=rng).as_matrix()[None]
        n3 = rng.normal(size=(1, 3))
        n3 /= np.linalg.norm(n3)
        np.testing.assert_allclose(
            lr.deformed_radius(Q3, R03, n3 @ Q3[0].T),
            lr.deformed_radius(np.eye(3)[None], R03, n3),
            rtol=1e-14,
        )
    # a surface sample (R0 = 0) has no radius
    assert lr.deformed_radius(F, np.zeros((1, 2)), e1)[0] == 0.0


def radial_distance_brute_force(F, R0, n):
    """Distance from the centre along n to the ellipse F diag(R0) S^1, by minimisation over the
    support function h(z) = max_u z . F diag(R0) u: r(n) = min_{z . n > 0} h(z) / (z . n)."""
    A = F @ np.diag(R0)
    base = np.arctan2(n[1], n[0])

    def support(z):  # brute force over the boundary, refined by a bounded search
        u = np.linspace(0, 2 * np.pi, 721)
        vals = z @ (A @ np.stack([np.cos(u), np.sin(u)]))
        t0 = u[np.argmax(vals)]
        best = minimize_scalar(
            lambda t: -(z @ A @ [np.cos(t), np.sin(t)]),
            bounds=(t0 - 0.01, t0 + 0.01),
            method="bounded",
            options={"xatol": 1e-13},
        )
        return -best.fun

    def ratio(a):
        z = np.array([np.cos(a), np.sin(a)])
        return support(z) / (z @ n)

    grid = base + np.linspace(-1.5, 1.5, 301)
    a0 = grid[np.argmin([ratio(a) for a in grid])]
    best = minimize_scalar(
        ratio, bounds=(a0 - 0.011, a0 + 0.011), method="bounded", options={"xatol": 1e-13}
    )

    # cross-check: the boundary point in the direction n (a root of its cross product with n)
    def cross(t):
        y = A @ [np.cos(t), np.sin(t)]
        return y[0] * n[1] - y[1] * n[0]

    ts = np.linspace(0, 2 * np.pi, 2001)
    cs = np.array([cross(t) for t in ts])
    for k in np.flatnonzero(np.sign(cs[:-1]) != np.sign(cs[1:])):
        t = brentq(cross, ts[k], ts[k + 1], xtol=1e-15)
        y = A @ [np.cos(t), np.sin(t)]
        if y @ n > 0:
            ray = float(np.linalg.norm(y))
    return best.fun, ray


def test_deformed_radius_against_brute_force_over_the_ellipse():
    rng = np.random.default_rng(11)
    for _ in range(6):
        F = np.eye(2) + 0.5 * rng.normal(size=(2, 2))
        if np.linalg.det(F) < 0.1:
            F[:, 0] *= -1.0
        F = F if np.linalg.det(F) > 0.05 else np.eye(2)
        R0 = rng.uniform(0.5, 2.0, 2) * 1e-3
        n = rng.normal(size=2)
        n /= np.linalg.norm(n)
        r = lr.deformed_radius(F[None], R0[None], n[None])[0]
        by_support, by_ray = radial_distance_brute_force(F, R0, n)
        assert abs(r - by_ray) < 1e-10 * np.max(R0) * 1e3
        assert abs(r - by_support) < 1e-10 * np.max(R0) * 1e3


# ---- L7: the linear start and convergence on clean clouds -------------------------------------


def test_first_iterate_is_scaled_linear_regression():
    node = np.array([4 * DX, 6 * DX])
    x, side, ptr, idx = one_cloud(*fig3c(node))
    xt = np.c_[x - node, np.ones(len(x))]
    lam = np.diag([1e-7 * DX**2] * 2 + [0.0])
    lin = np.linalg.solve(xt.T @ xt + lam, xt.T @ side)  # linear regression (LR App.)
    for scale in (2.0, 3.0):
        start = solve(node, x, side, ptr, idx, max_iterations=0, linear_scale=scale)
        np.testing.assert_allclose(start.phi[0], scale * lin, rtol=1e-12)
        assert start.iterations[0] == 0 and not start.converged[0]
    # the exact Gauss-Newton step from phi = 0 (psi = 1/2, f = 0; eqs. 21, 53-56) is the same
    gn = np.linalg.solve(0.25 * xt.T @ xt + lam, 0.5 * xt.T @ side)
    np.testing.assert_allclose(gn, 2.0 * lin, rtol=1e-6)
    # one logistic step moves it (the fit is not the linear one: LR App., "still tilted")
    one = solve(node, x, side, ptr, idx, max_iterations=1, tol=0.0)
    assert one.iterations[0] == 1 and np.linalg.norm(one.phi[0] - 2.0 * lin) > 1.0


def omega_gradient(phi, xt, c, lam):
    """Gradient of eq. 20's Omega (w_p = 1) with respect to phi, by the chain rule."""
    s = xt @ phi
    f = np.tanh(0.5 * s)
    psi = 0.5 * (1.0 - f * f)  # eq. 53
    return 2.0 * ((f - c) * psi) @ xt + 2.0 * lam * phi


@pytest.mark.parametrize("d", [2, 3])
def test_gauss_newton_reaches_the_minimum_of_eq20(d):
    # a noisy (not separable) cloud: Omega has a finite, well-defined minimum
    rng = np.random.default_rng(20 + d)
    node = rng.uniform(-1, 1, d) * DX
    x = node + rng.uniform(-1.5, 1.5, (60, d)) * DX
    rel = (x - node) / DX
    c = np.where(rel @ rng.normal(size=d) + 0.2 + 0.6 * rng.normal(size=60) > 0, 1, -1)
    side = c.astype(np.int8)
    ptr, idx = np.array([0, 60]), np.arange(60)
    xt = np.c_[x - node, np.ones(60)]
    lam = np.r_[np.full(d, 1e-7 * DX**2), 0.0]
    start = solve(node, x, side, ptr, idx, max_iterations=0)
    res = solve(node, x, side, ptr, idx, tol=0.0, max_iterations=60)
    g0 = np.abs(omega_gradient(start.phi[0], xt, c, lam) * np.r_[np.full(d, DX), 1.0]).max()
    g1 = np.abs(omega_gradient(res.phi[0], xt, c, lam) * np.r_[np.full(d, DX), 1.0]).max()
    assert g1 < 1e-6 * g0
    sol = least_squares(
        lambda p: np.r_[np.tanh(0.5 * xt @ p) - c, np.sqrt(lam[:d]) * p[:d]],
        start.phi[0],
        xtol=1e-15,
        ftol=1e-15,
        gtol=1e-15,
    )
    n = sol.x[:d] / np.linalg.norm(sol.x[:d])
    assert np.arccos(min(1.0, n @ res.normal[0])) < 1e-4


def rotated_half_stencils(rot, d, node, dx=DX):
    """Clean cloud: the node's stencil box (3 x 3 cells) split into two 2 x 2 PPC halves along
    the interface, the whole cloud rotated by ``rot`` about the node; true normal rot e_d."""
    k = (np.arange(6) - 2.5) * dx / 2
    loc = np.stack(np.meshgrid(*[k] * d, indexing="ij"), -1).reshape(-1, d)
    side = np.where(loc[:, -1] > 0, 1, -1).astype(np.int8)
    return node + loc @ rot.T, side, rot[:, -1]


def grid_window_cloud(rot, d, node, dx=DX):
    """Clean cloud: two touching bodies of a rotated 2 x 2 PPC lattice; the cloud is the
    particles in the axis-aligned stencil box of a node near the interface (not symmetric)."""
    k = (np.arange(-8, 8) + 0.5) * dx / 2
    loc = np.stack(np.meshgrid(*[k] * d, indexing="ij"), -1).reshape(-1, d)
    side = np.where(loc[:, -1] > 0, 1, -1).astype(np.int8)
    x = loc @ rot.T
    keep = np.all(np.abs(x - node) < 1.5 * dx, axis=1)
    return x[keep], side[keep], rot[:, -1]


@pytest.mark.parametrize("d", [2, 3])
def test_clean_clouds_converge_to_the_interface_normal(d):
    rng = np.random.default_rng(5 + d)
    worst_window = 0.0
    for _ in range(6):
        rot = (
            rotation_2d(rng.uniform(0, 2 * np.pi))
            if d == 2
            else Rotation.random(random_state=rng).as_matrix()
        )
        node = rng.uniform(-0.5, 0.5, d) * DX
        x, side, n_true = rotated_half_stencils(rot, d, node)
        res = solve(node, x, side, np.array([0, len(x)]), np.arange(len(x)))
        assert res.converged[0] and res.iterations[0] <= 15 and not res.fallback[0]
        assert np.arccos(min(1.0, res.normal[0] @ n_true)) < 1e-3
        assert abs(res.separation[0]) < 1e-12  # touching halves

        x, side, n_true = grid_window_cloud(rot, d, node)
        res = solve(node, x, side, np.array([0, len(x)]), np.arange(len(x)))
        assert res.converged[0] and res.iterations[0] <= 15 and not res.fallback[0]
        worst_window = max(worst_window, np.arccos(min(1.0, res.normal[0] @ n_true)))
    # asymmetric windows: the penalised logistic optimum itself tilts by a few mrad, and the
    # stop rule (1 - cos < 1e-5) allows 4.4 mrad per step; measured worst about 0.01 rad
    assert worst_window < 0.02


def test_warm_start_and_zero_rows():
    node = np.array([0.0, 0.0])
    rot = rotation_2d(0.3)
    x, side, n_true = grid_window_cloud(rot, 2, node)
    ptr, idx = np.array([0, len(x)]), np.arange(len(x))
    cold = solve(node, x, side, ptr, idx)
    same = solve(node, x, side, ptr, idx, normal_start=np.zeros((1, 2)))
    np.testing.assert_array_equal(same.normal, cold.normal)
    warm = solve(node, x, side, ptr, idx, normal_start=n_true[None])
    assert warm.converged[0] and warm.iterations[0] <= cold.iterations[0]
    assert np.arccos(min(1.0, warm.normal[0] @ cold.normal[0])) < 0.01


def test_parallel_path_equals_one_node_at_a_time():
    rng = np.random.default_rng(2)
    clouds = []
    for _ in range(70):  # >= PARALLEL_MIN nodes: the prange kernel
        node = rng.uniform(-0.5, 0.5, 2) * DX
        x, side, _ = grid_window_cloud(rotation_2d(rng.uniform(0, 6.3)), 2, node)
        clouds.append((node, x, side))
    xs = np.vstack([c[1] for c in clouds])
    sides = np.concatenate([c[2] for c in clouds])
    ptr = np.concatenate([[0], np.cumsum([len(c[1]) for c in clouds])])
    nodes = np.array([c[0] for c in clouds])
    allc = solve(nodes, xs, sides, ptr, np.arange(len(xs)))
    for c in (0, 33, 69):
        node, x, side = clouds[c]
        one = solve(node, x, side, np.array([0, len(x)]), np.arange(len(x)))
        np.testing.assert_array_equal(allc.normal[c], one.normal[0])
        assert allc.separation[c] == one.separation[0]


def test_fallback_to_the_linear_normal_on_a_singular_step():
    # a start so steep that every psi underflows (eq. 53): J^T W J = 0 and, with the offset
    # unpenalised, the Gauss-Newton matrix is singular; the linear-regression normal is returned
    node = np.array([0.0, 0.0])
    x, side, ptr, idx = one_cloud(*fig3c(node))  # the linear normal tilts 8.7 degrees here
    res = solve(node, x, side, ptr, idx, linear_scale=1e6)
    lin = solve(node, x, side, ptr, idx, max_iterations=0)
    assert res.fallback[0] and not res.converged[0] and res.iterations[0] == 1
    np.testing.assert_allclose(res.normal[0], lin.normal[0], atol=1e-15)
    assert np.all(np.isfinite(res.phi)) and np.isfinite(res.separation[0])
    normal = solve(node, x, side, ptr, idx)
    assert not normal.fallback[0] and np.linalg.norm(normal.normal[0] - lin.normal[0]) > 1e-4


# ---- separation (eqs. 22-25) -------------------------------------------------------------------


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("gap_cells", [0.0, 0.37, -0.2])
def test_flat_blocks_separation_and_a_compressed_particle(gap_cells, d):
    g = gap_cells * DX
    node = np.zeros(d)
    e = 1.5 * DX
    x_alpha = lattice([-e] * d, [e] * (d - 1) + [0.0])
    x_beta = lattice([-e] * (d - 1) + [g], [e] * (d - 1) + [e + g])
    x, side, ptr, idx = one_cloud(x_alpha, x_beta)
    res = solve(node, x, side, ptr, idx)
    np.testing.assert_allclose(res.normal[0], np.eye(d)[-1], atol=1e-14)
    assert abs(res.separation[0] - g) < 1e-12
    # beta's bottom layer compressed to half its height: its radius along n halves (eq. 25)
    F = np.tile(np.eye(d), (len(x), 1, 1))
    bottom = (side > 0) & (x[:, -1] < g + 0.3 * DX)
    F[bottom] = np.diag([1.0] * (d - 1) + [0.5])
    squeezed = solve(node, x, side, ptr, idx, F=F)
    assert abs(squeezed.separation[0] - (g + DX / 8)) < 1e-12
    # surface samples (R0 = 0) on alpha's top layer: no radius
    R0 = np.full((len(x), d), DX / 4)
    top = (side < 0) & (x[:, -1] > -0.3 * DX)
    R0[top] = 0.0
    surf = solve(node, x, side, ptr, idx, R0=R0)
    assert abs(surf.separation[0] - (g + DX / 4)) < 1e-12


# ---- grid normals and CP ----------------------------------------------------------------------


def test_grid_moments_and_cp_separation_against_numpy():
    rng = np.random.default_rng(4)
    xa = lattice((0.0, 0.0), (4 * DX, 2 * DX))
    xb = lattice((0.0, 2.3 * DX), (4 * DX, 4 * DX))
    x = np.vstack([xa, xb])
    mat = np.r_[np.zeros(len(xa)), np.ones(len(xb))].astype(np.int64)
    mass = rng.uniform(0.5, 1.5, len(x))
    st_ = contact_stencils(x, DX)
    g = lr.mass_gradient_normals(st_.nodes, st_.grads, mass, mat, st_.n_nodes, 2)
    mom = lr.material_mass_moments(st_.nodes, st_.weights, mass, x, mat, st_.n_nodes, 2)
    ref_g = np.zeros_like(g)
    ref_m = np.zeros_like(mom)
    ref_mass = np.zeros(g.shape[:2])
    for s in range(st_.nodes.shape[1]):
        np.add.at(ref_g, (mat, st_.nodes[:, s]), mass[:, None] * st_.grads[:, s])
        np.add.at(ref_m, (mat, st_.nodes[:, s]), (st_.weights[:, s] * mass)[:, None] * x)
        np.add.at(ref_mass, (mat, st_.nodes[:, s]), st_.weights[:, s] * mass)
    np.testing.assert_allclose(g, ref_g, rtol=1e-13, atol=1e-13 * np.abs(ref_g).max())
    np.testing.assert_allclose(mom, ref_m, rtol=1e-13, atol=1e-13 * np.abs(ref_m).max())
    both = np.flatnonzero((ref_mass[0] > 0) & (ref_mass[1] > 0))
    zeros = np.zeros(both.size, dtype=np.int64)
    n = lr.ag_normals(g, both, zeros, zeros + 1)
    unit = lr.mass_gradient_normals(st_.nodes, st_.grads, np.ones(len(x)), mat, st_.n_nodes, 2)
    mid = both[np.argmin(np.abs(st_.node_x[both, 0] - 2.0 * DX))]
    j = int(np.flatnonzero(both == mid)[0])
    n_unit = lr.ag_normals(unit, both, zeros, zeros + 1)
    np.testing.assert_allclose(n_unit[j], [0.0, 1.0], atol=1e-12)  # from alpha (below) to beta
    sep = lr.cp_separation(st_.node_x[both], both, zeros, zeros + 1, ref_mass, mom, n, 0.8, DX)
    xa_i = ref_m[0, both] / ref_mass[0, both, None]
    xb_i = ref_m[1, both] / ref_mass[1, both, None]
    np.testing.assert_allclose(sep, np.einsum("cd,cd->c", xb_i - xa_i, n) - 0.8 * DX, atol=1e-15)


def test_point_clouds_from_stencils_against_a_direct_construction():
    rng = np.random.default_rng(8)
    x = rng.uniform(0.0, 4 * DX, (60, 2))
    mat = rng.integers(0, 3, 60)
    st_ = contact_stencils(x, DX)
    rows_node = np.array([5, 5, 9, 12, 5])
    alpha = np.array([0, 1, 2, 0, 2])
    beta = np.array([1, -1, 0, 2, -1])
    ptr, idx, side = lr.contact_point_clouds(
        st_.nodes, st_.weights, mat, rows_node, alpha, beta, st_.n_nodes
    )
    assert ptr[0] == 0 and ptr[-1] == idx.size == side.size and side.dtype == np.int8
    for r in range(len(rows_node)):
        near = np.flatnonzero(((st_.nodes == rows_node[r]) & (st_.weights > 0)).any(axis=1))
        a = near[mat[near] == alpha[r]]
        b = near[mat[near] != alpha[r]] if beta[r] < 0 else near[mat[near] == beta[r]]
        want = np.sort(np.r_[a, b])
        np.testing.assert_array_equal(idx[ptr[r] : ptr[r + 1]], want)
        np.testing.assert_array_equal(side[ptr[r] : ptr[r + 1]], np.where(np.isin(want, a), -1, 1))


# ---- the contact law (LR eqs. 7-10, 14-15; L8) ------------------------------------------------


def law(p_a, p_b, sep, m_a=2.0, m_b=3.0, n=(0.0, 1.0), **kw):
    one = np.ones(1)
    return lr.contact_momentum(
        m_a * one,
        m_b * one,
        np.atleast_2d(p_a),
        np.atleast_2d(p_b),
        np.atleast_2d(n),
        None if sep is None else sep * one,
        **kw,
    )


@pytest.mark.parametrize("name", ["frictionless", "coulomb"])
def test_contact_needs_approach_and_touch(name):
    kw = dict(mu=0.2, law=name, detector="lr")
    approaching = ([0.0, 2.0], [0.0, -3.0])  # a moves up toward b, b down (n from a to b = +y)
    separating = ([0.0, -2.0], [0.0, 3.0])
    dp, hit = law(*separating, -0.1 * DX, **kw)  # overlapping but separating
    assert not hit[0] and np.all(dp == 0.0)
    dp, hit = law(*approaching, 0.1 * DX, **kw)  # approaching but apart
    assert not hit[0] and np.all(dp == 0.0)
    dp, hit = law(*approaching, -0.1 * DX, **kw)  # approaching and touching
    assert hit[0]
    # the normal relative velocity vanishes after the correction: m_red (v_b - v_a) . n = -dp.n
    v_a = (np.array(approaching[0]) + dp[0]) / 2.0
    v_b = (np.array(approaching[1]) - dp[0]) / 3.0
    assert abs((v_b - v_a)[1]) < 1e-15
    dp, hit = law(*approaching, 0.1 * DX, mu=0.2, law=name, detector="velocity")
    assert hit[0] and dp[0, 1] < 0.0  # "velocity" ignores the separation


def test_coulomb_sliding_loses_tangential_momentum_and_sticks_below_the_cone():
    m_a, m_b = 2.0, 3.0
    p_a, p_b = np.array([4.0, 2.0]), np.array([-3.0, -3.0])  # fast slide, slow approach
    dp, hit = law(p_a, p_b, -1.0, mu=0.2, law="coulomb")
    assert hit[0]
    rel0 = p_b / m_b - p_a / m_a
    rel1 = (p_b - dp[0]) / m_b - (p_a + dp[0]) / m_a
    assert abs(rel1[1]) < 1e-14  # no interpenetration
    assert 0.0 < rel1[0] / rel0[0] < 1.0  # same direction, smaller: slowed, never reversed
    m_red = m_a * m_b / (m_a + m_b)
    d_n = m_red * rel0[1]
    np.testing.assert_allclose(dp[0, 0], np.sign(rel0[0]) * 0.2 * abs(d_n), rtol=1e-14)
    # a slow slide within the cone sticks: the full Delta p(0)
    p_a, p_b = np.array([0.1, 2.0]), np.array([0.0, -3.0])
    dp, _ = law(p_a, p_b, -1.0, mu=0.5, law="coulomb")
    np.testing.assert_allclose(dp[0], m_red * (p_b / m_b - p_a / m_a), rtol=1e-14)
    # perfect: Delta p(0) whatever the detection
    dp, hit = law(-p_a, -p_b, 1.0, mu=0.0, law="perfect")
    assert hit[0]
    np.testing.assert_allclose(dp[0], m_red * (-p_b / m_b + p_a / m_a), rtol=1e-14)


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    d=st.sampled_from([2, 3]),
    name=st.sampled_from(lr.LAWS),
    detector=st.sampled_from(lr.DETECTORS),
    mu=st.floats(0.0, 2.0),
)
def test_no_law_increases_the_pair_kinetic_energy(seed, d, name, detector, mu):
    rng = np.random.default_rng(seed)
    c = 16
    m_a, m_b = rng.uniform(0.01, 10.0, c), rng.uniform(0.01, 10.0, c)
    p_a, p_b = rng.normal(size=(c, d)), rng.normal(size=(c, d))
    n = rng.normal(size=(c, d))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    sep = rng.normal(size=c)
    dp, hit = lr.contact_momentum(m_a, m_b, p_a, p_b, n, sep, mu=mu, law=name, detector=detector)

    def ke(pa, pb):
        return 0.5 * (np.sum(pa**2, axis=1) / m_a + np.sum(pb**2, axis=1) / m_b)

    before, after = ke(p_a, p_b), ke(p_a + dp, p_b - dp)
    assert np.all(after <= before * (1 + 1e-12) + 1e-15)
    assert np.all(dp[~hit] == 0.0)
    if name == "coulomb":  # relative tangential momentum never grows
        rel0 = p_b / m_b[:, None] - p_a / m_a[:, None]
        rel1 = (p_b - dp) / m_b[:, None] - (p_a + dp) / m_a[:, None]
        t0 = rel0 - np.sum(rel0 * n, 1, keepdims=True) * n
        t1 = rel1 - np.sum(rel1 * n, 1, keepdims=True) * n
        assert np.all(np.sum(t1 * t0, axis=1) >= -1e-12)  # never reversed
        assert np.all(np.linalg.norm(t1, axis=1) <= np.linalg.norm(t0, axis=1) + 1e-12)


# ---- bad input ------------------------------------------------------------------------------


def test_bad_input_names_the_argument_or_node():
    node = np.zeros((2, 2))
    x, side, _, _ = one_cloud(lattice((-DX, -DX), (DX, 0.0)), lattice((-DX, 0.0), (DX, DX)))
    q = len(x)
    F, R0 = np.tile(np.eye(2), (q, 1, 1)), np.full((q, 2), DX / 4)
    ptr = np.array([0, q, 2 * q])
    idx = np.r_[np.arange(q), np.flatnonzero(side < 0), np.flatnonzero(side < 0)]
    sides = np.r_[side, -np.ones(q, dtype=np.int8)]
    ptr[2] = idx.size
    with pytest.raises(ValueError, match="contact node 1"):
        lr.lr_planes(node, ptr, idx, sides, x, F, R0, DX)
    ptr1, idx1 = np.array([0, q]), np.arange(q)
    with pytest.raises(ValueError, match="points_F"):
        lr.lr_planes(node[:1], ptr1, idx1, side, x, F[:, :1], R0, DX)
    with pytest.raises(ValueError, match="points_R0"):
        lr.lr_planes(node[:1], ptr1, idx1, side, x, F, R0[:-1], DX)
    with pytest.raises(ValueError, match="cloud_ptr"):
        lr.lr_planes(node[:1], np.array([0, q - 1]), idx1, side, x, F, R0, DX)
    with pytest.raises(ValueError, match="cloud_side"):
        lr.lr_planes(node[:1], ptr1, idx1, 2 * side, x, F, R0, DX)
    with pytest.raises(ValueError, match="cloud_idx"):
        lr.lr_planes(node[:1], ptr1, idx1 + 1, side, x, F, R0, DX)
    with pytest.raises(ValueError, match="node_x"):
        lr.lr_planes(np.zeros((1, 4)), ptr1, idx1, side, x, F, R0, DX)
    bad_F = F.copy()
    bad_F[0] = np.diag([1.0, -1.0])
    with pytest.raises(ValueError, match="det F"):
        lr.lr_planes(node[:1], ptr1, idx1, side, x, bad_F, R0, DX)
    bad_x = x.copy()
    bad_x[3, 0] = np.nan
    with pytest.raises(ValueError, match="points_x"):
        lr.lr_planes(node[:1], ptr1, idx1, side, bad_x, F, R0, DX)
    one = np.ones(1)
    with pytest.raises(ValueError, match="frictionless"):
        lr.contact_momentum(
            one, one, np.zeros((1, 2)), np.zeros((1, 2)), np.eye(2)[:1], one, mu=0.2, law="sticky"
        )
    with pytest.raises(ValueError, match="velocity"):
        lr.contact_momentum(
            one,
            one,
            np.zeros((1, 2)),
            np.zeros((1, 2)),
            np.eye(2)[:1],
            one,
            mu=0.2,
            law="coulomb",
            detector="grid",
        )
    with pytest.raises(ValueError, match="separation"):
        lr.contact_momentum(
            one,
            one,
            np.zeros((1, 2)),
            np.zeros((1, 2)),
            np.eye(2)[:1],
            None,
            mu=0.2,
            law="coulomb",
            detector="lr",
        )


def test_thin_cloud_normal_keeps_only_directions_the_cloud_spans():
    """A node beside a body's side sees one particle column per material, the upper column
    bulged 0.09 mm further out (as in ``lr_compression`` at 10 % strain): the classes are
    separated sideways too, and the plain fit takes that sideways normal; with ``thin`` the
    normal keeps only the direction the cloud spans (vertical), and d_LR is measured along it."""
    dx = 5e-3
    ys = np.array([43.75, 46.25, 48.75, 51.25, 53.75, 56.25]) * 1e-3
    xs = np.where(ys < 0.05, 1.25e-3, 1.16e-3)
    x = np.stack([xs, ys], axis=1)
    side = np.array([-1, -1, -1, 1, 1, 1], dtype=np.int8)
    F = np.broadcast_to(np.eye(2), (6, 2, 2)).copy()
    R0 = np.full((6, 2), 1.25e-3)
    args = (np.array([[-5e-3, 0.05]]), np.array([0, 6]), np.arange(6), side, x, F, R0, dx)
    plain = lr.lr_planes(*args)
    assert abs(plain.normal[0, 0]) > 0.9  # the sideways plane
    thin = lr.lr_planes(*args, thin=0.05)
    # within 1 degree of vertical (the thin axis of the cloud is itself tilted by the offset)
    assert thin.normal[0, 1] > np.cos(np.radians(1.0))
    assert abs(thin.separation[0]) < 0.01 * dx  # the rows touch along y (2.5 mm apart)
    # a cloud spanning both directions is left alone
    grid = np.array([[ix, iy] for ix in (-1.25e-3, 1.25e-3) for iy in ys])
    side2 = np.where(grid[:, 1] < 0.05, -1, 1).astype(np.int8)
    F2 = np.broadcast_to(np.eye(2), (12, 2, 2)).copy()
    args2 = (
        np.array([[0.0, 0.05]]),
        np.array([0, 12]),
        np.arange(12),
        side2,
        grid,
        F2,
        np.full((12, 2), 1.25e-3),
        dx,
    )
    assert np.allclose(lr.lr_planes(*args2).normal, lr.lr_planes(*args2, thin=0.05).normal, atol=0)
