"""Belief: the one owner of grasp -> Phi_n -> likelihood -> posterior (single, batched, z-subsets, predictions)."""

from __future__ import annotations

import copy
import subprocess
import sys

import numpy as np
import pytest

from haptic_env.belief import Belief, get_recognizer
from haptic_env.recognizers.updaters import BayesianUpdater, bayes_steps


class _Fixed:
    def __init__(self, k):
        self.n_classes = k

    def log_likelihood(self, Q):
        return np.asarray(Q, dtype=np.float64)


def test_bayes_steps_updates_many_beliefs_as_one_updater_each():
    """B log beliefs at once (a vector env's step) = B separate updaters, including no-information rows."""
    rng = np.random.default_rng(0)
    B, K = 6, 4
    updaters = [BayesianUpdater(_Fixed(K)) for _ in range(B)]
    for u in updaters:
        u.update(rng.normal(size=(2, K)))  # different beliefs
    rows = [rng.normal(size=(m, K)) for m in (1, 3, 0, 2, 1, 1)]
    rows[4] = np.full((1, K), -np.inf)  # every class impossible: no information
    starts = np.concatenate([[0], np.cumsum([len(r) for r in rows])])
    new, updated = bayes_steps(np.stack([u.log_belief for u in updaters]), np.concatenate(rows), starts)
    for b, (u, r) in enumerate(zip(updaters, rows)):
        u.update_scores(log_lik=r)
        np.testing.assert_array_equal(new[b], u.log_belief)
    assert updated.tolist() == [True, True, False, True, False, True]
    with pytest.raises(ValueError, match="NaN"):
        bayes_steps(new[:1], np.full((1, K), np.nan), [0, 1])


@pytest.fixture(scope="module")
def recognizer(env_config):
    from haptic_env.objects import load_object_set

    return get_recognizer(load_object_set(env_config.objects), env_config.replace(z_fingers=3, updater="bc-ip"))


@pytest.mark.parametrize("kind,subsets", [("bc-np", False), ("bc-ip", False), ("ic", False), ("ic-full", False),
                                           ("bc-np", True), ("bc-ip", True)])
def test_predict_grasps_equals_updating_a_copy(recognizer, kind, subsets):
    """Also with z-subset scoring counted as at most 2 subsets (a complete grasp's 4 rows weigh 1/2)."""
    from haptic_env.grasping import make_backend

    belief = Belief(recognizer, kind, z_fingers=3, score_subsets=subsets, subset_k=2)
    backend = make_backend("geometric", n_fingers=4)
    from haptic_env.objects import load_object_set

    backend.set_object(load_object_set("default")[0], np.eye(4))
    res = backend.grasp_batch(np.random.default_rng(1).uniform(-1, 1, (24, 4)), np.random.default_rng(2))
    for _ in range(2):  # before and after a first grasp (BC-IP's classifier prior, then Bayes steps)
        before = belief.probs.copy()
        post, scored = belief.predict_grasps(res.contacts, res.normals, res.touched)
        assert scored.size > 0 and np.array_equal(belief.probs, before)
        for p, i in zip(post, scored):
            ref = copy.deepcopy(belief)
            q, usable = ref.update(res.contacts[i], res.normals[i], res.touched[i])
            assert usable
            np.testing.assert_allclose(p, ref.probs, rtol=1e-9, atol=1e-12)
        belief.update(res.contacts[scored[0]], res.normals[scored[0]], res.touched[scored[0]])


