r"""The touch-pattern likelihood :math:`P(\text{pattern} \mid \text{object})` of a hand's grasps.

Which of its ``n`` fingertips a hand touches an object with, when it closes along a random approach, depends
on the object: a flat plate stops two or three fingers of a 5-finger hand, an apple all five. A grasp's
*pattern* (the set of touching fingertips, known from the hand's joint torques like the contacts themselves)
is therefore evidence too, and it is there for every grasp, also for those whose contacts are too few to
score (fewer than ``z`` fingertips). The paper's method ignores it; BC-NP (and BC-IP, beside its classifier
prior) can multiply it in:

.. math:: \log b_{t}(c) = \log b_{t-1}(c) + \ell_{\mathrm{KDE}}(q_t \mid c) / T + w \log P(\text{pattern}_t \mid c)

:class:`TouchModel` is that categorical distribution, estimated from the hand's own grasps of each mesh (the
hand-matched training pool, :mod:`haptic_env.hand_grasps`; still meshes only) with add-``alpha`` (Laplace)
smoothing over the ``2 ** n`` patterns. The weight ``w`` is chosen on validation grasps
(``HapticRecogConfig.touch_weight``; the pattern and the contacts of one grasp are not independent given the
object, so ``w < 1`` is expected). Pure array functions, shapes documented:

``touch_patterns(touched (..., n)) -> (...,)``   the pattern code of each grasp (bit ``i``: fingertip ``i``)
``TouchModel.fit(touched (K, A, n), counts)``    the smoothed per-object pattern distribution
``TouchModel.log_likelihood(touched (m, n))``    ``(m, K)`` log-probabilities of the grasps' patterns
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from haptic_env.numbers import finite_number, positive_number

__all__ = ["MAX_TOUCH_FINGERS", "TOUCH_UPDATERS", "TouchModel", "check_touch_weight", "check_touch_updater",
           "touch_patterns"]

#: fingers a pattern table may have (``2 ** n`` patterns per object)
MAX_TOUCH_FINGERS = 16


def check_touch_weight(w) -> float:
    """``w`` as a float; a ``ValueError`` naming it unless it is a finite number >= 0 (0: the pattern is off)."""
    f = finite_number(w)
    if f is None or f < 0:
        raise ValueError(f"touch_weight must be a finite number >= 0, got {w!r}")
    return f


#: the updaters that weigh the touch pattern (the Bayesian ones: IC has no likelihood to add it to)
TOUCH_UPDATERS = ("bc-np", "bc-ip")


def check_touch_updater(weight: float, updater: str) -> None:
    """A ``ValueError`` naming both when a touch weight ``weight > 0`` comes with an updater that cannot weigh it."""
    if weight > 0 and updater not in TOUCH_UPDATERS:
        raise ValueError(f"touch_weight={weight} needs a Bayesian updater ('bc-np' or 'bc-ip'), got {updater!r}")


def touch_patterns(touched) -> np.ndarray:
    """Pattern codes ``(...,)`` int64 of boolean touch flags ``(..., n)``: bit ``i`` set when fingertip ``i`` touched.

    ``n`` must be in ``[1, MAX_TOUCH_FINGERS]``; the flags must be booleans (or 0/1)."""
    T = np.asarray(touched)
    if T.ndim < 1 or not (1 <= T.shape[-1] <= MAX_TOUCH_FINGERS):
        raise ValueError(f"touched must have shape (..., n) with 1 <= n <= {MAX_TOUCH_FINGERS}, got {T.shape}")
    if T.dtype != bool:
        if not np.isin(T, (0, 1)).all():
            raise ValueError("touched must hold booleans (or 0/1)")
        T = T.astype(bool)
    return T.astype(np.int64) @ (np.int64(1) << np.arange(T.shape[-1], dtype=np.int64))


@dataclass(frozen=True, eq=False)
class TouchModel:
    """Per-object pattern distribution: ``log_p (K, 2 ** n)``, each row a normalised log-distribution."""

    log_p: np.ndarray
    n_fingers: int

    @property
    def n_classes(self) -> int:
        return int(self.log_p.shape[0])

    @classmethod
    def fit(cls, touched, counts=None, *, alpha: float = 1.0) -> TouchModel:
        """From the touch flags ``touched (K, A, n)`` of ``A`` approaches per object (``counts (K,)``: object ``k``'s
        first ``counts[k]`` rows only, as :class:`~haptic_env.hand_grasps.HandGraspPool` pads them).

        ``alpha`` > 0: add-``alpha`` smoothing, so that a pattern never seen for an object is unlikely, not
        impossible (one odd grasp cannot rule the true object out)."""
        T = np.asarray(touched)
        if T.ndim != 3 or T.shape[0] < 1 or T.shape[1] < 1:
            raise ValueError(f"touched must have shape (K, A, n) with K, A >= 1, got {T.shape}")
        positive_number(alpha, "alpha")
        K, A, n = T.shape
        counts = np.full(K, A) if counts is None else np.asarray(counts)
        if counts.shape != (K,) or (counts < 1).any() or (counts > A).any():
            raise ValueError(f"counts must have shape ({K},) with values in [1, {A}], got {counts!r}")
        codes = touch_patterns(T)  # (K, A)
        table = np.stack([np.bincount(codes[k, : counts[k]], minlength=2 ** n) for k in range(K)]).astype(np.float64)
        table += alpha
        return cls(np.log(table / table.sum(axis=1, keepdims=True)), int(n))

    @classmethod
    def from_pool(cls, pool, *, alpha: float = 1.0) -> TouchModel:
        """:meth:`fit` on a :class:`~haptic_env.hand_grasps.HandGraspPool`."""
        return cls.fit(pool.touched, pool.approaches, alpha=alpha)

    def log_likelihood(self, touched) -> np.ndarray:
        """``(m, K)`` log-probabilities of the patterns of ``touched (m, n)`` (or one grasp ``(n,)``)."""
        T = np.asarray(touched)
        if T.shape[-1:] != (self.n_fingers,) or T.ndim > 2:
            raise ValueError(f"touched must have shape (m, {self.n_fingers}) or ({self.n_fingers},), got {T.shape}")
        return self.log_p[:, np.atleast_1d(touch_patterns(T))].T

    def accuracy(self, touched, labels) -> float:
        """One-shot accuracy of the pattern alone (argmax over objects) on grasps ``touched (m, n)`` of ``labels (m,)``."""
        return float(np.mean(self.log_likelihood(touched).argmax(axis=1) == np.asarray(labels)))
