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


def _data(x):
    """A waveform's number as data: a float64 array leaf (a compiled program takes it
    as an argument, so a source of another value reuses the program); a traced value
    stays the tracer it is."""
    return x if isinstance(x, jax.core.Tracer) else np.asarray(x, dtype=np.float64)


class Waveform(eqx.Module):
    """A source value ``u(t)`` (volts or amperes)."""

    def __call__(self, t):
        raise NotImplementedError

    def breakpoints(self, t_start: float, t_stop: float) -> tuple[float, ...]:
        """The times in ``[t_start, t_stop]`` where ``u`` or a derivative jumps (its
        corners), increasing: a variable-step run ends a step exactly on each, since a
        step across a corner loses the rule's order. None for a smooth waveform."""
        return ()

    def cycles(self, t_start: float, t_stop: float) -> float:
        """How many periods of the waveform's fastest instantaneous frequency fit in
        ``[t_start, t_stop]``, ``∫ f_max dt``: the pace a run must keep to follow it,
        whatever its TMAX (0 for a waveform that does not oscillate)."""
        return 0.0


class DC(Waveform):
    """``u(t) = value``."""

    value: object

    def __init__(self, value):
        self.value = _data(_num("DC", "value", value))

    def __call__(self, t):
        return jnp.asarray(self.value, dtype=jnp.float64) + 0.0 * t


class Sine(Waveform):
    r"""SPICE ``SIN(VO VA FREQ TD THETA PHASE)``.

    ``u = VO + VA sin(φ)`` for ``t ≤ TD``, else
    ``u = VO + VA e^{−θ (t−TD)} sin(2π f (t − TD) + φ)``, ``φ = PHASE·π/180``
    (ngspice holds the phase's value before the delay). ``TD`` may be negative, as in
    ngspice: the wave is then already running at ``t = 0``.
    """

    offset: object
    amplitude: object
    frequency: object
    delay: object
    damping: object
    phase: object

    def __init__(self, offset, amplitude, frequency, delay=0.0, damping=0.0, phase=0.0):
        self.offset = _data(_num("SIN", "VO", offset))
        self.amplitude = _data(_num("SIN", "VA", amplitude))
        self.frequency = _data(_num("SIN", "FREQ", frequency, nonneg=True))
        # a negative TD (ngspice accepts it) starts the sine before t = 0: a cosine is
        # SIN(0 A f −1/(4f))
        self.delay = _data(_num("SIN", "TD", delay))
        self.damping = _data(_num("SIN", "THETA", damping))
        self.phase = _data(_num("SIN", "PHASE", phase))

    def __call__(self, t):
        phi = self.phase * math.pi / 180.0
        s = jnp.maximum(t - self.delay, 0.0)
        wave = jnp.exp(-self.damping * s) * jnp.sin(2.0 * math.pi * self.frequency * s + phi)
        return self.offset + self.amplitude * wave

    def breakpoints(self, t_start, t_stop):
        # the delay's end: held value before it, the sine (or its slope) after
        return _within((self.delay,), t_start, t_stop) if self.delay > 0.0 else ()

    def cycles(self, t_start, t_stop):
        return _running(self.frequency, self.delay, t_start, t_stop)


