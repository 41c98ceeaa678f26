"""Experiment 4: scaled objects (a random scale in ``cfg.scale_range`` per grasp, n = 4), trained and tested
with and without scale normalisation."""

from __future__ import annotations

import numpy as np

from haptic_env.experiments import paper
from haptic_env.experiments.config import MAIN_KINDS, AnalysisConfig
from haptic_env.experiments.fresh_grasps import fresh_pool, pool_scores, scored_models
from haptic_env.experiments.report import Report, mean_std
from haptic_env.experiments.trials import simulate_trials, summarize
from haptic_env.recognizers.recognizer import build_recognizer

__all__ = ["run"]


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    rep.h(f"4. Scaled objects (scale ~ U{cfg.scale_range} per grasp, n = 4, normals: {cfg.normals}; "
          f"{cfg.scores_label})")
    rows = []
    with_paper = paper.applies(cfg.objects, cfg.threshold)  # its figures are at lambda = 0.85
    for norm in (False, True):
        kw = {"scale_range": cfg.scale_range, "normalize_scale": norm}
        rec = build_recognizer(objects, 4, cfg.normals, config=cfg.recognizer_config(**kw), progress=False)
        LL, PR = pool_scores(scored_models(rec, cfg), fresh_pool(objects, 4, cfg.normals, cfg, **kw))
        oneshot = np.mean(np.concatenate([p.argmax(1) == k for k, p in enumerate(PR)]))
        row = ["yes" if norm else "no", f"{100 * oneshot:.1f}"]
        for kind in MAIN_KINDS:
            sr, se, gm, gs = summarize(simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps,
                                                       threshold=cfg.threshold, rng=rng, ic_certainty=cfg.ic_certainty))
            row += [f"{sr:.1f} ± {se:.1f}", mean_std(gm, gs, 2)]
        if with_paper:  # the paper's figures are with scale normalisation, scales in [0.1, 5]
            row.append(" / ".join(f"{paper.SCALED[kind][(4, cfg.normals)]:g}" for kind in MAIN_KINDS)
                       if norm and tuple(cfg.scale_range) == paper.SCALE_RANGE else "-")
        rows.append(row)
    rep.table(["scale normalisation", "MLP one-shot %", "IC success %", "IC grasps", "BC-NP success %", "BC-NP grasps",
               "BC-IP success %", "BC-IP grasps"]
              + (["paper success % (IC / BC-NP / BC-IP)"] if with_paper else []), rows)
    if with_paper:
        rep.p("Paper: kit8 at 200,000 grasps per object, scales in [0.1, 5] with scale normalisation (success only; "
              "beside our row with scale normalisation when the scale range is the paper's).")
