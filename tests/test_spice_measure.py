""".measure tran: against closed forms (ngspice's own unedited measure deck, whose sources
are sines; an RC step), against ngspice's printed measurements on a nonlinear deck, and the
reader's errors."""

from __future__ import annotations

import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from diracvi import spice
from diracvi.spice._ngspice import available

DATA = Path(__file__).parent / "data" / "netlists"
needs_ngspice = pytest.mark.skipif(not available(), reason="ngspice is not installed")


def _crossings(f, t0, t1, n=200_001):
    """``[(kind, t)]`` of ``f`` through 0 on ``[t0, t1]``, by a fine scan and Brent's
    method (independent of the code under test)."""
    t = np.linspace(t0, t1, n)
    y = f(t)
    out = []
    for k in np.nonzero(np.sign(y[1:]) != np.sign(y[:-1]))[0]:
        if y[k + 1] == 0.0:
            continue
        root = brentq(f, t[k], t[k + 1], xtol=1e-15)
        out.append(("rise" if y[k + 1] > y[k] else "fall", root))
    return out


def _nth(crossings, kind, n):
    chosen = [t for k, t in crossings if kind in (None, "cross", k)]
    return chosen[-1] if n == "last" else chosen[n - 1]


def _by_line(result):
    return {m.line: m for m in result.measurements}


def test_ngspice_measure_deck_against_closed_forms():
    """ngspice's example `simple-meas-tran.sp` (unedited): its two sources are sines, so
    every measurement has a closed form. diracvi at the deck's own settings against them:
    times to 2e-8 s (a 50 000th of the 1 kHz period; ngspice at these settings is 1e-8 off
    on TRIG, 4e-4 on FIND), values to 1e-4 of the 1 V amplitude."""
    result = spice.run(DATA / "ng_simple_meas_tran.sp")
    got = _by_line(result)
    v1 = lambda t: np.sin(2 * np.pi * 1e3 * t)  # noqa: E731
    v2 = lambda t: 1.2 * np.sin(2 * np.pi * 900 * t)  # noqa: E731
    stop = 5e-3

    def c(f, val, t0=0.0):
        return _crossings(lambda t: f(t) - val, t0, stop)

    trig = _nth(c(v1, 0.5), "rise", 1)
    times = {
        "line 9": _nth(c(v1, 0.5), "rise", 2) - trig,
        "line 10": _nth(c(v1, 0.5), "rise", 3) - trig,
        "line 11": _nth(c(v1, 0.5), "fall", 1) - trig,
        "line 12": _nth(c(v2, 0.0), "fall", 3) - _nth(c(v1, 0.0), "fall", 3),
        "line 13": _nth(c(v2, -0.8), "cross", 1) - _nth(c(v1, -0.6), "cross", 1),
        "line 14": _nth(c(v2, -0.8), "cross", 3) - 1e-3,
        "line 15": _nth(c(v2, 0.7), "cross", "last"),
    }
    for line, want in times.items():
        assert got[line].value == pytest.approx(want, abs=2e-8), (line, got[line])
    # TRIG/TARG print both times
    assert got["line 9"].extras["trig"] == pytest.approx(trig, abs=2e-8)
    # lines 16 and 17 (v(2) = v(1), the last FALL, the last CROSS): v(2) − v(1) reaches 0
    # exactly at TSTOP = 5 ms (both sines are 0 there), falling, so the last crossing
    # touches the run's end; within the waveforms' accuracy it is there or not, and the
    # one before it (3.94 ms for the FALL, 4.47 ms for the CROSS) is taken: ngspice at
    # the deck's settings reports the earlier ones
    d = lambda t: v2(t) - v1(t)  # noqa: E731
    inner = _crossings(d, 0.0, stop - 1e-7)
    for line, kind in (("line 16", "fall"), ("line 17", "cross")):
        either = (stop, _nth(inner, kind, "last"))
        assert min(abs(got[line].value - w) for w in either) <= 2e-8, (line, got[line])
    t_when = _nth(c(v1, 0.2), "fall", 2)
    values = {
        "line 18": v2(t_when),
        "line 19": v2(2e-3),
        "line 20": 1.2,  # MAX of v(2) over [2, 3] ms
        "line 22": 2.0,  # PP of v(1) over [2, 4] ms
        "line 23": 1 / math.sqrt(2),  # RMS of v(1) over 1.5 periods
        "line 24": 0.0,  # AVG of v(1) over 2 periods
        # INTEG of v(2) over [2, 3] ms
        "line 25": 1.2 / (2 * np.pi * 900) * (np.cos(2 * np.pi * 1.8) - np.cos(2 * np.pi * 2.7)),
        "line 27": 12.0,  # PARAM 'fval + 7'
        "line 29": 1.0,  # PARAM '(vout_diff < 100k) ? 1 : 0'
        "line 30": v1(2.3e-3) * v2(2.3e-3),  # FIND par('v(2)*v(1)') AT=2.3m
    }
    for line, want in values.items():
        assert got[line].value == pytest.approx(want, abs=1e-4), (line, got[line])
    assert got["line 25"].value == pytest.approx(values["line 25"], rel=1e-4)
    # MAX_AT: v(2)'s peak in [2, 3] ms is at 2.25 periods of 900 Hz
    assert got["line 21"].value == pytest.approx(2.25 / 900, abs=2e-7)
    assert got["line 20"].extras["at"] == pytest.approx(2.25 / 900, abs=2e-7)
    assert [m.failed for m in result.measurements] == [None] * len(result.measurements)


