"""Experiment 2: sequential recognition at ``lambda = cfg.threshold`` for each finger count ``cfg.fingers``:
success and grasps of IC, IC-full, BC-NP and BC-IP, the calibration temperatures, and confusion matrices
for n = 4 (``confusion_n4_<kind>.png``) and ``sequential_vs_fingers.png``. By default (``cfg.uses_stop_scale``)
BC-NP and BC-IP divide their log-likelihoods by a stop scale chosen on validation trials
(:mod:`~haptic_env.experiments.stop_scale`)."""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from haptic_env.experiments import paper
from haptic_env.experiments.config import KINDS, AnalysisConfig
from haptic_env.experiments.fresh_grasps import fresh_pool, pool_scores, scored_models
from haptic_env.experiments.plots import plot_confusion, plot_sequential_vs_fingers
from haptic_env.experiments.report import Report, kde_temperature, mean_std
from haptic_env.experiments.stop_scale import (STOP_SCALES, VALIDATION_GRASPS, VALIDATION_TRIALS, fit_cell_stop_scales,
                                               scaled)
from haptic_env.experiments.trials import confusion, simulate_trials, summarize
from haptic_env.recognizers.recognizer import build_recognizer
from haptic_env.splits import VALIDATION_SEED_OFFSET

__all__ = ["run", "PAPER_KINDS"]

#: the updaters whose grasps the paper gives (:data:`~haptic_env.experiments.paper.GRASPS`)
PAPER_KINDS = tuple(paper.GRASPS)


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    rep.h(f"2. Sequential recognition at lambda = {cfg.threshold} (normals: {cfg.normals}; {cfg.scores_label})")
    rows = []
    curves = {}
    K = len(objects)
    with_paper = paper.applies(cfg.objects, cfg.threshold)  # its figures are at lambda = 0.85
    for n in tqdm(cfg.fingers, desc="exp2 fingers", disable=not cfg.progress):
        rec = build_recognizer(objects, n, cfg.normals, config=cfg.recognizer_config(), progress=False)
        models = scored_models(rec, cfg)
        LL, PR = pool_scores(models, fresh_pool(objects, n, cfg.normals, cfg))
        oneshot = np.mean(np.concatenate([p.argmax(1) == k for k, p in enumerate(PR)]))
        T = rec.models.temperature(n)
        row = [n, f"{100 * oneshot:.1f}", kde_temperature(rec.models, n), f"{T['classifier']:.2f}"]
        if cfg.uses_stop_scale:  # its own stream: the test trials below are the same with and without it
            [(s, rate, grasps)] = fit_cell_stop_scales(models, objects, n, cfg.normals, cfg, [cfg.threshold])
            LL = scaled(LL, s)
            row.append(f"{s:g} ({100 * rate:.1f} % / {grasps:.2f})")
        for kind in KINDS:
            res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps, threshold=cfg.threshold,
                                  rng=rng, ic_certainty=cfg.ic_certainty)
            sr, se, gm, gs = summarize(res)
            dc = 100 * float(np.mean(res["success"] & res["decided"]))  # the hand table's measure beside it
            row += [f"{sr:.1f} ± {se:.1f} (d&c {dc:.1f})", mean_std(gm, gs, 2)]
            curves.setdefault(kind, []).append((n, sr, gm))
            if n == 4:
                plot_confusion(confusion(res["truth"], res["pred"], K), objects.names,
                               f"{kind}, n=4, lambda={cfg.threshold}", rep.out / f"confusion_n4_{kind}.png")
        if with_paper:
            for kind in PAPER_KINDS:
                theirs = paper.GRASPS[kind].get((n, cfg.normals))
                row.append("-" if theirs is None else mean_std(*theirs, 2))
        rows.append(row)
    t_lik = "T KDE" if cfg.likelihood == "kde" else f"T {cfg.likelihood}"
    hdr = ["n", "MLP one-shot %", t_lik, "T MLP"] + (["stop scale (validation BC-NP)"] if cfg.uses_stop_scale else [])
    for kind in KINDS:
        hdr += [f"{kind} success %", f"{kind} grasps"]
    if with_paper:
        hdr += [f"paper {kind} grasps" for kind in PAPER_KINDS]
    rep.table(hdr, rows)
    rep.p(f"{cfg.trials} trials per cell, at most {cfg.max_grasps} grasps; success = the prediction right at the "
          f"stop, the decision or the {cfg.max_grasps}th grasp (undecided trials count when right) ± binomial std, "
          "and in brackets d&c, decided (certainty >= lambda) and correct, the hand table's measure; grasps mean ± "
          "std. "
          "T: the calibration temperatures fitted on validation grasps (" +
          ("applied" if cfg.calibrated else "not applied: `--raw`") + "); " +
          ("BC's likelihood: gradient boosting (`--likelihood hgb`), no correction and no temperature of its own. "
           if cfg.likelihood == "hgb" else
           "\"corrected\": the KDE's learned correction comes first (`KDEConfig.correct`). ") +
          ("Confusion matrices for n = 4: `confusion_n4_<kind>.png`." if 4 in cfg.fingers else
           "(Confusion matrices are drawn for n = 4, not in this run's finger counts.)") +
          (f" Stop scale s (the default; `--no-stop-scale` turns it off): BC-NP and BC-IP sum log-likelihoods / s; "
           f"s is the scale of "
           f"{list(STOP_SCALES)} with the fewest BC-NP grasps whose validation stops are decided and right in at "
           f"least lambda of {VALIDATION_TRIALS} trials ({VALIDATION_GRASPS} fresh validation grasps per object, seed "
           f"{cfg.seed + VALIDATION_SEED_OFFSET}; 1 when none is); in brackets its validation rate and grasps."
           if cfg.uses_stop_scale else "") +
          (" Paper: kit8's mean ± std grasps to the stop at 200,000 grasps per object (n = 3-5; its success rates are "
           "given as plots only)." if with_paper else ""))
    if curves:
        theirs = None if not with_paper else {
            kind: [(n, paper.GRASPS[kind][(n, cfg.normals)][0]) for n, _, _ in curves[kind]
                   if (n, cfg.normals) in paper.GRASPS[kind]] for kind in PAPER_KINDS if kind in curves}
        plot_sequential_vs_fingers(curves, rep.out / "sequential_vs_fingers.png", theirs)
