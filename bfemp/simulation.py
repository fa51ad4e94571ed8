"""The time loop users drive: ``Simulation(scene, ...)``, ``step()``, ``run()``.

``run`` shows a tqdm progress bar (simulated time, Newton iterations, residual, time per step),
records one metrics row per step (energies, momenta, Newton iterations, per-phase timings), and
when given an output folder writes VTK frames of every body with a PVD time series for ParaView,
``metrics.csv``, ``metrics.png``, a run manifest (:mod:`bfemp.manifest`) and checkpoints from which
``run(..., resume=True)`` continues bit for bit (:mod:`bfemp.checkpoint`; Ctrl-C writes one), the
snapshot sheet and animation (:mod:`bfemp.io.snapshots`) and ``scene.toml``; what a run folder
holds and the final writes are :mod:`bfemp.io.outputs`.
"""

from __future__ import annotations

import logging
import math
import numbers
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from bfemp import diagnostics
from bfemp.checkpoint import InterruptGuard, restore_checkpoint, write_checkpoint
from bfemp.integrators import integrator_from_name
from bfemp.io import outputs
from bfemp.io.metrics import MetricsLog
from bfemp.io.snapshots import check_animation_format, write_animation, write_snapshot_sheet
from bfemp.io.vtk import Block, FrameWriter
from bfemp.manifest import RunManifest
from bfemp.model import Model
from bfemp.plotting import plot_metrics
from bfemp.scene import Scene
from bfemp.state import State
from bfemp.steppers import StepReport, stepper_class
from bfemp.validation import validate_initial
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
        integrator: ``"backward_euler"``, ``"newmark"``, ``"newmark_damped"`` or
            ``"newmark_implicit_contact"`` (mid-point Newmark with memory-free contact forces:
            no energy gain at stiff impacts; see :mod:`bfemp.integrators`), or an
            ``Integrator``.
        transfer: particle-grid transfer for MPM bodies (``"apic"``, ``"pic"``, ``"flip"``).
        dt: time step in s.
        tol: Newton tolerance on ``||p||_inf / dt`` in m/s (section 5).
        max_newton_iterations: Newton iteration cap per step.
        linear_solver: override the linear solver (default CHOLMOD, scipy fallback).
        warm_start: start each step's Newton solve from the predicted x^{n+1} where no contact
            is active (see ``ImplicitStepper``); off by default: it saved no Newton iterations
            on the rings and cantilever demos (measured, see the tradeoff record).
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
        warm_start: bool = False,
    ) -> None:
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"Simulation.dt must be a positive number of seconds, got {dt!r}")
        if transfer not in _TRANSFERS:
            raise ValueError(f"Simulation.transfer must be one of {_TRANSFERS}, got {transfer!r}")
        self.model = scene.build() if isinstance(scene, Scene) else scene
        #: the scene this simulation was built from (written to ``out/scene.toml`` by runs)
        self.scene = scene if isinstance(scene, Scene) else None
        if self.model.contact is not None:
            # the barrier is finite only for bodies that start apart (and beyond d-hat)
            validate_initial(self.model)
        self.dt = float(dt)
        self.strategy = strategy
        self.transfer = transfer
        self.integrator = integrator_from_name(integrator)
        #: the settings of this simulation (recorded in manifests and checkpoints)
        self.settings = {
            "strategy": strategy,
            "integrator": self.integrator.name,
            "transfer": transfer,
            "dt": self.dt,
            "tol": float(tol),
            "max_newton_iterations": int(max_newton_iterations),
            "warm_start": bool(warm_start),
        }
        newton = NewtonOptions(tol=tol, max_iter=max_newton_iterations)
        self.stepper = stepper_class(strategy)(
            self.model,
            integrator=self.integrator,
            dt=self.dt,
            newton=newton,
            linear_solver=linear_solver,
            transfer=transfer,
            warm_start=warm_start,
        )
        self.state: State = self.stepper.initialize(self.model.initial_state())
        self.metrics = MetricsLog()
        #: named warnings raised during the run (e.g. "ENERGY_GROWTH: ..."), also logged
        self.diagnostics: list[str] = []
        self._closed = _is_closed(self.model)
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
        checkpoint_every: int | None = None,
        resume: bool = False,
        metadata: dict | None = None,
        overwrite: bool = False,
        animation: str | None = None,
        scene_toml: str | None = None,
    ) -> MetricsLog:
        """Step until ``t_end`` s; with ``out``, write a frame every ``every`` steps.

        ``callback(sim)`` is called after every step (to record custom quantities).

        With an output folder ``out`` the run also writes ``metrics.csv``, ``metrics.png``, a
        run manifest (``manifest.json``, see :mod:`bfemp.manifest`) and checkpoints
        (:mod:`bfemp.checkpoint`): at the end, every ``checkpoint_every`` steps if given, when a
        step fails (the last good state), and on Ctrl-C: the first Ctrl-C finishes the current
        step, writes a checkpoint and raises ``KeyboardInterrupt``; a second one aborts at once
        (the last periodic checkpoint remains). ``resume=True`` continues the run of ``out``
        from its checkpoint; the continued run equals an uninterrupted one bit for bit (frames,
        PVD files and metrics; wall-clock ``time_*`` columns excepted).

        A fresh run refuses a folder that holds an earlier run's outputs unless ``overwrite``
        (then deletes them first: :mod:`bfemp.io.outputs`). Every run with ``out`` writes
        ``snapshots.png`` (the bodies at up to 6 frame times, coloured by von Mises stress) and
        ``scene.toml``; ``animation="gif"`` (or ``"mp4"``, with ffmpeg) also writes
        ``animation.gif`` of every frame (:mod:`bfemp.io.snapshots`).

        Args:
            t_end: end time in s.
            out: output folder, or None for no output.
            every: frame interval in steps (>= 1).
            progress: show a tqdm progress bar.
            callback: called as ``callback(sim)`` after every step.
            checkpoint_every: checkpoint interval in steps (None or 0: only at the end).
            resume: continue from the checkpoint in ``out``.
            metadata: extra parameters recorded in the manifest (e.g. the scene file).
            overwrite: replace the outputs of an earlier run in ``out`` (else refused).
            animation: ``"gif"`` or ``"mp4"``: also write ``out/animation.FMT``.
            scene_toml: text of ``out/scene.toml`` (default: the scene of this simulation with
                its settings; nothing for a simulation built from a ``Model``).

        Returns the metrics log (also written to ``out/metrics.csv`` and plotted to
        ``out/metrics.png``).
        """
        _check_run_args(t_end, every, checkpoint_every, resume, out)
        if animation is not None:
            check_animation_format(animation)
        if out is None:
            self._loop(self._n_steps(t_end), progress, callback)
            return self.metrics
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        if resume:
            restore_checkpoint(out, self, every=every)
        else:
            outputs.prepare_run_folder(out, overwrite=overwrite)
            outputs.write_scene_file(out, self, scene_toml)
        every, checkpoint_every = int(every), int(checkpoint_every or 0)
        run = {"t_end": float(t_end), "every": every, "checkpoint_every": checkpoint_every}
        writer = FrameWriter(out, resume=resume)
        manifest = RunManifest.start(out, self, run=run, resume=resume, extra=metadata)
        if not resume and self.state.step % every == 0:
            writer.write_frame(self.state.t, self.frame_blocks())
        status, message, guard = "failed", "", InterruptGuard()
        try:
            with guard:
                self._loop(
                    self._n_steps(t_end),
                    progress,
                    callback,
                    writer=writer,
                    every=every,
                    checkpoint_every=checkpoint_every,
                    guard=guard,
                )
            status = "completed"
        except KeyboardInterrupt:
            status = "interrupted"
            message = f"interrupted at step {self.state.step} (t = {self.state.t:.6g} s)"
            raise
        except Exception as err:
            message = f"{type(err).__name__}: {err}"
            raise
        finally:
            writer.close()
            if guard.hard:  # stopped anywhere, maybe mid-update: keep the last checkpoint
                message += "; aborted without a checkpoint (the last periodic one remains)"
            plots = [
                (
                    "metrics.png",
                    lambda: plot_metrics(self.metrics, out / "metrics.png", title="bfemp run"),
                ),
                ("snapshots.png", lambda: write_snapshot_sheet(out)),
            ]
            if animation is not None:
                plots.append((f"animation.{animation}", lambda: write_animation(out, animation)))
            outputs.finish_outputs(
                out, self, manifest, status, message, hard=guard.hard, every=every,
                frames=writer.frame_index, writes=plots,
            )  # fmt: skip
        return self.metrics

    def _n_steps(self, t_end: float) -> int:
        return max(0, math.ceil((t_end - self.state.t) / self.dt - 1e-9))

    def _loop(
        self,
        n_steps: int,
        progress: bool,
        callback: Callable[[Simulation], None] | None,
        *,
        writer: FrameWriter | None = None,
        every: int = 1,
        checkpoint_every: int = 0,
        guard: InterruptGuard | None = None,
    ) -> None:
        """The time loop: step, callback, progress, frames, checkpoints, interrupt check."""
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
                step = self.state.step
                if writer is not None and step % every == 0:
                    writer.write_frame(self.state.t, self.frame_blocks())
                if writer is not None and checkpoint_every and step % checkpoint_every == 0:
                    write_checkpoint(writer.out_dir, self, every=every)
                if guard is not None and guard.requested:
                    raise KeyboardInterrupt(f"interrupted after step {step}")
        finally:
            bar.close()

    # ------------------------------------------------------------------ checkpoints
    def save_checkpoint(self, out: str | Path, *, every: int | None = None) -> Path:
        """Write a checkpoint of the current state and metrics to the folder ``out``."""
        return write_checkpoint(out, self, every=every)

    def load_checkpoint(self, out: str | Path) -> None:
        """Continue from the checkpoint in the folder ``out`` (same model required)."""
        restore_checkpoint(out, self)

    # ------------------------------------------------------------------ output
    def energies(self, state: State | None = None) -> dict[str, float]:
        """Kinetic, elastic, gravitational (load, contact) and total energy in J (J/m in 2D).

        The contact (barrier) energy B is that of the current state's active pairs; it is the
        elastic energy stored by the barrier while bodies touch, so the total of a scene on which
        nothing external works is what a conservative integrator keeps.
        """
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
        barrier = self.stepper.barrier
        if barrier is not None:
            current = state is self.state and barrier.pairs is not None
            out["energy_contact"] = barrier.value(None) if current else 0.0
        out["energy_total"] = sum(out.values())
        return out

    def _metrics_row(self, report: StepReport | None) -> dict[str, float]:
        row: dict[str, float] = {"t": self.state.t, "step": self.state.step}
        row.update(self.energies())
        if report is not None and self._closed:
            self._check_energy(row["energy_total"])
        axes = "xyz"
        for k, p in enumerate(diagnostics.linear_momentum(self.model, self.state)):
            row[f"momentum_{axes[k]}"] = float(p)
        angular = diagnostics.angular_momentum(self.model, self.state, self.transfer)
        for k, value in enumerate(angular):
            row[f"angular_momentum_{'z' if angular.size == 1 else axes[k]}"] = float(value)
        barrier = self.stepper.barrier if report is not None else None
        row.update(diagnostics.body_metrics(self.model, self.state, self.transfer, barrier))
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

    def contact_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Barrier contact forces at the end of the last step, in N (N/m in 2D).

        Returns ``(fem (N, d), mpm (P, d))``: the force on every FEM node (zero off the
        boundary) and on every particle; both zero before the first step or without contact.
        """
        model = self.model
        fem = np.zeros((model.n_fem_nodes, model.dim))
        mpm = np.zeros((model.n_particles, model.dim))
        barrier = self.stepper.barrier
        if barrier is None or barrier.pairs is None:
            return fem, mpm
        forces = barrier.point_forces()
        cs = barrier.collisions
        nf = cs.n_fem_points
        np.add.at(fem, cs.nodes[:nf, 0], forces[:nf])
        mpm[cs.particle_index[nf:]] = forces[nf:]
        return fem, mpm

    #: relative growth of the total energy of a closed scene that triggers ENERGY_GROWTH
    ENERGY_GROWTH_TOL = 1e-2

    def _check_energy(self, total: float) -> None:
        """Warn once when a scene on which nothing external works gains energy.

        Backward Euler only dissipates; Newmark's trapezoidal rule conserves energy for linear
        problems but can gain it when a stiff barrier switches on and off within steps (known for
        the trapezoidal rule with contact; measured +62 % for a 40 m/s impact at dt = 1e-4 s and
        h = 0.05 m, none at h = 0.025 m). The remedies are ``"newmark_implicit_contact"``
        (contact forces without the trapezoidal rule's memory), a smaller dt (resolving the
        approach through dhat in a few steps), ``"newmark_damped"`` or backward Euler.
        """
        first = self.metrics.column("energy_total")[0] if len(self.metrics) else total
        scale = max(abs(first), 1e-300)
        growth = (total - first) / scale
        if growth > self.ENERGY_GROWTH_TOL and not any(
            d.startswith("ENERGY_GROWTH") for d in self.diagnostics
        ):
            message = (
                f"ENERGY_GROWTH: the total energy grew by {100 * growth:.1f} % since t = 0 at "
                f"t = {self.state.t:.6g} s although nothing external works on the scene "
                f"({self.integrator.name}); with contact, Newmark can gain energy: use "
                "integrator='newmark_implicit_contact', a smaller dt or "
                "integrator='backward_euler'"
            )
            self.diagnostics.append(message)
            log.warning(message)

    def frame_blocks(self) -> list[Block]:
        """One VTK block per FEM body with velocity, J and von Mises stress."""
        blocks = []
        model, state = self.model, self.state
        j_cells, von_mises = _cell_stress_fields(model, state)
        fem_force, mpm_force = self.contact_forces()
        for body in model.fem_bodies:
            cells = model.fem_cells[body.cells] - body.nodes.start
            blocks.append(
                Block(
                    name=body.name,
                    points=state.fem_x[body.nodes],
                    cells=cells,
                    point_data={
                        "velocity": state.fem_v[body.nodes],
                        "contact_force": fem_force[body.nodes],
                    },
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
                        "contact_force": mpm_force[sl],
                    },
                )
            )
        return blocks

    def wall_clock(self) -> float:
        """Seconds spent in steps so far (sum of the per-step timings)."""
        col = "time_step"
        return float(np.nansum(self.metrics.column(col))) if col in self.metrics.columns else 0.0


def _is_closed(model: Model) -> bool:
    """Nothing external works on the scene: no moving scripted nodes, loads or moving boundaries."""
    from bfemp.motion import Fixed

    moving = any(
        b.prescribed_motion is not None and not isinstance(b.prescribed_motion, Fixed)
        for b in model.fem_bodies
    )
    moving_boundary = any(b.motion is not None for b in model.boundaries)
    return not (moving or moving_boundary or model.has_load)


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


def _check_run_args(
    t_end: object, every: object, checkpoint_every: object, resume: bool, out: object
) -> None:
    """Validate the arguments of ``Simulation.run`` (errors name the argument)."""
    if isinstance(every, bool) or not isinstance(every, numbers.Integral) or every < 1:
        raise ValueError(f"Simulation.run: every must be an integer >= 1, got {every!r}")
    if checkpoint_every is not None and (
        isinstance(checkpoint_every, bool)
        or not isinstance(checkpoint_every, numbers.Integral)
        or checkpoint_every < 0
    ):
        raise ValueError(
            f"Simulation.run: checkpoint_every must be an integer >= 0, got {checkpoint_every!r}"
        )
    if not (isinstance(t_end, numbers.Real) and math.isfinite(t_end)):
        raise ValueError(f"Simulation.run: t_end must be a finite time in s, got {t_end!r}")
    if resume and out is None:
        raise ValueError("Simulation.run: resume=True needs out, the folder of the run")
