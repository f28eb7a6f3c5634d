"""XSPICE's memoryless analog code models and ``d_dt`` (``spice/_xspice.py``): their laws at points
where the equations give exact values, transients and operating points of ngspice 39
across each model's range (limit's and pwl's smoothing regions, aswitch's laws in both
modes, divide's limited denominator on both sides, climit with an empty range, the
zener's three regions), every port type, and the refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice

#: one deck driving every model over its range: ``in`` ramps −3 → 3 V, ``b`` is a 2 V
#: sine, ``c`` a constant; ports of every type (``%v``, ``%vd``, ``%i``, ``%id``, ``%vnam``,
#: ``%gd``, vector ports of mixed types) and vector parameters
DECK = """xspice analog models against ngspice
vin in 0 pwl(0 -3 1m 3)
vb b 0 sin(0 2 2k)
vc c 0 dc -3.2
a1 in o1 g1
r1 o1 0 1k
a2 %vd(in c) %id(o2 0) g2
r2 o2 0 1k
a3 [in b %vd(c in)] o3 s1
r3 o3 0 1k
a4 [in b] o4 m1
r4 o4 0 1k
a5 b in o5 d1
r5 o5 0 1k
a6 in o6 l1
r6 o6 0 1k
a7 in o7 l2
r7 o7 0 1k
a8 in b c o8 cl1
r8 o8 0 1k
a9 in o9 p1
r9 o9 0 1k
a10 in o10 p2
r10 o10 0 1k
vdd dd 0 5
a11 in (dd o11) sw1
r11 o11 0 1k
a12 in (dd o12) sw2
r12 o12 0 1k
rz dd2 z 100
vdd2 dd2 0 pwl(0 0 0.6m -8 1m 1.5)
a13 z 0 zz
vm in m 0
rm m 0 1k
a14 %vnam vm o14 g1
r14 o14 0 1k
a15 %i in2 %vd (o15 0) g1
vin2 in3 0 pwl(0 -3 1m 3)
rin2 in3 in2 1k
r15 o15 0 1k
.model g1 gain(gain=2 in_offset=0.1 out_offset=-0.3)
.model g2 gain(gain=1e-3)
.model s1 summer(in_gain=[1 -0.5 2] in_offset=[0 0.1 0] out_gain=0.7 out_offset=0.2)
.model m1 mult(in_gain=[1 0.5] in_offset=[0.1 0] out_gain=1.5)
.model d1 divide(num_gain=2 den_offset=3.3 den_gain=0.1 den_lower_limit=0.2 den_domain=0.05
+ out_offset=0.1)
.model l1 limit(gain=2 out_lower_limit=-2 out_upper_limit=3 limit_range=0.4)
.model l2 limit(gain=1 in_offset=0.5 out_lower_limit=-1 out_upper_limit=1 limit_range=0.2
+ fraction=TRUE)
.model cl1 climit(gain=1 upper_delta=0.1 lower_delta=0.2 limit_range=0.3)
.model p1 pwl(x_array=[-2 -1 0 1 2] y_array=[1 0 0.5 2 1] input_domain=0.2)
.model p2 pwl(x_array=[-2 -1 0 1.5 2] y_array=[1 0 0.5 2 1] input_domain=0.1 fraction=FALSE
+ limit=TRUE)
.model sw1 aswitch(cntl_off=-1 cntl_on=2 r_on=10 r_off=1e6 log=TRUE)
.model sw2 aswitch(cntl_off=-1 cntl_on=2 r_on=10 r_off=1e4 log=FALSE limit=TRUE)
.model zz zener(v_breakdown=5 i_breakdown=1e-3 r_breakdown=10)
.tran 1u 1m
.end
"""

PROBES = [f"v(o{k})" for k in range(1, 16) if k != 13] + ["v(z)"]
#: the agreement asked of each signal on the TSTEP grid, of its peak (else 1e-4). The
#: midpoint rule evaluates a law at the step's mean input, O(h²) off at a smooth point and
#: O(h) at a kink: measured 2.5e-5 at most (pwl p2, then the zener 2.1e-5, climit 1.5e-5),
#: the linear gain to round-off, and 4.0e-4 for sw2 (the linear aswitch clipped at r_on,
#: a corner of 16 V/V in V(o12))
TOL = {"v(o12)": 1e-3}


@pytest.fixture(scope="module")
def runs():
    result = spice.run(DECK)
    t, ref = ng.ngspice(DECK, PROBES, tmax=1e-3 / 200000)
    return result, t, ref


@pytest.mark.slow  # ~30 s CPU: a transient of ~20 instances and a 5 ns ngspice run
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_transient_agrees_with_ngspice(runs):
    """Each output against ngspice 39 (reltol 1e-7, 5 ns steps) on diracvi's TSTEP grid.
    A wrong term moves a signal by far more than its tolerance: limit without its
    parabolas is off by d/4 = 0.1 V (3e-2 of peak), pwl's by up to 0.05."""
    result, t, ref = runs
    for p in PROBES:
        want = np.interp(result.time, t, ref[p])
        peak = np.max(np.abs(ref[p]))
        err = np.max(np.abs(result[p] - want)) / peak
        assert err <= TOL.get(p, 1e-4), (p, err)


