"""Belief-updater maths on hand-made likelihoods and probabilities."""

import copy

import numpy as np
import pytest
from scipy.special import logsumexp

from haptic_env.recognizers.updaters import BCIP, BayesianUpdater, IterativeClassification, make_updater


class FixedModel:
    """Returns preset rows: ``log_likelihood``/``predict_proba`` of row ``int(q[0])``."""

    def __init__(self, table):
        self.table = np.asarray(table, dtype=float)
        self.n_classes = self.table.shape[1]

    def log_likelihood(self, Q):
        return self.table[np.asarray(Q)[:, 0].astype(int)]

    def predict_proba(self, Q):
        return self.table[np.asarray(Q)[:, 0].astype(int)]


def test_ic_accumulates_winner_probability():
    P = [[0.6, 0.3, 0.1], [0.2, 0.7, 0.1], [0.5, 0.4, 0.1]]
    u = IterativeClassification(FixedModel(P), threshold=0.85)
    assert np.allclose(u.reset(), 1 / 3) and not u.decided
    u.update([0.0])
    u.update([1.0])
    b = u.update([2.0])
    assert np.allclose(u.scores, [0.6 + 0.5, 0.7, 0.0])
    assert np.allclose(b, u.scores / 3)
    assert u.prediction == 0 and u.certainty == pytest.approx(1.1 / 3)


def test_ic_full_adds_whole_vector():
    P = [[0.6, 0.3, 0.1], [0.2, 0.7, 0.1]]
    u = make_updater("ic-full", classifier=FixedModel(P))
    u.update([0.0])
    b = u.update([1.0])
    assert np.allclose(b, np.mean(P, axis=0)) and b.sum() == pytest.approx(1.0)


def test_ic_decides_at_threshold():
    u = IterativeClassification(FixedModel([[0.9, 0.1], [0.7, 0.3], [0.85, 0.15]]), threshold=0.85)
    u.update([0.0])
    assert u.decided and u.certainty == pytest.approx(0.9)  # one grasp at 0.9 >= 0.85
    u.update([1.0])
    assert not u.decided and u.certainty == pytest.approx(0.8)  # (0.9 + 0.7) / 2
    u.reset()
    u.update([2.0])
    assert u.certainty == 0.85 and u.decided  # exactly at the threshold counts as decided


def test_ic_share_certainty_is_the_winners_share_from_the_second_grasp():
    """``certainty="share"`` (the authors' code): the last grasp's winner's score while below 0.6, then its share of the
    winners' scores; never decided on one grasp."""
    P = [[0.7, 0.3, 0.0], [0.8, 0.2, 0.0], [0.4, 0.6, 0.0], [0.4, 0.3, 0.3], [0.3, 0.4, 0.3]]
    u = make_updater("ic", classifier=FixedModel(P), ic_certainty="share")
    u.reset()
    u.update([0.0])
    assert u.certainty == pytest.approx(1.0) and not u.decided  # 0.7 >= 0.6: share 1, but one grasp never decides
    u.update([1.0])
    assert u.certainty == pytest.approx(1.0) and u.decided and u.prediction == 0  # the count rule: 1.5 / 2 = 0.75
    u.update([2.0])  # class 1 wins this grasp with 0.6: its share 0.6 / 2.1
    assert u.certainty == pytest.approx(0.6 / 2.1) and not u.decided and u.prediction == 0
    u.reset()
    u.update([3.0])
    u.update([4.0])  # winners 0 then 1, each 0.4 < 0.6: the certainty is the last winner's score
    assert u.certainty == pytest.approx(0.4) and not u.decided
    with pytest.raises(ValueError, match=r"IC certainty must be one of \('count', 'share'\), got 'sum'"):
        make_updater("ic", classifier=FixedModel(P), ic_certainty="sum")
    with pytest.raises(ValueError, match="winner-only IC"):
        IterativeClassification(FixedModel(P), full=True, certainty="share")


