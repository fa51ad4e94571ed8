"""Geometry only: meshes, shape generators, grids, distances, CCD, broad phase, sampling,
level sets.

Imports numpy, numba, meshio and python-fcl; never imports ``solvers`` or ``bfemp``.
"""

import os as _os

# numba's OpenMP threading layer (where ``solvers`` has not put it on TBB's pool: see
# solvers.numba_threads) spin-waits between parallel regions by default; on small
# machines that costs milliseconds per kernel call (measured: 8 ms vs 13 us for a 200-particle
# kernel on 2 cores). Passive waiting must be set before the OpenMP runtime starts.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
