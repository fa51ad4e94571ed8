"""The time loop users drive: ``Simulation(scene, ...)``, ``step()``, ``run()``.

``run`` shows a tqdm progress bar, records one metrics row per step (energies, momenta, Newton
iterations, per-phase timings) and, given an output folder, writes what :meth:`Simulation.run`
lists; what a run folder holds and the final writes are :mod:`bfemp.io.outputs`.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from bfemp import diagnostics, scenefile
from bfemp._energy_watch import EnergyWatch, dissipation
from bfemp._run_arguments import (
    check_run_args,
    check_t_end,
    merge_flat_options,
    n_steps,
    resolve_dt,
)
from bfemp._run_folder import run_to_folder
from bfemp.checkpoint import InterruptGuard, restore_checkpoint, write_checkpoint
from bfemp.contact.penetration import PenetrationCheck
from bfemp.errors import (
    PlausibilityWarning,
    SceneError,
    StepNoteWarning,
    collect_warnings,
    note_name,
    warn_user,
)
from bfemp.integrators import Integrator, integrator_from_name
from bfemp.io import outputs
from bfemp.io.fields import frame_blocks
from bfemp.io.metrics import MetricsLog
from bfemp.io.snapshots import check_animation_format
from bfemp.io.vtk import Block, FrameWriter
from bfemp.model import Model
from bfemp.mpm.transfer import SCHEMES
from bfemp.plausibility import discretisation_notes
from bfemp.scene import Scene
from bfemp.state import State
from bfemp.steppers import (
    STRATEGIES,
    StepError,
    StepperOptions,
    StepReport,
    options_to_dict,
    stepper_class,
)
from bfemp.steppers.capabilities import check_scene
from bfemp.terms import fem_elastic_groups
from bfemp.validation import validate_initial
from solvers.blas import serial_wheel_blas
from solvers.linear import LinearSolver

__all__ = ["Simulation"]

log = logging.getLogger(__name__)


class Simulation:
    """A scene advanced in time by one coupling strategy.

    Args:
        scene: a ``Scene`` (built here) or a ``Model``.
        strategy: coupling strategy name, one of ``bfemp.steppers.STRATEGIES`` (``"barrier"``:
            BFEMP implicit).
        integrator: ``"backward_euler"``, ``"newmark"``, ``"newmark_damped"`` or
            ``"newmark_implicit_contact"`` (mid-point Newmark with memory-free contact forces:
            no energy gain at stiff impacts; see :mod:`bfemp.integrators`), or an
            ``Integrator``; explicit strategies take ``"symplectic_euler"``. None: the
            strategy's default (``backward_euler`` for ``barrier``).
        transfer: particle-grid transfer for MPM bodies (``"apic"``, ``"pic"``, ``"flip"``); None:
            the strategy's default (``"apic"``; ``"flip"`` for ``lr``, which refuses APIC).
        dt: time step in s, or ``"auto"`` for an explicit strategy's stable step.
        options: the strategy's options (``bfemp.BarrierOptions`` for ``barrier``, ...); None
            for its defaults.
        tol, max_newton_iterations, linear_solver, warm_start: the ``BarrierOptions`` fields as
            flat keywords (``barrier`` only; not together with ``options``).
        allow_uncoupled: run a scene with a pair of bodies the strategy does not couple (an MPM
            and a FEM body under ``single_field``, ...), with a warning, instead of refusing it
            (:mod:`bfemp.steppers.capabilities`; ``bfemp strategies`` lists what each couples).

    Every named note of a step (``StepReport.notes``: ``INTERPENETRATION``, ``LR_UNCONVERGED``,
    ...), and every warning the library issues while the simulation works
    (:func:`bfemp.errors.warn_user`: ``P2G_ZERO_MASS``, ``LR_GRID_FINE``, ``ENERGY_GROWTH``,
    ``OUTPUT_NOT_WRITTEN``, ...), is counted in ``note_counts`` (also in the run's manifest and
    ``bfemp info``) and, the first time each name occurs, issued through Python's ``warnings``
    (a ``bfemp.StepNoteWarning`` or ``bfemp.BfempWarning``: a plain script sees it without
    configuring logging), logged, and kept in ``diagnostics``. Scenes with a FEM body and
    another body get a ``penetration_depth`` metrics column: the deepest any FEM node or particle
    lies inside another FEM body, in m (``bfemp.contact.penetration``, the same geometric check
    for every strategy).
    """

    def __init__(
        self,
        scene: Scene | Model,
        *,
        strategy: str = "barrier",
        integrator: str | Integrator | None = None,
        transfer: str | None = None,
        dt: float | str,
        options: StepperOptions | None = None,
        tol: float | None = None,
        max_newton_iterations: int | None = None,
        linear_solver: LinearSolver | None = None,
        warm_start: bool | None = None,
        allow_uncoupled: bool = False,
    ) -> None:
        stepper_cls = stepper_class(strategy)
        if transfer is None:
            transfer = getattr(stepper_cls, "default_transfer", "apic")
        allowed = getattr(stepper_cls, "transfers", SCHEMES)
        if transfer not in allowed:
            raise ValueError(
                f"Simulation.transfer must be one of {allowed} for strategy {strategy!r}, "
                f"got {transfer!r}"
            )
        flat = {
            "tol": tol,
            "max_newton_iterations": max_newton_iterations,
            "linear_solver": linear_solver,
            "warm_start": warm_start,
        }
        options = merge_flat_options(strategy, options, flat)
        #: the first warning of each name (e.g. "ENERGY_GROWTH: ..."), as issued and logged
        self.diagnostics: list[str] = []
        #: how many times each named note (``StepReport.notes``) or warning was reported
        self.note_counts: dict[str, int] = {}
        with collect_warnings(self._notice):  # warn_user reaches diagnostics
            self.model = scene.build() if isinstance(scene, Scene) else scene
            for message in check_scene(
                self.model, strategy, STRATEGIES, allow_uncoupled=allow_uncoupled
            ):
                warn_user(message, category=StepNoteWarning, logger=log)
            #: the report of the step that failed last (None after a step that succeeded)
            self.failed_report: StepReport | None = None
            #: the scene this simulation was built from (written to ``out/scene.toml`` by runs)
            self.scene = scene if isinstance(scene, Scene) else None
            #: the text of the scene file this simulation was read from (``from_file``), or None
            self.scene_text: str | None = None
            if integrator is None:
                integrator = getattr(stepper_cls, "default_integrator", "backward_euler")
            self.integrator = integrator_from_name(integrator)
            initial = self.model.initial_state()
            self.dt = resolve_dt(dt, stepper_cls, self.model, initial, options)
            if self.model.contact is not None:
                # the barrier is finite only for bodies that start apart (and beyond d-hat)
                validate_initial(self.model)
            self.strategy = strategy
            self.transfer = transfer
            self.options = options
            #: the settings of this simulation (recorded in manifests and checkpoints): the
            #: [simulation] table with the strategy's options one key per field
            self.settings = {k: v for k, v in self.scene_settings().items() if k != "options"}
            self.settings.update(options_to_dict(options))
            if allow_uncoupled:
                self.settings["allow_uncoupled"] = True
            self.stepper = stepper_cls(
                self.model,
                integrator=self.integrator,
                transfer=transfer,
                dt=self.dt,
                options=options,
            )
            self.state: State = self.stepper.initialize(initial)
            for note in discretisation_notes(self.model, self.dt, self.integrator):
                self._notice(note, PlausibilityWarning, log)
            self.metrics = MetricsLog()
            self._energy = EnergyWatch(self.model, self.integrator, dissipation(self), self._notice)
            self._fem_groups = fem_elastic_groups(self.model)
            self._contact_columns = self.model.contact is not None
            self._penetration = PenetrationCheck.for_model(self.model)
            self.metrics.append(self._metrics_row(None))

    @classmethod
    def from_file(cls, source: str | Path | scenefile.SceneFile, **overrides: object) -> Simulation:
        """A simulation of a scene file with its ``[simulation]`` settings.

        Args:
            source: the scene file's path, or a ``bfemp.scenefile.SceneFile`` already read.
            overrides: ``Simulation`` keyword arguments replacing those of the file.

        Errors (a missing dt, a bad option, an initial overlap) name the file and the field.
        """
        sf = source if isinstance(source, scenefile.SceneFile) else scenefile.load(source)
        kwargs = {**sf.simulation, **overrides}
        if "dt" not in kwargs:
            raise SceneError(
                "missing key 'dt'", file=sf.file, field="simulation.dt", hint="the time step in s"
            )
        model = sf.build_model()
        try:
            sim = cls(model, **kwargs)
        except SceneError as err:
            raise err.located(file=sf.file) from None
        except ValueError as err:
            raise SceneError(str(err), file=sf.file, field="simulation") from None
        sim.scene, sim.scene_text = sf.scene, sf.text
        return sim

    def scene_settings(self) -> dict:
        """The ``[simulation]`` table of this simulation (strategy, integrator, transfer, dt and
        the strategy's options as ``[simulation.options]``)."""
        return {
            "strategy": self.strategy,
            "integrator": self.integrator.name,
            "transfer": self.transfer,
            "dt": self.dt,
            "options": self.options,
        }

    def scene_file_text(self) -> str | None:
        """The scene-file text of this simulation: the file it was read from, else its
        ``Scene`` with :meth:`scene_settings`; None for a ``Model`` or a scene the format cannot
        hold (a custom material, motion or level set; logged)."""
        if self.scene_text is not None:
            return self.scene_text
        if self.scene is None:
            log.info("no scene.toml written: the simulation was built from a Model")
            return None
        try:
            return scenefile.save(self.scene, simulation=self.scene_settings())
        except ValueError as err:
            warn_user(
                f"NO_SCENE_FILE: no scene.toml written: the scene cannot be written as TOML "
                f"({err})",
                logger=log,
            )
            return None

    @property
    def terms(self) -> list[str]:
        """Names of the energy terms this scene pays for."""
        return self.stepper.terms

    # ------------------------------------------------------------------ stepping
    def step(self) -> StepReport:
        """Advance one time step; returns its report (raises ``StepError`` on failure, whose
        report is also kept as ``failed_report``: its iterations go to the run's manifest).
        numpy's BLAS runs on one thread inside (``solvers.blas.serial_wheel_blas``)."""
        with collect_warnings(self._notice), serial_wheel_blas():
            try:
                self.state, report = self.stepper.step(self.state)
            except StepError as err:
                self.failed_report = err.report
                raise
            self.failed_report = None
            self._count_notes(report)
            self.metrics.append(self._metrics_row(report))
        return report

    def _count_notes(self, report: StepReport) -> None:
        """Count the step's named notes; warn the first time each name occurs."""
        for note in report.notes:
            name = note_name(note)
            if name not in self.note_counts:
                note = (
                    f"{note} (step {report.step}, t = {report.t:.6g} s; the first {name} note "
                    "of this run: later ones are counted in note_counts, the manifest and "
                    "bfemp info)"
                )
            self._notice(note, StepNoteWarning, log)

    def _notice(
        self, message: str, category: type[Warning] = StepNoteWarning, logger: object = log
    ) -> None:
        """A named warning ``"NAME: text"`` of this simulation, counted and (the first of each
        name) kept, logged and issued as the class docstring says; later ones logged at debug
        level only."""
        name = note_name(message)
        self.note_counts[name] = self.note_counts.get(name, 0) + 1
        if self.note_counts[name] > 1:
            logger.debug("%s", message)
            return
        self.diagnostics.append(message)
        logger.warning("%s", message)
        warnings.warn(message, category, stacklevel=3)

    def run(
        self,
        t_end: float,
        *,
        out: str | Path | None = None,
        every: int | None = None,
        progress: bool = True,
        callback: Callable[[Simulation], None] | None = None,
        checkpoint_every: int | None = None,
        resume: bool = False,
        metadata: dict | None = None,
        overwrite: bool = False,
        animation: str | None = None,
        scene_toml: str | None = None,
    ) -> MetricsLog:
        """Step until ``t_end`` s; with ``out``, write a frame of the start state (not on resume)
        and one every ``every`` steps.

        The run takes whole steps of ``dt``: it ends at the first ``t = t0 + n dt >= t_end`` (within
        ``1e-9 dt``), past ``t_end`` by less than one step when ``dt`` does not divide the time
        to go (``dt="auto"``: 0.300539 s for 0.3 s; logged). The last step is not shortened to
        land on ``t_end``: a run continued from its checkpoint (``resume``) equals an uninterrupted
        one bit for bit (frames, PVD files and metrics; wall-clock ``time_*`` columns excepted),
        which a short step in its middle would break, and the explicit strategies derive
        settings from ``dt`` once (augury's ``tau``, the CFL checks).

        With an output folder ``out`` the run also writes ``metrics.csv``, ``metrics.png``, a
        run manifest (``manifest.json``, see :mod:`bfemp.manifest`) and checkpoints
        (:mod:`bfemp.checkpoint`): at the end, every ``checkpoint_every`` steps if given, when a
        step fails (the last good state), and on Ctrl-C: the first Ctrl-C finishes the current
        step, writes a checkpoint and raises ``KeyboardInterrupt``; a second one aborts at once
        (the last periodic checkpoint remains).

        A fresh run refuses a folder that holds an earlier run's outputs unless ``overwrite``
        (then deletes them first: :mod:`bfemp.io.outputs`). One run writes a folder at a time:
        it holds the folder's lock, and a second run into it is refused (``RunFolderError``
        naming the holder), as are, on resume, a corrupt checkpoint, manifest or frame; the
        temporary files of a killed run are removed. Every run with ``out`` writes
        ``snapshots.png`` (the bodies at up to 6 frame times, coloured by von Mises stress) and
        ``scene.toml``.

        Args:
            t_end: end time in s.
            out: output folder, or None for no output.
            every: frame interval in steps (>= 1); None: 1, or on resume the interval of the
                run being continued (its checkpoint's).
            progress: show a tqdm progress bar.
            callback: called as ``callback(sim)`` after every step (to record custom quantities).
            checkpoint_every: checkpoint interval in steps (0: only at the end); None: 0, or on
                resume the interval of the run being continued (its manifest's).
            resume: continue from the checkpoint in ``out``.
            metadata: extra parameters recorded in the manifest (e.g. the scene file).
            overwrite: replace the outputs of an earlier run in ``out`` (else refused).
            animation: ``"gif"`` or ``"mp4"`` (with ffmpeg): also write ``out/animation.FMT`` of
                every frame (:mod:`bfemp.io.snapshots`).
            scene_toml: text of ``out/scene.toml`` (default: the scene of this simulation with
                its settings; nothing for a simulation built from a ``Model``).

        Returns the metrics log (also written to ``out/metrics.csv`` and plotted to
        ``out/metrics.png``).
        """
        check_run_args(t_end, every, checkpoint_every, resume, out)
        if resume and overwrite:
            raise ValueError(
                "Simulation.run: resume=True continues the run in out and overwrite=True deletes "
                "it; give one of them"
            )
        if not resume:
            check_t_end(t_end, self.state.t, self.dt)
        if animation is not None:
            check_animation_format(animation)
        if out is None:
            self._loop(n_steps(self.state.t, t_end, self.dt), progress, callback)
            return self.metrics
        # one writer per folder: RunFolderError if in use
        with collect_warnings(self._notice), outputs.lock_run_folder(out):
            return run_to_folder(
                self,
                Path(out),
                t_end,
                every,
                progress,
                callback,
                checkpoint_every,
                resume,
                metadata,
                overwrite,
                animation,
                scene_toml,
            )

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
                    **{name: count for name, count in report.iterations.items()},
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
        with collect_warnings(self._notice):
            restore_checkpoint(out, self)

    # ------------------------------------------------------------------ output
    def energies(
        self, state: State | None = None, *, mpm_elastic: list[float] | None = None
    ) -> dict[str, float]:
        """Kinetic, elastic, gravitational (load, contact) and total energy in J (J/m in 2D).

        The contact (barrier) energy B is that of the current state's active pairs; it is the
        elastic energy stored by the barrier while bodies touch, so the total of a scene on which
        nothing external works is what a conservative integrator keeps. A strategy without a
        contact energy reports NaN for it, and the total leaves it out. Explicit strategies store
        half-step velocities (symplectic Euler), so their kinetic energy is that of v^{n+1/2}:
        off by O(dt) from the full-step one. ``mpm_elastic``: the MPM bodies' elastic energies
        (``diagnostics.mpm_body_elastic_energies``) where the caller has them.
        """
        state = self.state if state is None else state
        contact = None
        if self._contact_columns:
            contact = self.stepper.contact().energy if state is self.state else 0.0
        return diagnostics.energy_columns(
            self.model, state, self.transfer, self._fem_groups, contact, mpm_elastic
        )

    def _metrics_row(self, report: StepReport | None) -> dict[str, float]:
        model, state, transfer = self.model, self.state, self.transfer
        row: dict[str, float] = {"t": state.t, "step": state.step}
        mpm_elastic = diagnostics.mpm_body_elastic_energies(model, state)  # once for both uses
        row.update(self.energies(mpm_elastic=mpm_elastic))
        self._energy.check(row, report is not None, self.metrics, state.t)
        row.update(diagnostics.momentum_columns(model, state, transfer))
        if self._penetration is not None:
            row["penetration_depth"] = self._penetration.depth(state)
        forces = self.stepper.contact().body_forces if report is not None else None
        row.update(diagnostics.body_metrics(model, state, transfer, forces, mpm_elastic))
        if report is not None:
            contact = self.stepper.contact() if self._contact_columns else None
            row.update(diagnostics.report_columns(report, contact))
        return row

    def contact_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Barrier contact forces at the end of the last step, in N (N/m in 2D).

        Returns ``(fem (N, d), mpm (P, d))``: the force on every FEM node (zero off the
        boundary) and on every particle; both zero before the first step or without contact.
        """
        view = self.stepper.contact()
        return view.fem_forces, view.particle_forces

    def frame_blocks(self) -> list[Block]:
        """One VTK block per body at the current state (:func:`bfemp.io.fields.frame_blocks`)."""
        return frame_blocks(self.model, self.state, *self.contact_forces())
