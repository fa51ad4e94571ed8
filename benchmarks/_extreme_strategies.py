"""How each case of ``extremes`` maps to each coupling strategy, and what each strategy promises.

Every strategy of ``bfemp.steppers.STRATEGIES`` runs the same scenes (``_extreme_cases``).
**barrier** (BFEMP, implicit) takes every knob as the case states it (backward Euler or Newmark,
APIC, the case's Newton settings) and promises no crossing and J > 0. The others are explicit
(symplectic Euler, no det F > 0 guard: an inversion is a named ``INVERTED``); a case outside a
strategy's knobs is ``NOT_APPLICABLE`` (``not_applicable``), its options come from
``strategy_options``:

- **two_stage** (explicit elasticity, the barrier's CCD-filtered contact solve at the
  particles): d-hat, kappa and friction through ``scene.set_contact``, the Newton settings through
  ``TwoStageOptions``; promises no crossing (``NO_CROSSING``); refuses ``kappa = "auto"``.
- **augury** and **lr**: no barrier; friction from ``scene.set_contact(mu=...)``; no promise
  about crossing (``crossing_reason``): particles inside the FEM body are a named
  ``PENETRATION``. augury takes the fixed slab of the resting case as kinematic foreground.
- **single_field** (no contact algorithm): the block passes through the slab, ``PENETRATION``.

A case's dt above an explicit strategy's stable step is refused with the bound named (the
case's outcome); beside it an extra run at ``dt = "auto"`` is recorded (``row["auto"]``), except
for the dt cases (it would repeat the base case's). A run whose stable step needs more than
``MAX_STEPS[mode]`` steps is not started: ``TOO_MANY_STEPS``. The resting case runs
``EXPLICIT_DURATION`` under the explicit strategies (at their stable step 0.5 s is 10^4 steps;
the block lands after about 22 ms, the drift is measured over the second half); a block that
then moves by more than the barrier's tolerance is a named ``DRIFT`` (``drift_reason``).
"""

from __future__ import annotations

from benchmarks._extreme_cases import Case, CaseConfig
from bfemp.steppers import STRATEGIES, AuguryOptions, TwoStageOptions

#: every strategy, barrier first (the column order of the table)
STRATEGY_NAMES: tuple[str, ...] = ("barrier",) + tuple(s for s in STRATEGIES if s != "barrier")
#: strategies with an explicit stable step (symplectic Euler)
EXPLICIT = frozenset(s for s in STRATEGY_NAMES if s != "barrier")
#: strategies that promise that no particle ends inside a FEM body (a penetration is a bug)
NO_CROSSING = frozenset({"barrier", "two_stage"})
#: why a particle inside a FEM body is no bug for the others
_CROSSING_REASON = {
    "augury": "augury contact on the background grid does not prevent crossing (AUG pitfall A9)",
    "lr": "LR contact acts at grid nodes and does not prevent crossing",
    "single_field": "single_field's FEM bodies meet nothing but level sets",
}
#: most steps a run may take per mode (more: TOO_MANY_STEPS, decided before running)
MAX_STEPS = {"quick": 2500, "full": 25000}
#: simulated time of cases under the explicit strategies, per mode, where it differs from the
#: case's (s)
EXPLICIT_DURATION = {"resting": {"quick": 0.06, "full": 0.2}}
#: why the resting block of an explicit strategy may move by more than the barrier's tolerance
#: (measured on the quick run; named outcome ``DRIFT``)
_DRIFT_REASON = {
    "two_stage": (
        "symplectic Euler keeps the landing's energy, so the block bounces on the barrier "
        "(measured: lands at 0.19 m/s, leaves at 0.11 m/s); backward Euler's numerical damping "
        "is what settles the barrier's block"
    ),
    "augury": (
        "augury corrects velocities on the contact grid and holds no gap: the block creeps down "
        "at a steady speed (measured: 0.02 m/s)"
    ),
    "lr": "LR corrects grid velocities and holds no gap",
    "single_field": "single_field's FEM bodies meet nothing: the block falls",
}

_BARRIER_GROUPS = {
    "dhat": "{s} has no barrier: d-hat is not one of its knobs",
    "kappa": "{s} has no barrier: kappa is not one of its knobs",
}


def drift_reason(strategy: str) -> str | None:
    """Why the resting block may drift under ``strategy``; None: a drift is a bug."""
    return _DRIFT_REASON.get(strategy)


def crossing_reason(strategy: str) -> str | None:
    """Why ``strategy`` may let particles into a FEM body; None if it promises it does not."""
    return None if strategy in NO_CROSSING else _CROSSING_REASON[strategy]


def not_applicable(case: Case, strategy: str) -> str | None:
    """Why ``case`` does not apply to ``strategy`` (None: it does)."""
    if strategy not in STRATEGY_NAMES:
        raise ValueError(f"strategy must be one of {STRATEGY_NAMES}, got {strategy!r}")
    cfg = case.config
    if strategy == "barrier":
        return None
    if cfg.integrator != "backward_euler":
        return f"{strategy} is explicit (symplectic Euler); {cfg.integrator} is barrier's"
    if strategy in ("augury", "lr", "single_field") and case.group in _BARRIER_GROUPS:
        return _BARRIER_GROUPS[case.group].format(s=strategy)
    if strategy == "single_field" and cfg.mu > 0.0:
        return "single_field has no contact, hence no friction"
    return None


def strategy_options(config: CaseConfig, strategy: str):
    """The ``options`` for ``Simulation`` (None: the strategy's defaults)."""
    if strategy == "two_stage":
        return TwoStageOptions(tol=config.tol, max_newton_iterations=config.max_newton_iterations)
    if strategy == "augury" and config.geometry == "resting":
        # the slab is fixed (scripted): it must be kinematic foreground (augury's default since
        # issue 40), else the block falls through it
        return AuguryOptions(kinematic_foreground=True)
    return None


def duration(case: Case, mode: str, strategy: str) -> float | None:
    """Simulated time of ``case`` under ``strategy`` in s when it differs from the case's."""
    if strategy in EXPLICIT and case.name in EXPLICIT_DURATION:
        return EXPLICIT_DURATION[case.name][mode]
    return None
