"""Replay backend: a hand's recorded MuJoCo grasps looked up by approach (generic hand: no data needed)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from haptic_env.grasping import make_backend
from haptic_env.grasping.replay import ReplayBackend, ReplayConfig, approach_embedding
from haptic_env.hand_grasps import hand_grasp_pool, pool_actions
from haptic_env.objects import load_object_set


@pytest.fixture(scope="module")
def two_objects():
    return load_object_set("default").subset(("can", "mug"), name="can-mug")


def _yaw_pose(psi: float) -> np.ndarray:
    T = np.eye(4)
    c, s = np.cos(psi), np.sin(psi)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def test_a_recorded_approach_replays_the_physics_grasp(two_objects):
    """At a recorded approach the replay gives the pool's grasp, which is the MuJoCo backend's grasp there; under a
    yaw it gives that grasp turned, along the azimuth turned by the same yaw."""
    be = make_backend("replay", hand="generic", approaches=12, pool_seed=3, progress=False)
    assert be.n_fingers == 4
    be.prepare(two_objects)
    pool = hand_grasp_pool(two_objects, "generic", 4, 12, seed=3, progress=False)  # the same cached pool
    assert pool.from_cache
    actions = pool_actions(3, 1, 12).astype(np.float32)  # object 1 (the mug)'s approach stream
    mug = two_objects["mug"]
    be.set_object(mug)
    batch = be.grasp_batch(actions, None)
    np.testing.assert_allclose(batch.contacts, pool.contacts[1], atol=1e-6)
    np.testing.assert_array_equal(batch.touched, pool.touched[1])
    phys = make_backend("mujoco", n_fingers=4, hand="generic", normals=True)
    phys.set_object(mug)
    i = int(np.argmax(pool.touched[1].sum(1)))  # an approach that touches
    r = phys.grasp(actions[i], np.random.default_rng(0))
    np.testing.assert_allclose(r.contacts, batch.contacts[i], atol=1e-6)  # solver round-off
    np.testing.assert_allclose(r.normals, batch.normals[i], atol=1e-6)
    phys.close()
    # turned by psi: the azimuth turned by psi gives the same grasp, turned
    psi = 2.4
    be.set_object(mug, _yaw_pose(psi))
    turned = actions.astype(np.float64).copy()
    turned[:, 0] = np.mod(turned[:, 0] + psi / np.pi + 1.0, 2.0) - 1.0
    tb = be.grasp_batch(turned.astype(np.float32), None)
    R = _yaw_pose(psi)[:3, :3]
    np.testing.assert_allclose(tb.contacts, batch.contacts @ R.T, atol=1e-5)
    np.testing.assert_allclose(tb.normals, batch.normals @ R.T, atol=1e-5)
    np.testing.assert_array_equal(tb.touched, batch.touched)
    one = be.grasp(turned[i].astype(np.float32), None)  # the single grasp is the batch's row, with its usability
    np.testing.assert_allclose(one.contacts, tb.contacts[i])
    assert one.info["usable"] == (one.touched.sum() >= 3)


def test_nearest_approach_and_periodic_distance(two_objects):
    be = make_backend("replay", hand="generic", approaches=12, pool_seed=3, normals=False, progress=False)
    be.set_object(two_objects["can"])  # not prepared: recorded (here: read from the cache) on first use
    actions = pool_actions(3, 0, 12)
    near = actions[5] + 0.01
    near[0] = near[0] - 2.0 if near[0] > 1.0 else near[0]
    g = be.grasp(np.clip(near, -1, 1).astype(np.float32), None)
    assert g.normals is None
    expect = be.grasp(actions[5].astype(np.float32), None)
    np.testing.assert_array_equal(g.contacts, expect.contacts)
    # azimuth and roll are periodic: -1 and 1 are the same approach
    e = approach_embedding(np.array([[-1.0, 0.2, 1.0, 0.3], [1.0, 0.2, -1.0, 0.3]]))
    np.testing.assert_allclose(e[0], e[1], atol=1e-12)


def test_bad_input(two_objects):
    be = make_backend("replay", hand="generic", approaches=12, pool_seed=3, progress=False)
    with pytest.raises(RuntimeError, match="set_object"):
        be.grasp(np.zeros(4, np.float32), None)
    tilted = np.eye(4)
    tilted[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]  # a quarter turn about x
    with pytest.raises(ValueError, match="vertical axis only"):
        be.set_object(two_objects["can"], tilted)
    moved = np.eye(4)
    moved[0, 3] = 0.1
    with pytest.raises(ValueError, match="vertical axis only"):
        be.set_object(two_objects["can"], moved)
    be.set_object(two_objects["can"])
    scaled = two_objects["can"].mesh.copy()
    scaled.apply_scale(1.5)
    with pytest.raises(ValueError, match="scaled copy"):
        be.set_object(dataclasses.replace(two_objects["can"], mesh=scaled))
    with pytest.raises(ValueError, match="outside"):
        be.grasp(np.full(4, 2.0, np.float32), None)
    for bad in ({"approaches": 0}, {"approaches": True}, {"pool_seed": -1}, {"hand": ""}, {"support": "wall"}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            ReplayConfig(**bad)
    from pathlib import Path

    assert ReplayConfig(hand=Path("hand.xml")).hand == "hand.xml"  # an MJCF file as a Path, as the MuJoCo backend


def test_env_on_the_replay_backend(small_recognizer_kwargs):
    """An env with backend="replay" trains its recogniser on the hand's own grasps by default ("auto" -> "hand", as
    for "mujoco"), and steps with the spaces of the mujoco env."""
    from haptic_env.config import recognizer_kwargs
    from haptic_env.env import HapticRecogConfig, HapticRecogEnv

    grasps = recognizer_kwargs(HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic"}))["config"].grasps
    assert grasps.source == "hand" and grasps.hand == "generic"
    HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic"}, touch_weight=0.5)  # hand-matched: allowed
    cfg = HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic", "approaches": 8, "progress": False},
                            recognizer_source="surface", recognizer_kwargs=small_recognizer_kwargs, max_grasps=3)
    env = HapticRecogEnv(cfg)
    try:
        assert env.action_space.shape == (4,)
        obs, info = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        done = False
        while not done:
            obs, r, term, trunc, info = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs)
            done = term or trunc
    finally:
        env.close()


def test_the_greedy_look_ahead_on_a_replay_env_replays_the_envs_own_records(small_recognizer_kwargs):
    """``greedy-env`` on a replay env simulates each hypothesis with the env's recordings: at the true pose its grasp
    of the true object along an approach is the env's own (an object's recorded approaches depend on its index in
    the set; a backend per object had recorded each as the first object of a set of one)."""
    from agents.evaluate import make_agent
    from haptic_env.env import HapticRecogConfig, HapticRecogEnv

    cfg = HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic", "approaches": 8, "progress": False},
                            recognizer_source="surface", recognizer_kwargs=small_recognizer_kwargs, max_grasps=3)
    env = HapticRecogEnv(cfg)
    try:
        agent = make_agent("greedy-env:4", seed=0)
        acts = np.random.default_rng(1).uniform(-1, 1, (5, 4))
        for k in (1, 2):  # objects past the first
            env.reset(seed=k, options={"object": env.object_names[k]})
            agent.reset(env)
            sim = agent._grasp(env, k, acts)
            real = env.scene.backend.grasp_batch(acts, np.random.default_rng(0))
            np.testing.assert_array_equal(sim.touched, real.touched)
            np.testing.assert_allclose(sim.contacts, real.contacts)
    finally:
        env.close()


def test_fidelity_benchmark_runs_on_the_generic_hand(load_benchmark, capsys, usage_error):
    """benchmarks/replay_fidelity.py on a small pool: the replay of a pool's own approaches (same seed) is exact."""
    fidelity = load_benchmark("replay_fidelity")
    assert fidelity.main(["--hand", "generic", "--objects", "default", "--approaches", "6", "--replay-seed", "4",
                          "--pool-seed", "4", "--pool-approaches", "6", "--time-approaches", "2"]) == 0
    out = capsys.readouterr().out
    assert "| **mean** | **100 %** | **100 %** | **0.0** |" in out  # the held-out pool is the replay's own
    assert out.strip().splitlines()[-1].startswith("replay backend: ")
    usage_error(fidelity.main, ["--approaches", "0"], match="--approaches: must be >= 1, got 0")
    # --table: the records are a table's approaches at yaws, queried at random yaws
    assert fidelity.main(["--hand", "generic", "--objects", "default", "--table", "2", "--yaws", "4",
                          "--pool-seed", "4", "--pool-approaches", "4", "--time-approaches", "2"]) == 0
    out = capsys.readouterr().out
    assert "replay of the 2 table approaches at 4 yaws each against MuJoCo's grasps of 4 table approaches" in out
    assert "| **mean** |" in out
    usage_error(fidelity.main, ["--yaws", "0"], match="--yaws: must be >= 1, got 0")


