"""Temperature scaling: recovers a known temperature, lowers the ECE, is stored with the models."""

from __future__ import annotations

import numpy as np
import pytest

from haptic_env.recognizers import KDEConfig, KDELikelihood
from haptic_env.recognizers.calibration import (
    PowerCorrection,
    ScoreCorrection,
    calibration_rows,
    expected_calibration_error,
    fit_correction,
    fit_temperature,
    reliability,
    select_correction,
    sequence_scores,
    tempered_nll,
)
from scipy.special import softmax


def _calibrated_draws(rng, B=20_000, K=5):
    """Scores z whose softmax IS the true class distribution, and labels drawn from it."""
    z = rng.normal(0.0, 2.0, (B, K))
    P = softmax(z, axis=1)
    y = (P.cumsum(1) > rng.random((B, 1))).argmax(1)
    return z, y


def _two_gaussians(rng, n_train: int, n_val: int, d: int, shift: float):
    """Two unit Gaussians in ``d`` dimensions, ``shift`` apart on every axis: ``X, y`` (n_train each), ``Xv, yv``
    (n_val each), drawn in that order."""
    X = np.concatenate([rng.normal(0, 1, (n_train, d)), rng.normal(shift, 1, (n_train, d))])
    Xv = np.concatenate([rng.normal(0, 1, (n_val, d)), rng.normal(shift, 1, (n_val, d))])
    return X, np.repeat([0, 1], n_train), Xv, np.repeat([0, 1], n_val)


def test_fit_temperature_recovers_the_over_confidence():
    rng = np.random.default_rng(0)
    z, y = _calibrated_draws(rng)
    T = fit_temperature(3.0 * z, y)  # scores 3x too sharp
    assert T == pytest.approx(3.0, rel=0.05)
    assert tempered_nll(3.0 * z, y, T) < tempered_nll(3.0 * z, y, 1.0)
    assert expected_calibration_error(softmax(z, axis=1), y) < 0.02
    assert expected_calibration_error(softmax(3.0 * z, axis=1), y) > 0.1
    assert expected_calibration_error(softmax(3.0 * z / T, axis=1), y) < 0.02


def test_minus_inf_scores_and_degenerate_input():
    S = np.array([[0.0, -np.inf, -1.0], [-np.inf, 0.0, -2.0]])
    T = fit_temperature(S, np.array([0, 1]))
    assert np.isfinite(T) and T > 0
    assert fit_temperature(np.zeros((0, 3)), np.zeros(0, dtype=int)) == 1.0
    with pytest.raises(ValueError, match="shape"):
        fit_temperature(np.zeros(3), np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="class indices"):
        fit_temperature(np.zeros((2, 3)), np.array([0, 3]))
    with pytest.raises(ValueError, match="NaN"):
        fit_temperature(np.full((1, 2), np.nan), np.array([0]))
    # +inf was put at the floor (the surest class scored as the least likely: T at its upper bound)
    with pytest.raises(ValueError, match=r"NaN or \+inf"):
        fit_temperature(np.array([[np.inf, 0.0, 0.0]]), np.array([0]))
    for fit in (ScoreCorrection(W=np.eye(3), b=np.zeros(3), floor=-50.0), PowerCorrection(p=1.5, cap=50.0)):
        for bad in (np.inf, np.nan):  # both were put at the floor silently when a correction was applied
            with pytest.raises(ValueError, match=r"NaN or \+inf"):
                fit(np.array([[bad, 0.0, -1.0]]))
        assert np.isfinite(fit(np.array([[-np.inf, 0.0, -1.0]]))).any()  # -inf: a class ruled out, as before
    with pytest.raises(ValueError, match="bins"):
        reliability(np.full((1, 2), 0.5), np.array([0]), bins=0)


def test_reliability_bins_count_every_row():
    rng = np.random.default_rng(1)
    z, y = _calibrated_draws(rng, B=1000)
    r = reliability(softmax(z, axis=1), y, bins=10)
    assert r["count"].sum() == 1000 and r["edges"].shape == (11,)
    ok = r["count"] > 0
    assert np.all((r["confidence"][ok] >= r["edges"][:-1][ok]) & (r["confidence"][ok] <= r["edges"][1:][ok]))


