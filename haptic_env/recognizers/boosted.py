"""Gradient boosting as the beliefs' likelihood: an opt-in alternative to the KDE (``RecognizerConfig.likelihood``).

BC-NP multiplies one grasp's likelihood ``p(q | object)`` after another. By Bayes, a classifier's posterior gives it
up to a factor that is the same for every object: ``log p(q | k) = log p(k | q) - log p(k) + log p(q)``. So a
well-trained classifier of the grasp vectors is a likelihood, and on experiment 2's kit8 cells without normals at
n = 4 and 5 scikit-learn's histogram gradient boosting tells the objects apart with fewer grasps than the KDE at the
same rate of right stops (chosen on validation grasps, ``benchmarks/stop_classifier.py``, then tested once; RESULTS.md,
"Gradient boosting as experiment 2's likelihood"). It is not the paper's method, so the KDE stays the default.

:class:`BoostedLikelihood` has the KDE's scoring interface (``log_likelihood (m, d) -> (m, K)``,
``calibrate_scores``, ``temperature``, ``n_classes``), so a :class:`~haptic_env.recognizers.recognizer.ModelBank`
holds it in the KDE's place. It carries no temperature of its own (1): experiment 2's stop scale, fitted on validation
trials, scales its scores as it scales the KDE's.
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass

import numpy as np

from haptic_env.numbers import whole_at_least

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
    """

    max_iter: int = 300
    max_train_per_class: int = 50_000
    floor: float = 1e-6
    seed: int = 0

    def __post_init__(self):
        whole_at_least(self.max_iter, 1, "max_iter")
        whole_at_least(self.max_train_per_class, 1, "max_train_per_class")
        whole_at_least(self.seed, 0, "seed")
        if isinstance(self.floor, bool) or not (isinstance(self.floor, (int, float)) and 0.0 < self.floor < 1.0):
            raise ValueError(f"floor must be a number in (0, 1), got {self.floor!r}")


class BoostedLikelihood:
    """``log p(q | k) = log max(p(k | q), floor) - log prior_k`` (up to a term shared by every ``k``) from a histogram
    gradient-boosting classifier; ``prior_k`` is object ``k``'s share of the vectors it was trained on."""

    #: no temperature: the stop scale of the analyses scales these scores (``ModelBank`` reads these two)
    temperature = 1.0
    calibrated = False

    def __init__(self, config: BoostedConfig | None = None):
        self.config = config or BoostedConfig()
        self.clf = None
        self.log_prior: np.ndarray | None = None

    @property
    def n_classes(self) -> int:
        return 0 if self.log_prior is None else len(self.log_prior)

    def fit(self, X: np.ndarray, y: np.ndarray, X_val=None, y_val=None, n_classes: int | None = None):
        """Train on ``X (m, d)``, ``y (m,)`` in ``0..n_classes-1`` (every class present); ``X_val``/``y_val`` are
        not used (early stopping draws its own 10 %), accepted for the KDE's signature."""
        from sklearn.ensemble import HistGradientBoostingClassifier

        X, y = np.asarray(X, dtype=np.float64), np.asarray(y)
        if X.ndim != 2 or y.shape != (len(X),):
            raise ValueError(f"X must be (m, d) and y (m,), got {X.shape} and {y.shape}")
        if not np.isfinite(X).all():
            raise ValueError("X holds non-finite values")
        if not np.issubdtype(y.dtype, np.integer):
            raise ValueError(f"y must hold integer class labels, got dtype {y.dtype}")
        k = int(y.max()) + 1 if n_classes is None else int(n_classes)
        counts = np.bincount(y, minlength=k) if len(y) and y.min() >= 0 else np.array([-1])
        if len(counts) != k or not (counts > 0).all():
            raise ValueError(f"every one of the {k} classes needs training vectors, got counts {counts.tolist()}")
        keep = np.zeros(len(y), dtype=bool)
        for c in range(k):
            keep[np.flatnonzero(y == c)[: self.config.max_train_per_class]] = True
        X, y = X[keep], y[keep]
        self.clf = HistGradientBoostingClassifier(max_iter=self.config.max_iter, early_stopping=True,
                                                  random_state=self.config.seed).fit(X, y)
        self.log_prior = np.log(np.bincount(y, minlength=k) / len(y))
        return self

    def log_likelihood(self, Q) -> np.ndarray:
        """``(m, d) -> (m, K)`` log-likelihoods (up to a per-row constant)."""
        if self.clf is None:
            raise RuntimeError("BoostedLikelihood is not fitted: call fit first")
        Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        return np.log(np.maximum(self.clf.predict_proba(Q), self.config.floor)) - self.log_prior

    def calibrate_scores(self, ll: np.ndarray) -> np.ndarray:
        """No calibration of its own: ``ll`` unchanged."""
        return ll

    def to_bytes(self) -> bytes:
        """The fitted model as bytes (a pickle; load only from a trusted, digest-checked cache)."""
        if self.clf is None:
            raise RuntimeError("BoostedLikelihood is not fitted: nothing to save")
        return pickle.dumps({"clf": self.clf, "log_prior": self.log_prior}, protocol=pickle.HIGHEST_PROTOCOL)

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
        if out.log_prior.ndim != 1 or len(getattr(out.clf, "classes_", ())) != len(out.log_prior):
            raise ValueError("the saved classifier and its priors disagree on the number of classes")
        return out
