"""Agents: random and greedy complete episodes, a tiny PPO run saves/reloads/resumes, evaluate writes its report."""

from __future__ import annotations

import copy
import csv
import json
import re

import numpy as np
import pytest

import haptic_env
from agents.evaluate import (EpisodeRecord, confusion, errors_markdown, evaluate_agents, plot_learning_curves,
                             summarize, write_report)
from agents.greedy import GreedyInfoGainAgent
from agents.random_policy import RandomAgent
from haptic_env.belief import Belief, get_recognizer
from haptic_env.task import entropy


def test_random_and_greedy_complete_episodes(env_config):
    make = lambda: haptic_env.make(env_config.replace(max_grasps=12))  # noqa: E731
    recs = evaluate_agents([RandomAgent(), GreedyInfoGainAgent(n_candidates=8)], make, 2, seeds=[0, 1],
                           progress=False)
    assert len(recs) == 8
    for r in recs:
        assert 1 <= r.grasps <= 12
        assert r.decided == (r.certainty >= env_config.threshold)
    # both agents saw the same objects (same env seeds)
    objs = {a: [r.object for r in recs if r.agent == a] for a in ("random", "greedy")}
    assert objs["random"] == objs["greedy"]


def test_interrupted_evaluation_resumes_from_its_saved_blocks(env_config, tmp_path):
    """evaluate_agents(store=...) saves each finished (agent, seed) block; after an interruption the same call runs
    only the missing blocks and returns what an uninterrupted evaluation returns (greedy included: its candidates
    are seeded per block). An unreadable block is run again."""
    cfg = env_config.replace(max_grasps=8)
    made = []

    def make():
        if len(made) == 3:
            raise KeyboardInterrupt  # Ctrl-C when the fourth block starts
        made.append(1)
        return haptic_env.make(cfg)

    agents = lambda: [RandomAgent(), GreedyInfoGainAgent(n_candidates=4)]  # noqa: E731
    store, keys = tmp_path / ".partial", ["random-k", "greedy-k"]
    with pytest.raises(KeyboardInterrupt):
        evaluate_agents(agents(), make, 2, seeds=[0, 1], progress=False, store=store, keys=keys)
    assert sorted(p.name for p in store.iterdir()) == ["greedy-k-seed0.json", "random-k-seed0.json",
                                                       "random-k-seed1.json"]
    (store / "random-k-seed1.json").write_text("{not json")
    made.clear()
    with pytest.warns(RuntimeWarning, match="running them again"):
        resumed = evaluate_agents(agents(), make, 2, seeds=[0, 1], progress=False, store=store, keys=keys)
    assert len(made) == 2  # random seed 1 (unreadable) and greedy seed 1
    whole = evaluate_agents(agents(), lambda: haptic_env.make(cfg), 2, seeds=[0, 1], progress=False)
    assert resumed == whole
    with pytest.raises(ValueError, match="one key per agent"):
        evaluate_agents(agents(), make, 2, seeds=[0], progress=False, store=store, keys=["a"])


def test_agent_seed_gives_distinct_runs_on_the_same_episodes(env_config):
    """run_episodes: without agent_seed the agent's numbers follow the env seed (agents share them); with it,
    two agent seeds act differently on the same objects and poses, and one agent seed repeats exactly."""
    from agents.evaluate import run_episodes

    make = lambda: haptic_env.make(env_config.replace(max_grasps=12))  # noqa: E731
    runs = {a: run_episodes(RandomAgent(seed=a), make, 6, seed=3, agent_seed=a) for a in (0, 1)}
    again = run_episodes(RandomAgent(seed=1), make, 6, seed=3, agent_seed=1)
    plain = [run_episodes(RandomAgent(seed=a), make, 6, seed=3) for a in (0, 1)]
    assert plain[0] == plain[1]  # the env seed alone seeds the agent: its own seed does not matter
    assert runs[1] == again
    # every episode's object (drawn by the env from the env seed alone), not only the first one's
    assert [r.object for r in runs[0]] == [r.object for r in runs[1]] == [r.object for r in plain[0]]
    assert [(r.grasps, r.ret) for r in runs[0]] != [(r.grasps, r.ret) for r in runs[1]]


def test_agent_numbers_are_apart_from_the_env_seeds_stream():
    """An agent's random numbers under env seed s are not the env's own (gymnasium's SeedSequence(s)): a random
    agent seeded with s itself drew, in its first action, the very numbers the env drew the object and its yaw with
    (its elevation a function of the yaw). Neither do they coincide with another env seed's stream, an agent seed's,
    or the approaches of a hand pool of that seed (which the old stream did for the pool's first object)."""
    from gymnasium.utils import seeding

    from agents.evaluate import agent_seed_for
    from haptic_env.hand_grasps import pool_actions

    for s in range(20):
        env_rng, _ = seeding.np_random(s)
        env_draws = env_rng.random(8)
        own = agent_seed_for(s)
        assert own not in range(20)
        assert not np.isin(np.random.default_rng(own).random(8), env_draws).any()
        assert own != agent_seed_for(s, 0) and own != agent_seed_for(s, 1)
        assert np.isin(np.random.default_rng(s).random(8), env_draws).all()  # the coupling this replaced
        assert agent_seed_for(s, stream="env") == s  # the committed runs' seeding, to repeat them
        # nor a hand pool's approaches (object 0's stream SeedSequence([s, 0]) is SeedSequence(s), the env's)
        pool = pool_actions(s, 0, 3)
        assert not np.isin(np.random.default_rng(own).uniform(-1, 1, (3, 4)), pool).any()
        np.testing.assert_array_equal(np.random.default_rng(s).uniform(-1, 1, (3, 4)), pool)  # the old stream's
        assert agent_seed_for(s, 3, stream="env") == agent_seed_for(s, 3)  # an agent seed: the same either way
    assert len({agent_seed_for(s) for s in range(1000)}) == 1000
    with pytest.raises(ValueError, match=r"agent stream must be one of \('apart', 'env'\), got 'own'"):
        agent_seed_for(0, stream="own")


def test_evaluate_agents_repeats_the_env_stream_runs_on_request(env_config):
    """``agent_stream="env"`` plays what an agent seeded with the env seed itself plays (every evaluate run before
    the fix of 2026-12-07); the default plays other random approaches on the same objects; a bad stream fails before any
    episode."""
    from agents.evaluate import evaluate_agents, run_episodes

    make = lambda: haptic_env.make(env_config.replace(max_grasps=12))  # noqa: E731
    legacy = evaluate_agents([RandomAgent()], make, 4, seeds=[5], progress=False, agent_stream="env")

    class Seeded(RandomAgent):  # seeds itself with the env seed whatever run_episodes passes
        def reset(self, env, seed=None):
            super().reset(env, None if seed is None else 5)

    assert legacy == run_episodes(Seeded(), make, 4, seed=5)
    apart = evaluate_agents([RandomAgent()], make, 4, seeds=[5], progress=False)
    assert [r.object for r in apart] == [r.object for r in legacy]
    assert [(r.grasps, r.ret) for r in apart] != [(r.grasps, r.ret) for r in legacy]
    with pytest.raises(ValueError, match="agent stream"):
        evaluate_agents([RandomAgent()], lambda: pytest.fail("built an env"), 1, seeds=[0], progress=False,
                        agent_stream="both")


