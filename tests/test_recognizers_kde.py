"""KDE likelihoods: tree evaluation vs the dense reference; bandwidth selection."""

import numpy as np
import pytest

from haptic_env.recognizers.kde import KDEConfig, KDELikelihood, _dense_logsum


def _blobs(rng, n=3000, d=6, k=3):
    centres = rng.normal(scale=2.0, size=(k, d))
    X = np.concatenate([c + rng.normal(size=(n, d)) * (0.5 + 0.2 * i) for i, c in enumerate(centres)])
    y = np.repeat(np.arange(k), n)
    return X, y


def test_tree_matches_dense_reference():
    rng = np.random.default_rng(1)
    X, y = _blobs(rng)
    q = X[rng.choice(len(X), 200)] + rng.normal(scale=0.3, size=(200, X.shape[1]))
    exact = KDELikelihood(KDEConfig(factor=0.3, k=3000, cutoff=100.0)).fit(X, y)
    dense = exact.log_likelihood(q, method="dense")
    assert np.allclose(exact.log_likelihood(q), dense, atol=1e-8)  # every kernel in range: exact
    kde = KDELikelihood(KDEConfig(factor=0.3)).fit(X, y)  # default k, cutoff
    tree = kde.log_likelihood(q)
    assert np.all(tree <= dense + 1e-9)  # a partial sum never exceeds the full sum
    assert np.mean(tree.argmax(1) == dense.argmax(1)) >= 0.95
    true = np.arange(len(q)), y[np.argmin(((q[:, None] - X[None]) ** 2).sum(-1), axis=1)]
    assert np.median((dense - tree)[true]) < 0.3


def test_tree_takes_enough_neighbours_where_a_kernel_covers_many_vectors():
    """1-d vectors (2 fingers without normals): thousands of an object's vectors lie within its kernel, so a sum
    over the k = 32 nearest saturates; the tree raises each object's k to cover them and matches the dense sum."""
    rng = np.random.default_rng(6)
    X = np.concatenate([rng.normal(0.0, 1.0, 8000), rng.gamma(2.0, 0.6, 8000)])[:, None]
    y = np.repeat([0, 1], 8000)
    q = np.concatenate([rng.normal(0.0, 1.0, 200), rng.gamma(2.0, 0.6, 200)])[:, None]
    yq = np.repeat([0, 1], 200)
    kde = KDELikelihood(KDEConfig(factor=0.5, eps=0.0)).fit(X, y)
    assert np.all(kde.tree_k > 500) and np.all(kde.tree_k <= kde.config.k_max)
    dense = kde.log_likelihood(q, method="dense")
    rows = np.arange(len(q))
    assert np.median((dense - kde.log_likelihood(q))[rows, yq]) < 0.05
    capped = KDELikelihood(KDEConfig(factor=0.5, eps=0.0, k_max=32)).fit(X, y)
    assert np.array_equal(capped.tree_k, [32, 32])
    assert np.median((dense - capped.log_likelihood(q))[rows, yq]) > 1.0  # the saturation the floor alone gives
    again = KDELikelihood.from_state(kde.config, kde.state())  # a cached KDE gets the same neighbour counts
    assert np.array_equal(again.tree_k, kde.tree_k)
    # where a kernel covers few vectors (10 dimensions, a narrow kernel) the floor k stays
    Xs = rng.normal(size=(2000, 10))
    assert np.array_equal(KDELikelihood(KDEConfig(factor=0.25)).fit(Xs, np.arange(2000) % 2).tree_k, [32, 32])


def test_dense_logsum_against_explicit_formula():
    rng = np.random.default_rng(2)
    Z, D = rng.normal(size=(5, 3)), rng.normal(size=(50, 3))
    d2 = ((Z[:, None] - D[None]) ** 2).sum(-1)
    explicit = np.log(np.exp(-0.7 * d2).sum(1))
    assert np.allclose(_dense_logsum(Z, D, 0.7, chunk=64), explicit)


def test_density_normalisation_in_one_dimension():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(4000, 1))
    y = np.zeros(4000, dtype=int)
    X2 = np.concatenate([X, X + 50.0])
    y2 = np.concatenate([y, y + 1])
    kde = KDELikelihood(KDEConfig(factor=1.0, method="dense")).fit(X2, y2)
    grid = np.linspace(-40, 90, 8000)[:, None]  # bandwidth ~ 0.19 * 25 in raw units
    dens = np.exp(kde.log_likelihood(grid))
    integral = dens.sum(0) * (grid[1, 0] - grid[0, 0])
    assert np.allclose(integral, 1.0, atol=1e-2)


