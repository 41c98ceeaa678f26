"""Torch-free helpers shared by the models: feature standardisation and input checks.

(The KDE imports these; keeping them out of :mod:`.mlp` keeps ``import haptic_env.recognizers.kde`` free of torch.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from haptic_env.numbers import whole_at_least

__all__ = ["Standardizer", "check_xy", "class_count"]


@dataclass(frozen=True)
class Standardizer:
    """Per-feature ``(x - mean) / std``; constant features get std 1."""

    mean: np.ndarray  #: (d,)
    std: np.ndarray  #: (d,)

    @classmethod
    def fit(cls, X: np.ndarray) -> Standardizer:
        X = np.asarray(X, dtype=np.float64)
        std = X.std(axis=0)
        return cls(X.mean(axis=0), np.where(std > 1e-12, std, 1.0))

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return (np.asarray(X, dtype=np.float64) - self.mean) / self.std


def check_xy(X, y=None, d: int | None = None, what: str = "X"):
    X = np.asarray(X)
    if X.ndim != 2:
        raise ValueError(f"{what} must have shape (B, d), got {X.shape}")
    if d is not None and X.shape[1] != d:
        raise ValueError(f"{what} has {X.shape[1]} features, the model expects {d}")
    if not np.isfinite(X).all():
        i = int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])
        raise ValueError(f"{what} row {i} is not finite: {X[i].tolist()}")
    if y is None:
        return X
    y = np.asarray(y)
    if y.shape != (X.shape[0],):
        raise ValueError(f"labels must have shape ({X.shape[0]},), got {y.shape}")
    if not np.issubdtype(y.dtype, np.integer) or (y < 0).any():
        raise ValueError("labels must be non-negative integers (class indices)")
    return X, y.astype(np.int64)


def check_validation_pair(X_val, y_val) -> None:
    """A ``ValueError`` when only one of a fit's ``X_val`` / ``y_val`` is given (the labels were unpacked from the
    vectors' rows: a numpy error, or a fit on the wrong rows)."""
    if (X_val is None) != (y_val is None):
        raise ValueError("X_val and y_val go together: got " + ("X_val without y_val" if y_val is None
                                                               else "y_val without X_val"))


def class_count(n_classes, *labels) -> int:
    """The classes a model is fitted for: ``n_classes`` (an int >= 1), or with None one more than the largest of
    ``labels`` (class-index arrays: the training labels, and the validation labels where given; None entries are
    skipped). A ``ValueError`` names a label at or past the count, which the model would silently drop or misplace."""
    labels = [np.asarray(y) for y in labels if y is not None]
    top = max((int(y.max()) for y in labels if y.size), default=-1)
    if n_classes is None:
        return top + 1 if top >= 0 else whole_at_least(n_classes, 1, "n_classes")
    k = whole_at_least(n_classes, 1, "n_classes")
    if top >= k:
        raise ValueError(f"class labels must lie in 0..{k - 1} (n_classes={k}), got a label {top}")
    return k
