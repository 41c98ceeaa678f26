"""The hand-written k-d tree (haptic_env/recognizers/knn.py) against scipy's cKDTree, on the same single pooled search.

The pooled KDE (the env's default, ``KDEConfig(method="pooled")``) answers each grasp with ONE k-nearest-
neighbour search over the training vectors of all objects (k = 32, eps = 2, standardised 14-dimensional vectors
of 4-finger grasps with normals), then per object the log-sum of its kernels among them. Measured in the same
run, one query at a time (an env step scores one grasp), single-threaded, on held-out grasps:

* the search alone: ``knn.KDTree.query`` (compiled, float32 vectors in tree order) vs ``cKDTree.query``
  (float64) of the same vectors, same ``k`` and ``eps``;
* the whole row of log densities: the compiled ``knn.log_density_row`` (what the env calls, search and sums in
  one call) vs ``cKDTree.query`` + the same sums in NumPy;
* agreement: the argmax of the two rows, and the exact k-NN overlap of both searches.

Run: ``python benchmarks/bench_knn.py [--grasps 100000] [--queries 2000]``. Headline (printed last): the
per-query time ratio cKDTree / knn.KDTree of the whole row, and of the same single pooled search alone.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"  # one core, before numpy is imported

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import int_in  # noqa: E402
from haptic_env.dataset import DatasetConfig, build_dataset  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood  # noqa: E402
from haptic_env.recognizers.knn import log_density_row, workspace  # noqa: E402


def ckdtree_row(tree: cKDTree, labels: np.ndarray, z: np.ndarray, k: int, eps: float, log_norms: np.ndarray,
                inv: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """``knn.log_density_row`` with the search done by ``cKDTree`` and the sums in NumPy (same semantics;
    ``inv``, ``radius``: ``(K,)`` per class)."""
    d, i = tree.query(z, k=k, eps=eps)
    d2 = d * d
    c = labels[i]
    x = -inv[c] * d2
    K = len(log_norms)
    out = -inv * d2[-1]  # no vector of the class among the k: the kernel at the k-th distance
    first = np.full(K, -1)
    first[c[::-1]] = np.arange(k)[::-1]  # nearest found vector of each class
    has = first >= 0
    out[has] = x[first[has]]
    near = d2 <= radius[c] * radius[c]
    cn, xn = c[near], x[near]
    top = np.full(K, -np.inf)
    np.maximum.at(top, cn, xn)
    acc = np.bincount(cn, weights=np.exp(xn - top[cn]), minlength=K)
    ok = acc > 0
    out[ok] = top[ok] + np.log(acc[ok])
    return out + log_norms


def per_query(fn, Z: np.ndarray, repeats: int) -> float:
    """Median over ``repeats`` of the mean seconds per query of ``fn(z)`` over the rows of ``Z``."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for z in Z:
            fn(z)
        times.append((time.perf_counter() - t0) / len(Z))
    return float(np.median(times))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grasps", type=int_in(100), default=100_000,
                    help="training grasps per object in the pooled tree")
    ap.add_argument("--queries", type=int_in(1), default=2000, help="held-out grasps queried one at a time")
    ap.add_argument("--repeats", type=int_in(1), default=5)
    args = ap.parse_args(argv)
    objects = load_object_set("default")
    ds = build_dataset(objects, DatasetConfig(n_fingers=4, normals=True, grasps_per_object=args.grasps), progress=False)
    cfg = KDEConfig(method="pooled")
    kde = KDELikelihood(cfg).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val)
    test = build_dataset(objects, DatasetConfig(n_fingers=4, normals=True, grasps_per_object=-(-args.queries // len(objects)),
                                                val_fraction=0.0, seed=7919), progress=False)
    Z = np.ascontiguousarray((test.X_train.astype(np.float64) - kde.scaler.mean) / kde.scaler.std)[: args.queries]
    k, eps, inv, radius = min(cfg.k, kde.pooled.n), float(cfg.eps), 0.5 / kde.bandwidth**2, cfg.cutoff * kde.bandwidth
    log_norms = kde._norms()
    pooled = np.concatenate(kde.data).astype(np.float64)
    labels = np.repeat(np.arange(kde.n_classes), [len(z) for z in kde.data])
    t0 = time.perf_counter()
    ck = cKDTree(pooled)
    t_ck_build = time.perf_counter() - t0
    data, nodes, split = kde.pooled.arrays()
    work = workspace(nodes, Z.shape[1], k, kde.n_classes)
    row = np.empty(kde.n_classes)

    def ours_row_eps(z, e):
        log_density_row(data, nodes, split, kde.pooled_labels, z, k, e, log_norms, inv, radius, work, row)
        return row

    def ours_row(z):
        return ours_row_eps(z, eps)

    ours_row(Z[0])  # compile
    kde.pooled.query(Z[:1], k, eps)
    # agreement
    ours = np.array([ours_row(z).copy() for z in Z])
    theirs = np.array([ckdtree_row(ck, labels, z, k, eps, log_norms, inv, radius) for z in Z])
    agree = float(np.mean(ours.argmax(1) == theirs.argmax(1)))
    assert np.allclose(ours, kde.log_likelihood(Z * kde.scaler.std + kde.scaler.mean))  # the production path
    # the baseline computes the same row: exactly so with exact searches (eps = 0; at eps > 0 the two trees return
    # other approximate neighbours, so only the argmax agreement above is comparable)
    Z0 = Z[:300]
    exact = np.array([ours_row_eps(z, 0.0).copy() for z in Z0])
    if not np.allclose(exact, [ckdtree_row(ck, labels, z, k, 0.0, log_norms, inv, radius) for z in Z0], atol=1e-4):
        raise SystemExit("bench_knn: the cKDTree baseline's log-density rows differ from the compiled rows at eps = 0")
    _, i_ours = kde.pooled.query(Z, k, eps)
    _, i_ck = ck.query(Z, k=k, eps=eps)
    _, i_exact = ck.query(Z, k=k)
    overlap = lambda a, b: float(np.mean([len(np.intersect1d(x, y)) / k for x, y in zip(a, b)]))  # noqa: E731
    # timing, one query at a time
    t_row_ours = per_query(ours_row, Z, args.repeats)
    t_row_ck = per_query(lambda z: ckdtree_row(ck, labels, z, k, eps, log_norms, inv, radius), Z, args.repeats)
    Z1 = [z[None] for z in Z]
    t_q_ours = per_query(lambda z: kde.pooled.query(z, k, eps), Z1, args.repeats)
    t_q_ck = per_query(lambda z: ck.query(z, k=k, eps=eps), Z1, args.repeats)
    print(f"pooled vectors: {len(pooled):,} x {pooled.shape[1]} (default set, {args.grasps:,} grasps per object, 4 fingers "
          f"+ normals); k = {k}, eps = {eps}; {len(Z)} held-out queries, one at a time; cKDTree build {t_ck_build:.2f} s")
    print(f"search alone:      knn.KDTree.query {1e6 * t_q_ours:6.1f} us   cKDTree.query {1e6 * t_q_ck:6.1f} us")
    print(f"log-density row:   knn (compiled)   {1e6 * t_row_ours:6.1f} us   cKDTree + NumPy {1e6 * t_row_ck:6.1f} us")
    print(f"argmax agreement of the two rows: {100 * agree:.1f} %; k-NN overlap with the exact {k} nearest: "
          f"knn.KDTree {100 * overlap(i_ours, i_exact):.1f} %, cKDTree {100 * overlap(i_ck, i_exact):.1f} %")
    print(f"cKDTree / knn.KDTree time per query: whole log-density row {t_row_ck / t_row_ours:.1f}x; the same single "
          f"pooled search alone {t_q_ck / t_q_ours:.1f}x ({1e6 * t_q_ck:.0f} us vs {1e6 * t_q_ours:.0f} us)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
