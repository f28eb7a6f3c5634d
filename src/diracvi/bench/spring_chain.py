r"""Spring chain (paper §5.1), 1000 steps: diracvi vs NumPy, and torn vs monolithic.

The NumPy baseline implements the paper's interconnected (+) retraction equations
(int_springs) the way the paper's Matlab code would: at every step it assembles the
dense 5×5 linear system in the unknowns ``(q¹, q², q̄², q³)_{k+1}`` and ``λ_k`` and calls
``np.linalg.solve``. With ``v = (q_{k+1} − q_k)/h`` (diracvi's conventions, DESIGN.md §1:
``p_k = −D₁L_d + Bᵀλ``, ``B = dq² − dq̄²``)::

    p¹_k  = m₁ v¹ + h k₁ q¹_k − h k₂ (q²_k − q¹_k)
    p²_k  = m₂ v² + h k₂ (q²_k − q¹_k) + λ
    p̄²_k  = −h k₃ (q³_k − q̄²_k) − λ
    p³_k  = m₃ v³ + h k₃ (q³_k − q̄²_k)
    0     = v² − v̄²
    p_{k+1} = (m₁ v¹, m₂ v², 0, m₃ v³)

Parameters, initial state, step and horizon come from :mod:`diracvi.reproduce.paper`
(the paper's numbers), not from diracvi's problem definitions, so the agreement check
also tests that ``problems.spring_chain_torn`` is the paper's model.
"""

from __future__ import annotations

import numpy as np

from .. import problems
from ..reproduce.paper import SPRING_CHAIN
from ._core import Result, Settings
from ._paper import in_order, run_example

NAME = "spring-chain"
DESCRIPTION = "paper §5.1 spring chain: vs NumPy per-step solve; torn ÷ monolithic"

#: torn coordinate → the paper's name (q0/p0 entries of reproduce.paper)
COORDS = {"left.q1": "q1", "left.q2": "q2", "right.q2bar": "q2bar", "right.q3": "q3"}
MOMENTA = {c: "p" + name[1:] for c, name in COORDS.items()}


def numpy_torn_chain(params: dict, q0, p0, dt: float, steps: int):
    """``(q, p, λ)`` of the interconnected chain, one dense solve per step.

    ``q0``/``p0`` in the order ``(q¹, q², q̄², q³)``; returns ``q, p`` of shape
    (steps+1, 4) and ``λ`` of shape (steps, 1), diracvi's layout.
    """
    m1, m2, m3 = params["m1"], params["m2"], params["m3"]
    k1, k2, k3 = params["k1"], params["k2"], params["k3"]
    h = dt
    q = np.empty((steps + 1, 4))
    p = np.empty((steps + 1, 4))
    lam = np.empty((steps, 1))
    q[0], p[0] = q0, p0
    for k in range(steps):
        q1, q2, qb, q3 = q[k]
        p1, p2, pb, p3 = p[k]
        jac = np.zeros((5, 5))
        jac[0, 0] = m1 / h
        jac[1, 1], jac[1, 4] = m2 / h, 1.0
        jac[2, 4] = -1.0
        jac[3, 3] = m3 / h
        jac[4, 1], jac[4, 2] = 1.0 / h, -1.0 / h
        rhs = np.array(
            [
                p1 + m1 * q1 / h - h * k1 * q1 + h * k2 * (q2 - q1),
                p2 + m2 * q2 / h - h * k2 * (q2 - q1),
                pb + h * k3 * (q3 - qb),
                p3 + m3 * q3 / h - h * k3 * (q3 - qb),
                (q2 - qb) / h,
            ]
        )
        x = np.linalg.solve(jac, rhs)
        q[k + 1] = x[:4]
        lam[k] = x[4]
        v = (x[:4] - q[k]) / h
        p[k + 1] = (m1 * v[0], m2 * v[1], 0.0, m3 * v[3])
    return q, p, lam


def run(settings: Settings) -> Result:
    paper = SPRING_CHAIN
    problem = problems.spring_chain_torn(dt=paper["dt"], steps=paper["steps"])
    coords = problem.system.coords
    q0 = in_order(paper["q0"], COORDS, coords)
    p0 = in_order(paper["p0"], MOMENTA, coords)

    def baseline():
        return numpy_torn_chain(paper["parameters"], q0, p0, paper["dt"], paper["steps"])

    return run_example(
        benchmark=NAME,
        title="spring chain",
        problem=problem,
        baseline=baseline,
        paper_timing=paper["timing"],
        settings=settings,
    )