def test_auto_bandwidth_picks_from_grid_and_state_round_trip():
    rng = np.random.default_rng(4)
    X, y = _blobs(rng, n=1500)
    kde = KDELikelihood(KDEConfig()).fit(X, y, X[::7] + 0.01, y[::7])
    assert len(set(kde.factor)) == 1 and kde.factor[0] in KDEConfig().factor_grid  # shared: one factor
    assert kde.selection[kde.factor[0]] == max(kde.selection.values())
    again = KDELikelihood.from_state(kde.config, kde.state())
    q = X[:20]
    assert np.allclose(again.log_likelihood(q), kde.log_likelihood(q), atol=1e-4)


@pytest.mark.parametrize("select", ["likelihood", "posterior"])
def test_without_validation_vectors_the_bandwidth_is_chosen_on_vectors_the_choosing_kde_does_not_hold(select):
    """``fit`` without ``X_val`` holds 10 % of each class out of the KDE that chooses the bandwidth: scored by a KDE
    that holds them, each vector matched itself and the narrowest factor of the grid always won. The choice is then
    the one a separate validation set gives (or next to it), and the fitted KDE keeps every vector."""
    rng = np.random.default_rng(3)
    X = np.concatenate([rng.normal(size=(2000, 3)), rng.normal(size=(2000, 3)) + 0.8])  # two overlapping classes
    y = np.repeat([0, 1], 2000)
    perm = rng.permutation(len(X))
    val, train = perm[:500], perm[500:]
    cfg = KDEConfig(method="dense", select=select)
    alone = KDELikelihood(cfg).fit(X[train], y[train])
    with_val = KDELikelihood(cfg).fit(X[train], y[train], X[val], y[val])
    grid = sorted(cfg.factor_grid)
    assert alone.factor[0] > grid[0]  # not the narrowest by default
    assert abs(grid.index(alone.factor[0]) - grid.index(with_val.factor[0])) <= 1
    assert sum(len(z) for z in alone.data) == len(train)


@pytest.mark.parametrize("method", ["tree", "pooled"])
def test_a_loaded_kde_scores_exactly_as_the_fitted_one(method):
    """The cache keeps the training vectors as fitted: float32 copies built other search trees, and the approximate
    search (eps = 2) then found other neighbours, so an env's later makes scored differently from its first."""
    rng = np.random.default_rng(9)
    X, y = _blobs(rng, n=2000, d=4, k=4)
    kde = KDELikelihood(KDEConfig(method=method)).fit(X, y, X[::5] + 0.05, y[::5])
    again = KDELikelihood.from_state(kde.config, kde.state())
    q = np.concatenate([X[rng.choice(len(X), 300)] + rng.normal(scale=0.5, size=(300, 4)),
                        rng.uniform(-12, 12, size=(300, 4))])  # near the data and far from it
    assert np.array_equal(again.log_likelihood(q), kde.log_likelihood(q))
    assert np.array_equal(again.calibrate_scores(again.log_likelihood(q)), kde.calibrate_scores(kde.log_likelihood(q)))


def test_kde_errors():
    with pytest.raises(ValueError, match="method"):
        KDEConfig(method="fast")
    with pytest.raises(ValueError, match="k_max"):
        KDEConfig(k_max=0)
    with pytest.raises(RuntimeError, match="not fitted"):
        KDELikelihood().log_likelihood(np.zeros((1, 2)))
    kde = KDELikelihood(KDEConfig(factor=1.0)).fit(np.random.default_rng(0).normal(size=(20, 2)), np.arange(20) % 2)
    with pytest.raises(ValueError, match="features"):
        kde.log_likelihood(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="not finite"):
        kde.log_likelihood(np.array([[np.nan, 0.0]]))
    X, y = np.random.default_rng(0).normal(size=(30, 2)), np.arange(30) % 3
    for fit in (lambda: KDELikelihood(KDEConfig(factor=1.0)).fit(X, y, n_classes=2),  # class 2 was dropped
                lambda: KDELikelihood(KDEConfig(factor=1.0)).fit(X[y < 2], y[y < 2], X, y, n_classes=2)):
        with pytest.raises(ValueError, match=r"class labels must lie in 0\.\.1 \(n_classes=2\), got a label 2"):
            fit()
    with pytest.raises(ValueError, match="n_classes must be an int >= 1, got 2.0"):
        KDELikelihood(KDEConfig(factor=1.0)).fit(X, y, n_classes=2.0)
    # a method typo was the dense sum without a word; X_val without y_val a numpy unpacking error
    with pytest.raises(ValueError, match=r"method must be one of .*got 'bogus'"):
        kde.log_likelihood(np.zeros((1, 2)), method="bogus")
    for val in ((X[:5], None), (None, y[:5]), (X[:2], None)):
        with pytest.raises(ValueError, match="X_val and y_val go together"):
            KDELikelihood(KDEConfig(factor=1.0)).fit(X, y, *val)
    from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig

    with pytest.raises(ValueError, match="X_val and y_val go together: got X_val without y_val"):
        MLPClassifier(MLPConfig(max_epochs=1, progress=False)).fit(X, y, X[:5])


