"""The paper's theorem: interconnected equations = (+) equations of the monolithic system;
torn models = hand-built models on the shared coordinates."""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
from hypothesis import given
from hypothesis import strategies as st

import diracvi as dv
from conftest import examples, loglog_slope, one_rule_each, run
from diracvi import problems

TORN = [name for name in problems.REGISTRY if problems.get(name).reduced is not None]


def scale_of(traj):
    return max(1.0, float(np.max(np.abs(traj.q))))


def interconnected_vs_monolithic(problem, discretization, steps):
    torn = run(problem, discretization=discretization, steps=steps)
    mono = dv.simulate(
        problem.system.monolithic(),
        problem.q0,
        problem.p0,
        dt=problem.dt,
        steps=steps,
        discretization=discretization,
    )
    return torn, mono


# both rules on the paper's two examples; one rule per other torn problem by default and
# the twin with -m slow (each case compiles two systems). The driven DC motor runs with
# -m slow only: a driven torn model is shown equal to its monolithic one by default in
# test_driven.py (the driven RLC), and the DC motor's torn form here.
PAPER_TORN = ("spring-chain-torn", "rlc-torn")


# The n-mass chain (15 s) and the driven RLC (8 s) with -m slow too (the default suite's
# time on CI): by default the chain torn into pieces is test_n_mass_chain_torn_into_m_pieces;
# a driven torn model equals its monolithic one only under -m slow (test_driven.py's too).
_THEOREM_SLOW = {"dc-motor-driven", "chain-torn", "rlc-sine-torn"}


def _theorem_slow(name, rule):
    return name in _THEOREM_SLOW or (name not in PAPER_TORN and rule == "retraction")


THEOREM_CASES = [
    pytest.param(name, rule, marks=[pytest.mark.slow] if _theorem_slow(name, rule) else [])
    for name in TORN
    for rule in ("retraction", "midpoint")
]


@pytest.mark.parametrize(("name", "discretization"), THEOREM_CASES)
def test_theorem_on_every_torn_problem(name, discretization):
    check_theorem(name, discretization)


# the order-4 rule compiles a larger step (stages): one cheap case by default, the rest slow
@pytest.mark.parametrize(
    "name", [n if n == "rlc-torn" else pytest.param(n, marks=pytest.mark.slow) for n in TORN]
)
def test_theorem_on_every_torn_problem_under_the_order_four_rule(name):
    check_theorem(name, "lobatto")


def check_theorem(name, discretization):
    problem = problems.get(name)
    torn, mono = interconnected_vs_monolithic(problem, discretization, steps=1000)
    assert torn.success and mono.success
    dq, dp = np.max(np.abs(torn.q - mono.q)), np.max(np.abs(torn.p - mono.p))
    q_bound, p_bound = 1e-12 * scale_of(torn), 1e-12 * max(1.0, np.max(np.abs(torn.p)))
    if dq > q_bound or dp > p_bound:
        # The equations are the same; torn and monolithic runs round differently, and
        # a sensitive orbit (the double pendulum under the staged rule) amplifies one
        # step's ulp to ~1e-12 over 1000 steps. The round-off bound there is the spread
        # of the monolithic run restarted one ulp away; a torn model that broke the
        # theorem would differ by the rule's truncation error (> 1e-8 here).
        twin_q, twin_p = round_off_spread(problem, discretization, mono)
        q_bound, p_bound = max(q_bound, 10 * twin_q), max(p_bound, 10 * twin_p)
    assert dq <= q_bound
    assert dp <= p_bound
    assert mono.constraint_names == torn.constraint_names
    # the same multipliers too: μ_i and λ of the torn equations are the monolithic μ
    lam = max(1.0, float(np.max(np.abs(mono.multipliers))))
    assert np.max(np.abs(torn.multipliers - mono.multipliers)) <= 1e-10 * lam


def round_off_spread(problem, discretization, mono):
    """How far the monolithic run moves when its initial state moves by one ulp:
    ``(max |Δq|, max |Δp|)`` over the run (the floor of any comparison of two runs that
    round differently)."""
    ulp = np.finfo(np.float64).eps
    sign = np.where(np.arange(problem.system.n) % 2 == 0, 1.0, -1.0)
    twin = dv.simulate(
        problem.system.monolithic(),
        problem.q0 * (1.0 + ulp * sign),
        problem.p0 * (1.0 - ulp * sign),
        dt=problem.dt,
        steps=len(mono.t) - 1,
        discretization=discretization,
    )
    assert twin.success
    return np.max(np.abs(twin.q - mono.q)), np.max(np.abs(twin.p - mono.p))


