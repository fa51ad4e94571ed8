"""Pictures of the bodies without ParaView: a snapshot sheet (PNG) and an animation (GIF, MP4).

Both are drawn from the frames of a run folder (the ``BODY.pvd`` collections and their VTU
files, read with meshio) or from a list of :class:`Snapshot` (made from ``Simulation.
frame_blocks()`` with :func:`snapshot_from_blocks`). FEM meshes are drawn as their cells (2D) or
boundary triangles (3D, mplot3d), coloured by the cells' von Mises stress; MPM particles as dots
coloured by theirs. One colour scale (0 to the largest stress of the frames drawn, in Pa, but at
least :data:`STRESS_FLOOR_PA`) and one set of axis limits serve every panel, so that panels
compare at a glance.

Choices:

- Round-off is not drawn as stress: the top of the colour scale is at least ``stress_floor``
  (default :data:`STRESS_FLOOR_PA` = 1 Pa), so a run whose every stress is round-off (a fixed
  plate that nothing touches, a scene at rest) is drawn in the colour of zero stress, and the
  colour bar's label says that the scale was floored and what the largest value was. No paper
  fixes this; the rule and its numbers are a choice, made from what the frames carry. The frames
  hold no material data, so the floor is absolute: round-off of an unstrained body, E eps with
  eps a few machine epsilons, stays below the lowest of the 256 colours even for E ~ 1e12 Pa,
  and round-off next to real stress already gets the lowest colour on the linear scale. The
  price: a run whose real stresses all stay below 1 Pa is drawn pale, with the label saying
  so (sizing measured: design note ``measurements``, snapshots);
  ``stress_floor=0`` restores the bare 0-to-largest scale.

- The sheet shows up to :data:`SHEET_PANELS` frames evenly spaced over the run (first and last
  frame included); only those VTU files are read, so it costs a fraction of a second. The last
  panel is the last *frame*: with ``every > 1`` the end state is drawn only when it was a frame.
- Figures are ``matplotlib.figure.Figure`` on an Agg canvas (never pyplot). GIFs are written by
  matplotlib's ``PillowWriter`` (Pillow comes with matplotlib); MP4 needs ``ffmpeg`` on the
  ``PATH`` (matplotlib's ``FFMpegWriter``); without it :func:`check_animation_format` raises a
  ``ValueError`` saying so, before a run starts (``bfemp run --animate mp4``: exit status 2).
- An animation draws every frame of the folder, at most ``max_frames`` (evenly subsampled).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np
from matplotlib import animation as mpl_animation
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from bfemp.io.vtk import atomic_path, read_pvd
from geometry._meshing_metrics import facets

__all__ = [
    "ANIMATION_FORMATS",
    "SHEET_PANELS",
    "STRESS_FLOOR_PA",
    "BodyView",
    "Snapshot",
    "check_animation_format",
    "read_snapshots",
    "snapshot_figure",
    "snapshot_from_blocks",
    "write_animation",
    "write_snapshot_sheet",
]

log = logging.getLogger(__name__)

#: animation formats of ``Simulation.run(animation=...)`` and ``bfemp run --animate``
ANIMATION_FORMATS = ("gif", "mp4")
#: number of frames on the snapshot sheet (at most)
SHEET_PANELS = 6
#: least top of the von Mises colour scale in Pa: stresses below it are round-off (module notes)
STRESS_FLOOR_PA = 1.0
_CMAP = "viridis"


@dataclass(frozen=True)
class BodyView:
    """One body at one instant, as drawn.

    Attributes:
        name: body name.
        points: ``(n, d)`` positions in m (d = 2 or 3).
        cells: ``(m, d + 1)`` cell vertex indices of a FEM mesh, or None for particles.
        von_mises: ``(m,)`` per cell (FEM) or ``(n,)`` per particle, in Pa.
    """

    name: str
    points: np.ndarray
    cells: np.ndarray | None
    von_mises: np.ndarray


@dataclass(frozen=True)
class Snapshot:
    """The bodies at time ``t`` (s)."""

    t: float
    bodies: tuple[BodyView, ...]

    @property
    def dim(self) -> int:
        """Spatial dimension of the bodies (2 or 3)."""
        return max(b.points.shape[1] for b in self.bodies)


def snapshot_from_blocks(t: float, blocks: Sequence[object]) -> Snapshot:
    """A snapshot from ``bfemp.io.Block`` s (e.g. ``Simulation.frame_blocks()``) at ``t`` s."""
    bodies = []
    for b in blocks:
        data = b.point_data if b.cells is None else b.cell_data
        vm = np.asarray(
            data.get("von_mises", np.zeros(len(b.points if b.cells is None else b.cells)))
        )
        bodies.append(BodyView(b.name, np.asarray(b.points), b.cells, vm))
    return Snapshot(float(t), tuple(bodies))


def _body_from_mesh(name: str, mesh: meshio.Mesh, dim: int) -> BodyView:
    block = mesh.cells[0]
    points = np.asarray(mesh.points[:, :dim], dtype=np.float64)
    if block.type in ("triangle", "tetra"):
        vm = mesh.cell_data.get("von_mises", [np.zeros(len(block.data))])[0]
        return BodyView(name, points, np.asarray(block.data), np.asarray(vm, dtype=np.float64))
    vm = mesh.point_data.get("von_mises", np.zeros(len(points)))
    return BodyView(name, points, None, np.asarray(vm, dtype=np.float64))


def _collections(out: Path) -> dict[str, dict[float, Path]]:
    pvds = sorted(Path(out).glob("*.pvd"))
    if not pvds:
        raise ValueError(f"{out} holds no .pvd collection: no frames to draw")
    return {p.stem: dict(read_pvd(p)) for p in pvds}


def _evenly(n: int, count: int) -> list[int]:
    """``count`` indices (at most ``n``) evenly spaced over ``range(n)``, first and last kept."""
    if n <= count:
        return list(range(n))
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, count)})


def read_snapshots(out: str | Path, count: int | None = SHEET_PANELS) -> list[Snapshot]:
    """Snapshots of up to ``count`` frames evenly spaced over the run in folder ``out``.

    ``count=None`` reads every frame. Only the VTU files of the chosen frames are read.
    """
    collections = _collections(Path(out))
    times = sorted({t for entries in collections.values() for t in entries})
    chosen = [times[i] for i in (_evenly(len(times), count) if count else range(len(times)))]
    meshes = {
        t: {name: meshio.read(e[t]) for name, e in collections.items() if t in e} for t in chosen
    }
    three_d = any(
        m.cells[0].type == "tetra" or np.any(m.points[:, 2] != 0.0)
        for frame in meshes.values()
        for m in frame.values()
    )
    dim = 3 if three_d else 2
    return [
        Snapshot(t, tuple(_body_from_mesh(n, m, dim) for n, m in frame.items()))
        for t, frame in meshes.items()
    ]


def _boundary_faces(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles ``(f, 3)`` of a tetrahedral mesh and the cell of each ``(f,)``."""
    faces, inverse, counts = facets(cells)  # the cells' faces, cell by cell
    once = counts[inverse] == 1
    return faces[once], np.repeat(np.arange(cells.shape[0]), 4)[once]


