"""diracvi: interconnected Lagrange–Dirac systems and discrete Dirac variational integrators.

import diracvi as dv
L = lambda q, v: 0.5 * v @ v - 0.5 * q @ q
system = dv.LagrangeDiracSystem(coords=("x",), lagrangian=L)
traj = dv.simulate(system, [1.0], [0.0], dt=0.01, steps=1000)
"""

# float64 on; CPU dispatch on the caller
from . import dirac as dirac  # the Dirac-structure subpackage: dv.dirac.…
from .discretization.rules import Lobatto, Midpoint, QuadratureRule, Retraction
from .driver.ensemble import Ensemble, simulate_ensemble
from .driver.simulate import momenta, simulate
from .driver.trajectory import Trajectory, load
from .errors import DiracviError, ModelError, StepFailure, UnsolvableStepError
from .model.consistency import InconsistentInitialDataWarning
from .model.consistency import project as project_initial_state
from .model.interaction import Connection, Interaction, connect
from .model.interconnect import InterconnectedSystem, interconnect
from .model.system import DiracSystem, LagrangeDiracSystem
from .runtime import cache as _cache
from .runtime import config as _config  # noqa: F401
from .runtime import dispatch as _dispatch  # noqa: F401
from .solvers import AffineSolver, NewtonSolver, PartitionedSolver, SolveStatus, StepSolver
from .sweeps.run import sweep

_cache.enable()  # the on-disk compilation cache (DIRACVI_CACHE_DIR; "" switches it off)

__version__ = "0.1.0"

__all__ = [
    "AffineSolver",
    "Connection",
    "DiracSystem",
    "DiracviError",
    "Ensemble",
    "InconsistentInitialDataWarning",
    "Interaction",
    "InterconnectedSystem",
    "LagrangeDiracSystem",
    "Lobatto",
    "Midpoint",
    "ModelError",
    "NewtonSolver",
    "PartitionedSolver",
    "QuadratureRule",
    "Retraction",
    "SolveStatus",
    "StepFailure",
    "StepSolver",
    "Trajectory",
    "UnsolvableStepError",
    "connect",
    "interconnect",
    "load",
    "momenta",
    "project_initial_state",
    "simulate",
    "simulate_ensemble",
    "sweep",
]