def test_greedy_prediction_matches_the_updater(env_config):
    """Belief.predict (what greedy scores candidates with) equals really updating a copy of the belief."""
    env = haptic_env.make(env_config)
    env.reset(seed=0)
    base = env.unwrapped
    rng = np.random.default_rng(0)
    Q = []
    while len(Q) < 3:  # a few scored grasp vectors of this object
        _, _, term, trunc, info = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        if info["usable"]:  # complete grasp: the observed grasp vector is the scored one
            Q.append(base.task.last_q.copy())
        if term or trunc:
            env.reset()
    Q = np.stack(Q)
    belief = base.belief_state
    before = belief.probs.copy()
    pred = belief.predict([q[None] for q in Q])
    for q, p in zip(Q, pred):
        u = copy.deepcopy(belief)  # reference: really update a copy
        np.testing.assert_allclose(p, u.update_rows(q), rtol=1e-12, atol=1e-15)
    assert np.all(entropy(pred) >= 0)
    # several rows per grasp (z-subset scoring): rows 0-1 are one grasp, row 2 another
    pred = belief.predict([Q[:2], Q[2:]])
    np.testing.assert_allclose(pred[0], copy.deepcopy(belief).update_rows(Q[:2]), rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(belief.probs, before)
    # a non-Bayesian updater (IC) goes through copies of its state; the original is untouched
    ic = Belief(get_recognizer(base.objects, base.config.replace(updater="ic")), "ic")  # the env built the KDE only
    ic.update_rows(Q[0])
    before = ic.probs.copy()
    pred = ic.predict([q[None] for q in Q[1:]])
    np.testing.assert_allclose(pred[0], copy.deepcopy(ic).update_rows(Q[1]), rtol=1e-12)
    np.testing.assert_array_equal(ic.probs, before)


def test_greedy_picks_the_lowest_expected_entropy(env_config):
    env = haptic_env.make(env_config)
    obs, _ = env.reset(seed=5)
    agent = GreedyInfoGainAgent(n_candidates=12, seed=0)
    agent.reset(env, seed=0)
    a = agent.act(obs, env)
    assert a.shape == env.action_space.shape and env.action_space.contains(a)
    assert agent.last_scores.shape == (12,)
    assert np.all(agent.last_scores <= entropy(env.unwrapped.belief) + 1e-9)
    # the candidates, drawn again from the agent's seed (a known pose draws nothing else): the action is the one with
    # the lowest expected entropy, and the scores differ, so the choice is not a tie broken by position
    space = env.action_space
    cands = np.random.default_rng(0).uniform(space.low, space.high, size=(12,) + space.shape)
    assert np.ptp(agent.last_scores) > 0
    np.testing.assert_array_equal(a, cands[np.argmin(agent.last_scores)].astype(space.dtype))


def test_greedy_builds_its_backends_again_for_another_env_even_at_a_reused_id(env_config):
    """The look-ahead's backends belong to the env they were built for: a new env (which may get the id of one that
    was freed) gets its own, not a stale one."""
    env = haptic_env.make(env_config)
    env.reset(seed=5)
    agent = GreedyInfoGainAgent(n_candidates=4, seed=0)
    agent.reset(env, seed=0)
    first = agent._sim_backends(env.unwrapped)
    assert agent._built_for(env.unwrapped) and agent._sim_backends(env.unwrapped) is first  # kept for that env
    other = haptic_env.make(env_config)
    other.reset(seed=6)
    assert not agent._built_for(other.unwrapped)
    agent.act(other.reset(seed=6)[0], other)
    assert agent._built_for(other.unwrapped) and agent._sim_backends(other.unwrapped) is not first
    base = other.unwrapped
    del other, base  # freed: the agent does not keep it alive, nor take a later env at its id for it
    import gc

    gc.collect()
    assert agent._env_ref() is None and not agent._built_for(env.unwrapped)


def test_greedy_env_lookahead_simulates_the_envs_own_backend(env_config):
    """simulate="env": on the geometric env it is the default look-ahead (same actions); on a MuJoCo hand config its
    hypotheses are grasped by MuJoCo backends of that hand; "-blind" hides the pose. Bad settings fail at
    construction, naming the value."""
    from types import SimpleNamespace

    from agents.evaluate import make_agent
    from haptic_env.env import HapticRecogConfig
    from haptic_env.grasping.mujoco_backend import MujocoBackend

    env = haptic_env.make(env_config)
    obs, _ = env.reset(seed=5)
    acts = []
    for agent in (GreedyInfoGainAgent(n_candidates=8, seed=0), make_agent("greedy-env:8", seed=0)):
        agent.reset(env, seed=0)
        acts.append(agent.act(obs, env))
    np.testing.assert_array_equal(acts[0], acts[1])
    assert make_agent("greedy-env:8").name == "greedy-env:8" and make_agent("greedy").name == "greedy"
    # -blind: the hypotheses are placed at a pose of the agent's own draw, not the env's
    seen, blind = make_agent("greedy:8", seed=0), make_agent("greedy-blind:8", seed=0)
    for agent in (seen, blind):
        agent.reset(env, seed=0)
    assert not blind.pose_known and seen.pose_known
    np.testing.assert_array_equal(seen._backends[0]._T, env.unwrapped.pose)
    assert not np.allclose(blind._backends[0]._T, env.unwrapped.pose)
    # blind with S = 3 poses per candidate: every active hypothesis is re-placed 3 times per step
    blind3 = make_agent("greedy-blind:5:3", seed=0)
    assert (blind3.n_candidates, blind3.n_samples) == (5, 3)
    blind3.reset(env, seed=0)
    a = blind3.act(obs, env)
    assert env.action_space.contains(a) and blind3.last_scores.shape == (5,)
    hand = SimpleNamespace(config=HapticRecogConfig(backend="mujoco", backend_kwargs={"hand": "generic"}),
                           objects=env.unwrapped.objects[:2])
    sims = GreedyInfoGainAgent(simulate="env")._sim_backends(hand)
    assert len(sims) == 2 and all(isinstance(b, MujocoBackend) for b in sims)
    # the default geometric look-ahead decodes an action as the hand env does: with its support (the elevation)
    floating = SimpleNamespace(config=HapticRecogConfig(backend="mujoco", pose="so3", backend_kwargs={
        "hand": "generic", "support": "floating"}), objects=env.unwrapped.objects[:2])
    sims = GreedyInfoGainAgent()._sim_backends(floating)
    assert [b.config.support for b in sims] == ["floating", "floating"]
    assert [b.config.support for b in GreedyInfoGainAgent()._sim_backends(hand)] == ["table", "table"]
    with pytest.raises(ValueError, match="'hand'"):
        GreedyInfoGainAgent(simulate="hand")
    with pytest.raises(ValueError, match="backend_kwargs"):
        GreedyInfoGainAgent(simulate="env", backend_kwargs={"n_rays": 4})
    with pytest.raises(ValueError, match=r"greedy-envy.*greedy\[-env\]\[-blind\]\[:M\[:S\]\] or greedy-env-infer"):
        make_agent("greedy-envy")
    with pytest.raises(ValueError, match="greedy-infer"):  # -infer needs the env's look-ahead
        make_agent("greedy-infer")


def _train_args(algo: str, steps: int, run, recognizer_kwargs: dict, hyperparams: dict) -> list[str]:
    """``train.py`` arguments of a tiny run (one dummy-vec env, 10-grasp episodes, small recogniser);
    the hyper-parameters come last so a test can replace them."""
    return ["--algo", algo, "--total-timesteps", str(steps), "--n-envs", "1", "--vec", "dummy",
            "--run-dir", str(run), "--checkpoint-freq", "128", "--env.max-grasps", "10",
            "--env-kwargs", json.dumps({"recognizer_kwargs": recognizer_kwargs}),
            "--hyperparams", json.dumps(hyperparams)]


def test_tiny_ppo_trains_saves_reloads_and_resumes(env_config, small_recognizer_kwargs, tmp_path, capsys):
    import train
    from agents.sb3 import SB3Agent, load_model

    run = tmp_path / "ppo"
    args = _train_args("ppo", 256, run, small_recognizer_kwargs, {"n_steps": 64, "batch_size": 32, "n_epochs": 2})
    path = train.main(args)
    assert path.exists() and (run / "args.json").exists()
    assert sorted(p.name for p in (run / "checkpoints").glob("*.zip")) == ["ppo_128_steps.zip", "ppo_256_steps.zip"]
    assert list((run / "monitor").glob("*.monitor.csv")) and list((run / "tb").rglob("events.out.tfevents*"))

    model = load_model(path)
    agent = SB3Agent(model)
    env = haptic_env.make(env_config.replace(max_grasps=10))
    obs, _ = env.reset(seed=0)
    a1, a2 = agent.act(obs, env), SB3Agent.from_path(path).act(obs, env)
    np.testing.assert_array_equal(a1, a2)
    from agents.evaluate import make_agent

    sampled = make_agent(f"ppo={path}", stochastic=True)  # evaluate --stochastic
    assert sampled.name == "ppo-stochastic" and not sampled.deterministic
    sampled.reset(env, seed=0)
    s1 = sampled.act(obs, env)
    sampled.reset(env, seed=0)
    np.testing.assert_array_equal(s1, sampled.act(obs, env))  # seeded: repeatable
    assert not np.array_equal(s1, a1)  # a sample, not the mean action
    with pytest.raises(ValueError, match=r"no_repeat .* needs a categorical policy .*'ppo-norepeat' has an action"):
        make_agent(f"ppo={path}", no_repeat=True)  # evaluate --no-repeat with a Gaussian policy
    # a model whose name starts as a baseline's is a model (it was refused as an unknown greedy spec)
    named = make_agent(f"greedy-ft={path}")
    assert named.name == "greedy-ft" and isinstance(named, SB3Agent)
    np.testing.assert_array_equal(named.act(obs, env), a1)

    capsys.readouterr()
    path2 = train.main(args[:-2] + ["--resume", str(run / "checkpoints" / "ppo_128_steps.zip"),
                                    "--total-timesteps", "256", "--run-dir", str(tmp_path / "resumed"),
                                    "--hyperparams", json.dumps({"n_steps": 64, "batch_size": 32})])
    assert load_model(path2).num_timesteps >= 256
    assert "256 steps (128 in this run)" in capsys.readouterr().out  # went on from step 128, not from 0

    curves = plot_learning_curves({"ppo": run}, tmp_path / "lc.png", window=5)
    assert curves.stat().st_size > 0


def test_tiny_sac_trains_and_acts_in_bounds(env_config, small_recognizer_kwargs, tmp_path):
    import train
    from agents.sb3 import SB3Agent, load_model

    run = tmp_path / "sac"
    args = _train_args("sac", 128, run, small_recognizer_kwargs, {"learning_starts": 32, "batch_size": 32,
                                                                 "buffer_size": 1000})
    path = train.main(args)
    model = load_model(path)
    assert type(model).__name__ == "SAC" and model.num_timesteps >= 128
    env = haptic_env.make(env_config.replace(max_grasps=10))
    obs, _ = env.reset(seed=0)
    a = SB3Agent(model).act(obs, env)
    assert a.shape == env.action_space.shape and env.action_space.contains(a.astype(np.float32))


def test_tiny_recurrent_ppo_trains_resumes_and_remembers_within_an_episode(env_config, small_recognizer_kwargs,
                                                                          tmp_path, capsys):
    """``--algo rppo`` (sb3-contrib's RecurrentPPO): trains, checkpoints and resumes like PPO; as an agent it carries
    its LSTM state from step to step of an episode and starts every episode from a cleared state."""
    import train
    from agents.evaluate import make_agent, run_episodes
    from agents.sb3 import SB3Agent, latest_checkpoint, load_model

    run = tmp_path / "rppo"
    hp = {"n_steps": 64, "batch_size": 32, "n_epochs": 2}
    path = train.main(_train_args("rppo", 128, run, small_recognizer_kwargs, hp))
    assert path.name == "rppo_final.zip" and latest_checkpoint(run).name == "rppo_128_steps.zip"
    model = load_model(path)  # the algorithm from the file name
    assert type(model).__name__ == "RecurrentPPO" and model.num_timesteps == 128

    agent = make_agent(f"rppo={path}")
    assert isinstance(agent, SB3Agent) and agent.recurrent and agent.deterministic
    env = haptic_env.make(env_config.replace(max_grasps=10))
    obs, _ = env.reset(seed=0)
    agent.reset(env, seed=0)
    first = agent.act(obs, env)
    again = agent.act(obs, env)  # the same observation, but the memory has the first step now
    assert not np.array_equal(first, again) and env.action_space.contains(first)
    agent.reset(env)
    np.testing.assert_array_equal(agent.act(obs, env), first)  # a new episode: the state is cleared
    a, b = (run_episodes(make_agent(f"rppo={path}"), lambda: haptic_env.make(env_config.replace(max_grasps=10)),
                         3, seed=1) for _ in range(2))
    assert [(r.grasps, r.predicted) for r in a] == [(r.grasps, r.predicted) for r in b]

    capsys.readouterr()
    resumed = train.main(_train_args("rppo", 256, tmp_path / "resumed", small_recognizer_kwargs, hp)
                         + ["--resume", str(run / "checkpoints" / "rppo_128_steps.zip")])
    assert type(load_model(resumed)).__name__ == "RecurrentPPO" and load_model(resumed).num_timesteps == 256
    assert "256 steps (128 in this run)" in capsys.readouterr().out  # went on from step 128, not from 0


def test_discrete_approaches_train_a_categorical_ppo_that_acts_with_the_tables_rows(env_config,
                                                                                      small_recognizer_kwargs,
                                                                                      tmp_path, usage_error):
    """``--discrete-approaches N``: each training env takes one of N fixed approaches (the first N Halton points of
    the action box, a table that depends on N alone); PPO's policy is categorical, and as an agent it acts on the
    continuous env with the row of its choice. SAC and the native vector env are refused at parse time."""
    import train
    from agents.evaluate import make_agent
    from agents.sb3 import DiscreteApproaches, SB3Agent, approach_table, build_model, load_model, make_vec_env

    t = approach_table(16)
    assert t.shape == (16, 4) and t.dtype == np.float32 and np.all(np.abs(t) < 1)
    np.testing.assert_array_equal(t, approach_table(64)[:16])  # a prefix: the table depends on n alone
    assert len(np.unique(t, axis=0)) == 16
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="n must be"):
            approach_table(bad)
    env = DiscreteApproaches(haptic_env.make(env_config.replace(max_grasps=10)), 16)
    env.reset(seed=0)
    env.step(3)
    np.testing.assert_array_equal(env.unwrapped.last_approach, t[3])
    for bad in (16, -1, 1.0, np.array([1, 2])):
        with pytest.raises(ValueError, match=r"action must be one approach index in \[0, 16\)"):
            env.action(bad)

    run = tmp_path / "ppo_discrete"
    args = _train_args("ppo", 128, run, small_recognizer_kwargs, {"n_steps": 64, "batch_size": 32, "n_epochs": 2})
    path = train.main(args + ["--discrete-approaches", "16"])
    model = load_model(path)
    assert model.action_space.n == 16 and json.loads((run / "args.json").read_text())["discrete_approaches"] == 16
    agent = make_agent(f"ppo={path}")
    assert isinstance(agent, SB3Agent)
    plain = haptic_env.make(env_config.replace(max_grasps=10))
    obs, _ = plain.reset(seed=0)
    a = agent.act(obs, plain)
    i = int(model.predict(obs, deterministic=True)[0])
    np.testing.assert_array_equal(a, t[i])
    assert plain.action_space.contains(a)
    plain.step(a)
    import torch as th

    fresh = make_agent(f"ppo={path}", no_repeat=True)  # a real policy's probabilities, on the real observation
    assert fresh.name == "ppo-norepeat" and fresh.no_repeat
    obs, _ = plain.reset(seed=0)
    for _ in range(12):  # at each new belief, with nothing tried there: exactly SB3's deterministic choice
        fresh.reset(plain)
        own = int(model.predict(obs, deterministic=True)[0])
        np.testing.assert_array_equal(fresh.act(obs, plain), t[own])
        with th.no_grad():
            probs = model.policy.get_distribution(model.policy.obs_to_tensor(obs)[0]).distribution.probs[0].numpy()
        second = int(np.argsort(-probs, kind="stable")[1])
        np.testing.assert_array_equal(fresh.act(obs, plain), t[second])  # the same belief again: its runner-up
        obs, _, term, trunc, _ = plain.step(t[own])
        if term or trunc:
            obs, _ = plain.reset()
    checkpoint = str(run / "checkpoints" / "ppo_128_steps.zip")
    usage_error(train.parse_args, args + ["--resume", checkpoint],  # resumed without its N: refused, naming both
                match="--discrete-approaches: .*ppo_128_steps.zip was trained with --discrete-approaches 16, got 0")
    assert train.parse_args(args + ["--discrete-approaches", "16", "--resume", checkpoint]).discrete_approaches == 16
    venv = make_vec_env(env_config.replace(max_grasps=10), n_envs=1, vec="dummy", discrete_approaches=4)
    try:
        with pytest.raises(ValueError, match=r"sac's policy takes a continuous action, got the env's Discrete\(4\)"):
            build_model("sac", venv)
    finally:
        venv.close()
    usage_error(train.parse_args, ["--algo", "sac", "--discrete-approaches", "8"],
                match="--discrete-approaches: sac's policy takes a continuous action only")
    usage_error(train.parse_args, ["--vec", "native", "--discrete-approaches", "8"],
                match="--discrete-approaches: wraps each env")
    usage_error(train.parse_args, ["--discrete-approaches", "-1"], match="--discrete-approaches: must be >= 0")


