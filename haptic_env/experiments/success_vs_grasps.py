"""Experiment 6: success rate vs number of grasps, threshold disregarded (n = 4; ``success_vs_grasps.png``)."""

from __future__ import annotations

import numpy as np

from haptic_env.experiments.config import KINDS, AnalysisConfig
from haptic_env.experiments.fresh_grasps import fresh_pool, pool_scores, scored_models
from haptic_env.experiments.plots import plot_success_vs_grasps
from haptic_env.experiments.report import Report
from haptic_env.experiments.trials import simulate_trials
from haptic_env.recognizers.recognizer import build_recognizer

__all__ = ["run", "MAX_CURVE_GRASPS"]

#: Grasps the curve runs to (at most ``cfg.max_grasps``).
MAX_CURVE_GRASPS = 15


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    rep.h(f"6. Success rate vs number of grasps (threshold disregarded; n = 4, normals: {cfg.normals}; "
          f"{cfg.scores_label})")
    rec = build_recognizer(objects, 4, cfg.normals, config=cfg.recognizer_config(), progress=False)
    LL, PR = pool_scores(scored_models(rec, cfg), fresh_pool(objects, 4, cfg.normals, cfg))
    M = min(cfg.max_grasps, MAX_CURVE_GRASPS)
    curves = {}
    for kind in KINDS:
        res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=M, threshold=cfg.threshold, rng=rng,
                              fixed_steps=True)
        curves[kind] = 100 * res["correct_at"].mean(0)
    rep.table(["grasps", *KINDS], [[m + 1, *[f"{curves[k][m]:.1f}" for k in KINDS]] for m in range(M)])
    plot_success_vs_grasps(curves, rep.out / "success_vs_grasps.png")
