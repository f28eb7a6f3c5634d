"""The SPICE reader on netlists as engineers write them: every problem at once, the
directives a transient does not need, includes and libraries, subcircuits (scoped names
and numbers checked against ngspice), the saved vectors, raw files ngspice reads back,
and the run's result as a mapping."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest
from typer.testing import CliRunner

import _ngspice as ng
from diracvi import ModelError, spice
from diracvi.cli import app
from diracvi.spice._values import number

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")


def _parts(netlist):
    return {p.name: p for p, _ in netlist.circuit._parts}


def _value(part, key):
    """A part's R, C or L (R from F = −R q̇, C from L = −q²/2C at q = 1)."""
    one, zero = np.ones(1), np.zeros(1)
    if key == "resistance":
        return float(-part.force(zero, one)[0])
    if key == "capacitance":
        return float(-0.5 / part.lagrangian(one, zero))
    return float(dict(part.parameters)[key])


# --------------------------------------------------------------- every problem at once
BROKEN = """a deck with a problem on many lines
V1 in 0 PULSE(0 1 0 1u 1u 1m 2m) AC 1
R1 in a {undefined*2}
B1 a 0 V=2*V(in)*volume(1)
Z1 c b 0 mod1
.model mod1 NMF(BETA=1m)
R1 a 0 1k
C1 a 0 0
.func f {x*2}
.temp 85 90
D1 a 0 nomodel
.tran 1u 1m
.end
"""


def test_every_problem_is_reported_at_once_with_line_text_and_fix():
    with pytest.raises(spice.NetlistError) as info:
        spice.read(BROKEN)
    err = info.value
    assert isinstance(err, ModelError)
    text = str(err)
    assert text.startswith("the netlist has 8 problems:")
    where = [w for w, _, _ in err.problems]
    assert where == [f"line {k}" for k in (3, 4, 5, 7, 8, 9, 10, 11)]
    lines = BROKEN.splitlines()
    for k in (3, 4, 5, 7, 8, 9, 10, 11):
        assert f"line {k}: " in text and lines[k - 1] in text  # its number and its text
    assert "line 2" not in text and "'ac'" not in text  # the AC spec is no parameter
    assert "unknown parameter 'undefined'" in text and "(define it with .param)" in text
    assert "element 'B1': unknown function 'volume' at column 9" in text
    assert "expected '.func NAME(arg1, arg2, …) = expr'" in text
    # the transistor is refused at its element line, naming its model's line
    assert "element 'Z1': a MESFET, model 'mod1' (NMF, line 6)" in text
    assert "line 6:" not in text
    assert "element 'R1' is defined twice (first line 3)" in text
    assert "Capacitor 'C1'" in text
    assert "'.temp' with 2 values" in text and "give one" in text
    assert "model 'nomodel' is not defined" in text


def test_a_model_no_element_uses_is_accepted_with_a_note():
    net = spice.read("t\nV1 a 0 1\nR1 a 0 1k\n.model qn NPN(BF=100 IS=1e-16)\n.model sw1 SW\n")
    assert any("line 4: .model qn NPN is not used" in n for n in net.notes)
    assert any("line 5: .model sw1 SW is not used" in n for n in net.notes)


@pytest.mark.parametrize(
    "spec",
    [
        "PULSE(0 1 0 1u 1u 1m 2m) AC 1",
        "DC 0 AC 1 0 PULSE(0 1 0 1u 1u 1m 2m)",
        "AC 1 PULSE 0 1 0 1u 1u 1m 2m",
    ],
)
def test_ac_and_dc_specs_on_sources_leave_the_transient_function(spec):
    plain = spice.read("t\nV1 a 0 PULSE(0 1 0 1u 1u 1m 2m)\nR1 a 0 1k\n.tran 1u 1m\n")
    net = spice.read(f"t\nV1 a 0 {spec}\nR1 a 0 1k\n.tran 1u 1m\n")
    times = np.linspace(0, 4e-3, 41)
    v_plain = _parts(plain)["V1"].force  # the voltage enters through the force
    v_net = _parts(net)["V1"].force
    q, v = np.zeros(1), np.zeros(1)
    assert np.array_equal([v_plain(q, v, t) for t in times], [v_net(q, v, t) for t in times])
    assert float(v_net(q, v, 0.5e-3)[0]) == -1.0  # F = −u(t): the pulse's top
    assert any("line 2: AC specification ignored" in n for n in net.notes)


def test_a_source_with_dc_and_ac_only_is_its_dc_value():
    net = spice.read("t\nV1 a 0 DC 2.5 AC 1\nR1 a 0 1k\n")
    force = _parts(net)["V1"].force
    assert abs(float(force(np.zeros(1), np.zeros(1), 0.3)[0])) == 2.5


