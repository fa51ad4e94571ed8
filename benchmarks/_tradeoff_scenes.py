"""The scenes, knobs and sweeps of the trade study (``benchmarks.tradeoff``).

``SCENES[scene]``: ``module`` (the benchmark module whose ``run_point(settings)`` runs one
point), ``knobs`` (the knobs it has), ``error`` (what the error is, in words), either
``error_key`` (the metric that is the error: an analytic reference) or ``reference_keys`` (the
metrics compared with the reference run), and per mode the ``base`` settings (every input of
``run_point``; the strategy by its trade-study name) and the ``sweeps`` (knob -> values);
``warmup`` shortens the quick base to a few steps that meet every kernel of the scene (contact
included): run once before the timed points, it fills numba's cache so that no point's time
holds compilation (results discarded).
"""

from __future__ import annotations

import math

KNOBS = ("strategy", "dt", "dx", "ppc", "spacing", "dhat", "eps_v", "tol")
#: knob -> +1 when a larger value is finer (more accurate, costlier), -1 when a smaller one is
FINER = {"dt": -1, "dx": -1, "ppc": 1, "spacing": -1, "dhat": -1, "eps_v": -1, "tol": -1}
#: strategy names of the trade study -> the library's stepper names
STRATEGIES = {"bfemp": "barrier"}
_HERTZ_PAPER_SPACING = math.sqrt(math.pi / 42920)  # m: the paper's particle count in the disk

SCENES = {
    "rings": {
        "module": "benchmarks.rings",
        "warmup": {"t_end": 0.05},  # the rings touch at t = 0.025 s
        "knobs": ("strategy", "dt", "dx", "ppc", "dhat", "tol"),
        "error": "max(|L - L_ref| / L_ref, |T - T_ref| / T_ref) of the energy loss L over the "
        "collision window and the contact duration T, against the reference run (the finest "
        "value of every swept knob at once)",
        "reference_keys": ("energy_loss_pct", "contact_duration_s"),
        "modes": {
            "quick": {
                "base": dict(
                    strategy="bfemp",
                    dt=1e-2,
                    dx=0.5,
                    ppc=4,
                    dhat=1e-2,
                    tol=1e-6,
                    fem_h=0.5,
                    t_end=0.3,
                    transfer="apic",
                ),
                "sweeps": {
                    "strategy": ("bfemp",),
                    "dt": (2e-2, 1e-2, 5e-3),
                    "dx": (0.5, 1.0 / 3.0),
                    "ppc": (4, 9),
                    "dhat": (2e-2, 1e-2),
                    "tol": (1e-4, 1e-6),
                },
            },
            "full": {
                "base": dict(
                    strategy="bfemp",
                    dt=2e-4,
                    dx=0.1,
                    ppc=9,
                    dhat=1e-2,
                    tol=1e-6,
                    fem_h=0.13,
                    t_end=0.3,
                    transfer="apic",
                ),
                "sweeps": {
                    "strategy": ("bfemp",),
                    "dt": (4e-4, 2e-4, 1e-4),
                    "dx": (0.2, 0.1),
                    "ppc": (4, 9, 16),
                    "dhat": (2e-2, 1e-2, 5e-3),
                    "tol": (1e-4, 1e-5, 1e-6),
                },
            },
        },
    },
    "slope": {
        "module": "benchmarks.slope",
        "warmup": {"settle_s": 0.005, "release_s": 0.005, "fit_start_s": 0.0},
        "knobs": ("strategy", "dt", "dx", "ppc", "dhat", "eps_v", "tol"),
        "error": "|a_fit - a_analytic| / a_analytic of the box's acceleration down the slope "
        "(mu = 0.1, eq. 40)",
        "error_key": "accel_rel_error",
        "modes": {
            "quick": {
                "base": dict(
                    strategy="bfemp",
                    dt=1e-3,
                    dx=5e-3,
                    ppc=4,
                    dhat=1e-3,
                    eps_v=1e-5,
                    tol=1e-8,
                    mu=0.1,
                    settle_s=0.02,
                    release_s=0.06,
                    fit_start_s=0.02,
                ),
                "sweeps": {
                    "strategy": ("bfemp",),
                    "dt": (2e-3, 1e-3, 5e-4),
                    "dx": (1e-2, 5e-3),
                    "ppc": (4, 9),
                    "dhat": (2e-3, 1e-3, 5e-4),
                    "eps_v": (1e-4, 1e-5, 1e-6),
                    "tol": (1e-6, 1e-7, 1e-8),
                },
            },
            "full": {
                "base": dict(
                    strategy="bfemp",
                    dt=1e-3,
                    dx=5e-3,
                    ppc=4,
                    dhat=1e-3,
                    eps_v=1e-5,
                    tol=1e-8,
                    mu=0.1,
                    settle_s=2.0,
                    release_s=1.0,
                    fit_start_s=0.1,
                ),
                "sweeps": {
                    "strategy": ("bfemp",),
                    "dt": (2e-3, 1e-3, 5e-4),
                    "dx": (1e-2, 5e-3, 2.5e-3),
                    "ppc": (4, 9, 16),
                    "dhat": (2e-3, 1e-3, 5e-4),
                    "eps_v": (1e-4, 1e-5, 1e-6),
                    "tol": (1e-6, 1e-7, 1e-8),
                },
            },
        },
    },
    "hertz": {
        "module": "benchmarks.hertz",
        "warmup": {"t_end": 0.12},  # the plates start d-hat from the disk: contact at once
        "knobs": ("strategy", "dt", "dx", "spacing", "dhat", "eps_v", "tol"),
        "error": "|C_fit / C_hertz - 1| of the linear-elastic disk (F = C a^2, eq. 39)",
        "error_key": "rel_error",
        "modes": {
            "quick": {
                "base": dict(
                    strategy="bfemp",
                    dt=6e-2,
                    dx=0.05,
                    spacing=0.035,
                    dhat=1e-4,
                    eps_v=1e-3,
                    tol=1e-4,
                    material="linear",
                    mu=1.0,
                    t_end=0.6,
                    max_newton_iterations=500,
                    boundary_refine=4,
                    grid_offset_cells=0.25,
                ),
                "sweeps": {
                    "strategy": ("bfemp",),
                    "dt": (6e-2, 3e-2),
                    "dx": (0.05, 0.04),
                    "spacing": (0.035, 0.025),
                    "dhat": (2e-4, 1e-4, 5e-5),
                    "eps_v": (1e-2, 1e-3, 1e-4),
                    "tol": (1e-3, 1e-4, 1e-5),
                },
            },
            "full": {
                "base": dict(
                    strategy="bfemp",
                    dt=1e-2,
                    dx=0.025,
                    spacing=_HERTZ_PAPER_SPACING,
                    dhat=1e-4,
                    eps_v=1e-5,
                    tol=1e-6,
                    material="linear",
                    mu=1.0,
                    t_end=0.6,
                    max_newton_iterations=1000,
                    boundary_refine=4,
                    grid_offset_cells=0.25,
                ),
                "sweeps": {
                    "strategy": ("bfemp",),
                    "dt": (2e-2, 1e-2, 5e-3),
                    "dx": (0.04, 1.0 / 30.0, 0.025),
                    "spacing": (2.0 * _HERTZ_PAPER_SPACING, _HERTZ_PAPER_SPACING),
                    "dhat": (2e-4, 1e-4, 5e-5),
                    "eps_v": (1e-4, 1e-5, 1e-6),
                    "tol": (1e-5, 1e-6),
                },
            },
        },
    },
}
