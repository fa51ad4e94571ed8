"""The ``bfemp`` command line.

::

    bfemp demo [--out DIR] [--quiet]
    bfemp run SCENE.toml [--out DIR] [--t-end T] [--resume] [--quick] [--check] [--quiet]
                         [--every N] [--checkpoint-every N] [--dry-run]
    bfemp bench NAME [--quick | --full | --mode MODE] [--out DIR]
    bfemp sweep [--quick | --full] [--out DIR] [--scenes S,..] [--knobs K,..] [--workers N]
                [--scheduler tcp://HOST:PORT] [--threads-per-point N] [--point-timeout S]
    bfemp sweep --replay TRADEOFF.json --id ID | --point JSON
    bfemp info RESULT_DIR [--json]

Mistakes in a scene file or argument are printed as ``bfemp: error: <message>`` without a
traceback and exit with status 2 (``--debug`` shows the traceback); a failed run (a time step
that does not converge) exits with 1, a failed ``--check`` with 1, Ctrl-C with 130 after writing
a checkpoint that ``--resume`` continues.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import logging
import os
import sys
import warnings
from pathlib import Path

from bfemp.errors import SceneError

__all__ = ["main"]

log = logging.getLogger(__name__)

EXIT_INPUT, EXIT_RUN, EXIT_INTERRUPTED = 2, 1, 130


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bfemp", description="Coupled MPM-FEM simulation")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of errors")
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
    run.add_argument("--resume", action="store_true", help="continue from the checkpoint in OUT")
    run.add_argument("--quick", action="store_true", help="apply the [quick] overrides")
    run.add_argument("--check", action="store_true", help="evaluate the [check] table")
    run.add_argument("--every", type=int, help="frame interval in steps")
    run.add_argument("--checkpoint-every", type=int, help="checkpoint interval in steps")
    run.add_argument("--dry-run", action="store_true", help="read and check the scene only")
    run.add_argument("--quiet", action="store_true", help="no progress bar, warnings only")
    run.add_argument("--verbose", action="store_true", help="log progress messages")

    bench = sub.add_parser("bench", help="run a benchmark (python -m benchmarks NAME)")
    bench.add_argument("name", help="benchmark name")
    mode = bench.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_const", const="quick", dest="mode")
    mode.add_argument("--full", action="store_const", const="full", dest="mode")
    mode.add_argument(
        "--mode", dest="mode", help="another mode of the benchmark (rings: partial; hertz: refined)"
    )
    bench.add_argument("--out", default="results", help="output folder (default results/)")

    sweep = sub.add_parser(
        "sweep",
        help="trade study: accuracy against cost of the discretisation knobs "
        "(python -m benchmarks tradeoff)",
    )
    mode = sweep.add_mutually_exclusive_group()
    mode.add_argument(
        "--quick", action="store_const", const="quick", dest="mode", help="tiny sweep (minutes)"
    )
    mode.add_argument(
        "--full",
        action="store_const",
        const="full",
        dest="mode",
        help="sweep around the paper's settings (the default; about a day of CPU)",
    )
    mode.add_argument("--mode", dest="mode", help="quick or full (as --quick, --full)")
    sweep.add_argument("--out", default="results", help="output folder (default results/)")
    # the options of benchmarks.tradeoff.add_arguments (a test keeps both in step)
    sweep.add_argument("--scenes", help="comma-separated scenes (default: all)")
    sweep.add_argument("--knobs", help="comma-separated knobs (default: all of each scene)")
    sweep.add_argument("--workers", type=int, help="local point processes at once (default: cores)")
    sweep.add_argument("--scheduler", help="run the points on a Dask scheduler (tcp://host:port)")
    sweep.add_argument(
        "--threads-per-point", type=int, default=1, help="threads of each point (default 1)"
    )
    sweep.add_argument("--point-timeout", type=float, help="wall-time limit of one point in s")
    sweep.add_argument(
        "--cost",
        choices=("wall", "cpu"),
        default="wall",
        help="cost axis: the points' wall time (default) or CPU time (steadier on a busy machine)",
    )
    sweep.add_argument(
        "--replay", metavar="JSON", help="re-run a recorded point (record or tradeoff.json)"
    )
    sweep.add_argument("--id", help="with --replay: the point's id in tradeoff.json")
    sweep.add_argument("--point", metavar="JSON", help="re-run the point given as a JSON record")
    sweep.add_argument("--verbose", action="store_true", help="log every point as it finishes")

    info = sub.add_parser("info", help="summarise a result folder")
    info.add_argument("result_dir", help="the output folder of a run")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    return parser


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


def _run(args: argparse.Namespace, argv: list[str]) -> int:
    from bfemp import scenefile
    from bfemp.scenefile.checks import CheckRecorder, evaluate_checks

    scene_path = Path(args.scene)
    sf = scenefile.load(scene_path)
    settings = sf.run_settings(quick=args.quick, t_end=args.t_end)
    every = _positive_int(args.every, "--every", 1) or settings["every"]
    ckpt = _positive_int(args.checkpoint_every, "--checkpoint-every", 0)
    ckpt = settings["checkpoint_every"] if ckpt is None else ckpt
    out = Path(args.out or settings.get("out") or Path("results") / scene_path.stem)
    if not args.dry_run:
        _first_run_notice(args)
    sim = sf.make_simulation()
    if args.dry_run:
        print(
            f"{scene_path}: ok: {sim.model.n_fem_nodes} FEM nodes, {sim.model.n_particles} "
            f"particles, terms {', '.join(sim.terms)}; t_end {settings['t_end']:g} s"
        )
        return 0
    if not args.resume:
        scenefile.write_text(out / "scene.toml", sf.text)
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
        )
    except KeyboardInterrupt:
        print(
            f"bfemp: interrupted at t = {sim.state.t:.6g} s (step {sim.state.step}); "
            f"checkpoint in {out}\n  continue with: bfemp run {scene_path} --out {out} --resume",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    print(f"run finished: t = {sim.state.t:.6g} s, step {sim.state.step}; output in {out}")
    for pvd in sorted(out.glob("*.pvd")):
        print(f"  ParaView: {pvd}")
    print(f"  metrics: {out / 'metrics.csv'}, {out / 'metrics.png'}; manifest: {out}/manifest.json")
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


def _benchmark_module(name: str) -> object:
    # The benchmarks are a sibling package, not a dependency of the library: they are looked up
    # by name at run time (only here), so bfemp itself never imports them.
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as err:
        if not (err.name or "").startswith("benchmarks"):
            raise
        raise SceneError(
            "the benchmarks package is not installed",
            hint="run from a source checkout (pip install -e .)",
        ) from None


def _bench(args: argparse.Namespace) -> int:
    registry = _benchmark_module("benchmarks.__main__").BENCHMARKS
    if args.name not in registry:
        raise SceneError(
            f"unknown benchmark '{args.name}'; available: {', '.join(sorted(registry))}"
        )
    module = importlib.import_module(registry[args.name])
    try:
        summary = module.run(args.mode or "full", args.out)
    except ValueError as err:  # a mode the benchmark does not have, named by it
        raise SceneError(f"bench {args.name}: {err}") from None
    print(f"{args.name}: wrote {summary.get('json', args.out)}")
    return 0


def _sweep(args: argparse.Namespace) -> int:
    # sweep, or replay one point; its ValueErrors (unknown knob, scene, bad scheduler address)
    # are input errors (exit 2), a point that does not reproduce its error exits 1
    return _benchmark_module("benchmarks.tradeoff").main_from_args(args)


def _info(args: argparse.Namespace) -> int:
    from bfemp.manifest import format_info, run_info

    info = run_info(args.result_dir)
    print(json.dumps(info, indent=2, default=str) if args.json else format_info(info))
    return 0


def _log_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
    """Library warnings (the SuperLU fall-back) as one log line each: ``--quiet`` silences them."""
    log.warning("%s: %s", category.__name__, message)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bfemp`` console script; returns the exit status."""
    from bfemp.steppers import StepError

    argv = sys.argv[1:] if argv is None else list(argv)
    args = _parser().parse_args(argv)
    quiet, verbose = getattr(args, "quiet", False), getattr(args, "verbose", False)
    level = logging.INFO if verbose else (logging.ERROR if quiet else logging.WARNING)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    commands = {
        "demo": _demo,
        "run": lambda a: _run(a, argv),
        "bench": _bench,
        "sweep": _sweep,
        "info": _info,
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
