"""How far is BC-NP from what the grasps themselves allow? Validation grasps only.

Two references for the analyses' experiment 2 (lambda = 0.85, at most 30 grasps, uniform prior):

* ``--bound histogram`` (2 fingers without normals, where a grasp vector is one distance): each object's density is
  a histogram of the training split of ``--big`` fresh grasps per object (80 %; seed 12345, 50 / 100 / 200 bins,
  add-half smoothing). With 80,000 grasps per object this is the likelihood up to binning, so BC-NP with it is what any likelihood reaches.
* ``--bound data``: a KDE with the package's default settings (``KDEConfig(calibrate=False)``: the bandwidth by
  held-out likelihood, no correction, raw scores; not the analyses' posterior-chosen one) fitted on the training
  split (80 %) of 10,000 grasps per object and of ``--big`` per object, both evaluated on the same validation grasps: the 10,000 row separates the
  effect of more data from that of the bandwidth rule.

Both are compared with the analyses' own recogniser (``AnalysisConfig``; raw and calibrated scores). Trials run on
the analyses' validation split of the object set (never test grasps): ``--trials`` trials, objects drawn
uniformly, grasps of the trial's object without replacement.

    python benchmarks/likelihood_bound.py --objects default --fingers 2 --bound histogram
    python benchmarks/likelihood_bound.py --objects kit8 --fingers 3 --bound data

Headline (last line): BC-NP right at the stop with the reference (the histogram: the best of its three bin counts, a
generous bound; the data bound: the ``--big`` KDE) against the analyses' calibrated KDE.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import int_in  # noqa: E402
from haptic_env.dataset import build_dataset  # noqa: E402
from haptic_env.experiments.config import AnalysisConfig  # noqa: E402
from haptic_env.experiments.trials import simulate_trials  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood  # noqa: E402
from haptic_env.recognizers.recognizer import build_recognizer  # noqa: E402
from haptic_env.recognizers.updaters import DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD  # noqa: E402


def bc_np(S: list[np.ndarray], trials: int) -> tuple[str, float]:
    """BC-NP on per-object score rows ``S[k] (m_k, K)``: a line with the success right at the stop, decided and correct,
    mean grasps and one-shot accuracy; and the success right at the stop (%)."""
    K = len(S)
    r = simulate_trials(S, [np.full_like(s, 1.0 / K) for s in S], "bc-np", trials=trials, max_grasps=DEFAULT_MAX_GRASPS,
                        threshold=DEFAULT_THRESHOLD, rng=np.random.default_rng(2))
    one = np.mean(np.concatenate([np.argmax(s, 1) == k for k, s in enumerate(S)]))
    return (f"right at the stop {100 * np.mean(r['success']):.1f} %, decided and correct "
            f"{100 * np.mean(r['success'] & r['decided']):.1f} %, {np.mean(r['grasps']):.2f} grasps "
            f"(one-shot {100 * one:.1f} %)"), 100 * np.mean(r["success"])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", default="default")
    ap.add_argument("--fingers", type=int_in(2), default=2,
                    help="grasp vectors without normals (the cells in question)")
    ap.add_argument("--bound", choices=("histogram", "data"), default="histogram")
    ap.add_argument("--big", type=int_in(100), default=100_000, help="grasps per object of the reference")
    ap.add_argument("--trials", type=int_in(1), default=3000)
    args = ap.parse_args(argv)
    if args.bound == "histogram" and args.fingers != 2:
        ap.error(f"--bound histogram needs --fingers 2 (one distance per grasp), got {args.fingers}")
    objects = load_object_set(args.objects)
    K, n = len(objects), args.fingers
    rc = AnalysisConfig(progress=False).recognizer_config()
    dcfg = rc.dataset_config(n, False, hand_fingers=n)
    ds = build_dataset(objects, dcfg, progress=False)
    Xv = [ds.X_val[ds.y_val == k].astype(np.float64) for k in range(K)]
    print(f"{args.objects}, {n} fingers without normals; {sum(len(x) for x in Xv)} validation grasps, "
          f"{args.trials} BC-NP trials, lambda {DEFAULT_THRESHOLD}, at most {DEFAULT_MAX_GRASPS} grasps")
    t0 = time.perf_counter()
    big = build_dataset(objects, dataclasses.replace(dcfg, grasps_per_object=args.big, seed=12345), progress=False)
    best = 0.0
    if args.bound == "histogram":
        x = big.X_train[:, 0]
        lo = min(float(x.min()), min(float(v.min()) for v in Xv)) - 1e-9
        hi = max(float(x.max()), max(float(v.max()) for v in Xv)) + 1e-9
        for bins in (50, 100, 200):
            edges = np.linspace(lo, hi, bins + 1)
            H = np.stack([np.histogram(x[big.y_train == k], edges)[0] + 0.5 for k in range(K)])
            logp = np.log(H / H.sum(1, keepdims=True) / np.diff(edges))  # (K, bins)
            S = [logp[:, np.clip(np.searchsorted(edges, v[:, 0]) - 1, 0, bins - 1)].T for v in Xv]
            line, succ = bc_np(S, args.trials)
            best = max(best, succ)
            print(f"histogram of {len(x) // K} grasps per object (the training split of --big {args.big}), {bins} "
                  f"bins: {line}")
    else:
        for N, data in ((10_000, build_dataset(objects, dataclasses.replace(dcfg, grasps_per_object=10_000, seed=12345),
                                               progress=False)), (args.big, big)):
            kde = KDELikelihood(KDEConfig(calibrate=False)).fit(data.X_train, data.y_train, data.X_val, data.y_val)
            line, succ = bc_np([kde.log_likelihood(v) for v in Xv], args.trials)
            best = succ if N == args.big else best
            print(f"KDE (raw) of {len(data.X_train) // K} grasps per object (the training split of {N}): {line}")
    print(f"(references built in {time.perf_counter() - t0:.0f} s)")
    rec = build_recognizer(objects, n, False, config=rc, models=("kde",), progress=False)
    ours = 0.0
    for cal in (False, True):
        line, succ = bc_np([rec.models.with_calibration(cal).log_likelihood(v) for v in Xv], args.trials)
        ours = succ if cal else ours
        print(f"the analyses' KDE ({'calibrated' if cal else 'raw'}): {line}")
    ref = "histogram, best of 50 / 100 / 200 bins" if args.bound == "histogram" else f"data, {args.big:,} per object"
    se = 100 * np.sqrt(0.25 / args.trials)  # the binomial standard error's largest value, at 50 %
    print(f"HEADLINE: BC-NP right at the stop {best:.1f} % with the reference ({ref}) against {ours:.1f} % with "
          f"the analyses' calibrated KDE ({args.objects}, n = {n}, no normals, validation; {args.trials} trials, "
          f"one seed, binomial SE <= {se:.1f} points)")


if __name__ == "__main__":
    main()
