"""The SPICE front end: numbers and expressions, the reader's errors, agreement with
ngspice (committed reference waveforms) and convergence at the rule's order, the CLI."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

import _ngspice as ng
from conftest import examples, loglog_slope
from diracvi import spice
from diracvi.cli import app
from diracvi.spice._values import evaluate, number


@pytest.mark.parametrize(
    ("token", "value"),
    [
        ("4.7k", 4.7e3),
        ("1MEG", 1e6),
        ("1m", 1e-3),
        ("1M", 1e-3),  # SPICE: M is milli, whatever the case
        ("10uF", 10e-6),
        ("1kOhm", 1e3),
        ("1F", 1e-15),  # SPICE's gotcha: F is femto
        ("2.5e-3", 2.5e-3),
        ("3p", 3e-12),
        ("1g", 1e9),
        ("2T", 2e12),
        ("-5n", -5e-9),
        ("1mil", 25.4e-6),
        ("10V", 10.0),
    ],
)
def test_numbers_with_spice_suffixes(token, value):
    assert number(token) == pytest.approx(value, rel=1e-15)


def test_expressions_are_evaluated_without_eval():
    params = {"r": 1e3, "C": 1e-6}
    assert evaluate("1/(2*pi*sqrt(r*c))", params) == pytest.approx(1 / (2 * np.pi * np.sqrt(1e-3)))
    assert evaluate("2*1k + 3^2", {}) == pytest.approx(2009.0)
    for bad in ("__import__('os')", "r.real", "[1, 2]", "lambda: 1", "undefined*2", "1/0"):
        with pytest.raises(ValueError, match=r"expression|unknown|unsupported|division"):
            evaluate(bad, params)


NETLIST = """title: an RC with every syntax feature
* a comment line
.param rval = 2k  cval={1u/2}
V1 in 0 PULSE(0 1 1m 1u 1u
+ 10m 20m)                      ; a continuation line and an inline comment
R1 in out {rval}
C1 out gnd cval IC=0.25
.ic v(out)=0.5
.options reltol=1e-6
.tran 10u 5m uic
.end
R9 this line is after .end and ignored
"""


def test_reader_understands_the_supported_syntax():
    net = spice.read(NETLIST)
    assert net.title.startswith("title")
    assert net.params == {"rval": 2e3, "cval": 0.5e-6}
    assert (net.dt, net.steps, net.uic) == (1e-5, 500, True)
    assert net.assembly.nodes == ("in", "out")  # gnd and 0 are ground
    c1 = dict((p.name, p) for p, _ in net.circuit._parts)["C1"]
    assert c1.initial_q == (0.25 * 0.5e-6,)  # IC= on the line wins over .ic
    assert any(".options" in note for note in net.notes)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("X1 a b sub", r"line 2: subcircuit 'sub' is not defined"),
        ("Z1 d g s zmod", r"line 2: element 'Z1': a MESFET"),
        ("J1 d g s jmod", r"line 2: model 'jmod' is not defined"),
        ("Q1 c b e npn", r"line 2: element 'Q1': no defined model"),
        (".subckt amp a b", r"line 2: '.subckt' without its '.ends'"),
        (".func f {x}", r"line 2: expected '.func NAME\(arg1, arg2, …\) = expr'"),
        ("R1 a 0", r"line 2: expected 'Rname n\+ n- \[value\] \[model\].*a resistor \.model"),
        ("R1 a 0 1k tcx=1", r"line 2: unsupported parameters \['tcx'\]"),
        ("R1 a 0 {1/0}", r"line 2: R1 value: '1/0'"),
        ("R1 a 0 abc", r"line 2: R1 value: unknown parameter 'abc'"),
        # (a negative R, L or C is read, as ngspice 39 reads it; a zero C is refused)
        ("C1 a 0 0", r"line 2: Capacitor 'C1': capacitance=0.0 must be a finite nonzero"),
        ("D1 a 0 nomodel", r"line 2: model 'nomodel' is not defined"),
        ("M1 d g s b nmos", r"line 2: model 'nmos' is not defined"),
        ("Q1 c b e q1\n.model q1 NPN(BF=100 PTF=1)", r"line 2: model 'q1' \(line 3\): NPN .*PTF=1"),
        ("D1 a 0 d1 2 3", r"line 2: expected 'Dname anode cathode model \[area\] \[AREA=a\]"),
        ("D1 a 0 d1\n.model d1 D(IS=1e-14 JTUN=10)", r"line 2: diode model 'd1' \(line 3\) sets"),
        ("V1 a 0 SIN(0 1 50", r"line 2: unbalanced"),
        ("V1 a 0 AM(1)", r"line 2: AM\(VA VO .*takes 2 to 7 values"),
        ("V1 a 0 TRNOISE(1 2 3)", r"line 2: source function 'TRNOISE' is not supported"),
        (".tran 1u", r"line 2: '.tran' expects"),
        ("+ 1k", r"line 2: a '\+' continuation with nothing to continue"),
        ("K1 L1 L2 0.5", r"line 2 \(K1\): coupled inductor 'L1' is not in the circuit"),
    ],
)
def test_unsupported_or_malformed_lines_name_line_and_text(text, match):
    with pytest.raises(spice.NetlistError, match=match) as info:
        spice.read(f"title\nR0 a 0 1\n{text}\n".replace("R0 a 0 1\n", "", 1) + "R0 a 0 1\n")
    assert text.split()[0] in str(info.value)  # the offending text is quoted


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("R1 a 0 1\nR4 a 0 1\nR2 x y 1\nR3 y x 1\n", r"nodes \['x', 'y'\] are floating"),
        ("V1 a 0 1\nV2 a b 2\nV3 b 0 1\nR1 a 0 1\n", r"line 4 \(V3\) closes a loop of voltage"),
        (
            "R1 a 0 1\nI1 a b 1m\nR2 b c 1\nI2 c 0 1m\n",
            r"nodes \['b', 'c'\] reach ground only through current sources \(line 3 \(I1\), line 5",
        ),
        ("R1 a b 1\nR2 b a 1\n", r"no ground node"),
    ],
)
def test_topology_errors_name_elements_and_nodes(body, match):
    with pytest.raises(spice.NetlistError, match=match):
        spice.read("title\n" + body)


@pytest.mark.slow
def test_a_node_with_one_connection_carries_no_current_as_in_spice():
    """A voltage source alone at a node sets it and carries 0 A; a resistor alone passes
    its other end's voltage; a capacitor alone keeps its charge, and its node, which has
    no DC path, gets ngspice's GMIN to ground (a note says so)."""
    netlist = spice.read(
        "lonely\nV1 a 0 SIN(0 1 1k)\nV2 b 0 2\nR1 b c 1k\nR2 b 0 1k\n"
        "C1 b d 1u\n.tran 10u 2m\n.end\n"
    )
    assert any("node 'd' has no DC path to ground" in n and "1e-12 S" in n for n in netlist.notes)
    result = spice.run(netlist)
    t = result.time
    np.testing.assert_allclose(result["v(a)"], np.sin(2 * np.pi * 1e3 * t), atol=1e-4)
    assert np.max(np.abs(result["i(V1)"])) <= 1e-15
    np.testing.assert_allclose(result["v(c)"], 2.0, rtol=1e-12)
    # C1 (charged to 2 V by the operating point through GMIN) holds: v(d) = 0 after
    np.testing.assert_allclose(result["v(d)"], 0.0, atol=1e-6)


