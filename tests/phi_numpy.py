r"""TEST ORACLE, not used by the package: the vectorised NumPy implementation of :math:`\Phi_n` and of the
surface area that :mod:`haptic_env.grasp_features` served large batches with until issue 8.

The production path is the compiled one (:mod:`haptic_env._phi_kernels`, called by
:func:`haptic_env.grasp_features.phi` and :func:`~haptic_env.grasp_features.surface_area` at every batch
size): faster at every batch size measured, with the same results (``benchmarks/bench_phi.py``, one thread,
200,000 grasps with normals: phi 2.3x / 2.8x / 1.6x for n = 3 / 4 / 8 on surface grasps of the default set, where
6 % of the 8-finger grasps need Qhull in both paths; 2.1-3.0x on contacts in general position; 7-112x on
batches of 1-64 grasps). This second, independently
vectorised implementation of the same algorithm stays as the oracle the compiled path is tested against
(``tests/test_grasp_features.py``) and as the baseline of ``benchmarks/bench_phi.py``. Its ``n = 2`` code
(:func:`_phi2`) was the package's own until the compiled two-pass kernel replaced it; that kernel is tested
equal to it bit for bit.
"""

from __future__ import annotations

import numpy as np

from haptic_env.grasp_features import (
    _angle,
    _as_batch,
    _canonical_hull_triangles,
    _cross,
    _dot,
    _norm,
    _topology,
    _unit,
    feature_dim,
    DEFAULT_TOL,
    GRASP_SIZE_RANGE,
)

__all__ = ["phi_numpy", "surface_area_numpy"]

_CHUNK_ELEMENTS = 1 << 18  # bound on B * T * n per chunk (cache-friendly; measured fastest)
_MIN_CHUNK_ROWS = 1024  # but never fewer rows than this (Python overhead of the chain loop)


