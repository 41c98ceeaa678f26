r"""Belief updaters: turn a sequence of grasps into a belief over the ``K`` objects.

All updaters share one interface (:class:`BeliefUpdater`)::

    b = u.reset(prior=None)     # (K,) initial belief
    b = u.update(q)             # q: (d,) one grasp vector, or (m, d) sub-grasp vectors of ONE grasp
    u.belief, u.certainty, u.decided, u.prediction, u.n_grasps

``update`` evaluates the models and hands the per-row scores to :meth:`BeliefUpdater.update_scores`
(``log_lik (m, K)`` and/or ``proba (m, K)``), which holds the maths; experiments that precompute
scores for a pool of grasps call it directly.

Sub-grasps (z-finger scoring, Algorithms 3 and 4 of the paper): the ``m`` rows of one update are
combined before the belief step. Likelihood updaters multiply the likelihoods of the subsets
(sum of log-likelihoods; ``combine="mean"`` takes their geometric mean instead, which does not
count the heavily overlapping subsets as independent evidence); classifier updaters sum the
subsets' probability vectors (equivalently, use their mean).

IC — iterative classification (paper, Algorithm 1)
    Scores ``S (K,)`` start at 0. Per grasp the classifier gives ``p``; the winner ``j = argmax p``
    gets ``S_j += p_j`` (``"ic"``), or the whole vector is added, ``S += p`` (``"ic-full"``).
    Belief ``S / k`` after ``k`` grasps (sub-stochastic for ``"ic"``); certainty ``max S / k``.
    We normalise by the grasp count: normalising the winner-only scores by ``sum S`` would give
    certainty 1 after the first grasp whatever the classifier said. The authors' public code does normalise by
    ``sum S``, guarded: the last grasp's winner's ``S_j`` until it reaches 0.6, then ``S_j / sum S``, and no
    decision before the second grasp (``certainty="share"``, opt-in).
BC-NP — Bayesian classification, non-informative prior
    ``log b <- log b + log p(q | c)``, renormalised with logsumexp (exact in log space).
BC-IP — informative prior
    The first grasp's classifier probabilities (clipped at ``eps``) form the prior; later grasps
    are KDE likelihood updates as in BC-NP. With evidence rows (below), the first grasp the classifier scores.

Evidence other than the grasp vector (the hand's touch pattern, :mod:`~haptic_env.recognizers.touch`) enters a
Bayesian updater as ``evidence (r, K)`` log-likelihood rows of the same grasp: ``update_scores(log_lik, proba,
evidence=E)`` takes them in the same step (BC-NP: beside the KDE's rows; BC-IP: also on the grasp that sets the
classifier's prior), and ``update_scores(evidence=E)`` alone is a grasp the models do not score (BC-IP: its prior
then waits for the first grasp the classifier scores, :attr:`BCIP.prior_set`). IC takes none.

A decision is made once ``certainty >= threshold`` (``lambda_s``, default :data:`DEFAULT_THRESHOLD`).

:meth:`BeliefUpdater.predict` gives the beliefs after one more grasp for ``G`` candidate grasps at once
without changing the updater (Bayesian updaters: one batched kernel, :func:`bayes_steps`, which also updates
``B`` independent log beliefs at once).
"""

from __future__ import annotations

import copy
import math
from abc import ABC, abstractmethod

import numpy as np
from numba import njit

from haptic_env.numbers import finite_number, whole_number

__all__ = ["BeliefUpdater", "IterativeClassification", "BayesianUpdater", "BCNP", "BCIP", "make_updater", "UPDATERS",
           "DEFAULT_UPDATER", "DEFAULT_THRESHOLD", "DEFAULT_MAX_GRASPS", "check_threshold", "IC_CERTAINTIES", "DEFAULT_IC_CERTAINTY",
           "check_ic_certainty", "bayes_steps"]