def test_sb3_agent_maps_a_recurrent_or_sampled_categorical_choice_to_its_approach():
    """SB3's predict gives a categorical choice as a 0-d array (PPO) or a (1,) batch (recurrent PPO), sampled or not:
    the agent plays that row of the approach table either way."""
    from types import SimpleNamespace

    import gymnasium as gym

    from agents.sb3 import SB3Agent, approach_table

    class Stub:
        action_space = gym.spaces.Discrete(8)

        def __init__(self, recurrent: bool):
            self.policy = SimpleNamespace(lstm_actor=None) if recurrent else SimpleNamespace()
            self.recurrent, self.calls = recurrent, []

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            self.calls.append(deterministic)
            return (np.array([5]), "state") if self.recurrent else (np.array(5), None)

    env4 = SimpleNamespace(action_space=gym.spaces.Box(-1, 1, (4,)))
    for recurrent in (False, True):
        for deterministic in (True, False):
            model = Stub(recurrent)
            agent = SB3Agent(model, deterministic=deterministic)
            assert agent.recurrent == recurrent
            np.testing.assert_array_equal(agent.act(np.zeros(3, np.float32), env4), approach_table(8)[5])
            assert model.calls == [deterministic]
    # the approaches take the dimension of the env's action, as DiscreteApproaches built them in training
    env5 = SimpleNamespace(action_space=gym.spaces.Box(-1, 1, (5,)))
    agent = SB3Agent(Stub(False))
    np.testing.assert_array_equal(agent.act(np.zeros(3, np.float32), env5), approach_table(8, 5)[5])
    np.testing.assert_array_equal(agent.act(np.zeros(3, np.float32), env4), approach_table(8)[5])
    with pytest.raises(ValueError, match=r"fixed approaches need an env with a continuous \(Box\) action, got Disc"):
        agent.act(np.zeros(3, np.float32), SimpleNamespace(action_space=gym.spaces.Discrete(8)))