def test_a_subcircuits_floating_node_gets_its_gmin_too():
    """A node inside a subcircuit (``x1.d``) with only a capacitor to the rest gets GMIN
    as a top-level one does (a part's name holds no dot; the CircuitSim90 deck gm1 was
    refused over it)."""
    netlist = spice.read(
        "sub\n.subckt cap a\nC1 a d 1u\nR1 d e 1k\n.ends\nV1 b 0 1\nX1 b cap\n.tran 10u 1m\n.end\n"
    )
    assert any("node 'x1.d' has no DC path to ground" in n for n in netlist.notes)
    assert sum(p.name.startswith("gmin:x1") for p in netlist.circuit.parts) == 2


_TOKENS = st.sampled_from(
    ["R1", "C2", "L3", "V4", "I5", "D6", "K7", "X8", "Q9", "E1", "a", "b", "0", "gnd",
     "1k", "2u", "-3", "{1+}", "{x}", "'2*3'", "(", ")", "=", "IC=1", "DC", "SIN", "PULSE",
     "PWL", ".tran", ".ic", ".param", ".model", ".end", ".subckt", ".ac", "+", "*", ";",
     "v(a)=1", "D(IS=1e-14)", "1meg", "uic", "", "\t", "é", "1e999", ".ends", "params:",
     "x=2", "sub", ".control", ".endc", "tran", ".save", "@r1[i]", "AC", ".global", ".op",
     ".include", ".lib", ".temp", "27", "NPN", ".options"]
)  # fmt: skip


