"""How far a MuJoCo hand's fingertips reach into the table, with the visual table and with a solid one.

Until 2026-12-07 the MuJoCo backend's table was a visual plane (the hand collided with the object only), so a
fingertip could sink into it and touch an object low on its side or underneath; ``MujocoConfig(solid_table=False)``
gives that table back, and the default (solid) makes it collide with the hand. This benchmark grasps the same random
approaches to each object with both tables, one process, and reports per hand and table: the share of grasps with a
touching fingertip sphere more than ``--depth`` (m) below the table top, the median depth of those, and the share of
usable grasps (>= 3 fingertips on the object; both pads for the 2-finger gripper), per object and overall.

    OMP_NUM_THREADS=1 python benchmarks/table_reach.py [--hands allegro,shadow,aero,robotiq] [--objects ycb10]
        [--approaches 30] [--seed 0] [--depth 0.002]

Headline figure last: the share of the first hand's grasps that reach into the visual table, and with the solid one.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from haptic_env.cli import distinct, float_in, int_in  # noqa: E402
from haptic_env.grasping import make_backend  # noqa: E402
from haptic_env.grasping.base import support_height  # noqa: E402
from haptic_env.grasping.hands import HANDS, HandUnavailableError  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402


def depth_below_table(tip_sites: np.ndarray, tip_radius: np.ndarray, touched: np.ndarray, table_z: float) -> float:
    """How far (m) the lowest touching fingertip sphere of one grasp reaches under the table top, 0 if none does.

    ``tip_sites (n, 3)`` fingertip centres (world), ``tip_radius (n,)``, ``touched (n,)`` bool, ``table_z`` the table
    top's height (world)."""
    low = tip_sites[:, 2] - tip_radius - table_z
    return float(max(0.0, -low[touched].min())) if touched.any() else 0.0


def run(hand: str, objects, approaches: int, seed: int, solid: bool) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per object: ``(depths (approaches,), usable (approaches,) bool)`` of ``hand``'s grasps along the approaches of
    ``SeedSequence([seed, k])`` (the same for both tables)."""
    be = make_backend("mujoco", hand=hand, n_fingers=None, support="table", solid_table=solid)
    out = {}
    try:
        for k, obj in enumerate(objects):
            be.set_object(obj)
            table_z = support_height(obj.mesh.vertices)  # the backend's table top at the identity pose
            acts = np.random.default_rng(np.random.SeedSequence([seed, k])).uniform(-1, 1, (approaches, be.action_dim))
            rng = np.random.default_rng([seed, k, 1])
            res = [be.grasp(a, rng) for a in acts]
            depth = np.array([depth_below_table(r.info["tip_sites"], be.scene.tip_radius, r.touched, table_z)
                              for r in res])
            out[obj.name] = (depth, np.array([r.usable for r in res]))
    finally:
        be.close()
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--hands", default="allegro,shadow,aero,robotiq", help="comma-separated hand names")
    p.add_argument("--objects", default="ycb10", help="object set (default ycb10)")
    p.add_argument("--approaches", type=int_in(1, 100_000), default=30, help="random approaches per object")
    p.add_argument("--seed", type=int_in(0, 2**32 - 1), default=0)
    p.add_argument("--depth", type=float_in(0.0, 0.1), default=0.002,
                   help="m below the table top that counts as reaching into it (default 0.002)")
    a = p.parse_args(argv)
    hands = [h for h in a.hands.split(",") if h]
    bad = [h for h in hands if h not in HANDS]
    if not hands or bad:
        p.error(f"--hands: unknown hand {', '.join(bad) or '(none)'}; choose from {HANDS}")
    distinct(p, "--hands", hands)  # a hand twice printed its rows twice and dropped the HEADLINE
    try:
        objects = load_object_set(a.objects)
    except (ValueError, FileNotFoundError) as exc:
        p.error(f"--objects: {exc}")
    print(f"# Fingertips into the table: {a.objects}, {a.approaches} random approaches per object, seed {a.seed}\n")
    print(f"Reach = share of grasps with a touching fingertip more than {a.depth * 1000:g} mm below the table top "
          "(median depth of those); usable = >= 3 fingertips on the object (both pads for the gripper).\n")
    print("| hand | table | reach (all objects) | median depth mm | usable | per object: reach / usable |")
    print("|---|---|---|---|---|---|")
    headline = None
    for hand in hands:
        for solid in (False, True):
            try:
                per = run(hand, objects, a.approaches, a.seed, solid)
            except HandUnavailableError as exc:
                print(f"| {hand} | - | skipped: {exc} | | | |")
                break
            depth = np.concatenate([d for d, _ in per.values()])
            usable = np.concatenate([u for _, u in per.values()])
            deep = depth > a.depth
            med = float(np.median(depth[deep])) * 1000 if deep.any() else 0.0
            objs = ", ".join(f"{n} {np.mean(d > a.depth):.2f} / {np.mean(u):.2f}" for n, (d, u) in per.items())
            print(f"| {hand} | {'solid' if solid else 'visual'} | {deep.mean():.3f} ({deep.sum()} of {len(deep)}) "
                  f"| {med:.1f} | {usable.mean():.3f} | {objs} |")
            if hand == hands[0]:
                headline = (headline or ()) + (deep.mean(),)
    if headline is not None and len(headline) == 2:
        print(f"\nHEADLINE: {hands[0]} grasps reaching into the table: {headline[0]:.3f} visual, "
              f"{headline[1]:.3f} solid")
    return 0


if __name__ == "__main__":
    sys.exit(main())