RC = """RC step, measured
V1 in 0 DC 1
R1 in out 1k
C1 out 0 1u
.tran 10u 5m uic
.meas tran trise TRIG v(out) VAL=0.1 RISE=1 TARG v(out) VAL=0.9 RISE=1
.meas tran t50 WHEN v(out)=0.5
.meas tran late WHEN v(out)=0.5 TD=2m
.meas tran vavg AVG v(out) FROM=1m TO=3m
.meas tran q INTEG i(v1)
.meas tran imin MIN i(v1)
.meas tran tmid WHEN v(in,out)=v(out) CROSS=LAST
.meas tran ratio PARAM='trise / t50'
.meas tran v3 FIND v(out) AT=3m
.meas ac ignored MAX v(out)
.end
"""


def test_rc_step_measurements_against_the_exact_solution():
    """v(out) = 1 − e^{−t/τ}, τ = 1 ms, and i(V1) = −(1/R) e^{−t/τ} (SPICE's sign: the
    current into the source's + node): rise time τ ln 9, half time τ ln 2; a crossing
    that never comes after TD fails with the reason; INTEG of the source current is
    −C·v(out)(TSTOP); AVG, MIN (at t = 0), FIND … AT, WHEN between two vectors, PARAM."""
    tau, stop = 1e-3, 5e-3
    result = spice.run(RC)
    m = {x.name: x for x in result.measurements}
    assert m["trise"].value == pytest.approx(tau * math.log(9), rel=1e-4)
    assert m["trise"].extras["trig"] == pytest.approx(-tau * math.log(0.9), rel=1e-4)
    assert m["t50"].value == pytest.approx(tau * math.log(2), rel=1e-4)
    assert m["late"].value is None and "no crossing v(out)=0.5" in m["late"].failed
    exact_avg = 1 - tau / 2e-3 * (math.exp(-1) - math.exp(-3))
    assert m["vavg"].value == pytest.approx(exact_avg, rel=1e-4)
    assert m["vavg"].extras == {"from": 1e-3, "to": 3e-3}
    assert m["q"].value == pytest.approx(-1e-6 * (1 - math.exp(-stop / tau)), rel=1e-4)
    assert m["imin"].value == pytest.approx(-1e-3, rel=1e-4)
    assert m["imin"].extras["at"] == pytest.approx(0.0, abs=1e-9)
    # v(in) − v(out) = v(out) once only: at the half time
    assert m["tmid"].value == pytest.approx(tau * math.log(2), rel=1e-4)
    assert m["ratio"].value == pytest.approx(math.log(9) / math.log(2), rel=2e-4)
    assert m["v3"].value == pytest.approx(1 - math.exp(-3), rel=1e-5)
    assert "ignored" not in m  # .meas ac: noted, not measured
    assert any(".measure ac ignored" in n for n in result.netlist.notes)


