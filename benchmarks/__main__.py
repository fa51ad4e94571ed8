"""``python -m benchmarks NAME [--quick | --full | --mode M] [--out DIR] [options]``: run one
benchmark; ``python -m benchmarks verify NAME [NAME ...] [--mode M]``: rerun a mode (quick by
default) into a temporary folder and compare its non-timing fields with the committed record.

The names are those of the catalogue (``benchmarks.runner.catalogue``: every module registers
its ``Benchmark``). A benchmark's own options come from its entry's ``arguments`` and reach its
``measure``; a module may instead take over with ``add_arguments(parser)`` and
``main_from_args(args) -> int`` (``tradeoff``: its ``--replay``). A ``ValueError`` is printed as
a usage error (exit status 2).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from benchmarks.runner import catalogue, mode_options, run_named, verify

#: benchmark name (aliases included) -> module exposing ``run(mode: str, out: Path) -> dict``
BENCHMARKS = {name: bench.module for name, bench in catalogue().items()}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    parser.add_argument("name", choices=sorted(BENCHMARKS))
    mode_options(parser)
    return parser


def _verify(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks verify")
    parser.add_argument("names", nargs="+", choices=sorted(BENCHMARKS), metavar="NAME")
    parser.add_argument("--mode", default="quick", help="the mode rerun (default quick)")
    args = parser.parse_args(argv)
    failed = 0
    for name in args.names:
        try:
            diffs = verify(name, args.mode)
        except ValueError as err:
            parser.error(str(err))
        failed += bool(diffs)
        print(f"{name} ({args.mode}): " + ("reproduces" if not diffs else f"{len(diffs)} differ"))
        for line in diffs:
            print(f"  {line}")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if argv[:1] == ["verify"]:
        return _verify(argv[1:])
    parser = _parser()
    # first pass: only the name, to add the options of the chosen benchmark (--help included)
    first = argparse.ArgumentParser(add_help=False)
    first.add_argument("name", nargs="?")
    name = first.parse_known_args(argv)[0].name
    module = importlib.import_module(BENCHMARKS[name]) if name in BENCHMARKS else None
    bench = catalogue().get(name)
    own = []
    if bench is not None and bench.arguments is not None:
        group = parser.add_argument_group(name)
        bench.arguments(group)
        own = [action.dest for action in group._group_actions]
    elif module is not None and hasattr(module, "add_arguments"):
        module.add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        if hasattr(module, "main_from_args"):
            return module.main_from_args(args)
        options = {d: getattr(args, d) for d in own if getattr(args, d) is not None}
        summary = run_named(args.name, args.mode or "full", args.out, module=module, **options)
    except ValueError as err:  # a mode the benchmark does not have, named by it
        parser.error(f"{args.name}: {err}")
    print(f"{args.name}: wrote {summary['json']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