#: Every belief-updater kind (the env, the recogniser and the experiments take these names).
UPDATERS = ("ic", "ic-full", "bc-np", "bc-ip")
#: The updater wherever one is not given (the env, the belief, the recogniser's ``make_updater``): BC-NP.
DEFAULT_UPDATER = UPDATERS[2]
#: How IC turns its scores into a certainty (:class:`IterativeClassification`): ours, or the authors' code's.
IC_CERTAINTIES = ("count", "share")
#: IC's certainty rule wherever one is not given (the env, the analyses, the benchmarks).
DEFAULT_IC_CERTAINTY = IC_CERTAINTIES[0]
#: ``"share"``: below this winner score the certainty is the score itself (the authors' code's 0.6).
SHARE_FROM = 0.6


def check_ic_certainty(rule, name: str = "ic_certainty") -> str:
    """``rule`` unchanged; a ``ValueError`` naming it (as ``name``) unless it is one of :data:`IC_CERTAINTIES`."""
    if rule not in IC_CERTAINTIES:
        raise ValueError(f"{name} must be one of {IC_CERTAINTIES}, got {rule!r}")
    return rule


#: The certainty ``lambda_s`` at which a recogniser decides (the paper's 0.85); the one default of every threshold.
DEFAULT_THRESHOLD = 0.85
#: Grasps an episode or a simulated trial takes at most before it ends undecided; the one default of every cap.
DEFAULT_MAX_GRASPS = 30


def check_threshold(threshold, name: str = "threshold (lambda_s)") -> float:
    """``threshold`` as a float if it is a finite number in ``(0, 1]`` (:func:`~haptic_env.numbers.finite_number`:
    1 and numpy scalars yes, True and strings no); else a ``ValueError`` naming it as ``name``. The one check of every
    certainty threshold."""
    t = finite_number(threshold)
    if t is None or not 0.0 < t <= 1.0:
        raise ValueError(f"{name} must be in (0, 1], got {threshold!r}")
    return t


_OK, _NO_INFORMATION, _NAN = 0, 1, 2


@njit(cache=True)
def _bayes_step(log_belief, L, product, max_log_ratio):
    """``log b + sum_rows L`` (or the row mean), shifted by its best class and renormalised in log space.

    Returns ``(new log belief, status)``: ``_NAN`` if ``L`` holds a NaN or +inf, or a class's rows sum past the
    float range (+inf: not a likelihood; it was taken as no information), ``_NO_INFORMATION`` if every class
    has log-likelihood -inf (the belief is returned unchanged), else ``_OK``. ``max_log_ratio``: a class's
    log-likelihood is raised to at least ``best - max_log_ratio`` (``inf``: the plain rule).
    """
    m, K = L.shape
    if m == 0:  # no rows: no information (the row mean of none is not 0)
        return log_belief, _NO_INFORMATION
    ll = np.zeros(K)
    for r in range(m):
        for c in range(K):
            v = L[r, c]
            if np.isnan(v) or v == np.inf:
                return log_belief, _NAN
            ll[c] += v
    if not product:
        ll /= m
    for c in range(K):
        if np.isnan(ll[c]) or ll[c] == np.inf:  # a sum past the float range
            return log_belief, _NAN
    top = ll.max()
    if top == -np.inf:
        return log_belief, _NO_INFORMATION
    post = np.empty(K)
    for c in range(K):
        post[c] = log_belief[c] + (max(ll[c], top - max_log_ratio) - top)
    mx = post.max()
    if not np.isfinite(mx):  # the grasp fits only classes the belief has ruled out: it cannot be used
        return log_belief, _NO_INFORMATION
    total = 0.0
    for c in range(K):
        total += np.exp(post[c] - mx)
    return post - (mx + np.log(total)), _OK


@njit(cache=True)
def _bayes_steps(log_beliefs, L, starts, product, max_log_ratio, out, status):
    """:func:`_bayes_step` of ``B`` beliefs at once: belief ``b`` takes the rows ``starts[b]:starts[b + 1]`` of ``L``."""
    for b in range(log_beliefs.shape[0]):
        post, s = _bayes_step(log_beliefs[b], L[starts[b]:starts[b + 1]], product, max_log_ratio)
        out[b] = post
        status[b] = s


