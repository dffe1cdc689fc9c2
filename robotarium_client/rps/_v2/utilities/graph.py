"""Graph Laplacians and neighbours with 2.x's names (2.1.0 rps/utilities/graph.py; cycleGL is the
guide's cycle_GL). The random graphs draw from numpy's global generator as 2.x does."""
import numpy as np

__all__ = ["np", "completeGL", "cycleGL", "lineGL", "random_connectedGL", "randomGL", "delta_disk_neighbors",
           "topological_neighbors"]


def _edges(n, pairs):
    L = np.zeros((n, n))
    for i, j in pairs:
        L[i, j] = L[j, i] = -1
        L[i, i] += 1
        L[j, j] += 1
    return L


def completeGL(n):
    """Laplacian of the complete graph: n I - 1 1'."""
    assert isinstance(n, int) and n > 0, "n must be a positive integer."
    return n * np.eye(n) - np.ones((n, n))


def cycleGL(n):
    """Laplacian of the cycle 0 - 1 - ... - (n-1) - 0."""
    assert isinstance(n, int) and n >= 3, "n must be an integer >= 3."
    return _edges(n, [(i, (i + 1) % n) for i in range(n)])


def lineGL(n):
    """Laplacian of the path 0 - 1 - ... - (n-1)."""
    assert isinstance(n, int) and n >= 2, "n must be an integer >= 2."
    return _edges(n, [(i, i + 1) for i in range(n - 1)])


def _add_random(L, candidates, count):
    count = min(count, len(candidates))
    if count > 0:
        np.random.shuffle(candidates)
        for i, j in candidates[:count]:
            L[i, j] = L[j, i] = -1
            L[i, i] += 1
            L[j, j] += 1
    return L


def random_connectedGL(v, e):
    """A random spanning tree (node i joins a random j < i) plus up to e random extra edges."""
    assert isinstance(v, int) and v > 0, "v must be a positive integer."
    assert isinstance(e, int) and e >= 0, "e must be a non-negative integer."
    L = _edges(v, [(i, np.random.randint(0, i)) for i in range(1, v)])
    return _add_random(L, np.argwhere(np.triu(L == 0, 1)), e)


def randomGL(v, e):
    """Up to e random edges on v nodes (maybe disconnected)."""
    assert isinstance(v, int) and v > 0, "v must be a positive integer."
    assert isinstance(e, int) and e >= 0, "e must be a non-negative integer."
    return _add_random(np.zeros((v, v)), np.argwhere(np.triu(np.ones((v, v)), 1)), e)


def delta_disk_neighbors(poses, agent, delta):
    """Indices of the agents (other than `agent`) within `delta` of it."""
    n = poses.shape[1]
    assert 0 <= agent < n, "agent (%d) must be between 0 and %d." % (agent, n - 1)
    others = np.concatenate((np.arange(agent), np.arange(agent + 1, n)))
    return others[np.linalg.norm(poses[:2, others] - poses[:2, agent:agent + 1], axis=0) <= delta]


def topological_neighbors(L, agent):
    """Indices of `agent`'s neighbours in the graph of Laplacian L."""
    n = L.shape[0]
    assert 0 <= agent < n, "agent (%d) must be between 0 and %d." % (agent, n - 1)
    row = np.copy(L[agent, :])
    row[agent] = 0
    return np.where(row != 0)[0]
