"""ngspice's ``.probe`` vectors: the voltage differences ``vd(…)`` under ngspice's names.

ngspice (``src/frontend/inpc_probe.c``) writes ``vd(R1)``, ``vd(a, b)``, ``vd(M1:d:s)``,
``vd(M1:g, D1:a)``, ``vd(M1:2:0)`` as the node ``vd_…`` of an E source of gain 1; a deck
holding each form is run by ngspice 39 and by diracvi, and every ``v(vd_…)`` vector
ngspice writes must be one of diracvi's, by the same name, with the same values (a
swapped sign, a wrong pin or name fails), and none of diracvi's may be missing from
ngspice's. ``i(R2)`` is the resistor's current under ngspice's 0 V source at its second
node: the same sign as diracvi's ``i(R2)``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import _corpus as corpus
from diracvi import spice
from diracvi.bench.ladders import ladder
from diracvi.spice import _stream

DECK = """probe forms against ngspice
V1 in 0 PULSE(0 5 0 10n 10n 100n 200n)
R1 in g 1k
Cg g 0 20p
M1 out g s 0 nm
R2 vdd out 2k
Vdd vdd 0 5
Rs s 0 100
D1 s 0 dd
C1 out 0 1p
.model nm nmos
.model dd d
.tran 5n 400n
.probe vd(R1) vd(in, out) vd(M1:d:s) vd(M1:g, D1:a) vd(M1:2:0) vd(D1) i(R2) v(out)
.probe i(m1:s) p(m1) vd(m1:9:0) vd(zz) vd(M1:1:1)
.end
"""

#: ngspice's names of the first .probe line's differences (checked against its run)
NAMES = {
    "v(vd_r1)": ("in", "g"),
    "v(vd_in:out)": ("in", "out"),
    "v(vd_m1:d:s)": ("out", "s"),
    "v(vd_m1:g_d1:a)": ("g", "s"),
    "v(vd_m1:g:0)": ("g", None),
    "v(vd_d1)": ("s", None),
}


def test_probe_differences_are_named_and_formed_as_ngspice_reads_them():
    net = spice.read(DECK)
    assert net.differences == NAMES
    saved = dict(net.vectors)
    # no .save: ngspice adds '.save all', so the default set is there beside the probes
    assert {"v(in)", "v(g)", "v(out)", "v(s)", "v(vdd)", "i(v1)", "i(vdd)"} <= set(saved)
    assert set(NAMES) <= set(saved) and saved["i(r2)"] == "i(R2)"
    notes = "\n".join(net.notes)
    for skipped in ("i(m1:s)", "p(m1)", "vd(m1:9:0)", "vd(zz)", "vd(m1:1:1)"):
        assert f"line 15: '.probe {skipped}'" in notes, skipped
    assert "'m1' has 4 pins, not 9" in notes
    assert "no instance 'zz'" in notes


def test_a_deck_with_a_save_saves_what_it_names_and_the_probes():
    # ngspice adds '.save all' only to a deck without .save (inpc_probe.c)
    net = spice.read(DECK.replace(".end", ".save v(s)\n.end"))
    assert [name for name, _ in net.vectors] == ["v(s)", *NAMES, "i(r2)", "v(out)"]


@pytest.mark.slow  # ~36 s wall at a load of ~13: ngspice's fine run and diracvi's
@pytest.mark.skipif(shutil.which("ngspice") is None, reason="ngspice is not installed")
def test_probe_vectors_are_ngspices(tmp_path: Path):
    deck = tmp_path / "probe.cir"
    deck.write_text(DECK)
    names, data, _ = corpus.run_ngspice(deck, timeout=300)
    t = data[:, 0]
    ng = {n: data[:, j] for j, n in enumerate(names) if j}
    theirs = {n for n in ng if n.startswith("v(vd_")}
    assert theirs == set(NAMES)
    result = spice.run(net := spice.read(DECK))
    mine = result.at(t)
    saved = dict(net.vectors)
    for name in [*NAMES, "i(r2)"]:
        values = ng[name]
        peak = max(np.max(np.abs(values)), corpus.VNTOL)
        error = np.max(np.abs(mine[saved[name]] - values)) / peak
        assert error <= corpus.TOL, (name, error)
    # the differences are those of diracvi's own node voltages, to round-off (formed at
    # the step centres, then sampled on the TSTEP grid as every signal is)
    for name, (a, b) in NAMES.items():
        plus, minus = result[f"v({a})"], result[f"v({b})"] if b else 0.0
        bound = 16 * np.finfo(float).eps * np.max(np.abs(plus) + np.abs(minus))
        assert np.max(np.abs(result[name] - (plus - minus))) <= bound, name


#: a 6-stage RLC ladder: 18 coordinates, the sparse maps, whose run streams when over
#: the budget (tests/test_stream.py)
LADDER = (
    ladder(6, steps=200)
    .replace("SIN(0 1 1000.0)", "PULSE(0 1 20u 5u 5u 40u 100u)")
    .replace(".tran", ".probe vd(R1) vd(n3, n1) vd(L2) vd(n4, 0)\n.tran")
)


@pytest.mark.slow  # two runs of a 6-stage ladder, ~4 s each
def test_a_streamed_run_forms_the_same_differences(monkeypatch):
    # a large circuit's run forms only the saved vectors while it steps (spice/_stream.py):
    # the .probe differences there are the whole run's, bit for bit
    whole = spice.run(LADDER)
    names = {"v(vd_r1)", "v(vd_n3:n1)", "v(vd_l2)", "v(vd_n4:0)"}
    assert names | {"v(n0)", "v(n6)", "i(v1)", "i(l6)"} <= set(whole)
    monkeypatch.setattr(_stream, "KEEP_MAX", 0)
    lean = spice.run(LADDER)
    assert lean.trajectory.q is None  # (streamed)
    assert list(lean) == list(whole)
    for key in whole:
        np.testing.assert_array_equal(lean[key], whole[key], err_msg=key)
    np.testing.assert_array_equal(whole["v(vd_n4:0)"], whole["v(n4)"])
    for name, (a, b) in {"v(vd_r1)": ("n0", "m1"), "v(vd_n3:n1)": ("n3", "n1"),
                         "v(vd_l2)": ("m2", "n2")}.items():  # fmt: skip
        plus, minus = whole[f"v({a})"], whole[f"v({b})"]
        bound = 16 * np.finfo(float).eps * np.max(np.abs(plus) + np.abs(minus))
        assert np.max(np.abs(whole[name] - (plus - minus))) <= bound, name
        assert np.max(np.abs(plus - minus)) > 1e-3, name  # not a trivial difference
