"""The level-2 MOSFET (ngspice's ``mos2``, Grove–Frohman): its static currents against
ngspice's ``.dc`` sweeps for the corpus decks' cards and cards with weak inversion,
velocity saturation, narrow width and short channels, in every region and both
polarities; each model parameter shown to matter; Meyer's capacitances with level 2's
``von`` and ``V_DSAT``; gradients; the card's notes and refusals (docs/circuits.md,
"Transistors")."""

from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import test_mosfet_level6 as level6
from diracvi import components as cp
from diracvi import spice
from test_mosfet_level6 import _excess, _ngspice_meyer, _part, needs_ngspice, terminal_currents

SWEEP = level6.sweep_deck(2)
# the corpus decks' cards: ng_mosamp's 'm' and xy_mosrect's 'nenh' and 'penh'
MOSAMP = ("nsub=2.2e15 uo=575 ucrit=49k uexp=0.1 tox=0.11u xj=2.95u cgso=1.5n cgdo=1.5n "
          "cbd=4.5f cbs=4.5f ld=2.4485u nss=3.2e10 kp=2e-5 phi=0.6")  # fmt: skip
NENH = ("Ld=0.0u Tox=225.000e-10 Nsub=1.066e+16 Vto=0.622490 Kp=6.326640E-05 Gamma=.639243 "
        "Phi=.31 Uo=1215.74 Uexp=4.612355e-2 Ucrit=174667 Delta=0.0 Vmax=177269 Xj=.9u "
        "Lambda=0.0 Nfs=4.55168e+12 Neff=4.68830 Nss=3.000000E+10 Tpg=1")  # fmt: skip
PENH = ("Ld=.03000000u Tox=225.000e-10 Nsub=6.575441e+16 Vto=-0.63025 Kp=2.635440E-05 "
        "Gamma=0.618101 Phi=.541111 Uo=361.941 Uexp=8.886957e-02 Ucrit=637449 Delta=0.0 "
        "Vmax=63253.3 Xj=0.112799u Lambda=0. Nfs=1.668437e+11 Neff=0.64354 Nss=3.000000E+10 "
        "Tpg=-1")  # fmt: skip
# every law parameter at once, with NFS and DELTA but no VMAX (the other branch of the
# channel shortening), and a given LAMBDA with VMAX
FULL = ("VTO=0.8 KP=3e-5 GAMMA=0.5 PHI=0.7 NSUB=1e16 TOX=4e-8 U0=700 UCRIT=2e4 UEXP=0.15 "
        "XJ=0.5u DELTA=1.5 NFS=1e12 IS=1e-13")  # fmt: skip
# (kind, card, instance, V_BS)
SLOW = pytest.mark.slow  # the quick suite keeps one sweep per deck card and FULL
CARDS = [
    ("NMOS", MOSAMP, "w=88.9u l=25.4u", -0.5),
    pytest.param("NMOS", MOSAMP, "w=12.7u l=106.7u", 0.3, marks=SLOW),
    pytest.param("NMOS", NENH, "l=1.25u w=50u", -1.0, marks=SLOW),
    ("NMOS", NENH, "l=1.25u w=50u", 0.6),  # V_BS above PHI: ngspice's quartic finds no root
    pytest.param("PMOS", PENH, "l=1.25u w=50u", -0.5, marks=SLOW),
    ("NMOS", FULL, "L=2u W=4u", -1.0),
    pytest.param("PMOS", "VTO=-0.7 NSUB=3e16 TOX=3e-8 VMAX=8e4 NEFF=2 LAMBDA=0.03 UEXP=0.1",
                 "L=1u W=5u", -0.5, marks=SLOW),
    pytest.param("NMOS", "", "M=2", 0.3, marks=SLOW),  # defaults: TOX 0.1 µm, KP from U0
]  # fmt: skip


def _sweep(kind, card, instance, vb):
    return level6._sweep(kind, card, instance, vb, SWEEP)


@needs_ngspice
@pytest.mark.parametrize(("kind", "card", "instance", "vb"), CARDS)
def test_static_currents_are_ngspices_in_every_region(kind, card, instance, vb):
    """Drain and bulk currents over a (V_DS, V_GS) grid at a reverse or forward V_BS —
    cutoff or weak inversion, linear, saturation, the inverse mode — equal ngspice's
    ``.dc`` to 1e-9 relative or 1e-12 A."""
    out, part = _sweep(kind, card, instance, vb)
    mine = terminal_currents(part, out["v(g)"], out["v(d)"], out["v(b)"])
    assert _excess(mine, out) <= 0.0
    s = -1.0 if kind == "PMOS" else 1.0
    i_d = s * mine[0]
    assert np.count_nonzero(i_d > 1e-6) >= 100 and np.count_nonzero(i_d < -1e-6) >= 10


