"""benchmarks/hand_experiment.py: the training config of each regime and likelihood, and its command line's errors."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from haptic_env.recognizers.boosted import BoostedConfig


@pytest.fixture(scope="module")
def bench(load_benchmark):
    return load_benchmark("hand_experiment")


def _args(**kw):
    base = dict(hand_budget="uniform", surface_grasps=500, surface_noise=0.0, surface_normal_noise=0.0)
    return SimpleNamespace(**{**base, **kw})


@pytest.mark.parametrize("regime", ["hand", "surface"])
def test_hgb_takes_the_kdes_place_with_the_same_k(bench, regime):
    kde = bench.training_config(regime, "allegro", _args(likelihood="kde"), calibrate_grasps=4, approaches=300)
    hgb = bench.training_config(regime, "allegro", _args(likelihood="hgb"), calibrate_grasps=4, approaches=300)
    assert kde.likelihood == "kde" and kde.kde.calibrate_grasps == 4
    assert hgb.likelihood == "hgb" and hgb.boosted == BoostedConfig(calibrate_grasps=4)
    assert hgb.grasps == kde.grasps  # the same training grasps; only the likelihood differs
    # the callers that pass their own args without the flag (stop_frontier.py, hand_classifiers.py) keep the KDE
    assert bench.training_config(regime, "allegro", _args(), calibrate_grasps=4, approaches=300) == kde


def test_command_line_errors_name_the_bad_value(bench, usage_error):
    usage_error(bench.main, ["--likelihood", "mlp"], match=r"--likelihood: invalid choice: 'mlp'")
    usage_error(bench.main, ["--likelihood", "hgb", "--kde-bandwidth", "per-class"],
                match=r"--kde-bandwidth per-class sets the KDE, which --likelihood hgb replaces")