def test_ic_share_stops_where_the_authors_loop_stops():
    """On random probability sequences, the ``share`` updater stops on the grasp and with the prediction of the authors'
    IC loop (``IC_inference.py``: ``P[j] += p[j]``; ``p_all = P[j]`` if ``P[j] < 0.6`` else ``P[j] / sum(P)``; at
    least two grasps), written out here as the oracle."""
    from haptic_env.experiments.trials import run_trial, scores_updater

    rng = np.random.default_rng(3)
    K, lam = 4, 0.85
    u = scores_updater("ic", K, lam, ic_certainty="share")
    for _ in range(300):
        seq = rng.dirichlet(np.full(K, rng.choice([0.3, 1.0, 3.0])), size=30)
        Pref, stop = np.zeros(K), len(seq)
        for count, p in enumerate(seq, start=1):
            j = int(np.argmax(p))
            Pref[j] += p[j]
            p_all = Pref[j] if Pref[j] < 0.6 else Pref[j] / Pref.sum()
            if count > 1 and p_all >= lam:
                stop = count
                break
        run_trial(u, ((np.zeros((1, K)), p[None]) for p in seq))
        assert u.n_grasps == stop and u.prediction == int(np.argmax(Pref))
        assert u.decided == (stop < len(seq) or p_all >= lam)


def test_bc_posterior_is_normalised_product():
    rng = np.random.default_rng(0)
    L = rng.uniform(0.01, 1.0, size=(5, 4))
    prior = np.array([0.1, 0.2, 0.3, 0.4])
    u = BayesianUpdater(FixedModel(np.log(L)), threshold=0.99)
    u.reset(prior)
    for i in range(5):
        b = u.update([float(i)])
    expect = prior * L.prod(axis=0)
    assert np.allclose(b, expect / expect.sum())
    assert u.n_grasps == 5


def test_bc_log_space_stable_with_tiny_likelihoods():
    ll = np.array([[-2000.0, -2001.0, -2010.0]])  # exp() underflows to 0 in every class
    u = BayesianUpdater(FixedModel(ll), threshold=0.85)
    for _ in range(3):
        b = u.update([0.0])
    assert np.all(np.isfinite(b)) and b.sum() == pytest.approx(1.0)
    w = np.exp(3 * (ll[0] - logsumexp(ll[0])))
    assert np.allclose(b, w / w.sum())


def test_bc_decided_threshold_and_sub_grasp_product():
    ll = np.log([[0.5, 0.5], [0.9, 0.1]])
    u = BayesianUpdater(FixedModel(ll), threshold=0.85)
    u.update([0.0])
    assert not u.decided and u.certainty == pytest.approx(0.5)
    u.update(np.array([[1.0], [1.0]]))  # two sub-grasps of one grasp multiply: 0.81 : 0.01
    assert u.decided and u.prediction == 0 and u.certainty == pytest.approx(0.81 / 0.82)
    m = BayesianUpdater(FixedModel(ll), combine="mean")
    m.update(np.array([[1.0], [1.0]]))
    assert m.certainty == pytest.approx(0.9)
    # evidence rows (the touch pattern) are summed beside the models' mean row, not averaged in with its rows
    E = np.log([[0.2, 0.8]])
    for combine, model in (("product", 2 * ll[1]), ("mean", ll[1])):
        u = BayesianUpdater(FixedModel(ll), combine=combine)
        post = model + E[0]
        np.testing.assert_allclose(u.update(np.array([[1.0], [1.0]]), evidence=E), np.exp(post) / np.exp(post).sum())


def test_bcip_prior_from_classifier_then_kde():
    proba = np.array([[0.7, 0.2, 0.1]])
    ll = np.log([[0.2, 0.5, 0.3]])

    class Clf(FixedModel):
        pass

    u = BCIP(Clf(proba), FixedModel(ll), threshold=0.99)
    b1 = u.update([0.0])
    assert np.allclose(b1, proba[0])  # first grasp: classifier only
    b2 = u.update([0.0])
    e = proba[0] * np.exp(ll[0])
    assert np.allclose(b2, e / e.sum())


