"""Run output: VTK frames with PVD time series (:mod:`bfemp.io.vtk`) and the metrics table
(:mod:`bfemp.io.metrics`); both take plain arrays and know no physics."""

from bfemp.io.metrics import MetricsLog
from bfemp.io.vtk import Block, FrameWriter, atomic_path, read_pvd

__all__ = ["Block", "FrameWriter", "MetricsLog", "atomic_path", "read_pvd"]
