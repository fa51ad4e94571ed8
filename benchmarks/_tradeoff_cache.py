"""Measured points of a trade study kept on disk, so that a stopped sweep resumes (``--resume``).

One JSON file per point in ``<out>/tradeoff_points/`` (or ``--points DIR``), written as soon as
it arrives and named by a hash of its module, settings, thread count and the code that computes
it (``code_version``), not the commit: a sweep of several sessions goes on across commits that
touch only what a point does not run; each kept point names the commit that measured it. A run
that ended in a named step failure (``StepError``) is kept (the same code and settings end the
same way); a point without metrics (a crash, a timeout, a refusal) runs again.
"""

from __future__ import annotations

import hashlib
import json
import logging
import modulefinder
import os
from pathlib import Path

log = logging.getLogger(__name__)

FOLDER = "tradeoff_points"
CODE_PACKAGES = ("bfemp", "solvers", "geometry")
# the modules a point's process runs; _tradeoff_point loads _tradeoff_runs by name
# (importlib, which the static reading does not follow), hence both are named here
POINT_MODULES = ("benchmarks._tradeoff_point", "benchmarks._tradeoff_runs")
ROOT = Path(__file__).resolve().parents[1]


def imported_modules(root: str | Path, modules: tuple[str, ...]) -> dict[str, Path]:
    """``modules`` and every project module under ``root`` they import, directly or not (read
    statically by ``modulefinder`` from the compiled code, so an import inside a function
    counts): name -> file.

    Raises:
        ValueError: a module of ``modules`` has no file under ``root``.
    """
    finder = modulefinder.ModuleFinder(path=[str(root)])
    for name in modules:
        try:
            finder.import_hook(name)
        except ImportError:
            raise ValueError(f"code_version: module {name!r} has no file under {root}") from None
    return {n: Path(m.__file__) for n, m in sorted(finder.modules.items()) if m.__file__}


def code_version(
    root: str | Path = ROOT,
    packages: tuple[str, ...] = CODE_PACKAGES,
    modules: tuple[str, ...] = POINT_MODULES,
) -> str:
    """A 20-hex-digit digest of the code a point runs: every ``*.py`` file under ``packages``
    of ``root`` and the files of ``modules`` and of the project modules they import
    (``imported_modules``), each by relative path and content, so that edited code, committed or
    not, gets another digest and code the point never imports does not."""
    root = Path(root)
    files = {p for package in packages for p in (root / package).rglob("*.py")}
    files |= set(imported_modules(root, modules).values()) if modules else set()
    digest = hashlib.sha256()
    for path in sorted(files):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()[:20]


class PointCache:
    """One JSON file per measured point, keyed by what the point runs.

    Args:
        folder: where the files go (created on the first write).
        commit: the commit that measures (stored with each point; None outside git).
        code: the digest of the code (part of every key; default ``code_version()``).
    """

    def __init__(self, folder: str | Path, commit: str | None, code: str | None = None) -> None:
        self.folder = Path(folder)
        self.commit = commit
        self.code = code_version() if code is None else code

    def key(self, job: dict) -> str:
        """A 20-hex-digit name for ``job`` (``execute_point``'s argument) with this code."""
        what = {
            "module": job["module"],
            "settings": job["settings"],
            "threads": int(job["threads"]),
            "code": self.code,
        }
        text = json.dumps(what, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def path(self, job: dict) -> Path:
        return self.folder / f"{self.key(job)}.json"

    def entry(self, job: dict) -> dict | None:
        """The kept file of ``job`` (``id``, ``commit``, ``code``, ``job``, ``measurement``), or
        None (none kept, or an unreadable file)."""
        path = self.path(job)
        try:
            entry = json.loads(path.read_text())
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as err:
            log.warning("tradeoff cache: %s is unreadable (%s); the point runs again", path, err)
            return None
        return entry if isinstance(entry, dict) and entry.get("measurement") else None

    def get(self, job: dict) -> dict | None:
        """The kept measurement of ``job``, or None."""
        entry = self.entry(job)
        return None if entry is None else entry["measurement"]

    def put(self, point_id: str, job: dict, measurement: dict) -> bool:
        """Keep ``measurement`` of ``job`` (not one without metrics: a crash, a timeout or a
        refusal; a run's own step failure is kept); whether it was written."""
        if measurement.get("metrics") is None:
            return False
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.path(job)
        entry = {
            "id": point_id,
            "commit": self.commit,
            "code": self.code,
            "job": {k: job[k] for k in ("module", "settings", "threads")},
            "measurement": measurement,
        }
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(entry, default=float))
        tmp.replace(path)  # atomic: a reader never sees half a file
        return True
