"""The paper's figures for its kit8 analysis, which the analysis reports print beside ours.

Sintov & Ben-David, *Simple Kinesthetic Haptics for Object Recognition*, as summarised in
``../shared/reference/paper_figures.md``: kit8 (8 KIT objects), 200,000 grasps per object, 1,000 trials per object,
lambda = 0.85. The paper gives these for kit8 only (:data:`PAPER_SET`); the reports of other object sets print none.
Every table is keyed by the finger count ``n`` and whether the grasp vectors carry normals. The robot-hand table is
:data:`benchmarks.hand_experiment.PAPER`'s.
"""

from __future__ import annotations

__all__ = ["PAPER_SET", "THRESHOLD", "ONESHOT", "PAPER_NN", "PAPER_KNN", "GRASPS", "ZFINGER", "INCOMPLETE", "SCALED",
           "SCALE_RANGE", "applies", "PAPER"]

#: the object set the paper's analysis figures are for
PAPER_SET = "kit8"


def _row(*values) -> dict[tuple[int, bool], object]:
    """``values`` in the paper's column order n = 3, 4, 5 (with normals, then without) -> ``{(n, normals): value}``."""
    keys = [(n, normals) for n in (3, 4, 5) for normals in (True, False)]
    return dict(zip(keys, values, strict=True))


#: one-shot accuracy (%) by classifier (this project's names, :data:`~haptic_env.recognizers.baselines.CLASSIFIERS`;
#: the paper's neural network is ``"mlp"``): "One-shot accuracy (%) by classifier (kit8)"
ONESHOT = {
    "knn": _row(70.8, 45.6, 59.1, 56.1, 62.2, 61.8),
    "linear-svm": _row(41.2, 41.0, 50.0, 49.6, 55.6, 55.7),
    "rbf-svm": _row(76.9, 46.9, 47.6, 57.8, 37.3, 63.5),
    "gp": _row(69.5, 42.7, 59.0, 57.3, 64.7, 63.8),
    "random-forest": _row(66.8, 47.3, 58.7, 57.7, 64.6, 63.3),
    "mlp": _row(86.0, 47.0, 80.7, 62.4, 83.7, 71.1),
    "decision-tree": _row(61.9, 45.7, 58.2, 54.4, 61.8, 61.0),
}
#: the neural-network and nearest-neighbour rows of :data:`ONESHOT`
PAPER_NN = ONESHOT["mlp"]
PAPER_KNN = ONESHOT["knn"]

#: mean (std) grasps to the stop by updater: "Grasps to the stop, mean (std), kit8" (success only as plots)
GRASPS = {
    "ic": _row((3.57, 4.57), (2.96, 3.25), (4.35, 5.80), (3.60, 4.45), (4.67, 6.43), (4.37, 5.70)),
    "bc-np": _row((3.53, 2.07), (9.62, 13.81), (3.37, 1.90), (6.52, 4.87), (3.40, 1.46), (5.07, 3.04)),
}

#: z-finger scoring with 4 random z-subsets per grasp: ``(updater, z, n, normals) -> (success %, grasps)``
ZFINGER = {
    (kind, z, n, normals): value
    for (kind, z), values in {
        ("ic", 3): ((95.7, 1.60), (62, 1.26), (96.7, 1.57), (62.8, 1.25), (96.1, 1.57), (64, 1.26), (96.8, 1.49),
                    (62.3, 1.28)),
        ("ic", 4): (None, None, (93.5, 1.75), (72.0, 1.58), (95.0, 2.2), (76.2, 1.26), (97.0, 2.2), (76.7, 1.43)),
        ("bc-np", 3): ((92.5, 1.33), (91.9, 4.2), (91.7, 1.27), (93.1, 4.65), (93.4, 1.32), (96.2, 4.8), (94.5, 1.3),
                       (96.1, 5.2)),
        ("bc-np", 4): (None, None, (96.0, 1.36), (89.0, 2.48), (95.5, 1.29), (91.0, 2.53), (97.2, 1.31),
                       (94.0, 2.15)),
    }.items()
    for (n, normals), value in zip([(n, nm) for n in (4, 5, 6, 7) for nm in (True, False)], values, strict=True)
    if value is not None
}

#: incomplete grasps, each scored by the model of its finger count: ``(updater, n, normals) -> (success %, grasps)``
#: (n: the hand's fingers; the paper's p_n(z) is not in the reference summary)
INCOMPLETE = {("ic", 4, True): (98.7, 4.99), ("ic", 4, False): (75.8, 3.47), ("ic", 5, True): (98.8, 4.19),
              ("ic", 5, False): (87.1, 3.56), ("bc-np", 4, True): (97.3, 3.27), ("bc-np", 4, False): (95.3, 7.72),
              ("bc-np", 5, True): (93.3, 2.87), ("bc-np", 5, False): (96.0, 6.3)}

#: the scales of the paper's scaled objects (one per grasp, uniform), which :data:`SCALED` is for
SCALE_RANGE = (0.1, 5.0)
#: scaled objects (scale in :data:`SCALE_RANGE`, with scale normalisation): success % by updater
SCALED = {
    "ic": _row(96.2, 43.3, 90.2, 63.8, 91.1, 73.5),
    "bc-np": _row(91.5, 84.0, 92.2, 91.3, 85.2, 90.9),
    "bc-ip": _row(93.25, 86.8, 91.0, 90.5, 90.2, 91.8),
}

#: two figures the first reports quoted: MLP one-shot at n = 3 and BC-NP's grasps at n = 4, both with normals
PAPER = {"mlp_oneshot_n3_normals": PAPER_NN[(3, True)], "bcnp_grasps_n4_normals": GRASPS["bc-np"][(4, True)][0]}


#: the certainty threshold of the paper's sequential figures (experiments 2-4)
THRESHOLD = 0.85


def applies(objects: str, threshold: float | None = None) -> bool:
    """Whether the analysis of object set ``objects`` (``AnalysisConfig.objects``) has the paper's figures; for the
    sequential experiments (``threshold``: their lambda) only at the paper's lambda, :data:`THRESHOLD`."""
    return objects == PAPER_SET and (threshold is None or threshold == THRESHOLD)
