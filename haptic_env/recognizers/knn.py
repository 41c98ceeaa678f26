r"""A compiled (numba) k-d tree for the k-nearest-neighbour search of the pooled KDE.

:class:`scipy.spatial.cKDTree` answers one query in ~15 us when its data sit in the caches, but an
environment step interleaves the search with ray casting and Python, and there the same query costs
40-55 us: most of it is cache misses, plus the Python overhead of the call. :class:`KDTree` keeps
what a query touches small: the vectors as float32 in tree order (every leaf one contiguous block),
and per node only its first child, leaf range, split dimension and split value (16 + 8 bytes). The
search bounds a node by the distance to its region, updated incrementally along the splits (Arya &
Mount), and the whole query, with the KDE's kernel sums, runs in one compiled call.

Search semantics are those of ``cKDTree.query(x, k, eps)``: the ``j``-th neighbour returned is within
``(1 + eps)`` times the distance of the true ``j``-th nearest neighbour (``eps = 0``: exact). Distances
are computed in float64 from the float32 vectors.

Build: median split along the widest dimension of each node's points until at most ``leafsize``
remain; ``O(N log^2 N)`` (about 0.3 s for 144,000 vectors of 14 dimensions).

Kept only while it measures faster than the library: ``benchmarks/bench_knn.py`` runs it against
``cKDTree`` on the same single pooled search (and the whole log-density row), one query at a time.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from haptic_env.numbers import finite_number, whole_at_least, whole_number

__all__ = ["KDTree", "pooled_log_density", "log_density_row", "workspace"]

_LEFT, _START, _END, _DIM = 0, 1, 2, 3  # columns of KDTree.nodes; the right child is left + 1; leaves: left = -1


class KDTree:
    """k-d tree over ``X (N, d)``; :meth:`query` mirrors ``cKDTree.query`` for 2-D queries."""

    def __init__(self, X: np.ndarray, leafsize: int = 32):
        X = np.ascontiguousarray(X, dtype=np.float64)
        if X.ndim != 2 or len(X) == 0:
            raise ValueError(f"KDTree needs a non-empty (N, d) array, got shape {X.shape}")
        if not np.isfinite(X).all():  # as cKDTree: a NaN row would be placed and found arbitrarily
            raise ValueError(f"KDTree data row {int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])} is not finite")
        order, nodes, split = _build(X, whole_at_least(leafsize, 1, "leafsize"))
        self.indices = order  #: tree position -> row of X
        self.data = np.ascontiguousarray(X[order], dtype=np.float32)  #: vectors in tree order
        self.nodes = nodes  #: (n_nodes, 4) int32: first child (-1: leaf), leaf start, leaf end, split dimension
        self.split = split  #: (n_nodes,) split values: left child <= split <= right child along the dimension
        self.n, self.m = X.shape

    def query(self, Z: np.ndarray, k: int, eps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``(dist (B, k), idx (B, k))`` of the ``k`` nearest rows of ``X`` to each row of ``Z (B, d)``, sorted."""
        Z = np.ascontiguousarray(Z, dtype=np.float64)
        if Z.ndim != 2 or Z.shape[1] != self.m:
            raise ValueError(f"queries must have shape (B, {self.m}), got {Z.shape}")
        if not np.isfinite(Z).all():  # as cKDTree (NaN distances and arbitrary neighbours otherwise)
            raise ValueError(f"query row {int(np.flatnonzero(~np.isfinite(Z).all(axis=1))[0])} is not finite")
        if not 1 <= (whole_number(k) or 0) <= self.n:
            raise ValueError(f"k must be in [1, {self.n}], got {k!r}")
        e = finite_number(eps)
        if e is None or e < 0:
            raise ValueError(f"eps must be a finite number >= 0, got {eps!r}")
        d2, pos = _query(*self.arrays(), Z, int(k), float(eps))
        return np.sqrt(d2), self.indices[pos]

    def arrays(self) -> tuple:
        """The compiled search's inputs ``(data, nodes, split)``, for callers that fuse the search into their kernel."""
        return self.data, self.nodes, self.split