def test_max_log_ratio_limits_one_outlier():
    ll = np.array([[0.0, -500.0]])
    u = BayesianUpdater(FixedModel(ll), max_log_ratio=10.0)
    b = u.update([0.0])
    assert b[1] == pytest.approx(np.exp(-10) / (1 + np.exp(-10)))


def test_bad_inputs_are_rejected():
    m = FixedModel([[0.5, 0.5]])
    with pytest.raises(ValueError, match="threshold"):
        BayesianUpdater(m, threshold=1.5)
    with pytest.raises(ValueError, match="prior"):
        BayesianUpdater(m).reset([1.0, -1.0])
    with pytest.raises(ValueError, match="unknown updater"):
        make_updater("bogus", classifier=m, likelihood=m)
    with pytest.raises(ValueError, match="needs a classifier"):
        make_updater("ic", likelihood=m)


def test_bc_nan_raises_and_impossible_grasp_carries_no_information():
    ll = np.array([[0.0, -1.0, -2.0], [np.nan, 0.0, 0.0], [-np.inf, -np.inf, -np.inf]])
    u = BayesianUpdater(FixedModel(ll))
    before = u.update([0.0]).copy()
    with pytest.raises(ValueError, match="NaN"):
        u.update([1.0])
    np.testing.assert_allclose(u.belief, before)  # nothing half-applied
    assert u.n_grasps == 1  # the failed update did not count
    np.testing.assert_allclose(u.update([2.0]), before)  # every class impossible: belief unchanged
    assert u.n_grasps == 2
    assert u.certainty == pytest.approx(before.max())


def test_bc_weight_tempers_one_step_and_predict_matches_update():
    """``update(q, weight)`` multiplies the step's summed log-likelihood; ``predict(weights=...)`` gives the same
    posteriors; BC-IP's first grasp (the classifier prior) takes no weight; bad weights are named."""
    rng = np.random.default_rng(5)
    L = np.log(rng.uniform(0.01, 1.0, size=(4, 3)))
    for cls in (BayesianUpdater, BCIP):
        model = FixedModel(L)
        proba = FixedModel(np.exp(L) / np.exp(L).sum(1, keepdims=True))
        u = BayesianUpdater(model) if cls is BayesianUpdater else BCIP(proba, model)
        u.update([[3.0]])  # a first step (BC-IP: its prior)
        Q, starts, w = np.array([[0.0], [1.0], [2.0]]), np.array([0, 2, 3]), np.array([0.4, 2.0])
        pred = u.predict(Q, starts, weights=w)
        for g in range(2):
            v = copy.deepcopy(u)
            got = v.update(Q[starts[g]:starts[g + 1]], weight=w[g])
            np.testing.assert_allclose(pred[g], got, rtol=1e-12)
            post = u.log_belief + w[g] * L[starts[g]:starts[g + 1]].sum(0)
            np.testing.assert_allclose(got, np.exp(post - logsumexp(post)), rtol=1e-10)
        for bad in (0.0, -1.0, np.inf, np.nan):
            with pytest.raises(ValueError, match="weight"):
                copy.deepcopy(u).update([[0.0]], weight=bad)
        for bad in ([1.0], [True, True], ["2", "1"], [1.0, np.nan]):
            with pytest.raises(ValueError, match="weights must be 2 positive finite numbers"):
                u.predict(Q, starts, weights=bad)
        if cls is BCIP:  # before its prior too (the weights were dropped unchecked there)
            fresh = BCIP(proba, model)
            for bad in ([-1.0, 0.0], [np.nan, np.inf], ["2", "x"]):
                with pytest.raises(ValueError, match="weights must be 2 positive finite numbers"):
                    fresh.predict(Q, starts, weights=bad)


