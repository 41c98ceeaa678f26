"""Gradient boosting as the beliefs' likelihood: an opt-in alternative to the KDE (``RecognizerConfig.likelihood``).

BC-NP multiplies one grasp's likelihood ``p(q | object)`` after another. By Bayes, a classifier's posterior gives it
up to a factor that is the same for every object: ``log p(q | k) = log p(k | q) - log p(k) + log p(q)``. So a
well-trained classifier of the grasp vectors is a likelihood, and on experiment 2's kit8 cells without normals at
n = 4 and 5 scikit-learn's histogram gradient boosting tells the objects apart with fewer grasps than the KDE at the
same rate of right stops (chosen on validation grasps, ``benchmarks/stop_classifier.py``, then tested once; RESULTS.md,
"Gradient boosting as experiment 2's likelihood"). It is not the paper's method, so the KDE stays the default.

:class:`BoostedLikelihood` has the KDE's scoring interface (``log_likelihood (m, d) -> (m, K)``,
``calibrate_scores``, ``temperature``, ``n_classes``), so a :class:`~haptic_env.recognizers.recognizer.ModelBank`
holds it in the KDE's place. By default it carries no temperature of its own (1): experiment 2's stop scale, fitted on
validation trials, scales its scores as it scales the KDE's. With ``BoostedConfig.calibrate_grasps >= 1`` it fits a
sequence temperature on the validation vectors as the KDE does (``KDEConfig.calibrate_grasps``; the hand envs).

Scoring walks the fitted trees in one compiled call (:func:`_raw_scores`, numba) instead of scikit-learn's
``predict_proba``, whose per-call overhead (about 50 ms for one vector of a 2,000-tree model) would dwarf an env step;
the two agree to rounding (tested). In an env the trees (a few MB) have left the CPU caches by the next grasp, so
each node read waits on memory: the walk packs each node in 16 bytes with its two children side by side
(:func:`_flatten`) and walks an iteration's per-class trees together, so that their reads overlap
(``benchmarks/bench_boosted.py``, "cold cache").
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.special import expit, softmax

from haptic_env.cache import KEY_ONLY_WHEN_SET
from haptic_env.numbers import whole_at_least
from haptic_env.recognizers.calibration import check_calibrate_grasps
from haptic_env.recognizers.preprocess import class_count

__all__ = ["BoostedConfig", "BoostedLikelihood", "LIKELIHOODS", "check_likelihood"]

#: the likelihoods a recogniser can hold in the beliefs' slot (``RecognizerConfig.likelihood``)
LIKELIHOODS = ("kde", "hgb")


def check_likelihood(value) -> None:
    """Raise ValueError naming ``value`` unless it is one of :data:`LIKELIHOODS`."""
    if value not in LIKELIHOODS:
        raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {value!r}")


@dataclass(frozen=True)
class BoostedConfig:
    """Settings of :class:`BoostedLikelihood` (the ones ``benchmarks/stop_classifier.py`` validated).

    ``max_iter`` boosting iterations at most, early stopping on 10 % of the training vectors (scikit-learn's own
    split, ``seed``); at most ``max_train_per_class`` training vectors of each object (the first ones of the data
    set's training split, whose order is random); each class probability floored at ``floor`` before its log.
    ``calibrate_grasps``: 0 (the default), no temperature; ``k >= 1``, a temperature fitted on at most
    ``n_calibrate`` validation vectors per object for beliefs of ``1 .. k`` grasps of one object
    (:func:`~.calibration.sequence_scores`, as ``KDEConfig.calibrate_grasps``).
    """

    max_iter: int = 300
    max_train_per_class: int = 50_000
    floor: float = 1e-6
    seed: int = 0
    calibrate_grasps: int = field(default=0, metadata={KEY_ONLY_WHEN_SET: True})
    n_calibrate: int = field(default=1_000, metadata={KEY_ONLY_WHEN_SET: True})

    def __post_init__(self):
        whole_at_least(self.max_iter, 1, "max_iter")
        whole_at_least(self.max_train_per_class, 1, "max_train_per_class")
        whole_at_least(self.seed, 0, "seed")
        check_calibrate_grasps(self.calibrate_grasps, 0, "calibrate_grasps")
        whole_at_least(self.n_calibrate, 1, "n_calibrate")
        if isinstance(self.floor, bool) or not (isinstance(self.floor, (int, float)) and 0.0 < self.floor < 1.0):
            raise ValueError(f"floor must be a number in (0, 1), got {self.floor!r}")


class BoostedLikelihood:
    """``log p(q | k) = log max(p(k | q), floor) - log prior_k`` (up to a term shared by every ``k``) from a histogram
    gradient-boosting classifier; ``prior_k`` is object ``k``'s share of the vectors it was trained on."""

    def __init__(self, config: BoostedConfig | None = None):
        self.config = config or BoostedConfig()
        self.clf = None
        self.log_prior: np.ndarray | None = None
        #: the calibration temperature ``T`` (``calibrate_grasps >= 1``; 1: none): :meth:`calibrate_scores` divides
        #: by it (``ModelBank`` reads it and :attr:`calibrated`)
        self.temperature = 1.0
        self._trees: tuple | bool | None = None  # the fitted trees as packed arrays (:func:`_flatten`), set with clf

    @property
    def calibrated(self) -> bool:
        """Whether :meth:`calibrate_scores` changes anything."""
        return self.temperature != 1.0

    @property
    def n_classes(self) -> int:
        return 0 if self.log_prior is None else len(self.log_prior)

    @property
    def n_features(self) -> int:
        """The grasp-vector length it was fitted on (0 before :meth:`fit`)."""
        return 0 if self.clf is None else int(self.clf.n_features_in_)

    def fit(self, X: np.ndarray, y: np.ndarray, X_val=None, y_val=None, n_classes: int | None = None):
        """Train on ``X (m, d)``, ``y (m,)`` in ``0..n_classes-1`` (every class present). Early stopping draws its
        own 10 % of ``X``; ``X_val``/``y_val`` fit the temperature (``calibrate_grasps >= 1``; without them it
        stays 1, as the KDE's)."""
        from sklearn.ensemble import HistGradientBoostingClassifier

        X, y = np.asarray(X, dtype=np.float64), np.asarray(y)
        if X.ndim != 2 or y.shape != (len(X),):
            raise ValueError(f"X must be (m, d) and y (m,), got {X.shape} and {y.shape}")
        if not np.isfinite(X).all():
            raise ValueError("X holds non-finite values")
        if not np.issubdtype(y.dtype, np.integer):
            raise ValueError(f"y must hold integer class labels, got dtype {y.dtype}")
        if len(y) == 0:
            raise ValueError("no training vectors (X and y are empty)")
        if y.min() < 0:
            raise ValueError(f"class labels must be >= 0, got a label {int(y.min())}")
        k = class_count(n_classes, y)
        counts = np.bincount(y, minlength=k)
        if not (counts > 0).all():
            raise ValueError(f"every one of the {k} classes needs training vectors, got counts {counts.tolist()}")
        keep = np.zeros(len(y), dtype=bool)
        for c in range(k):
            keep[np.flatnonzero(y == c)[: self.config.max_train_per_class]] = True
        X, y = X[keep], y[keep]
        # early stopping holds out a stratified 10 %: it needs 2 vectors of each class and room for every class on
        # both sides; with fewer (a hand whose grasps of an object rarely complete) all max_iter iterations are fit
        kept, held = np.bincount(y, minlength=k), -(-len(y) // 10)
        early = bool(kept.min() >= 2 and k <= held <= len(y) - k)
        self.clf = HistGradientBoostingClassifier(max_iter=self.config.max_iter, early_stopping=early,
                                                  random_state=self.config.seed).fit(X, y)
        self.log_prior = np.log(kept / len(y))
        self._trees, self.temperature = _flatten(self.clf), 1.0
        if self.config.calibrate_grasps and X_val is not None:
            self._fit_temperature(np.asarray(X_val, dtype=np.float64), np.asarray(y_val), X.shape[1])
        return self

    def _fit_temperature(self, Xv: np.ndarray, yv: np.ndarray, d: int) -> None:
        from haptic_env.recognizers.calibration import calibration_rows, fit_temperature, sequence_scores

        if Xv.ndim != 2 or Xv.shape[1] != d or yv.shape != (len(Xv),):
            raise ValueError(f"X_val must be (m, {d}) and y_val (m,), got {Xv.shape} and {yv.shape}")
        rng = np.random.default_rng(self.config.seed)
        keep = calibration_rows(yv, self.n_classes, self.config.n_calibrate, rng)
        S, Y = sequence_scores(self.log_likelihood(Xv[keep]), yv[keep], self.config.calibrate_grasps, rng)
        self.temperature = fit_temperature(S, Y)

    def log_likelihood(self, Q) -> np.ndarray:
        """``(m, d) -> (m, K)`` log-likelihoods (up to a per-row constant)."""
        if self.clf is None:
            raise RuntimeError("BoostedLikelihood is not fitted: call fit first")
        Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        if Q.ndim != 2 or Q.shape[1] != self.clf.n_features_in_:
            raise ValueError(f"Q must be (m, {self.clf.n_features_in_}), got {Q.shape}")
        if not np.isfinite(Q).all():  # the compiled walk has no missing-value branch (nor has the training data)
            raise ValueError("Q holds non-finite values")
        if self._trees is False:  # a scikit-learn whose trees this module cannot read: its own (slower) path
            proba = self.clf.predict_proba(Q)
        else:
            baseline, (nodes, roots) = self._trees
            raw = np.empty((len(Q), len(baseline)))
            _raw_scores(np.ascontiguousarray(Q), baseline, nodes, roots, raw)
            if raw.shape[1] == 1:  # two classes: one tree per iteration, scikit-learn's sigmoid
                proba = np.column_stack([expit(-raw[:, 0]), expit(raw[:, 0])])
            else:
                proba = softmax(raw, axis=1)
        if self.n_classes == 1:  # scikit-learn fits one class as two (the second never seen): (m, 1) as the KDE's
            proba = proba[:, :1]
        return np.log(np.maximum(proba, self.config.floor)) - self.log_prior

    def calibrate_scores(self, ll: np.ndarray) -> np.ndarray:
        """``ll`` divided by the temperature (unchanged at 1, the default)."""
        return ll / self.temperature if self.temperature != 1.0 else ll

    def to_bytes(self) -> bytes:
        """The fitted model as bytes (a pickle; load only from a trusted, digest-checked cache)."""
        if self.clf is None:
            raise RuntimeError("BoostedLikelihood is not fitted: nothing to save")
        return pickle.dumps({"clf": self.clf, "log_prior": self.log_prior, "temperature": self.temperature},
                            protocol=pickle.HIGHEST_PROTOCOL)

    @classmethod
    def from_bytes(cls, config: BoostedConfig, blob: bytes) -> BoostedLikelihood:
        try:  # a model pickled by other library versions may not load: the caller rebuilds it
            state = pickle.loads(blob)  # noqa: S301 - the caller checked the file's digest first
        except Exception as exc:
            raise ValueError(f"the saved model does not load here: {exc!r}") from exc
        if not (isinstance(state, dict) and {"clf", "log_prior"} <= state.keys()):
            raise ValueError("not a BoostedLikelihood state")
        out = cls(config)
        out.clf, out.log_prior = state["clf"], np.asarray(state["log_prior"], dtype=np.float64)
        out.temperature = float(state.get("temperature", 1.0))
        out._trees = _flatten(out.clf)  # here, not at the first score: an env's first step stays as fast as the rest
        if out.log_prior.ndim != 1 or len(getattr(out.clf, "classes_", ())) != len(out.log_prior):
            raise ValueError("the saved classifier and its priors disagree on the number of classes")
        return out


def _flatten(clf):
    """The fitted trees of a ``HistGradientBoostingClassifier`` packed for :func:`_raw_scores`:
    ``(baseline (T,), (nodes (N, 2), roots (iterations, T)))``. Each tree's nodes are renumbered breadth-first, so
    that a split's two children are neighbours (the right one follows the left one); a node's row is ``(threshold,
    feature * 2**32 + left child)`` at a split and ``(value, -1)`` at a leaf, 16 bytes, all float64 (exact: features <
    2**20 and nodes < 2**32 are checked). False where they cannot be read (categorical splits, or a scikit-learn whose
    private tree layout differs)."""
    try:
        predictors, baseline = clf._predictors, np.asarray(clf._baseline_prediction, dtype=np.float64).ravel()
        nodes = [p.nodes for it in predictors for p in it]
        if any(len(it) != len(baseline) for it in predictors) or any(n["is_categorical"].any() for n in nodes):
            return False
        sizes = np.array([len(n) for n in nodes])
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        # field by field: concatenating the structured records themselves is 10x slower (NumPy promotes each dtype)
        flat = {f: np.concatenate([n[f] for n in nodes])
                for f in ("is_leaf", "feature_idx", "left", "right", "num_threshold", "value")}
        if sizes.sum() >= 2**32 or clf.n_features_in_ >= 2**20:
            return False
        shift = np.repeat(offsets, sizes)
        links = np.column_stack([np.where(flat["is_leaf"].astype(bool), -1, flat["feature_idx"]),
                                 flat["left"].astype(np.int64) + shift, flat["right"].astype(np.int64) + shift])
        numbers = np.column_stack([flat["num_threshold"], flat["value"]]).astype(np.float64)
        roots = offsets.reshape(len(predictors), len(baseline)).astype(np.int64)
    except (AttributeError, KeyError, TypeError, ValueError):
        return False
    packed, new_roots = np.empty((len(links), 2)), np.empty_like(roots)
    _pack(np.ascontiguousarray(links, dtype=np.int64), np.ascontiguousarray(numbers), roots, packed, new_roots)
    return baseline, (packed, new_roots)


@njit(cache=True)
def _pack(links, numbers, roots, packed, new_roots):
    """Renumber every tree breadth-first into ``packed`` (the rows :func:`_flatten` documents). ``links (N, 3)``:
    (feature or -1 at a leaf, left, right) with global node indices; ``numbers (N, 2)``: (threshold, value)."""
    queue = np.empty(len(links), np.int64)  # one tree's old nodes in breadth-first order: its new index - start
    start = 0
    for it in range(roots.shape[0]):
        for t in range(roots.shape[1]):
            new_roots[it, t] = start
            queue[0] = roots[it, t]
            head, tail = 0, 1
            while head < tail:
                old = queue[head]
                row = start + head
                head += 1
                f = links[old, 0]
                if f < 0:
                    packed[row, 0] = numbers[old, 1]
                    packed[row, 1] = -1.0
                else:
                    queue[tail] = links[old, 1]
                    queue[tail + 1] = links[old, 2]
                    packed[row, 0] = numbers[old, 0]
                    packed[row, 1] = f * 4294967296.0 + (start + tail)
                    tail += 2
            start += tail


@njit(cache=True)
def _raw_scores(X, baseline, nodes, roots, out):
    """``out[i, t]`` = the baseline plus every iteration's tree ``t`` at ``X[i]`` (scikit-learn's raw prediction,
    summed in its order: ``x <= threshold`` goes left). The ``T`` trees of one iteration are walked a level at a time
    together: their memory reads do not wait on each other."""
    T = roots.shape[1]
    at = np.empty(T, np.int64)
    for i in range(X.shape[0]):
        for t in range(T):
            out[i, t] = baseline[t]
        for it in range(roots.shape[0]):
            for t in range(T):
                at[t] = roots[it, t]
            moving = True
            while moving:
                moving = False
                for t in range(T):
                    node = at[t]
                    code = nodes[node, 1]
                    if code >= 0.0:
                        c = np.int64(code)
                        at[t] = (c & 0xFFFFFFFF) + (0 if X[i, c >> 32] <= nodes[node, 0] else 1)
                        moving = True
            for t in range(T):
                out[i, t] += nodes[at[t], 0]
