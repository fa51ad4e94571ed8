"""Measured points of a trade study kept on disk, so that a stopped sweep resumes (``--resume``).

A full sweep runs for many hours; a machine that goes down, a killed job or a Dask worker lost
would otherwise throw away every point measured so far, since the record is written once at the
end. Each point's measurement is therefore written as soon as it arrives, one JSON file per
point in ``<out>/tradeoff_points/`` (or ``--points DIR``), named by a hash of what the point
runs: its benchmark module, its settings, its thread count and the code that computes it
(``code_version``: the content of every Python file of ``bfemp``, ``solvers``, ``geometry`` and
``benchmarks``). ``sweep(..., resume=True)`` takes the points found there instead of running them
again; a point of other code, other settings or other threads has another name and runs again.
Keying on the code rather than the commit lets a sweep that takes several sessions go on across
commits that touch only documentation, tests or records (the folder can be committed); each
kept point names the commit that measured it. Failed points (a crash, a timeout, a refusal)
are not kept: a resumed sweep runs them again.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path

log = logging.getLogger(__name__)

FOLDER = "tradeoff_points"
CODE_PACKAGES = ("bfemp", "solvers", "geometry", "benchmarks")
ROOT = Path(__file__).resolve().parents[1]


def code_version(root: str | Path = ROOT, packages: tuple[str, ...] = CODE_PACKAGES) -> str:
    """A 20-hex-digit digest of every ``*.py`` file under ``packages`` of ``root`` (relative
    path and content), so that edited code, committed or not, gets another digest."""
    digest = hashlib.sha256()
    root = Path(root)
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
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
        """Keep ``measurement`` of ``job`` (not a failed one); whether it was written."""
        if measurement.get("failure"):
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
