"""MOSFET parts of levels 1, 2, 3, 6 (and the VDMOS channel) are data: the part's
Lagrangian and force are ``equinox.Module``s of a static layout and one vector of numbers,
the level's law a :class:`~diracvi.components._mos_part.Law` of its own vector, so
devices that differ only in their numbers (every inverter of its own width) are one
function of different numbers — read once per kind, stacked into one group per kind —
where each device's closures used to be traced and printed (≈ 28 CPU ms a device).

What is checked: the number of traces while reading does not grow with the number of
distinct devices; the packed system has one group per polarity whatever the sizes; the
part's channel and Meyer lines equal, bit for bit, the ones the level's law computes as a
closure over Python floats (what the part was before), values and Jacobians; a traced
KP still reaches the force.

White-box: counts ``diracvi.runtime.program._lift`` and
``diracvi.model.system._user_function_uncached``, reads ``diracvi.driver.events``, and
calls ``diracvi.components._mos_part``'s helpers."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diracvi import components as cp
from diracvi import spice
from diracvi.components import _mos_part
from diracvi.driver import events
from diracvi.model import system as system_module
from diracvi.runtime import program
from test_read_alike import assert_same

CARDS = {
    1: ("level=1 vto=0.7 kp=1e-4 cbd=1f cgso=1e-10 tox=2e-8 gamma=0.4 lambda=0.02",
        "level=1 vto=-0.7 kp=5e-5 cbd=1f cgso=1e-10 tox=2e-8 rd=5"),
    2: ("level=2 vto=0.7 nsub=2e16 tox=2e-8 vmax=5e4 nfs=1e11 xj=0.3u cbd=2f",
        "level=2 vto=-0.7 nsub=2e16 tox=2e-8 lambda=0.01 rs=4"),
    3: ("level=3 vto=0.7 tox=2e-8 theta=0.1 nsub=1e16 xj=0.2u vmax=1e5 nfs=1e11 eta=0.1",
        "level=3 vto=-0.7 tox=2e-8 theta=0.1 kappa=0.3 delta=0.5 cbs=1f"),
    6: ("level=6 kc=3.9e-05 nc=1.17 kv=0.92 nv=0.87 lambda0=0.013 tox=3e-8 cbd=1f",
        "level=6 vto=-0.8 kc=2e-05 nc=1.2 kv=1.1 nv=0.8 tox=3e-8"),
}  # fmt: skip


def chain(level: int, n: int) -> str:
    """``n`` CMOS inverters of one card pair at ``level``, stage k of its own W and L."""
    nmos, pmos = CARDS[level]
    lines = [f"level-{level} chain of {n}", "vdd dd 0 3.3", "vin n0 0 pulse 0 3.3 1n 1n 1n 10n 20n"]
    for k in range(n):
        w, ell = 1.0 + 0.25 * k, 1.0 + 0.05 * k
        lines += [f"mn{k} n{k + 1} n{k} 0 0 nch w={w}u l={ell}u",
                  f"mp{k} n{k + 1} n{k} dd dd pch w={2 * w}u l={ell}u"]  # fmt: skip
    lines += [f"cl n{n} 0 10f", f".model nch nmos {nmos}", f".model pch pmos {pmos}"]
    return "\n".join([*lines, ".tran 0.1n 4n", ".end", ""])


def count_calls(monkeypatch, module, name: str) -> list:
    calls = []
    original = getattr(module, name)

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


@pytest.mark.parametrize("level", sorted(CARDS))
def test_distinct_devices_are_read_without_a_trace_each(monkeypatch, level):
    counts = []
    for n in (3, 7):  # (8 parts or more are packed)
        lifted = count_calls(monkeypatch, program, "_lift")
        forms = count_calls(monkeypatch, system_module, "_user_function_uncached")
        netlist = spice.read(chain(level, n))
        monkeypatch.undo()
        counts.append((len(lifted), len(forms)))
        # one group per polarity whatever the sizes
        packed = events.packed_unless_switched(netlist.system)
        assert packed.packed
        names = [s.name for s in netlist.system.subsystems]
        roles = [s.role for s in netlist.system.subsystems]
        groups = [[names[i] for i in m] for m in packed._packing.tables.members]
        transistors = sorted(g for g in groups if roles[names.index(g[0])] == "transistor")
        assert transistors == [[f"mn{k}" for k in range(n)], [f"mp{k}" for k in range(n)]]
    # the reads of 3 and of 7 distinct sizes trace and read forms alike: nothing per device
    # (a form is read per kind of part; the first read may read some for the first time)
    assert counts[1][0] <= counts[0][0] and counts[1][1] <= counts[0][1], counts


def _float_law(law: _mos_part.Law):
    """The level's law as the part held it before it was data: a closure over Python
    floats."""
    values = {k: float(x) for k, x in zip(law.names, np.asarray(law.numbers), strict=True)}
    return law.make(**values, **dict(law.flags))


def _force_module(part) -> _mos_part.MosForce:
    """The part's force as built (its wrapped function's arrays put back into the rest)."""
    wrapped = part._force
    return eqx.combine(wrapped.arrays, wrapped.rest)


def _equal(a, b, what):
    """Equal number for number (a zero's sign aside: the force adds into zeros)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and np.array_equal(a, b), what


@pytest.mark.parametrize("level", sorted(CARDS))
def test_the_module_computes_the_closure_over_floats_bit_for_bit(level):
    """The force's channel and Meyer lines against the shared helpers called with the
    law as a closure over Python floats (the part before it was data) at random
    voltages — both modes, cut-off, linear and saturated regions: values and Jacobians
    equal, number for number."""
    netlist = spice.read(chain(level, 2))
    rng = np.random.default_rng(level)
    parts = [p for p in netlist.circuit.parts if p.role == "transistor"]
    assert len(parts) == 4
    for part in parts:
        mod = _force_module(part)
        assert isinstance(mod, _mos_part.MosForce) and isinstance(mod.law, _mos_part.Law)
        lay = mod.layout
        p = {k: float(x) for k, x in zip(lay.names, np.asarray(mod.numbers), strict=True)}
        closure = _float_law(mod.law)

        def reference(q, v, lay=lay, p=p, closure=closure):
            ig, iw, ibs, _ = lay.terminals
            vgs, vds, vbs, sign = v[ig], v[iw], v[ibs], p["sign"]
            if not lay.meyer:
                return jnp.stack([-_mos_part.channel_current(vgs, vds, vbs, sign, closure)])
            y = [q[j] / _mos_part.TAU for _, j in lay.meyer]
            i, cs = _mos_part.channel_and_gates(
                vgs, vds, vbs, y, sign, closure, p["phi"], p["c_ox"]
            )
            gates = [-c * v[j] / _mos_part.TAU for (_, j), c in zip(lay.meyer, cs, strict=True)]
            return jnp.stack([-i, *gates])

        def lines(q, v, lay=lay, part=part):
            f = part.force(q, v)
            return jnp.stack([f[lay.terminals[1]], *(f[a] for a, _ in lay.meyer)])

        n = len(part.coords)
        for _ in range(8):
            q = jnp.asarray(rng.normal(size=n) * 2e-12)  # Meyer's y = τ V: volts
            v = jnp.asarray(rng.normal(size=n) * 2.0)
            _equal(lines(q, v), reference(q, v), (part.name, "values"))
            for arg in (0, 1):
                _equal(
                    jax.jacfwd(lines, arg)(q, v),
                    jax.jacfwd(reference, arg)(q, v),
                    (part.name, "jacobian", arg),
                )


def test_a_traced_kp_reaches_the_force():
    """``jax.grad`` of the channel current in KP (the law's vector is then traced):
    I_D ∝ KP in saturation, so ∂I/∂KP = I/KP."""
    v = jnp.zeros(6).at[1].set(2.0).at[3].set(1.5)  # V_DS = 2, V_GS = 1.5 (coords: q w sg wg …)

    def current(kp):
        part = cp.MOSFET(vto=0.7, kp=kp, w=2e-6, l=1e-6, name="m")
        assert part.coords[:4] == ("q", "w", "sg", "wg")
        return -part.force(jnp.zeros(len(part.coords)), v)[1]

    kp = 1e-4
    i = float(current(kp))
    assert i == pytest.approx(0.5 * kp * 2.0 * 0.8**2, rel=1e-12)
    assert float(jax.grad(current)(kp)) == pytest.approx(i / kp, rel=1e-12)


VDMOS_CHAIN = """VDMOS chain, each device its own size
vdd dd 0 5
vin n0 0 pulse 0 5 10n 10n 10n 140n 300n
{stages}
cl n{n} 0 10f
.model n1 vdmos cgdmin=0.2p cgdmax=1p a=2 cgs=0.5p rg=5k rb=1e9 cjo=0.1p
.model p1 vdmos cgdmin=0.2p cgdmax=1p a=2 cgs=0.5p rg=5k rb=1e9 cjo=0.1p pchan
.tran 1n 10n
.end
"""


def _distinct_decks():
    """Decks of devices all of their own size, of levels 1, 2, 3, 6 (each card pair:
    Meyer, overlaps, RD or RS, junction charges; W, L and M) and VDMOS, with ``.ic`` voltages that
    give the gate capacitors their own initial charges per device."""
    decks = {}
    for level in sorted(CARDS):
        text = chain(level, 5)
        for k in range(5):  # each its own multiplier too: its own junctions' I_S, limits
            for kind in ("mn", "mp"):
                at = text.index(f"\n{kind}{k} ")
                end = text.index("\n", at + 1)
                text = text[:end] + f" m={1 + 0.5 * k:g}" + text[end:]
        ic = " ".join(f"v(n{k})={0.3 * k:g}" for k in range(1, 6))
        decks[level] = text.replace(".tran", f".ic {ic}\n.tran")
    stages = "\n".join(
        f"mp{k} n{k + 1} n{k} dd p1 m={1 + 0.5 * k:g}\nmn{k} n{k + 1} n{k} 0 n1 m={1 + 0.25 * k:g}"
        for k in range(5)
    )
    decks["vdmos"] = VDMOS_CHAIN.format(stages=stages, n=5)
    return decks


@pytest.mark.parametrize("kind", [1, 2, 3, 6, "vdmos"])
def test_parts_copied_from_a_template_equal_parts_constructed(monkeypatch, kind):
    """A transistor of a structure already built is that part's copy with its own name,
    numbers, junction limits, initial state and parameters
    (``_mos_part._from_template``): it must equal, field for field and leaf for leaf,
    the part ``ControlledPart`` constructs — and so must the assembled system. Only the
    first device of each structure is constructed."""
    from diracvi.components._part import fields

    source = _distinct_decks()[kind]
    _mos_part._TEMPLATES.clear()
    constructed = count_calls(monkeypatch, _mos_part, "ControlledPart")
    copied = spice.read(source)
    monkeypatch.undo()
    monkeypatch.setattr(_mos_part, "_template_key", lambda *a, **k: None)
    each = spice.read(source)
    monkeypatch.undo()
    parts_a = [p for p, _ in copied.circuit._parts if fields(p)["role"] == "transistor"]
    parts_b = [p for p, _ in each.circuit._parts if fields(p)["role"] == "transistor"]
    assert len(parts_a) == len(parts_b) == 10
    assert len(constructed) == 2  # one NMOS and one PMOS structure
    # the devices differ: a copy that kept its template's numbers would fail below
    numbers = {np.asarray(p._force.arrays.numbers).tobytes() for p in parts_a}
    assert len(numbers) == 10
    for a, b in zip(parts_a, parts_b, strict=True):
        assert type(a) is type(b) and fields(a).keys() == fields(b).keys()
        for key in fields(a):
            if key in ("_lagrangian", "_force", "junction_limits", "_forms_const"):
                continue
            assert fields(a)[key] == fields(b)[key], (fields(a)["name"], key)
        assert_same(a, b, fields(a)["name"])
    assert_same(copied.system, each.system, "system")