def bayes_steps(log_beliefs, log_lik, starts, *, combine: str = "product", max_log_ratio: float | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """One Bayes step for each of ``B`` log beliefs ``(B, K)`` (the rule of :class:`BayesianUpdater`).

    Belief ``b`` is updated by the score rows ``log_lik[starts[b]:starts[b + 1]]`` (``starts (B + 1,)``,
    ascending; an empty range leaves it unchanged). Returns the new log beliefs ``(B, K)`` and a boolean
    ``(B,)``: True where the belief was updated, False where every class had log-likelihood -inf (no
    information: that belief is returned unchanged). NaN or +inf scores (or rows that sum past the float range)
    raise ``ValueError``, as do a ``log_lik`` that is not ``(R, K)`` and options :class:`BayesianUpdater` refuses.
    """
    logb = np.ascontiguousarray(log_beliefs, dtype=np.float64)
    if logb.ndim != 2:
        raise ValueError(f"bayes_steps: log_beliefs must be (B, K), got shape {logb.shape}")
    L = score_rows(log_lik, logb.shape[1], "log_lik")
    starts = _check_starts(starts, len(L), len(logb) + 1, "bayes_steps: ")
    check_combine(combine)
    mlr = check_max_log_ratio(max_log_ratio)
    out = np.empty_like(logb)
    status = np.empty(len(logb), dtype=np.int64)
    _bayes_steps(logb, L, starts, combine == "product", mlr, out, status)
    if (status == _NAN).any():
        raise ValueError("log-likelihood contains NaN or +inf, or its rows sum past the float range")
    empty = starts[1:] == starts[:-1]
    out[empty] = logb[empty]
    return out, (status == _OK) & ~empty


def _logsumexp(v: np.ndarray) -> float:
    """``log(sum(exp(v)))`` of a 1-D array with a finite maximum (scipy's costs ~0.1 ms of dispatch per call)."""
    m = v.max()
    return float(m + np.log(np.exp(v - m).sum()))


def _check_starts(starts, n_rows: int, n_entries: int | None = None, where: str = "") -> np.ndarray:
    """``starts`` as contiguous int64, rising from 0 to ``n_rows`` (with ``n_entries`` entries when given); a
    ValueError otherwise, also for fractional values (1.5 was cut to 1). ``where`` heads the message."""
    starts = np.asarray(starts)
    if starts.dtype.kind not in "iu":
        raise ValueError(f"{where}starts must be whole numbers, got {starts}")
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if (starts.ndim != 1 or len(starts) < 1 or (n_entries is not None and len(starts) != n_entries)
            or starts[0] != 0 or starts[-1] != n_rows or (np.diff(starts) < 0).any()):
        entries = "" if n_entries is None else f" with {n_entries} entries"
        raise ValueError(f"{where}starts must rise from 0 to {n_rows}{entries}, got {starts}")
    return starts


def _grouped(Q, starts) -> tuple[np.ndarray, np.ndarray]:
    Q = _rows(Q)
    return Q, np.arange(len(Q) + 1) if starts is None else _check_starts(starts, len(Q))


def score_rows(x, n_classes: int, name: str) -> np.ndarray:
    """Precomputed scores of one grasp's rows as ``(m, K)`` float64: ``(m, K)`` or one row ``(K,)``; any other
    shape is a ValueError naming ``name`` (a transposed or other-K array was reshaped into other rows)."""
    X = np.asarray(x, dtype=np.float64)
    if X.ndim == 1 and X.shape[0] == n_classes:
        return X[None]
    if X.ndim != 2 or X.shape[1] != n_classes:
        raise ValueError(f"{name} must have shape (m, {n_classes}) (m rows of {n_classes} classes), got {X.shape}")
    return X


def _probabilities(proba, n_classes: int) -> np.ndarray:
    """:func:`score_rows` of classifier probabilities, each finite and in [0, 1] (a NaN made the belief NaN for
    good; inf decided at once)."""
    P = score_rows(proba, n_classes, "proba")
    if not (np.isfinite(P).all() and (P >= 0).all() and (P <= 1).all()):
        raise ValueError(f"proba must hold probabilities (finite, in [0, 1]), got {P.tolist()}")
    return P


def check_combine(combine) -> str:
    if combine not in ("product", "mean"):
        raise ValueError(f"combine must be 'product' or 'mean', got {combine!r}")
    return combine


def check_max_log_ratio(max_log_ratio) -> float:
    """``max_log_ratio`` (None, a positive number or inf) as the kernels take it (None: inf)."""
    if max_log_ratio is not None and not (max_log_ratio == math.inf or (finite_number(max_log_ratio) or 0) > 0):
        raise ValueError(f"max_log_ratio must be positive or None, got {max_log_ratio!r}")
    return math.inf if max_log_ratio is None else float(max_log_ratio)


def model_rows(L: np.ndarray, combine: str) -> np.ndarray:
    """The models' checked rows ``L (m, K)`` of one grasp as a summing (product) step takes them: ``L`` itself, or
    with ``combine="mean"`` their mean row (none when ``m = 0``), so that evidence rows joined after them are summed
    as they are, not averaged in with the models' rows."""
    if combine == "product" or len(L) <= 1:
        return L
    with np.errstate(over="ignore", invalid="ignore"):  # a NaN or a sum past the float range: the step refuses it
        return L.mean(axis=0, keepdims=True)


def _joined(log_lik, evidence, n_classes: int, combine: str = "product") -> np.ndarray:
    """One grasp's log-likelihood rows for a summing step: the models' ``log_lik (m, K)`` (:func:`model_rows`) and
    the ``evidence (r, K)`` (either may be None), each checked (:func:`score_rows`)."""
    parts = [score_rows(x, n_classes, name) for x, name in ((log_lik, "log_lik"), (evidence, "evidence"))
             if x is not None]
    if log_lik is not None:
        parts[0] = model_rows(parts[0], combine)
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def evidence_rows(evidence, n_classes: int) -> np.ndarray:
    """``evidence (r, K)`` of one grasp (or one row ``(K,)``) checked: :func:`score_rows`, and no NaN or +inf (a
    ValueError naming it, before anything uses them)."""
    E = score_rows(evidence, n_classes, "evidence")
    if np.isnan(E).any() or (E == np.inf).any():
        raise ValueError("evidence contains NaN or +inf")
    return E


def _check_weight(weight) -> float:
    w = finite_number(weight)
    if w is None or not w > 0:
        raise ValueError(f"weight must be positive and finite, got {weight!r}")
    return w


def _check_weights(weights, G: int) -> np.ndarray:
    """``weights`` of ``G`` grasps as ``(G,)`` float64, each one :func:`_check_weight` takes (a bool or a string
    is refused, as :meth:`BayesianUpdater.update` refuses it)."""
    w = list(weights) if isinstance(weights, (list, tuple, np.ndarray)) else None
    if w is None or len(w) != G or np.ndim(weights) != 1:
        raise ValueError(f"weights must be {G} positive finite numbers, got {weights!r}")
    try:
        return np.array([_check_weight(x) for x in w], dtype=np.float64)
    except ValueError:
        raise ValueError(f"weights must be {G} positive finite numbers, got {weights!r}") from None


def _rows(q) -> np.ndarray:
    Q = np.asarray(q, dtype=np.float64)
    if Q.ndim == 1:
        Q = Q[None]
    if Q.ndim != 2:
        raise ValueError(f"a grasp update takes q of shape (d,) or (m, d), got {Q.shape}")
    return Q


class BeliefUpdater(ABC):
    """Common state and interface; subclasses implement :meth:`_step` and the belief."""

    kind: str = ""

    def __init__(self, n_classes: int, threshold: float = DEFAULT_THRESHOLD):
        if (whole_number(n_classes) or 0) < 2:
            raise ValueError(f"an updater needs at least 2 classes, got {n_classes!r}")
        self.n_classes = int(n_classes)
        self.threshold = check_threshold(threshold)
        self.n_grasps = 0
        self.reset()

    def _check_prior(self, prior) -> np.ndarray:
        if prior is None:
            return np.full(self.n_classes, 1.0 / self.n_classes)
        p = np.asarray(prior, dtype=np.float64)
        if p.shape != (self.n_classes,) or not np.isfinite(p).all() or (p < 0).any() or not p.max() > 0:
            raise ValueError(f"prior must be {self.n_classes} non-negative finite numbers with a positive sum, got {prior!r}")
        p = p / p.max()  # first: the sum of huge entries overflowed (1e308 each gave a belief of zeros)
        return p / p.sum()

    @abstractmethod
    def reset(self, prior=None) -> np.ndarray:
        """Forget all grasps; returns the initial belief ``(K,)``."""

    @abstractmethod
    def update_scores(self, log_lik=None, proba=None, *, evidence=None) -> np.ndarray:
        """One grasp from precomputed scores of its ``m`` rows: ``log_lik (m, K)``, ``proba (m, K)``; ``evidence
        (r, K)``: log-likelihood rows of the same grasp from outside the grasp vector (Bayesian updaters only)."""

    @abstractmethod
    def update(self, q) -> np.ndarray:
        """One grasp: ``q (d,)`` or ``(m, d)`` sub-grasp vectors; returns the new belief ``(K,)``."""

    @property
    @abstractmethod
    def belief(self) -> np.ndarray: ...

    def predict(self, Q, starts=None) -> np.ndarray:
        """Beliefs ``(G, K)`` after ONE more grasp, for each of ``G`` candidate grasps; the updater is unchanged.

        ``Q (R, d)`` holds the score rows of the grasps, grasp ``g`` owning ``Q[starts[g]:starts[g + 1]]``
        (``starts (G + 1,)``; default: one row per grasp). Exactly what :meth:`update` would give; here through
        a copy of the state per grasp (Bayesian updaters override it with one batched call).
        """
        Q, starts = _grouped(Q, starts)
        out = np.empty((len(starts) - 1, self.n_classes))
        for g in range(len(out)):
            u = copy.copy(self)  # shallow: share the models, copy the mutable state arrays
            for name, value in vars(u).items():
                if isinstance(value, np.ndarray):
                    setattr(u, name, value.copy())
            out[g] = u.update(Q[starts[g]:starts[g + 1]])
        return out

    @property
    def certainty(self) -> float:
        return float(self.belief.max())

    @property
    def decided(self) -> bool:
        return self.n_grasps > 0 and self.certainty >= self.threshold

    @property
    def prediction(self) -> int:
        return int(np.argmax(self.belief))


class IterativeClassification(BeliefUpdater):
    """IC (``full=False``, paper Algorithm 1) and its full-accumulation variant (``full=True``).

    ``certainty`` (IC only) is how the scores become a certainty: ``"count"`` (default) ``max S / k``; ``"share"``
    as the authors' public code (``IC_inference.py``) computes it: for the class ``j`` that won the LAST grasp,
    ``S_j`` while ``S_j < 0.6`` and its share ``S_j / sum S`` of the winners' scores from then on, with no
    decision before the second grasp. The share stops far sooner (two grasps won by the same class with ``p >= 0.3``
    give certainty 1) and is not a probability; ``"count"`` stays at or below the fraction of grasps the class won.
    """

    def __init__(self, classifier, threshold: float = DEFAULT_THRESHOLD, *, full: bool = False,
                 n_classes: int | None = None, certainty: str = DEFAULT_IC_CERTAINTY):
        check_ic_certainty(certainty, "IC certainty")
        if full and certainty != "count":
            raise ValueError(f"IC certainty {certainty!r} is defined for winner-only IC ('ic'), not 'ic-full'")
        self.classifier = classifier
        self.full = bool(full)
        self.kind = "ic-full" if full else "ic"
        self.certainty_rule = certainty
        super().__init__(n_classes or classifier.n_classes, threshold)

    def reset(self, prior=None) -> np.ndarray:
        self._prior = self._check_prior(prior)  # shown as the belief before the first grasp only
        self.scores = np.zeros(self.n_classes)
        self.n_grasps = 0
        self.last_winner = -1  # the class that won the last scored grasp ("share" certainty)
        return self.belief

    @property
    def certainty(self) -> float:
        if self.certainty_rule == "count" or self.last_winner < 0:
            return float(self.belief.max())
        s = float(self.scores[self.last_winner])
        return s if s < SHARE_FROM else s / float(self.scores.sum())

    @property
    def decided(self) -> bool:
        first = 2 if self.certainty_rule == "share" else 1
        return self.n_grasps >= first and self.certainty >= self.threshold

    @property
    def belief(self) -> np.ndarray:
        if self.n_grasps == 0:
            return self._prior.copy()
        return self.scores / self.n_grasps

    def update_scores(self, log_lik=None, proba=None, *, evidence=None) -> np.ndarray:
        if evidence is not None:  # before anything changes
            raise ValueError("IC takes no evidence rows (the touch pattern needs a Bayesian updater: 'bc-np', 'bc-ip')")
        if proba is None:
            raise ValueError("IC updates need classifier probabilities (proba)")
        P = _probabilities(proba, self.n_classes)  # before anything changes
        self.n_grasps += 1
        if len(P) == 0:  # no usable (sub-)grasp: the grasp is spent, the scores stay
            return self.belief
        p = P.mean(axis=0)
        j = int(np.argmax(p))
        if self.full:
            self.scores += p
        else:
            self.scores[j] += p[j]
        self.last_winner = j
        return self.belief

    def update(self, q) -> np.ndarray:
        Q = _rows(q)
        return self.update_scores(proba=self.classifier.predict_proba(Q) if len(Q) else np.zeros((0, self.n_classes)))


class BayesianUpdater(BeliefUpdater):
    """Posterior ``∝ prior × Π likelihoods`` in log space (BC-NP; base of BC-IP)."""

    kind = "bc-np"

    def __init__(self, likelihood, threshold: float = DEFAULT_THRESHOLD, *, combine: str = "product",
                 max_log_ratio: float | None = None, n_classes: int | None = None):
        """``likelihood`` has ``log_likelihood(Q (m, d)) -> (m, K)``.

        ``max_log_ratio``: if set, one grasp can lower a class's log-likelihood by at most this much
        below the best class (robustness against an outlier grasp); ``None`` is the plain rule.
        """
        check_combine(combine)
        check_max_log_ratio(max_log_ratio)
        self.likelihood = likelihood
        self.combine = combine
        self.max_log_ratio = max_log_ratio
        super().__init__(n_classes or likelihood.n_classes, threshold)

    def reset(self, prior=None) -> np.ndarray:
        with np.errstate(divide="ignore"):  # a class the prior rules out is impossible (-inf), not 1e-300 likely
            self.log_belief = np.log(self._check_prior(prior))
        self.n_grasps = 0
        return self.belief

    @property
    def belief(self) -> np.ndarray:
        return np.exp(self.log_belief)

    @property
    def certainty(self) -> float:
        # the belief is normalised: max b = exp(max log b) (ufunc reduce: no Python wrapper on the env's hot path)
        return math.exp(float(np.maximum.reduce(self.log_belief)))

    def _stepped(self, log_belief: np.ndarray, L: np.ndarray, what: str = "log-likelihood") -> np.ndarray:
        """The log belief after a Bayes step that sums the checked rows ``L (m, K)`` (the models' rows already
        combined by :func:`model_rows`, evidence rows beside them), or ``log_belief`` itself when ``L`` has no rows
        or every class is impossible (no information); raises before anything changes when ``L`` holds NaN or +inf,
        or its rows sum past the float range (``what``: its name)."""
        if len(L) == 0:
            return log_belief
        mlr = np.inf if self.max_log_ratio is None else float(self.max_log_ratio)
        post, status = _bayes_step(log_belief, L, True, mlr)
        if status == _NAN:
            raise ValueError(f"{what} contains NaN or +inf, or its rows sum past the float range")
        return post if status == _OK else log_belief

    def update_scores(self, log_lik=None, proba=None, *, evidence=None) -> np.ndarray:
        if log_lik is None and evidence is None:
            raise ValueError("Bayesian updates need log-likelihoods (log_lik or evidence rows)")
        # raises on NaN, +inf, a bad shape before any change
        self.log_belief = self._stepped(self.log_belief, _joined(log_lik, evidence, self.n_classes, self.combine))
        self.n_grasps += 1
        return self.belief

    def update(self, q, weight: float = 1.0, *, evidence=None) -> np.ndarray:
        """One grasp's rows ``q (d,)`` or ``(m, d)``; ``weight`` (> 0) multiplies their combined log-likelihood (a
        tempered step: z-subset scoring counts ``C(t, z)`` correlated subsets as ``k``, see
        :class:`~haptic_env.belief.Belief`); ``evidence (r, K)``: the same grasp's other log-likelihood rows (the
        touch pattern), not weighted."""
        w = _check_weight(weight)  # before the model runs: a bad weight (True, '2') is refused, not read as a number
        Q = _rows(q)
        L = self.likelihood.log_likelihood(Q) if len(Q) else np.zeros((0, self.n_classes))
        return self.update_scores(log_lik=L if w == 1.0 else w * L, evidence=evidence)

    def predict(self, Q, starts=None, weights=None) -> np.ndarray:
        """:meth:`BeliefUpdater.predict` in one likelihood call and one batched Bayes step (:func:`bayes_steps`);
        ``weights (G,)``: each grasp's ``weight`` of :meth:`update` (default 1)."""
        Q, starts = _grouped(Q, starts)
        G = len(starts) - 1
        L = self.likelihood.log_likelihood(Q) if len(Q) else np.zeros((0, self.n_classes))
        if weights is not None:
            w = _check_weights(weights, G)
            L = L * np.repeat(w, np.diff(starts))[:, None]
        post, _ = bayes_steps(np.broadcast_to(self.log_belief, (G, self.n_classes)), L, starts, combine=self.combine,
                              max_log_ratio=self.max_log_ratio)
        return np.exp(post)


BCNP = BayesianUpdater


class BCIP(BayesianUpdater):
    """BC with the informative prior of the first grasp's classifier probabilities.

    "First grasp": the first the classifier scores. Before it, only ``evidence`` rows (the touch pattern) may
    update the belief (:meth:`update_scores`); :attr:`prior_set` tells whether the prior is in."""

    kind = "bc-ip"

    def __init__(self, classifier, likelihood, threshold: float = DEFAULT_THRESHOLD, *, eps: float = 1e-4, **kw):
        if not 0 < (finite_number(eps) or 0) < 1:
            raise ValueError(f"eps must be in (0, 1), got {eps!r}")
        self.classifier = classifier
        self.eps = float(eps)
        super().__init__(likelihood, threshold, **kw)

    def reset(self, prior=None) -> np.ndarray:
        b = super().reset(prior)  # a bad prior raises before anything changes
        self.prior_set = False
        return b

    def with_prior(self, log_belief: np.ndarray, proba) -> np.ndarray:
        """``log_belief (K,)`` times the prior of one grasp's classifier probabilities ``proba (m, K)``, ``m >= 1``
        (the rows' mean clipped at ``eps``), renormalised: the log belief once that grasp has set the prior."""
        P = _probabilities(proba, self.n_classes)
        if len(P) == 0:
            raise ValueError("a classifier prior needs at least one row of probabilities")
        p = np.maximum(P.mean(axis=0), self.eps)
        post = log_belief + np.log(p / p.sum())
        return post - _logsumexp(post)

    def update_scores(self, log_lik=None, proba=None, *, evidence=None) -> np.ndarray:
        """After the prior: a Bayes step of ``log_lik`` and ``evidence``. Before it: ``proba`` rows set the prior (the
        grasp's ``log_lik`` unused, as the paper's first grasp) and ``evidence`` joins in the same step; with
        ``proba`` of no rows (no usable row) the grasp is spent (without evidence the prior then stays uniform, as
        the paper's first grasp; with evidence it waits); ``evidence`` alone is a Bayes step (a grasp the classifier
        does not score) and the prior waits."""
        if self.prior_set:
            return super().update_scores(log_lik=log_lik, evidence=evidence)
        if proba is None and (evidence is None or log_lik is not None):  # before anything changes
            raise ValueError("the first BC-IP update needs classifier probabilities (proba), or evidence rows alone")
        E = None if evidence is None else evidence_rows(evidence, self.n_classes)
        if proba is None:
            return super().update_scores(evidence=E)
        P = _probabilities(proba, self.n_classes)
        log_b = self.with_prior(self.log_belief, P) if len(P) else self.log_belief
        if E is not None:  # the step computed aside, so that a bad row changes nothing
            log_b = self._stepped(log_b, E, "evidence")
        self.log_belief = log_b
        self.prior_set = len(P) > 0 or E is None  # no evidence: the first grasp was the prior's, usable or not
        self.n_grasps += 1
        return self.belief

    def update(self, q, weight: float = 1.0, *, evidence=None) -> np.ndarray:
        """As :meth:`BayesianUpdater.update`; the first grasp's classifier prior takes no weight (a bad one is refused
        all the same, before anything changes)."""
        _check_weight(weight)
        Q = _rows(q)
        if len(Q) == 0:
            return self.update_scores(log_lik=np.zeros((0, self.n_classes)), proba=np.zeros((0, self.n_classes)),
                                      evidence=evidence)
        if not self.prior_set:
            return self.update_scores(proba=self.classifier.predict_proba(Q), evidence=evidence)
        return super().update(Q, weight, evidence=evidence)

    def predict(self, Q, starts=None, weights=None) -> np.ndarray:
        if not self.prior_set:  # the first scored grasp sets the classifier prior: not a Bayes step (no weight)
            if weights is not None:  # refused all the same, as update refuses a bad weight before the prior
                _check_weights(weights, len(_grouped(Q, starts)[1]) - 1)
            return BeliefUpdater.predict(self, Q, starts)
        return super().predict(Q, starts, weights)


def make_updater(kind: str, *, classifier=None, likelihood=None, threshold: float = DEFAULT_THRESHOLD,
                 ic_certainty: str = DEFAULT_IC_CERTAINTY, **kw) -> BeliefUpdater:
    """An updater by name (:data:`UPDATERS`), given the models it needs. ``ic_certainty``: IC's certainty rule
    (:data:`IC_CERTAINTIES`), which only ``"ic"`` takes; the other kinds ignore it."""
    if kind not in UPDATERS:
        raise ValueError(f"unknown updater kind {kind!r}; choose one of {UPDATERS}")
    check_ic_certainty(ic_certainty, "IC certainty")
    if kind in ("ic", "ic-full", "bc-ip") and classifier is None:
        raise ValueError(f"updater {kind!r} needs a classifier")
    if kind in ("bc-np", "bc-ip") and likelihood is None:
        raise ValueError(f"updater {kind!r} needs a likelihood model")
    if kind == "ic":
        return IterativeClassification(classifier, threshold, full=False, certainty=ic_certainty, **kw)
    if kind == "ic-full":
        return IterativeClassification(classifier, threshold, full=True, **kw)
    if kind == "bc-np":
        return BayesianUpdater(likelihood, threshold, **kw)
    return BCIP(classifier, likelihood, threshold, **kw)