def test_sb3_agent_no_repeat_moves_on_while_the_belief_stays():
    """``no_repeat``: at an unchanged belief the agent takes its most probable approach not yet tried there (sampled:
    never a tried one), whatever else of the observation changed; a new belief frees every approach again, and with
    every approach tried it takes its own choice. A Gaussian or a recurrent policy is refused, naming the model."""
    from types import SimpleNamespace

    import gymnasium as gym
    import torch as th

    from agents.sb3 import SB3Agent, approach_table

    probs = th.tensor([[0.05, 0.1, 0.05, 0.2, 0.1, 0.4, 0.05, 0.05]])
    policy = SimpleNamespace(obs_to_tensor=lambda o: (th.as_tensor(o)[None], True), set_training_mode=lambda mode: None,
                             get_distribution=lambda o: SimpleNamespace(distribution=SimpleNamespace(logits=probs.log())))
    model = SimpleNamespace(action_space=gym.spaces.Discrete(8), policy=policy)
    env = SimpleNamespace(unwrapped=SimpleNamespace(task=SimpleNamespace(obs_slices={"belief": slice(1, 3)})),
                          action_space=gym.spaces.Box(-1, 1, (4,)))
    table = approach_table(8)

    def obs(count, belief):  # [grasp count, belief (2)]
        return np.array([count, *belief], np.float32)

    agent = SB3Agent(model, no_repeat=True)
    rows = [agent.act(obs(k, (0.5, 0.5)), env) for k in range(3)]
    np.testing.assert_array_equal(rows, table[[5, 3, 1]])  # by probability, ties to the lower index
    np.testing.assert_array_equal(agent.act(obs(3, (0.6, 0.4)), env), table[5])  # a new belief: all free again
    for k in range(7):
        agent.act(obs(4 + k, (0.6, 0.4)), env)
    np.testing.assert_array_equal(agent.act(obs(11, (0.6, 0.4)), env), table[5])  # all 8 tried: its own choice
    agent.reset(None)
    np.testing.assert_array_equal(agent.act(obs(0, (0.6, 0.4)), env), table[5])  # an episode starts afresh
    sampled = SB3Agent(model, deterministic=False, no_repeat=True)
    th.manual_seed(0)
    chosen = [tuple(sampled.act(obs(k, (0.5, 0.5)), env)) for k in range(8)]
    assert len(set(chosen)) == 8  # eight draws at one belief: each approach once
    with pytest.raises(ValueError, match=r"no_repeat .* needs a categorical policy .*'gauss' has an action space Box"):
        SB3Agent(SimpleNamespace(action_space=gym.spaces.Box(-1, 1, (4,)), policy=policy), name="gauss", no_repeat=True)
    with pytest.raises(ValueError, match=r"no_repeat .* needs .*'lstm' has a recurrent policy"):
        SB3Agent(SimpleNamespace(action_space=gym.spaces.Discrete(8), policy=SimpleNamespace(lstm_actor=None)),
                 name="lstm", no_repeat=True)


def test_repeat_mask_bars_the_approaches_tried_while_the_belief_stays():
    """:class:`RepeatMask` (the mask ``mppo`` trains with): after a step that leaves the observation's belief as it
    was, the approach just taken is barred, and every one tried since; a changed belief or a reset frees them all;
    with all tried, all are allowed. It changes nothing the env returns. Only fixed approaches are accepted."""
    from types import SimpleNamespace

    import gymnasium as gym

    from agents.sb3 import RepeatMask, RepeatTracker

    class Stub(gym.Env):  # obs [grasp count, belief (2)]; the belief moves on actions 2 and 3 only
        observation_space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
        action_space = gym.spaces.Discrete(4)
        task = SimpleNamespace(obs_slices={"belief": slice(1, 3)})

        def reset(self, *, seed=None, options=None):
            self.k, self.b = 0, np.array([0.5, 0.5], np.float32)
            return np.array([0, *self.b], np.float32), {}

        def step(self, action):
            self.k += 1
            if action >= 2:
                self.b = np.array([self.b[0] + 0.1, self.b[1] - 0.1], np.float32)
            return np.array([self.k, *self.b], np.float32), -1.0, False, False, {"k": self.k}

    env = RepeatMask(Stub())
    env.reset()
    np.testing.assert_array_equal(env.action_masks(), [True] * 4)
    obs, reward, term, trunc, info = env.step(0)
    assert (reward, term, trunc, info) == (-1.0, False, False, {"k": 1}) and obs[0] == 1  # passed through
    np.testing.assert_array_equal(env.action_masks(), [False, True, True, True])
    env.step(np.array(1))
    np.testing.assert_array_equal(env.action_masks(), [False, False, True, True])
    env.step(2)  # the belief moved: everything free again, the approach just taken too
    np.testing.assert_array_equal(env.action_masks(), [True] * 4)
    for a in (0, 1):
        env.step(a)
    env.reset()
    np.testing.assert_array_equal(env.action_masks(), [True] * 4)
    tracker = RepeatTracker(3)
    tracker.see([0.5, 0.5])
    for i in range(3):
        tracker.add(i)
    np.testing.assert_array_equal(tracker.mask(), [True] * 3)  # all tried: the policy's own choice stands
    continuous = Stub()
    continuous.action_space = gym.spaces.Box(-1, 1, (4,), np.float32)
    with pytest.raises(ValueError, match=r"RepeatMask needs fixed approaches \(a Discrete action\), got Box"):
        RepeatMask(continuous)
    with pytest.raises(ValueError, match="n must be"):
        RepeatTracker(0)


