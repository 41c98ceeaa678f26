r"""Force closure of frictional point contacts: can a grasp resist every external wrench?

Pure functions over batches of grasps, shapes as in :mod:`haptic_env.grasp_features`: ``contacts (B, n, 3)``
and inward unit ``normals (B, n, 3)`` (or ``(n, 3)`` each for one grasp).

A point contact with Coulomb friction ``mu`` can push along any direction of its friction cone. The cone
is linearised as a pyramid of ``edges`` unit-friction edges inscribed in it (so the test is conservative:
a grasp in closure with the pyramids is in closure with the cones). Each edge ``f`` at contact ``c`` gives a
primitive wrench ``(f, (c - centroid) x f / s)``; the grasp is in *force closure* when these ``n * edges``
wrenches positively span :math:`R^6`, i.e. the origin lies strictly inside their convex hull (Ferrari &
Canny 1992; Murray, Li & Sastry, *A Mathematical Introduction to Robotic Manipulation*, ch. 5). Neither the
torque's reference point nor its scale ``s`` (here the contacts' largest distance from their centroid, which
keeps the numbers unit-free) changes the answer.

:func:`force_closure` decides it exactly for the pyramids with Qhull (``scipy.spatial.ConvexHull``). Most
random grasps are not in closure (about 96 % of three random surface points on kit8 at ``mu = 0.5``), and a
vectorised search over the whole batch first looks for a direction ``d`` with ``d . w < 0`` for every
primitive wrench ``w`` (a perceptron on the wrenches): such a ``d`` proves that the origin is outside the
hull, so the search only ever rejects grasps that are not in closure, and every grasp it cannot reject goes to
Qhull. ``benchmarks/force_closure.py`` checks the answers against Qhull alone on every grasp and gives the
speed-up.

Degenerate grasps
    Coincident or collinear contacts, ``n <= 2`` (two point contacts cannot resist a torque about the line
    through them), ``mu = 0`` with fewer than 7 contacts, a zero normal: their wrenches do not span
    :math:`R^6`, so they are not in force closure (``False``, never an error).
"""

from __future__ import annotations

import numpy as np

__all__ = ["primitive_wrenches", "force_closure", "check_friction", "DEFAULT_EDGES"]

#: Edges of the pyramid that linearises each friction cone.
DEFAULT_EDGES = 4
#: Perceptron steps of the rejection search, and grasps per vectorised chunk (bounds its memory).
_SEARCH_STEPS = 200
_CHUNK = 50_000


