"""What does a trained policy look at? Evaluate it with parts of its observation removed or falsified.

A policy that uses an observation part acts differently, and needs more grasps, when that part is gone. This script
runs ``haptic-recog evaluate``'s episodes (the same env seeds, objects and poses) for the policy as trained and for
each ablation of it:

* ``zero``: the named parts (``env.obs_slices`` keys, e.g. ``contacts contact_normals``) set to 0, as before the
  first grasp or for a finger that did not touch;
* ``yaw``: the named 3-vector parts (world-frame contacts and normals) turned about the world z axis by a random
  angle at every step: still plausible contacts, but the object's pose they tell is wrong.

If the grasps and success do not move, the policy does not use the part. Random is run too, as the baseline of the
report's "fewer grasps than random" column.

    python benchmarks/obs_ablation.py --model runs/v5/ppo_contacts_s0/ppo_final.zip --env-id HapticRecogMuJoCo-v0 \\
        --env-kwargs '{"observe_contacts": true}' --parts contacts contact_normals --seeds 500 501 502 503 504 \\
        --out results/hands/ppo_contacts_allegro_s0_val/ablation

Writes ``evaluate``'s report (``results.md``, ``episodes.csv``, plots) under ``--out``; the headline is printed last.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from haptic_env.cli import int_in, output_path, script_command  # noqa: E402
from haptic_env.splits import ENV_VALIDATION_SEEDS  # noqa: E402

MODES = ("zero", "yaw")


class ObsAblation:
    """``agent`` acting on observations whose ``parts`` (names of ``env.obs_slices``) are zeroed (``mode="zero"``) or
    turned by a random yaw about the world z axis (``mode="yaw"``; each part a flat ``(3m,)`` array of 3-vectors).
    The yaw angles come from a generator seeded at the agent's seeded resets, so runs repeat."""

    def __init__(self, agent, parts: list[str], mode: str, seed: int = 0):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if not parts:
            raise ValueError("parts must name at least one observation part")
        self.agent, self.parts, self.mode = agent, list(parts), mode
        self.name = f"{agent.name}-{mode}-{'+'.join(self.parts)}"
        self._rng = np.random.default_rng(seed)

    def reset(self, env, seed: int | None = None) -> None:
        slices = env.unwrapped.obs_slices
        missing = [p for p in self.parts if p not in slices]
        if missing:
            raise ValueError(f"observation part(s) {missing} not in this env's observation {list(slices)}")
        for p in self.parts:
            size = slices[p].stop - slices[p].start
            if self.mode == "yaw" and size % 3:
                raise ValueError(f"mode='yaw' turns 3-vectors, but part {p!r} has {size} values")
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agent.reset(env, seed=seed)

    def ablate(self, obs: np.ndarray, env) -> np.ndarray:
        out = np.array(obs, dtype=np.float32, copy=True)
        slices = env.unwrapped.obs_slices
        if self.mode == "zero":
            for p in self.parts:
                out[slices[p]] = 0.0
            return out
        th = self._rng.uniform(0.0, 2.0 * np.pi)
        c, s = np.cos(th), np.sin(th)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        for p in self.parts:
            out[slices[p]] = (out[slices[p]].reshape(-1, 3) @ rot.T).ravel()
        return out

    def act(self, obs: np.ndarray, env) -> np.ndarray:
        return self.agent.act(self.ablate(obs, env), env)


def main(argv: list[str] | None = None) -> int:
    import gymnasium as gym

    import haptic_env  # noqa: F401  (registers the envs)
    from agents.evaluate import evaluate_agents, make_agent, summarize, write_report

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True, help="a trained SB3 model (.zip; ppo/sac from its file name)")
    ap.add_argument("--env-id", default="HapticRecogMuJoCo-v0")
    ap.add_argument("--env-kwargs", default="{}", help="JSON dict of HapticRecogConfig fields")
    ap.add_argument("--parts", nargs="+", default=["contacts", "contact_normals"])
    ap.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    ap.add_argument("--episodes", type=int_in(1), default=40)
    ap.add_argument("--seeds", type=int_in(0), nargs="+", default=list(ENV_VALIDATION_SEEDS))
    ap.add_argument("--out", type=output_path("folder"), default="results/obs_ablation")  # checked before the episodes
    args = ap.parse_args(argv)
    try:
        kwargs = json.loads(args.env_kwargs)
    except json.JSONDecodeError as exc:
        ap.error(f"--env-kwargs is not valid JSON ({exc.msg}): {args.env_kwargs!r}")
    if not isinstance(kwargs, dict):
        ap.error(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
    if not Path(args.model).is_file():
        ap.error(f"--model {args.model!r} is not a file")

    def make_env():
        return gym.make(args.env_id, **kwargs)

    probe = make_env()
    missing = [p for p in args.parts if p not in probe.unwrapped.obs_slices]
    probe.close()
    if missing:
        ap.error(f"--parts {missing} not in {args.env_id}'s observation {list(probe.unwrapped.obs_slices)} "
                 f"(with --env-kwargs {kwargs})")
    name = Path(args.model).stem.split("_")[0]
    agents = [make_agent("random"), make_agent(f"{name}={args.model}")]
    agents += [ObsAblation(make_agent(f"{name}={args.model}"), args.parts, mode) for mode in args.modes]
    records = evaluate_agents(agents, make_env, args.episodes, args.seeds)
    out = Path(args.out)
    write_report(records, out, max_grasps=probe.unwrapped.config.max_grasps,
                 title=f"{args.env_id}, {kwargs}: {args.model} with observation parts {args.parts} ablated",
                 extra=f"`{script_command('obs_ablation.py', argv)}`")
    lines = [f"{row['agent']}: {100 * row['success']:.1f} % in {row['grasps_mean']:.2f} grasps, "
             f"{100 * row['fewer_than_random']:.1f} % fewer than random" for row in summarize(records)[1:]]
    print(f"[obs_ablation] {len(args.seeds)} seeds x {args.episodes} episodes; " + "; ".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
