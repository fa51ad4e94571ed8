"""Timing probe of the colliding rings at the paper's resolution (``rings --mode full_probe``).

The full mode (``benchmarks.rings``: 19796 particles, 1714 FEM vertices, 1500 steps per
transfer) takes 15-20 minutes on 2 cores; the probe runs the same scene, the same stepper and
both transfers, cut at ``t_end = 0.035`` s: 125 steps of free flight (the rings touch at 0.025 s)
and about 50 in contact. Its record holds, per transfer, the seconds of every phase of the step
(``phase_s``: the ``StepReport.timings`` of the barrier stepper summed over the steps), the mean
wall time of a step apart for free-flight steps and for steps with a contact pair, and a
digest of the end state (bit-for-bit comparison of two code versions).

The full mode's wall is extrapolated from the probe in two ways (``extrapolation``):

- ``by_steps``: per transfer, ``n_free * mean_free + n_contact * mean_contact`` with the step
  counts of the committed full record (``benchmarks/records/rings.json``: 1500 steps, about 1180
  of them with a contact pair);
- ``by_iterations``: per transfer, ``n_free * mean_free + its_contact * s_per_iteration`` with
  ``s_per_iteration`` the probe's contact-step seconds over its contact Newton iterations and
  ``its_contact`` the full record's Newton iterations less its free steps' (at the probe's
  iterations per free step): deeper contact takes more Newton iterations per step than the
  probe's first contact steps.

Both add the run's seconds per step outside the stepper (the metrics row of every step and the
penetration check of ``benchmarks.rings``), leave out the model set-up (a few seconds) and
assume the cost of a Newton iteration in deep contact is that of the first contact steps (more
pairs later: the line search's CCD and the barrier's Hessian grow with them).
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np

#: contact steps left out of the means: the first two compile the contact kernels (pairs, CCD)
WARM_CONTACT_STEPS = 2
#: the committed full-mode record whose step and iteration counts the extrapolation takes
FULL_RECORD = Path(__file__).resolve().parent / "records" / "rings.json"


def full_counts(record: Path = FULL_RECORD) -> dict:
    """transfer -> ``{"steps", "contact_steps", "newton_iterations", "commit"}`` of the full
    record's runs (``{}`` when the record is missing or not a full-mode one)."""
    if not record.exists():
        return {}
    payload = json.loads(record.read_text())
    if payload.get("mode") != "full":
        return {}
    commit = payload.get("environment", {}).get("commit")
    keys = ("steps", "contact_steps", "newton_iterations")
    return {t: {**{k: r[k] for k in keys}, "commit": commit} for t, r in payload["runs"].items()}


def digest(array: np.ndarray) -> str:
    """First 16 hex digits of the SHA-256 of ``array``'s float64 bytes (C order)."""
    data = np.ascontiguousarray(array, dtype=np.float64).tobytes()
    return hashlib.sha256(data).hexdigest()[:16]


def step_table(metrics: object) -> dict[str, np.ndarray]:
    """Per-step columns of a run's metrics (row 0, the initial state, dropped): every
    ``time_*`` phase in s, ``contact_pairs`` and ``iterations_newton``."""
    times = [c for c in metrics.columns if c.startswith("time_")]
    out = {c: np.nan_to_num(metrics.column(c)[1:]) for c in times}
    out["contact_pairs"] = metrics.column("contact_pairs")[1:]
    out["iterations_newton"] = np.nan_to_num(metrics.column("iterations_newton")[1:])
    return out


