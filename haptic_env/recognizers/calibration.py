r"""Calibration of one-shot class posteriors: a temperature (and learned corrections) fitted on validation grasps,
and its checks.

Both recognisers give class scores ``s (B, K)`` per grasp: the KDE's log-likelihoods
:math:`\log p(q \mid c)` (BC) and the MLP's logits (IC, BC-IP's prior). The one-shot posterior is
``softmax(s / T)``. A KDE in ``d = 5n - 6`` dimensions is sharply over-confident (``T > 1`` fixes it),
and a posterior multiplied over grasps inherits that. :func:`fit_temperature` chooses ``T`` by the
negative log-likelihood of the true class on *validation* grasps (Guo et al., 2017, "On Calibration
of Modern Neural Networks"); the test grasps are never seen. For BC a temperature ``T`` turns the
likelihood into the tempered (power) likelihood :math:`p(q \mid c)^{1/T}` of every Bayes step.

Two learned corrections may come before the temperature (:data:`CORRECTIONS`): :class:`ScoreCorrection`
(matrix scaling, it re-weighs and offsets the classes) and :class:`PowerCorrection` (one exponent on each class's
gap to the best, it reshapes how gaps turn into confidence). :func:`select_calibration` chooses among them and the
temperature alone on held-out halves of the validation grasps.

:func:`expected_calibration_error` and :func:`reliability` measure how well the confidence
``max_c p(c | q)`` matches the accuracy (equal-width confidence bins). All functions are pure: arrays in,
arrays or floats out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import log_softmax

from haptic_env.numbers import finite_number, positive_range, whole_at_least

__all__ = ["fit_temperature", "sequence_scores", "calibration_rows", "tempered_nll", "expected_calibration_error",
           "reliability", "T_BOUNDS", "ScoreCorrection", "fit_correction", "select_correction", "SELECT_GRASPS",
           "PowerCorrection", "fit_power", "P_BOUNDS", "CORRECTIONS", "check_corrections", "select_calibration"]

#: Range of temperatures searched by :func:`fit_temperature`.
T_BOUNDS = (0.02, 200.0)


def _check(scores, y) -> tuple[np.ndarray, np.ndarray]:
    S = np.asarray(scores, dtype=np.float64)
    Y = np.asarray(y)
    if S.ndim != 2 or S.shape[1] < 2:
        raise ValueError(f"scores must have shape (B, K) with K >= 2, got {S.shape}")
    if Y.shape != (S.shape[0],) or not np.issubdtype(Y.dtype, np.integer) or (Y < 0).any() or (Y >= S.shape[1]).any():
        raise ValueError(f"y must be ({S.shape[0]},) class indices in [0, {S.shape[1]}), got shape {Y.shape}")
    _finite_or_minus_inf(S)  # +inf was put at the floor: the surest class made the least likely
    return S, Y.astype(np.int64)


def _row_top(S: np.ndarray) -> np.ndarray:
    """``(B, 1)``: each row's best finite score (0 for a row with none)."""
    top = np.max(np.where(np.isfinite(S), S, -np.inf), axis=1, keepdims=True)
    return np.where(np.isfinite(top), top, 0.0)


def _finite_or_minus_inf(scores, n_classes: int | None = None) -> np.ndarray:
    """Scores to correct as ``(B, K)`` float64 (``K = n_classes`` when given), each finite or -inf: a ValueError
    otherwise (NaN and +inf were put at the floor silently)."""
    S = np.asarray(scores, dtype=np.float64)
    if S.ndim != 2 or (n_classes is not None and S.shape[1] != n_classes):
        raise ValueError(f"scores must have shape (B, {'K' if n_classes is None else n_classes}), got {S.shape}")
    if np.isnan(S).any() or (S == np.inf).any():
        raise ValueError("scores contain NaN or +inf (log-likelihoods are finite or -inf)")
    return S


def _finite_rows(S: np.ndarray) -> np.ndarray:
    """Scores with -inf replaced by a large finite floor below each row's best (a class a KDE ruled out)."""
    return np.where(np.isfinite(S), S, _row_top(S) - 1e4)


