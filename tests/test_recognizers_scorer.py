"""GraspScorer (Phi + pooled KDE in one compiled call) against phi + KDELikelihood."""

import numpy as np
import pytest

from haptic_env.grasp_features import phi
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
from haptic_env.recognizers.scorer import GraspScorer


@pytest.mark.parametrize("n, normals, axis", [(3, False, "t2"), (4, False, "t2"), (5, True, "t2"), (5, True, "ab"),
                                             (3, True, "frame"), (5, True, "frame")])
def test_scorer_equals_phi_then_kde(n, normals, axis):
    rng = np.random.default_rng(n)
    P = rng.normal(size=(3000, n, 3))
    N = rng.normal(size=P.shape) if normals else None
    f = phi(P, N, normal_axis=axis)
    y = (P[:, 0, 0] > 0).astype(int) + 2 * (P[:, 1, 1] > 0)
    kde = KDELikelihood(KDEConfig(factor=0.5, method="pooled")).fit(f.q[f.valid], y[f.valid])
    scorer = GraspScorer(n, normals, kde, normal_axis=axis)
    for i in range(40):
        Pi = rng.normal(size=(n, 3))
        if n == 5 and i % 10 == 0:  # a square hull face: the Qhull fallback of the general path
            Pi[:4] = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
            Pi[4, 2] = 0.7
        Ni = rng.normal(size=(n, 3)) if normals else None
        q, ll = scorer(Pi, Ni)
        g = phi(Pi, Ni, normal_axis=axis)
        np.testing.assert_allclose(q, g.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ll, kde.log_likelihood(g.q), rtol=1e-12, atol=1e-9)


def test_scorer_needs_a_pooled_kde_of_the_right_dimension():
    rng = np.random.default_rng(0)
    X, y = rng.normal(size=(200, 6)), np.arange(200) % 2
    with pytest.raises(ValueError, match="pooled"):
        GraspScorer(4, False, KDELikelihood(KDEConfig(factor=1.0, method="tree")).fit(X, y))
    with pytest.raises(ValueError, match="features"):
        GraspScorer(4, True, KDELikelihood(KDEConfig(factor=1.0, method="pooled")).fit(X, y))
    two = KDELikelihood(KDEConfig(factor=1.0, method="pooled")).fit(X[:, :1], y)  # q of two contacts: a distance
    with pytest.raises(ValueError, match="GraspScorer needs n_fingers >= 3"):  # its first call failed in numba
        GraspScorer(2, False, two)


@pytest.mark.parametrize("n, normals, heights", [(4, True, False), (5, False, True)])
def test_scorer_with_gradient_boosting_equals_phi_then_its_walk(n, normals, heights):
    """With gradient boosting in the KDE's place the scorer runs Phi compiled and hands q to the model's walk:
    the same scores as ``phi`` then ``BoostedLikelihood.log_likelihood``, one grasp or a batch."""
    from haptic_env.recognizers.boosted import BoostedConfig, BoostedLikelihood

    rng = np.random.default_rng(n)
    P = rng.normal(size=(1500, n, 3))
    N = rng.normal(size=P.shape) if normals else None
    f = phi(P, N, heights=heights)
    y = (P[:, 0, 0] > 0).astype(int) + 2 * (P[:, 1, 1] > 0)
    lik = BoostedLikelihood(BoostedConfig(max_iter=20)).fit(f.q[f.valid], y[f.valid])
    scorer = GraspScorer(n, normals, lik, post=lambda ll: ll / 2.0, heights=heights)
    Pt = rng.normal(size=(30, n, 3))
    Nt = rng.normal(size=Pt.shape) if normals else None
    Pt[3] = 0.0  # degenerate: no information
    qb, llb, scored = scorer.batch(Pt, Nt)
    assert not scored[3] and scored.sum() == 29
    for i in range(len(Pt)):
        q, ll = scorer(Pt[i], None if Nt is None else Nt[i])
        g = phi(Pt[i], None if Nt is None else Nt[i], heights=heights)
        np.testing.assert_allclose(q, g.q, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(qb[i], q)
        if not g.valid:
            assert ll is None
            continue
        np.testing.assert_allclose(ll, lik.log_likelihood(g.q) / 2.0, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(llb[i], ll[0])
    with pytest.raises(ValueError, match=r"the likelihood has \d+ features"):
        GraspScorer(n, not normals, lik, heights=heights)
    with pytest.raises(ValueError, match="'pooled' or a BoostedLikelihood, got str"):
        GraspScorer(n, normals, "kde")
