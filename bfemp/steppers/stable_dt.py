"""The stable (CFL) time step of the explicit strategies, per body, and who sets it.

An explicit step is stable while a wave (or a particle) crosses less than one element per step:

- FEM (central differences, lumped masses): dt <= s_fem h_min / c_p, with h_min the smallest
  altitude of a cell in its current shape (2D: 2 A / l_max, twice the area over the longest
  edge; 3D: 3 V / A_max, three times the volume over the largest face) and c_p =
  ``material.p_wave_speed`` = sqrt((lam + 2 mu) / rho). The exact bound of a linear simplex with
  lumped masses is 2 / omega_max, a little above h_min / c_p for well-shaped cells;
  s_fem = 0.5 (the default ``SingleFieldOptions.cfl_safety_fem``) also covers slivers and the
  stiffening of Neo-Hookean cells under compression, which this small-strain c_p ignores.
- MPM (quadratic B-splines, USL): dt <= s_mpm dx / max_p (c_p + |v_p|), the particle speed added
  so that no particle crosses more than a fraction of a cell per step. s_mpm = 0.4 (default
  ``cfl_safety_mpm``) is our choice; neither the augury nor the LR paper gives one.

Cells whose every node is scripted are skipped (nothing integrates them). The bound is refused
or reported with the body and the cell or particle that sets it (:class:`StableStep`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from bfemp.model import Model
from bfemp.state import State

__all__ = ["StableStep", "cell_altitudes", "stable_time_step"]


@dataclass(frozen=True)
class StableStep:
    """The stable step and what sets it.

    Attributes:
        dt: the bound in s (safety factor included); inf when nothing limits it.
        body: name of the body that sets it ("" when none).
        kind: ``"fem"`` (a cell) or ``"mpm"`` (a particle); "" when none.
        index: the cell's or particle's index within its body (-1 when none).
        length: the cell's smallest altitude, or the grid dx, in m.
        speed: the P-wave speed (FEM) or P-wave plus particle speed (MPM) in m/s.
        safety: the safety factor applied.
    """

    dt: float
    body: str = ""
    kind: str = ""
    index: int = -1
    length: float = float("nan")
    speed: float = float("nan")
    safety: float = float("nan")

    @property
    def limit(self) -> float:
        """The bound without the safety factor, length / speed in s (CFL number 1)."""
        return self.dt / self.safety if self.kind else math.inf

    def describe(self) -> str:
        """'... s, set by cell 17 of fem body 'bar' (altitude ..., c_p ..., safety 0.5)'."""
        if not self.kind:
            return "inf (no body limits the step)"
        if self.kind == "fem":
            what = f"cell {self.index} of fem body '{self.body}'"
            how = f"smallest altitude {self.length:.6g} m, c_p {self.speed:.6g} m/s"
        else:
            what = f"particle {self.index} of mpm body '{self.body}'"
            how = f"dx {self.length:.6g} m, c_p + |v_p| {self.speed:.6g} m/s"
        return f"{self.dt:.6g} s, set by {what} ({how}, safety {self.safety:g})"


def cell_altitudes(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Smallest altitude of each simplex ``(M,)`` in m at node positions ``x (N, d)``.

    2D: 2 A / l_max; 3D: 3 V / A_max,face. Inverted or degenerate cells give 0. A numba loop
    over the cells (the explicit engine checks the CFL bound every step).
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    if x.shape[1] == 2:
        return _altitudes_2d(x, cells)
    return _altitudes_3d(x, cells)


@njit(cache=True)
def _altitudes_2d(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    out = np.empty(cells.shape[0])
    for m in range(cells.shape[0]):
        i, j, k = cells[m, 0], cells[m, 1], cells[m, 2]
        ax, ay = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1]
        bx, by = x[k, 0] - x[i, 0], x[k, 1] - x[i, 1]
        area = 0.5 * abs(ax * by - ay * bx)
        cx, cy = x[k, 0] - x[j, 0], x[k, 1] - x[j, 1]
        longest = math.sqrt(max(ax * ax + ay * ay, cx * cx + cy * cy, bx * bx + by * by))
        out[m] = 2.0 * area / longest
    return out


@njit(cache=True)
def _tri_area(x: np.ndarray, a: int, b: int, c: int) -> float:
    ux, uy, uz = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2]
    vx, vy, vz = x[c, 0] - x[a, 0], x[c, 1] - x[a, 1], x[c, 2] - x[a, 2]
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    return 0.5 * math.sqrt(nx * nx + ny * ny + nz * nz)


@njit(cache=True)
def _altitudes_3d(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    out = np.empty(cells.shape[0])
    for m in range(cells.shape[0]):
        n0, n1, n2, n3 = cells[m, 0], cells[m, 1], cells[m, 2], cells[m, 3]
        e = np.empty((3, 3))
        for a, n in enumerate((n1, n2, n3)):
            for c in range(3):
                e[a, c] = x[n, c] - x[n0, c]
        c0 = e[1, 1] * e[2, 2] - e[1, 2] * e[2, 1]  # e1 x e2, as np.cross
        c1 = e[1, 2] * e[2, 0] - e[1, 0] * e[2, 2]
        c2 = e[1, 0] * e[2, 1] - e[1, 1] * e[2, 0]
        det = e[0, 0] * c0 + e[0, 1] * c1 + e[0, 2] * c2
        volume = abs(det) / 6.0
        largest = max(
            _tri_area(x, n1, n2, n3),
            _tri_area(x, n0, n2, n3),
            _tri_area(x, n0, n1, n3),
            _tri_area(x, n0, n1, n2),
        )
        out[m] = 3.0 * volume / largest
    return out


def _fem_bound(model: Model, state: State, safety: float) -> StableStep:
    moving = ~np.all(model.fem_prescribed[model.fem_cells], axis=1)
    if model.fem_cells.shape[0] == 0 or not moving.any():
        return StableStep(math.inf)
    speed_b = np.array([b.material.p_wave_speed for b in model.fem_bodies])
    cells = np.flatnonzero(moving)
    h = cell_altitudes(state.fem_x, model.fem_cells[cells])
    c = speed_b[model.fem_cell_body[cells]]
    dt = safety * h / c
    k = int(np.argmin(dt))
    body = model.fem_bodies[int(model.fem_cell_body[cells[k]])]
    index = int(cells[k] - body.cells.start)
    return StableStep(float(dt[k]), body.name, "fem", index, float(h[k]), float(c[k]), safety)


def _mpm_bound(model: Model, state: State, safety: float) -> StableStep:
    if model.n_particles == 0:
        return StableStep(math.inf)
    speed_b = np.array([b.material.p_wave_speed for b in model.mpm_bodies])
    k, speed = _fastest_particle(speed_b, model.mpm_particle_body, state.mpm_v)
    body = model.mpm_bodies[int(model.mpm_particle_body[k])]
    dx = model.grid.dx
    return StableStep(
        safety * dx / speed, body.name, "mpm", int(k - body.particles.start), dx, speed, safety
    )


@njit(cache=True)
def _fastest_particle(speed_b: np.ndarray, body: np.ndarray, v: np.ndarray) -> tuple[int, float]:
    """The particle k with the largest c_p + |v_p| (``speed_b (B,)`` m/s per body, ``body
    (P,)``, ``v (P, d)`` m/s; the first of equals, the first NaN, as ``np.argmax``) and that
    speed in m/s; |v_p| sums the squares in axis order, as ``np.einsum`` does.

    One serial pass: the numpy route took 0.2 ms a step at 33k particles, a tenth of an explicit
    step, this 0.03 ms; a parallel pass costs more in thread wake-ups than it saves."""
    k, top = 0, -np.inf
    for p in range(v.shape[0]):
        sq = 0.0
        for r in range(v.shape[1]):
            sq += v[p, r] * v[p, r]
        speed = speed_b[body[p]] + math.sqrt(sq)
        if math.isnan(speed):
            return p, speed
        if speed > top:
            k, top = p, speed
    return k, top


def stable_time_step(
    model: Model, state: State, *, fem_safety: float = 0.5, mpm_safety: float = 0.4
) -> StableStep:
    """The explicit stable step of ``state`` over all bodies, and the cell or particle that
    sets it (see the module docstring); ``dt = inf`` for a scene with nothing to integrate."""
    fem = _fem_bound(model, state, fem_safety)
    mpm = _mpm_bound(model, state, mpm_safety)
    return fem if fem.dt <= mpm.dt else mpm