def test_malformed_measure_lines_are_noted_and_skipped_as_ngspice_does():
    """ngspice 39 prints "measure … failed" for each measure line it cannot read and runs
    the rest: each bad line here is noted (its line, what is wrong, its text), measured as
    failed with that reason (never a value), and the good lines are measured."""
    deck = RC.replace(
        ".end",
        ".meas tran a TRIG v(out) VAL=0.1 RISE=1\n"
        ".meas tran b WHEN v(nowhere)=1\n"
        ".meas tran c DERIV v(out) AT=1m\n"
        ".meas tran d MAX i(r1)\n"
        ".meas tran e AVG v(out) FROM=3m TO=1m\n"
        ".meas tran f FIND v(out AT=1m\n"
        ".end",
    )
    result = spice.run(deck)
    notes = "\n".join(result.netlist.notes)
    expected = {
        16: "line 16: .measure a: TRIG needs a TARG",
        17: "line 17: .measure b: no such vector v(nowhere)",
        18: "line 18: .measure c: function 'DERIV' is not supported (ngspice 39",
        19: "line 19: .measure d: no such vector i(r1)",
        20: "line 20: .measure e: TO=0.001 must be after FROM=0.003",
        21: "line 21: unbalanced parentheses",
    }
    lines = deck.splitlines()
    for number, start in expected.items():
        note = next(n for n in result.netlist.notes if n.startswith(f"line {number}: "))
        assert note.startswith(start), notes
        assert note.endswith(lines[number - 1]) and "skipped" in note, note
    got = _by_line(result)
    for number in expected:
        m = got[f"line {number}"]
        assert m.value is None and m.failed.startswith("not read: "), m
    # the good lines are measured as before: the half time τ ln 2
    assert got["line 7"].value == pytest.approx(1e-3 * math.log(2), rel=1e-4)
    assert got["line 13"].value == pytest.approx(math.log(9) / math.log(2), rel=2e-4)


GOOD_AND_BAD = """good and malformed .measure lines (two sines, ngspice's buggy-meas-tran)
vac1 1 0 DC 0 sin(0 1 1k 0 0)
R1 1 0 100k
vac2 2 0 DC 0 sin(0 1.2 0.9k 0 0)
.tran 10u 5m
.measure tran tdiff RIG v(1) VAL=0.5 RISE=1 TARG v(1) VAL=0.5 RISE=3
.measure tran tgood TRIG v(1) VAL=0.5 RISE=1 TARG v(1) VAL=0.5 RISE=2
.measure tran tbad TRIG v(1 VAL=0.5 RISE=1 TARG v(1) VAL=0.5 FALL=1
.measure tran yeval FIND v(2) WHEN v(1)=0.2 FALL=2
.measure tran ybad FIND v(2) AT=2 m
.measure tran ypp PP v(1) from=2m to=4m
.measure tran yrms RMS v() from=2m to=3.5m
.measure tran yavg AVG v(1) from 2m to=4m
.measure tran ymax MAX v(2) from=2m to=3m
.measure tran ymax MAX v(2) fro m=2m to=3m
.end
"""


@needs_ngspice
def test_good_measures_beside_malformed_ones_agree_with_ngspice(tmp_path):
    """Each malformed line (6, 8, 10, 12, 13, 15) noted with its line number and failed; each
    good one equal to what ngspice 39 prints for the same deck (run finely, so its own
    time points do not limit it): times to 2e-7 s, values to 1e-3 of the 1.2 V peak."""
    out = _ngspice_printout(GOOD_AND_BAD, ".tran 10u 5m", "0.2u", tmp_path)
    block = out.split("Total analysis", 1)[0]
    want = {name: float(v) for name, v in re.findall(r"^(\w+)\s+=\s+(\S+)", block, re.M)}
    assert set(want) == {"tgood", "yeval", "ypp", "ymax"}, out  # ngspice skips the rest
    result = spice.run(GOOD_AND_BAD)
    for number in (6, 8, 10, 12, 13, 15):
        assert any(n.startswith(f"line {number}: ") for n in result.netlist.notes), number
    got = {m.name: m for m in result.measurements if m.failed is None}
    assert set(got) == set(want)
    failed = [m for m in result.measurements if m.failed is not None]
    assert [m.line for m in failed] == [f"line {n}" for n in (6, 8, 10, 12, 13, 15)]
    assert all(m.value is None and m.failed.startswith("not read: ") for m in failed)
    assert got["tgood"].value == pytest.approx(want["tgood"], abs=2e-7)
    for name in ("yeval", "ypp", "ymax"):
        assert got[name].value == pytest.approx(want[name], abs=1.2e-3), name
    # the file's measure_<name>: a good line's value, a bad line's reason, never a number
    attrs = result.to_xarray().attrs
    assert attrs["measure_tgood"] == got["tgood"].value
    assert attrs["measure_ybad"].startswith("failed: not read: .measure ybad: 'm' is not")
    # a bad line of a good one's name leaves its value (ngspice prints the good one)
    assert attrs["measure_ymax"] == got["ymax"].value