def summarise(table: dict[str, np.ndarray], sim: object, wall_s: float, cpu_s: float) -> dict:
    """The probe's view of one transfer: phase seconds, mean step times, iterations, digest;
    ``cpu_s``: the process's CPU seconds over the run (all threads: less sensitive than the wall
    to other processes on a shared machine).

    The first step and the first ``WARM_CONTACT_STEPS`` steps with a contact pair are left out
    of the means (they compile what the numba cache lacks: the elastic and the contact kernels,
    up to minutes on a loaded machine; ``first_step_s`` and ``first_contact_steps_s`` record
    them); ``step_s`` keeps every step's seconds.
    """
    step_s = table["time_step"]
    contact = table["contact_pairs"] > 0
    later = np.arange(step_s.size) > 0
    warm = np.flatnonzero(contact)[:WARM_CONTACT_STEPS]
    later[warm] = False
    free, touch = later & ~contact, later & contact
    phases = sorted(c for c in table if c.startswith("time_") and c != "time_step")

    def per_step(mask: np.ndarray) -> dict[str, float]:
        n = max(1, int(mask.sum()))
        return {p[len("time_") :]: float(table[p][mask].sum() / n) for p in phases}

    its = table["iterations_newton"]
    state = sim.state
    return {
        "steps": int(step_s.size),
        "free_steps": int((~contact).sum()),
        "contact_steps": int(contact.sum()),
        "wall_s": wall_s,
        "first_step_s": float(step_s[0]),
        "first_contact_steps_s": step_s[warm].tolist(),
        "mean_step_s": float(step_s[later].mean()),
        "mean_step_free_s": float(step_s[free].mean()) if free.any() else None,
        "mean_step_contact_s": float(step_s[touch].mean()) if touch.any() else None,
        "newton_iterations_free": int(its[~contact].sum()),
        "newton_iterations_contact": int(its[contact].sum()),
        "s_per_contact_iteration": float(step_s[touch].sum() / max(1.0, its[touch].sum())),
        "cpu_s": cpu_s,
        "outside_step_s": wall_s - float(step_s.sum()),
        "phase_s": {p[len("time_") :]: float(table[p].sum()) for p in phases + ["time_step"]},
        "phase_s_per_free_step": per_step(free),
        "phase_s_per_contact_step": per_step(touch),
        "end_state": {
            "t": float(state.t),
            "mpm_x": digest(state.mpm_x),
            "mpm_v": digest(state.mpm_v),
            "mpm_F": digest(state.mpm_F),
            "fem_x": digest(state.fem_x),
            "fem_v": digest(state.fem_v),
            "mpm_x_sum": float(state.mpm_x.sum()),
            "fem_x_sum": float(state.fem_x.sum()),
        },
        "step_s": step_s.tolist(),
    }


def extrapolate(runs: dict, full: dict) -> dict:
    """The full mode's wall in s from the probe's runs (see the module docstring).

    Args:
        runs: transfer -> ``summarise`` output.
        full: transfer -> ``full_counts`` entry (a transfer missing there is left out).
    """
    by_steps, by_its = {}, {}
    for transfer, run in runs.items():
        if transfer not in full:
            continue
        counts = full[transfer]
        n_touch = counts["contact_steps"]
        n_free = counts["steps"] - n_touch
        free = run["mean_step_free_s"] or 0.0
        touch = run["mean_step_contact_s"] or free
        # the run's seconds outside the stepper (metrics row, penetration check) per step
        outside = (run["wall_s"] - sum(run["step_s"])) / max(1, run["steps"])
        by_steps[transfer] = n_free * free + n_touch * touch + counts["steps"] * outside
        its_free_per_step = run["newton_iterations_free"] / max(1, run["free_steps"])
        its_contact = counts["newton_iterations"] - n_free * its_free_per_step
        by_its[transfer] = (
            n_free * free + its_contact * run["s_per_contact_iteration"] + counts["steps"] * outside
        )
    return {
        "full_counts": full,
        "by_steps_s": {**by_steps, "total": sum(by_steps.values())},
        "by_iterations_s": {**by_its, "total": sum(by_its.values())},
        "target_s": 600.0,
    }


def threads() -> dict:
    """numba's thread count and layer (the Hessian and assembly kernels run on it)."""
    import numba

    try:
        layer = numba.threading_layer()
    except ValueError:  # no parallel kernel has run yet
        layer = None
    return {"numba_threads": int(numba.get_num_threads()), "numba_layer": layer}


def measure_probe(cfg: dict, run_transfer, transfers: tuple[str, ...]) -> dict:  # noqa: ANN001
    """Both transfers cut at ``cfg["t_end"]``: ``{"runs", "extrapolation", "threads", ...}``."""
    import os

    runs, physics = {}, {}
    load = [os.getloadavg()[0]]
    for transfer in transfers:
        keep: dict = {}
        start, cpu = time.perf_counter(), time.process_time()
        reduced = run_transfer(cfg, transfer, keep=keep)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        runs[transfer] = summarise(step_table(keep["sim"].metrics), keep["sim"], wall, cpu)
        keys = ("momentum_drift_rel", "min_distance", "penetrations", "error", "contact_steps")
        physics[transfer] = {k: reduced[k] for k in keys}
        load.append(os.getloadavg()[0])
    return {
        "runs": runs,
        "physics": physics,
        "extrapolation": extrapolate(runs, full_counts()),
        "threads": threads(),
        "load_average_1min": load,
        "wall_s": sum(r["wall_s"] for r in runs.values()),
    }
