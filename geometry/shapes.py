"""Mesh generators for the benchmark shapes; ``h`` is the target edge length in metres.

Every generator returns a positively oriented :class:`~geometry.mesh.TriMesh` (2D) or
:class:`~geometry.mesh.TetMesh` (3D) whose boundary nodes lie exactly (to round-off) on the
analytic boundary. Choices made here:

- ``rectangle`` / ``box``: structured, ``n_x = ceil(width / h)`` cells per side, so a large ``h``
  gives one cell per side (e.g. a rigid plate of 4 nodes and 2 triangles). Cells have aspect
  ratio <= 2 (min angle >= 26.5 deg) when ``h`` does not exceed the shortest side.
- ``disk``: ring k (k = 0..K) at radius ``k R / K`` with ``6 k`` nodes (a hexagonal pattern bent
  onto circles), consecutive rings joined by band triangulation; min angle about 44 deg.
- ``ring`` / ``semicircular_ring``: circles (arcs over angles 0..pi) spaced ``dr <= h sqrt(3)/2``
  apart carrying nodes ``2 dr / sqrt(3)`` apart, i.e. near-equilateral triangles with edges about
  ``h``; a layer thinner than ``h`` thus also refines tangentially. Min angle about 40 deg.
- ``spherical_shell``: equiangular cubed sphere (``N = ceil(pi r_outer / (2 h))`` cells per cube
  edge) of hexahedra in radial layers about ``min(h, tangential spacing)`` thick (geometrically
  graded where the tangential spacing is below h), each hex split into 6 tetrahedra conformingly
  (see :mod:`geometry._meshing_build`); cube-seam nodes are merged exactly through their
  integer lattice coordinates.
- ``sine_strip``: structured mapped mesh; nodes are equally spaced in arc length along the wavy
  profile and stacked vertically; every quad is cut by its shorter diagonal, so the min angle is
  about ``90 deg - atan(max slope)`` (32 deg for the paper's sine boundary).
"""

from __future__ import annotations

import numpy as np

from geometry import _meshing_build as mb
from geometry._checks import positive as _positive
from geometry._checks import vector as _vector
from geometry._meshing_metrics import unique_rows
from geometry.mesh import TetMesh, TriMesh

_SQRT3_2 = np.sqrt(3.0) / 2.0


def _radii(r_inner: object, r_outer: object, h: float) -> np.ndarray:
    """Radii of the node circles of an annulus, (K + 1,), spacing ``<= h sqrt(3) / 2``."""
    r_in, r_out = _positive("r_inner", r_inner), _positive("r_outer", r_outer)
    if r_out <= r_in:
        raise ValueError(f"r_outer must exceed r_inner, got r_inner={r_in}, r_outer={r_out}")
    layers = int(np.ceil((r_out - r_in) / (_SQRT3_2 * h) - 1e-9))
    return np.linspace(r_in, r_out, max(layers, 1) + 1)


def _shell_radii(r_in: float, r_out: float, h: float, c: float) -> np.ndarray:
    """Radii (L + 1,) of the radial node layers of a cubed-sphere shell, metres.

    The layer spacing follows ``dr(r) = min(h, c r)``: never more than h, nor more than the
    tangential spacing ``c r`` (c = (pi/2) / N), so cells stay near-cubic even for
    ``r_inner << r_outer``. With the stretched coordinate ``s(r) = int dr / min(h, c r)``, i.e.
    ``ln(r) / c`` below ``r* = h / c`` and ``ln(r*) / c + (r - r*) / h`` above it, the layers are
    equally spaced in s, their number being ``s(r_out) - s(r_in)`` rounded (at least 1).
    """
    r_star = h / c

    def s(r: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=np.float64)
        return np.where(r <= r_star, np.log(r) / c, np.log(r_star) / c + (r - r_star) / h)

    def s_inv(t: np.ndarray) -> np.ndarray:
        t_star = np.log(r_star) / c
        return np.where(t <= t_star, np.exp(c * t), r_star + h * (t - t_star))

    s_in, s_out = float(s(r_in)), float(s(r_out))
    layers = max(int(np.round(s_out - s_in)), 1)
    radii = s_inv(np.linspace(s_in, s_out, layers + 1))
    radii[0], radii[-1] = r_in, r_out
    return radii


