"""Reading a run folder back into Python: frames, metrics, and the simulation itself.

- :func:`read_frames` (``BODY.pvd`` -> times and ``meshio.Mesh`` es, with the fields written:
  velocity, J, von Mises stress, contact force); :func:`bfemp.io.read_pvd` lists the
  ``(time, file)`` entries without reading the files;
- :func:`read_metrics` (``metrics.csv`` -> :class:`~bfemp.io.MetricsLog`, every value bit for
  bit);
- a run folder back to a ``bfemp.Simulation``: :func:`bfemp.runs.load_run`.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from bfemp.errors import RunFolderError
from bfemp.io.metrics import MetricsLog
from bfemp.io.vtk import read_pvd

__all__ = ["read_frames", "read_metrics"]


def read_frames(path: str | Path) -> tuple[np.ndarray, list[meshio.Mesh]]:
    """The frames of one body: ``times (N,)`` in s and the ``N`` meshes, in time order.

    Args:
        path: a ``BODY.pvd`` collection of a run folder.

    Points are 3D (2D runs: z = 0); FEM fields are cell data (``J``, ``von_mises``) and point
    data (``velocity``, ``contact_force``), MPM fields point data (see ``frame_blocks``).

    Raises:
        RunFolderError: a frame file is missing or does not read (named, with its time).
    """
    entries = read_pvd(path)
    times = np.array([t for t, _ in entries], dtype=np.float64)
    return times, [_read_frame(file, t) for t, file in entries]


def _read_frame(file: Path, t: float) -> meshio.Mesh:
    """One frame file; ``RunFolderError`` naming it (and its time) when missing or corrupt."""
    if not file.is_file():
        raise RunFolderError(f"frame at t = {t:.9g} s is missing", file=str(file))
    try:  # not meshio.read: on a file it cannot read, that prints and calls sys.exit(1)
        return meshio.vtu.read(str(file))
    except Exception as err:  # ReadError, ParseError, ValueError, zlib.error, ...
        detail = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
        raise RunFolderError(
            f"frame at t = {t:.9g} s is corrupt ({file.stat().st_size} bytes; truncated?): "
            f"{detail}",
            file=str(file),
        ) from None


def read_metrics(path: str | Path) -> MetricsLog:
    """The metrics table of a run: ``path`` is ``metrics.csv`` or the run folder."""
    path = Path(path)
    return MetricsLog.from_csv(path / "metrics.csv" if path.is_dir() else path)
