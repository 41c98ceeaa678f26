"""Gradient boosting in the beliefs' likelihood slot (``RecognizerConfig(likelihood="hgb")``)."""

from __future__ import annotations

import argparse
import dataclasses
import pickle

import numpy as np
import pytest

from haptic_env.cache import _jsonable, cache_dir
from haptic_env.dataset import GraspDataset
from haptic_env.experiments.cli import add_parser, config_from_args
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.objects import load_object_set
from haptic_env.recognizers.boosted import BoostedConfig, BoostedLikelihood
from haptic_env.recognizers.recognizer import RecognizerConfig, build_recognizer


def blobs(n_per_class: int, seed: int, k: int = 3, d: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """``k`` Gaussian blobs in ``d`` dimensions, unit apart on the diagonal."""
    rng = np.random.default_rng(seed)
    y = np.repeat(np.arange(k), n_per_class)
    return rng.normal(size=(len(y), d)) + y[:, None], y


def test_log_likelihood_is_the_posterior_over_the_prior():
    X, y = blobs(300, 0)
    keep = np.r_[0:300, 300:450, 600:900]  # unequal classes: the prior is not uniform
    lik = BoostedLikelihood(BoostedConfig(max_iter=30)).fit(X[keep], y[keep], n_classes=3)
    Q, yq = blobs(50, 1)
    ll = lik.log_likelihood(Q)
    assert ll.shape == (150, 3) and np.isfinite(ll).all()
    prior = np.array([300, 150, 300]) / 750
    p = np.maximum(lik.clf.predict_proba(Q), 1e-6)
    np.testing.assert_allclose(ll, np.log(p) - np.log(prior))
    assert np.mean(ll.argmax(1) == yq) > 0.5  # chance is 1/3
    assert lik.calibrate_scores(ll) is ll and lik.temperature == 1.0 and lik.n_classes == 3


def test_the_floor_bounds_every_score_from_below():
    X, y = blobs(200, 0, d=1)
    X[y == 2] += 50.0  # far away: the classifier is sure
    lik = BoostedLikelihood(BoostedConfig(max_iter=50, floor=1e-3)).fit(X, y)
    assert (lik.clf.predict_proba(X[y == 2])[:, :2] < 1e-3).any()  # the floor binds here
    ll = lik.log_likelihood(X[y == 2])
    assert ll.min() == pytest.approx(np.log(1e-3) - np.log(1 / 3))


def test_training_rows_are_capped_per_class():
    X, y = blobs(100, 0)
    lik = BoostedLikelihood(BoostedConfig(max_iter=5, max_train_per_class=40)).fit(X, y)
    assert lik.clf.n_features_in_ == 3
    np.testing.assert_allclose(lik.log_prior, np.log(np.full(3, 1 / 3)))
    same = BoostedLikelihood(BoostedConfig(max_iter=5, max_train_per_class=40))
    first = np.concatenate([np.flatnonzero(y == c)[:40] for c in range(3)])
    same.fit(X[first], y[first])
    np.testing.assert_array_equal(lik.log_likelihood(X), same.log_likelihood(X))


@pytest.mark.parametrize("kw, match", [({"max_iter": 0}, "max_iter"), ({"max_train_per_class": 0}, "max_train"),
                                        ({"floor": 0.0}, "floor"), ({"floor": 1.5}, "floor"), ({"seed": -1}, "seed")])
def test_bad_config_is_named(kw, match):
    with pytest.raises(ValueError, match=match):
        BoostedConfig(**kw)


def test_bad_training_data_is_named_before_any_fit():
    X, y = blobs(20, 0)
    with pytest.raises(ValueError, match="every one of the 4 classes"):
        BoostedLikelihood().fit(X, y, n_classes=4)
    with pytest.raises(ValueError, match="integer class labels"):
        BoostedLikelihood().fit(X, y.astype(float))
    X[3, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        BoostedLikelihood().fit(X, y)
    with pytest.raises(RuntimeError, match="not fitted"):
        BoostedLikelihood().log_likelihood(X)
    with pytest.raises(ValueError, match="likelihood must be one of"):
        RecognizerConfig(likelihood="gp")
    with pytest.raises(ValueError, match="likelihood must be one of"):
        AnalysisConfig(likelihood="forest")
    with pytest.raises(ValueError, match="no training vectors"):
        BoostedLikelihood().fit(X[:0], y[:0])
    with pytest.raises(ValueError, match=r"class labels must lie in 0\.\.1 \(n_classes=2\), got a label 2"):
        BoostedLikelihood().fit(np.nan_to_num(X), y, n_classes=2)


def test_small_data_and_one_class_fit_and_score_as_the_kde_does():
    """Few vectors per class (too few for early stopping's stratified 10 %) still fit, with every iteration; one
    class gives ``(m, 1)`` scores of 0 (scikit-learn fits it as two classes), as the KDE's."""
    X, y = blobs(5, 0)  # 3 classes x 5 vectors: a 2-vector hold-out cannot hold all 3 classes
    b = BoostedLikelihood(BoostedConfig(max_iter=20)).fit(X, y)
    assert b.clf.n_iter_ == 20 and b.log_likelihood(X[:4]).shape == (4, 3)
    one = BoostedLikelihood(BoostedConfig(max_iter=5)).fit(X, np.zeros(len(X), dtype=np.int64))
    ll = one.log_likelihood(X[:4])
    assert ll.shape == (4, 1) and np.allclose(ll, 0.0)


def test_the_default_keeps_every_cache_key():
    """``likelihood`` and ``boosted`` stay out of the keys while at their defaults (old caches and results stand)."""
    assert "likelihood" not in _jsonable(AnalysisConfig())
    assert not {"likelihood", "boosted"} & _jsonable(RecognizerConfig()).keys()
    rc = RecognizerConfig()
    assert rc.model_config("kde") is rc.kde and rc.model_config("mlp") is rc.mlp
    assert dataclasses.replace(rc, likelihood="hgb").model_config("kde")[:2] == ("hgb", rc.boosted)


def parse(argv: list[str]) -> AnalysisConfig:
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="cmd"))
    return config_from_args(parser.parse_args(["analysis", "--out", "unused", *argv]))