def test_the_allegro_physics_turns_with_the_object():
    """The replay's premise, on the MuJoCo Allegro: a grasp of the object turned by a yaw, along the azimuth turned
    by the same yaw, is the unturned grasp, turned (to round-off)."""
    from haptic_env.objects import data_dir

    if data_dir() is None:
        pytest.skip("needs the shared data (ycb/ meshes and the menagerie Allegro): set HAPTIC_DATA")
    drill = load_object_set("ycb10")["035_power_drill"]
    be = make_backend("mujoco", hand="allegro", normals=True)
    rng = np.random.default_rng(0)
    try:
        for _ in range(4):
            a, psi = rng.uniform(-1, 1, 4), rng.uniform(0, 2 * np.pi)
            be.set_object(drill)
            r0 = be.grasp(a, np.random.default_rng(1))
            b = a.copy()
            b[0] = np.mod(a[0] + psi / np.pi + 1.0, 2.0) - 1.0
            be.set_object(drill, _yaw_pose(psi))
            r1 = be.grasp(b, np.random.default_rng(1))
            np.testing.assert_array_equal(r1.touched, r0.touched)
            np.testing.assert_allclose(r1.contacts, r0.contacts @ _yaw_pose(psi)[:3, :3].T, atol=1e-9)
    finally:
        be.close()


