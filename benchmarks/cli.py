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
    from benchmarks.runner import mode_options

    bench = sub.add_parser("bench", help="run a benchmark (python -m benchmarks NAME)")
    bench.add_argument("name", help="benchmark name")
    mode_options(bench)

    sweep = sub.add_parser(
        "sweep",
        help="trade study: accuracy against cost of the discretisation knobs "
        "(python -m benchmarks tradeoff)",
    )
    mode_options(sweep)
    tradeoff.add_arguments(sweep)
    sweep.add_argument("--verbose", action="store_true", help="log every point as it finishes")
    return {"bench": _bench, "sweep": tradeoff.main_from_args}


def _bench(args: argparse.Namespace) -> int:
    import importlib

    from benchmarks.__main__ import BENCHMARKS
    from benchmarks.runner import run_named

    module = importlib.import_module(BENCHMARKS[args.name]) if args.name in BENCHMARKS else None
    try:
        summary = run_named(args.name, args.mode or "full", args.out, module=module)
    except ValueError as err:  # an unknown name, or a mode the benchmark does not have
        raise SceneError(f"bench {args.name}: {err}") from None
    print(f"{args.name}: wrote {summary.get('json', args.out)}")
    return 0