def rectangle(
    lower: tuple[float, float],
    upper: tuple[float, float],
    h: float,
    *,
    diagonals: str = "alternating",
) -> TriMesh:
    """Structured triangle mesh of the rectangle ``[x0, x1] x [y0, y1]`` (metres).

    Args:
        lower: (x0, y0) lower-left corner, metres.
        upper: (x1, y1) upper-right corner, metres; ``upper > lower`` componentwise.
        h: target edge length (m); ``ceil(width / h)`` by ``ceil(height / h)`` quads.
        diagonals: ``"alternating"`` (one diagonal per quad, checkerboard, 2 triangles per quad)
            or ``"crossed"`` (both diagonals through a centre node, 4 triangles per quad).
    """
    lo, hi, h = _vector("lower", lower, 2), _vector("upper", upper, 2), _positive("h", h)
    if np.any(hi <= lo):
        raise ValueError(f"upper must exceed lower in x and y, got lower={lo}, upper={hi}")
    if diagonals not in ("alternating", "crossed"):
        raise ValueError(f"diagonals must be 'alternating' or 'crossed', got {diagonals!r}")
    nx, ny = (int(n) for n in np.maximum(np.ceil((hi - lo) / h - 1e-9), 1))
    x, y = np.meshgrid(np.linspace(lo[0], hi[0], nx + 1), np.linspace(lo[1], hi[1], ny + 1))
    points = np.stack([x.ravel(), y.ravel()], axis=1)
    if diagonals == "crossed":
        xc, yc = np.meshgrid(0.5 * (x[0, 1:] + x[0, :-1]), 0.5 * (y[1:, 0] + y[:-1, 0]))
        points = np.concatenate([points, np.stack([xc.ravel(), yc.ravel()], axis=1)])
        return TriMesh(points, mb.grid_triangles_crossed(nx, ny))
    return TriMesh(points, mb.grid_triangles(nx, ny, mb.checkerboard(nx, ny)))


