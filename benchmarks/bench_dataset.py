"""Speed of training-grasp generation and of Phi_n, single-threaded.

1. Seconds to generate 200,000 random 4-finger grasps with normals of one ~25k-face object
   (KIT GreenCup when the shared data is present, else the generated mug subdivided to ~25k faces),
   against the paper's 4.72 minutes (283.2 s) for the same job.
2. Phi_n throughput (grasps/s) for n = 3, 4, 5, 10 against a naive per-grasp loop that calls
   scipy's ConvexHull on every grasp and finds its largest facet (for n = 3 just the triangle's
   area), measured in the same run; it computes no features, so the ratio understates the gain
   over a full per-grasp implementation.

Run: ``python benchmarks/bench_dataset.py [--grasps 200000] [--repeats 3]``. The headline is the last line.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_v] = "1"  # one core, before numpy is imported

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.dataset import DatasetConfig, grasp_vectors, sample_grasps  # noqa: E402
from haptic_env.grasp_features import phi  # noqa: E402
from haptic_env.objects import GraspObject, data_dir, make_shape  # noqa: E402
from haptic_env.objects.loaders import load_mesh_object  # noqa: E402

PAPER_SECONDS = 4.72 * 60  # 200,000 grasps, 4 fingers with normals, one object


def bench_object() -> GraspObject:
    root = data_dir()
    if root is not None and (root / "kit" / "GreenCup.stl").is_file():
        return load_mesh_object(root / "kit" / "GreenCup.stl", units="mm")
    return GraspObject("mug-25k", make_shape("mug", min_faces=25_000))


def best_of(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def naive_rate(n: int, count: int, rng: np.random.Generator) -> float:
    """Grasps/s of a per-grasp Python loop over scipy ConvexHull (the baseline)."""
    from scipy.spatial import ConvexHull

    P = rng.standard_normal((count, n, 3))
    t = time.perf_counter()
    for p in P:
        # n = 3: the triangle itself (qhull needs 4 points in 3-D)
        tri = p[None] if n == 3 else p[ConvexHull(p).simplices]
        np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).argmax()
    return count / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grasps", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    obj = bench_object()
    cfg = DatasetConfig(n_fingers=4, normals=True, grasps_per_object=args.grasps)
    print(f"object: {obj.name}, {len(obj.mesh.faces)} faces; {args.grasps} grasps x 4 fingers with normals; 1 thread")

    rng = np.random.default_rng(0)
    obj.sample_surface(10, rng)  # build the sampling tables outside the timing
    t_sample = best_of(lambda: sample_grasps(obj, args.grasps, 4, rng), args.repeats)
    C, N = sample_grasps(obj, args.grasps, 4, rng)
    t_phi = best_of(lambda: grasp_vectors(C, N, cfg, rng=rng), args.repeats)
    total = t_sample + t_phi
    print(f"  surface sampling {t_sample:7.3f} s   ({args.grasps * 4 / t_sample / 1e6:.1f} M points/s)")
    print(f"  phi (+checks)    {t_phi:7.3f} s   ({args.grasps / t_phi / 1e3:.0f} k grasps/s)")

    print("Phi_n throughput vs naive per-grasp scipy ConvexHull loop (same run):")
    rows = []
    for n in (3, 4, 5, 10):
        B = 50_000 if n < 10 else 10_000
        Pn = rng.standard_normal((B, n, 3))
        Nn = rng.standard_normal((B, n, 3))
        t = best_of(lambda: phi(Pn, Nn), args.repeats)
        base = naive_rate(n, 2_000, rng)
        rows.append((n, B / t, base))
        print(f"  n={n:<2}  phi {B / t:12,.0f} grasps/s   naive {base:10,.0f} grasps/s   x{B / t / base:7.1f}")

    print(f"HEADLINE: 200k-grasp generation (4 fingers, normals, 1 core): {total:.2f} s "
          f"= {PAPER_SECONDS / total:.0f}x faster than the paper's {PAPER_SECONDS:.1f} s "
          f"(ratio {total / PAPER_SECONDS:.4f}); goal <= 2 s: {'met' if total <= 2 else 'NOT met'}")


if __name__ == "__main__":
    main()
