"""``lr_contact_time``: the detected contact time of two blocks, LR paper Fig. 2B.

The column of ``benchmarks.lr_compression`` with the blocks 7.5 mm (1.5 cells) apart; the
contact plane (the top of the lower block) on a grid line (y = 50 mm) or mid-cell (52.5 mm). The
upper block starts moving down at v0 (bfemp's choice, so that the exact contact time is
t_c = 7.5 mm / v0 from the start; the paper drives the top only), the top boundary moving with
it. t_detect is the end time of the first step whose second correction changes a momentum
(``StepReport.contact_pairs > 0``). Detectors: LR and the velocity-only one (mass-gradient
normals, contact when approaching).

Targets (T): |t_detect - t_c| < 2 % t_c for LR on the grid line and mid-cell; control: the
velocity-only detector detects before t_c - 0.5 dx / v0 in both cases. Runs to 1.2 t_c; v0 =
0.5 % of c_K in quick mode, 0.05 % in full (the paper's).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from benchmarks.common import figure, save
from benchmarks.lr_compression import C_K, DX, MODES, column_scene, run_case
from benchmarks.runner import Benchmark, name_unless, register

log = logging.getLogger(__name__)

NAME = "lr_contact_time"
GAP = 0.0075  # m
TOL_CONTACT_TIME = 0.02


def contact_time(mode: str) -> dict:
    """Fig. 2B: the detected contact time against t_c = gap / v0 (grid line and mid-cell)."""
    frac, _ = MODES[mode]
    v0 = frac * C_K
    t_c = GAP / v0
    cases = {}
    for where, y in (("grid_line", 0.050), ("mid_cell", 0.0525)):
        for detector in ("lr", "velocity"):
            scene = column_scene(v0=v0, interface_y=y, gap=GAP, moving_top=True)
            case = run_case(
                scene,
                strain=0.0,
                v0=v0,
                stop_at_contact=1.2 * t_c,
                samples=50,
                detector=detector,
                corrections=2,  # the paper's two corrections
            )
            t_det = case["t_detect"]
            cases[f"{where}/{detector}"] = {
                "t_detect": t_det,
                "relative_error": None if t_det is None else (t_det - t_c) / t_c,
                "dt": case["dt"],
                "t": case["t"],
                "stress": case["stress"],
            }
    early = t_c - 0.5 * DX / v0
    lr = [cases[f"{w}/lr"] for w in ("grid_line", "mid_cell")]
    velocity = [cases[f"{w}/velocity"]["t_detect"] for w in ("grid_line", "mid_cell")]
    lr_ok = all(
        c["t_detect"] is not None and abs(c["relative_error"]) < TOL_CONTACT_TIME for c in lr
    )
    velocity_early = all(t is not None and t < early for t in velocity)
    return {
        "v0": v0,
        "gap": GAP,
        "t_c": t_c,
        "cases": cases,
        "targets": {"lr_within_2pct": lr_ok, "velocity_detector_early": velocity_early},
    }


def plot(record: dict, path: Path) -> None:
    """Fig. 2B: the mean stress against time per case, t_c dashed."""
    fig, ax = figure((6, 4.2), layout="tight")
    for key, case in record["cases"].items():
        ax.plot(1e3 * np.asarray(case["t"]), -1e-6 * np.asarray(case["stress"]), label=key)
    ax.axvline(1e3 * record["t_c"], color="k", lw=0.6, ls="--")
    ax.set(xlabel="t (ms)", ylabel="mean -sigma_yy (MPa)")
    save(fig, path, [ax])


BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        MODES,
        lambda mode, cfg: contact_time(mode),
        plot=plot,
        record=name_unless("full", NAME),
    )
)
run = BENCHMARK.run
