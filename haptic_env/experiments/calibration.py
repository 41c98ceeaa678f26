"""Experiment 7: calibration of the posteriors on fresh test grasps.

Per cell (``cfg.calib_fingers`` with normals, ``cfg.calib_fingers_no_normals`` without): the one-shot
expected calibration error (ECE), NLL and confidence of BC (softmax of the KDE log-likelihoods) and of the
MLP, raw and temperature-scaled, with reliability diagrams (``reliability_<cell>.png``); success at the stop
and mean grasps vs lambda for IC, BC-NP and BC-IP, raw and calibrated (``lambda_sweep_<cell>.png``), and with
``cfg.uses_stop_scale`` (the default) for BC-NP and BC-IP with experiment 2's stop scale, chosen on validation trials
at each lambda (:mod:`~haptic_env.experiments.stop_scale`): the curve a stop that means what it says should follow,
just above ``success = lambda``.
"""

from __future__ import annotations

import numpy as np
from scipy.special import softmax
from tqdm.auto import tqdm

from haptic_env.experiments.config import MAIN_KINDS, AnalysisConfig
from haptic_env.experiments.fresh_grasps import fresh_pool, pool_scores
from haptic_env.experiments.plots import plot_lambda_sweep, plot_reliability
from haptic_env.experiments.report import Report, kde_temperature, mean_std
from haptic_env.experiments.stop_scale import fit_cell_stop_scales, scaled
from haptic_env.experiments.trials import simulate_trials
from haptic_env.recognizers.calibration import _finite_or_minus_inf, _finite_rows, expected_calibration_error
from haptic_env.recognizers.recognizer import build_recognizer
from haptic_env.splits import TEST_SEED_OFFSET

__all__ = ["run", "oneshot_posterior", "calibration_summary", "cell_name"]


def oneshot_posterior(scores) -> np.ndarray:
    """Row-wise softmax of class scores ``(B, K)`` (BC's one-shot posterior under a uniform prior when the
    scores are KDE log-likelihoods). ``-inf`` allowed; a row with no finite score is uniform (the updater
    leaves its belief unchanged); NaN or ``+inf`` is a ValueError (it was put at the floor: probability 0)."""
    return softmax(_finite_rows(_finite_or_minus_inf(scores)), axis=1)


def calibration_summary(proba, y, bins: int = 10) -> dict[str, float]:
    """Accuracy, ECE (``bins`` equal-width bins), NLL of the true class and mean confidence of ``proba (B, K)``."""
    P = np.asarray(proba, dtype=np.float64)
    y = np.asarray(y, dtype=np.int64)
    return {"accuracy": float(np.mean(P.argmax(1) == y)), "ece": expected_calibration_error(P, y, bins),
            "nll": float(-np.log(np.maximum(P[np.arange(len(y)), y], 1e-300)).mean()),
            "confidence": float(P.max(1).mean())}