def test_pooled_matches_tree_and_dense():
    """One search over all classes: the classes among the k nearest get the tree's sums; argmax as dense."""
    rng = np.random.default_rng(5)
    X, y = _blobs(rng)
    q = X[rng.choice(len(X), 200)] + rng.normal(scale=0.3, size=(200, X.shape[1]))
    exact = KDELikelihood(KDEConfig(factor=0.3, method="pooled", k=len(X), cutoff=100.0, eps=0.0)).fit(X, y)
    assert np.allclose(exact.log_likelihood(q), exact.log_likelihood(q, method="dense"), atol=1e-8)
    # the tree with the pooled search's k (k_max = k: no raise), so both sum the same neighbours
    tree = KDELikelihood(KDEConfig(factor=0.3, method="tree", eps=0.0, k_max=32)).fit(X, y)
    pooled = tree.with_method("pooled")
    assert pooled.config.method == "pooled" and np.array_equal(pooled.bandwidth, tree.bandwidth)
    lp, lt, ld = pooled.log_likelihood(q), tree.log_likelihood(q), pooled.log_likelihood(q, method="dense")
    assert np.mean(lp.argmax(1) == ld.argmax(1)) >= 0.95
    best = np.arange(len(q)), lt.argmax(1)  # the nearest class is always among the pooled neighbours
    assert np.allclose(lp[best], lt[best], atol=0.05)


def test_pooled_floor_for_classes_beyond_the_k_nearest():
    """A class with no vector among the k nearest gets the kernel at the k-th distance (its upper bound)."""
    X = np.array([[0.0], [0.1], [0.2], [10.0], [50.0]])
    y = np.array([0, 0, 0, 1, 2])
    kde = KDELikelihood(KDEConfig(factor=1.0, method="pooled", k=3, eps=0.0)).fit(X, y)
    Z = kde.scaler(np.array([[0.05]]))
    ll = kde.log_likelihood(np.array([[0.05]]))
    d3 = np.abs(kde.scaler(X[2:3]) - Z)[0, 0]  # third nearest: 0.2
    inv = 0.5 / kde.bandwidth**2
    norms = kde._norms()
    assert ll[0, 1] == pytest.approx(-inv[1] * d3**2 + norms[1])
    assert ll[0, 2] == pytest.approx(-inv[2] * d3**2 + norms[2])  # both far classes tie at the floor
    near = np.abs(kde.scaler(X[:3]) - Z)[:, 0]
    assert ll[0, 0] == pytest.approx(np.log(np.exp(-inv[0] * near**2).sum()) + norms[0])
    again = KDELikelihood.from_state(kde.config, kde.state())  # the pooled index is rebuilt on load
    assert np.allclose(again.log_likelihood(np.array([[0.05]])), ll, atol=1e-6)


def test_per_class_bandwidth_fits_each_class_by_its_own_validation_likelihood():
    """A compact class and a spread one: "per-class" gives the compact one the narrower kernel, every
    evaluation method agrees with the dense sum, and the bandwidths survive the cache round trip."""
    rng = np.random.default_rng(8)
    X = np.concatenate([rng.normal(scale=0.05, size=(800, 3)), rng.normal(scale=1.0, size=(800, 3)) + 0.5])
    y = np.repeat([0, 1], 800)
    Xv = np.concatenate([rng.normal(scale=0.05, size=(300, 3)), rng.normal(scale=1.0, size=(300, 3)) + 0.5])
    yv = np.repeat([0, 1], 300)
    shared = KDELikelihood(KDEConfig(calibrate=False)).fit(X, y, Xv, yv)
    per = KDELikelihood(KDEConfig(bandwidth="per-class", calibrate=False, factor_grid=(0.05, 0.1, 0.2, 0.4, 0.8, 1.6))
                        ).fit(X, y, Xv, yv)
    assert shared.bandwidth[0] == shared.bandwidth[1]
    assert per.bandwidth[0] < per.bandwidth[1]
    # held-out likelihood of each class under its own density: no worse than the shared bandwidth's
    for c in (0, 1):
        own = lambda k: k.log_likelihood(Xv[yv == c])[:, c].mean()  # noqa: E731
        assert own(per) >= own(shared) - 1e-9
    q = np.concatenate([Xv[::20], rng.normal(size=(10, 3))])
    dense = per.with_method("dense").log_likelihood(q)
    for method in ("tree", "pooled"):
        wide = KDELikelihood(KDEConfig(bandwidth="per-class", calibrate=False, method=method, k=len(X), cutoff=50.0,
                                       eps=0.0, factor_grid=per.config.factor_grid)).fit(X, y, Xv, yv)
        assert np.array_equal(wide.bandwidth, per.bandwidth)
        assert np.allclose(wide.log_likelihood(q), dense, rtol=1e-4, atol=1e-4)  # float32 sums at far queries
    again = KDELikelihood.from_state(per.config, per.state())
    assert np.array_equal(again.bandwidth, per.bandwidth) and np.allclose(again.log_likelihood(q), per.log_likelihood(q))
    with pytest.raises(ValueError, match="bandwidth"):
        KDEConfig(bandwidth="adaptive")


