"""scikit-learn baselines expose the same predict_proba interface as the MLP."""

import numpy as np
import pytest

from haptic_env.recognizers.baselines import CLASSIFIERS, make_classifier


@pytest.mark.parametrize("name", [c for c in CLASSIFIERS if c != "mlp"])
def test_baseline_interface(name):
    rng = np.random.default_rng(0)
    centres = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0]], dtype=float)
    y = np.repeat(np.arange(3), 150)
    X = centres[y] + rng.normal(size=(450, 3))
    cfg = {"max_train": 90} if name == "gp" else {}
    if name == "random-forest":
        cfg["n_jobs"] = 1
    clf = make_classifier(name, seed=0, **cfg).fit(X, y, n_classes=4)  # class 3 never seen
    P = clf.predict_proba(X[:40])
    assert P.shape == (40, 4) and np.allclose(P.sum(1), 1.0) and np.all(P[:, 3] == 0)
    assert clf.score(X, y) > 0.85
    assert list(clf.classes_) == [0, 1, 2, 3]


def test_unknown_classifier():
    with pytest.raises(ValueError, match="unknown"):
        make_classifier("xgboost")
    assert make_classifier("mlp", depth=1, width=4).config.width == 4
