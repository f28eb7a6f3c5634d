r"""One partitioned Newton step: local factorizations group by group (vmapped), the
interface system of the slot unknowns, and the back-substitution (see the package
docstring)."""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np

from ...discretization.equations import new_momentum, residual
from .. import banded as _banded
from .interface import (
    _Couplings,
)
from .plan import (
    _aug_entries,
    _concatenate_tiles,
    _Plan,
    _port_pairs,
    _tile,
    _uniform_ports,
)


class _Step:
    """One step's operators over the plan: residual, factorization and linear solve on
    the stacked representation ``X = ((y_g for each group), λ)``.

    ``λ`` holds every copy of the interaction multipliers, copy-major (``plan.rows``);
    a member's coordinates ``y[:, : n·copies]`` are ``(n, copies)`` row-major (local order)."""

    def __init__(self, plan: _Plan, eqs, stacked, bands, couplings: _Couplings):
        self.plan = plan
        self.eqs = eqs
        self.bands = bands  # per group: (kl, ku) of banded local factors, or None
        self.c = couplings
        system = eqs.system
        self.h = eqs.h
        self.stacks, self.index, self.q, self.p, self.blocks = [], [], [], [], []
        self.tiles, self.uniform, self.inverse, self.port_cols = [], [], [], []
        general = system.general_forms(eqs.q) if system.interactions else None
        for g, arrays in zip(plan.groups, stacked, strict=True):
            first = system.subsystems[int(g.members[0])]
            self.stacks.append((arrays, eqx.partition(first, eqx.is_array)[1]))
            # local order → the own step's order (None: they are the same)
            self.inverse.append(None if g.copies == 1 else np.argsort(g.perm))
            # a group whose members' unknowns lie side by side is a reshaped slice of x
            # (no gather, no scatter, no N-sized index table in the program)
            self.tiles.append(_tile(g))
            # one constant per table (not one per use): N-sized tables bloat the program
            self.index.append(None if self.tiles[-1] else jnp.asarray(g.y_index))
            self.q.append(self._take(index=len(self.q), x=eqs.q, coords_only=True))
            self.p.append(self._take(index=len(self.p), x=eqs.p, coords_only=True))
            # B restricted to each member's columns and rows, at the known configuration:
            # the same small (rows × n) matrix E for every member when only connections
            # touch the group at the same local places, else one block per member
            self.uniform.append(_uniform_ports(g))
            # the columns E touches (a connection: one per row): σ and the reaction
            # read and write only these, not all n·copies unknowns of every member
            self.port_cols.append(
                None if self.uniform[-1] is None else np.flatnonzero(self.uniform[-1].any(0))
            )
            if self.uniform[-1] is not None:
                self.blocks.append(None)
                continue
            block = jnp.zeros((len(g.members), g.rows_each, g.n), dtype=eqs.q.dtype)
            k, r, c, val = g.ports
            if k.size:
                block = block.at[k, r, c].set(jnp.asarray(val))
            k, r, grow = g.general
            if k.size:
                cols = jnp.asarray(g.y_index[:, : g.n * g.copies : g.copies])[k]
                block = block.at[k, r].set(general[grow[:, None], cols])
            self.blocks.append(block)

    def _take(self, index, x, coords_only=False):
        """Group ``index``'s unknowns (or only its ``q_other``, of ``x = q``), (G, ·)."""
        g, tile = self.plan.groups[index], self.tiles[index]
        copies = g.copies
        if tile is None:
            table = self.index[index]
            return x[table[:, : g.n * copies : copies]] if coords_only else x[table]
        count = len(g.members)
        q_at, mu_at = tile
        if coords_only:
            return x[q_at[0] : q_at[0] + count * g.n].reshape(count, g.n)

        def interleaved(starts, size):
            parts = [x[a : a + count * size].reshape(count, size) for a in starts]
            if copies == 1:
                return parts[0]
            return jnp.stack(parts, axis=-1).reshape(count, size * copies)

        q = interleaved(q_at, g.n)
        if not g.m:
            return q
        return jnp.concatenate([q, interleaved(mu_at, g.m)], axis=1)

    def block(self, index):
        """``B_i`` of every member of group ``index``, (G, rows, n)."""
        if self.blocks[index] is not None:
            return self.blocks[index]
        shape = (len(self.plan.groups[index].members), *self.uniform[index].shape)
        return jnp.broadcast_to(jnp.asarray(self.uniform[index]), shape)

    def spread(self, index, lam):
        """``B_iᵀ λ_j`` for every member and copy: (G, copies·rows) → (G, copies, n)."""
        g = self.plan.groups[index]
        v = lam.reshape(len(g.members), g.copies, g.rows_each)
        if self.uniform[index] is not None:
            return v @ jnp.asarray(self.uniform[index])
        return jnp.einsum("krn,kjr->kjn", self.blocks[index], v)

    def reaction(self, index, lam):
        """``G_i λ_i`` on the coordinate lines, (G, n·copies) in the local order."""
        g = self.plan.groups[index]
        u = jnp.einsum("ij,kjn->kni", jnp.asarray(self.c.reaction), self.spread(index, lam))
        return u.reshape(len(g.members), g.n * g.copies)

    def add_reaction(self, index, r, lam):
        """``r`` with ``G_i λ_i`` added on its coordinate lines (local order); with a
        uniform ``E`` only at the columns it touches (the same numbers: the rest adds 0)."""
        g, cols = self.plan.groups[index], self.port_cols[index]
        if cols is None:
            return r.at[:, : g.n * g.copies].add(self.reaction(index, lam))
        count = len(g.members)
        v = lam.reshape(count, g.copies, g.rows_each)
        spread = v @ jnp.asarray(self.uniform[index][:, cols])  # (G, copies, cols)
        u = jnp.einsum("ij,kjc->kci", jnp.asarray(self.c.reaction), spread)
        at = (cols[:, None] * g.copies + np.arange(g.copies)[None, :]).ravel()
        return r.at[:, at].add(u.reshape(count, at.size))

    def sigma(self, index, y, block=None):
        """``H_i y`` for every member: its share of every copy of its interface rows.

        ``y``: (G, n·copies, …) in the local order (the coordinate rows of ``y_i``, or of
        a matrix); returns (G, copies·rows, …)."""
        g = self.plan.groups[index]
        count, extra = len(g.members), y.shape[2:]
        y = y.reshape(count, g.n, g.copies, *extra)
        if block is None and self.uniform[index] is not None:
            cols = self.port_cols[index]  # E is zero elsewhere: read only these columns
            z = jnp.einsum("ju,kcu...->kjc...", jnp.asarray(self.c.rate), y[:, cols]) / self.h
            out = jnp.einsum("rc,kjc...->kjr...", jnp.asarray(self.uniform[index][:, cols]), z)
        else:
            z = jnp.einsum("ju,knu...->kjn...", jnp.asarray(self.c.rate), y) / self.h
            block = self.blocks[index] if block is None else block
            out = jnp.einsum("krn,kjn...->kjr...", block, z)
        return out.reshape(count, g.copies * g.rows_each, *extra)

    def g_matrix(self, index, block):
        """``G_i`` restricted to the coordinate lines, (G, n·copies, copies·rows)."""
        g = self.plan.groups[index]
        gm = jnp.einsum("ij,krc->kcijr", jnp.asarray(self.c.reaction), block)
        return gm.reshape(len(g.members), g.n * g.copies, g.copies * g.rows_each)

    # ---------------------------------------------------------------- layout
    def split(self, x):
        ys = tuple(self._take(i, x) for i in range(len(self.plan.groups)))
        plan = self.plan
        if len(plan.lam_at) == 1:
            return ys, x[plan.lam_at[0] : plan.lam_at[0] + plan.base_rows]
        return ys, jnp.concatenate([x[a : a + plan.base_rows] for a in plan.lam_at])

    def _lam_pieces(self, lam):
        size = self.plan.base_rows
        return [(a, lam[j * size : (j + 1) * size]) for j, a in enumerate(self.plan.lam_at)]

    def join(self, ys, lam):
        plan = self.plan
        pieces = self._lam_pieces(lam)
        for g, tile, y in zip(plan.groups, self.tiles, ys, strict=True):
            if tile is None:
                break
            count = len(g.members)
            coords = y[:, : g.n * g.copies].reshape(count, g.n, g.copies)
            mults = y[:, g.n * g.copies :].reshape(count, g.m, g.copies)
            for j in range(g.copies):
                pieces.append((tile[0][j], coords[:, :, j].ravel()))
                if g.m:
                    pieces.append((tile[1][j], mults[:, :, j].ravel()))
        else:
            joined = _concatenate_tiles(pieces, plan.size)
            if joined is not None:
                return joined
        x = jnp.zeros(plan.size, dtype=lam.dtype)
        for index, y in enumerate(ys):
            table = jnp.asarray(plan.groups[index].y_index)
            x = x.at[table].set(y)
        for at, values in self._lam_pieces(lam):
            x = x.at[at : at + values.shape[0]].set(values)
        return x

    # -------------------------------------------------------------- equations
    def momentum(self, ys, lam):
        """The explicit line ``p_{k+1} = D₂L_d + f_d^+`` (or ``p_k``), group by group (a
        staged rule's line carries its stage reactions, the interaction's among them)."""
        eqs, plan = self.eqs, self.plan
        lines = []
        for index, y in enumerate(ys):
            g = plan.groups[index]
            arrays, rest = self.stacks[index]

            def line(arrays, q, y, rest=rest, inverse=self.inverse[index]):
                sub = eqx.combine(arrays, rest)
                y = y if inverse is None else y[inverse]
                return new_momentum(sub, eqs.rule, eqs.scheme, eqs.h, q, y, eqs.t)

            p = jax.vmap(line)(arrays, self.q[index], y)
            if np.any(self.c.momentum) and g.rows_each:
                u = self.spread(index, lam[g.rows])
                p = p + jnp.einsum("j,kjn->kn", jnp.asarray(self.c.momentum), u)
            lines.append(p)
        if all(tile is not None for tile in self.tiles):
            pieces = [(tile[0][0], p.ravel()) for tile, p in zip(self.tiles, lines, strict=True)]
            joined = _concatenate_tiles(pieces, eqs.system.n)
            if joined is not None:
                return joined
        out = jnp.zeros(eqs.system.n, dtype=eqs.q.dtype)
        for g, p in zip(plan.groups, lines, strict=True):
            out = out.at[jnp.asarray(g.y_index[:, : g.n * g.copies : g.copies])].set(p)
        return out

    def _local(self, index):
        """``ρ_i(y_i)`` of group ``index`` in the local order, for one member."""
        eqs = self.eqs
        _, rest = self.stacks[index]
        inverse, perm = self.inverse[index], self.plan.groups[index].perm

        def rho(arrays, q, p, y):
            sub = eqx.combine(arrays, rest)
            if inverse is None:
                return residual(sub, eqs.rule, eqs.scheme, eqs.h, q, p, y, eqs.t)
            return residual(sub, eqs.rule, eqs.scheme, eqs.h, q, p, y[inverse], eqs.t)[perm]

        return rho

    def _band_jacobian(self, index, arrays, q, p, y):
        """One member's ``J_i`` as banded rows, from ``kl + ku + 1`` compressed JVPs."""
        kl, ku = self.bands[index]
        rho = self._local(index)
        seeds = jnp.asarray(_banded.seeds(y.shape[0], kl, ku), dtype=y.dtype)
        _, products = jax.vmap(lambda s: jax.jvp(lambda y: rho(arrays, q, p, y), (y,), (s,)))(seeds)
        return _banded.from_products(products, kl, ku)

    def residual(self, ys, lam):
        """The step residual, per group ``ρ_i + G_i λ``, and the interface rows ``α_d``."""
        plan, out = self.plan, []
        alpha = jnp.zeros(plan.rows, dtype=lam.dtype)
        for index, (g, y) in enumerate(zip(plan.groups, ys, strict=True)):
            arrays, _ = self.stacks[index]
            r = jax.vmap(self._local(index))(arrays, self.q[index], self.p[index], y)
            coords = g.n * g.copies
            out.append(self.add_reaction(index, r, lam[g.rows]))
            # α is linear in the unknowns and vanishes when every copy is the known q
            moved = y[:, :coords] - jnp.repeat(self.q[index], g.copies, axis=1)
            alpha = alpha.at[g.rows].add(self.sigma(index, moved))
        return tuple(out), alpha

    def factorize(self, ys):
        """Factors of ``K_i = J_i + G_i W H_i`` and of the slot system ``T``."""
        plan, h = self.plan, self.h
        jacs, scales = [], jnp.zeros(plan.subsystems, dtype=self.q[0].dtype)
        for index, (g, y) in enumerate(zip(plan.groups, ys, strict=True)):
            arrays, _ = self.stacks[index]
            args = (arrays, self.q[index], self.p[index], y)
            if self.bands[index] is None:
                jac = jax.vmap(jax.jacfwd(self._local(index), argnums=3))(*args)
            else:  # banded rows R[i, d] = J[i, i − kl + d]: kl + ku + 1 JVPs per member
                jac = jax.vmap(partial(self._band_jacobian, index))(*args)
            jacs.append(jac)
            # max|J_i| / max|G_i H_i|: the weight that makes G_i W H_i comparable to J_i
            if self.uniform[index] is None:
                bmax = jnp.max(jnp.abs(self.blocks[index]), axis=(1, 2), initial=0.0)
            else:
                bmax = jnp.full(len(g.members), np.abs(self.uniform[index]).max(initial=0.0))
            jmax = jnp.max(jnp.abs(jac), axis=(1, 2))
            tau = jnp.where(bmax > 0, jmax * h / jnp.where(bmax > 0, bmax, 1.0) ** 2, 0.0)
            scales = scales.at[g.members].set(tau)
        tau = scales[plan.slot_sub]
        total = jax.ops.segment_sum(tau, plan.slot_row, num_segments=plan.rows)
        used = jax.ops.segment_sum((tau > 0).astype(tau.dtype), plan.slot_row, plan.rows)
        w = jnp.where(total > 0, total / jnp.where(used > 0, used, 1.0), 1.0)
        w = self.c.sign * w  # the scheme's sign (see _couplings)

        flat = jnp.zeros(plan.slots * plan.width, dtype=w.dtype)
        pos, val = plan.fixed
        flat = flat.at[pos].add(jnp.asarray(val))
        reaction, rate = jnp.asarray(self.c.reaction), jnp.asarray(self.c.rate)
        local = []
        for index, (g, jac) in enumerate(zip(plan.groups, jacs, strict=True)):
            block = self.block(index)
            count, coords = len(g.members), g.n * g.copies
            weight = w[g.rows].reshape(count, g.copies, g.rows_each)
            gmat = self.g_matrix(index, block)
            if self.bands[index] is None:
                bwb = jnp.einsum("krn,kjr,krp->kjnp", block, weight, block)
                aug = jnp.einsum("ij,kjnp,ju->knipu", reaction, bwb, rate) / h
                aug = aug.reshape(count, coords, coords)
                # explicit inverses: see the module documentation
                kinv = jnp.linalg.inv(jac.at[:, :coords, :coords].add(aug))
                kinv_g = jnp.einsum("ksn,knr->ksr", kinv[:, :, :coords], gmat)  # K⁻¹ G_i
            else:
                kl, ku = self.bands[index]
                c, c2 = _port_pairs(g)
                a, b = _aug_entries(g)  # G_i W H_i's entries, all inside the band
                bwb = jnp.einsum("kre,kjr,kre->kje", block[:, :, c], weight, block[:, :, c2])
                aug = jnp.einsum("ij,kje,ju->keiu", reaction, bwb, rate) / h
                rows = jac.at[:, a, b - a + kl].add(aug)
                kinv = jax.vmap(partial(_banded.lu, kl=kl, ku=ku))(rows)  # banded P K = L U
                rhs = jnp.zeros((count, jac.shape[1], gmat.shape[2]), dtype=block.dtype)
                rhs = rhs.at[:, :coords].set(gmat)
                kinv_g = jax.vmap(partial(_banded.solve, kl=kl, ku=ku))(kinv, rhs)
            p_mat = self.sigma(index, kinv_g[:, :coords])  # H_i K_i⁻¹ G_i
            pos, eq_row, k, r, c, coef = g.assembly
            if pos.size:
                flat = flat.at[pos].add(jnp.asarray(coef) * w[eq_row] * p_mat[k, r, c])
            # B_i with the factors: a configuration-dependent one is kept as it was
            local.append((kinv, kinv_g, self.blocks[index]))
        if plan.slots == 0:
            interface = ()
        elif plan.tridiagonal:
            tri = flat.reshape(plan.slots, 3)
            interface = (tri[:, 0], tri[:, 1], tri[:, 2])
        elif plan.band is not None:
            interface = _banded.lu(flat.reshape(plan.slots, plan.width), *plan.band)
        else:
            interface = jsl.lu_factor(flat.reshape(plan.slots, plan.slots))
        return tuple(local), w, interface

    def solve_linear(self, factors, rs, r_alpha):
        """``(dy, dλ)`` with ``J_i dy_i + G_i dλ = −r_i`` and ``Σ_i H_i dy_i = −r_α``."""
        plan = self.plan
        local, w, interface = factors
        base, z = [], jnp.zeros(plan.slots, dtype=w.dtype)
        for index, (g, (kinv, _, block), r) in enumerate(zip(plan.groups, local, rs, strict=True)):
            band = self.bands[index]
            if band is None:
                kinv_a = -jnp.einsum("kst,kt->ks", kinv, r)
            else:
                kinv_a = -jax.vmap(partial(_banded.solve, kl=band[0], ku=band[1]))(kinv, r)
            base.append(kinv_a)
            z = z.at[g.slots].set(self.sigma(index, kinv_a[:, : g.n * g.copies], block))
        dys = []
        if plan.slots:
            eq, slot, coef = plan.sigma_terms
            sigma_part = jax.ops.segment_sum(jnp.asarray(coef) * z[slot], eq, plan.slots)
            weight = w[plan.slot_row]
            rhs = -weight * (sigma_part - jnp.asarray(plan.flux_coef) * r_alpha[plan.slot_row])
            if plan.tridiagonal:
                dl, d, du = interface
                g_all = jax.lax.linalg.tridiagonal_solve(dl, d, du, rhs[:, None])[:, 0]
            elif plan.band is not None:
                g_all = _banded.solve(interface, rhs, *plan.band)
            else:
                g_all = jsl.lu_solve(interface, rhs)
        else:
            g_all = jnp.zeros(0, dtype=w.dtype)
        sigma = jnp.zeros(plan.slots, dtype=w.dtype)
        for index, (g, (_, kinv_g, block), kinv_a) in enumerate(
            zip(plan.groups, local, base, strict=True)
        ):
            # the few slots' terms written out: one elementwise pass (a batched dot of
            # (s × slots) by (slots,) per member, or a reduction over the slot axis, is a
            # separate pass that XLA runs 4–20× slower at 10⁴ members)
            dy = kinv_a
            g_here = g_all[g.slots]
            for j in range(g_here.shape[1]):
                dy = dy - kinv_g[:, :, j] * g_here[:, j, None]
            dys.append(dy)
            share = self.sigma(index, dy[:, : g.n * g.copies], block)
            sigma = sigma.at[g.slots].set(share)
        first = plan.first_slot
        dlam = g_all[first] + w * sigma[first]
        return tuple(dys), dlam
