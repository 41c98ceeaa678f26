"""benchmarks/hand_classifiers.py: a classifier as the belief's likelihood, and its batched scores of the queries'
grasps, which must be those of the stop frontier's per-grasp scorer (the env's way) for the same likelihood."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from haptic_env.dataset import DatasetConfig


@pytest.fixture(scope="module")
def bench(load_benchmark):
    return load_benchmark("hand_classifiers")


def test_classifier_likelihood_divides_by_the_training_prior(bench):
    rng = np.random.default_rng(0)
    X = np.vstack([rng.normal(0, 1, (60, 2)), rng.normal(4, 1, (20, 2)), rng.normal(-4, 1, (20, 2))])
    y = np.repeat([0, 1, 2], [60, 20, 20])
    lik = bench.ClassifierLikelihood("knn", X, y, n_classes=3)
    Q = np.array([[0.0, 0.0], [4.0, 4.0], [-4.0, -4.0]])
    P = lik.proba(Q)
    assert P.shape == (3, 3) and np.allclose(P.sum(1), 1)
    L = lik.log_likelihood(Q)
    np.testing.assert_allclose(L, np.log(np.maximum(P, bench.P_FLOOR)) - np.log([0.6, 0.2, 0.2]))
    np.testing.assert_array_equal(L.argmax(1), [0, 1, 2])
    with pytest.raises(ValueError, match=r"every one of the 4 classes needs training vectors; counts \[60, 20, 20, 0"):
        bench.ClassifierLikelihood("knn", X, y, n_classes=4)


class Linear:
    """A stand-in likelihood of any vector length: a fixed linear map of the vector to K scores."""

    def __init__(self, K: int):
        self.K = K

    def log_likelihood(self, Q):
        Q = np.asarray(Q)
        W = np.cos(np.arange(Q.shape[1] * self.K)).reshape(Q.shape[1], self.K)
        return Q @ W

    def with_calibration(self, flag):
        return self


@pytest.mark.parametrize("z", [None, 3])
@pytest.mark.parametrize("touch_weight", [0.0, 0.5])
def test_batched_scores_are_the_frontier_scorers(bench, z, touch_weight):
    K, n = 2, 4
    A = bench.QUERIES * bench.MAX_GRASPS
    rng = np.random.default_rng(1)
    C = rng.normal(0, 0.04, (K, A, n, 3))
    N = rng.normal(size=C.shape)
    N /= np.linalg.norm(N, axis=-1, keepdims=True)
    T = rng.random((K, A, n)) < 0.75
    pool = SimpleNamespace(contacts=C, normals=N, touched=T)
    objects = [None] * K  # support_frame reads no object without heights
    touch = SimpleNamespace(log_likelihood=lambda t: np.stack([t.sum(1) * 0.1, -t.sum(1) * 0.2], axis=1))
    rec = SimpleNamespace(models=Linear(K), touch=touch, heights=False, normal_axis="t2",
                          config=SimpleNamespace(grasps=DatasetConfig()), n_classes=K)
    from haptic_env.grasp_features import feature_dim

    liks = {"linear": {feature_dim(m, True): Linear(K) for m in (3, 4)}}
    out, labels = bench.query_scores(pool, objects, rec, True, z, liks, touch_weight, subset_k=4)
    assert out["KDE"].shape == out["linear"].shape == (K * bench.QUERIES, bench.MAX_GRASPS, K)
    np.testing.assert_array_equal(labels, np.repeat(np.arange(K), bench.QUERIES))
    np.testing.assert_allclose(out["linear"], out["KDE"], rtol=1e-10, atol=1e-10)
    assert np.count_nonzero(out["KDE"]) > 0


def test_bad_scales_are_named(bench, capsys):
    with pytest.raises(SystemExit):
        bench.main(["--scales", "0", "1"])
    assert "--scales must be finite and > 0, got [0.0]" in capsys.readouterr().err
