"""The built-in quadrature rules' names, readable without importing the rules (JAX,
Equinox): the command line's help lists them, and :mod:`.rules` registers its rule
classes under them (``tests/test_imports.py`` checks that the two agree)."""

#: the built-in rules, in the order :func:`.rules.rule_names` gives them
BUILT_IN = ("retraction", "midpoint", "lobatto")

__all__ = ["BUILT_IN"]
