"""A netlist's alike devices are built once: a subcircuit instantiated n times repeats
each semiconductor line with the same card, size and initial voltages, and the reader
builds that part once and gives the others its fields under their own names
(``spice/_cards.py: built``, ``components/_part.py: renamed``).

What is checked: the parts (and the assembled system) equal, leaf for leaf and in their
static structure, those read with every device built by its constructor; the number of
parts constructed is the number of distinct devices, whatever the number of instances
(reading stays linear in the element count, with a constant per alike device); calls
that differ only in a zero's sign or a number's type are not merged.

White-box: counts calls of ``diracvi.components._mos_part._assemble``,
``diracvi.components._bsim3.size_dependent`` and switches the reader's memory off
(``spice._parse.REMEMBER_PARTS``).
"""

import jax
import numpy as np
import pytest

from diracvi import components as cp
from diracvi import spice
from diracvi.components import _bsim3, _mos_part
from diracvi.components._part import fields, renamable, renamed
from diracvi.errors import ModelError
from diracvi.spice import _parse
from diracvi.spice._cards import built

#: one subcircuit of every semiconductor line the memory serves: MOSFET levels 1, 2, 3, 6
#: and BSIM3, a BJT, a JFET, a diode (two lines of one card and size in M1, M1B)
CELL = """.subckt cell a b vdd
M1 b a vdd vdd p1 W=2u L=1u
M1B b a vdd vdd p1 W=2u L=1u
M2 b a 0 0 n2 W=1u L=1u
M3 b a 0 0 n3 W=1u L=1u
M6 b a 0 0 n6 W=1u L=1u
MB b a 0 0 nb W=1u L=0.5u
Q1 vdd a b qn
J1 vdd a b jn
D1 b vdd dd
C1 b 0 10f
.ends cell
.model p1 pmos level=1 vto=-0.7 kp=5e-5 cbd=1f cgso=1e-10 tox=2e-8 rd=5
.model n2 nmos level=2 vto=0.7 nsub=2e16 tox=2e-8
.model n3 nmos level=3 vto=0.7 tox=2e-8 theta=0.1
.model n6 nmos level=6 kc=3.9e-05 nc=1.17 kv=0.92 nv=0.87 lambda0=0.013
.model nb nmos level=49 tox=6e-9 capmod=3
.model qn npn bf=80 cje=1p
.model jn njf vto=-2 beta=1e-4 cgs=1p
.model dd d is=1e-14 cjo=1p
"""


def deck(n: int, cell: str = CELL) -> str:
    lines = ["alike cells", cell, "VDD vdd 0 3.3", "VIN n0 0 PULSE(0 3.3 1n 1n 1n 10n 20n)"]
    lines += [f"X{k} n{k - 1} n{k} vdd cell" for k in range(1, n + 1)]
    return "\n".join([*lines, ".tran 0.1n 4n", ".end", ""])


def read_each_built(source: str, monkeypatch):
    """The netlist with every device built by its constructor (no memory)."""
    with monkeypatch.context() as m:
        m.setattr(_parse, "REMEMBER_PARTS", False)
        return spice.read(source)


def assert_same(a, b, where: str):
    """Equal structure (the tree's static part: names, pins, programs…) and equal
    leaves, bit for bit."""
    leaves_a, tree_a = jax.tree.flatten(a)
    leaves_b, tree_b = jax.tree.flatten(b)
    assert tree_a == tree_b, where
    assert len(leaves_a) == len(leaves_b), where
    for x, y in zip(leaves_a, leaves_b, strict=True):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype and x.shape == y.shape, where
        assert x.tobytes() == y.tobytes(), where


def test_alike_parts_equal_parts_built_each(monkeypatch):
    source = deck(3)
    remembered = spice.read(source)
    each = read_each_built(source, monkeypatch)
    parts_a, parts_b = remembered.circuit._parts, each.circuit._parts
    assert [fields(p)["name"] for p, _ in parts_a] == [fields(p)["name"] for p, _ in parts_b]
    assert len(parts_a) >= 3 * 10
    for (a, nodes_a), (b, nodes_b) in zip(parts_a, parts_b, strict=True):
        assert type(a) is type(b) and nodes_a == nodes_b
        assert fields(a).keys() == fields(b).keys()
        assert_same(a, b, fields(a)["name"])
    assert_same(remembered.system, each.system, "system")
    assert remembered.notes == each.notes


