"""benchmarks/pose_ceiling.py's oracle: the pose-blind look-ahead for the first grasp, the pose-told one after."""

from __future__ import annotations

import numpy as np


class _Stub:
    def __init__(self, tag: float):
        self.tag, self.seeds = tag, []

    def reset(self, env, seed=None):
        self.seeds.append(seed)

    def act(self, obs, env):
        return np.full(4, self.tag)


class _Env:
    def __init__(self):
        self.grasp_count = 0

    @property
    def unwrapped(self):
        return self


def test_blind_then_known_switches_after_the_first_grasp(load_benchmark):
    bench = load_benchmark("pose_ceiling")
    agent = bench.BlindThenKnown(8, 3, seed=0)
    assert agent.blind.pose_known is False and agent.blind.n_samples == 3 and agent.blind.simulate == "env"
    assert agent.known.pose_known is True and agent.known.n_samples == 1 and agent.known.n_candidates == 8
    agent.blind, agent.known = _Stub(-1.0), _Stub(1.0)
    env = _Env()
    agent.reset(env, seed=5)
    assert agent.blind.seeds == [5] and agent.known.seeds == [6]
    assert agent.act(None, env)[0] == -1.0
    env.grasp_count = 1
    assert agent.act(None, env)[0] == 1.0
    agent.reset(env)  # a later episode of the same seed: the agents' generators run on
    assert agent.blind.seeds == [5, None] and agent.known.seeds == [6, None]
