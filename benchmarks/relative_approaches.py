"""Does turning each approach relative to the last one beat random approaches? (issue 5, PPO's reference points)

A pose-blind policy on the hand envs cannot aim an approach at the object's unknown yaw, but it can choose the next
approach relative to its previous one ("grasp again from 90 degrees round"), which a learned policy could express
through ``prev_action`` in its observation. Scripted policies measure what that strategy is worth before any
training:

* ``random``: every action uniform in the action box (the baseline);
* ``turnT``: the first grasp random, each next one turned by ``T * pi`` about the vertical from the previous one, the
  other approach parameters (elevation, roll, spread) drawn anew;
* ``turnT-keep``: the same turn, the other parameters kept from the previous grasp (the same approach, turned).

Same env seeds, objects and poses for every policy (``haptic-recog evaluate``'s episodes, ``evaluate_agents``).

    OMP_NUM_THREADS=1 python benchmarks/relative_approaches.py --env-id HapticRecogMuJoCo-v0 \\
        --seeds 500 501 502 503 504 --episodes 40 --out results/hands/relative_approaches_val.md

Prints ``haptic-recog evaluate``'s markdown table (success at the stop, decided, grasps, fewer grasps than random,
with bootstrap CIs); the headline, the best turned policy against random, is printed last.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.evaluate import evaluate_agents, markdown_table, summarize
from agents.random_policy import RandomAgent
from haptic_env.cache import atomic_write
from haptic_env.cli import float_in, int_in, output_path
from haptic_env.splits import ENV_VALIDATION_SEEDS

importlib.import_module("haptic_env")  # registers the envs


class TurnedAgent(RandomAgent):
    """First grasp random; each next approach turned by ``turn * pi`` about the world z axis from the previous one
    (azimuth wrapped into ``[-1, 1)``); ``keep``: the other approach parameters repeated, else drawn anew."""

    def __init__(self, turn: float, keep: bool, seed: int | None = None):
        if not np.isfinite(turn):
            raise ValueError(f"turn must be finite, got {turn!r}")
        super().__init__(seed)
        self.turn, self.keep, self._prev = float(turn), bool(keep), None
        self.name = f"turn{turn:g}" + ("-keep" if keep else "")

    def reset(self, env, seed: int | None = None) -> None:
        super().reset(env, seed)
        self._prev = None

    def act(self, obs: np.ndarray, env) -> np.ndarray:
        a = super().act(obs, env)
        if self._prev is not None:
            if self.keep:
                a = self._prev.copy()
            a[0] = (self._prev[0] + self.turn + 1.0) % 2.0 - 1.0
        self._prev = a.astype(env.action_space.dtype)
        return self._prev


def main(argv=None) -> int:
    p = compare_parser(__doc__.split("\n\n")[0])
    p.add_argument("--turns", type=float_in(), nargs="+", default=[0.5, 1.0], help="turns in units of pi")
    a = p.parse_args(argv)
    agents = [RandomAgent()] + [TurnedAgent(t, k) for t in a.turns for k in (False, True)]
    compare(agents, a, "", "turned policy", argv)
    return 0


def compare_parser(description: str) -> argparse.ArgumentParser:
    """The arguments that :func:`compare` reads: ``--env-id``, ``--seeds``, ``--episodes``, ``--out``."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--env-id", default="HapticRecogMuJoCo-v0")
    p.add_argument("--seeds", type=int_in(0), nargs="+", default=list(ENV_VALIDATION_SEEDS),
                   help="env seeds (500-504: the hand envs' validation seeds)")
    p.add_argument("--episodes", type=int_in(1), default=40, help="episodes per seed")
    p.add_argument("--out", type=output_path("file"), default=None, help="also write the table to this markdown file")
    return p


def compare(agents, a: argparse.Namespace, note: str, what: str, argv=None) -> list[dict]:
    """Every agent on the same env seeds (``a.env_id``, ``a.seeds``, ``a.episodes``: the same objects and poses),
    ``agents[0]`` the random baseline; prints ``haptic-recog evaluate``'s table (``agents.evaluate.summarize``:
    success at the stop, grasps, fewer grasps than random, with bootstrap CIs) after a line naming the env and
    ``note``, writes it to ``a.out`` with the command when given, and prints the best ``what`` against random last.
    Shared by the scripted-policy benchmarks (``usable_approaches.py``). Returns the summary rows."""
    agents[0].name = "random"
    rows = summarize(evaluate_agents(agents, lambda: gym.make(a.env_id), a.episodes, a.seeds, progress=False))
    text = (f"`{a.env_id}`, env seeds {' '.join(map(str, a.seeds))}, {a.episodes} episodes each{note}\n\n"
            f"{markdown_table(rows)}")
    print(text)
    if a.out is not None:
        with atomic_write(a.out, "w") as fh:
            fh.write(f"python benchmarks/{Path(sys.argv[0]).name} {' '.join(argv or sys.argv[1:])}\n\n{text}\n")
    best = max(rows[1:], key=lambda r: r["fewer_than_random"])
    print(f"best {what}: {best['agent']}, {100 * best['fewer_than_random']:.1f} % fewer grasps than random "
          f"({100 * best['success']:.1f} % right at the stop against {100 * rows[0]['success']:.1f} %)")
    return rows


if __name__ == "__main__":
    sys.exit(main())
