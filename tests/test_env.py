"""HapticRecogEnv: API conformance, determinism, pickling, errors, rewards, termination, observation layout."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
import warnings

import gymnasium as gym

import numpy as np
import pytest

import haptic_env
from haptic_env.env import HapticRecogConfig, HapticRecogEnv


def _make(env_config, **kw):
    return gym.make("HapticRecog-v0", config=env_config, **kw)


def _rollout(env, seed, n_steps, action_seed=123, options=None):
    """(obs list, rewards, infos) of ``n_steps`` random actions (resetting on episode end)."""
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed, options=options)
    out = [(obs, 0.0, info)]
    for _ in range(n_steps):
        a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, info))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs, 0.0, info))
    return out


def test_import_is_cheap_and_registers_ids():
    code = ("import sys, haptic_env, gymnasium as gym; "
            "assert 'torch' not in sys.modules and 'mujoco' not in sys.modules, sorted(sys.modules); "
            "ids = [i for i in gym.registry if i.startswith('HapticRecog')]; print(sorted(ids))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    for env_id in ("HapticRecog-v0", "HapticRecogMuJoCo-v0", "HapticRecogShadow-v0", "HapticRecogAero-v0",
                   "HapticRecogRobotiq-v0", "HapticRecogKIT-v0"):
        assert env_id in out
    assert gym.spec("HapticRecog-v0").max_episode_steps is None  # the env truncates itself: max_grasps is the one source


def _has_display() -> bool:
    import matplotlib
    import matplotlib.pyplot  # noqa: F401  (picks an interactive backend when there is a display)

    return matplotlib.get_backend().lower() not in ("agg", "pdf", "ps", "svg", "cairo", "template", "pgf")


def test_gymnasium_check_env(env_config):
    from gymnasium.utils.env_checker import check_env

    env = _make(env_config)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker only warns (e.g. an observation outside its space): fail on it
        # the render check makes a "human" env too, which needs a display (headless: see the test below)
        check_env(env.unwrapped, skip_render_check=not _has_display())
    env.close()


def test_human_render_without_a_display_is_a_clear_error(env_config):
    """render_mode="human" opens a window; without one (a non-interactive matplotlib backend) make raises at once
    instead of drawing every step into nothing."""
    if _has_display():
        pytest.skip("a display is available: human rendering opens a window")
    with pytest.raises(RuntimeError, match="render_mode='human' needs a display"):
        _make(env_config, render_mode="human")


def test_sb3_check_env(env_config):
    from stable_baselines3.common.env_checker import check_env

    env = _make(env_config)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SB3's checks warn; none may
        check_env(env.unwrapped, warn=True)
    env.close()


def test_same_seed_same_episode(env_config):
    a, b = _make(env_config), _make(env_config)
    ra, rb = _rollout(a, 7, 25), _rollout(b, 7, 25)
    assert len(ra) == len(rb)
    for (oa, rwa, ia), (ob, rwb, ib) in zip(ra, rb):
        np.testing.assert_array_equal(oa, ob)
        assert rwa == rwb
        assert ia["true_object"] == ib["true_object"] and ia["grasps"] == ib["grasps"]
        np.testing.assert_array_equal(ia["belief"], ib["belief"])
    # another seed gives another scene (object and/or pose)
    c = _make(env_config)
    c.reset(seed=8)
    a.reset(seed=7)
    assert (c.unwrapped.target != a.unwrapped.target) or not np.allclose(c.unwrapped.pose, a.unwrapped.pose)


def test_pickle_round_trip(env_config):
    env = _make(env_config)
    env2 = pickle.loads(pickle.dumps(env))
    assert env2.unwrapped.config == env.unwrapped.config
    assert env2.observation_space == env.observation_space and env2.action_space == env.action_space
    r1, r2 = _rollout(env, 3, 6), _rollout(env2, 3, 6)
    for (o1, w1, _), (o2, w2, _) in zip(r1, r2):
        np.testing.assert_array_equal(o1, o2)
        assert w1 == w2
    # a flat override survives pickling too
    env3 = pickle.loads(pickle.dumps(HapticRecogEnv(env_config, grasp_cost=0.05)))
    assert env3.config.grasp_cost == 0.05


@pytest.mark.parametrize(
    "action, match",
    [
        (np.zeros(3), "shape"),
        (np.zeros((1, 4)), "shape"),
        (np.array([0.0, np.nan, 0.0, 0.0]), "finite"),
        (np.array([0.0, 0.0, 1.5, 0.0]), r"\[-1, 1\]"),
        ("left", "numeric"),
    ],
)
def test_invalid_actions_raise(env_config, action, match):
    env = _make(env_config).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_bad_config_and_options_raise(env_config):
    for bad in ({"reward": "bogus"}, {"updater": "xx"}, {"threshold": 1.5}, {"n_fingers": 1},
                {"grasp_cost": -1.0}, {"pose": "upside-down"}, {"scale_range": (2.0, 1.0)}, {"z_fingers": 4},
                {"subset_k": 0}, {"subset_k": True}, {"min_fingers": 2},
                {"z_fingers": 3, "score_subsets": True, "min_fingers": 3}):
        with pytest.raises(ValueError, match=str(list(bad)[-1])):
            env_config.replace(**bad)
    with pytest.raises(TypeError, match="unknown HapticRecogConfig field"):
        HapticRecogEnv(env_config, no_such_field=1)
    env = HapticRecogEnv(env_config)
    with pytest.raises(ValueError, match="not in the object set"):
        env.reset(seed=0, options={"object": "unicorn"})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(seed=0, options={"colour": "red"})
    with pytest.raises(RuntimeError, match="reset"):
        HapticRecogEnv(env_config).step(np.zeros(env.action_dim))


def test_a_variant_refuses_a_config_whose_choices_it_would_replace():
    """gym.make(variant, config=...) gets the variant's fields as keyword overrides, which win: a config that set
    one of them otherwise is refused by name (it ran silently with the variant's value); fields left at their
    defaults take the variant's, and haptic_env.make(variant_config(...)) keeps the config's."""
    with pytest.raises(ValueError, match=r"HapticRecogKIT-v0 sets objects over the given config: objects=.kit20."):
        gym.make("HapticRecogKIT-v0", config=HapticRecogConfig(objects="kit20", max_grasps=7))
    with pytest.raises(ValueError, match=r"HapticRecogMuJoCoHeights-v0 sets calibrate_grasps .*variant's 5"):
        gym.make("HapticRecogMuJoCoHeights-v0", config=HapticRecogConfig(calibrate_grasps=2))
    # not refused (they get as far as loading kit8's meshes from a folder that is not there)
    with pytest.raises(FileNotFoundError, match="absent"):
        gym.make("HapticRecogKIT-v0", config=HapticRecogConfig(max_grasps=7), object_kwargs={"data_dir": "absent"})
    cfg = haptic_env.variant_config("HapticRecogKIT-v0", max_grasps=7, object_kwargs={"data_dir": "absent"})
    with pytest.raises(FileNotFoundError, match="absent"):
        haptic_env.make(cfg, env_id="HapticRecogKIT-v0")
    plain = gym.make("HapticRecog-v0", config=HapticRecogConfig(n_fingers=3), grasp_cost=0.01).unwrapped.config
    assert plain.n_fingers == 3 and plain.grasp_cost == 0.01  # explicit keyword arguments still go on top
    # keyword arguments that happen to be a variant's fields are the caller's, not a variant's: no refusal
    with pytest.raises(FileNotFoundError, match="absent"):  # got as far as loading kit8
        gym.make("HapticRecog-v0", config=HapticRecogConfig(objects="ycb10"), objects="kit8",
                 object_kwargs={"data_dir": "absent"})
    with pytest.raises(FileNotFoundError, match="absent"):  # a keyword argument for the variant's field wins
        gym.make("HapticRecogKIT-v0", config=HapticRecogConfig(objects="kit20"), objects="kit8",
                 object_kwargs={"data_dir": "absent"})
    with pytest.raises(ValueError, match="HapticRecogKIT-v0 sets objects"):  # the native vector env alike
        gym.make_vec("HapticRecogKIT-v0", num_envs=2, config=HapticRecogConfig(objects="kit20"))
    # a variant's config with changes that only hold together (each alone with the variant's fields would fail the
    # config's checks): one replace, no in-between config
    from haptic_env.config import resolve_env_config

    cfg = haptic_env.variant_config("HapticRecogShadow-v0", updater="ic", touch_weight=0.0)
    kw = haptic_env.config_kwargs(cfg, "HapticRecogShadow-v0", {})
    assert resolve_env_config(cfg, "HapticRecogShadow-v0", kw) == cfg


def test_a_mapping_keyword_updates_the_variants_mapping_rather_than_dropping_its_hand():
    """``backend_kwargs={"solid_table": False}`` on a hand variant keeps its hand (a whole replacement fell back to
    the generic hand, silently): through ``gym.make``, ``variant_config``, ``haptic_env.make(config, ...)``, the
    native vector env and ``train.py --env-kwargs``; the keyword's own keys win."""
    import train
    from haptic_env.config import backend_hand, resolve_env_config

    kw = {"backend_kwargs": {"solid_table": False}}
    want = {"hand": "shadow", "solid_table": False}
    assert dict(haptic_env.variant_config("HapticRecogShadow-v0", **kw).backend_kwargs) == want
    assert dict(resolve_env_config(None, "HapticRecogShadow-v0", kw).backend_kwargs) == want
    cfg = haptic_env.variant_config("HapticRecogShadow-v0", backend_kwargs={"contact_noise": 0.001})
    assert dict(resolve_env_config(cfg, "HapticRecogShadow-v0", haptic_env.config_kwargs(
        cfg, "HapticRecogShadow-v0", kw)).backend_kwargs) == {**want, "contact_noise": 0.001}
    other = haptic_env.variant_config("HapticRecogShadow-v0", backend_kwargs={"hand": "generic"})
    assert backend_hand(other) == "generic"  # the keyword's keys win
    # haptic_env.make(config, env_id) keeps the config's mappings whole: a key the config left out stays out
    bare = haptic_env.variant_config("HapticRecogMuJoCo-v0").replace(backend_kwargs={})
    assert dict(resolve_env_config(bare, "HapticRecogMuJoCo-v0", haptic_env.config_kwargs(
        bare, "HapticRecogMuJoCo-v0", {})).backend_kwargs) == {}
    args = train.parse_args(["--env-id", "HapticRecogAero-v0", "--env-kwargs", json.dumps(kw)])
    assert dict(train.env_config(args).backend_kwargs) == {"hand": "aero", "solid_table": False}
    # gym.make and the vector env resolve alike (stopped before any MuJoCo model is built: an unknown key)
    for make in (lambda: gym.make("HapticRecogShadow-v0", backend_kwargs={"bogus": 1}),
                 lambda: gym.make_vec("HapticRecogShadow-v0", num_envs=2, backend_kwargs={"bogus": 1})):
        with pytest.raises((TypeError, ValueError), match="bogus"):
            make()
    plain = HapticRecogConfig(backend_kwargs={"margin": 1.1})
    assert dict(resolve_env_config(plain, None, {"backend_kwargs": {"min_spread": 0.1}}).backend_kwargs) == {
        "margin": 1.1, "min_spread": 0.1}


def test_kit_variant_without_data_raises_clearly(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "missing")):
        gym.make("HapticRecogKIT-v0", object_kwargs={"data_dir": tmp_path / "missing"})


