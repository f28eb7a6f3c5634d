"""Counting a jaxpr's equations, those of its sub-jaxprs (loops, conditionals, nested
jits) included: the size of a traced program, as the tests of what is traced once
(the lobatto stages, alike parts) measure it."""

from __future__ import annotations


def count_equations(jaxpr, names=None) -> int:
    """Equations of ``jaxpr`` and its sub-jaxprs; only those applying a primitive in
    ``names`` when given."""
    count = 0
    for eqn in jaxpr.eqns:
        count += names is None or eqn.primitive.name in names
        for value in eqn.params.values():
            for sub in value if isinstance(value, tuple | list) else (value,):
                inner = getattr(sub, "jaxpr", sub)  # a ClosedJaxpr's, or a Jaxpr itself
                if hasattr(inner, "eqns"):
                    count += count_equations(inner, names)
    return count
