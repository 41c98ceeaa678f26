"""The compiled k-d tree of the pooled KDE against scipy's cKDTree."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from haptic_env.recognizers.knn import KDTree


@pytest.mark.parametrize("leafsize", [1, 8, 32])
def test_exact_search_matches_ckdtree(leafsize):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(3000, 5)) * [1.0, 2.0, 0.5, 1.0, 3.0]
    Z = rng.normal(size=(50, 5))
    tree, ref = KDTree(X, leafsize=leafsize), cKDTree(X)
    d, i = tree.query(Z, k=12)
    dr, ir = ref.query(Z, k=12)
    np.testing.assert_allclose(d, dr, rtol=1e-6, atol=1e-6)  # float32 storage
    np.testing.assert_array_equal(i, ir)
    np.testing.assert_allclose(tree.data, X[tree.indices].astype(np.float32))


def test_approximate_search_keeps_the_eps_guarantee():
    rng = np.random.default_rng(1)
    X, Z = rng.normal(size=(5000, 8)), rng.normal(size=(100, 8))
    d, i = KDTree(X).query(Z, k=16, eps=2.0)
    exact, _ = cKDTree(X).query(Z, k=16)
    assert np.all(np.diff(d, axis=1) >= 0)  # sorted
    assert np.all(d <= 3.0 * exact + 1e-6)  # j-th found within (1 + eps) x the true j-th
    np.testing.assert_allclose(d, np.linalg.norm(X[i] - Z[:, None], axis=-1), rtol=1e-5, atol=1e-6)


def test_duplicates_k_equals_n_and_errors():
    X = np.zeros((40, 3))
    X[20:] = 1.0
    d, i = KDTree(X, leafsize=4).query(np.array([[0.1, 0.0, 0.0]]), k=40)
    assert sorted(i[0].tolist()) == list(range(40))
    np.testing.assert_allclose(d[0, :20], 0.1, rtol=1e-6)
    with pytest.raises(ValueError, match="k must be"):
        KDTree(X).query(np.zeros((1, 3)), k=41)
    with pytest.raises(ValueError, match="shape"):
        KDTree(X).query(np.zeros((1, 2)), k=1)
    with pytest.raises(ValueError, match="non-empty"):
        KDTree(np.zeros((0, 3)))
    for bad in (np.nan, np.inf):  # as cKDTree (they gave NaN / inf distances and arbitrary neighbours)
        with pytest.raises(ValueError, match="query row 1 is not finite"):
            KDTree(X).query(np.array([[0.0, 0, 0], [bad, 0, 0]]), k=1)
        Y = X.copy()
        Y[7, 2] = bad
        with pytest.raises(ValueError, match="KDTree data row 7 is not finite"):
            KDTree(Y)
