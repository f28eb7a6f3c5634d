r"""Source waveforms ``u(t)`` with SPICE semantics (the ngspice manual, §4.1).

Each is an immutable callable of time, traceable by JAX; a number stands for
:class:`DC`. The defaults that SPICE takes from ``.tran`` (``TSTEP``, ``TSTOP``) are
explicit arguments here; :mod:`diracvi.spice` fills them in from the netlist.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError


def _num(where: str, arg: str, value, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, jax.core.Tracer):  # a differentiated amplitude: used unchecked
        return value
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{where}: {arg}={value!r} is not a number.") from None
    if not math.isfinite(x) or (positive and x <= 0.0) or (nonneg and x < 0.0):
        need = "positive" if positive else "non-negative" if nonneg else "finite"
        raise ModelError(f"{where}: {arg}={value!r} must be a {need} number.")
    return x


class Waveform(eqx.Module):
    """A source value ``u(t)`` (volts or amperes)."""

    def __call__(self, t):
        raise NotImplementedError

    def breakpoints(self, t_start: float, t_stop: float) -> tuple[float, ...]:
        """The times in ``[t_start, t_stop]`` where ``u`` or a derivative jumps (its
        corners), increasing: a variable-step run ends a step exactly on each, since a
        step across a corner loses the rule's order. None for a smooth waveform."""
        return ()


class DC(Waveform):
    """``u(t) = value``."""

    value: float = eqx.field(static=True)

    def __init__(self, value):
        self.value = _num("DC", "value", value)

    def __call__(self, t):
        return jnp.asarray(self.value, dtype=jnp.float64) + 0.0 * t


class Sine(Waveform):
    r"""SPICE ``SIN(VO VA FREQ TD THETA PHASE)``.

    ``u = VO + VA sin(φ)`` for ``t ≤ TD``, else
    ``u = VO + VA e^{−θ (t−TD)} sin(2π f (t − TD) + φ)``, ``φ = PHASE·π/180``
    (ngspice holds the phase's value before the delay).
    """

    offset: float = eqx.field(static=True)
    amplitude: float = eqx.field(static=True)
    frequency: float = eqx.field(static=True)
    delay: float = eqx.field(static=True)
    damping: float = eqx.field(static=True)
    phase: float = eqx.field(static=True)

    def __init__(self, offset, amplitude, frequency, delay=0.0, damping=0.0, phase=0.0):
        self.offset = _num("SIN", "VO", offset)
        self.amplitude = _num("SIN", "VA", amplitude)
        self.frequency = _num("SIN", "FREQ", frequency, nonneg=True)
        self.delay = _num("SIN", "TD", delay, nonneg=True)
        self.damping = _num("SIN", "THETA", damping)
        self.phase = _num("SIN", "PHASE", phase)

    def __call__(self, t):
        phi = self.phase * math.pi / 180.0
        s = jnp.maximum(t - self.delay, 0.0)
        wave = jnp.exp(-self.damping * s) * jnp.sin(2.0 * math.pi * self.frequency * s + phi)
        return self.offset + self.amplitude * wave

    def breakpoints(self, t_start, t_stop):
        # the delay's end: held value before it, the sine (or its slope) after
        return _within((self.delay,), t_start, t_stop) if self.delay > 0.0 else ()