def test_neighbours_draw_one_of_the_nearest_records(two_objects):
    be = make_backend("replay", hand="generic", approaches=12, pool_seed=3, neighbours=3, progress=False)
    be.set_object(two_objects["mug"])
    tree, C, _, _ = be.records(two_objects["mug"])
    a = np.tile(np.array([0.2, -0.3, 0.5, 0.1], np.float32), (64, 1))
    got = be.grasp_batch(a, np.random.default_rng(0))
    _, near = tree.query(approach_embedding(a[:1].astype(np.float64)), k=3)
    records = {C[i].tobytes() for i in near[0]}  # (two records may be alike, e.g. both missed)
    assert {g.tobytes() for g in got.contacts} == records  # every one of the 3 nearest, and nothing else
    again = be.grasp_batch(a, np.random.default_rng(0))
    np.testing.assert_array_equal(again.contacts, got.contacts)  # the generator decides
    with pytest.raises(ValueError, match="Generator"):
        be.grasp_batch(a, None)
    for bad in (0, 13, True):
        with pytest.raises(ValueError, match="neighbours"):
            ReplayConfig(approaches=12, neighbours=bad)


def test_a_table_replay_answers_each_table_approach_with_its_own_grasp_at_the_nearest_recorded_yaw(two_objects):
    """ReplayConfig.table: the records are the table's approaches turned by evenly spaced yaws
    (hand_grasps.table_actions), grasped by the physics; a table approach asked at any yaw of the object gets its own
    grasp at the nearest recorded yaw, turned; the pool is cached under a key that holds the approaches."""
    from haptic_env.grasping.base import approach_table
    from haptic_env.grasping.replay import turned_azimuth
    from haptic_env.hand_grasps import pool_cache_path, table_actions

    acts = table_actions(3, 8)
    assert acts.shape == (24, 4)
    np.testing.assert_array_equal(acts[::8], approach_table(3).astype(np.float64))  # yaw 0 first
    np.testing.assert_allclose(acts[1], turned_azimuth(approach_table(3)[0], 2 * np.pi / 8))
    be = make_backend("replay", hand="generic", table=3, yaws=8, progress=False)
    assert be.config.records == 24
    mug = two_objects["mug"]
    psi = 2 * np.pi * 5 / 8 + 0.1  # 0.1 rad past recorded yaw 5 (the grid is 0.785 rad)
    be.set_object(mug, _yaw_pose(psi))
    got = be.grasp_batch(approach_table(3), None)
    phys = make_backend("mujoco", n_fingers=4, hand="generic", normals=True)
    phys.set_object(mug)
    R = _yaw_pose(psi)[:3, :3]
    for i, a in enumerate(approach_table(3)):
        # the object turned by psi is met by approach a at azimuth -psi in its frame; recorded: -(5/8) turn
        want = phys.grasp(turned_azimuth(a, -2 * np.pi * 5 / 8).astype(np.float32), np.random.default_rng(0))
        np.testing.assert_array_equal(got.touched[i], want.touched)
        np.testing.assert_allclose(got.contacts[i], want.contacts @ R.T, atol=1e-6)
    phys.close()
    key = pool_cache_path(load_object_set("default").subset(("mug",), name="mug"), "generic", 4, 24, "table", 1,
                          actions=acts)
    assert key != pool_cache_path(load_object_set("default").subset(("mug",), name="mug"), "generic", 4, 24,
                                  "table", 1)
    with pytest.raises(ValueError, match="given actions need approaches == len"):
        hand_grasp_pool(two_objects, "generic", 4, 25, actions=acts, cache=False)
    for bad, match in ((np.zeros((2, 3)), r"shape \(B, 4\)"), (np.full((2, 4), np.nan), "must be finite"),
                       (np.full((2, 4), 1.5), r"outside \[-1, 1\]")):
        with pytest.raises(ValueError, match=match):
            hand_grasp_pool(two_objects, "generic", 4, 2, actions=bad, cache=False)
    for bad in ({"table": -1}, {"table": 1.5}, {"table": True}, {"yaws": 0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            ReplayConfig(**bad)
    with pytest.raises(ValueError, match=r"neighbours must be an int in \[1, 8\]"):
        ReplayConfig(table=2, yaws=4, neighbours=9)


def _records(rng, A=200, n=4):
    """Synthetic records of one object: approaches, contacts and touches (no physics), as ``records`` returns them."""
    from scipy.spatial import cKDTree

    actions = rng.uniform(-1, 1, (A, 4))
    C = rng.normal(0.0, 0.05, (A, n, 3))
    T = rng.random((A, n)) < 0.8
    C[~T] = 0.0
    return actions, (cKDTree(approach_embedding(actions)), C, np.zeros_like(C), T)


def test_yaw_likelihood_peaks_at_the_yaw_that_turned_a_recorded_grasp():
    """A recorded grasp turned by psi, along its approach turned by psi, fits the yaw psi best (the record itself at
    distance 0); turning the query and the yaws together leaves the scores; a touch mismatch costs log(miss)."""
    from haptic_env.grasping.replay import yaw_log_likelihood

    rng = np.random.default_rng(0)
    actions, rec = _records(rng)
    yaws = np.arange(36) * 2 * np.pi / 36
    i, j = 7, 20
    psi = yaws[j]
    a = actions[i].copy()
    a[0] = np.mod(a[0] + psi / np.pi + 1.0, 2.0) - 1.0
    c = rec[1][i] @ _yaw_pose(psi)[:3, :3].T
    ll = yaw_log_likelihood(rec, a, c, rec[3][i], yaws, sigma=0.005, neighbours=1)
    assert ll.shape == (36,) and int(np.argmax(ll)) == j
    assert ll[j] == pytest.approx(3 * rec[3][i].sum() * -np.log(0.005))  # d = 0 at every touching finger
    # the same grasp turned once more by 90 degrees is scored at the yaws turned by 90 degrees alike
    turn = np.pi / 2
    a2 = a.copy()
    a2[0] = np.mod(a2[0] + turn / np.pi + 1.0, 2.0) - 1.0
    ll2 = yaw_log_likelihood(rec, a2, c @ _yaw_pose(turn)[:3, :3].T, rec[3][i], yaws + turn, sigma=0.005,
                             neighbours=1)
    np.testing.assert_allclose(ll2, ll, atol=1e-9)
    # a finger that touched in the record but not in the grasp: log(miss) instead of its Gaussian term
    t = rec[3][i].copy()
    f = int(np.flatnonzero(t)[0])
    t[f] = False
    ll3 = yaw_log_likelihood(rec, a, c, t, yaws, sigma=0.005, neighbours=1, miss=0.1)
    assert ll3[j] == pytest.approx(ll[j] + np.log(0.005) * 3 + np.log(0.1))


@pytest.mark.parametrize("bad, match", [
    ({"action": np.zeros(3)}, "action must be 4 finite numbers"),
    ({"action": np.array([0.0, np.nan, 0.0, 0.0])}, "action must be 4 finite numbers"),
    ({"action": np.array([0.0, 1.5, 0.0, 0.0])}, r"action must be 4 finite numbers in \[-1, 1\]"),
    ({"contacts": np.zeros((3, 3))}, r"contacts must be \(4, 3\)"),
    ({"touched": np.ones(4)}, "touched must be a bool array"),
    ({"yaws": np.array([])}, "yaws must be a non-empty 1-d array"),
    ({"sigma": 0.0}, "sigma must be a finite number > 0, got 0.0"),
    ({"sigma": "1"}, "sigma must be a finite number > 0"),
    ({"miss": 0.0}, r"miss must be in \(0, 1\], got 0.0"),
    ({"neighbours": 0}, r"neighbours must be an int in \[1, 200\], got 0"),
    ({"neighbours": 2.0}, r"neighbours must be an int in \[1, 200\], got 2.0"),
])
def test_yaw_likelihood_bad_input(bad, match):
    from haptic_env.grasping.replay import yaw_log_likelihood

    _, rec = _records(np.random.default_rng(1))
    args = {"action": np.zeros(4), "contacts": np.zeros((4, 3)), "touched": np.ones(4, dtype=bool),
            "yaws": np.zeros(3), "sigma": 0.01, "neighbours": 4, "miss": 0.05}
    args.update(bad)
    with pytest.raises(ValueError, match=match):
        yaw_log_likelihood(rec, args.pop("action"), args.pop("contacts"), args.pop("touched"), args.pop("yaws"), **args)


def test_yaw_belief_sums_each_grasp_once_per_object_and_restarts():
    """YawBelief: an object's posterior is the uniform prior times every grasp's yaw likelihood, computed when asked
    for (each object and grasp once, in order); reset forgets the episode; the mode and the draws follow it."""
    from haptic_env.grasping.replay import YawBelief, yaw_log_likelihood

    rng = np.random.default_rng(2)
    (_, r0), (a1, r1) = _records(rng), _records(rng)
    yb = YawBelief([r0, r1], bins=36, sigma=0.005, neighbours=1)
    assert yb.grasps == 0 and yb.mode(1) == 0.0 and np.allclose(yb.probs(0), 1 / 36)
    psi = yb.yaws[9]
    queries = []
    for i in (3, 11):  # two grasps of object 1 turned by psi
        a = a1[i].copy()
        a[0] = np.mod(a[0] + psi / np.pi + 1.0, 2.0) - 1.0
        queries.append((a, r1[1][i] @ _yaw_pose(psi)[:3, :3].T, r1[3][i]))
    yb.add(*queries[0])
    first = yb.log_likelihood(1)
    np.testing.assert_allclose(first, yaw_log_likelihood(r1, *queries[0], yb.yaws, sigma=0.005, neighbours=1))
    yb.add(*queries[1])
    both = first + yaw_log_likelihood(r1, *queries[1], yb.yaws, sigma=0.005, neighbours=1)
    np.testing.assert_allclose(yb.log_likelihood(1), both)
    np.testing.assert_allclose(yb.log_likelihood(1), both)  # asked again: not summed twice
    assert yb.mode(1) == pytest.approx(psi) and yb.probs(1).sum() == pytest.approx(1.0)
    draws = np.array([yb.sample(1, rng) for _ in range(200)])
    assert np.all(np.abs(draws - psi) <= np.pi / 36 + 1e-12)  # the posterior's one bin, jittered within it
    assert yb.log_likelihood(0).shape == (36,) and yb.grasps == 2  # object 0 catches up with both grasps
    yb.reset()
    assert yb.grasps == 0 and not yb.log_likelihood(1).any()
    with pytest.raises(ValueError, match="bins must be an int >= 4, got 3"):
        YawBelief([r0], bins=3)
    with pytest.raises(ValueError, match=r"neighbours must be an int in \[1, 200\], got 500"):
        YawBelief([r0], neighbours=500)  # the kernel is checked at construction, not at the first grasp
    with pytest.raises(ValueError, match=r"k must be an object index in \[0, 2\), got -1"):
        yb.log_likelihood(-1)
    with pytest.raises(ValueError, match="records must hold at least one object"):
        YawBelief([])


def test_yaw_certainty_is_the_posterior_mass_near_the_mode():
    """YawBelief.certainty: object k's posterior mass within ``window`` bins of its mode, either side, wrapping round
    the circle; (2 window + 1) / bins before any grasp; a bad window is refused, naming it."""
    from haptic_env.grasping.replay import YAW_WINDOW, YawBelief

    rng = np.random.default_rng(3)
    _, rec = _records(rng)
    yb = YawBelief([rec], bins=36, sigma=0.005, neighbours=1)
    assert yb.certainty(0) == pytest.approx((2 * YAW_WINDOW + 1) / 36)
    assert yb.certainty(0, window=0) == pytest.approx(1 / 36)
    lp = np.log(np.arange(1, 37, dtype=float))[::-1]  # mode at bin 0: the window wraps to bins 35, 34, ...
    yb._log[0], yb._upto[0] = lp, 0
    p = np.exp(lp - lp.max())
    p /= p.sum()
    assert yb.certainty(0, window=2) == pytest.approx(p[[34, 35, 0, 1, 2]].sum())
    assert yb.certainty(0, window=17) == pytest.approx(1.0 - p[18])
    lp = np.full(36, -50.0)  # two equal peaks: the window is centred on the first, the bin mode() returns
    lp[[5, 20]], lp[[4, 6]] = 0.0, -1.0
    yb._log[0] = lp
    assert yb.mode(0) == pytest.approx(yb.yaws[5])
    p = np.exp(lp)
    assert yb.certainty(0, window=1) == pytest.approx(p[4:7].sum() / p.sum())
    assert yb.certainty(0, window=np.int64(1)) == yb.certainty(0, window=1)
    with pytest.raises(ValueError, match=r"k must be an object index in \[0, 1\), got 1"):
        yb.certainty(1)
    for bad in (-1, 18, 1.5, "2", True):
        with pytest.raises(ValueError, match=rf"window must be an int in \[0, bins // 2 = 18\), got {bad!r}"):
            yb.certainty(0, window=bad)


def test_env_observes_the_yaw_certainty(small_recognizer_kwargs):
    """observe_yaw: one more observation part, last, holding the most probable object's yaw certainty after reset and
    every grasp; refused without action_frame="estimated", naming it."""
    from haptic_env.env import HapticRecogConfig, HapticRecogEnv

    with pytest.raises(ValueError, match="observe_yaw=True .* needs action_frame='estimated', got action_frame='world'"):
        HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic"}, observe_yaw=True)
    with pytest.raises(ValueError, match="observe_yaw must be True or False, got 1"):
        HapticRecogConfig(observe_yaw=1)
    with pytest.raises(ValueError, match="needs action_frame='estimated', got action_frame='oracle'"):
        HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic"}, action_frame="oracle", observe_yaw=True)
    cfg = HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic", "approaches": 40, "progress": False},
                            recognizer_source="surface", recognizer_kwargs=small_recognizer_kwargs, max_grasps=4,
                            threshold=0.999, action_frame="estimated")
    plain, env = HapticRecogEnv(cfg), HapticRecogEnv(cfg.replace(observe_yaw=True))
    try:
        assert list(env.observation_structure) == [*plain.observation_structure, "yaw_certainty"]
        assert env.obs_slices["yaw_certainty"] == slice(plain.observation_space.shape[0], env.observation_space.shape[0])
        obs, _ = env.reset(seed=1)
        obs_plain, _ = plain.reset(seed=1)
        assert obs[-1] == pytest.approx(7 / 72) and env.observation_space.contains(obs)
        rng = np.random.default_rng(0)
        seen = []
        for _ in range(3):
            a = rng.uniform(-0.9, 0.9, 4)
            obs, *_ = env.step(a)
            obs_plain, *_ = plain.step(a)
            np.testing.assert_array_equal(obs[:-1], obs_plain)  # the rest of the observation is the plain env's
            want = env._yaw_belief.certainty(int(np.argmax(env.belief)))
            assert obs[-1] == pytest.approx(want, abs=1e-6) and env.observation_space.contains(obs)
            seen.append(float(obs[-1]))
        assert max(seen) > 7 / 72  # grasps do tell the yaw
        # and the value is that of the frame the next grasp is aimed in: centred on the yaw that turns it
        k = int(np.argmax(env.belief))
        p = env._yaw_belief.probs(k)
        mode = int(round(env._yaw_belief.mode(k) / (2 * np.pi / 72)))
        assert obs[-1] == pytest.approx(p[(mode + np.arange(-3, 4)) % 72].sum(), abs=1e-6)
        if not env._episode_over:
            psi = env._yaw_belief.mode(k)  # read before the grasp adds to the yaw belief
            env.step(np.zeros(4))
            assert env.last_approach[0] == pytest.approx(np.mod(psi / np.pi + 1.0, 2.0) - 1.0)
        obs, _ = env.reset(seed=2)
        assert obs[-1] == pytest.approx(7 / 72)  # a new episode: no grasps, every yaw equally likely
    finally:
        env.close()
        plain.close()


def test_env_reads_the_azimuth_in_the_estimated_frame(small_recognizer_kwargs):
    """action_frame="estimated": each grasp's azimuth is turned by the most probable object's most probable yaw given
    the episode's grasps (the first grasp: no turn); the observation keeps the policy's own action. A setting that
    cannot have it is refused at make, naming it."""
    from haptic_env.env import HapticRecogConfig, HapticRecogEnv

    frames = r"\('world', 'estimated', 'oracle'\)"
    with pytest.raises(ValueError, match=rf"action_frame must be one of {frames}, got 'object'"):
        HapticRecogConfig(action_frame="object")
    with pytest.raises(ValueError, match="action_frame='estimated' needs a hand backend .* backend='geometric'"):
        HapticRecogConfig(action_frame="estimated")
    with pytest.raises(ValueError, match="pose='so3'"):
        HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic"}, pose="so3", action_frame="estimated")
    with pytest.raises(ValueError, match=r"scale_range=\(0.8, 1.2\)"):
        HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic"}, scale_range=(0.8, 1.2),
                          action_frame="estimated")
    cfg = HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic", "approaches": 40, "progress": False},
                            recognizer_source="surface", recognizer_kwargs=small_recognizer_kwargs, max_grasps=4,
                            threshold=0.999, action_frame="estimated")
    env = HapticRecogEnv(cfg)
    try:
        rng = np.random.default_rng(0)
        turned = 0
        for seed in (1, 3, 5):  # episodes until one turns a later grasp (a grasp of too few fingers tells no yaw)
            env.reset(seed=seed)
            assert env.last_approach is None
            for step in range(3):
                a = rng.uniform(-0.9, 0.9, 4)
                yb = env._yaw_belief
                psi = yb.mode(int(np.argmax(env.belief)))
                if step == 0:
                    assert psi == 0.0
                obs, *_ = env.step(a)
                want = a.copy()
                want[0] = np.mod(a[0] + psi / np.pi + 1.0, 2.0) - 1.0
                np.testing.assert_allclose(env.last_approach, want, atol=1e-12)
                np.testing.assert_allclose(obs[env.obs_slices["prev_action"]], a, atol=1e-6)  # the policy's frame
                assert yb.grasps == step + 1
                turned += psi != 0.0
            if turned:
                break
        assert turned  # the estimate did turn a later grasp
        env.reset(seed=2)
        assert env._yaw_belief.grasps == 0
        assert env._yaw_belief.kernel["neighbours"] == 32  # the default: 40 records per object
        # the belief's records are a pool apart from the replay's, which answer the env's grasps (with the same, each
        # grasp is one of the belief's records turned by the true yaw: a yaw found almost exactly)
        answers = env.backend.records(env.objects[0])
        believed = env._yaw_belief.records[0]
        assert answers[1].shape == believed[1].shape and not np.allclose(answers[1], believed[1])
        pooled = ReplayBackend(ReplayConfig(hand="generic", approaches=40, pool_seed=2, progress=False))
        pooled.prepare(env.objects)
        np.testing.assert_array_equal(pooled.records(env.objects[0])[1], believed[1])
        from agents.greedy import GreedyInfoGainAgent  # the look-ahead simulates world-frame actions: refused

        with pytest.raises(ValueError, match="it needs action_frame='world', got 'estimated'"):
            GreedyInfoGainAgent(n_candidates=2).reset(env)
    finally:
        env.close()
    small = HapticRecogEnv(cfg.replace(backend_kwargs={"hand": "generic", "approaches": 8, "progress": False}))
    try:  # fewer records than the kernel's default neighbours: the belief uses them all
        small.reset(seed=0)
        assert small._yaw_belief.kernel["neighbours"] == 8
        small.step(np.zeros(4))
        small.step(np.zeros(4))
        assert small._yaw_belief.log_likelihood(0).shape == (72,)
    finally:
        small.close()