@pytest.mark.parametrize(
    ("name", "discretization"),
    one_rule_each(["spring-chain-torn", "rlc-torn", "chain-torn", "dc-motor"]),
)
def test_torn_model_equals_hand_built_model(name, discretization):
    """Paper §5: the extra port variables change nothing on the shared coordinates."""
    problem = problems.get(name)
    torn = run(problem, discretization=discretization)
    reduced = run(problem.reduced, discretization=discretization, steps=problem.steps)
    scale = scale_of(reduced)
    for a, b in problem.shared.items():
        assert np.max(np.abs(torn[a] - reduced[b])) <= 1e-12 * scale, (a, b)
    for a, b in problem.ports:  # the interconnection constraint, position level
        assert np.max(np.abs(torn[a] - torn[b])) <= 1e-13 * scale


@pytest.mark.parametrize(
    ("masses", "pieces"),
    [
        (2, 2),
        (5, 2),
        (12, 3),
        *(pytest.param(*c, marks=pytest.mark.slow) for c in [(9, 9), (40, 7)]),
    ],
)
def test_n_mass_chain_torn_into_m_pieces(masses, pieces):
    problem = problems.chain_torn(masses, pieces, steps=500)
    assert len(problem.system.subsystems) == pieces
    torn = run(problem)
    reduced = run(problem.reduced, steps=500)
    for a, b in problem.shared.items():
        assert np.max(np.abs(torn[a] - reduced[b])) <= 1e-12 * scale_of(reduced)


def test_chain_torn_shared_names_pair_each_mass_once():
    """The torn chain's ``shared`` (a mapping computed on lookup) pairs every mass
    coordinate of the pieces with one reduced coordinate at the same initial position,
    and nothing else (no port variable, no unknown name)."""
    problem = problems.chain_torn(17, 5)
    shared, reduced = problem.shared, problem.reduced
    ports = {b for _, b in problem.ports}
    masses = [c for c in problem.system.coords if c not in ports]
    assert list(shared) == masses and len(shared) == 17
    assert sorted(shared.values(), key=lambda c: int(c[1:])) == list(reduced.system.coords)
    q0 = dict(zip(problem.system.coords, problem.q0, strict=True))
    r0 = dict(zip(reduced.system.coords, reduced.q0, strict=True))
    assert all(q0[a] == r0[b] for a, b in shared.items())
    for missing in ("s5.q0", "s1.q4", "s1.qbar", "s01.q0", "q1", 3):
        assert missing not in shared


# 9 s, in `-m slow` (CI time): interconnections of interconnections are stepped by default
# in test_controlled.py's subcircuits and tests/test_spice_reader.py's nested .subckt
@pytest.mark.slow
def test_hierarchical_interconnection_equals_the_flat_one():
    flat = problems.chain_torn(9, 3, steps=300)
    s0, s1, s2 = flat.system.subsystems
    last0, last1 = s0.coords[-1], s1.coords[-1]
    front = dv.interconnect([s0, s1], [dv.connect(f"s0.{last0}", "s1.qbar")], name="front")
    whole = dv.interconnect([front, s2], [dv.connect(f"front.s1.{last1}", "s2.qbar")])
    assert whole.coords == tuple(f"front.{c}" for c in front.coords) + tuple(
        f"s2.{c}" for c in s2.coords
    )
    nested = dv.simulate(whole, flat.q0, flat.p0, dt=flat.dt, steps=300)
    np.testing.assert_allclose(nested.q, run(flat).q, rtol=0, atol=1e-12 * scale_of(nested))


