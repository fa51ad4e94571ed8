"""Measured points of a trade study kept on disk, so that a stopped sweep resumes (``--resume``).

A full sweep runs for many hours; a machine that goes down, a killed job or a Dask worker lost
would otherwise throw away every point measured so far, since the record is written once at the
end. Each point's measurement is therefore written as soon as it arrives, one JSON file per
point in ``<out>/tradeoff_points/``, named by a hash of what the point runs: its benchmark
module, its settings, its thread count and the commit of the code. ``sweep(..., resume=True)``
takes the points found there instead of running them again; a point of another commit, other
settings or other threads has another name and runs again. Failed points (a crash, a timeout,
a refusal) are not kept: a resumed sweep runs them again.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path

log = logging.getLogger(__name__)

FOLDER = "tradeoff_points"


class PointCache:
    """One JSON file per measured point, keyed by what the point runs.

    Args:
        folder: where the files go (created on the first write).
        commit: the commit of the code that measures (part of every key; None outside git).
    """

    def __init__(self, folder: str | Path, commit: str | None) -> None:
        self.folder = Path(folder)
        self.commit = commit

    def key(self, job: dict) -> str:
        """A 20-hex-digit name for ``job`` (``execute_point``'s argument) at this commit."""
        what = {
            "module": job["module"],
            "settings": job["settings"],
            "threads": int(job["threads"]),
            "commit": self.commit,
        }
        text = json.dumps(what, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def path(self, job: dict) -> Path:
        return self.folder / f"{self.key(job)}.json"

    def get(self, job: dict) -> dict | None:
        """The kept measurement of ``job``, or None (none kept, or an unreadable file)."""
        path = self.path(job)
        try:
            entry = json.loads(path.read_text())
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as err:
            log.warning("tradeoff cache: %s is unreadable (%s); the point runs again", path, err)
            return None
        return entry.get("measurement")

    def put(self, point_id: str, job: dict, measurement: dict) -> bool:
        """Keep ``measurement`` of ``job`` (not a failed one); whether it was written."""
        if measurement.get("failure"):
            return False
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.path(job)
        entry = {
            "id": point_id,
            "commit": self.commit,
            "job": {k: job[k] for k in ("module", "settings", "threads")},
            "measurement": measurement,
        }
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(entry, default=float))
        tmp.replace(path)  # atomic: a reader never sees half a file
        return True
