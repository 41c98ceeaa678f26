r"""Compiled (numba) scalar kernels of :math:`\Phi_n` and of the surface area, one grasp at a time.

The production implementation: :func:`haptic_env.grasp_features.phi` and
:func:`~haptic_env.grasp_features.surface_area` call :func:`phi_rows` / :func:`surface_area_rows` at every
batch size. The vectorised NumPy implementation of the same algorithm (same floating-point operations in
the same order, same tie-breaking: first maximum) is kept only as a test oracle, ``tests/phi_numpy.py``;
both agree to rounding (tested on random, degenerate and symmetric grasps in ``tests/test_grasp_features.py``).

Each kernel returns a status: ``0`` ok, ``1``/``2``/``3``/``4`` the degeneracy codes of
:data:`haptic_env.grasp_features.DEGENERACY_REASONS`, or ``-1`` (:data:`AMBIGUOUS`) when a hull face holds
four or more coplanar contacts: that face needs the canonical triangulation of
``grasp_features._canonical_hull_triangles`` (Qhull), after which the caller runs :func:`phi_on_hull`.

Compiled on first use and cached on disk (numba ``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["phi_one", "phi_checked", "phi_on_hull", "phi_rows", "phi2_prepare", "phi2_finish", "surface_area_one",
           "surface_area_rows", "AMBIGUOUS", "BAD_INPUT", "OUT_OF_RANGE", "SIZE_MIN", "SIZE_MAX"]

AMBIGUOUS = -1  #: a hull face with >= 4 coplanar contacts: triangulate it canonically, then phi_on_hull
BAD_INPUT = -2  #: non-finite contacts, or a zero / non-finite normal: the caller raises the error
#: status of a grasp whose diameter (largest contact distance) lies outside ``[SIZE_MIN, SIZE_MAX]`` but above the
#: coincident limit ``1e-300``: squared lengths and products of lengths would underflow or overflow there (angles of
#: pi/2 at 1e80, "collinear" at 1e-160, an infinite length at 1e155), so it is refused as out of range
OUT_OF_RANGE = 4
SIZE_MIN = 1e-50
SIZE_MAX = 1e50
#: ``has_normals`` codes: False / 0 no normals; True / 1 each normal's angles to t1's normal and to the normal of the
#: triangle (a, b, order[3]) (for n = 3: to the edge ab), the paper's; 2 (:data:`NORMALS_AB`) to t1's normal and to the
#: edge ab at every n (``phi(normal_axis="ab")``); 3 (:data:`NORMALS_FRAME`) to the three axes of t1's frame: its
#: normal, the edge ab and the in-plane direction perpendicular to ab on the third contact's side
#: (``phi(normal_axis="frame")``, 3 per contact)
NORMALS_AB = 2
NORMALS_FRAME = 3


@njit(cache=True, inline="always")
def _sub(P, i, j):
    return P[i, 0] - P[j, 0], P[i, 1] - P[j, 1], P[i, 2] - P[j, 2]


@njit(cache=True, inline="always")
def _dist(P, i, j):
    d0, d1, d2 = P[i, 0] - P[j, 0], P[i, 1] - P[j, 1], P[i, 2] - P[j, 2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(cache=True, inline="always")
def _cross(u0, u1, u2, v0, v1, v2):
    return u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0


@njit(cache=True, inline="always")
def _norm(u0, u1, u2):
    return math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)


@njit(cache=True, inline="always")
def _angle(u0, u1, u2, v0, v1, v2):
    c0, c1, c2 = _cross(u0, u1, u2, v0, v1, v2)
    return math.atan2(_norm(c0, c1, c2), u0 * v0 + u1 * v1 + u2 * v2)


@njit(cache=True)
def _signed_dihedral(P, x, y, w, u):
    """Signed angle about axis ``y - x`` from half-plane ``(x, y, w)`` to ``(x, y, u)`` (contact indices)."""
    e0, e1, e2 = _sub(P, y, x)
    n = _norm(e0, e1, e2)
    if n > 0:
        e0, e1, e2 = e0 / n, e1 / n, e2 / n
    a0, a1, a2 = _sub(P, w, x)
    b0, b1, b2 = _sub(P, u, x)
    da = a0 * e0 + a1 * e1 + a2 * e2
    db = b0 * e0 + b1 * e1 + b2 * e2
    a0, a1, a2 = a0 - da * e0, a1 - da * e1, a2 - da * e2
    b0, b1, b2 = b0 - db * e0, b1 - db * e1, b2 - db * e2
    c0, c1, c2 = _cross(a0, a1, a2, b0, b1, b2)
    ang = math.atan2(e0 * c0 + e1 * c1 + e2 * c2, a0 * b0 + a1 * b1 + a2 * b2)
    if abs(ang) > math.pi - 1e-9:
        return math.pi
    return ang


@njit(cache=True)
def _hull(P, tri, tol, area, hull):
    """Fill ``area (T,)`` and ``hull (T,)`` of one grasp; return its status (see module docs)."""
    n = P.shape[0]
    T = tri.shape[0]
    dmin = np.inf
    scale = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            d = _dist(P, i, j)
            dmin = min(dmin, d)
            scale = max(scale, d)
    sc = max(scale, 1e-300)
    status = 0
    if scale <= 1e-300:
        status = 1
    elif not (scale >= SIZE_MIN and scale <= SIZE_MAX):  # before the next test: dmin = scale = inf passes it
        status = OUT_OF_RANGE
    elif dmin <= tol * sc:
        status = 1
    amax = -np.inf
    for t in range(T):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        u0, u1, u2 = _sub(P, b, a)
        v0, v1, v2 = _sub(P, c, a)
        c0, c1, c2 = _cross(u0, u1, u2, v0, v1, v2)
        area[t] = 0.5 * _norm(c0, c1, c2)
        amax = max(amax, area[t])
        hull[t] = True
    s2 = sc * sc
    if status == 0 and amax <= 0.5 * tol * s2:
        status = 2
    if n == 3:
        return status
    thr = tol * sc * sc * sc
    any_side = False
    ambiguous = False
    for t in range(T):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        u0, u1, u2 = _sub(P, b, a)
        v0, v1, v2 = _sub(P, c, a)
        c0, c1, c2 = _cross(u0, u1, u2, v0, v1, v2)
        off = c0 * P[a, 0] + c1 * P[a, 1] + c2 * P[a, 2]
        pos = neg = onplane = False
        for m in range(n):
            if m == a or m == b or m == c:
                continue
            s = (c0 * P[m, 0] + c1 * P[m, 1] + c2 * P[m, 2]) - off
            if s > thr:
                pos = True
            elif s < -thr:
                neg = True
            else:
                onplane = True
        any_side = any_side or pos or neg
        proper = area[t] > 0.5 * tol * s2
        hull[t] = proper and not (pos and neg)
        if hull[t] and onplane:
            ambiguous = True
    if status == 0 and not any_side:
        status = 3
    if status == 0 and ambiguous:
        status = -1
    return status


@njit(cache=True)
def surface_area_one(P, tri, tol):
    """``(area, status)`` of one grasp ``P (n, 3)``; ``tri`` are ``combinations(range(n), 3)``."""
    T = tri.shape[0]
    area = np.empty(T)
    hull = np.empty(T, dtype=np.bool_)
    status = _hull(P, tri, tol, area, hull)
    total = 0.0
    for t in range(T):
        if hull[t]:
            total += area[t]
    return total, status


@njit(cache=True)
def phi_one(P, N, has_normals, tri, tri_edges, n_edges, tol, q, order):
    """Chain of one grasp ``P (n, 3)`` (unit normals ``N`` if ``has_normals``) into ``q`` and ``order``.

    ``q (d,)`` and ``order (n,)`` are written only when the status is 0 (ok).
    """
    T = tri.shape[0]
    area = np.empty(T)
    hull = np.empty(T, dtype=np.bool_)
    status = _hull(P, tri, tol, area, hull)
    if status != 0:
        return status
    return _chain(P, N, has_normals, tri, tri_edges, n_edges, area, hull, q, order)


@njit(cache=True)
def _facet_areas(P, tri, area):
    """``area (T,)`` of the candidate triangles ``tri`` of one grasp (the formula of :func:`_hull`)."""
    for t in range(tri.shape[0]):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        u0, u1, u2 = _sub(P, b, a)
        v0, v1, v2 = _sub(P, c, a)
        c0, c1, c2 = _cross(u0, u1, u2, v0, v1, v2)
        area[t] = 0.5 * _norm(c0, c1, c2)


@njit(cache=True)
def phi_on_hull(P, N, has_normals, tri, tri_edges, n_edges, hull, q, order, Nu):
    """:func:`phi_checked` of one grasp whose hull facets are given, ``hull (T,)`` over ``tri``: the caller's
    canonical triangulation of a grasp with a planar hull face of >= 4 contacts (:data:`AMBIGUOUS`)."""
    if _bad_input(P, N, has_normals):
        return BAD_INPUT
    _unit_normals(P.shape[0], N, has_normals, Nu)
    area = np.empty(tri.shape[0])
    _facet_areas(P, tri, area)
    return _chain(P, Nu, has_normals, tri, tri_edges, n_edges, area, hull, q, order)


@njit(cache=True)
def _chain(P, N, has_normals, tri, tri_edges, n_edges, area, hull, q, order):
    """The chain of one non-degenerate grasp over its hull facets ``hull`` (areas ``area``): fills ``q``, ``order``."""
    n = P.shape[0]
    T = tri.shape[0]
    # --- t1 and its longest edge ab
    t1 = 0
    best = -np.inf
    for t in range(T):
        v = area[t] if hull[t] else -1.0
        if v > best:
            best, t1 = v, t
    p0, p1, p2 = tri[t1, 0], tri[t1, 1], tri[t1, 2]
    L0 = _dist(P, p1, p2)
    L1 = _dist(P, p0, p2)
    L2 = _dist(P, p0, p1)
    opp = 0
    if L1 > L0:
        opp = 1
    if L2 > max(L0, L1):
        opp = 2
    ia, ib, ic = tri[t1, (opp + 1) % 3], tri[t1, (opp + 2) % 3], tri[t1, opp]
    ba0, ba1, ba2 = _sub(P, ib, ia)
    ca0, ca1, ca2 = _sub(P, ic, ia)
    ab0, ab1, ab2 = _sub(P, ia, ib)
    cb0, cb1, cb2 = _sub(P, ic, ib)
    ang_a = _angle(ba0, ba1, ba2, ca0, ca1, ca2)
    ang_b = _angle(ab0, ab1, ab2, cb0, cb1, cb2)
    if ang_b > ang_a:
        ia, ib = ib, ia
        ang_a, ang_b = ang_b, ang_a
    q[0] = _dist(P, ib, ia)
    q[1] = ang_a
    q[2] = ang_b
    order[0], order[1], order[2] = ia, ib, ic
    rank = np.full(n, n, dtype=np.int64)
    rank[ia], rank[ib], rank[ic] = 0, 1, 2
    visited = np.zeros(n, dtype=np.bool_)
    visited[ia] = visited[ib] = visited[ic] = True
    owner = np.full(n_edges, -1, dtype=np.int64)
    for j in range(3):
        owner[tri_edges[t1, j]] = t1
    if n >= 4:
        ba0, ba1, ba2 = _sub(P, ib, ia)
        ab0, ab1, ab2 = _sub(P, ia, ib)
        att_a = np.empty(n)
        att_b = np.empty(n)
        att_d = np.empty(n)
        for m in range(n):
            pa0, pa1, pa2 = _sub(P, m, ia)
            pb0, pb1, pb2 = _sub(P, m, ib)
            att_a[m] = _angle(ba0, ba1, ba2, pa0, pa1, pa2)
            att_b[m] = _angle(ab0, ab1, ab2, pb0, pb1, pb2)
            att_d[m] = _signed_dihedral(P, ia, ib, ic, m)
        upos = np.empty(T, dtype=np.int64)
        g_all = np.empty(T, dtype=np.int64)
        for k in range(3, n):
            f = -1
            best = -np.inf
            for t in range(T):
                n_unv = 0
                up = -1
                for j in range(3):
                    if not visited[tri[t, j]]:
                        n_unv += 1
                        if up < 0:
                            up = j
                if up < 0:
                    up = 0
                upos[t] = up
                g_all[t] = owner[tri_edges[t, up]]
                if hull[t] and n_unv == 1 and g_all[t] >= 0 and area[t] > best:
                    best, f = area[t], t
            base = 3 + 3 * (k - 3)
            if f >= 0:
                fu = upos[f]
                u_new = tri[f, fu]
                o1, o2 = tri[f, (fu + 1) % 3], tri[f, (fu + 2) % 3]
                if rank[o2] < rank[o1]:
                    x, y = o2, o1
                else:
                    x, y = o1, o2
                g = g_all[f]
                w = tri[g, 0]
                for j in range(3):
                    if tri[g, j] != x and tri[g, j] != y:
                        w = tri[g, j]
                        break
                yx0, yx1, yx2 = _sub(P, y, x)
                ux0, ux1, ux2 = _sub(P, u_new, x)
                xy0, xy1, xy2 = _sub(P, x, y)
                uy0, uy1, uy2 = _sub(P, u_new, y)
                q[base] = _angle(yx0, yx1, yx2, ux0, ux1, ux2)
                q[base + 1] = _angle(xy0, xy1, xy2, uy0, uy1, uy2)
                q[base + 2] = _signed_dihedral(P, x, y, w, u_new)
                for j in range(3):
                    e = tri_edges[f, j]
                    if owner[e] < 0:
                        owner[e] = f
            else:  # no hull facet reaches a new contact: attach to ab, largest angle at a first
                u_new = -1
                best = -np.inf
                for m in range(n):
                    if not visited[m] and (u_new < 0 or att_a[m] > best):
                        best, u_new = att_a[m], m
                q[base] = att_a[u_new]
                q[base + 1] = att_b[u_new]
                q[base + 2] = att_d[u_new]
            order[k] = u_new
            rank[u_new] = k
            visited[u_new] = True
    if has_normals:
        ba0, ba1, ba2 = _sub(P, ib, ia)
        ca0, ca1, ca2 = _sub(P, ic, ia)
        m0, m1, m2 = _cross(ba0, ba1, ba2, ca0, ca1, ca2)
        s = _norm(m0, m1, m2)
        if s > 0:
            m0, m1, m2 = m0 / s, m1 / s, m2 / s
        if n == 3 or has_normals == NORMALS_AB or has_normals == NORMALS_FRAME:  # both read in t1's frame
            r0, r1, r2 = ba0, ba1, ba2
        else:
            da0, da1, da2 = _sub(P, order[3], ia)
            r0, r1, r2 = _cross(ba0, ba1, ba2, da0, da1, da2)
        s = _norm(r0, r1, r2)
        if s > 0:
            r0, r1, r2 = r0 / s, r1 / s, r2 / s
        base = 3 * n - 6
        if has_normals == NORMALS_FRAME:  # t1's frame: normal m, ab (r) and m x r, towards c within t1
            p0, p1, p2 = _cross(m0, m1, m2, r0, r1, r2)
            for j in range(n):
                o = order[j]
                q[base + 3 * j] = _angle(N[o, 0], N[o, 1], N[o, 2], m0, m1, m2)
                q[base + 3 * j + 1] = _angle(N[o, 0], N[o, 1], N[o, 2], r0, r1, r2)
                q[base + 3 * j + 2] = _angle(N[o, 0], N[o, 1], N[o, 2], p0, p1, p2)
        else:
            for j in range(n):
                o = order[j]
                q[base + 2 * j] = _angle(N[o, 0], N[o, 1], N[o, 2], m0, m1, m2)
                q[base + 2 * j + 1] = _angle(N[o, 0], N[o, 1], N[o, 2], r0, r1, r2)
    return 0


@njit(cache=True)
def _bad_input(P, N, has_normals):
    for i in range(P.shape[0]):
        for j in range(3):
            if not math.isfinite(P[i, j]):
                return True
    if has_normals:
        for i in range(N.shape[0]):
            s = N[i, 0] * N[i, 0] + N[i, 1] * N[i, 1] + N[i, 2] * N[i, 2]
            if not (math.isfinite(s) and math.sqrt(s) > 1e-12):
                return True
    return False


@njit(cache=True)
def phi_checked(P, N, has_normals, tri, tri_edges, n_edges, tol, q, order, Nu):
    """:func:`phi_one` of one grasp from raw normals ``N (n, 3)``: :data:`BAD_INPUT` for non-finite contacts or
    a zero / non-finite normal, else the normals are normalised into the scratch ``Nu (n, 3)`` first."""
    if _bad_input(P, N, has_normals):
        return BAD_INPUT
    _unit_normals(P.shape[0], N, has_normals, Nu)
    return phi_one(P, Nu, has_normals, tri, tri_edges, n_edges, tol, q, order)


@njit(cache=True)
def _unit_normals(n, N, has_normals, Nu):
    if has_normals:
        for j in range(n):
            s = math.sqrt(N[j, 0] * N[j, 0] + N[j, 1] * N[j, 1] + N[j, 2] * N[j, 2])
            Nu[j, 0], Nu[j, 1], Nu[j, 2] = N[j, 0] / s, N[j, 1] / s, N[j, 2] / s


@njit(cache=True)
def phi_rows(P, N, has_normals, tri, tri_edges, n_edges, tol, q, order, reason, valid):
    """:func:`phi_one` over a batch ``P (B, n, 3)``; normals ``N (B, n, 3)`` are normalised here.

    Fills ``q (B, d)`` (zero rows unless ok), ``order (B, n)``, ``reason (B,)`` int8 (the degeneracy code, or
    :data:`AMBIGUOUS`) and ``valid (B,)``. Returns :data:`BAD_INPUT` when some row has non-finite contacts or
    a bad normal (the caller re-validates to raise a precise error), else the number of :data:`AMBIGUOUS` rows.
    """
    B, n = P.shape[0], P.shape[1]
    Nu = np.empty((n, 3))
    n_ambiguous = 0
    for i in range(B):
        for j in range(n):
            order[i, j] = j
        valid[i] = False
        st = phi_checked(P[i], N[i], has_normals, tri, tri_edges, n_edges, tol, q[i], order[i], Nu)
        if st == BAD_INPUT:
            return BAD_INPUT
        if st != 0:
            q[i, :] = 0.0
            for j in range(n):
                order[i, j] = j
        if st == AMBIGUOUS:
            n_ambiguous += 1
        reason[i] = st
        valid[i] = st == 0
    return n_ambiguous


@njit(cache=True)
def surface_area_rows(P, tri, tol, out, status):
    """:func:`surface_area_one` over a batch ``P (B, n, 3)`` into ``out (B,)`` and ``status (B,)``."""
    bad = False
    for i in range(P.shape[0]):
        if _bad_input(P[i], P[i], False):
            status[i] = BAD_INPUT
            out[i] = 0.0
            bad = True
            continue
        out[i], status[i] = surface_area_one(P[i], tri, tol)
    return bad


# ------------------------------------------------------------------------------------------- n = 2
# Phi_2 (distance; with normals each normal's angle to the line and the twist about it) in two passes around
# one ``np.arctan2`` of the caller: NumPy's float64 arctan2 is a SIMD (SVML) routine that differs from libm's
# ``atan2`` in the last bit of ~2 % of the values, and Phi_2 had been NumPy's all along (``tests/phi_numpy.py``
# keeps that code as the oracle). Everything else replays the NumPy expressions operation for operation,
# including NumPy's order of the 3-term reductions on x86-64: ``np.sum(x, -1)`` and ``np.linalg.norm`` add
# ``((0 + x0) + x1) + x2``, ``einsum("...k,...k->...")`` adds ``(x0 + x2) + (x1 + 0)``; the results are equal
# bit for bit (tested on random and degenerate grasps).


@njit(cache=True, inline="always")
def _esum(x0, x1, x2):
    """``einsum("...k,...k->...")``'s sum of three products."""
    return (x0 + x2) + (x1 + 0.0)