def test_tiny_maskable_ppo_trains_with_the_repeat_mask_and_acts_with_it(env_config, small_recognizer_kwargs,
                                                                         tmp_path, usage_error):
    """``--algo mppo`` (sb3-contrib's MaskablePPO) over ``--discrete-approaches N``: trains and checkpoints like
    PPO, with each env's :class:`RepeatMask`; as an agent it always acts with that mask (``no_repeat`` whatever the
    flag), choosing what the model's own masked predict chooses. Without fixed approaches it is refused at parse
    time; train.py and agents.sb3 name the same algorithms."""
    import train
    from agents.evaluate import make_agent
    from agents.sb3 import (ALGOS, RepeatTracker, SB3Agent, approach_table, build_model, latest_checkpoint, load_model,
                            make_vec_env)

    assert train.ALGOS == ALGOS
    run = tmp_path / "mppo"
    args = _train_args("mppo", 128, run, small_recognizer_kwargs, {"n_steps": 64, "batch_size": 32, "n_epochs": 2})
    path = train.main(args + ["--discrete-approaches", "16"])
    assert path.name == "mppo_final.zip" and latest_checkpoint(run).name == "mppo_128_steps.zip"
    model = load_model(path)
    assert type(model).__name__ == "MaskablePPO" and model.action_space.n == 16
    agent = make_agent(f"m={path}")
    assert isinstance(agent, SB3Agent) and agent.masked and agent.no_repeat and agent.name == "m"
    assert make_agent(f"ppo={path}").masked  # the file's name, not the agent's, says which algorithm saved it
    t = approach_table(16)
    env = haptic_env.make(env_config.replace(max_grasps=10))
    tracker = RepeatTracker(16)
    obs, _ = env.reset(seed=0)
    agent.reset(env)
    belief = env.unwrapped.task.obs_slices["belief"]
    barred = 0
    for _ in range(15):
        tracker.see(obs[belief])
        barred += not tracker.mask().all()
        own = int(model.predict(obs, deterministic=True, action_masks=tracker.mask())[0])
        a = agent.act(obs, env)
        np.testing.assert_array_equal(a, t[own])
        tracker.add(own)
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            obs, _ = env.reset()
            agent.reset(env)
            tracker.clear()
    assert barred > 0  # some of these choices were made with approaches barred: the masked path is exercised
    usage_error(train.parse_args, ["--algo", "mppo"],
                match="--discrete-approaches: mppo masks fixed approaches: it needs discrete_approaches >= 1, got 0")
    venv = make_vec_env(env_config.replace(max_grasps=10), n_envs=1, vec="dummy")
    try:
        with pytest.raises(ValueError, match=r"mppo masks fixed approaches: it needs a Discrete action, got .*Box"):
            build_model("mppo", venv)
    finally:
        venv.close()


def test_train_env_flags_change_the_fields_a_variant_sets(small_recognizer_kwargs, usage_error):
    """``--env.*`` start from the ``--env-id`` variant's config and may change what the variant sets; the envs the
    run makes are that config (``haptic_env.make`` takes the variant's fields from a given config; before, gymnasium
    put the variant's values back over the flags, silently)."""
    import train
    from agents import sb3

    args = train.parse_args(["--env-id", "HapticRecogKIT-v0", "--env.grasp-cost", "0.03"])
    assert train.env_config(args).objects == "kit8" and train.env_config(args).grasp_cost == 0.03
    args = train.parse_args(["--env-id=HapticRecogKIT-v0", "--env.objects", "default", "--env.max-grasps", "3",
                             "--env-kwargs", json.dumps({"recognizer_kwargs": small_recognizer_kwargs})])
    config = train.env_config(args)
    assert config.objects == "default"  # the KIT variant's "kit8" changed by the flag: no shared data needed
    venv = sb3.make_vec_env(config, n_envs=1, vec="dummy", env_id="HapticRecogKIT-v0")
    try:
        assert venv.envs[0].unwrapped.config == config
    finally:
        venv.close()
    assert haptic_env.make(config, env_id="HapticRecogKIT-v0").unwrapped.config.objects == "default"
    assert haptic_env.variant_config("HapticRecogKIT-v0").objects == "kit8"
    with pytest.raises(ValueError, match="unknown env id"):
        haptic_env.variant_config("Nope-v0")
    usage_error(train.parse_args, ["--env-id", "Nope-v0"], match="--env-id: unknown env 'Nope-v0'")


@pytest.mark.parametrize("argv, match", [
    # each of these was taken, then failed after the run folder was written (or, for nan / inf, never stopped)
    (["--seed", str(2**32)], r"--seed: must be <= 4294967295, got 4294967296"),
    (["--max-minutes", "nan"], r"--max-minutes: must be >= 0.0, got nan"),
    (["--max-minutes", "inf"], r"--max-minutes: must be finite \(0: no limit\), got inf"),
    (["--run-dir", ""], r"--run-dir: must name a folder, got ''"),
    (["--hyperparams", '{"n_steps": 0}'], r"PPO hyperparameter n_steps must be an int >= 1, got 0"),
    (["--hyperparams", '{"batch_size": 1}'], r"PPO hyperparameter batch_size must be an int >= 2, got 1"),
    (["--hyperparams", '{"gamma": 1.5}'], r"PPO hyperparameter gamma must be a number in \[0, 1\], got 1.5"),
    (["--algo", "sac", "--hyperparams", '{"tau": 0}'], r"SAC hyperparameter tau must be a number in \(0, 1\]"),
    # these failed once the lock, args.json and the Monitor files were written
    (["--hyperparams", '{"policy_kwargs": {"nett_arch": [8]}}'],
     r"unknown ActorCriticPolicy policy_kwargs \['nett_arch'\]; valid: \['activation_fn'"),
    (["--hyperparams", '{"_init_setup_model": false}'], r"unknown PPO hyperparameter\(s\) \['_init_setup_model'\]"),
    (["--n-envs", "1", "--hyperparams", '{"n_steps": 1}'],
     r"PPO needs a rollout of more than one step, n_steps x n_envs > 1, got n_steps=1 with n_envs=1"),
    (["--algo", "sac", "--hyperparams", '{"policy_kwargs": 3}'],
     r"SAC hyperparameter policy_kwargs must be a table of SACPolicy's arguments, got 3"),
    (["--vec", "native", "--env.backend", "uniform"], r"--vec: the native vector env steps the backends "
                                                        r"\('geometric',\), got --env.backend 'uniform'"),
    (["--env-kwargs", '{"backend_kwargs": {"foo": 1}}'], r"invalid backend_kwargs for backend 'geometric'.*'foo'"),
])
def test_train_refuses_bad_values_before_its_run_folder(argv, match, usage_error, tmp_path):
    import train

    run = tmp_path / "run"
    usage_error(train.main, ["--run-dir", str(run), *argv] if "--run-dir" not in argv else argv, match=match)
    assert not run.exists()
    assert train.parse_args(["--algo", "sac", "--hyperparams", '{"ent_coef": "auto_0.1", "tau": 1}']).algo == "sac"
    # SB3 asserts a rollout of more than one step only to normalise its advantages
    assert train.parse_args(["--n-envs", "1", "--hyperparams", '{"n_steps": 1, "normalize_advantage": false}']).n_envs == 1


