"""The ``bfemp`` command line.

::

    bfemp demo [--out DIR] [--quiet]
    bfemp run SCENE.toml [--out DIR] [--t-end T] [--resume | --overwrite] [--quick] [--check]
                         [--every N] [--checkpoint-every N] [--animate {gif,mp4}] [--dry-run]
                         [--quiet]
    bfemp bench NAME [--quick | --full | --mode MODE] [--out DIR]
    bfemp sweep [--quick | --full] [--out DIR] [--scenes S,..] [--knobs K,..] [--workers N]
                [--scheduler tcp://HOST:PORT] [--threads-per-point N] [--point-timeout S]
    bfemp sweep --replay TRADEOFF.json --id ID | --point JSON
    bfemp info RESULT_DIR [--json]
    bfemp regress [NAMES...] [--update] [--dir DIR] [--all] [--quiet]
    bfemp warmup [--dir DIR] [--processes N] [--quiet]   (compile the numba kernels once)
    bfemp --version      (also the BLAS CHOLMOD runs on and the linear solvers installed)

``bench`` and ``sweep`` come from the ``benchmarks`` package of a source checkout, which registers
them under the ``bfemp.commands`` entry points (the library never imports it).

Mistakes in a scene file or argument are printed as ``bfemp: error: <message>`` without a
traceback and exit with status 2 (``--debug`` shows the traceback); a failed run (a time step
that does not converge) exits with 1, a failed ``--check`` with 1, Ctrl-C with 130 after writing
a checkpoint that ``--resume`` continues. ``regress`` exits with 1 when a reference drifted.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import os
import sys
import warnings
from importlib import metadata
from pathlib import Path

from bfemp.errors import SceneError

__all__ = ["main"]

log = logging.getLogger(__name__)

EXIT_INPUT, EXIT_RUN, EXIT_INTERRUPTED = 2, 1, 130


class _VersionAction(argparse.Action):
    """``bfemp --version``: the version and the linear-algebra stack, then exit."""

    def __init__(self, option_strings, dest, **kwargs) -> None:  # noqa: ANN001
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:  # noqa: ANN001
        import bfemp
        from solvers.allocator import format_allocator
        from solvers.choice import format_linear_algebra, linear_algebra
        from solvers.numba_threads import format_numba_threads
        from solvers.openmp import format_openmp

        print(
            f"bfemp {bfemp.__version__}\n{format_linear_algebra(linear_algebra())}\n"
            f"{format_openmp()}\n{format_allocator()}\n{format_numba_threads()}"
        )
        parser.exit()


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bfemp", description="Coupled MPM-FEM simulation")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of errors")
    parser.add_argument(
        "--version",
        action=_VersionAction,
        help="print the version, the BLAS CHOLMOD runs on and the linear solvers installed",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser(
        "demo", help="run a demo (colliding MPM and FEM rings) and write its outputs"
    )
    demo.add_argument("--out", default="results/demo", help="output folder (default results/demo)")
    demo.add_argument(
        "--case",
        choices=("rings", "cantilever"),
        default="rings",
        help="rings: coupled MPM-FEM collision (default); cantilever: FEM only",
    )
    demo.add_argument("--quiet", action="store_true", help="no progress bar")

    run = sub.add_parser("run", help="run a scene file")
    run.add_argument("scene", help="the scene file (TOML, format: bfemp.scenefile)")
    run.add_argument("--out", help="output folder (default: [run] out, else results/SCENE_NAME)")
    run.add_argument("--t-end", type=float, help="end time in s (default: [run] t_end)")
    # one or the other: --resume continues the run in OUT, --overwrite deletes it
    folder = run.add_mutually_exclusive_group()
    folder.add_argument("--resume", action="store_true", help="continue from the checkpoint in OUT")
    folder.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the outputs of an earlier run in OUT (without it such a folder is refused)",
    )
    run.add_argument(
        "--animate",
        choices=("gif", "mp4"),
        help="also write OUT/animation.gif (or .mp4, needs ffmpeg) of every frame",
    )
    run.add_argument("--quick", action="store_true", help="apply the [quick] overrides")
    run.add_argument("--check", action="store_true", help="evaluate the [check] table")
    run.add_argument("--every", type=int, help="frame interval in steps")
    run.add_argument("--checkpoint-every", type=int, help="checkpoint interval in steps")
    run.add_argument("--dry-run", action="store_true", help="read and check the scene only")
    run.add_argument("--quiet", action="store_true", help="no progress bar, warnings only")
    run.add_argument("--verbose", action="store_true", help="log progress messages")

    info = sub.add_parser("info", help="summarise a result folder")
    info.add_argument("result_dir", help="the output folder of a run")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")

    strategies = sub.add_parser(
        "strategies",
        help="which body pairs each coupling strategy couples, friction, penetration guarantee",
    )
    strategies.add_argument("--json", action="store_true", help="print the table as JSON")

    regress = sub.add_parser(
        "regress", help="rerun regression references and report drifted quantities"
    )
    regress.add_argument("names", nargs="*", help="reference names (default: all in DIR)")
    regress.add_argument(
        "--dir",
        default=None,
        help="folder of the references (default the checkout's references/, wherever bfemp "
        "regress is run from)",
    )
    regress.add_argument(
        "--update", action="store_true", help="rewrite the stored trajectories and say what changed"
    )
    regress.add_argument("--all", action="store_true", help="list every quantity, not only drifts")
    regress.add_argument("--quiet", action="store_true", help="warnings only")
    regress.add_argument("--verbose", action="store_true", help="log progress messages")

    warmup = sub.add_parser(
        "warmup", help="compile and cache the numba kernels by running small scenes in parallel"
    )
    warmup.add_argument(
        "--dir", default=None, help="folder of the references (default the checkout's references/)"
    )
    warmup.add_argument("--processes", type=int, help="worker processes (default: CPU count)")
    warmup.add_argument("--quiet", action="store_true", help="warnings only")
    warmup.add_argument("--verbose", action="store_true", help="log each scene as it finishes")
    return parser


#: entry-point group through which installed packages add sub-commands (``benchmarks`` adds
#: ``bench`` and ``sweep``); each entry point is ``add_commands(subparsers) -> {name: handler}``
COMMAND_GROUP = "bfemp.commands"


def _parser_and_plugins() -> tuple[argparse.ArgumentParser, dict]:
    """The parser with the commands of installed plugins, and their handlers."""
    parser = _parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    handlers: dict = {}
    for entry in sorted(metadata.entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            add_commands = entry.load()
        except ImportError as err:  # a broken plugin must not take the command line down
            log.warning("bfemp command plugin %r not loaded: %s", entry.value, err)
            continue
        handlers.update(add_commands(sub))
    return parser, handlers


def _demo(args: argparse.Namespace) -> int:
    from bfemp.demo import run_cantilever_demo, run_demo

    runner = run_demo if args.case == "rings" else run_cantilever_demo
    _first_run_notice(args)
    summary = runner(args.out, progress=not args.quiet)
    outputs = summary["outputs"]
    print(
        f"demo ({args.case}) finished: {summary['steps']} steps, "
        f"{summary['newton_iterations_total']} Newton iterations"
    )
    if args.case == "rings":
        print(
            f"  momentum drift {summary['momentum_drift_rel']:.1e} (relative), closest approach "
            f"{summary['min_distance']:.2e} m, energy lost {summary['energy_loss_pct']:.1f} %"
        )
    frames = outputs["frames"] if isinstance(outputs["frames"], list) else [outputs["frames"]]
    print(f"  ParaView frames: {', '.join(frames)}")
    print(f"  metrics:         {outputs['metrics']}")
    print(f"  plots:           {', '.join(outputs['plots'])}")
    print(f"  scene file:      {outputs['scene']}")
    if "summary" in outputs:
        print(f"  summary (JSON):  {outputs['summary']}")
    return 0


def _first_run_notice(args: argparse.Namespace) -> None:
    """Say that this run compiles the numba kernels when none is cached (unless --quiet)."""
    from bfemp._numba_cache import first_run_notice

    notice = None if args.quiet else first_run_notice()
    if notice:
        print(f"bfemp: {notice}", file=sys.stderr)


def _positive_int(value: int | None, name: str, minimum: int) -> int | None:
    if value is not None and value < minimum:
        raise SceneError(f"must be an integer >= {minimum}, got {value}", field=name)
    return value


def _check_resume_t_end(out: Path, t_end: float, given: bool) -> None:
    """Refuse ``--resume`` towards an end time before the checkpoint's time (nothing to run)."""
    from bfemp.checkpoint import read_checkpoint

    t = float(read_checkpoint(out).state.t)
    if t_end < t * (1.0 - 1e-12):
        raise SceneError(
            f"t_end = {t_end:.9g} s is earlier than the checkpoint in {out}, at t = {t:.9g} s",
            field="--t-end" if given else "run.t_end",
            hint=f"give --t-end after {t:.9g} s to continue the run, or run without --resume",
        )


