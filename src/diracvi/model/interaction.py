r"""The interaction of subsystems: one-forms ``α^b(q)`` on the product space (paper §4.1).

An :class:`Interaction` holds the rows of ``B(q)`` (l × dim Q) that span the annihilator
of the interaction distribution ``Σ``: a callable, a constant array, or a constant sparse
matrix (a circuit's KCL rows). :func:`connect` is the common one-form ``dx − dy`` of a
port. :mod:`diracvi.model.interconnect` joins subsystems through them.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax

from ..errors import ModelError
from ..runtime.program import Program, lift
from .sparse_rows import SparseRows, is_scipy_sparse
from .validate import check_forms_array


class Interaction(eqx.Module):
    r"""Interaction one-forms ``α^b(q)`` over the whole product space ``Q``.

    Args:
        forms: ``B(q) -> (l, N)`` (a callable of the interconnected coordinates, in
            ``system.coords`` order), a constant (l, N) array, or a constant SciPy
            sparse matrix (kept as its non-zero triples, :class:`SparseRows`: memory and
            every product O(non-zeros), as a circuit's KCL rows need). Rows may involve
            any number of subsystems and may depend on the configuration.
        names: names of the l rows (default ``"λ0"``, ``"λ1"``, … numbered across the
            whole interconnection).

    :func:`connect` builds the common case ``dx − dy`` from two coordinate names.
    """

    _fn: Callable | None = eqx.field(static=True)
    _const: jax.Array | None
    names: tuple[str, ...] | None = eqx.field(static=True)
    #: the captured arrays of ``_fn`` once it is a lifted :class:`Program` (see
    #: :meth:`lifted`): leaves, so alike interactions share one program
    _consts: tuple = ()
    #: constant sparse rows (host constants: static)
    _sparse: SparseRows | None = eqx.field(static=True, default=None)

    def __init__(self, forms, names=None, _consts=()):
        self._sparse = None
        if isinstance(forms, SparseRows) or is_scipy_sparse(forms):
            self._fn, self._const = None, None
            self._sparse = forms if isinstance(forms, SparseRows) else SparseRows.from_scipy(forms)
        elif callable(forms):  # a function, or a lifted Program with its constants
            self._fn, self._const, self._consts = forms, None, tuple(_consts)
        else:
            const = check_forms_array("Interaction(forms=...)", forms)
            placed = jax.device_put(const)
            # built inside jax.jit (a netlist read under a traced fit), device_put gives a
            # tracer; the constant is kept as the NumPy array it is, readable host-side
            self._fn, self._const = None, const if isinstance(placed, jax.core.Tracer) else placed
        self.names = None if names is None else tuple(str(n) for n in names)

    def forms(self, q):
        """``B(q)``: the constant (sparse rows made dense), the lifted program or the
        function as given."""
        if self._sparse is not None:
            return self._sparse.dense(q.dtype)
        if self._fn is None:
            return self._const
        if isinstance(self._fn, Program):
            return self._fn(self._consts, q)
        return self._fn(q)

    def lifted(self, n: int) -> Interaction:
        """This interaction with ``B`` traced once on ``q`` of length ``n`` and kept as a
        :class:`Program` with its captured constants as leaves (a program compares by
        what it computes, so its compiled code can be found again in a later process:
        :mod:`diracvi.runtime.store`); itself if ``B`` is constant or cannot be lifted."""
        if self._fn is None or isinstance(self._fn, Program):
            return self
        found = lift(self._fn, [(n,)])
        if found is None:
            return self
        program, consts, _ = found
        return Interaction(program, self.names, consts)


class Connection(eqx.Module):
    """``dx − dy`` between two named coordinates; resolved when interconnected."""

    a: str = eqx.field(static=True)
    b: str = eqx.field(static=True)
    name: str = eqx.field(static=True)


def connect(a: str, b: str, name: str | None = None) -> Connection:
    r"""The interaction one-form ``dx − dy`` for ``a = "sys1.x"``, ``b = "sys2.y"``.

    It enforces equal velocities at a port (``ẋ = ẏ``), as in the paper's examples
    (``q² = q̄²`` for the spring chain, ``v^{S1} = v^{S2}`` for the circuit).
    """
    for arg, value in (("a", a), ("b", b)):
        if not isinstance(value, str) or "." not in value:
            raise ModelError(
                f"connect({arg}={value!r}): name a coordinate as 'subsystem.coordinate', "
                "e.g. connect('left.q2', 'right.q2bar')."
            )
    if a == b:
        raise ModelError(
            f"connect({a!r}, {b!r}) connects a coordinate to itself, which constrains "
            "nothing: name two different coordinates."
        )
    return Connection(a, b, name or f"{a}={b}")
