"""Input checks of the configs and the functions that take settings: a bad value is a ``ValueError`` naming the field
and the value, raised where it is given (never a bare ``TypeError``, never a silently cut or truthy-read value), and
every valid form (numpy scalars included) stays accepted with the same stored values, so the same cache keys.

Each bad case below is one that an earlier version accepted (``n_fingers=4.0``, ``normals="false"``,
``threshold=True``, ``cpus=-2``, ...) or refused with an error naming neither the field nor the value."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from haptic_env.cache import config_key
from haptic_env.config import HapticRecogConfig
from haptic_env.dataset import DatasetConfig
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.sweep.spec import SpecError, parse_spec


def _greedy(**kw):
    from agents.greedy import GreedyInfoGainAgent

    return GreedyInfoGainAgent(**kw)


def _sample_grasps(count=10, n_fingers=3):
    from haptic_env.dataset import sample_grasps

    return sample_grasps(None, count, n_fingers, np.random.default_rng(0))  # checked before the object is read


def _hand_dataset(min_rows):
    from haptic_env.dataset import hand_dataset

    return hand_dataset(None, None, min_rows=min_rows)


def _family_temperatures(grasps):
    from haptic_env.experiments.families import family_temperatures

    return family_temperatures(None, None, None, None, grasps=grasps)


def _family_floor(quantiles):
    from haptic_env.experiments.families import family_floor

    return family_floor(None, None, None, None, None, None, quantiles=quantiles, grasps=1, seed=0)


def _stop_scale(threshold=0.85, scales=(1.0,)):
    from haptic_env.experiments.stop_scale import fit_stop_scale

    return fit_stop_scale(None, None, threshold, scales=scales, rng=np.random.default_rng(0))


def _run_episodes(n):
    from agents.evaluate import run_episodes

    return run_episodes(None, None, n, 0)


def _evaluate_agents(n):
    from agents.evaluate import evaluate_agents

    return evaluate_agents([], None, n, [0], progress=False)


def _episode_seed(seed, agent_seed=None):
    from agents.evaluate import run_episodes

    return run_episodes(None, None, 1, seed, agent_seed=agent_seed)  # refused before the env is made


def _evaluate_seeds(seeds):
    from agents.evaluate import evaluate_agents

    return evaluate_agents([], None, 1, seeds, progress=False)  # refused before any episode


def _spec_cpus(table: str, cpus):
    tables = {"command": {"name": "a", "run": "true"}, "dataset": {"grasps_per_object": 10},
              "analysis": {"flags": {"experiments": "1"}}}
    return parse_spec({"name": "x", table: [{**tables[table], "cpus": cpus}]})


def _spec_eval_cpus(cpus):
    return parse_spec({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "random"}],
                       "evaluate": {"cpus": cpus}})


def _spec_train_cpus(cpus):
    return parse_spec({"name": "x", "env_ids": ["HapticRecog-v0"],
                       "agent": [{"name": "ppo", "algo": "ppo", "cpus": cpus}]})


def _spec_normals(normals):
    return parse_spec({"name": "x", "dataset": [{"normals": normals, "grasps_per_object": 10}]})


A = AnalysisConfig
D = DatasetConfig
H = HapticRecogConfig

#: (what is called with the bad value, the bad value, a regex naming the field)
BAD = [
    # HapticRecogConfig: yes/no fields are ValueErrors (were TypeErrors); counts and the threshold refuse bool
    (lambda v: H(observe_contacts=v), "yes", r"observe_contacts must be True or False, got 'yes'"),
    (lambda v: H(normals=v), "false", r"normals must be True or False, got 'false'"),
    (lambda v: H(grasp_heights=v), 1, r"grasp_heights must be True or False, got 1"),
    (lambda v: H(calibrate_grasps=v), True, r"calibrate_grasps must be an int >= 1, got True"),
    (lambda v: H(max_grasps=v), True, r"max_grasps must be an int >= 1, got True"),
    (lambda v: H(threshold=v), True, r"threshold must be in \(0, 1\], got True"),
    # the longest calibrated belief (sequence_scores makes max x rows sums), and the recogniser's options at make
    (lambda v: H(calibrate_grasps=v), 10**9, r"calibrate_grasps must be <= 100 .*got 1000000000"),
    (lambda v: H(recognizer_kwargs={"config": v}), 5, r"recognizer_kwargs\['config'\] must be a RecognizerConfig"),
    (lambda v: H(recognizer_kwargs={"config": {"kde": v}}), "x", r"kde must be a KDEConfig, got str"),
    (lambda v: H(recognizer_kwargs={"models": v}), "kde", r"models must be a sequence of model names.*got 'kde'"),
    (lambda v: H(recognizer_kwargs={"cache": v}), "no", r"cache must be True or False, got 'no'"),
    # the backend and its keyword arguments at make, through the backend's own config (they failed at the build)
    (lambda v: H(backend=v), "nope", r"backend must be one of \('geometric', .*got 'nope'"),
    (lambda v: H(backend=v), 3, r"backend must be one of .*got 3"),
    (lambda v: H(backend_kwargs=v), {"foo": 1}, r"invalid backend_kwargs for backend 'geometric'.*'foo'"),
    (lambda v: H(backend_kwargs=v), {"n_fingers": 3}, r"backend_kwargs must not set n_fingers \(3\)"),
    (lambda v: H(n_fingers=v), 50, r"n_fingers must be an integer in \[2, 16\], got 50"),
    (lambda v: H(backend="mujoco", backend_kwargs={"hand": "allegro", "friction": v}), -1,
     r"friction must be finite and >= 0, got -1"),
    # what the backend needs of the env, at make (they failed at the first step or reset)
    (lambda v: H(backend_kwargs={"normals": v}), False,
     r"normals=True but backend 'geometric' with backend_kwargs normals=False senses no contact normals"),
    (lambda v: H(backend="replay", backend_kwargs={"hand": "allegro"}, pose=v), "so3",
     r"the replay backend .* needs pose='table-yaw' and scale_range=None, got pose='so3', scale_range=None"),
    (lambda v: H(backend="replay", backend_kwargs={"hand": "allegro"}, scale_range=v), (0.9, 1.1),
     r"needs pose='table-yaw' and scale_range=None, got pose='table-yaw', scale_range=\(0.9, 1.1\)"),
    # DatasetConfig: whole numbers are ints (4.0 was stored as 4.0), fractions numbers, yes/no fields bools
    (lambda v: D(n_fingers=v), 4.0, r"n_fingers must be an int >= 2, got 4.0"),
    (lambda v: D(n_fingers=v), np.float64(4.0), r"n_fingers must be an int >= 2, got np.float64\(4.0\)"),
    (lambda v: D(n_fingers=v), "x", r"n_fingers must be an int >= 2, got 'x'"),
    (lambda v: D(n_fingers=v), math.nan, r"n_fingers must be an int >= 2, got nan"),
    (lambda v: D(n_fingers=v), math.inf, r"n_fingers must be an int >= 2, got inf"),
    (lambda v: D(n_fingers=v), None, r"n_fingers must be an int >= 2, got None"),
    (lambda v: D(grasps_per_object=v), True, r"grasps_per_object must be an int >= 1, got True"),
    # another source's settings were taken and ignored
    (lambda v: D(hand_fingers=v), 7, r"hand_fingers=7 would be ignored with source='surface'"),
    (lambda v: D(support=v), "floating", r"support='floating' would be ignored with source='surface'"),
    (lambda v: D(source="geometric", hand_budget=v), "balanced", r"hand_budget='balanced' would be ignored with "
                                                                   r"source='geometric'"),
    (lambda v: D(grasps_per_object=v), 100.0, r"grasps_per_object must be an int >= 1, got 100.0"),
    (lambda v: D(source="geometric", hand_fingers=v), 5.0, r"hand_fingers must be an int >= n_fingers=4, got 5.0"),
    (lambda v: D(source="geometric", hand_fingers=v), "x", r"hand_fingers must be an int >= n_fingers=4, got 'x'"),
    (lambda v: D(val_fraction=v), False, r"val_fraction must be in \[0, 1\), got False"),
    (lambda v: D(val_fraction=v), "0.2", r"val_fraction must be in \[0, 1\), got '0.2'"),
    (lambda v: D(val_fraction=v), None, r"val_fraction must be in \[0, 1\), got None"),
    (lambda v: D(normals=v), "false", r"normals must be a bool, got 'false'"),
    (lambda v: D(normals=v), 0, r"normals must be a bool, got 0"),
    (lambda v: D(normalize_scale=v), "no", r"normalize_scale must be a bool, got 'no'"),
    (lambda v: _sample_grasps(n_fingers=v), 2.0, r"n_fingers must be an int >= 1, got 2.0"),
    (lambda v: _sample_grasps(n_fingers=v), True, r"n_fingers must be an int >= 1, got True"),
    (lambda v: _sample_grasps(count=v), 2.5, r"count must be an int >= 0, got 2.5"),
    (_hand_dataset, True, r"min_rows must be an int >= 1, got True"),
    # AnalysisConfig: yes/no fields, one whole-number check, fractions that refuse bool, tuples that refuse scalars
    (lambda v: A(normals=v), "no", r"normals must be a bool, got 'no'"),
    (lambda v: A(calibrated=v), None, r"calibrated must be a bool, got None"),
    (lambda v: A(stop_scale=v), 0, r"stop_scale must be a bool, got 0"),
    # experiment 5 fits its temperature on beliefs of up to max_grasps: it failed there, after experiments 1-4
    (lambda v: A(max_grasps=v), 150, r"max_grasps must be <= 100 with experiment 5 on calibrated scores .*got 150"),
    (lambda v: A(progress=v), "no", r"progress must be a bool, got 'no'"),
    (lambda v: A(family_members=v), True, r"family_members must be an int >= 1, got True"),
    (lambda v: A(threshold=v), True, r"threshold must be in \(0, 1\], got True"),
    (lambda v: A(lambdas=v), (True, 0.5), r"lambdas must be .* in \(0, 1\], got \(True, 0.5\)"),
    (lambda v: A(lambdas=v), 0.5, r"lambdas must be a non-empty tuple of thresholds in \(0, 1\], got 0.5"),
    (lambda v: A(family_floors=v), (False, 0.1), r"family_floors must be .* in \[0, 1\), got \(False, 0.1\)"),
    (lambda v: A(family_floors=v), 0.1, r"family_floors must be a non-empty tuple of quantiles .*, got 0.1"),
    (lambda v: A(incomplete_pn=v), ((3, True),), r"incomplete_pn must be .*, got \(\(3, True\),\)"),
    (lambda v: A(incomplete_pn=v), (3, 0.2), r"incomplete_pn must be .*, got \(3, 0.2\)"),
    (lambda v: A(fingers=v), 3, r"fingers must be a tuple of ints in \[2, 20\], each once, got 3"),
    (lambda v: A(zfinger_hands=v), 5, r"zfinger_hands must be a tuple of ints in \[4, 20\], each once, got 5"),
    (lambda v: A(classifiers=v), 3, r"classifiers must name at least one of .*, got 3"),
    (lambda v: A(experiments=v), (99,), r"experiments must be .* experiment numbers \[1, .*, 7\], each once, got \(99,\)"),
    (lambda v: A(experiments=v), (-1,), r"experiments must be .* experiment numbers .*, got \(-1,\)"),
    # experiment 5's and the stop scale's own arguments
    (_family_temperatures, True, r"grasps must be an int >= 1, got True"),
    (_family_floor, (False, 0.1), r"quantiles must be a non-empty list in \[0, 1\), got \(False, 0.1\)"),
    (_family_floor, ("x",), r"quantiles must be a non-empty list in \[0, 1\), got \('x',\)"),
    (lambda v: _stop_scale(threshold=v), "0.9", r"threshold must be in \(0, 1\], got '0.9'"),
    (lambda v: _stop_scale(threshold=v), True, r"threshold must be in \(0, 1\], got True"),
    (lambda v: _stop_scale(scales=v), ("1",), r"scales must be positive and finite, got \('1',\)"),
    (lambda v: _stop_scale(scales=v), (True,), r"scales must be positive and finite, got \(True,\)"),
    (lambda v: _stop_scale(scales=v), 1.0, r"scales must be positive and finite, got 1.0"),
    # the greedy agent and the evaluation
    (lambda v: _greedy(n_candidates=v), 2.7, r"n_candidates must be an int >= 1, got 2.7"),
    (lambda v: _greedy(n_candidates=v), True, r"n_candidates must be an int >= 1, got True"),
    (lambda v: _greedy(n_candidates=v), math.nan, r"n_candidates must be an int >= 1, got nan"),
    (lambda v: _greedy(n_candidates=v), "4", r"n_candidates must be an int >= 1, got '4'"),
    (lambda v: _greedy(n_samples=v), 1.5, r"n_samples must be an int >= 1, got 1.5"),
    (lambda v: _greedy(min_weight=v), False, r"min_weight must be in \[0, 1\), got False"),
    (lambda v: _greedy(min_weight=v), "x", r"min_weight must be in \[0, 1\), got 'x'"),
    (lambda v: _greedy(pose_known=v), "no", r"pose_known must be True or False, got 'no'"),
    (_run_episodes, 2.5, r"n_episodes must be an int >= 1, got 2.5"),
    (_run_episodes, True, r"n_episodes must be an int >= 1, got True"),
    (_evaluate_agents, True, r"n_episodes must be an int >= 1, got True"),
    (_episode_seed, 2.5, r"seed must be an int >= 0, got 2.5"),
    (_episode_seed, True, r"seed must be an int >= 0, got True"),
    (_episode_seed, "3", r"seed must be an int >= 0, got '3'"),
    (_episode_seed, -1, r"seed must be an int >= 0, got -1"),
    (_episode_seed, None, r"seed must be an int >= 0, got None"),
    (lambda v: _episode_seed(0, v), 1.5, r"agent_seed must be an int >= 0, got 1.5"),
    (_evaluate_seeds, [0, 2.5], r"seed must be an int >= 0, got 2.5"),
    # sweep specs: a job's CPUs, a dataset's normals
    (lambda v: _spec_cpus("command", v), -2, r"command\[0\]\.cpus: expected a number >= 0 .*, got -2"),
    (lambda v: _spec_cpus("command", v), math.nan, r"command\[0\]\.cpus: .*, got nan"),
    (lambda v: _spec_cpus("command", v), math.inf, r"command\[0\]\.cpus: .*, got inf"),
    (lambda v: _spec_cpus("command", v), True, r"command\[0\]\.cpus: .*, got True"),
    (lambda v: _spec_cpus("command", v), "x", r"command\[0\]\.cpus: .*, got 'x'"),
    (lambda v: _spec_cpus("command", v), 1e-5, r"command\[0\]\.cpus: .*, got 1e-05"),
    (lambda v: _spec_cpus("dataset", v), -1, r"dataset\[0\]\.cpus: .*, got -1"),
    (lambda v: _spec_cpus("analysis", v), "2", r"analysis\[0\]\.cpus: .*, got '2'"),
    (_spec_eval_cpus, -1.0, r"evaluate\.cpus: .*, got -1.0"),
    (_spec_train_cpus, math.nan, r"agent\[0\]\.cpus: .*, got nan"),
    (_spec_normals, "false", r"dataset\[0\]\.normals: expected true or false .*, got 'false'"),
    (_spec_normals, [True, "false"], r"dataset\[0\]\.normals: .*, got 'false'"),
]


@pytest.mark.parametrize("make, bad, match", BAD, ids=[f"{i}-{m.split(' ')[0][:30]}" for i, (*_, m) in enumerate(BAD)])
def test_a_bad_value_is_a_value_error_naming_the_field(make, bad, match):
    with pytest.raises(ValueError, match=match):
        make(bad)


def test_the_spec_errors_are_spec_errors():
    with pytest.raises(SpecError):
        _spec_cpus("command", -2)


def _same_types(a, b) -> bool:
    """``a`` and ``b`` hold equal fields of the same Python types (nested tuples included)."""
    def walk(x, y):
        if isinstance(x, (tuple, list)):
            return type(x) is type(y) and len(x) == len(y) and all(walk(p, q) for p, q in zip(x, y))
        return type(x) is type(y) and x == y
    return all(walk(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))


@pytest.mark.parametrize("cls", [HapticRecogConfig, DatasetConfig, AnalysisConfig])
def test_defaults_are_stored_as_declared(cls):
    """The checks store every default as it is declared (same value, same type): no config made with the defaults
    gets a new cache key."""
    cfg = cls()
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        got = getattr(cfg, f.name)
        assert got == default and type(got) is type(default), f.name


def test_numpy_scalars_are_accepted_and_stored_as_python_values(env_config):
    # AnalysisConfig: one whole-number check for every count (numpy ints too), np.bool_ for flags
    assert _same_types(A(family_members=np.int64(5)), A(family_members=5))
    assert A(family_members=np.int64(5)) == A(family_members=5)
    assert config_key(A(family_members=np.int64(5))) == config_key(A(family_members=5))
    np_flags = A(family_source="hand", family_heights=np.True_, family_lying=np.True_, normals=np.False_,
                 calibrated=np.True_, stop_scale=np.False_, progress=np.False_, trials=np.int32(7), seed=np.int64(2))
    py_flags = A(family_source="hand", family_heights=True, family_lying=True, normals=False, calibrated=True,
                 stop_scale=False, progress=False, trials=7, seed=2)
    assert _same_types(np_flags, py_flags) and config_key(np_flags) == config_key(py_flags)
    assert np_flags.family_heights is True and np_flags.family_lying is True
    cfg = A(threshold=np.float32(0.75), lambdas=(np.float32(0.5), np.int64(1)), family_floors=(np.float64(0.1), 0),
            incomplete_pn=((np.int64(3), np.float32(0.25)),), experiments=(np.int64(2),), fingers=np.array([3, 4]))
    assert cfg.threshold == 0.75 and type(cfg.threshold) is float
    assert cfg.family_floors == (0.1, 0.0) and all(type(q) is float for q in cfg.family_floors)
    # a plain 1 is a threshold; Python values are stored as given
    assert A(threshold=1).threshold == 1 and type(A(threshold=1).threshold) is int
    assert A(lambdas=(0.5, 1)).lambdas == (0.5, 1) and A(experiments=(2, 5)).experiments == (2, 5)
    assert A(family_floors=(0, 0.1)).family_floors == (0.0, 0.1)

    # DatasetConfig
    np_d = D(n_fingers=np.int64(3), grasps_per_object=np.int32(50), seed=np.int64(4), source="geometric",
             hand_fingers=np.int64(4), normals=np.False_, normalize_scale=np.True_, heights=np.True_,
             val_fraction=np.float32(0.25))
    py_d = D(n_fingers=3, grasps_per_object=50, seed=4, source="geometric", hand_fingers=4, normals=False,
             normalize_scale=True, heights=True, val_fraction=0.25)
    assert np_d == py_d and config_key(np_d) == config_key(py_d)
    assert all(type(getattr(np_d, f)) is type(getattr(py_d, f)) for f in ("n_fingers", "grasps_per_object", "seed",
                                                                          "hand_fingers", "normals", "heights"))
    assert type(np_d.feature_dim) is int and np_d.feature_dim == py_d.feature_dim
    assert D(val_fraction=0).val_fraction == 0 and D(n_fingers=2).n_fingers == 2

    # HapticRecogConfig
    np_h = H(threshold=np.float32(0.5), max_grasps=np.int64(5), calibrate_grasps=np.int64(2), normals=np.False_,
             observe_contacts=np.True_)
    py_h = H(threshold=0.5, max_grasps=5, calibrate_grasps=2, normals=False, observe_contacts=True)
    assert np_h == py_h and np_h.normals is False and np_h.observe_contacts is True
    assert type(np_h.threshold) is float and H(threshold=1).threshold == 1 and type(H(threshold=1).threshold) is int
    # every count and number too (a np.int64 max_grasps made the env's `truncated` a numpy bool)
    np_h = H(max_grasps=np.int64(3), n_fingers=np.int64(4), z_fingers=np.int64(3), training_grasps=np.int32(900),
             grasp_cost=np.float32(0.25))
    assert _same_types(np_h, H(max_grasps=3, n_fingers=4, z_fingers=3, training_grasps=900, grasp_cost=0.25))
    import haptic_env

    env = haptic_env.make(env_config.replace(max_grasps=np.int64(1)))
    env.reset(seed=0)
    *_, terminated, truncated, _ = env.step(env.action_space.sample())
    assert type(truncated) is bool and type(terminated) is bool


def test_make_names_a_config_that_is_not_one():
    """``haptic_env.make("HapticRecogShadow-v0")`` (the id where the config goes) was an AttributeError of a str."""
    import haptic_env

    for bad in ("HapticRecogShadow-v0", {"n_fingers": 3}):
        match = rf"config must be a HapticRecogConfig, got {re.escape(repr(bad))} \(an env"
        with pytest.raises(TypeError, match=match):
            haptic_env.make(bad)


def test_valid_arguments_of_the_functions_stay_accepted():
    from agents.evaluate import _check_episodes
    from haptic_env.dataset import sample_grasps
    from haptic_env.objects import load_object_set

    g = _greedy(n_candidates=np.int64(3), n_samples=np.int32(2), min_weight=np.float32(0.01), pose_known=np.False_)
    assert (g.n_candidates, g.n_samples, g.pose_known) == (3, 2, False)
    assert type(g.n_candidates) is int and type(g.pose_known) is bool
    assert _greedy(min_weight=0).min_weight == 0.0
    _check_episodes(np.int64(2))
    C, N = sample_grasps(load_object_set("default")["box"], np.int64(5), np.int64(3), np.random.default_rng(0))
    assert C.shape == N.shape == (5, 3, 3)
    # the thresholds pass their check (then the empty scales are refused)
    for t in (np.float32(0.85), 1, np.int64(1)):
        with pytest.raises(ValueError, match="scales must"):
            _stop_scale(threshold=t, scales=())


def test_sweep_cpus_are_numbers_outside_the_job_key():
    spec = parse_spec({"name": "x", "command": [{"name": "a", "run": "true", "cpus": 0.5},
                                                {"name": "b", "run": "true", "cpus": 0},
                                                {"name": "c", "run": "true", "cpus": 2},
                                                {"name": "d", "run": "true"}]})
    assert [j.cpus for j in spec.jobs] == [0.5, 0.0, 2.0, 1.0] and all(type(j.cpus) is float for j in spec.jobs)
    same = parse_spec({"name": "x", "command": [{"name": "a", "run": "true", "cpus": 3}]}).jobs[0]
    assert same.key == spec.jobs[0].key  # cpus is not part of a job's key
    ds = parse_spec({"name": "x", "dataset": [{"normals": [True, False], "grasps_per_object": 10}]}).jobs
    assert [j.params["config"]["normals"] for j in ds] == [True, False]


def test_int_in_and_int_lists_read_the_same_forms():
    """One rule: an integer as ``int`` reads it, or a whole number as ``float`` reads it (``2e5``)."""
    import argparse

    from haptic_env.cli import int_in, parse_int_list

    big = "12345678901234567890"  # beyond 2**53: exact as an int
    for text, v in (("2e5", 200_000), ("1_000", 1000), ("4.0", 4), ("7", 7), (big, int(big))):
        assert int_in(0)(text) == v and parse_int_list(text) == (v,)
    for text in ("3.5", "x", "nan", "inf", "1e300", ""):
        with pytest.raises(argparse.ArgumentTypeError, match=re.escape(repr(text))):
            int_in(0)(text)
        if text:
            with pytest.raises(ValueError, match=re.escape(repr(text))):
                parse_int_list(text)


def test_repeated_names_the_values_given_more_than_once():
    from haptic_env.numbers import repeated

    assert repeated([3, 1, 3, 2, 1, 3]) == [1, 3] and repeated([0, 1, 2]) == [] and repeated([]) == []
    assert repeated(iter(["a", "b", "a"])) == ["a"]
