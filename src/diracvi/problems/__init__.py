"""Canonical systems: the paper's examples and more, shared by tests, docs, benchmarks
and the command line.

    from diracvi import problems
    prob = problems.get("spring-chain")
    traj = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps)
"""

from __future__ import annotations

from collections.abc import Callable

from ..errors import ModelError
from ._problem import Problem
from .andrews import andrews
from .chaplygin_sleigh import chaplygin_sleigh
from .circuits import build_rlc, lc_circuit, rlc_circuit, rlc_torn
from .dc_motor import dc_motor, dc_motor_driven
from .double_pendulum import double_pendulum_torn
from .driven import (
    forced_linear_solution,
    forced_oscillator,
    rlc_ladder,
    rlc_ladder_state,
    rlc_sine,
    rlc_sine_current,
    rlc_sine_torn,
)
from .linkages import FourBar, cart_pendulum_torn, cartesian_pendulum, four_bar
from .oscillator import damped_oscillator
from .rigid_bodies import free_rigid_body, heavy_top, spatial_double_pendulum
from .rolling_disk import rolling_disk
from .slider_crank import slider_crank
from .spherical_pendulum import spherical_pendulum
from .spring_chain import chain_torn, spring_chain, spring_chain_torn

#: name → factory (called with no arguments gives the source's parameters)
REGISTRY: dict[str, Callable[[], Problem]] = {
    "spring-chain": spring_chain,
    "rlc": rlc_circuit,
    "lc": lc_circuit,
    "damped-oscillator": damped_oscillator,
    "rolling-disk": rolling_disk,
    "spring-chain-torn": spring_chain_torn,
    "rlc-torn": rlc_torn,
    "chain-torn": chain_torn,
    "double-pendulum-torn": double_pendulum_torn,
    "dc-motor": dc_motor,
    "forced-oscillator": forced_oscillator,
    "rlc-sine": rlc_sine,
    "rlc-sine-torn": rlc_sine_torn,
    "rlc-ladder": rlc_ladder,
    "dc-motor-driven": dc_motor_driven,
    "cartesian-pendulum": cartesian_pendulum,
    "four-bar": four_bar,
    "cart-pendulum-torn": cart_pendulum_torn,
    "chaplygin-sleigh": chaplygin_sleigh,
    "spherical-pendulum": spherical_pendulum,
    "andrews": andrews,
    "slider-crank": slider_crank,
}
"""Name → factory of every built-in problem; ``factory()`` gives the source's parameters.

``diracvi list`` shows these names and ``diracvi run NAME`` runs one; ``get(name)`` looks a
name up (``ModelError`` for an unknown one).
"""


def available() -> dict[str, str]:
    """``{name: one-line description}`` of every built-in problem (each factory called once
    with its defaults; errors of a factory propagate)."""
    return {name: factory().description for name, factory in REGISTRY.items()}


def get(name: str) -> Problem:
    """The built-in problem ``name`` with its source's parameters.

    Raises:
        ModelError: ``name`` is not in [`REGISTRY`][diracvi.problems.REGISTRY] (the message
            lists the known names).
    """
    try:
        factory = REGISTRY[name]
    except KeyError:
        raise ModelError(
            f"problem={name!r} is unknown; built-in problems are {sorted(REGISTRY)}."
        ) from None
    return factory()


__all__ = [
    "REGISTRY",
    "FourBar",
    "Problem",
    "andrews",
    "available",
    "build_rlc",
    "cart_pendulum_torn",
    "cartesian_pendulum",
    "chain_torn",
    "chaplygin_sleigh",
    "damped_oscillator",
    "dc_motor",
    "dc_motor_driven",
    "double_pendulum_torn",
    "forced_linear_solution",
    "forced_oscillator",
    "four_bar",
    "free_rigid_body",
    "get",
    "heavy_top",
    "lc_circuit",
    "rlc_circuit",
    "rlc_ladder",
    "rlc_ladder_state",
    "rlc_sine",
    "rlc_sine_current",
    "rlc_sine_torn",
    "rlc_torn",
    "rolling_disk",
    "slider_crank",
    "spatial_double_pendulum",
    "spherical_pendulum",
    "spring_chain",
    "spring_chain_torn",
]
