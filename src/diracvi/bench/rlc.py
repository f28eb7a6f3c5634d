r"""RLC circuit (paper §5.2), 400 steps: diracvi vs NumPy, and torn vs monolithic.

The NumPy baseline implements the forced interconnected (+) retraction equations
(forced_int_eqns) with a dense 8×8 solve per step in the unknowns
``(q^R, q^L, q^{S1}, q^{S2}, q^C)_{k+1}`` and ``(μ₁, μ₂, λ)``. It uses diracvi's
conventions (docs/discretizations.md, "Where the paper is wrong"): the physical resistor
sign ``f_d^− = h F = (−R Δq^R, 0, 0)``, entering as ``p_k = −D₁L_d − f_d^− + …``; the RL
loop's one-form ``(1, −1, −1)``; the capacitor's ``ω₂ = −dq^{S2} + dq^C`` as the paper
states it (its printed equations carry μ₂ with the opposite sign); ``B = dq^{S1} − dq^{S2}``.
With ``Δx = x_{k+1} − x_k``::

    p^R_k    = R Δq^R + μ₁
    p^L_k    = (l/h) Δq^L − μ₁
    p^{S1}_k = −μ₁ + λ
    p^{S2}_k = −μ₂ − λ
    p^C_k    = (h/C) q^C_k + μ₂
    0 = Δq^R − Δq^L − Δq^{S1},   0 = Δq^C − Δq^{S2},   0 = Δq^{S1} − Δq^{S2}
    p_{k+1} = (0, (l/h) Δq^L, 0, 0, 0)

(the three constraint rows are divided by h, as ω_{d+} = A v_k). Parameters and initial
data come from :mod:`diracvi.reproduce.paper`.
"""

from __future__ import annotations

import numpy as np

from .. import problems
from ..reproduce.paper import RLC
from ._core import Result, Settings
from ._paper import in_order, run_example

NAME = "rlc"
DESCRIPTION = "paper §5.2 RLC circuit: vs NumPy per-step solve; torn ÷ monolithic"

#: torn coordinate → the paper's name (q0/p0 entries of reproduce.paper)
COORDS = {"rl.qR": "qR", "rl.qL": "qL", "rl.qS1": "qS1", "cap.qS2": "qS2", "cap.qC": "qC"}
MOMENTA = {c: "p" + name[1:] for c, name in COORDS.items()}


def numpy_torn_rlc(params: dict, q0, p0, dt: float, steps: int):
    """``(q, p, (μ₁, μ₂, λ))`` of the interconnected circuit, one dense solve per step.

    ``q0``/``p0`` in the order ``(q^R, q^L, q^{S1}, q^{S2}, q^C)``; returns ``q, p`` of
    shape (steps+1, 5) and the multipliers of shape (steps, 3), diracvi's layout.
    """
    r, ell, cap = params["R"], params["l"], params["C"]
    h = dt
    q = np.empty((steps + 1, 5))
    p = np.empty((steps + 1, 5))
    mult = np.empty((steps, 3))
    q[0], p[0] = q0, p0
    for k in range(steps):
        qr, ql, qs1, qs2, qc = q[k]
        jac = np.zeros((8, 8))
        # momentum rows, unknowns (qR', qL', qS1', qS2', qC', μ1, μ2, λ)
        jac[0, 0], jac[0, 5] = r, 1.0
        jac[1, 1], jac[1, 5] = ell / h, -1.0
        jac[2, 5], jac[2, 7] = -1.0, 1.0
        jac[3, 6], jac[3, 7] = -1.0, -1.0
        jac[4, 6] = 1.0
        # constraint rows: ω_{d+} = A (q_{k+1} − q_k)/h
        jac[5, 0], jac[5, 1], jac[5, 2] = 1.0 / h, -1.0 / h, -1.0 / h
        jac[6, 3], jac[6, 4] = -1.0 / h, 1.0 / h
        jac[7, 2], jac[7, 3] = 1.0 / h, -1.0 / h
        rhs = np.array(
            [
                p[k, 0] + r * qr,
                p[k, 1] + ell * ql / h,
                p[k, 2],
                p[k, 3],
                p[k, 4] - h * qc / cap,
                (qr - ql - qs1) / h,
                (qc - qs2) / h,
                (qs1 - qs2) / h,
            ]
        )
        x = np.linalg.solve(jac, rhs)
        q[k + 1] = x[:5]
        mult[k] = x[5:]
        p[k + 1] = (0.0, ell * (x[1] - ql) / h, 0.0, 0.0, 0.0)
    return q, p, mult


def run(settings: Settings) -> Result:
    paper = RLC
    prm = paper["parameters"]
    problem = problems.rlc_torn(prm["R"], prm["l"], prm["C"], dt=paper["dt"], steps=paper["steps"])
    coords = problem.system.coords
    q0 = in_order(paper["q0"], COORDS, coords)
    p0 = in_order(paper["p0"], MOMENTA, coords)

    def baseline():
        return numpy_torn_rlc(prm, q0, p0, paper["dt"], paper["steps"])

    return run_example(
        benchmark=NAME,
        title="RLC circuit",
        problem=problem,
        baseline=baseline,
        paper_timing=paper["timing"],
        settings=settings,
    )