class Pulse(Waveform):
    r"""SPICE ``PULSE(V1 V2 TD TR TF PW PER NP)``.

    With ``s = t − TD`` reduced modulo ``PER`` (after at most ``NP`` periods, if given):
    ``V1`` for ``s ≤ 0`` or ``s ≥ TR + PW + TF``; a linear rise over ``TR``; ``V2`` for
    ``TR ≤ s ≤ TR + PW``; a linear fall over ``TF``.
    """

    v1: object
    v2: object
    delay: object
    rise: object
    fall: object
    width: object
    period: object
    count: int = eqx.field(static=True)

    def __init__(self, v1, v2, delay, rise, fall, width, period, count=0):
        self.v1, self.v2 = _data(_num("PULSE", "V1", v1)), _data(_num("PULSE", "V2", v2))
        self.delay = _data(_num("PULSE", "TD", delay, nonneg=True))
        self.rise = _data(_num("PULSE", "TR", rise, positive=True))
        self.fall = _data(_num("PULSE", "TF", fall, positive=True))
        self.width = _data(_num("PULSE", "PW", width, nonneg=True))
        self.period = _data(_num("PULSE", "PER", period, positive=True))
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
    r"""SPICE ``PWL(T1 V1 T2 V2 …) [TD=td] [R=r]``: linear between the points, constant
    outside, shifted by ``TD``; with ``R``, the part from the point ``r`` to the last
    point ``Tn`` repeats for ever after ``Tn`` (period ``P = Tn − r``).

    With ``τ = t − TD``: ``u = V1`` for ``τ < T1``; the interpolant for ``τ ≤ Tn``; and,
    when ``R`` is given, for ``τ > Tn`` the interpolant at
    ``r + (τ − Tn) − (⌈(τ − Tn)/P⌉ − 1) P ∈ (r, Tn]``, so that each repeat ends on the
    last value and the jump back to ``u(r)`` is taken just after it (as ngspice does).
    """

    times: object
    values: object
    delay: object
    repeat: object

    def __init__(self, times, values, delay=0.0, repeat=None):
        ts = tuple(_num("PWL", f"T{i + 1}", x) for i, x in enumerate(times))
        vs = tuple(_num("PWL", f"V{i + 1}", x) for i, x in enumerate(values))
        if len(ts) != len(vs) or len(ts) < 1:
            raise ModelError(
                f"PWL: got {len(ts)} times and {len(vs)} values; give pairs T1 V1 T2 V2 …"
            )
        if np.any(np.diff(ts) <= 0.0):
            raise ModelError(f"PWL: times {ts} must increase strictly.")
        # arrays (data; their length is the structure): a traced value keeps them JAX's
        xp = jnp if any(isinstance(x, jax.core.Tracer) for x in (*ts, *vs)) else np
        self.times = xp.asarray(ts, dtype=np.float64)
        self.values = xp.asarray(vs, dtype=np.float64)
        self.delay = _data(_num("PWL", "TD", delay))
        if repeat is not None:
            repeat = _num("PWL", "R", repeat)
            if repeat not in ts[:-1]:
                raise ModelError(
                    f"PWL: R={repeat:g} must be one of the times before the last "
                    f"{ts[:-1]} (the repeat runs from that point to the last)."
                )
        self.repeat = None if repeat is None else _data(repeat)

    def __call__(self, t):
        tau = t - self.delay
        if self.repeat is not None:
            end = self.times[-1]
            period = end - self.repeat
            past = jnp.maximum(tau - end, 0.0)
            cycles = jnp.maximum(jnp.ceil(past / period) - 1.0, 0.0)
            tau = jnp.where(tau > end, self.repeat + past - cycles * period, tau)
        return jnp.interp(tau, jnp.asarray(self.times), jnp.asarray(self.values))

    def breakpoints(self, t_start, t_stop):
        times = [self.delay + x for x in self.times]
        if self.repeat is not None:
            # each repeat's points: TD + Tn + k·P + (Tj − r) for the points Tj ≥ r
            end = self.times[-1]
            period = end - self.repeat
            tail = [x - self.repeat for x in self.times if x > self.repeat]
            first = max(0, math.floor((t_start - self.delay - end) / period) - 1)
            last = math.floor((t_stop - self.delay - end) / period)
            times += [
                self.delay + end + k * period + d for k in range(first, last + 1) for d in tail
            ]
        return _within(times, t_start, t_stop)


class Exp(Waveform):
    r"""SPICE ``EXP(V1 V2 TD1 TAU1 TD2 TAU2)``: a rise towards ``V2`` from ``TD1``, a
    fall back towards ``V1`` from ``TD2``.

    ``u = V1`` for ``t ≤ TD1``; ``u = V1 + (V2 − V1)(1 − e^{−(t−TD1)/TAU1})`` up to
    ``TD2``; after it ``(V1 − V2)(1 − e^{−(t−TD2)/TAU2})`` is added. The corners are
    ``TD1`` and ``TD2`` (the slope jumps there).
    """

    v1: object
    v2: object
    delay_rise: object
    tau_rise: object
    delay_fall: object
    tau_fall: object

    def __init__(self, v1, v2, delay_rise, tau_rise, delay_fall, tau_fall):
        self.v1, self.v2 = _data(_num("EXP", "V1", v1)), _data(_num("EXP", "V2", v2))
        self.delay_rise = _data(_num("EXP", "TD1", delay_rise))
        self.tau_rise = _data(_num("EXP", "TAU1", tau_rise, positive=True))
        self.delay_fall = _data(_num("EXP", "TD2", delay_fall))
        self.tau_fall = _data(_num("EXP", "TAU2", tau_fall, positive=True))

    def __call__(self, t):
        span = self.v2 - self.v1
        # clamped arguments: the branch not taken stays finite (no inf·0 in a gradient)
        rise = -jnp.expm1(-jnp.maximum(t - self.delay_rise, 0.0) / self.tau_rise)
        fall = -jnp.expm1(-jnp.maximum(t - self.delay_fall, 0.0) / self.tau_fall)
        value = self.v1 + span * rise - span * fall
        return jnp.where(t <= self.delay_rise, self.v1 + 0.0 * t, value)

    def breakpoints(self, t_start, t_stop):
        return _within((self.delay_rise, self.delay_fall), t_start, t_stop)


