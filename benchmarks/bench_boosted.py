"""Gradient boosting's log-likelihoods through the compiled tree walk against scikit-learn's ``predict_proba``.

:class:`~haptic_env.recognizers.boosted.BoostedLikelihood` scores grasp vectors by walking the fitted trees in one
numba call; the baseline is the same model scored through scikit-learn (the fallback path,
``HistGradientBoostingClassifier.predict_proba``), in the same process on the same vectors. Both are timed on one
vector per call (an env step scores one grasp) and on a batch (the analyses' trials), in three blocks (scikit-learn,
compiled, scikit-learn again: the baseline is the faster of its two), best of ``--repeats``; the two paths must
agree to rounding first. In an env the physics between two grasps pushes the trees out of the CPU caches, so the
one-vector calls are also timed cold: ``--evict-mb`` MB of other memory written before each call (outside the
timing; 0 skips it).

    OMP_NUM_THREADS=1 python benchmarks/bench_boosted.py --objects default --fingers 4 --grasps-per-object 10000

Headline (last line, ``HEADLINE:``): the compiled walk's time for one vector as a ratio of scikit-learn's.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

import numpy as np  # noqa: E402

from haptic_env.dataset import build_dataset  # noqa: E402
from haptic_env.experiments.config import AnalysisConfig  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.boosted import BoostedConfig, BoostedLikelihood  # noqa: E402


def _best(fn, repeats: int) -> float:
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--objects", default="default")
    p.add_argument("--units", default="m")
    p.add_argument("--fingers", type=int, default=4)
    p.add_argument("--no-normals", action="store_true")
    p.add_argument("--grasps-per-object", type=int, default=10_000)
    p.add_argument("--max-iter", type=int, default=BoostedConfig.max_iter)
    p.add_argument("--singles", type=int, default=200, help="one-vector calls per timing")
    p.add_argument("--batch", type=int, default=2_000, help="vectors in the batch timing")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--evict-mb", type=int, default=64, help="MB written between the cold one-vector calls (0: none)")
    a = p.parse_args(argv)
    for name in ("fingers", "grasps_per_object", "max_iter", "singles", "batch", "repeats"):
        if getattr(a, name) < (2 if name == "fingers" else 100 if name == "grasps_per_object" else 1):
            p.error(f"--{name.replace('_', '-')} is too small: {getattr(a, name)}")
    if a.evict_mb < 0:
        p.error(f"--evict-mb must be >= 0, got {a.evict_mb}")
    normals = not a.no_normals
    cfg = AnalysisConfig(objects=a.objects, units=a.units, grasps_per_object=a.grasps_per_object, normals=normals,
                         progress=False)
    objects = load_object_set(a.objects, units=a.units)
    ds = build_dataset(objects, cfg.recognizer_config().dataset_config(a.fingers, normals, hand_fingers=a.fingers),
                       progress=True)
    t = time.perf_counter()
    lik = BoostedLikelihood(BoostedConfig(max_iter=a.max_iter)).fit(ds.X_train, ds.y_train, n_classes=len(objects))
    trees = sum(len(it) for it in lik.clf._predictors)
    print(f"{a.objects}, n = {a.fingers}, {'with' if normals else 'without'} normals: {len(ds.X_train)} training "
          f"vectors, {lik.clf.n_iter_} iterations ({trees} trees), fitted in {time.perf_counter() - t:.1f} s")
    Q = np.asarray(ds.X_val[: a.batch], dtype=np.float64)
    singles = Q[: a.singles]
    if not isinstance(lik._trees, tuple):  # trees this scikit-learn's layout hides: both sides would be its own path
        print("the compiled walk is not in use (BoostedLikelihood could not read this scikit-learn's trees): "
              "nothing to compare", file=sys.stderr)
        return 1
    compiled = lik.log_likelihood(Q)  # also compiles the walk (numba caches it on disk)
    library = BoostedLikelihood.from_bytes(lik.config, lik.to_bytes())
    library._trees = False  # scikit-learn's own path
    gap = float(np.abs(compiled - library.log_likelihood(Q)).max())
    print(f"largest difference of the two paths' log-likelihoods on {len(Q)} vectors: {gap:.2e}")
    if gap > 1e-9:
        print("the compiled walk disagrees with scikit-learn", file=sys.stderr)
        return 1
    times = {}
    for name, model in [("scikit-learn", library), ("compiled", lik), ("scikit-learn again", library)]:
        one = _best(lambda m=model: [m.log_likelihood(q[None]) for q in singles], a.repeats) / len(singles)
        batch = _best(lambda m=model: m.log_likelihood(Q), a.repeats) / len(Q)
        times[name] = one
        print(f"{name:20s} one vector per call {one * 1e6:9.1f} us   batch of {len(Q)}: {batch * 1e6:8.2f} us per vector")
    if a.evict_mb:
        other = np.ones(a.evict_mb * 2**20 // 8)
        for name, model in [("scikit-learn", library), ("compiled", lik)]:
            spent = 0.0
            for q in singles:
                np.add(other, 1.0, out=other)  # as a grasp's physics would, between two scores
                t = time.perf_counter()
                model.log_likelihood(q[None])
                spent += time.perf_counter() - t
            print(f"{name:20s} one vector per call, cold cache ({a.evict_mb} MB written before each): "
                  f"{spent / len(singles) * 1e6:9.1f} us")
    base = min(times["scikit-learn"], times["scikit-learn again"])
    print(f"HEADLINE: the compiled walk scores one vector in {times['compiled'] / base:.4f}x scikit-learn's time "
          f"({times['compiled'] * 1e6:.0f} us against {base * 1e6:.0f} us)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