def test_a_grasp_that_fits_only_ruled_out_classes_leaves_the_belief_as_it_was():
    """After a grasp rules class 0 out, a grasp that rules out every other class has nothing to update: the belief
    stays (it became NaN, reported as a valid update, on the batched path too)."""
    from haptic_env.recognizers.updaters import bayes_steps

    u = BayesianUpdater(None, 0.85, n_classes=3)
    u.update_scores(log_lik=np.array([[-np.inf, 0.0, 0.0]]))
    before = u.belief.copy()
    u.update_scores(log_lik=np.array([[0.0, -np.inf, -np.inf]]))
    assert np.allclose(u.belief, before) and np.isfinite(u.belief).all()
    log_b = np.log(np.array([[1e-300, 0.5, 0.5]]))
    log_b[0, 0] = -np.inf
    post, ok = bayes_steps(log_b, np.array([[0.0, -np.inf, -np.inf]]), np.array([0, 1]))
    assert not ok[0]  # reported as no information
    np.testing.assert_array_equal(post, log_b)  # the belief as it was


def test_evidence_rows_join_a_bayes_step_and_wait_for_bc_ips_prior():
    """Evidence (the touch pattern) is a Bayes step of its own before BC-IP's prior, joins the prior's step on the
    first grasp the classifier scores, and the KDE's step after; BC-NP's = log_lik and evidence as one step; IC and
    bad rows are refused before anything changes."""
    proba = np.array([[0.7, 0.2, 0.1]])
    ll = np.log([[0.2, 0.5, 0.3]])
    ev = np.log([[0.5, 0.25, 0.25]])
    u = BCIP(FixedModel(proba), FixedModel(ll), threshold=0.99)
    b = u.update_scores(evidence=ev)  # a grasp the classifier does not score
    np.testing.assert_allclose(b, [0.5, 0.25, 0.25])
    assert not u.prior_set and u.n_grasps == 1
    u.update_scores(proba=np.zeros((0, 3)), evidence=ev)  # no usable row: the grasp is spent, its evidence counts
    assert not u.prior_set and u.n_grasps == 2
    b = u.update([0.0], evidence=ev)  # the classifier's prior and the evidence in one step
    e = np.array([0.5, 0.25, 0.25]) ** 3 * proba[0]
    np.testing.assert_allclose(b, e / e.sum())
    assert u.prior_set and u.n_grasps == 3
    b = u.update([0.0], evidence=ev)
    e = e * np.exp(ll[0]) * [0.5, 0.25, 0.25]
    np.testing.assert_allclose(b, e / e.sum())
    for bad in (dict(log_lik=ll, evidence=np.full((1, 3), np.nan)), dict(log_lik=ll, evidence=np.zeros((1, 2)))):
        with pytest.raises(ValueError, match="evidence|NaN"):
            u.update_scores(**bad)
        np.testing.assert_allclose(u.belief, e / e.sum())
    u.reset()
    assert not u.prior_set
    with pytest.raises(ValueError, match="NaN"):
        u.update_scores(proba=proba, evidence=np.full((1, 3), np.nan))
    assert not u.prior_set and u.n_grasps == 0 and np.allclose(u.belief, 1 / 3)
    with pytest.raises(ValueError, match="probabilities"):  # the contacts' log_lik without the classifier's proba
        u.update_scores(log_lik=ll, evidence=ev)

    np_ = BayesianUpdater(FixedModel(ll))
    np_.update_scores(log_lik=ll, evidence=ev)
    e = np.exp(ll[0]) * [0.5, 0.25, 0.25]
    np.testing.assert_allclose(np_.belief, e / e.sum())
    np_.update_scores(evidence=ev)
    assert np_.n_grasps == 2
    with pytest.raises(ValueError, match="evidence"):
        IterativeClassification(FixedModel(proba), 0.85).update_scores(proba=proba, evidence=ev)