class SFFM(Waveform):
    r"""SPICE ``SFFM(VO VA FC MDI FS PHASEC PHASES)``: a single-frequency FM wave,

    ``u = VO + VA sin(2π FC t + φ_c + MDI sin(2π FS t + φ_s))``, ``φ = PHASE·π/180``,

    as ngspice 39 (and SPICE3, PSpice's ``SFFM(VOFF VAMPL FC MOD FM)``) has it: no delay,
    smooth everywhere, so no breakpoints. ngspice ≥ 46 reads the sixth and seventh values
    as TD and PHASEM (and defaults FC = 5/TSTOP, MDI = 90, FS = 500/TSTOP, against 39's
    1/TSTOP, 0, 1/TSTOP): the reader notes it where a deck gives them.
    """

    offset: object
    amplitude: object
    carrier: object
    index: object
    signal: object
    carrier_phase: object
    signal_phase: object

    def __init__(
        self, offset, amplitude, carrier, index=0.0, signal=None, carrier_phase=0.0,
        signal_phase=0.0,
    ):  # fmt: skip
        self.offset = _data(_num("SFFM", "VO", offset))
        self.amplitude = _data(_num("SFFM", "VA", amplitude))
        self.carrier = _data(_num("SFFM", "FC", carrier, nonneg=True))
        self.index = _data(_num("SFFM", "MDI", index))
        self.signal = _data(_num("SFFM", "FS", carrier if signal is None else signal, nonneg=True))
        self.carrier_phase = _data(_num("SFFM", "PHASEC", carrier_phase))
        self.signal_phase = _data(_num("SFFM", "PHASES", signal_phase))

    def __call__(self, t):
        phi_c = self.carrier_phase * math.pi / 180.0
        phi_s = self.signal_phase * math.pi / 180.0
        modulation = self.index * jnp.sin(2.0 * math.pi * self.signal * t + phi_s)
        return self.offset + self.amplitude * jnp.sin(
            2.0 * math.pi * self.carrier * t + phi_c + modulation
        )

    def cycles(self, t_start, t_stop):
        # the phase's rate is 2π (FC + MDI·FS cos(2π FS t + φ_s)): at most FC + |MDI|·FS
        fastest = self.carrier + abs(self.index) * self.signal
        return _running(fastest, 0.0, t_start, t_stop)


class AM(Waveform):
    r"""ngspice 39's ``AM(VA VO MF FC TD PHASEC PHASES)``: an amplitude-modulated wave,

    ``u = VA (VO + sin(2π MF (t−TD) + φ_s)) sin(2π FC (t−TD) + φ_s)`` for ``t > TD``,
    ``u = 0`` up to ``TD``, ``φ_s = PHASES·π/180``,

    as ngspice 39's ``vsrcload.c``/``isrcload.c`` compute it: the signal's phase PHASES
    enters both sines, and the carrier's phase PHASEC is read but not used (checked
    against ngspice 39). ``TD`` is a corner (the wave starts there from 0 with a jump in
    its slope, or in its value when ``φ_s ≠ 0``). ngspice ≥ 46 reads the values
    differently (``AM(VO VMO VMA FM FC TD PHASEM PHASEC)``); the reader notes it.
    """

    amplitude: object
    offset: object
    signal: object
    carrier: object
    delay: object
    carrier_phase: object
    signal_phase: object

    def __init__(
        self, amplitude, offset, signal, carrier=0.0, delay=0.0, carrier_phase=0.0,
        signal_phase=0.0,
    ):  # fmt: skip
        self.amplitude = _data(_num("AM", "VA", amplitude))
        self.offset = _data(_num("AM", "VO", offset))
        self.signal = _data(_num("AM", "MF", signal, nonneg=True))
        self.carrier = _data(_num("AM", "FC", carrier, nonneg=True))
        self.delay = _data(_num("AM", "TD", delay))
        self.carrier_phase = _data(_num("AM", "PHASEC", carrier_phase))
        self.signal_phase = _data(_num("AM", "PHASES", signal_phase))

    def __call__(self, t):
        phi = self.signal_phase * math.pi / 180.0
        s = t - self.delay
        value = (
            self.amplitude
            * (self.offset + jnp.sin(2.0 * math.pi * self.signal * s + phi))
            * jnp.sin(2.0 * math.pi * self.carrier * s + phi)
        )
        return jnp.where(s <= 0.0, 0.0 * t, value)

    def breakpoints(self, t_start, t_stop):
        return _within((self.delay,), t_start, t_stop) if self.delay > 0.0 else ()

    def cycles(self, t_start, t_stop):
        # the product of the two sines holds the frequencies FC ± MF
        return _running(self.carrier + self.signal, self.delay, t_start, t_stop)


def _running(frequency, delay, t_start: float, t_stop: float) -> float:
    """``frequency ×`` the time of ``[t_start, t_stop]`` after ``delay`` (0 where either
    is traced: the count only sizes a run's budget of tries, it is not differentiated)."""
    if isinstance(frequency, jax.core.Tracer) or isinstance(delay, jax.core.Tracer):
        return 0.0
    return float(frequency) * max(0.0, t_stop - max(t_start, float(delay)))


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
            "Pulse, PWL, Exp, SFFM, AM) or a function u(t)."
        ) from None


class _Callable(Waveform):
    fn: object = eqx.field(static=True)

    def __call__(self, t):
        return self.fn(t)
