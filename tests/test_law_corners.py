"""The corners of a behavioural law, located by the variable-step loop
(``diracvi.driver.law_corners``, ``diracvi.runtime.roundoff.corner_arguments``).

A law with an ``abs`` (a comparison, a ``max``) has a kink where its argument changes
sign. The midpoint rule samples it at step centres, and step doubling compares centres
with centres, so a kink after a try's last centre was unseen: the try was accepted with
the law's other piece missing, and the output, read through four step centres, crossed
the kink (``ng_memristor``: 4.1e-3 of peak). Located, the kink is a node of the run, and
each side is read from its own centres.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from diracvi import spice
from diracvi.runtime.config import ensure_float64
from diracvi.runtime.roundoff import corner_arguments

ensure_float64()

#: a hinge: i = k·max(v(1) − Vt, 0) written with ``abs``, v(1) = A sin(ωt) a source, so
#: the current is known in closed form whatever the rest of the circuit does
A, F, VT, K = 3.0, 1e8, 1.6, 2e-3
HINGE = f"""hinge: a B source's law with a kink, driven by a sine
V1 1 0 SIN(0 {A} {F:g})
B1 0 2 I = {K / 2:g}*(V(1)-{VT}+abs(V(1)-{VT}))
R1 2 0 1k
C1 2 0 1p
.tran 0.1n 10n
.end
"""


def test_corner_arguments_are_the_laws_kinks_with_their_terms():
    # ng_memristor's f(y) = β y + ½(α − β)(|y + Vt| − |y − Vt|) and the comparisons of
    # its select: the arguments are y + Vt, y − Vt, f, f; their terms (inputs seeded
    # with |y|) |y|, |y|, and β|y| + β|y| + β|y|·... carried without cancellation
    beta, vt = 2e12, 1.6

    def law(y):
        f = beta * y - 0.5 * beta * (jnp.abs(y + vt) - jnp.abs(y - vt))
        return jnp.where(f > 0, f, jnp.where(f < 0, f, 0.0))

    for y in (-2.0, 0.5, 1.7):
        g, terms = corner_arguments(law, [y], [abs(y)])
        f = beta * y - 0.5 * beta * (abs(y + vt) - abs(y - vt))
        assert np.allclose(np.asarray(g), [y + vt, y - vt, f, f], rtol=1e-15, atol=1e-3)
        # each abs's argument moves by |y| with y; f's terms by β|y| + ½β(|y| + |y|)
        assert np.allclose(np.asarray(terms), [abs(y)] * 2 + [2 * beta * abs(y)] * 2)
        # an absolute tolerance of 1 µV on y moves them by 1 µV and 2β µV
        _, atol = corner_arguments(law, [y], [1e-6])
        assert np.allclose(np.asarray(atol), [1e-6, 1e-6, 2 * beta * 1e-6, 2 * beta * 1e-6])
    # a law without corners has none
    g, terms = corner_arguments(lambda y: 3.0 * y * y, [0.3], [0.3])
    assert g.shape == (0,) and terms.shape == (0,)


@pytest.mark.slow  # a simulation with its compilation (~5 s)
def test_a_hinge_is_located_and_read_on_either_side_of_it():
    result = spice.run(HINGE)
    omega = 2 * np.pi * F
    t = np.linspace(0.0, 1e-8, 20001)
    exact = K * np.maximum(A * np.sin(omega * t) - VT, 0.0)
    error = np.max(np.abs(np.asarray(result.at(t)["i(B1)"]) - exact)) / np.max(exact)
    # measured 5.4e-7 of peak (4.1e-3 before the corners were located: the kink at
    # 0.895 ns after the last centre of a try, 1.1e-11 s from any node)
    assert error <= 1e-4, error
    # each kink of the run's span is a node, to the window's time: the argument
    # v(1) − Vt within w = vntol + 0.03·reltol·Vt of 0 (the terms of v(1) − Vt: |v(1)|)
    nodes = np.asarray(result.trajectory.t)
    w = 1e-6 + 0.03 * 1e-3 * VT
    for corner in (np.arcsin(VT / A) / omega, (np.pi - np.arcsin(VT / A)) / omega):
        slope = A * omega * abs(np.cos(omega * corner))
        assert np.min(np.abs(nodes - corner)) <= w / slope, corner