# ------------------------------------------------------------------ tolerated directives
@pytest.mark.parametrize(
    ("directive", "said"),
    [
        (".four 1k v(a)", ".four ignored"),
        (".op", ".op noted"),
        (".print tran v(a)", ".print ignored"),
        (".plot tran v(a)", ".plot ignored"),
        (".probe", ".probe alli (every device's pin currents"),  # ngspice: '.probe alli'
        # (.measure tran is measured: tests/test_spice_measure.py)
        (".meas ac vmax MAX vdb(a)", ".measure ac ignored"),
        (".measure dc t1 WHEN v(a)=0.5", ".measure dc ignored"),
        (".width out=80", ".width ignored"),
        (".nodeset v(a)=1", ".nodeset noted"),
        (".ac dec 10 1 1meg", ".ac ignored"),
        (".options reltol=1e-4 method=gear", "read into netlist.options"),
    ],
)
def test_directives_a_transient_does_not_need_are_noted(directive, said):
    net = spice.read(f"t\nV1 a 0 1\nR1 a 0 1k\n{directive}\n.tran 1u 1m\n")
    assert [n for n in net.notes if n.startswith("line 4: ") and said in n]


def test_options_values_are_kept():
    net = spice.read("t\nV1 a 0 1\nR1 a 0 1k\n.options reltol=1e-4 abstol=1p method=gear\n")
    assert net.options == {"reltol": 1e-4, "abstol": 1e-12, "method": "gear"}


def test_temperature_lines_are_read_and_two_values_refused():
    # (the devices at these temperatures against ngspice: tests/test_temperature.py)
    for line in (".temp 27", ".temp 50", ".options temp=0"):
        assert spice.read(f"t\nV1 a 0 1\nR1 a 0 1k\n{line}\n")
    with pytest.raises(spice.NetlistError, match=r"line 4: '\.temp' with 2 values"):
        spice.read("t\nV1 a 0 1\nR1 a 0 1k\n.temp 50 60\n")


def test_global_nodes_are_shared_by_subcircuits():
    net = spice.read(
        "t\n.global vdd\n.subckt load a\nR1 a vdd 1k\nR2 a inner 1k\nR3 inner 0 1k\n.ends\n"
        "V1 vdd 0 1\nX1 n load\nX2 n load\n"
    )
    assert set(net.assembly.nodes) == {"vdd", "n", "x1.inner", "x2.inner"}


CONTROL = """a deck driven from a .control block
V1 a 0 SIN(0 1 1k)
R1 a b 1k
C1 b 0 1u
.control
tran 5u 2m
run
plot v(b)
.endc
.end
"""


def test_control_blocks_are_skipped_and_their_tran_used():
    net = spice.read(CONTROL)
    assert (net.dt, net.stop, net.steps) == (5e-6, 2e-3, 400)
    assert any("line 5: .control" in n and "skipped" in n for n in net.notes)
    # a .tran of the netlist wins over the block's
    net = spice.read(CONTROL.replace(".end\n", ".tran 1u 1m\n.end\n"))
    assert (net.dt, net.stop) == (1e-6, 1e-3)


def test_an_unclosed_control_block_is_a_problem():
    with pytest.raises(spice.NetlistError, match=r"line 4: '.control' without '.endc'"):
        spice.read("t\nV1 a 0 1\nR1 a 0 1k\n.control\nrun\n")


@pytest.mark.parametrize(
    ("tran", "expected"),
    [
        (".tran 1u 1m", (1e-6, 1e-3, 0.0, None, False)),
        (".tran 1u 1m 0.5m", (1e-6, 1e-3, 5e-4, None, False)),
        (".tran 1u 1m 0.5m 0.1u uic", (1e-6, 1e-3, 5e-4, 1e-7, True)),
        (".TRAN 1U 1M 0 2N UIC", (1e-6, 1e-3, 0.0, 2e-9, True)),
    ],
)
def test_tran_start_and_tmax_are_kept(tran, expected):
    net = spice.read(f"t\nV1 a 0 1\nR1 a 0 1k\n{tran}\n")
    assert (net.dt, net.stop, net.start, net.tmax, net.uic) == expected


def test_tran_start_after_stop_is_refused():
    with pytest.raises(spice.NetlistError, match=r"line 4: '.tran' needs 0 ≤ TSTART < TSTOP"):
        spice.read("t\nV1 a 0 1\nR1 a 0 1k\n.tran 1u 1m 2m\n")


