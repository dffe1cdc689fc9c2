"""Graph Laplacians and neighbours with 2.x's names (2.1.0 rps/utilities/graph.py; cycleGL is the
guide's cycle_GL). The random graphs draw from numpy's global generator as 2.x does.

The graphs are built by robotarium_core.graphs, which the guide's module shares; this module keeps
2.x's names, asserts and messages."""
import numpy as np

from robotarium_core import graphs

__all__ = ["np", "completeGL", "cycleGL", "lineGL", "random_connectedGL", "randomGL", "delta_disk_neighbors",
           "topological_neighbors"]


def completeGL(n):
    """Laplacian of the complete graph: n I - 1 1'."""
    assert isinstance(n, int) and n > 0, "n must be a positive integer."
    return graphs.complete_laplacian(n)


def cycleGL(n):
    """Laplacian of the cycle 0 - 1 - ... - (n-1) - 0."""
    assert isinstance(n, int) and n >= 3, "n must be an integer >= 3."
    return graphs.cycle_laplacian(n)


def lineGL(n):
    """Laplacian of the path 0 - 1 - ... - (n-1)."""
    assert isinstance(n, int) and n >= 2, "n must be an integer >= 2."
    return graphs.path_laplacian(n)


def random_connectedGL(v, e):
    """A random spanning tree (node i joins a random j < i) plus up to e random extra edges."""
    assert isinstance(v, int) and v > 0, "v must be a positive integer."
    assert isinstance(e, int) and e >= 0, "e must be a non-negative integer."
    return graphs.random_connected_laplacian(v, e)


def randomGL(v, e):
    """Up to e random edges on v nodes (maybe disconnected)."""
    assert isinstance(v, int) and v > 0, "v must be a positive integer."
    assert isinstance(e, int) and e >= 0, "e must be a non-negative integer."
    # 2.x draws nothing when no edge is to be added (rps 0.0.0, the guide's API, does).
    return graphs.random_laplacian(v, e)


def delta_disk_neighbors(poses, agent, delta):
    """Indices of the agents (other than `agent`) within `delta` of it."""
    n = poses.shape[1]
    assert 0 <= agent < n, "agent (%d) must be between 0 and %d." % (agent, n - 1)
    return graphs.delta_disk_neighbors(poses, agent, delta)


def topological_neighbors(L, agent):
    """Indices of `agent`'s neighbours in the graph of Laplacian L."""
    n = L.shape[0]
    assert 0 <= agent < n, "agent (%d) must be between 0 and %d." % (agent, n - 1)
    return graphs.topological_neighbors(L, agent)
