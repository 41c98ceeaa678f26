"""How close is the replay backend to the MuJoCo hand it records, and how much faster is it?

The replay backend (:mod:`haptic_env.grasping.replay`) answers an approach with the recorded grasp of the nearest of
``--approaches`` recorded approaches. This script asks it for the approaches of a held-out pool of the same hand (the
hand table's validation pools: ``--pool-seed 500``, ``--pool-approaches 300`` per object, grasped by MuJoCo at the
identity pose) and compares, object by object, what it returns with what MuJoCo gave there:

* the touched fingertips: the same set, and the same usability (>= 3 fingertips);
* the contacts of fingertips that touched in both: mean distance (mm).

With ``--table N`` the replay records instead the ``N`` approaches of a ``--discrete-approaches N`` agent, each at
``--yaws`` evenly spaced yaws (``ReplayConfig.table``), and is asked for those approaches at random yaws of the object
(``--pool-approaches`` queries per object, approach ``i % N`` turned by a yaw drawn from ``--pool-seed``'s stream),
which MuJoCo grasps as the held-out pool.

Each figure is also given for a *random* record of the same object (the replay with its lookup replaced by a random
index): what a replay that ignored the approach would score. Speed: replayed grasps per second against MuJoCo's own
grasps per second on ``--time-approaches`` approaches, in the same run (one process), as a ratio.

    python benchmarks/replay_fidelity.py [--hand allegro] [--objects ycb10] [--approaches 6000] [--pool-seed 500]
    python benchmarks/replay_fidelity.py --table 64 [--yaws 72]   # the records of a 64-approach agent

The first run records the replay pool (``approaches`` per object; 4.6 min for the Allegro's 60,000 on 2 cores) and the
held-out pool unless they are cached. The headline (the speed ratio) is printed last.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main(argv=None) -> int:
    from haptic_env.cli import int_in

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hand", default="allegro")
    ap.add_argument("--objects", default="ycb10")
    ap.add_argument("--approaches", type=int_in(1), default=6000, help="recorded approaches per object of the replay")
    ap.add_argument("--replay-seed", type=int_in(0), default=1, help="the replay pool's seed (ReplayConfig.pool_seed)")
    ap.add_argument("--pool-seed", type=int_in(0), default=500, help="seed of the held-out MuJoCo pool compared with")
    ap.add_argument("--pool-approaches", type=int_in(1), default=300, help="held-out approaches per object")
    ap.add_argument("--time-approaches", type=int_in(1), default=100, help="approaches timed on each backend")
    ap.add_argument("--table", type=int_in(0), default=0,
                    help="N > 0: record the N approaches of approach_table(N) at --yaws yaws each, and query "
                         "them at random yaws")
    ap.add_argument("--yaws", type=int_in(1), default=72, help="recorded yaws per table approach (with --table)")
    args = ap.parse_args(argv)

    from haptic_env.grasping import make_backend, usable_touch
    from haptic_env.grasping.base import approach_table
    from haptic_env.grasping.replay import turned_azimuth
    from haptic_env.hand_grasps import hand_grasp_pool, pool_actions
    from haptic_env.objects import load_object_set

    objects = load_object_set(args.objects)
    replay = make_backend("replay", hand=args.hand, approaches=args.approaches, pool_seed=args.replay_seed,
                          table=args.table, yaws=args.yaws)
    replay.prepare(objects)
    n = replay.n_fingers
    queries = None
    if args.table:  # table approach i % N at a random yaw, the same queries for every object
        q_rng = np.random.default_rng(args.pool_seed)
        rows_ = approach_table(args.table)[np.arange(args.pool_approaches) % args.table]
        queries = turned_azimuth(rows_, q_rng.uniform(0, 2 * np.pi, args.pool_approaches))
    held = hand_grasp_pool(objects, args.hand, n, args.pool_approaches, seed=args.pool_seed, actions=queries)
    rng = np.random.default_rng(0)
    rows, tot = [], {"replay": [], "random": []}
    for k, obj in enumerate(objects):
        actions = (pool_actions(args.pool_seed, k, args.pool_approaches) if queries is None else queries)
        actions = actions.astype(np.float32)
        replay.set_object(obj)
        got = replay.grasp_batch(actions, rng)
        _, C, _, T = replay.records(obj)
        pick = rng.integers(0, len(T), len(actions))
        cells = []
        for label, contacts, touched in (("replay", got.contacts, got.touched), ("random", C[pick], T[pick])):
            same = (touched == held.touched[k]).all(axis=1).mean()
            usable = (usable_touch(touched) == usable_touch(held.touched[k])).mean()
            both = touched & held.touched[k]
            dist = 1000 * np.linalg.norm(contacts - held.contacts[k], axis=-1)[both].mean() if both.any() else np.nan
            tot[label].append((same, usable, dist))
            cells += [same, usable, dist]
        rows.append((obj.name, *cells))

    records = (f"the {args.table} table approaches at {args.yaws} yaws each" if args.table else
               f"{args.approaches} recorded approaches per object (seed {args.replay_seed})")
    asked = (f"{args.pool_approaches} table approaches at random yaws" if args.table else
             f"{args.pool_approaches} held-out approaches")
    print(f"{args.hand} on {args.objects}: replay of {records} against MuJoCo's grasps of {asked} (seed "
          f"{args.pool_seed})\n")
    print("| object | same fingertips | same usability | contact distance (mm) | random record: same fingertips | "
          "same usability | distance (mm) |")
    print("|---|---|---|---|---|---|---|")
    for name, s, u, d, rs, ru, rd in rows:
        print(f"| {name} | {100 * s:.0f} % | {100 * u:.0f} % | {d:.1f} | {100 * rs:.0f} % | {100 * ru:.0f} % | {rd:.1f} |")
    m = {lab: np.nanmean(np.array(v), axis=0) for lab, v in tot.items()}
    print(f"| **mean** | **{100 * m['replay'][0]:.0f} %** | **{100 * m['replay'][1]:.0f} %** | "
          f"**{m['replay'][2]:.1f}** | {100 * m['random'][0]:.0f} % | {100 * m['random'][1]:.0f} % | "
          f"{m['random'][2]:.1f} |\n")

    # speed: the same approaches on both backends, one process
    acts = rng.uniform(-1, 1, (args.time_approaches, 4)).astype(np.float32)
    phys = make_backend("mujoco", hand=args.hand, normals=True)
    obj = objects[0]
    phys.set_object(obj)
    replay.set_object(obj)
    phys.grasp(acts[0], rng)  # warm up
    t0 = time.perf_counter()
    for a in acts:
        phys.grasp(a, rng)
    t_phys = (time.perf_counter() - t0) / len(acts)
    reps = max(1, int(0.5 / max(t_phys, 1e-6)))
    t0 = time.perf_counter()
    for _ in range(reps):
        for a in acts:
            replay.grasp(a, rng)
    t_replay = (time.perf_counter() - t0) / (reps * len(acts))
    phys.close()
    print(f"grasp time on {obj.name}: MuJoCo {1e3 * t_phys:.2f} ms, replay {1e3 * t_replay:.3f} ms")
    print(f"replay backend: {t_phys / t_replay:.0f}x the grasps per second of the MuJoCo {args.hand} "
          f"({1 / t_replay:,.0f} against {1 / t_phys:,.0f} grasps/s, one process)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
