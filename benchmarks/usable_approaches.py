"""Approaches that the hand's own training grasps say touch well: a pose-blind scripted policy (issue 5, PPO's
reference points).

The recogniser of a hand env is trained on the hand's MuJoCo grasps of the meshes under uniformly random approaches
(``recognizer_source="hand"``: the object at the identity pose). Those grasps also tell, from the meshes alone, how
often each approach touches with enough fingertips. The env turns the object by a random yaw, so a policy that
cannot see the pose gains nothing from the approach's azimuth, but it can prefer the elevation, roll and spread
that touch well on average over the objects. Policies (same env seeds, objects and poses for all,
``relative_approaches.compare``):

* ``random``: every action uniform in the action box (the baseline);
* ``best-complete`` / ``best-usable``: the (elevation, roll, spread) cell of a ``B x B x B`` grid with the highest
  rate of complete grasps (every fingertip touching) / of usable ones (>= 3 fingertips) in the training pool,
  uniform within the cell, the azimuth uniform;
* ``weighted``: cells drawn with probability proportional to their complete-grasp rate squared (a softer choice
  that keeps some variety), uniform within the cell, the azimuth uniform.

    OMP_NUM_THREADS=1 python benchmarks/usable_approaches.py --env-id HapticRecogMuJoCo-v0 \\
        --seeds 500 501 502 503 504 --episodes 40 --out results/hands/usable_approaches_val.md

Prints ``haptic-recog evaluate``'s markdown table (success at the stop, decided, grasps, fewer grasps than random,
with bootstrap CIs); the headline, the best scripted policy against random, last. The training pool is the env's own (cached; built on
the first make).
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.random_policy import RandomAgent
from haptic_env.config import recognizer_kwargs
from haptic_env.cli import int_in
from haptic_env.dataset import hand_pool
from haptic_env.grasping import usable_touch
from haptic_env.hand_grasps import pool_actions

importlib.import_module("haptic_env")  # registers the envs
sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling benchmark, also when imported by the tests
from relative_approaches import compare, compare_parser  # noqa: E402


#: grasps a cell needs for its rate to count (a best cell, a weight of the ``weighted`` agent)
MIN_CELL = 20


def cell_rates(env_id: str, bins: int) -> tuple[np.ndarray, np.ndarray, int, tuple[float, float]]:
    """``(complete (B, B, B), usable (B, B, B), grasps, (complete, usable) over all grasps)``: the training pool's rate
    of complete and of usable grasps (:func:`~haptic_env.grasping.usable_touch`) per (elevation, roll, spread) cell,
    pooled over the objects and azimuths (0 in a cell of fewer than :data:`MIN_CELL` grasps), and over the pool."""
    env = gym.make(env_id)
    try:
        dc = recognizer_kwargs(env.unwrapped.config)["config"].grasps
        if dc.source != "hand":
            raise ValueError(f"{env_id} trains on {dc.source!r} grasps; this benchmark needs a hand env")
        objects = env.unwrapped.scene.objects
    finally:
        env.close()
    pool = hand_pool(objects, dc, progress=False)
    A = np.concatenate([pool_actions(dc.seed, k, c) for k, c in enumerate(pool.approaches)])
    T = np.concatenate([pool.touched[k, :c] for k, c in enumerate(pool.approaches)])
    idx = np.clip(((A[:, 1:] + 1) / 2 * bins).astype(int), 0, bins - 1)
    flat = np.ravel_multi_index(idx.T, (bins,) * 3)
    n = np.bincount(flat, minlength=bins ** 3).astype(float)
    comp = np.bincount(flat, weights=T.all(1), minlength=bins ** 3) / np.maximum(n, 1)
    use = np.bincount(flat, weights=usable_touch(T), minlength=bins ** 3) / np.maximum(n, 1)
    # a cell with fewer than MIN_CELL grasps is no best cell (at --bins 40 one grasp made a "best cell 1.00")
    sparse = n < MIN_CELL
    comp[sparse], use[sparse] = 0.0, 0.0
    pooled = (float(T.all(1).mean()), float(usable_touch(T).mean()))  # over grasps, not cells (empty ones as 0)
    return comp.reshape((bins,) * 3), use.reshape((bins,) * 3), len(A), pooled


class CellAgent(RandomAgent):
    """Azimuth uniform; (elevation, roll, spread) uniform within a cell drawn with probabilities ``p`` (flat)."""

    def __init__(self, name: str, p: np.ndarray, bins: int, seed: int | None = None):
        super().__init__(seed)
        self.name, self.p, self.bins = name, np.asarray(p, dtype=np.float64) / np.sum(p), int(bins)

    def act(self, obs: np.ndarray, env) -> np.ndarray:
        a = super().act(obs, env)  # the azimuth (and a fresh draw of the rest, replaced below)
        cell = np.unravel_index(self._rng.choice(len(self.p), p=self.p), (self.bins,) * 3)
        a[1:] = -1 + 2 * (np.array(cell) + self._rng.uniform(size=3)) / self.bins
        return a.astype(env.action_space.dtype)


def main(argv=None) -> int:
    p = compare_parser(__doc__.split("\n\n")[0])
    p.add_argument("--bins", type=int_in(1), default=6, help="grid cells per approach parameter")
    a = p.parse_args(argv)
    comp, use, n, (pooled_comp, pooled_use) = cell_rates(a.env_id, a.bins)
    one = lambda r: np.eye(r.size)[np.argmax(r)]  # noqa: E731
    agents = [RandomAgent(), CellAgent("best-complete", one(comp), a.bins), CellAgent("best-usable", one(use), a.bins),
              CellAgent("weighted", comp.ravel() ** 2, a.bins)]
    compare(agents, a, f"; training pool {n} grasps, {a.bins}^3 cells; pooled rates: complete {pooled_comp:.2f} (best "
            f"cell {comp.max():.2f}), usable {pooled_use:.2f} (best {use.max():.2f}; cells of >= {MIN_CELL} grasps)",
            "scripted policy", argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