def test_case_does_not_matter():
    net = spice.read(
        "T\n.PARAM RV=2K\nv1 IN 0 dc 1\nR1 in OUT {rv}\nc1 Out GND 1U IC=0.5\n"
        ".TRAN 1U 1M UIC\n.END\n"
    )
    assert net.assembly.nodes == ("in", "out")
    assert _value(_parts(net)["R1"], "resistance") == 2e3
    assert net.uic


# ---------------------------------------------------------------------- SPICE numbers
NUMBERS = ["1k", "1meg", "1MEGohm", "1e-6F", "10uF", "5mil", "2.5mF", "1.5e3k", "2a", "3x", "47n"]


@pytest.mark.parametrize(
    ("token", "value"),
    [("1e-6F", 1e-21), ("10uF", 1e-5), ("5mil", 1.27e-4), ("1.5e3k", 1.5e6), ("2a", 2.0)],
)
def test_numbers_as_ngspice_reads_them(token, value):
    # (checked with ngspice 39: 1e-6F is femto, 'a' is no atto; see the live test below)
    assert number(token) == pytest.approx(value, rel=1e-15)


@needs_ngspice
def test_numbers_agree_with_ngspice(tmp_path):
    # each value as a resistance fed 1 A: ngspice's operating point prints it as v(k)
    lines = ["numbers"]
    for k, token in enumerate(NUMBERS, start=1):
        lines += [f"I{k} 0 {k} 1", f"R{k} {k} 0 {token}"]
    (tmp_path / "n.cir").write_text("\n".join([*lines, ".op", ".end", ""]))
    out = subprocess.run(
        ["ngspice", "-b", "n.cir"], cwd=tmp_path, capture_output=True, text=True, timeout=60
    ).stdout
    found = dict(re.findall(r"V\((\d+)\)\s+(\S+)", out))
    assert len(found) == len(NUMBERS)
    for k, token in enumerate(NUMBERS, start=1):
        assert number(token) == pytest.approx(float(found[str(k)]), rel=1e-6), token


# ------------------------------------------------------------------ include and .lib
def test_include_and_lib_of_local_files(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "load.inc").write_text(
        "* no title line in an included file\nR2 b 0 {rload}\n.include ../more.inc\n.end\n"
        "R99 this is after the included file's .end\n"
    )
    (tmp_path / "more.inc").write_text("C1 b 0 1u\n")
    (tmp_path / "models.lib").write_text(
        "* a library with two corners\n.lib fast\n.param rload=1k\n.endl\n"
        ".lib slow\n.param rload=5k\n.endl fast\n"
    )
    deck = tmp_path / "top.cir"
    deck.write_text(
        "includes\n.lib models.lib slow\nV1 a 0 1\nR1 a b 1k\n.inc parts/load.inc\n"
        "R3 a 0 2k\n.tran 1u 1m\n.end\n"
    )
    net = spice.read(deck)
    parts = _parts(net)
    assert set(parts) == {"V1", "R1", "R2", "C1", "R3"}  # R3 is read: .end ended load.inc
    assert _value(parts["R2"], "resistance") == 5e3
    assert net.circuit.origin["R2"] == "load.inc line 2 (R2)"


def test_a_line_starting_with_an_unusual_character_is_a_comment(tmp_path):
    # ngspice replaces a leading ')' (and '=', '[', '?', '&', '%', ...) by '*' with a
    # warning; eSim's model libraries close '.model NAME NPN(' with a lone ')' line
    # (npn_1.lib of the corpus), whose '(' the .model reader then accepts unclosed
    (tmp_path / "npn.lib").write_text(".model qq NPN(\n+ Bf=125\n+ Is=1e-15\n)")
    deck = tmp_path / "top.cir"
    deck.write_text(
        "lone paren\n.include npn.lib\nv1 1 0 5\nr1 1 2 1k\nrb 1 3 100k\nq1 2 3 0 qq\n"
        "= 7 stray\n.tran 1u 10u\n.end\n"
    )
    net = spice.read(deck)
    q1 = _parts(net)["q1"]
    assert dict(q1.parameters) == pytest.approx({"is": 1e-15, "bf": 125.0, "br": 1.0})
    said = [n for n in net.notes if "read as a comment" in n]
    assert any(n.startswith("npn.lib line 4: ')'") for n in said), net.notes
    assert any(n.startswith("line 7: '= 7 stray'") for n in said), net.notes


def test_include_problems_name_the_file_and_line(tmp_path):
    (tmp_path / "bad.inc").write_text("R2 b 0 {nope}\n")
    (tmp_path / "lib.l").write_text(".lib tt\n.param r=1\n.endl\n")
    deck = tmp_path / "top.cir"
    deck.write_text(
        "t\nV1 a 0 1\nR1 a b 1k\n.include bad.inc\n.include missing.inc\n.lib lib.l ff\n"
    )
    with pytest.raises(spice.NetlistError) as info:
        spice.read(deck)
    where = [w for w, _, _ in info.value.problems]
    assert where == ["bad.inc line 1", "line 5", "line 6"]
    assert "has no section 'ff' (it has ['tt'])" in str(info.value)


