"""Experiment 2's BC-NP belief with a gradient-boosted classifier as the likelihood (validation only).

On the simulated hands a tree ensemble in the KDE's place let BC-NP stop sooner at the same success (RESULTS.md, "A
tree ensemble as the belief's likelihood"). This benchmark asks the same of experiment 2's cells that miss their
target, kit8 without normals at n = 3-5 (BC-NP needs more grasps than 1.5x the paper's). Each likelihood is trained on
exactly experiment 2's training grasps (``AnalysisConfig``'s data set, its 80 % training split):

* ``kde``: experiment 2's calibrated KDE scores (its correction and temperature), the reported belief;
* ``hgb``: scikit-learn's histogram gradient boosting as ``log p(object | q) - log prior``, each class probability
  floored at 1e-6, on at most 50,000 training vectors per object (300 iterations at most, early stopping on 10 % of
  them): the analyses' ``--likelihood hgb`` (:mod:`haptic_env.recognizers.boosted`, ``AnalysisConfig.likelihood``),
  built and cached by ``build_recognizer`` as they build it.

Then experiment 2's stop scale is fitted on top of each, exactly as experiment 2 fits it
(``stop_scale.fit_stop_scale``: the scale with the fewest grasps whose validation stops are decided and right in at
least lambda of the trials; the log-likelihoods are divided by it), over a grid that reaches further down than
experiment 2's, in case a classifier's scores need more sharpening than the calibrated KDE's (none chose below 0.8):

* set A: experiment 2's own validation grasps (seed + 500, 1,500 per object) and trial stream, used to CHOOSE;
* set B: further fresh grasps (seed + ``CHECK_SEED_OFFSET``), only to CHECK, with the scale chosen on A.

No test grasp is used. The KDE's row at experiment 2's grid reproduces its own validation choice. Each finished finger
count is kept beside ``--out`` (``<out>.state.json``; without ``--out`` in the cache), and a run started again with
the same settings resumes from it (a run took 6.5-25 minutes). Run::

    OMP_NUM_THREADS=1 python benchmarks/stop_classifier.py --objects kit8 --no-normals --fingers 3,4,5 \\
        --grasps-per-object 200000 --out docs/results/stop_classifier/kit8_no_normals_200k.md
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.stop_floor import (CHECK_SEED_OFFSET, analysis_config, choose_and_check, chosen_cell,  # noqa: E402
                                   emit, experiment2_parser, finger_counts, kept_parts, md_table)
from haptic_env.cache import save_keyed_json  # noqa: E402
from haptic_env.experiments.fresh_grasps import fresh_pool  # noqa: E402
from haptic_env.experiments.stop_scale import STOP_SCALES, VALIDATION_GRASPS, VALIDATION_TRIALS  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.boosted import BoostedConfig  # noqa: E402
from haptic_env.recognizers.recognizer import build_recognizer  # noqa: E402
from haptic_env.splits import VALIDATION_SEED_OFFSET  # noqa: E402

#: experiment 2's grid and below it (sharper beliefs)
SCALES = (0.1, 0.15, 0.2, 0.25, 0.3, 0.35) + STOP_SCALES
LIKELIHOODS = ("kde", "hgb")


def main(argv=None):
    a = experiment2_parser(__doc__.split("\n\n")[0]).parse_args(argv)
    t0 = time.time()
    objects = load_object_set(a.objects)
    cfg = analysis_config(a)
    rows, frontier = [], []
    state, key, parts = kept_parts(a, "stop_classifier")
    for n in finger_counts(a):
        if str(n) in parts:  # an interrupted run finished it
            rows += parts[str(n)]["rows"]
            frontier += parts[str(n)]["frontier"]
            continue
        mark = len(rows), len(frontier)
        rec = build_recognizer(objects, n, cfg.normals, config=cfg.recognizer_config(), models=("kde",), progress=False)
        t1 = time.time()  # the fit, or reading it back from the cache
        hgb = build_recognizer(objects, n, cfg.normals, config=dataclasses.replace(cfg, likelihood="hgb")
                               .recognizer_config(), models=("kde",), progress=False)
        fit_s = time.time() - t1
        like = {"kde": rec.models.with_calibration(True).log_likelihood, "hgb": hgb.models.log_likelihood}
        pools = {name: fresh_pool(objects, n, cfg.normals, cfg, seed_offset=off, grasps=VALIDATION_GRASPS)
                 for name, off in (("A", VALIDATION_SEED_OFFSET), ("B", CHECK_SEED_OFFSET))}
        for lik in LIKELIHOODS:
            t1 = time.time()
            sets = {name: [like[lik](X) for X in pool] for name, pool in pools.items()}
            score_us = 1e6 * (time.time() - t1) / sum(len(X) for pool in pools.values() for X in pool)
            s, at, every, reached = choose_and_check(sets, n, cfg, SCALES)
            fit = fit_s if lik == "hgb" else float("nan")
            r = {"n": n, "lik": lik, "us": score_us, "fit": fit, "s": s, "reached": reached, **at}
            frontier += [[str(n), lik, k] + [by_s[v] for v in SCALES if v <= 1.0] for k, by_s in every.items()]
            rows.append(r)
            print(r, file=sys.stderr, flush=True)
        parts[str(n)] = {"rows": rows[mark[0]:], "frontier": frontier[mark[1]:]}
        save_keyed_json(state, key, parts=parts)
    head = ["n", "likelihood", "s chosen on A", "A at s: right / grasps", "B at s", "fit or cache read (s)",
            "scoring (us/vector)"]
    lines = [f"{a.objects}, normals: {cfg.normals}, {a.grasps_per_object} grasps per object (hgb: at most "
             f"{BoostedConfig().max_train_per_class} training vectors per object), seed {a.seed}, lambda "
             f"{a.threshold}; {VALIDATION_GRASPS} "
             f"validation grasps per object, {VALIDATION_TRIALS} BC-NP trials per cell (right = decided and right at "
             f"the stop); {time.time() - t0:.0f} s", ""]
    lines += md_table(head, [[str(r["n"]), r["lik"], chosen_cell(r), r["A"], r["B"], f"{r['fit']:.0f}",
                              f"{r['us']:.1f}"] for r in rows])
    head = ["n", "likelihood", "set"] + [f"s = {s:g}" for s in SCALES if s <= 1.0]
    lines += ["", "Every scale (the frontier of right stops against grasps; s > 1 only adds grasps here):", ""]
    emit(lines + md_table(head, frontier), a.out, "stop_classifier.py", argv)


if __name__ == "__main__":
    main()