@njit(cache=True, inline="always")
def _rsum(x0, x1, x2):
    """``np.sum(x, axis=-1)``'s (``add.reduce``'s) sum of three values."""
    return ((0.0 + x0) + x1) + x2


@njit(cache=True)
def phi2_prepare(P, N, has_normals, dist, ys, xs):
    """First pass of Phi_2 over ``P (B, 2, 3)`` (raw normals ``N``): ``dist (B,)`` and the arguments of the three
    ``arctan2`` of each grasp, ``ys``, ``xs (B, 3)``: the angles of normal 0 to ``v = P1 - P0`` and of normal 1
    to ``-v``, and the twist. Returns :data:`BAD_INPUT` for non-finite contacts or a zero / non-finite normal
    (the caller raises the precise error), else 0."""
    B = P.shape[0]
    for b in range(B):
        for i in range(2):
            for j in range(3):
                if not math.isfinite(P[b, i, j]):
                    return BAD_INPUT
        if has_normals:
            for i in range(2):
                s = math.sqrt(_esum(N[b, i, 0] * N[b, i, 0], N[b, i, 1] * N[b, i, 1], N[b, i, 2] * N[b, i, 2]))
                if not (math.isfinite(s) and s > 1e-12):
                    return BAD_INPUT
    for b in range(B):
        v0, v1, v2 = P[b, 1, 0] - P[b, 0, 0], P[b, 1, 1] - P[b, 0, 1], P[b, 1, 2] - P[b, 0, 2]
        dist[b] = math.sqrt(_rsum(v0 * v0, v1 * v1, v2 * v2))  # np.linalg.norm
        if not has_normals:
            continue
        # the normals as _as_batch makes them unit: N / sqrt(einsum(N, N))
        s = math.sqrt(_esum(N[b, 0, 0] * N[b, 0, 0], N[b, 0, 1] * N[b, 0, 1], N[b, 0, 2] * N[b, 0, 2]))
        a0, a1, a2 = N[b, 0, 0] / s, N[b, 0, 1] / s, N[b, 0, 2] / s
        s = math.sqrt(_esum(N[b, 1, 0] * N[b, 1, 0], N[b, 1, 1] * N[b, 1, 1], N[b, 1, 2] * N[b, 1, 2]))
        c0, c1, c2 = N[b, 1, 0] / s, N[b, 1, 1] / s, N[b, 1, 2] / s
        # _angle(N0, v) and _angle(N1, -v): arctan2(|u x w|, u . w), norm and dot through einsum
        x0, x1, x2 = _cross(a0, a1, a2, v0, v1, v2)
        ys[b, 0] = math.sqrt(_esum(x0 * x0, x1 * x1, x2 * x2))
        xs[b, 0] = _esum(a0 * v0, a1 * v1, a2 * v2)
        m0, m1, m2 = -v0, -v1, -v2
        x0, x1, x2 = _cross(c0, c1, c2, m0, m1, m2)
        ys[b, 1] = math.sqrt(_esum(x0 * x0, x1 * x1, x2 * x2))
        xs[b, 1] = _esum(c0 * m0, c1 * m1, c2 * m2)
        # twist: e = _unit(v); n_i = N_i - sum(N_i * e) e; arctan2(sum(e * (n0 x n1)), sum(n0 * n1))
        nv = math.sqrt(_esum(v0 * v0, v1 * v1, v2 * v2))
        nv = nv if nv > 0 else 1.0
        e0, e1, e2 = v0 / nv, v1 / nv, v2 / nv
        t = _rsum(a0 * e0, a1 * e1, a2 * e2)
        p0, p1, p2 = a0 - t * e0, a1 - t * e1, a2 - t * e2
        t = _rsum(c0 * e0, c1 * e1, c2 * e2)
        r0, r1, r2 = c0 - t * e0, c1 - t * e1, c2 - t * e2
        x0, x1, x2 = _cross(p0, p1, p2, r0, r1, r2)
        ys[b, 2] = _rsum(e0 * x0, e1 * x1, e2 * x2)
        xs[b, 2] = _rsum(p0 * r0, p1 * r1, p2 * r2)
    return 0


