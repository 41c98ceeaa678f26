"""Stable-Baselines3 PPO / SAC, and sb3-contrib's recurrent PPO (``rppo``) and maskable PPO (``mppo``), on
:class:`haptic_env.env.HapticRecogEnv`.

The env is partially observable: the object's pose is hidden and each observation holds the latest grasp only.
``rppo`` (``RecurrentPPO`` with an LSTM policy) carries a memory of the episode's grasps; PPO and SAC see one
observation at a time.

* :func:`make_vec_env` — ``n_envs`` copies (``SubprocVecEnv`` or ``DummyVecEnv``; ``vec="native"``: the native
  vector env through :class:`agents.native_vec.NativeVecEnv`, one process), each wrapped in a
  ``Monitor`` writing ``<log_dir>/monitor/<rank>.monitor.csv`` (with the episode's ``correct`` and
  ``grasps``), seeded ``seed + rank``.
* :func:`build_model` — PPO, SAC, recurrent PPO or maskable PPO with TensorBoard logs under ``<log_dir>/tb``.
* :func:`train` — learn with checkpoints (``<log_dir>/checkpoints/<algo>_<steps>_steps.zip``, SAC also
  ``<algo>_replay_buffer_<steps>_steps.pkl``), optionally resuming from a checkpoint (its step counter
  continues up to ``total_timesteps``), and save ``<log_dir>/<algo>_final.zip``. SIGINT / SIGTERM or a dead
  env worker stop learning, save a checkpoint and raise :class:`TrainingInterrupted`.
* :func:`latest_checkpoint` — the checkpoint with the most steps in a run directory.
* :class:`SB3Agent` — a trained model as an :class:`agents.base.Agent` for :mod:`agents.evaluate`.
* :func:`approach_table` (from :mod:`haptic_env.grasping.base`), :class:`DiscreteApproaches` — a fixed set of
  ``N`` approaches as a ``Discrete(N)`` action (``make_vec_env(discrete_approaches=N)``,
  ``train.py --discrete-approaches N``): PPO's policy is then categorical,
  so it can put its mass on a few separate approaches instead of the one mode of a Gaussian. :class:`SB3Agent` maps
  such a model's choice back to the approach, so the env it is evaluated on keeps the continuous action box.
* :class:`RepeatTracker`, :class:`RepeatMask` — the approaches tried since the belief last changed: the rule by which
  :class:`SB3Agent` with ``no_repeat`` moves on, and the action mask that ``mppo`` (sb3-contrib's ``MaskablePPO``,
  ``train.py --algo mppo``) is trained with, so that the policy learns what to choose once a grasp has told nothing.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import re
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
import numpy as np

from haptic_env.grasping.base import approach_table
from haptic_env.numbers import finite_number, flag, whole_at_least, whole_number

__all__ = ["ALGOS", "DEFAULT_HYPERPARAMS", "make_vec_env", "build_model", "load_model", "algo_of_file", "train",
           "SB3Agent", "TrainingInterrupted", "latest_checkpoint", "checkpoint_extras", "close_vec_env",
           "check_hyperparams", "replay_buffer_problem", "replay_envs_problem", "approach_table", "approaches_for",
           "DiscreteApproaches", "DISCRETE_ALGOS", "discrete_approaches_problem", "RepeatTracker", "RepeatMask"]

#: ``rppo``: sb3-contrib's ``RecurrentPPO`` (an LSTM policy); ``mppo``: sb3-contrib's ``MaskablePPO`` over fixed
#: approaches, trained and acting with :class:`RepeatMask`. Their model files are named ``rppo_*`` / ``mppo_*``.
ALGOS = ("ppo", "sac", "rppo", "mppo")

_PPO = dict(n_steps=256, batch_size=128, n_epochs=10, learning_rate=3e-4, gamma=0.95, gae_lambda=0.95, ent_coef=0.0,
            clip_range=0.2)
#: Defaults tuned for short episodes (a handful of grasps) and a cheap env; override per key. ``rppo`` is PPO's
#: with an LSTM of 64 units before the actor's and the critic's layers; ``mppo`` is PPO's.
DEFAULT_HYPERPARAMS: dict[str, dict[str, Any]] = {
    "ppo": dict(_PPO, policy_kwargs=dict(net_arch=[64, 64])),
    "sac": dict(buffer_size=100_000, learning_starts=1_000, batch_size=256, learning_rate=3e-4, gamma=0.95,
                tau=0.01, train_freq=1, gradient_steps=1, policy_kwargs=dict(net_arch=[64, 64])),
    "rppo": dict(_PPO, policy_kwargs=dict(net_arch=[64, 64], lstm_hidden_size=64)),
    "mppo": dict(_PPO, policy_kwargs=dict(net_arch=[64, 64])),
}

#: the policy class each algorithm is built with
_POLICY = {"ppo": "MlpPolicy", "sac": "MlpPolicy", "rppo": "MlpLstmPolicy", "mppo": "MlpPolicy"}


def _is_maskable(model) -> bool:
    """Whether ``model``'s policy is sb3-contrib's maskable one (a model trained with ``--algo mppo``)."""
    from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy

    return isinstance(getattr(model, "policy", None), MaskableActorCriticPolicy)


def _algo_class(algo: str):
    algo = algo.lower() if isinstance(algo, str) else algo
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    if algo == "rppo":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    if algo == "mppo":
        from sb3_contrib import MaskablePPO

        return MaskablePPO
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC}[algo]


#: the algorithms whose policies take a ``Discrete`` action (SAC's does not); ``mppo`` takes nothing else
DISCRETE_ALGOS = ("ppo", "rppo", "mppo")


def discrete_approaches_problem(n: int, algo: str | None, vec: str) -> str | None:
    """Why ``n`` fixed approaches (``--discrete-approaches``) cannot be trained with ``algo`` (None: not checked) on
    a ``vec`` vector env, or None if they can (``n == 0``, the continuous action, can with any algo but ``mppo``,
    which masks fixed approaches). The one statement of the rule: :func:`make_vec_env`, ``train.py`` and the sweep
    specs each report it in their own terms."""
    if not n:
        if algo == "mppo":
            return "mppo masks fixed approaches: it needs discrete_approaches >= 1, got 0"
        return None
    if algo is not None and algo not in DISCRETE_ALGOS:
        return (f"{algo}'s policy takes a continuous action only (got discrete_approaches {n}); use an algo of "
                f"{DISCRETE_ALGOS} or 0")
    if vec == "native":
        return (f"wraps each env (discrete_approaches {n}), and the native vector env steps them in one batch: use "
                'vec "subproc" or "dummy", got "native"')
    return None


def approaches_for(n: int, space) -> np.ndarray:
    """:func:`approach_table`'s ``n`` approaches in the dimension of ``space``, an env's continuous (``Box``) action
    space: the table :class:`DiscreteApproaches` maps ``Discrete(n)`` onto, and :class:`SB3Agent` maps its choice back
    with. A ``ValueError`` names any other space."""
    if not isinstance(space, gym.spaces.Box):
        raise ValueError(f"fixed approaches need an env with a continuous (Box) action, got {space}")
    return approach_table(n, int(np.prod(space.shape)))


class DiscreteApproaches(gym.ActionWrapper):
    """The env with a ``Discrete(n)`` action: action ``i`` is :func:`approaches_for`'s row ``i``."""

    def __init__(self, env, n: int):
        super().__init__(env)
        self.table = approaches_for(n, env.action_space)
        self.action_space = gym.spaces.Discrete(len(self.table))

    def action(self, action) -> np.ndarray:
        i = np.asarray(action)
        if i.size != 1 or i.dtype.kind not in "iu" or not 0 <= int(i.reshape(-1)[0]) < len(self.table):
            raise ValueError(f"action must be one approach index in [0, {len(self.table)}), got {action!r}")
        return self.table[int(i.reshape(-1)[0])].copy()


