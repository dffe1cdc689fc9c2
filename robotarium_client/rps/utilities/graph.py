"""Graph Laplacians and neighbour sets (guide section 4.8).

A graph Laplacian is L = D - A: node degrees on the diagonal, -1 for every edge off it, so each
row sums to zero and the neighbours of i are the nonzero off-diagonal entries of row i.

The graphs are built by robotarium_core.graphs, shared with 2.x's module; this one keeps the
guide's names, argument checks and messages. Its fixes to rps 0.0.0 are marked "Fix:" in the code
and listed in docs/user-guide.md#the-toolboxs-fixes-to-rps-000.
"""
import numpy as np

from robotarium_core import graphs
from rps.utilities import RobotariumError, _check_array, _check_number

__all__ = [
    "np",
    "cycle_GL",
    "lineGL",
    "completeGL",
    "random_connectedGL",
    "randomGL",
    "topological_neighbors",
    "delta_disk_neighbors",
]


def cycle_GL(N):
    """N x N Laplacian of the cycle 0-1-...-(N-1)-0 (guide 4.8.1). N >= 1.

    Fix: N = 1 and N = 2 give the graphs a cycle degenerates to (one node; one edge), where rps
    returned matrices whose rows do not sum to zero.
    """
    N = _check_number(N, "N (number of nodes)", "cycle_GL", low=1, integer=True)
    return graphs.cycle_laplacian(N)


def lineGL(N):
    """N x N Laplacian of the path 0-1-...-(N-1) (guide 4.8.2). N >= 1.

    Fix: lineGL(1) is [[0]] (rps: [[1]]).
    """
    N = _check_number(N, "N (number of nodes)", "lineGL", low=1, integer=True)
    return graphs.path_laplacian(N)


def completeGL(N):
    """N x N Laplacian of the complete graph: N - 1 on the diagonal, -1 elsewhere (guide 4.8.3). N >= 1."""
    N = _check_number(N, "N (number of nodes)", "completeGL", low=1, integer=True)
    return graphs.complete_laplacian(N)


def random_connectedGL(v, e):
    """v x v Laplacian of a random connected graph with v - 1 + min(e, free pairs) edges (guide 4.8.4).

    rps's algorithm and draws from numpy's global random state: a random tree (node i joins a
    uniformly drawn earlier node), then e more distinct edges among the pairs not yet joined.
    v: >= 1 nodes. e: >= 0 extra edges.
    """
    where = "random_connectedGL"
    v = _check_number(v, "v (number of vertices)", where, low=1, integer=True)
    e = _check_number(e, "e (number of additional edges)", where, low=0, integer=True)
    return graphs.random_connected_laplacian(v, e)


def randomGL(v, e):
    """v x v Laplacian of a random graph with min(e, v(v-1)/2) distinct edges (guide 4.8.5).

    rps's algorithm and draws (one np.random.permutation over all node pairs, even for e = 0).
    v: >= 1 nodes. e: >= 0 edges. The graph need not be connected.
    """
    where = "randomGL"
    # Fix: rps checked neither argument.
    v = _check_number(v, "v (number of vertices)", where, low=1, integer=True)
    e = _check_number(e, "e (number of edges)", where, low=0, integer=True)
    # rps draws the permutation even when no edge is added (2.x does not): the stream moves on as in rps.
    return graphs.random_laplacian(v, e, draw_without_edges=True)


def _check_agent(agent, n, where):
    # Fix: rps allowed agent == N (it checked agent <= N), then failed with IndexError.
    return _check_number(agent, "agent", where + " (for %d agents)" % n, low=0, high=n - 1, integer=True)


def topological_neighbors(L, agent):
    """Indices of agent's neighbours in the graph with Laplacian L (guide 4.8.6).

    L: N x N numpy array; agent: 0 to N-1. Returns a 1-D integer array (M neighbours).
    Fix: rps zeroed L[agent, agent] in the caller's matrix; L is left untouched here.
    """
    where = "topological_neighbors"
    L = _check_array(L, "L", where, None, what="graph Laplacian (N x N)")
    if L.shape[0] != L.shape[1]:
        raise RobotariumError("%s: L must be a square N x N graph Laplacian; received an array of shape %s."
                              % (where, L.shape))
    agent = _check_agent(agent, L.shape[0], where)
    return graphs.topological_neighbors(L, agent)


def delta_disk_neighbors(poses, agent, delta):
    """Indices of the agents within distance delta (2-norm, inclusive) of agent, itself excluded (guide 4.8.7).

    poses: 2xN or 3xN numpy array (x, y first); agent: 0 to N-1; delta: >= 0 (m).
    Returns a 1-D integer array (M neighbours).
    """
    where = "delta_disk_neighbors"
    poses = _check_array(poses, "poses", where, None, what="of poses [x; y] or [x; y; theta]")
    if poses.shape[0] < 2:
        raise RobotariumError("%s: poses must have at least 2 rows ([x; y] ...); received an array of shape %s."
                              % (where, poses.shape))
    agent = _check_agent(agent, poses.shape[1], where)
    # Fix: rps's message for a bad delta named agent.
    delta = _check_number(delta, "delta", where, low=0, allow_inf=True)
    return graphs.delta_disk_neighbors(poses, agent, delta)
