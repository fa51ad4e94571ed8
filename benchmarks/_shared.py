"""Small helpers shared by several benchmarks (beside ``benchmarks.common``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

#: the repository (the folder above ``benchmarks``)
ROOT = Path(__file__).resolve().parents[1]


def python_child(
    args: list[str], env: dict | None = None, timeout: float = 3600.0, **run: object
) -> subprocess.CompletedProcess:
    """``python ARGS`` in a child process with the repository first on its ``PYTHONPATH``
    (``env``: its environment, this process's by default), its output captured as text;
    ``run``: more ``subprocess.run`` options (``check``, ``cwd``). Raises
    ``subprocess.TimeoutExpired`` past ``timeout`` s."""
    env = dict(os.environ if env is None else env)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, env=env, timeout=timeout, **run
    )


def child_json(code: str, *args: str, env: dict | None = None, timeout: float = 3600.0) -> dict:
    """The JSON object that ``python -c CODE ARGS`` (``python_child``) prints last; a child
    past ``timeout`` s or failing gives ``{"error": why}`` (recorded, not fatal)."""
    try:
        done = python_child(["-c", code, *args], env, timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:.0f} s"}
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1:]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def falls_with_h(rows: list[dict], key: str, group: tuple[str, ...]) -> dict[tuple, bool]:
    """Whether ``row[key]`` falls at every refinement (h decreasing), per group of ``rows``
    (the values of the keys ``group``, in order of first appearance) holding two h or more;
    rows whose ``key`` is None are left out. ``rows``: dicts with ``"h"`` (m), ``key`` and
    ``group``."""
    series: dict[tuple, list] = {}
    for row in sorted(rows, key=lambda r: -r["h"]):
        if row[key] is not None:
            series.setdefault(tuple(row[g] for g in group), []).append(row[key])
    return {
        g: all(b < a for a, b in zip(v, v[1:], strict=False))
        for g, v in series.items()
        if len(v) > 1
    }


def check_settings(where: str, settings: dict, keys: tuple[str, ...]) -> None:
    """A ValueError naming the keys of ``keys`` missing from ``settings`` and those of
    ``settings`` not among ``keys`` (``where``: the function that checks, e.g.
    ``"hertz.run_point"``)."""
    missing = [key for key in keys if key not in settings]
    unknown = sorted(set(settings) - set(keys))
    if missing or unknown:
        raise ValueError(f"{where}: missing settings {missing}, unknown {unknown}")


class StepCost:
    """Wall time per phase (``report.timings``, s) and contact nodes
    (``report.extra["contact_nodes"]``) summed over the steps of an ``LRStepper`` run."""

    def __init__(self) -> None:
        self.phases: dict[str, float] = {}
        self.contact_nodes, self.steps = 0.0, 0

    def add(self, report: object) -> None:
        """Add one step's report."""
        for key, value in report.timings.items():
            self.phases[key] = self.phases.get(key, 0.0) + value
        self.contact_nodes += report.extra["contact_nodes"]
        self.steps += 1

    def summary(self) -> dict:
        """``ms_per_step`` (per phase) and ``mean_contact_nodes`` over the steps added."""
        return {
            "ms_per_step": {k: 1e3 * v / self.steps for k, v in self.phases.items()},
            "mean_contact_nodes": self.contact_nodes / self.steps,
        }
