"""A long benchmark case that goes on across processes and sessions (``buckling``'s full modes).

Some cases of the paper's experiments take longer than one session on 2 cores (the buckling
rings pressed by the paper's plate at full resolution: hours per friction coefficient). A case
run with a ``CaseCheckpoint`` keeps, in its own folder:

- ``checkpoint.npz`` / ``checkpoint.json``: the simulation (``bfemp.checkpoint``: state, metrics
  and stepper data; a resumed run equals the uninterrupted one bit for bit, and a checkpoint of
  another scene is refused);
- ``progress.json``: what the case measured so far (its series and counters, JSON) with the
  step it belongs to and the wall time of every segment (one per process that ran it).

The folder can be committed and the case continued in a later session (``resume``); the
case's wall time is then the sum of its segments.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from bfemp.checkpoint import (
    CHECKPOINT_FILE,
    read_checkpoint,
    restore_checkpoint,
    write_checkpoint,
)
from bfemp.io.vtk import atomic_path

log = logging.getLogger(__name__)

PROGRESS_FILE = "progress.json"


class CaseCheckpoint:
    """The checkpoint folder of one case.

    Args:
        folder: the case's folder (created on the first ``save``).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)

    def exists(self) -> bool:
        """True when the folder holds a checkpoint to resume from."""
        return (self.folder / CHECKPOINT_FILE).is_file() and (self.folder / PROGRESS_FILE).is_file()

    def save(self, sim: object, progress: dict) -> None:
        """Write the simulation ``sim`` (a ``bfemp.Simulation``) and the case's ``progress``
        (JSON-ready; the step of ``sim.state`` is added as ``step``)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        write_checkpoint(self.folder, sim)
        with atomic_path(self.folder / PROGRESS_FILE) as tmp:
            tmp.write_text(json.dumps({**progress, "step": sim.state.step}) + "\n")

    def restore(self, sim: object) -> dict:
        """Load the checkpoint into ``sim`` and return the progress saved with it.

        Raises:
            ValueError: when the progress and the checkpoint are of different steps (a process
                stopped between the two writes) or the folder holds no checkpoint.
            bfemp.errors.SceneError: when the checkpoint is of another scene.
        """
        if not self.exists():
            raise ValueError(f"no case checkpoint in {self.folder} to resume from")
        progress = json.loads((self.folder / PROGRESS_FILE).read_text())
        step = read_checkpoint(self.folder).state.step
        if progress.get("step") != step:
            raise ValueError(
                f"{self.folder}: {PROGRESS_FILE} is of step {progress.get('step')} but the "
                f"checkpoint of step {step} (a run stopped between the two writes); "
                "start the case again without resume"
            )
        restore_checkpoint(self.folder, sim)
        log.info("case resumed at step %d from %s", step, self.folder)
        return progress
