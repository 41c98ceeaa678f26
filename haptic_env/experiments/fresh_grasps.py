"""Fresh test grasps of the experiments and their model scores.

Test grasps are sampled from another seed than training (``seed + TEST_SEED_OFFSET``), so they are never
training data. Pools are per object; their scores are computed once, in batch, and replayed by
:mod:`~haptic_env.experiments.trials` (the z-subset scores of raw grasps: :meth:`haptic_env.belief.Belief.subset_scores`).
"""

from __future__ import annotations

import numpy as np

from haptic_env.dataset import DatasetConfig, build_dataset, draw_held_grasps, sample_grasps
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.splits import TEST_SEED_OFFSET

__all__ = ["fresh_pool", "contact_pool", "pool_scores", "scored_models"]


def fresh_pool(objects, n: int, normals: bool, cfg: AnalysisConfig, *, seed_offset: int = TEST_SEED_OFFSET,
               grasps: int | None = None, **dkw) -> list[np.ndarray]:
    """Fresh grasp vectors: list over objects of ``(G, d)``; by default the test grasps (``cfg.test_grasps``
    each, seed ``cfg.seed + TEST_SEED_OFFSET``). ``seed_offset`` and ``grasps`` draw another pool (validation
    grasps: :data:`~haptic_env.splits.VALIDATION_SEED_OFFSET`); ``dkw``: more
    :class:`DatasetConfig` fields."""
    dc = DatasetConfig(n_fingers=n, normals=normals, grasps_per_object=cfg.test_grasps if grasps is None else grasps,
                       val_fraction=0.0, seed=cfg.seed + seed_offset,
                       **{"normal_axis": cfg.normal_axis, "force_closure": cfg.force_closure, **dkw})
    ds = build_dataset(objects, dc, progress=False)
    return [ds.X_train[ds.y_train == k].astype(np.float64) for k in range(len(objects))]


def contact_pool(objects, n: int, normals: bool, count: int, seed: int,
                 force_closure: float | None = None) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Raw ``count`` n-contact surface grasps per object: ``(contacts (G, n, 3), normals (G, n, 3) or None)``; with
    ``force_closure`` (a friction coefficient) only grasps in force closure (:func:`~haptic_env.dataset.draw_held_grasps`)."""
    out = []
    for k, obj in enumerate(objects):
        rng = np.random.default_rng([seed, k])
        if force_closure is None:
            C, N = sample_grasps(obj, count, n, rng)
        else:
            C, N = draw_held_grasps(obj, count, n, rng, force_closure)
        out.append((C, N if normals else None))
    return out


def scored_models(rec, cfg: AnalysisConfig):
    """The recogniser's :class:`~haptic_env.recognizers.recognizer.ModelBank`, calibrated or raw per
    ``cfg.calibrated``."""
    return rec.models.with_calibration(cfg.calibrated)


def pool_scores(models, pool: list[np.ndarray]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per object ``(log_lik (G, K), proba (G, K))`` of a test pool."""
    LL = [models.log_likelihood(X) for X in pool]
    PR = [models.predict_proba(X) for X in pool]
    return LL, PR