def phi_numpy(contacts, normals=None, *, tol: float = DEFAULT_TOL):
    """``(q, valid, order, reason)`` of a batch ``(B, n, 3)`` (or one grasp), as :func:`haptic_env.grasp_features.phi`."""
    P, N, single = _as_batch(contacts, normals, 3)
    B, n, _ = P.shape
    d = feature_dim(n, N is not None)
    q = np.zeros((B, d))
    valid = np.zeros(B, dtype=bool)
    order = np.tile(np.arange(n), (B, 1))
    reason = np.zeros(B, dtype=np.int8)
    T = max(1, len(_topology(n)[0])) if n >= 3 else 1
    step = max(_MIN_CHUNK_ROWS, _CHUNK_ELEMENTS // (T * n))
    for lo in range(0, B, step):
        sl = slice(lo, min(B, lo + step))
        fn = _phi2 if n == 2 else _phi_chain
        q[sl], valid[sl], order[sl], reason[sl] = fn(P[sl], None if N is None else N[sl], tol)
    if single:
        return q[0], valid[0], order[0], reason[0]
    return q, valid, order, reason


def surface_area_numpy(contacts, *, tol: float = DEFAULT_TOL) -> np.ndarray:
    """As :func:`haptic_env.grasp_features.surface_area`."""
    P, _, single = _as_batch(contacts, None, 3)
    out = _surface_area_numpy(P, tol)
    return out[0] if single else out


def _phi2(P, N, tol):
    """Phi_2 in NumPy (the production code until the compiled two-pass kernel replaced it)."""
    B = P.shape[0]
    v = P[:, 1] - P[:, 0]
    dist = np.linalg.norm(v, axis=-1)
    in_range = (dist >= GRASP_SIZE_RANGE[0]) & (dist <= GRASP_SIZE_RANGE[1])
    reason = np.where(in_range, 0, np.where(dist > 1e-300, 4, 1)).astype(np.int8)
    order = np.tile(np.arange(2), (B, 1))
    if N is None:
        q = dist[:, None]
    else:
        al0 = _angle(N[:, 0], v)
        al1 = _angle(N[:, 1], -v)
        # canonical order: the contact whose normal makes the larger angle with the line first
        swap = al1 > al0
        order[swap] = [1, 0]
        e = _unit(v)
        n0 = N[:, 0] - np.sum(N[:, 0] * e, -1, keepdims=True) * e
        n1 = N[:, 1] - np.sum(N[:, 1] * e, -1, keepdims=True) * e
        twist = np.arctan2(np.sum(e * np.cross(n0, n1), -1), np.sum(n0 * n1, -1))  # symmetric in swap
        q = np.stack([dist, np.maximum(al0, al1), np.minimum(al0, al1), twist], axis=1)
    valid = reason == 0
    q = np.where(valid[:, None], q, 0.0)
    return q, valid, order, reason


def _signed_dihedral(x, y, w, u) -> np.ndarray:
    """Signed angle about axis ``y - x`` from half-plane ``(x, y, w)`` to half-plane ``(x, y, u)``."""
    e = _unit(y - x)
    u1 = w - x
    u2 = u - x
    u1 = u1 - _dot(u1, e)[..., None] * e
    u2 = u2 - _dot(u2, e)[..., None] * e
    ang = np.arctan2(_dot(e, _cross(u1, u2)), _dot(u1, u2))
    # a flat (coplanar) pair of facets is +-pi up to rounding: report it as +pi
    return np.where(np.abs(ang) > np.pi - 1e-9, np.pi, ang)


def _take(P: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``P[b, idx[b]]`` for ``P`` of shape (B, n, k) and ``idx`` (B,) -> (B, k)."""
    return P[np.arange(P.shape[0]), idx]


def _hull_facets(P: np.ndarray, tol: float):
    """Candidate triangles of each grasp, which of them are hull facets, and degeneracy codes.

    Returns ``area (B,T)``, ``hull (B,T)`` bool, ``reason (B,)`` int8 and ``scale (B,)``.
    Where near-coplanar points make the facet test ambiguous the hull comes from Qhull
    (triangulated), so every grasp gets a proper triangulated surface.
    """
    B, n, _ = P.shape
    tri, _, lut, _ = _topology(n)
    iu = np.triu_indices(n, 1)
    dist = _norm(P[:, iu[0]] - P[:, iu[1]])  # (B, n(n-1)/2)
    scale = dist.max(axis=1)
    reason = np.zeros(B, dtype=np.int8)
    reason[dist.min(axis=1) <= tol * np.maximum(scale, 1e-300)] = 1
    reason[~((scale >= GRASP_SIZE_RANGE[0]) & (scale <= GRASP_SIZE_RANGE[1]))] = 4  # a diameter out of range
    reason[scale <= 1e-300] = 1
    a, b, c = P[:, tri[:, 0]], P[:, tri[:, 1]], P[:, tri[:, 2]]
    cr = _cross(b - a, c - a)
    area = 0.5 * _norm(cr)
    s2 = np.maximum(scale, 1e-300) ** 2
    flat = area.max(axis=1) <= 0.5 * tol * s2
    reason[(reason == 0) & flat] = 2
    if n == 3:
        return area, np.ones_like(area, dtype=bool), reason, scale
    # signed volumes of every other contact against every triangle's plane: (B, T, n)
    s = np.matmul(cr, P.transpose(0, 2, 1)) - _dot(cr, a)[..., None]
    own = np.zeros((len(tri), n), dtype=bool)
    own[np.arange(len(tri))[:, None], tri] = True
    s = s[:, ~own].reshape(B, len(tri), n - 3)  # each triangle against the other contacts only
    thr = tol * np.maximum(scale, 1e-300)[:, None, None] ** 3
    pos = (s > thr).any(-1)
    neg = (s < -thr).any(-1)
    onplane = (np.abs(s) <= thr).any(-1)  # another contact on the triangle's plane
    planar = ~(pos | neg).any(-1)
    reason[(reason == 0) & planar] = 3
    proper = area > 0.5 * tol * s2[:, None]
    hull = proper & ~(pos & neg)
    # ambiguous: a hull candidate with another contact on its plane (a planar face of >= 4
    # contacts has several triangulations): triangulate those faces canonically instead
    ambiguous = (hull & onplane).any(-1) & (reason == 0)
    for i in np.flatnonzero(ambiguous):
        tris = _canonical_hull_triangles(P[i], tol)
        if tris is None:  # pragma: no cover - qhull failure on an input already near-flat
            reason[i] = 3
            continue
        hull[i] = False
        hull[i, lut[tris[:, 0], tris[:, 1], tris[:, 2]]] = True
    return area, hull, reason, scale



def _phi_chain(P, N, tol):
    B, n, _ = P.shape
    tri, tri_edges, _, n_edges = _topology(n)
    area, hull, reason, _ = _hull_facets(P, tol)
    valid = reason == 0
    rows = np.arange(B)
    # --- t1 and its longest edge ab
    t1 = np.argmax(np.where(hull, area, -1.0), axis=1)
    v = tri[t1]  # (B, 3) contact indices
    pts = P[rows[:, None], v]  # (B, 3, 3)
    # edge lengths opposite each position: edge (1,2), (0,2), (0,1)
    L = _norm(pts[:, [1, 0, 0]] - pts[:, [2, 2, 1]])
    opp = np.argmax(L, axis=1)  # position of c (opposite the longest edge)
    cpos = opp
    apos = (opp + 1) % 3
    bpos = (opp + 2) % 3
    ia, ib, ic = v[rows, apos], v[rows, bpos], v[rows, cpos]
    A, Bp, C = _take(P, ia), _take(P, ib), _take(P, ic)
    ang_a = _angle(Bp - A, C - A)
    ang_b = _angle(A - Bp, C - Bp)
    swap = ang_b > ang_a
    ia, ib = np.where(swap, ib, ia), np.where(swap, ia, ib)
    A, Bp = np.where(swap[:, None], Bp, A), np.where(swap[:, None], A, Bp)
    ang_a, ang_b = np.maximum(ang_a, ang_b), np.minimum(ang_a, ang_b)
    shape_vals = [_norm(Bp - A), ang_a, ang_b]

    order = np.empty((B, n), dtype=np.int64)
    order[:, 0], order[:, 1], order[:, 2] = ia, ib, ic
    rank = np.full((B, n), n, dtype=np.int64)
    rank[rows, ia], rank[rows, ib], rank[rows, ic] = 0, 1, 2
    visited = np.zeros((B, n), dtype=bool)
    visited[rows, ia] = visited[rows, ib] = visited[rows, ic] = True
    owner = np.full((B, n_edges), -1, dtype=np.int64)  # first visited facet on each edge
    owner[rows[:, None], tri_edges[t1]] = t1[:, None]

    if n >= 4:
        # virtual attachment of every contact to ab of t1, for contacts inside the hull
        att_a = _angle(Bp[:, None] - A[:, None], P - A[:, None])
        att_b = _angle(A[:, None] - Bp[:, None], P - Bp[:, None])
        att_d = _signed_dihedral(A[:, None], Bp[:, None], C[:, None], P)
        for k in range(3, n):
            unv = ~visited[:, tri]  # (B, T, 3)
            n_unv = unv.sum(-1)
            upos = np.argmax(unv, axis=-1)  # position of the (first) unvisited vertex
            shared = tri_edges[np.arange(len(tri))[None], upos]  # (B, T) edge opposite it
            g_all = np.take_along_axis(owner, shared, axis=1)  # (B, T)
            cand = hull & (n_unv == 1) & (g_all >= 0)
            has = cand.any(axis=1)
            f = np.argmax(np.where(cand, area, -1.0), axis=1)
            fv = tri[f]  # (B, 3)
            fu = upos[rows, f]
            u_new = fv[rows, fu]
            others = np.stack([fv[rows, (fu + 1) % 3], fv[rows, (fu + 2) % 3]], axis=1)
            early = rank[rows[:, None], others].argmin(axis=1)
            x = others[rows, early]
            y = others[rows, 1 - early]
            g = g_all[rows, f]
            gv = tri[np.maximum(g, 0)]
            w = gv[rows, np.argmax((gv != x[:, None]) & (gv != y[:, None]), axis=1)]
            X, Y, U, W = _take(P, x), _take(P, y), _take(P, u_new), _take(P, w)
            vals = np.stack([_angle(Y - X, U - X), _angle(X - Y, U - Y), _signed_dihedral(X, Y, W, U)], 1)
            # contacts no hull facet reaches: attach to ab, largest angle at a first
            u_att = np.argmax(np.where(visited, -np.inf, att_a), axis=1)
            vals_att = np.stack([att_a[rows, u_att], att_b[rows, u_att], att_d[rows, u_att]], 1)
            u_new = np.where(has, u_new, u_att)
            vals = np.where(has[:, None], vals, vals_att)
            shape_vals.extend(vals.T)
            order[:, k] = u_new
            rank[rows, u_new] = k
            visited[rows, u_new] = True
            fe = tri_edges[f]
            cur = owner[rows[:, None], fe]
            owner[rows[:, None], fe] = np.where((cur < 0) & has[:, None], f[:, None], cur)
    parts = [np.stack(shape_vals, axis=1)]
    if N is not None:
        N1 = _unit(_cross(Bp - A, C - A))
        if n == 3:
            N2 = _unit(Bp - A)
        else:
            N2 = _unit(_cross(Bp - A, _take(P, order[:, 3]) - A))
        No = N[rows[:, None], order]  # (B, n, 3) in chain order
        ang1 = _angle(No, N1[:, None])
        ang2 = _angle(No, N2[:, None])
        parts.append(np.stack([ang1, ang2], axis=-1).reshape(B, 2 * n))
    q = np.concatenate(parts, axis=1)
    q = np.where(valid[:, None], q, 0.0)
    order = np.where(valid[:, None], order, np.arange(n)[None])
    return q, valid, order, reason



def _surface_area_numpy(P: np.ndarray, tol: float) -> np.ndarray:
    B, n, _ = P.shape
    if n == 2:
        d2 = np.sum((P[:, 1] - P[:, 0]) ** 2, -1)
        return np.where(_phi2(P, None, tol)[1], d2, 0.0)  # zero where phi flags the grasp
    out = np.zeros(B)
    T = len(_topology(n)[0])
    step = max(_MIN_CHUNK_ROWS, _CHUNK_ELEMENTS // (T * n))
    for lo in range(0, B, step):
        area, hull, reason, _ = _hull_facets(P[lo : lo + step], tol)
        ok = reason == 0  # phi's verdict at every n (n = 3: near-coincident contacts get 0 too)
        out[lo : lo + step] = np.where(ok, np.where(hull, area, 0.0).sum(1), 0.0)
    return out