def _limits(snapshots: Sequence[Snapshot], dim: int) -> np.ndarray:
    """Common axis limits ``(dim, 2)`` in m over all bodies of all snapshots (5 % margin)."""
    pts = [b.points[np.isfinite(b.points).all(axis=1)] for s in snapshots for b in s.bodies]
    pts = np.concatenate([p for p in pts if p.size] or [np.zeros((1, dim))])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * max(float(np.max(hi - lo)), 1e-12)
    return np.stack([lo - pad, hi + pad], axis=1)


def _check_floor(stress_floor: float) -> float:
    if not (isinstance(stress_floor, int | float) and math.isfinite(stress_floor)):
        raise ValueError(f"stress_floor must be a finite stress in Pa, got {stress_floor!r}")
    if stress_floor < 0.0:
        raise ValueError(f"stress_floor must be >= 0 Pa, got {stress_floor!r}")
    return float(stress_floor)


def _norm(
    snapshots: Sequence[Snapshot], stress_floor: float = STRESS_FLOOR_PA
) -> tuple[Normalize, str]:
    """The von Mises colour scale, 0 to max(largest stress drawn, ``stress_floor``) in Pa, and
    the colour bar's label (which says when the floor set the top: round-off, module notes)."""
    floor = _check_floor(stress_floor)
    values = [b.von_mises[np.isfinite(b.von_mises)] for s in snapshots for b in s.bodies]
    vmax = max((float(np.abs(v).max()) for v in values if v.size), default=0.0)
    label = "von Mises stress [Pa]"
    if vmax >= floor and vmax > 0.0:
        return Normalize(vmin=0.0, vmax=vmax), label
    top = floor if floor > 0.0 else 1.0
    label += f"\n(scale floored at {top:g} Pa; max {vmax:.2g} Pa)"
    return Normalize(vmin=0.0, vmax=top), label