def test_reliability_takes_probabilities_only():
    """Log-probabilities or scores above 1 gave an ECE (above 1 at times) without a word."""
    from haptic_env.recognizers.calibration import expected_calibration_error

    P, y = np.array([[0.7, 0.3], [0.4, 0.6]]), np.array([0, 0])
    assert expected_calibration_error(P, y) == pytest.approx(0.5 * 0.3 + 0.5 * 0.6)
    for bad in (np.log(P), 3 * P, P + 0.2):
        with pytest.raises(ValueError, match=r"proba must hold probabilities .* got row 0"):
            expected_calibration_error(bad, y)


def test_reliability_bins_are_half_open_at_every_edge():
    """A confidence of exactly k / 10 opens bin k, for every k (numpy's linspace put 0.3, 0.6 and 0.7 a hair above
    themselves, so those three once fell into the bin below); 1.0 is in the last bin."""
    conf = np.arange(1, 11) / 10  # 0.1 .. 1.0
    P = np.stack([conf, 1.0 - conf], axis=1)  # two classes: the max is conf from 0.5 on
    r = reliability(P[4:], np.zeros(6, dtype=int), bins=10)  # 0.5, 0.6, 0.7, 0.8, 0.9, 1.0
    assert r["count"].tolist() == [0, 0, 0, 0, 0, 1, 1, 1, 1, 2]
    assert np.allclose(r["confidence"][5:9], [0.5, 0.6, 0.7, 0.8])
    r = reliability(np.array([[0.3, 0.3, 0.4]]), np.array([2]), bins=10)  # three classes: a max of 0.4
    assert r["count"].tolist() == [0, 0, 0, 0, 1, 0, 0, 0, 0, 0]
    r = reliability(np.array([[0.3, 0.35, 0.35], [0.3, 0.3, 0.3]]), np.array([1, 0]), bins=10)  # maxima 0.35, 0.3
    assert r["count"].tolist() == [0, 0, 0, 2, 0, 0, 0, 0, 0, 0]


def test_kde_fits_and_stores_its_temperature():
    # two overlapping classes in 8 dimensions: a KDE on few points is over-confident (T > 1)
    X, y, Xv, yv = _two_gaussians(np.random.default_rng(2), 400, 300, d=8, shift=0.5)
    kde = KDELikelihood(KDEConfig(method="dense", correct=False)).fit(X, y, Xv, yv)
    assert kde.temperature > 1.0 and kde.correction is None
    back = KDELikelihood.from_state(kde.config, kde.state())
    assert back.temperature == kde.temperature and back.correction is None
    # with the learned correction (the analyses' setting) the temperature is fitted on the corrected scores; both are stored
    kde = KDELikelihood(KDEConfig(method="dense", correct=True)).fit(X, y, Xv, yv)
    assert kde.correction is not None and 0.5 < kde.temperature < 2.0
    back = KDELikelihood.from_state(kde.config, kde.state())
    S = kde.log_likelihood(Xv[:50])
    # (the training vectors are stored as fitted; exact equality: test_recognizers_kde.py's round-trip test)
    np.testing.assert_allclose(back.calibrate_scores(back.log_likelihood(Xv[:50])), kde.calibrate_scores(S), rtol=1e-5)
    assert KDELikelihood(KDEConfig(method="dense", calibrate=False)).fit(X, y, Xv, yv).temperature == 1.0
    assert KDELikelihood(KDEConfig(method="dense")).fit(X, y).temperature == 1.0  # no validation set: none


