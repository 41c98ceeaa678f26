"""Stable-Baselines3 PPO / SAC on :class:`haptic_env.env.HapticRecogEnv`.

* :func:`make_vec_env` — ``n_envs`` copies (``SubprocVecEnv`` or ``DummyVecEnv``), each wrapped in a
  ``Monitor`` writing ``<log_dir>/monitor/<rank>.monitor.csv`` (with the episode's ``correct`` and
  ``grasps``), seeded ``seed + rank``.
* :func:`build_model` — PPO or SAC with TensorBoard logs under ``<log_dir>/tb``.
* :func:`train` — learn with a ``CheckpointCallback`` (``<log_dir>/checkpoints/<algo>_<steps>_steps.zip``),
  optionally resuming from a checkpoint (its step counter continues), and save ``<log_dir>/<algo>_final.zip``.
* :class:`SB3Agent` — a trained model as an :class:`agents.base.Agent` for :mod:`agents.evaluate`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = ["ALGOS", "DEFAULT_HYPERPARAMS", "make_vec_env", "build_model", "load_model", "train", "SB3Agent"]

ALGOS = ("ppo", "sac")

#: Defaults tuned for short episodes (a handful of grasps) and a cheap env; override per key.
DEFAULT_HYPERPARAMS: dict[str, dict[str, Any]] = {
    "ppo": dict(n_steps=256, batch_size=128, n_epochs=10, learning_rate=3e-4, gamma=0.95, gae_lambda=0.95,
                ent_coef=0.0, clip_range=0.2, policy_kwargs=dict(net_arch=[64, 64])),
    "sac": dict(buffer_size=100_000, learning_starts=1_000, batch_size=256, learning_rate=3e-4, gamma=0.95,
                tau=0.01, train_freq=1, gradient_steps=1, policy_kwargs=dict(net_arch=[64, 64])),
}


def _algo_class(algo: str):
    from stable_baselines3 import PPO, SAC

    algo = algo.lower()
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    return {"ppo": PPO, "sac": SAC}[algo]


def _env_fn(config, rank: int, monitor_dir: str | None, env_id: str) -> Callable[[], Any]:
    def _init():
        os.environ.setdefault("OMP_NUM_THREADS", "1")
        import haptic_env
        from stable_baselines3.common.monitor import Monitor

        env = haptic_env.make(config, env_id=env_id)
        path = os.path.join(monitor_dir, str(rank)) if monitor_dir else None
        return Monitor(env, filename=path, info_keywords=("correct", "grasps"))

    return _init


def make_vec_env(config=None, n_envs: int = 2, seed: int = 0, log_dir: str | os.PathLike | None = None,
                 vec: str = "subproc", env_id: str = "HapticRecog-v0"):
    """``n_envs`` monitored copies of the env. ``vec="subproc"`` runs each in its own process."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    from haptic_env.env import HapticRecogConfig, get_recognizer

    if vec not in ("subproc", "dummy"):
        raise ValueError(f"vec must be 'subproc' or 'dummy', got {vec!r}")
    config = config or HapticRecogConfig()
    monitor_dir = None
    if log_dir is not None:
        monitor_dir = str(Path(log_dir) / "monitor")
        Path(monitor_dir).mkdir(parents=True, exist_ok=True)
    if vec == "subproc":
        # build (or load) the recogniser once here so the workers only read the cache
        import haptic_env

        probe = haptic_env.make(config, env_id=env_id).unwrapped
        get_recognizer(probe.objects, probe.config)
        probe.close()
    fns = [_env_fn(config, i, monitor_dir, env_id) for i in range(n_envs)]
    venv = SubprocVecEnv(fns) if vec == "subproc" and n_envs > 1 else DummyVecEnv(fns)
    venv.seed(seed)
    venv.action_space.seed(seed)
    return venv


