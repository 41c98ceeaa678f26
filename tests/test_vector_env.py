"""The native vector env (haptic_env.vector_env): equivalence with single envs under the documented seeding scheme
(bit for bit), Gymnasium's vector contract and autoreset modes, determinism, pickling, the batched pieces
(grasp_placed, GraspScorer.batch) and the SB3 adapter."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import haptic_env
from haptic_env.env import HapticRecogEnv
from haptic_env.vector_env import HapticRecogVectorEnv

STEP_KEYS = ("true_index", "predicted_index", "correct", "certainty", "decided", "grasps", "usable", "belief",
             "touched")


def _actions(T, B, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (T, B, 4)).astype(np.float32)


def _assert_same_step(r1, r2):
    for x, y in zip(r1[:4], r2[:4]):  # obs, rewards, terminations, truncations: bit for bit
        np.testing.assert_array_equal(x, y)
    i1, i2 = r1[4], r2[4]
    for key in STEP_KEYS:
        np.testing.assert_array_equal(i1["_" + key], i2["_" + key], err_msg=key)
        m = i2["_" + key]
        np.testing.assert_array_equal(np.asarray(i1[key])[m], np.asarray(i2[key])[m], err_msg=key)
    assert ("reward_terms" in i1) == ("reward_terms" in i2)  # none where every sub-env was reset
    if "reward_terms" in i2:
        m = i2["_reward_terms"]
        np.testing.assert_array_equal(i1["_reward_terms"], m)
        assert sorted(i1["reward_terms"]) == sorted(i2["reward_terms"])  # each term with its nested mask
        for k in ("gain", "grasp_cost"):
            np.testing.assert_array_equal(i1["reward_terms"]["_" + k], i2["reward_terms"]["_" + k])
            np.testing.assert_array_equal(i1["reward_terms"][k][m], i2["reward_terms"][k][m])
    if "final_obs" in i2:
        np.testing.assert_array_equal(i1["_final_obs"], i2["_final_obs"])
        for i in np.flatnonzero(i2["_final_obs"]):
            np.testing.assert_array_equal(i1["final_obs"][i], i2["final_obs"][i])
            assert i1["final_info"]["grasps"][i] == i2["final_info"]["grasps"][i]
            assert i1["final_info"]["correct"][i] == i2["final_info"]["correct"][i]


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("overrides", [
    {},
    {"pose": "so3", "scale_range": (0.8, 1.2), "reward": "entropy-reduction", "max_grasps": 4,
     "backend_kwargs": {"contact_noise": 0.002, "normal_noise_deg": 3.0}, "observe_contacts": True},
    {"grasp_heights": True, "scale_range": (0.8, 1.2), "backend_kwargs": {"contact_noise": 0.002}},
    {"normal_axis": "ab", "backend_kwargs": {"contact_noise": 0.002}},
    {"normal_axis": "frame", "backend_kwargs": {"contact_noise": 0.002}},
])
def test_sub_env_i_equals_a_single_env_seeded_seed_plus_i(env_config, mode, overrides):
    """The documented scheme: reset(seed=s) -> sub-env i is HapticRecogEnv reset(seed=s + i), autoresets continue
    its generator; i.e. SyncVectorEnv of single envs in the same autoreset mode, bit for bit."""
    cfg = env_config.replace(grasp_cost=0.05, **overrides)
    B, T = 5, 60
    venv = HapticRecogVectorEnv(B, cfg, autoreset_mode=mode)
    ref = SyncVectorEnv([lambda: HapticRecogEnv(cfg) for _ in range(B)], autoreset_mode=mode)
    o1, i1 = venv.reset(seed=11)
    o2, i2 = ref.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(i1["true_index"], i2["true_index"])
    ends = 0
    for a in _actions(T, B):
        r1, r2 = venv.step(a), ref.step(a)
        _assert_same_step(r1, r2)
        ends += int(r2[2].sum() + r2[3].sum())
    assert venv.fast_path and ends > B  # episodes ended and autoreset along the way
    assert (venv.scene.backend.config.contact_noise > 0) == bool(overrides)


@pytest.mark.parametrize("heights,subsets", [(False, False), (True, False), (True, True)])
def test_general_belief_path_equals_single_envs(env_config, heights, subsets):
    """A setting outside the fast path (z-finger models for incomplete grasps; z-subsets that also score two-finger
    grasps) keeps one Belief per sub-env."""
    cfg = env_config.replace(z_fingers=3, grasp_cost=0.01, observe_contacts=True)
    if heights:
        cfg = cfg.replace(grasp_heights=True, scale_range=(0.9, 1.1))
    if subsets:
        cfg = cfg.replace(score_subsets=True, min_fingers=2)
    B = 3
    venv = HapticRecogVectorEnv(B, cfg)
    ref = SyncVectorEnv([lambda: HapticRecogEnv(cfg) for _ in range(B)])
    np.testing.assert_array_equal(venv.reset(seed=2)[0], ref.reset(seed=2)[0])
    assert not venv.fast_path
    for a in _actions(25, B, seed=1):
        _assert_same_step(venv.step(a), ref.step(a))


def test_seed_list_object_option_and_reset_mask(env_config):
    B = 3
    venv = HapticRecogVectorEnv(B, env_config, autoreset_mode="disabled")
    obs, info = venv.reset(seed=[5, 9, 1], options={"object": [venv.object_names[0], None, 2]})
    for i, s in enumerate([5, 9, 1]):
        single = HapticRecogEnv(env_config)
        o, inf = single.reset(seed=s, options={"object": info["true_index"][i]} if i != 1 else None)
        np.testing.assert_array_equal(obs[i], o)
        assert inf["true_index"] == info["true_index"][i]
    assert venv.metadata["autoreset_mode"] == AutoresetMode.DISABLED
    # disabled: a finished sub-env must be reset by the caller (reset_mask), the others keep their episodes
    acts = _actions(40, B)
    for a in acts:
        _, _, term, trunc, _ = venv.step(a)
        if (term | trunc).any():
            break
    done = term | trunc
    with pytest.raises(RuntimeError, match="reset_mask"):
        venv.step(acts[0])
    grasps = venv.grasps.copy()
    obs, info = venv.reset(options={"reset_mask": done})
    assert (venv.grasps[done] == 0).all() and (venv.grasps[~done] == grasps[~done]).all()
    np.testing.assert_array_equal(info["_grasps"], done)
    venv.step(acts[1])
    with pytest.raises(ValueError, match="reset_mask"):
        venv.reset(options={"reset_mask": np.zeros(B, bool)})
    with pytest.raises(ValueError, match="unknown reset option"):
        venv.reset(options={"objects": 1})
    # a float or bool object and a ragged action were numpy / Python errors that did not name the value
    with pytest.raises(ValueError, match=r"options\['object'\] must be a name, an index or a sequence .*got 2.0"):
        venv.reset(options={"object": 2.0})
    with pytest.raises(ValueError, match=r"options\['object'\] must be an object name or index, got True"):
        venv.reset(options={"object": True})


def test_vector_contract_spaces_and_infos(env_config):
    """Gymnasium's vector contract (its env checker takes single envs only, which test_env.py runs): batched
    spaces, observations inside them, float64 rewards, bool flags, masked infos, autoreset metadata."""
    B = 4
    venv = gym.make_vec("HapticRecog-v0", num_envs=B, vectorization_mode="vector_entry_point", config=env_config)
    assert isinstance(venv.unwrapped, HapticRecogVectorEnv) and venv.num_envs == B
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    single = HapticRecogEnv(env_config)
    assert venv.single_observation_space == single.observation_space
    assert venv.single_action_space == single.action_space
    assert venv.observation_space.shape == (B,) + single.observation_space.shape
    obs, info = venv.reset(seed=0)
    assert venv.observation_space.contains(obs) and set(STEP_KEYS) <= set(info)
    venv.action_space.seed(0)
    for _ in range(20):
        obs, rew, term, trunc, info = venv.step(venv.action_space.sample())
        assert venv.observation_space.contains(obs)
        assert rew.dtype == np.float64 and rew.shape == (B,)
        assert term.dtype == np.bool_ and trunc.dtype == np.bool_ and not (term & trunc).any()
        for key in STEP_KEYS:
            assert info["_" + key].all()
        np.testing.assert_allclose(info["belief"].sum(axis=1), 1.0)
    for bad, match in [(np.zeros((B, 3)), "shape"), (np.full((B, 4), 1.5), r"\[-1, 1\]"),
                       (np.full((B, 4), np.nan), "finite"),
                       ([[0, 0, 0]] + [[0, 0, 0, 0]] * (B - 1), "got \\[\\[0, 0, 0\\]"),
                       (None, "numeric array of shape .* got None"), (np.full((B, 4), 1j), "complex")]:
        with pytest.raises(ValueError, match=match):
            venv.step(bad)
    venv.close()
    # every geometric variant has the vector entry point; the MuJoCo ones do not (no batched backend yet)
    for env_id, kw in haptic_env.ENV_VARIANTS.items():
        spec = gym.spec(env_id)
        assert (spec.vector_entry_point is not None) == (kw.get("backend", "geometric") == "geometric")
    with pytest.raises(ValueError, match="autoreset_mode"):
        HapticRecogVectorEnv(2, env_config, autoreset_mode="sometimes")
    with pytest.raises(ValueError, match="max_grasps"):
        HapticRecogVectorEnv(2, env_config, max_episode_steps=5)


def test_determinism_and_pickling(env_config):
    B = 3
    a, b = HapticRecogVectorEnv(B, env_config), HapticRecogVectorEnv(B, env_config)
    c = pickle.loads(pickle.dumps(HapticRecogVectorEnv(B, env_config, grasp_cost=0.05)))
    assert c.config == env_config.replace(grasp_cost=0.05)
    d = pickle.loads(pickle.dumps(a))
    oa, ob, od = a.reset(seed=4)[0], b.reset(seed=4)[0], d.reset(seed=4)[0]
    np.testing.assert_array_equal(oa, ob)
    np.testing.assert_array_equal(oa, od)
    for act in _actions(15, B, seed=3):
        ra, rb, rd = a.step(act), b.step(act), d.step(act)
        for x, y, z in zip(ra[:4], rb[:4], rd[:4]):
            np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(x, z)
    e = HapticRecogVectorEnv(B, env_config)
    e.reset(seed=5)
    a.reset(seed=4)
    assert (e.targets != a.targets).any() or not np.allclose(e.poses, a.poses)


def test_grasp_placed_equals_set_object_then_grasp(env_config):
    """The batched backend call: each grasp equals set_object + grasp, bit for bit (scales, so3 poses, noise)."""
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set
    from haptic_env.scene import random_pose

    objects = list(load_object_set(env_config.objects))
    backend = make_backend("geometric", n_fingers=4, contact_noise=0.001, normal_noise_deg=2.0)
    rng = np.random.default_rng(0)
    B = 24
    placed = backend.placed_objects(objects, B)
    setups = []
    for b in range(B):
        k = int(rng.integers(len(objects)))
        pose = random_pose(rng, "so3" if b % 2 else "table-yaw")
        pose[:3, 3] = rng.normal(0, 0.01, 3) if b % 3 == 0 else 0.0
        scale = 1.0 if b % 4 else float(rng.uniform(0.7, 1.3))
        placed.place(b, k, pose, scale)
        setups.append((k, pose, scale))
    actions = rng.uniform(-1, 1, (B, 4))
    rows = rng.permutation(B)
    batch = backend.grasp_placed(actions, placed, rows=rows, rngs=[np.random.default_rng(j) for j in range(B)])
    for j, b in enumerate(rows):
        k, pose, scale = setups[b]
        backend.set_object(objects[k], pose, scale=scale)
        one = backend.grasp(actions[j], np.random.default_rng(j))
        np.testing.assert_array_equal(batch.touched[j], one.touched)
        np.testing.assert_array_equal(batch.contacts[j], one.contacts)
        np.testing.assert_array_equal(batch.normals[j], one.normals)
    assert batch.touched.any() and not batch.touched.all()


@pytest.mark.parametrize("support,n_fingers", [("table", 4), ("floating", 3), ("table", 5)])
def test_grasp_placed_kernels_equal_the_numpy_reference_on_many_grasps(env_config, support, n_fingers):
    """grasp_placed's compiled ray set-up and hit maths (_geometric_kernels) against set_object + grasp (the NumPy
    reference) on 300 grasps, bit for bit: boundary actions (the poles, where the approach frame takes its
    fallback reference; +-1 rolls and spreads), scales, so3 poses, translations."""
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set
    from haptic_env.scene import random_pose

    objects = list(load_object_set(env_config.objects))
    backend = make_backend("geometric", n_fingers=n_fingers, support=support)
    rng = np.random.default_rng(n_fingers)
    B = 300
    placed = backend.placed_objects(objects, B)
    setups = []
    for b in range(B):
        k = int(rng.integers(len(objects)))
        pose = random_pose(rng, "so3" if b % 3 == 0 else "table-yaw")
        pose[:3, 3] = rng.normal(0, 0.01, 3) if b % 5 == 0 else 0.0
        scale = 1.0 if b % 4 else float(rng.uniform(0.7, 1.3))
        setups.append((k, pose, scale))
    ks = [k for k, _, _ in setups]
    placed.place_many(np.arange(B), ks, np.array([p for _, p, _ in setups]), [s for _, _, s in setups])
    actions = rng.uniform(-1, 1, (B, 4))
    actions[: B // 3] = rng.choice([-1.0, 0.0, 1.0, 0.5], (B // 3, 4))  # poles, edges, zero
    batch = backend.grasp_placed(actions, placed)
    for b in range(B):
        k, pose, scale = setups[b]
        backend.set_object(objects[k], pose, scale=scale)
        one = backend.grasp(actions[b], np.random.default_rng(0))
        np.testing.assert_array_equal(batch.touched[b], one.touched)
        if one.touched.sum() == 1:  # the single grasp's one hit goes to the world as a (1, 3) @ (3, 3), another
            # BLAS route than the batch's (n, 3) @ (3, 3) (so before the kernels too): the last bit may differ; the
            # env never uses such a contact (fewer than 2 touching: no grasp vector)
            np.testing.assert_allclose(batch.contacts[b], one.contacts, rtol=0, atol=1e-15)
            np.testing.assert_allclose(batch.normals[b], one.normals, rtol=0, atol=1e-15)
            continue
        np.testing.assert_array_equal(batch.contacts[b], one.contacts)
        np.testing.assert_array_equal(batch.normals[b], one.normals)
    assert batch.touched.any() and not batch.touched.all() and (batch.touched.sum(axis=1) >= 2).sum() > B // 2


@pytest.mark.parametrize("overrides", [{}, {"pose": "so3", "scale_range": (0.8, 1.2)}])
def test_scene_draw_many_equals_draw(env_config, overrides):
    """Scene.draw_many (a vector env's resets of one step) draws what Scene.draw draws from each generator."""
    from haptic_env.scene import Scene

    scene = Scene(env_config.replace(**overrides))
    which = [None, 2, None, "mug" if "mug" in scene.names else 0, None] * 40
    a = [np.random.default_rng(s) for s in range(len(which))]
    b = [np.random.default_rng(s) for s in range(len(which))]
    for _ in range(3):  # the generators continue
        targets, poses, scales, seeds = scene.draw_many(a, which)
        for j, rng in enumerate(b):
            k, pose, scale, seed = scene.draw(rng, which[j])
            assert (targets[j], scales[j], seeds[j]) == (k, scale, seed)
            np.testing.assert_array_equal(poses[j], pose)
    scene.close()


def test_scorer_batch_equals_one_grasp_at_a_time(env_config):
    from haptic_env.belief import get_recognizer
    from haptic_env.grasping import make_backend
    from haptic_env.objects import load_object_set

    objects = load_object_set(env_config.objects)
    scorer = get_recognizer(objects, env_config).grasp_scorer(True)
    backend = make_backend("geometric", n_fingers=4)
    backend.set_object(objects[0], np.eye(4))
    res = backend.grasp_batch(np.random.default_rng(1).uniform(-1, 1, (200, 4)), np.random.default_rng(0))
    full = res.touched.all(axis=1)
    C, N = res.contacts[full], res.normals[full]
    C[0, 3] = C[0, 0]  # a degenerate grasp (repeated contact)
    q, ll, scored = scorer.batch(C, N)
    assert not scored[0] and scored.sum() > 10
    for b in range(len(C)):
        q1, ll1 = scorer(C[b], N[b])
        np.testing.assert_array_equal(q[b], q1)
        assert (ll1 is None) == (not scored[b])
        if ll1 is not None:
            np.testing.assert_array_equal(ll[b], ll1[0])


def test_sb3_adapter_steps_like_dummy_vec_env(env_config, tmp_path):
    """train.py --vec native: the adapter gives DummyVecEnv's observations, rewards, dones, terminal
    observations and info dicts (every sub-env's at every step: those whose episode went on were empty) for the same
    seeds and actions, and writes Monitor files with the same columns."""
    from agents.sb3 import make_vec_env

    cfg = env_config.replace(grasp_cost=0.05, max_grasps=5)
    nat = make_vec_env(cfg, n_envs=3, seed=7, log_dir=tmp_path / "nat", vec="native")
    ref = make_vec_env(cfg, n_envs=3, seed=7, log_dir=tmp_path / "ref", vec="dummy")
    for venv in (nat, ref):  # the next reset's objects (the native adapter ignored set_options)
        venv.set_options([{"object": 2}, {}, {"object": 5}])
    np.testing.assert_array_equal(nat.reset(), ref.reset())
    assert [i["true_index"] for i in nat.reset_infos] == [i["true_index"] for i in ref.reset_infos]
    assert [nat.reset_infos[i]["true_index"] for i in (0, 2)] == [2, 5]
    episodes = 0
    for a in _actions(30, 3, seed=2):
        o1, r1, d1, inf1 = nat.step(a)
        o2, r2, d2, inf2 = ref.step(a)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(d1, d2)
        for x, y in zip(nat.reset_infos, ref.reset_infos):  # an autoreset's info (it kept the first reset's)
            assert set(x) == set(y)
            for key in y:
                np.testing.assert_equal(x[key], y[key])
        for x, y in zip(inf1, inf2):
            assert set(x) == set(y) and x  # the single env's keys, every step
            for key in set(y) - {"terminal_observation", "episode"}:
                np.testing.assert_equal(x[key], y[key])
            if "terminal_observation" in y:
                episodes += 1
                np.testing.assert_array_equal(x["terminal_observation"], y["terminal_observation"])
                assert x["TimeLimit.truncated"] == y["TimeLimit.truncated"]
                assert (x["episode"]["r"], x["episode"]["l"]) == (y["episode"]["r"], y["episode"]["l"])
                assert x["episode"]["correct"] == y["correct"] and x["episode"]["grasps"] == y["grasps"]
    assert episodes > 3
    nat.close()
    ref.close()
    for r in range(3):
        a = (tmp_path / "nat" / "monitor" / f"{r}.monitor.csv").read_text().splitlines()
        b = (tmp_path / "ref" / "monitor" / f"{r}.monitor.csv").read_text().splitlines()
        assert a[1] == b[1] and len(a) == len(b)
        assert [row.split(",")[:2] + row.split(",")[3:] for row in a[2:]] == \
               [row.split(",")[:2] + row.split(",")[3:] for row in b[2:]]


@pytest.mark.slow
def test_ppo_learns_the_same_on_native_and_dummy(env_config, tmp_path):
    """Same seeds, same PPO: the native vector env's learning run is episode for episode the DummyVecEnv run."""
    from agents import sb3

    cfg = env_config.replace(grasp_cost=0.05)
    rows = {}
    for vec in ("native", "dummy"):
        venv = sb3.make_vec_env(cfg, n_envs=2, seed=0, log_dir=tmp_path / vec, vec=vec)
        sb3.train("ppo", venv, 1024, tmp_path / vec, seed=0, checkpoint_freq=10**6, n_steps=128, batch_size=64)
        venv.close()
        rows[vec] = [[r.split(",")[:2] for r in (tmp_path / vec / "monitor" / f"{i}.monitor.csv").read_text()
                      .splitlines()[2:]] for i in range(2)]
    assert rows["native"] == rows["dummy"] and len(rows["native"][0]) > 20