@pytest.mark.parametrize("argv, match", [
    (["--hyperparams", '{"gamma": "0.9"}'], r"PPO hyperparameter gamma must be a number in \[0, 1\], got '0.9'"),
    (["--hyperparams", '{"ent_coef": "auto"}'], r"PPO hyperparameter ent_coef must be a number >= 0, got 'auto'"),
    (["--algo", "sac", "--hyperparams", '{"learning_rate": "auto"}'], r"SAC hyperparameter learning_rate must be"),
    (["--algo", "sac", "--hyperparams", '{"ent_coef": "0.1"}'],
     r"SAC hyperparameter ent_coef must be a number >= 0 or 'auto' or 'auto_<initial value > 0>', got '0.1'"),
    (["--algo", "sac", "--hyperparams", '{"ent_coef": "auto_0"}'], r"SAC hyperparameter ent_coef .* got 'auto_0'"),
    (["--algo", "sac", "--hyperparams", '{"target_entropy": "auto_1"}'],
     r"SAC hyperparameter target_entropy must be a number \(any finite value\) or 'auto', got 'auto_1'"),
    # these too were taken, then failed in the first update (after the run's files were written)
    (["--hyperparams", '{"target_kl": "0.01"}'],
     r"PPO hyperparameter target_kl must be a number > 0 or null, got '0.01'"),
    (["--hyperparams", '{"target_kl": -1}'], r"PPO hyperparameter target_kl must be a number > 0 or null, got -1"),
    (["--algo", "sac", "--hyperparams", '{"target_update_interval": "1"}'],
     r"SAC hyperparameter target_update_interval must be an int >= 1, got '1'"),
    (["--algo", "sac", "--hyperparams", '{"train_freq": [2, "steps"]}'],
     r"SAC hyperparameter train_freq must be an int >= 1 or \[int >= 1, \"step\" \| \"episode\"\], got \[2, 'steps'\]"),
    (["--hyperparams", '{"normalize_advantage": "false"}'],
     r"PPO hyperparameter normalize_advantage must be true or false, got 'false'"),
    (["--algo", "sac", "--hyperparams", '{"action_noise": "normal"}'],
     r"SAC hyperparameter action_noise must be a Python object or class .*got 'normal'"),
    (["--hyperparams", '{"policy_kwargs": {"activation_fn": "tanh"}}'],
     r"PPO policy_kwargs activation_fn must be a torch.nn activation module class or its name .*got 'tanh'"),
    (["--hyperparams", '{"policy_kwargs": {"net_arch": [64, "a"]}}'],
     r"PPO policy_kwargs net_arch must be a list of layer widths >= 1 or a table of such lists"),
])
def test_train_refuses_a_number_given_as_a_string(argv, match, usage_error):
    """A string for a numeric hyperparameter was taken, then failed inside SB3 after the first rollout (the run's
    files written); only SAC's own strings ("auto" ent_coef / target_entropy) pass."""
    import train

    usage_error(train.parse_args, argv, match=match)
    for sac in ('{"ent_coef": "auto_0.1"}', '{"ent_coef": "auto", "target_entropy": "auto"}',
                '{"ent_coef": 0.1, "target_entropy": -3.5}', '{"train_freq": [2, "episode"], "gradient_steps": -1}'):
        assert train.parse_args(["--algo", "sac", "--hyperparams", sac]).algo == "sac"
    ppo = '{"target_kl": null, "policy_kwargs": {"activation_fn": "Tanh", "net_arch": {"pi": [8], "vf": [8]}}}'
    assert train.parse_args(["--hyperparams", ppo]).algo == "ppo"


def test_an_activation_named_in_json_builds_its_torch_class(env_config):
    import torch

    from agents import sb3

    venv = sb3.make_vec_env(env_config.replace(max_grasps=5), n_envs=1, vec="dummy")
    try:
        model = sb3.build_model("ppo", venv, n_steps=8, batch_size=8, policy_kwargs={"activation_fn": "Tanh"})
    finally:
        venv.close()
    assert model.policy.activation_fn is torch.nn.Tanh


def test_evaluate_writes_table_and_plots(env_config, tmp_path):
    make = lambda: haptic_env.make(env_config.replace(max_grasps=8))  # noqa: E731
    second = RandomAgent()
    second.name = "random2"
    recs = evaluate_agents([RandomAgent(), second], make, 3, seeds=[0, 1], progress=False)
    paths = write_report(recs, tmp_path / "eval", max_grasps=8)
    for p in paths.values():
        assert p.exists() and p.stat().st_size > 0
    md = paths["md"].read_text()
    assert "| random |" in md and "| random2 |" in md
    rows = summarize(recs)
    assert rows[0]["episodes"] == 6 and rows[0]["seeds"] == 2
    assert rows[1]["fewer_than_random"] == pytest.approx(0.0, abs=1e-12)  # identical agents
    lo, hi = rows[0]["grasps_mean_ci"]
    assert lo <= rows[0]["grasps_mean"] <= hi
    data = json.loads(paths["json"].read_text())
    assert len(data["success_vs_grasps"]["random"]) == 8
    assert "## RL aggregates (rliable)" in md and paths["profile"].stat().st_size > 1000
    agg = data["rliable"]["agents"]
    assert agg["random2"]["p_fewer_grasps"] == pytest.approx(0.5) and agg["random2"]["p_success"] == pytest.approx(0.5)
    assert "p_fewer_grasps" not in agg["random"]  # the baseline itself
    lo, hi = agg["random"]["grasps_iqm_ci"]
    assert lo <= agg["random"]["grasps_iqm"] <= hi
    assert len(agg["random"]["profile"]) == 8 and np.all(np.diff(agg["random"]["profile"]) >= 0)
    # the prediction at the stop is kept: correct means predicted == true, and the confusion matrix counts them
    assert all(r.predicted and (r.predicted == r.object) == r.correct for r in recs)
    assert paths["confusion"].stat().st_size > 1000
    with open(paths["csv"], newline="") as fh:
        assert [row["predicted"] for row in csv.DictReader(fh)] == [r.predicted for r in recs]


def test_confusion_and_errors_table():
    R = lambda agent, true, pred: EpisodeRecord(agent, 0, 0, true, 3, True, true == pred, 0.9, 0.0, pred)  # noqa: E731
    recs = [R("a", "box", "box"), R("a", "box", "can"), R("a", "box", "can"), R("a", "can", "can"),
            R("b", "can", "box"), R("b", "ball", "ball")]
    conf = confusion(recs)
    labels, M = conf["a"]
    assert labels == ["ball", "box", "can"]
    assert M.tolist() == [[0, 0, 0], [0, 1, 2], [0, 0, 1]]
    assert conf["b"][1].tolist() == [[1, 0, 0], [0, 0, 0], [0, 1, 0]]
    md = errors_markdown(conf)
    assert "| a | 2 of 4 | box -> can: 2 (67 %) |" in md and "| b | 1 of 2 | can -> box: 1 (100 %) |" in md
    # episodes written before predictions were kept: no confusion matrix rather than a wrong one
    assert confusion([*recs, EpisodeRecord("a", 0, 1, "box", 3, True, True, 0.9, 0.0)]) == {}


def test_rl_aggregates_on_known_episodes():
    from agents.evaluate import bootstrap_ci, rl_aggregates, score_matrix

    def rec(agent, seed, ep, grasps, correct):
        return EpisodeRecord(agent, seed, ep, "box", grasps, correct, correct, 0.9, 0.0)

    recs = [rec("random", s, e, 10, e % 2 == 0) for s in range(3) for e in range(8)]
    recs += [rec("fast", s, e, 2, True) for s in range(3) for e in range(8)]
    assert score_matrix(recs, "fast", lambda r: r.grasps).shape == (8, 3)  # (episodes, seeds)
    agg = rl_aggregates(recs, max_grasps=10, reps=200)["agents"]
    assert agg["fast"]["grasps_iqm"] == 2 and agg["fast"]["grasps_iqm_ci"] == (2, 2)
    assert agg["fast"]["p_fewer_grasps"] == 1.0  # every episode of fast beats every episode of random
    assert agg["fast"]["p_success"] == pytest.approx(0.75)  # P(1 > Y) + P(1 = Y) / 2 with P(Y = 1) = 0.5
    assert agg["random"]["success"] == pytest.approx(0.5) and agg["fast"]["profile"][1] == 1.0
    assert agg["random"]["profile"][8] == 0 and agg["random"]["profile"][9] == pytest.approx(0.5)
    lo, hi = bootstrap_ci(np.r_[np.zeros(50), np.ones(50)])
    assert 0.35 < lo < 0.5 < hi < 0.65


def test_rl_aggregates_are_reproducible_and_leave_the_global_rng_alone():
    """rliable resamples from NumPy's global RNG: the same episodes give the same CIs, and the caller's global
    state is what it was."""
    from agents.evaluate import rl_aggregates

    rng = np.random.default_rng(0)
    recs = [EpisodeRecord(a, s, e, "box", int(rng.integers(1, 9)), bool(rng.random() < 0.8), True, 0.9, 0.0)
            for a in ("random", "other") for s in range(3) for e in range(10)]
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    a, b = (rl_aggregates(recs, max_grasps=10, reps=100) for _ in range(2))
    assert np.array_equal(np.random.get_state()[1], before)
    assert a == b


