"""Cross-thread round-off of the regression references (how bfemp.regress's tolerances were chosen).

Run twice with different thread counts, then compare::

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python tools/regress_drift.py run A
    NUMBA_NUM_THREADS=2 OMP_NUM_THREADS=2 OPENBLAS_NUM_THREADS=2 python tools/regress_drift.py run B
    python tools/regress_drift.py compare A B

``run`` writes ``OUT/NAME.npz`` per reference of ``references/``; ``compare`` prints, per reference
and quantity, the largest deviation relative to the quantity's scale (``max |stored|``).
"""

import sys
from pathlib import Path

import numpy as np

from bfemp import regress


def main() -> None:
    cmd, *dirs = sys.argv[1:]
    refs = regress.find_references("references")
    if cmd == "run":
        out = Path(dirs[0])
        out.mkdir(parents=True, exist_ok=True)
        for ref in refs:
            traj = regress.run_reference(ref)
            np.savez(out / f"{ref.name}.npz", **traj.data)
        return
    a, b = (Path(d) for d in dirs)
    for ref in refs:
        za, zb = np.load(a / f"{ref.name}.npz"), np.load(b / f"{ref.name}.npz")
        worst = []
        for q in za.files:
            x, y = za[q], zb[q]
            fin = np.isfinite(y)
            scale = float(np.max(np.abs(y[fin]), initial=0.0)) or 1.0
            both_nan = np.isnan(x) & np.isnan(y)
            dev = float(np.max(np.where(both_nan, 0.0, np.abs(x - y)), initial=0.0))
            worst.append((dev / scale, q, dev))
        worst.sort(reverse=True)
        print(ref.name, " ".join(f"{q}={r:.1e}" for r, q, _ in worst[:4]))


if __name__ == "__main__":
    main()