@njit(cache=True)
def phi2_finish(dist, ang, has_normals, q, order, reason, valid):
    """Second pass of Phi_2: from ``dist`` and ``ang = arctan2(ys, xs)`` fill ``q (B, 1 | 4)`` (zero rows for
    coincident contacts and for a distance out of range, :data:`OUT_OF_RANGE`), ``order (B, 2)`` (with normals: the
    contact whose normal makes the larger angle with the line first), ``reason`` and ``valid``."""
    for b in range(dist.shape[0]):
        ok = dist[b] >= SIZE_MIN and dist[b] <= SIZE_MAX
        reason[b] = 0 if ok else (1 if dist[b] <= 1e-300 else OUT_OF_RANGE)
        valid[b] = ok
        order[b, 0], order[b, 1] = 0, 1
        if not has_normals:
            q[b, 0] = dist[b] if ok else 0.0
            continue
        al0, al1 = ang[b, 0], ang[b, 1]
        if al1 > al0:
            order[b, 0], order[b, 1] = 1, 0
        if ok:
            q[b, 0] = dist[b]
            q[b, 1] = max(al0, al1) if not (math.isnan(al0) or math.isnan(al1)) else math.nan
            q[b, 2] = min(al0, al1) if not (math.isnan(al0) or math.isnan(al1)) else math.nan
            q[b, 3] = ang[b, 2]
        else:
            q[b, 0] = q[b, 1] = q[b, 2] = q[b, 3] = 0.0
