"""z-finger scoring of n-finger grasps (paper, Algorithms 3 and 4) and incomplete grasps.

A model trained on z-finger grasps can score an ``n``-finger grasp (``n > z``) through its
z-subsets of contacts: every subset (Algorithm 3, ``k=None``) or ``k`` random distinct subsets
(Algorithm 4, the paper uses ``k = 4``). Each subset gives one grasp vector ``Phi_z``; the
:class:`~haptic_env.recognizers.updaters.BeliefUpdater` combines the rows of one update (product of
likelihoods for BC, sum of probabilities for IC).

Incomplete grasps: when only ``z`` of the ``n`` fingers touch, the grasp is scored by the z-finger
model (the models are routed by feature dimension, see :class:`~haptic_env.recognizers.recognizer.ModelBank`);
:func:`sample_finger_counts` draws ``z ~ p_n(z)`` for such experiments.
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations
from math import comb

import numpy as np

from haptic_env.grasp_features import feature_dim, normalize_scale, phi
from haptic_env.numbers import whole_number

__all__ = ["subsets", "subset_vectors", "grasp_vectors_for", "ZFingerUpdater", "sample_finger_counts", "check_subset_k",
           "check_min_fingers", "check_z_fingers", "DEFAULT_SUBSET_K"]


def subsets(n: int, z: int, k: int | None = None, rng: np.random.Generator | None = None) -> np.ndarray:
    """Contact-index subsets: all ``C(n, z)`` (``k=None``) or ``min(k, C(n, z))`` distinct random ones.

    Returns an ``(m, z)`` int array, rows sorted ascending (the lexicographic order for "all").
    """
    if not 2 <= z <= n:
        raise ValueError(f"need 2 <= z <= n, got z={z}, n={n}")
    total = comb(n, z)
    if k is None or k >= total:
        return _all_subsets(n, z).copy()
    if k < 1:
        raise ValueError(f"k must be >= 1 or None, got {k}")
    if rng is None:
        raise ValueError("random subsets (k given) need an rng (np.random.Generator)")
    if total <= 4096:
        pick = np.sort(rng.choice(total, size=k, replace=False))
        allsub = list(combinations(range(n), z))
        return np.array([allsub[i] for i in pick], dtype=np.int64)
    seen: set[tuple[int, ...]] = set()
    while len(seen) < k:
        seen.add(tuple(sorted(rng.choice(n, size=z, replace=False).tolist())))
    return np.array(sorted(seen), dtype=np.int64)


#: The subsets one Bayes step of z-subset scoring counts at most: the paper's ``k = 4`` (Algorithm 4); the one default
#: of ``HapticRecogConfig.subset_k`` and ``Belief(subset_k=)``.
DEFAULT_SUBSET_K = 4


def check_subset_k(k) -> int | None:
    """``k`` (the subsets one Bayes step counts at most, ``HapticRecogConfig.subset_k``) as an int, or None; a
    ``ValueError`` naming it unless it is None or an int >= 1."""
    if k is not None and (isinstance(k, bool) or not (isinstance(k, (int, np.integer)) and k >= 1)):
        raise ValueError(f"subset_k must be None or an int >= 1, got {k!r}")
    return None if k is None else int(k)


def check_z_fingers(z, n_fingers: int) -> int | None:
    """``z`` (the fewest touching fingers scored, ``HapticRecogConfig.z_fingers``) as an int, or None (complete grasps
    only); a ``ValueError`` naming it unless it is None or a whole number in ``[2, n_fingers)``."""
    if z is None:
        return None
    w = whole_number(z)
    if w is None or not 2 <= w < n_fingers:
        raise ValueError(f"z_fingers must be None or in [2, n_fingers={n_fingers}), got {z!r}")
    return w


def check_min_fingers(m, z: int | None, score_subsets: bool) -> int | None:
    """``m`` (the fewest touching fingers scored besides the ``z``-subsets, ``HapticRecogConfig.min_fingers``) as an
    int, or None; a ``ValueError`` naming it unless it is None, or an int in ``[2, z)`` with ``score_subsets`` (without
    subsets the same scoring is ``z_fingers=m``)."""
    if m is None:
        return None
    if not score_subsets:
        raise ValueError(f"min_fingers={m!r} needs score_subsets=True (without it, set z_fingers={m!r})")
    if isinstance(m, bool) or not (isinstance(m, (int, np.integer)) and z is not None and 2 <= m < z):
        raise ValueError(f"min_fingers must be None or an int in [2, z_fingers={z}), got {m!r}")
    return int(m)


def subset_weight(m: int, k: int | None) -> float:
    """The weight of the summed log-likelihood of one grasp's ``m`` z-subset rows in a Bayes step: ``k / m`` when more
    than ``k`` subsets are scored (they count as the paper's ``k`` random ones, Algorithm 4), else 1; ``k = None``: 1."""
    return k / m if k is not None and m > k else 1.0


@lru_cache(maxsize=None)
def _all_subsets(n: int, z: int) -> np.ndarray:
    out = np.array(list(combinations(range(n), z)), dtype=np.int64).reshape(-1, z)
    out.flags.writeable = False
    return out


def grasp_vectors_for(contacts, normals=None, *, normalize: bool = False, heights: bool = False,
                      normal_axis: str = "t2") -> tuple[np.ndarray, np.ndarray]:
    """``Phi`` of a batch ``(B, n, 3)`` (optionally scale-normalised; ``heights``: with the contacts' heights, the
    contacts in the support frame; ``normal_axis``: :func:`~haptic_env.grasp_features.phi`'s): ``(q (B, d),
    valid (B,))``."""
    P = np.asarray(contacts, dtype=np.float64)
    if normalize:
        P, _ = normalize_scale(P)
    f = phi(P, normals, heights=heights, normal_axis=normal_axis)
    if f.q.ndim == 2:
        return f.q, f.valid
    return np.atleast_2d(f.q), np.atleast_1d(f.valid)


def subset_vectors(contacts, normals=None, z: int | None = None, *, k: int | None = None,
                   rng: np.random.Generator | None = None, touched=None, normalize: bool = False,
                   heights: bool = False, normal_axis: str = "t2") -> np.ndarray:
    """Grasp vectors of the z-subsets of one grasp's touching contacts.

    Args:
        contacts: ``(n, 3)``; normals ``(n, 3)`` or None.
        z: subset size (default: all touching contacts, i.e. one row = the whole grasp).
        k: number of random subsets (None: all of them).
        touched: optional ``(n,)`` bool; only touching contacts are used (incomplete grasps).
        normalize: scale-normalise each subset (objects of unknown scale).
        heights: append the contacts' heights (contacts in the support frame; ``phi(heights=True)``).
        normal_axis: each normal's second angle (``phi(normal_axis=...)``).

    Returns:
        ``(m, feature_dim(z, normals, heights=heights))`` vectors of the non-degenerate subsets (``m`` may be 0).
    """
    P = np.asarray(contacts, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"contacts of one grasp must have shape (n, 3), got {P.shape}")
    N = None if normals is None else np.asarray(normals, dtype=np.float64)
    if touched is not None:
        t = np.asarray(touched, dtype=bool)
        if t.shape != (len(P),):
            raise ValueError(f"touched must have shape ({len(P)},), got {t.shape}")
        if not t.all():
            P = P[t]
            N = None if N is None else N[t]
    n = len(P)
    z = n if z is None else int(z)
    d = feature_dim(max(z, 2), N is not None, heights=heights, normal_axis=normal_axis)
    if n < z or z < 2:
        return np.zeros((0, d))
    if z == n:  # the whole grasp: one row (the common case: an env step)
        Pz, Nz = P[None], None if N is None else N[None]
    else:
        idx = subsets(n, z, k, rng)
        Pz, Nz = P[idx], None if N is None else N[idx]
    q, valid = grasp_vectors_for(Pz, Nz, normalize=normalize, heights=heights, normal_axis=normal_axis)
    return q if valid.all() else q[valid]


class ZFingerUpdater:
    """Wraps a belief updater whose models are z-finger models; updates from whole n-finger grasps."""

    def __init__(self, base, z: int | None = None, *, k: int | None = None, rng: np.random.Generator | None = None,
                 normalize: bool = False, heights: bool = False, normal_axis: str = "t2"):
        if k is not None and rng is None:
            raise ValueError("ZFingerUpdater with random subsets (k) needs an rng")
        self.base, self.z, self.k, self.rng, self.normalize, self.heights = base, z, k, rng, normalize, heights
        self.normal_axis = normal_axis

    def __getattr__(self, name):  # certainty, prediction, n_grasps, n_classes, ...
        if name == "base":  # not set yet (copy / pickle build the object before its __dict__)
            raise AttributeError(name)
        return getattr(self.base, name)

    @property
    def belief(self) -> np.ndarray:  # explicit: read on every env step (__getattr__ is the slow path)
        return self.base.belief

    @property
    def decided(self) -> bool:
        return self.base.decided

    def reset(self, prior=None) -> np.ndarray:
        return self.base.reset(prior)

    def update(self, q, **kw) -> np.ndarray:
        """Sub-grasp vectors ``(m, d_z)`` of one grasp (already computed); ``kw``: the base's (``weight`` of a
        Bayesian updater)."""
        return self.base.update(q, **kw)

    def update_scores(self, log_lik=None, proba=None, *, evidence=None) -> np.ndarray:
        """Precomputed scores of one grasp's rows (see ``BeliefUpdater.update_scores``)."""
        return self.base.update_scores(log_lik=log_lik, proba=proba, evidence=evidence)

    def update_grasp(self, contacts, normals=None, touched=None, *, evidence=None) -> np.ndarray:
        """One grasp from raw contacts ``(n, 3)`` (+ inward normals; with ``heights``, in the support frame) -> new
        belief ``(K,)``; ``evidence (r, K)``: the grasp's other log-likelihood rows (the touch pattern; Bayesian
        updaters)."""
        if evidence is not None:  # before the subsets are drawn: a bad evidence row changes nothing, the rng included
            from .updaters import BayesianUpdater, evidence_rows

            if not isinstance(self.base, BayesianUpdater):
                raise ValueError(f"{self.base.kind!r} takes no evidence rows (the touch pattern needs a Bayesian "
                                 "updater: 'bc-np', 'bc-ip')")
            evidence = evidence_rows(evidence, self.base.n_classes)
        Q = subset_vectors(contacts, normals, self.z, k=self.k, rng=self.rng, touched=touched, normalize=self.normalize,
                           heights=self.heights, normal_axis=self.normal_axis)
        return self.base.update(Q) if evidence is None else self.base.update(Q, evidence=evidence)


def sample_finger_counts(p_n, size: int, rng: np.random.Generator) -> np.ndarray:
    """Draw ``size`` finger counts from ``p_n``: a dict ``{z: prob}`` -> ``(size,)`` int array."""
    zs = np.array(sorted(p_n), dtype=np.int64)
    p = np.array([p_n[z] for z in zs], dtype=np.float64)
    if (zs < 2).any() or (p < 0).any() or not np.isfinite(p).all() or p.sum() <= 0:
        raise ValueError(f"p_n must map finger counts >= 2 to non-negative probabilities, got {p_n!r}")
    return rng.choice(zs, size=size, p=p / p.sum())