def test_a_refused_update_changes_nothing():
    """IC and BC-IP's first grasp refuse an update without classifier probabilities before counting the grasp; a
    bad prior leaves BC-IP as it was (its prior still set)."""
    for u in (IterativeClassification(None, 0.85, n_classes=2), BCIP(None, None, 0.85, n_classes=2)):
        with pytest.raises(ValueError, match="probabilities"):
            u.update_scores(log_lik=np.zeros((1, 2)))
        assert u.n_grasps == 0
    u = BCIP(None, None, 0.85, n_classes=2)
    u.update_scores(proba=[[0.7, 0.3]])
    with pytest.raises(ValueError, match="prior"):
        u.reset(prior=[-1.0, 1.0])
    assert u.prior_set and u.n_grasps == 1 and np.allclose(u.belief, [0.7, 0.3])


def test_bc_ip_without_evidence_keeps_the_papers_first_grasp():
    """A first grasp with no usable row is the prior's all the same (it stays uniform) when no evidence comes with
    it: the next grasp is a KDE step, as before evidence rows existed; with evidence the prior waits."""
    proba, ll = np.array([[0.7, 0.2, 0.1]]), np.log([[0.2, 0.5, 0.3]])
    u = BCIP(FixedModel(proba), FixedModel(ll), threshold=0.99)
    u.update(np.zeros((0, 1)))
    assert u.prior_set and u.n_grasps == 1
    np.testing.assert_allclose(u.update([0.0]), [0.2, 0.5, 0.3])
    u.reset()
    u.update(np.zeros((0, 1)), evidence=np.zeros((1, 3)))
    assert not u.prior_set
    np.testing.assert_allclose(u.update([0.0]), proba[0])


def test_scores_of_another_shape_or_not_probabilities_are_refused_before_anything_changes():
    """A transposed or other-K score array was reshaped into other rows (a belief from nonsense); NaN, inf, negative
    or > 1 probabilities made IC and BC-IP's beliefs NaN for good or decided at once. Each is a ValueError that
    changes nothing."""
    from haptic_env.recognizers.updaters import bayes_steps

    K = 3
    for make, kw, bad in [
        (lambda: BayesianUpdater(None, 0.85, n_classes=K), "log_lik", np.zeros((K, 2))),  # (K, m): transposed
        (lambda: BayesianUpdater(None, 0.85, n_classes=K), "log_lik", np.zeros((2, K + 1))),
        (lambda: IterativeClassification(None, 0.85, n_classes=K), "proba", np.full((1, 4), 0.25)),
        (lambda: BCIP(None, None, 0.85, n_classes=K), "proba", np.full((2, K + 1), 0.25)),
    ]:
        u = make()
        with pytest.raises(ValueError, match=rf"{kw} must have shape \(m, 3\)"):
            u.update_scores(**{kw: bad})
        assert u.n_grasps == 0
    for p in ([np.nan, 0.5, 0.5], [np.inf, 0.5, 0.5], [-0.2, 0.6, 0.6], [5.0, 0.0, 0.0], [1e308, 1e308, 1.0]):
        for u in (IterativeClassification(None, 0.85, n_classes=K), BCIP(None, None, 0.85, n_classes=K)):
            before = u.belief.copy()
            with pytest.raises(ValueError, match=r"proba must hold probabilities"):
                u.update_scores(proba=[p])
            assert u.n_grasps == 0 and np.array_equal(u.belief, before)
    one = BayesianUpdater(None, 0.85, n_classes=K)
    one.update_scores(log_lik=np.array([0.0, -1.0, -2.0]))  # one row as (K,) is still one grasp
    assert one.n_grasps == 1 and one.prediction == 0
    with pytest.raises(ValueError, match=r"log_lik must have shape \(m, 3\)"):
        bayes_steps(np.zeros((2, K)), np.zeros((K, 2)), np.array([0, 1, 2]))
    for bad in ({"combine": "mean "}, {"max_log_ratio": -5.0}):
        with pytest.raises(ValueError, match="combine|max_log_ratio"):
            bayes_steps(np.zeros((1, K)), np.zeros((1, K)), np.array([0, 1]), **bad)
    with pytest.raises(ValueError, match="starts must be whole numbers"):
        bayes_steps(np.zeros((2, K)), np.zeros((2, K)), np.array([0, 1.5, 2]))