def cell_name(n: int, normals: bool) -> str:
    """The file-name part of a cell's plots: ``n4_normals``, ``n3_no_normals``."""
    return f"n{n}_{'normals' if normals else 'no_normals'}"


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    rep.h("7. Calibration of the posteriors on fresh test grasps (raw vs calibrated)")
    cells = [(n, True) for n in cfg.calib_fingers] + [(n, False) for n in cfg.calib_fingers_no_normals]
    ece_rows, stop_rows, sweeps, stop_scales = [], [], {}, {}
    for n, normals in tqdm(cells, desc="exp7 cells", disable=not cfg.progress):
        rec = build_recognizer(objects, n, normals, config=cfg.recognizer_config(), progress=False)
        T = rec.models.temperature(n)
        pool = fresh_pool(objects, n, normals, cfg)
        y = np.concatenate([np.full(len(p), k) for k, p in enumerate(pool)])
        scores = {v: pool_scores(rec.models.with_calibration(v == "calibrated"), pool) for v in ("raw", "calibrated")}
        curves = {}
        bc = "BC (KDE)" if cfg.likelihood == "kde" else f"BC ({cfg.likelihood})"
        for model, Tm, label in ((bc, T["kde"], kde_temperature(rec.models, n)),
                                 ("MLP", T["classifier"], f"{T['classifier']:.2f}")):
            row = [n, "yes" if normals else "no", model, label]
            for v in ("raw", "calibrated"):
                LL, PR = scores[v]
                P = oneshot_posterior(np.concatenate(LL)) if model.startswith("BC") else np.concatenate(PR)
                s = calibration_summary(P, y, cfg.ece_bins)  # the calibrated scores' own argmax (a correction moves it)
                row += [f"{100 * s['accuracy']:.1f}", f"{s['ece']:.3f}", f"{s['nll']:.3f}",
                        f"{100 * s['confidence']:.1f}"]
                curves.setdefault(model, {})[v] = (P, y, Tm)
            ece_rows.append(row)
        title = f"n = {n}, {'with' if normals else 'without'} normals"
        plot_reliability(curves, cfg.ece_bins, title, rep.out / f"reliability_{cell_name(n, normals)}.png")
        # (updater, scores, their per-lambda stop scale): raw and calibrated unscaled; BC also with experiment 2's
        # stop scale, fitted on validation trials at each lambda (at experiment 2's lambda, its scale)
        runs = [(kind, v, [1.0] * len(cfg.lambdas)) for kind in MAIN_KINDS for v in ("raw", "calibrated")]
        if cfg.uses_stop_scale:
            stop_scales[(n, normals)] = [row[0] for row in fit_cell_stop_scales(
                rec.models.with_calibration(True), objects, n, normals, cfg, cfg.lambdas)]
            runs += [(kind, "stop scale", stop_scales[(n, normals)]) for kind in ("bc-np", "bc-ip")]
        sweep = {}
        for kind, v, scales in runs:
            LL, PR = scores["raw" if v == "raw" else "calibrated"]
            # one trial rng per cell: every updater, lambda and variant sees the same objects and grasp sequences
            # (paired comparisons, smooth curves)
            sweep[(kind, v)] = [
                _sweep_point(simulate_trials(scaled(LL, sc), PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps,
                                             threshold=lam, rng=np.random.default_rng([cfg.seed, n, int(normals)]),
                                             ic_certainty=cfg.ic_certainty))
                for lam, sc in zip(cfg.lambdas, scales)]
        sweeps[(n, normals)] = sweep
        plot_lambda_sweep({k: [p[:2] for p in v] for k, v in sweep.items()}, cfg.lambdas, title,
                          rep.out / f"lambda_sweep_{cell_name(n, normals)}.png")
        li = int(np.argmin(np.abs(np.asarray(cfg.lambdas) - cfg.threshold)))
        for kind in MAIN_KINDS:
            r, c = sweep[(kind, "raw")][li], sweep[(kind, "calibrated")][li]
            stop_rows.append([n, "yes" if normals else "no", kind, f"{r[2]:.1f}", f"{r[0]:.1f}", mean_std(r[1], r[3], 2),
                              f"{c[2]:.1f}", f"{c[0]:.1f}", mean_std(c[1], c[3], 2)])
            if cfg.uses_stop_scale:
                z = sweep.get((kind, "stop scale"))
                stop_rows[-1] += ([f"{z[li][2]:.1f}", f"{z[li][0]:.1f}", mean_std(z[li][1], z[li][3], 2)] if z
                                  else ["-", "-", "-"])
    rep.p(f"Test grasps: {cfg.test_grasps} fresh grasps per object (seed {cfg.seed + TEST_SEED_OFFSET}), never used to "
          f"fit T (T is fitted on the training data's validation split). One-shot posterior: "
          f"BC = {_bc_posterior(cfg)}, MLP = softmax(logits / T). ECE over {cfg.ece_bins} equal-width confidence "
          "bins; NLL of the true class; conf = mean max posterior; acc = one-shot accuracy of each variant's own "
          "argmax (a temperature does not move it, the KDE's learned correction can). Reliability diagrams: "
          "`reliability_<cell>.png`.")
    rep.table(["n", "normals", "model", "T", "acc raw %", "ECE raw", "NLL raw", "conf raw %", "acc cal %", "ECE cal",
               "NLL cal", "conf cal %"], ece_rows)
    lam0 = cfg.lambdas[int(np.argmin(np.abs(np.asarray(cfg.lambdas) - cfg.threshold)))]
    rep.p(f"Sequential recognition at lambda = {lam0}: success = correct at the stop; d&c = decided (certainty "
          f">= lambda within {cfg.max_grasps} grasps) and correct; grasps mean ± std. {cfg.trials} trials per cell, "
          "the same objects and grasp sequences for every updater, lambda, raw and calibrated (paired).")
    rep.table(["n", "normals", "updater", "raw success %", "raw d&c %", "raw grasps", "cal success %", "cal d&c %",
               "cal grasps"] + (["stop-scaled success %", "stop-scaled d&c %", "stop-scaled grasps"]
                                if cfg.uses_stop_scale else []), stop_rows)
    rep.p("Success at the stop (decided and correct, %) / mean grasps vs lambda; plots `lambda_sweep_<cell>.png` "
          "(solid: calibrated, dashed: raw, dotted: success = lambda" +
          (", dash-dot: BC with the stop scale, chosen on validation trials at each lambda as in experiment 2, the "
           "scale s in brackets" if cfg.uses_stop_scale else "") + ").")
    hdr = ["n", "normals", "updater", "scores", *[f"λ={lam:g}" for lam in cfg.lambdas]]
    rows = []
    for (n, normals), sweep in sweeps.items():
        for (kind, v), pts in sweep.items():
            ss = stop_scales[(n, normals)] if v == "stop scale" else [None] * len(pts)
            rows.append([n, "yes" if normals else "no", kind, v,
                         *[f"{p[0]:.1f} / {p[1]:.2f}" + ("" if sc is None else f" (s {sc:g})")
                           for p, sc in zip(pts, ss)]])
    rep.table(hdr, rows)


def _sweep_point(res: dict) -> tuple[float, float, float, float]:
    """One lambda of the sweep from ``simulate_trials``: (decided and correct %, mean grasps, correct %, grasps std)."""
    dc = res["success"] & res["decided"]
    return 100 * dc.mean(), float(res["grasps"].mean()), 100 * res["success"].mean(), float(res["grasps"].std())


def _bc_posterior(cfg: AnalysisConfig) -> str:
    """BC's one-shot posterior in words: of the KDE, as it is calibrated, or of the opt-in gradient boosting."""
    if cfg.likelihood == "hgb":
        return ("softmax of the gradient-boosting log-likelihoods (`--likelihood hgb`: no correction, and no "
                "temperature of its own: T = 1)")
    return f"softmax of the KDE log-likelihoods ({_kde_calibration(cfg.kde)})"


def _kde_calibration(kde) -> str:
    """How the KDE's one-shot scores are calibrated, in words (``KDEConfig.correct``, ``correct_candidates``)."""
    if kde.correct == "auto":
        power = (", or the power of each class's gap to the best, marked 'power p',"
                 if "power" in kde.correct_candidates else "")
        return (f"learned correction{power} where it lowers the held-out validation NLL, marked 'corrected', then / T"
                if "matrix" in kde.correct_candidates else
                "the power of each class's gap to the best where it lowers the held-out validation NLL, marked "
                "'power p', then / T")
    if kde.correct == "power":
        return "the power of each class's gap to the best, then / T"
    return "learned correction, then / T" if kde.correct else "/ T"
