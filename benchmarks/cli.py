"""The ``bfemp bench`` and ``bfemp sweep`` commands, contributed to the ``bfemp`` command line.

The library never imports the benchmarks: this package registers these commands under the
``bfemp.commands`` entry-point group (``pyproject.toml``), and ``bfemp.cli`` adds whatever
commands installed packages register. The options of ``bfemp sweep`` are those of
``python -m benchmarks tradeoff`` (``benchmarks.tradeoff.add_arguments``), defined once.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from bfemp.errors import SceneError

__all__ = ["add_commands"]


def add_commands(sub: argparse._SubParsersAction) -> dict[str, Callable[[argparse.Namespace], int]]:
    """Add the ``bench`` and ``sweep`` sub-commands to ``sub``; returns their handlers."""
    from benchmarks import tradeoff

    bench = sub.add_parser("bench", help="run a benchmark (python -m benchmarks NAME)")
    bench.add_argument("name", help="benchmark name")
    _mode_options(bench)
    bench.add_argument("--out", default="results", help="output folder (default results/)")

    sweep = sub.add_parser(
        "sweep",
        help="trade study: accuracy against cost of the discretisation knobs "
        "(python -m benchmarks tradeoff)",
    )
    _mode_options(sweep)
    sweep.add_argument("--out", default="results", help="output folder (default results/)")
    tradeoff.add_arguments(sweep)
    sweep.add_argument("--verbose", action="store_true", help="log every point as it finishes")
    return {"bench": _bench, "sweep": tradeoff.main_from_args}


def _mode_options(parser: argparse.ArgumentParser) -> None:
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_const", const="quick", dest="mode")
    mode.add_argument("--full", action="store_const", const="full", dest="mode")
    mode.add_argument(
        "--mode", dest="mode", help="another mode of the benchmark (rings: partial; hertz: refined)"
    )


def _bench(args: argparse.Namespace) -> int:
    import importlib

    from benchmarks.__main__ import BENCHMARKS
    from benchmarks.runner import run_named

    if args.name not in BENCHMARKS:
        raise SceneError(
            f"unknown benchmark '{args.name}'; available: {', '.join(sorted(BENCHMARKS))}"
        )
    module = importlib.import_module(BENCHMARKS[args.name])
    try:
        summary = run_named(args.name, args.mode or "full", args.out, module=module)
    except ValueError as err:  # a mode the benchmark does not have, named by it
        raise SceneError(f"bench {args.name}: {err}") from None
    print(f"{args.name}: wrote {summary.get('json', args.out)}")
    return 0
