"""The time loop users drive: ``Simulation(scene, ...)``, ``step()``, ``run()``.

``run`` shows a tqdm progress bar (simulated time, Newton iterations, residual, time per step),
records one metrics row per step (energies, momenta, Newton iterations, per-phase timings), and
when given an output folder writes VTK frames of every body with a PVD time series for ParaView,
``metrics.csv`` and ``metrics.png``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from bfemp import diagnostics
from bfemp.integrators import integrator_from_name
from bfemp.io.metrics import MetricsLog
from bfemp.io.vtk import Block, FrameWriter
from bfemp.model import Model
from bfemp.plotting import plot_metrics
from bfemp.scene import Scene
from bfemp.state import State
from bfemp.steppers import StepReport, stepper_class
from solvers.linear import LinearSolver
from solvers.options import NewtonOptions

__all__ = ["Simulation"]

log = logging.getLogger(__name__)

_TRANSFERS = ("apic", "pic", "flip")


class Simulation:
    """A scene advanced in time by one coupling strategy.

    Args:
        scene: a ``Scene`` (built here) or a ``Model``.
        strategy: coupling strategy name (``"barrier"``: BFEMP implicit).
        integrator: ``"backward_euler"`` or ``"newmark"``.
        transfer: particle-grid transfer for MPM bodies (``"apic"``, ``"pic"``, ``"flip"``).
        dt: time step in s.
        tol: Newton tolerance on ``||p||_inf / dt`` in m/s (section 5).
        max_newton_iterations: Newton iteration cap per step.
        linear_solver: override the linear solver (default CHOLMOD, scipy fallback).
    """

    def __init__(
        self,
        scene: Scene | Model,
        *,
        strategy: str = "barrier",
        integrator: str = "backward_euler",
        transfer: str = "apic",
        dt: float,
        tol: float = 1e-6,
        max_newton_iterations: int = 200,
        linear_solver: LinearSolver | None = None,
    ) -> None:
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"Simulation.dt must be a positive number of seconds, got {dt!r}")
        if transfer not in _TRANSFERS:
            raise ValueError(f"Simulation.transfer must be one of {_TRANSFERS}, got {transfer!r}")
        self.model = scene.build() if isinstance(scene, Scene) else scene
        self.dt = float(dt)
        self.strategy = strategy
        self.transfer = transfer
        self.integrator = integrator_from_name(integrator)
        newton = NewtonOptions(tol=tol, max_iter=max_newton_iterations)
        self.stepper = stepper_class(strategy)(
            self.model,
            integrator=self.integrator,
            dt=self.dt,
            newton=newton,
            linear_solver=linear_solver,
            transfer=transfer,
        )
        self.state: State = self.stepper.initialize(self.model.initial_state())
        self.metrics = MetricsLog()
        self.metrics.append(self._metrics_row(None))

    @property
    def terms(self) -> list[str]:
        """Names of the energy terms this scene pays for."""
        return self.stepper.terms

    # ------------------------------------------------------------------ stepping
    def step(self) -> StepReport:
        """Advance one time step; returns its report (raises ``StepError`` on failure)."""
        self.state, report = self.stepper.step(self.state)
        self.metrics.append(self._metrics_row(report))
        return report

    def run(
        self,
        t_end: float,
        *,
        out: str | Path | None = None,
        every: int = 1,
        progress: bool = True,
        callback: Callable[[Simulation], None] | None = None,
    ) -> MetricsLog:
        """Step until ``t_end`` s; with ``out``, write a frame every ``every`` steps.

        ``callback(sim)`` is called after every step (to record custom quantities).

        Returns the metrics log (also written to ``out/metrics.csv`` and plotted to
        ``out/metrics.png``).
        """
        if every < 1:
            raise ValueError(f"Simulation.run: every must be >= 1, got {every}")
        n_steps = max(0, math.ceil((t_end - self.state.t) / self.dt - 1e-9))
        writer = FrameWriter(Path(out)) if out is not None else None
        if writer is not None and self.state.step % every == 0:
            writer.write_frame(self.state.t, self.frame_blocks())
        bar = tqdm(total=n_steps, disable=not progress, unit="step", desc="bfemp")
        try:
            for _ in range(n_steps):
                report = self.step()
                if callback is not None:
                    callback(self)
                bar.update(1)
                bar.set_postfix(
                    t=f"{self.state.t:.4g}",
                    newton=report.newton_iterations,
                    res=f"{report.residual:.1e}",
                    ms=f"{1e3 * report.timings.get('step', 0.0):.0f}",
                )
                if writer is not None and self.state.step % every == 0:
                    writer.write_frame(self.state.t, self.frame_blocks())
        finally:
            bar.close()
            if writer is not None:
                writer.close()
                self.metrics.to_csv(Path(out) / "metrics.csv")
                plot_metrics(self.metrics, Path(out) / "metrics.png", title="bfemp run")
                log.info("wrote frames, metrics.csv and metrics.png to %s", out)
        return self.metrics

    # ------------------------------------------------------------------ output
    def energies(self, state: State | None = None) -> dict[str, float]:
        """Kinetic, elastic, gravitational and total energy in J (J/m in 2D)."""
        state = self.state if state is None else state
        elastic = sum(
            term.energy_at(state.fem_x)
            for term in self.stepper.potential.potentials
            if hasattr(term, "energy_at") and not hasattr(term, "particles")
        )
        if self.model.n_particles:
            elastic += diagnostics.mpm_elastic_energy(self.model, state)
        out = {
            "energy_kinetic": diagnostics.kinetic_energy(self.model, state, self.transfer),
            "energy_elastic": float(elastic),
            "energy_gravity": diagnostics.gravity_energy(self.model, state),
        }
        if self.model.has_load:
            out["energy_load"] = diagnostics.load_energy(self.model, state)
        out["energy_total"] = sum(out.values())
        return out

    def _metrics_row(self, report: StepReport | None) -> dict[str, float]:
        row: dict[str, float] = {"t": self.state.t, "step": self.state.step}
        row.update(self.energies())
        axes = "xyz"
        for k, p in enumerate(diagnostics.linear_momentum(self.model, self.state)):
            row[f"momentum_{axes[k]}"] = float(p)
        angular = diagnostics.angular_momentum(self.model, self.state, self.transfer)
        for k, value in enumerate(angular):
            row[f"angular_momentum_{'z' if angular.size == 1 else axes[k]}"] = float(value)
        if report is not None:
            row["newton_iterations"] = report.newton_iterations
            row["residual"] = report.residual
            if self.stepper.barrier is not None:
                row["min_distance"] = report.min_distance
                row["contact_pairs"] = report.contact_pairs
                row["kappa"] = self.stepper.barrier.kappa
            for phase, seconds in report.timings.items():
                row[f"time_{phase}"] = seconds
        return row

    def frame_blocks(self) -> list[Block]:
        """One VTK block per FEM body with velocity, J and von Mises stress."""
        blocks = []
        model, state = self.model, self.state
        j_cells, von_mises = _cell_stress_fields(model, state)
        for body in model.fem_bodies:
            cells = model.fem_cells[body.cells] - body.nodes.start
            blocks.append(
                Block(
                    name=body.name,
                    points=state.fem_x[body.nodes],
                    cells=cells,
                    point_data={"velocity": state.fem_v[body.nodes]},
                    cell_data={"J": j_cells[body.cells], "von_mises": von_mises[body.cells]},
                )
            )
        for body in model.mpm_bodies:
            sl = body.particles
            blocks.append(
                Block(
                    name=body.name,
                    points=state.mpm_x[sl],
                    cells=None,
                    point_data={
                        "velocity": state.mpm_v[sl],
                        "J": np.linalg.det(state.mpm_F[sl]),
                        "von_mises": _von_mises(body.material, state.mpm_F[sl]),
                        "volume": model.mpm_volume[sl],
                    },
                )
            )
        return blocks

    def wall_clock(self) -> float:
        """Seconds spent in steps so far (sum of the per-step timings)."""
        col = "time_step"
        return float(np.nansum(self.metrics.column(col))) if col in self.metrics.columns else 0.0


def _von_mises(material: object, F: np.ndarray) -> np.ndarray:
    """Von Mises Cauchy stress ``(n,)`` in Pa of deformation gradients ``(n, d, d)``.

    In 2D (plane strain) the in-plane sqrt(sxx^2 - sxx syy + syy^2 + 3 sxy^2) is reported.
    """
    n = F.shape[0]
    J = np.linalg.det(F)
    with np.errstate(all="ignore"):
        P = material.law.first_piola(F, np.full(n, material.mu), np.full(n, material.lam))
        sigma = P @ np.swapaxes(F, 1, 2) / J[:, None, None]
    if F.shape[1] == 2:
        sxx, syy, sxy = sigma[:, 0, 0], sigma[:, 1, 1], sigma[:, 0, 1]
        return np.sqrt(np.maximum(sxx**2 - sxx * syy + syy**2 + 3 * sxy**2, 0.0))
    dev = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
    return np.sqrt(1.5 * np.einsum("mij,mij->m", dev, dev))


def _cell_stress_fields(model: Model, state: State) -> tuple[np.ndarray, np.ndarray]:
    """Per-cell J ``(M,)`` and von Mises Cauchy stress ``(M,)`` in Pa."""
    x = state.fem_x[model.fem_cells]  # (M, d+1, d)
    F = np.einsum("mai,maj->mij", x, model.fem_cell_grad)
    vm = np.zeros(F.shape[0])
    for body in model.fem_bodies:  # a few bodies; vectorised over cells
        vm[body.cells] = _von_mises(body.material, F[body.cells])
    return np.linalg.det(F), vm