@pytest.mark.slow  # ~30 s CPU: a transient of ~20 instances and a 5 ns ngspice run
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_the_deck_visits_every_region(runs):
    """The reference reaches both hard limits of limit, climit's both limits, pwl's
    flat ends (limit=TRUE) and the zener's breakdown (a check on the deck, so that the
    agreement above covers the smoothing regions and the clipped ones). To 1e-6 V: ngspice
    ends its Newton within reltol 1e-7 of a node (3.0000000022 V for the 3 V limit)."""
    _, _, ref = runs
    assert ref["v(o6)"].min() == pytest.approx(-2, abs=1e-6)
    assert ref["v(o6)"].max() == pytest.approx(3, abs=1e-6)
    assert ref["v(o7)"].min() == pytest.approx(-1, abs=1e-6)
    assert ref["v(o7)"].max() == pytest.approx(1, abs=1e-6)
    # p2's corner at x = −1 (slopes −1, then 0.5; d = 0.1) lifts its minimum from the
    # knot's y = 0 to the parabola's: −u + 1.5 (u + 0.1)²/0.4 least at u = 1/30, 1/30
    assert ref["v(o10)"].min() == pytest.approx(1 / 30, abs=1e-6)
    assert ref["v(o10)"][0] == pytest.approx(1, abs=1e-6)  # flat below x = −2
    assert ref["v(o12)"].max() == pytest.approx(5 * 1e3 / 1010, rel=1e-9)  # r_on
    assert ref["v(z)"].min() < -5.0  # past the breakdown
    lo = -3.2 + 0.2  # climit's lower limit, met by in = −3 at t = 0: its corner's centre
    assert ref["v(o8)"].min() == pytest.approx(lo + 0.3 / 4, abs=1e-6)


DDT_DECK = """d_dt against ngspice
v1 1 0 sin(0 1 1k)
a1 1 2 dd
r2 2 0 1k
vd 3 4 sin(0.2 0.5 2k)
r4 4 0 1k
a2 %vd(3 4) %id(5 0) dd2
r5 5 0 1k
.model dd d_dt(gain=1e-3 out_offset=0.5 out_lower_limit=-4 out_upper_limit=5 limit_range=0.5)
.model dd2 d_dt(gain=1e-4 out_lower_limit=-10 out_upper_limit=10)
.tran 1u 2m
.end
"""