# ------------------------------------------------------------------------ subcircuits
FILTER = """Nested subcircuits with parameters: two LC low-pass sections
.param cbase=1u
.subckt section in out params: l=1m c={cbase}
L1 in mid {l}
C1 mid 0 {c}
Rd mid out 10
C2 out 0 {c/2}
.ends
.subckt filter a b params: scale=1
X1 a m section l={scale*1m}
X2 m b section c={2*cbase}
Rm m 0 1k
.ends
V1 in 0 SIN(0 1 2k)
Rs in a 5
XF a out filter scale=2
RL out 0 50
.tran 2u 2m uic
.end
"""


def test_subcircuit_names_and_parameters():
    net = spice.read(FILTER)
    assert set(net.assembly.nodes) == {"in", "a", "out", "xf.m", "xf.x1.mid", "xf.x2.mid"}
    parts = _parts(net)
    # parameters: instance values, else defaults over the global .param
    assert _value(parts["l:xf:x1:l1"], "inductance") == pytest.approx(2e-3)
    assert _value(parts["l:xf:x2:l1"], "inductance") == pytest.approx(1e-3)
    assert _value(parts["c:xf:x1:c1"], "capacitance") == pytest.approx(1e-6)
    assert _value(parts["c:xf:x2:c2"], "capacitance") == pytest.approx(1e-6)
    assert net.display["l:xf:x1:l1"] == "l.xf.x1.l1"
    assert dict(net.vectors)["i(l.xf.x2.l1)"] == "i(l.xf.x2.l1)"
    assert net.circuit.origin["r:xf:x2:rd"] == "line 6 (r.xf.x2.rd)"


@needs_ngspice
def test_nested_subcircuits_agree_with_ngspice():
    probes = ("v(xf.m)", "v(out)", "i(v1)", "i(l.xf.x1.l1)", "v(xf.x2.mid)")
    t, ref = ng.ngspice(FILTER, probes, tmax=2e-3 / 40000)
    result = spice.run(FILTER, dt=1e-6)
    for probe in probes:
        got = np.interp(t, result.time, result[probe])
        assert np.max(np.abs(got - ref[probe])) <= 1e-3 * np.max(np.abs(ref[probe])), probe


# ngspice's examples/probe/F5models.lib: a potentiometer whose parameters are .param lines
# of its body ("default parameters, which are required by some simulators"), set per instance
RPOT = """Instance values over a subcircuit body's own .param lines
.subckt RPOT 1 2 3
R1 1 2 {value*ratio + 1m}
R2 2 3 {value*(1-ratio)+ 1m}
.param value=1k
.param ratio=1
.ends
V1 a 0 1
XP a b 0 RPOT value=5k ratio=0.15
XQ a c 0 RPOT
C1 b 0 1n
.tran 1u 10u
.end
"""


def test_an_instance_sets_a_parameter_its_subcircuits_body_assigns():
    result = spice.run(RPOT)
    # XP: R1 = 5k·0.15 + 1m, R2 = 5k·0.85 + 1m (the instance's values); XQ: the body's
    # defaults, R1 = 1k + 1m, R2 = 1m
    r1, r2, q1, q2 = 750.001, 4250.001, 1000.001, 1e-3
    assert result["v(b)"][-1] == pytest.approx(r2 / (r1 + r2), rel=1e-6)
    assert result["v(c)"][-1] == pytest.approx(q2 / (q1 + q2), rel=1e-6)
    current = -(1 / (r1 + r2) + 1 / (q1 + q2))
    assert result["i(v1)"][-1] == pytest.approx(current, rel=1e-6)
    if ng.available():  # and what ngspice 39 makes of it
        op = ng.operating_point(RPOT)
        for key in ("v(b)", "v(c)", "i(v1)"):
            assert result[key][-1] == pytest.approx(op[key], rel=1e-6), key


def test_problems_inside_instances_name_the_instance_chain():
    deck = (
        "t\n.subckt inner a b params: r=1\nR1 a b {r}\nR2 a b {1/(r-2)+10}\n.ends\n"
        ".subckt outer a b\nX1 a m inner r=2\nX2 m b inner\n.ends\n"
        "V1 1 0 1\nXA 1 0 outer\n"
    )
    with pytest.raises(spice.NetlistError) as info:
        spice.read(deck)
    # one line of the definition, one problem (only where r = 2 does 1/(r-2) fail)
    assert [w for w, _, _ in info.value.problems] == ["line 4"]
    assert "line 4: in xa.x1: R2 value" in str(info.value)


