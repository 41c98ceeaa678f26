"""One-shot ECE of the analyses' calibrated KDE against its bandwidth factor: is an ECE miss over-fitting of the
calibration, or the calibration family's limit at the NLL optimum?

For each fixed bandwidth factor (x Scott's rule) the analyses' KDE (``AnalysisConfig``, 10,000 grasps per object) is
fitted without calibration; the two calibrations of :mod:`haptic_env.recognizers.calibration` (the temperature
alone, and the learned correction then the temperature) are fitted on one half of the validation split (seed 5)
and scored on the other half (``val``) by the NLL of the true class and the ECE (10 bins). The test columns use the
experiments' fresh test grasps (``--test-grasps`` per object, seed + 7919); nothing is chosen on them. The factor
the analyses' own KDE picks (``KDEConfig.factor = "auto"`` with the analyses' ``KDEConfig.select``, the calibrated
posterior's held-out validation NLL; ``--select likelihood`` gives the density's validation likelihood) is marked
``(auto)``.

    python benchmarks/ece_bandwidth.py --objects default --fingers 4 --no-normals

Headline (last line): the factor with the lowest held-out validation NLL after the correction and temperature,
and its test ECE, against the ``auto`` factor's.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
from scipy.special import log_softmax, softmax

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import float_list_in, int_in  # noqa: E402
from haptic_env.dataset import build_dataset  # noqa: E402
from haptic_env.experiments.config import AnalysisConfig  # noqa: E402
from haptic_env.experiments.fresh_grasps import fresh_pool  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.calibration import expected_calibration_error, fit_correction, fit_temperature  # noqa: E402
from haptic_env.recognizers.kde import SELECTS, KDELikelihood  # noqa: E402


def _nll(S: np.ndarray, y: np.ndarray) -> float:
    return float(-log_softmax(S, axis=1)[np.arange(len(y)), y].mean())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--objects", default="default")
    p.add_argument("--fingers", type=int_in(2), default=4)
    p.add_argument("--no-normals", action="store_true")
    p.add_argument("--factors", type=float_list_in(0.0, lo_open=True), default="0.35,0.5,0.7,1.0,1.4,2.0,2.8",
                   help="comma list of bandwidth factors, each a finite number > 0")
    p.add_argument("--test-grasps", type=int_in(1), default=400)
    p.add_argument("--select", default=None, choices=SELECTS,
                   help="the (auto) row's bandwidth criterion (default: the analyses' KDEConfig.select)")
    a = p.parse_args(argv)
    factors = list(a.factors)
    if not factors:
        p.error("argument --factors: give at least one factor")
    normals = not a.no_normals
    objects = load_object_set(a.objects)
    cfg = dataclasses.replace(AnalysisConfig(), objects=a.objects, test_grasps=a.test_grasps, progress=False)
    rc = cfg.recognizer_config()
    t0 = time.perf_counter()
    ds = build_dataset(objects, rc.dataset_config(a.fingers, normals, hand_fingers=a.fingers), progress=False)
    pool = fresh_pool(objects, a.fingers, normals, cfg)
    Xt = np.concatenate(pool)
    yt = np.concatenate([np.full(len(g), k) for k, g in enumerate(pool)])
    yv = np.asarray(ds.y_val)
    perm = np.random.default_rng(5).permutation(len(yv))
    A, B = perm[: len(perm) // 2], perm[len(perm) // 2:]
    kcfg = dataclasses.replace(rc.kde, calibrate=False, **({} if a.select is None else {"select": a.select}))
    auto = KDELikelihood(kcfg).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=len(objects))
    auto_f = float(auto.factor[0])
    if auto_f not in factors:
        factors = sorted([*factors, auto_f])
    crit = ", ".join(f"{f:g}: {v:.4f}" for f, v in auto.selection.items())
    print(f"(auto): factor {auto_f:g}, chosen by {kcfg.select} ({crit})")
    print(f"{a.objects}, n = {a.fingers}, {'with' if normals else 'without'} normals; {len(ds.X_train)} training, "
          f"{len(yv)} validation ({len(B)} held out), {len(yt)} test grasps\n")
    print("| factor | accuracy val / test % | T only: T | val NLL | val ECE | test ECE | correction + T: T | val NLL "
          "| val ECE | test ECE | test NLL |")
    print("|" + "---|" * 11)
    rows = []
    for f in factors:
        kde = KDELikelihood(dataclasses.replace(rc.kde, factor=f, calibrate=False)).fit(
            ds.X_train, ds.y_train, n_classes=len(objects))
        Sv, St = kde.log_likelihood(ds.X_val), kde.log_likelihood(Xt)
        T = fit_temperature(Sv[A], yv[A])
        corr = fit_correction(Sv[A], yv[A])
        T2 = fit_temperature(corr(Sv[A]), yv[A])
        cv, ct = corr(Sv[B]) / T2, corr(St) / T2
        r = dict(f=f, nll_v=_nll(cv, yv[B]), ece_t=expected_calibration_error(softmax(ct, axis=1), yt))
        rows.append(r)
        print(f"| {f:g}{' (auto)' if f == auto_f else ''} | {100 * np.mean(Sv.argmax(1) == yv):.1f} / "
              f"{100 * np.mean(St.argmax(1) == yt):.1f} | {T:.2f} | {_nll(Sv[B] / T, yv[B]):.3f} "
              f"| {expected_calibration_error(softmax(Sv[B] / T, axis=1), yv[B]):.3f} "
              f"| {expected_calibration_error(softmax(St / T, axis=1), yt):.3f} | {T2:.2f} | {r['nll_v']:.3f} "
              f"| {expected_calibration_error(softmax(cv, axis=1), yv[B]):.3f} | {r['ece_t']:.3f} "
              f"| {_nll(ct, yt):.3f} |", flush=True)
    best = min(rows, key=lambda r: r["nll_v"])
    at = next(r for r in rows if r["f"] == auto_f)
    print(f"\n{time.perf_counter() - t0:.0f} s")
    print(f"lowest held-out validation NLL (correction + T): factor {best['f']:g}, test ECE {best['ece_t']:.3f}; "
          f"auto factor {auto_f:g}: test ECE {at['ece_t']:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