def test_the_analysis_cli_passes_the_likelihood_on():
    cfg = parse(["--likelihood", "hgb", "--experiments", "2"])
    assert cfg.likelihood == "hgb" and cfg.recognizer_config().likelihood == "hgb"
    assert "gradient boosting" in cfg.scores_label and "KDE" not in cfg.scores_label
    assert parse(["--experiments", "2"]).recognizer_config().likelihood == "kde"


def test_a_saved_model_reads_back_and_a_foreign_blob_is_named():
    X, y = blobs(50, 0)
    lik = BoostedLikelihood(BoostedConfig(max_iter=5)).fit(X, y)
    back = BoostedLikelihood.from_bytes(lik.config, lik.to_bytes())
    np.testing.assert_array_equal(back.log_likelihood(X), lik.log_likelihood(X))
    with pytest.raises(ValueError, match="does not load"):
        BoostedLikelihood.from_bytes(lik.config, b"not a pickle")
    with pytest.raises(ValueError, match="not a BoostedLikelihood"):
        BoostedLikelihood.from_bytes(lik.config, pickle.dumps([1, 2]))
    with pytest.raises(ValueError, match="disagree"):
        BoostedLikelihood.from_bytes(lik.config, pickle.dumps({"clf": lik.clf, "log_prior": np.zeros(2)}))


