"""Where the Aero's paper rows without the touch pattern lose their queries, per object, on the VALIDATION pools
(pool seeds 500-502, 10 queries per object and seed, <= 30 grasps each, lambda = 0.85): right / wrong at the stop,
undecided after 30 grasps, and the share of the object's grasps with >= 3 touching fingertips (the only ones BC
scores without the touch pattern). The recogniser is the hand table's hand-trained one with the registered env's
K = 5; the queries run as `benchmarks/hand_experiment.py` runs them (its `run_query`, the same seeds).

    python results/hands/aero_k/per_object.py > results/hands/aero_k/per_object.txt
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))
import hand_experiment as he  # noqa: E402

from haptic_env.dataset import support_frame  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers import build_recognizer  # noqa: E402


class Args:  # the hand table's defaults for the hand regime
    hand_budget, heights, normal_axis, likelihood = "uniform", False, "t2", "kde"


objects = load_object_set("ycb10")
pools, _ = he.query_pools(objects, "aero", 5, "validation", [0, 1, 2], 10, 30)
env = he.env_config("aero")
cfg = he.training_config("hand", "aero", Args, env.calibrate_grasps, env.training_grasps, "shared")
rec = build_recognizer(objects, 5, False, z_values=(3, 4), config=cfg, touch=True)
for kind, label in (("bc-ip", "BC-IP (the paper's)"), ("bc-np", "BC-NP without the touch pattern")):
    stats = {nm: np.zeros(4) for nm in objects.names}
    for s, pool in enumerate(pools):
        upd = rec.make_updater(kind, threshold=0.85, z=None, k=None, rng=np.random.default_rng([7, s]),
                               calibrated=True)
        for i, nm in enumerate(objects.names):
            C = support_frame(pool.contacts[i], objects[i], rec.config.grasps).reshape(10, 30, 5, 3)
            N = pool.normals[i].reshape(10, 30, 5, 3)
            T = pool.touched[i].reshape(10, 30, 5)
            for q in range(10):
                p, g, d = he.run_query(upd, C[q], N[q], T[q], False, None)
                stats[nm] += (d and p == i, d and p != i, not d, (T[q].sum(-1) >= 3).mean())
    total = sum(stats.values())
    print(f"{label}, K = {env.calibrate_grasps}: right {total[0]:.0f}, wrong {total[1]:.0f}, undecided "
          f"{total[2]:.0f} of 300")
    for nm, st in stats.items():
        print(f"  {nm:22s} right {st[0]:2.0f}  wrong {st[1]:2.0f}  undecided {st[2]:2.0f}  usable {st[3] / 30:.2f}")
