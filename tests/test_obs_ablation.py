"""benchmarks/obs_ablation.py: the ablated observation differs from the env's only in the named parts, as documented,
and a policy run through it sees exactly that observation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest


@pytest.fixture(scope="module")
def ablation(load_benchmark):
    return load_benchmark("obs_ablation")


class Recorder:
    name = "rec"

    def __init__(self):
        self.seen = []

    def reset(self, env, seed=None):
        pass

    def act(self, obs, env):
        self.seen.append(obs.copy())
        return np.zeros(4, dtype=np.float32)


def test_zero_and_yaw_touch_only_the_named_parts(ablation, env_config):
    env = gym.make("HapticRecog-v0", config=env_config.replace(observe_contacts=True))
    sl = env.unwrapped.obs_slices
    obs, _ = env.reset(seed=3)
    obs, *_ = env.step(np.array([0.2, 0.5, -0.3, 0.1], dtype=np.float32))
    parts = ["contacts", "contact_normals"]
    assert obs[sl["contacts"]].any()
    others = np.ones(obs.shape, bool)
    for p in parts:
        others[sl[p]] = False

    rec = Recorder()
    zero = ablation.ObsAblation(rec, parts, "zero")
    zero.reset(env, seed=0)
    zero.act(obs, env)
    z = rec.seen[-1]
    np.testing.assert_array_equal(z[others], obs[others])
    assert not z[~others].any()

    yaw = ablation.ObsAblation(rec, parts, "yaw")
    yaw.reset(env, seed=0)
    yaw.act(obs, env)
    y = rec.seen[-1]
    np.testing.assert_array_equal(y[others], obs[others])
    for p in parts:
        a, b = obs[sl[p]].reshape(-1, 3), y[sl[p]].reshape(-1, 3)
        np.testing.assert_allclose(np.linalg.norm(b, axis=1), np.linalg.norm(a, axis=1), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(b[:, 2], a[:, 2], atol=1e-6)  # a turn about the world z axis
    assert not np.allclose(y[sl["contacts"]], obs[sl["contacts"]])
    # one turn for every contact and normal of the observation (still a plausible grasp): the angle read off the
    # touched contact farthest from the axis turns every 3-vector of both parts into the ablated ones
    a = obs[sl["contacts"]].reshape(-1, 3)
    k = int(np.argmax(np.linalg.norm(a[:, :2], axis=1)))
    b = y[sl["contacts"]].reshape(-1, 3)
    t = np.arctan2(b[k, 1], b[k, 0]) - np.arctan2(a[k, 1], a[k, 0])
    R = np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])
    for p in parts:
        np.testing.assert_allclose(y[sl[p]].reshape(-1, 3), obs[sl[p]].reshape(-1, 3) @ R.T, atol=1e-5)
    yaw.reset(env, seed=0)  # seeded: the same turn again
    yaw.act(obs, env)
    np.testing.assert_array_equal(rec.seen[-1], y)

    with pytest.raises(ValueError, match="not in this env's observation"):
        ablation.ObsAblation(rec, ["nope"], "zero").reset(env)
    with pytest.raises(ValueError, match="3-vectors"):
        ablation.ObsAblation(rec, ["grasp_count"], "yaw").reset(env)
    with pytest.raises(ValueError, match="mode"):
        ablation.ObsAblation(rec, parts, "flip")
    env.close()
