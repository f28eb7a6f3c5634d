"""A ``.control`` block's ``tran`` with control-language variables (``spice/_control.py``):
``$&name`` of a ``let`` or a ``.csparam``, ``$name`` of a ``set``, each compared with
ngspice 39 run on the same deck (its ``option interp`` output is the TSTEP grid, so the
raw file's times are ``k·TSTEP`` and end at TSTOP: the TSTEP and TSTOP ngspice ran);
and the refusals, each naming the line, the value and the fix."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import _corpus as corpus
from diracvi import spice
from diracvi.spice._ngspice import available

needs_ngspice = pytest.mark.skipif(not available(), reason="ngspice is not installed")

CIRCUIT = """control-language variables in a tran
.param tend = 1/3*1e-6
.csparam tst = {tend}
V1 1 0 sin(0 1 1e7)
R1 1 2 1k
C1 2 0 1p
"""


def _ngspice_times(tmp_path, deck: str) -> tuple[np.ndarray, str]:
    """The times of ngspice's first plot for ``deck`` run with ``option interp`` ahead of
    its commands (its output on the TSTEP grid), and what ngspice printed."""
    raw = tmp_path / "out.raw"
    text = deck.replace(".control\n", ".control\noption interp\n", 1).replace(
        ".endc\n", f"setplot tran1\nwrite {raw} time v(2)\n.endc\n"
    )
    path = tmp_path / "deck.cir"
    path.write_text(text)
    proc = subprocess.run(
        ["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    out = proc.stdout + proc.stderr
    if not raw.exists():
        return np.array([]), out
    _, data = corpus.read_raw(raw)
    return data[:, 0], out


def _grid_of(times: np.ndarray, net) -> None:
    """ngspice's interpolated times are consecutive ``k·TSTEP`` (from 0, or from TSTEP
    with UIC, where ngspice 39's interpolated file leaves t = 0 out), TSTOP last."""
    k = np.round(times[:-1] / net.dt)
    assert k[0] == (1 if net.uic else 0) and np.all(np.diff(k) == 1)
    assert np.allclose(times[:-1], k * net.dt, rtol=1e-13, atol=0.0)
    # TSTOP to the last bit but one: ngspice scales 100n as 100·1e-9 (ft_numparse)
    assert times[-1] == pytest.approx(net.stop, rel=3e-16, abs=0.0)
    assert times[-2] < net.stop <= times[-2] + net.dt


@needs_ngspice
def test_vectors_of_let_and_csparam_give_the_tran_ngspice_runs(tmp_path):
    """``$&name``: a .csparam (a .param's value) and lets over it, written with six
    digits (%G) as ngspice writes them: TSTOP 1/3 µs runs as 3.33333e-7, TSTEP as
    4.7619e-8. A let before the op is in the const plot, seen after it; a let after it,
    in the op's plot, is seen by the tran (no analysis between)."""
    deck = CIRCUIT + (
        ".control\nlet early = 20n\nop\nlet stp = tst/7\n"
        "tran $&stp $&tst 0 $&early uic\ntran 1n 2n\n.endc\n.end\n"
    )
    net = spice.read(deck)
    assert (net.dt, net.stop, net.tmax, net.uic) == (4.7619e-8, 3.33333e-7, 2e-8, True)
    assert net.dt != (1 / 3 * 1e-6) / 7  # the rounded value, not the let's own
    said = next(n for n in net.notes if "read as" in n)
    assert "'tran 4.7619E-08 3.33333E-07 0 2E-08 uic'" in said and "line 10" in said
    assert any("line 12: a further 'tran'" in n and "first, line 11" in n for n in net.notes)
    times, out = _ngspice_times(tmp_path, deck)
    assert len(times) == 7, out  # 1 … 6·TSTEP, TSTOP = 7·TSTEP
    _grid_of(times, net)


@needs_ngspice
def test_set_variables_give_the_tran_ngspice_runs(tmp_path):
    """``$name``: a ``set`` number is written %G (1.23456789n runs as 1.23457e-9), a
    quoted one as written ("100n")."""
    deck = CIRCUIT + (
        '.control\nset tstep = 1.23456789n\nset tstop = "100n"\ntran $tstep $tstop\n.endc\n.end\n'
    )
    net = spice.read(deck)
    assert (net.dt, net.stop, net.uic) == (1.23457e-9, 1e-7, False)
    times, out = _ngspice_times(tmp_path, deck)
    assert len(times) == 82, out  # 0 … 80·TSTEP, then TSTOP
    _grid_of(times, net)


@needs_ngspice
def test_a_let_of_a_replaced_plot_is_refused_as_ngspice_does_not_see_it(tmp_path):
    """A let made after the op lands in the op's plot; the ac after it makes a new current
    plot where ngspice does not find it ("no such variable") and runs no tran."""
    deck = CIRCUIT + (".control\nop\nlet stp = 1n\nac lin 3 1 10\ntran $&stp $&tst\n.endc\n.end\n")
    with pytest.raises(spice.NetlistError) as err:
        spice.read(deck)
    text = str(err.value)
    assert "line 11: '$&stp': no vector 'stp' at this tran" in text
    assert "its let, line 9, is in a plot an analysis after it replaced" in text
    times, out = _ngspice_times(tmp_path, deck)
    assert "&stp: no such variable" in out and len(times) == 0