class RepeatTracker:
    """The approaches tried since the belief last changed, among ``n``: the one statement of the rule that
    :class:`SB3Agent` with ``no_repeat`` acts by and :class:`RepeatMask` trains ``mppo`` with. Call :meth:`see` with
    the belief before each choice (a belief other than the last one seen frees every approach), :meth:`add` with the
    approach chosen, :meth:`clear` at an episode's start."""

    def __init__(self, n: int):
        self.n = whole_at_least(n, 1, "n")
        self.clear()

    def clear(self) -> None:
        self.tried: set[int] = set()
        self.last: np.ndarray | None = None

    def see(self, belief) -> None:
        belief = np.asarray(belief)
        if self.last is None or not np.array_equal(belief, self.last):
            self.tried = set()
        self.last = belief.copy()

    def add(self, i: int) -> None:
        self.tried.add(int(i))

    def mask(self) -> np.ndarray:
        """``(n,)`` bool: True where an approach may be chosen, i.e. not tried at this belief; all True once every
        approach has been (then the policy's own choice stands)."""
        allowed = np.ones(self.n, dtype=bool)
        if len(self.tried) < self.n:
            allowed[sorted(self.tried)] = False
        return allowed


class RepeatMask(gym.Wrapper):
    """An env over fixed approaches (``Discrete(N)``, :class:`DiscreteApproaches`) with ``action_masks()``, the
    method sb3-contrib's ``MaskablePPO`` asks each env for: False for the approaches tried since the belief (the
    observation's ``belief`` part, ``env.unwrapped.task.obs_slices``) last changed (:class:`RepeatTracker`). A grasp
    that touches with too few fingers leaves the belief as it was; the mask then moves the policy on. Other
    algorithms ignore the method; the wrapper changes no observation, reward or step."""

    def __init__(self, env):
        super().__init__(env)
        if not isinstance(env.action_space, gym.spaces.Discrete):
            raise ValueError(f"RepeatMask needs fixed approaches (a Discrete action), got {env.action_space}")
        self._belief = env.unwrapped.task.obs_slices["belief"]
        self.tracker = RepeatTracker(int(env.action_space.n))

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.tracker.clear()
        self.tracker.see(np.asarray(obs)[self._belief])
        return obs, info

    def step(self, action):
        self.tracker.add(int(np.asarray(action).reshape(-1)[0]))
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.tracker.see(np.asarray(obs)[self._belief])
        return obs, reward, terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        return self.tracker.mask()


def _env_fn(config, rank: int, monitor_dir: str | None, env_id: str, monitor_suffix: str = "",
            worker: bool = False, discrete_approaches: int = 0, env=None) -> Callable[[], Any]:
    """A builder of env ``rank``, monitored; ``env``: one of ``config`` already built (in this process) to use."""

    def _init():
        os.environ.setdefault("OMP_NUM_THREADS", "1")
        if worker:
            # Ctrl-C reaches every process of the group: the workers keep serving so that the main process
            # can stop at the next step, save and close them (SIGTERM keeps its default: multiprocessing's
            # exit handler terminates the workers with it)
            import signal

            signal.signal(signal.SIGINT, signal.SIG_IGN)
        import haptic_env
        from stable_baselines3.common.monitor import Monitor

        built = haptic_env.make(config, env_id=env_id) if env is None else env
        path = os.path.join(monitor_dir, f"{rank}{monitor_suffix}") if monitor_dir else None
        built = Monitor(built, filename=path, info_keywords=("correct", "grasps"))
        return RepeatMask(DiscreteApproaches(built, discrete_approaches)) if discrete_approaches else built

    return _init


#: ``make_vec_env(vec=...)`` (and ``train.py --vec``): one process per env, all in this process, or the native
#: batched vector env (``haptic_env.vector_env``)
VEC_KINDS = ("subproc", "dummy", "native")


def make_vec_env(config=None, n_envs: int = 2, seed: int = 0, log_dir: str | os.PathLike | None = None,
                 vec: str = "subproc", env_id: str = "HapticRecog-v0", monitor_suffix: str = "",
                 discrete_approaches: int = 0, probe=None):
    """``n_envs`` monitored copies of the env. ``vec="subproc"`` runs each in its own process (which ignores
    SIGINT, so that Ctrl-C reaches only the main process's handler). ``monitor_suffix`` names the Monitor files
    ``<rank><suffix>.monitor.csv`` (a resumed run writes a new segment, e.g. ``.part2``, keeping the old ones).
    ``discrete_approaches=N > 0`` gives each env a ``Discrete(N)`` action (:class:`DiscreteApproaches`; not with
    ``vec="native"``) and the action mask ``mppo`` trains with (:class:`RepeatMask`). ``probe``: an env of
    ``config`` already built in this process (``haptic_env.make(config, env_id=env_id)``, not yet reset; e.g.
    ``train.py``'s check of a resumed checkpoint's spaces), taken over instead of building another: with
    ``vec="subproc"`` and ``n_envs > 1`` it prepares the workers' cache, else it is env 0 (``"subproc"`` with one
    env runs it here, as ``"dummy"`` does); ``"native"`` closes it. It is closed here too when the vec env cannot be
    built (a bad argument, a failing env)."""
    try:
        return _vec_env(config, n_envs, seed, log_dir, vec, env_id, monitor_suffix, discrete_approaches, probe)
    except BaseException:
        if probe is not None:  # taken over by nothing (closing it twice is harmless)
            probe.close()
        raise


