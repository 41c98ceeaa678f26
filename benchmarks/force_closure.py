"""Force-closure grasps: are grasps that hold an object more telling of it than random surface points, and is the
force-closure test fast?

1. **Speed and exactness**: :func:`haptic_env.force_closure.force_closure`'s fast methods (``"search"``: a
   vectorised search for a separating direction, then Qhull on what it cannot reject; ``"plane"``, three contacts
   only: the planar reduction, vectorised) against Qhull on every grasp, on the same random surface grasps: the
   answers must agree on every grasp; the figure is the default method's speed-up, printed last.
2. **Separability** (with ``--objects``): kNN one-shot accuracy (k = 15, distance-weighted, standardised) on fresh
   test grasps, training and test grasps both drawn the same way: all random surface grasps (the paper's stated
   protocol) or only those in force closure at friction ``--mu`` with ``--edges``-edge pyramids turned by
   ``--frame`` (the object's axes or the grasp's own; :data:`haptic_env.force_closure.FRAMES`) (and, with
   ``--min-epsilon``, only those of them whose Ferrari-Canny epsilon quality reaches it); the paper's kNN row
   beside (kit8).
3. **Transfer to a hand** (with ``--hand``): the same kNN trained on each kind of ycb10 surface grasp, scored on the
   hand's complete grasps of ycb10 (its validation pool, seed 500; :mod:`haptic_env.hand_grasps`).

    python benchmarks/force_closure.py [--objects kit8] [--fingers 3,4] [--grasps 3000] [--test-grasps 500]
        [--mu 0.5] [--edges 4] [--frame axes] [--min-epsilon 0.077] [--hand allegro] [--speed-grasps 3000]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from haptic_env.cli import float_in, int_in
from haptic_env.force_closure import DEFAULT_EDGES, DEFAULT_MU, FRAMES


def _grasps(objects, n: int, count: int, rng, mu: float | None, bar, min_epsilon: float = 0.0,
            edges: int = DEFAULT_EDGES, frame: str = FRAMES[0]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` grasps per object: random surface grasps, or (``mu``) those of them in force closure (pyramids of
    ``edges`` edges turned by ``frame``), and of those (``min_epsilon > 0``) the ones whose epsilon quality reaches
    ``min_epsilon``."""
    from haptic_env.dataset import draw_held_grasps, sample_grasps
    from haptic_env.force_closure import epsilon_quality

    out = []
    for obj in objects:
        if mu is None:
            out.append(sample_grasps(obj, count, n, rng))
        else:
            parts, got = [], 0
            while got < count:
                C, N = draw_held_grasps(obj, count, n, rng, mu, edges=edges, frame=frame)
                good = (epsilon_quality(C, N, mu, edges, frame=frame) >= min_epsilon if min_epsilon > 0
                        else np.ones(len(C), bool))
                parts.append((C[good], N[good]))
                got += int(good.sum())
                if got == 0 and len(parts) >= 10:
                    raise SystemExit(f"--min-epsilon {min_epsilon:g}: none of {10 * count:,} force-closure grasps of "
                                     f"{obj.name} reaches it (n = {n}, mu = {mu:g})")
            out.append(tuple(np.concatenate(a)[:count] for a in zip(*parts)))
        bar.update()
    return out


def _vectors(pool, n: int, normals: bool):
    from haptic_env.dataset import DatasetConfig, grasp_vectors

    cfg = DatasetConfig(n_fingers=n, normals=normals)
    X, y = [], []
    for k, (C, N) in enumerate(pool):
        q, valid = grasp_vectors(C, N if normals else None, cfg)
        X.append(q[valid])
        y.append(np.full(int(valid.sum()), k))
    return np.concatenate(X), np.concatenate(y)


def _knn(Xtr, ytr, Xte, yte) -> float:
    """One-shot accuracy of the project's kNN baseline (standardised, k = 15, distance-weighted; every training row)."""
    from haptic_env.recognizers.baselines import make_classifier

    clf = make_classifier("knn", max_train=None, n_neighbors=15).fit(Xtr, ytr, n_classes=int(ytr.max()) + 1)
    return float(np.mean(clf.predict(Xte) == yte))


