r"""The grasp parameterisation :math:`\Phi_n` and scale normalisation.

Pure functions over batches of grasps. A grasp is ``n`` fingertip contact
points ``contacts`` of shape ``(B, n, 3)`` (or ``(n, 3)`` for a single grasp) and, optionally,
unit contact normals of the same shape. :func:`phi` maps it to a vector ``q`` that is invariant to
rigid motions of the grasp (Theorem 1 of Sintov & Ben-David) and to the order of the fingers.

Spatial grasps, ``n >= 3`` (:func:`phi`)
    The contacts span a polyhedron (their convex hull; a single triangle for ``n = 3``).

    1. ``t1`` is the largest-area hull facet and ``d = ab`` its longest edge, with ``a`` the
       endpoint of the larger interior angle of ``t1``: values ``|ab|, angle_a(t1), angle_b(t1)``.
    2. Each further facet, from the second on, is the largest-area hull facet that shares an edge with an
       already visited facet and adds one new contact; the second (``t2``) is thus the largest facet next to
       ``t1`` on any of its three edges, not necessarily on ``ab``, and adds the fourth contact ``d``. A facet
       adds its two interior angles at the shared edge (earlier contact of the chain first) and the signed
       dihedral angle (radians, in ``(-pi, pi]``) from the facet it is attached to. Exact ties are ranked by
       rounding, so there the vector may depend on the pose or the finger order: facets of exactly equal area
       (e.g. a square pyramid's side and base halves), and a ``t1`` with two equally long longest edges (an
       isosceles ``t1``: which is ``ab``). Both are measure-zero cases, but a symmetric grasp can meet them.
    3. Contacts that the facet walk of 2. does not reach are attached to ``ab`` of ``t1`` as a virtual facet with
       the same three values, taken in the order of their angle at ``a``: those that are no hull vertex (inside the
       polyhedron; possible on concave objects), and, rarely, hull vertices behind facets whose three contacts the
       walk had already visited (such a facet adds no contact, so the walk does not go on past it; measured in
       about 1 % of random grasps of 8-12 contacts on a sphere). Either way a function of the geometry alone.

    That is ``3 + 3 (n - 3) = 3n - 6`` values, and the contact order is that of the chain, never the
    input order. With normals, each contact (in chain order) adds its angle to the normal of
    ``t1`` and to the normal of the triangle ``(a, b, d)`` on ``ab`` and the chain's fourth contact (``t2`` itself
    when the second facet lies on ``ab``; for ``n = 3``: to ``t1``'s normal and to the direction of ``ab``):
    ``5n - 6`` values.

    ``normal_axis="ab"`` (not the paper's; the default ``"t2"`` is) takes each normal's second angle to ``ab``
    at every ``n``, as the paper does for ``n = 3``, so both angles are read in ``t1``'s own frame. With
    ``n >= 4`` that carries more: ``t2``'s normal depends on the fourth contact, and when the contacts lie
    nearly in a plane (a grasp across a flat face) it is nearly opposite ``t1``'s, so the two angles repeat
    each other. Measured on kit8 surface grasps, n = 4 with normals, 20,000 per object, one-shot: kNN 47.9 -> 57.8 %,
    KDE 46.0 -> 54.5 %, MLP 3x256 58.3 -> 68.4 % (``benchmarks/normal_axis.py``). Same length, ``5n - 6``.

    ``normal_axis="frame"`` (not the paper's) reads each normal in ``t1``'s whole frame: its angles to ``t1``'s
    normal, to ``ab`` and to the direction in ``t1``'s plane perpendicular to ``ab`` on the third contact's side,
    ``6n - 6`` values. The two angles of ``"ab"`` (and the paper's at ``n = 3``) leave out on which side of the plane
    through ``ab`` and ``t1``'s normal a normal points (towards the third contact or away from it): a grasp and the
    same contacts with each normal mirrored in that plane get one vector. A unit vector needs three angles to be read
    without that loss and without a jump (an azimuth wraps round). One-shot on kit8 surface grasps, 20,000 per
    object: see ``benchmarks/normal_axis.py``.

Two contacts, ``n = 2``
    The distance; with normals also each normal's angle to the line between the contacts and the
    signed twist between the normals about that line: ``1`` or ``4`` (``= 5n - 6``) values.

Heights above the support (``phi(..., heights=True)``)
    An object resting on a table in one of its resting poses, turned only about the vertical, keeps the
    heights of its surface points above the table. With the contacts given in the *support frame*
    (z up, ``z = 0`` on the table top), ``heights=True`` appends each contact's height ``z`` in chain
    order (two contacts: Phi_2's order, the lower first where the normals' angles do not order them, since
    2026-12-07): ``n`` more values. That vector is invariant to turns about the vertical and to horizontal
    moves, not to tilts, so it only suits objects that keep their resting pose (the envs' ``"table-yaw"``
    poses); a robot knows its table, so the heights are sensed as the contacts are (forward kinematics).

Planar grasps (:func:`phi_planar`, ``(B, n, 2)``)
    The polygon of the contacts sorted counter-clockwise about their centroid; starting at the
    longest counter-clockwise edge ``v0 v1``: ``|v0 v1|``, then for each further vertex the signed
    interior angle at the previous vertex and the next edge length: ``2n - 3`` values; normals add
    their signed angle to ``v0 v1``: ``3n - 3``. Ties are ranked by rounding, as in 3-D: two equally long
    longest edges (a kite, an isosceles triangle) and a contact exactly at the centroid (no angle about it).

Degenerate grasps
    Coincident contacts, collinear contacts, and (for ``n >= 4``) coplanar contacts have no
    polyhedron. In a batch they are reported in ``valid`` (their ``q`` row is all zeros, never NaN);
    with ``strict=True`` a :class:`DegenerateGraspError` names the first bad grasp and why.
    Non-finite input is always an error, and so are complex contacts or normals.

Range of sizes
    Contacts are expected at robot scales (metres or millimetres). A grasp whose diameter (its largest contact
    distance) lies outside ``[1e-50, 1e50]`` (:data:`GRASP_SIZE_RANGE`) is flagged like a degenerate one (reason 4,
    "grasp size out of range", or 1 below ~1e-154 where its distances underflow to 0; :func:`surface_area` gives it
    0): squared lengths and products of lengths underflow or overflow not far beyond (unflagged, a grasp 1e80 across
    got angles of pi/2, one 1e-160 across was "collinear", one 1e155 across a length of inf). The coplanarity test
    of ``n >= 4`` contacts reads positions relative to the origin: a flat grasp ~1e10 diameters from the origin can
    pass as a polyhedron (the coordinates' own rounding, ~1e-6 of its size there, exceeds ``tol``).

Implementation
    The chain of ``n >= 3`` contacts and the surface area run in the compiled (numba) kernels of
    :mod:`haptic_env._phi_kernels`, one grasp at a time, at every batch size; this module validates
    the input, raises the errors and triangulates planar hull faces of >= 4 contacts (Qhull,
    :func:`_canonical_hull_triangles`) for the kernels. ``n = 2`` runs in two compiled passes around one
    NumPy ``arctan2`` (:func:`_phi2_rows`, the same bits as the NumPy code it replaced); planar grasps are NumPy. The
    vectorised NumPy chain that served large batches before is a test oracle now
    (``tests/phi_numpy.py``; ``benchmarks/bench_phi.py`` compares the two).

Scale (:func:`normalize_scale`)
    Contacts are divided by ``A = sqrt(total surface area of the grasp polyhedron)``; angles are
    unchanged and lengths become scale-free (Theorem 2).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations
from typing import NamedTuple

import numpy as np

from .numbers import checked_flag, positive_number, whole_number

__all__ = [
    "DegenerateGraspError",
    "GraspFeatures",
    "DEGENERACY_REASONS",
    "GRASP_SIZE_RANGE",
    "feature_dim",
    "phi",
    "phi_planar",
    "surface_area",
    "normalize_scale",
    "NORMAL_AXES",
    "NORMAL_AXIS_WORDS",
    "check_normal_axis",
    "normals_code",
]

#: Relative tolerance for degeneracy tests (lengths relative to the grasp's diameter).
DEFAULT_TOL = 1e-7

#: Values of ``phi(normal_axis=...)``: each normal's second angle to t2's normal (the paper's) or to the edge ab, or
#: (``"frame"``) its angles to all three axes of t1's frame.
NORMAL_AXES = ("t2", "ab", "frame")
#: Each value of :data:`NORMAL_AXES` in words, for reports.
NORMAL_AXIS_WORDS = {
    "t2": "each normal's angles to t1's normal and to t2's (n >= 4; at n = 3 to the edge ab), the paper's",
    "ab": "each normal's second angle to the edge ab of t1, not to t2's normal (n >= 4; n = 3 is the same)",
    "frame": "each normal's angles to all three axes of t1's frame (its normal, the edge ab and the in-plane "
             "direction towards the third contact): 6n - 6 values",
}

#: Codes of :attr:`GraspFeatures.reason`.
DEGENERACY_REASONS = {0: "ok", 1: "coincident contacts", 2: "collinear contacts", 3: "coplanar contacts",
                      4: "grasp size out of range"}

#: ``(lo, hi)``: the diameters (largest contact distance) of a grasp that :func:`phi` reads; outside it (and above the
#: coincident limit 1e-300) a grasp gets reason 4 (the kernels' ``SIZE_MIN``, ``SIZE_MAX``; see the module docstring).
GRASP_SIZE_RANGE = (1e-50, 1e50)



class DegenerateGraspError(ValueError):
    """A grasp whose contacts span no polyhedron (coincident, collinear or coplanar), or whose size is out of range."""


class GraspFeatures(NamedTuple):
    """Result of :func:`phi` for a batch of ``B`` grasps of ``n`` contacts."""

    q: np.ndarray  #: ``(B, d)`` float64 grasp vectors; all-zero rows where not ``valid``
    valid: np.ndarray  #: ``(B,)`` bool, False for degenerate grasps
    order: np.ndarray  #: ``(B, n)`` int, input index of the contact at each chain position
    reason: np.ndarray  #: ``(B,)`` int8 code into :data:`DEGENERACY_REASONS`


def feature_dim(n: int, normals: bool = False, dim: int = 3, heights: bool = False, normal_axis: str = "t2") -> int:
    """Length of :math:`\\Phi_n` for ``n`` contacts in ``dim`` (2 or 3) dimensions; ``heights``: plus the ``n``
    contact heights (:func:`phi` with ``heights=True``, 3-d only); ``normal_axis="frame"``: with normals and
    ``n >= 3``, three angles per normal instead of two.

    ``n`` is a whole number ``>= 2`` (as :func:`phi` takes), ``dim`` 2 or 3 (whole numbers, numpy integers too) and
    ``normal_axis`` one of :data:`NORMAL_AXES` whatever ``n`` and ``normals``; else a ``ValueError`` naming it."""
    d = whole_number(dim)
    if d not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    m = whole_number(n)
    if m is None or m < 2:
        raise ValueError(f"a grasp needs at least 2 contacts: n must be a whole number >= 2, got n={n!r}")
    check_normal_axis(normal_axis)
    normals, heights = checked_flag(normals, "normals"), checked_flag(heights, "heights")  # "no" was read as True
    if heights and d != 3:
        raise ValueError("contact heights need 3-d contacts (dim=3)")
    return _feature_dim(m, normals, d, heights, normal_axis)


def _feature_dim(n: int, normals, dim: int, heights, normal_axis: str) -> int:
    """:func:`feature_dim` of checked arguments (phi's own calls: no second check per call)."""
    if heights:
        return _feature_dim(n, normals, dim, False, normal_axis) + n
    if n == 2:
        return (4 if dim == 3 else 3) if normals else 1
    if dim == 3:
        if normals and normal_axis == "frame":
            return 6 * n - 6
        return 5 * n - 6 if normals else 3 * n - 6
    return 3 * n - 3 if normals else 2 * n - 3


# --------------------------------------------------------------------------------------- helpers
def _check_tol(tol) -> float:
    """``tol`` as a Python float if it is a finite real number ``> 0`` (numpy scalars too), else a ``ValueError``
    naming it. Not 0: the degeneracy tests and the grouping of a planar hull face's facets would become exact
    comparisons that rounding decides (a rotated square "valid", its canonical fan lost)."""
    return positive_number(tol, "tol")


def _real(x, name: str) -> np.ndarray:
    """``x`` as an array (as given if it is one), refused with a ``ValueError`` naming ``name`` and the dtype if it
    holds no real numbers (complex, strings, dates): a dtype check, no pass over the data."""
    a = x if isinstance(x, np.ndarray) else np.asarray(x)
    if a.dtype.kind not in "biufO":
        raise ValueError(f"{name} must be real numbers, got an array of dtype {a.dtype}")
    return a


def _float64(x, name: str) -> np.ndarray:
    """``x`` (:func:`_real`) as contiguous float64; an object array of what is not a real number (complex, None) is
    a ``ValueError`` naming ``name`` (a ``TypeError`` of ``float()`` before)."""
    a = _real(x, name)
    try:
        return np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be real numbers, got {x!r}") from None


def _batched(contacts, normals) -> tuple[np.ndarray, np.ndarray | None, bool]:
    """Contiguous float64 ``(P, N, single)``, a single grasp given a batch axis; no checks but the dtype's
    (:func:`_real`)."""
    P = _float64(contacts, "contacts")
    single = P.ndim == 2
    N = None if normals is None else _float64(normals, "normals")
    if single:
        P, N = P[None], None if N is None else N[None]
    return P, N, single


def _as_batch(contacts, normals, dim: int) -> tuple[np.ndarray, np.ndarray | None, bool]:
    P, N, single = _batched(contacts, normals)
    if P.ndim != 3 or P.shape[-1] != dim:
        raise ValueError(f"contacts must have shape (B, n, {dim}) or (n, {dim}), got {np.shape(contacts)}")
    if P.shape[1] < 2:
        raise ValueError(f"a grasp needs at least 2 contacts, got n={P.shape[1]}")
    bad = ~np.isfinite(P).all(axis=(1, 2))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"contacts of grasp {i} are not finite: {P[i].tolist()}")
    if N is not None:
        if N.shape != P.shape:  # the shapes as given (a single grasp's were reported with its batch axis)
            raise ValueError(f"normals must have the shape of contacts {np.shape(contacts)}, got {np.shape(normals)}")
        norm = _norm(N)
        bad = ~(np.isfinite(norm) & (norm > 1e-12))
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ValueError(f"normal {j} of grasp {i} is zero, shorter than 1e-12, longer than about 1e154 or not "
                             f"finite: {N[i, j].tolist()}")
        N = N / norm[..., None]
    return P, N, single


