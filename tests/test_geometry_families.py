"""Geometry families (issue 6): the family generator's scale range, experiment 5's helpers and labels."""

import numpy as np
import pytest

from haptic_env.objects import FAMILIES, family_set
from haptic_env.experiments import EXPECTED_FAMILY, family_temperatures, family_trials


def test_family_set_scale_range():
    fs = family_set(2, np.random.default_rng(0), scale_range=(1.0, 1.0))
    ext = {o.name: np.sort(o.mesh.extents) for o in fs}
    for name, e in ext.items():  # cube, round cylinder (height = diameter), sphere: all extents 0.08 m
        assert np.allclose(e, 0.08, atol=2e-3), (name, e)
    wide = family_set(3, np.random.default_rng(0))  # default range still (0.5, 1.5) x 0.08 m
    e = np.concatenate([o.mesh.extents for o in wide])
    assert e.min() >= 0.04 - 1e-6 and e.max() <= 0.12 + 1e-6 and e.max() - e.min() > 0.02
    with pytest.raises(ValueError):
        family_set(1, np.random.default_rng(0), scale_range=(0.0, 1.0))
    with pytest.raises(ValueError):
        family_set(1, np.random.default_rng(0), scale_range=(1.5, 0.5))


def test_expected_family_labels_are_families():
    assert {v for v in EXPECTED_FAMILY.values() if v is not None} <= set(FAMILIES)
    assert EXPECTED_FAMILY["can"] == "elliptic_cylinder" and EXPECTED_FAMILY["ball"] == "ellipsoid"
    assert EXPECTED_FAMILY["036_wood_block"] == "box" and EXPECTED_FAMILY["hammer"] is None


def test_family_trials_votes_and_decisions():
    rng = np.random.default_rng(0)
    G = 50
    LL = np.tile([[-3.0, 0.0, -3.0]], (G, 1))  # every grasp favours class 1 strongly
    PR = np.tile([[0.02, 0.96, 0.02]], (G, 1))
    for kind in ("ic", "bc-np"):
        votes, decided, used = family_trials(LL, PR, kind, trials=10, max_grasps=30, threshold=0.85, rng=rng)
        assert votes.tolist() == [0, 10, 0] and decided == 10 and used.max() <= 2
    flat = np.zeros((G, 3))  # no information: never decided, all 30 grasps used
    votes, decided, used = family_trials(flat, np.full((G, 3), 1 / 3), "bc-np", trials=5, max_grasps=30,
                                          threshold=0.85, rng=rng)
    assert votes.sum() == 5 and decided == 0 and (used == 30).all()


class _Fixed:
    def __init__(self, S):
        self.S = S

    def log_likelihood(self, X):
        return self.S

    def predict_proba(self, X):
        from scipy.special import softmax

        return softmax(self.S, axis=1)


def test_family_temperatures_flatten_uninformative_scores():
    rng = np.random.default_rng(1)
    y = rng.integers(0, 3, 600)
    noise = rng.normal(0, 5, (600, 3))  # confident scores that carry no information about y
    T_kde, T_mlp = family_temperatures(_Fixed(noise), _Fixed(noise), np.zeros((600, 6)), y)
    assert T_kde > 5 and T_mlp > 5
    good = np.eye(3)[y] * 4.0  # informative scores keep a moderate temperature
    T_kde, _ = family_temperatures(_Fixed(good), _Fixed(good), np.zeros((600, 6)), y)
    assert T_kde < 5
