"""Checkpoints of a run, from which ``--resume`` continues bit for bit.

A checkpoint is ``{out}/checkpoint.npz`` (``np.savez``, written atomically: temporary file, then
rename) with a human-readable sidecar ``{out}/checkpoint.json``. The ``.npz`` is authoritative
and holds everything a continued run needs to equal the uninterrupted one:

- ``state.<field>``: every array of the ``State`` (positions, velocities, accelerations, F, C;
  a strategy's carried arrays as ``state.carried.<name>``);
  its scalar fields (``t``, ``step``) are in ``meta`` as JSON numbers (``repr`` of a float
  reads back to the same float);
- ``metrics``: the metrics log so far (JSON rows; ints stay ints, NaN stays NaN);
- ``pvd.<block>``: the text of each ``.pvd`` collection of the run folder, so frames written
  after the checkpoint are dropped on resume and the frame numbering continues where it was;
- ``stepper.<name>``: the data a stepper carries between steps, through the hooks every
  stepper declares (``checkpoint_data() -> dict[str, ndarray]``, ``restore_checkpoint_data``;
  ``bfemp.steppers.base.Stepper``). The barrier stepper's sparsity patterns and CHOLMOD
  symbolic factorisation are caches that do not change results; what it carries is the
  adaptive barrier stiffness of ``kappa = "auto"`` (an ``AdaptiveKappa``, as JSON);
- ``meta``: JSON with the format version, the model fingerprint (SHA-256 of every array and
  parameter of the ``Model``), the simulation settings and the frame interval.

Resuming refuses a checkpoint of another model (the scene changed) and warns when the settings
(dt, tolerance, integrator, ...) differ, since the continuation then differs from an
uninterrupted run. Wall-clock timing columns (``time_*``) of the metrics differ between any two
runs by nature; everything else of a resumed run equals the uninterrupted one bit for bit.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import signal
import threading
import tokenize
import xml.etree.ElementTree as ET
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bfemp.errors import RunFolderError, SceneError, warn_user
from bfemp.io.metrics import MetricsLog
from bfemp.io.vtk import atomic_path, atomic_write_text
from bfemp.state import State

__all__ = [
    "CHECKPOINT_FILE",
    "InterruptGuard",
    "SIDECAR_FILE",
    "Checkpoint",
    "check_frames",
    "model_fingerprint",
    "read_checkpoint",
    "restore_checkpoint",
    "write_checkpoint",
]

log = logging.getLogger(__name__)

CHECKPOINT_FILE = "checkpoint.npz"
SIDECAR_FILE = "checkpoint.json"
FORMAT_VERSION = 2


def _feed(h: object, obj: object) -> None:
    """Hash ``obj`` recursively: arrays by dtype, shape and bytes; dataclasses by fields."""
    if isinstance(obj, np.ndarray):
        h.update(f"nd{obj.dtype.str}{obj.shape}".encode())
        h.update(np.ascontiguousarray(obj).tobytes())
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(type(obj).__qualname__.encode())
        for f in dataclasses.fields(obj):
            h.update(f.name.encode())
            _feed(h, getattr(obj, f.name))
    elif isinstance(obj, list | tuple):
        h.update(f"[{len(obj)}".encode())
        for item in obj:
            _feed(h, item)
    elif isinstance(obj, dict):
        h.update(f"{{{len(obj)}".encode())
        for key in sorted(obj, key=repr):
            _feed(h, key)
            _feed(h, obj[key])
    else:
        h.update(f"{type(obj).__qualname__}:{obj!r}".encode())


def model_fingerprint(model: object) -> str:
    """SHA-256 (hex) of a ``Model``: every array, material, motion, boundary and parameter."""
    h = hashlib.sha256()
    _feed(h, model)
    return h.hexdigest()


@dataclass(frozen=True)
class Checkpoint:
    """A checkpoint read back.

    Attributes:
        state: the saved ``State``.
        metrics: the metrics log up to ``state``.
        meta: format version, fingerprint, settings, frame interval (``every``), ...
        pvd: block name -> text of its ``.pvd`` collection at checkpoint time.
        stepper: data of the stepper (empty for the implicit stepper).
    """

    state: State
    metrics: MetricsLog
    meta: dict
    pvd: dict[str, str]
    stepper: dict[str, np.ndarray]


def write_checkpoint(out: str | Path, sim: object, *, every: int | None = None) -> Path:
    """Write the checkpoint of ``sim`` (a ``bfemp.Simulation``) to ``out`` atomically.

    Args:
        out: the run folder (its ``*.pvd`` files are stored with the checkpoint).
        sim: the simulation.
        every: the frame interval of the run (recorded; resuming with another one warns).

    Returns:
        the path of the ``.npz``.
    """
    out = Path(out)
    state = sim.state
    arrays = {f"state.{name}": value for name, value in state.arrays().items()}
    scalars = {
        f.name: getattr(state, f.name)
        for f in dataclasses.fields(state)
        if f.name != "carried" and not isinstance(getattr(state, f.name), np.ndarray)
    }
    for key, value in sim.stepper.checkpoint_data().items():
        arrays[f"stepper.{key}"] = np.asarray(value)
    pvd = {p.stem: p.read_text(encoding="utf-8") for p in sorted(out.glob("*.pvd"))}
    for name, text in pvd.items():
        arrays[f"pvd.{name}"] = np.array(text)
    meta = {
        "format": FORMAT_VERSION,
        "t": state.t,
        "step": state.step,
        "scalars": scalars,
        "fingerprint": model_fingerprint(sim.model),
        "settings": dict(sim.settings),
        "every": every,
        "pvd": sorted(pvd),
    }
    arrays["meta"] = np.array(json.dumps(meta))
    columns = sim.metrics.columns
    rows = [[row[c] for c in columns] for row in sim.metrics.rows]
    arrays["metrics"] = np.array(json.dumps({"columns": columns, "rows": rows}))
    path = out / CHECKPOINT_FILE
    with atomic_path(path) as tmp, tmp.open("wb") as fh:
        np.savez(fh, **arrays)
    sidecar = {**meta, "metrics_rows": len(sim.metrics), "file": CHECKPOINT_FILE}
    atomic_write_text(out / SIDECAR_FILE, json.dumps(sidecar, indent=2) + "\n")
    log.info("checkpoint at step %d (t = %.6g s) written to %s", state.step, state.t, path)
    return path


#: how to go on when a checkpoint cannot be read
_CORRUPT_HINT = (
    "the run cannot continue from it: put back a good copy, or start again from t = 0 with "
    "--overwrite (overwrite=True)"
)


def _corrupt(path: Path, what: str) -> RunFolderError:
    """The refusal of a corrupt checkpoint ``path``: ``what`` is wrong with it."""
    return RunFolderError(f"corrupt checkpoint: {what}", file=str(path), hint=_CORRUPT_HINT)


def read_checkpoint(out: str | Path) -> Checkpoint:
    """Read ``{out}/checkpoint.npz``.

    Raises:
        RunFolderError: ``out`` is a file, the checkpoint is missing, or it is corrupt (not a
            complete zip archive, a member that does not decompress, a meta or metrics record
            that does not parse, another format version); the message names the file and what
            is wrong with it.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RunFolderError("is a file, not a run folder", file=str(out))
    path = out / CHECKPOINT_FILE
    if not path.is_file():
        # a hint that works: a folder with the evidence of an earlier run that bfemp.io.outputs
        # (which imports this module) refuses to write over (its manifest, its metrics or a
        # frame collection: a run killed before its first checkpoint) needs --overwrite
        earlier = any((out / name).is_file() for name in ("manifest.json", "metrics.csv"))
        if earlier or any(out.glob("*.pvd")):
            hint = (
                f"the run in {out} stopped before its first checkpoint: start it again from "
                "t = 0 with --overwrite instead of --resume (overwrite=True instead of "
                "resume=True)"
            )
        else:
            hint = "run without --resume (resume=False) to start from t = 0"
        raise RunFolderError(f"no checkpoint in {out} ({CHECKPOINT_FILE} is missing)", hint=hint)
    if not zipfile.is_zipfile(path):  # np.load would try it as a pickle: a misleading message
        size = path.stat().st_size
        raise _corrupt(path, f"not a complete zip archive ({size} bytes; truncated or overwritten)")
    try:
        with np.load(path, allow_pickle=False) as data:
            contents = {key: data[key] for key in data.files}
        if "meta" not in contents or "metrics" not in contents:
            raise KeyError("no 'meta' or 'metrics' record")
        meta = json.loads(str(contents.pop("meta")))
        table = json.loads(str(contents.pop("metrics")))
        metrics = MetricsLog(dict(zip(table["columns"], r, strict=True)) for r in table["rows"])
        if not isinstance(meta, dict):
            raise TypeError("the 'meta' record is not a JSON object")
    except (
        OSError,
        ValueError,
        KeyError,
        TypeError,
        EOFError,
        SyntaxError,  # numpy parses a member's .npy header with ast.literal_eval
        tokenize.TokenError,  # ... and, when that fails, re-reads it with tokenize
        zipfile.BadZipFile,
        zlib.error,
    ) as err:
        raise _corrupt(path, f"{type(err).__name__}: {err}") from None
    if meta.get("format") != FORMAT_VERSION:
        raise RunFolderError(
            f"checkpoint of format {meta.get('format')}, not {FORMAT_VERSION} (written by "
            "another bfemp version)",
            file=str(path),
            hint="resume it with the bfemp version that wrote it, or start again with --overwrite",
        )
    missing = [k for k in ("scalars", "fingerprint", "settings") if k not in meta]
    if missing:
        raise _corrupt(path, f"its meta record lacks {', '.join(missing)}")
    state_arrays = {k[6:]: v for k, v in contents.items() if k.startswith("state.")}
    carried = {k[8:]: state_arrays.pop(k) for k in list(state_arrays) if k.startswith("carried.")}
    for name in ("aug_B", "aug_Bp"):  # written as State fields before they moved to carried
        if name in state_arrays:
            carried[name] = state_arrays.pop(name)
    try:
        state = State(**meta["scalars"], **state_arrays, carried=carried)
    except TypeError as err:
        raise _corrupt(path, f"its state does not match a State ({err})") from None
    pvd = {k[4:]: str(v) for k, v in contents.items() if k.startswith("pvd.")}
    stepper = {k[8:]: v for k, v in contents.items() if k.startswith("stepper.")}
    return Checkpoint(state=state, metrics=metrics, meta=meta, pvd=pvd, stepper=stepper)


