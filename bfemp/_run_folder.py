"""A run that writes an output folder: frames, checkpoints, manifest, metrics and plots."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from bfemp._run_arguments import check_t_end, n_steps
from bfemp.checkpoint import InterruptGuard, restore_checkpoint
from bfemp.io import outputs
from bfemp.io.metrics import MetricsLog
from bfemp.io.snapshots import write_animation, write_snapshot_sheet
from bfemp.io.vtk import FrameWriter
from bfemp.manifest import RunManifest, read_manifest
from bfemp.plotting import plot_metrics

__all__ = ["run_to_folder"]


def run_to_folder(
    sim: object,
    out: Path,
    t_end: float,
    every: int,
    progress: bool,
    callback: Callable[[object], None] | None,
    checkpoint_every: int | None,
    resume: bool,
    metadata: dict | None,
    overwrite: bool,
    animation: str | None,
    scene_toml: str | None,
) -> MetricsLog:
    """``sim.run`` (``sim`` a ``bfemp.Simulation``) with the output folder ``out``, whose lock
    the caller holds: the folder prepared (or the checkpoint restored on ``resume``), the start
    frame, the time loop with frames and checkpoints, and, however it ends, the manifest,
    metrics, plots and the last checkpoint (:func:`bfemp.io.outputs.finish_outputs`)."""
    if resume:
        # a corrupt manifest is refused before anything changes
        earlier = read_manifest(out) or {}
        ckpt = restore_checkpoint(out, sim, every=every)
        check_t_end(t_end, sim.state.t, sim.dt, f"the checkpoint in {out}")
        if every is None:  # the continued run's frame interval
            every = ckpt.meta.get("every")
        if checkpoint_every is None:
            checkpoint_every = earlier.get("parameters", {}).get("run", {}).get("checkpoint_every")
    else:
        outputs.prepare_run_folder(out, overwrite=overwrite)
        text = scene_toml if scene_toml is not None else sim.scene_file_text()
        if text is not None:
            outputs.write_scene_file(out, text)
    every, checkpoint_every = int(every or 1), int(checkpoint_every or 0)
    run = {"t_end": float(t_end), "every": every, "checkpoint_every": checkpoint_every}
    writer = FrameWriter(out, resume=resume)
    manifest = RunManifest.start(out, sim, run=run, resume=resume, extra=metadata)
    if not resume:  # the start state, whatever its step (a run after sim.step() too)
        writer.write_frame(sim.state.t, sim.frame_blocks())
    status, message, guard = "failed", "", InterruptGuard()
    try:
        with guard:
            sim._loop(
                n_steps(sim.state.t, t_end, sim.dt),
                progress,
                callback,
                writer=writer,
                every=every,
                checkpoint_every=checkpoint_every,
                guard=guard,
            )
        status = "completed"
    except KeyboardInterrupt:
        status = "interrupted"
        message = f"interrupted at step {sim.state.step} (t = {sim.state.t:.6g} s)"
        raise
    except Exception as err:
        message = f"{type(err).__name__}: {err}"
        raise
    finally:
        writer.close()
        if guard.hard:  # stopped anywhere, maybe mid-update: keep the last checkpoint
            message += "; aborted without a checkpoint (the last periodic one remains)"
        plots = [
            (
                "metrics.png",
                lambda: plot_metrics(sim.metrics, out / "metrics.png", title="bfemp run"),
            ),
            ("snapshots.png", lambda: write_snapshot_sheet(out)),
        ]
        if animation is not None:
            plots.append((f"animation.{animation}", lambda: write_animation(out, animation)))
        outputs.finish_outputs(
            out,
            sim,
            manifest,
            status,
            message,
            hard=guard.hard,
            every=every,
            frames=writer.frame_index,
            writes=plots,
        )
    return sim.metrics
