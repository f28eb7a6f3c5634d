r"""The circuit-scale linear path: a sparse step matrix condensed onto the nodes, factored
once, stepped on the host.

For an interconnection whose step equations are affine (the affine screen's test, done
here on compressed Jacobians) the step from ``z = (q, p)`` is, in increments
``y = (q_other − q, μ)`` as in :mod:`diracvi.solvers.affine`,

    J_x y = −(r₀(t_k) + J_z z),        p_other − p = P₀(t_k) + P_z z + P_x y

with ``J_x = ∂r/∂y`` the step Jacobian. For an interconnection of many small parts it
is sparse: a part's equations involve its own unknowns and the multipliers of the
interaction rows it is in, an interaction row (a node's KCL) the unknowns of the parts it
joins — the structure of modified nodal analysis. The dense affine map ``Δ`` of
:mod:`diracvi.solvers.affine` is full (O(n²) per step and memory); here ``J_x`` is
assembled sparse and solved by **condensing the parts' own unknowns**
(:mod:`diracvi.solvers.condensed`): each part's own block of ``J_x`` is inverted (alike
parts as one stacked array) and the Schur complement ``S`` onto the nodes' multipliers
(and the unknowns of parts whose own block is singular, as a voltage source's) — a
system of the node count, like MNA's — is factored ONCE by SuperLU (COLAMD). The step
is then, on the augmented state ``z̃ = (q, p, 1, u)`` (``u`` the driven parts' moving
offsets at the step's time),

    v = S⁻¹ (G_s z̃),        z' = G_z (z̃, v),

two sparse products accumulated in place and one solve of the node count; the step's
unknowns ``y``, the constraint residuals and the momenta's impulses are recovered after
each block of steps from ``(z̃, v)``, one product each over the block. ``lu`` (a
:class:`~diracvi.solvers.condensed.CondensedSolve`) is ``J_x⁻¹``: ``lu.solve(rhs)`` for
``rhs`` of shape ``(size,)`` or ``(size, m)``; ``lu.schur`` is the SuperLU factor of ``S``.

**Assembly, compiled once per kind of part.** The Jacobians come from ``K`` compressed
JVPs of the packed interconnection's residual (alike parts vmapped, so the program does
not grow with their number). The pattern is structural: a column of part ``i``
(its ``q``, ``p``, increment or own multiplier) can touch only part ``i``'s equations
and the interaction rows ``i`` is in; a multiplier ``λ_b`` only the equations of the
parts row ``b`` joins. Parts that share no interaction row get the same seed (a greedy
colouring), so ``K`` is a few times the largest part's size, whatever their number.

**Affinity** is checked as in the dense screen, on those products: the JVPs at zero and
at a pseudo-random point (at another time, for a driven model) must agree, and the
residual and momentum line at that point must equal ``f(0) + J w`` — which also checks
the structural pattern (a missed entry would break the equality). ``detect_rtol``
relative, as :class:`~diracvi.AffineSolver`.

**Why condensed, and why SciPy on the host.** The factorization has data-dependent fill
and pivoting; JAX has no sparse LU, and a dense or banded one would be O(n·b²) to form
and would not serve general meshes. The per-step solve is latency-bound (a chain of
dependent row updates, ≈ 3.5 ns per non-zero of L + U whatever the ordering), so what
pays is fewer unknowns in the factored system: on the 1000-stage ladder ``J_x`` has 5002
unknowns and nnz(L + U) = 22 002 (74 µs CPU a solve), ``S`` 2002 and 8011 (36 µs).
Measured side by side (``benchmarks/ladder_step.py``; ``benchmarks/README.md``, "Fixed-step
sparse path, condensed onto the nodes"), CPU µs a step, products and solve: 18.6 → 11.0
at 100 stages, 93.5 → 58.0 at 1000, 909 → 533 at 10⁴ (1.6–1.7×; the nodal solve is
36 of the 58). Folding the offsets into the state and accumulating the two products in
place (SciPy's ``csr_matvec``) saved the rest of the per-step calls.
Dropped by measurement: a banded LAPACK solve in reverse Cuthill–McKee order
(``dgbtrs`` 430 µs against SuperLU's 240 µs on ``J_x``; on ``S``, tridiagonal in that
order, ``dgbtrs`` 149 µs and ``dgttrs`` 91 µs against SuperLU's 112 µs at the same
load: not worth a special case), the augmented system ``[J_x 0; −S I]`` (130 µs),
``spsolve_triangular`` (2 ms). The driven offsets ``r₀(t_k)``, ``P₀(t_k)`` and the
energies are evaluated by compiled JAX programs, a block of steps per call (the
energies by ``lax.map`` over the steps: vmapped, the packed parts' gathers ran 4.6×
slower).

**Verification.** A sample of steps (the last of every block) is re-evaluated with the
model's own residual, and one Newton correction ``J_x⁻¹ r`` of it (by ``lu``) must be below
``verify_rtol`` relative to the step's size, as the dense map's per-step test.
"""

from __future__ import annotations

import functools

import numpy as np

from ..discretization.equations import new_momentum, reaction_impulse, residual, unknown_count
from ..runtime.compile import run_once_jit
from .affine import AffineSolver
from .condensed import ScaledLU, SingularStep, condense, own_unknowns
from .sparse_pattern import NotSparseAffine, _by_identity, _pattern, _structure
from .sparse_pattern import driving as parts_driving

#: the initial-data check of a run on this path checks momenta (a dense O(n³)
#: projector) up to this many coordinates; joined ports always
SPARSE_MOMENTUM_CHECK_LIMIT = 256

