"""Experiment 3: z-finger scoring of n-finger grasps (z = 3, 4; every subset, or k = 4 random ones per grasp;
paper Algorithms 3 and 4) and incomplete grasps (finger count z ~ p_n(z) per grasp, each scored by its
z-finger model)."""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from haptic_env.experiments import paper
from haptic_env.experiments.config import MAIN_KINDS, AnalysisConfig
from haptic_env.belief import Belief
from haptic_env.experiments.fresh_grasps import contact_pool, fresh_pool, pool_scores, scored_models
from haptic_env.experiments.report import Report, mean_std
from haptic_env.experiments.trials import incomplete_trials, simulate_trials, summarize
from haptic_env.recognizers.recognizer import build_recognizer
from haptic_env.splits import TEST_SEED_OFFSET

__all__ = ["run", "SUBSET_SIZES"]

#: The z of the z-finger models.
SUBSET_SIZES = (3, 4)


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    rep.h(f"3. z-finger scoring and incomplete grasps (lambda = {cfg.threshold}, normals: {cfg.normals}; "
          f"{cfg.scores_label})")
    rows = []
    with_paper = paper.applies(cfg.objects, cfg.threshold)  # its figures are at lambda = 0.85
    recs = {z: build_recognizer(objects, z, cfg.normals, config=cfg.recognizer_config(), progress=False)
            for z in SUBSET_SIZES}
    beliefs = {z: Belief(rec, calibrated=cfg.calibrated) for z, rec in recs.items()}  # their subset scoring
    for n in tqdm(cfg.zfinger_hands, desc="exp3 hands", disable=not cfg.progress):
        raw = contact_pool(objects, n, cfg.normals, max(50, cfg.test_grasps // 2), cfg.seed + TEST_SEED_OFFSET + n,
                           cfg.force_closure)
        for z in SUBSET_SIZES:
            if z >= n:
                continue
            for k_sub in (None, 4):
                srng = np.random.default_rng([cfg.seed, n, z])
                LL, PR = [], []
                for C, N in raw:
                    ll, pr, _ = beliefs[z].subset_scores(C, N, z, k_sub, srng)
                    LL.append(ll)
                    PR.append(pr)
                row = [n, z, "all" if k_sub is None else f"k={k_sub}"]
                for kind in MAIN_KINDS:
                    sr, se, gm, gs = summarize(simulate_trials(LL, PR, kind, trials=cfg.trials,
                                                               max_grasps=cfg.max_grasps, threshold=cfg.threshold,
                                                               rng=rng, ic_certainty=cfg.ic_certainty))
                    row += [f"{sr:.1f} ± {se:.1f}", mean_std(gm, gs, 2)]
                if with_paper:  # the paper's figures are for 4 random subsets per grasp
                    row += [_paper_cell(paper.ZFINGER.get((kind, z, n, cfg.normals)) if k_sub == 4 else None)
                            for kind in ("ic", "bc-np")]
                rows.append(row)
    rep.table(["hand n", "z", "subsets", "IC success %", "IC grasps", "BC-NP success %", "BC-NP grasps",
               "BC-IP success %", "BC-IP grasps"]
              + (["paper IC success % / grasps", "paper BC-NP success % / grasps"] if with_paper else []), rows)
    rep.p("Per grasp, every (or k = 4 random) z-subset of the n contacts is mapped to Phi_z; BC multiplies the "
          "subsets' KDE likelihoods, IC sums their probability vectors (paper Algorithms 3, 4)." +
          (" Paper: kit8 at 200,000 grasps per object, 4 random z-subsets per grasp (so beside the k = 4 rows), "
           "hands of 4-7 fingers." if with_paper else ""))
    # incomplete grasps
    pn = dict(cfg.incomplete_pn)
    zlist = sorted(pn)
    recs_inc = {z: build_recognizer(objects, z, cfg.normals, config=cfg.recognizer_config(), progress=False)
                for z in zlist}
    pools = {z: pool_scores(scored_models(recs_inc[z], cfg), fresh_pool(objects, z, cfg.normals, cfg)) for z in zlist}
    p = np.array([pn[z] for z in zlist]) / sum(pn.values())
    rows = []
    for kind in MAIN_KINDS:
        sr, se, gm, gs = summarize(incomplete_trials(pools, p, kind, trials=cfg.trials, max_grasps=cfg.max_grasps,
                                                     threshold=cfg.threshold, rng=rng, ic_certainty=cfg.ic_certainty))
        rows.append([kind, f"{sr:.1f} ± {se:.1f}", mean_std(gm, gs, 2)]
                    + ([_paper_cell(paper.INCOMPLETE.get((kind, max(zlist), cfg.normals)))] if with_paper else []))
    rep.p(f"Incomplete grasps: finger count z ~ p_n(z) = {pn} per grasp, each scored by its z-finger model." +
          (f" Paper: kit8's incomplete grasps of an n = {max(zlist)} hand (its p_n(z) is not in the reference "
           "summary)." if with_paper else ""))
    rep.table(["updater", "success %", "grasps"] + (["paper success % / grasps"] if with_paper else []), rows)


def _paper_cell(figure: tuple[float, float] | None) -> str:
    """The paper's ``(success %, grasps)`` as a table cell; "-" where it gives none."""
    return "-" if figure is None else f"{figure[0]:g} / {figure[1]:g}"