def test_sequence_scores_sums_k_rows_of_one_class():
    rng = np.random.default_rng(3)
    S = np.repeat(np.array([[1.0, 0.0, -np.inf], [0.0, 2.0, -1.0]]), [4, 6], axis=0)  # class 0: 4 rows, 1: 6
    Y = np.repeat([0, 1], [4, 6])
    out, y = sequence_scores(S, Y, 3, rng)
    assert out.shape == (36, 3) and y.shape == (36,)
    assert np.bincount(y).tolist() == [18, 18]  # every k = 1..3, as many sums per class as the largest class has rows
    k = np.tile(np.repeat([1, 2, 3], 6), 2)
    want = np.where(y[:, None] == 0, [1.0, 0.0, -np.inf], [0.0, 2.0, -1.0]) * k[:, None]
    np.testing.assert_array_equal(out, want)  # each row: the sum of k rows of its own class; -inf stays -inf
    same, ys = sequence_scores(S, Y, 1, rng)
    assert same is not None and np.array_equal(same, S) and np.array_equal(ys, Y)
    for bad in (0, 2.5, -1):
        with pytest.raises(ValueError, match="max_grasps"):
            sequence_scores(S, Y, bad, rng)


def test_sequence_temperature_calibrates_beliefs_over_several_grasps():
    """Grasps of one object share a systematic error: the one-shot T leaves the k-grasp belief over-confident."""
    rng = np.random.default_rng(4)
    K, B = 4, 4000
    y = rng.integers(0, K, B)
    bias = rng.normal(0.0, 1.0, (K, K))  # each object's grasps lean the same (wrong) way, grasp after grasp
    S = 2.0 * np.eye(K)[y] + bias[y] + rng.normal(0.0, 1.0, (B, K))
    T1 = fit_temperature(S, y)
    seq, ys = sequence_scores(S, y, 5, rng)
    T5 = fit_temperature(seq, ys)
    assert T5 > 1.2 * T1
    # fresh 5-grasp beliefs (5 grasps of one object each): the sequence T scores them better than the one-shot T
    idx = np.stack([rng.choice(np.flatnonzero(y == c), 5) for c in rng.integers(0, K, 2000)])
    five, y5 = S[idx].sum(axis=1), y[idx[:, 0]]
    assert tempered_nll(five, y5, T5) < tempered_nll(five, y5, T1)


def test_kde_sequence_calibration_is_a_config_setting():
    X, y, Xv, yv = _two_gaussians(np.random.default_rng(6), 300, 200, d=6, shift=0.6)
    one = KDELikelihood(KDEConfig(method="dense")).fit(X, y, Xv, yv)
    seq = KDELikelihood(KDEConfig(method="dense", calibrate_grasps=5)).fit(X, y, Xv, yv)
    assert np.array_equal(seq.factor, one.factor) and seq.temperature != one.temperature
    S, Y = sequence_scores(one.log_likelihood(Xv), yv, 5, np.random.default_rng(0))
    assert tempered_nll(S, Y, seq.temperature) <= tempered_nll(S, Y, one.temperature) + 1e-9
    assert KDELikelihood.from_state(seq.config, seq.state()).temperature == seq.temperature
    for bad in (0, 1.5):
        with pytest.raises(ValueError, match="calibrate_grasps"):
            KDEConfig(calibrate_grasps=bad)


def test_correction_undoes_a_systematic_bias():
    """Scores that favour class 0 by a constant (a compact look-alike's KDE) make summed beliefs converge on it;
    the fitted correction removes the offset, and its one-shot posteriors are calibrated (NLL <= raw's)."""
    rng = np.random.default_rng(7)
    K, B = 3, 3000
    y = rng.integers(0, K, B)
    S = rng.normal(0, 1, (B, K))
    S[np.arange(B), y] += 1.0   # the true class scores higher ...
    S[:, 0] += 1.5              # ... but class 0 always gets a bonus
    S[rng.random(B) < 0.02, 2] = -np.inf  # a class ruled out now and then
    corr = fit_correction(S[:2000], y[:2000])
    Sc = corr(S[2000:])
    assert Sc.shape == (1000, K) and np.allclose(np.exp(Sc).sum(1), 1.0)
    yt = y[2000:]
    assert np.mean(Sc.argmax(1) == yt) > np.mean(S[2000:].argmax(1) == yt) + 0.1
    raw_nll = tempered_nll(S[2000:] - S[2000:].max(1, keepdims=True), yt, fit_temperature(S[:2000], y[:2000]))
    assert -Sc[np.arange(1000), yt].mean() < raw_nll
    # one row at a time gives the same as the batch (the vector env relies on it)
    np.testing.assert_array_equal(np.concatenate([corr(S[i:i + 1]) for i in range(2000, 2010)]), Sc[:10])
    with pytest.raises(ValueError, match="every class"):
        fit_correction(S[y != 1], y[y != 1])
    with pytest.raises(ValueError, match=r"shape \(B, 3\)"):
        corr(S[:, :2])


