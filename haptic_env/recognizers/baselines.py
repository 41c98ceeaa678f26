"""scikit-learn baseline classifiers behind the :class:`Classifier` interface of the MLP.

``make_classifier(name, **cfg)`` returns an object with ``fit(X, y, X_val=None, y_val=None)``,
``predict_proba(X (B, d)) -> (B, K)``, ``predict``, ``score``, ``classes_`` and ``n_classes``.
Features are standardised inside each model. Kernel methods do not scale to the paper's
1.6 M training grasps, so each baseline trains on a random subsample of at most ``max_train``
grasps (defaults in :data:`DEFAULT_MAX_TRAIN`; the GP on 1,000), drawn from ``seed``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig, _check_xy
from haptic_env.recognizers.preprocess import class_count

__all__ = ["Classifier", "SklearnClassifier", "make_classifier", "CLASSIFIERS", "DEFAULT_MAX_TRAIN"]


@runtime_checkable
class Classifier(Protocol):
    """What recognisers need from a classifier."""

    n_classes: int

    def fit(self, X, y, X_val=None, y_val=None): ...

    def predict_proba(self, X) -> np.ndarray: ...


#: names accepted by :func:`make_classifier`
CLASSIFIERS = ("mlp", "knn", "linear-svm", "rbf-svm", "gp", "random-forest", "decision-tree")

#: training-set cap per baseline (None: all)
DEFAULT_MAX_TRAIN = {
    "knn": 200_000,
    "linear-svm": 50_000,
    "rbf-svm": 10_000,
    "gp": 1_000,
    "random-forest": 200_000,
    "decision-tree": None,
}


def _estimator(name: str, seed: int, **cfg):
    from sklearn.calibration import CalibratedClassifierCV
    from sklearn.ensemble import RandomForestClassifier
    from sklearn.gaussian_process import GaussianProcessClassifier
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.svm import SVC, LinearSVC
    from sklearn.tree import DecisionTreeClassifier

    if name == "knn":
        return KNeighborsClassifier(n_neighbors=cfg.get("n_neighbors", 15), weights="distance")
    if name == "linear-svm":
        return CalibratedClassifierCV(LinearSVC(C=cfg.get("C", 1.0), dual=False, random_state=seed), cv=3)
    if name == "rbf-svm":
        return CalibratedClassifierCV(SVC(C=cfg.get("C", 10.0), gamma="scale", random_state=seed), cv=3, ensemble=False)
    if name == "gp":
        # one-vs-rest Laplace GP with a fixed kernel on standardised features (length scale
        # ~ typical nearest-class distances; optimising it on small one-vs-rest subsamples tends to
        # run to the flat upper bound and predict the prior)
        ls = cfg.get("length_scale", 2.0)
        return GaussianProcessClassifier(ConstantKernel(cfg.get("amplitude", 9.0), "fixed") * RBF(ls, "fixed"),
                                         optimizer=None, random_state=seed)
    if name == "random-forest":
        return RandomForestClassifier(n_estimators=cfg.get("n_estimators", 100), min_samples_leaf=cfg.get("min_samples_leaf", 2),
                                      n_jobs=cfg.get("n_jobs", -1), random_state=seed)
    if name == "decision-tree":
        return DecisionTreeClassifier(min_samples_leaf=cfg.get("min_samples_leaf", 5), random_state=seed)
    raise ValueError(f"unknown classifier {name!r}; choose one of {CLASSIFIERS}")


class SklearnClassifier:
    """A standardising scikit-learn classifier trained on at most ``max_train`` grasps."""

    def __init__(self, name: str, *, max_train: int | None | str = "default", seed: int = 0, **cfg):
        if name not in CLASSIFIERS or name == "mlp":
            raise ValueError(f"unknown scikit-learn baseline {name!r}; choose one of {CLASSIFIERS[1:]}")
        self.name = name
        self.max_train = DEFAULT_MAX_TRAIN[name] if max_train == "default" else max_train
        self.seed = seed
        self.cfg = cfg
        self.model = None
        self.n_classes = 0

    @property
    def classes_(self) -> np.ndarray:
        return np.arange(self.n_classes)

    def fit(self, X, y, X_val=None, y_val=None, *, n_classes: int | None = None) -> SklearnClassifier:
        """Fit on ``X (N, d)``, ``y (N,)``; the validation set is unused (accepted for the interface)."""
        from sklearn.pipeline import make_pipeline
        from sklearn.preprocessing import StandardScaler

        X, y = _check_xy(X, y)
        self.n_classes = class_count(n_classes, y)
        if self.max_train is not None and len(X) > self.max_train:
            rng = np.random.default_rng(self.seed)
            idx = rng.choice(len(X), self.max_train, replace=False)
            X, y = X[idx], y[idx]
        self.model = make_pipeline(StandardScaler(), _estimator(self.name, self.seed, **self.cfg))
        self.model.fit(X, y)
        self._cols = np.asarray(self.model.classes_, dtype=np.int64)
        return self

    def predict_proba(self, X) -> np.ndarray:
        """``(B, d) -> (B, K)``; classes absent from the training subsample get probability 0."""
        if self.model is None:
            raise RuntimeError(f"{self.name} classifier is not fitted")
        X = _check_xy(np.atleast_2d(X))
        out = np.zeros((len(X), self.n_classes))
        out[:, self._cols] = self.model.predict_proba(X)
        return out

    def predict(self, X) -> np.ndarray:
        return self.predict_proba(X).argmax(axis=1)

    def score(self, X, y) -> float:
        return float(np.mean(self.predict(X) == np.asarray(y)))


def make_classifier(name: str, **cfg):
    """A classifier by name (see :data:`CLASSIFIERS`).

    ``"mlp"`` takes :class:`MLPConfig` fields (or ``config=MLPConfig(...)``); the scikit-learn
    baselines take ``max_train``, ``seed`` and their hyper-parameters (``n_neighbors``, ``C``,
    ``n_estimators``, ``min_samples_leaf``).
    """
    if name == "mlp":
        config = cfg.pop("config", None) or MLPConfig()
        return MLPClassifier(config, **cfg)
    return SklearnClassifier(name, **cfg)
