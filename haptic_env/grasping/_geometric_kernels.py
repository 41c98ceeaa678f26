r"""Compiled (numba) pieces of :meth:`GeometricBackend.grasp_placed <haptic_env.grasping.geometric.GeometricBackend.grasp_placed>`:
the ray set-up and the hit maths of ``B`` grasps, each in one call instead of a few dozen small NumPy calls.

The single grasp's NumPy code (:meth:`~haptic_env.grasping.geometric.GeometricBackend.rays`,
:func:`~haptic_env.grasping.base.approach_frame`, ``GeometricBackend._cast``) stays the reference, and these
kernels give its numbers **bit for bit**: the same IEEE operations in the same order, no fast-math. What a
kernel cannot reproduce stays in NumPy around it: ``np.cos`` / ``np.sin`` (the caller evaluates them on the
angles :func:`ray_angles` returns), and the ``matmul`` of the rays into each object's frame and of the hits
back to the world (BLAS). The reductions over the 3 coordinates follow NumPy's order on x86-64
(``np.sum(x, -1)`` / ``np.linalg.norm``: ``((0 + x0) + x1) + x2``; ``einsum("ij,ij->i")``:
``(x0 + x2) + (x1 + 0)``), which ``tests/test_grasping_geometric.py`` checks against the NumPy reference on
random and boundary actions, and ``tests/test_vector_env.py`` through whole episodes.

Compiled on first use and cached on disk (numba ``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["ray_angles", "ray_frames", "embree_inputs", "hit_maths", "hit_results"]


@njit(cache=True)
def ray_angles(a, table, n, min_spread, out):
    """``decode_approach`` and ``finger_angles`` of validated actions ``a (B, 4)`` into ``out (B, 3 + n)``:
    azimuth, elevation, roll, then the ``n`` finger angles (the thumb's 0 last)."""
    pi = math.pi
    el_scale = pi / 4.0 if table else pi / 2.0
    step = 2.0 * pi / n
    spread_w = 1.0 - min_spread
    half = (n - 2) / 2.0
    for b in range(a.shape[0]):
        out[b, 0] = pi * a[b, 0]
        out[b, 1] = (a[b, 1] + 1.0) * el_scale if table else a[b, 1] * el_scale
        out[b, 2] = pi * a[b, 2]
        s = (a[b, 3] + 1.0) / 2.0
        delta = (min_spread + spread_w * s) * step
        for j in range(n - 1):
            out[b, 3 + j] = pi + (j - half) * delta
        out[b, 3 + n - 1] = 0.0


@njit(cache=True)
def ray_frames(c, s, cb, sb, centre, t, radius, margin, d_w, o_t):
    """The approach frame and the ``n`` fingertip rays of each grasp from ``c = cos``, ``s = sin`` of
    :func:`ray_angles`'s output, ``cb``/``sb`` the cos / sin of the curl angles ``beta (n,)``, each grasp's
    object ``centre (B, 3)``, translation ``t (B, 3)`` and ``radius (B,)``: world directions ``d_w (B, n, 3)``
    and the origins minus the translation, ``o_t = o_w - t (B, n, 3)`` (:meth:`GeometricBackend.rays`)."""
    B, n = d_w.shape[0], d_w.shape[1]
    for b in range(B):
        caz, saz, cel, sel, cro, sro = c[b, 0], s[b, 0], c[b, 1], s[b, 1], c[b, 2], s[b, 2]
        # approach_frame: u = direction, e3 = -u
        e30 = -(cel * caz)
        e31 = -(cel * saz)
        e32 = -sel
        # ref = zref - sum(zref * e3) * e3, zref = (0, 0, 1)
        sz = ((0.0 + 0.0 * e30) + 0.0 * e31) + 1.0 * e32
        r0 = 0.0 - sz * e30
        r1 = 0.0 - sz * e31
        r2 = 1.0 - sz * e32
        nref = math.sqrt(((0.0 + r0 * r0) + r1 * r1) + r2 * r2)
        if nref > 1e-6:
            m = max(nref, 1e-12)
            b10, b11, b12 = r0 / m, r1 / m, r2 / m
        else:  # alt = horiz - sum(horiz * e3) * e3, horiz = sign(e3_z) (cos az, sin az, 0)
            sg = math.copysign(1.0, e32)
            h0, h1, h2 = caz * sg, saz * sg, 0.0 * sg
            sh = ((0.0 + h0 * e30) + h1 * e31) + h2 * e32
            a0 = h0 - sh * e30
            a1 = h1 - sh * e31
            a2 = h2 - sh * e32
            m = max(math.sqrt(((0.0 + a0 * a0) + a1 * a1) + a2 * a2), 1e-12)
            b10, b11, b12 = a0 / m, a1 / m, a2 / m
        b20 = e31 * b12 - e32 * b11
        b21 = e32 * b10 - e30 * b12
        b22 = e30 * b11 - e31 * b10
        e10 = cro * b10 + sro * b20
        e11 = cro * b11 + sro * b21
        e12 = cro * b12 + sro * b22
        e20 = e31 * e12 - e32 * e11
        e21 = e32 * e10 - e30 * e12
        e22 = e30 * e11 - e31 * e10
        R0 = margin * radius[b]
        for k in range(n):
            ca, sa = c[b, 3 + k], s[b, 3 + k]
            rad0 = ca * e10 + sa * e20
            rad1 = ca * e11 + sa * e21
            rad2 = ca * e12 + sa * e22
            mcb, sbk = -cb[k], sb[k]
            d0 = mcb * rad0 + sbk * e30
            d1 = mcb * rad1 + sbk * e31
            d2 = mcb * rad2 + sbk * e32
            d_w[b, k, 0], d_w[b, k, 1], d_w[b, k, 2] = d0, d1, d2
            o_t[b, k, 0] = (centre[b, 0] - R0 * d0) - t[b, 0]
            o_t[b, k, 1] = (centre[b, 1] - R0 * d1) - t[b, 1]
            o_t[b, k, 2] = (centre[b, 2] - R0 * d2) - t[b, 2]


@njit(cache=True)
def embree_inputs(o, d, kind, n_objects, origin, scale, order, starts, o32, d32):
    """Rays ``o``, ``d (m, 3)`` grouped by object ``kind (m,)`` (stable: each object's rays in input order):
    ``order (m,)`` the input row of each grouped ray, ``starts (n_objects + 1,)`` each object's first grouped
    ray, and trimesh's ``_EmbreeWrap.run`` inputs: ``o32 = float32((o - origin[k]) * scale[k])``,
    ``d32 = float32(d)``."""
    m = o.shape[0]
    starts[:] = 0
    for r in range(m):
        starts[kind[r] + 1] += 1
    for k in range(n_objects):
        starts[k + 1] += starts[k]
    fill = starts[:-1].copy()
    for r in range(m):
        k = kind[r]
        p = fill[k]
        fill[k] += 1
        order[p] = r
        for j in range(3):
            o32[p, j] = np.float32((o[r, j] - origin[k, j]) * scale[k])
            d32[p, j] = np.float32(d[r, j])


@njit(cache=True)
def hit_maths(tri_s, order, face_offset, kind, face_normals, face_v0, o, d, reach, n, L, Nf, ok):
    """``_cast``'s hit maths of every ray: ``tri_s`` the first-hit triangle of each grouped ray (-1: none),
    ``order`` its input row; fills the object-frame hit ``L (m, 3)``, the inward normal ``Nf (m, 3)`` (zero
    rows for misses) and ``ok (m,)`` (hit, in front, within ``reach[ray // n]``, not grazing)."""
    L[:] = 0.0
    Nf[:] = 0.0
    ok[:] = False
    for p in range(tri_s.shape[0]):
        h = tri_s[p]
        if h < 0:
            continue
        r = order[p]
        f = h + face_offset[kind[r]]
        fn0, fn1, fn2 = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
        d0, d1, d2 = d[r, 0], d[r, 1], d[r, 2]
        dn = (fn0 * d0 + fn2 * d2) + (fn1 * d1 + 0.0)  # einsum("ij,ij->i")
        safe = dn if abs(dn) > 1e-12 else 1e-12
        v0 = face_v0[f, 0] - o[r, 0]
        v1 = face_v0[f, 1] - o[r, 1]
        v2 = face_v0[f, 2] - o[r, 2]
        td = ((v0 * fn0 + v2 * fn2) + (v1 * fn1 + 0.0)) / safe
        L[r, 0] = o[r, 0] + td * d0
        L[r, 1] = o[r, 1] + td * d1
        L[r, 2] = o[r, 2] + td * d2
        sign = 1.0 if dn >= 0.0 else -1.0
        Nf[r, 0], Nf[r, 1], Nf[r, 2] = sign * fn0, sign * fn1, sign * fn2
        ok[r] = (td >= 0.0) and (td <= reach[r // n] + 1e-9) and (abs(dn) > 1e-12)


@njit(cache=True)
def hit_results(pw, nw, t, ok, table, table_z, clearance, n, contacts, normals, touched):
    """World hits ``pw + t`` and normals ``nw (B, n, 3)`` (the caller's ``matmul``s) of the ``ok`` rays above
    the table (``table``: ``z > table_z[grasp] + clearance``) into ``contacts``, ``normals``, ``touched``."""
    B = pw.shape[0]
    for b in range(B):
        for k in range(n):
            r = b * n + k
            if not ok[r]:
                continue
            x0 = pw[b, k, 0] + t[b, 0]
            x1 = pw[b, k, 1] + t[b, 1]
            x2 = pw[b, k, 2] + t[b, 2]
            if table and not (x2 > table_z[b] + clearance):
                continue
            contacts[b, k, 0], contacts[b, k, 1], contacts[b, k, 2] = x0, x1, x2
            normals[b, k, 0], normals[b, k, 1], normals[b, k, 2] = nw[b, k, 0], nw[b, k, 1], nw[b, k, 2]
            touched[b, k] = True
