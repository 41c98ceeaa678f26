"""Each normal's angles in Phi_n: the second to t2's normal (the paper's) or to the edge ab (``normal_axis="ab"``), or
three, to the axes of t1's frame (``normal_axis="frame"``, 6n - 6 values).

One-shot accuracy on fresh test grasps of kNN (k = 15, distance-weighted, standardised), the project's KDE
(``KDELikelihood``, default config, bandwidth chosen on a 20 % validation split) and the MLP (3 x 256, early
stopping on a 15 % validation split), trained on the same surface grasps encoded each way. Needs the shared data
for kit8 (``$HAPTIC_DATA``); ``--objects default`` runs without it.

    python benchmarks/normal_axis.py [--objects kit8] [--fingers 4] [--grasps 20000] [--models knn,kde,mlp]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", default="kit8")
    ap.add_argument("--fingers", type=int, default=4)
    ap.add_argument("--grasps", type=int, default=20_000, help="training grasps per object")
    ap.add_argument("--test-grasps", type=int, default=1_000, help="fresh test grasps per object")
    ap.add_argument("--models", default="knn,kde,mlp", help="comma list of knn, kde, mlp")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    models = [m for m in args.models.split(",") if m]
    bad = [m for m in models if m not in ("knn", "kde", "mlp")]
    if args.fingers < 3 or args.grasps < 100 or args.test_grasps < 1 or args.seed < 0 or bad or not models:
        ap.error(f"need --fingers >= 3, --grasps >= 100, --test-grasps >= 1, --seed >= 0 and --models among knn, "
                 f"kde, mlp; "
                 f"got {vars(args)}")
    from sklearn.neighbors import KNeighborsClassifier

    from haptic_env.dataset import sample_grasps
    from haptic_env.grasp_features import NORMAL_AXES, phi
    from haptic_env.objects import load_object_set
    from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
    from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig

    objects = load_object_set(args.objects)
    n, K = args.fingers, len(objects)

    def grasps(count, seed):
        rng = np.random.default_rng(seed)
        return [sample_grasps(o, count, n, rng) for o in objects]

    t0 = time.perf_counter()
    train, test = grasps(args.grasps, args.seed + 1), grasps(args.test_grasps, args.seed + 2)
    print(f"{args.objects}, n = {n} with normals, {args.grasps:,} training and {args.test_grasps:,} test grasps per "
          f"object (surface, area-uniform); one-shot accuracy %\n")
    print("| normal_axis | " + " | ".join(models) + " |")
    print("|---|" + "---|" * len(models))
    for axis in NORMAL_AXES:
        def vectors(pool):
            X, y = [], []
            for k, (C, N) in enumerate(pool):
                f = phi(C, N, normal_axis=axis)
                X.append(f.q[f.valid])
                y.append(np.full(int(f.valid.sum()), k))
            return np.concatenate(X), np.concatenate(y)

        Xtr, ytr = vectors(train)
        Xte, yte = vectors(test)
        perm = np.random.default_rng(args.seed).permutation(len(ytr))
        row = []
        for m in models:
            if m == "knn":
                mu, sd = Xtr.mean(0), Xtr.std(0) + 1e-12
                acc = KNeighborsClassifier(15, weights="distance").fit((Xtr - mu) / sd, ytr).score((Xte - mu) / sd, yte)
            elif m == "kde":
                nv = int(0.2 * len(perm))
                kde = KDELikelihood(KDEConfig()).fit(Xtr[perm[nv:]], ytr[perm[nv:]], Xtr[perm[:nv]], ytr[perm[:nv]],
                                                     n_classes=K)
                acc = float(np.mean(kde.log_likelihood(Xte).argmax(1) == yte))
            else:
                nv = int(0.15 * len(perm))
                clf = MLPClassifier(MLPConfig(threads=1, progress=False, seed=args.seed)).fit(
                    Xtr[perm[nv:]], ytr[perm[nv:]], Xtr[perm[:nv]], ytr[perm[:nv]], n_classes=K)
                acc = float(np.mean(clf.predict(Xte) == yte))
            row.append(f"{100 * acc:.1f}")
        label = "t2 (the paper's)" if axis == "t2" else axis
        print(f"| {label} | " + " | ".join(row) + " |", flush=True)
    se = 100 * np.sqrt(0.25 / (K * args.test_grasps))
    print(f"\nbinomial standard error of one cell <= {se:.1f} points; {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
