"""The graph kernel both rps APIs build their Laplacians and neighbour sets with (robotarium_core.graphs)."""
import numpy as np
import pytest

from robotarium_core import graphs


def _is_laplacian(L):
    off = L - np.diag(np.diag(L))
    return (np.array_equal(L, L.T) and np.all(L.sum(axis=1) == 0) and np.all(np.isin(off, (0, -1)))
            and np.array_equal(np.diag(L), -off.sum(axis=1)))


def _edges(L):
    return int(np.count_nonzero(np.triu(L, 1)))


def _connected(L):
    seen, todo = {0}, [0]
    while todo:
        for j in np.flatnonzero(L[todo.pop()]):
            if j not in seen:
                seen.add(int(j))
                todo.append(int(j))
    return len(seen) == L.shape[0]


def test_fixed_laplacians_by_hand():
    np.testing.assert_array_equal(graphs.cycle_laplacian(4), [[2, -1, 0, -1], [-1, 2, -1, 0], [0, -1, 2, -1], [-1, 0, -1, 2]])
    np.testing.assert_array_equal(graphs.path_laplacian(4), [[1, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])
    np.testing.assert_array_equal(graphs.complete_laplacian(3), [[2, -1, -1], [-1, 2, -1], [-1, -1, 2]])
    # the degenerate cycles are the paths they collapse to, still Laplacians
    np.testing.assert_array_equal(graphs.cycle_laplacian(1), [[0]])
    np.testing.assert_array_equal(graphs.cycle_laplacian(2), [[1, -1], [-1, 1]])
    np.testing.assert_array_equal(graphs.laplacian(3, np.array([0, 1, 1]), np.array([2, 2, 2])),
                                  [[1, 0, -1], [0, 1, -1], [-1, -1, 2]])   # a repeated edge counts once
    for n in range(1, 12):
        for L in (graphs.cycle_laplacian(n), graphs.path_laplacian(n), graphs.complete_laplacian(n)):
            assert L.dtype == np.float64 and _is_laplacian(L) and _connected(L)
        assert _edges(graphs.path_laplacian(n)) == n - 1
        assert _edges(graphs.cycle_laplacian(n)) == (n if n >= 3 else n - 1)
        assert _edges(graphs.complete_laplacian(n)) == n * (n - 1) // 2


@pytest.mark.parametrize("v, e", [(1, 0), (1, 5), (2, 0), (2, 3), (6, 0), (6, 4), (8, 100), (20, 15)])
def test_random_graphs_have_the_edges_asked_for(v, e):
    rng = np.random.RandomState(v * 100 + e)
    L = graphs.random_connected_laplacian(v, e, rng)
    assert _is_laplacian(L) and _connected(L)
    assert _edges(L) == v - 1 + min(e, (v - 1) * (v - 2) // 2)
    R = graphs.random_laplacian(v, e, rng)
    assert _is_laplacian(R) and _edges(R) == min(e, v * (v - 1) // 2)


def test_random_graphs_draw_as_the_simulators_do():
    # rps 0.0.0 draws each tree edge as randint(i, size=(1, 1)), 2.1.0 as randint(0, i): the same numbers
    for seed in range(20):
        a, b = np.random.RandomState(seed), np.random.RandomState(seed)
        assert [a.randint(0, i) for i in range(1, 40)] == [b.randint(i, size=(1, 1))[0, 0] for i in range(1, 40)]
    # rps 0.0.0 picks extra edges by permutation(K)[:count], 2.1.0 by shuffling the K candidates: the same edges
    for seed in range(20):
        candidates = np.argwhere(np.triu(np.ones((7, 7)), 1))
        np.random.RandomState(seed).shuffle(candidates)
        L = graphs.add_random_edges(np.zeros((7, 7)), *np.triu_indices(7, 1), 5, np.random.RandomState(seed))
        expected = graphs.laplacian(7, candidates[:5, 0], candidates[:5, 1])
        np.testing.assert_array_equal(L, expected)
    # the same seed, the same graph; rps 0.0.0's randomGL draws even for no edges, 2.1.0's does not
    np.testing.assert_array_equal(graphs.random_connected_laplacian(9, 6, np.random.RandomState(3)),
                                  graphs.random_connected_laplacian(9, 6, np.random.RandomState(3)))
    quiet, loud = np.random.RandomState(5), np.random.RandomState(5)
    graphs.random_laplacian(4, 0, quiet)
    graphs.random_laplacian(4, 0, loud, draw_without_edges=True)
    assert quiet.rand() == np.random.RandomState(5).rand() != loud.rand()


def test_neighbours():
    L = graphs.cycle_laplacian(5)
    before = L.copy()
    assert graphs.topological_neighbors(L, 0).tolist() == [1, 4]
    assert graphs.topological_neighbors(L, 2).tolist() == [1, 3]
    np.testing.assert_array_equal(L, before)                       # the caller's L is left alone
    assert graphs.topological_neighbors(graphs.complete_laplacian(1), 0).size == 0
    points = np.array([[0.0, 0.3, 0.0, 1.0], [0.0, 0.0, -0.3, 1.0], [0.0, 0.0, 0.0, 0.0]])
    near = graphs.delta_disk_neighbors(points, 0, 0.3)             # inclusive, itself excluded
    assert near.tolist() == [1, 2] and near.dtype.kind == "i"
    assert graphs.delta_disk_neighbors(points, 0, 0.29).size == 0
    assert graphs.delta_disk_neighbors(points, 3, np.inf).tolist() == [0, 1, 2]