def test_env_reads_the_azimuth_in_the_true_frame_after_the_first_grasp_with_oracle(small_recognizer_kwargs):
    """action_frame="oracle" (training only): the first grasp in the world frame, as "estimated"'s before any grasp,
    every later one turned by the object's true yaw; it needs what "estimated" needs, and builds no yaw belief."""
    from haptic_env.env import HapticRecogConfig, HapticRecogEnv

    with pytest.raises(ValueError, match="action_frame='oracle' needs a hand backend .* backend='geometric'"):
        HapticRecogConfig(action_frame="oracle")
    cfg = HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic", "approaches": 40, "progress": False},
                            recognizer_source="surface", recognizer_kwargs=small_recognizer_kwargs, max_grasps=4,
                            threshold=0.999, action_frame="oracle")
    env = HapticRecogEnv(cfg)
    try:
        for seed in (1, 2):
            env.reset(seed=seed)
            psi = env.unwrapped.scene.yaw
            np.testing.assert_allclose(env.unwrapped.scene.pose[:3, :3] @ [1.0, 0.0, 0.0],
                                       [np.cos(psi), np.sin(psi), 0.0], atol=1e-12)
            rng = np.random.default_rng(seed)
            for step in range(3):
                a = rng.uniform(-0.9, 0.9, 4)
                obs, *_ = env.step(a)
                want = a.copy()
                if step:
                    want[0] = np.mod(a[0] + psi / np.pi + 1.0, 2.0) - 1.0
                np.testing.assert_allclose(env.last_approach, want, atol=1e-12)
                np.testing.assert_allclose(obs[env.obs_slices["prev_action"]], a, atol=1e-6)
            assert env._yaw_belief is None
    finally:
        env.close()


