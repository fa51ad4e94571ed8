"""bfemp: coupled MPM-FEM simulation of elastic bodies in contact.

User code imports this package only::

    import bfemp
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    beam = scene.add_fem(bfemp.shapes.rectangle((0, 0), (4, 0.5), h=0.125),
                         material=bfemp.NeoHookean(E=5e7, nu=0.3, density=1000.0))
    sim = bfemp.Simulation(scene, integrator="newmark", dt=1e-2)
    sim.run(t_end=1.0, out="out/beam")
"""

import logging

# OMP_WAIT_POLICY=PASSIVE (unless set) is set by geometry and solvers (see their __init__),
# which the imports below load before any numba kernel runs
from bfemp import levelset, motion, sample, scenefile, shapes
from bfemp.errors import (
    BfempWarning,
    PlausibilityWarning,
    RunFolderError,
    SceneError,
    StepNoteWarning,
)
from bfemp.integrators import (
    BACKWARD_EULER,
    INTEGRATOR_NAMES,
    NEWMARK,
    NEWMARK_DAMPED,
    NEWMARK_IMPLICIT_CONTACT,
    SYMPLECTIC_EULER,
    ExplicitIntegrator,
    Integrator,
)
from bfemp.materials import BulkShearHyperelastic, LinearElastic, NeoHookean
from bfemp.model import FemBody, Model, MpmBody
from bfemp.runs import load_run
from bfemp.scene import Scene
from bfemp.simulation import Simulation
from bfemp.state import State
from bfemp.steppers import (
    STRATEGIES,
    AuguryOptions,
    BarrierOptions,
    ContactView,
    LROptions,
    SingleFieldOptions,
    StepError,
    StepperOptions,
    StepReport,
    TwoStageOptions,
    strategy_table,
)

# library convention: no log output unless the application configures logging; what the user
# must see is issued through Python's warnings as well (bfemp.BfempWarning, errors.warn_user)
logging.getLogger(__name__).addHandler(logging.NullHandler())

__version__ = "0.1.0"

__all__ = [
    "BACKWARD_EULER",
    "INTEGRATOR_NAMES",
    "NEWMARK",
    "NEWMARK_DAMPED",
    "NEWMARK_IMPLICIT_CONTACT",
    "STRATEGIES",
    "SYMPLECTIC_EULER",
    "AuguryOptions",
    "BarrierOptions",
    "BfempWarning",
    "BulkShearHyperelastic",
    "ContactView",
    "ExplicitIntegrator",
    "FemBody",
    "Integrator",
    "LROptions",
    "LinearElastic",
    "Model",
    "MpmBody",
    "NeoHookean",
    "PlausibilityWarning",
    "RunFolderError",
    "Scene",
    "SceneError",
    "Simulation",
    "SingleFieldOptions",
    "State",
    "StepError",
    "StepNoteWarning",
    "StepReport",
    "StepperOptions",
    "TwoStageOptions",
    "levelset",
    "load_run",
    "motion",
    "sample",
    "scenefile",
    "shapes",
    "strategy_table",
]
