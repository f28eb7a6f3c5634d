"""Hand-written NumPy references of the (±) discrete Lagrange–Dirac equations (DESIGN.md
§1), shared by test_reference_steps.py and test_dirac_discrete.py. Nothing of diracvi is
used here: gradients, one-forms and forces are written out by hand and each step is solved
by a hand Newton iteration with a finite-difference Jacobian.

For a rule with node ``q_θ = q_k + θ (q_{k+1} − q_k)`` (θ = 0 left point, ½ midpoint) and
``L_d = h L(q_θ, v_k)``::

    D₁L_d = h (1 − θ) ∂L/∂q − ∂L/∂v,      D₂L_d = h θ ∂L/∂q + ∂L/∂v,
    f_d^− = w⁻ h F(q_θ, v_k),             f_d^+ = w⁺ h F(q_θ, v_k),

(w⁻, w⁺) = (1, 0) for the left point and (½, ½) for the midpoint;

    (+)  p_k     = −D₁L_d − f_d^− + A(q_k)ᵀ μ,        A(c₊) v_k = 0,   p_{k+1} = D₂L_d + f_d^+
    (−)  p_{k+1} =  D₂L_d + f_d^+ + A(q_{k+1})ᵀ μ,    A(c₋) v_k = 0,   p_k     = −D₁L_d − f_d^−

with the constraint node c₊ = q_k, c₋ = q_{k+1} (left point) and c± = q̄ (midpoint).
"""

from __future__ import annotations

import numpy as np

THETA = {"retraction": 0.0, "midpoint": 0.5}
WEIGHTS = {"retraction": (1.0, 0.0), "midpoint": (0.5, 0.5)}


def hand_newton(fun, x0, tol=1e-15, max_iter=50):
    """Newton's method with a central-difference Jacobian (NumPy only)."""
    x = np.array(x0, dtype=np.float64)
    for _ in range(max_iter):
        r = fun(x)
        jac = np.empty((r.size, x.size))
        for j in range(x.size):
            e = np.zeros_like(x)
            e[j] = 1e-6 * max(1.0, abs(x[j]))
            jac[:, j] = (fun(x + e) - fun(x - e)) / (2 * e[j])
        dx = np.linalg.solve(jac, -r)
        x = x + dx
        if np.max(np.abs(dx)) <= tol * max(1.0, np.max(np.abs(x))):
            return x
    raise AssertionError(f"reference Newton did not converge: |r| = {np.max(np.abs(fun(x)))}")


class HandModel:
    """``dL/dq``, ``dL/dv``, ``F`` and ``A`` written out by hand for one model."""

    def __init__(self, n, l_q, l_v, forms=None, force=None):
        self.n, self.l_q, self.l_v = n, l_q, l_v
        self.forms = forms if forms is not None else (lambda q: np.zeros((0, n)))
        self.force = force if force is not None else (lambda q, v: np.zeros(n))

    def momenta(self, rule, qk, qk1, h):
        """``(−D₁L_d − f_d^−, D₂L_d + f_d^+)`` from the formulas in the module docstring."""
        theta = THETA[rule]
        w_minus, w_plus = WEIGHTS[rule]
        v = (qk1 - qk) / h
        node = qk + theta * (qk1 - qk)
        lq, lv, f = self.l_q(node, v), self.l_v(node, v), self.force(node, v)
        d1 = h * (1 - theta) * lq - lv
        d2 = h * theta * lq + lv
        return -d1 - w_minus * h * f, d2 + w_plus * h * f

    def constraint_node(self, rule, scheme, qk, qk1):
        if rule == "midpoint":
            return 0.5 * (qk + qk1)
        return qk if scheme == "plus" else qk1

    def step(self, rule, scheme, h, q, p, guess):
        """One step from the known end: returns (q_other, p_other, μ)."""
        n = self.n
        m = self.forms(q).shape[0]

        def residual(x):
            other, mu = x[:n], x[n:]
            qk, qk1 = (q, other) if scheme == "plus" else (other, q)
            left, right = self.momenta(rule, qk, qk1, h)
            if scheme == "plus":
                r_mom = left + self.forms(qk).T @ mu - p
            else:
                r_mom = right + self.forms(qk1).T @ mu - p
            c = self.constraint_node(rule, scheme, qk, qk1)
            return np.concatenate([r_mom, self.forms(c) @ ((qk1 - qk) / h)])

        x = hand_newton(residual, np.concatenate([guess, np.zeros(m)]))
        other, mu = x[:n], x[n:]
        qk, qk1 = (q, other) if scheme == "plus" else (other, q)
        left, right = self.momenta(rule, qk, qk1, h)
        return other, (right if scheme == "plus" else left), mu

    def run(self, rule, scheme, h, q0, p0, steps):
        q, p, mus = [np.asarray(q0, float)], [np.asarray(p0, float)], []
        sign = 1.0 if scheme == "plus" else -1.0
        for k in range(steps):
            guess = q[-1] + sign * (q[-1] - q[-2]) if k else q[-1]
            qn, pn, mu = self.step(rule, scheme, h, q[-1], p[-1], guess)
            q.append(qn)
            p.append(pn)
            mus.append(mu)
        return np.array(q), np.array(p), np.array(mus).reshape(steps, -1)


def disk_model(prob):
    par = prob.parameters
    mass = np.array([par["m"], par["m"], par["I"], par["J"]])
    rad = par["R"]

    def forms(q):
        c, s = np.cos(q[3]), np.sin(q[3])
        return np.array([[1.0, 0.0, -rad * c, 0.0], [0.0, 1.0, -rad * s, 0.0]])

    return HandModel(4, lambda q, v: np.zeros(4), lambda q, v: mass * v, forms=forms)


def pendulum_model(prob):
    par = prob.parameters
    m1, m2, l1, l2, g = (par[k] for k in ("m1", "m2", "l1", "l2", "g"))

    def bob(q, v):
        c2, s2 = np.cos(q[3]), np.sin(q[3])
        return v[1] + l2 * c2 * v[3], v[2] + l2 * s2 * v[3], c2, s2

    def l_q(q, v):  # coords (θ₁, x, y, θ₂)
        bx, by, c2, s2 = bob(q, v)
        d_theta2 = m2 * (bx * (-l2 * s2 * v[3]) + by * (l2 * c2 * v[3])) - m2 * g * l2 * s2
        return np.array([-m1 * g * l1 * np.sin(q[0]), 0.0, -m2 * g, d_theta2])

    def l_v(q, v):
        bx, by, c2, s2 = bob(q, v)
        return np.array([m1 * l1**2 * v[0], m2 * bx, m2 * by, m2 * l2 * (c2 * bx + s2 * by)])

    def joint(q):
        return np.array([[-l1 * np.cos(q[0]), 1.0, 0.0, 0.0], [-l1 * np.sin(q[0]), 0.0, 1.0, 0.0]])

    return HandModel(4, l_q, l_v, forms=joint)


C_DAMP = np.array([[0.4, 0.1], [0.1, 0.3]])
MASS = np.array([[2.0, 0.3], [0.3, 1.0]])
STIFF = np.array([[3.0, -1.0], [-1.0, 2.0]])


def damped_model():
    return HandModel(
        2,
        lambda q, v: -STIFF @ q - np.array([0.4 * q[0] ** 3, 0.0]),
        lambda q, v: MASS @ v,
        force=lambda q, v: -(1.0 + 0.5 * q[1] ** 2) * (C_DAMP @ v),
    )
