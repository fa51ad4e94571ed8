"""The scenes of the trade study across strategies (``benchmarks.tradeoff``).

``SCENES[scene]``:

- ``error``: what the point's error is, in words (against an analytic value, or against the
  scene's reference run); ``error_key`` (the metric that is the error) or ``reference_keys``
  (metrics compared, relative, with the reference run's) with ``reference_strategy`` (whose run
  at the finest value of every swept knob at once is the reference);
- ``scene_knobs``: the scene's discretisation knobs beside dt (``dx``, ``ppc``, ``dhat``, ...),
  and per mode ``base`` (the scene's settings), ``sweeps`` (scene knob -> values) and
  optionally ``reference_at_base`` (knob -> why the reference run keeps that knob at the
  reference strategy's base instead of its finest value);
- ``strategies``: the registry names that apply, each with ``dt`` (per mode: a number in s, or
  ``"auto"``: the explicit stable step, whose CFL fractions are then the knobs), ``options``
  (its options' base values: fixed choices and the base of its swept fields), ``no_knobs``
  (scene knobs it does not have, with the reason), optionally ``spec`` (narrowing of
  a knob's sweep declaration, e.g. the largest stable dt) and ``note`` (how it runs the scene);
- ``not_applicable``: strategy -> why it does not run the scene.

A strategy's own knobs are not listed here: they are the options fields that declare ``sweep``
metadata (``benchmarks._tradeoff_knobs``). ``warmup`` shortens the quick base to a few steps
that meet every kernel (contact included), run once per strategy before the timed points to
fill numba's cache (results discarded).
"""

from __future__ import annotations

import math

from benchmarks.catalogue import RINGS_DISCRETISATION, SLOPE_PHYSICS, SLOPE_TIMES

#: scene knobs -> +1 when a larger value is finer (more accurate, costlier), -1 when smaller is
SCENE_FINER = {"dx": -1, "ppc": 1, "spacing": -1, "dhat": -1, "eps_v": -1}
_HERTZ_PAPER_SPACING = math.sqrt(math.pi / 42920)  # m: the paper's particle count in the disk
#: the slope's discretisation (the paper's) and friction of every point
_SLOPE_BASE = dict(
    dx=SLOPE_PHYSICS["dx_m"],
    ppc=4,
    dhat=SLOPE_PHYSICS["dhat_m"],
    eps_v=SLOPE_PHYSICS["eps_v_m_s"],
    mu=0.1,
)
_SOFT = "the softened slope of two_stage_slope (E = 1e5 Pa instead of 4e12, kappa 1e6 Pa)"
# the hertz and hertz_soft scenes share their discretisation (hertz_soft changes the material)
_HERTZ_QUICK_BASE = dict(dx=0.05, spacing=0.035, dhat=1e-4, eps_v=1e-3, material="linear") | dict(
    mu=1.0, t_end=0.6, boundary_refine=4, grid_offset_cells=0.25
)
_HERTZ_FULL = {
    "base": dict(dx=0.025, spacing=_HERTZ_PAPER_SPACING, dhat=1e-4, eps_v=1e-5)
    | dict(material="linear", mu=1.0, t_end=0.6, boundary_refine=4)
    | {"grid_offset_cells": 0.25},
    "sweeps": {"dx": (0.04, 1.0 / 30.0, 0.025)}
    | {"spacing": (2.0 * _HERTZ_PAPER_SPACING, _HERTZ_PAPER_SPACING)}
    | {"dhat": (2e-4, 1e-4, 5e-5), "eps_v": (1e-4, 1e-5, 1e-6)},
}
_HERTZ_BARRIER = {
    "dt": {"quick": 6e-2, "full": 1e-2},
    "options": {"tol": 1e-4, "max_newton_iterations": 500},
}
_HERTZ_SOFT = (
    "E = 1e5 Pa instead of 1e10, kappa scaled with E, the top plate as stiff as the disk and "
    "16 x denser, both plates meshed at dx / 2"
)
# the strip is scripted whole: no FEM cell takes part in the explicit stable step
_SINE_REFERENCE_TOL = (
    "the reference keeps barrier's base tol = 1e-4 m/s: in the quick sweep tol 1e-5 changed "
    "the error by 2e-6 (dt by 6e-4) at 2.3x the time, and at full resolution with tol 1e-5 "
    "the reference would not end within a point's 2 h"
)
_SINE_NO_FEM_BOUND = "the scripted strip sets no stable step: the box's E = 1e6 Pa does"

