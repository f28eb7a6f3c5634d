"""The order-4 rule keeps the structural properties of the others on the paper's
degenerate RLC circuit: the affine step map is Newton's step, the (−) scheme inverts
the (+) scheme (Lobatto IIID is symmetric), and checkpointed and ensemble runs are the
plain run.

White-box: reads internals of ``diracvi.discretization.lobatto``."""

import numpy as np
import pytest

import diracvi as dv
from _jaxpr import count_equations
from diracvi import problems

STEPS = 60


def rlc_run(q0=None, p0=None, **kw):
    problem = problems.get("rlc")
    q0 = problem.q0 if q0 is None else q0
    p0 = problem.p0 if p0 is None else p0
    args = dict(dt=0.05, steps=STEPS, discretization="lobatto") | kw
    return dv.simulate(problem.system, q0, p0, **args)


def test_affine_step_map_is_newtons_step():
    affine = rlc_run()
    newton = rlc_run(solver=dv.NewtonSolver())
    assert "affine" in str(affine.solver).lower() and "newton" in str(newton.solver).lower()
    scale = np.max(np.abs(newton.q))
    assert np.max(np.abs(affine.q - newton.q)) < 1e-12 * scale
    assert np.max(np.abs(affine.p - newton.p)) < 1e-12 * np.max(np.abs(newton.p))
    lam = np.max(np.abs(newton.multipliers))
    assert np.max(np.abs(affine.multipliers - newton.multipliers)) < 1e-10 * lam


def test_minus_scheme_retraces_the_plus_run():
    """The (−) equations are the (+) equations solved for the other end: marching back
    from the final state of a (+) run returns its states to round-off."""
    fwd = rlc_run(solver=dv.NewtonSolver())
    back = rlc_run(fwd.q[-1], fwd.p[-1], solver=dv.NewtonSolver(), scheme="minus", t0=fwd.t[-1])
    np.testing.assert_allclose(back.t, fwd.t[::-1], atol=1e-12)
    assert np.max(np.abs(back.q - fwd.q[::-1])) < 1e-11 * np.max(np.abs(fwd.q))
    assert np.max(np.abs(back.p - fwd.p[::-1])) < 1e-11 * np.max(np.abs(fwd.p))


@pytest.mark.slow  # two more compilations (a chunked run, an ensemble)
def test_checkpointed_and_ensemble_runs_are_the_plain_run(tmp_path):
    problem = problems.get("rlc")
    plain = rlc_run()
    chunked = rlc_run(checkpoint=tmp_path / "run.nc", checkpoint_every=STEPS // 3)
    # a chunk is its own compiled program: XLA may order a sum differently (1 ulp seen)
    for a, b in ((chunked.q, plain.q), (chunked.p, plain.p)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14 * np.max(np.abs(b)))
    q0 = np.stack([problem.q0, problem.q0 + np.array([0.0, 0.1, 0.0])])
    p0 = np.stack([problem.p0, problem.p0])
    ens = dv.simulate_ensemble(
        problem.system, q0, p0, dt=0.05, steps=STEPS, discretization="lobatto"
    )
    np.testing.assert_allclose(ens.q[0], plain.q, rtol=0, atol=1e-13 * np.max(np.abs(plain.q)))
    other = rlc_run(q0[1], p0[1])
    np.testing.assert_allclose(ens.q[1], other.q, rtol=0, atol=1e-13 * np.max(np.abs(other.q)))


def rlc_stage_jacobian(a, a_hat, h=0.1, r=1.0, ell=0.75, cap=3.0):
    """Jacobian of a partitioned Runge–Kutta step ``(a, a_hat)`` in Hamilton–Pontryagin
    form on the paper's RLC circuit (``P_i = p_k + h Σ_j â_ij G_j`` with ``P = ∂L/∂v``,
    ``G = ∂L/∂q + F + Aᵀλ``, and ``A V_j = 0`` at each stage), in the unknowns
    ``(V_1, V_2, V_3, λ_1, λ_2, λ_3)``: the system is linear, so columns are residuals."""
    a, a_hat = np.asarray(a), np.asarray(a_hat)
    forms = np.array([1.0, -1.0, -1.0])

    def residual(x):
        v, lam = x[:9].reshape(3, 3), x[9:]
        q = h * a @ v  # stage positions from q_k = 0
        p = np.stack([[0.0, ell * vj[1], 0.0] for vj in v])
        g = np.stack([[-r * v[j, 0], 0.0, -q[j, 2] / cap] + forms * lam[j] for j in range(3)])
        return np.concatenate([(p - h * a_hat @ g).ravel(), v @ forms])

    base = residual(np.zeros(12))
    return np.stack([residual(e) - base for e in np.eye(12)], axis=1)


def test_lobatto_iiia_iiib_is_singular_on_the_degenerate_rlc_and_iiid_is_not():
    """Why the rule is IIID: under IIIA–IIIB (IIIB's last column is zero) the resistor's
    last-stage velocity enters no equation but the constraint, so the step is singular
    on the paper's RLC; IIID's invertible ``a`` determines every stage."""
    from diracvi.discretization.lobatto import IIID

    iiia = [[0, 0, 0], [5 / 24, 1 / 3, -1 / 24], [1 / 6, 2 / 3, 1 / 6]]
    iiib = [[1 / 6, -1 / 6, 0], [1 / 6, 1 / 3, 0], [1 / 6, 5 / 6, 0]]
    assert np.linalg.matrix_rank(rlc_stage_jacobian(iiia, iiib)) < 12
    assert np.linalg.matrix_rank(rlc_stage_jacobian(IIID, IIID)) == 12


def test_the_three_stages_share_one_trace_of_each_model_function():
    """The stages are evaluated by one ``jax.vmap`` (issue 30): the step residual of the
    four-bar linkage (L, the one-forms, g and the reactions all hold sines and cosines)
    applies as many trigonometric primitives under ``"lobatto"`` as under ``"midpoint"``,
    which evaluates each once, plus those of one reaction ``A(q)ᵀμ`` — the holonomic
    rows' multiplier at the known node, a call of its own (in the stages' batch, the
    step's Jacobian differentiated ``A`` at the known ``q_k`` along zero directions:
    ``benchmarks/README.md``). A loop over the stages would triple them."""
    import jax
    import jax.numpy as jnp

    from diracvi.discretization.equations import StepEquations, first_guess
    from diracvi.discretization.rules import get_rule

    problem = problems.get("four-bar")
    system, q = problem.system, jnp.asarray(problem.q0, dtype=float)
    counts = {}
    for name in ("midpoint", "lobatto"):
        rule = get_rule(name)
        eqs = StepEquations(system, rule, "plus", jnp.asarray(problem.dt), q, q, 0.0)
        x = first_guess(system, rule, q, q, jnp.zeros(system.m))
        counts[name] = count_equations(jax.make_jaxpr(eqs.residual)(x).jaxpr, {"sin", "cos"})
    nodal = count_equations(
        jax.make_jaxpr(system.multiplier_force)(q, jnp.zeros(system.m), 0.0).jaxpr, {"sin", "cos"}
    )
    assert counts["midpoint"] > 0 and nodal > 0
    assert counts["lobatto"] == counts["midpoint"] + nodal
