"""VTK output of simulation frames: one ``.vtu`` file per block and frame, one ``.pvd`` per block.

A *block* is one body (a FEM mesh or an MPM particle cloud) at one instant, given as plain arrays.
:class:`FrameWriter` writes, for frame index ``i`` at time ``t``::

    {out_dir}/{name}/{prefix}_{i:05d}.vtu     # via meshio, zlib-compressed binary VTU
    {out_dir}/{name}.pvd                       # ParaView collection listing every frame of `name`

Choices (ParaView is the reader we target):

- Cell types come from the cell width ``k`` and the dimension ``d``: ``k = 1`` vertex, ``k = 2``
  line, ``k = 3`` triangle, ``k = 4`` tetra (3D only). ``cells=None`` is a point cloud, written
  as one vertex cell per point, so that cell data of a point cloud is per point.
- 2D points get ``z = 0``; 2D vector data ``(n, 2)`` (point or cell data) gets a zero third
  component so that ParaView shows them as vectors. Tensor data ``(n, a, b)`` is flattened
  row-major to ``a * b`` components (2D tensors are *not* padded to 3x3: which value ``zz`` should
  take, 0 or 1, depends on the quantity).
- Boolean data is written as ``uint8``; other real dtypes are kept.
- Every file is written atomically (:func:`atomic_path`): a reader, or an interrupted run, sees
  either the previous complete file or the new complete one. The PVD of a block is rewritten
  after each frame, so it is valid at any time. A frame whose ``.vtu`` files fail to write does
  not advance the frame index and leaves every PVD unchanged.
- Frame times must increase strictly. ``resume=True`` continues the collections already in
  ``out_dir`` (restart from a checkpoint): numbering continues after the highest existing index,
  and entries at or after the time of a new frame are dropped from that block's collection.
  Without ``resume`` the collections start empty; stale ``.vtu`` files of an earlier run are left
  on disk (never deleted) but no longer listed.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import meshio
import numpy as np

from bfemp.errors import warn_user

logger = logging.getLogger(__name__)

_NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")
_NEW_FILE_MODE = 0o644


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it onto ``path`` when the block succeeds.

    The temporary file lives in the same directory (``os.replace`` is atomic only within one file
    system); its name is hidden and ends in ``.tmp``. On any exception it is removed and ``path``
    keeps its previous content. Parent directories are created. The final file gets the mode of
    the file it replaces, or 0o644.

    Args:
        path: final file path.

    Yields:
        the temporary path to write to (it exists, empty).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        mode = path.stat().st_mode & 0o777 if path.exists() else _NEW_FILE_MODE
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`atomic_path`); returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def _validate_name(what: str, name: object) -> str:
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise ValueError(
            f"{what} {name!r} is not a valid name: use letters, digits, '_', '.', '-' "
            "(not starting with '.' or '-')"
        )
    return name


def _check_data(block: str, kind: str, key: object, value: object, n: int) -> np.ndarray:
    """Check one named data array: real, of shape ``(n,)``, ``(n, c)`` or ``(n, a, b)``."""
    if not isinstance(key, str) or not key:
        raise ValueError(f"block {block!r}: {kind} name {key!r} must be a non-empty string")
    arr = np.asarray(value)
    where = f"block {block!r}: {kind} {key!r}"
    if arr.dtype.kind not in "biuf":  # bool, signed or unsigned integer, floating
        raise ValueError(f"{where} has dtype {arr.dtype}; expected real numbers")
    if arr.ndim < 1 or arr.ndim > 3:
        raise ValueError(f"{where} has shape {arr.shape}; expected (n,), (n, c) or (n, a, b)")
    if arr.shape[0] != n:
        raise ValueError(f"{where} has first dimension {arr.shape[0]}, expected {n}")
    return np.ascontiguousarray(arr)


def _vtk_data(arr: np.ndarray, dim: int) -> np.ndarray:
    """Convert a checked data array to what the VTU file holds (see the module docstring)."""
    n = arr.shape[0]
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8)
    if arr.ndim == 3:
        arr = arr.reshape(n, arr.shape[1] * arr.shape[2])
    elif arr.ndim == 2 and dim == 2 and arr.shape[1] == 2:
        # In-plane vector of a 2D (plane strain) body: its out-of-plane component is zero.
        arr = np.concatenate([arr, np.zeros((n, 1), dtype=arr.dtype)], axis=1)
    return np.ascontiguousarray(arr)


def _check_points(block: str, points: object) -> np.ndarray:
    """Check positions: a real ``(n, 2)`` or ``(n, 3)`` array with ``n >= 1``; return float64."""
    arr = np.asarray(points)
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"block {block!r}: points have dtype {arr.dtype}; expected real")
    if arr.ndim != 2 or arr.shape[1] not in (2, 3) or arr.shape[0] == 0:
        raise ValueError(
            f"block {block!r}: points have shape {arr.shape}; expected (n, 2) or (n, 3) with n >= 1"
        )
    finite = np.isfinite(arr)
    if not np.all(finite):
        warn_user(
            f"NON_FINITE_POINTS: block {block!r}: {int(np.sum(~finite))} non-finite point "
            "coordinates written",
            logger=logger,
        )
    return np.ascontiguousarray(arr, dtype=np.float64)


def _check_cells(block: str, cells: object, n: int, dim: int) -> np.ndarray:
    """Check connectivity: an integer ``(m, k)`` array, k in 1..4 (4 only in 3D), indices < n."""
    arr = np.asarray(cells)
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"block {block!r}: cells have dtype {arr.dtype}; expected integer")
    if arr.ndim != 2 or arr.shape[1] not in (1, 2, 3, 4) or (arr.shape[1] == 4 and dim != 3):
        raise ValueError(
            f"block {block!r}: cells have shape {arr.shape} for {dim}D points; expected (m, k) "
            "with k = 1 (vertex), 2 (line), 3 (triangle) or 4 (tetra, 3D only)"
        )
    bad = np.flatnonzero(np.any((arr < 0) | (arr >= n), axis=1))
    if bad.size:
        raise ValueError(f"block {block!r}: cells {bad[:5].tolist()} index outside [0, {n})")
    return np.ascontiguousarray(arr, dtype=np.int64)


@dataclass(frozen=True, eq=False)
class Block:
    """One body at one instant: a mesh or a point cloud with data, in plain arrays.

    Attributes:
        name: block name, used for the sub-directory and the ``.pvd`` file
            (letters, digits, ``_ . -``).
        points: ``(n, d)`` float, ``d`` in {2, 3}: point positions [m]; ``n >= 1``.
        cells: ``(m, k)`` int indices into ``points`` (k = 1 vertex, 2 line, 3 triangle,
            4 tetra in 3D), or ``None`` for a point cloud (one vertex cell per point).
        point_data: name -> ``(n,)``, ``(n, c)`` or ``(n, a, b)`` array, values per point
            (SI units of the quantity).
        cell_data: name -> ``(m, ...)`` array, values per cell (``m = n`` for a point cloud).

    Arrays are validated on construction (``points`` converted to float64, ``cells`` to int64,
    data arrays kept as given); a bad array raises ``ValueError`` naming the block and the field.
    The conversions for the file (padding, flattening) happen in :meth:`to_meshio`.
    """

    name: str
    points: np.ndarray
    cells: np.ndarray | None = None
    point_data: Mapping[str, np.ndarray] = field(default_factory=dict)
    cell_data: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        name = _validate_name("block name", self.name)
        points = _check_points(name, self.points)
        n, dim = points.shape
        cells = None if self.cells is None else _check_cells(name, self.cells, n, dim)
        m = n if cells is None else cells.shape[0]
        for attr, count in (("point_data", n), ("cell_data", m)):
            data = getattr(self, attr)
            if not isinstance(data, Mapping):
                raise ValueError(f"block {name!r}: {attr} must be a mapping name -> array")
            checked = {k: _check_data(name, attr, k, v, count) for k, v in data.items()}
            object.__setattr__(self, attr, checked)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "cells", cells)

    @property
    def dim(self) -> int:
        """Spatial dimension ``d`` of the points (2 or 3)."""
        return int(self.points.shape[1])

    @property
    def cell_type(self) -> str:
        """meshio cell type name of the written cells ("vertex", "line", "triangle", "tetra")."""
        k = 1 if self.cells is None else self.cells.shape[1]
        return ("vertex", "line", "triangle", "tetra")[k - 1]

    def to_meshio(self) -> meshio.Mesh:
        """The block as a ``meshio.Mesh``: points padded to 3D, cells typed, data converted."""
        points = self.points
        n, dim = points.shape
        if dim == 2:
            points = np.concatenate([points, np.zeros((n, 1))], axis=1)
        cells = np.arange(n, dtype=np.int64).reshape(n, 1) if self.cells is None else self.cells
        return meshio.Mesh(
            points,
            [(self.cell_type, cells)],
            point_data={k: _vtk_data(v, dim) for k, v in self.point_data.items()},
            cell_data={k: [_vtk_data(v, dim)] for k, v in self.cell_data.items()},
        )


def _write_pvd(path: Path, entries: Sequence[tuple[float, str]]) -> None:
    """Write a ParaView collection file listing ``(time [s], relative file)`` entries."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ET.SubElement(root, "Collection")
    for t, file in entries:
        ET.SubElement(collection, "DataSet", timestep=repr(float(t)), group="", part="0", file=file)
    ET.indent(root)
    with atomic_path(path) as tmp:
        ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)


