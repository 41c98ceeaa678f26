"""benchmarks/stop_frontier.py: its vectorised replay of scaled beliefs is the Bayesian updater's, stop for stop."""

from __future__ import annotations

import numpy as np
import pytest

from haptic_env.recognizers.updaters import BayesianUpdater


@pytest.fixture(scope="module")
def frontier(load_benchmark):
    return load_benchmark("stop_frontier")


def updater_stop(L: np.ndarray, threshold: float) -> tuple[int, int, bool]:
    upd = BayesianUpdater(None, threshold, n_classes=L.shape[1])
    upd.reset()
    for g, row in enumerate(L):
        upd.update_scores(log_lik=row[None])
        if upd.decided:
            return upd.prediction, g + 1, True
    return upd.prediction, len(L), False


def test_replay_matches_the_updater(frontier):
    rng = np.random.default_rng(0)
    Q, G, K = 40, 12, 5
    L = rng.normal(0.0, 1.5, (Q, G, K))
    L[rng.random((Q, G)) < 0.2] = 0.0  # unusable grasps: no information
    L[rng.random((Q, G, K)) < 0.05] = -np.inf  # a class ruled out by one grasp
    L[3, 2] = -np.inf  # every class impossible: the belief stays
    scales = np.array([0.3, 1.0, 4.0])
    pred, used, done = frontier.replay(L, scales, 0.85)
    assert pred.shape == used.shape == done.shape == (3, Q)
    for i, s in enumerate(scales):
        for q in range(Q):
            assert (pred[i, q], used[i, q], done[i, q]) == updater_stop(s * L[q], 0.85), (s, q)
    assert done.any() and not done.all()  # both stops and run-outs are exercised
    assert used[2].mean() < used[0].mean()  # a sharper belief stops sooner


@pytest.mark.parametrize("argv, message", [(["--scales", "0", "1"], "--scales must be finite and > 0"),
                                           (["--scales", "2", "3"], "--scales must include 1"),
                                           (["--threshold", "1.5"], "--threshold must be in (0, 1)")])
def test_bad_arguments_are_named(frontier, argv, message, capsys):
    with pytest.raises(SystemExit):
        frontier.main(argv)
    assert message in capsys.readouterr().err