@dataclass(frozen=True)
class ScoreCorrection:
    r"""A learned correction of one grasp's class scores (matrix scaling, Guo et al. 2017, section 4.2):
    ``log_softmax(W @ clip(s - max(s)) + b)``.

    The KDE's log-likelihoods of one object's grasps can be *systematically* wrong, not only over-confident: a
    class whose training grasps are spread out (an apple) gets lower densities than a compact look-alike (a
    ball) at the grasps both share, so summing log-likelihoods over grasps converges on the look-alike, and no
    temperature changes that argmax. A multinomial logistic regression on the row-centred log-likelihood
    vector, fitted on validation grasps by the NLL of the true class, re-weighs and offsets the classes;
    its output is a calibrated one-shot log-posterior, i.e. (uniform prior) a log-likelihood ratio, so Bayes
    updates sum it over grasps exactly as they sum log-likelihoods.

    Attributes:
        W: ``(K, K)`` weights on the centred scores.
        b: ``(K,)`` offsets.
        floor: centred scores are clipped at this value (<= 0; a class a KDE ruled out scores ``-inf``).
    """

    W: np.ndarray
    b: np.ndarray
    floor: float

    def __call__(self, scores) -> np.ndarray:
        """``(B, K)`` scores -> ``(B, K)`` corrected log-posteriors (rows sum to 1 in probability)."""
        S = _finite_or_minus_inf(scores, len(self.b))
        # row by row (no BLAS matrix product): a row's result does not depend on the batch it came in
        X = _centred(S, self.floor)
        return log_softmax((X[:, None, :] * self.W[None]).sum(axis=2) + self.b, axis=1)


def _centred(S: np.ndarray, floor: float) -> np.ndarray:
    """Scores minus their row's best finite one, non-finite ones at ``floor``, all clipped at ``floor``."""
    return np.maximum(np.where(np.isfinite(S), S - _row_top(S), floor), floor)


def _bounds(bounds) -> tuple[float, float]:
    """A search interval ``(lo, hi)`` with ``0 < lo < hi``, both finite; a ``ValueError`` naming it otherwise."""
    try:
        lo, hi = positive_range(bounds, "bounds")
    except ValueError:
        lo = hi = 0.0
    if not 0 < lo < hi:
        raise ValueError(f"bounds must be 0 < lo < hi, got {bounds!r}")
    return lo, hi


def fit_correction(scores, y, *, C: float = 1.0) -> ScoreCorrection:
    """The :class:`ScoreCorrection` fitted on validation ``scores (B, K)`` of true classes ``y (B,)``
    (scikit-learn's multinomial ``LogisticRegression``, L2 strength ``1 / C`` on standardised inputs).

    The floor is the smallest finite centred validation score. Needs every class in ``y``."""
    from sklearn.linear_model import LogisticRegression

    S, Y = _check(scores, y)
    K = S.shape[1]
    missing = sorted(set(range(K)) - set(np.unique(Y).tolist()))
    if missing:
        raise ValueError(f"fit_correction needs validation scores of every class; classes {missing} have none")
    if not (finite_number(C) or 0) > 0:
        raise ValueError(f"C must be > 0, got {C!r}")
    centred = _centred(S, -np.inf)
    finite = centred[np.isfinite(centred)]
    floor = float(min(finite.min(), -1.0)) if finite.size else -1.0
    X = np.maximum(centred, floor)
    mu, sd = X.mean(axis=0), np.maximum(X.std(axis=0), 1e-9)
    lr = LogisticRegression(C=C, max_iter=5000).fit((X - mu) / sd, Y)
    coef, icpt = lr.coef_, lr.intercept_
    if K == 2:  # scikit-learn's binary model: one logit for class 1, i.e. +-logit / 2 as two softmax inputs
        coef, icpt = np.vstack([-coef / 2, coef / 2]), np.array([-icpt[0] / 2, icpt[0] / 2])
    W = coef / sd  # fold the standardisation into W and b
    b = icpt - W @ mu
    return ScoreCorrection(W=W, b=b, floor=floor)


#: Range of exponents searched by :func:`fit_power`.
P_BOUNDS = (0.1, 2.0)


