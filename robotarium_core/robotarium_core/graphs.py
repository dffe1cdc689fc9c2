"""Graph Laplacians and neighbour sets: plain numpy, no ROS, no argument checks.

A graph Laplacian is L = D - A: node degrees on the diagonal, -1 for every edge off it, so each
row sums to zero and the neighbours of i are the nonzero off-diagonal entries of row i.

Both rps APIs build their graphs here: the guide's (robotarium_client/rps/utilities/graph.py:
cycle_GL, lineGL, ...) and 2.x's (rps/_v2/utilities/graph.py: cycleGL, lineGL, ...) check their
arguments their own way, then call in. The random graphs draw from `rng` (numpy's global
generator, np.random, unless given a RandomState) in the order both simulators draw, so a script
that seeds numpy gets the graphs it gets there.
"""
import numpy as np


def laplacian(n, rows, cols):
    """n x n Laplacian of the simple undirected graph with the edges (rows[k], cols[k]).

    No self-loops; an edge given twice (either way round) counts once.
    """
    L = np.zeros((n, n))
    L[rows, cols] = -1
    L[cols, rows] = -1
    L[np.diag_indices(n)] = np.count_nonzero(L, axis=1)   # degree = number of edges at the node
    return L


def path_laplacian(n):
    """Laplacian of the path 0-1-...-(n-1); [[0]] for n = 1."""
    nodes = np.arange(n - 1)
    return laplacian(n, nodes, nodes + 1)


def cycle_laplacian(n):
    """Laplacian of the cycle 0-1-...-(n-1)-0. For n <= 2 a cycle degenerates to the path (one
    node; one edge): its rows still sum to zero."""
    if n <= 2:
        return path_laplacian(n)
    nodes = np.arange(n)
    return laplacian(n, nodes, (nodes + 1) % n)


def complete_laplacian(n):
    """Laplacian of the complete graph on n nodes: n I - 1 1' (n - 1 on the diagonal, -1 elsewhere)."""
    return n * np.identity(n) - np.ones((n, n))


def add_random_edges(L, rows, cols, count, rng=np.random):
    """Add to L (in place, and return it) `count` of the candidate edges (rows[k], cols[k]), chosen
    by one rng.permutation over all of the candidates (as np.random.shuffle of them would: the same
    draws). The candidates must be distinct node pairs that are not edges of L yet."""
    chosen = rng.permutation(len(rows))[:count]
    rows, cols = rows[chosen], cols[chosen]
    L[rows, cols] = -1
    L[cols, rows] = -1
    np.add.at(L, (rows, rows), 1)
    np.add.at(L, (cols, cols), 1)
    return L


def random_connected_laplacian(v, e, rng=np.random):
    """Laplacian of a random connected graph on v nodes with v - 1 + min(e, pairs left) edges.

    A random tree first (node i = 1, ..., v-1 joins a uniformly drawn j < i: one rng.randint(0, i)
    each, in that order), then min(e, pairs left) more distinct edges among the node pairs not yet
    joined (upper triangle, row by row), by add_random_edges; no draw for those when there are none
    to add.
    """
    parents = np.array([rng.randint(0, i) for i in range(1, v)], dtype=int)
    L = laplacian(v, np.arange(1, v), parents)
    rows, cols = np.nonzero(np.triu(L == 0, 1))
    count = min(e, len(rows))
    if count > 0:
        add_random_edges(L, rows, cols, count, rng)
    return L


def random_laplacian(v, e, rng=np.random, *, draw_without_edges=False):
    """Laplacian of a random graph on v nodes with min(e, v(v-1)/2) distinct edges (maybe disconnected),
    drawn by add_random_edges among all node pairs (upper triangle, row by row).

    draw_without_edges: draw the permutation even when no edge is to be added (rps 0.0.0's randomGL
    does, so the global stream moves on; 2.x's does not).
    """
    rows, cols = np.triu_indices(v, 1)
    count = min(e, len(rows))
    L = np.zeros((v, v))
    if count > 0 or draw_without_edges:
        add_random_edges(L, rows, cols, count, rng)
    return L


def topological_neighbors(L, agent):
    """Indices (1-D integer array) of agent's neighbours in the graph with Laplacian L: the nonzero
    off-diagonal entries of row agent. L is not changed."""
    row = L[agent] != 0
    row[agent] = False
    return np.nonzero(row)[0]


def delta_disk_neighbors(points, agent, delta):
    """Indices (1-D integer array) of the agents within distance delta (2-norm, inclusive) of agent,
    itself excluded. points: 2xN or more rows (x, y first)."""
    near = np.linalg.norm(points[:2] - points[:2, [agent]], axis=0) <= delta
    near[agent] = False
    return np.nonzero(near)[0]
