"""What every stepper returns, and the error it raises when a step cannot be taken."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["StepReport", "StepError"]


@dataclass(frozen=True, kw_only=True)
class StepReport:
    """Outcome of one time step.

    Attributes:
        step: index of the completed step (1 for the first).
        t: time at the end of the step in s.
        success: whether the step converged.
        status: solver status name (``"CONVERGED"``, ``"LINE_SEARCH_STALLED"``, ...).
        message: human-readable outcome.
        newton_iterations: Newton iterations of the step.
        residual: ``||p||_inf / dt`` of the last Newton increment in m/s.
        timings: seconds per phase (``"assemble"``, ``"factorize"``, ``"line_search"``, ...),
            summed over every minimisation of the step (the friction loop's, and the sub-steps'
            when scripted nodes move); ``"total"`` is the time inside those minimisations,
            ``"step"`` the whole step.
        min_distance: smallest active contact distance at the end of the step in m (NaN when no
            pair is within d-hat or the scene has no contact).
        contact_pairs: number of active contact pairs at the end of the step.
        friction_iterations: lagged-friction updates of the step (0 without friction); when
            the step is solved in sub-steps (scripted nodes moving), the most that any one
            sub-step's friction loop took, so it never exceeds the cap
            (``ContactParameters.friction_iterations``).
        friction_converged: whether the friction loop met the tolerance within its cap.
        boundary_forces: per level-set boundary, the reaction force (d,) in N its slip nodes
            exert on the body (empty without slip constraints).
    """

    step: int
    t: float
    success: bool
    status: str
    message: str
    newton_iterations: int
    residual: float
    timings: dict[str, float] = field(default_factory=dict)
    min_distance: float = float("nan")
    contact_pairs: int = 0
    friction_iterations: int = 0
    friction_converged: bool = True
    boundary_forces: tuple = ()


class StepError(RuntimeError):
    """A step failed; ``report`` says why (the state is left at the start of the step)."""

    def __init__(self, report: StepReport) -> None:
        super().__init__(
            f"step {report.step} (t = {report.t:.6g} s) failed: {report.status}: {report.message}"
        )
        self.report = report