def _draw(ax: object, snap: Snapshot, norm: Normalize, limits: np.ndarray) -> None:
    """Draw the bodies of ``snap`` on ``ax`` (2D axes or mplot3d axes)."""
    cmap = _CMAP
    dim = limits.shape[0]
    n_particles = sum(len(b.points) for b in snap.bodies if b.cells is None)
    dot_size = float(np.clip(2000.0 / max(n_particles, 1), 0.3, 8.0))
    if dim == 3:
        ax.computed_zorder = False  # particles over the meshes, not hidden behind their faces
    meshes = [b for b in snap.bodies if b.cells is not None]
    clouds = [b for b in snap.bodies if b.cells is None]
    for body in meshes:
        p = body.points
        if dim == 2:
            ax.tripcolor(
                p[:, 0],
                p[:, 1],
                body.cells,
                facecolors=body.von_mises,
                cmap=cmap,
                norm=norm,
                edgecolors="0.25",
                linewidth=0.2,
            )
        else:
            from mpl_toolkits.mplot3d.art3d import Poly3DCollection

            faces, owner = _boundary_faces(body.cells)
            colours = ScalarMappable(norm=norm, cmap=cmap).to_rgba(body.von_mises[owner])
            ax.add_collection3d(
                Poly3DCollection(
                    p[faces], facecolors=colours, edgecolors="0.25", linewidths=0.1, zorder=1
                )
            )
    for body in clouds:
        p = body.points
        kw = {"depthshade": False} if dim == 3 else {}
        ax.scatter(
            *p[:, :dim].T,
            c=body.von_mises,
            cmap=cmap,
            norm=norm,
            s=dot_size,
            edgecolors="white" if dim == 3 else "none",  # unstressed dots stay visible on a mesh
            linewidths=0.3,
            zorder=2,
            **kw,
        )
    ax.set(xlim=limits[0], ylim=limits[1], xlabel="x [m]", ylabel="y [m]")
    if dim == 3:
        ax.set(zlim=limits[2], zlabel="z [m]")
        ax.set_box_aspect(tuple(np.maximum(limits[:, 1] - limits[:, 0], 1e-12)))
    else:
        ax.set_aspect("equal")
    ax.set_title(f"t = {snap.t:.4g} s", fontsize="medium")


#: inches of a panel's longer plot side; room for its title and x labels, for its y labels
_PANEL_IN, _DECOR_H_IN, _DECOR_W_IN = 4.0, 0.95, 0.95
#: inches the colour bar and the sheet title take; the sheet's preferred width / height
_COLORBAR_IN, _SUPTITLE_IN, _SHEET_RATIO = 1.4, 0.5, 1.6


def _sheet_grid(n: int, aspect: float) -> tuple[int, int, tuple[float, float]]:
    """Rows, columns and figure size (width, height) in inches of a sheet of ``n`` panels.

    Args:
        n: number of panels (>= 1).
        aspect: height / width of a panel's plot (the scene's, 2D; 0.9 for mplot3d).

    Every panel gets its plot (longer side :data:`_PANEL_IN`, the shorter one at least 0.3 in,
    the narrower one at least 1.2 in for its tick labels) plus a fixed allowance for its title
    and x labels above and below and its y labels at the side, so constrained layout never runs
    out of room (it stops laying out, and titles land on the x labels above, when a figure is
    too small: the cantilever sheet, 4.4 x 1.2 m). The column count is the one whose sheet is
    closest to :data:`_SHEET_RATIO` wide per high (log distance, 0.25 per empty slot): wide
    scenes stack in few columns, tall ones stand side by side. A layout choice, no paper's.
    """
    a = float(np.clip(aspect, 1e-3, 1e3))
    plot_w, plot_h = (_PANEL_IN, _PANEL_IN * a) if a <= 1.0 else (_PANEL_IN / a, _PANEL_IN)
    cell_w = max(plot_w, 1.2) + _DECOR_W_IN
    cell_h = max(plot_h, 0.3) + _DECOR_H_IN

    def size(ncols: int) -> tuple[int, float, float]:
        nrows = math.ceil(n / ncols)
        return nrows, ncols * cell_w + _COLORBAR_IN, nrows * cell_h + _SUPTITLE_IN

    def cost(ncols: int) -> float:
        nrows, w, h = size(ncols)
        return abs(math.log(w / h / _SHEET_RATIO)) + 0.25 * (nrows * ncols - n)

    ncols = min(range(1, n + 1), key=cost)
    nrows, w, h = size(ncols)
    return nrows, ncols, (w, h)


