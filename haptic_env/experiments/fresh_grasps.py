"""Fresh test grasps of the experiments and their model scores.

Test grasps are sampled from another seed than training (``seed + TEST_SEED_OFFSET``), so they are never
training data. Pools are per object; their scores are computed once, in batch, and replayed by
:mod:`~haptic_env.experiments.trials`.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from haptic_env.dataset import DatasetConfig, build_dataset, sample_grasps
from haptic_env.experiments.config import TEST_SEED_OFFSET, AnalysisConfig
from haptic_env.recognizers.zfinger import grasp_vectors_for

__all__ = ["fresh_pool", "contact_pool", "pool_scores", "scored_models", "subset_scores"]


def fresh_pool(objects, n: int, normals: bool, cfg: AnalysisConfig, **dkw) -> list[np.ndarray]:
    """Fresh test grasp vectors: list over objects of ``(G, d)`` (``cfg.test_grasps`` each; ``dkw``: more
    :class:`DatasetConfig` fields)."""
    dc = DatasetConfig(n_fingers=n, normals=normals, grasps_per_object=cfg.test_grasps, val_fraction=0.0,
                       seed=cfg.seed + TEST_SEED_OFFSET, **dkw)
    ds = build_dataset(objects, dc, progress=False)
    return [ds.X_train[ds.y_train == k].astype(np.float64) for k in range(len(objects))]


def contact_pool(objects, n: int, normals: bool, count: int, seed: int) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Raw ``count`` n-contact surface grasps per object: ``(contacts (G, n, 3), normals (G, n, 3) or None)``."""
    out = []
    for k, obj in enumerate(objects):
        C, N = sample_grasps(obj, count, n, np.random.default_rng([seed, k]))
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


def subset_scores(models, C, N, z: int, k_sub: int | None, rng: np.random.Generator):
    """Per grasp of ``C (G, n, 3)``: summed log-likelihoods and mean probabilities of its z-subsets.

    ``k_sub=None``: every subset; else ``k_sub`` distinct random subsets per grasp. Degenerate
    subsets are left out; grasps without any valid subset are dropped. Returns two ``(G', K)``.
    """
    G, n, _ = C.shape
    allsub = np.array(list(combinations(range(n), z)))
    if k_sub is None or k_sub >= len(allsub):
        pick = np.broadcast_to(np.arange(len(allsub)), (G, len(allsub)))
    else:
        pick = np.argsort(rng.random((G, len(allsub))), axis=1)[:, :k_sub]
    idx = allsub[pick]  # (G, m, z)
    rows = np.arange(G)[:, None, None]
    Pz = C[rows, idx].reshape(-1, z, 3)
    Nz = None if N is None else N[rows, idx].reshape(-1, z, 3)
    q, valid = grasp_vectors_for(Pz, Nz)
    m = idx.shape[1]
    K = models.n_classes
    ll = np.zeros((G * m, K))
    pr = np.zeros((G * m, K))
    ll[valid] = models.log_likelihood(q[valid])
    pr[valid] = models.predict_proba(q[valid])
    v = valid.reshape(G, m)
    cnt = v.sum(1)
    keep = cnt > 0
    ll = ll.reshape(G, m, K).sum(1)
    pr = pr.reshape(G, m, K).sum(1) / np.maximum(cnt, 1)[:, None]
    return ll[keep], pr[keep]
