"""A stop scale for BC: the threshold calibrated on validation trials (experiment 2's default; ``haptic-recog
analysis --no-stop-scale`` turns it off).

The KDE's temperature (and learned correction) makes each *one-shot* posterior calibrated (experiment 7). A
belief of several grasps then stops at ``certainty >= lambda`` and overshoots: one more grasp often takes it from
0.7 to 0.97, so its stops are right more often than ``lambda`` says (89-92 % at ``lambda = 0.85`` on kit8 with
normals, at 3-8 grasps). The stop scale ``s`` turns the calibrated log-likelihoods ``L`` of every Bayes step into
``L / s`` and is chosen so that the *stop* means what it says: on validation trials, among :data:`STOP_SCALES`,
the scale with the fewest mean BC-NP grasps whose stops are decided and right at least ``lambda`` of the time
(1, i.e. no change, when none is). ``s < 1`` sharpens the belief; then a stop is a risk-controlled decision (right
with probability about ``lambda``), not a calibrated posterior, and the one-shot posteriors of experiment 7 keep
the KDE's one-shot calibration (its correction and temperature) without the scale.

Validation trials replay fresh grasps from seed ``seed + VALIDATION_SEED_OFFSET`` (never training or test
grasps) through the experiments' own trial runner and updater, with their own random stream, so that a run
with and without the scale draws the same test trials.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.fresh_grasps import fresh_pool, pool_scores
from haptic_env.experiments.trials import simulate_trials
from haptic_env.numbers import finite_number, items
from haptic_env.recognizers.updaters import DEFAULT_MAX_GRASPS, check_threshold
from haptic_env.splits import VALIDATION_SEED_OFFSET

__all__ = ["STOP_SCALES", "VALIDATION_GRASPS", "VALIDATION_TRIALS", "fit_stop_scale",
           "fit_cell_stop_scales", "scaled"]

#: The scales weighed (1 among them: the calibrated belief unchanged).
STOP_SCALES = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.15, 1.3, 1.5, 2.0)
#: Fresh validation grasps per object, and validation trials per scale.
VALIDATION_GRASPS = 1_500
VALIDATION_TRIALS = 3_000


def scaled(log_lik: Sequence[np.ndarray], s: float) -> list[np.ndarray]:
    """Per object ``(G, K)`` log-likelihoods divided by the stop scale ``s`` (``s == 1``: the same arrays)."""
    return list(log_lik) if s == 1.0 else [np.asarray(x) / s for x in log_lik]


def fit_stop_scale(log_lik: Sequence[np.ndarray], proba: Sequence[np.ndarray], threshold: float, *,
                   kind: str = "bc-np", scales: Sequence[float] = STOP_SCALES, trials: int = VALIDATION_TRIALS,
                   max_grasps: int = DEFAULT_MAX_GRASPS,
                   rng: np.random.Generator) -> tuple[tuple[float, float, float], list[tuple[float, float, float]]]:
    """The stop scale of ``kind``'s belief on validation scores.

    Args:
        log_lik, proba: per object ``(G_o, K)`` calibrated scores of its *validation* grasps.
        threshold: ``lambda``; a scale qualifies when its decided-and-right rate is at least ``threshold``.
        rng: the validation trials' stream; every scale replays the same trials (a fresh copy of its state).

    Returns:
        ``(chosen, table)``: per scale weighed, ``table`` holds ``(s, decided-and-right rate, mean grasps)``;
        ``chosen`` is the row of the qualifying scale with the fewest mean grasps, or when none qualifies the
        row of ``s = 1`` (``(1.0, nan, nan)`` if 1 was not weighed).
    """
    check_threshold(threshold, "threshold")
    given = items(scales)
    if not given or any((finite_number(s) or 0.0) <= 0.0 for s in given):
        raise ValueError(f"scales must be positive and finite, got {scales!r}")
    scales = given
    state = rng.bit_generator.state
    table = []
    for s in scales:
        r = np.random.Generator(type(rng.bit_generator)())
        r.bit_generator.state = state
        res = simulate_trials(scaled(log_lik, float(s)), proba, kind, trials=trials, max_grasps=max_grasps,
                              threshold=threshold, rng=r)
        table.append((float(s), float((res["success"] & res["decided"]).mean()), float(res["grasps"].mean())))
    ok = [row for row in table if row[1] >= threshold]
    if ok:
        return min(ok, key=lambda row: (row[2], -row[0])), table
    return next((row for row in table if row[0] == 1.0), (1.0, float("nan"), float("nan"))), table


def fit_cell_stop_scales(models, objects, n: int, normals: bool, cfg: AnalysisConfig,
                         thresholds: Sequence[float]) -> list[tuple[float, float, float]]:
    """The chosen ``(s, rate, grasps)`` of :func:`fit_stop_scale` at each threshold, for the cell ``(n, normals)``.

    Its validation grasps (``VALIDATION_GRASPS`` per object, seed ``cfg.seed + VALIDATION_SEED_OFFSET``) are scored
    once by ``models`` (the calibrated bank), and every threshold replays the cell's own validation stream, so the
    experiments that share a lambda choose the same scale there and their test trials do not depend on it."""
    VLL, VPR = pool_scores(models, fresh_pool(objects, n, normals, cfg, seed_offset=VALIDATION_SEED_OFFSET,
                                              grasps=VALIDATION_GRASPS))
    return [fit_stop_scale(VLL, VPR, lam, trials=VALIDATION_TRIALS, max_grasps=cfg.max_grasps,
                           rng=np.random.default_rng([cfg.seed, n, VALIDATION_SEED_OFFSET]))[0]
            for lam in thresholds]