@pytest.mark.parametrize("count", [2, 12])
def test_parts_constructed_once_per_distinct_device(monkeypatch, count):
    # a level-1 inverter cell: per-instance work is the line's reading, not a part
    cell = """.subckt cell a b vdd
M1 b a vdd vdd p1 W=2u L=1u
M2 b a 0 0 n1 W=1u L=1u
.ends cell
.model n1 nmos level=1 vto=0.7 kp=1e-4 tox=2e-8
.model p1 pmos level=1 vto=-0.7 kp=5e-5 tox=2e-8"""
    calls = []
    assemble = _mos_part._assemble
    monkeypatch.setattr(
        _mos_part, "_assemble", lambda *a, **k: calls.append(k["name"]) or assemble(*a, **k)
    )
    net = spice.read(deck(count, cell))
    transistors = [p for p, _ in net.circuit._parts if fields(p)["role"] == "transistor"]
    assert len(transistors) == 2 * count
    assert calls == ["m:x1:m1", "m:x1:m2"], calls
    assert len({fields(p)["name"] for p in transistors}) == 2 * count


def test_bsim3_sized_once_per_size(monkeypatch):
    cell = """.subckt cell a b vdd
MB b a 0 0 nb W=1u L=0.5u
MC b a 0 0 nb W=2u L=0.5u
.ends cell
.model nb nmos level=49 tox=6e-9 capmod=3"""
    sizes = []
    size_dependent = _bsim3.size_dependent
    monkeypatch.setattr(
        _bsim3,
        "size_dependent",
        lambda card, sign, l, w, *a: sizes.append((l, w)) or size_dependent(card, sign, l, w, *a),  # noqa: E741
    )
    spice.read(deck(5, cell))
    assert sizes == [(0.5e-6, 1e-6), (0.5e-6, 2e-6)]


def test_calls_merged_only_when_equal_bit_for_bit():
    made = []

    def resistor(r, *, name):
        made.append(name)
        return cp.Resistor(r, name=name)

    parts: dict = {}
    a = built(parts, resistor, 1.0, name="a")
    b = built(parts, resistor, 1.0, name="b")
    c = built(parts, resistor, np.float64(1.0), name="c")  # another type
    d = built(parts, resistor, 1, name="d")
    e = built(parts, cp.Resistor, 1.0, name="e")  # another constructor
    assert made == ["a", "c", "d"]
    assert_same(b, cp.Resistor(1.0, name="b"), "b")
    assert [fields(p)["name"] for p in (a, b, c, d, e)] == list("abcde")
    made.clear()
    built(parts, resistor, -0.0 * 1e-300 + 1e-300, name="f")  # a new value
    assert made == ["f"]


def test_renamed_equals_the_constructor_and_refuses_what_it_cannot():
    args = ("nmos", 0.7, 1e-4, 0.01, 1e-6, 1e-6, 0.4, 0.6)
    part = cp.MOSFET(*args, name="a", cox=1e-3, rd=5.0)
    assert renamable(part)
    assert_same(renamed(part, "b"), cp.MOSFET(*args, name="b", cox=1e-3, rd=5.0), "b")
    assert fields(part)["name"] == "a"  # the original is left as it was
    with pytest.raises(ModelError, match="not a valid name"):
        renamed(part, "x.y")
    # two branches, default currents i(name.1), i(name.2): the name is in them
    two = cp.Part(
        ("q1", "q2"),
        lambda q, v: 0.5 * v @ v,
        name="t",
        pins=(("a", "q1", 1), ("b", "q1", -1), ("c", "q2", 1), ("d", "q2", -1)),
    )
    assert not renamable(two)
    with pytest.raises(ModelError, match=r"reports currents under its own name"):
        renamed(two, "u")


def test_a_note_is_kept_once_also_when_appended_past_note_once():
    reader = _parse._Reader("t")
    reader.note_once("a")
    reader.notes.append("b")  # (as the reader's own note() and the loaders append)
    reader.notes += ["c"]
    for note in ("a", "b", "c", "d", "d"):
        reader.note_once(note)
    assert reader.notes == ["a", "b", "c", "d"]