def test_an_infinite_or_overflowing_log_likelihood_is_an_error_not_no_information():
    """+inf (or rows summing past the float range) was taken as 'no information': the grasp was spent, the belief
    kept; now it is refused as NaN is, with nothing changed."""
    from haptic_env.recognizers.updaters import bayes_steps

    for L in ([[np.inf, 0.0, 0.0]], [[1e308, 0.0, 0.0], [1e308, 0.0, 0.0]], [[np.inf, 0.0, 0.0], [-np.inf, 0.0, 0.0]]):
        u = BayesianUpdater(None, 0.85, n_classes=3)
        with pytest.raises(ValueError, match=r"NaN or \+inf"):
            u.update_scores(log_lik=np.array(L))
        assert u.n_grasps == 0
        with pytest.raises(ValueError, match=r"NaN or \+inf"):
            bayes_steps(np.zeros((1, 3)), np.array(L), np.array([0, len(L)]))


def test_a_prior_normalises_without_overflow_and_its_zeros_stay_impossible():
    """Huge prior entries overflowed their sum (a belief of zeros, or of 1e-300s that did not sum to 1); a class the
    prior gives 0 was 1e-300 likely, so that evidence against the allowed class made it win."""
    for kind in ("bc-np", "ic"):
        m = FixedModel([[1.0 / 3] * 3])
        u = make_updater(kind, classifier=m, likelihood=m)
        b = u.reset([1e308] * 3)
        np.testing.assert_allclose(b, [1 / 3] * 3)
    u = BayesianUpdater(None, 0.85, n_classes=3)
    u.reset([1.0, 0.0, 0.0])
    assert u.certainty == 1.0
    u.update_scores(log_lik=np.array([[-1000.0, 0.0, 0.0]]))  # fits the ruled-out classes better: still ruled out
    np.testing.assert_array_equal(u.belief, [1.0, 0.0, 0.0])  # no information: the belief stays
    u.update_scores(log_lik=np.array([[-1.0, 0.0, -5.0]]))
    np.testing.assert_array_equal(u.belief, [1.0, 0.0, 0.0])


def test_empty_rows_bad_starts_and_a_first_bc_ip_weight_are_handled_alike_on_every_path():
    """An empty row range leaves a belief unchanged with the row mean too (``0 / 0`` was NaN and raised); ``predict``
    refuses fractional ``starts`` as ``bayes_steps`` does (1.5 was cut to 1); BC-IP refuses a bad ``weight`` at its
    first grasp as at every later one."""
    from haptic_env.recognizers.updaters import bayes_steps

    L = np.log([[0.7, 0.2, 0.1], [0.2, 0.7, 0.1], [0.5, 0.25, 0.25]])
    logb = np.log(np.full((2, 3), 1 / 3))
    for combine in ("product", "mean"):
        new, updated = bayes_steps(logb, L[:1], [0, 0, 1], combine=combine)
        np.testing.assert_array_equal(new[0], logb[0])
        assert updated.tolist() == [False, True]
        u = BayesianUpdater(FixedModel(L), combine=combine)
        u.update([[0.0]])
        pred = u.predict(np.array([[1.0]]), [0, 0, 1])
        np.testing.assert_allclose(pred[0], u.belief, rtol=1e-12)
    u = BayesianUpdater(FixedModel(L))
    with pytest.raises(ValueError, match="starts must be whole numbers"):
        u.predict(np.array([[0.0], [1.0], [2.0]]), [0, 1.5, 3])
    for bad in (True, -1.0, 0.0, "2"):
        v = BCIP(FixedModel(np.exp(L)), FixedModel(L))
        with pytest.raises(ValueError, match="weight must be positive"):
            v.update([[0.0]], weight=bad)
        assert not v.prior_set and v.n_grasps == 0