def _read_pvd_entries(path: Path) -> list[tuple[float, str]]:
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"{path}: not a valid PVD file ({exc})") from exc
    collection = root.find("Collection")
    if root.tag != "VTKFile" or root.get("type") != "Collection" or collection is None:
        raise ValueError(f"{path}: not a VTKFile of type Collection")
    entries = []
    for i, dataset in enumerate(collection.iter("DataSet")):
        t, file = dataset.get("timestep"), dataset.get("file")
        if t is None or file is None:
            raise ValueError(f"{path}: DataSet {i} lacks a 'timestep' or 'file' attribute")
        try:
            entries.append((float(t), file))
        except ValueError as exc:
            raise ValueError(f"{path}: DataSet {i} has timestep {t!r}, not a number") from exc
    return entries


def read_pvd(path: str | Path) -> list[tuple[float, Path]]:
    """Read a ParaView ``.pvd`` collection.

    Args:
        path: the ``.pvd`` file.

    Returns:
        ``(time [s], file path)`` per data set, in file order; paths are resolved relative to the
        directory of the ``.pvd`` file, as ParaView does.
    """
    path = Path(path)
    return [(t, path.parent / file) for t, file in _read_pvd_entries(path)]


class FrameWriter:
    """Writes frames (sets of blocks at one time) as VTU files with one PVD collection per block.

    Use as a context manager or call :meth:`close`. See the module docstring for the layout.

    Args:
        out_dir: output directory (created).
        prefix: file name prefix of the frame files (letters, digits, ``_ . -``).
        binary: zlib-compressed binary VTU (default) or ASCII.
        resume: continue the collections found in ``out_dir`` instead of starting new ones.
    """

    def __init__(
        self,
        out_dir: str | Path,
        *,
        prefix: str = "frame",
        binary: bool = True,
        resume: bool = False,
    ) -> None:
        self._prefix = _validate_name("prefix", prefix)
        self._out_dir = Path(out_dir)
        self._out_dir.mkdir(parents=True, exist_ok=True)
        self._binary = bool(binary)
        self._collections: dict[str, list[tuple[float, str]]] = {}
        self._index = 0
        self._last_t = -np.inf
        self._closed = False
        if resume:
            self._load_existing()

    def _load_existing(self) -> None:
        frame_re = re.compile(rf"[^/]+/{re.escape(self._prefix)}_(\d+)\.vtu")
        for pvd in sorted(self._out_dir.glob("*.pvd")):
            entries = _read_pvd_entries(pvd)
            self._collections[pvd.stem] = entries
            for _, file in entries:
                match = frame_re.fullmatch(file)
                if match:
                    self._index = max(self._index, int(match.group(1)) + 1)
        logger.info(
            "resuming %d collections in %s at frame %d",
            len(self._collections),
            self._out_dir,
            self._index,
        )

    @property
    def out_dir(self) -> Path:
        """The output directory."""
        return self._out_dir

    @property
    def frame_index(self) -> int:
        """Index that the next frame will get (= frames written so far, unless resumed)."""
        return self._index

    def pvd_path(self, name: str) -> Path:
        """Path of the ``.pvd`` collection of block ``name``."""
        return self._out_dir / f"{name}.pvd"

    def write_frame(self, t: float, blocks: Sequence[Block]) -> list[Path]:
        """Write one frame: a ``.vtu`` per block, then rewrite the ``.pvd`` of each block.

        Args:
            t: simulation time of the frame [s]; finite and larger than the previous frame's.
            blocks: the blocks of this frame, distinct names; a block may be absent from some
                frames (its collection then skips them).

        Returns:
            paths of the ``.vtu`` files written, in the order of ``blocks``.
        """
        if self._closed:
            raise RuntimeError("FrameWriter is closed")
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        if t <= self._last_t:
            raise ValueError(
                f"t = {t!r} must be larger than the previous frame time {self._last_t!r}"
            )
        blocks = list(blocks)
        if not blocks:
            raise ValueError("blocks must not be empty")
        names = [b.name if isinstance(b, Block) else None for b in blocks]
        if None in names:
            raise ValueError(f"blocks[{names.index(None)}] is not a Block")
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"blocks have duplicate names {duplicates}")

        written = []
        for block in blocks:
            rel = f"{block.name}/{self._prefix}_{self._index:05d}.vtu"
            path = self._out_dir / rel
            with atomic_path(path) as tmp:
                meshio.write(tmp, block.to_meshio(), file_format="vtu", binary=self._binary)
            written.append(path)
        for block in blocks:
            rel = f"{block.name}/{self._prefix}_{self._index:05d}.vtu"
            # A restarted run recomputes the frames from its checkpoint time on: drop them.
            entries = [e for e in self._collections.get(block.name, []) if e[0] < t]
            entries.append((t, rel))
            _write_pvd(self.pvd_path(block.name), entries)
            self._collections[block.name] = entries
        logger.debug("frame %d at t = %g: %d blocks", self._index, t, len(blocks))
        self._index += 1
        self._last_t = t
        return written

    def close(self) -> None:
        """Finish writing; the PVD files are already complete, later writes raise RuntimeError."""
        self._closed = True

    def __enter__(self) -> FrameWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