def test_cli_evaluate_is_registered():
    from haptic_env.cli import build_parser

    args = build_parser().parse_args(["evaluate", "--agents", "random", "--episodes", "2", "--seeds", "0"])
    assert args.episodes == 2 and callable(args.func)


def test_make_vec_env_without_a_config_builds_the_registered_env(monkeypatch):
    """``make_vec_env(env_id=...)`` without a config makes that env's own config (``variant_config``), not the
    defaults with the id attached (which built the default objects for ``HapticRecogKIT-v0``)."""
    from agents import sb3

    seen = []

    def env_fn(config, rank, *args, **kwargs):
        seen.append(config)
        raise RuntimeError("stop before building")

    monkeypatch.setattr(sb3, "_env_fn", env_fn)
    with pytest.raises(RuntimeError, match="stop before building"):
        sb3.make_vec_env(None, n_envs=1, vec="dummy", env_id="HapticRecogKIT-v0")
    assert seen[0] == haptic_env.variant_config("HapticRecogKIT-v0") and seen[0].objects == "kit8"


def test_make_vec_env_closes_a_probe_it_could_not_take_over(env_config):
    """A ``probe`` env handed to ``make_vec_env`` is closed when the vec env cannot be built (nothing took it over)."""
    from agents import sb3

    env = haptic_env.make(env_config)
    closed = []
    close = env.close
    env.close = lambda: (closed.append(True), close())
    with pytest.raises(ValueError, match="vec must be"):
        sb3.make_vec_env(env_config, n_envs=2, vec="bogus", probe=env)
    assert closed == [True]


def test_make_vec_env_subproc_with_one_env_takes_the_probe_over(env_config, monkeypatch):
    """``vec="subproc"`` with one env runs it in this process: a ``probe`` is that env, not closed and built again
    (``train.py --vec subproc --n-envs 1 --resume`` built its env twice)."""
    from agents import sb3

    env = haptic_env.make(env_config.replace(max_grasps=4))
    built = []
    make = haptic_env.make
    monkeypatch.setattr(haptic_env, "make", lambda *a, **k: (built.append(a), make(*a, **k))[1])
    venv = sb3.make_vec_env(env_config.replace(max_grasps=4), n_envs=1, vec="subproc", probe=env)
    try:
        assert built == [] and venv.envs[0].unwrapped is env.unwrapped
        venv.reset()
    finally:
        sb3.close_vec_env(venv)


def test_training_envs_are_seeded_apart_from_the_evaluation_seeds():
    """train.py's envs start at 10000 + 1000 * seed by default (no training env replays the episodes of a test
    seed 0-4, a validation seed 500-504 or a sweep seed 1000-1002); --env-seed gives the earlier seed + rank."""
    import train

    assert [train.env_seed(train.parse_args(["--seed", str(s)])) for s in (0, 1, 2)] == [10_000, 11_000, 12_000]
    assert train.env_seed(train.parse_args(["--seed", "2", "--env-seed", "2"])) == 2


def test_a_run_whose_envs_would_leave_its_block_of_training_env_seeds_is_refused(tmp_path, usage_error):
    """Each --seed has 1,000 default training env seeds; nothing bounded --n-envs x segments, so a wide or long run
    took the next --seed's env seeds (its episodes). Refused before any file; --env-seed is the caller's own."""
    import dataclasses

    import train

    usage_error(train.parse_args, ["--n-envs", "1001"],
                match=r"--n-envs: this segment's envs would have seeds 10000\.\.11000, past the 1000 training env "
                      r"seeds of --seed 0 \(up to 10999")
    assert train.parse_args(["--n-envs", "1000"]).n_envs == 1000
    assert train.parse_args(["--n-envs", "1001", "--env-seed", "5"]).n_envs == 1001
    run = tmp_path / "run"  # a run whose first segment had 600 envs: a resume with 600 more would pass 11999
    (run / "checkpoints").mkdir(parents=True)
    (run / "args.json").write_text(json.dumps({"first_env_seed": 11000, "n_envs": 600, "seed": 1}))
    resume = str(run / "checkpoints" / "ppo_64_steps.zip")
    args = dataclasses.replace(train.parse_args(["--seed", "1", "--n-envs", "600", "--run-dir", str(run)]),
                               resume=resume)
    usage_error(train._check_env_seed_block, args, match=r"seeds 11600\.\.12199, past the 1000 training env seeds "
                                                         r"of --seed 1 \(up to 11999")
    train._check_env_seed_block(dataclasses.replace(args, n_envs=400))
    assert sorted(p.name for p in run.iterdir()) == ["args.json", "checkpoints"]


def test_two_agents_of_one_name_are_refused_not_pooled(env_config):
    make = lambda: haptic_env.make(env_config.replace(max_grasps=4))  # noqa: E731
    with pytest.raises(ValueError, match=r"agents must have distinct names, got \['random'\] more than once"):
        evaluate_agents([RandomAgent(), RandomAgent()], make, 1, seeds=[0], progress=False)


def test_evaluate_refuses_two_agents_of_one_name_before_any_episode(tmp_path, usage_error, monkeypatch):
    import agents.evaluate as ev
    from haptic_env.cli import main

    def must_not_run(*a, **k):
        raise AssertionError("episodes ran before the names were checked")

    monkeypatch.setattr(ev, "evaluate_agents", must_not_run)
    usage_error(main, ["evaluate", "--agents", "random", "random", "--episodes", "1", "--seeds", "0",
                       "--out", str(tmp_path / "e")], match=r"--agents: \['random'\] named more than once")


def test_evaluate_refuses_a_seed_given_twice(tmp_path, usage_error, env_config):
    """A seed given twice would count its episodes twice (twice the evidence, narrower intervals): refused by the
    command before any episode, and by ``evaluate_agents``."""
    from haptic_env.cli import main

    usage_error(main, ["evaluate", "--agents", "random", "--episodes", "1", "--seeds", "0", "0",
                       "--out", str(tmp_path / "e")], match=r"--seeds: each seed once, got \[0, 0\]")
    make = lambda: haptic_env.make(env_config.replace(max_grasps=4))  # noqa: E731
    with pytest.raises(ValueError, match=r"seeds must be distinct, got \[3, 3\]"):
        evaluate_agents([RandomAgent()], make, 1, seeds=[3, 3], progress=False)


def test_the_resumed_note_counts_only_the_blocks_read_back(tmp_path, small_recognizer_kwargs, monkeypatch):
    """The report's "resumed" note counts the saved blocks the run read back, not a damaged one it ran again."""
    import json
    import shlex

    import agents.evaluate as ev
    from haptic_env.cli import main

    out = tmp_path / "e"
    argv = ["evaluate", "--agents", "random", "--episodes", "1", "--seeds", "0", "1", "--out", str(out),
            "--env-kwargs", json.dumps({"recognizer_kwargs": small_recognizer_kwargs, "max_grasps": 4})]
    real = ev.write_report

    def interrupted(*a, **k):  # every block saved, then the run stops before its report
        raise KeyboardInterrupt

    monkeypatch.setattr(ev, "write_report", interrupted)
    main(argv)
    monkeypatch.setattr(ev, "write_report", real)
    blocks = sorted((out / ".partial").glob("*.json"))
    assert len(blocks) == 2
    blocks[0].write_text("not json")
    (out / "learning_curves.png").write_bytes(b"an earlier run's")
    with pytest.warns(RuntimeWarning, match="running them again"):
        assert main(argv) == 0
    text = (out / "results.md").read_text()
    assert "resumed: 1 of 2 agent-seed blocks" in text
    # the report's command reruns it: JSON overrides (it gave a Python repr), every setting; no stale curves beside it
    command = text.split("`")[1]
    assert shlex.split(command)[:2] == ["haptic-recog", "evaluate"] and argv[-1] in command
    from haptic_env.cli import build_parser

    assert build_parser().parse_args(shlex.split(command)[1:]).env_kwargs == json.loads(argv[-1])
    assert not (out / "learning_curves.png").exists()


def test_the_ratio_interval_is_not_a_crash_when_one_side_has_one_episode():
    """``_ratio_ci`` with one episode on one side and several varied ones on the other: the ratio, and no interval
    (the bootstrap needs two per sample), instead of scipy's error."""
    from agents.evaluate import _ratio_ci

    value, lo, hi = _ratio_ci([2.0], [3.0, 4.0, 5.0, 3.0])
    assert value == pytest.approx(1 - 2.0 / 3.75) and np.isnan(lo) and np.isnan(hi)