def test_entropy_rows_and_vectors():
    from scipy.stats import entropy as scipy_entropy

    from haptic_env.task import entropy

    P = np.array([[0.5, 0.5, 0.0], [1.0, 0.0, 0.0], [0.2, 0.3, 0.5]])
    h = entropy(P)
    assert h.shape == (3,) and np.allclose(h, scipy_entropy(P, axis=1), rtol=0, atol=1e-15)
    assert h[1] == 0.0  # 0 log 0 = 0: no nan from the zeros
    one = entropy(np.full(4, 0.25))
    assert isinstance(one, float) and one == pytest.approx(np.log(4), abs=1e-15)
    assert entropy(P[:, None, :]).shape == (3, 1)


@pytest.mark.parametrize("kind", ["true-posterior-gain", "max-posterior-gain", "entropy-reduction"])
def test_reward_terms_sum_to_reward(env_config, kind):
    def entropy(p):  # an oracle independent of haptic_env.task.entropy
        return float(-sum(x * np.log(x) for x in p if x > 0))

    env = _make(env_config, reward=kind, grasp_cost=0.01).unwrapped
    obs, info = env.reset(seed=1)
    rng = np.random.default_rng(0)
    prev = info["belief"]
    total_gain = 0.0
    for _ in range(30):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_dim))
        terms = info["reward_terms"]
        assert r == sum(terms.values())
        assert terms["grasp_cost"] == -0.01
        b = info["belief"]
        expected = {"true-posterior-gain": b[info["true_index"]] - prev[info["true_index"]],
                    "max-posterior-gain": b.max() - prev.max(),
                    "entropy-reduction": entropy(prev) - entropy(b)}[kind]
        assert terms["gain"] == pytest.approx(expected, abs=1e-12)
        total_gain += terms["gain"]
        prev = b
        if term or trunc:
            break
    if kind == "true-posterior-gain":  # the return telescopes
        assert total_gain == pytest.approx(prev[info["true_index"]] - 1.0 / env.n_classes, abs=1e-9)