def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (faster than ``np.linalg.norm`` for small last axes)."""
    return np.sqrt(np.einsum("...k,...k->...", v, v))


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Dot product over the last axis (einsum for equal shapes, broadcasting product otherwise)."""
    if u.shape == v.shape:
        return np.einsum("...k,...k->...", u, v)
    return (u * v).sum(-1)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """3-D cross product over the last axis (faster than ``np.cross`` on large batches)."""
    u0, u1, u2 = u[..., 0], u[..., 1], u[..., 2]
    v0, v1, v2 = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    n = _norm(v)[..., None]
    return v / np.where(n > 0, n, 1.0)


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unsigned angle between vectors (last axis), stable near 0 and pi."""
    if u.shape[-1] == 2:
        cr = np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
    else:
        cr = _norm(_cross(u, v))
    return np.arctan2(cr, _dot(u, v))


@lru_cache(maxsize=None)
def _topology(n: int):
    """Static index tables: triangles (T,3), their edges (T,3) and a (n,n,n) triangle lookup.

    Cached and shared by every caller, so the arrays are read-only."""
    tri = np.array(list(combinations(range(n), 3)), dtype=np.int64)
    edges = list(combinations(range(n), 2))
    eidx = {e: i for i, e in enumerate(edges)}
    # edge opposite triangle position 0, 1, 2
    tri_edges = np.array([[eidx[(j, k)], eidx[(i, k)], eidx[(i, j)]] for i, j, k in tri], dtype=np.int64)
    lut = -np.ones((n, n, n), dtype=np.int64)
    for t, (i, j, k) in enumerate(tri):
        for p in ((i, j, k), (i, k, j), (j, i, k), (j, k, i), (k, i, j), (k, j, i)):
            lut[p] = t
    for a in (tri, tri_edges, lut):
        a.flags.writeable = False
    return tri, tri_edges, lut, len(edges)


def _canonical_hull_triangles(pts: np.ndarray, tol: float) -> np.ndarray | None:
    """Hull triangles of one grasp ``(n, 3)`` whose planar faces of >= 4 contacts are fanned canonically.

    Qhull's triangulation of a planar face depends on the input order. Here each planar face is
    fanned from its vertex with the largest sum of distances to all contacts (a rigid- and
    permutation-invariant key), around the face in the direction of its outward normal, so the
    triangulation, and hence the chain, is a function of the geometry alone. A planar face is a set of facets linked
    pairwise by unit normals within ``1e3 * tol`` of each other (Euclidean) and offsets within ``1e3 * tol`` times
    the grasp's largest contact distance: a test and a grouping that no pose or finger order changes (since
    2026-12-07; before, the normals were compared per axis, the offsets against the bounding box's diagonal, and
    the grouping followed Qhull's facet order).
    """
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import ConvexHull

    try:
        hull = ConvexHull(pts - pts.mean(0))  # centred: the facets' offsets are lengths within the grasp
    except Exception:
        return None
    dist = _norm(pts[:, None] - pts[None])
    scale, key = dist.max(), dist.sum(1)  # the grasp's size and each contact's key: neither depends on the pose
    eq = hull.equations  # (F, 4): outward unit normal, offset from the centroid
    # one plane: facets linked by unit normals alike (their distance, not per axis, which turned with the grasp) and
    # offsets alike relative to the size; the linked sets (connected components, not a first-come grouping, which
    # followed Qhull's facet order and so the contacts' order) are the planar faces
    alike = ((_norm(eq[:, None, :3] - eq[None, :, :3]) <= 1e3 * tol)
             & (np.abs(eq[:, None, 3] - eq[None, :, 3]) <= 1e3 * tol * scale))
    _, label = connected_components(alike, directed=False)
    groups = [np.flatnonzero(label == c) for c in np.unique(label)]
    out = []
    for g in groups:
        verts = np.unique(hull.simplices[g])
        if len(verts) == 3:
            out.append(verts)
            continue
        nrm = eq[g[0], :3]
        c = pts[verts].mean(0)
        u = _unit(pts[verts[0]] - c)
        v = np.cross(nrm, u)
        rel = pts[verts] - c
        ring = verts[np.argsort(np.arctan2(rel @ v, rel @ u))]
        start = int(np.argmax(key[ring]))
        ring = np.roll(ring, -start)
        out.extend([ring[0], ring[j], ring[j + 1]] for j in range(1, len(ring) - 1))
    return np.array(out, dtype=np.int64)


# ------------------------------------------------------------------------------------------ phi
def phi(contacts, normals=None, *, strict: bool = False, tol: float = DEFAULT_TOL,
        heights: bool = False, normal_axis: str = "t2") -> GraspFeatures:
    r"""Grasp vectors :math:`q = \Phi_n(P[, N])` of a batch of spatial grasps.

    Args:
        contacts: ``(B, n, 3)`` or ``(n, 3)`` contact points, ``n >= 2``.
        normals: optional contact normals of the same shape (need not be unit length; each longer than 1e-12 and
            short enough to square, below about 1e154).
        strict: raise :class:`DegenerateGraspError` for the first degenerate grasp instead of
            flagging it in ``valid``.
        tol: relative tolerance of the degeneracy tests, a finite number ``> 0`` (``ValueError`` otherwise).
        heights: append the contacts' heights ``z`` in chain order (the contacts must be in the support
            frame; see the module docstring).
        normal_axis: with normals and ``n >= 4``, each normal's second angle is to ``t2``'s normal (``"t2"``, the
            paper's) or to the edge ``ab`` (``"ab"``; ``n <= 3`` is the same either way); ``"frame"`` (``n >= 3``)
            adds a third angle per normal. See the module docstring.

    Returns:
        :class:`GraspFeatures` with ``q`` of shape ``(B, feature_dim(n, normals, heights=heights,
        normal_axis=normal_axis))``
        (``(d,)`` etc. for a single grasp). Contacts are expected at robot scales: a grasp whose diameter is
        outside :data:`GRASP_SIZE_RANGE` is flagged with reason 4 (see the module docstring).

    Raises:
        ValueError: a bad ``tol`` or ``normal_axis``, complex or non-finite contacts or normals, bad shapes.
    """
    tol = _check_tol(tol)
    check_normal_axis(normal_axis)
    strict, heights = checked_flag(strict, "strict"), checked_flag(heights, "heights")  # "no" was read as True
    P, N, single = _batched(contacts, normals)
    if _compiled_shapes(P, N):
        q, valid, order, reason = _phi_rows(P, N, tol, normal_axis)
    elif _compiled_shapes(P, N, n_min=2):
        q, valid, order, reason = _phi2_rows(P, N)
    else:  # bad shapes (not (B, n >= 2, 3), or normals of another shape): _as_batch raises the precise error
        _as_batch(contacts, normals, 3)
        raise ValueError(f"contacts must have shape (B, n, 3) or (n, 3), got {np.shape(contacts)}")  # pragma: no cover
    if strict and not valid.all():
        i = int(np.flatnonzero(~valid)[0])
        raise DegenerateGraspError(
            f"grasp {i} is degenerate ({DEGENERACY_REASONS[int(reason[i])]}): contacts {P[i].tolist()}"
        )
    if heights:
        if P.shape[1] == 2:  # Phi_2 orders the contacts by their normals' angles; where none do (no normals, or
            tie = np.ones(len(q), bool) if N is None else q[:, 1] == q[:, 2]  # equal angles) the lower goes first
            order[tie] = np.argsort(P[tie, :, 2], axis=1, kind="stable")
        h = np.take_along_axis(P[:, :, 2], order, axis=1)
        q = np.concatenate([q, np.where(valid[:, None], h, 0.0)], axis=1)
    if single:
        return GraspFeatures(q[0], valid[0], order[0], reason[0])
    return GraspFeatures(q, valid, order, reason)


def _phi2_rows(P: np.ndarray, N: np.ndarray | None):
    """``(q, valid, order, reason)`` of a batch ``P (B, 2, 3)`` through the compiled two-pass kernel (its NumPy
    ``arctan2`` in between; :mod:`haptic_env._phi_kernels`)."""
    B = P.shape[0]
    k = _kernels()
    has_normals = N is not None
    N = P if N is None else N
    dist = np.empty(B)
    ys = np.zeros((B, 3))
    xs = np.zeros((B, 3))
    if k.phi2_prepare(P, N, has_normals, dist, ys, xs) == k.BAD_INPUT:
        _raise_bad_input(P, N if has_normals else None)
    q = np.empty((B, 4 if has_normals else 1))
    order = np.empty((B, 2), dtype=np.int64)
    reason = np.empty(B, dtype=np.int8)
    valid = np.empty(B, dtype=bool)
    k.phi2_finish(dist, np.arctan2(ys, xs) if has_normals else ys, has_normals, q, order, reason, valid)
    return q, valid, order, reason


def _compiled_shapes(P: np.ndarray, N: np.ndarray | None, n_min: int = 3) -> bool:
    """Whether the compiled kernels take this batch: ``(B, n, 3)`` contacts with ``n >= n_min`` and normals of
    the same shape (else :func:`_as_batch` raises; ``n = 2`` goes to :func:`_phi2_rows`)."""
    return P.ndim == 3 and P.shape[2] == 3 and P.shape[1] >= n_min and (N is None or N.shape == P.shape)


@lru_cache(maxsize=None)
def _kernels():
    """The compiled kernels module (imported on first use: numba costs ~0.3 s to import)."""
    from haptic_env import _phi_kernels

    return _phi_kernels


def _raise_bad_input(P: np.ndarray, N: np.ndarray | None) -> None:
    """The precise error of a batch the kernels rejected (non-finite contacts, a zero or non-finite normal)."""
    _as_batch(P, N, 3)
    raise ValueError("contacts or normals are not finite")  # pragma: no cover - _as_batch names the grasp


def _canonical_hull(P: np.ndarray, tol: float) -> np.ndarray | None:
    """``hull (T,)`` over :func:`_topology` ``(n)``'s triangles of one grasp with a planar hull face of >= 4
    contacts (:data:`haptic_env._phi_kernels.AMBIGUOUS`), from :func:`_canonical_hull_triangles`; None if
    Qhull fails (a grasp already near-flat: coplanar)."""
    tri, _, lut, _ = _topology(P.shape[0])
    tris = _canonical_hull_triangles(P, tol)
    if tris is None:  # pragma: no cover - qhull failure on an input already near-flat
        return None
    hull = np.zeros(len(tri), dtype=bool)
    hull[lut[tris[:, 0], tris[:, 1], tris[:, 2]]] = True
    return hull


def check_normal_axis(normal_axis) -> str:
    """``normal_axis`` if it is one of :data:`NORMAL_AXES`, else a ``ValueError`` naming it."""
    if normal_axis not in NORMAL_AXES:
        raise ValueError(f"normal_axis must be one of {NORMAL_AXES}, got {normal_axis!r}")
    return normal_axis


def normals_code(has_normals: bool, normal_axis: str = "t2") -> int:
    """The kernels' ``has_normals`` argument: 0 (none), 1 (the paper's second angle, to t2's normal), 2 (to ab) or 3
    (three angles, to t1's frame)."""
    return 0 if not has_normals else {"t2": 1, "ab": 2, "frame": 3}[check_normal_axis(normal_axis)]


def _phi_rows(P: np.ndarray, N: np.ndarray | None, tol: float, normal_axis: str = "t2"):
    """``(q, valid, order, reason)`` of a batch ``P (B, n, 3)``, ``n >= 3``, through the compiled kernels."""
    B, n, _ = P.shape
    tri, tri_edges, _, n_edges = _topology(n)
    q = np.zeros((B, _feature_dim(n, N is not None, 3, False, normal_axis)))
    order = np.empty((B, n), dtype=np.int64)
    reason = np.empty(B, dtype=np.int8)
    valid = np.empty(B, dtype=bool)
    k = _kernels()
    has_normals = normals_code(N is not None, normal_axis)
    N = P if N is None else N
    n_ambiguous = k.phi_rows(P, N, has_normals, tri, tri_edges, n_edges, tol, q, order, reason, valid)
    if n_ambiguous == k.BAD_INPUT:
        _raise_bad_input(P, N if has_normals else None)
    if n_ambiguous:  # planar hull faces of >= 4 contacts: the chain over their canonical triangulation
        Nu = np.empty((n, 3))
        for i in np.flatnonzero(reason == k.AMBIGUOUS):
            hull = _canonical_hull(P[i], tol)
            if hull is None:  # pragma: no cover
                reason[i] = 3
                continue
            k.phi_on_hull(P[i], N[i], has_normals, tri, tri_edges, n_edges, hull, q[i], order[i], Nu)
            reason[i], valid[i] = 0, True
    return q, valid, order, reason


# ----------------------------------------------------------------------------------- planar phi
@np.errstate(over="ignore", invalid="ignore")  # sizes out of range overflow to inf / nan: flagged (reason 4), zeroed
def phi_planar(contacts, normals=None, *, strict: bool = False, tol: float = DEFAULT_TOL) -> GraspFeatures:
    """Planar sibling of :func:`phi` for ``(B, n, 2)`` contacts (``2n - 3`` values, ``3n - 3`` with normals); ``tol``
    a finite number ``> 0``, sizes out of :data:`GRASP_SIZE_RANGE` flagged as in :func:`phi`."""
    tol = _check_tol(tol)
    P, N, single = _as_batch(contacts, normals, 2)
    B, n, _ = P.shape
    rows = np.arange(B)
    dist = np.linalg.norm(P[:, :, None] - P[:, None], axis=-1)
    scale = dist.max(axis=(1, 2))
    iu = np.triu_indices(n, 1)
    reason = np.zeros(B, dtype=np.int8)
    reason[dist[:, iu[0], iu[1]].min(axis=1) <= tol * np.maximum(scale, 1e-300)] = 1
    reason[~((scale >= GRASP_SIZE_RANGE[0]) & (scale <= GRASP_SIZE_RANGE[1]))] = 4
    reason[scale <= 1e-300] = 1
    if n == 2:
        v = P[:, 1] - P[:, 0]
        vals = [dist[:, 0, 1]]
        order = np.tile(np.arange(2), (B, 1))
        if N is not None:
            a0 = _signed_angle2(v, N[:, 0])
            a1 = _signed_angle2(-v, N[:, 1])
            swap = np.abs(a1) > np.abs(a0)
            order[swap] = [1, 0]
            vals += [np.where(swap, a1, a0), np.where(swap, a0, a1)]
        q = np.stack(vals, 1)
    else:
        c = P.mean(axis=1, keepdims=True)
        r = P - c
        # collinear: all cross products of edges from contact 0 vanish
        e0 = P[:, 1:] - P[:, :1]
        cr = e0[:, :, None, 0] * e0[:, None, :, 1] - e0[:, :, None, 1] * e0[:, None, :, 0]
        flat = np.abs(cr).max(axis=(1, 2)) <= tol * np.maximum(scale, 1e-300) ** 2
        reason[(reason == 0) & flat] = 2
        ccw = np.argsort(np.arctan2(r[..., 1], r[..., 0]), axis=1, kind="stable")
        V = P[rows[:, None], ccw]
        nxt = np.roll(V, -1, axis=1)
        elen = np.linalg.norm(nxt - V, axis=-1)
        start = np.argmax(elen, axis=1)
        idx = (start[:, None] + np.arange(n)[None]) % n
        order = ccw[rows[:, None], idx]
        V = P[rows[:, None], order]
        vals = [np.linalg.norm(V[:, 1] - V[:, 0], axis=-1)]
        for k in range(2, n):
            vals.append(_signed_angle2(V[:, k] - V[:, k - 1], V[:, k - 2] - V[:, k - 1]) % (2 * np.pi))
            vals.append(np.linalg.norm(V[:, k] - V[:, k - 1], axis=-1))
        if N is not None:
            e = V[:, 1] - V[:, 0]
            No = N[rows[:, None], order]
            vals.extend(_signed_angle2(e[:, None], No).T)
        q = np.stack(vals, axis=1)
    valid = reason == 0
    q = np.where(valid[:, None], q, 0.0)
    if strict and not valid.all():
        i = int(np.flatnonzero(~valid)[0])
        raise DegenerateGraspError(
            f"planar grasp {i} is degenerate ({DEGENERACY_REASONS[int(reason[i])]}): contacts {P[i].tolist()}"
        )
    if single:
        return GraspFeatures(q[0], valid[0], order[0], reason[0])
    return GraspFeatures(q, valid, order, reason)


def _signed_angle2(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Signed angle from 2-D vector ``u`` to ``v`` in ``(-pi, pi]``."""
    return np.arctan2(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0], np.sum(u * v, -1))


# ------------------------------------------------------------------------------------- scaling
def surface_area(contacts, *, tol: float = DEFAULT_TOL) -> np.ndarray:
    """Total surface area of each grasp polyhedron, ``(B,)`` (``(,)`` for one grasp).

    ``n = 2``: the squared distance (so that scaling divides it to 1); ``n = 3``: the triangle's
    area; ``n >= 4``: the area of the convex hull. Degenerate grasps get 0: those :func:`phi` flags (at the same
    ``tol``, a finite number ``> 0``), sizes out of range included.
    """
    tol = _check_tol(tol)
    P, _, single = _batched(contacts, None)
    if not _compiled_shapes(P, None):  # n = 2, or bad shapes (_as_batch raises)
        P, _, single = _as_batch(contacts, None, 3)
        with np.errstate(over="ignore"):  # a distance out of range: inf, then 0 below
            out = np.sum((P[:, 1] - P[:, 0]) ** 2, -1)
        dist = np.sqrt(out)  # phi's distance, bit for bit (the kernel adds in np.sum's order)
        out = np.where((dist >= GRASP_SIZE_RANGE[0]) & (dist <= GRASP_SIZE_RANGE[1]), out, 0.0)
        return out[0] if single else out
    B, n, _ = P.shape
    tri = _topology(n)[0]
    out, status = np.empty(B), np.empty(B, dtype=np.int64)
    k = _kernels()
    if k.surface_area_rows(P, tri, tol, out, status):
        _raise_bad_input(P, None)
    for i in np.flatnonzero(status == k.AMBIGUOUS):  # planar hull faces: their canonical triangulation
        hull = _canonical_hull(P[i], tol)
        if hull is None:  # pragma: no cover
            status[i] = 3
            continue
        a, b, c = P[i, tri[:, 0]], P[i, tri[:, 1]], P[i, tri[:, 2]]
        out[i] = np.where(hull, 0.5 * _norm(_cross(b - a, c - a)), 0.0).sum()
        status[i] = 0
    out = np.where(status == 0, out, 0.0)  # phi's verdict at every n (n = 3 too: near-coincident contacts get 0)
    return out[0] if single else out


def normalize_scale(contacts, *, tol: float = DEFAULT_TOL) -> tuple[np.ndarray, np.ndarray]:
    """Divide contacts by ``sqrt(surface_area)``: returns ``(scaled contacts, sqrt(area))``.

    Degenerate grasps (zero area: every grasp :func:`phi` flags at the same ``tol``) are returned unscaled with
    factor 1, and stay flagged by :func:`phi`. Normals are unaffected by scaling and need no change.
    """
    tol = _check_tol(tol)
    P = np.asarray(_real(contacts, "contacts"), dtype=np.float64)
    s = np.sqrt(surface_area(P, tol=tol))
    s = np.where(s > 0, s, 1.0)
    return P / np.asarray(s)[..., None, None], s
