"""How much could reading the object's pose from the contacts save? The look-ahead told the pose after the first grasp.

The hand envs hide the object's yaw. A one-step look-ahead with the hand's own physics that knows the pose needs
about 40 % fewer grasps than random on test (33 % on validation); one that marginalises the pose, 22 % (9 %). A
policy that reads the pose from the contacts (``greedy-env-infer``: the yaw posterior of the episode's grasps) sits
in between. But no policy can know the pose before its first grasp, and episodes end after two or three grasps, so
the first grasp is always pose-blind. This benchmark measures that ceiling with a scripted oracle:

* ``blind-then-known``: the first grasp chosen by the pose-blind look-ahead (``greedy-env-blind:16:4``), every
  later one by the look-ahead that is told the object's pose (``greedy-env:16``): what perfect pose reading after one
  grasp would give a look-ahead.

Same env seeds, objects and poses as random (``haptic-recog evaluate``'s episodes, ``evaluate_agents``).

    OMP_NUM_THREADS=1 python benchmarks/pose_ceiling.py --env-id HapticRecogMuJoCo-v0 \\
        --seeds 500 501 502 503 504 --episodes 40 --out results/hands/pose_ceiling_val.md

Prints ``haptic-recog evaluate``'s markdown table; the headline, the oracle against random, is printed last.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from relative_approaches import compare, compare_parser  # noqa: E402  (the scripted-policy comparison)

from agents.greedy import GreedyInfoGainAgent  # noqa: E402
from agents.random_policy import RandomAgent  # noqa: E402
from haptic_env.cli import int_in  # noqa: E402


class BlindThenKnown:
    """The pose-blind look-ahead for an episode's first grasp, the pose-told one for every later grasp."""

    name = "blind-then-known"

    def __init__(self, n_candidates: int = 16, n_samples: int = 4, seed: int | None = None):
        self.blind = GreedyInfoGainAgent(n_candidates, n_samples, seed=seed, simulate="env", pose_known=False)
        self.known = GreedyInfoGainAgent(n_candidates, 1, seed=seed, simulate="env", pose_known=True)

    def reset(self, env, seed: int | None = None) -> None:
        self.blind.reset(env, seed)
        self.known.reset(env, None if seed is None else seed + 1)

    def act(self, obs: np.ndarray, env) -> np.ndarray:
        return (self.blind if env.unwrapped.grasp_count == 0 else self.known).act(obs, env)


def main(argv=None) -> int:
    p = compare_parser(__doc__.split("\n\n")[0])
    p.add_argument("--candidates", type=int_in(1), default=16, help="candidate approaches per step")
    p.add_argument("--poses", type=int_in(1), default=4, help="pose draws per candidate of the blind first grasp")
    a = p.parse_args(argv)
    compare([RandomAgent(), BlindThenKnown(a.candidates, a.poses)], a, "", "oracle", argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
