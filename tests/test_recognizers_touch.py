"""The touch-pattern likelihood P(pattern | object): codes, the smoothed table, bad input, and a hand's own pool."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp

from haptic_env.recognizers.touch import MAX_TOUCH_FINGERS, TouchModel, touch_patterns


def test_touch_patterns_set_one_bit_per_touching_fingertip():
    T = np.array([[True, False, True], [False, False, False], [True, True, True]])
    assert touch_patterns(T).tolist() == [5, 0, 7]
    assert touch_patterns(T[0]).shape == ()  # one grasp -> one code
    assert touch_patterns(np.zeros((2, 4, 5), dtype=bool)).shape == (2, 4)
    np.testing.assert_array_equal(touch_patterns(T.astype(int)), touch_patterns(T))  # 0/1 as booleans
    with pytest.raises(ValueError, match="booleans"):
        touch_patterns(np.array([[0, 2, 1]]))
    with pytest.raises(ValueError, match="shape"):
        touch_patterns(np.zeros((3, MAX_TOUCH_FINGERS + 1), dtype=bool))
    with pytest.raises(ValueError, match="shape"):
        touch_patterns(np.zeros((3, 0), dtype=bool))


def test_fit_gives_smoothed_normalised_frequencies_per_object():
    # object 0: 3 complete grasps and 1 miss of 4 approaches; object 1: 2 approaches (the padded rows are ignored)
    T = np.zeros((2, 4, 2), dtype=bool)
    T[0, :3] = True
    T[1, 0] = [True, False]
    T[1, 2:] = True  # padding beyond counts[1] = 2: must not count
    model = TouchModel.fit(T, counts=np.array([4, 2]), alpha=1.0)
    assert model.log_p.shape == (2, 4) and model.n_classes == 2 and model.n_fingers == 2
    np.testing.assert_allclose(logsumexp(model.log_p, axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.exp(model.log_p[0]), [2 / 8, 1 / 8, 1 / 8, 4 / 8])  # codes 0, 1, 2, 3
    np.testing.assert_allclose(np.exp(model.log_p[1]), [2 / 6, 2 / 6, 1 / 6, 1 / 6])
    L = model.log_likelihood(np.array([[True, True], [False, False]]))
    np.testing.assert_allclose(L, model.log_p[:, [3, 0]].T)
    assert model.log_likelihood(np.array([True, False])).shape == (1, 2)
    assert np.isfinite(TouchModel.fit(np.zeros((2, 3, 3), dtype=bool)).log_p).all()  # unseen patterns: finite
    assert model.accuracy(np.array([[True, True], [True, False]]), [0, 1]) == 1.0


def test_fit_and_score_reject_bad_input():
    T = np.zeros((2, 4, 3), dtype=bool)
    with pytest.raises(ValueError, match="alpha"):
        TouchModel.fit(T, alpha=0.0)
    with pytest.raises(ValueError, match="alpha"):
        TouchModel.fit(T, alpha=np.nan)
    with pytest.raises(ValueError, match="counts"):
        TouchModel.fit(T, counts=np.array([4, 5]))
    with pytest.raises(ValueError, match="counts"):
        TouchModel.fit(T, counts=np.array([0, 4]))
    with pytest.raises(ValueError, match=r"\(K, A, n\)"):
        TouchModel.fit(T[0])
    with pytest.raises(ValueError, match="shape"):
        TouchModel.fit(T).log_likelihood(np.zeros((2, 4), dtype=bool))


def test_a_hands_recogniser_estimates_its_touch_model_from_its_training_pool():
    """build_recognizer(touch=True) reads the same hand pool as the training grasps (generic hand: no data needed)."""
    from haptic_env.dataset import DatasetConfig
    from haptic_env.hand_grasps import hand_grasp_pool
    from haptic_env.objects import load_object_set
    from haptic_env.recognizers import RecognizerConfig, build_recognizer

    objs = load_object_set("default").subset(("can", "mug"), name="can-mug")
    g = DatasetConfig(source="hand", hand="generic", grasps_per_object=40, seed=5)
    rec = build_recognizer(objs, 3, True, config=RecognizerConfig(grasps=g), models=("kde",), touch=True,
                           progress=False)
    pool = hand_grasp_pool(objs, "generic", 3, 40, seed=5, progress=False)
    np.testing.assert_array_equal(rec.touch.log_p, TouchModel.from_pool(pool).log_p)
    assert build_recognizer(objs, 3, True, config=RecognizerConfig(grasps=g), models=("kde",),
                            progress=False).touch is None
    with pytest.raises(ValueError, match="hand-matched"):
        build_recognizer(objs, 3, True, config=RecognizerConfig(grasps=DatasetConfig(grasps_per_object=50)),
                         models=("kde",), touch=True, progress=False)