def check_friction(value, name: str = "force_closure") -> float:
    """``value`` as a float if it is a friction coefficient a force-closure filter can use (finite, ``> 0``: with no
    friction no grasp of fewer than 7 contacts is in closure), else a ``ValueError`` naming ``name`` and the value."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float, np.number)) and np.isfinite(value) and value > 0
    if not ok:
        raise ValueError(f"{name} (a friction coefficient) must be a finite number > 0 or None, got {value!r}")
    return float(value)


def _check(contacts, normals, mu, edges) -> tuple[np.ndarray, np.ndarray, bool]:
    C = np.asarray(contacts, dtype=np.float64)
    N = np.asarray(normals, dtype=np.float64)
    single = C.ndim == 2
    if single:
        C, N = C[None], N[None]
    if C.ndim != 3 or C.shape[-1] != 3:
        raise ValueError(f"contacts must have shape (B, n, 3) or (n, 3), got {np.shape(contacts)}")
    if N.shape != C.shape:
        raise ValueError(f"normals must have the shape of contacts {C.shape}, got {np.shape(normals)}")
    if not (np.isfinite(mu) and mu >= 0):
        raise ValueError(f"mu (the friction coefficient) must be finite and >= 0, got {mu!r}")
    if int(edges) != edges or edges < 3:
        raise ValueError(f"edges must be an int >= 3, got {edges!r}")
    return C, N, single


def primitive_wrenches(contacts, normals, mu: float, edges: int = DEFAULT_EDGES) -> np.ndarray:
    """The primitive wrenches of the grasps' linearised friction cones.

    Args:
        contacts: ``(B, n, 3)`` contact points (any length unit).
        normals: ``(B, n, 3)`` inward contact normals (normalised here; a zero normal gives zero wrenches).
        mu: Coulomb friction coefficient, ``>= 0``.
        edges: edges of each friction pyramid, ``>= 3``.

    Returns:
        ``(B, n * edges, 6)``: force (unit normal component) and torque about the contacts' centroid divided
        by their largest distance from it, contact-major. ``(n * edges, 6)`` for a single grasp.
    """
    C, N, single = _check(contacts, normals, mu, edges)
    nn = np.linalg.norm(N, axis=-1, keepdims=True)
    N = np.divide(N, nn, out=np.zeros_like(N), where=nn > 0)
    # a tangent basis per normal: cross with the coordinate axis least aligned with it
    a = np.zeros_like(N)
    a[np.arange(N.shape[0])[:, None], np.arange(N.shape[1]), np.argmin(np.abs(N), axis=-1)] = 1.0
    t1 = np.cross(N, a)
    t1 /= np.maximum(np.linalg.norm(t1, axis=-1, keepdims=True), 1e-300)
    t2 = np.cross(N, t1)
    ang = 2.0 * np.pi * np.arange(int(edges)) / int(edges)
    f = N[..., None, :] + mu * (np.cos(ang)[:, None] * t1[..., None, :] + np.sin(ang)[:, None] * t2[..., None, :])
    f *= (nn > 0)[..., None, :]
    r = C - C.mean(axis=1, keepdims=True)
    s = np.linalg.norm(r, axis=-1).max(axis=1)
    r = np.divide(r, s[:, None, None], out=np.zeros_like(r), where=s[:, None, None] > 0)
    W = np.concatenate([f, np.cross(np.broadcast_to(r[..., None, :], f.shape), f)], axis=-1)
    W = W.reshape(C.shape[0], C.shape[1] * int(edges), 6)
    return W[0] if single else W


def _separable(W: np.ndarray) -> np.ndarray:
    """``(B,)`` True where a direction ``d`` with ``d . w < 0`` for every row of ``W[b] (m, 6)`` was found."""
    B = W.shape[0]
    rows = np.arange(B)
    d = -W.mean(axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True) + 1e-300
    found = np.zeros(B, dtype=bool)
    for _ in range(_SEARCH_STEPS):
        s = np.einsum("bmk,bk->bm", W, d)
        j = s.argmax(axis=1)
        found |= s[rows, j] < 0.0
        d -= 0.2 * W[rows, j]
        d /= np.linalg.norm(d, axis=1, keepdims=True) + 1e-300
    return found


def _hull_contains_origin(w: np.ndarray) -> bool:
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(w)
    except (QhullError, ValueError):  # fewer than 7 points or not full-dimensional: no positive span
        return False
    return bool(np.all(hull.equations[:, -1] < -1e-9))


def force_closure(contacts, normals, mu: float = 0.5, edges: int = DEFAULT_EDGES, *,
                  search: bool = True) -> np.ndarray | bool:
    """Whether each grasp is in force closure with friction ``mu`` (module docstring).

    Args:
        contacts: ``(B, n, 3)`` or ``(n, 3)``.
        normals: inward normals, the shape of ``contacts``.
        mu: Coulomb friction coefficient, ``>= 0``.
        edges: edges of each friction pyramid (inscribed in the cone), ``>= 3``.
        search: reject grasps with a separating direction before Qhull (the same answers, faster);
            ``False`` runs Qhull on every grasp (the reference the benchmark compares with).

    Returns:
        ``(B,)`` bool, or a bool for a single grasp.
    """
    W = primitive_wrenches(contacts, normals, mu, edges)
    single = W.ndim == 2
    W = W[None] if single else W
    out = np.zeros(W.shape[0], dtype=bool)
    for lo in range(0, W.shape[0], _CHUNK):
        Wc = W[lo:lo + _CHUNK]
        todo = np.flatnonzero(~_separable(Wc)) if search else np.arange(len(Wc))
        for i in todo:
            out[lo + i] = _hull_contains_origin(Wc[i])
    return bool(out[0]) if single else out
