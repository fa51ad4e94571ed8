"""A run folder back to a ``bfemp.Simulation`` (the frames and metrics: :mod:`bfemp.io`)."""

from __future__ import annotations

from pathlib import Path

from bfemp.errors import SceneError
from bfemp.simulation import Simulation

__all__ = ["load_run"]


def load_run(out: str | Path, *, checkpoint: bool = True) -> Simulation:
    """The ``Simulation`` of run folder ``out``, at the state of its checkpoint.

    It is made from the folder's ``scene.toml`` (its ``[simulation]`` settings, written by every
    run of a ``Scene`` or a scene file) and ``checkpoint.npz``; ``run(..., resume=True)`` on it
    continues the run.

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
    out = Path(out)
    scene_file = out / "scene.toml"
    if not scene_file.is_file():
        raise SceneError(
            f"{out} has no scene.toml: not a bfemp run folder (or a run of a Model, which has "
            "no scene file)",
            hint="give the --out folder of a run",
        )
    sim = Simulation.from_file(scene_file)
    if checkpoint:
        sim.load_checkpoint(out)
    return sim