@needs_ngspice
@pytest.mark.slow  # 17 diracvi parts beside two sweeps
def test_every_model_parameter_changes_the_currents():
    """The full card with one parameter removed at a time (so at ngspice's default, or
    derived from the process) gives currents that miss ngspice's of the full card far
    beyond the tolerance; so do VMAX, NEFF and the computed channel shortening on
    xy_mosrect's card."""
    for card, instance, vb, drops in (
        (FULL, "L=2u W=4u", -1.0,
         ("VTO", "KP", "GAMMA", "PHI", "NSUB", "TOX", "UCRIT", "UEXP", "XJ", "DELTA", "NFS")),
        (NENH, "l=1.25u w=50u", -1.0, ("Vmax", "Neff", "Lambda", "Uo")),
    ):  # fmt: skip
        out, _ = _sweep("NMOS", card, instance, vb)
        for drop in drops:
            changed = re.sub(rf"\b{drop}=\S+", "", card)
            if drop == "Lambda":  # a given LAMBDA > 0 replaces the computed shortening
                changed += " Lambda=0.05"
            net = SWEEP.format(kind="NMOS", card=changed, instance=instance, vb=vb)
            mine = terminal_currents(_part(net), out["v(g)"], out["v(d)"], out["v(b)"])
            assert _excess(mine, out) > 1e-8, drop


MEYER = """meyer
vd d 0 {vd}
vg g 0 {vg}
vb b 0 -0.5
m1 d g 0 b mm L=2u W=5u
.model mm NMOS(LEVEL=2 VTO=0.7 NSUB=2e16 TOX=2e-8 NFS=5e11 VMAX=1e5 XJ=0.3u UEXP=0.1)
.tran 0.1n 1n
.end
"""


@needs_ngspice
@pytest.mark.slow  # five ngspice transients
def test_meyer_capacitances_take_level_2s_von_and_vdsat_as_ngspice():
    """Meyer's ``C_GS``, ``C_GD``, ``C_GB`` of the part against ngspice's own at biases in
    depletion, weak inversion, saturation, the linear region and the inverse mode (level
    2's ``von`` with NFS and its velocity-saturated ``V_DSAT``): within 1e-9 of ``C_ox``."""
    cox = 3.9 * 8.854214871e-12 / 2e-8 * 5e-6 * 2e-6
    part = _part(MEYER.format(vg=0, vd=0))
    for vg, vd in ((0.3, 1.0), (0.9, 2.0), (2.5, 3.0), (2.5, 0.2), (2.0, -1.0)):
        mine = level6.part_meyer(part, vg, vg - vd, vg + 0.5)
        ref = _ngspice_meyer(MEYER.format(vg=vg, vd=vd))
        assert np.max(np.abs(np.subtract(mine, ref))) <= 1e-9 * cox, (vg, vd, mine, ref)


def test_level2_cards_note_what_ngspice_ignores_and_refuse_what_it_lacks():
    base = "t\nvd d 0 5\nvg g 0 2\nm1 d g 0 0 mm\n.model mm NMOS (LEVEL=2 {})\n.tran 1n 10n\n.end\n"
    read = spice.read(base.format("KF=1e-25 L=2u"))
    assert "KF ignored (noise only)" in " ".join(read.notes)
    part = read.circuit.parts[-1]  # TOX's 0.1 µm default: KP = U0 ε_ox/TOX
    assert dict(part.parameters)["kp"] == pytest.approx(600e-4 * 3.9 * 8.854214871e-12 / 1e-7)
    # not in ngspice 39's mos2 table: ngspice ignores it with a warning, and so does diracvi
    notes = " ".join(spice.read(base.format("UTRA=0.3")).notes)
    assert "UTRA ignored (not a parameter of ngspice 39's level-2 MOSFET" in notes
    card = r"line 4: model 'mm' \(line 5\): NMOS "
    for bad, match in (("PHI=-0.5", card + r"PHI=-0.5 must be > 0"),
                       ("TOX=0", card + r"TOX=0 must be > 0"),
                       ("NEFF=0", card + r"NEFF=0 must be > 0"),
                       ("NSUB=1e9", r"line 4: model of 'm1': NSUB=1e\+09 cm⁻³ is not above the "
                                    r"intrinsic density")):  # fmt: skip
        with pytest.raises(spice.NetlistError, match=match):
            spice.read(base.format(bad))


@pytest.mark.slow  # ~15 s: a compiled gradient per parameter
def test_gradients_reach_the_law_parameters():
    """``jax.grad`` of the drain current in the traced parameters of :func:`MOSFET2`
    (through the velocity-saturated ``V_DSAT``, weak inversion and mobility) equals
    central differences."""
    base = dict(vto=0.7, kp=4e-5, gamma=0.5, uexp=0.1, vmax=1e5, nfs=1e11, lambda_=0.02,
                delta=0.5)  # fmt: skip

    def drain(x, arg, vgs):
        part = cp.MOSFET2("nmos", w=5e-6, l=1e-6, tox=3e-8, nsub=1e16, **base | {arg: x},
                          name="m")  # fmt: skip
        idx = {c: j for j, c in enumerate(part.coords)}
        v = jnp.zeros(len(part.coords)).at[idx["wg"]].set(vgs).at[idx["w"]].set(2.0)
        return -part.force(jnp.zeros(len(part.coords)), v)[idx["w"]]

    for vgs in (2.5, 0.6):  # strong and weak inversion
        for arg, x in base.items():
            eps = 1e-6 * abs(x)
            grad = float(jax.grad(drain)(x, arg, vgs))
            fd = (float(drain(x + eps, arg, vgs)) - float(drain(x - eps, arg, vgs))) / (2 * eps)
            assert grad == pytest.approx(fd, rel=1e-5), (arg, vgs)