def test_select_correction_takes_it_where_a_bias_no_temperature_undoes():
    """Class 0's scores are systematically 2 nats too low: summing grasps converges on the wrong class, which the
    correction's offsets fix and a temperature cannot; with unbiased scores the two calibrations tie closely."""
    rng = np.random.default_rng(11)
    y = np.repeat(np.arange(3), 600)
    S = rng.normal(size=(len(y), 3))
    S[np.arange(len(y)), y] += 1.0  # the true class scores higher on average
    biased = S.copy()
    biased[:, 0] -= 2.0
    use, nll_t, nll_c = select_correction(biased, y)
    assert use and nll_c < nll_t - 0.1
    _, nll_t, nll_c = select_correction(S, y)
    assert abs(nll_c - nll_t) < 0.05
    with pytest.raises(ValueError, match="every class"):
        select_correction(S[:601], y[:601])


def test_kde_auto_correction_is_one_of_the_two_fits():
    """``correct="auto"`` decides on held-out validation scores with its own random stream, then fits exactly what
    ``correct=True`` or ``correct=False`` fits."""
    X, y, Xv, yv = _two_gaussians(np.random.default_rng(2), 400, 300, d=8, shift=0.5)
    fits = {c: KDELikelihood(KDEConfig(method="dense", correct=c)).fit(X, y, Xv, yv) for c in (True, False, "auto")}
    chosen = fits[True] if fits["auto"].correction is not None else fits[False]
    assert fits["auto"].temperature == chosen.temperature
    q = Xv[:20]
    np.testing.assert_array_equal(fits["auto"].calibrate_scores(fits["auto"].log_likelihood(q)),
                                  chosen.calibrate_scores(chosen.log_likelihood(q)))
    with pytest.raises(ValueError, match="correct"):
        KDEConfig(correct="sometimes")


def _stretched_gaps(rng, p_true: float, B=6000, K=5):
    """Scores whose gaps to the best class are the true log-posterior's gaps raised to ``1 / p_true`` (x 2), and
    labels drawn from the true posterior: a :class:`PowerCorrection` with ``p = p_true`` undoes the stretch."""
    from scipy.special import log_softmax

    z = rng.normal(0.0, 1.5, (B, K))
    P = softmax(z, axis=1)
    y = (P.cumsum(1) > rng.random((B, 1))).argmax(1)
    logp = log_softmax(z, axis=1)
    return -2.0 * (logp.max(1, keepdims=True) - logp) ** (1 / p_true), y


def test_power_correction_recovers_the_exponent_and_beats_a_temperature_held_out():
    from haptic_env.recognizers.calibration import PowerCorrection, fit_power, select_calibration

    S, y = _stretched_gaps(np.random.default_rng(4), 0.6)
    S[0, 1] = -np.inf  # a class a KDE ruled out
    pc = fit_power(S, y)
    assert pc.p == pytest.approx(0.6, abs=0.05)
    out = pc(S)
    assert out.shape == S.shape and np.isfinite(out).all() and np.all(out.max(1) == 0.0)
    assert out[0, 1] == pytest.approx(-pc.cap ** pc.p)  # the ruled-out class sits at the cap
    C = pc(S)
    T = fit_temperature(C, y)
    assert expected_calibration_error(softmax(C / T, axis=1), y) < expected_calibration_error(
        softmax(S / fit_temperature(S, y), axis=1), y)
    choice, nll = select_calibration(S, y, ("matrix", "power"))
    assert choice == "power" and nll["power"] < nll[None] - 0.01
    # the first candidates' choice and held-out NLLs do not depend on a later candidate (one random stream)
    only, nll1 = select_calibration(S, y, ("matrix",))
    assert nll1[None] == nll[None] and nll1["matrix"] == nll["matrix"]
    assert select_correction(S, y) == (only == "matrix", nll1[None], nll1["matrix"])
    np.testing.assert_array_equal(PowerCorrection(1.0, pc.cap)(S[1:]), np.maximum(S[1:] - S[1:].max(1, keepdims=True),
                                                                                 -pc.cap))  # p = 1: the identity
    with pytest.raises(ValueError, match="candidates"):
        select_calibration(S, y, ("matrix", "isotonic"))
    with pytest.raises(ValueError, match="bounds"):
        fit_power(S, y, bounds=(1.0, 0.5))