def test_a_definition_line_failing_in_many_instances_is_one_problem():
    deck = "t\n.subckt amp a b\nR1 a b 1k\nB1 b 0 V=2*V(a)*volume(1)\n.ends\nV1 1 0 1\n"
    deck += "".join(f"X{k} 1 0 amp\n" for k in range(6))
    with pytest.raises(spice.NetlistError) as info:
        spice.read(deck)
    ((where, text, why),) = info.value.problems
    assert (where, text) == ("line 4", "B1 b 0 V=2*V(a)*volume(1)")
    assert why.startswith("in x0, x1, x2, x3 and 2 more: element 'B1': unknown function")


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("X1 a 0 nosuch", r"line 5: subcircuit 'nosuch' is not defined \(subcircuits here: \['two"),
        ("X1 a 0 b two", r"line 5: subcircuit 'two' \(line 2\) has 2 pins \['p', 'n'\], the"),
        ("X1 a 0 two q=3", r"line 5: subcircuit 'two' has no parameters \['q'\]"),
        (".ends", r"line 5: '.ends' without a '.subckt'"),
        ("XR a 0 loop\n.subckt loop p n\nXL p n loop\n.ends",
         r"line 7: in xr(\.xl)+: instances nested 30 deep"),
    ],
)  # fmt: skip
def test_subcircuit_mistakes_are_named(body, match):
    deck = f"t\n.subckt two p n\nR1 p n 1k\n.ends\n{body}\nV1 a 0 1\nR0 a 0 1\n"
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(deck)


# ------------------------------------------------------------- conditionals, .func
# ngspice's .if/.elseif/.else/.endif: a divider per conditional, each branch its own
# lower resistor, so the branch taken is read off the node voltage (1k over R: R/(1k+R));
# nested, a non-integer condition (0.5 and -0.2 are true: ngspice tests the value ≠ 0),
# numparam's operators, and a subcircuit whose body branches on its instance's parameter
CONDITIONALS = """conditionals
.param m=2 half=0.5 neg=-0.2
.subckt load a b params: k=1
.if (k == 1)
R1 a b 1k
.elseif (k >= 2 && k < 3)
R1 a b 2k
.else
R1 a b 4k
.endif
.ends
V1 in 0 1
R0 in o1 1k
.if (m == 1)
R1 o1 0 1k
.elseif (m == 2)
.if (half)
R1 o1 0 3k
.else
R1 o1 0 5k
.endif
.else
R1 o1 0 7k
.endif
R2 in o2 1k
.if (neg)
R3 o2 0 1k
.endif
.if(0)
R3 o2 0 9k
.endif
R4 in o3 1k
X1 o3 0 load k=2
R5 in o4 1k
X2 o4 0 load k=5
R6 in o5 1k
X3 o5 0 load
.tran 1u 2u
.end
"""


def test_conditionals_take_ngspices_branches():
    result = spice.run(CONDITIONALS)
    # the branches: m = 2 and half ≠ 0 → 3k; neg ≠ 0 → 1k; k = 2 → 2k, k = 5 → 4k, k = 1 → 1k
    want = {"v(o1)": 3 / 4, "v(o2)": 1 / 2, "v(o3)": 2 / 3, "v(o4)": 4 / 5, "v(o5)": 1 / 2}
    for key, value in want.items():
        assert result[key][-1] == pytest.approx(value, rel=1e-12), key
    # read(params=) changes the branch, as the .param value it overrides would
    other = spice.run(CONDITIONALS, params={"m": 3})
    assert other["v(o1)"][-1] == pytest.approx(7 / 8, rel=1e-12)
    if ng.available():  # and the branches ngspice 39 takes
        op = ng.operating_point(CONDITIONALS)
        for key in want:
            assert result[key][-1] == pytest.approx(op[key], rel=1e-9), key


@pytest.mark.parametrize(
    ("body", "match"),
    [
        (".if (1)\nR1 a 0 1", r"line 2: '.if' without its '.endif'"),
        (".endif", r"line 2: '.endif' without an '.if' before it"),
        (".else\nR1 a 0 1", r"line 2: '.else' without an '.if' before it"),
        (".if\nR1 a 0 1\n.endif", r"line 2: '.if' expects '.if \(expression\)'"),
        (".if (nosuch)\nR1 a 0 1\n.endif", r"line 2: .if: unknown name 'nosuch'"),
        (".if (0)\n.else\n.elseif (1)\n.endif", r"line 4: '.elseif' after the '.else' of the"),
        (".if (0)\n.else\n.else\n.endif", r"line 4: a second '.else' for the '.if' on line 2"),
    ],
)
def test_conditional_mistakes_are_named(body, match):
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(f"t\n{body}\nV1 a 0 1\nR0 a 0 1\n.tran 1u 2u\n.end\n")