def speed(objects, n: int, count: int, mu: float, seed: int, edges: int = DEFAULT_EDGES,
          frame: str = FRAMES[0]) -> float:
    """Seconds of Qhull-only over seconds of the default method on ``count`` random grasps per object; every
    method's time per grasp printed."""
    from haptic_env.dataset import sample_grasps
    from haptic_env.force_closure import force_closure

    rng = np.random.default_rng(seed)
    pools = [sample_grasps(o, count, n, rng) for o in objects]
    methods = ["qhull", "search"] + (["plane"] if n == 3 else [])
    seconds = dict.fromkeys(methods, 0.0)
    held = total = 0
    for C, N in pools:
        answers = {}
        for m in methods:
            t0 = time.perf_counter()
            answers[m] = force_closure(C, N, mu, edges, method=m, frame=frame)
            seconds[m] += time.perf_counter() - t0
        for m in methods[1:]:
            if not np.array_equal(answers[m], answers["qhull"]):
                raise AssertionError(f"method {m!r} changed {int((answers[m] != answers['qhull']).sum())} answers "
                                     "of Qhull's")
        held += int(answers["qhull"].sum())
        total += len(answers["qhull"])
    per = ", ".join(f"{m} {1e6 * t / total:.1f} us/grasp" for m, t in seconds.items())
    print(f"n = {n}, mu = {mu:g}, {edges}-edge pyramids ({frame} frame): {total:,} random surface grasps, "
          f"{100 * held / total:.1f} % in force closure; {per}; the same answer on every grasp")
    return seconds["qhull"] / seconds["plane" if n == 3 else "search"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", default="kit8", help="object set of the separability table ('' to skip it)")
    ap.add_argument("--fingers", default="3,4", help="comma list of finger counts (>= 3)")
    ap.add_argument("--grasps", type=int_in(50), default=3_000, help="training grasps per object")
    ap.add_argument("--test-grasps", type=int_in(10), default=500, help="fresh test grasps per object")
    ap.add_argument("--mu", type=float_in(0.0, lo_open=True), default=DEFAULT_MU, help="friction coefficient")
    ap.add_argument("--edges", type=int_in(3), default=DEFAULT_EDGES,
                    help="edges of each friction pyramid in the separability table (more: closer to the cone)")
    ap.add_argument("--frame", choices=FRAMES, default=FRAMES[0],
                    help="how each pyramid of the separability table is turned about its normal: by the object's "
                         "axes, or towards the grasp's centroid (the same answer in any frame)")
    ap.add_argument("--min-epsilon", type=float_in(0.0), default=0.0,
                    help="also a column of force-closure grasps whose epsilon quality reaches this (0: none)")
    ap.add_argument("--hand", default=None, help="also score ycb10 surface-trained kNN on this hand's grasps (its "
                    "force-closure grasps with the default --edges and --frame and no --min-epsilon)")
    ap.add_argument("--speed-grasps", type=int_in(10), default=3_000, help="grasps per object of the speed check")
    ap.add_argument("--seed", type=int_in(0), default=0)
    args = ap.parse_args(argv)
    try:
        fingers = [int(x) for x in args.fingers.split(",") if x.strip()]
    except ValueError:
        ap.error(f"--fingers: a comma list of integers, got {args.fingers!r}")
    if not fingers or min(fingers) < 3:
        ap.error(f"--fingers: finger counts >= 3 (fewer are never in force closure), got {args.fingers!r}")
    hand = None
    if not args.objects and args.min_epsilon != ap.get_default("min_epsilon"):  # (--edges / --frame: the speed check)
        ap.error("--min-epsilon adds a column to the separability table (--objects ''), which this run skips")
    if args.hand:  # resolved before the tables, so that a typo does not wait for them
        from haptic_env.grasping.hands import HandUnavailableError, load_hand

        try:
            hand = load_hand(args.hand, None)
        except HandUnavailableError as exc:
            print(f"the hand's transfer will be skipped: {exc}")
        except ValueError as exc:
            ap.error(f"--hand: {exc}")
    from tqdm.auto import tqdm

    from haptic_env.experiments.paper import PAPER_KNN  # imports the analyses (torch): only when run
    from haptic_env.objects import load_object_set

    t_start = time.perf_counter()
    if args.objects:
        objects = load_object_set(args.objects)
        print(f"## Separability: {args.objects}, kNN (k = 15) one-shot accuracy %, {args.grasps:,} training and "
              f"{args.test_grasps:,} test grasps per object, force closure at mu = {args.mu:g} "
              f"({args.edges}-edge pyramids, {args.frame} frame)\n")
        kinds = [("all surface grasps", None, 0.0), ("force-closure grasps", args.mu, 0.0)]  # (column, mu, epsilon)
        if args.min_epsilon:
            kinds.append((f"force closure, epsilon quality >= {args.min_epsilon:g}", args.mu, args.min_epsilon))
        print("| n | normals | " + " | ".join(name for name, _, _ in kinds) + " | paper kNN (200,000 grasps/object) |")
        print("|---|---|" + "---|" * len(kinds) + "---|")
        for n in fingers:
            cells = {}
            for name, mu, eps in kinds:
                with tqdm(total=2 * len(objects), desc=f"n = {n}, {name}", unit="obj", leave=False) as bar:
                    rng = np.random.default_rng([args.seed, n])
                    train = _grasps(objects, n, args.grasps, rng, mu, bar, eps, args.edges, args.frame)
                    test = _grasps(objects, n, args.test_grasps, rng, mu, bar, eps, args.edges, args.frame)
                for normals in (False, True):
                    cells[name, normals] = _knn(*_vectors(train, n, normals), *_vectors(test, n, normals))
            for normals in (False, True):
                paper = PAPER_KNN.get((n, normals), "-") if args.objects == "kit8" else "-"
                row = " | ".join(f"{100 * cells[name, normals]:.1f}" for name, _, _ in kinds)
                print(f"| {n} | {'yes' if normals else 'no'} | {row} | {paper} |", flush=True)
        se = 100 * np.sqrt(0.25 / (len(objects) * args.test_grasps))
        print(f"\nbinomial standard error of one cell <= {se:.1f} points\n")
    if hand is not None:
        from haptic_env.grasping.hands import HandUnavailableError
        from haptic_env.hand_grasps import hand_grasp_pool

        ycb = load_object_set("ycb10")
        try:
            pool = hand_grasp_pool(ycb, args.hand, hand.n_fingers, 300, seed=500)
        except HandUnavailableError as exc:
            print(f"skipping the hand: {exc}")
        else:
            n = pool.touched.shape[-1]
            print(f"## Transfer: kNN trained on ycb10 surface grasps ({args.grasps:,} per object, n = {n}), scored on "
                  f"the {args.hand}'s complete grasps of ycb10 (validation pool, 300 approaches per object)\n")
            print("| normals | all surface grasps | force-closure grasps |")
            print("|---|---|---|")
            full = [pool.touched[i].sum(-1) == n for i in range(len(ycb))]
            queries = [(pool.contacts[i][full[i]], pool.normals[i][full[i]]) for i in range(len(ycb))]
            res = {}
            for mu in (None, args.mu):
                with tqdm(total=len(ycb), desc=f"ycb10, {'force closure' if mu else 'all'}", unit="obj",
                          leave=False) as bar:
                    train = _grasps(ycb, n, args.grasps, np.random.default_rng([args.seed, n, 1]), mu, bar)
                for normals in (False, True):
                    res[mu, normals] = _knn(*_vectors(train, n, normals), *_vectors(queries, n, normals))
            for normals in (False, True):
                print(f"| {'yes' if normals else 'no'} | {100 * res[None, normals]:.1f} | "
                      f"{100 * res[args.mu, normals]:.1f} |")
            print(f"\n{int(sum(f.sum() for f in full)):,} complete grasps scored (chance 10 %)\n")
    ratio = speed(load_object_set(args.objects or "default"), fingers[0], args.speed_grasps, args.mu, args.seed + 1,
                  args.edges, args.frame)
    print(f"({time.perf_counter() - t_start:.0f} s in all)")
    print(f"HEADLINE: the force-closure test (n = {fingers[0]}) is {ratio:.1f}x faster than Qhull on every grasp, "
          "with the same answers")
    return 0


if __name__ == "__main__":
    sys.exit(main())