SCENES = {
    "rings": {
        "error": "max(|L - L_ref| / L_ref, |T - T_ref| / T_ref) of the energy loss L over the "
        "collision window (0.025 s to 0.293 s) and the contact duration T, against the reference "
        "run: barrier at the finest value of every swept knob at once (the same reference for "
        "every strategy, so an explicit strategy's error holds its difference from barrier)",
        "reference_keys": ("energy_loss_pct", "contact_duration_s"),
        "reference_strategy": "barrier",
        "warmup": {"t_end": 0.05},  # the rings touch at t = 0.025 s
        "scene_knobs": ("dx", "ppc", "dhat"),
        "modes": {
            "quick": {
                "base": dict(dx=0.5, ppc=4, dhat=1e-2, fem_h=0.5, t_end=0.3),
                "sweeps": {"dx": (0.5, 1.0 / 3.0), "ppc": (4, 9), "dhat": (2e-2, 1e-2)},
            },
            "full": {
                "base": dict(**RINGS_DISCRETISATION["full"], dhat=1e-2, t_end=0.3),
                "sweeps": {"dx": (0.2, 0.1), "ppc": (4, 9, 16), "dhat": (2e-2, 1e-2, 5e-3)},
            },
        },
        "strategies": {
            "barrier": {
                "dt": {"quick": 1e-2, "full": 2e-4},
                "transfer": "apic",
                "options": {"tol": 1e-6},
                "note": "rings.INTEGRATOR (Newmark, implicit contact)",
            },
            "two_stage": {
                "dt": {"quick": "auto", "full": "auto"},
                "transfer": "apic",
                "options": {"tol": 1e-6},
                "note": "symplectic Euler at the explicit stable step (two_stage_rings)",
            },
            "augury": {
                "dt": {"quick": "auto", "full": "auto"},
                "transfer": "apic",
                "options": {"mode": "separate", "penetration_check_every": 0},
                "no_knobs": {"dhat": "augury has no barrier"},
                "note": "frictionless 'separate' mode, MPM foreground particles (augury_scenes); "
                "tau = dt (None) is not swept at dt = 'auto'",
            },
            "lr": {
                "dt": {"quick": "auto", "full": "auto"},
                "transfer": "flip",
                "options": {"law": "frictionless"},
                "no_knobs": {"dhat": "lr has no barrier"},
                "note": "the FEM ring as a material, meshed at fem_h = dx / 2 (lr_scenes)",
            },
        },
        "not_applicable": {
            "single_field": "no contact algorithm: the FEM ring and the MPM ring never interact"
        },
    },
    "slope": {
        "error": "|a_fit - a_analytic| / a_analytic of the box's acceleration down the slope "
        "(mu = 0.1, eq. 40); barrier on the paper's box (E = 4e12 Pa), the explicit strategies "
        f"on {_SOFT} (the analytic acceleration does not depend on E)",
        "error_key": "accel_rel_error",
        "warmup": {"settle_s": 0.002, "release_s": 0.002, "fit_start_s": 0.0},
        "scene_knobs": ("dx", "ppc", "dhat", "eps_v"),
        "modes": {
            "quick": {
                "base": _SLOPE_BASE | SLOPE_TIMES["quick"],
                "sweeps": {"dx": (1e-2, 5e-3), "ppc": (4, 9), "dhat": (2e-3, 1e-3)}
                | {"eps_v": (1e-4, 1e-5)},
            },
            "full": {
                "base": _SLOPE_BASE | SLOPE_TIMES["partial"],
                "sweeps": {"dx": (1e-2, 5e-3, 2.5e-3), "ppc": (4, 9, 16)}
                | {"dhat": (2e-3, 1e-3, 5e-4), "eps_v": (1e-4, 1e-5, 1e-6)},
            },
        },
        "strategies": {
            "barrier": {
                "dt": {"quick": 1e-3, "full": 1e-3},
                "options": {"tol": 1e-8},
                "note": "backward Euler, velocity_update='forces' (slope)",
            },
            "two_stage": {
                "dt": {"quick": 5e-5, "full": 5e-5},
                # the explicit stable step of the settling scene is 6.0e-5 s (two_stage_slope)
                "spec": {"dt": {"max": 6e-5}},
                "options": {"tol": 1e-6},
                "note": f"symplectic Euler on {_SOFT}",
            },
            "augury": {
                "dt": {"quick": 5e-5, "full": 5e-5},
                "spec": {"dt": {"max": 6e-5}},
                "options": {"tau": 5e-5, "kinematic_foreground": True}
                | {"penetration_check_every": 0},
                "no_knobs": {"dhat": "augury has no barrier", "eps_v": "augury's Coulomb is exact"},
                "note": f"{_SOFT}, the fixed slope as kinematic foreground (augury_scenes)",
            },
            "lr": {
                "dt": {"quick": 5e-5, "full": 5e-5},
                "spec": {"dt": {"max": 6e-5}},
                "transfer": "flip",
                "options": {},
                "no_knobs": {"dhat": "lr has no barrier", "eps_v": "lr's Coulomb is exact"},
                "note": f"{_SOFT}, the slope meshed at dx / 2 and 1 cm thick (lr_scenes)",
            },
        },
        "not_applicable": {"single_field": "no contact algorithm: the box falls through the slope"},
    },
    "hertz": {
        "error": "|C_fit / C_hertz - 1| of the linear-elastic disk (F = C a^2, eq. 39)",
        "error_key": "rel_error",
        "warmup": {"t_end": 0.12},  # the plates start d-hat from the disk: contact at once
        "scene_knobs": ("dx", "spacing", "dhat", "eps_v"),
        "modes": {
            "quick": {
                "base": _HERTZ_QUICK_BASE,
                "sweeps": {"dx": (0.05, 0.04), "spacing": (0.035, 0.025)}
                | {"dhat": (2e-4, 1e-4, 5e-5), "eps_v": (1e-2, 1e-3, 1e-4)},
            },
            "full": _HERTZ_FULL,
        },
        "strategies": {"barrier": _HERTZ_BARRIER | {"note": "backward Euler (hertz)"}},
        "not_applicable": {
            s: "E = 1e10 Pa disk: the explicit stable step scales as E^-1/2, 1.7e-6 s from the "
            "5.4e-4 s measured at E = 1e5 Pa (3.5e5 steps to 0.6 s); the explicit strategies run "
            "the softened disk, scene hertz_soft, beside barrier there"
            for s in ("two_stage", "augury", "lr")
        }
        | {"single_field": "no contact algorithm"},
    },
    "hertz_soft": {
        "error": "|C_fit / C_hertz - 1| of the linear-elastic disk (F = C a^2, eq. 39) on the "
        f"softened disk of hertz.SOFT: {_HERTZ_SOFT}; C_hertz from that E",
        "error_key": "rel_error",
        "warmup": {"t_end": 0.12},
        "scene_knobs": ("dx", "spacing", "dhat", "eps_v"),
        "modes": {
            "quick": {
                "base": _HERTZ_QUICK_BASE,
                "sweeps": {"dx": (0.05, 0.04), "spacing": (0.035, 0.025)}
                | {"dhat": (2e-4, 1e-4), "eps_v": (1e-2, 1e-3)},
            },
            "full": _HERTZ_FULL,
        },
        "strategies": {
            "barrier": _HERTZ_BARRIER
            | {"note": "backward Euler on the softened disk (hertz.SOFT)"},
            "two_stage": {
                "dt": {"quick": "auto", "full": "auto"},
                "options": {"tol": 1e-4},
                "note": "symplectic Euler at the explicit stable step (5.4e-4 s at dx = 0.05 m)",
            },
        },
        "not_applicable": {
            "augury": "measured (quick base, kinematic_foreground, grid_dx = dx = 2 x the "
            "plates' edge, 1101 steps at 5.4e-4 s): the disk sinks into the fixed bottom plate, "
            "8.79 mm deep at t = 0.6 s (88 d-hat; 6.95 mm with the plate at the disk's density), "
            "and its stresses carry 16 N/m where two_stage's carry 1642 N/m: no Hertz contact",
            "lr": "measured (quick base, 1101 steps at 5.4e-4 s): lr holds the disk (1789 N/m at "
            "t = 0.6 s; two_stage 1630; with the plate at the disk's density the disk went "
            "through it, 63.6 mm deep) but pushes every particle within the grid's reach of the "
            "plate from the first contact on (80 particles, half-width 0.196 m at 26 N/m, "
            "0.222 m at 1789 N/m): the width is the grid's, not the elasticity's, and the fit "
            "range (2 dx to 0.15 R) holds 2 samples: no C_fit",
            "single_field": "no contact algorithm",
        },
    },
    "sine_boundary": {
        "error": "|F_c - F_c,ref| / F_c,ref of the largest compressive force of the FEM strip on "
        "the box, against the reference run: barrier at the finest value of every swept knob "
        "(full mode: but tol, kept at the base's 1e-4 m/s, see reference_at_base); "
        "every strategy on the same scene, the scripted strip 1e4 x denser than the box (it "
        "weighs only in lr's velocity mixing: _tradeoff_runs.SINE_STRIP_DENSITY_FACTOR)",
        "reference_keys": ("max_compressive_force",),
        "reference_strategy": "barrier",
        "warmup": {"t_stop": 0.3},  # the strip reaches the box at t = 0.1 s (scale 0.5)
        "scene_knobs": ("dx", "ppc"),
        "modes": {
            "quick": {
                "base": dict(scale=0.5, dx=0.05, ppc=4, strip_h=0.025, t_stop=None),
                "sweeps": {"dx": (0.05, 0.04), "ppc": (4, 9)},
            },
            "full": {
                "base": dict(scale=1.0, dx=0.02, ppc=9, strip_h=0.005, t_stop=None),
                "sweeps": {"dx": (0.04, 0.02), "ppc": (4, 9)},
                "reference_at_base": {"tol": _SINE_REFERENCE_TOL},
            },
        },
        "strategies": {
            "barrier": {
                "dt": {"quick": 5e-3, "full": 1e-3},
                "options": {"tol": 1e-4, "max_newton_iterations": 1000},
                "note": "backward Euler, the FEM strip (sine_boundary's 'bfemp' treatment)",
            },
            # the box's E sets the stable step (6e-4 s at dx = 0.05 m): no softened variant
            "two_stage": {
                "dt": {"quick": "auto", "full": "auto"},
                "options": {"tol": 1e-4, "max_newton_iterations": 1000},
                "no_knobs": {"cfl_safety_fem": _SINE_NO_FEM_BOUND},
                "note": "symplectic Euler at the explicit stable step (the box's), the same "
                "scene, barrier's Newton cap of 1000 (at the default 100 the full base stopped "
                "with MAX_ITERATIONS at t = 0.879 s)",
            },
            "lr": {
                "dt": {"quick": "auto", "full": "auto"},
                "options": {},
                "no_knobs": {"cfl_safety_fem": _SINE_NO_FEM_BOUND},
                "note": "the scripted strip as a material (strip_h = dx / 2), the same scene; "
                "lr has no barrier: at the quick base 2 particles ended inside the strip, 6.9 mm "
                "deep",
            },
        },
        "not_applicable": {
            "augury": "measured (quick base, the scripted strip as kinematic foreground, 1750 "
            "steps at 6e-4 s): the strip passes through the box, 160 particles end inside it, "
            "0.215 m deep (0.243 m with the strip 1e4 x denser, 0.241 m in mode 'separate'): "
            "no contact force to compare",
            "single_field": "no contact algorithm",
        },
    },
    "augury_blocks": {
        "error": "|L - L_ref| / L_ref of the energy loss L = 1 - E(t_end) / E0 of the rotated "
        "3D blocks (AUG Figs. 8-9), against the reference run: augury at the finest value of "
        "every swept knob (dx is the FEM mesh size h, the contact grid 2 h); the record of "
        "augury_blocks found this loss not to converge with h, so barrier's and two_stage's "
        "errors are their difference from augury's loss, not an accuracy",
        "reference_keys": ("energy_loss",),
        "reference_strategy": "augury",
        "warmup": {"t_end": 0.002},  # the blocks share contact nodes from t = 0
        "scene_knobs": ("dx",),
        "modes": {
            "quick": {"base": dict(dx=1.0, t_end=0.06), "sweeps": {"dx": (1.0, 0.5)}},
            "full": {"base": dict(dx=0.5, t_end=0.06), "sweeps": {"dx": (1.0, 0.5, 0.25)}},
        },
        "strategies": {
            "augury": {
                "dt": {"quick": 1e-4, "full": 5e-5},
                "options": {"tau": 1e-4, "mode": "separate", "mu": 0.0}
                | {"contact_transfer": "apic", "penetration_check_every": 10},
                "note": "AUG's setting: APIC contact operator, frictionless 'separate' mode",
            },
            "barrier": {
                "dt": {"quick": 1e-3, "full": 5e-4},
                "options": {"tol": 1e-4, "max_newton_iterations": 200},
                "note": "Newmark with implicit contact, frictionless barrier (dhat 1e-2 m, "
                "kappa 1e5 Pa; _tradeoff_runs.BLOCKS_*)",
            },
            "two_stage": {
                "dt": {"quick": "auto", "full": "auto"},
                "options": {"tol": 1e-4},
                "note": "symplectic Euler at the stable step, FEM-FEM barrier pairs (as barrier)",
            },
        },
        "not_applicable": {
            "lr": "lr is multimaterial MPM: the blocks are FEM meshes sampled by no particles",
            "single_field": "no contact algorithm",
        },
    },
    "lr_compression": {
        "error": "max |sigma_MM - sigma_SMM| / |sigma_SMM| (%) of the mean sigma_yy over the "
        "strains above 1 %, against the single-material run of the same particles with the same "
        "transfer and options (LR Fig. 5); cost: the two-block run alone, without its "
        "single-material twin",
        "error_key": "max_abs_error_percent",
        "warmup": {"strain": 0.012},  # just past the 1 % below which no error is taken
        "scene_knobs": (),
        "modes": {
            "quick": {"base": dict(v0_over_cK=0.005, strain=0.10), "sweeps": {}},
            "full": {"base": dict(v0_over_cK=0.0005, strain=0.15), "sweeps": {}},
        },
        "strategies": {
            "lr": {
                "dt": {"quick": "auto", "full": "auto"},
                "transfer": "flip",
                "options": {},
                "no_knobs": {"cfl_safety_fem": "no FEM body: the FEM bound does not exist"},
                "note": "FLIP, dt = 'auto' (lr_compression); dx and ppc are the paper's, fixed",
            }
        },
        "not_applicable": {
            "barrier": "MPM-MPM contact: barrier couples MPM to FEM only",
            "two_stage": "MPM-MPM contact: two_stage couples MPM to FEM only",
            "augury": "MPM-MPM contact of two blocks: augury's contact is FEM-MPM",
            "single_field": "single_field on the two blocks is the single-material reference",
        },
    },
}
