"""``python -m benchmarks NAME [--quick | --full] [--out DIR]``: run one benchmark.

A benchmark module may add options of its own: ``add_arguments(parser)`` extends the parser and
``main_from_args(args) -> int`` then runs it instead of ``run`` (``tradeoff``: ``--scenes``,
``--knobs``, ``--workers``, ``--scheduler``, ``--replay``, ...). Its ``ValueError`` is printed
as a usage error (exit status 2).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

#: benchmark name -> module in this package exposing ``run(mode: str, out: Path) -> dict``.
BENCHMARKS = {
    "augury_blocks": "benchmarks.augury_blocks",
    "augury_gap": "benchmarks.augury_gap",
    "augury_probes": "benchmarks.augury_probes",
    "augury_ramp": "benchmarks.augury_ramp",
    "augury_scenes": "benchmarks.augury_scenes",
    "blas_wall": "benchmarks.blas_wall",
    "explicit_speed": "benchmarks.explicit_speed",
    "buckling": "benchmarks.buckling",
    "ccd_oracle": "benchmarks.ccd_oracle",
    "conformance": "benchmarks.conformance",
    "extremes": "benchmarks.extremes",
    "fuzz": "benchmarks.fuzz",
    "hertz": "benchmarks.hertz",
    "lr_compression": "benchmarks.lr_compression",
    "lr_contact_time": "benchmarks.lr_contact_time",
    "lr_ellipses": "benchmarks.lr_ellipses",
    "lr_scenes": "benchmarks.lr_scenes",
    "lr_variants": "benchmarks.lr_variants",
    "perf_broadphase": "benchmarks.perf_broadphase",
    "perf_contact": "benchmarks.perf_contact",
    "perf_explicit": "benchmarks.perf_explicit",
    "perf_fem": "benchmarks.perf_fem",
    "perf_mpm": "benchmarks.perf_mpm",
    "perf_3d": "benchmarks.perf_3d",
    "perf_threads": "benchmarks.perf_threads",
    "refinement": "benchmarks.refinement",
    "rings": "benchmarks.rings",
    "sine_boundary": "benchmarks.sine_boundary",
    "slope": "benchmarks.slope",
    "speed_knobs": "benchmarks.speed_knobs",
    "tradeoff": "benchmarks.tradeoff",
    "twist": "benchmarks.twist",
    "two_stage_gap": "benchmarks.two_stage_gap",
    "two_stage_rings": "benchmarks.two_stage_rings",
    "two_stage_slope": "benchmarks.two_stage_slope",
}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    parser.add_argument("name", choices=sorted(BENCHMARKS))
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_const", const="quick", dest="mode")
    mode.add_argument("--full", action="store_const", const="full", dest="mode")
    mode.add_argument(
        "--mode",
        dest="mode",
        help="another mode of the benchmark (rings: partial; hertz: refined; "
        "buckling: partial, plate_quick, plate_partial, plate_full; "
        "twist: partial, partial_probe, full_probe)",
    )
    parser.add_argument("--out", default="results", help="output folder (default results/)")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = _parser()
    # first pass: only the name, to add the options of the chosen benchmark (--help included)
    first = argparse.ArgumentParser(add_help=False)
    first.add_argument("name", nargs="?")
    name = first.parse_known_args(argv)[0].name
    module = importlib.import_module(BENCHMARKS[name]) if name in BENCHMARKS else None
    if module is not None and hasattr(module, "add_arguments"):
        module.add_arguments(parser)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if hasattr(module, "main_from_args"):
        try:
            return module.main_from_args(args)
        except ValueError as err:
            parser.error(str(err))
    try:
        summary = module.run(args.mode or "full", args.out)
    except ValueError as err:  # a mode the benchmark does not have, named by it
        parser.error(f"{args.name}: {err}")
    print(f"{args.name}: wrote {summary['json']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
