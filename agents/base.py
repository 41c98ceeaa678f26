"""The agent interface shared by every policy that :mod:`agents.evaluate` can run.

An agent is anything with

``name: str``
    label in tables and plots;
``reset(env, seed: int | None) -> None``
    called after ``env.reset()`` at the start of every episode (``seed`` only on the first episode of
    a run, so a run of episodes is reproducible);
``act(obs: np.ndarray, env) -> np.ndarray``
    the next action, shape ``env.action_space.shape``, in ``[-1, 1]``.

``env`` is the (possibly wrapped) :class:`haptic_env.env.HapticRecogEnv`; agents that need more than
the observation (e.g. :class:`agents.greedy.GreedyInfoGainAgent`) read ``env.unwrapped``.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["Agent"]


@runtime_checkable
class Agent(Protocol):
    name: str

    def reset(self, env: Any, seed: int | None = None) -> None: ...

    def act(self, obs: np.ndarray, env: Any) -> np.ndarray: ...
