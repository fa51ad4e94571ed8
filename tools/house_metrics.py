"""Size and shape of the house: lines per package, big files, long functions, import circles.

Run from the repository root: ``python tools/house_metrics.py``. The rules and their checks live
in ``tests/test_layering.py`` (which asserts them for the library); this prints the numbers.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.test_layering import (  # noqa: E402  (after the path set-up)
    LIBRARY,
    MAX_FILE_LINES,
    MAX_FUNCTION_LINES,
    PACKAGES,
    _find_cycle,
    _import_graph,
    long_functions,
)


def main() -> None:
    print("lines per package (all .py files):")
    for package in PACKAGES:
        files = sorted((ROOT / package).rglob("*.py"))
        total = sum(len(p.read_text().splitlines()) for p in files)
        print(f"  {package:<12} {total:>7} lines in {len(files)} files")
    library = sorted(p for package in LIBRARY for p in (ROOT / package).rglob("*.py"))
    big = [(p, len(p.read_text().splitlines())) for p in library]
    big = sorted(((p, n) for p, n in big if n > MAX_FILE_LINES), key=lambda t: -t[1])
    print(f"library files over {MAX_FILE_LINES} lines: {len(big)}")
    for p, n in big:
        print(f"  {n:>5}  {p.relative_to(ROOT)}")
    long = sorted(
        (
            (n, f"{p.relative_to(ROOT)}:{line} {name}")
            for p in library
            for name, line, n in long_functions(p)
        ),
        reverse=True,
    )
    print(f"library functions over {MAX_FUNCTION_LINES} lines (numba kernels skipped): {len(long)}")
    for n, where in long:
        print(f"  {n:>5}  {where}")
    graph = _import_graph(ROOT, PACKAGES)
    cycle = _find_cycle(graph)
    print("import circles: " + (" -> ".join(cycle) if cycle else "none"))


if __name__ == "__main__":
    main()