@examples(25)
@given(st.lists(st.lists(_TOKENS, max_size=7).map(" ".join), min_size=1, max_size=6))
def test_fuzzed_netlists_read_or_fail_with_a_netlist_error(lines):
    try:
        spice.read("fuzz\n" + "\n".join(lines) + "\n")
    except spice.NetlistError as exc:
        text = str(exc)
        assert "line " in text or "node" in text or "netlist" in text, text


@st.composite
def _ladders(draw):
    """A resistor ladder from node 1 to ground with one defect drawn on top."""
    n = draw(st.integers(2, 5))
    lines = [f"R{k} n{k} n{k + 1} 1k" for k in range(1, n)] + [f"R{n} n{n} 0 1k", "V1 n1 0 1"]
    defect = draw(st.sampled_from(["vloop", "icut", "float", "island", "none"]))
    j = draw(st.integers(1, n))
    if defect == "vloop":
        lines.append("V2 n1 0 2")
    elif defect == "icut":  # node z hangs between two current sources
        lines += ["I1 z 0 1m", f"I2 n{j} z 2m"]
    elif defect == "float":
        lines.append(f"R99 n{j} dangling 1k")
    elif defect == "island":
        lines += ["R98 p q 1", "R99 q p 1"]
    return defect, "title\n" + "\n".join(draw(st.permutations(lines))) + "\n"


@examples(15)
@given(_ladders())
def test_fuzzed_topology_defects_are_named(case):
    defect, text = case
    expected = {
        "vloop": "loop of voltage sources",
        "icut": "cut-set of current sources",
        "island": "are floating",
    }
    if defect in ("none", "float"):  # a dangling resistor is accepted, as in SPICE
        assert spice.read(text).assembly.nodes
        return
    with pytest.raises(spice.NetlistError, match=expected[defect]):
        spice.read(text)


# ------------------------------------------------------------- agreement with ngspice
def _errors(name, dt):
    """Max error over t > 0 of each probe relative to its peak, diracvi midpoint vs the
    committed ngspice run. (At t = 0 SPICE's UIC point is the given state, not a solved
    one, and diracvi's is extrapolated; neither is an independent check.)"""
    netlist, probes, _ = ng.CIRCUITS[name]
    t, ref = ng.load(name)
    result = spice.run(netlist, dt=dt, steps=round(t[-1] / dt))
    idx = np.rint(t / dt).astype(int)
    assert np.allclose(result.time[idx], t, rtol=0, atol=1e-9 * t[-1])
    return np.array(
        [np.max(np.abs(result[p][idx] - ref[p])[1:]) / np.max(np.abs(ref[p])) for p in probes]
    )


@pytest.mark.parametrize(
    "name",
    [
        pytest.param("rc", marks=pytest.mark.slow),
        "rlc",
        "coupled",
        "rectifier",
        pytest.param("bridge", marks=pytest.mark.slow),
    ],
)
def test_validation_circuits_agree_with_ngspice(name):
    # (rc runs by default through the command line: test_cli_runs_a_netlist_…)
    assert np.all(_errors(name, ng.CIRCUITS[name][2]) <= 1e-3)


@pytest.mark.parametrize(
    "name",
    ["ladder", *(pytest.param(n, marks=pytest.mark.slow) for n in ("rc", "rlc", "coupled"))],
)
def test_convergence_at_second_order_against_a_fine_ngspice_run(name):
    dt = ng.CIRCUITS[name][2]
    # steps that divide the reference's sampling interval (TSTOP/100)
    hs = [2 * dt, dt] if name == "ladder" else [dt, dt / 2, dt / 4]
    errors = np.array([_errors(name, h) for h in hs])
    assert np.all(errors[hs.index(dt)] <= 1e-3)  # the agreement at the test's dt
    for column in errors.T:
        assert 1.8 < loglog_slope(hs, column) < 2.3


@pytest.mark.slow
def test_rectifier_converges_at_second_order():
    hs = [4e-5, 2e-5, 1e-5]
    errors = np.array([_errors("rectifier", h) for h in hs])
    for column in errors.T:
        assert 1.7 < loglog_slope(hs, column) < 2.4


