"""Measured points of a trade study kept on disk, so that a stopped sweep resumes (``--resume``).

Each point's measurement is written as soon as it arrives, one JSON file per point in
``<out>/tradeoff_points/`` (or ``--points DIR``), named by a hash of its benchmark module, its
settings, its thread count and the code that computes it (``code_version``: every Python file of
``bfemp``, ``solvers`` and ``geometry``, and the ``benchmarks`` modules a point's process
imports, followed through every import statement). Keying on the code rather than the commit
lets a sweep that takes several sessions go on across commits that touch only documentation,
tests, records or benchmarks a point does not run; each kept point names the commit that
measured it. A run that ended in a named step failure (``StepError``) is kept like any
measurement (the same code and settings end the same way); points that gave no metrics (a
crash, a timeout, a refusal) are not: a resumed sweep runs them again.
"""

from __future__ import annotations

import ast
import hashlib
import json
import logging
import os
from pathlib import Path

log = logging.getLogger(__name__)

FOLDER = "tradeoff_points"
CODE_PACKAGES = ("bfemp", "solvers", "geometry")
# the modules a point's process runs; _tradeoff_point loads _tradeoff_runs by name
# (importlib, which the static reading does not follow), hence both are named here
POINT_MODULES = ("benchmarks._tradeoff_point", "benchmarks._tradeoff_runs")
ROOT = Path(__file__).resolve().parents[1]


def _module_file(root: Path, name: str) -> Path | None:
    """The file of module ``name`` under ``root`` (``a/b.py`` or ``a/b/__init__.py``), or None
    where it is not a module of the project."""
    base = root.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _imports(root: Path, name: str, path: Path) -> set[str]:
    """The project modules that the file ``path`` of module ``name`` names in any import
    statement (function bodies included), with the packages above each."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_bytes(), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from the package ``level - 1`` above this one
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)  # submodules
    with_parents = {".".join(m.split(".")[: i + 1]) for m in found for i in range(m.count(".") + 1)}
    return {m for m in with_parents if m and _module_file(root, m) is not None}


def imported_modules(root: str | Path, modules: tuple[str, ...]) -> dict[str, Path]:
    """``modules`` and every project module they import, directly or not (read statically from
    the import statements, so an import inside a function counts): name -> file.

    Raises:
        ValueError: a module of ``modules`` has no file under ``root``.
    """
    root = Path(root)
    todo = list(modules)
    for name in modules:
        if _module_file(root, name) is None:
            raise ValueError(f"code_version: module {name!r} has no file under {root}")
        todo += [".".join(name.split(".")[: i + 1]) for i in range(name.count("."))]
    seen: dict[str, Path] = {}
    while todo:
        name = todo.pop()
        path = _module_file(root, name)
        if name in seen or path is None:
            continue
        seen[name] = path
        todo += sorted(_imports(root, name, path) - set(seen))
    return dict(sorted(seen.items()))


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
