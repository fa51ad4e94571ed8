"""``python -m benchmarks NAME [--quick | --full] [--out DIR]``: run one benchmark."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

#: benchmark name -> module in this package exposing ``run(mode: str, out: Path) -> dict``.
BENCHMARKS = {
    "extremes": "benchmarks.extremes",
    "hertz": "benchmarks.hertz",
    "perf_broadphase": "benchmarks.perf_broadphase",
    "perf_contact": "benchmarks.perf_contact",
    "perf_fem": "benchmarks.perf_fem",
    "perf_mpm": "benchmarks.perf_mpm",
    "rings": "benchmarks.rings",
    "sine_boundary": "benchmarks.sine_boundary",
    "slope": "benchmarks.slope",
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    parser.add_argument("name", choices=sorted(BENCHMARKS))
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_const", const="quick", dest="mode")
    mode.add_argument("--full", action="store_const", const="full", dest="mode")
    parser.add_argument("--out", default="results", help="output folder (default results/)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    module = importlib.import_module(BENCHMARKS[args.name])
    summary = module.run(args.mode or "full", args.out)
    print(f"{args.name}: wrote {summary['json']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