# ------------------------------------------------------------------ random systems
@st.composite
def random_interconnection(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    sizes = draw(st.lists(st.integers(1, 3), min_size=2, max_size=5))
    subsystems = []
    for i, n in enumerate(sizes):
        a = rng.normal(size=(n, n))
        mass = a @ a.T + n * np.eye(n)
        b = rng.normal(size=(n, n))
        stiff = b @ b.T
        nonlin = 0.1 * rng.normal(size=n)

        def lag(q, v, mass=mass, stiff=stiff, nonlin=nonlin):
            return 0.5 * v @ mass @ v - 0.5 * q @ stiff @ q + nonlin @ jnp.cos(q)

        kind = draw(st.sampled_from(["none", "constant", "q-dependent"])) if n >= 2 else "none"
        row, tilt = rng.normal(size=(1, n)), 0.3 * rng.normal(size=(1, n))
        forms = {
            "none": None,
            "constant": row,
            "q-dependent": lambda q, row=row, tilt=tilt: row + tilt * jnp.sin(q)[None, :],
        }[kind]
        subsystems.append(
            dv.LagrangeDiracSystem(
                [f"x{j}" for j in range(n)], lag, constraints=forms, name=f"s{i}"
            )
        )
    total = sum(sizes)
    interactions = []
    for _ in range(draw(st.integers(1, 2))):
        row, tilt = rng.normal(size=(1, total)), 0.3 * rng.normal(size=(1, total))
        if draw(st.booleans()):
            interactions.append(dv.Interaction(row))
        else:
            interactions.append(
                dv.Interaction(lambda q, row=row, tilt=tilt: row + tilt * jnp.cos(q)[None, :])
            )
    system = dv.interconnect(subsystems, interactions)
    q0 = 0.5 * rng.normal(size=total)
    p0 = rng.normal(size=total)
    return system, q0, p0


# each example compiles two systems (3–8 s): 2 derandomized draws by default, 20 random
# ones under --hypothesis-profile=slow; the midpoint twin runs with -m slow
@pytest.mark.parametrize(
    "discretization", ["retraction", pytest.param("midpoint", marks=pytest.mark.slow)]
)
@examples(2)
@given(case=random_interconnection())
def test_theorem_on_random_interconnections(case, discretization):
    system, q0, p0 = case
    kwargs = {"dt": 0.01, "steps": 1000, "discretization": discretization, "throw": False}
    torn = dv.simulate(system, q0, p0, **kwargs)
    mono = dv.simulate(system.monolithic(), q0, p0, **kwargs)
    assert torn.status == mono.status == 0
    assert np.max(np.abs(torn.q - mono.q)) <= 1e-12 * scale_of(torn)
    assert np.max(np.abs(torn.constraint_residual)) <= 1e-11
    lam = max(1.0, float(np.max(np.abs(mono.multipliers))))
    assert np.max(np.abs(torn.multipliers - mono.multipliers)) <= 1e-9 * lam


# ------------------------------------------------------------------ double pendulum
def reduced_reference(problem, horizon):
    """Exact solution of the reduced double pendulum: DOP853 at tight tolerance."""
    import jax

    red = problem.reduced.system

    @jax.jit
    def acceleration(y):
        q, v = y[:2], y[2:]
        mass = jax.hessian(red.lagrangian, argnums=1)(q, v)
        dldq = jax.grad(red.lagrangian, argnums=0)(q, v)
        mixed = jax.jacfwd(jax.grad(red.lagrangian, argnums=1), argnums=0)(q, v)
        return jnp.concatenate([v, jnp.linalg.solve(mass, dldq - mixed @ v)])

    def rhs(_, y):
        return np.asarray(acceleration(y))

    v0 = np.array(problem.parameters["omega0"])
    sol = scipy.integrate.solve_ivp(
        rhs,
        (0, horizon),
        np.concatenate([problem.reduced.q0, v0]),
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )
    return sol.sol


@pytest.mark.parametrize(
    "discretization", [pytest.param("retraction", marks=pytest.mark.slow), "midpoint"]
)
def test_torn_double_pendulum_converges_to_the_reduced_one(discretization):
    problem = problems.get("double-pendulum-torn")
    horizon = 1.0
    exact = reduced_reference(problem, horizon)
    hs = np.array([0.02, 0.01, 0.005, 0.0025])
    errors = []
    for h in hs:
        traj = run(problem, dt=h, steps=round(horizon / h), discretization=discretization)
        angles = np.stack([traj["upper.theta1"], traj["lower.theta2"]], axis=1)
        errors.append(np.max(np.abs(angles - exact(traj.t)[:2].T)))
    order = {"retraction": 1, "midpoint": 2}[discretization]
    assert abs(loglog_slope(hs, errors) - order) < 0.2, errors


# ------------------------------------------------------------------ bad input
def two_masses():
    free = dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v, name="a")
    other = dv.LagrangeDiracSystem(("y",), lambda q, v: 0.5 * v @ v, name="b")
    return free, other


@pytest.mark.parametrize(
    ("interactions", "needles"),
    [
        ([dv.connect("c.x", "b.y")], ["'c.x'", "subsystem 'c'", "['a', 'b']"]),
        ([dv.connect("a.z", "b.y")], ["no coordinate 'z'", "('x',)"]),
        ([dv.Interaction(np.ones((1, 3)))], ["shape (1, 3)", "2 coordinates", "('a.x', 'b.y')"]),
        ([dv.Interaction(lambda q: jnp.ones(2))], ["shape (2,)"]),
        ([dv.Interaction([[1.0, -1.0]], names=("u", "v"))], ["1 one-form rows but 2 names"]),
        (dv.connect("a.x", "b.y"), ["must be a list"]),
    ],
)
def test_interconnect_rejects_bad_interactions(interactions, needles):
    with pytest.raises(dv.ModelError) as info:
        dv.interconnect(list(two_masses()), interactions)
    for needle in needles:
        assert needle in str(info.value)


