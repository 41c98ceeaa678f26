"""How much one grasp tells about the object, with and without the contacts' heights above the table.

One-shot accuracy of a k-NN classifier (scikit-learn, 15 neighbours, distance-weighted, standardised features)
trained on a hand's grasp pool of the YCB-10 meshes (pool seed 0, the envs' training pool) and scored on the
validation pools (seeds 500-502, 300 approaches per object each), complete grasps (every fingertip touching) and
(always, rows ``z = 3``) a random 3-subset of the touching fingertips of every grasp with at least three. Feature sets:

* ``phi``: the paper's frame-invariant Phi_n (with normals where the hand senses them);
* ``phi+approach``: plus the approach's yaw-free parameters (elevation, roll as cos / sin, spread);
* ``phi+heights``: plus the contacts' heights above the table, in Phi_n's chain order (``phi(heights=True)``).

The k-NN is a model-free check of the information in the features, not the env's recogniser (a KDE).

    python benchmarks/heights_information.py [--hands allegro shadow aero] [--approaches 6000] [--out DIR]

Writes ``information.md`` to ``--out``; the headline (the gain of the heights, averaged over the rows) is printed
last.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.hand_experiment import pm  # noqa: E402
from haptic_env.cache import atomic_write  # noqa: E402
from haptic_env.cli import distinct, int_in, output_path, script_command  # noqa: E402
from haptic_env.dataset import DatasetConfig, support_frame  # noqa: E402
from haptic_env.grasp_features import phi  # noqa: E402
from haptic_env.hand_grasps import hand_grasp_pool, pool_actions, pool_rows  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402

#: hand -> (fingers, normal settings)
SETUPS = {"allegro": (4, (True, False)), "shadow": (5, (False,)), "aero": (5, (False,))}
FEATURES = ("phi", "phi+approach", "phi+heights")


def features(pool, objects, seed: int, z: int, normals: bool, rng: np.random.Generator) -> tuple[dict, np.ndarray]:
    """Feature set -> ``X (m, d)`` of the pool's ``z``-finger grasps, and their labels ``(m,)``."""
    heights_cfg = DatasetConfig(n_fingers=z, heights=True)
    X = {name: [] for name in FEATURES}
    y = []
    A = pool.touched.shape[1]
    for k, obj in enumerate(objects):
        n = pool.touched.shape[2]
        if z == n:  # complete grasps, in hand order, with their approaches
            ok = pool.touched[k].all(1)
            C, N = pool.contacts[k][ok], pool.normals[k][ok]
            act = pool_actions(seed, k, A)[ok]
        else:
            C, N = pool_rows(pool, k, z, rng)
            act = None
        f = phi(support_frame(C, obj, heights_cfg), N if normals else None, heights=True)
        d = f.q.shape[1] - z
        q, valid = f.q[f.valid], f.valid
        X["phi"].append(q[:, :d])
        X["phi+heights"].append(q)
        if act is not None:
            a = act[valid]
            X["phi+approach"].append(np.hstack([q[:, :d], a[:, 1:2], np.cos(np.pi * a[:, 2:3]),
                                                np.sin(np.pi * a[:, 2:3]), a[:, 3:4]]))
        y.append(np.full(len(q), k))
    return {k: np.vstack(v) for k, v in X.items() if v}, np.concatenate(y)


def one_shot(train: tuple[dict, np.ndarray], tests: list[tuple[dict, np.ndarray]], name: str) -> np.ndarray:
    """k-NN accuracy of feature set ``name`` on each test split."""
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.preprocessing import StandardScaler

    X, y = train
    sc = StandardScaler().fit(X[name])
    clf = KNeighborsClassifier(15, weights="distance").fit(sc.transform(X[name]), y)
    return np.array([clf.score(sc.transform(Xt[name]), yt) for Xt, yt in tests])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hands", nargs="+", default=list(SETUPS), choices=list(SETUPS))
    ap.add_argument("--approaches", type=int_in(1), default=6000,
                    help="training pool approaches per object (the envs')")
    ap.add_argument("--validation-seeds", type=int_in(500, 999), nargs="+", default=[500, 501, 502],
                    help="pool seeds of the queries: validation pools (500-999; 0 and 1 are training, 1000+ test)")
    ap.add_argument("--queries", type=int_in(1), default=300, help="approaches per object of each validation pool")
    ap.add_argument("--out", type=output_path("folder"), default=None)
    args = ap.parse_args(argv)
    distinct(ap, "--validation-seeds", args.validation_seeds)
    if data_dir() is None:
        print("needs the YCB meshes and the menagerie hands (set HAPTIC_DATA and MENAGERIE_ROOT)")
        return 1
    t0 = time.perf_counter()
    objects = load_object_set("ycb10")
    lines = ["| hand | normals | grasps | " + " | ".join(FEATURES) + " |", "|---" * (3 + len(FEATURES)) + "|"]
    gains = []
    for hand in args.hands:
        n, normal_settings = SETUPS[hand]
        train_pool = hand_grasp_pool(objects, hand, n, args.approaches, seed=0)
        val_pools = [hand_grasp_pool(objects, hand, n, args.queries, seed=s) for s in args.validation_seeds]
        for normals in normal_settings:
            for z in (n, 3) if n > 3 else (n,):
                tr = features(train_pool, objects, 0, z, normals, np.random.default_rng(0))
                te = [features(p, objects, s, z, normals, np.random.default_rng(s))
                      for p, s in zip(val_pools, args.validation_seeds)]
                cells = []
                for name in FEATURES:
                    if name not in tr[0]:
                        cells.append("-")
                        continue
                    acc = one_shot(tr, te, name)
                    cells.append(f"{pm(acc, 100)} %")
                    if name == "phi":
                        base = acc.mean()
                    if name == "phi+heights":
                        gains.append(acc.mean() - base)
                what = "complete" if z == n else f"{z}-subsets"
                lines.append(f"| {hand} | {'yes' if normals else 'no'} | {what} | " + " | ".join(cells) + " |")
                print(lines[-1], flush=True)
    text = (f"k-NN one-shot accuracy (15 neighbours), training pool seed 0 ({args.approaches} approaches per object), "
            f"validation pools {args.validation_seeds} ({args.queries} approaches per object each); mean +- sample std "
            "over the validation pools.\n\n" + "\n".join(lines))
    if args.out is not None:
        cmd = script_command("heights_information.py", argv)  # shell-quoted (it was joined by spaces)
        with atomic_write(args.out / "information.md", "w") as fh:
            fh.write(f"`{cmd}` ({time.perf_counter() - t0:.0f} s)\n\n{text}\n")
    print(f"HEADLINE: the contacts' heights add {100 * np.mean(gains):.1f} points of k-NN one-shot accuracy "
          f"(mean over {len(gains)} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