@dataclass(frozen=True)
class PowerCorrection:
    r"""A one-parameter correction of the *shape* of a grasp's class scores: each class's gap to the best class,
    raised to a power, ``-min(max(s) - s_c, cap) ** p``.

    A temperature scales every gap alike. A KDE in few dimensions can be over-confident in its large gaps and
    under-confident in its small ones at once: then the NLL-optimal temperature leaves the posteriors mis-calibrated
    at middle confidences (measured: the default set, n = 4 without normals, 200,000 grasps per object, test ECE
    0.058 with the temperature alone). ``p < 1`` compresses large gaps more than small ones; ``p = 1`` is the identity.
    Followed by the temperature, it is a two-parameter family that contains temperature scaling. Like
    :class:`ScoreCorrection` its output is a one-shot log-posterior up to a constant per grasp, which Bayes updates sum
    over grasps.

    Attributes:
        p: the exponent (> 0).
        cap: gaps are clipped at this value (> 0; a class a KDE ruled out, ``-inf``, gets it).
    """

    p: float
    cap: float

    def __call__(self, scores) -> np.ndarray:
        """``(B, K)`` scores -> ``(B, K)`` corrected scores (the best class at 0, the others below)."""
        S = _finite_or_minus_inf(scores)
        return -(-_centred(S, -self.cap)) ** self.p


def fit_power(scores, y, bounds: tuple[float, float] = P_BOUNDS) -> PowerCorrection:
    """The :class:`PowerCorrection` whose exponent minimises the NLL of the true class after the best temperature
    (the temperature profiled out: :func:`fit_temperature` at every exponent tried), on validation ``scores (B, K)``
    of true classes ``y (B,)``. The cap is the largest finite validation gap (at least 1)."""
    S, Y = _check(scores, y)
    lo, hi = _bounds(bounds)
    gaps = -_centred(S, -np.inf)
    finite = gaps[np.isfinite(gaps)]
    cap = float(max(finite.max(), 1.0)) if finite.size else 1.0
    if len(Y) == 0:
        return PowerCorrection(1.0, cap)

    def nll(log_p: float) -> float:
        C = PowerCorrection(float(np.exp(log_p)), cap)(S)
        return tempered_nll(C, Y, fit_temperature(C, Y))

    res = minimize_scalar(nll, bounds=(np.log(lo), np.log(hi)), method="bounded", options={"xatol": 1e-3})
    return PowerCorrection(float(np.exp(res.x)), cap)


def tempered_nll(scores, y, T: float) -> float:
    """Mean negative log-probability of the true class under ``softmax(scores / T)``."""
    S, Y = _check(scores, y)
    if not (finite_number(T) or 0) > 0:
        raise ValueError(f"temperature must be > 0, got {T!r}")
    L = log_softmax(_finite_rows(S) / T, axis=1)
    return float(-L[np.arange(len(Y)), Y].mean())


def fit_temperature(scores, y, bounds: tuple[float, float] = T_BOUNDS) -> float:
    """The ``T`` in ``bounds`` that minimises :func:`tempered_nll` (bounded search on ``log T``).

    Args:
        scores: ``(B, K)`` validation scores (log-likelihoods or logits; ``-inf`` allowed).
        y: ``(B,)`` true classes.

    Returns:
        The temperature (1.0 when ``B == 0``: nothing to fit).
    """
    S, Y = _check(scores, y)
    lo, hi = _bounds(bounds)
    if len(Y) == 0:
        return 1.0
    S = _finite_rows(S)
    idx = np.arange(len(Y))

    def nll(log_t: float) -> float:
        return float(-log_softmax(S / np.exp(log_t), axis=1)[idx, Y].mean())

    res = minimize_scalar(nll, bounds=(np.log(lo), np.log(hi)), method="bounded", options={"xatol": 1e-3})
    return float(np.exp(res.x))