#: steps per block: the driven offsets and the energies are computed a block at a time
#: (one compiled program for every block: the last is padded)
BLOCK = 256
#: a block's buffers (states, increments, offsets) stay within about this many bytes:
#: fewer steps per block for a large circuit (256 steps of a 10⁵-stage ladder were
#: ≈ 5 GB of buffers), so a run that keeps no states is O(n) in memory
BLOCK_BYTES = 64 << 20


def block_length(n: int, size: int) -> int:
    """Steps per block for ``n`` coordinates and ``size`` unknowns (8 … ``BLOCK``)."""
    per_step = 8 * (5 * n + 2 * size)  # states, increments, padded q pairs, offsets
    return int(max(8, min(BLOCK, BLOCK_BYTES // per_step)))


def _parts(system, rule, scheme, h, w, tk):
    """``(r, p_other − p, A(q)ᵀμ)`` at ``w = (q, p, y)``, ``q_other = q + y[:n]``."""
    n = system.n
    q, p, y = w[:n], w[n : 2 * n], w[2 * n :]
    x = y.at[:n].add(q)
    r = residual(system, rule, scheme, h, q, p, x, tk)
    pm = new_momentum(system, rule, scheme, h, q, x, tk) - p
    impulse = reaction_impulse(system, scheme, h, q, x[n:], tk)
    return r, pm, impulse


def _probe_fn(system, rule, scheme, h, bases, times, seeds):
    """Values at each base point and time, and the JVPs along every seed there."""
    import jax

    def at(w, tk):
        def f(u):
            return _parts(system, rule, scheme, h, u, tk)

        # the value is the JVPs' primal output, not batched over the seeds: ``f`` traced
        # once, not once more for the value (measured on the 1000-stage ladder, fresh
        # process: 2469 → 1613 equations, tracing 1.1–1.5 → 0.8–0.95 CPU s, compiling
        # 0.1 s less; the values the same to 4 ulp)
        return jax.vmap(lambda s: jax.jvp(f, (w,), (s,)), out_axes=(None, 0))(seeds)

    return jax.vmap(at)(bases, times)


def _own_offsets(sub, rule, scheme, h, tk):
    """One part's own residual and momentum line at its zero state: its rows of the
    interconnection's at the zero state (the interaction terms ``Bᵀλ``, ``B v`` vanish
    there)."""
    import jax.numpy as jnp

    zero_q, zero_x = jnp.zeros(sub.n), jnp.zeros(sub.n + sub.m)
    r = residual(sub, rule, scheme, h, zero_q, zero_q, zero_x, tk)
    return r, new_momentum(sub, rule, scheme, h, zero_q, zero_x, tk)


def _block_fn(system, drivers, rule, scheme, h, times_next, qk, qk1, times):
    """The offsets ``r₀(t)``, ``P₀(t)`` of each ``t`` of ``times_next`` (the next block's)
    and ``E`` at the quadrature node of each step ``(q_k, q_{k+1}, t_k)`` of this block:
    one program for both. ``drivers``: the time-dependent parts, whose rows are all that
    move with ``t`` (each part's own rows, so the program does not evaluate the
    interconnection's dense one-forms), or ``None``: the whole residual at zero."""
    import jax
    import jax.numpy as jnp

    if drivers is None:
        size = 2 * system.n + unknown_count(system, rule)

        def offsets(tk):
            r, pm, _ = _parts(system, rule, scheme, h, jnp.zeros(size), tk)
            return r, pm

    else:

        def offsets(tk):
            pieces = [_own_offsets(sub, rule, scheme, h, tk) for sub in drivers]
            return (
                jnp.concatenate([r for r, _ in pieces]),
                jnp.concatenate([pm for _, pm in pieces]),
            )

    r0, pm0 = jax.vmap(offsets)(times_next)
    # the energy alone (the step diagnostics' constraint rows would evaluate the
    # interaction's dense one-forms: they are formed on the host, from the sparse rows)
    # (a loop over the steps, not vmap: the packed parts' gathers batched over 256 steps
    # ran 4.6× slower on the 1000-stage ladder, 67 → 14.6 ms a block)
    energy = jax.lax.map(
        lambda args: rule.step_energy(system.energy, *args[:2], h, args[2], None),
        (qk, qk1, times),
    )
    return r0, pm0, energy


#: at most this many time-dependent parts are evaluated part by part for the offsets
#: (more: the whole residual at zero, one program over the packed system)
MAX_DRIVERS = 16

#: ``(h, t)`` pairs in one call of the drivers' offsets program: the variable-step
#: path's calls (:mod:`diracvi.driver.sparse_offsets`, three pairs a try for ``AHEAD``
#: tries) and the check of the drivers here, so that one compiled program serves both
#: (a program per shape: a cold run compiled, a warm one loaded, two)
OFFSETS_PAIRS = 192


@functools.cache
def _csr_matvec():
    """SciPy's in-place ``y += A x`` for a CSR matrix, without its dispatch (≈ 3 µs a
    call), or None in a SciPy that moved it. Looked up on first use: importing diracvi
    does not import SciPy (``tests/test_imports.py``)."""
    try:
        from scipy.sparse._sparsetools import csr_matvec
    except ImportError:  # pragma: no cover (a SciPy that moved it: the public product)
        return None
    return csr_matvec


def _accumulate(a, x, y) -> None:
    """``y += a @ x`` for a CSR ``a`` and contiguous float64 ``x``, ``y``."""
    matvec = _csr_matvec()
    if matvec is None:
        y += a @ x
    else:
        matvec(a.shape[0], a.shape[1], a.indptr, a.indices, a.data, x, y)


def _offsets_fn(system, drivers, rule, scheme, hs, ts):
    """``(r₀, P₀)`` of each pair ``(h, t)``: the driven parts' own rows (``drivers``) or,
    with ``drivers=None``, the whole residual and momentum line at zero (``h`` is data:
    the variable-step path asks it for every step size)."""
    import jax
    import jax.numpy as jnp

    if drivers is None:
        size = 2 * system.n + unknown_count(system, rule)

        def one(h, t):
            r, pm, _ = _parts(system, rule, scheme, h, jnp.zeros(size), t)
            return r, pm

    else:

        def one(h, t):
            pieces = [_own_offsets(sub, rule, scheme, h, t) for sub in drivers]
            return (
                jnp.concatenate([r for r, _ in pieces]),
                jnp.concatenate([pm for _, pm in pieces]),
            )

    return jax.vmap(one)(hs, ts)


_probe = run_once_jit(_probe_fn, "diracvi.solvers.sparse_affine._probe")
_offsets = run_once_jit(_offsets_fn, "diracvi.solvers.sparse_affine._offsets")
_block = run_once_jit(_block_fn, "diracvi.solvers.sparse_affine._block")


# ----------------------------------------------------------------------- the map
class SparseAffineMap:
    """The assembled, factored step of a linear interconnection (host side).

    Built by :func:`build`; :meth:`run` steps it. ``describe`` names it in ``traj.solver``.
    """

    describe = "sparse affine step map (condensed to the nodes, SuperLU)"

    def __init__(self, system, rule, scheme, h, mats, lu, driven, r0, pm0, verify_rtol, seeds):
        self.system, self.rule, self.scheme, self.h = system, rule, scheme, float(h)
        self.jz, self.jx, self.pz, self.px, self.imp = mats
        self.n, self.size = system.n, self.jx.shape[0]
        self.block = block_length(self.n, self.size)
        import scipy.sparse as sp

        self._con = sp.hstack([self.jz[self.n :], self.jx[self.n :]]).tocsr()
        self.lu, self.driven = lu, driven
        self.r0, self.pm0 = r0, pm0  # the autonomous offsets (driven: at t0)
        self.verify_rtol = verify_rtol
        self.seeds = seeds
        self.drivers = self.driver_rows = self.driver_coords = None
        self._nk = lu.kept.size
        self._step = None  # (made when first stepped: see _augmented)
        self._one = None  # (one_step's bound calls, made at its first call)

    def _operators(self):
        """The step as products with the condensed solve's pieces (see :meth:`run`):

            s = T_z z + T_r r₀,   v = S⁻¹ s,   z' = M_z z + M_v v + M_r r₀ + (0, P₀),
            y = Y_x (z, v) + Y_r r₀,   c = C_x (z, v) + C_r r₀

        with ``v`` the kept unknowns (the multipliers of the nodes, and the unknowns of
        parts not condensed) and ``c`` the constraint rows' residual. All sparse with
        the parts' own patterns: O(n) entries. Returns them and ``M_v``; they are not
        kept (:meth:`_augmented` makes the step's operators of them once: kept, they were
        a third of a map's memory, 13 maps in a variable-step run of a large circuit)."""
        import scipy.sparse as sp

        n, size, lu = self.n, self.size, self.lu
        cond, kept = lu.cond, lu.kept
        e_c = sp.csr_matrix(
            (np.ones(cond.size), (cond, np.arange(cond.size))), shape=(size, cond.size)
        )
        e_k = sp.csr_matrix(
            (np.ones(kept.size), (kept, np.arange(kept.size))), shape=(size, kept.size)
        )
        jz = self.jz.tocsr()
        jz_c, jz_k = jz[cond], jz[kept]
        t_z = -(jz_k - lu.left @ jz_c)
        t_r = -(e_k.T - lu.left @ e_c.T)
        y_z = -(e_c @ (lu.inv_a @ jz_c))
        y_v = e_k - e_c @ lu.right
        y_r = -(e_c @ lu.inv_a @ e_c.T)
        q_of_y = sp.vstack([sp.eye(n, size), self.px]).tocsr()  # (q' − q, p' − p) from y
        m_z = sp.eye(2 * n) + sp.vstack([sp.csr_matrix((n, 2 * n)), self.pz]) + q_of_y @ y_z
        con_z, con_y = self._con[:, : 2 * n], self._con[:, 2 * n :]
        c_r = con_y @ y_r + sp.eye(size - n, size, k=n)
        parts = dict(
            t_z=t_z, m_z=m_z, y_z=y_z, y_v=y_v, c_z=con_z + con_y @ y_z, c_v=con_y @ y_v,
            offsets=sp.vstack([t_r, q_of_y @ y_r, y_r, c_r]).tocsc(),  # (T_r; M_r; Y_r; C_r)
        )  # fmt: skip
        return parts, (q_of_y @ y_v).tocsr()

    def resized(self, h, mats, lu):
        """This map at another step size: ``mats = (J_z, J_x, P_z, P_x, r₀, P₀)`` of size
        ``h`` (combined from others, see :mod:`diracvi.driver.adaptive_sparse`) and
        ``lu`` the :class:`~diracvi.solvers.condensed.CondensedSolve` of its ``J_x``; the
        drivers, seeds and verification carry over."""
        import copy

        import scipy.sparse as sp

        out = copy.copy(self)
        jz, jx, pz, px, r0, pm0 = mats
        out.h, out.lu = float(h), lu
        out.jz, out.jx, out.pz, out.px = jz.tocsr(), jx, pz.tocsr(), px.tocsr()
        out.r0, out.pm0 = np.asarray(r0), np.asarray(pm0)
        out._con = sp.hstack([out.jz[self.n :], jx.tocsr()[self.n :]]).tocsr()
        out._nk = lu.kept.size
        out._step = out._one = None
        return out

    def one_step(self, z, u, into, y):
        """One step from ``z = (q, p)`` with the moving offsets ``u`` (see
        :meth:`_augmented`): ``into`` gets ``z'``, ``y`` the step's unknowns (both
        overwritten). Three products accumulated in place and one solve of the node
        count."""
        if self._one is None:
            self._one = self._one_stepper()
        self._one(z, u, into, y)

    def _one_stepper(self):
        """:meth:`one_step` with its calls bound once, as :meth:`_stepper`'s (the same
        kernels in the same order, so the same bits), and its row and right-hand side
        buffers reused: the variable-step path takes ≈ 10⁴ steps of a map's size on a
        large circuit, one call each."""
        step = self._augmented()
        g_s, g_z, g_y = step["g_s"], step["g_z"], step["y"]
        width, n2, nk = step["width"], 2 * self.n, self._nk
        row, rhs = np.empty(width + nk), np.empty(nk)
        row[n2] = 1.0
        matvec, lu = _csr_matvec(), self.lu.schur
        if matvec is None or not isinstance(lu, ScaledLU):  # pragma: no cover

            def one(z, u, into, y):
                row[:n2], row[n2 + 1 : width] = z, u
                rhs[:] = 0.0
                _accumulate(g_s, row[:width], rhs)
                row[width:] = lu.solve(rhs)
                into[:] = 0.0
                _accumulate(g_z, row, into)
                y[:] = 0.0
                _accumulate(g_y, row, y)

            return one
        s_args = (g_s.shape[0], g_s.shape[1], g_s.indptr, g_s.indices, g_s.data)
        z_args = (g_z.shape[0], g_z.shape[1], g_z.indptr, g_z.indices, g_z.data)
        y_args = (g_y.shape[0], g_y.shape[1], g_y.indptr, g_y.indices, g_y.data)
        solve, r_scale, c_scale = lu._lu.solve, lu._rows, lu._cols
        multiply = np.multiply

        def one(z, u, into, y):
            row[:n2], row[n2 + 1 : width] = z, u
            rhs.fill(0.0)
            matvec(*s_args, row[:width], rhs)
            multiply(r_scale, rhs, out=rhs)
            multiply(solve(rhs), c_scale, out=row[width:])
            into.fill(0.0)
            matvec(*z_args, row, into)
            y.fill(0.0)
            matvec(*y_args, row, y)

        return one

    #: the rows and coordinates of parts whose offsets the caller sets step by step
    #: besides the drivers' (the variable-step path's transmission lines, whose incident
    #: waves are history: :mod:`diracvi.driver.sparse_lines`); none by default
    line_rows = line_coords = np.zeros(0, np.int64)

    def _moving(self):
        """The entries of ``r₀`` and ``P₀`` that move with ``t`` (the driven parts' rows,
        every row when they are many, none for an autonomous model), then
        :attr:`line_rows`, :attr:`line_coords` (unless every row moves already)."""
        n, size = self.n, self.size
        if self.driven and self.drivers is None:
            return np.arange(size), np.arange(n)
        if not self.driven:
            return self.line_rows, self.line_coords
        return (
            np.concatenate([self.driver_rows, self.line_rows]),
            np.concatenate([self.driver_coords, self.line_coords]),
        )

    def _augmented(self):
        """The step and its diagnostics as products with the augmented state
        ``z̃ = (q, p, 1, u)`` (``u``: the moving entries of ``r₀``, ``P₀`` at the step's
        time; the constant ones are the column of ``1``):

            s = G_s z̃,   v = S⁻¹ s,   z' = G_z (z̃, v),   y = Y (z̃, v),   c = C (z̃, v)

        (``G_z = (M_z, …, M_v)``) so a step is two products accumulated in place and one
        solve, whatever drives it."""
        if self._step is not None:
            return self._step
        import scipy.sparse as sp

        # (here, when first stepped: a map of the variable-step path's fit may never step)
        parts, m_v = self._operators()
        n, nk, size = self.n, self._nk, self.size
        rows, coords = self._moving()
        r_fixed, p_fixed = self.r0.copy(), self.pm0.copy()
        r_fixed[rows], p_fixed[coords] = 0.0, 0.0
        off = parts["offsets"]
        base = off @ r_fixed
        base[nk + n : nk + 2 * n] += p_fixed
        into_p = sp.csc_matrix(
            (np.ones(coords.size), (nk + n + coords, np.arange(coords.size))),
            shape=(off.shape[0], coords.size),
        )
        extra = sp.hstack([sp.csc_matrix(base[:, None]), off[:, rows], into_p]).tocsr()
        a, b, c = np.cumsum([nk, 2 * n, size])
        e_s, e_z, e_y, e_c = extra[:a], extra[a:b], extra[b:c], extra[c:]
        self._step = dict(
            g_s=sp.hstack([parts["t_z"], e_s]).tocsr(),
            g_z=sp.hstack([parts["m_z"], e_z, m_v]).tocsr(),
            y=sp.hstack([parts["y_z"], e_y, parts["y_v"]]).tocsr(),
            c=sp.hstack([parts["c_z"], e_c, parts["c_v"]]).tocsr(),
            width=2 * n + 1 + rows.size + coords.size,
        )
        for name in ("g_s", "g_z", "y", "c"):
            self._step[name].sort_indices()
        return self._step

    # ------------------------------------------------------------------ blocks
    def _block(self, times_next, qk, qk1, times):
        """The next block's moving offsets ``(r₀, P₀)`` (the driven parts' rows, or every
        row) and this block's energies (one call of one compiled program; every argument
        padded to ``self.block`` rows)."""

        def padded(a):
            if len(a) == self.block:
                return a
            return np.concatenate([a, np.repeat(a[-1:], self.block - len(a), axis=0)])

        r0, pm0, energy = _block(
            self.system, self.drivers, self.rule, self.scheme, np.float64(self.h),
            padded(times_next), padded(qk), padded(qk1), padded(times),
        )  # fmt: skip
        count = len(times_next)
        r0, pm0 = np.asarray(r0)[:count], np.asarray(pm0)[:count]
        return r0, pm0, np.asarray(energy)[: len(times)]

    def _check_steps(self, z, y, times, shift=None):
        """The largest Newton correction ``J_x⁻¹ r`` (relative) of the steps ``z → y``,
        with ``r`` the model's own residual: the probe program of :func:`build`, three
        steps per call (its shapes: nothing new is compiled). ``shift``: per step, what
        the residual has beyond the model's (a line's incident waves, set by the caller
        as offsets: :mod:`diracvi.driver.sparse_lines`)."""
        worst = 0.0
        for a in range(0, len(times), 3):
            w = np.concatenate([z[a : a + 3], y[a : a + 3]], axis=1)
            tk = times[a : a + 3]
            count = len(tk)
            w = np.concatenate([w, np.repeat(w[-1:], 3 - count, axis=0)])
            tk = np.concatenate([tk, np.repeat(tk[-1:], 3 - count)])
            (r, _, _), _ = _probe(
                self.system, self.rule, self.scheme, np.float64(self.h), w, tk, self.seeds
            )
            r = np.asarray(r)[:count]
            if shift is not None:
                r = r + shift[a : a + count]
            dx = self.lu.solve(np.ascontiguousarray(r.T)).T
            yy, zz = y[a : a + count], z[a : a + count, : self.n]
            size = np.maximum(np.max(np.abs(yy), axis=1), np.max(np.abs(zz), axis=1))
            worst = max(worst, float(np.max(np.max(np.abs(dx), axis=1) / np.maximum(size, 1e-300))))
        return worst

    # --------------------------------------------------------------------- run
    def _stepper(self):
        """``march(zs, ss, count)``: ``count`` steps on the rows of ``zs`` (row ``j`` the
        augmented state ``(z̃, v)`` of step ``j``; row ``j + 1``'s ``z`` is written,
        its ``1`` and offsets are the caller's), ``ss`` the right-hand sides' buffer:

            s_j = G_s z̃_j,   v_j = S⁻¹ s_j,   z_{j+1} = G_z (z̃_j, v_j)

        Its calls are bound once: SciPy's ``csr_matvec`` on the two products' arrays
        (:func:`_accumulate` without its per-call lookups) and SuperLU's solve between
        the equilibration's exact scalings (:class:`~.condensed.ScaledLU`'s ``solve``
        without its per-call Python): the same kernels in the same order, so the same
        bits, ≈ 10 µs less Python a step."""
        step = self._augmented()
        g_s, g_z = step["g_s"], step["g_z"]
        width, n2, nk = step["width"], 2 * self.n, self._nk
        matvec, lu = _csr_matvec(), self.lu.schur
        if matvec is None or not isinstance(lu, ScaledLU):  # pragma: no cover

            def march(zs, ss, count):
                for j in range(count):
                    row = zs[j]
                    rhs = ss[j]
                    _accumulate(g_s, row[:width], rhs)
                    row[width:] = lu.solve(rhs)
                    _accumulate(g_z, row, zs[j + 1, :n2])

            return march
        s_args = (g_s.shape[0], g_s.shape[1], g_s.indptr, g_s.indices, g_s.data)
        z_args = (g_z.shape[0], g_z.shape[1], g_z.indptr, g_z.indices, g_z.data)
        solve, r_scale, c_scale = lu._lu.solve, lu._rows, lu._cols
        scaled = np.empty(nk)
        multiply = np.multiply

        def march(zs, ss, count):
            for j in range(count):
                row = zs[j]
                matvec(*s_args, row[:width], ss[j])
                multiply(r_scale, ss[j], out=scaled)
                multiply(solve(scaled), c_scale, out=row[width:])
                matvec(*z_args, row, zs[j + 1, :n2])

        return march

    def _block_times(self, t0, sign, start, steps):
        """The times ``t_k`` of the steps of the block starting at step ``start`` (at most
        :attr:`block` of them): ``t0 + k h`` forward, ``t0 − (k + 1) h`` backward."""
        index = start + np.arange(min(self.block, steps - start), dtype=np.float64)
        return t0 + index * self.h if sign > 0 else t0 - (index + 1.0) * self.h

    def _march_blocks(self, q0, p0, t0, steps, first_offsets, on_block):
        """The steps of a run, block by block, shared by :meth:`run` and
        :meth:`run_selected`: each block of at most :attr:`block` steps is marched in
        place on the augmented states ``zs`` (one row a step: ``(q, p, 1, u)`` and the
        step's ``v``; see :meth:`_augmented` and :meth:`_stepper`), then handed to
        ``on_block(start, count, zs, times, following, last)``, which saves what its
        caller keeps and returns the block's last step's unknowns ``y`` and the next
        block's moving offsets (``first_offsets(times)`` gives the first block's). The
        last step of every block is verified at the end. Returns ``(z, y)``: the final
        state and the last step's unknowns; raises :class:`NotSparseAffine` if the
        verification rejects a step."""
        n, nk = self.n, self._nk
        sign = 1.0 if self.scheme == "plus" else -1.0
        width, march = self._augmented()["width"], self._stepper()
        block = self.block
        starts = list(range(0, steps, block))
        times = self._block_times(t0, sign, 0, steps)
        moving = first_offsets(times) if self.driven else None
        checks = []  # (z, y, t) of the last step of every block, verified at the end
        zs = np.zeros((block + 1, width + nk))
        zs[:, 2 * n] = 1.0
        zs[0, :n], zs[0, n : 2 * n] = q0, p0
        ss = np.empty((block, nk))
        y = None
        for b, start in enumerate(starts):
            count = len(times)
            if self.driven:
                zs[:count, 2 * n + 1 : width] = moving
            zs[1 : count + 1, : 2 * n] = 0.0
            ss[:count] = 0.0
            march(zs, ss, count)  # the steps (see _augmented and _stepper)
            last = b + 1 == len(starts)
            following = times if last else self._block_times(t0, sign, starts[b + 1], steps)
            y, moving = on_block(start, count, zs, times, following, last)
            checks.append((zs[count - 1, : 2 * n].copy(), y, times[-1]))
            zs[0] = zs[count]
            times = following
        z = zs[0, : 2 * n].copy()
        zc, yc, tc = (np.stack(c) for c in zip(*checks, strict=True))
        worst = self._check_steps(zc, yc, tc)
        if not (worst <= self.verify_rtol) or not np.all(np.isfinite(z)):
            raise NotSparseAffine(f"a step was off by {worst:.1e} relative (not affine)")
        return z, y

    def run(self, q0, p0, t0, steps, save_every, save_states, nodal, share):
        """Step ``steps`` times from ``(q0, p0)`` at ``t0``; returns a dict of the
        saved arrays (states every ``save_every`` steps, the initial one first) and the
        final state, or raises :class:`NotSparseAffine` if the verification rejects a
        step.

        The saved arrays are allocated once at their final size and written in place
        (no per-block pieces joined at the end: that doubled the peak memory of a large
        circuit's run); ``q`` and ``p`` are the two halves of one array of states."""
        n, size, k = self.n, self.size, save_every
        sign = 1.0 if self.scheme == "plus" else -1.0
        step = self._augmented()
        saves = steps // k
        if save_states:
            states = np.empty((saves + 1, 2 * n))
            states[0, :n], states[0, n:] = q0, p0
            mu_out = np.empty((saves, size - n))
            con_out = np.empty((saves, size - n))
            node_out = np.empty((saves + 1, n)) if nodal else None
            if nodal:
                node_out[0] = p0
        energy, violation = np.empty(steps), np.empty(steps)
        x_t = np.empty((step["width"] + self._nk, self.block))  # a block's (z̃, v) by columns

        def first_offsets(times):
            zeros = np.zeros((1, n))
            return np.concatenate(self._block(times, zeros, zeros, times[:1])[:2], axis=1)

        def on_block(start, count, zs, times, following, last):
            zb = zs[: count + 1, : 2 * n]
            # the block's diagnostics, vectorized over its steps: one transposed copy
            # of (z̃, v), then one product each; with them, the next block's offsets
            x = x_t[:, :count]
            x[:] = zs[:count].T
            con_t = step["c"] @ x
            q_from, q_to = zb[:-1, :n], zb[1:, :n]
            qk, qk1 = (q_from, q_to) if sign > 0 else (q_to, q_from)
            r0_next, pm0_next, e = self._block(following, qk, qk1, times)
            energy[start : start + count] = e
            violation[start : start + count] = np.max(np.abs(con_t), axis=0, initial=0.0)
            # the saved steps of this block: a slice (every k-th step), and the last step
            # (the check and the final y); their unknowns y from (z̃, v)
            first = (k - 1 - start % k) if save_states else count
            stored = slice(first, count, k)
            saved = len(range(first, count, k))
            if saved == count:
                y_t = step["y"] @ x
            else:
                cols = np.r_[first:count:k, count - 1]
                y_t = step["y"] @ np.ascontiguousarray(x[:, cols])
            if saved:
                rows = (start + first + 1) // k + np.arange(saved)  # rows of the saved arrays
                states[rows] = zb[1:][stored]
                mu_out[rows - 1] = y_t[n:, :saved].T
                con_out[rows - 1] = con_t[:, stored].T
                if nodal:
                    impulse = (self.imp @ y_t[:, :saved]).T
                    scale = np.full(saved, share)
                    if start == 0 and first == 0:
                        scale[0] = share / (1.0 - share)
                    node_out[rows] = zb[1:][stored][:, n:] - scale[:, None] * impulse
            moving = np.concatenate([r0_next, pm0_next], axis=1) if self.driven else None
            return y_t[:, -1].copy(), moving

        z, y = self._march_blocks(q0, p0, t0, steps, first_offsets, on_block)
        return dict(
            z=z,
            y=y.copy(),
            energy=energy[k - 1 :: k],
            violation=violation.reshape(-1, k).max(axis=1),
            q=states[:, :n] if save_states else None,
            p=states[:, n:] if save_states else None,
            mu=mu_out if save_states else None,
            con=con_out if save_states else None,
            node=node_out if (save_states and nodal) else None,
        )

    def _offsets_at(self, times):
        """The moving offsets ``(r₀, P₀)`` at ``times`` (at most ``self.block`` of them),
        without the energies: the drivers' own program (the whole system's residual at
        zero when they are many), padded to one compiled shape."""
        count = len(times)
        ts = np.concatenate([times, np.repeat(times[-1:], self.block - count)])
        hs = np.full(self.block, self.h)
        system = None if self.drivers is not None else self.system
        r0, pm0 = _offsets(system, self.drivers, self.rule, self.scheme, hs, ts)
        return np.asarray(r0)[:count], np.asarray(pm0)[:count]

    def run_selected(self, q0, p0, t0, steps, save_every, coords, rows):
        """As :meth:`run`, keeping only ``q[coords]`` of every ``save_every``-th state
        (the initial one first) and ``μ[rows]`` of the steps ending there:

            q_k[coords],   μ_k[rows] = Y[n + rows] (z̃_k, v_k)

        (``Y`` the step's unknowns as a product with the augmented state, see
        :meth:`_augmented`; only its columns that the chosen rows touch are read). The
        steps are :meth:`run`'s, in the same order of operations, so the kept values
        are its values bit for bit. What is not formed: the other states, the other
        multipliers, the constraint residuals, the nodal momenta, and the per-step
        energies and constraint violation (the energies are a compiled call per block
        beside the driven offsets; the offsets here come from the drivers' own
        program). The verification of the last step of every block is :meth:`run`'s.
        Returns ``dict(z, y, q, mu)``; raises :class:`NotSparseAffine` as :meth:`run`."""
        n, k = self.n, save_every
        coords, rows = np.asarray(coords, np.int64), np.asarray(rows, np.int64)
        y_all = self._augmented()["y"]
        # the chosen multipliers' rows of Y on the columns they touch (sorted indices
        # kept: each row's sum runs in the order of the whole product's)
        y_rows = y_all[n + rows]
        used = np.unique(y_rows.indices)
        y_sel = y_rows[:, used].tocsr()
        y_sel.sort_indices()
        # a multiplier that is itself a kept unknown (a node's, on a netlist) is a row
        # of Y with one entry 1: a column of (z̃, v), read directly (+ 0.0, as the
        # product's sum from zero, turns −0.0 into 0.0)
        unit = (
            bool(np.all(np.diff(y_sel.indptr) == 1) and np.all(y_sel.data == 1.0)) and rows.size > 0
        )
        direct = used[y_sel.indices] if unit else None
        saves = steps // k
        q_out = np.empty((saves + 1, coords.size))
        q_out[0] = np.asarray(q0)[coords]
        mu_out = np.empty((saves, rows.size))

        def first_offsets(times):
            return np.concatenate(self._offsets_at(times), axis=1)

        def on_block(start, count, zs, times, following, last):
            first = k - 1 - start % k
            saved = len(range(first, count, k))
            if saved:
                at = (start + first + 1) // k  # the first of this block's saved rows
                q_out[at : at + saved] = zs[first + 1 : count + 1 : k][:, coords]
                if direct is not None:
                    np.add(zs[first:count:k][:, direct], 0.0, out=mu_out[at - 1 : at - 1 + saved])
                else:
                    x = np.ascontiguousarray(zs[first:count:k][:, used].T)
                    mu_out[at - 1 : at - 1 + saved] = (y_sel @ x).T
            moving = None
            if self.driven and not last:
                moving = np.concatenate(self._offsets_at(following), axis=1)
            return y_all @ zs[count - 1], moving

        z, y = self._march_blocks(q0, p0, t0, steps, first_offsets, on_block)
        return dict(z=z, y=y.copy(), q=q_out, mu=mu_out)


def build(
    system, rule, scheme, h, q0, p0, t0=0.0, detect_rtol=1e-12, verify_rtol=1e-11, pattern=None
):
    """The :class:`SparseAffineMap` of ``system`` (a packed interconnection), or raise
    :class:`NotSparseAffine` saying why not (not an interconnection, a staged rule, not
    affine, a singular step Jacobian). ``pattern``:
    :func:`~diracvi.solvers.sparse_pattern.structural_pattern` of the same system and rule,
    when the caller builds the map for several step sizes (it does not depend on ``h``; on
    a large circuit it is most of a warm build's time)."""
    import scipy.sparse as sp

    if not hasattr(system, "row_subsystems"):
        raise NotSparseAffine("not an interconnection")
    n, size = system.n, unknown_count(system, rule)
    seeds, seed_of, row_of, col_of = _pattern(system, rule) if pattern is None else pattern
    rng = np.random.default_rng(20261125)
    scale = 1.0 + float(np.max(np.abs(q0), initial=0.0)) + float(np.max(np.abs(p0), initial=0.0))
    w_rand = scale * rng.uniform(-1.0, 1.0, 2 * n + size)
    driven = bool(system.time_dependent)
    t1 = t0 + 0.37 * (1.0 + abs(t0)) if driven else t0
    bases = np.stack([np.zeros_like(w_rand), w_rand, np.zeros_like(w_rand)])
    times = np.array([t0, t1, t1], dtype=np.float64)
    h64 = np.float64(h)
    values, jvps = _probe(system, rule, scheme, h64, bases, times, seeds)
    values = [np.asarray(v) for v in values]
    jvps = [np.asarray(v) for v in jvps]
    # stacked outputs: residual rows [0, U), momentum rows U + [0, n), impulse U + n + …
    out = [np.concatenate([jvps[0][b], jvps[1][b]], axis=1) for b in range(3)]
    imp = [jvps[2][b] for b in range(3)]
    if not all(np.all(np.isfinite(o)) for o in out):
        raise NotSparseAffine("the step equations are not finite at the probe points")
    ref = max(1.0, float(np.max(np.abs(out[0]))))
    if np.max(np.abs(out[1] - out[0])) > detect_rtol * ref or np.max(
        np.abs(imp[1] - imp[0])
    ) > detect_rtol * max(1.0, float(np.max(np.abs(imp[0])))):
        raise NotSparseAffine("the step equations have a non-constant Jacobian")
    vals = out[0][seed_of, row_of]
    nz = vals != 0.0
    shape = (size + n, 2 * n + size)
    full = sp.csr_matrix((vals[nz], (row_of[nz], col_of[nz])), shape=shape)
    # the pattern and affinity: f(w) − f(0) = J w at the random point, same time
    f_w = np.concatenate([values[0][1], values[1][1]])
    f_0 = np.concatenate([values[0][2], values[1][2]])
    bound = ref * np.max(np.abs(w_rand)) + np.abs(f_0)
    if np.any(np.abs(f_w - f_0 - full @ w_rand) > detect_rtol * np.maximum(bound, 1.0)):
        raise NotSparseAffine("the step equations are not affine (or not of the parts' pattern)")
    impulse_rows = row_of < size + n  # impulse: same columns as the momentum rows
    mom = (row_of >= size) & impulse_rows
    ivals = imp[0][seed_of[mom], row_of[mom] - size]
    inz = ivals != 0.0
    impulse = sp.csr_matrix(
        (ivals[inz], (row_of[mom][inz] - size, col_of[mom][inz] - 2 * n)), shape=(n, size)
    )
    jz, jx = full[:size, : 2 * n], full[:size, 2 * n :].tocsc()
    pz, px = full[size:, : 2 * n], full[size:, 2 * n :].tocsr()
    offsets, mu_start, mu_sizes, *_ = _structure(system)
    try:
        lu = condense(jx, own_unknowns(offsets, mu_start, mu_sizes))
    except SingularStep as exc:
        raise NotSparseAffine(f"the step Jacobian is singular ({exc})") from None
    r0 = np.asarray(values[0][0])
    pm0 = np.asarray(values[1][0])
    mats = (jz.tocsr(), jx, pz.tocsr(), px, impulse)
    out = SparseAffineMap(system, rule, scheme, h, mats, lu, driven, r0, pm0, verify_rtol, seeds)
    if driven:
        _use_drivers(out, system, values, t1)
    return out


def _use_drivers(out, system, values, t1) -> None:
    """Offsets from the time-dependent parts alone, if there are few and they give the
    interconnection's offsets at ``t1`` exactly (checked here; else the whole residual)."""
    driving = parts_driving(system)
    if not driving or len(driving) > MAX_DRIVERS:
        return
    offsets, mu_start, mu_sizes, *_ = _structure(system)
    coords = [np.arange(offsets[i], offsets[i + 1]) for i in driving]
    rows = np.concatenate(
        [np.concatenate([c, np.arange(mu_start[i], mu_start[i] + mu_sizes[i])])
         for c, i in zip(coords, driving, strict=True)]
    )  # fmt: skip
    # (the members sliced out of the packed stacks once per system: a build per step
    # size asks again, and slicing is a few eager JAX operations per driver)
    out.drivers = _by_identity(system, "drivers", lambda s: tuple(s._member(i) for i in driving))
    out.driver_rows, out.driver_coords = rows, np.concatenate(coords)
    # (the drivers' own program, not the block program: that one takes the whole
    # system, whose key alone is seconds on a large circuit, and the variable-step
    # path never runs it)
    # (the pair repeated to the variable-step path's call shape: the same program)
    hs, ts = np.full(OFFSETS_PAIRS, out.h), np.full(OFFSETS_PAIRS, float(t1))
    r_t1, p_t1 = _offsets(None, out.drivers, out.rule, out.scheme, hs, ts)
    r_t1, p_t1 = np.asarray(r_t1)[:1], np.asarray(p_t1)[:1]
    full_r, full_p = out.r0.copy(), out.pm0.copy()
    full_r[out.driver_rows], full_p[out.driver_coords] = r_t1[0], p_t1[0]
    same = np.array_equal(full_r, np.asarray(values[0][2])) and np.array_equal(
        full_p, np.asarray(values[1][2])
    )
    if not same:
        out.drivers = out.driver_rows = out.driver_coords = None
    out._step = out._one = None


class SparseAffineSolver(AffineSolver):
    """Ask for the circuit-scale sparse affine path (chosen automatically for large
    linear interconnections with ``solver=None``).

    As :class:`~diracvi.AffineSolver` (``fallback``, ``detect_rtol``, ``verify_rtol``):
    when the model is not an interconnection of linear parts, the rule has stages, or a
    checkpoint is asked for, the run takes the dense affine map or the ``fallback``
    instead, and ``traj.solver`` says which ran.
    """


def sparse_map(system, rule, scheme, h, q0, p0, t0, options):
    """``(map, "sparse affine")`` or ``(None, why not)`` (see :func:`build`)."""
    try:
        found = build(
            system, rule, scheme, h, np.asarray(q0), np.asarray(p0), float(t0),
            options.detect_rtol, options.verify_rtol,
        )  # fmt: skip
    except NotSparseAffine as exc:
        return None, f"the sparse affine path does not apply: {exc}"
    return found, "sparse affine"