@pytest.mark.slow  # ~30 s CPU: a transient of ~20 instances and a 5 ns ngspice run
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_d_dt_agrees_with_ngspice():
    """``d_dt`` through both of its smoothed limits (v(2): 0.5 + 6.28 cos, clipped to
    [−4, 5] over ±0.5) and a differential input into a current output (v(5)), against
    ngspice at 5 ns steps (its backward difference is then 3e-5 off the derivative):
    measured 1.4e-4 and 1.7e-4 of peak (the hard clip without the parabolas: 2.5e-2).
    From the first step on: at t = 0 ngspice's d_dt outputs 0, not its out_offset, where
    diracvi's operating point holds ``out_offset`` (d/dt = 0)."""
    result = spice.run(DDT_DECK)
    t, ref = ng.ngspice(DDT_DECK, ["v(2)", "v(5)"], tmax=2e-3 / 400000)
    for p in ("v(2)", "v(5)"):
        want = np.interp(result.time, t, ref[p])
        err = np.max(np.abs(result[p] - want)[1:]) / np.max(np.abs(ref[p]))
        assert err <= 5e-4, (p, err)
    assert ref["v(2)"].min() == pytest.approx(-4, abs=1e-9)
    assert ref["v(2)"].max() == pytest.approx(5, abs=1e-9)
    assert result["v(2)"][0] == pytest.approx(0.5, abs=1e-12)


INT_DECK = """int against ngspice
v1 1 0 sin(0.2 1 3)
a1 1 2 ia
r2 2 0 1k
v3 3 4 pwl(0 0 1 -2)
v4 4 0 0.5
a2 %vd(3 4) %vd(5 6) ib
r5 5 6 1k
r6 6 0 1k
.model ia int(in_offset=0.3 gain=2.5 out_lower_limit=-100 out_upper_limit=100 out_ic=0.7)
.model ib int(gain=-1.5 out_lower_limit=-10 out_upper_limit=10 limit_range=0.1 out_ic=-0.4)
.tran 1m 1
.end
"""


@pytest.mark.slow  # ~15 s CPU
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_int_is_the_integral_and_agrees_with_ngspice():
    """``int`` is ``out_ic + gain·∫(x + in_offset)``: v(2) = 0.7 + 2.5·(0.5 t + (1 − cos 6πt)
    /6π) from a %v input, v(5, 6) = −0.4 − 1.5·(−t²) from a %vd input into a %vd output
    (limits not reached), against the closed forms and ngspice at 10 µs steps. A gain,
    offset or out_ic off by 1 % moves v(2) by ≥ 7e-3 (3e-3 of its peak)."""
    result = spice.run(INT_DECK)
    t = result.time
    exact = {
        "v(2)": 0.7 + 2.5 * (0.5 * t + (1 - np.cos(6 * np.pi * t)) / (6 * np.pi)),
        "v(5,6)": -0.4 + 1.5 * t**2,
    }
    got = {"v(2)": result["v(2)"], "v(5,6)": result["v(5)"] - result["v(6)"]}
    tt, ref = ng.ngspice(INT_DECK, ["v(2)", "v(5)", "v(6)"], tmax=1e-5)
    ref["v(5,6)"] = ref["v(5)"] - ref["v(6)"]
    for p, want in exact.items():
        peak = np.max(np.abs(want))
        assert np.max(np.abs(got[p] - want)) <= 1e-5 * peak, p
        assert np.max(np.abs(got[p] - np.interp(t, tt, ref[p]))) <= 2e-5 * peak, p
    assert got["v(2)"][0] == pytest.approx(0.7, abs=1e-12)
    assert ref["v(2)"][0] == pytest.approx(0.7, abs=1e-12)


