"""Uniformly random approaches: the baseline every policy is compared with."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["RandomAgent"]


class RandomAgent:
    """Samples each action uniformly from the action box with its own ``np.random.Generator``."""

    name = "random"

    def __init__(self, seed: int | None = None):
        self._rng = np.random.default_rng(seed)

    def reset(self, env: Any, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def act(self, obs: np.ndarray, env: Any) -> np.ndarray:
        space = env.action_space
        return self._rng.uniform(space.low, space.high).astype(space.dtype)