class Pulse(Waveform):
    r"""SPICE ``PULSE(V1 V2 TD TR TF PW PER NP)``.

    With ``s = t − TD`` reduced modulo ``PER`` (after at most ``NP`` periods, if given):
    ``V1`` for ``s ≤ 0`` or ``s ≥ TR + PW + TF``; a linear rise over ``TR``; ``V2`` for
    ``TR ≤ s ≤ TR + PW``; a linear fall over ``TF``.
    """

    v1: float = eqx.field(static=True)
    v2: float = eqx.field(static=True)
    delay: float = eqx.field(static=True)
    rise: float = eqx.field(static=True)
    fall: float = eqx.field(static=True)
    width: float = eqx.field(static=True)
    period: float = eqx.field(static=True)
    count: int = eqx.field(static=True)

    def __init__(self, v1, v2, delay, rise, fall, width, period, count=0):
        self.v1, self.v2 = _num("PULSE", "V1", v1), _num("PULSE", "V2", v2)
        self.delay = _num("PULSE", "TD", delay, nonneg=True)
        self.rise = _num("PULSE", "TR", rise, positive=True)
        self.fall = _num("PULSE", "TF", fall, positive=True)
        self.width = _num("PULSE", "PW", width, nonneg=True)
        self.period = _num("PULSE", "PER", period, positive=True)
        self.count = int(_num("PULSE", "NP", count, nonneg=True))

    def __call__(self, t):
        s = t - self.delay
        cycles = jnp.floor(jnp.maximum(s, 0.0) / self.period)
        if self.count > 0:
            cycles = jnp.minimum(cycles, self.count - 1)
        s = s - cycles * self.period
        up = self.v1 + (self.v2 - self.v1) * s / self.rise
        down = self.v2 + (self.v1 - self.v2) * (s - self.rise - self.width) / self.fall
        top = self.rise + self.width
        value = jnp.where(s < self.rise, up, jnp.where(s <= top, self.v2, down))
        return jnp.where((s <= 0.0) | (s >= top + self.fall), self.v1, value)

    def breakpoints(self, t_start, t_stop):
        # the four corners of each period, TD + k·PER + (0, TR, TR+PW, TR+PW+TF), for
        # the periods that start before t_stop (at most NP of them when NP is given)
        corners = (0.0, self.rise, self.rise + self.width, self.rise + self.width + self.fall)
        first = max(0, math.floor((t_start - self.delay - corners[-1]) / self.period))
        last = math.floor((t_stop - self.delay) / self.period)
        if self.count > 0:
            last = min(last, self.count - 1)
        times = [self.delay + k * self.period + c for k in range(first, last + 1) for c in corners]
        return _within(times, t_start, t_stop)


class PWL(Waveform):
    """SPICE ``PWL(T1 V1 T2 V2 …)``: linear between the points, constant outside."""

    times: tuple[float, ...] = eqx.field(static=True)
    values: tuple[float, ...] = eqx.field(static=True)

    def __init__(self, times, values):
        ts = tuple(_num("PWL", f"T{i + 1}", x) for i, x in enumerate(times))
        vs = tuple(_num("PWL", f"V{i + 1}", x) for i, x in enumerate(values))
        if len(ts) != len(vs) or len(ts) < 1:
            raise ModelError(
                f"PWL: got {len(ts)} times and {len(vs)} values; give pairs T1 V1 T2 V2 …"
            )
        if np.any(np.diff(ts) <= 0.0):
            raise ModelError(f"PWL: times {ts} must increase strictly.")
        self.times, self.values = ts, vs

    def __call__(self, t):
        return jnp.interp(t, jnp.asarray(self.times), jnp.asarray(self.values))

    def breakpoints(self, t_start, t_stop):
        return _within(self.times, t_start, t_stop)


def _within(times, t_start: float, t_stop: float) -> tuple[float, ...]:
    """``times`` inside ``[t_start, t_stop]``, sorted, each once."""
    return tuple(sorted({float(x) for x in times if t_start <= x <= t_stop}))


def as_waveform(value, where: str) -> Waveform:
    """A :class:`Waveform`, a number (→ :class:`DC`) or a callable ``u(t)``."""
    if isinstance(value, Waveform):
        return value
    if callable(value):
        return _Callable(value)
    try:
        return DC(value)
    except ModelError:
        raise ModelError(
            f"{where}: source value {value!r} is not a number, a waveform (DC, Sine, "
            "Pulse, PWL) or a function u(t)."
        ) from None


class _Callable(Waveform):
    fn: object = eqx.field(static=True)

    def __call__(self, t):
        return self.fn(t)