def calibration_rows(y, n_classes: int, per_class: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of at most ``per_class`` validation rows of each class ``0 .. n_classes-1`` of ``y (B,)``, drawn at
    random without replacement (one permutation per class, in class order), to fit a calibration on."""
    y = np.asarray(y)
    return np.concatenate([rng.permutation(np.flatnonzero(y == c))[:per_class] for c in range(n_classes)])


#: The longest belief a sequence temperature is fitted for: :func:`sequence_scores` makes ``max_grasps x rows``
#: sums (the committed runs use 1-10; 10**9 would fill the memory).
MAX_CALIBRATE_GRASPS = 100


def check_calibrate_grasps(value, lo: int, name: str) -> int:
    """``value`` as a whole number in ``[lo, MAX_CALIBRATE_GRASPS]``; a ValueError names ``name`` otherwise."""
    whole_at_least(value, lo, name)
    if value > MAX_CALIBRATE_GRASPS:
        raise ValueError(f"{name} must be <= {MAX_CALIBRATE_GRASPS} (the longest calibrated belief), got {value!r}")
    return int(value)


def sequence_scores(scores, y, max_grasps: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Scores of beliefs after ``k = 1 .. max_grasps`` grasps of one object, for fitting a sequence temperature.

    A belief that multiplies tempered likelihoods over ``k`` grasps of the same object sums their scores.
    The one-shot ``T`` of :func:`fit_temperature` assumes the grasps' errors independent; the grasps of one
    object share the KDE's systematic errors (an object whose grasps look like another's keeps looking
    like it), so the ``k``-grasp posterior is over-confident by more than one grasp's ``T`` corrects.
    Fitting ``T`` on these sums instead calibrates the posteriors an episode actually forms. Every class
    gets the same number of sums (episodes draw their object uniformly), however few validation rows it has.

    Args:
        scores: ``(B, K)`` validation scores of single grasps (``-inf`` allowed; it stays ``-inf`` in a sum).
        y: ``(B,)`` true classes.
        max_grasps: the longest belief (>= 1; 1 returns ``scores, y`` unchanged).
        rng: draws the grasps of each sum (with replacement, within one class).

    Returns:
        ``(S, Y)``: for every class present in ``y`` and every ``k``, ``m`` sums of ``k`` of its rows, ``m`` the
        largest class's row count (``S (M, K)``, ``M = max_grasps * m * classes``), and their classes ``Y (M,)``.
    """
    S, Y = _check(scores, y)
    check_calibrate_grasps(max_grasps, 1, "max_grasps")
    if max_grasps == 1 or len(Y) == 0:
        return S, Y
    classes, counts = np.unique(Y, return_counts=True)
    m = int(counts.max())
    out_s, out_y = [], []
    for c in classes:
        rows = np.flatnonzero(Y == c)
        for k in range(1, int(max_grasps) + 1):
            out_s.append(S[rng.choice(rows, (m, k))].sum(axis=1))
            out_y.append(np.full(m, c, dtype=np.int64))
    return np.concatenate(out_s), np.concatenate(out_y)


#: beliefs of ``k = 1 .. SELECT_GRASPS`` grasps score the choice of :func:`select_correction` (1: one-shot posteriors)
SELECT_GRASPS = 1


#: the learned corrections :func:`select_calibration` weighs against the temperature alone, by name
CORRECTIONS = {"matrix": fit_correction, "power": fit_power}


def check_corrections(names, what: str = "candidates", *, allow_empty: bool = True) -> tuple[str, ...]:
    """``names`` as a tuple, each a name of :data:`CORRECTIONS` and each once (none only with ``allow_empty``);
    otherwise a ValueError naming ``what`` and the bad value."""
    out = tuple(names)
    if (not out and not allow_empty) or len(set(out)) != len(out) or any(c not in CORRECTIONS for c in out):
        raise ValueError(f"{what} must be distinct names of {tuple(CORRECTIONS)}, got {names!r}")
    return out


def select_calibration(scores, y, candidates=("matrix",), *, calibrate_grasps: int = 1, horizon: int = SELECT_GRASPS,
                       rng: np.random.Generator | None = None) -> tuple[str | None, dict]:
    """Which calibration gives the KDE's held-out validation posteriors the lowest NLL: the temperature alone
    (``None``) or one of the learned ``candidates`` (names in :data:`CORRECTIONS`) followed by the temperature.

    Each class's rows are halved; every calibration is fitted on the first halves (its temperature for
    ``calibrate_grasps``-grasp beliefs, as the KDE fits it) and scored on the second by the mean NLL of the true class
    after ``k = 1 .. horizon`` summed grasps of one object (:func:`sequence_scores`), in the order temperature alone,
    then ``candidates`` (one random stream, so the choice between the first ones does not depend on later ones).

    Args:
        scores: ``(B, K)`` raw validation log-likelihoods; every class needs >= 2 rows.
        y: ``(B,)`` true classes.
        candidates: correction names, each once.
        calibrate_grasps: the temperature's belief length (``KDEConfig.calibrate_grasps``).
        horizon: longest held-out belief scored.
        rng: draws the summed grasps (default: a fixed seed, so a fit is reproducible).

    Returns:
        ``(choice, nll)``: ``None`` or the winning name, and the held-out NLL of each (``None`` for the temperature).
    """
    S, Y = _check(scores, y)
    candidates = check_corrections(candidates)
    rng = np.random.default_rng(0) if rng is None else rng
    K = S.shape[1]
    rows = [np.flatnonzero(Y == c) for c in range(K)]
    if min(len(r) for r in rows) < 2:
        raise ValueError("select_calibration needs >= 2 validation scores of every class, got "
                         f"{[len(r) for r in rows]}")
    A = np.concatenate([r[: len(r) // 2] for r in rows])
    B = np.concatenate([r[len(r) // 2:] for r in rows])
    fits = {None: (lambda s: s)} | {c: CORRECTIONS[c](S[A], Y[A]) for c in candidates}
    nll = {}
    for name, f in fits.items():
        T = fit_temperature(*sequence_scores(f(S[A]), Y[A], calibrate_grasps, rng))
        nll[name] = tempered_nll(*sequence_scores(f(S[B]), Y[B], horizon, rng), T)
    return min(nll, key=nll.get), nll


def select_correction(scores, y, *, calibrate_grasps: int = 1, horizon: int = SELECT_GRASPS,
                      rng: np.random.Generator | None = None) -> tuple[bool, float, float]:
    """Whether the learned correction improves the KDE's calibrated posteriors, judged on held-out validation scores.

    Each class's rows are halved: both calibrations (the temperature alone, and :func:`fit_correction` then the
    temperature, each fitted for ``calibrate_grasps``-grasp beliefs as the KDE does) are fitted on the first
    halves and scored on the second by the mean NLL of the true class after ``k = 1 .. horizon`` summed grasps of one
    object (:func:`sequence_scores`). The default scores the one-shot posterior (a proper scoring rule); on the
    validation grasps of the analyses' object sets its choice agreed with BC-NP's success at the stop in every cell
    where the two calibrations differed by more than a point, while ``horizon = 10`` once dropped a correction that
    kept the one-shot ECE under 0.05 (RESULTS.md).

    Args:
        scores: ``(B, K)`` raw validation log-likelihoods; every class needs >= 2 rows.
        y: ``(B,)`` true classes.
        calibrate_grasps: the temperature's belief length (``KDEConfig.calibrate_grasps``).
        horizon: longest held-out belief scored.
        rng: draws the summed grasps (default: a fixed seed, so a fit is reproducible).

    Returns:
        ``(use, nll_temperature, nll_correction)``.
    """
    choice, nll = select_calibration(scores, y, ("matrix",), calibrate_grasps=calibrate_grasps, horizon=horizon,
                                     rng=rng)
    return choice == "matrix", float(nll[None]), float(nll["matrix"])


def reliability(proba, y, bins: int = 10) -> dict[str, np.ndarray]:
    """Reliability diagram data of ``proba (B, K)``: per equal-width confidence bin ``[k / bins, (k + 1) / bins)``
    (the last one closed), the mean confidence, the accuracy and the count (``nan`` for empty bins)."""
    P, Y = _check(proba, y)
    whole_at_least(bins, 1, "bins")
    bad = ~((P >= 0) & (P <= 1)).all(axis=1) | (P.sum(axis=1) > 1 + 1e-6)
    if bad.any():  # log-probabilities or scores gave an ECE (above 1 at times) without a word
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"proba must hold probabilities (each in [0, 1], each row summing to at most 1), got row "
                         f"{i}: {P[i].tolist()}")
    conf = P.max(axis=1)
    hit = (P.argmax(axis=1) == Y).astype(np.float64)
    edges = np.arange(bins + 1) / bins  # each edge the double nearest k / bins (linspace puts 0.3 a hair above 0.3)
    which = np.clip(np.searchsorted(edges, conf, side="right") - 1, 0, bins - 1)  # bins [k / bins, (k + 1) / bins)
    count = np.bincount(which, minlength=bins).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_conf = np.bincount(which, conf, bins) / count
        acc = np.bincount(which, hit, bins) / count
    return {"edges": edges, "confidence": mean_conf, "accuracy": acc, "count": count}


def expected_calibration_error(proba, y, bins: int = 10) -> float:
    """ECE: the count-weighted mean ``|accuracy - confidence|`` over :func:`reliability`'s bins."""
    r = reliability(proba, y, bins)
    ok = r["count"] > 0
    if not ok.any():
        return 0.0
    w = r["count"][ok] / r["count"].sum()
    return float(np.sum(w * np.abs(r["accuracy"][ok] - r["confidence"][ok])))
