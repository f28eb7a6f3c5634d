"""The circuit graph's connected components (components/_topology.py), checked against
SciPy's ``connected_components`` on random graphs and on the worst orders for hooking."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from diracvi.components._topology import components


def _same_partition(labels, reference) -> bool:
    """Whether two labelings split the vertices the same way."""
    pairs = set(zip(labels.tolist(), reference.tolist(), strict=True))
    return len(pairs) == len(set(labels.tolist())) == len(set(reference.tolist()))


@pytest.mark.parametrize("seed", range(8))
def test_components_match_scipy_on_random_graphs(seed):
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 400))
    edges = int(rng.integers(0, 2 * count))
    a, b = rng.integers(0, count, edges), rng.integers(0, count, edges)
    labels = components(count, a, b)
    graph = sp.coo_matrix((np.ones(edges), (a, b)), shape=(count, count))
    _, reference = connected_components(graph, directed=False)
    assert _same_partition(labels, reference)
    # each component is named by its smallest vertex
    assert np.all(labels <= np.arange(count))
    assert np.all(labels[labels] == labels)


@pytest.mark.parametrize("order", ["forward", "backward", "shuffled"])
def test_components_of_a_long_path(order):
    """A ladder's node graph is a long path; every order of its edges ends in one
    component named 0."""
    n = 5000
    a, b = np.arange(n - 1), np.arange(1, n)
    if order == "backward":
        a, b = a[::-1], b[::-1]
    elif order == "shuffled":
        perm = np.random.default_rng(1).permutation(n - 1)
        a, b = b[perm], a[perm]
    assert np.array_equal(components(n, a, b), np.zeros(n, dtype=np.int64))


def test_isolated_vertices_are_their_own_components():
    assert components(4, [], []).tolist() == [0, 1, 2, 3]
    assert components(4, [3], [1]).tolist() == [0, 1, 2, 1]
