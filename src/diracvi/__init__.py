"""diracvi: interconnected Lagrange–Dirac systems and discrete Dirac variational integrators.

import diracvi as dv
L = lambda q, v: 0.5 * v @ v - 0.5 * q @ q
system = dv.LagrangeDiracSystem(coords=("x",), lagrangian=L)
traj = dv.simulate(system, [1.0], [0.0], dt=0.01, steps=1000)
"""

from . import _cache, _config, _dispatch  # noqa: F401  (float64 on; CPU dispatch on the caller)
from . import dirac as dirac  # the Dirac-structure subpackage: dv.dirac.…
from ._consistency import InconsistentInitialDataWarning
from ._consistency import project as project_initial_state
from ._discretize import Lobatto, Midpoint, QuadratureRule, Retraction
from ._ensemble import Ensemble, simulate_ensemble
from ._errors import DiracviError, ModelError, StepFailure, UnsolvableStepError
from ._interconnect import Connection, Interaction, InterconnectedSystem, connect, interconnect
from ._simulate import momenta, simulate
from ._solvers import AffineSolver, NewtonSolver, PartitionedSolver, SolveStatus, StepSolver
from ._sweep import sweep
from ._system import DiracSystem, LagrangeDiracSystem
from ._trajectory import Trajectory, load

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