def test_terminates_at_threshold_and_truncates(env_config):
    env = _make(env_config, threshold=0.5, max_grasps=60)
    rng = np.random.default_rng(1)
    env.reset(seed=2)
    n_terminated = 0
    for _ in range(6):
        done = False
        while not done:
            _, _, term, trunc, info = env.step(rng.uniform(-1, 1, 4))
            assert term == (info["certainty"] >= 0.5) == info["decided"]
            done = term or trunc
        n_terminated += term
        env.reset()
    assert n_terminated > 0, "no episode reached a certainty of 0.5 in 60 grasps"
    # threshold 1 is rarely reached: the env truncates itself at max_grasps (no TimeLimit wrapper)
    env = haptic_env.make(env_config.replace(threshold=1.0, max_grasps=4))
    env.reset(seed=0)
    truncated_once = False
    for _ in range(20):
        for i in range(4):
            _, _, term, trunc, info = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
            assert trunc == (i == 3 and not term) and info["grasps"] == i + 1
            if term or trunc:
                break
        truncated_once |= trunc and not term
        env.reset()
    assert truncated_once


def test_observation_slices(env_config):
    env = _make(env_config).unwrapped
    sl = env.obs_slices
    K, n, A, d = env.n_classes, env.config.n_fingers, env.action_dim, env.feature_dim
    assert [sl[k].stop - sl[k].start for k in env.observation_structure] == [d, n, 1, K, A, 1]
    assert env.observation_space.shape == (d + n + 1 + K + A + 1,)
    obs, info = env.reset(seed=4, options={"object": "ball"})
    assert info["true_object"] == "ball"
    np.testing.assert_allclose(obs[sl["belief"]], np.full(K, 1 / K), rtol=1e-6)
    assert not obs[sl["grasp"]].any() and not obs[sl["prev_action"]].any() and obs[sl["grasp_count"]][0] == 0
    rng = np.random.default_rng(0)
    for step in range(1, 6):
        a = rng.uniform(-1, 1, A).astype(np.float32)
        obs, _, term, trunc, info = env.step(a)
        assert obs in env.observation_space
        np.testing.assert_allclose(obs[sl["belief"]], info["belief"], rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(obs[sl["contact_mask"]], info["touched"].astype(np.float32))
        np.testing.assert_allclose(obs[sl["prev_action"]], a)
        assert obs[sl["usable"]][0] == float(info["usable"])
        assert obs[sl["grasp_count"]][0] == pytest.approx(step / env.config.max_grasps)
        if info["usable"]:
            assert info["touched"].all() and obs[sl["grasp"]].any()
        if term or trunc:
            break


def test_observe_contacts_appends_world_frame_contacts(env_config):
    """``observe_contacts``: the same observation as the plain env, followed by the latest grasp's world-frame
    contacts and normals, zeroed for fingers that did not touch."""
    plain = _make(env_config).unwrapped
    env = _make(env_config.replace(observe_contacts=True)).unwrapped
    n, base = env.config.n_fingers, plain.observation_space.shape[0]
    assert env.observation_structure["contacts"] == env.observation_structure["contact_normals"] == 3 * n
    assert env.observation_space.shape == (base + 6 * n,)
    sl = env.obs_slices
    o1, _ = plain.reset(seed=5, options={"object": "ring"})
    o2, _ = env.reset(seed=5, options={"object": "ring"})
    np.testing.assert_array_equal(o2[:base], o1)
    assert not o2[base:].any()
    rng = np.random.default_rng(2)
    partial = 0
    for _ in range(12):
        a = rng.uniform(-1, 1, 4)
        o1, *_, = plain.step(a)
        o2, _, term, trunc, info = env.step(a)
        np.testing.assert_array_equal(o2[:base], o1)
        assert o2 in env.observation_space
        res, touched = env._last_result, info["touched"]
        partial += int(not touched.all())
        c = o2[sl["contacts"]].reshape(n, 3)
        nrm = o2[sl["contact_normals"]].reshape(n, 3)
        np.testing.assert_allclose(c[touched], np.asarray(res.contacts)[touched], atol=1e-6)
        np.testing.assert_allclose(np.linalg.norm(nrm[touched], axis=1), 1.0, atol=1e-5)
        assert not c[~touched].any() and not nrm[~touched].any()
        if term or trunc:
            o1, _ = plain.reset(seed=6, options={"object": "ring"})
            o2, _ = env.reset(seed=6, options={"object": "ring"})
            assert not o2[base:].any()
    assert partial  # the ring leaves fingers off the object: the zeroing is exercised
    with pytest.raises(ValueError, match="observe_contacts must be True or False, got 'yes'"):
        env_config.replace(observe_contacts="yes")
    no_normals = _make(env_config.replace(observe_contacts=True, normals=False)).unwrapped
    assert "contact_normals" not in no_normals.observation_structure


def test_incomplete_grasp_carries_no_information(env_config):
    env = _make(env_config).unwrapped
    env.reset(seed=0, options={"object": "ring"})  # thin: many grasps miss with some fingers
    rng = np.random.default_rng(3)
    seen = 0
    for _ in range(40):
        before = env.belief
        _, r, term, trunc, info = env.step(rng.uniform(-1, 1, 4))
        if not info["touched"].all():
            seen += 1
            assert not info["usable"]
            np.testing.assert_array_equal(info["belief"], before)
            assert info["reward_terms"]["gain"] == 0.0
        if term or trunc:
            env.reset(options={"object": "ring"})
    assert seen > 0


def test_pose_modes_and_scale(env_config):
    env = HapticRecogEnv(env_config.replace(pose="so3", scale_range=(0.8, 1.2)))
    up, scales = [], []
    for s in range(20):
        env.reset(seed=s)
        R = env.pose[:3, :3]
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0) and 0.8 <= env.scale <= 1.2
        up.append(R[2, 2])
        scales.append(env.scale)
    # so3 tilts the object (a uniform rotation's R[2, 2] is uniform on [-1, 1]), and the scale varies
    assert min(up) < 0.0 < max(up) and np.ptp(scales) > 0.1
    env = HapticRecogEnv(env_config)
    env.reset(seed=0)
    R = env.pose[:3, :3]
    assert R[2, 2] == pytest.approx(1.0) and env.scale == 1.0  # table-yaw: a rotation about z only


