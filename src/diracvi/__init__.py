"""diracvi: interconnected Lagrange–Dirac systems and discrete Dirac variational integrators.

import diracvi as dv
L = lambda q, v: 0.5 * v @ v - 0.5 * q @ q
system = dv.LagrangeDiracSystem(coords=("x",), lagrangian=L)
traj = dv.simulate(system, [1.0], [0.0], dt=0.01, steps=1000)
"""

import importlib
import importlib.util
from typing import TYPE_CHECKING

from .errors import DiracviError, ModelError, StepFailure, UnsolvableStepError
from .runtime import cache as _cache
from .runtime import config as _config  # noqa: F401  (float64 on)
from .runtime import dispatch as _dispatch  # noqa: F401  (CPU dispatch on the caller)
from .runtime import small_loops as _small_loops  # noqa: F401  (small loops: one kernel)
from .runtime import typed_ffi as _typed_ffi

_typed_ffi.install()  # LAPACK calls as typed FFI: one-CPU processes compile them (XLA bug)
_cache.enable()  # the on-disk compilation cache (DIRACVI_CACHE_DIR; "" switches it off)

__version__ = "0.1.0"

#: public name -> (module, its name there), imported at the first use of the name: so
#: ``import diracvi`` costs JAX and little more, and a netlist run (``diracvi run
#: deck.cir``) imports neither the sweeps, the Dirac structures nor the ensembles
_PUBLIC = {
    "dirac": ("dirac", None),  # the Dirac-structure subpackage: dv.dirac.…
    "Lobatto": ("discretization.rules", "Lobatto"),
    "Midpoint": ("discretization.rules", "Midpoint"),
    "QuadratureRule": ("discretization.rules", "QuadratureRule"),
    "Retraction": ("discretization.rules", "Retraction"),
    "Ensemble": ("driver.ensemble", "Ensemble"),
    "simulate_ensemble": ("driver.ensemble", "simulate_ensemble"),
    "momenta": ("driver.simulate", "momenta"),
    "simulate": ("driver.simulate", "simulate"),
    "Trajectory": ("driver.trajectory", "Trajectory"),
    "load": ("driver.trajectory", "load"),
    "InconsistentInitialDataWarning": ("model.consistency", "InconsistentInitialDataWarning"),
    "project_initial_state": ("model.consistency", "project"),
    "Connection": ("model.interaction", "Connection"),
    "Interaction": ("model.interaction", "Interaction"),
    "connect": ("model.interaction", "connect"),
    "InterconnectedSystem": ("model.interconnect", "InterconnectedSystem"),
    "interconnect": ("model.interconnect", "interconnect"),
    "DiracSystem": ("model.system", "DiracSystem"),
    "LagrangeDiracSystem": ("model.system", "LagrangeDiracSystem"),
    "AffineSolver": ("solvers", "AffineSolver"),
    "NewtonSolver": ("solvers", "NewtonSolver"),
    "PartitionedSolver": ("solvers", "PartitionedSolver"),
    "SolveStatus": ("solvers", "SolveStatus"),
    "StepSolver": ("solvers", "StepSolver"),
    "sweep": ("sweeps.run", "sweep"),
}


if TYPE_CHECKING:  # the same names as type checkers and the API docs (griffe) read them
    from . import dirac as dirac
    from .discretization.rules import Lobatto, Midpoint, QuadratureRule, Retraction
    from .driver.ensemble import Ensemble, simulate_ensemble
    from .driver.simulate import momenta, simulate
    from .driver.trajectory import Trajectory, load
    from .model.consistency import InconsistentInitialDataWarning
    from .model.consistency import project as project_initial_state
    from .model.interaction import Connection, Interaction, connect
    from .model.interconnect import InterconnectedSystem, interconnect
    from .model.system import DiracSystem, LagrangeDiracSystem
    from .solvers import AffineSolver, NewtonSolver, PartitionedSolver, SolveStatus, StepSolver
    from .sweeps.run import sweep


def __getattr__(name: str):
    """A public name (or a subpackage: ``dv.problems``), imported at its first use."""
    if name in _PUBLIC:
        where, attribute = _PUBLIC[name]
        module = importlib.import_module(f"{__name__}.{where}")
        value = module if attribute is None else getattr(module, attribute)
    elif not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}"):
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_PUBLIC})


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
