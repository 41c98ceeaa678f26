"""A thin Stable-Baselines3 ``VecEnv`` over the native :class:`~haptic_env.vector_env.HapticRecogVectorEnv`.

``train.py --vec native`` (through :func:`agents.sb3.make_vec_env`) trains on it. The vector env runs in
``"same_step"`` autoreset mode, which is SB3's convention; this adapter only renames: ``terminated | truncated``
-> ``dones``, Gymnasium's ``info["final_obs"]`` -> ``infos[i]["terminal_observation"]``,
``infos[i]["TimeLimit.truncated"]``, and a list of per-sub-env info dicts at every step (the single env's keys and
values, as ``DummyVecEnv`` gives them; an episode's last step: its final info). It also does
SB3 ``Monitor``'s job for every sub-env: ``infos[i]["episode"] = {"r", "l", "t"}`` at an episode's end and, with a
``monitor_dir``, ``<monitor_dir>/<rank><suffix>.monitor.csv`` per sub-env with the same columns as the
``SubprocVecEnv`` run's (``r, l, t, correct, grasps``), so ``evaluate --learning-curves`` reads either.
``set_options`` (an ``"object"`` per sub-env) applies to the next ``reset()`` and ``reset_infos`` holds each
sub-env's last reset info (an autoreset's too), as in ``DummyVecEnv``.

Seeding as SB3's ``DummyVecEnv``: ``seed(s)`` then ``reset()`` seeds sub-env ``i`` with ``s + i`` (the native env's
scheme, see :mod:`haptic_env.vector_env`), so with the same actions it steps exactly like ``DummyVecEnv`` /
``SubprocVecEnv`` of ``num_envs`` single envs seeded ``s + rank``.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

__all__ = ["NativeVecEnv"]


class NativeVecEnv(VecEnv):
    """SB3 ``VecEnv`` of a :class:`HapticRecogVectorEnv` (which must autoreset in ``"same_step"`` mode)."""

    def __init__(self, venv, monitor_dir: str | os.PathLike | None = None, monitor_suffix: str = "",
                 env_id: str = "HapticRecog-v0", info_keywords: tuple[str, ...] = ("correct", "grasps")):
        from gymnasium.vector import AutoresetMode

        if venv.autoreset_mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"NativeVecEnv needs the vector env in 'same_step' autoreset mode, got {venv.autoreset_mode}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.info_keywords = tuple(info_keywords)
        self._actions: np.ndarray | None = None
        self._t_start = time.time()
        self._ep_return = np.zeros(self.num_envs)
        self._ep_len = np.zeros(self.num_envs, dtype=np.int64)
        self._writers = None
        if monitor_dir is not None:
            from stable_baselines3.common.monitor import ResultsWriter

            self._writers = [ResultsWriter(os.path.join(str(monitor_dir), f"{i}{monitor_suffix}"),
                                           header={"t_start": self._t_start, "env_id": env_id},
                                           extra_keys=self.info_keywords) for i in range(self.num_envs)]

    def reset(self):
        from haptic_env.scene import reset_options

        # set_options' per-sub-env options (DummyVecEnv passes each its own; checked as the single env checks them)
        objects = [reset_options(o, ("object",)).get("object") for o in self._options]
        options = {"object": objects} if any(o is not None for o in objects) else None
        obs, info = self.venv.reset(seed=list(self._seeds) if any(s is not None for s in self._seeds) else None,
                                    options=options)
        self.reset_infos = _rows(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        self._ep_return[:] = 0.0
        self._ep_len[:] = 0
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.num_envs, -1)

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        self._ep_return += rewards
        self._ep_len += 1
        infos = _rows(info, self.num_envs)  # a sub-env whose episode goes on: its step's info, as DummyVecEnv's
        for i in np.flatnonzero(dones).tolist():  # an autoreset's info, which DummyVecEnv keeps in reset_infos
            self.reset_infos[i] = dict(infos[i])
        for fi in infos:
            fi["TimeLimit.truncated"] = False  # DummyVecEnv sets it at every step (an ending one's: below)
        if dones.any():
            final = _rows(info["final_info"], self.num_envs)
            now = round(time.time() - self._t_start, 6)
            for i in np.flatnonzero(dones).tolist():
                fi = final[i]
                fi["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                fi["terminal_observation"] = info["final_obs"][i]
                ep = {"r": round(float(self._ep_return[i]), 6), "l": int(self._ep_len[i]), "t": now}
                for key in self.info_keywords:
                    ep[key] = fi[key]
                fi["episode"] = ep
                if self._writers is not None:
                    self._writers[i].write_row(ep)
                infos[i] = fi
                self._ep_return[i] = 0.0
                self._ep_len[i] = 0
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        if self._writers is not None:
            for w in self._writers:
                w.close()
            self._writers = None
        self.venv.close()

    # --- the VecEnv attribute API (one shared env object: every index answers the same) -----------------------
    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.venv, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return [getattr(self.venv, method_name)(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self):
        raise NotImplementedError("the native vector env does not render")


def _rows(info: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """The ``n`` sub-envs' entries of a Gymnasium vector info (each where its ``_<key>`` mask is set) as plain dicts:
    Python scalars, and arrays of their own (rows of a copy, not views of the env's buffers). Column by column
    (``tolist``), which costs a fraction of a row-by-row walk."""
    keys, cols, masks = [], [], []
    for key, value in info.items():
        if key.startswith("_") or key in ("final_obs", "final_info"):
            continue
        mask = info.get("_" + key)
        keys.append(key)
        masks.append(None if mask is None else np.asarray(mask).tolist())
        if isinstance(value, dict):
            cols.append(_rows(value, n))
        elif isinstance(value, np.ndarray) and value.ndim > 1:
            cols.append(list(value.copy()))
        else:
            cols.append(value.tolist() if isinstance(value, np.ndarray) else list(value))
    return [{k: c[i] for k, c, m in zip(keys, cols, masks) if m is None or m[i]} for i in range(n)]