def test_cli_prints_the_measurements_and_the_file_keeps_them(tmp_path):
    from typer.testing import CliRunner

    from diracvi.cli import app

    deck = tmp_path / "rc.cir"
    deck.write_text(RC)
    out = tmp_path / "rc.nc"
    ran = CliRunner().invoke(app, ["run", str(deck), "--out", str(out)])
    assert ran.exit_code == 0, ran.output
    assert re.search(r"^t50 +=  ?6\.93\d+e-04$", ran.output, re.M), ran.output
    assert re.search(r"^late +failed \(line 8\): no crossing v\(out\)=0\.5", ran.output, re.M)
    import xarray as xr

    with xr.open_dataset(out) as ds:
        assert ds.attrs["measure_t50"] == pytest.approx(math.log(2) * 1e-3, rel=1e-4)
        assert ds.attrs["measure_late"].startswith("failed: no crossing")


HALFWAVE = """Half-wave rectifier with a smoothing capacitor, measured
V1 in 0 SIN(0 5 1k)
D1 in out dmod
R1 out 0 1k
C1 out 0 2u
.model dmod D(IS=1e-14 N=1.5 RS=2)
.tran 5u 4m
.meas tran vpk MAX v(out) FROM=2m TO=3m
.meas tran vlow MIN v(out) FROM=2m TO=3m
.meas tran ripple PP v(out) FROM=2m TO=4m
.meas tran tcharge WHEN v(out)=3.5 RISE=2
.meas tran ion TRIG v(in) VAL=3.5 RISE=2 TARG v(out) VAL=3.5 RISE=2
.meas tran vdrms RMS par('v(in)-v(out)') FROM=2m TO=4m
.meas tran vmean AVG v(out) FROM=2m TO=4m
.end
"""


def _ngspice_printout(deck: str, tran: str, tmax: str, tmp_path) -> str:
    """What ngspice 39 prints for the deck run at fine settings (reltol 1e-7, the deck's
    ``.tran TSTEP TSTOP`` line, given as ``tran``, with TMAX = TSTEP/50 as ``tmax``), so
    its own time points do not limit its measurements."""
    fine = deck.replace(tran, f"{tran} 0 {tmax}\n.options reltol=1e-7")
    path = tmp_path / "deck.cir"
    path.write_text(fine)
    return subprocess.run(
        ["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=120, check=True
    ).stdout


def _ngspice_measurements(deck: str, tmp_path) -> dict:
    """ngspice 39's printed measurements of the deck (:func:`_ngspice_printout`)."""
    out = _ngspice_printout(deck, ".tran 5u 4m", "0.1u", tmp_path)
    block = out.split("Measurements for Transient Analysis", 1)[1].split("Total analysis", 1)[0]
    assert "failed" not in block, block
    found = re.findall(r"^(\w+)\s+=\s+(\S+)", block, re.M)
    return {name: float(value) for name, value in found}


@needs_ngspice
def test_a_rectifiers_measurements_agree_with_ngspice(tmp_path):
    """A diode circuit (no closed form) at the deck's own settings against ngspice's
    printed measurements at fine settings: times to 2e-7 s (a 5000th of the period),
    values to 1e-3 of their scale (the deck's RELTOL)."""
    want = _ngspice_measurements(HALFWAVE, tmp_path)
    got = {m.name: m for m in spice.run(HALFWAVE).measurements}
    assert set(want) == set(got), (want, got)
    for name in ("tcharge", "ion"):
        assert got[name].value == pytest.approx(want[name], abs=2e-7), name
    for name in ("vpk", "vlow", "ripple", "vmean"):
        assert got[name].value == pytest.approx(want[name], abs=1e-3 * 5), name
    assert got["vdrms"].value == pytest.approx(want["vdrms"], rel=1e-3)
