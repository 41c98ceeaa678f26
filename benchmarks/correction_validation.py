"""How the KDE's scores are calibrated, chosen on validation grasps only: BC-NP with the temperature alone
(one-shot, or fitted for beliefs of 1-5 grasps) against the learned correction (``calibration.fit_correction``)
with a one-shot or a 5-grasp temperature on top, and what ``KDEConfig.correct="auto"`` (the analyses' KDE, whose
candidates are the matrix and the power correction) chose for each n.

    python benchmarks/correction_validation.py [--objects default] [--fingers 4,5,8] [--no-normals]

The recogniser is the analyses' (``AnalysisConfig``: 10,000 surface grasps per object, tree KDE). Its validation
split (20 % of the training grasps, ``DatasetConfig.val_fraction``, never trained on) is halved per object: the
calibration is fitted on half A and BC-NP runs on half B (600 trials, lambda = 0.85, at most 30 grasps, grasps drawn
from the trial's object without replacement). Success = decided and correct at the stop. Also printed: the held-out
NLL of the true class under the one-shot posterior on half B (the criterion of ``calibration.select_correction``),
and the argmax accuracy of the summed scores after m grasps (does the belief converge on the right object at all?).
Test grasps are never used. Headline (last line): BC-NP success with the correction against the one-shot temperature
at the last ``--fingers`` entry (the largest n of the default list), with its trial count (one seed).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import int_in, int_list_in  # noqa: E402
from haptic_env.dataset import build_dataset  # noqa: E402
from haptic_env.experiments.config import AnalysisConfig  # noqa: E402
from haptic_env.experiments.report import kde_temperature  # noqa: E402
from haptic_env.experiments.trials import simulate_trials  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.calibration import fit_correction, fit_temperature, sequence_scores, tempered_nll  # noqa: E402
from haptic_env.recognizers.recognizer import build_recognizer  # noqa: E402
from haptic_env.recognizers.updaters import DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD  # noqa: E402


def argmax_accuracy(S: list[np.ndarray], m: int, rng: np.random.Generator, draws: int = 200) -> float:
    """Fraction of ``draws`` per object whose sum of ``m`` random rows has its argmax at the object."""
    hits = [np.argmax(s[rng.choice(len(s), m, replace=False)].sum(0)) == k for k, s in enumerate(S) for _ in range(draws)]
    return float(np.mean(hits))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", default="default")
    ap.add_argument("--fingers", type=int_list_in(2), default=(4, 5, 8), help="comma list of finger counts")
    ap.add_argument("--no-normals", action="store_true")
    ap.add_argument("--trials", type=int_in(1), default=600)
    args = ap.parse_args(argv)
    objects = load_object_set(args.objects)
    normals = not args.no_normals
    cfg = AnalysisConfig(progress=False)
    K = len(objects)
    print(f"{args.objects}, normals={normals}; validation halves A (fit) / B (trials); BC-NP at lambda "
          f"{DEFAULT_THRESHOLD}")
    print("| n | scores | BC-NP success % | grasps | held-out one-shot NLL | argmax after 1 / 5 / 10 / 30 grasps % |")
    print("|---|---|---|---|---|---|")
    last = None
    for n in args.fingers:
        rc = cfg.recognizer_config()
        rec = build_recognizer(objects, n, normals, config=rc, models=("kde",), progress=False)
        ds = build_dataset(objects, rc.dataset_config(n, normals, hand_fingers=n), progress=False)
        raw = rec.models.with_calibration(False)
        LL = [raw.log_likelihood(ds.X_val[ds.y_val == k].astype(np.float64)) for k in range(K)]
        A, B = [s[: len(s) // 2] for s in LL], [s[len(s) // 2:] for s in LL]
        SA, yA = np.concatenate(A), np.concatenate([np.full(len(a), k) for k, a in enumerate(A)])
        corr = fit_correction(SA, yA)
        T1 = fit_temperature(SA, yA)
        T5 = fit_temperature(*sequence_scores(SA, yA, 5, np.random.default_rng(1)))
        Tc1 = fit_temperature(corr(SA), yA)
        Tc5 = fit_temperature(*sequence_scores(corr(SA), yA, 5, np.random.default_rng(1)))
        variants = {f"one-shot T = {T1:.2f}": lambda S: S / T1, f"5-grasp T = {T5:.2f}": lambda S: S / T5,
                    "correction": corr, f"correction + one-shot T = {Tc1:.2f}": lambda S: corr(S) / Tc1,
                    f"correction + 5-grasp T = {Tc5:.2f}": lambda S: corr(S) / Tc5}
        yB = np.concatenate([np.full(len(b), k) for k, b in enumerate(B)])
        res = {}
        for name, f in variants.items():
            Bs = [f(b) for b in B]
            r = simulate_trials(Bs, [np.full_like(b, 1.0 / K) for b in Bs], "bc-np", trials=args.trials,
                                max_grasps=DEFAULT_MAX_GRASPS, threshold=DEFAULT_THRESHOLD,
                                rng=np.random.default_rng(2))
            succ = 100 * np.mean(r["success"] & r["decided"])
            acc = " / ".join(f"{100 * argmax_accuracy(Bs, m, np.random.default_rng(3)):.1f}" for m in (1, 5, 10, 30))
            nll = tempered_nll(np.concatenate(Bs), yB, 1.0)
            print(f"| {n} | {name} | {succ:.1f} | {r['grasps'].mean():.2f} | {nll:.3f} | {acc} |", flush=True)
            res[name.split(" =")[0]] = succ
        print(f"| {n} | the analyses' KDE (correct='auto'): T {kde_temperature(rec.models, n)} (\"corrected\": the "
              "matrix correction first; \"power p\": the power; neither: the temperature alone) | | | | |")
        last = (n, res["one-shot T"], res["correction"])
    if last:
        n, a, b = last
        se = 100 * np.sqrt(0.25 / args.trials)  # the binomial standard error's largest value, at 50 %
        print(f"\nBC-NP success on validation at n = {n} ({args.trials} trials, one seed; binomial SE <= {se:.1f} "
              f"points): {a:.1f} % (one-shot T) -> {b:.1f} % (learned correction)")


if __name__ == "__main__":
    main()