def test_cli_runs_a_netlist_and_writes_spice_names(tmp_path):
    netlist, _, _ = ng.CIRCUITS["rc"]
    path = tmp_path / "rc.cir"
    path.write_text(netlist)
    out = tmp_path / "rc.nc"
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(out)])
    assert res.exit_code == 0, res.output
    ds = xr.open_dataset(out)
    # the saved vectors, as ngspice saves them without .save: nodes and source currents
    assert set(ds.data_vars) == {"v(in)", "v(out)", "i(v1)"}
    assert ds.attrs["discretization"] == "midpoint"
    # the RC circuit's agreement with ngspice, as for the others below (t > 0, ≤ 1e-3 peak)
    t, ref = ng.load("rc")
    for probe in ("v(out)", "i(V1)"):
        got = np.interp(t, ds["time"].values, ds[probe.lower()].values)
        assert np.max(np.abs(got - ref[probe])[1:]) <= 1e-3 * np.max(np.abs(ref[probe]))
    ds.close()


def test_cli_reports_a_bad_netlist_by_line(tmp_path):
    path = tmp_path / "bad.cir"
    path.write_text("title\nR1 a 0 1k\nM1 d g s b nmos\n.tran 1u 1m\n")
    res = CliRunner().invoke(app, ["run", str(path)])
    assert res.exit_code != 0
    assert "line 3" in res.output and "M1" in res.output
    assert "Traceback" not in res.output


def test_a_one_step_run_is_refused_with_the_fix(tmp_path):
    # the first node voltage is extrapolated from the steps after t0: one step has none
    netlist, _, _ = ng.CIRCUITS["rc"]
    with pytest.raises(ValueError, match=r"at least 2 steps.*has 1 \(dt=0\.005\).*smaller dt"):
        spice.run(netlist, dt=5e-3)
    path = tmp_path / "rc.cir"
    path.write_text(netlist)
    for extra in (["--out", str(tmp_path / "rc.nc")], ["--plot"]):
        res = CliRunner().invoke(app, ["run", str(path), "--steps", "1", *extra])
        assert res.exit_code != 0 and "smaller dt" in res.output, res.output
        assert "Traceback" not in res.output


def test_output_holds_the_saved_vectors_proportionately(monkeypatch):
    """A fixed-step run's dataset: the ``.save`` vectors only; beyond ``SEPARATE_MAX``
    vectors one ``vectors(time, vector)`` variable with the same values; the
    trajectory's states dropped beyond ``STATES_MAX`` coordinates (diagnostics kept)."""
    from diracvi.spice import _run

    netlist, _, _ = ng.CIRCUITS["rc"]
    deck = netlist.replace(".tran", ".save v(out) i(R1)\n.tran")
    result = spice.run(deck, dt=1e-5, steps=50)
    ds = result.to_xarray()
    assert {"v(out)", "i(r1)"} <= set(ds.data_vars) and "v(in)" not in ds.data_vars
    assert "q" in ds.data_vars and "energy" in ds.data_vars
    monkeypatch.setattr(_run, "SEPARATE_MAX", 1)
    monkeypatch.setattr(_run, "STATES_MAX", 1)
    ds = result.to_xarray()
    assert list(ds["vector"].values) == list(result) == ["v(out)", "i(r1)"]
    for name in result:
        np.testing.assert_array_equal(ds["vectors"].sel(vector=name).values, result[name])
    assert "q" not in ds.data_vars and "energy" in ds.data_vars
    assert ds.attrs["vectors"] == "vectors(time, vector)"


def test_host_waveforms_equal_the_traced_path():
    """``spice.waveforms`` forms a host trajectory's signals all at once (one gather per
    kind) and a traced one signal by signal in JAX: two codings of the same formulas
    (node voltages from the KCL multipliers, currents from the charges, both ends
    extrapolated), which must agree to round-off on every signal, ends included."""
    import jax

    import diracvi as dv
    from diracvi.bench.ladders import ladder
    from diracvi.spice import waveforms

    netlist = spice.read(ladder(4, steps=20))
    traj = dv.simulate(
        netlist.system, netlist.q0, netlist.p0, dt=netlist.dt, steps=netlist.steps,
        discretization="midpoint",
    )  # fmt: skip
    host = waveforms(netlist, traj)
    traced = jax.jit(lambda tr: waveforms(netlist, tr))(traj)
    assert sorted(host) == sorted(traced) and len(host) == 9 + 13  # 9 nodes, 13 currents
    for key, values in host.items():
        peak = float(np.max(np.abs(values)))
        np.testing.assert_allclose(values, traced[key], rtol=0, atol=1e-13 * peak, err_msg=key)