def box(lower: tuple[float, float, float], upper: tuple[float, float, float], h: float) -> TetMesh:
    """Structured tetrahedral mesh of the box ``[x0, x1] x [y0, y1] x [z0, z1]`` (metres).

    ``ceil(side / h)`` hexahedra per side, each split into 6 tetrahedra around its main diagonal
    (Kuhn split: the conforming rule of :func:`geometry._meshing_build.split_hexes`).

    Args:
        lower: (x0, y0, z0) corner, metres.
        upper: (x1, y1, z1) opposite corner, metres; ``upper > lower`` componentwise.
        h: target edge length, metres.
    """
    lo, hi, h = _vector("lower", lower, 3), _vector("upper", upper, 3), _positive("h", h)
    if np.any(hi <= lo):
        raise ValueError(f"upper must exceed lower in x, y and z, got lower={lo}, upper={hi}")
    n = np.maximum(np.ceil((hi - lo) / h - 1e-9), 1).astype(np.int64)
    axes = [np.linspace(lo[a], hi[a], n[a] + 1) for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    k, j, i = (g.ravel() for g in np.meshgrid(*(np.arange(m) for m in n[::-1]), indexing="ij"))

    def node(di: int, dj: int, dk: int) -> np.ndarray:
        return ((k + dk) * (n[1] + 1) + (j + dj)) * (n[0] + 1) + (i + di)

    hexes = np.stack([node(*c) for c in mb.HEX_CORNERS], axis=1)
    return TetMesh(points, mb.split_hexes(points, hexes))


def disk(center: tuple[float, float], radius: float, h: float) -> TriMesh:
    """Triangle mesh of the disk of ``radius`` (m) about ``center`` (2,) (m); edge length ~h (m).

    ``K = ceil(radius / h)`` rings; ring k has ``6 k`` nodes at radius ``k radius / K``.
    """
    c, radius, h = _vector("center", center, 2), _positive("radius", radius), _positive("h", h)
    rings = max(int(np.ceil(radius / h - 1e-9)), 1)
    k = np.arange(rings + 1)
    points, cells = mb.ring_stack(c, radius * k / rings, np.maximum(6 * k, 1), 2.0 * np.pi)
    return TriMesh(points, cells)


def ring(center: tuple[float, float], r_inner: float, r_outer: float, h: float) -> TriMesh:
    """Triangle mesh of the annulus ``r_inner <= |x - center| <= r_outer`` (metres); edges ~h."""
    c, h = _vector("center", center, 2), _positive("h", h)
    radii = _radii(r_inner, r_outer, h)
    spacing = (radii[1] - radii[0]) / _SQRT3_2
    counts = np.maximum(np.round(2.0 * np.pi * radii / spacing), 3).astype(np.int64)
    return TriMesh(*mb.ring_stack(c, radii, counts, 2.0 * np.pi))


def semicircular_ring(
    center: tuple[float, float], r_inner: float, r_outer: float, h: float
) -> TriMesh:
    """Upper half (angles 0..pi) of the annulus about ``center``, radii in metres; edges ~h (m).

    The two feet are the segments ``[center_x + r_inner, center_x + r_outer]`` and its mirror on
    the line ``y = center_y``.
    """
    c, h = _vector("center", center, 2), _positive("h", h)
    radii = _radii(r_inner, r_outer, h)
    spacing = (radii[1] - radii[0]) / _SQRT3_2
    counts = np.maximum(np.round(np.pi * radii / spacing), 2).astype(np.int64)
    return TriMesh(*mb.ring_stack(c, radii, counts, np.pi))


def spherical_shell(
    center: tuple[float, float, float], r_inner: float, r_outer: float, h: float
) -> TetMesh:
    """Tetrahedral mesh of the shell ``r_inner <= |x - center| <= r_outer`` (metres); edges ~h.

    Equiangular cubed sphere: a cube-surface lattice point with coordinates ``c`` in [-1, 1]^3
    maps to the direction of ``tan(pi c / 4)``, which keeps the patch cells near-square.
    """
    c, h = _vector("center", center, 3), _positive("h", h)
    r_in, r_out = _positive("r_inner", r_inner), _positive("r_outer", r_outer)
    if r_out <= r_in:
        raise ValueError(f"r_outer must exceed r_inner, got r_inner={r_in}, r_outer={r_out}")
    n = max(int(np.ceil(0.5 * np.pi * r_out / h - 1e-9)), 1)
    # Cube-surface lattice: face (axis a, side s) holds the points with coordinate a equal to s.
    p, q = (g.ravel() for g in np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij"))
    lattice = []
    for axis in range(3):
        others = [b for b in range(3) if b != axis]
        for side in (0, n):
            face = np.empty((p.size, 3), dtype=np.int64)
            face[:, axis], face[:, others[0]], face[:, others[1]] = side, p, q
            lattice.append(face)
    lattice = np.concatenate(lattice)
    nodes, inverse, _ = unique_rows(lattice)
    local = np.arange(n * n)
    pi, qi = local // n, local % n
    at = pi * (n + 1) + qi  # each quad's corners cycle (p,q) (p+1,q) (p+1,q+1) (p,q+1)
    face_quads = np.stack([at, at + n + 1, at + n + 2, at + 1], axis=1)
    quads = inverse[(np.arange(6)[:, None, None] * p.size + face_quads).reshape(-1, 4)]
    direction = np.tan(0.25 * np.pi * (2.0 * nodes / n - 1.0))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radii = _shell_radii(r_in, r_out, h, 0.5 * np.pi / n)
    points = (c + radii[:, None, None] * direction[None]).reshape(-1, 3)
    n_s = nodes.shape[0]
    base = (np.arange(radii.size - 1) * n_s)[:, None, None]
    hexes = np.concatenate([quads + base, quads + base + n_s], axis=2).reshape(-1, 8)
    return TetMesh(points, mb.split_hexes(points, hexes))


def sine_strip(
    x_range: tuple[float, float],
    y_base: float,
    thickness: float,
    amplitude: float,
    wavelength: float,
    h: float,
    profile: str = "bottom",
    other_side: str = "offset",
) -> TriMesh:
    """Strip whose ``profile`` side follows ``y = y_base + amplitude cos(2 pi x / wavelength)``.

    Args:
        x_range: (x0, x1) horizontal extent, metres, x1 > x0.
        y_base: mean height of the wavy side, metres.
        thickness: vertical thickness of the strip, metres (> 0).
        amplitude: wave amplitude, metres (any sign; 0 gives a rectangle).
        wavelength: wave length, metres (> 0).
        h: target edge length, metres.
        profile: ``"bottom"`` (the body lies above the wave) or ``"top"`` (below it).
        other_side: ``"offset"`` (the wave shifted vertically by ``thickness``) or ``"flat"``
            (a straight line ``thickness`` beyond the wave's extreme, so the thinnest part is
            ``thickness``).
    """
    xr = _vector("x_range", x_range, 2)
    if xr[1] <= xr[0]:
        raise ValueError(f"x_range must be increasing, got {tuple(xr)}")
    y_base = float(_vector("y_base", [y_base], 1)[0])
    amp = float(_vector("amplitude", [amplitude], 1)[0])
    thickness, wavelength = _positive("thickness", thickness), _positive("wavelength", wavelength)
    h = _positive("h", h)
    if profile not in ("bottom", "top"):
        raise ValueError(f"profile must be 'bottom' or 'top', got {profile!r}")
    if other_side not in ("offset", "flat"):
        raise ValueError(f"other_side must be 'offset' or 'flat', got {other_side!r}")
    k = 2.0 * np.pi / wavelength

    def wave(x: np.ndarray) -> np.ndarray:
        return y_base + amp * np.cos(k * x)

    # Equal arc-length spacing along the wave: invert s(x) sampled finely (64 per h or per
    # wavelength, whichever is finer).
    n_fine = 64 * int(np.ceil((xr[1] - xr[0]) / min(h, wavelength))) + 1
    xf = np.linspace(xr[0], xr[1], n_fine)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xf), np.diff(wave(xf))))])
    nx = max(int(np.ceil(arc[-1] / h - 1e-9)), 1)
    x = np.interp(np.linspace(0.0, arc[-1], nx + 1), arc, xf)
    x[0], x[-1] = xr
    sign = 1.0 if profile == "bottom" else -1.0
    y_wave = wave(x)
    if other_side == "offset":
        y_other = y_wave + sign * thickness
    else:
        y_other = np.full_like(x, y_base + sign * (abs(amp) + thickness))
    ny = max(int(np.ceil(np.max(np.abs(y_other - y_wave)) / h - 1e-9)), 1)
    # Rows from the lower side (j = 0) to the upper side (j = ny), nodes j * (nx + 1) + i.
    lower, upper = (y_wave, y_other) if profile == "bottom" else (y_other, y_wave)
    s = np.linspace(0.0, 1.0, ny + 1)[:, None]
    y = (1.0 - s) * lower[None, :] + s * upper[None, :]
    points = np.stack([np.broadcast_to(x, y.shape).ravel(), y.ravel()], axis=1)
    return TriMesh(points, mb.grid_triangles(nx, ny, mb.shorter_diagonal(points, nx, ny)))
