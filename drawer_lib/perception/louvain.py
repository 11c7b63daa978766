"""Louvain community detection (Blondel et al. 2008), bounded by work, never by time.

networkx <= 3.6.1 can cycle forever in its local-moving loop when two communities tie up to
floating-point round-off (networkx issue #8739; its fix is in a release this project cannot
install). Here a node moves only when the move raises the modularity by more than ``tol``
relative to the node's degree, so no move can undo an equal one, and the work is bounded
outright: at most ``max_sweeps`` passes over the nodes per level and ``max_levels`` levels.
The same graph, resolution and seed give the same communities on every machine.

Modularity with resolution gamma: Q = sum_c [ w_in(c) / m - gamma (S_c / 2m)^2 ], m the total
edge weight, w_in(c) the weight inside community c, S_c the summed degree of its nodes. Moving
node u (degree k_u) into community C changes Q by [w_uC - gamma S_C k_u / 2m] / m, up to terms
that do not depend on C (w_uC: the weight from u to C's nodes, S_C without u).
"""

from typing import no_type_check

import numpy as np
from jaxtyping import Float, Int
from numba import njit
from scipy.sparse import coo_matrix, csr_matrix


@njit(cache=True)
@no_type_check  # keep the test-suite type-check hook away from numba
def _one_level(indptr, indices, data, k, order, gamma, m2, max_sweeps, tol):
    """Local moving on one level: (community per node, moves made, sweeps run)."""
    n = len(k)
    comm = np.arange(n)
    stot = k.copy()
    w_to = np.zeros(n)  # scratch: weight from the current node to each community
    mark = np.full(n, -1)  # community touched while visiting node u (mark == u)
    touched = np.empty(n, np.int64)
    total_moves = 0
    sweeps = 0
    for _ in range(max_sweeps):
        sweeps += 1
        moves = 0
        for u in order:
            cu = comm[u]
            nt = 0
            for p in range(indptr[u], indptr[u + 1]):
                v = indices[p]
                if v == u:
                    continue
                c = comm[v]
                if mark[c] != u:
                    mark[c] = u
                    w_to[c] = 0.0
                    touched[nt] = c
                    nt += 1
                w_to[c] += data[p]
            stot[cu] -= k[u]
            stay = (w_to[cu] if mark[cu] == u else 0.0) - gamma * stot[cu] * k[u] / m2
            best, best_gain = cu, stay
            for j in range(nt):
                c = touched[j]
                if c == cu:
                    continue
                g = w_to[c] - gamma * stot[c] * k[u] / m2
                if g > best_gain:
                    best, best_gain = c, g
            if best != cu and best_gain - stay > tol * (k[u] + 1e-300):
                comm[u] = best
                moves += 1
            else:
                best = cu
            stot[best] += k[u]
        total_moves += moves
        if moves == 0:
            break
    return comm, total_moves, sweeps


def _csr(n: int, edges: np.ndarray, weights: np.ndarray) -> csr_matrix:
    """Symmetric weighted adjacency [n, n] (each undirected edge stored both ways, duplicates summed)."""
    r = np.concatenate([edges[:, 0], edges[:, 1]])
    c = np.concatenate([edges[:, 1], edges[:, 0]])
    w = np.concatenate([weights, weights]).astype(np.float64)
    return coo_matrix((w, (r, c)), shape=(n, n)).tocsr()


def louvain(n: int, edges: Int[np.ndarray, "E 2"], weights: Float[np.ndarray, "E"], resolution: float = 1.0,
            seed: int = 0, max_levels: int = 32, max_sweeps: int = 64, tol: float = 1e-10
            ) -> tuple[Int[np.ndarray, "n"], dict]:
    """Communities of the undirected graph on nodes ``0..n-1`` with ``edges`` [E, 2] and
    positive ``weights`` [E]. Nodes are visited in an order drawn from ``seed`` per level; a
    level stops when a sweep moves no node or after ``max_sweeps`` sweeps, and the graph of
    communities is the next level, until a level moves nothing or ``max_levels`` levels ran.

    Returns (community id per node [n], 0..K-1 in order of first appearance; a report with
    ``levels``, ``sweeps`` and ``capped``: the levels that hit ``max_sweeps``).

    >>> e = np.array([[0, 1], [1, 2], [0, 2], [3, 4], [4, 5], [3, 5], [2, 3]])
    >>> louvain(6, e, np.ones(7))[0].tolist()
    [0, 0, 0, 1, 1, 1]
    """
    edges = np.asarray(edges, np.int64).reshape(-1, 2)
    weights = np.asarray(weights, np.float64)
    if len(weights) != len(edges):
        raise ValueError(f"louvain: {len(edges)} edges but {len(weights)} weights")
    if len(edges) and (edges.min() < 0 or edges.max() >= n):
        raise ValueError(f"louvain: edge endpoints must lie in [0, {n})")
    if not np.all(np.isfinite(weights)) or (weights <= 0).any():
        raise ValueError("louvain: weights must be finite and positive")
    if not resolution > 0 or max_levels < 1 or max_sweeps < 1:
        raise ValueError("louvain: need resolution > 0, max_levels >= 1 and max_sweeps >= 1")
    report = {"levels": 0, "sweeps": 0, "capped": 0}
    labels = np.arange(n, dtype=np.int64)
    if n == 0 or len(edges) == 0:
        return _first_appearance(labels), report
    A = _csr(n, edges, weights)
    rng = np.random.default_rng(seed)
    for _ in range(max_levels):
        k = np.asarray(A.sum(1)).ravel()
        m2 = float(k.sum())
        order = rng.permutation(A.shape[0]).astype(np.int64)
        comm, moves, sweeps = _one_level(A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data, k, order,
                                         float(resolution), m2, int(max_sweeps), float(tol))
        report["levels"] += 1
        report["sweeps"] += int(sweeps)
        report["capped"] += int(sweeps == max_sweeps and moves > 0)
        if moves == 0:
            break
        _, comm = np.unique(comm, return_inverse=True)
        labels = comm[labels]
        K = int(comm.max()) + 1
        P = csr_matrix((np.ones(len(comm)), (np.arange(len(comm)), comm)), shape=(len(comm), K))
        A = (P.T @ A @ P).tocsr()
    return _first_appearance(labels), report


def _first_appearance(labels: np.ndarray) -> np.ndarray:
    """Relabel to 0..K-1 in the order in which labels first appear (a canonical numbering)."""
    _, first, inv = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[inv]