#: how to go on when a frame before the checkpoint is damaged
_FRAME_HINT = (
    "the frames before the checkpoint are not recomputed on resume: put back a good copy, or "
    "start again from t = 0 with --overwrite (overwrite=True)"
)
#: the closing tag of a complete VTU file (meshio ends it with a newline)
_VTU_END = b"</VTKFile>"


def check_frames(out: str | Path, pvd: dict[str, str]) -> int:
    """Check that every frame listed in the ``.pvd`` texts ``pvd`` (block -> collection text,
    as a checkpoint stores them) is a complete file in ``out``; return how many were checked.

    A frame is complete when it exists and ends with ``</VTKFile>``: a frame truncated by a
    crash (a file renamed into place before its data reached the disk) or by a full disk
    fails this. Only the last 64 bytes of each file are read (a run of thousands of frames is
    checked in milliseconds); damage inside a file that keeps its end is not detected.

    Raises:
        RunFolderError: a collection that does not parse, or a missing or incomplete frame
            (named, with its time).
    """
    out = Path(out)
    checked = 0
    for block, text in pvd.items():
        try:
            root = ET.fromstring(text)
        except ET.ParseError as err:
            raise _corrupt(
                out / CHECKPOINT_FILE, f"its copy of {block}.pvd does not parse ({err})"
            ) from None
        for dataset in root.iter("DataSet"):
            rel, t = dataset.get("file", ""), f"{float(dataset.get('timestep', 'nan')):.9g}"
            path = out / rel
            try:
                size = path.stat().st_size
                with path.open("rb") as fh:
                    fh.seek(max(0, size - 64))
                    tail = fh.read().rstrip()
            except OSError as err:
                raise RunFolderError(
                    f"frame of block {block!r} at t = {t} s listed by the checkpoint cannot be "
                    f"read ({err.strerror or err})",
                    file=str(path),
                    hint=_FRAME_HINT,
                ) from None
            if not tail.endswith(_VTU_END):
                raise RunFolderError(
                    f"corrupt frame of block {block!r} at t = {t} s: {size} bytes, not ending "
                    "with </VTKFile> (truncated)",
                    file=str(path),
                    hint=_FRAME_HINT,
                )
            checked += 1
    return checked