def test_success_rates_carry_wilson_intervals_and_the_decided_and_correct_share():
    from agents.evaluate import markdown_table, proportion_ci

    def rec(agent, i, grasps, decided):  # every prediction at the stop right
        return EpisodeRecord(agent=agent, seed=0, episode=i, object="a", grasps=grasps, decided=decided,
                             correct=True, certainty=0.9 if decided else 0.5, ret=0.0, predicted="a")

    recs = [rec("random", i, 3, True) for i in range(40)]
    recs += [rec("slow", i, 30, False) for i in range(20)] + [rec("slow", 20 + i, 2, True) for i in range(20)]
    rows = {r["agent"]: r for r in summarize(recs)}
    # 40 of 40: a bootstrap interval has no width there, Wilson's does
    assert rows["random"]["success"] == 1.0 and rows["random"]["success_ci"] == pytest.approx((0.91238, 1.0), abs=1e-5)
    assert np.isnan(proportion_ci(0, 0)).all()  # nan for no episodes
    # right at the stop but undecided counts for "success", not for "decided and correct"
    assert rows["slow"]["success"] == 1.0 and rows["slow"]["decided"] == 0.5 and rows["slow"]["decided_correct"] == 0.5
    lo, hi = rows["slow"]["decided_correct_ci"]
    assert lo < 0.5 < hi
    table = markdown_table(list(rows.values()))
    assert "| decided and correct [95% CI] |" in table and "| 50.0% [35.2, 64.8] |" in table


def test_evaluate_blocks_are_keyed_by_the_code_that_played_them(tmp_path, monkeypatch):
    """A resumed ``evaluate`` reuses a saved block only if the same code played it: the block keys hash
    ``code_fingerprint()`` (the sources of haptic_env and agents) with the command's arguments."""
    import agents.evaluate as ev
    from haptic_env.cli import main

    fp = ev.code_fingerprint()
    assert re.fullmatch(r"[0-9a-f]{64}", fp) and ev.code_fingerprint() == fp
    seen = []

    class Stop(Exception):
        pass

    def capture(agents, make_env, n, seeds, progress=True, store=None, keys=None, agent_stream="apart"):
        seen.append(list(keys))
        raise Stop

    monkeypatch.setattr(ev, "evaluate_agents", capture)
    argv = ["evaluate", "--agents", "random", "--episodes", "1", "--seeds", "0", "--out", str(tmp_path / "e")]
    for code in ("A", "A", "B"):
        monkeypatch.setattr(ev, "code_fingerprint", lambda code=code: code)
        with pytest.raises(Stop):
            main(argv)
    assert seen[0] == seen[1] != seen[2]
    # what the agents do is part of the key: blocks never mix
    for flag in (["--no-repeat"], ["--stochastic"], ["--agent-stream", "env"]):
        with pytest.raises(Stop):
            main(argv + flag)
    with pytest.raises(Stop):  # the default stream named: the same key as unnamed
        main(argv + ["--agent-stream", "apart"])
    assert len({tuple(k) for k in seen[2:]}) == 4 and seen[-1] == seen[2]


def test_greedy_infer_pose_scores_the_episodes_grasps_for_the_yaw(env_config, small_recognizer_kwargs):
    """greedy-env-infer: the look-ahead's poses are drawn from each hypothesis's yaw posterior, which sums the
    replay likelihood of every grasp of the episode so far (one per step) and starts again at a reset. It needs
    a hand env's upright poses; bad settings fail at construction or reset, naming what is wrong."""
    from agents.evaluate import make_agent
    from haptic_env.env import HapticRecogConfig, HapticRecogEnv
    from haptic_env.grasping.replay import yaw_log_likelihood

    agent = make_agent("greedy-env-infer:4:2", seed=0)
    assert agent.infer_pose and not agent.pose_known and (agent.n_candidates, agent.n_samples) == (4, 2)
    with pytest.raises(ValueError, match="infer_pose=True draws the poses the look-ahead does not know"):
        GreedyInfoGainAgent(infer_pose=True)
    with pytest.raises(ValueError, match="yaw_bins must be"):
        GreedyInfoGainAgent(pose_known=False, infer_pose=True, yaw_bins=2)
    geometric = haptic_env.make(env_config)
    geometric.reset(seed=0)
    with pytest.raises(ValueError, match="infer_pose .* needs a hand backend .* backend='geometric'"):
        GreedyInfoGainAgent(pose_known=False, infer_pose=True).reset(geometric)
    cfg = HapticRecogConfig(backend="replay", backend_kwargs={"hand": "generic", "approaches": 40, "progress": False},
                            recognizer_source="surface", recognizer_kwargs=small_recognizer_kwargs, max_grasps=3,
                            threshold=0.999)
    env = HapticRecogEnv(cfg)
    try:
        obs, _ = env.reset(seed=3)
        agent = GreedyInfoGainAgent(n_candidates=3, n_samples=2, seed=0, simulate="env", pose_known=False,
                                    infer_pose=True, yaw_bins=24)
        agent.reset(env, seed=0)
        yb = agent.yaw_belief
        records = yb.records
        assert len(records) == len(env.objects) and len(records[0][1]) == 40  # the env's own 40 records
        expected = np.zeros((len(env.objects), 24))
        for step in range(2):
            a = agent.act(obs, env)
            assert yb.grasps == step
            np.testing.assert_allclose([yb.log_likelihood(k) for k in range(len(records))], expected)
            obs, *_ = env.step(a)
            g = env.last_grasp
            np.testing.assert_array_equal(env.last_approach, env.task.last_action)  # the world frame: as given
            expected += [yaw_log_likelihood(r, env.last_approach, g.contacts, np.asarray(g.touched, dtype=bool),
                                            yb.yaws) for r in records]
        agent.act(obs, env)
        assert yb.grasps == 2
        np.testing.assert_allclose([yb.log_likelihood(k) for k in range(len(records))], expected)
        T = agent._pose_sample(env, 0)  # a turn about the vertical, no translation
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
        assert T[2, 2] == 1.0 and not T[:3, 3].any()
        obs, _ = env.reset(seed=4)  # a new episode: its grasps count from zero
        agent.reset(env)
        agent.act(obs, env)
        assert agent.yaw_belief is yb and yb.grasps == 0 and not yb.log_likelihood(0).any()
        for _ in range(2):  # two grasps the agent did not see: it cannot score the first any more
            obs, *_ = env.step(env.action_space.sample())
        with pytest.raises(RuntimeError, match="the env has made 2 grasps and the agent saw 0"):
            agent.act(obs, env)
        obs, _ = env.reset(seed=5)
        agent.reset(env)
        for _ in range(2):
            obs, *_ = env.step(agent.act(obs, env))
        agent.act(obs, env)
        assert yb.grasps == 2
        obs, _ = env.reset(seed=6)  # a new episode the agent is not reset for: its count restarting is noticed
        obs, *_ = env.step(env.action_space.sample())
        agent.act(obs, env)
        assert yb.grasps == 1
    finally:
        env.close()
        geometric.close()


def test_a_deterministic_sb3_agent_leaves_the_global_generators_alone(env_config, tmp_path):
    """SB3Agent.reset(seed) seeded Python's, NumPy's and torch's global generators (SB3's set_random_seed): a
    deterministic policy draws nothing, so its resets now leave them as they were."""
    import random

    import torch

    from agents import sb3

    venv = sb3.make_vec_env(env_config.replace(max_grasps=5), n_envs=1, seed=10000, vec="dummy")
    model = sb3.build_model("ppo", venv, seed=0, n_steps=8, batch_size=8)
    venv.close()
    agent = sb3.SB3Agent(model)
    np.random.seed(123), random.seed(123), torch.manual_seed(123)
    before = (np.random.get_state()[1].copy(), random.getstate(), torch.random.get_rng_state().clone())
    agent.reset(None, seed=7)
    assert np.array_equal(np.random.get_state()[1], before[0]) and random.getstate() == before[1]
    assert torch.equal(torch.random.get_rng_state(), before[2])
