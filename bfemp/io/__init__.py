"""Run output: VTK frames with PVD time series (:mod:`bfemp.io.vtk`), the metrics table
(:mod:`bfemp.io.metrics`), pictures of the bodies (:mod:`bfemp.io.snapshots`), what a run folder
holds (:mod:`bfemp.io.outputs`) and reading it back (:mod:`bfemp.io.readback`; a whole run:
:func:`bfemp.runs.load_run`)."""

from bfemp.io.metrics import MetricsLog
from bfemp.io.readback import read_frames, read_metrics
from bfemp.io.vtk import Block, FrameWriter, atomic_path, read_pvd

__all__ = [
    "Block",
    "FrameWriter",
    "MetricsLog",
    "atomic_path",
    "read_frames",
    "read_metrics",
    "read_pvd",
]