def test_subset_k_weighs_a_grasps_subsets_as_k_of_them(recognizer):
    """A complete 4-finger grasp has C(4, 3) = 4 subsets: subset_k = 2 halves their summed log-likelihood, 4 (the
    paper's k) and None leave the product as it is; a 3-finger grasp's one subset is never down-weighted."""
    from scipy.special import softmax

    rng = np.random.default_rng(4)
    C, N = rng.normal(size=(4, 3)) * 0.05, rng.normal(size=(4, 3))
    probs = {}
    for k in (None, 4, 2):
        b = Belief(recognizer, "bc-np", z_fingers=3, score_subsets=True, subset_k=k)
        _, Q = b.rows(C, N, np.ones(4, bool))
        assert len(Q) == 4 and b.row_weight(len(Q)) == (0.5 if k == 2 else 1.0) and b.row_weight(1) == 1.0
        b.update(C, N, np.ones(4, bool))
        probs[k] = b.probs
        L = b.scores(Q)[0].sum(0)
    np.testing.assert_allclose(probs[None], probs[4], rtol=1e-12)
    np.testing.assert_allclose(probs[None], softmax(L), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(probs[2], softmax(0.5 * L), rtol=1e-9, atol=1e-12)
    for bad in (0, -1, 2.5, True, "4"):
        with pytest.raises(ValueError, match="subset_k"):
            Belief(recognizer, "bc-np", z_fingers=3, score_subsets=True, subset_k=bad)


def test_min_fingers_scores_the_grasps_that_z_subsets_drop(env_config):
    """With z = 3 subsets, a grasp of two touching fingers carries no contact information unless ``min_fingers=2``
    scores it by the 2-finger model (one row of its width); grasps of t >= 3 keep their z-subsets."""
    from haptic_env.objects import load_object_set

    rec = get_recognizer(load_object_set(env_config.objects), env_config.replace(z_fingers=2, updater="bc-ip"))
    rng = np.random.default_rng(5)
    C, N = rng.normal(size=(4, 3)) * 0.05, rng.normal(size=(4, 3))
    two = np.array([True, False, True, False])
    plain = Belief(rec, "bc-np", z_fingers=3, score_subsets=True)
    both = Belief(rec, "bc-np", z_fingers=3, score_subsets=True, min_fingers=2)
    assert plain.rows(C, N, two)[1] is None
    _, Q = both.rows(C, N, two)
    np.testing.assert_array_equal(Q, rec.features(C[two], N[two]))
    for touched in (np.ones(4, bool), np.array([True, True, True, False])):
        np.testing.assert_array_equal(both.rows(C, N, touched)[1], plain.rows(C, N, touched)[1])
    post, scored = both.predict_grasps(C[None], N[None], two[None])  # the look-ahead sees it too
    q, usable = both.update(C, N, two)
    assert usable and scored.tolist() == [0] and not np.allclose(both.probs, plain.probs)
    np.testing.assert_allclose(post[0], both.probs, rtol=1e-9, atol=1e-12)
    for bad in (3, 1, 2.5, True):
        with pytest.raises(ValueError, match="min_fingers"):
            Belief(rec, "bc-np", z_fingers=3, score_subsets=True, min_fingers=bad)
    with pytest.raises(ValueError, match="min_fingers"):
        Belief(rec, "bc-np", z_fingers=3, min_fingers=2)


def test_subset_scores_are_the_rows_of_each_grasps_subsets(recognizer):
    from itertools import combinations

    belief = Belief(recognizer, "bc-ip", z_fingers=3)
    rng = np.random.default_rng(3)
    C, N = rng.normal(size=(5, 4, 3)) * 0.05, rng.normal(size=(5, 4, 3))
    ll, pr, kept = belief.subset_scores(C, N, 3)
    assert kept.tolist() == list(range(5))
    for g in range(5):
        Q = np.concatenate([recognizer.features(C[g][list(s)], N[g][list(s)]) for s in combinations(range(4), 3)])
        L, P = belief.scores(Q)
        np.testing.assert_allclose(ll[g], L.sum(0), rtol=1e-10)
        np.testing.assert_allclose(pr[g], P.mean(0), rtol=1e-10)
    # k = 2 random subsets per grasp: the two drawn from the same generator (an independent random order per grasp)
    ll2, pr2, _ = belief.subset_scores(C, N, 3, k=2, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="trained with normals; pass the contact normals"):  # as rows_batch says
        belief.subset_scores(C, None, 3)
    subsets = list(combinations(range(4), 3))
    pick = np.argsort(np.random.default_rng(0).random((5, len(subsets))), axis=1)[:, :2]
    for g in range(5):
        Q = np.concatenate([recognizer.features(C[g][list(subsets[i])], N[g][list(subsets[i])]) for i in pick[g]])
        L, P = belief.scores(Q)
        np.testing.assert_allclose(ll2[g], L.sum(0), rtol=1e-10)
        np.testing.assert_allclose(pr2[g], P.mean(0), rtol=1e-6)  # the MLP in float32, another batch size
    assert not np.allclose(ll2, ll)  # two of the four subsets, not all of them


def test_importing_the_kde_or_the_updaters_does_not_load_torch():
    for module in ("haptic_env.recognizers.kde", "haptic_env.recognizers.updaters", "haptic_env.belief",
                   "haptic_env.env", "haptic_env.recognizers.recognizer", "haptic_env.recognizers.mlp_config"):
        code = f"import sys, {module}; assert 'torch' not in sys.modules, '{module} loaded torch'"
        subprocess.run([sys.executable, "-c", code], check=True)
    # an env's recogniser settings (BC-NP: the KDE only) are built without torch, which only the MLP needs
    code = ("import sys; from haptic_env.config import HapticRecogConfig, recognizer_kwargs; "
            "rc = recognizer_kwargs(HapticRecogConfig(recognizer_kwargs={'config': {'mlp': {'depth': 1}}}))['config']; "
            "assert rc.mlp.depth == 1; assert 'torch' not in sys.modules, 'recognizer_kwargs loaded torch'")
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.fixture(scope="module")
def touch_recognizer(recognizer):
    """The small recogniser with a made-up touch model (4 fingers, 16 patterns; a real one needs a hand's pool)."""
    import dataclasses

    from haptic_env.recognizers.touch import TouchModel

    rng = np.random.default_rng(11)
    T = rng.random((recognizer.n_classes, 50, 4)) < rng.uniform(0.2, 0.9, (recognizer.n_classes, 1, 4))
    return dataclasses.replace(recognizer, touch=TouchModel.fit(T))


def test_touch_pattern_adds_w_log_p_at_every_grasp(touch_recognizer):
    """A grasp without contacts still moves the belief by its pattern; a complete grasp by contacts + pattern, the
    same on the compiled and the general path; predict_grasps = updating a copy, every grasp scored."""
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set

    w = 0.5
    belief = Belief(touch_recognizer, "bc-np", z_fingers=3, touch_weight=w)
    plain = Belief(touch_recognizer, "bc-np", z_fingers=3)
    none = np.zeros(4, dtype=bool)
    q, usable = belief.update(np.zeros((4, 3)), np.zeros((4, 3)), none)
    assert usable and not q.any()
    lp = w * touch_recognizer.touch.log_p[:, 0]
    np.testing.assert_allclose(belief.probs, np.exp(lp - logsumexp_(lp)), rtol=1e-12)
    assert plain.update(np.zeros((4, 3)), np.zeros((4, 3)), none)[1] is False  # without: no information

    backend = make_backend("geometric", n_fingers=4)
    backend.set_object(load_object_set("default")[1], np.eye(4))
    res = backend.grasp_batch(np.random.default_rng(1).uniform(-1, 1, (24, 4)), np.random.default_rng(2))
    full = int(np.flatnonzero(res.touched.all(axis=1))[0])
    general = copy.deepcopy(belief)
    general.compiled = False
    belief.update(res.contacts[full], res.normals[full], res.touched[full])
    general.update(res.contacts[full], res.normals[full], res.touched[full])
    np.testing.assert_allclose(belief.probs, general.probs, rtol=1e-9, atol=1e-12)
    ref = copy.deepcopy(plain)  # contacts alone, then the pattern's row: the same sum
    ref.update(res.contacts[full], res.normals[full], res.touched[full])
    lb = np.log(ref.probs) + belief.touch_rows(res.touched[full])[0] + w * touch_recognizer.touch.log_p[:, 0]
    np.testing.assert_allclose(belief.probs, np.exp(lb - logsumexp_(lb)), rtol=1e-9)

    mean = copy.deepcopy(belief)  # the subsets' mean row (combine="mean"), the pattern's row beside it
    mean.updater.combine = "mean"
    for b in (belief, mean):
        post, scored = b.predict_grasps(res.contacts, res.normals, res.touched)
        assert scored.tolist() == list(range(24))
        for p, i in zip(post, scored):
            cp = copy.deepcopy(b)
            cp.update(res.contacts[i], res.normals[i], res.touched[i])
            np.testing.assert_allclose(p, cp.probs, rtol=1e-9, atol=1e-12)


def test_touch_pattern_with_bc_ip_sets_the_classifier_prior_at_the_first_scored_grasp(touch_recognizer):
    """BC-IP with the touch pattern: a grasp without contacts moves the belief by its pattern and leaves the prior
    to come; the first complete grasp multiplies in the classifier's prior and its pattern in one step; later
    grasps are KDE + pattern steps, the compiled path as the general one; predict_grasps = updating a copy."""
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set

    w = 0.5
    belief = Belief(touch_recognizer, "bc-ip", z_fingers=3, touch_weight=w)
    none = np.zeros(4, dtype=bool)
    assert belief.update(np.zeros((4, 3)), np.zeros((4, 3)), none)[1]
    lp = w * touch_recognizer.touch.log_p[:, 0]
    np.testing.assert_allclose(belief.probs, np.exp(lp - logsumexp_(lp)), rtol=1e-12)
    assert not belief.updater.prior_set and belief.n_grasps == 1

    backend = make_backend("geometric", n_fingers=4)
    backend.set_object(load_object_set("default")[1], np.eye(4))
    res = backend.grasp_batch(np.random.default_rng(1).uniform(-1, 1, (24, 4)), np.random.default_rng(2))
    full = np.flatnonzero(res.touched.all(axis=1))
    post, scored = belief.predict_grasps(res.contacts, res.normals, res.touched)  # before the prior
    for p, i in zip(post, scored):
        cp = copy.deepcopy(belief)
        cp.update(res.contacts[i], res.normals[i], res.touched[i])
        np.testing.assert_allclose(p, cp.probs, rtol=1e-9, atol=1e-12)
    before = np.log(belief.probs)
    _, Q = belief.rows(res.contacts[full[0]], res.normals[full[0]], res.touched[full[0]])
    with_prior = belief.updater.with_prior(before, belief.models.predict_proba(Q))
    belief.update(res.contacts[full[0]], res.normals[full[0]], res.touched[full[0]])
    lb = with_prior + belief.touch_rows(res.touched[full[0]])[0]
    np.testing.assert_allclose(belief.probs, np.exp(lb - logsumexp_(lb)), rtol=1e-9)
    assert belief.updater.prior_set and belief.n_grasps == 2

    general = copy.deepcopy(belief)
    general.compiled = False
    for b in (belief, general):
        b.update(res.contacts[full[1]], res.normals[full[1]], res.touched[full[1]])
    np.testing.assert_allclose(belief.probs, general.probs, rtol=1e-9, atol=1e-12)
    post, scored = belief.predict_grasps(res.contacts, res.normals, res.touched)  # after it
    for p, i in zip(post, scored):
        cp = copy.deepcopy(belief)
        cp.update(res.contacts[i], res.normals[i], res.touched[i])
        np.testing.assert_allclose(p, cp.probs, rtol=1e-9, atol=1e-12)
    belief.reset()
    assert not belief.updater.prior_set and belief.n_grasps == 0


def test_touch_weight_is_checked(recognizer, touch_recognizer):
    with pytest.raises(ValueError, match="touch model"):
        Belief(recognizer, "bc-np", touch_weight=0.5)
    with pytest.raises(ValueError, match="bc-np"):
        Belief(touch_recognizer, "ic", touch_weight=0.5)
    for bad in (-0.1, np.nan, np.inf, True, "0.5"):
        with pytest.raises(ValueError, match="touch_weight"):
            Belief(touch_recognizer, "bc-np", touch_weight=bad)
    assert not Belief(touch_recognizer, "bc-np", touch_weight=0).touch_rows(np.ones((3, 4), bool)).any()


def logsumexp_(v):
    from scipy.special import logsumexp

    return logsumexp(v)


@pytest.mark.parametrize("axis", ["ab", "frame"])
def test_a_recogniser_with_normal_axis_ab_or_frame_is_scored_with_it(env_config, small_recognizer_kwargs, axis):
    """A recogniser trained on ``DatasetConfig(normal_axis=axis)`` vectors: the belief computes the same Phi (compiled
    and general path alike), and predictions equal updates."""
    import copy as _copy

    from haptic_env.grasp_features import phi
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set

    kw = _copy.deepcopy(small_recognizer_kwargs)
    kw["config"]["grasps"]["normal_axis"] = axis
    cfg = env_config.replace(recognizer_kwargs=kw, normal_axis=axis)  # the env config follows its recogniser
    rec = get_recognizer(load_object_set(cfg.objects), cfg)
    assert rec.normal_axis == axis and rec.config.grasps.normal_axis == axis
    backend = make_backend("geometric", n_fingers=4)
    backend.set_object(load_object_set("default")[2], np.eye(4))
    res = backend.grasp_batch(np.random.default_rng(3).uniform(-1, 1, (40, 4)), np.random.default_rng(4))
    full = np.flatnonzero(res.touched.all(axis=1))[:3]
    belief, general = Belief(rec, "bc-np"), Belief(rec, "bc-np")
    general.compiled = False
    assert belief.normal_axis == axis and rec.grasp_scorer() is not None
    for i in full:
        q, usable = belief.update(res.contacts[i], res.normals[i], res.touched[i])
        general.update(res.contacts[i], res.normals[i], res.touched[i])
        assert usable
        np.testing.assert_allclose(q, phi(res.contacts[i], res.normals[i], normal_axis=axis).q, atol=1e-12)
        np.testing.assert_allclose(belief.probs, general.probs, rtol=1e-9, atol=1e-12)
    post, scored = belief.predict_grasps(res.contacts, res.normals, res.touched)
    for p, i in zip(post[:3], scored[:3]):
        ref = _copy.deepcopy(belief)
        ref.update(res.contacts[i], res.normals[i], res.touched[i])
        np.testing.assert_allclose(p, ref.probs, rtol=1e-9, atol=1e-12)


def test_ic_certainty_reaches_the_belief_and_the_env_config(recognizer, env_config):
    """``HapticRecogConfig.ic_certainty`` / ``Belief(ic_certainty=)``: the env's IC can take the authors' share rule,
    which never decides on the first grasp; a bad rule is refused by name."""
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set

    share, count = Belief(recognizer, "ic", ic_certainty="share"), Belief(recognizer, "ic")
    assert (share.updater.base.certainty_rule, count.updater.base.certainty_rule) == ("share", "count")
    backend = make_backend("geometric", n_fingers=4)
    backend.set_object(load_object_set("default")[0], np.eye(4))
    res = backend.grasp_batch(np.random.default_rng(1).uniform(-1, 1, (24, 4)), np.random.default_rng(2))
    i = int(np.flatnonzero(res.touched.all(1))[0])
    share.update(res.contacts[i], res.normals[i], res.touched[i])
    count.update(res.contacts[i], res.normals[i], res.touched[i])
    assert share.n_grasps == 1 and not share.decided
    np.testing.assert_allclose(share.probs, count.probs)  # the rule changes the certainty, not the belief
    assert env_config.replace(updater="ic", ic_certainty="share").ic_certainty == "share"
    with pytest.raises(ValueError, match=r"ic_certainty must be one of \('count', 'share'\), got 'sum'"):
        env_config.replace(ic_certainty="sum")


def test_the_process_keeps_the_last_recognisers_used(env_config, monkeypatch):
    import haptic_env.belief as belief
    import haptic_env.recognizers as recognizers

    from haptic_env.objects import load_object_set

    objects = load_object_set(env_config.objects)
    configs = [env_config.replace(n_fingers=n) for n in (2, 3, 4, 5, 6)]
    built = []
    monkeypatch.setattr(recognizers, "build_recognizer", lambda *a, **k: built.append(k) or object())
    monkeypatch.setattr(belief, "_RECOGNIZERS", type(belief._RECOGNIZERS)())
    first = [get_recognizer(objects, c) for c in configs[:4]]
    assert get_recognizer(objects, configs[0]) is first[0] and len(built) == 4  # memoised, now the most recent
    get_recognizer(objects, configs[4])  # a fifth: the least recently used (n = 3) goes
    assert len(belief._RECOGNIZERS) == belief.MAX_RECOGNIZERS == 4
    assert get_recognizer(objects, configs[0]) is first[0] and len(built) == 5
    assert get_recognizer(objects, configs[1]) is not first[1] and len(built) == 6  # n = 3 built again


def test_a_set_of_the_same_names_but_other_meshes_gets_its_own_recogniser(env_config, monkeypatch):
    """The process's memo is keyed by the meshes, not only the names: the same set loaded in other units (or from
    another folder) is another recogniser."""
    import haptic_env.belief as belief
    import haptic_env.recognizers as recognizers

    from haptic_env.objects import GraspObject, ObjectSet, load_object_set

    objects = load_object_set(env_config.objects)
    scaled = ObjectSet(objects.name, [GraspObject(o.name, o.mesh.copy().apply_scale(2.0)) for o in objects])
    assert scaled.names == objects.names and scaled.identity != objects.identity
    built = []
    monkeypatch.setattr(recognizers, "build_recognizer", lambda *a, **k: built.append(k) or object())
    monkeypatch.setattr(belief, "_RECOGNIZERS", type(belief._RECOGNIZERS)())
    assert get_recognizer(objects, env_config) is not get_recognizer(scaled, env_config) and len(built) == 2


def test_a_recogniser_of_other_grasp_vectors_is_refused_by_the_belief(env_config):
    """The make-time check reads recognizer_kwargs; ``check_grasp_vectors`` is the one for a recogniser however it
    came: its normal axis and heights must be the config's."""
    from types import SimpleNamespace

    from haptic_env.belief import check_grasp_vectors

    with pytest.raises(ValueError, match=r"second angle to 't2' but the config has normal_axis='ab'"):
        check_grasp_vectors(SimpleNamespace(normal_axis="t2", heights=False), env_config.replace(normal_axis="ab"))
    with pytest.raises(ValueError, match="lack the contact heights but the config has grasp_heights=True"):
        check_grasp_vectors(SimpleNamespace(normal_axis="t2", heights=False), env_config.replace(grasp_heights=True))
    check_grasp_vectors(SimpleNamespace(normal_axis="t2", heights=False), env_config)


def test_bad_grasps_are_refused_alike_on_the_compiled_and_the_general_path(recognizer):
    """``update`` checks ``touched`` before either path (the compiled one read only its count: a ``touched`` of the
    wrong length was scored as a complete grasp); ``z_fingers`` outside ``[2, n)`` is refused as the env config
    refuses it; the prior after a reset is read-only as every later belief."""
    contacts = np.array([[0.03, 0, 0], [-0.03, 0, 0], [0, 0.03, 0.01], [0, -0.03, -0.01]])
    normals = -contacts / np.linalg.norm(contacts, axis=1, keepdims=True)
    for compiled in (True, False):
        b = Belief(recognizer, "bc-np")
        b.compiled = compiled
        for touched in (np.ones(3, bool), np.ones(5, bool), np.ones(0, bool)):
            with pytest.raises(ValueError, match=rf"touched must have shape \(4,\), got \({len(touched)},\)"):
                b.update(contacts, normals, touched)
        assert b.n_grasps == 0
        assert not b.probs.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            b.probs[0] = 5.0
    for z in (1, 4, 5, 2.0, True):
        with pytest.raises(ValueError, match=r"z_fingers must be None or in \[2, n_fingers=4\)"):
            Belief(recognizer, "bc-np", z_fingers=z)


def test_a_recogniser_without_normals_ignores_them_on_every_path(env_config):
    """Normals given to a belief whose recogniser has none are ignored by ``update`` (compiled and general, as
    ``rows_batch`` ignores them) and by ``subset_scores``, which refuses ``k`` random subsets without an ``rng``."""
    from haptic_env.objects import load_object_set

    rec = get_recognizer(load_object_set(env_config.objects), env_config.replace(normals=False, z_fingers=3))
    assert not rec.normals
    contacts = np.array([[0.03, 0, 0], [-0.03, 0, 0], [0, 0.03, 0.01], [0, -0.03, -0.01]])
    normals = -contacts / np.linalg.norm(contacts, axis=1, keepdims=True)
    touched = np.ones(4, bool)
    posts = []
    for compiled in (True, False):
        for n in (None, normals):
            b = Belief(rec, "bc-np")
            b.compiled = compiled
            b.update(contacts, n, touched)
            posts.append(b.probs)
    for p in posts[1:]:
        np.testing.assert_allclose(p, posts[0], rtol=1e-12, atol=1e-15)
    b = Belief(rec, "bc-np", z_fingers=3, score_subsets=True)
    with_n, without = b.subset_scores(contacts[None], normals[None], 3), b.subset_scores(contacts[None], None, 3)
    for x, y in zip(with_n, without):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(ValueError, match=r"k=2 of the 4 3-subsets are drawn at random; pass rng"):
        b.subset_scores(contacts[None], None, 3, k=2)