# ----------------------------------------------------------------- exact values of laws
@pytest.mark.parametrize(
    ("model", "x", "want"),
    [
        # limit at its corner centres: L + d/4 and U − d/4; hard beyond ±d
        ("limit(out_lower_limit=-1 out_upper_limit=2 limit_range=0.2)", -1.0, -1.0 + 0.05),
        ("limit(out_lower_limit=-1 out_upper_limit=2 limit_range=0.2)", 2.0, 2.0 - 0.05),
        ("limit(out_lower_limit=-1 out_upper_limit=2 limit_range=0.2)", -1.2, -1.0),
        ("limit(out_lower_limit=-1 out_upper_limit=2 limit_range=0.2)", 1.8, 1.8),
        # pwl at an interior knot: y_i + (s₊ − s₋)·d/4 with d = 0.1·1
        ("pwl(x_array=[0 1 2] y_array=[0 1 3] input_domain=0.1)", 1.0, 1.0 + 0.1 / 4),
        # beyond the end: the end segment's line continues (limit=FALSE)
        ("pwl(x_array=[0 1 2] y_array=[0 1 3] input_domain=0.1)", 5.0, 3.0 + 3 * 2.0),
        ("pwl(x_array=[0 1 2] y_array=[0 1 3] input_domain=0.1 limit=TRUE)", 5.0, 3.0),
        ("gain(gain=3 in_offset=0.5 out_offset=-1)", 2.0, -1 + 3 * 2.5),
    ],
)
def test_laws_at_exact_points(model, x, want):
    import jax.numpy as jnp

    from diracvi.spice._magnetic import _PARAM
    from diracvi.spice._xspice import MODELS, _law

    kind = model.split("(")[0]
    params = dict(MODELS[kind].params, given=set())
    for k, v in _PARAM.findall(model[len(kind) :]):
        if v.startswith("["):
            params[k] = tuple(float(t) for t in v.strip("[]").split())
        elif v in ("TRUE", "FALSE"):
            params[k] = v == "TRUE"
        else:
            params[k] = float(v)
    got = float(_law(kind, params, None, "a1")([jnp.float64(x)]))
    assert got == pytest.approx(want, rel=1e-14, abs=1e-15)


def test_aswitch_resistance_laws():
    """log: ``r`` is the geometric mean of r_on and r_off half-way, r_on at cntl_on and
    below r_on beyond it (no limit by default); linear: the arithmetic mean, clipped with
    limit=TRUE."""
    import jax.numpy as jnp

    from diracvi.spice._xspice import MODELS, _law

    def r(x, **kw):
        p = dict(MODELS["aswitch"].params, given=set(), **kw)
        return 1.0 / float(_law("aswitch", p, None, "a1")([jnp.float64(x), jnp.float64(1.0)]))

    base = {"cntl_off": 0.0, "cntl_on": 1.0, "r_on": 10.0, "r_off": 1e6}
    assert r(0.5, **base) == pytest.approx(math.sqrt(1e7), rel=1e-13)
    assert r(1.0, **base) == pytest.approx(10.0, rel=1e-13)
    assert r(2.0, **base) == pytest.approx(10.0 / 1e5, rel=1e-12)
    assert r(40.0, **base) == pytest.approx(1e-9, rel=1e-12)  # ngspice's floor
    assert r(2.0, **base, limit=True) == pytest.approx(10.0, rel=1e-13)
    assert r(0.5, **base, log=False) == pytest.approx((10.0 + 1e6) / 2, rel=1e-13)
    assert r(-1.0, **base, log=False, limit=True) == pytest.approx(1e6, rel=1e-13)


# ------------------------------------------------------------ operating points vs ngspice
OP_DECK = """divide's two sides, climit's empty range, aswitch beyond cntl_on, zeners
vn n 0 1
{dens}
{divs}
vu u 0 0.1
vl l 0 0.5
vx x 0 0.3
acl x u l ocl cl
rcl ocl 0 1
vs s 0 2.5
vd d 0 1
asw s (d os) sw
ros os 0 1k
asw2 s (d os2) swf
ros2 os2 0 1k
{zeners}
.model dv divide(den_lower_limit=0.2 den_domain=0.05 out_gain=2)
.model cl climit(limit_range=0.1)
.model sw aswitch(cntl_off=0 cntl_on=1 r_on=100 r_off=1e6)
.model swf aswitch(cntl_off=0 cntl_on=0.1 r_on=100 r_off=1e6)
.model z3 zener(v_breakdown=5 i_breakdown=1e-3 r_breakdown=10)
.model z2 zener(v_breakdown=0.5 i_breakdown=2e-2 r_breakdown=1 n_forward=2)
.tran 1u 1m
.end
"""
DENS = (-0.3, -0.26, -0.22, -0.2, -0.18, -0.1, 0.1, 0.16, 0.2, 0.24, 0.3)
ZENER_V = (-8.0, -5.05, -4.9, -1.0, 0.2, 0.75)


