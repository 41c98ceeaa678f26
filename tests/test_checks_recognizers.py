"""Bad settings of the recognisers (KDE, MLP, calibration, touch model, updaters, k-d tree) get a ValueError naming the
field and the value, at construction; valid ones (numpy scalars included) are kept as given."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from haptic_env.recognizers.calibration import (expected_calibration_error, fit_correction, fit_power, fit_temperature,
                                                reliability, sequence_scores, tempered_nll)
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
from haptic_env.recognizers.knn import KDTree
from haptic_env.recognizers.mlp_config import MLPConfig
from haptic_env.recognizers.touch import TouchModel
from haptic_env.recognizers.updaters import BCIP, BayesianUpdater, check_threshold
from tests.test_recognizers_updaters import FixedModel

NAN, INF = float("nan"), float("inf")


_M = FixedModel([[0.0, -1.0]])  # log-likelihood / probability rows by int(q[0])
_S, _Y = np.log(np.array([[0.7, 0.3], [0.4, 0.6]])), np.array([0, 1])
_T = np.zeros((2, 4, 3), dtype=bool)
_X = np.random.default_rng(0).normal(size=(50, 3))


def _kde(name):
    return lambda v: KDEConfig(**{name: v})


def _mlp(name):
    return lambda v: MLPConfig(**{name: v})


def _threads(v):
    from haptic_env.recognizers.mlp import torch_threads

    with torch_threads(v):
        pass


def _case(call, values, match):
    return [pytest.param(call, v, match, id=f"{match.replace(chr(92), '').split()[0]}={v!r}") for v in values]


CASES = [
    # KDEConfig: correct by equality took 1, 1.0, 0 (then KeyError at fit); yes/no and whole-number fields
    *_case(_kde("correct"), [1, 1.0, 0, np.int64(1)], r"KDEConfig\.correct must be True, False"),
    *_case(_kde("calibrate"), ["no", 1, 0, None], r"KDEConfig\.calibrate must be True or False"),
    *_case(_kde("k"), [2.5, True, NAN, "32"], r"KDEConfig\.k must be an int >= 1"),
    *_case(_kde("k_max"), [True, 2.5, NAN], r"KDEConfig\.k_max must be an int >= 1"),
    *_case(_kde("max_samples"), [True, 2.5, NAN], r"KDEConfig\.max_samples must be an int >= 1"),
    *_case(_kde("cutoff"), [NAN, INF, True, "4"], r"KDEConfig\.cutoff must be a finite number > 0"),
    *_case(_kde("eps"), [NAN, INF, True, "2"], r"KDEConfig\.eps must be a finite number >= 0"),
    *_case(_kde("factor_grid"), [(NAN,), (INF,), (0.5, INF), 0.5, ("0.5",), (True,)],
           r"KDEConfig\.factor_grid must hold positive factors"),
    *_case(_kde("factor"), [[1.0], True, np.True_, None], r"KDEConfig\.factor must be positive and finite"),
    *_case(_kde("n_select"), [0, -5, 2.5, True], r"KDEConfig\.n_select must be an int >= 1"),
    *_case(_kde("select_samples"), [0, -5, "x", 2.5], r"KDEConfig\.select_samples must be an int >= 1"),
    *_case(_kde("seed"), [-1, "x", 2.5, True, None], r"KDEConfig\.seed must be an int >= 0"),
    *_case(_kde("n_calibrate"), [True], r"KDEConfig\.n_calibrate must be an int >= 1"),
    *_case(_kde("calibrate_grasps"), [True], r"KDEConfig\.calibrate_grasps must be an int >= 1"),
    # MLPConfig
    *[c for f in ("depth", "width", "batch_size", "max_epochs", "patience")
      for c in _case(_mlp(f), [True], rf"MLPConfig\.{f} must be an integer >= {0 if f == 'depth' else 1}")],
    *_case(_mlp("max_train"), [True], r"MLPConfig\.max_train must be None or an int >= 1"),
    *_case(_mlp("lr"), ["0.01", True, None], r"MLPConfig\.lr must be positive and finite"),
    *_case(_mlp("weight_decay"), [None, True, "0"], r"MLPConfig\.weight_decay must be >= 0 and finite"),
    *_case(_mlp("lr_decay"), ["0.9", None, True], r"MLPConfig\.lr_decay must be in \(0, 1\]"),
    *_case(_mlp("val_fraction"), ["0.1", None], r"MLPConfig\.val_fraction must be in \(0, 1\)"),
    *_case(_mlp("seed"), [-1, "x", 2.5, True], r"MLPConfig\.seed must be an int >= 0"),
    *_case(_mlp("threads"), [0, "4", 2.5, True], r"MLPConfig\.threads must be None or an int >= 1"),
    *_case(_mlp("decoupled_weight_decay"), ["no", 1, None], r"MLPConfig\.decoupled_weight_decay must be True or"),
    *_case(_mlp("progress"), ["no", 0, None], r"MLPConfig\.progress must be True or False"),
    *_case(_threads, [2.5, "4", True], r"torch threads must be >= 1"),
    # calibration: True was taken as 1
    *_case(lambda v: sequence_scores(_S, _Y, v, np.random.default_rng(0)), [True],
           r"max_grasps must be an int >= 1"),
    *_case(lambda v: reliability(np.exp(_S), _Y, v), [True], r"bins must be an int >= 1"),
    *_case(lambda v: expected_calibration_error(np.exp(_S), _Y, v), [True], r"bins must be an int >= 1"),
    # fit bounds took (1, inf) and (True, 2), a scalar ended in a TypeError; C took inf; T a string
    *_case(lambda v: fit_temperature(_S, _Y, bounds=v), [(1, INF), (True, 2.0), 3.0], r"bounds must be 0 < lo < hi"),
    *_case(lambda v: fit_power(_S, _Y, bounds=v), [(0.5, INF), ("0.5", 2.0)], r"bounds must be 0 < lo < hi"),
    *_case(lambda v: fit_correction(_S, _Y, C=v), [INF, "1", True], r"C must be > 0"),
    *_case(lambda v: tempered_nll(_S, _Y, v), ["1", True], r"temperature must be > 0"),
    # touch model
    *_case(lambda v: TouchModel.fit(_T, alpha=v), ["1", None, True], r"alpha must be a finite number > 0"),
    # updaters
    *_case(lambda v: BayesianUpdater(_M).update([0.0], weight=v), ["2", "x", True, None],
           r"weight must be positive and finite"),
    *_case(lambda v: BayesianUpdater(_M, threshold=v), ["0.9", True, None], r"threshold \(lambda_s\) must be in"),
    *_case(lambda v: BayesianUpdater(_M, n_classes=v), [2.5, "3"], r"an updater needs at least 2 classes"),
    *_case(lambda v: BayesianUpdater(_M, max_log_ratio=v), ["1", True], r"max_log_ratio must be positive or None"),
    *_case(lambda v: BCIP(_M, _M, eps=v), ["0.1", None], r"eps must be in \(0, 1\)"),
    # k-d tree: int() truncated 2.5; True was 1
    *_case(lambda v: KDTree(_X, leafsize=v), [2.5, True, "8"], r"leafsize must be an int >= 1"),
    *_case(lambda v: KDTree(_X).query(_X[:2], k=v), [2.5, True, "3"], r"k must be in \[1, 50\]"),
    *_case(lambda v: KDTree(_X).query(_X[:2], k=3, eps=v), [NAN, "0", True, -1.0], r"eps must be a finite number"),
]


@pytest.mark.parametrize("call, bad, match", CASES)
def test_bad_value_is_a_value_error_naming_the_field_and_value(call, bad, match):
    with pytest.raises(ValueError, match=match) as info:
        call(bad)
    assert repr(bad) in str(info.value)


def test_bad_torch_threads_environment_variable_is_named(monkeypatch):
    monkeypatch.setenv("HAPTIC_TORCH_THREADS", "four")
    with pytest.raises(ValueError, match=r"HAPTIC_TORCH_THREADS must be an int >= 1, got 'four'"):
        _threads(None)


def test_valid_kde_settings_are_kept_as_given():
    assert KDEConfig() == KDEConfig(factor="auto", factor_grid=(0.25, 0.35, 0.5, 0.7, 1.0, 1.4), k=32, k_max=4096,
                                    cutoff=4.0, eps=2.0, max_samples=20_000, select_samples=4_000, n_select=500,
                                    calibrate=True, correct=False, n_calibrate=1_000, calibrate_grasps=1, seed=0)
    given = dict(factor=np.float32(0.5), factor_grid=[np.float64(0.5), 1], k=np.int64(8), k_max=np.int32(100),
                 cutoff=np.float64(3.0), eps=0, max_samples=np.int64(10), select_samples=np.int16(20),
                 n_select=np.uint8(5), n_calibrate=np.int64(7), calibrate_grasps=np.int64(2), seed=np.int64(3),
                 calibrate=np.False_)
    cfg = KDEConfig(**given)
    for name, v in given.items():
        assert getattr(cfg, name) is v, name
    for c in (True, False, "auto", "matrix", "power"):
        assert KDEConfig(correct=c).correct is c
    assert KDEConfig(correct=np.True_).correct is True and KDEConfig(correct=np.False_).correct is False
    assert KDEConfig(factor=2).factor == 2 and isinstance(KDEConfig(factor=2).factor, int)


def test_numpy_correct_flag_fits():
    """np.True_ used to pass the check by equality and fail the fit with KeyError: np.True_."""
    rng = np.random.default_rng(1)
    X = np.concatenate([rng.normal(size=(60, 2)), rng.normal(size=(60, 2)) + 1.5])
    y = np.repeat([0, 1], 60)
    fits = [KDELikelihood(KDEConfig(factor=1.0, method="dense", correct=c, seed=np.int64(0))).fit(X, y, X, y)
            for c in (True, np.True_)]
    assert fits[0].temperature == fits[1].temperature
    np.testing.assert_array_equal(fits[0].correction.W, fits[1].correction.W)


def test_valid_mlp_settings_are_kept_as_given():
    from haptic_env.recognizers.mlp import torch_threads

    assert MLPConfig() == MLPConfig(depth=3, width=256, lr=3e-3, lr_decay=0.93, weight_decay=0.0,
                                    decoupled_weight_decay=False, batch_size=1024, max_epochs=40, patience=4,
                                    max_train=None, val_fraction=0.1, seed=0, threads=None, progress=True)
    given = dict(depth=0, width=np.int64(8), batch_size=np.int32(16), max_epochs=np.int64(2), patience=np.int64(1),
                 max_train=np.int64(100), lr=1, weight_decay=np.float32(0.5), lr_decay=np.float64(1.0),
                 val_fraction=np.float32(0.2), seed=np.int64(4), threads=np.int64(2), decoupled_weight_decay=np.True_,
                 progress=np.False_)
    cfg = MLPConfig(**given)
    for name, v in given.items():
        assert getattr(cfg, name) is v, name
    assert dataclasses.replace(cfg, threads=None).threads is None
    with torch_threads(np.int64(1)) as n:
        assert n == 1


def test_valid_numbers_elsewhere_stay_accepted():
    for t, want in ((1, 1.0), (1.0, 1.0), (np.float32(0.5), 0.5), (np.float64(0.85), 0.85)):
        got = check_threshold(t)
        assert got == want and type(got) is float
    assert BayesianUpdater(_M, threshold=1).threshold == 1.0
    u = BayesianUpdater(_M, n_classes=np.int64(2), max_log_ratio=np.float32(10.0))
    assert u.n_classes == 2 and type(u.n_classes) is int
    BayesianUpdater(_M, max_log_ratio=INF)
    BCIP(_M, _M, eps=np.float32(1e-3))
    for w in (1, 1.0, np.float32(0.5), np.float64(2.0)):
        v = BayesianUpdater(_M)
        b = v.update([0.0], weight=w)
        e = np.exp(float(w) * np.array([0.0, -1.0]))
        np.testing.assert_allclose(b, e / e.sum(), rtol=1e-6)
    np.testing.assert_array_equal(TouchModel.fit(_T, alpha=np.float32(0.5)).log_p, TouchModel.fit(_T, alpha=0.5).log_p)
    np.testing.assert_array_equal(TouchModel.fit(_T, alpha=2).log_p, TouchModel.fit(_T, alpha=2.0).log_p)
    S2, Y2 = sequence_scores(_S, _Y, np.int64(2), np.random.default_rng(0))
    assert S2.shape == (4, 2)
    assert reliability(np.exp(_S), _Y, np.int64(5))["count"].shape == (5,)
    tree = KDTree(_X, leafsize=np.int64(4))
    d, i = tree.query(_X[:2], k=np.int64(3), eps=0)
    assert d.shape == (2, 3) and (i[:, 0] == [0, 1]).all()
    tree.query(_X[:2], k=3, eps=np.float32(0.5))


@pytest.mark.parametrize("kw, match", [({"n_fingers": 4.0}, r"n_fingers must be an int >= 2, got 4\.0"),
                                       ({"progress": 0}, r"progress must be True or False, got 0"),
                                       ({"touch": "no"}, r"touch must be True or False, got 'no'"),
                                       ({"cache": None}, r"cache must be True or False, got None")])
def test_build_recognizer_checks_its_arguments_before_any_work(kw, match):
    from haptic_env.objects import load_object_set
    from haptic_env.recognizers import recognizer

    def must_not_run(*a, **k):
        raise AssertionError("the dataset was built before the arguments were checked")

    args = {"n_fingers": 4, **kw}
    with pytest.raises(ValueError, match=match):
        recognizer.build_recognizer(load_object_set("default"), args.pop("n_fingers"), True, dataset_fn=must_not_run,
                                    **args)