def build_model(algo: str, venv, seed: int = 0, log_dir: str | os.PathLike | None = None, verbose: int = 0,
                **hyperparams: Any):
    """A fresh PPO/SAC model on ``venv`` (:data:`DEFAULT_HYPERPARAMS` updated with ``hyperparams``)."""
    cls = _algo_class(algo)
    params = {**DEFAULT_HYPERPARAMS[algo.lower()], **hyperparams}
    tb = str(Path(log_dir) / "tb") if log_dir is not None else None
    return cls("MlpPolicy", venv, seed=seed, tensorboard_log=tb, verbose=verbose, device="cpu", **params)


def load_model(path: str | os.PathLike, algo: str | None = None, env=None):
    """Load a saved model; ``algo`` is inferred from the file name (``ppo_*``/``sac_*``) when omitted."""
    path = Path(path)
    if not path.exists() and not path.with_suffix(".zip").exists():
        raise FileNotFoundError(f"no SB3 model at {path}")
    if algo is None:
        stem = path.name.lower()
        algo = next((a for a in ALGOS if stem.startswith(a)), None)
        if algo is None:
            raise ValueError(f"cannot infer the algorithm from {path.name!r}; pass algo='ppo' or 'sac'")
    return _algo_class(algo).load(str(path), env=env, device="cpu")


def _time_limit_callback(max_minutes: float):
    from stable_baselines3.common.callbacks import BaseCallback

    class TimeLimit(BaseCallback):
        """Stop learning after ``max_minutes`` of wall-clock time (the model is then saved as usual)."""

        def _on_training_start(self) -> None:
            import time

            self._deadline = time.monotonic() + 60.0 * max_minutes

        def _on_step(self) -> bool:
            import time

            return time.monotonic() < self._deadline

    return TimeLimit()


def train(algo: str, venv, total_timesteps: int, log_dir: str | os.PathLike, *, seed: int = 0,
          checkpoint_freq: int = 10_000, resume: str | os.PathLike | None = None, progress_bar: bool = False,
          verbose: int = 0, max_minutes: float | None = None, **hyperparams: Any):
    """Train (or resume) and save ``<log_dir>/<algo>_final.zip``; returns ``(model, path)``.

    ``checkpoint_freq`` is in env steps summed over the envs; with ``resume`` the model (and, for SAC, its
    replay buffer if ``<checkpoint>_replay_buffer.pkl`` exists) continues from the checkpoint's step count.
    ``max_minutes`` stops learning early after that much wall-clock time.
    """
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback

    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    if resume is not None:
        model = load_model(resume, algo, env=venv)
        model.tensorboard_log = str(log_dir / "tb")
        buf = Path(str(resume).removesuffix(".zip") + "_replay_buffer.pkl")
        if algo.lower() == "sac" and buf.exists():
            model.load_replay_buffer(str(buf))
    else:
        model = build_model(algo, venv, seed=seed, log_dir=log_dir, verbose=verbose, **hyperparams)
    ckpt = CheckpointCallback(
        save_freq=max(1, checkpoint_freq // venv.num_envs), save_path=str(log_dir / "checkpoints"),
        name_prefix=algo.lower(), save_replay_buffer=algo.lower() == "sac",
    )
    callbacks = [ckpt] + ([_time_limit_callback(max_minutes)] if max_minutes else [])
    model.learn(total_timesteps=total_timesteps, callback=CallbackList(callbacks), reset_num_timesteps=resume is None,
                tb_log_name=algo.lower(), progress_bar=progress_bar)
    path = log_dir / f"{algo.lower()}_final.zip"
    model.save(str(path))
    return model, path


class SB3Agent:
    """A trained SB3 model acting deterministically (the mean action)."""

    def __init__(self, model, name: str | None = None, deterministic: bool = True):
        self.model = model
        self.name = name or type(model).__name__.lower()
        self.deterministic = deterministic

    @classmethod
    def from_path(cls, path: str | os.PathLike, algo: str | None = None, name: str | None = None) -> "SB3Agent":
        return cls(load_model(path, algo), name=name)

    def reset(self, env: Any, seed: int | None = None) -> None:
        if seed is not None:
            self.model.set_random_seed(seed)

    def act(self, obs: np.ndarray, env: Any) -> np.ndarray:
        action, _ = self.model.predict(np.asarray(obs), deterministic=self.deterministic)
        return np.asarray(action, dtype=np.float32)
