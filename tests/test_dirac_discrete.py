"""Discrete Dirac structures (paper §2.3, §4.2): the Tulczyjew maps and 𝔇^±L_d by hand,
the (±) equations they encode vs the integrator's residuals, the discrete direct-sum
lemma and the main theorem (D^{d+}_{Δ1} ⊕ D^{d+}_{Δ2}) ⊠_d D^{d+}_int = D^{d+}_Δ.

White-box: reads internals of ``diracvi.dirac._linalg``, ``diracvi.dirac._structure``."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import diracvi as dv
from _dirac_cases import random_instance, rlc_torn, spring_chain_torn
from _references import C_DAMP, MASS, STIFF, damped_model, disk_model, pendulum_model
from conftest import examples
from diracvi import ModelError, problems
from diracvi.dirac import (
    DirectSumDiscrete,
    DiscreteDiracStructure,
    InducedDiscrete,
    InteractionDiscrete,
    TensorDiscrete,
    dirac_differential_minus,
    dirac_differential_plus,
    gamma_d_minus,
    gamma_d_plus,
    is_clean,
    kappa_d,
    kappa_d_inverse,
    omega_flat_minus,
    omega_flat_plus,
    system_dirac_differential,
)
from diracvi.dirac._linalg import rank
from diracvi.dirac._structure import combined_forms

pytestmark = pytest.mark.filterwarnings("ignore::diracvi.dirac.RedundantFormsWarning")

Z0 = (np.array([1.0, 2.0]), np.array([3.0, 4.0]))
Z1 = (np.array([5.0, 6.0]), np.array([7.0, 8.0]))


def test_tulczyjew_maps_by_hand():
    assert kappa_d(Z0, Z1).tolist() == [1, 2, 5, 6, -3, -4, 7, 8]
    assert omega_flat_plus(Z0, Z1).tolist() == [1, 2, 7, 8, 3, 4, 5, 6]
    assert omega_flat_minus(Z0, Z1).tolist() == [3, 4, 5, 6, -1, -2, -7, -8]
    (q0, p0), (q1, p1) = kappa_d_inverse(kappa_d(Z0, Z1))
    assert np.array_equal(np.concatenate([q0, p0, q1, p1]), np.arange(1.0, 9.0))
    # γ^{d±} = Ω^♭_{d±} ∘ (κ^d)^{-1}: (q0, q1, a0, a1) ↦ (q0, a1, −a0, q1) / (−a0, q1, −q0, −a1)
    w = np.array([1.0, 2.0, 3.0, 4.0])  # n = 1
    assert gamma_d_plus(w).tolist() == [1, 4, -3, 2]
    assert gamma_d_minus(w).tolist() == [-3, 2, -1, -4]


def _oscillator_ld(m=2.0, k=3.0, h=0.1):
    # L_d = h (½ m ((q1 − q0)/h)² − ½ k q0²)  (the retraction rule)
    return lambda a, b: h * (0.5 * m * jnp.sum(((b - a) / h) ** 2) - 0.5 * k * jnp.sum(a**2))


def test_dirac_differentials_by_hand():
    m, k, h = 2.0, 3.0, 0.1
    q0, q1 = np.array([0.4]), np.array([0.7])
    # D₁L_d = −m (q1 − q0)/h − h k q0,  D₂L_d = m (q1 − q0)/h
    d1 = -m * (q1 - q0) / h - h * k * q0
    d2 = m * (q1 - q0) / h
    plus = dirac_differential_plus(_oscillator_ld(m, k, h), q0, q1)
    np.testing.assert_allclose(plus, np.concatenate([q0, d2, -d1, q1]), rtol=1e-14)
    minus = dirac_differential_minus(_oscillator_ld(m, k, h), q0, q1)
    np.testing.assert_allclose(minus, np.concatenate([-d1, q1, -q0, -d2]), rtol=1e-14)
    # forced: γ^{d±}(dL_d + F_d) with F_d = (f⁻, f⁺)
    f = (np.array([0.25]), np.array([-0.5]))
    forced = dirac_differential_plus(_oscillator_ld(m, k, h), q0, q1, lambda a, b: f)
    np.testing.assert_allclose(forced, np.concatenate([q0, d2 + f[1], -d1 - f[0], q1]), rtol=1e-14)


DAMPED_FORM = np.array([[1.0, -0.5]])


def _hand_cases():
    """(diracvi system, the same model written by hand in NumPy) — tests/_references.py."""
    disk = problems.get("rolling-disk")
    pendulum = problems.get("double-pendulum-torn")
    damped = damped_model()
    damped.forms = lambda q: DAMPED_FORM
    damped_system = dv.LagrangeDiracSystem(
        ("a", "b"),
        lambda q, v: 0.5 * v @ MASS @ v - 0.5 * q @ STIFF @ q - 0.1 * q[0] ** 4,
        constraints=DAMPED_FORM,
        force=lambda q, v: -(1.0 + 0.5 * q[1] ** 2) * (C_DAMP @ v),
    )
    return {
        "rolling-disk": (disk.system, disk_model(disk)),
        "pendulum-joint": (pendulum.system, pendulum_model(pendulum)),
        "damped": (damped_system, damped),
    }


@pytest.mark.parametrize("rule_name", ["retraction", "midpoint"])
@pytest.mark.parametrize("name", ["rolling-disk", "pendulum-joint", "damped"])
@pytest.mark.parametrize("scheme", ["plus", "minus"])
def test_structure_encodes_the_papers_equations(name, rule_name, scheme):
    """At random (q_k, p_k, q_{k+1}, p_{k+1}) — not on any trajectory — the pieces of
    (X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ are the (±) equations written by hand from the paper
    (momentum line with the Dirac multipliers, ω_{d±}, explicit momentum update). Both
    𝔇^±L_d and the equations come from the hand model, not from diracvi's step code."""
    system, hand = _hand_cases()[name]
    h = 0.05
    rng = np.random.default_rng(7)
    n = system.n
    structure = InducedDiscrete(system.constraint_forms, rule_name, h=h, side=scheme, n=n)
    for _ in range(5):
        q0, p0, q1, p1 = (0.5 * rng.standard_normal(n) for _ in range(4))
        p_minus, p_plus = hand.momenta(rule_name, q0, q1, h)  # (−D₁L_d − f⁻, D₂L_d + f⁺)
        if scheme == "plus":  # 𝔇⁺ = γ^{d+}(dL_d + F_d) = (q₀, P⁺, P⁻, q₁)
            alpha = np.concatenate([q0, p_plus, p_minus, q1])
        else:  # 𝔇⁻ = (P⁻, q₁, −q₀, −P⁺)
            alpha = np.concatenate([p_minus, q1, -q0, -p_plus])
        parts = structure.batched_parts(q0[None], p0[None], q1[None], p1[None], alpha[None])
        nu = parts["nu"][0]
        fib = parts["fiber"][0]
        node = hand.constraint_node(rule_name, scheme, q0, q1)
        if scheme == "plus":
            mu = -nu  # p_k = P⁻ + A(q_k)ᵀμ: the fibre residual is (P⁻ − p_k) − A(q_k)ᵀν
            momentum_line = p_minus + hand.forms(q0).T @ mu - p0
            np.testing.assert_allclose(fib[:n], momentum_line, atol=1e-11)
        else:
            mu = nu  # p_{k+1} = P⁺ + A(q_{k+1})ᵀμ: minus the fibre residual
            momentum_line = p_plus + hand.forms(q1).T @ mu - p1
            np.testing.assert_allclose(-fib[n:], momentum_line, atol=1e-11)
        # constraint line: ω_{d±}(q_k, q_{k+1}) = A(node) v_k, by hand
        omega = hand.forms(node) @ ((q1 - q0) / h)
        np.testing.assert_allclose(parts["constraint"][0], omega, atol=1e-13)
        # explicit update p_{k+1} = P⁺ (plus) / p_k = P⁻ (minus): the base-point mismatch
        base = parts["base"][0]
        if scheme == "plus":
            np.testing.assert_allclose(base[n:], p_plus - p1, atol=1e-12)
        else:
            np.testing.assert_allclose(base[:n], p_minus - p0, atol=1e-12)
        # the other slot of α − Ω^♭ (q_{k+1} = q_k⁺) is satisfied by construction
        other_slot = fib[n:] if scheme == "plus" else fib[:n]
        assert np.max(np.abs(other_slot)) == 0.0
    # the constraint line is not trivially zero at random points
    assert np.max(np.abs(omega)) > 1e-3 or hand.forms(node).shape[0] == 0


def test_membership_accepts_alpha_with_or_without_base_point():
    forms = np.array([[1.0, -1.0]])
    d = InducedDiscrete(forms, "retraction", h=0.1, side="plus")
    q0, q1 = np.array([0.0, 0.0]), np.array([0.3, 0.3])  # ω_{d+} = 0
    p0, p1 = np.array([1.0, 2.0]), np.array([-1.0, 0.5])
    alpha = np.concatenate([p0 + 5.0 * forms[0], q1])  # (α_q, α_{p⁺}) = Ω^♭ + (Δ°, 0)
    assert d.contains((q0, p0), (q1, p1), alpha)
    assert d.contains((q0, p0), (q1, p1), np.concatenate([q0, p1, alpha]))
    assert not d.contains((q0, p0), (q1, p1), np.concatenate([q0, p1 + 0.1, alpha]))
    assert not d.contains((q0, p0), (q1 + np.array([0.1, 0.0]), p1), alpha)  # off Δ^{d+}
    assert not d.contains((q0, p0), (q1, p1), alpha + np.array([0.1, 0.0, 0.0, 0.0]))
    res, ok = d.membership((q0, p0), (q1, p1), alpha + np.array([0.0, 0.0, 0.0, 1e-3]))
    assert not ok and res == pytest.approx(1e-3, rel=1e-9)
    with pytest.raises(ModelError, match="alpha has 3 entries"):
        d.residual((q0, p0), (q1, p1), np.ones(3))


def _structures(inst, rule, side="plus", h=0.1):
    parts = [
        InducedDiscrete(f, rule, h=h, side=side, n=d)
        for f, d in zip(inst.forms, inst.dims, strict=True)
    ]
    direct = DirectSumDiscrete(*parts)
    product = TensorDiscrete(
        direct, InteractionDiscrete(inst.sigma, rule, h=h, side=side, n=inst.n)
    )
    no_sigma = combined_forms(inst.forms, np.zeros((0, inst.n)), inst.dims)
    monolithic = InducedDiscrete(
        combined_forms(inst.forms, inst.sigma, inst.dims), rule, h=h, side=side, n=inst.n
    )
    return direct, product, InducedDiscrete(no_sigma, rule, h=h, side=side, n=inst.n), monolithic


@pytest.mark.parametrize("rule", ["retraction", "midpoint"])
@pytest.mark.parametrize("make", [spring_chain_torn, rlc_torn], ids=["springs", "rlc"])
def test_lemma_and_theorem_on_paper_examples(make, rule):
    inst = make()
    direct, product, induced_sum, monolithic = _structures(inst, rule)
    assert direct.discrepancy(induced_sum, samples=6) < 1e-12  # Lemma (discrete direct sum)
    assert product.discrepancy(monolithic, samples=6) < 1e-12  # Theorem (⊠_d)
    # the interaction is not a no-op: the bare direct sum is a different structure
    assert not direct.equals(monolithic, samples=6)


def test_theorem_along_an_integrated_torn_spring_chain():
    """Each step of the (+) integrator on the torn chain (coords q1, q2, q2bar, q3 with
    Σ° = dq2 − dq2bar, L = L¹ + L²) lies in (D^{d+}_{Δ1} ⊕ D^{d+}_{Δ2}) ⊠_d D^{d+}_int."""
    inst = spring_chain_torn()
    sigma = inst.sigma

    def lagrangian(q, v):
        l1 = 0.5 * (v[0] ** 2 + v[1] ** 2) - 0.5 * q[0] ** 2 - 0.5 * (q[1] - q[0]) ** 2
        l2 = 0.5 * 0.0 * v[2] ** 2 + 0.5 * v[3] ** 2 - 0.5 * (q[3] - q[2]) ** 2
        return l1 + l2

    system = dv.LagrangeDiracSystem(("q1", "q2", "q2bar", "q3"), lagrangian, constraints=sigma)
    traj = dv.simulate(system, [0.0, 1.0, 1.0, 2.0], [0.0, 0.0, 0.0, 3.0], dt=0.01, steps=30)
    _, product, _, _ = _structures(inst, "retraction", h=0.01)
    worst = 0.0
    for k in range(traj.steps):
        z0, z1 = (traj.q[k], traj.p[k]), (traj.q[k + 1], traj.p[k + 1])
        alpha = system_dirac_differential(system, traj.q[k], traj.q[k + 1], h=0.01)
        res, ok = product.membership(z0, z1, alpha)
        assert ok
        worst = max(worst, res)
    assert worst < 1e-12
    # and a step of a different trajectory does not
    alpha = system_dirac_differential(system, traj.q[3], traj.q[4], h=0.01)
    assert not product.contains((traj.q[3], traj.p[3] + 1e-6), (traj.q[4], traj.p[4]), alpha)


def test_tensor_witness_beta_is_a_valid_beta():
    inst = rlc_torn()
    direct, product, _, _ = _structures(inst, "retraction")
    q0 = np.zeros(5)
    q1 = np.array([0.3, 0.1, 0.2, 0.2, 0.2])  # satisfies all three discrete constraints
    p0, p1 = np.arange(5.0), -np.arange(5.0)
    sigma_row = inst.sigma[0]
    alpha = np.concatenate([p0 + 2.0 * np.array([1.0, -1.0, -1.0, 0, 0]) + 3.0 * sigma_row, q1])
    z0, z1 = (q0, p0), (q1, p1)
    assert product.contains(z0, z1, alpha)
    beta, left = product.witness(z0, z1, alpha)
    assert left < 1e-12
    interaction = product.b
    assert direct.contains(z0, z1, alpha + beta) and interaction.contains(z0, z1, -beta)


@examples(8)  # 21 s at 15: 8 draws by default (CI's time), 80 with the slow profile
@given(
    seed=st.integers(0, 2**31 - 1),
    dims=st.tuples(st.integers(1, 4), st.integers(1, 4)),
    data=st.data(),
    varying=st.booleans(),
    rule=st.sampled_from(["retraction", "midpoint"]),
)
def test_lemma_and_theorem_on_random_instances(seed, dims, data, varying, rule):
    rows = [data.draw(st.integers(0, d), label=f"m{i}") for i, d in enumerate(dims)]
    sigma_rows = data.draw(st.integers(1, 2), label="l")
    inst = random_instance(seed, dims, rows, sigma_rows, varying)
    q = np.random.default_rng(seed).standard_normal(inst.n)
    assume(is_clean(combined_forms(inst.forms, inst.sigma, inst.dims), q))
    direct, product, induced_sum, monolithic = _structures(inst, rule)
    pts = direct.sample_points(samples=3, seed=seed % 1000)
    assert direct.discrepancy(induced_sum, points=pts) < 1e-9
    assert product.discrepancy(monolithic, points=pts) < 1e-9
    # where Σ adds constraints, forgetting D_int must be detected
    with_sigma = combined_forms(inst.forms, inst.sigma, inst.dims)
    without = combined_forms(inst.forms, np.zeros((0, inst.n)), inst.dims)
    if rank(np.asarray(with_sigma(q))) > rank(np.asarray(without(q))):
        assert product.discrepancy(induced_sum, points=pts) > 1e-3


@pytest.mark.parametrize("rule", ["retraction", "midpoint"])
def test_minus_side_theorem_holds_too(rule):
    inst = random_instance(11, (3, 2), (1, 1), 1, True)
    _, product, _, monolithic = _structures(inst, rule, side="minus")
    assert product.discrepancy(monolithic, samples=4) < 1e-9


def test_mismatched_structures_are_refused():
    plus = InducedDiscrete(np.ones((1, 2)), side="plus")
    minus = InducedDiscrete(np.ones((1, 2)), side="minus")
    with pytest.raises(ModelError, match="same side"):
        DiscreteDiracStructure.tensor(plus, minus)
    with pytest.raises(ModelError, match="n=<dim Q>"):
        InducedDiscrete(lambda q: q[None, :])
    with pytest.raises(ModelError, match="rule="):
        InducedDiscrete(np.ones((1, 2)), rule="simpson")


@pytest.mark.parametrize("rule", ["retraction", "midpoint"])
@pytest.mark.parametrize("side", ["plus", "minus"])
def test_constraint_factorization_and_projection(rule, side):
    """c = ω_{d±} (the rule's discrete one-forms) = M(q₀, q₁)(q₁ − q₀); projecting a pair
    onto the discrete distribution moves only q₁ (plus) or q₀ (minus) and zeroes c."""
    forms = problems.get("rolling-disk").system.constraint_forms
    d = InducedDiscrete(forms, rule, h=0.01, side=side, n=4)
    rng = np.random.default_rng(3)
    q0, q1 = rng.standard_normal(4), rng.standard_normal(4)
    p0, p1 = rng.standard_normal(4), rng.standard_normal(4)
    c = d.constraint(q0, q1)
    np.testing.assert_allclose(c, d.constraint_matrix(q0, q1) @ (q1 - q0), rtol=1e-13)
    assert np.max(np.abs(c)) > 1.0  # a random pair is far off Δ^{d±}
    (a, pa), (b, pb) = d.project((q0, p0), (q1 + 0.0, p1))
    assert np.max(np.abs(d.constraint(a, b))) < 1e-10
    fixed, moved = (a, b) if side == "plus" else (b, a)
    np.testing.assert_array_equal(fixed, q0 if side == "plus" else q1)
    assert np.max(np.abs(moved - (q1 if side == "plus" else q0))) > 1e-3
    np.testing.assert_array_equal(pa, p0)
    np.testing.assert_array_equal(pb, p1)


def test_fiber_comparison_at_a_given_point():
    a = InducedDiscrete(np.array([[1.0, -1.0]]), side="plus")
    b = InducedDiscrete(np.array([[2.0, -2.0], [1.0, -1.0]]), side="plus")  # same Δ°
    c = InducedDiscrete(np.array([[1.0, 1.0]]), side="plus")
    z0, z1 = (np.zeros(2), np.ones(2)), (np.ones(2), -np.ones(2))
    assert a.fiber_gap(b, z0, z1) < 1e-14
    assert a.fiber_gap(c, z0, z1) == pytest.approx(1.0)
    interaction = InteractionDiscrete(np.array([[1.0, -1.0]]), side="plus")
    # same W, different offset (Ω^♭_{d+} vs Ω^{d+}_int = 0): the gap sees the shift
    assert a.fiber_gap(interaction, z0, z1) > 0.1
