"""The run manifest (``{out}/manifest.json``) and the summary of a result folder (``bfemp info``).

The manifest records what a run was and how it went, so that a result folder explains itself:

- ``parameters``: the simulation settings (strategy, integrator, transfer, dt, tol, ...), the run
  settings (t_end, frame and checkpoint intervals) and what the caller adds (the command line
  adds the scene file, its SHA-256 and the command);
- ``model``: dimension, bodies (nodes, cells, particles, materials), grid, boundaries, contact,
  and the model fingerprint that checkpoints are matched against;
- ``versions``: Python, bfemp and the libraries; ``git``: commit (and whether the tree had
  changes) of the bfemp sources when they are a git checkout;
- ``sessions``: one entry per ``run`` call (a resumed run adds one): start, end, steps, wall time
  and status (``running``, ``completed``, ``interrupted`` or ``failed`` with its message);
- ``status``, ``message`` and ``result`` (t, step, frames, Newton iterations) of the last session.

The file is rewritten atomically at the start and at the end of every session. A session that
was killed (SIGKILL, a crash, power loss) cannot record its end and stays ``running`` in the
file; the run folder's lock (:mod:`bfemp.io.outputs`) tells it from a live one: ``bfemp info``
shows it as ``interrupted``, and the next session (``--resume``) records it so in the file, with
the step of the checkpoint it was resumed from. A manifest that is not a JSON object with a
``sessions`` list is refused (``RunFolderError``), never silently replaced.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

from bfemp.checkpoint import SIDECAR_FILE, model_fingerprint
from bfemp.errors import RunFolderError, SceneError
from bfemp.io.metrics import MetricsLog
from bfemp.io.outputs import _now, lock_holder
from bfemp.io.vtk import atomic_write_text, read_pvd
from bfemp.materials import BulkShearHyperelastic

__all__ = [
    "MANIFEST_FILE",
    "RunManifest",
    "format_info",
    "git_info",
    "read_manifest",
    "run_info",
    "versions",
]


MANIFEST_FILE = "manifest.json"
_PACKAGES = (
    "bfemp",
    "numpy",
    "scipy",
    "numba",
    "meshio",
    "python-fcl",
    "scikit-sparse",
    "tqdm",
    "matplotlib",
)


def versions() -> dict[str, str | None]:
    """Python and package versions (None for a package that is not installed)."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