def test_connect_rejects_self_and_unqualified_names():
    with pytest.raises(dv.ModelError, match="to itself"):
        dv.connect("a.x", "a.x")
    with pytest.raises(dv.ModelError, match=r"'subsystem\.coordinate'"):
        dv.connect("x", "b.y")


def test_duplicate_and_too_few_subsystems():
    a, _ = two_masses()
    with pytest.raises(dv.ModelError, match=r"\['a'\] are used more than once"):
        dv.interconnect([a, a], [])
    with pytest.raises(dv.ModelError, match="at least two"):
        dv.interconnect([a], [])


def test_unconnected_massless_port_is_reported_before_stepping():
    problem = problems.get("spring-chain-torn")
    left, right = problem.system.subsystems
    loose = dv.interconnect([left, right], [])
    with pytest.raises(dv.UnsolvableStepError) as info:
        dv.simulate(loose, problem.q0, problem.p0, dt=0.01, steps=10)
    assert "q_{k+1}[right.q2bar]" in str(info.value)
    assert "q_{k+1}[left.q1]" not in str(info.value)


def test_multipliers_report_subsystems_then_interactions():
    problem = problems.get("dc-motor")
    system = problem.system
    assert system.interaction_names == ("armature.qM=gyrator.qe", "rotor.theta=gyrator.phi")
    assert system.constraint_names[:3] == (
        "armature.KCL_SR",
        "armature.KCL_RL",
        "armature.KCL_LM",
    )
    traj = run(problem, steps=100)
    torque = traj.multiplier("rotor.theta=gyrator.phi")
    current = np.diff(traj["armature.qL"]) / problem.dt
    # the rotor-side λ is the gyrator torque impulse: λ = −h K i (per step)
    k = problem.parameters["K"]
    np.testing.assert_allclose(torque, -problem.dt * k * current, rtol=1e-9, atol=1e-15)


def test_monolithic_keeps_the_subsystems_affine_constraint_offsets():
    # a current source u(t) = I₀ cos ωt inside the torn subsystem ``src`` (the affine row
    # v^I − u(t) = 0) feeds R ∥ C across the tear: q̇^C = u − q^C/(RC), a closed form.
    # monolithic() must carry the offset b(q, t) = −u(t): without it the twin's source
    # is dead and q^C stays at rest.
    r, c, i0, om = 2.0, 0.5, 1.5, 3.0
    src = dv.LagrangeDiracSystem(
        ("qI", "qR", "qS1"),
        lambda q, v, t: 0.0 * v[0],
        constraints=lambda q, t: jnp.array([[1.0, 0.0, 0.0], [1.0, -1.0, -1.0]]),
        constraint_offset=lambda q, t: jnp.array([-i0 * jnp.cos(om * t), 0.0]),
        force=lambda q, v, t: jnp.stack([0.0 * v[0], -r * v[1], 0.0 * v[2]]),
        name="src",
        constraint_names=("I", "KCL"),
    )
    cap = dv.LagrangeDiracSystem(
        ("qS2", "qC"),
        lambda q, v: -(q[1] ** 2) / (2.0 * c),
        constraints=np.array([[-1.0, 1.0]]),
        name="cap",
        constraint_names=("KCL",),
    )
    torn = dv.interconnect([src, cap], [dv.connect("src.qS1", "cap.qS2")])
    kwargs = dict(dt=0.01, steps=300, discretization="midpoint")
    a_torn = dv.simulate(torn, np.zeros(5), np.zeros(5), **kwargs)
    a_mono = dv.simulate(torn.monolithic(), np.zeros(5), np.zeros(5), **kwargs)
    a, t = 1.0 / (r * c), np.asarray(a_torn.t)
    exact = (-i0 * a * np.exp(-a * t) + i0 * (a * np.cos(om * t) + om * np.sin(om * t))) / (
        a * a + om * om
    )
    np.testing.assert_allclose(np.asarray(a_torn.q)[:, 4], exact, atol=1e-4)  # O(h²) = 3e-5
    np.testing.assert_allclose(np.asarray(a_mono.q), np.asarray(a_torn.q), rtol=0, atol=1e-12)