def snapshot_figure(
    snapshots: Sequence[Snapshot],
    *,
    title: str | None = None,
    stress_floor: float = STRESS_FLOOR_PA,
) -> Figure:
    """A sheet with one panel per snapshot and one von Mises colour bar.

    The grid (rows x columns) and the figure size follow the scene's aspect ratio
    (:func:`_sheet_grid`), so that titles, tick labels and axis labels of neighbouring panels
    never overlap, for wide scenes (a cantilever, 20:1) as for tall ones.

    Args:
        snapshots: the states drawn, one panel each.
        title: sheet title (default: the body names).
        stress_floor: least top of the colour scale in Pa (round-off is not drawn as stress,
            module notes); 0 for the bare 0-to-largest scale.

    Returns:
        the figure (Agg canvas); its panels are the axes titled ``t = ... s``.
    """
    if not snapshots:
        raise ValueError("snapshot_figure: no snapshot to draw")
    dim = max(s.dim for s in snapshots)
    n = len(snapshots)
    limits = _limits(snapshots, dim)
    span = np.maximum(limits[:, 1] - limits[:, 0], 1e-12)
    nrows, ncols, figsize = _sheet_grid(n, float(span[1] / span[0]) if dim == 2 else 0.9)
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    norm, label = _norm(snapshots, stress_floor)
    kw = {"projection": "3d"} if dim == 3 else {}
    axes = [fig.add_subplot(nrows, ncols, i + 1, **kw) for i in range(n)]
    for ax, snap in zip(axes, snapshots, strict=True):
        _draw(ax, snap, norm, limits)
    fig.colorbar(ScalarMappable(norm=norm, cmap=_CMAP), ax=axes, label=label, shrink=0.9)
    names = sorted({b.name for s in snapshots for b in s.bodies})
    fig.suptitle(title or f"bodies: {', '.join(names)}")
    return fig


def write_snapshot_sheet(
    out: str | Path,
    path: str | Path | None = None,
    *,
    snapshots: Sequence[Snapshot] | None = None,
    count: int = SHEET_PANELS,
    title: str | None = None,
    stress_floor: float = STRESS_FLOOR_PA,
) -> Path:
    """Write the snapshot sheet PNG (default ``{out}/snapshots.png``) of run folder ``out``.

    Args:
        out: the run folder (its frames are read unless ``snapshots`` are given).
        path: the PNG file.
        snapshots: draw these instead of the folder's frames.
        count: number of frames drawn (evenly spaced over the run).
        title: sheet title (default: the body names).
        stress_floor: least top of the colour scale in Pa (module notes).
    """
    path = Path(out) / "snapshots.png" if path is None else Path(path)
    _check_floor(stress_floor)
    snaps = read_snapshots(out, count) if snapshots is None else list(snapshots)
    fig = snapshot_figure(snaps, title=title, stress_floor=stress_floor)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    log.info("snapshot sheet of %d frames written to %s", len(snaps), path)
    return path


def check_animation_format(fmt: str) -> str:
    """``fmt`` if it is an animation format that can be written here, else an error.

    Raises:
        ValueError: ``fmt`` is not ``"gif"`` or ``"mp4"``, or is ``"mp4"`` without ``ffmpeg`` on
            the ``PATH`` (a choice the user can change: the command line exits with 2).
    """
    if fmt not in ANIMATION_FORMATS:
        raise ValueError(f"animation must be 'gif' or 'mp4', got {fmt!r}")
    if fmt == "mp4" and not mpl_animation.FFMpegWriter.isAvailable():
        raise ValueError(
            "animation='mp4' needs ffmpeg on the PATH (not found); install ffmpeg or use 'gif'"
        )
    return fmt


def write_animation(
    out: str | Path,
    fmt: str = "gif",
    path: str | Path | None = None,
    *,
    fps: float = 10.0,
    max_frames: int = 200,
    stress_floor: float = STRESS_FLOOR_PA,
) -> Path:
    """Write an animation of the frames of run folder ``out`` (default ``{out}/animation.FMT``).

    Args:
        out: the run folder.
        fmt: ``"gif"`` (Pillow) or ``"mp4"`` (ffmpeg).
        path: the file (its suffix should be ``.FMT``).
        fps: frames per second.
        max_frames: at most this many frames (evenly subsampled).
        stress_floor: least top of the colour scale in Pa (module notes).
    """
    check_animation_format(fmt)
    _check_floor(stress_floor)
    path = Path(out) / f"animation.{fmt}" if path is None else Path(path)
    snaps = read_snapshots(out, None)
    snaps = [snaps[i] for i in _evenly(len(snaps), max_frames)]
    dim = max(s.dim for s in snaps)
    limits, (norm, label) = _limits(snaps, dim), _norm(snaps, stress_floor)
    fig = Figure(figsize=(6.4, 5.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d") if dim == 3 else fig.add_subplot()
    fig.colorbar(ScalarMappable(norm=norm, cmap=_CMAP), ax=ax, label=label)

    def update(i: int) -> list:
        ax.clear()
        _draw(ax, snaps[i], norm, limits)
        return []

    anim = mpl_animation.FuncAnimation(fig, update, frames=len(snaps), blit=False)
    writer = (
        mpl_animation.PillowWriter(fps=fps) if fmt == "gif" else mpl_animation.FFMpegWriter(fps=fps)
    )
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        anim.save(tmp, writer=writer, dpi=90)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    log.info("animation of %d frames written to %s", len(snaps), path)
    return path