def git_output(*args: str) -> str | None:
    """Standard output of ``git ARGS`` run in the bfemp package folder; None where git fails
    (not a checkout, no git, a 10 s timeout)."""
    try:
        out = subprocess.run(
            ["git", *args],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout


def git_info() -> dict[str, object]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the bfemp sources' git checkout."""
    commit = git_output("rev-parse", "HEAD")
    if commit is None:
        return {"commit": None, "dirty": None}
    status = git_output("status", "--porcelain", "--untracked-files=no")
    return {"commit": commit.strip(), "dirty": None if status is None else bool(status.strip())}


def _material(material: object) -> dict:
    out = {
        "type": getattr(material, "name", type(material).__name__),
        "E": material.E,
        "nu": material.nu,
        "density": material.density,
    }
    if isinstance(material, BulkShearHyperelastic):  # given by K and G; E, nu derived
        out.update(K=material.K, G=material.G)
    return out


def model_summary(model: object) -> dict:
    """Sizes and parameters of a ``Model`` (JSON-friendly)."""
    fem = [
        {
            "name": b.name,
            "nodes": b.n_nodes,
            "cells": b.cells.stop - b.cells.start,
            "prescribed_nodes": int(model.fem_prescribed[b.nodes].sum()),
            "material": _material(b.material),
        }
        for b in model.fem_bodies
    ]
    mpm = [
        {"name": b.name, "particles": b.n_particles, "material": _material(b.material)}
        for b in model.mpm_bodies
    ]
    contact = getattr(model, "contact", None)
    return {
        "dim": model.dim,
        "gravity": model.gravity.tolist(),
        "fem_bodies": fem,
        "mpm_bodies": mpm,
        "grid_dx": None if model.grid is None else model.grid.dx,
        "boundaries": [
            {"kind": b.kind, "levelset": type(b.levelset).__name__} for b in model.boundaries
        ],
        "contact": None
        if contact is None
        else {k: getattr(contact, k) for k in ("dhat", "kappa", "mu", "eps_v")},
        "fingerprint": model_fingerprint(model),
    }


def _write(path: Path, data: dict) -> None:
    atomic_write_text(path, json.dumps(data, indent=2, allow_nan=False, default=str) + "\n")


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def read_manifest(out: str | Path) -> dict | None:
    """The manifest of run folder ``out`` (None when it has none).

    Raises:
        RunFolderError: the file is unreadable, not JSON (e.g. truncated) or not an object
            with a ``sessions`` list; the message names the file and what is wrong.
    """
    path = Path(out) / MANIFEST_FILE
    if not path.is_file():
        return None
    hint = (
        "it records the run's earlier sessions: put back a good copy, or move it away to go "
        "on with a new manifest (that record is then lost)"
    )
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        what = "not valid JSON (truncated?)" if isinstance(err, ValueError) else "unreadable"
        raise RunFolderError(
            f"corrupt run manifest: {what}: {err}", file=str(path), hint=hint
        ) from None
    if not isinstance(data, dict) or not isinstance(data.get("sessions"), list):
        raise RunFolderError(
            "corrupt run manifest: not a JSON object with a 'sessions' list",
            file=str(path),
            hint=hint,
        )
    return data


#: what a session left ``running`` by a killed process is recorded as
_STALE = "interrupted"
_STALE_NOTE = "the session ended without recording its end (the process was killed or crashed)"


class RunManifest:
    """The manifest of one run folder, updated at the start and end of each session.

    Use :meth:`start`, then :meth:`finish`.
    """

    def __init__(self, out: Path, data: dict) -> None:
        self.out = out
        self.data = data
        self._clock = time.perf_counter()

    @property
    def path(self) -> Path:
        """``{out}/manifest.json``."""
        return self.out / MANIFEST_FILE

    @classmethod
    def start(
        cls,
        out: str | Path,
        sim: object,
        *,
        run: dict,
        resume: bool,
        extra: dict | None = None,
    ) -> RunManifest:
        """Write the manifest of a starting session (a resumed run keeps its earlier sessions).

        Args:
            out: the run folder.
            sim: the ``bfemp.Simulation``.
            run: run settings (``t_end`` s, ``every``, ``checkpoint_every``).
            resume: whether this session continues a checkpoint.
            extra: caller's parameters (e.g. ``{"scene_file": ..., "command": [...]}``).
        """
        out = Path(out)
        data: dict = (read_manifest(out) if resume else None) or {}
        for earlier in data.get("sessions", []):  # the caller holds the folder: none is live
            if earlier.get("status", "running") == "running":
                earlier.update(
                    status=_STALE,
                    message=f"{_STALE_NOTE}; resumed from the checkpoint at step "
                    f"{sim.state.step} (t = {sim.state.t:.6g} s)",
                )
        data.setdefault("created", _now())
        data["parameters"] = {
            "simulation": dict(sim.settings),
            "run": dict(run),
            **(extra or {}),
        }
        data["model"] = model_summary(sim.model)
        data["versions"] = versions()
        data["git"] = git_info()
        data["host"] = {"machine": platform.machine(), "cpus": os.cpu_count()}
        session = {
            "started": _now(),
            "resumed": bool(resume),
            "from_step": sim.state.step,
            "from_t": sim.state.t,
        }
        data.setdefault("sessions", []).append(session)
        data["status"], data["message"] = "running", ""
        manifest = cls(out, data)
        _write(manifest.path, data)
        return manifest

    def finish(
        self, sim: object, status: str, message: str = "", frames: int | None = None
    ) -> None:
        """Record the end of the session: ``status`` and the result reached."""
        metrics: MetricsLog = sim.metrics
        session = self.data["sessions"][-1]
        session.update(
            finished=_now(),
            to_step=sim.state.step,
            to_t=sim.state.t,
            wall_s=round(time.perf_counter() - self._clock, 3),
            status=status,
            notes=dict(getattr(sim, "note_counts", {})),
        )
        # named step notes and warnings (Simulation.note_counts) summed over the run's sessions
        totals: dict[str, int] = {}
        for s in self.data["sessions"]:
            for name, count in s.get("notes", {}).items():
                totals[name] = totals.get(name, 0) + int(count)
        self.data["notes"] = totals
        result = {"t": sim.state.t, "step": sim.state.step, "frames": frames}
        if "iterations_newton" in metrics.columns:
            result["newton_iterations_total"] = int(np.nansum(metrics.column("iterations_newton")))
        failed = getattr(sim, "failed_report", None)
        if status == "failed" and failed is not None:
            # the failed step is not in the metrics (it has no end state): its iterations here
            result["failed_step"] = {
                "step": int(failed.step),
                "t": float(failed.t),
                "status": str(failed.status),
                "iterations": {k: int(v) for k, v in failed.iterations.items()},
            }
        if "energy_total" in metrics.columns:
            e = metrics.column("energy_total")
            result["energy_total_first"] = _finite(e[0])
            result["energy_total_last"] = _finite(e[-1])
        self.data.update(status=status, message=message, result=result, updated=_now())
        _write(self.path, self.data)


def run_info(out: str | Path) -> dict:
    """Summary of a result folder: manifest, metrics, frames and checkpoint (what exists)."""
    out = Path(out)
    if not out.is_dir():
        raise SceneError(f"result folder not found: {out}")
    manifest_path, metrics_path = out / MANIFEST_FILE, out / "metrics.csv"
    if not manifest_path.is_file() and not metrics_path.is_file():
        raise SceneError(
            f"{out} has neither {MANIFEST_FILE} nor metrics.csv: not a bfemp result folder",
            hint="give the --out folder of a run",
        )
    info: dict = {"folder": str(out)}
    manifest = read_manifest(out)
    if manifest is not None:
        info["manifest"] = manifest
        info["status"] = manifest.get("status", "?")
        holder = lock_holder(out)
        if holder is not None:  # a live run holds the folder (its manifest may lag behind)
            info["running"] = holder
            info["status"] = "running"
        elif info["status"] == "running":  # no live run holds the folder: it was killed
            info["status"] = _STALE
            info["status_note"] = _STALE_NOTE
    if metrics_path.is_file():
        metrics = MetricsLog.from_csv(metrics_path)
        summary: dict = {"rows": len(metrics)}
        if len(metrics):
            summary["t_last"] = float(metrics.column("t")[-1])
        failed = (manifest or {}).get("result", {}).get("failed_step")
        failed_its = (failed or {}).get("iterations", {}).get("newton")
        if "iterations_newton" in metrics.columns and len(metrics) > 1:
            it = metrics.column("iterations_newton")[1:]
            summary["newton"] = {
                "total": int(np.nansum(it)),
                "mean": float(np.nanmean(it)),
                "max": int(np.nanmax(it)),
            }
        if failed_its is not None:  # the failed step is not in metrics.csv: count it too
            steps = int(np.count_nonzero(np.isfinite(it))) if "newton" in summary else 0
            newton = summary.setdefault("newton", {"total": 0, "max": 0})
            newton["total"] += int(failed_its)
            newton["mean"] = newton["total"] / (steps + 1)
            newton["max"] = max(newton["max"], int(failed_its))
            newton["failed_step"] = {"step": failed["step"], "iterations": int(failed_its)}
        if "energy_total" in metrics.columns:
            e = metrics.column("energy_total")
            summary["energy_total"] = [_finite(e[0]), _finite(e[-1])]
        timings = [c for c in metrics.columns if c.startswith("time_") and c != "time_step"]
        summary["time_per_phase_s"] = {c[5:]: float(np.nansum(metrics.column(c))) for c in timings}
        if "time_step" in metrics.columns:
            summary["time_steps_s"] = float(np.nansum(metrics.column("time_step")))
        info["metrics"] = summary
    info["frames"] = {p.stem: len(read_pvd(p)) for p in sorted(out.glob("*.pvd"))}
    if (out / SIDECAR_FILE).is_file():
        try:
            ckpt = json.loads((out / SIDECAR_FILE).read_text())
            info["checkpoint"] = {"t": ckpt.get("t"), "step": ckpt.get("step")}
        except (OSError, ValueError, AttributeError) as err:
            info["checkpoint"] = {"error": f"{out / SIDECAR_FILE} unreadable: {err}"}
    if info.get("status_note") and "step" in info.get("checkpoint", {}):
        info["status_note"] += (
            f"; --resume continues from the checkpoint at step {info['checkpoint']['step']}"
        )
    return info


def _fmt(value: object, unit: str = "") -> str:
    if isinstance(value, float):
        return f"{value:.6g}{unit}"
    return f"{value}{unit}" if value is not None else "?"


def format_info(info: dict) -> str:
    """The text ``bfemp info`` prints for :func:`run_info`."""
    lines = [f"result folder: {info['folder']}"]
    man = info.get("manifest", {})
    if man:
        status = info.get("status", man.get("status", "?"))
        note = info.get("status_note") or man.get("message")
        if "running" in info:
            holder = info["running"]
            pid, host, since = (holder.get(k, "?") for k in ("pid", "host", "started"))
            where = "" if holder.get("alive") else ", not checked: another host"
            note = f"pid {pid} on {host}{where}, since {since}"
        lines.append(f"status:        {status}" + (f" ({note})" if note else ""))
        params = man.get("parameters", {})
        if "scene_file" in params:
            lines.append(f"scene file:    {params['scene_file']}")
        sim, run = params.get("simulation", {}), params.get("run", {})
        lines.append(
            "simulation:    "
            + ", ".join(f"{k} {_fmt(v)}" for k, v in sim.items())
            + (f"; t_end {_fmt(run.get('t_end'), ' s')}" if run else "")
        )
        for body in man.get("model", {}).get("fem_bodies", []):
            lines.append(
                f"fem body:      {body['name']}: {body['nodes']} nodes, {body['cells']} cells, "
                f"{body['material']['type']} E {_fmt(body['material']['E'], ' Pa')}"
            )
        for body in man.get("model", {}).get("mpm_bodies", []):
            lines.append(
                f"mpm body:      {body['name']}: {body['particles']} particles, "
                f"{body['material']['type']} E {_fmt(body['material']['E'], ' Pa')}"
            )
        sessions = man.get("sessions", [])
        wall = sum(s.get("wall_s", 0.0) for s in sessions)
        lines.append(f"sessions:      {len(sessions)} (wall time {wall:.1f} s)")
        if man.get("notes"):
            counts = ", ".join(f"{k} x {v}" for k, v in sorted(man["notes"].items()))
            lines.append(f"notes:         {counts} (times each was reported; warned once per run)")
        git = man.get("git", {})
        vers = man.get("versions", {})
        lines.append(
            f"versions:      bfemp {vers.get('bfemp')}, numpy {vers.get('numpy')}, "
            f"git {git.get('commit') or 'unknown'}{' (modified)' if git.get('dirty') else ''}"
        )
    met = info.get("metrics")
    if met:
        lines.append(f"progress:      t = {_fmt(met.get('t_last'), ' s')}, {met['rows'] - 1} steps")
        if "newton" in met:
            n = met["newton"]
            failed = n.get("failed_step")
            lines.append(
                f"newton:        {n['total']} iterations (mean {n['mean']:.2f}, max {n['max']})"
                + (f"; the failed step {failed['step']}: {failed['iterations']}" if failed else "")
            )
        if "energy_total" in met:
            e0, e1 = met["energy_total"]
            lines.append(f"energy_total:  {_fmt(e0)} -> {_fmt(e1)} J")
        if met.get("time_per_phase_s"):
            phases = ", ".join(f"{k} {v:.2f}" for k, v in met["time_per_phase_s"].items())
            lines.append(f"time (s):      steps {met.get('time_steps_s', 0.0):.2f}; {phases}")
    for name, count in info.get("frames", {}).items():
        lines.append(f"frames:        {name}.pvd: {count}")
    if "checkpoint" in info:
        c = info["checkpoint"]
        if "error" in c:
            lines.append(f"checkpoint:    {c['error']}")
        else:
            lines.append(f"checkpoint:    step {c['step']}, t = {_fmt(c['t'], ' s')}")
    return "\n".join(lines)