@needs_ngspice
def test_a_let_vector_read_as_a_set_variable_is_refused_as_ngspice_drops_it(tmp_path):
    """``$name`` is a ``set`` variable: of a ``let`` vector ngspice says "no such
    variable" and drops the word; diracvi refuses it, naming ``$&name``."""
    deck = CIRCUIT + ".control\nlet stp = 1n\ntran $stp $&tst\n.endc\n.end\n"
    with pytest.raises(spice.NetlistError, match=r"line 9: '\$stp': no 'set stp = …'.*'\$&stp'"):
        spice.read(deck)
    _, out = _ngspice_times(tmp_path, deck)
    assert "stp: no such variable" in out


@pytest.mark.parametrize(
    ("lets", "why"),
    [
        ("", r"'\$&stp': no vector 'stp' at this tran; define it before the tran with 'let stp"),
        (
            "let stp = v(1)",
            r"'\$&stp': its value is not known before the run \(line 8: 'let "
            r"stp = v\(1\)' is not a number \(a vector of a run, or a list\)",
        ),
        ("let stp = vector(3)", r"line 8: 'let stp = vector\(3\)' is not a number"),
        ("let a = v(2)\nlet stp = a/2", r"line 9: 'let stp = a/2' reads 'a' \(line 8: 'let a"),
        ("let stp[0] = 1n", r"line 8: 'let stp\[0\] = …' sets an element of a vector"),
        ("if 1\nlet stp = 1n\nend", r"line 9: the let is inside an if/while"),
        ("let stp = 1n\nunlet stp", r"no vector 'stp' at this tran"),
        ("let stp = 1n\nsetplot const", r"a setplot \(line 9\) comes before the tran"),
    ],
)
def test_a_tran_variable_diracvi_cannot_give_is_refused_naming_it(lets, why):
    deck = CIRCUIT + f".control\n{lets}\ntran $&stp $&tst\n.endc\n.end\n"
    with pytest.raises(spice.NetlistError, match=why) as err:
        spice.read(deck)
    assert "tran $&stp $&tst" in str(err.value)  # the line itself is shown


def test_what_is_not_applied_or_skipped_is_noted():
    deck = CIRCUIT.replace(".csparam tst = {tend}", ".csparam tst = {tend} junk") + (
        ".control\nalter R1 2k\nlet stp = 1n\ntran $&stp 10n\n.endc\n.end\n"
    )
    net = spice.read(deck)
    assert (net.dt, net.stop) == (1e-9, 1e-8)
    notes = "\n".join(net.notes)
    assert "line 3: .csparam: 'junk' is not name=value; the line is skipped" in notes
    assert "line 8: 'alter R1 2k' before the .control block's tran is not applied" in notes
    # an unused let with no value before the run is ignored, as the rest of the block
    net = spice.read(deck.replace("let stp = 1n", "let stp = 1n\nlet res = v(1)/i(v1)"))
    assert net.dt == 1e-9


def test_the_corpus_tool_reads_the_same_tran():
    """``tests/_corpus.py``'s ``find_tran`` (the fine reference's tran) resolves the same
    forms to the same numbers as the reader."""
    for control in (
        "let early = 20n\nop\nlet stp = tst/7\ntran $&stp $&tst 0 $&early uic",
        'set tstep = 1.23456789n\nset tstop = "100n"\ntran $tstep $tstop',
    ):
        deck = CIRCUIT + f".control\n{control}\ntran 1n 2n\n.endc\n.end\n"
        net, tran = spice.read(deck), corpus.find_tran(deck)
        assert (tran.tmax, tran.uic) == (net.tmax, net.uic)
        assert (tran.step, tran.stop) == pytest.approx((net.dt, net.stop), rel=3e-16, abs=0.0)
    with pytest.raises(ValueError, match=r"\$&nope"):
        corpus.find_tran(CIRCUIT + ".control\ntran $&nope 1n\n.endc\n.end\n")


@pytest.mark.parametrize("name", ["ng_memristor", "ng_memristor_x"])
def test_the_memristor_decks_tran_and_csparams_are_read(name):
    """ngspice's memristor examples (corpus, unedited): their ``tran $&deltime $&stime uic``
    is ngspice's first tran, 1e-10 1e-8 uic (``let deltime = stime/100``, ``.csparam
    stime={stime}``, ``.param stime=10n``). Both are read whole: ``ng_memristor``'s braces in
    a B expression and its subcircuit's ``.func`` since branch memfix, ``ng_memristor_x``'s
    XSPICE device since branch memristor."""
    deck = corpus.DATA / f"{name}.sp"
    assert corpus.find_tran(deck.read_text()) == corpus.Tran(1e-10, 1e-8, 0.0, None, True)
    net = spice.read(deck)
    assert (net.dt, net.stop, net.uic) == (1e-10, 1e-8, True)