# a .func in a .param and in a .measure PARAM (ngspice's examples/measure/func_cap.sp's
# forms): f(2, 3) = 2·3 + 1 = 7, g calls f; numparam's max/min with one argument take
# 1.0 as their other (ngspice 39's xpressn.c: max(0.25) is 1, max(9.8) is 9.8)
FUNC_PARAM = """a .func in .param and .measure
.func f(a, b) 'a*b + 1'
.func g(x) {2*f(x, x)}
.param r1 = {f(2, 3)*1k}
.param r2 = 'g(3)*1k'
.param one = max(0.25)
V1 in 0 1
R1 in out {r1}
R2 out 0 {r2}
.measure tran m1 param='f(2, 3)'
.measure tran m2 param='max(0.25) + min(3) + max(g(1))'
.measure tran m3 find v(out) at=1u
.tran 1u 2u
.end
"""


def test_a_func_is_read_in_params_and_measures(tmp_path):
    result = spice.run(FUNC_PARAM)
    params = result.netlist.params
    assert params["r1"] == 7e3 and params["r2"] == 2 * 10 * 1e3 and params["one"] == 1.0
    measured = {m.name: m.value for m in result.measurements}
    assert measured["m1"] == 7.0
    assert measured["m2"] == 1.0 + 1.0 + 4.0
    assert measured["m3"] == pytest.approx(20 / 27, rel=1e-12)
    with pytest.raises(spice.NetlistError, match=r"line 3: .param r: .func f takes 2 arguments"):
        spice.read("t\n.func f(a, b) 'a*b'\n.param r = {f(1)}\nR1 a 0 {r}\nV1 a 0 1\n.end\n")
    if ng.available():  # what ngspice 39 prints for the measures
        path = tmp_path / "deck.cir"
        path.write_text(FUNC_PARAM.replace(".end\n", ".control\nrun\n.endc\n.end\n"))
        out = subprocess.run(
            ["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=120, check=True
        ).stdout
        found = dict(re.findall(r"^(m\d)\s+=\s+(\S+)", out, re.M))
        assert sorted(found) == ["m1", "m2", "m3"], out[-2000:]
        for name, value in found.items():
            assert measured[name] == pytest.approx(float(value), rel=1e-5), name


# ------------------------------------------------------------ saved vectors, raw files
DECK = """Saved vectors of an RLC fed through a subcircuit
.subckt stage in out
R1 in m 100
L1 m out 1m
V1 out sense 0
C1 sense 0 1u
.ends
V1 1 0 SIN(0 1 5k)
XA 1 2 stage
R9 2 0 1k
I1 0 2 SIN(0 1m 3k)
.tran 2u 1m uic
.end
"""


def test_default_vectors_are_node_voltages_and_branch_currents():
    # ngspice saves node voltages and the branch currents of V and L, not R, C or I
    names = {name for name, _ in spice.read(DECK).vectors}
    nodes = {"v(1)", "v(xa.m)", "v(2)", "v(xa.sense)"}
    assert names == nodes | {"i(v1)", "i(l.xa.l1)", "i(v.xa.v1)"}


def test_save_lines_choose_the_vectors():
    net = spice.read(DECK.replace(".tran", ".save v(2) @r9[i] i(v.xa.v1) xa.m\n.tran"))
    assert [n for n, _ in net.vectors] == ["v(2)", "i(@r9[i])", "i(v.xa.v1)", "v(xa.m)"]
    with pytest.raises(spice.NetlistError) as info:
        spice.read(DECK.replace(".tran", ".save v(nope) i(r77)\n.save v(1)\n.tran"))
    assert [w for w, _, _ in info.value.problems] == ["line 12", "line 12"]


_MOS_DECK = """A MOSFET whose internal quantity is asked for
Vd d 0 5
Vg g 0 2
M1 d g 0 0 nm
.model nm nmos
{save}
.tran 1n 10n
.end
"""


def test_a_device_quantity_is_noted_not_a_refusal():
    # ngspice saves @m1[id]; diracvi has no such waveform, says so and runs the deck on
    # (it is a request for output, not part of the circuit)
    net = spice.read(_MOS_DECK.format(save=".save v(d) @m1[id]"))
    assert [n for n, _ in net.vectors] == ["v(d)"]
    assert any("'.save @m1[id]' not saved" in n and "line 6" in n for n in net.notes)
    alone = spice.read(_MOS_DECK.format(save=".save @m1[id]"))
    default = spice.read(_MOS_DECK.format(save="")).vectors
    assert [n for n, _ in alone.vectors] == [n for n, _ in default]
    assert any("the default vectors are" in n for n in alone.notes)
    with pytest.raises(spice.NetlistError, match="@m7\\[id\\]"):  # no element m7: a typo
        spice.read(_MOS_DECK.format(save=".save @m7[id]"))


def test_a_malformed_output_line_is_noted_as_ngspice_goes_on():
    # ngspice warns on a broken .probe/.plot and runs; it is not read word by word
    net = spice.read(_MOS_DECK.format(save=".probe i(m1:z) hhhh) i(()"))
    for token in ("i(m1:z)", "hhhh)", "i(()"):  # each parameter noted, none refused
        assert any(n.startswith(f"line 6: '.probe {token}'") for n in net.notes), token
    with pytest.raises(spice.NetlistError, match="unbalanced"):  # a circuit line is read
        spice.read(_MOS_DECK.format(save="R1 d (0 1k"))


def test_result_is_a_short_read_only_mapping():
    result = spice.run(DECK.replace(".tran", ".save v(2) @r9[i]\n.tran"))
    assert list(result) == list(result.keys()) == ["v(2)", "i(@r9[i])"]
    assert len(result) == 2 and "v(2)" in result and "V(2)" in result
    assert "i(R9)" in result  # not saved, but a waveform that can be asked for
    assert np.array_equal(result["i(@r9[i])"], result["i(R9)"])
    assert "v(nope)" not in result
    assert dict(result.items()).keys() == {"v(2)", "i(@r9[i])"}
    text = repr(result)
    assert text.startswith("<spice.Result 'Saved vectors")
    assert "t 0 → 0.001 s, " in text and " variable steps of " in text
    assert text.endswith("; vectors v(2), i(@r9[i])>")
    assert "[" not in text.replace("[i]", "")  # no array dumped
    with pytest.raises(TypeError):
        result["v(2)"] = 0


def _ngspice_raw(tmp_path, deck):
    (tmp_path / "deck.cir").write_text(deck)
    subprocess.run(
        ["ngspice", "-b", "-r", "ng.raw", "deck.cir"],
        cwd=tmp_path,
        capture_output=True,
        timeout=120,
    )
    return (tmp_path / "ng.raw").read_bytes()


def _names(raw: bytes) -> list[str]:
    header = raw.split(b"Binary:\n")[0].split(b"Values:\n")[0].decode()
    return re.findall(r"^\t\d+\t(\S+)\t", header, re.MULTILINE)


@needs_ngspice
@pytest.mark.parametrize("save", ["", ".save v(2) @r9[i] i(v.xa.v1) v(xa.m) @r.xa.r1[i]\n"])
def test_raw_vector_names_equal_ngspice_own(tmp_path, save):
    deck = DECK.replace(".tran", save + ".tran")
    ours = spice.write_raw(spice.run(deck), tmp_path / "ours.raw").read_bytes()
    theirs = _ngspice_raw(tmp_path, deck)
    assert sorted(_names(ours)) == sorted(_names(theirs))
    assert len(_names(ours)) == (8 if not save else 6)


@needs_ngspice
@pytest.mark.parametrize("ascii", [False, True])
def test_raw_file_round_trip_through_ngspice(tmp_path, ascii):
    result = spice.run(DECK)
    spice.write_raw(result, tmp_path / "ours.raw", ascii=ascii)
    names = list(result)
    k = [0, 137, 500]
    prints = " ".join(f"{n}[{j}]" for n in ["time", *names] for j in k)
    (tmp_path / "load.cir").write_text(
        f"load\n.control\nload ours.raw\nset numdgt=15\nprint {prints}\n.endc\n.end\n"
    )
    out = subprocess.run(
        ["ngspice", "-b", "load.cir"], cwd=tmp_path, capture_output=True, text=True, timeout=60
    ).stdout
    got = dict(re.findall(r"^(\S+\[\d+\]) = (\S+)$", out, re.MULTILINE))
    assert len(got) == 3 * (len(names) + 1), out[-2000:]
    for name in ["time", *names]:
        values = result.time if name == "time" else result[name]
        for j in k:
            assert float(got[f"{name}[{j}]"]) == pytest.approx(values[j], rel=1e-12, abs=1e-300)


def test_raw_header_and_binary_layout(tmp_path):
    result = spice.run(DECK)
    raw = spice.write_raw(result, tmp_path / "x.raw").read_bytes()
    header, _, body = raw.partition(b"Binary:\n")
    lines = header.decode().splitlines()
    assert lines[0] == "Title: Saved vectors of an RLC fed through a subcircuit"
    assert lines[2:5] == ["Plotname: Transient Analysis", "Flags: real", "No. Variables: 8"]
    assert lines[5] == f"No. Points: {len(result.time)}"
    data = np.frombuffer(body, dtype="<f8").reshape(len(result.time), 8)
    assert np.array_equal(data[:, 0], result.time)
    assert np.array_equal(data[:, 1:], np.column_stack([result[n] for n in result]))


def test_cli_run_writes_raw_and_reads_spice_steps(tmp_path):
    deck = tmp_path / "d.cir"
    deck.write_text(DECK)
    raw = tmp_path / "d.raw"
    res = CliRunner().invoke(app, ["run", str(deck), "--dt", "1u", "--raw", str(raw)])
    assert res.exit_code == 0, res.output
    header = raw.read_bytes().split(b"Binary:\n")[0].decode()
    assert "No. Points: 1001" in header  # TSTOP = 1m at the step 1u
    assert "\ti(v.xa.v1)\tcurrent" in header
    bad = CliRunner().invoke(app, ["run", str(deck), "--dt", "fast"])
    assert bad.exit_code == 2 and "'fast' is not a number" in bad.output
    res = CliRunner().invoke(app, ["run", "rlc", "--raw", str(raw)])
    assert res.exit_code != 0 and "is not a netlist" in res.output


def test_ngspice_keyword_forms_of_values():
    net = spice.read("t\nV1 a 0 DC=3\nV2 b 0\nR1 a b r=2k\nC1 b 0 c={1u*2}\nL1 a 0 l=1m\n")
    parts = _parts(net)
    q, v = np.zeros(1), np.zeros(1)
    assert float(parts["V1"].force(q, v, 0.0)[0]) == -3.0  # F = −u(t)
    assert float(parts["V2"].force(q, v, 0.0)[0]) == 0.0  # no value: a 0 V source
    assert _value(parts["R1"], "resistance") == 2e3
    assert _value(parts["C1"], "capacitance") == pytest.approx(2e-6)
    assert _value(parts["L1"], "inductance") == 1e-3


def test_ic_inside_a_subcircuit_sets_the_instance_nodes():
    net = spice.read(
        "t\n.subckt rc a\nR1 a m 1k\nC1 m 0 1u\n.ic v(m)=0.25\n.ends\nV1 in 0 1\nXA in rc\n"
        "XB in rc\n.ic v(xb.m)=0.5\n"
    )
    parts = _parts(net)
    assert parts["c:xa:c1"].initial_q == (0.25e-6,)  # the instance's own .ic line
    assert parts["c:xb:c1"].initial_q == (0.5e-6,)  # the top-level .ic wins (ngspice 39 too)


def test_what_kicad_and_ngspice_decks_write_reads_as_ngspice_does():
    """``SINE(…)`` is SIN (KiCad/eSim decks), ``2µ`` is 2e-6 (the micro sign as ``u``),
    and a resistor's ``ac=`` value (AC analysis only) is noted, not refused."""
    base = "t\nV1 a 0 {}\nR1 a 0 1k{}\n.tran 1u 1m\n"
    sin = spice.read(base.format("SIN(0 1 1k)", ""))
    sine = spice.read(base.format("sine(0 1 1k)", " ac=2k"))
    t = np.linspace(0.0, 1e-3, 7)
    (w_sin,), (w_sine,) = (n.system.subsystems[0].waveforms for n in (sin, sine))
    assert np.array_equal(w_sin(t), w_sine(t)) and abs(w_sine(2.5e-4) - 1.0) < 1e-12
    assert any("ac=2k ignored" in note for note in sine.notes)
    micro = spice.read(base.format("PULSE(0 1 2\u00b5 1u 1u 5u 20u)", ""))
    micro_u = spice.read(base.format("PULSE(0 1 2u 1u 1u 5u 20u)", ""))
    (w_mu,), (w_u,) = (n.system.subsystems[0].waveforms for n in (micro, micro_u))
    assert np.array_equal(w_mu(t), w_u(t)) and w_mu(3.5e-6) == 1.0 and w_mu(1.9e-6) == 0.0


def test_a_dos_end_of_file_mark_ends_an_included_file(tmp_path):
    # ngspice's examples/Opamp/TL072.301 (a vendor model file) ends with ctrl-Z, 0x1A,
    # which DOS editors wrote as the end of a file; it was read as an element '\x1a'
    (tmp_path / "model.lib").write_text("R2 b 0 2k\n\x1a")
    deck = tmp_path / "top.cir"
    deck.write_text("ctrl-z\nV1 a 0 1\nR1 a b 1k\n.include model.lib\n.tran 1u 1m\n.end\n")
    assert set(_parts(spice.read(deck))) == {"V1", "R1", "R2"}
