"""Experiment 1: one-shot accuracy of every classifier (and the KDE's argmax) on fresh test grasps, for
``cfg.oneshot_fingers`` with and without normals.

The MLP and the KDE are the recogniser's own (:func:`~haptic_env.recognizers.build_recognizer`, cached and
shared with the other experiments), scored raw (accuracy does not depend on the calibration temperature);
the scikit-learn baselines train on subsamples of the same training grasps.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from haptic_env.dataset import build_dataset
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments import paper
from haptic_env.experiments.fresh_grasps import fresh_pool
from haptic_env.experiments.report import Report
from haptic_env.recognizers.baselines import make_classifier
from haptic_env.recognizers.recognizer import build_recognizer
from haptic_env.splits import TEST_SEED_OFFSET

__all__ = ["run", "baseline_train_cap"]


def baseline_train_cap(name: str, cfg: AnalysisConfig) -> int | None:
    """Training rows a scikit-learn baseline is fitted on: ``cfg.baseline_max_train`` (GP: a fifth of it, at
    least 200; kNN and trees: ten times it); None: all."""
    cap = cfg.baseline_max_train
    if cap is None:
        return None
    if name == "gp":
        return max(200, cap // 5)
    if name in ("knn", "random-forest", "decision-tree"):
        return cap * 10
    return cap


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    rep.h("1. One-shot accuracy (%) on fresh test grasps")
    rows = []
    with_paper = paper.applies(cfg.objects)
    names = [*cfg.classifiers, cfg.likelihood]  # the beliefs' likelihood as a classifier: the KDE or hgb
    for normals in (False, True):
        for n in cfg.oneshot_fingers:
            rc = cfg.recognizer_config()
            clf, kde = build_recognizer(objects, n, normals, config=rc, progress=False).models.model(n)
            pool = fresh_pool(objects, n, normals, cfg)
            Xt = np.concatenate(pool)
            yt = np.concatenate([np.full(len(p), k) for k, p in enumerate(pool)])
            ds = None
            row = [n, "yes" if normals else "no"]
            for name in tqdm(names, desc=f"exp1 n={n} normals={normals}", disable=not cfg.progress, leave=False):
                if name == cfg.likelihood:
                    acc = np.mean(kde.log_likelihood(Xt).argmax(1) == yt)
                elif name == "mlp":
                    acc = clf.score(Xt, yt)
                else:
                    if ds is None:  # the recogniser's training grasps (from the dataset cache)
                        ds = build_dataset(objects, rc.dataset_config(n, normals), progress=False)
                    m = make_classifier(name, max_train=baseline_train_cap(name, cfg), seed=cfg.seed)
                    acc = m.fit(ds.X_train, ds.y_train, n_classes=len(objects)).score(Xt, yt)
                theirs = paper.ONESHOT.get(name, {}).get((n, normals)) if with_paper else None
                row.append(f"{100 * acc:.1f}" + ("" if theirs is None else f" ({theirs})"))
            rows.append(row)
    rep.table(["n", "normals", *names], rows)
    rep.p(f"Test grasps: {cfg.test_grasps} per object (seed {cfg.seed + TEST_SEED_OFFSET}); binomial std of an "
          f"accuracy near 85% is about {100 * np.sqrt(0.85 * 0.15 / (cfg.test_grasps * len(objects))):.1f} points. " +
          ("Baselines train on every training row." if cfg.baseline_max_train is None else
           f"Baselines train on subsamples (GP {baseline_train_cap('gp', cfg)}, SVMs "
           f"{baseline_train_cap('rbf-svm', cfg)}, kNN/trees {baseline_train_cap('knn', cfg)} rows).") +
          (" In brackets: the paper's figure (kit8, 200,000 grasps per object; its neural network is `mlp` here)."
           if with_paper else ""))