def _op_deck():
    dens = "\n".join(f"vd{k} d{k} 0 {x}" for k, x in enumerate(DENS))
    divs = "\n".join(f"adv{k} n d{k} q{k} dv\nrq{k} q{k} 0 1" for k in range(len(DENS)))
    zeners = "\n".join(
        f"vz{k}{m} z{k}{m} 0 {v}\naz{k}{m} z{k}{m} 0 {m}"
        for k, v in enumerate(ZENER_V)
        for m in ("z3", "z2")
    )
    return OP_DECK.format(dens=dens, divs=divs, zeners=zeners)


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_operating_points_agree_with_ngspice():
    """ngspice's own values, to 1e-10: divide on both sides of its limited denominator
    (the negative side with ngspice's jumps at −L ± D), climit with U − L < 2d (its
    output 0), aswitch log-linear past cntl_on (r = r_on·e^{−1.5 ln 1e4} = 1e-4 Ω) and
    at ngspice's 1 nΩ floor, and both zener forms in each of their regions (the current
    of the source across each)."""
    deck = _op_deck()
    ref = ng.operating_point(deck)
    ours = spice.operating_point(deck)
    keys = [f"v(q{k})" for k in range(len(DENS))] + ["v(ocl)", "v(os)", "v(os2)"]
    keys += [f"i(vz{k}{m})" for k in range(len(ZENER_V)) for m in ("z3", "z2")]
    for key in keys:
        want = ref[key]
        assert abs(ours[key] - want) <= 1e-10 * max(abs(want), 1e-9), (key, ours[key], want)
    # the jumps are there: δ(−0.26) = −0.26 but δ(−0.22) = −0.2 + 0.03²/0.2 = −0.1955
    assert ref["v(q1)"] == pytest.approx(2 / -0.26, rel=1e-9)
    assert ref["v(q2)"] == pytest.approx(2 / (-0.2 + 0.03**2 / 0.2), rel=1e-9)
    assert ref["v(ocl)"] == 0.0
    assert ref["v(os2)"] == pytest.approx(1e3 / (1e3 + 1e-9), rel=1e-12)


# ----------------------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    ("lines", "match"),
    [
        ("a1 a o g\n.model g gain(gain=2 bogus=1)", r"unknown parameters \['bogus'\]"),
        ("a1 a %v o s\n.model s aswitch(r_on=1)", r"'out' takes the types %gd, not %v"),
        ("a1 %h a o g\n.model g gain(gain=2)", r"'in' takes the types %v, %vd, %i, %id, %vnam"),
        ("a1 a o g\n.model g limit(out_lower_limit=0)", r"'out_upper_limit' is required"),
        ("a1 [a 0] o g\n.model g summer(in_gain=[1 2 3])", r"in_gain has 3 entries for 2 inputs"),
        ("a1 a o g\n.model g gain(gain=[1 2])", r"gain is a number, not a vector"),
        ("a1 a (o 0) g\n.model g aswitch(log=maybe)", r"log='maybe' must be TRUE or FALSE"),
        ("a1 a o g\n.model g hyst(in_low=0)", r"'hyst' .* a code model with state"),
        ("a1 a o g\n.model g int(gain=1)", r"'out_lower_limit' is required"),
        ("a1 %i a o g\n.model g int(out_lower_limit=-1 out_upper_limit=1)", r"%v, %vd, not %i"),
        (
            "a1 a o g\n.model g int(out_lower_limit=-1 out_upper_limit=1 limit_range=0.5 out_ic=1)",
            r"out_ic=1 is not inside .* \[-0.5, 0.5\]; move out_ic",
        ),
        ("a1 a o g\n.model g d_dt(gain=1)", r"'out_lower_limit' is required"),
        ("a1 a o g\n.model g d_inverter(rise_delay=1n)", r"'d_inverter' .* a digital model"),
        ("a1 a o x g\n.model g gain", r"1 extra field"),
    ],
)
def test_bad_lines_are_refused_naming_the_fix(lines, match):
    deck = f"t\nv1 a 0 1\nr1 o 0 1k\n{lines}\n.tran 1u 1m\n.end\n"
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(deck)