def test_a_hand_envs_hand_is_its_backends_default_when_not_given():
    """The recogniser's hand pool and the yaw belief read the env's hand by one rule: backend_kwargs["hand"], else
    the backend's own default (the replay's Allegro, the MuJoCo backend's generic hand)."""
    from haptic_env.config import HapticRecogConfig, backend_hand, recognizer_kwargs

    assert backend_hand(HapticRecogConfig(backend="replay")) == ReplayConfig.hand == "allegro"
    assert backend_hand(HapticRecogConfig(backend="mujoco")) == "generic"
    assert backend_hand(HapticRecogConfig(backend="replay", backend_kwargs={"hand": "shadow"})) == "shadow"
    assert recognizer_kwargs(HapticRecogConfig(backend="replay"))["config"].grasps.hand == "allegro"


def test_the_replay_backend_and_the_yaw_belief_record_the_envs_table(two_objects, monkeypatch):
    """``solid_table`` reaches the replay's recordings and an env's yaw belief (they recorded the default, solid,
    table whatever the env's; a replay env with ``solid_table=False`` was a TypeError)."""
    import haptic_env.hand_grasps as hg
    from haptic_env.grasping.replay import ReplayBackend
    from haptic_env.scene import Scene

    asked = []

    def fake_pool(objects, hand, n_fingers, approaches, **kw):
        asked.append(kw.get("solid_table"))
        raise RuntimeError("recorded")

    monkeypatch.setattr(hg, "hand_grasp_pool", fake_pool)
    for table in (None, False):
        with pytest.raises(RuntimeError, match="recorded"):
            ReplayBackend(ReplayConfig(hand="generic", approaches=4, solid_table=table)).prepare(two_objects)
    with pytest.raises(ValueError, match="solid_table needs support='table'"):
        ReplayConfig(hand="generic", support="floating", solid_table=True)
    scene = Scene.__new__(Scene)  # only what yaw_belief reads: the config and the objects
    scene.config = dataclasses.replace(_plain_hand_config(), backend_kwargs={"hand": "generic", "solid_table": False})
    scene.objects = two_objects
    with pytest.raises(RuntimeError, match="recorded"):
        scene.yaw_belief()
    assert asked == [None, False, False]


def _plain_hand_config():
    from haptic_env.env import HapticRecogConfig

    return HapticRecogConfig(backend="mujoco", backend_kwargs={"hand": "generic"}, recognizer_source="surface",
                             action_frame="estimated")
