"""Reading a run folder back into Python: frames, metrics, and the simulation itself.

- :func:`read_frames` (``BODY.pvd`` -> times and ``meshio.Mesh`` es, with the fields written:
  velocity, J, von Mises stress, contact force); :func:`bfemp.io.read_pvd` lists the
  ``(time, file)`` entries without reading the files;
- :func:`read_metrics` (``metrics.csv`` -> :class:`~bfemp.io.MetricsLog`, every value bit for
  bit);
- :func:`load_run` (folder -> ``bfemp.Simulation`` at the state of its checkpoint), from the
  folder's ``scene.toml`` (its ``[simulation]`` settings) and ``checkpoint.npz``; ``run(...,
  resume=True)`` on it continues the run.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from bfemp.errors import SceneError
from bfemp.io.metrics import MetricsLog
from bfemp.io.vtk import read_pvd

__all__ = ["load_run", "read_frames", "read_metrics"]


def read_frames(path: str | Path) -> tuple[np.ndarray, list[meshio.Mesh]]:
    """The frames of one body: ``times (N,)`` in s and the ``N`` meshes, in time order.

    Args:
        path: a ``BODY.pvd`` collection of a run folder.

    Points are 3D (2D runs: z = 0); FEM fields are cell data (``J``, ``von_mises``) and point
    data (``velocity``, ``contact_force``), MPM fields point data (see ``frame_blocks``).
    """
    entries = read_pvd(path)
    times = np.array([t for t, _ in entries], dtype=np.float64)
    return times, [meshio.read(file) for _, file in entries]


def read_metrics(path: str | Path) -> MetricsLog:
    """The metrics table of a run: ``path`` is ``metrics.csv`` or the run folder."""
    path = Path(path)
    return MetricsLog.from_csv(path / "metrics.csv" if path.is_dir() else path)


def load_run(out: str | Path, *, checkpoint: bool = True) -> object:
    """The ``bfemp.Simulation`` of run folder ``out``, at the state of its checkpoint.

    Args:
        out: the run folder (``scene.toml`` needed; ``checkpoint.npz`` unless ``checkpoint``
            is false).
        checkpoint: restore the checkpoint's state and metrics (and put the folder's ``.pvd``
            collections back as they were at the checkpoint, as ``--resume`` does); false:
            the simulation at t = 0.

    Raises:
        SceneError: no ``scene.toml`` or no checkpoint in ``out``, or a checkpoint of another
            model.
    """
    from bfemp import scenefile
    from bfemp.checkpoint import restore_checkpoint

    out = Path(out)
    scene_file = out / "scene.toml"
    if not scene_file.is_file():
        raise SceneError(
            f"{out} has no scene.toml: not a bfemp run folder (or a run of a Model, which has "
            "no scene file)",
            hint="give the --out folder of a run",
        )
    sim = scenefile.load(scene_file).make_simulation()
    if checkpoint:
        restore_checkpoint(out, sim)
    return sim