@njit(cache=True)
def _build(X, leafsize):
    n, d = X.shape
    order = np.arange(n)
    cap = 2 * (n // max(1, leafsize // 2) + 1) + 1
    nodes = np.full((cap, 4), -1, np.int32)
    split = np.zeros(cap)
    stack = np.empty(cap, np.int64)
    nodes[0, _START], nodes[0, _END] = 0, n
    n_nodes, top = 1, 0
    stack[0] = 0
    lo = np.empty(d)
    hi = np.empty(d)
    while top >= 0:
        node = stack[top]
        top -= 1
        s, e = nodes[node, _START], nodes[node, _END]
        if e - s <= leafsize:
            continue
        lo[:] = np.inf
        hi[:] = -np.inf
        for i in range(s, e):
            for j in range(d):
                v = X[order[i], j]
                lo[j] = min(lo[j], v)
                hi[j] = max(hi[j], v)
        dim = int(np.argmax(hi - lo))
        if hi[dim] <= lo[dim]:  # all points equal: keep as a (large) leaf
            continue
        seg = order[s:e]
        keys = np.empty(e - s)
        for i in range(e - s):
            keys[i] = X[seg[i], dim]
        srt = np.argsort(keys, kind="mergesort")
        order[s:e] = seg[srt]
        mid = s + (e - s) // 2
        a = n_nodes
        n_nodes += 2
        nodes[node, _LEFT], nodes[node, _DIM] = a, dim
        split[node] = X[order[mid], dim]  # keys[:mid] <= split <= keys[mid:]
        nodes[a, _START], nodes[a, _END], nodes[a + 1, _START], nodes[a + 1, _END] = s, mid, mid, e
        stack[top + 1], stack[top + 2] = a, a + 1
        top += 2
    return order, nodes[:n_nodes].copy(), split[:n_nodes].copy()


@njit(cache=True)
def _knn_one(data, nodes, split, z, k, eps, best_d2, best_pos, stack, stack_d2, stack_off):
    """k nearest tree positions of one query ``z`` into ``best_d2 / best_pos`` (ascending); returns the count.

    Each stack entry holds a node, the squared distance ``rd`` from ``z`` to the node's region and the
    per-dimension offsets ``off`` that make it up; the far child of a split differs from its parent in
    one offset only, so ``rd`` is updated in O(1) and ``off`` copied (d floats, in L1).
    """
    scale = 1.0 / ((1.0 + eps) * (1.0 + eps))
    d = z.shape[0]
    count = 0
    top = 0
    stack[0] = 0
    stack_d2[0] = 0.0
    stack_off[0, :] = 0.0
    while top >= 0:
        node = stack[top]
        rd = stack_d2[top]
        if count == k and rd > best_d2[k - 1] * scale:
            top -= 1
            continue
        left = nodes[node, _LEFT]
        if left < 0:  # leaf: scan its contiguous block
            top -= 1
            for p in range(nodes[node, _START], nodes[node, _END]):
                s = 0.0
                for j in range(d):
                    t = z[j] - data[p, j]
                    s += t * t
                if count < k or s < best_d2[count - 1]:
                    i = count if count < k else k - 1
                    while i > 0 and best_d2[i - 1] > s:
                        best_d2[i] = best_d2[i - 1]
                        best_pos[i] = best_pos[i - 1]
                        i -= 1
                    best_d2[i] = s
                    best_pos[i] = p
                    if count < k:
                        count += 1
            continue
        dim = nodes[node, _DIM]
        diff = z[dim] - split[node]
        near, far = (left, left + 1) if diff < 0.0 else (left + 1, left)
        # the far child replaces this entry; the near child goes on top (searched next) with this entry's off
        old = stack_off[top, dim]
        far_rd = rd - old * old + diff * diff
        stack[top] = far
        stack_d2[top] = far_rd
        stack_off[top + 1, :] = stack_off[top, :]
        stack_off[top, dim] = diff
        top += 1
        stack[top] = near
        stack_d2[top] = rd
    return count


@njit(cache=True)
def _query(data, nodes, split, Z, k, eps):
    B = Z.shape[0]
    out_d2 = np.empty((B, k))
    out_pos = np.empty((B, k), np.int64)
    work = workspace(nodes, Z.shape[1], k, 1)
    for b in range(B):
        _knn_one(data, nodes, split, Z[b], k, eps, out_d2[b], out_pos[b], work[2], work[3], work[4])
    return out_d2, out_pos


@njit(cache=True)
def pooled_log_density(data, nodes, split, labels, Z, k, eps, log_norms, inv, radius):
    """The pooled KDE's ``(B, K)`` log densities of standardised queries ``Z (B, d)`` in one call.

    ``labels (N,)`` is the class of each vector in tree order; ``log_norms (K,)`` the class normalisers;
    ``inv (K,) = 1 / (2 h_c^2)`` and ``radius (K,) = cutoff * h_c``, per class (a shared bandwidth repeats one value). Per class: log-sum of the kernels of its vectors among
    the ``k`` nearest within ``radius``; else its nearest found vector's kernel; else (no vector of the
    class among the ``k``) the kernel at the ``k``-th distance (see :mod:`haptic_env.recognizers.kde`).
    """
    out = np.empty((Z.shape[0], log_norms.shape[0]))
    work = workspace(nodes, Z.shape[1], k, log_norms.shape[0])
    for b in range(Z.shape[0]):
        log_density_row(data, nodes, split, labels, Z[b], k, eps, log_norms, inv, radius, work, out[b])
    return out


@njit(cache=True)
def workspace(nodes, d, k, n_classes):
    """Scratch arrays of :func:`log_density_row` (allocated once per caller; the stack holds at most
    depth + 2 entries, and the depth of a median-split tree is below 64)."""
    m = 66
    return (np.empty(k), np.empty(k, np.int64), np.empty(m, np.int64), np.empty(m), np.empty((m, d)),
            np.empty(n_classes), np.empty(n_classes), np.empty(n_classes))


@njit(cache=True)
def log_density_row(data, nodes, split, labels, z, k, eps, log_norms, inv, radius, work, out):
    """:func:`pooled_log_density` of one standardised query ``z (d,)`` into ``out (K,)``."""
    best_d2, best_pos, stack, stack_d2, stack_off, top, acc, near = work
    count = _knn_one(data, nodes, split, z, k, eps, best_d2, best_pos, stack, stack_d2, stack_off)
    top[:] = -np.inf
    acc[:] = 0.0
    near[:] = np.nan
    for j in range(count):
        c = labels[best_pos[j]]
        x = -inv[c] * best_d2[j]
        if np.isnan(near[c]):
            near[c] = x
        if best_d2[j] <= radius[c] * radius[c]:
            if acc[c] == 0.0:
                top[c] = x
            acc[c] += np.exp(x - top[c])
    for c in range(log_norms.shape[0]):
        if acc[c] > 0.0:
            out[c] = top[c] + np.log(acc[c]) + log_norms[c]
        elif not np.isnan(near[c]):
            out[c] = near[c] + log_norms[c]
        else:
            out[c] = -inv[c] * best_d2[count - 1] + log_norms[c]