def test_a_recogniser_holds_it_in_the_kde_slot_and_caches_it(tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))  # its own cache: the call counts below do not hang on others
    objects = load_object_set("default")
    K = len(objects)
    calls = []

    def dataset_fn(objs, dcfg):
        calls.append(dcfg.n_fingers)
        X, y = blobs(120, dcfg.n_fingers, k=K, d=3)
        Xv, yv = blobs(20, 99, k=K, d=3)
        return GraspDataset(X.astype(np.float32), y, Xv.astype(np.float32), yv, tuple(objects.names), dcfg)

    cfg = RecognizerConfig(likelihood="hgb", boosted=BoostedConfig(max_iter=10))
    rec = build_recognizer(objects, 3, False, config=cfg, models=("kde",), progress=False, dataset_fn=dataset_fn)
    lik = rec.models.model(3)[1]
    assert isinstance(lik, BoostedLikelihood)
    Q = blobs(5, 7, k=K, d=3)[0]
    np.testing.assert_array_equal(rec.models.log_likelihood(Q), lik.log_likelihood(Q))  # no temperature
    scorer = rec.grasp_scorer()  # Phi compiled, then the model's walk: the same scores as features -> model
    P = np.random.default_rng(3).normal(size=(3, 3))
    q, ll = scorer(P)
    np.testing.assert_array_equal(ll, lik.log_likelihood(q))
    files = sorted(p.name for p in cache_dir("recognizers").glob("*_hgb.pkl"))
    assert files and calls == [3]
    again = build_recognizer(objects, 3, False, config=cfg, models=("kde",), progress=False, dataset_fn=dataset_fn)
    assert calls == [3]  # read back, not retrained
    np.testing.assert_array_equal(again.models.log_likelihood(Q), rec.models.log_likelihood(Q))
    path = cache_dir("recognizers") / files[0]
    path.write_bytes(path.read_bytes()[:-7] + b"damaged")
    with pytest.warns(UserWarning, match="rebuilding"):
        build_recognizer(objects, 3, False, config=cfg, models=("kde",), progress=False, dataset_fn=dataset_fn)
    assert calls == [3, 3]
    # the KDE of the same data has its own files: neither reads the other's
    kde = build_recognizer(objects, 3, False, config=RecognizerConfig(), models=("kde",), progress=False,
                           dataset_fn=dataset_fn)
    assert calls == [3, 3, 3] and not isinstance(kde.models.model(3)[1], BoostedLikelihood)
    assert len(list(cache_dir("recognizers").glob("*_kde.npz"))) == 1
    assert len(list(cache_dir("recognizers").glob("*_hgb.pkl"))) == 1


def test_the_env_config_takes_it_as_json():
    from haptic_env.config import HapticRecogConfig, recognizer_kwargs

    cfg = HapticRecogConfig(recognizer_kwargs={"config": {"likelihood": "hgb", "boosted": {"max_iter": 5}}})
    rc = recognizer_kwargs(cfg)["config"]  # the temperature for the env's calibrate_grasps, as the KDE's
    assert rc.likelihood == "hgb" and rc.boosted == BoostedConfig(max_iter=5, calibrate_grasps=cfg.calibrate_grasps)
    with pytest.raises(ValueError, match="max_iter"):
        HapticRecogConfig(recognizer_kwargs={"config": {"likelihood": "hgb", "boosted": {"max_iter": 0}}})


def test_the_env_setting_picks_the_likelihood_and_its_temperature():
    from haptic_env.config import HapticRecogConfig, recognizer_kwargs

    assert recognizer_kwargs(HapticRecogConfig())["config"].likelihood == "kde"
    rc = recognizer_kwargs(HapticRecogConfig(likelihood="hgb", calibrate_grasps=5))["config"]
    assert rc.likelihood == "hgb" and rc.boosted == BoostedConfig(calibrate_grasps=5)
    own = HapticRecogConfig(likelihood="hgb", calibrate_grasps=5,
                            recognizer_kwargs={"config": {"boosted": {"calibrate_grasps": 0}}})
    assert recognizer_kwargs(own)["config"].boosted == BoostedConfig()  # the JSON's own setting wins
    json_kde = HapticRecogConfig(likelihood="hgb", recognizer_kwargs={"config": {"likelihood": "kde"}})
    assert recognizer_kwargs(json_kde)["config"].likelihood == "kde"
    with pytest.raises(ValueError, match="likelihood must be one of .*'forest'"):
        HapticRecogConfig(likelihood="forest")