def _run(args: argparse.Namespace, argv: list[str]) -> int:
    from bfemp import scenefile
    from bfemp.scenefile.checks import CheckRecorder, evaluate_checks
    from bfemp.simulation import Simulation

    scene_path = Path(args.scene)
    if args.animate is not None:  # before the scene is built: mp4 without ffmpeg is refused
        from bfemp.io.snapshots import check_animation_format

        check_animation_format(args.animate)
    sf = scenefile.load(scene_path)
    settings = sf.run_settings(quick=args.quick, t_end=args.t_end)
    every = _positive_int(args.every, "--every", 1)
    ckpt = _positive_int(args.checkpoint_every, "--checkpoint-every", 0)
    if not args.resume:  # a resumed run keeps the intervals of the run it continues
        every = every or settings["every"]
        ckpt = settings["checkpoint_every"] if ckpt is None else ckpt
    out = Path(args.out or settings.get("out") or Path("results") / scene_path.stem)
    if not args.dry_run:
        _first_run_notice(args)
    sim = Simulation.from_file(sf)
    if args.dry_run:
        print(
            f"{scene_path}: ok: {sim.model.n_fem_nodes} FEM nodes, {sim.model.n_particles} "
            f"particles, terms {', '.join(sim.terms)}; t_end {settings['t_end']:g} s"
        )
        return 0
    if args.resume:
        _check_resume_t_end(out, settings["t_end"], args.t_end is not None)
    metadata = {
        "scene_file": str(scene_path.resolve()),
        "scene_sha256": hashlib.sha256(sf.text.encode()).hexdigest(),
        "command": ["bfemp", *argv],
        "quick": bool(args.quick),
    }
    recorder = CheckRecorder()
    recorder.record(sim)
    try:
        sim.run(
            settings["t_end"],
            out=out,
            every=every,
            progress=not args.quiet,
            callback=recorder,
            checkpoint_every=ckpt,
            resume=args.resume,
            metadata=metadata,
            overwrite=args.overwrite,
            animation=args.animate,
            scene_toml=sf.text,
        )
    except KeyboardInterrupt:
        from bfemp.checkpoint import CHECKPOINT_FILE

        if (out / CHECKPOINT_FILE).is_file():
            how = f"checkpoint in {out}\n  continue with: bfemp run {scene_path} --out {out}"
            how += " --resume" + _repeated_options(args)
        else:  # stopped before any checkpoint: --resume would be refused
            how = f"no checkpoint was written to {out}\n  start again with: bfemp run {scene_path}"
            how += f" --out {out} --overwrite"
        where = f"interrupted at t = {sim.state.t:.6g} s (step {sim.state.step})"
        print(f"bfemp: {where}; {how}", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(f"run finished: t = {sim.state.t:.6g} s, step {sim.state.step}; output in {out}")
    for pvd in sorted(out.glob("*.pvd")):
        print(f"  ParaView: {pvd}")
    print(f"  metrics: {out / 'metrics.csv'}, {out / 'metrics.png'}; manifest: {out}/manifest.json")
    print(
        f"  pictures: {out / 'snapshots.png'}"
        + (f", {out}/animation.{args.animate}" if args.animate else "")
    )
    if args.check:
        if not sf.check:
            print("check: the scene file has no [check] table")
            return 0
        results = evaluate_checks(sf.check, sim.metrics, recorder)
        for result in results:
            print(f"check {result}")
        if not all(r.ok for r in results):
            print("bfemp: error: a check failed", file=sys.stderr)
            return EXIT_RUN
    return 0


def _repeated_options(args: argparse.Namespace) -> str:
    """The options of ``bfemp run`` a continuation must repeat (``--quick``, ``--t-end``,
    ``--animate``); the frame and checkpoint intervals are the checkpoint's by default."""
    text = " --quick" if args.quick else ""
    if args.t_end is not None:
        text += f" --t-end {args.t_end!r}"
    if args.animate:
        text += f" --animate {args.animate}"
    return text


def _info(args: argparse.Namespace) -> int:
    from bfemp.manifest import format_info, run_info

    info = run_info(args.result_dir)
    print(json.dumps(info, indent=2, default=str) if args.json else format_info(info))
    return 0


def _strategies(args: argparse.Namespace) -> int:
    from bfemp.steppers import STRATEGIES, strategy_table

    if args.json:
        table = {name: vars(cls.capabilities) for name, cls in STRATEGIES.items()}
        print(json.dumps(table, indent=2, default=dict))  # default: the read-only pairs mapping
    else:
        print(strategy_table())
    return 0


def _regress(args: argparse.Namespace) -> int:
    from bfemp import regress

    directory = args.dir if args.dir is not None else regress.default_reference_dir()
    refs = regress.find_references(directory, args.names)
    if not refs:
        raise SceneError(f"no reference (a scene file with [regress]) in {directory}")
    failed = []
    for ref in refs:
        if args.update:
            changes = regress.update(ref)
            what = ", ".join(
                f"{k} {v:.3e}" if isinstance(v, float) else f"{k} {v}" for k, v in changes.items()
            )
            print(f"{ref.name}: " + (f"written ({what})" if what else "unchanged, not rewritten"))
            continue
        report = regress.check(ref)
        print(report.table(all_quantities=args.all))
        if not report.ok:
            failed.append(ref.name)
    if failed:
        print(f"bfemp: error: drift in {', '.join(failed)}", file=sys.stderr)
        return EXIT_RUN
    return 0


def _warmup(args: argparse.Namespace) -> int:
    import time

    from numba.core import config

    from bfemp.warmup import warm_up

    start = time.perf_counter()
    walls = warm_up(args.dir, args.processes)
    where = config.CACHE_DIR or "the __pycache__ folders of the packages"
    if not args.quiet:
        print(
            f"bfemp warmup: {len(walls)} scenes in {time.perf_counter() - start:.0f} s; "
            f"numba kernels cached in {where}"
        )
    return 0


def _log_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
    """Library warnings (the SuperLU fall-back) as one log line each: ``--quiet`` silences them.

    A ``BfempWarning`` (step notes included) is left out: ``bfemp.errors.warn_user`` and
    ``Simulation`` log it themselves.
    """
    from bfemp.errors import BfempWarning

    if issubclass(category, BfempWarning):
        return
    log.warning("%s: %s", category.__name__, message)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bfemp`` console script; returns the exit status."""
    from bfemp.steppers import StepError

    argv = sys.argv[1:] if argv is None else list(argv)
    parser, plugins = _parser_and_plugins()
    args = parser.parse_args(argv)
    quiet, verbose = getattr(args, "quiet", False), getattr(args, "verbose", False)
    level = logging.INFO if verbose else (logging.ERROR if quiet else logging.WARNING)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    commands = {
        "demo": _demo,
        "run": lambda a: _run(a, argv),
        "info": _info,
        "strategies": _strategies,
        "regress": _regress,
        "warmup": _warmup,
        **plugins,
    }
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _log_warning
            return commands[args.command](args)
    except (StepError, RuntimeError) as err:
        if args.debug:
            raise
        print(f"bfemp: error: {err}", file=sys.stderr)
        return EXIT_RUN
    except BrokenPipeError:  # the reader of our output went away (bfemp info DIR | head)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (ValueError, OSError) as err:
        if args.debug:
            raise
        print(f"bfemp: error: {err}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("bfemp: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