def test_posterior_selection_picks_the_factor_whose_calibrated_posterior_scores_best_held_out():
    """``select="posterior"``: each factor's criterion is the held-out validation NLL of the calibration that
    ``correct`` keeps (recomputed here from a fixed-factor KDE on the same rows), the lowest wins, and the result is
    the KDE fitted at that factor directly (same bandwidth, scores, temperature and correction)."""
    from haptic_env.recognizers.calibration import select_correction

    rng = np.random.default_rng(3)
    X, y = _blobs(rng, n=1500, d=4)
    Xv, yv = _blobs(np.random.default_rng(4), n=300, d=4)
    cfg = KDEConfig(correct="auto", select="posterior", n_calibrate=200, seed=5)
    kde = KDELikelihood(cfg).fit(X, y, Xv, yv)
    assert set(kde.selection) == set(cfg.factor_grid)
    best = min(kde.selection, key=kde.selection.get)
    assert np.all(kde.factor == best)
    pick = np.random.default_rng([cfg.seed, 2])
    keep = np.concatenate([pick.permutation(np.flatnonzero(yv == c))[:200] for c in range(3)])
    for f in (cfg.factor_grid[0], best):
        fixed = KDELikelihood(KDEConfig(factor=f, calibrate=False)).fit(X, y)
        _, n_t, n_c = select_correction(fixed.log_likelihood(Xv[keep]), yv[keep], rng=np.random.default_rng([5, 1]))
        assert kde.selection[f] == pytest.approx(min(n_t, n_c), rel=1e-12)
    direct = KDELikelihood(KDEConfig(factor=best, correct="auto", n_calibrate=200, seed=5)).fit(X, y, Xv, yv)
    assert np.array_equal(direct.bandwidth, kde.bandwidth) and np.array_equal(direct.tree_k, kde.tree_k)
    assert direct.temperature == kde.temperature
    q = Xv[::37]
    assert np.array_equal(direct.calibrate_scores(direct.log_likelihood(q)),
                          kde.calibrate_scores(kde.log_likelihood(q)))
    likelihood = KDELikelihood(KDEConfig(correct="auto", n_calibrate=200, seed=5)).fit(X, y, Xv, yv)
    assert kde.selection[best] <= kde.selection[float(likelihood.factor[0])]


def test_posterior_selection_refuses_what_it_cannot_do():
    with pytest.raises(ValueError, match="select"):
        KDEConfig(select="nll")
    with pytest.raises(ValueError, match="bandwidth='shared'"):
        KDEConfig(select="posterior", bandwidth="per-class")
    rng = np.random.default_rng(0)
    X, y = _blobs(rng, n=200, d=3)
    with pytest.raises(ValueError, match=r"validation vectors of every class, got \[5, 5, 1\]"):
        KDELikelihood(KDEConfig(select="posterior")).fit(X, y, X[[0, 1, 2, 3, 4, 200, 201, 202, 203, 204, 400]],
                                                         y[[0, 1, 2, 3, 4, 200, 201, 202, 203, 204, 400]])


@pytest.mark.parametrize("method", ["tree", "pooled"])
def test_a_refit_searches_its_own_vectors(method):
    """Fitting one KDE object again on other vectors rebuilds its search index (the bandwidth alone does not)."""
    X1, y1 = _blobs(np.random.default_rng(1), n=500, d=3)
    X2, y2 = _blobs(np.random.default_rng(2), n=500, d=3)
    kde = KDELikelihood(KDEConfig(factor=0.5, method=method, calibrate=False)).fit(X1, y1)
    kde.fit(X2, y2)
    fresh = KDELikelihood(KDEConfig(factor=0.5, method=method, calibrate=False)).fit(X2, y2)
    q = X2[::50]
    np.testing.assert_array_equal(kde.log_likelihood(q), fresh.log_likelihood(q))