@pytest.mark.parametrize("k", [2, 4])
def test_the_compiled_trees_give_scikit_learns_probabilities(k):
    """The numba tree walk (two classes: one tree per iteration and a sigmoid) equals ``predict_proba``."""
    X, y = blobs(200, 0, k=k, d=6)
    lik = BoostedLikelihood(BoostedConfig(max_iter=40, floor=1e-12)).fit(X, y)
    # the walk is in use: _flatten falls back to scikit-learn's own path (False) where it cannot read the trees, and
    # then this test would compare scikit-learn with itself
    assert isinstance(lik._trees, tuple)
    Q = blobs(30, 3, k=k, d=6)[0]
    Q[0] = X[5]  # on training values, where ``x <= threshold`` decides
    expected = np.log(np.maximum(lik.clf.predict_proba(Q), 1e-12)) - lik.log_prior
    np.testing.assert_allclose(lik.log_likelihood(Q), expected, rtol=1e-12, atol=1e-12)
    lik._trees = False  # the fallback for trees this module cannot read: scikit-learn's own path
    np.testing.assert_allclose(lik.log_likelihood(Q), expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match=r"Q must be \(m, 6\)"):
        lik.log_likelihood(Q[:, :5])
    Q[2, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        lik.log_likelihood(Q)


def test_a_temperature_is_fitted_on_validation_vectors_and_saved():
    X, y = blobs(300, 0)
    Xv, yv = blobs(100, 1)
    plain = BoostedLikelihood(BoostedConfig(max_iter=30)).fit(X, y, Xv, yv)
    assert plain.temperature == 1.0 and not plain.calibrated  # calibrate_grasps=0: the analyses' default
    lik = BoostedLikelihood(BoostedConfig(max_iter=30, calibrate_grasps=3)).fit(X, y, Xv, yv)
    assert lik.temperature != 1.0 and lik.calibrated
    np.testing.assert_array_equal(lik.log_likelihood(Xv), plain.log_likelihood(Xv))  # the same trees
    ll = lik.log_likelihood(Xv)
    np.testing.assert_allclose(lik.calibrate_scores(ll), ll / lik.temperature)
    # the temperature minimises the NLL of 1..3-grasp beliefs: a nearby one does worse on the same sums
    from haptic_env.recognizers.calibration import sequence_scores, tempered_nll

    rng = np.random.default_rng(0)
    keep = np.concatenate([rng.permutation(np.flatnonzero(yv == c))[:1000] for c in range(3)])
    S, Y = sequence_scores(ll[keep], yv[keep], 3, rng)
    best = tempered_nll(S, Y, lik.temperature)
    assert best <= tempered_nll(S, Y, lik.temperature * 1.2) and best <= tempered_nll(S, Y, lik.temperature / 1.2)
    back = BoostedLikelihood.from_bytes(lik.config, lik.to_bytes())
    assert back.temperature == lik.temperature
    assert BoostedLikelihood(BoostedConfig(max_iter=30, calibrate_grasps=3)).fit(X, y).temperature == 1.0  # no X_val
    with pytest.raises(ValueError, match=r"X_val must be \(m, 3\)"):
        BoostedLikelihood(BoostedConfig(max_iter=5, calibrate_grasps=2)).fit(X, y, Xv[:, :2], yv)


@pytest.mark.parametrize("kw, match", [({"calibrate_grasps": -1}, "calibrate_grasps"),
                                        ({"n_calibrate": 0}, "n_calibrate"), ({"calibrate_grasps": 1.5}, "calibrate")])
def test_bad_calibration_settings_are_named(kw, match):
    with pytest.raises(ValueError, match=match):
        BoostedConfig(**kw)


def test_the_calibration_settings_stay_out_of_the_key_at_their_defaults():
    assert not {"calibrate_grasps", "n_calibrate"} & _jsonable(BoostedConfig()).keys()
    assert _jsonable(BoostedConfig(calibrate_grasps=5))["calibrate_grasps"] == 5
