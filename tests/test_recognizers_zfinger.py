"""z-finger subset enumeration and sub-grasp vectors."""

from math import comb

import numpy as np
import pytest

from haptic_env.grasp_features import feature_dim, phi
from haptic_env.recognizers.zfinger import sample_finger_counts, subset_vectors, subsets


def test_all_subsets_enumerated():
    S = subsets(5, 3)
    assert S.shape == (comb(5, 3), 3)
    assert len({tuple(r) for r in S}) == len(S) and np.all(np.diff(S, axis=1) > 0)


def test_random_subsets_distinct_and_seeded():
    a = subsets(10, 4, k=4, rng=np.random.default_rng(0))
    b = subsets(10, 4, k=4, rng=np.random.default_rng(0))
    assert a.shape == (4, 4) and np.array_equal(a, b) and len({tuple(r) for r in a}) == 4
    assert subsets(4, 3, k=10, rng=np.random.default_rng(0)).shape == (4, 3)  # k >= C(n,z): all
    big = subsets(40, 6, k=5, rng=np.random.default_rng(1))
    assert big.shape == (5, 6) and len({tuple(r) for r in big}) == 5
    with pytest.raises(ValueError, match="rng"):
        subsets(6, 3, k=2)
    with pytest.raises(ValueError, match="z="):
        subsets(3, 4)


def test_subset_vectors_match_phi_of_each_subset():
    rng = np.random.default_rng(2)
    P = rng.normal(size=(5, 3))
    N = rng.normal(size=(5, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    Q = subset_vectors(P, N, 3)
    assert Q.shape == (10, feature_dim(3, True))
    for row, idx in zip(Q, subsets(5, 3)):
        assert np.allclose(row, phi(P[idx], N[idx]).q)
    whole = subset_vectors(P, N)  # z=None: the whole grasp
    assert np.allclose(whole, phi(P, N).q[None])


def test_touched_mask_gives_incomplete_grasp():
    rng = np.random.default_rng(3)
    P = rng.normal(size=(4, 3))
    touched = np.array([True, False, True, True])
    Q = subset_vectors(P, None, touched=touched)
    assert np.allclose(Q, phi(P[touched]).q[None])
    assert subset_vectors(P, None, 4, touched=touched).shape == (0, feature_dim(4, False))


def test_sample_finger_counts():
    z = sample_finger_counts({2: 0.0, 3: 1.0, 4: 3.0}, 4000, np.random.default_rng(0))
    assert set(np.unique(z)) == {3, 4} and abs(np.mean(z == 4) - 0.75) < 0.03
    with pytest.raises(ValueError, match="p_n"):
        sample_finger_counts({1: 1.0}, 3, np.random.default_rng(0))