def _vec_env(config, n_envs, seed, log_dir, vec, env_id, monitor_suffix, discrete_approaches, probe):
    """:func:`make_vec_env`'s body."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    from haptic_env import variant_config
    from haptic_env.env import get_recognizer

    if vec not in VEC_KINDS:
        raise ValueError(f"vec must be 'subproc', 'dummy' or 'native', got {vec!r}")
    discrete_approaches = whole_at_least(discrete_approaches, 0, "discrete_approaches")
    problem = discrete_approaches_problem(discrete_approaches, None, vec)
    if problem is not None:
        raise ValueError(f"discrete_approaches: {problem}")
    config = config or variant_config(env_id)  # no config: the registered env's own (not the defaults)
    monitor_dir = None
    if log_dir is not None:
        monitor_dir = str(Path(log_dir) / "monitor")
        Path(monitor_dir).mkdir(parents=True, exist_ok=True)
    if vec == "native":  # the native vector env (haptic_env.vector_env) through a thin VecEnv adapter
        from agents.native_vec import NativeVecEnv
        from haptic_env.vector_env import make_vector_env

        if probe is not None:  # the batched env steps its own scenes
            probe.close()
        venv = NativeVecEnv(make_vector_env(n_envs, config, env_id=env_id, autoreset_mode="same_step"),
                            monitor_dir=monitor_dir, monitor_suffix=monitor_suffix, env_id=env_id)
        venv.seed(seed)
        venv.action_space.seed(seed)
        return venv
    subproc = vec == "subproc" and n_envs > 1  # one env needs no worker: it runs here (the probe is env 0)
    if subproc:
        # build (or load) the recogniser once here so the workers only read the cache
        import haptic_env

        probe = haptic_env.make(config, env_id=env_id) if probe is None else probe
        inner = probe.unwrapped
        get_recognizer(inner.objects, inner.config)
        # and whatever a first reset builds (the estimated frame's yaw belief records the hand's replay pool): a
        # worker is a daemonic process, which may not start the pool's processes
        inner.reset(seed=0)
        probe.close()
        probe = None
    fns = [_env_fn(config, i, monitor_dir, env_id, monitor_suffix, worker=subproc,
                   discrete_approaches=discrete_approaches, env=probe if i == 0 else None) for i in range(n_envs)]
    venv = SubprocVecEnv(fns) if subproc else DummyVecEnv(fns)
    venv.seed(seed)
    venv.action_space.seed(seed)
    return venv


#: ``build_model``'s own arguments to the SB3 class, which hyperparams may not set
_SET_BY_BUILD = ("policy", "env", "seed", "tensorboard_log", "verbose", "device")


#: Hyperparameters that are counts, and their least value (PPO asserts batch_size > 1; -1: SB3's "every step" /
#: "as many gradient steps as env steps").
_WHOLE_AT_LEAST = {"n_steps": 1, "batch_size": 2, "n_epochs": 1, "buffer_size": 1, "learning_starts": 0,
                   "target_update_interval": 1, "stats_window_size": 1, "sde_sample_freq": -1, "gradient_steps": -1}
#: Hyperparameters that are a number > 0 or None (off).
_POSITIVE_OR_NONE = ("target_kl", "clip_range_vf")
#: Hyperparameters and policy_kwargs that are yes / no.
_FLAGS = ("normalize_advantage", "use_sde", "use_sde_at_warmup", "optimize_memory_usage", "ortho_init",
          "share_features_extractor", "squash_output", "full_std", "use_expln", "normalize_images")
#: Hyperparameters and policy_kwargs that are Python objects or classes (JSON names none of them).
_OBJECTS = ("action_noise", "replay_buffer_class", "rollout_buffer_class", "features_extractor_class",
            "optimizer_class")
#: Hyperparameters that are numbers: (lower-bound test, upper bound, the range in words).
_NUMBER_IN = {"learning_rate": (lambda f: f > 0, np.inf, "> 0"), "gamma": (lambda f: f >= 0, 1.0, "in [0, 1]"),
              "gae_lambda": (lambda f: f >= 0, 1.0, "in [0, 1]"), "clip_range": (lambda f: f > 0, np.inf, "> 0"),
              "ent_coef": (lambda f: f >= 0, np.inf, ">= 0"), "vf_coef": (lambda f: f >= 0, np.inf, ">= 0"),
              "max_grad_norm": (lambda f: f > 0, np.inf, "> 0"), "tau": (lambda f: f > 0, 1.0, "in (0, 1]"),
              "target_entropy": (lambda f: True, np.inf, "(any finite value)")}
#: The strings SB3 takes for a number, by algorithm and key: SAC's ``ent_coef`` "auto" (learned from 1) or "auto_<x>"
#: (learned from x > 0) and its ``target_entropy`` "auto" (minus the action's dimension); SB3 float()s any other.
_AUTO = {("sac", "ent_coef"), ("sac", "target_entropy")}


def _auto_problem(key: str, value: str) -> str | None:
    """Why ``value`` is not one of SB3's strings for SAC's ``key`` (:data:`_AUTO`), or None if it is."""
    if value == "auto":
        return None
    if key == "ent_coef" and value.startswith("auto_"):
        with contextlib.suppress(ValueError):
            if 0 < float(value.removeprefix("auto_")) < np.inf:
                return None
    return "'auto'" if key == "target_entropy" else "'auto' or 'auto_<initial value > 0>'"


def _value_problem(key: str, value) -> str | None:
    """What ``value`` must be for the SB3 argument ``key`` (a hyperparameter or a policy_kwargs key), or None when it
    is that or ``key`` is not checked here (the counts and numbers are :func:`check_hyperparams`' own loop)."""
    if key in _POSITIVE_OR_NONE and value is not None and (finite_number(value) is None or value <= 0):
        return "a number > 0 or null"
    if key in _FLAGS and flag(value) is None:
        return "true or false"
    if key in _OBJECTS and isinstance(value, (str, int, float, list, dict)):
        return "a Python object or class (given from Python; JSON cannot name one) or null"
    if key == "train_freq":
        if whole_number(value) is not None and value >= 1:
            return None
        if (isinstance(value, (list, tuple)) and len(value) == 2 and whole_number(value[0]) is not None
                and value[0] >= 1 and value[1] in ("step", "episode")):
            return None
        return 'an int >= 1 or [int >= 1, "step" | "episode"]'
    if key in ("rollout_buffer_kwargs", "replay_buffer_kwargs", "features_extractor_kwargs", "optimizer_kwargs"):
        return None if value is None or isinstance(value, dict) else "a table or null"
    return None


def _layers(value) -> bool:
    return isinstance(value, (list, tuple)) and all(whole_number(v) is not None and v >= 1 for v in value)


def _check_policy_kwargs(algo: str, pk: dict) -> None:
    """A ``ValueError`` naming a ``policy_kwargs`` value its policy would fail on once built or trained: ``net_arch``
    (a list of layer widths >= 1, or a table of such lists), ``activation_fn`` (a ``torch.nn`` module class, or the
    name of one, e.g. ``"Tanh"``, which :func:`build_model` looks up), ``log_std_init`` (a finite number) and the
    yes / no and object keys."""
    for key, value in pk.items():
        problem = _value_problem(key, value)
        if key == "net_arch" and not (_layers(value) or (isinstance(value, dict) and value
                                                         and all(_layers(v) for v in value.values()))):
            problem = "a list of layer widths >= 1 or a table of such lists (pi / vf / qf)"
        if key == "activation_fn" and _activation(value) is None:
            problem = "a torch.nn activation module class or its name (e.g. \"Tanh\", \"ReLU\")"
        if key == "log_std_init" and finite_number(value) is None:
            problem = "a finite number"
        if problem is not None:
            raise ValueError(f"{algo.upper()} policy_kwargs {key} must be {problem}, got {value!r}")


def _activation(value):
    """The ``torch.nn.Module`` subclass ``value`` is or names (a ``torch.nn`` attribute), else None."""
    import inspect

    import torch

    cls = getattr(torch.nn, value, None) if isinstance(value, str) else value
    return cls if inspect.isclass(cls) and issubclass(cls, torch.nn.Module) else None


def check_hyperparams(algo: str, hyperparams: dict, n_envs: int | None = None) -> None:
    """A ``ValueError`` naming every key of ``hyperparams`` that the SB3 ``algo`` class does not take (or that
    :func:`build_model` sets itself, or a private one such as ``_init_setup_model``), a ``policy_kwargs`` key its
    policy class does not take, or a common count or number out of its range (``n_steps``, ``batch_size``,
    ``gamma``, ``learning_rate``, ...), before any env or run file is made; with ``n_envs``, also an on-policy
    rollout of one step (``n_steps x n_envs``, which SB3 asserts > 1 only when it builds the model). A number given
    as a string is refused (SB3 would fail on it mid-training, after the run's files were written) except SB3's own
    strings, SAC's ``ent_coef`` ``"auto"`` / ``"auto_0.1"`` and ``target_entropy`` ``"auto"`` (:data:`_AUTO`); so are
    a yes / no that is not one, ``target_kl`` / ``clip_range_vf`` that are not > 0 or null, a ``train_freq`` SB3
    cannot read, an object or class named in JSON, and the ``policy_kwargs`` values of :func:`_check_policy_kwargs`."""
    import inspect

    cls = _algo_class(algo)
    taken = {k for k in inspect.signature(cls.__init__).parameters if not k.startswith("_")} - {"self", *_SET_BY_BUILD}
    bad = sorted(set(hyperparams) - taken)
    if bad:
        raise ValueError(f"unknown {algo.upper()} hyperparameter(s) {bad}; valid: {sorted(taken)}")
    if "policy_kwargs" in hyperparams:  # the policy's own arguments: a typo failed once the run's files were there
        pk = hyperparams["policy_kwargs"]
        policy = cls.policy_aliases[_POLICY[algo.lower()]]
        own = set(inspect.signature(policy.__init__).parameters) - {"self", "observation_space", "action_space",
                                                                     "lr_schedule"}
        if not isinstance(pk, dict):
            raise ValueError(f"{algo.upper()} hyperparameter policy_kwargs must be a table of {policy.__name__}'s "
                             f"arguments, got {pk!r}")
        if set(pk) - own:
            raise ValueError(f"unknown {policy.__name__} policy_kwargs {sorted(set(pk) - own)}; valid: {sorted(own)}")
        _check_policy_kwargs(algo, pk)
    for key, value in hyperparams.items():  # the types and ranges SB3 checks only when it builds or trains
        problem = _value_problem(key, value)
        if problem is not None:
            raise ValueError(f"{algo.upper()} hyperparameter {key} must be {problem}, got {value!r}")
        if key in _WHOLE_AT_LEAST and (whole_number(value) is None or value < _WHOLE_AT_LEAST[key]):
            raise ValueError(f"{algo.upper()} hyperparameter {key} must be an int >= {_WHOLE_AT_LEAST[key]}, "
                             f"got {value!r}")
        if key in _NUMBER_IN:
            lo, hi, text = _NUMBER_IN[key]
            if isinstance(value, str) and (algo.lower(), key) in _AUTO:  # SB3's own forms (SAC's "auto" ent_coef)
                forms = _auto_problem(key, value)
                if forms is not None:
                    raise ValueError(f"{algo.upper()} hyperparameter {key} must be a number {text} or {forms}, "
                                     f"got {value!r}")
                continue
            f = finite_number(value)
            if f is None or not lo(f) or f > hi:
                raise ValueError(f"{algo.upper()} hyperparameter {key} must be a number {text}, got {value!r}")
    params = {**DEFAULT_HYPERPARAMS[algo.lower()], **hyperparams}
    n_steps = params.get("n_steps")  # checked whole above; SB3 asserts a longer rollout only to normalise advantages
    if n_envs is not None and n_steps is not None and n_steps * n_envs <= 1 and params.get("normalize_advantage", True):
        raise ValueError(f"{algo.upper()} needs a rollout of more than one step, n_steps x n_envs > 1, got n_steps="
                         f"{n_steps} with n_envs={n_envs}")


def build_model(algo: str, venv, seed: int = 0, log_dir: str | os.PathLike | None = None, verbose: int = 0,
                **hyperparams: Any):
    """A fresh PPO / SAC / recurrent PPO / maskable PPO model on ``venv`` (:data:`DEFAULT_HYPERPARAMS` updated with
    ``hyperparams``)."""
    cls = _algo_class(algo)
    check_hyperparams(algo, hyperparams)
    algo = algo.lower()
    if isinstance(venv.action_space, gym.spaces.Discrete) and algo not in DISCRETE_ALGOS:
        raise ValueError(f"{algo}'s policy takes a continuous action, got the env's {venv.action_space} (fixed "
                         f"approaches: use one of {DISCRETE_ALGOS})")
    if algo == "mppo" and not isinstance(venv.action_space, gym.spaces.Discrete):
        raise ValueError(f"mppo masks fixed approaches: it needs a Discrete action, got the env's {venv.action_space} "
                         "(make_vec_env(discrete_approaches=N))")
    params = {**DEFAULT_HYPERPARAMS[algo], **hyperparams}
    if "activation_fn" in params.get("policy_kwargs", {}):  # a torch.nn class named in JSON
        params["policy_kwargs"] = {**params["policy_kwargs"],
                                   "activation_fn": _activation(params["policy_kwargs"]["activation_fn"])}
    tb = str(Path(log_dir) / "tb") if log_dir is not None else None
    return cls(_POLICY[algo], venv, seed=seed, tensorboard_log=tb, verbose=verbose, device="cpu", **params)


def saved_data(path: str | os.PathLike) -> dict | None:
    """The data a model file was saved with (stable-baselines3's ``data``: its ``num_timesteps``, spaces, ...), or
    None for a file SB3 cannot read (not a zip file, a truncated one)."""
    import zipfile

    from stable_baselines3.common.save_util import load_from_zip_file

    try:
        data, _, _ = load_from_zip_file(path, load_data=True, device="cpu")
    except (ValueError, OSError, EOFError, zipfile.BadZipFile):
        return None
    return data or {}


def algo_of_file(path: str | os.PathLike) -> str | None:
    """The algorithm a model file's name starts with (``ppo_*``/``sac_*``/``rppo_*``/``mppo_*``), or None."""
    stem = Path(path).name.lower()
    return next((a for a in ALGOS if stem.startswith(a)), None)


def load_model(path: str | os.PathLike, algo: str | None = None, env=None):
    """Load a saved model; ``algo`` is inferred from the file name (:func:`algo_of_file`) when omitted."""
    path = Path(path)
    if not path.exists() and not path.with_suffix(".zip").exists():
        raise FileNotFoundError(f"no SB3 model at {path}")
    if algo is None:
        algo = algo_of_file(path)
        if algo is None:
            raise ValueError(f"cannot infer the algorithm from {path.name!r}; pass algo='ppo', 'sac', 'rppo' or "
                             "'mppo'")
    return _algo_class(algo).load(str(path), env=env, device="cpu")


#: ``<algo>_<steps>_steps.zip``: how SB3's ``CheckpointCallback`` (and :func:`train`) name checkpoints
_CHECKPOINT = re.compile(r"^(?P<algo>[a-z0-9]+)_(?P<steps>\d+)_steps\.zip$")


def checkpoint_steps(path: str | os.PathLike) -> int | None:
    """The step count in a checkpoint's name (``ppo_20000_steps.zip``: 20000); None for another name (a final
    model)."""
    m = _CHECKPOINT.match(Path(path).name)
    return int(m["steps"]) if m else None


def latest_checkpoint(run_dir: str | os.PathLike, algo: str | None = None) -> Path | None:
    """The ``<algo>_<steps>_steps.zip`` with the most steps in ``<run_dir>/checkpoints`` (or in ``run_dir``
    itself when it has no ``checkpoints`` folder); ``None`` when there is none."""
    run_dir = Path(run_dir)
    folder = run_dir / "checkpoints" if (run_dir / "checkpoints").is_dir() else run_dir
    found = []
    for p in folder.glob("*_steps.zip"):
        m = _CHECKPOINT.match(p.name)
        if m and m["algo"] in ALGOS and (algo is None or m["algo"] == algo.lower()):
            found.append((int(m["steps"]), p))
    return max(found)[1] if found else None


def checkpoint_extras(path: str | os.PathLike) -> dict[str, Path]:
    """The files saved with checkpoint ``path`` that exist: ``"replay_buffer"`` (SAC) and ``"vecnormalize"``
    (``<algo>_replay_buffer_<steps>_steps.pkl`` as ``CheckpointCallback`` names them, or the older
    ``<checkpoint>_replay_buffer.pkl``)."""
    path = Path(path)
    m = _CHECKPOINT.match(path.name)
    out = {}
    for kind in ("replay_buffer", "vecnormalize"):
        cands = [path.with_name(f"{m['algo']}_{kind}_{m['steps']}_steps.pkl")] if m else []
        cands.append(Path(str(path).removesuffix(".zip") + f"_{kind}.pkl"))
        hit = next((c for c in cands if c.exists()), None)
        if hit is not None:
            out[kind] = hit
    return out


#: the algorithms that learn from a replay buffer, which a resume needs beside its checkpoint
_OFF_POLICY = ("sac",)


def replay_buffer_problem(checkpoint: str | os.PathLike, algo: str) -> str | None:
    """Why ``algo``'s ``checkpoint`` cannot be resumed for want of its replay buffer (SAC: without it the run would go
    on as another one), or None (a buffer is beside it, or ``algo`` keeps none). :func:`train` refuses such a
    resume, and ``train.py`` before any run file is written."""
    if algo.lower() not in _OFF_POLICY or "replay_buffer" in checkpoint_extras(checkpoint):
        return None
    return (f"checkpoint {checkpoint} has no replay buffer beside it ({Path(checkpoint).name} from a run killed while "
            "saving?); delete it (and any later ones) and resume from the one before it")


def replay_envs_problem(algo: str, saved: int | None, n_envs: int) -> str | None:
    """Why ``algo``'s checkpoint trained with ``saved`` envs cannot go on with ``n_envs``, or None (the same count,
    ``saved`` unknown, or ``algo`` keeps no replay buffer). SAC's replay buffer holds ``saved`` envs' transitions per
    step (stable-baselines3 shapes it ``(buffer_size // n_envs, n_envs, ...)``) and cannot store a step of another
    count: the resumed run failed at its first stored step. :func:`train` refuses such a resume, and ``train.py``
    before any run file is written."""
    if algo.lower() not in _OFF_POLICY or saved is None or int(saved) == int(n_envs):
        return None
    return (f"was trained with --n-envs {saved}, got {n_envs} ({algo.upper()}'s replay buffer holds {saved} envs' "
            f"transitions per step; resume with --n-envs {saved})")


class TrainingInterrupted(Exception):
    """Learning stopped early (a signal, a dead env worker); the state was saved to ``path`` first."""

    def __init__(self, reason: str, path: Path, num_timesteps: int, exit_code: int):
        super().__init__(f"{reason}: saved {path} at {num_timesteps} steps")
        self.reason, self.path, self.num_timesteps, self.exit_code = reason, path, num_timesteps, exit_code


def _run_guard(save_path: Path, algo: str, checkpoint_freq: int, max_minutes: float | None):
    from stable_baselines3.common.callbacks import CheckpointCallback

    class RunGuard(CheckpointCallback):
        """Checkpoints and clean stops at *consistent* points only, where the model has learned from every
        counted step: the start of a rollout (PPO: after the update on the previous rollout; SAC: after the
        gradient step on the last stored transition) and the end of learning.

        * a checkpoint whenever ``num_timesteps`` passed a multiple of ``checkpoint_freq`` (env steps summed
          over the envs, whatever step the run resumed from), with the SAC replay buffer and any
          ``VecNormalize`` statistics, named as SB3's ``CheckpointCallback`` names them;
        * :meth:`request_stop` (a signal handler) or the ``max_minutes`` deadline: the next env step returns
          ``False`` and ``num_timesteps`` is rewound to the last consistent point (the unfinished rollout is
          dropped), so a run resumed from the saved state counts every step it learned from exactly once.

        ``updating`` is True from the end of a rollout to the start of the next one, while the model learns from it
        (PPO's epochs, SAC's gradient steps): a second signal then waits for the update's end (a stop at once there
        saved a model half-way through an update under the rollout's starting step count).
        """

        def __init__(self) -> None:
            super().__init__(save_freq=checkpoint_freq, save_path=str(save_path), name_prefix=algo,
                             save_replay_buffer=True, save_vecnormalize=True)
            self.stop_reason: str | None = None
            self.signum: int | None = None
            self.stopped = False  # learn() was stopped early (not: reached total_timesteps)
            self._safe: int | None = None
            self._buffer_at: tuple[int, bool] | None = None  # the replay buffer's (pos, full) at _safe
            self._saved_at = -1
            self.saving = False  # inside save(): a signal now is deferred to its end
            self.updating = False  # learning from the last rollout: a second signal now is deferred to its end

        def request_stop(self, reason: str, signum: int | None = None) -> None:
            if self.stop_reason is None:
                self.stop_reason, self.signum = reason, signum

        def _on_training_start(self) -> None:
            self._t_start = time.monotonic()
            self._deadline = time.monotonic() + 60.0 * max_minutes if max_minutes else None
            self._safe = self.model.num_timesteps
            self._buffer_at = self._buffer_position()
            self._next = (self._safe // self.save_freq + 1) * self.save_freq

        def _buffer_position(self) -> tuple[int, bool] | None:
            buffer = getattr(self.model, "replay_buffer", None)
            return None if buffer is None else (buffer.pos, buffer.full)

        def _on_rollout_start(self) -> None:
            self.updating = False
            self._safe = self.model.num_timesteps
            self._buffer_at = self._buffer_position()
            if self._safe >= self._next:
                path = self.save()
                self._next = (self._safe // self.save_freq + 1) * self.save_freq
                # a line per checkpoint: progress in a log file, where no progress bar is drawn
                print(f"[train] {self._safe} steps, {time.monotonic() - self._t_start:.0f} s: saved {path.name}",
                      flush=True)

        def _on_step(self) -> bool:
            if self.stop_reason is None and self._deadline is not None and time.monotonic() >= self._deadline:
                self.request_stop("time limit")
            if self.stop_reason is not None:
                self.stopped = True
                self.rewind()
                return False
            return True

        def _on_rollout_end(self) -> None:
            self.updating = True  # the update on this rollout comes next

        def _on_training_end(self) -> None:
            self.updating = False
            if not self.stopped:
                self._on_rollout_start()  # the last update is done

        def rewind(self) -> None:
            """Back to the last consistent step count (after an early stop or an exception in learn()), and an
            off-policy replay buffer back to where it stood then: with ``train_freq > 1`` a rollout stores
            transitions before its stop, which the saved buffer kept although their steps were not counted (a
            resume stored those steps again)."""
            if self._safe is not None:
                self.model.num_timesteps = self._safe
            buffer = getattr(self.model, "replay_buffer", None)
            if buffer is not None and self._buffer_at is not None:
                buffer.pos, buffer.full = self._buffer_at

        def save(self) -> Path:
            """Save the model (and replay buffer / VecNormalize) as ``<algo>_<num_timesteps>_steps.zip``.

            Each file is written under a temporary name and moved into place, the model's zip last: a checkpoint
            :func:`latest_checkpoint` finds is whole, with its extras. A signal during the save waits for it
            (``saving``, read by :func:`_stop_on_signals`)."""
            self.num_timesteps = self.model.num_timesteps  # the file names use it
            path = Path(self._checkpoint_path(extension="zip"))
            if self._saved_at != self.num_timesteps:
                with self.signals_deferred():
                    if getattr(self.model, "replay_buffer", None) is not None:
                        _save_atomic(self._checkpoint_path("replay_buffer_", extension="pkl"),
                                     self.model.save_replay_buffer)
                    vec_normalize = self.model.get_vec_normalize_env()
                    if vec_normalize is not None:  # what VecNormalize.save writes (it takes a path only)
                        _save_atomic(self._checkpoint_path("vecnormalize_", extension="pkl"),
                                     lambda fh: pickle.dump(vec_normalize, fh))
                    _save_atomic(path, self.model.save)
                self._saved_at = self.num_timesteps
            return path

        @contextlib.contextmanager
        def signals_deferred(self):
            """A SIGINT / SIGTERM during the block waits for its end (``saving``, read by :func:`_stop_on_signals`):
            the files it writes are whole."""
            self.saving = True
            try:
                yield
            finally:
                self.saving = False

    return RunGuard()


def _save_atomic(path, save) -> None:
    """``save(fh)`` into ``path`` through :func:`haptic_env.cache.atomic_write` (a hidden temporary file that no
    checkpoint search matches, moved into place when whole): a kill mid-write leaves no file under the final name.
    ``save`` writes a binary file object: SB3's ``model.save`` and ``save_replay_buffer`` take one."""
    from haptic_env.cache import atomic_write

    with atomic_write(path) as fh:
        save(fh)


@contextlib.contextmanager
def handling_signals(handler: Callable[[int, Any], None]):
    """SIGINT and SIGTERM go to ``handler(signum, frame)`` inside the block and back to their previous handlers after
    it; outside the main thread, where Python allows no handlers, nothing changes."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextlib.contextmanager
def _stop_on_signals(guard):
    """SIGINT / SIGTERM ask ``guard`` to stop at the next env step; a second one raises KeyboardInterrupt, except
    while a checkpoint is written or the model learns from a rollout (``guard.updating``): those finish first, and the
    run stops at the env step after them."""
    import signal

    def handler(signum, frame):
        if guard.stop_reason is not None and guard.signum is not None:
            if guard.saving:  # a checkpoint being written: let it finish (the run stops right after)
                return
            if guard.updating:  # a model half-way through an update is no state to save: the update finishes
                print(f"[train] {signal.Signals(signum).name} again: the update in progress finishes first, then "
                      "the run stops and saves", file=sys.stderr, flush=True)
                return
            raise KeyboardInterrupt
        guard.request_stop(signal.Signals(signum).name, signum)

    with handling_signals(handler):
        yield


def close_vec_env(venv) -> None:
    """``venv.close()``; when that fails (a worker died) terminate the other workers (SIGKILL after 5 s)
    and close the pipes."""
    try:
        venv.close()
    except (EOFError, OSError):
        for p in getattr(venv, "processes", []):
            if p.is_alive():
                p.terminate()
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
                p.join(timeout=5)
        for remote in getattr(venv, "remotes", []):
            with contextlib.suppress(OSError):
                remote.close()
        venv.closed = True


def train(algo: str, venv, total_timesteps: int, log_dir: str | os.PathLike, *, seed: int = 0,
          checkpoint_freq: int = 10_000, resume: str | os.PathLike | None = None, progress_bar: bool = False,
          verbose: int = 0, max_minutes: float | None = None, **hyperparams: Any):
    """Train (or resume) up to ``total_timesteps`` and save ``<log_dir>/<algo>_final.zip``; returns
    ``(model, path)``.

    ``checkpoint_freq`` is in env steps summed over the envs. With ``resume`` (a checkpoint ``.zip``) the model,
    its SAC replay buffer and any ``VecNormalize`` statistics saved with it (:func:`checkpoint_extras`) are
    loaded and learning continues from the checkpoint's step count (``reset_num_timesteps=False``: the same
    TensorBoard run folder, ``num_timesteps`` goes on) until ``total_timesteps`` in all, so an interrupted run
    resumed with the same settings ends at the same step count. A resumed model's random numbers (torch, NumPy,
    Python's, the action space's) are seeded with ``seed``: stable-baselines3's load seeds them with the
    checkpoint's seed, which would replay the first segment's draws, so a caller gives each resumed segment a seed
    of its own (``train.segment_seeds``), as it gives its envs their seeds. ``max_minutes`` stops learning early
    after that much wall-clock time (a checkpoint and the final model are saved). SIGINT / SIGTERM (a second one:
    at once) or a dead ``SubprocVecEnv`` worker (``EOFError``, ``BrokenPipeError``, ``ConnectionResetError``) stop
    learning, save a checkpoint (see ``RunGuard`` in :func:`_run_guard`) and raise :class:`TrainingInterrupted`
    naming it; closing ``venv`` is left to the caller (:func:`close_vec_env`).
    """
    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    algo = algo.lower()
    env_seeds = list(venv.unwrapped._seeds)  # the caller's: SB3 replaces them when it builds or loads the model
    if resume is not None:
        problem = replay_buffer_problem(resume, algo)
        if problem is not None:
            raise ValueError(problem)
        extras = checkpoint_extras(resume)
        if "vecnormalize" in extras:  # the saved statistics, into the caller's VecNormalize or a new one
            from stable_baselines3.common.vec_env import VecNormalize

            inner = venv.venv if isinstance(venv, VecNormalize) else venv
            loaded = VecNormalize.load(str(extras["vecnormalize"]), inner)
            if isinstance(venv, VecNormalize):
                venv.obs_rms, venv.ret_rms = loaded.obs_rms, loaded.ret_rms
            else:
                venv = loaded
        model = load_model(resume, algo, env=venv)
        model.verbose = verbose  # this segment's (SB3's load restored the checkpoint's)
        model.set_random_seed(seed)  # not the checkpoint's seed again (SB3's load set it): this segment's
        model.tensorboard_log = str(log_dir / "tb")
        if "replay_buffer" in extras and hasattr(model, "load_replay_buffer"):  # SAC's (replay_buffer_problem)
            model.load_replay_buffer(str(extras["replay_buffer"]))
            problem = replay_envs_problem(algo, model.replay_buffer.n_envs, venv.num_envs)
            if problem is not None:
                raise ValueError(f"{resume} {problem}")
    else:
        model = build_model(algo, venv, seed=seed, log_dir=log_dir, verbose=verbose, **hyperparams)
    # SB3 seeds the model's env with the model's seed + rank (set_random_seed in _setup_model), which would replay the
    # evaluation seeds' episodes (test 0-4); the envs start where the caller seeded them (make_vec_env's seed)
    venv.unwrapped._seeds = env_seeds
    guard = _run_guard(log_dir / "checkpoints", algo, checkpoint_freq, max_minutes)
    failure = None  # (reason, exit code) of an exception that ended learn()
    with _stop_on_signals(guard):  # also covers the final save: a signal then lets it finish
        remaining = total_timesteps - model.num_timesteps
        model._num_timesteps_at_start = model.num_timesteps  # learn() sets it too; kept when it has nothing to do
        if remaining > 0:
            try:
                with warnings.catch_warnings():  # SB3's bar is tqdm.rich, which warns that it is experimental
                    warnings.filterwarnings("ignore", message="rich is experimental")
                    model.learn(total_timesteps=remaining, callback=guard, reset_num_timesteps=resume is None,
                                tb_log_name=algo, progress_bar=progress_bar)
            except (EOFError, BrokenPipeError, ConnectionResetError) as exc:
                by = f"stopped by {guard.stop_reason}; " if guard.signum is not None else ""
                failure = (f"{by}an env worker died ({type(exc).__name__})",
                           128 + guard.signum if guard.signum is not None else 1)
            except KeyboardInterrupt:
                failure = (f"{guard.stop_reason or 'SIGINT'} (twice: stopped at once)",
                           128 + (guard.signum or 2))
            finally:
                with contextlib.suppress(Exception):
                    model.logger.close()  # flush the TensorBoard events
        if failure is not None or (guard.stopped and guard.signum is not None):
            if getattr(guard, "model", None) is None:  # learn() failed before SB3 set up the callback (the envs' reset)
                guard.init_callback(model)
            guard.rewind()
            reason, code = failure or (f"stopped by {guard.stop_reason}", 128 + guard.signum)
            raise TrainingInterrupted(reason, guard.save(), int(model.num_timesteps), code)
        if guard.stopped:  # time limit: a checkpoint to resume from, and the final model
            guard.save()
        path = log_dir / f"{algo}_final.zip"
        with guard.signals_deferred():  # a signal now lets the final model finish
            _save_atomic(path, model.save)
    return model, path


class SB3Agent:
    """A trained SB3 model acting deterministically (the mean action; a categorical policy: its most probable
    approach). A recurrent model (``rppo``) keeps its LSTM state through an episode; :meth:`reset` clears it, so
    every episode starts from the state it was trained to. A model trained with a ``Discrete(N)`` action
    (:class:`DiscreteApproaches`) acts with :func:`approach_table`'s row of its choice.

    ``no_repeat`` (a categorical, non-recurrent policy only): the agent does not choose an approach twice while the
    belief stays the same; it takes its most probable approach among those it has not tried since the belief last
    changed (sampled: draws among them, in proportion to the policy's probabilities). A grasp that touches with too
    few fingers leaves the belief as it was, and the observation nearly so, so a deterministic policy may choose the
    same approach again (or two in turn), with the object's pose fixed get the same grasp, and so on up to the
    episode's cap; with ``no_repeat`` it moves on. Deterministic, it acts as without until it would repeat an
    approach at an unchanged belief. The belief is read from the observation's ``belief`` part
    (``env.unwrapped.task.obs_slices``); the rule is :class:`RepeatTracker`'s. A model trained with that mask
    (``mppo``, :class:`RepeatMask`) always acts with it, whatever ``no_repeat`` says: it is part of its policy. A
    ``ValueError`` names a model it does not apply to."""

    def __init__(self, model, name: str | None = None, deterministic: bool = True, no_repeat: bool = False):
        self.model = model
        self.name = name or type(model).__name__.lower()
        self.deterministic = deterministic
        self.recurrent = hasattr(model.policy, "lstm_actor")
        space = model.action_space
        # the approaches of a categorical policy; their dimension follows the env the agent acts in (:meth:`_row`)
        self.table = approach_table(space.n) if isinstance(space, gym.spaces.Discrete) else None
        if no_repeat and (self.table is None or self.recurrent):
            kind = "a recurrent policy" if self.recurrent else f"an action space {space}"
            raise ValueError(f"no_repeat (evaluate --no-repeat) needs a categorical policy without memory (ppo trained "
                             f"with --discrete-approaches); the model of agent {self.name!r} has {kind}")
        self.masked = _is_maskable(model)  # trained with RepeatMask: its mask is its policy's
        self.no_repeat = bool(no_repeat) or self.masked
        self.tracker = RepeatTracker(len(self.table)) if self.no_repeat else None
        self._clear_memory()

    @classmethod
    def from_path(cls, path: str | os.PathLike, algo: str | None = None, name: str | None = None) -> "SB3Agent":
        return cls(load_model(path, algo), name=name)

    def reset(self, env: Any, seed: int | None = None) -> None:
        if seed is not None:
            # not SB3's set_random_seed, which seeds Python's, NumPy's and torch's global generators: a deterministic
            # policy draws nothing, and a stochastic one samples from torch's (SB3's distributions know no other)
            self.model.action_space.seed(seed)
            if not self.deterministic:
                import torch

                torch.manual_seed(seed)
        self._clear_memory()

    def _clear_memory(self) -> None:
        """A recurrent model's LSTM state back to an episode's start (no state, ``episode_start`` set), and no
        belief seen yet."""
        self._state, self._start = None, np.ones((1,), dtype=bool)
        if self.tracker is not None:
            self.tracker.clear()

    def _untried_choice(self, obs: np.ndarray) -> int:
        """The policy's choice among the approaches the tracker allows (not tried at this belief): the largest logit
        among them, or a draw from its probabilities renormalised over them, with SB3's seeded torch generator (on
        the logits, so that an allowed approach whose probability underflows to 0 keeps its rank, as in
        MaskablePPO's own masked distribution)."""
        import torch as th

        self.model.policy.set_training_mode(False)  # as SB3's predict does
        obs_t, _ = self.model.policy.obs_to_tensor(np.asarray(obs))
        with th.no_grad():
            logits = self.model.policy.get_distribution(obs_t).distribution.logits[0].clone()
        logits[th.as_tensor(~self.tracker.mask())] = -th.inf
        if self.deterministic:
            return int(th.argmax(logits))
        return int(th.multinomial(th.softmax(logits, dim=0), 1)[0])

    def act(self, obs: np.ndarray, env: Any) -> np.ndarray:
        if self.no_repeat:
            obs = np.asarray(obs)
            self.tracker.see(obs[env.unwrapped.task.obs_slices["belief"]])
            i = self._untried_choice(obs)
            self.tracker.add(i)
            return self._row(i, env)
        if not self.recurrent:
            action, _ = self.model.predict(np.asarray(obs), deterministic=self.deterministic)
        else:
            action, self._state = self.model.predict(np.asarray(obs)[None], state=self._state,
                                                     episode_start=self._start, deterministic=self.deterministic)
            self._start = np.zeros((1,), dtype=bool)
            action = action[0]
        if self.table is not None:
            return self._row(int(np.asarray(action).reshape(-1)[0]), env)
        return np.asarray(action, dtype=np.float32)

    def _row(self, i: int, env: Any) -> np.ndarray:
        """Approach ``i`` of the table as :class:`DiscreteApproaches` built it in training (:func:`approaches_for` of
        ``env``'s action space; built again only when that space's dimension differs from the last one's)."""
        if self.table.shape[1:] != (int(np.prod(env.action_space.shape)),):
            self.table = approaches_for(len(self.table), env.action_space)
        return self.table[i].copy()