def test_kde_power_correction_is_stored_and_chosen_by_auto_only_where_it_helps(monkeypatch):
    """``correct="power"`` fits it and the cache round trip keeps it; ``correct="auto"`` with the power among its
    candidates fits exactly what the chosen one fits, and what it fits is select_calibration's choice on the KDE's
    own validation scores (whose choice, the lowest held-out NLL, is tested above); bad names are refused."""
    import haptic_env.recognizers.kde as kde_module
    from haptic_env.recognizers.calibration import PowerCorrection, ScoreCorrection

    X, y, Xv, yv = _two_gaussians(np.random.default_rng(2), 400, 300, d=8, shift=0.5)
    power = KDELikelihood(KDEConfig(method="dense", correct="power")).fit(X, y, Xv, yv)
    assert isinstance(power.correction, PowerCorrection)
    again = KDELikelihood.from_state(power.config, power.state())
    q = Xv[:20]
    assert again.correction == power.correction and again.temperature == power.temperature
    np.testing.assert_allclose(again.calibrate_scores(again.log_likelihood(q)),
                               power.calibrate_scores(power.log_likelihood(q)), atol=1e-5)
    auto = KDELikelihood(KDEConfig(method="dense", correct="auto", correct_candidates=("matrix", "power"))
                         ).fit(X, y, Xv, yv)
    kind = {type(None): False, PowerCorrection: "power"}.get(type(auto.correction), True)
    chosen = KDELikelihood(KDEConfig(method="dense", correct=kind)).fit(X, y, Xv, yv)
    assert auto.temperature == chosen.temperature
    np.testing.assert_array_equal(auto.calibrate_scores(auto.log_likelihood(q)),
                                  chosen.calibrate_scores(chosen.log_likelihood(q)))
    # the wiring: auto takes whatever select_calibration chooses among the configured candidates
    seen = []
    for forced, expected in ((None, type(None)), ("power", PowerCorrection), ("matrix", ScoreCorrection)):
        def select(S, Y, candidates, *, forced=forced, **kw):
            seen.append((S.shape, tuple(candidates)))
            return forced, {}

        monkeypatch.setattr(kde_module, "select_calibration", select)
        fitted = KDELikelihood(KDEConfig(method="dense", correct="auto", correct_candidates=("matrix", "power"))
                               ).fit(X, y, Xv, yv)
        assert type(fitted.correction) is expected
    assert seen == [((len(Xv), 2), ("matrix", "power"))] * 3  # the KDE's scores of its validation vectors
    with pytest.raises(ValueError, match="correct_candidates"):
        KDEConfig(correct="auto", correct_candidates=("power", "power"))
    with pytest.raises(ValueError, match="correct must be"):
        KDEConfig(correct="isotonic")


def test_calibration_rows_take_at_most_n_of_each_class_without_repeats():
    y = np.array([0] * 5 + [1] * 2 + [3] * 4)  # class 2 has no rows
    rows = calibration_rows(y, 4, 3, np.random.default_rng(0))
    assert len(rows) == len(set(rows.tolist())) == 3 + 2 + 3
    assert np.bincount(y[rows], minlength=4).tolist() == [3, 2, 0, 3]
    assert (np.diff(y[rows]) >= 0).all()  # in class order
    np.testing.assert_array_equal(rows, calibration_rows(y, 4, 3, np.random.default_rng(0)))
