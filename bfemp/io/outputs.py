"""What a run folder's own outputs are, preparing a folder for a run, and the final writes.

A run folder (``Simulation.run(out=...)``, ``bfemp run --out``, ``bfemp demo --out``) holds:

- ``BODY.pvd`` + ``BODY/frame_*.vtu`` per body (the frames), ``metrics.csv``, ``metrics.png``,
  ``snapshots.png``, ``animation.gif`` / ``animation.mp4`` (on request), ``manifest.json``,
  ``checkpoint.npz`` + ``checkpoint.json``, ``scene.toml``; the demos add ``demo.json``,
  ``demo.png`` and ``tip.png``.

A folder holds an *earlier run* when it has a ``manifest.json``, ``metrics.csv``, a checkpoint or
a ``.pvd`` collection. A fresh run (no ``resume``) refuses such a folder unless ``overwrite`` is
given, and then deletes those outputs first (only these files, and a body folder when it is
left empty), so that no old frame, collection or plot of another mesh is taken for one of the
new run. Other files in the folder are never touched.

:func:`finish_outputs` does the writes at the end of a run (metrics table, checkpoint, plots,
manifest) so that the manifest always ends ``completed``, ``interrupted`` or ``failed``, never
``running``: a first Ctrl-C during these writes lets them finish; a second one (or any
``KeyboardInterrupt`` raised in a write) skips what is left; either way the manifest records
``interrupted`` with what was not written, and ``KeyboardInterrupt`` is raised afterwards.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from pathlib import Path

from bfemp.checkpoint import CHECKPOINT_FILE, SIDECAR_FILE, InterruptGuard, write_checkpoint
from bfemp.errors import SceneError
from bfemp.io.vtk import atomic_path

__all__ = [
    "ANIMATION_FORMATS",
    "RUN_FILES",
    "earlier_run_outputs",
    "finish_outputs",
    "prepare_run_folder",
    "write_scene_file",
]

log = logging.getLogger(__name__)

#: files a run (or a demo) writes at the top of its folder, besides the ``*.pvd`` collections
RUN_FILES = (
    "manifest.json",
    "metrics.csv",
    "metrics.png",
    "snapshots.png",
    "animation.gif",
    "animation.mp4",
    CHECKPOINT_FILE,
    SIDECAR_FILE,
    "demo.json",
    "demo.png",
    "tip.png",
)
#: files whose presence marks a folder as holding an earlier run
_EVIDENCE = ("manifest.json", "metrics.csv", CHECKPOINT_FILE)
#: animation formats of ``Simulation.run(animation=...)`` and ``bfemp run --animate``
ANIMATION_FORMATS = ("gif", "mp4")


def earlier_run_outputs(out: str | Path) -> list[Path]:
    """The outputs of an earlier run in ``out`` (empty when it holds none, or does not exist).

    Returns the files of :data:`RUN_FILES` present, every ``*.pvd`` collection and the
    ``frame_*.vtu`` files in the folder of each collection's block (``BODY/``).
    """
    out = Path(out)
    if not out.is_dir():
        return []
    pvds = sorted(out.glob("*.pvd"))
    if not pvds and not any((out / name).is_file() for name in _EVIDENCE):
        return []
    found = [out / name for name in RUN_FILES if (out / name).is_file()]
    for pvd in pvds:
        found.append(pvd)
        found += sorted((out / pvd.stem).glob("frame_*.vtu"))
    return found


def prepare_run_folder(out: str | Path, *, overwrite: bool) -> Path:
    """Make ``out`` ready for a fresh run: refuse or clean the outputs of an earlier run.

    Args:
        out: the run folder (created if missing).
        overwrite: delete the earlier run's outputs (:func:`earlier_run_outputs`) instead of
            refusing.

    Raises:
        SceneError: ``out`` holds an earlier run and ``overwrite`` is false.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise SceneError(f"the output folder {out} is a file", field="out")
    old = earlier_run_outputs(out)
    if old and not overwrite:
        names = sorted({p.relative_to(out).parts[0] for p in old})
        shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
        raise SceneError(
            f"the output folder {out} holds the outputs of an earlier run ({shown})",
            field="out",
            hint="pass overwrite=True (bfemp run --overwrite) to replace them, resume=True "
            "(--resume) to continue that run, or choose another folder",
        )
    for path in old:
        path.unlink()
    for folder in {p.parent for p in old if p.parent != out}:
        with contextlib.suppress(OSError):  # not empty: it holds files of the user's
            folder.rmdir()
    if old:
        log.info("removed %d files of an earlier run from %s", len(old), out)
    out.mkdir(parents=True, exist_ok=True)
    return out


def write_scene_file(out: str | Path, text: str) -> Path:
    """Write ``{out}/scene.toml`` (atomically): the scene file of the run (``Simulation.run``
    makes it from the scene file it was read from, or writes its ``Scene``)."""
    path = Path(out) / "scene.toml"
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def finish_outputs(
    out: Path,
    sim: object,
    manifest: object,
    status: str,
    message: str,
    *,
    hard: bool,
    every: int,
    frames: int,
    writes: list[tuple[str, Callable[[], object]]],
) -> None:
    """The final writes of a run, then ``manifest.finish`` whatever happens.

    Args:
        out: the run folder.
        sim: the ``Simulation``.
        manifest: its ``RunManifest``.
        status: ``completed``, ``interrupted`` or ``failed`` (the outcome of the time loop).
        message: the outcome's message.
        hard: the loop was aborted by a second Ctrl-C (maybe mid-update): nothing but the
            manifest is written (the last periodic checkpoint remains).
        every: frame interval in steps (recorded in the checkpoint).
        frames: frames written (recorded in the manifest).
        writes: ``(name, write)`` pairs of optional outputs (plots), done after the metrics
            table and the checkpoint; a ``ValueError``, ``RuntimeError`` or ``OSError`` of one
            is logged and the next one is done.

    Raises:
        KeyboardInterrupt: Ctrl-C during the writes (after the manifest is written).
    """
    if hard:
        with InterruptGuard():
            manifest.finish(sim, status, message, frames=frames)
        return
    essential = [
        ("metrics.csv", lambda: sim.metrics.to_csv(out / "metrics.csv")),
        ("checkpoint", lambda: write_checkpoint(out, sim, every=every)),
    ]
    done: list[str] = []
    guard = InterruptGuard()
    try:
        with guard:
            for name, write in essential + list(writes):
                try:
                    write()
                except (ValueError, RuntimeError, OSError) as err:
                    if any(name == e for e, _ in essential):
                        raise
                    log.warning("%s not written: %s", name, err)
                    continue
                done.append(name)
    except KeyboardInterrupt:
        guard.requested = True
        raise
    except Exception as err:  # the metrics table or the checkpoint could not be written
        status = "failed"
        note = f"{type(err).__name__} in the final writes: {err}"
        message = f"{message}; {note}" if message else note
        raise
    finally:
        if guard.requested:
            skipped = [n for n, _ in essential + list(writes) if n not in done]
            status = "interrupted"
            note = "interrupted during the final writes"
            note += f" ({', '.join(skipped)} not written)" if skipped else " (all written)"
            message = f"{message}; {note}" if message else note
        with InterruptGuard() as last:  # a Ctrl-C now waits for the manifest's atomic write
            manifest.finish(sim, status, message, frames=frames)
        log.info("wrote frames, metrics, manifest and checkpoint to %s", out)
    if guard.requested or last.requested:
        raise KeyboardInterrupt(message)
