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

One writer at a time: a run holds the folder's lock (:func:`lock_run_folder`,
:class:`RunFolderLock`) from before it reads or deletes anything there until its manifest is
final, and meanwhile removes the temporary files a killed run left (:func:`remove_temporary_files`).
"""

from __future__ import annotations

import contextlib
import datetime
import json
import logging
import os
import re
import socket
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from bfemp.checkpoint import CHECKPOINT_FILE, SIDECAR_FILE, InterruptGuard, write_checkpoint
from bfemp.errors import RunFolderError, SceneError, warn_user
from bfemp.io.vtk import atomic_write_text

__all__ = [
    "LOCK_FILE",
    "RUN_FILES",
    "RunFolderLock",
    "earlier_run_outputs",
    "finish_outputs",
    "lock_holder",
    "lock_run_folder",
    "prepare_run_folder",
    "remove_temporary_files",
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
    _make_folder(out)
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
    return out


def _make_folder(out: Path) -> None:
    """Create the run folder ``out``; ``RunFolderError`` naming it when it is a file or
    cannot be made (instead of the OS's ``[Errno 17] File exists``)."""
    if out.exists() and not out.is_dir():
        raise RunFolderError(
            "the output folder is a file",
            file=str(out),
            hint="give --out (out=) a folder, or a path that does not exist yet",
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise RunFolderError(
            f"cannot create the output folder: {err.strerror or err}", file=str(out)
        ) from None


#: the lock file of a run folder (see :class:`RunFolderLock`)
LOCK_FILE = ".bfemp.lock"
#: a temporary file of ``atomic_path``: ``.NAME.`` + the random part of ``tempfile`` + ``.tmp``
_TMP_RE = re.compile(r"\.(?P<name>.+)\.[A-Za-z0-9_]+\.tmp")
_FRAME_RE = re.compile(r"frame_\d+\.vtu")


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _process_start(pid: int) -> str | None:
    """Start time of process ``pid`` (clock ticks after boot, field 22 of ``/proc/PID/stat``),
    which tells a process from a later one given the same pid; None where there is no /proc."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rindex(")") + 2 :].split()  # fields from 3 on (the name may hold spaces)
    return fields[19] if len(fields) > 19 else None


def _holder_alive(holder: dict) -> bool | None:
    """Whether the process of lock record ``holder`` still runs (None: another host, unknown)."""
    if holder.get("host") != socket.gethostname():
        return None
    pid = holder.get("pid")
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, as another user's process
        pass
    start = holder.get("process_start")
    return start is None or _process_start(pid) in (None, start)


def _describe(holder: dict) -> str:
    pid = holder.get("pid", "?")
    return f"pid {pid} on {holder.get('host', '?')}, started {holder.get('started', '?')}" + (
        f": {' '.join(holder['command'])}" if holder.get("command") else ""
    )


def _read_holder(text: str) -> dict:
    try:
        holder = json.loads(text) if text.strip() else {}
    except ValueError:
        return {}
    return holder if isinstance(holder, dict) else {}


def lock_holder(out: str | Path) -> dict | None:
    """The lock record (``pid``, ``host``, ``started``, ``command``) of the run writing ``out``
    now; None when no run holds it (no lock file, or one left by a process that has ended).

    It reads the lock file and checks that its process runs (pid and, on Linux, the process'
    start time, so a reused pid is not taken for the holder); it never takes the lock, so it
    cannot get in a starting run's way. A holder on another host (a shared file system)
    cannot be checked and is reported with ``alive`` None.
    """
    try:
        text = (Path(out) / LOCK_FILE).read_text()
    except OSError:
        return None
    holder = _read_holder(text)
    alive = _holder_alive(holder)
    return None if alive is False else {**holder, "alive": alive}


class RunFolderLock:
    """The exclusive lock of a run folder: one writing run at a time.

    The lock is ``fcntl.flock`` on ``{out}/.bfemp.lock``. Chosen over an ``O_EXCL`` lock file
    because the kernel releases a flock when its process ends, however it ends (SIGKILL, a
    crash, the out-of-memory killer): a lock file that nobody flocks is stale by construction,
    and taking it over needs no guess from a pid (which can be reused, or belong to another
    host). The file holds the holder's ``pid``, ``host``, ``started`` (UTC), ``command`` and
    ``process_start``, for the refusal of a second writer and for ``bfemp info``. On release
    the file is deleted while still locked; a run that opened it just before then locks a
    deleted file, which it sees (its file is no longer the one at the path) and starts over.
    On NFS, Linux maps flock to NFS byte-range locks; where ``fcntl`` is missing (Windows) or
    the file system refuses locks, the folder is not locked and a warning says so.

    Args:
        out: the run folder (it must exist).

    Raises:
        RunFolderError: another process holds the lock (the message names it).
    """

    def __init__(self, out: str | Path) -> None:
        self.out = Path(out)
        self.path = self.out / LOCK_FILE
        self.previous: dict | None = None  # the record of a stale lock taken over
        self._fd: int | None = None
        self._acquire()

    def _acquire(self) -> None:
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX
            warn_user(
                f"RUN_FOLDER_UNLOCKED: no fcntl on this platform: {self.out} is not locked "
                "against a second run",
                logger=log,
            )
            return
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as err:
                raise RunFolderError(
                    f"cannot write in the output folder: {err.strerror or err}", file=str(self.out)
                ) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(self.path.read_text() if self.path.exists() else "")
                os.close(fd)
                who = _describe(holder) if holder else "a process that is starting"
                raise RunFolderError(
                    f"the folder is in use by another bfemp run ({who})",
                    file=str(self.out),
                    hint="wait until it ends (bfemp info shows it as running), stop it, or "
                    f"choose another folder; the lock is {LOCK_FILE}",
                ) from None
            except OSError as err:  # a file system without locks (some network mounts)
                os.close(fd)
                warn_user(
                    f"RUN_FOLDER_UNLOCKED: {self.out} cannot be locked "
                    f"({err.strerror or err}): a second run into it is not refused",
                    logger=log,
                )
                return
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # its holder deleted it on release while we waited: lock the new one
        text = os.read(fd, 1 << 16).decode("utf-8", "replace")
        if text.strip():  # a lock file nobody held: left by a run that was killed
            self.previous = _read_holder(text)
            holder = _describe(self.previous) if self.previous else "holder unknown"
            warn_user(
                f"STALE_LOCK: took over the lock of {self.out} left by a run that ended without "
                f"releasing it (killed or crashed): {holder}",
                logger=log,
            )
        record = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": _now(),
            "command": list(sys.argv),
            "process_start": _process_start(os.getpid()),
        }
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)
        self._fd = fd

    def release(self) -> None:
        """Delete the lock file and release the lock (idempotent)."""
        if self._fd is None:
            return
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()
        os.close(self._fd)
        self._fd = None


def remove_temporary_files(out: str | Path) -> list[Path]:
    """Delete the temporary files that atomic writes left in ``out`` when their run was killed.

    Those are the hidden ``.NAME.XXXXXXXX.tmp`` files of :func:`bfemp.io.vtk.atomic_path`
    beside a run's own files: ``NAME`` one of :data:`RUN_FILES`, ``scene.toml`` or a ``.pvd``
    in ``out``, a ``frame_*.vtu`` in a body folder ``out/BODY/``. Call it only while holding the
    folder's lock (no run of ours writes there then). Returns the paths removed.
    """
    out = Path(out)
    ours = {*RUN_FILES, "scene.toml"}
    removed = []
    for folder in [out, *(p for p in out.iterdir() if p.is_dir() and not p.name.startswith("."))]:
        for path in folder.glob(".*.tmp"):
            match = _TMP_RE.fullmatch(path.name)
            if not match or not path.is_file():
                continue
            name = match.group("name")
            if (folder == out and (name in ours or name.endswith(".pvd"))) or (
                folder != out and _FRAME_RE.fullmatch(name)
            ):
                path.unlink()
                removed.append(path)
    if removed:
        log.info(
            "removed %d temporary files left by an interrupted run: %s",
            len(removed),
            ", ".join(str(p.relative_to(out)) for p in removed[:5])
            + (", ..." if len(removed) > 5 else ""),
        )
    return removed


@contextlib.contextmanager
def lock_run_folder(out: str | Path) -> Iterator[RunFolderLock]:
    """Create the run folder ``out``, hold its lock (:class:`RunFolderLock`) for the block and
    remove the temporary files of a killed run first (:func:`remove_temporary_files`).

    Raises:
        RunFolderError: ``out`` is a file or cannot be created, or another run holds it.
    """
    out = Path(out)
    _make_folder(out)
    lock = RunFolderLock(out)
    try:
        remove_temporary_files(out)
        yield lock
    finally:
        lock.release()


def write_scene_file(out: str | Path, text: str) -> Path:
    """Write ``{out}/scene.toml`` (atomically): the scene file of the run (``Simulation.run``
    makes it from the scene file it was read from, or writes its ``Scene``)."""
    return atomic_write_text(Path(out) / "scene.toml", text)


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
                    warn_user(f"OUTPUT_NOT_WRITTEN: {name} not written: {err}", logger=log)
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