def restore_checkpoint(out: str | Path, sim: object, *, every: int | None = None) -> Checkpoint:
    """Load the checkpoint of ``out`` into ``sim`` and put back the run's ``.pvd`` files.

    Raises ``SceneError`` when the checkpoint belongs to another model, ``RunFolderError``
    when it is missing or corrupt or a frame it lists is (:func:`check_frames`), before
    anything is changed; warns when the simulation settings or the frame interval differ
    from the checkpoint's.
    """
    out = Path(out)
    ckpt = read_checkpoint(out)
    if ckpt.meta["fingerprint"] != model_fingerprint(sim.model):
        raise SceneError(
            f"the checkpoint in {out} was written for another model (the scene changed)",
            hint="resume with the scene the run started with, or run without --resume",
        )
    check_frames(out, ckpt.pvd)
    old, new = ckpt.meta["settings"], dict(sim.settings)
    changed = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    if changed:
        now, before = {k: new.get(k) for k in changed}, {k: old.get(k) for k in changed}
        warn_user(
            f"RESUME_SETTINGS_CHANGED: resuming with settings {now} different from the "
            f"checkpoint's {before}: the continued run will differ from an uninterrupted one",
            logger=log,
        )
    if every is not None and ckpt.meta.get("every") not in (None, every):
        warn_user(
            f"RESUME_EVERY_CHANGED: resuming with a frame every {every} steps instead of the "
            f"checkpoint's {ckpt.meta['every']}",
            logger=log,
        )
    try:
        sim.stepper.restore_checkpoint_data(dict(ckpt.stepper))
    except ValueError as err:
        raise SceneError(
            f"the checkpoint in {out} holds stepper data this stepper cannot take: {err}"
        ) from None
    sim.state = ckpt.state
    sim.metrics = ckpt.metrics
    for name, text in ckpt.pvd.items():
        atomic_write_text(out / f"{name}.pvd", text)
    log.info(
        "resumed from step %d (t = %.6g s) of %s", ckpt.state.step, ckpt.state.t, out / "checkpoint"
    )
    return ckpt


class InterruptGuard:
    """Ctrl-C during a run: the first sets ``requested`` (the loop stops after the current step
    and a checkpoint is written); the second raises ``KeyboardInterrupt`` at once (``hard``).
    Only the main thread can own signal handlers; elsewhere the guard does nothing."""

    def __init__(self) -> None:
        self.requested = False
        self.hard = False
        self._previous: object = None
        self._installed = False

    def _handle(self, signum: int, frame: object) -> None:
        if self.requested:
            self.hard = True
            raise KeyboardInterrupt("aborted by a second Ctrl-C")
        self.requested = True
        log.warning(
            "interrupted: finishing this step, then writing a checkpoint (Ctrl-C again aborts)"
        )

    def __enter__(self) -> InterruptGuard:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.getsignal(signal.SIGINT)
            signal.signal(signal.SIGINT, self._handle)
            self._installed = True
        return self

    def __exit__(self, *exc: object) -> None:
        if self._installed:
            previous = self._previous if self._previous is not None else signal.SIG_DFL
            signal.signal(signal.SIGINT, previous)
            self._installed = False
