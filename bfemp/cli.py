"""Command line: ``bfemp demo [--out DIR]``."""

from __future__ import annotations

import argparse
import logging
import sys

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bfemp`` console script; returns the exit status."""
    parser = argparse.ArgumentParser(prog="bfemp", description="Coupled MPM-FEM simulation")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the main demo and write its outputs")
    demo.add_argument("--out", default="results/demo", help="output folder (default results/demo)")
    demo.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if args.command == "demo":
        from bfemp.demo import run_demo

        try:
            summary = run_demo(args.out, progress=not args.quiet)
        except (ValueError, RuntimeError) as err:
            print(f"bfemp demo: error: {err}", file=sys.stderr)
            return 1
        outputs = summary["outputs"]
        print(
            f"demo finished: {summary['steps']} steps, "
            f"{summary['newton_iterations_total']} Newton iterations"
        )
        print(f"  ParaView frames: {outputs['frames']}")
        print(f"  metrics:         {outputs['metrics']}")
        print(f"  plots:           {', '.join(outputs['plots'])}")
        return 0
    return 2


if __name__ == "__main__":
    sys.exit(main())