def test_render_rgb_array(env_config):
    env = _make(env_config, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(4, np.float32))
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and img.std() > 0
    env.close()


def test_subproc_vec_env(env_config):
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # forkserver, SB3's default (as train.py uses): a plain fork after this process has cast rays can copy
    # a lock held by Embree's TBB worker threads into the child, which then hangs (seen in a full run)
    venv = SubprocVecEnv([lambda: haptic_env.make(env_config) for _ in range(2)], start_method="forkserver")
    try:
        venv.seed(0)
        obs = venv.reset()
        assert obs.shape == (2,) + venv.observation_space.shape
        for _ in range(5):
            obs, rew, done, infos = venv.step(np.zeros((2, 4), np.float32))
            assert np.isfinite(rew).all() and len(infos) == 2
    finally:
        venv.close()


def test_z_finger_models_score_incomplete_grasps_and_subsets(env_config):
    from haptic_env.grasp_features import feature_dim

    n = env_config.n_fingers
    z = n - 1
    env = HapticRecogEnv(env_config.replace(z_fingers=z))
    env.reset(seed=0, options={"object": "ring"})
    rng = np.random.default_rng(0)
    scored_incomplete = 0
    for _ in range(60):
        _, _, term, trunc, info = env.step(rng.uniform(-1, 1, 4))
        t = int(info["touched"].sum())
        if t < z:
            assert not info["usable"]
        scored_incomplete += info["usable"] and t == z
        if term or trunc:
            env.reset(options={"object": "ring"})
    assert scored_incomplete > 0
    # z-subset scoring: each scored grasp gives C(t, z) rows of the z-finger model
    env = HapticRecogEnv(env_config.replace(z_fingers=z, score_subsets=True))
    env.reset(seed=1)
    from itertools import combinations
    from math import comb

    res = env.backend.grasp(np.zeros(4), np.random.default_rng(0))
    _, Q = env.grasp_rows(res.contacts, res.normals, res.touched)
    t = int(res.touched.sum())
    assert t == n and Q is not None and Q.shape == (comb(t, z), feature_dim(z, env_config.normals))
    # the rows are Phi_z of each z-subset of the (complete) grasp, in some order
    rec = env.unwrapped.recognizer
    N = res.normals
    expected = np.concatenate([rec.features(res.contacts[list(s)], None if N is None else N[list(s)])
                               for s in combinations(range(t), z)])
    np.testing.assert_allclose(np.sort(Q, axis=0), np.sort(expected, axis=0), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("z", [None, "n-1"])
def test_grasp_rows_batch_matches_grasp_rows(env_config, z):
    env = HapticRecogEnv(env_config.replace(z_fingers=None if z is None else env_config.n_fingers - 1))
    env.reset(seed=3, options={"object": "ring"})
    res = env.backend.grasp_batch(np.random.default_rng(0).uniform(-1, 1, (40, 4)), np.random.default_rng(1))
    rows, scored = env.grasp_rows_batch(res.contacts, res.normals, res.touched)
    expect = [(i, env.grasp_rows(res.contacts[i], res.normals[i], res.touched[i])[1]) for i in range(40)]
    expect = [(i, q) for i, q in expect if q is not None]
    assert scored.tolist() == [i for i, _ in expect] and len(expect) > 0
    for r, (_, q) in zip(rows, expect):
        np.testing.assert_allclose(r, q, rtol=1e-12, atol=1e-12)


def test_recognizer_source_reaches_the_recognizer_config(env_config):
    from haptic_env.config import recognizer_kwargs as _recognizer_kwargs
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers import RecognizerConfig

    assert _recognizer_kwargs(env_config)["config"].grasps.source == "geometric"
    surf = _recognizer_kwargs(env_config.replace(recognizer_source="surface"))["config"].grasps
    assert surf.source == "surface" and surf.grasps_per_object == 1500  # the rest of the JSON config kept
    floating = env_config.replace(backend_kwargs={"support": "floating"}, pose="so3")
    assert _recognizer_kwargs(floating)["config"].grasps.support == "floating"
    explicit = RecognizerConfig(grasps=DatasetConfig(grasps_per_object=10))
    assert _recognizer_kwargs(env_config.replace(recognizer_kwargs={"config": explicit}))["config"] is explicit
    with pytest.raises(ValueError, match="recognizer_source"):
        env_config.replace(recognizer_source="photos")


def test_kde_method_reaches_the_recognizer_config(env_config):
    from haptic_env.config import recognizer_kwargs as _recognizer_kwargs

    assert HapticRecogConfig().kde_method == "pooled"
    assert _recognizer_kwargs(env_config)["config"].kde.method == env_config.kde_method
    assert _recognizer_kwargs(env_config.replace(kde_method="tree"))["config"].kde.method == "tree"
    own = env_config.replace(recognizer_kwargs={"config": {"kde": {"method": "dense", "factor": 0.5}}})
    assert _recognizer_kwargs(own)["config"].kde.method == "dense"  # the JSON config's own method wins
    with pytest.raises(ValueError, match="method"):
        _recognizer_kwargs(env_config.replace(kde_method="fastest"))


def test_calibrate_grasps_reaches_the_kde_config(env_config):
    from haptic_env import ENV_VARIANTS
    from haptic_env.config import recognizer_kwargs as _recognizer_kwargs

    assert HapticRecogConfig().calibrate_grasps == 1  # one-shot temperature unless a variant says otherwise
    assert _recognizer_kwargs(env_config)["config"].kde.calibrate_grasps == 1
    assert _recognizer_kwargs(env_config.replace(calibrate_grasps=5))["config"].kde.calibrate_grasps == 5
    own = env_config.replace(calibrate_grasps=5, recognizer_kwargs={"config": {"kde": {"calibrate_grasps": 3}}})
    assert _recognizer_kwargs(own)["config"].kde.calibrate_grasps == 3  # the JSON config's own setting wins
    for env_id, k in (("HapticRecogMuJoCo-v0", 5), ("HapticRecogShadow-v0", 10), ("HapticRecogAero-v0", 5)):
        assert ENV_VARIANTS[env_id]["calibrate_grasps"] == k  # chosen on validation (the Shadow's for a margin)
    for bad in (0, 2.0, "5"):
        with pytest.raises(ValueError, match="calibrate_grasps"):
            env_config.replace(calibrate_grasps=bad)


def test_touch_weight_is_checked_at_make_and_reaches_the_recogniser(env_config):
    from haptic_env import ENV_VARIANTS
    from haptic_env.config import recognizer_kwargs as _recognizer_kwargs

    assert HapticRecogConfig().touch_weight == 0.0  # off: the paper's method
    assert "touch" not in _recognizer_kwargs(env_config)
    hand = HapticRecogConfig(backend="mujoco", backend_kwargs={"hand": "generic"}, touch_weight=0.5)
    assert _recognizer_kwargs(hand)["touch"] is True
    assert _recognizer_kwargs(hand.replace(updater="bc-ip"))["touch"] is True  # BC-IP weighs it too
    assert ENV_VARIANTS["HapticRecogShadow-v0"]["touch_weight"] == 0.5  # chosen per hand on validation grasps
    assert ENV_VARIANTS["HapticRecogAero-v0"]["touch_weight"] == 0.5
    assert ENV_VARIANTS["HapticRecogRobotiq-v0"]["touch_weight"] == 1.0  # on 600 validation episodes, for a margin
    for bad, match in [({"touch_weight": -1.0}, "touch_weight"), ({"touch_weight": float("nan")}, "touch_weight"),
                       ({"touch_weight": True}, "touch_weight"), ({"touch_weight": 0.5}, "hand-matched"),
                       ({"touch_weight": 0.5, "backend": "mujoco", "updater": "ic"}, "bc-np"),
                       ({"touch_weight": 0.5, "backend": "mujoco", "recognizer_source": "surface"}, "hand-matched")]:
        with pytest.raises(ValueError, match=match):
            HapticRecogConfig(**bad)


def test_training_grasps_reaches_the_dataset_config(env_config):
    from haptic_env import ENV_VARIANTS
    from haptic_env.config import HAND_APPROACHES
    from haptic_env.config import recognizer_kwargs as _recognizer_kwargs
    from haptic_env.dataset import DatasetConfig

    grasps = lambda cfg: _recognizer_kwargs(cfg)["config"].grasps  # noqa: E731
    assert HapticRecogConfig().training_grasps is None
    assert grasps(HapticRecogConfig()).grasps_per_object == DatasetConfig().grasps_per_object  # the source's default
    assert grasps(HapticRecogConfig(training_grasps=1234)).grasps_per_object == 1234
    mujoco = dict(backend="mujoco", backend_kwargs={"hand": "generic"})
    assert grasps(HapticRecogConfig(**mujoco)).grasps_per_object == HAND_APPROACHES
    allegro = HapticRecogConfig().replace(**ENV_VARIANTS["HapticRecogMuJoCo-v0"])
    assert allegro.training_grasps == 6000 and grasps(allegro).grasps_per_object == 6000
    assert grasps(allegro).source == "hand" and grasps(allegro).hand == "allegro"
    own = allegro.replace(recognizer_kwargs={"config": {"grasps": {"grasps_per_object": 50}}})
    assert grasps(own).grasps_per_object == 50  # the JSON config's own setting wins
    for bad in (0, -5, 2.5, "6000", True):
        with pytest.raises(ValueError, match="training_grasps"):
            env_config.replace(training_grasps=bad)


HAND_ENVS = {"HapticRecogMuJoCo-v0": 4, "HapticRecogShadow-v0": 5, "HapticRecogAero-v0": 5, "HapticRecogRobotiq-v0": 2,
             "HapticRecogMuJoCoHeights-v0": 4, "HapticRecogShadowHeights-v0": 5, "HapticRecogAeroHeights-v0": 5,
             "HapticRecogRobotiqHeights-v0": 2}


@pytest.mark.parametrize("env_id", list(HAND_ENVS))
def test_mujoco_hand_variants_run_an_episode(env_id):
    """Every registered hand grasps YCB objects in MuJoCo inside a full env loop, with a recogniser trained on that
    hand's own grasps of the meshes (``recognizer_source="auto"`` -> "hand"; few approaches to stay fast)."""
    from haptic_env.objects import data_dir

    if data_dir() is None:
        pytest.skip("needs the shared data (ycb/ meshes and the menagerie hands): set HAPTIC_DATA")
    # the Allegro's own grasps (few approaches, to stay fast: with the solid table 200 give its hardest objects, the
    # hammer, the plate and the drill, a few complete ones each, and a hand data set keeps an object with one); the
    # 5-finger hands rarely touch the plate with all five fingers, so a fast recogniser for them trains on
    # surface grasps (the hand source itself: tests/test_hand_grasps.py), so without the touch pattern, which needs
    # the hand's own grasps
    allegro = env_id.startswith("HapticRecogMuJoCo")
    grasps = {"grasps_per_object": 200} if allegro else {"grasps_per_object": 300, "source": "surface"}
    kw = {"recognizer_kwargs": {"config": {"grasps": grasps}, "progress": False}}
    if haptic_env.ENV_VARIANTS[env_id].get("touch_weight", 0) > 0 and not allegro:
        with pytest.raises(ValueError, match="hand-matched"):
            haptic_env.make(env_id=env_id, **kw)
        kw["touch_weight"] = 0.0
    env = haptic_env.make(env_id=env_id, **kw)
    obs, info = env.reset(seed=0)
    base = env.unwrapped
    assert base.config.backend == "mujoco" and len(base.objects) == 10
    assert base.recognizer.config.grasps.source == grasps.get("source", "hand")
    assert base.recognizer.models.model(HAND_ENVS[env_id])[0] is None  # BC-NP: no classifier trained
    assert base.recognizer.heights == ("Heights" in env_id) == base.config.grasp_heights
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert np.isclose(sum(info["reward_terms"].values()), reward)
        assert info["touched"].shape == (HAND_ENVS[env_id],)
        if terminated or truncated:
            break
    env.close()


def test_the_allegro_env_weighs_the_touch_pattern_with_bc_ip_too():
    """``updater="bc-ip"`` on the Allegro env keeps its touch weight (before, a touch weight needed BC-NP): every
    grasp updates the belief, and the classifier's prior comes with the first grasp the classifier scores."""
    from haptic_env.objects import data_dir

    if data_dir() is None:
        pytest.skip("needs the shared data (ycb/ meshes and the menagerie hands): set HAPTIC_DATA")
    kw = {"recognizer_kwargs": {"config": {"grasps": {"grasps_per_object": 200}}, "progress": False}}
    env = haptic_env.make(env_id="HapticRecogMuJoCo-v0", updater="bc-ip", **kw)
    base = env.unwrapped
    assert base.config.touch_weight == 0.75 and base.config.updater == "bc-ip"
    env.reset(seed=3)
    env.action_space.seed(0)
    updater = base.belief_state.updater
    assert not updater.prior_set
    for _ in range(12):
        before = base.belief.copy()
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        assert info["usable"] and not np.array_equal(base.belief, before)  # the pattern moves it at every grasp
        if updater.prior_set or terminated or truncated:
            break
    assert updater.prior_set  # set by a grasp its 2-4-finger classifiers scored
    env.close()


def _step_alike(fast, slow, a) -> bool:
    """Step two envs with action ``a`` and check that they agree (observation, belief, reward, end, usable); returns
    whether the episode ended."""
    of, rf, tf, uf, f = fast.step(a)
    os_, rs, ts, us, s = slow.step(a)
    np.testing.assert_allclose(of, os_, rtol=0, atol=1e-6)
    np.testing.assert_allclose(f["belief"], s["belief"], rtol=1e-9, atol=1e-12)
    assert (rf, tf, uf, f["usable"]) == pytest.approx((rs, ts, us, s["usable"]))
    return bool(tf or uf)


@pytest.mark.parametrize("updater", ["bc-np", "bc-ip"])
def test_compiled_scorer_path_equals_the_general_path(env_config, updater):
    """Complete grasps go through Recognizer.grasp_scorer (one compiled call): same observations, rewards, beliefs."""
    cfg = env_config.replace(updater=updater, threshold=1.0, max_grasps=60)
    fast, slow = HapticRecogEnv(cfg), HapticRecogEnv(cfg)
    fast.reset(seed=3)
    slow.reset(seed=3)
    assert fast.belief_state.compiled and fast.belief_state._scorer is not None
    slow.belief_state.compiled = False  # force Belief.rows + updater.update
    rng = np.random.default_rng(0)
    for _ in range(50):
        if _step_alike(fast, slow, rng.uniform(-1, 1, fast.action_dim).astype(np.float32)):
            # a certainty of exactly 1.0 ends the episode: go on in the next one
            seed = int(rng.integers(1 << 30))
            fast.reset(seed=seed)
            slow.reset(seed=seed)


def test_grasp_scorer_matches_features_and_kde(env_config):
    from haptic_env.env import get_recognizer
    from haptic_env.objects import load_object_set

    rec = get_recognizer(load_object_set(env_config.objects), env_config)
    scorer, raw = rec.grasp_scorer(), rec.grasp_scorer(calibrated=False)
    kde = rec.models.model(4)[1]
    assert kde.temperature != 1.0  # fitted on the validation grasps
    rng = np.random.default_rng(1)
    for _ in range(30):
        P, N = rng.normal(size=(4, 3)) * 0.05, rng.normal(size=(4, 3))
        q, ll = scorer(P, N)
        Q = rec.features(P, N)
        np.testing.assert_allclose(q, Q[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(raw(P, N)[1], kde.log_likelihood(Q), rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(ll, rec.models.log_likelihood(Q), rtol=1e-12, atol=1e-9)  # tempered: / T
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    q, ll = scorer(flat, rng.normal(size=(4, 3)))
    assert ll is None and not q.any()  # coplanar: no information
    with pytest.raises(ValueError, match="not finite"):
        scorer(np.full((4, 3), np.nan), rng.normal(size=(4, 3)))
    with pytest.raises(ValueError, match="shape"):
        scorer(P[:3], N[:3])


def test_grasp_heights_reach_the_recogniser_observation_and_belief(env_config):
    """grasp_heights=True: the recogniser trains on vectors with the contacts' heights above the table, the observed
    grasp vector has n more values, and the belief scores the world-frame contacts of an episode from its object's
    table height (compiled and general paths alike); settings that break the premise raise at make."""
    from haptic_env.grasp_features import feature_dim
    from haptic_env.grasping.base import support_height

    cfg = env_config.replace(grasp_heights=True, threshold=1.0, max_grasps=40)
    fast, slow = HapticRecogEnv(cfg), HapticRecogEnv(cfg)
    fast.reset(seed=4)
    slow.reset(seed=4)
    assert fast.recognizer.heights and fast.recognizer.config.grasps.heights
    assert fast.feature_dim == feature_dim(4, True, heights=True) == fast.belief_state.feature_dim
    obj = fast.objects[fast.target]
    assert fast.belief_state.support_z == fast.scene.support_z == pytest.approx(
        support_height(obj.mesh.vertices, fast.pose))
    slow.belief_state.compiled = False
    rng = np.random.default_rng(2)
    seen = 0
    for _ in range(30):
        ended = _step_alike(fast, slow, rng.uniform(-1, 1, fast.action_dim).astype(np.float32))
        res = fast._last_result
        if res.touched.all():  # the observed vector ends with the contacts' heights above the table
            rows = fast.recognizer.features(res.contacts - [0, 0, fast.scene.support_z], res.normals)
            if len(rows):
                seen += 1
                np.testing.assert_allclose(fast.belief_state.rows(res.contacts, res.normals, res.touched)[1], rows)
                assert (rows[0, -4:] >= -1e-6).all()
        if ended:
            seed = int(rng.integers(1 << 30))
            fast.reset(seed=seed)
            slow.reset(seed=seed)
    assert seen > 0
    with pytest.raises(ValueError, match="grasp_heights=True needs"):
        env_config.replace(grasp_heights=True, pose="so3")
    plain = {"config": {"grasps": {"grasps_per_object": 1500, "heights": False},
                        "mlp": {"depth": 1, "width": 32, "max_epochs": 1, "progress": False}}, "progress": False}
    with pytest.raises(ValueError, match="heights=False but the config has grasp_heights=True"):  # at make
        env_config.replace(grasp_heights=True, recognizer_kwargs=plain)


@pytest.mark.parametrize("axis", ["ab", "frame"])
def test_normal_axis_ab_or_frame_reaches_the_recogniser_and_the_observation(env_config, axis):
    """normal_axis="ab" or "frame": the recogniser trains on it, the observed grasp vector is phi(...,
    normal_axis=axis) of the grasp, compiled and general paths agree; a recogniser built otherwise is refused, and so
    is a bad value."""
    from haptic_env.grasp_features import phi

    cfg = env_config.replace(normal_axis=axis, threshold=1.0, max_grasps=40)
    fast, slow = HapticRecogEnv(cfg), HapticRecogEnv(cfg)
    fast.reset(seed=6)
    slow.reset(seed=6)
    assert fast.recognizer.normal_axis == axis == fast.belief_state.normal_axis
    slow.belief_state.compiled = False
    rng, sl, seen = np.random.default_rng(3), fast.obs_slices, 0
    for _ in range(25):
        a = rng.uniform(-1, 1, fast.action_dim).astype(np.float32)
        obs, _, term, trunc, info = fast.step(a)
        obs_slow, *_, info_slow = slow.step(a)
        np.testing.assert_allclose(obs, obs_slow, rtol=0, atol=1e-6)
        np.testing.assert_allclose(info["belief"], info_slow["belief"], rtol=1e-9, atol=1e-12)
        res = fast._last_result
        if info["usable"] and res.touched.all():  # the observed vector is the grasp's Phi with normal_axis=axis
            seen += 1
            np.testing.assert_allclose(obs[sl["grasp"]], phi(res.contacts, res.normals, normal_axis=axis).q, atol=1e-5)
        ended = term or trunc
        if ended:
            fast.reset(seed=seen + 100)
            slow.reset(seed=seen + 100)
    assert seen > 0
    other = {"config": {"grasps": {"grasps_per_object": 1500, "normal_axis": "t2"},
                        "mlp": {"depth": 1, "width": 32, "max_epochs": 1, "progress": False}}, "progress": False}
    with pytest.raises(ValueError, match=f"second angle to 't2' but the config has normal_axis={axis!r}"):  # at make
        env_config.replace(normal_axis=axis, recognizer_kwargs=other)
    with pytest.raises(ValueError, match="normal_axis must be one of .*'t1'"):
        env_config.replace(normal_axis="t1")


def test_greedy_look_ahead_with_grasp_heights(env_config):
    from agents.greedy import GreedyInfoGainAgent

    env = gym.make("HapticRecog-v0", config=env_config.replace(grasp_heights=True))
    agent = GreedyInfoGainAgent(n_candidates=4, n_samples=2, seed=0)
    obs, _ = env.reset(seed=1)
    agent.reset(env)
    base = env.unwrapped
    tables = [base.scene.support_height(k, base.pose) for k in range(base.n_classes)]
    assert len(set(tables)) > 1  # the objects stand on tables at different heights: a shared one would be wrong
    belief, seen = base.belief_state, []
    predict = belief.predict_grasps

    def spy(*args, support_z=None):  # each hypothesis's simulated grasps are measured from its own table
        seen.append(support_z)
        return predict(*args, support_z=support_z)

    belief.predict_grasps = spy
    for _ in range(3):
        seen.clear()
        obs, r, term, trunc, info = env.step(agent.act(obs, env))
        assert np.isfinite(r) and agent.last_scores.shape == (4,)
        assert seen and all(any(z == pytest.approx(t) for t in tables) for z in seen)
        assert len(set(seen)) == len(seen)  # one call per active hypothesis, each with its own table
        if term or trunc:
            break


def test_heights_hand_envs_are_the_plain_ones_with_grasp_heights():
    """The Heights hand envs change only the grasp vector (heights) and the touch weight chosen for it on validation;
    the Allegro's keeps the z_fingers it was validated with (3; the plain env's 2 since the solid table), the Shadow's
    its calibrate_grasps (5; the plain env's 10 since 2026-12-07)."""
    from haptic_env import ENV_VARIANTS

    for hand, w, more in (("MuJoCo", 1.0, {"z_fingers": 3}), ("Shadow", 0.5, {"calibrate_grasps": 5}),
                          ("Aero", 1.0, {}), ("Robotiq", 1.0, {})):
        plain, heights = ENV_VARIANTS[f"HapticRecog{hand}-v0"], ENV_VARIANTS[f"HapticRecog{hand}Heights-v0"]
        assert heights == {**plain, "grasp_heights": True, "touch_weight": w, **more}
        assert haptic_env.variant_config(f"HapticRecog{hand}Heights-v0").grasp_heights
        assert not haptic_env.variant_config(f"HapticRecog{hand}-v0").grasp_heights


def test_gradient_boosting_as_the_envs_likelihood(env_config):
    """``likelihood="hgb"``: the belief multiplies gradient boosting's tempered scores, in the single env and the
    native vector env (its array fast path: Phi compiled, the trees walked for the batch) alike, and an episode is
    reproducible by seed."""
    from gymnasium.vector import SyncVectorEnv
    from scipy.special import log_softmax

    from haptic_env.recognizers.boosted import BoostedLikelihood

    rk = {**env_config.recognizer_kwargs, "config": {**env_config.recognizer_kwargs["config"],
                                                     "boosted": {"max_iter": 15}}}
    cfg = env_config.replace(likelihood="hgb", calibrate_grasps=2, recognizer_kwargs=rk)
    env = _make(cfg)
    obs, _ = env.reset(seed=3)
    u = env.unwrapped
    lik = u.recognizer.models.model(cfg.n_fingers)[1]
    assert isinstance(lik, BoostedLikelihood) and lik.config.calibrate_grasps == 2 and lik.calibrated
    scored = []
    raw = lik.log_likelihood

    def spy(Q):
        scored.append(raw(Q))
        return scored[-1]

    lik.log_likelihood = spy  # the instance's own scores, recorded
    rng = np.random.default_rng(0)
    try:
        for _ in range(30):  # until a grasp scores: the belief is the prior times its tempered likelihood
            before = u.belief.copy()
            *_, info = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
            if info["usable"]:
                break
    finally:
        del lik.log_likelihood
    assert info["usable"] and len(scored) == 1
    expected = log_softmax(np.log(before) + scored[0].sum(0) / lik.temperature)
    np.testing.assert_allclose(np.log(u.belief), expected, atol=1e-9)
    ra, rb = _rollout(_make(cfg), 5, 12), _rollout(_make(cfg), 5, 12)
    for (oa, _, ia), (ob, _, ib) in zip(ra, rb):
        np.testing.assert_array_equal(oa, ob)
    venv = gym.make_vec("HapticRecog-v0", num_envs=2, vectorization_mode="vector_entry_point", config=cfg)
    ref = SyncVectorEnv([lambda: HapticRecogEnv(cfg) for _ in range(2)])
    vo, _ = venv.reset(seed=5)
    np.testing.assert_array_equal(vo, ref.reset(seed=5)[0])
    np.testing.assert_array_equal(vo[0], ra[0][0])
    assert venv.unwrapped.fast_path
    for a in np.random.default_rng(1).uniform(-1, 1, (25, 2, 4)).astype(np.float32):
        for x, y in zip(venv.step(a)[:4], ref.step(a)[:4]):  # obs, rewards, terminations, truncations
            np.testing.assert_array_equal(x, y)
    venv.close()
    ref.close()
