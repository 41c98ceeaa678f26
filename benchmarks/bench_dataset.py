"""Speed of training-grasp generation and of Phi_n, single-threaded.

1. Seconds to generate ``--grasps`` (default 200,000) random 4-finger grasps with normals of one ~25k-face object
   (KIT GreenCup when the shared data is present, else the generated mug subdivided to ~25k faces) through the
   dataset's own per-object path (``build_dataset``'s: sampling, Phi_n, the top-up rounds that replace degenerate
   grasps; the object's sampling tables built inside the timing), best of ``--repeats``. As context, not a
   measurement of this run: the paper's published 4.72 minutes (283.2 s) for 200,000 such grasps, against this
   run's time scaled to 200,000 where ``--grasps`` differs.
2. Phi_n throughput (grasps/s) for n = 3, 4, 5, 10 against a naive per-grasp loop that calls
   scipy's ConvexHull on every grasp and finds its largest facet (for n = 3 just the triangle's
   area), on the same grasps and in the same run (best of ``--repeats`` each); it computes no features, so the ratio
   understates the gain over a full per-grasp implementation.

Run: ``python benchmarks/bench_dataset.py [--grasps 200000] [--repeats 3]``. The headline, last, is the same-run
ratio at n = 4.
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

from haptic_env.cli import int_in  # noqa: E402
from haptic_env.dataset import DatasetConfig, _object_grasps  # noqa: E402
from haptic_env.grasp_features import phi  # noqa: E402
from haptic_env.objects import GraspObject, data_dir, make_shape  # noqa: E402
from haptic_env.objects.loaders import load_mesh_object  # noqa: E402

PAPER_SECONDS = 4.72 * 60  # 200,000 grasps, 4 fingers with normals, one object (the paper's, not measured here)
PAPER_GRASPS = 200_000
NAIVE_GRASPS = 2_000  # the naive loop's share of the grasps (it is ~20x slower)


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


def naive_loop(P: np.ndarray) -> None:
    """The baseline: a per-grasp Python loop over scipy's ConvexHull and its largest facet."""
    from scipy.spatial import ConvexHull

    n = P.shape[1]
    for p in P:
        # n = 3: the triangle itself (qhull needs 4 points in 3-D)
        tri = p[None] if n == 3 else p[ConvexHull(p).simplices]
        np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).argmax()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grasps", type=int_in(NAIVE_GRASPS), default=200_000)
    ap.add_argument("--repeats", type=int_in(1), default=3)
    args = ap.parse_args()
    obj = bench_object()
    cfg = DatasetConfig(n_fingers=4, normals=True, grasps_per_object=args.grasps)
    print(f"object: {obj.name}, {len(obj.mesh.faces)} faces; {args.grasps} grasps x 4 fingers with normals; 1 thread")

    rng = np.random.default_rng(0)

    def generate():  # a fresh object each time: its sampling tables are built inside the timing
        X = _object_grasps(GraspObject(obj.name, obj.mesh), cfg, rng)
        assert X.shape == (args.grasps, 14), X.shape  # 5n - 6 values

    generate()  # untimed: the compiled kernels' first call (with --repeats 1 it made the figure about 30x slower)
    total = best_of(generate, args.repeats)
    per_paper_job = total * PAPER_GRASPS / args.grasps
    scaled = "" if args.grasps == PAPER_GRASPS else f" (scaled from {args.grasps:,})"
    print(f"  generation (sampling, Phi_n, top-up of degenerate grasps) {total:7.3f} s "
          f"({args.grasps / total / 1e3:.0f} k grasps/s)")
    print(f"  context, not measured in this run: {PAPER_GRASPS:,} grasps take {per_paper_job:.2f} s here{scaled}, the "
          f"paper reports {PAPER_SECONDS:.1f} s ({PAPER_SECONDS / per_paper_job:.0f}x); goal <= 2 s: "
          f"{'met' if per_paper_job <= 2 else 'NOT met'}")

    print("Phi_n throughput vs naive per-grasp scipy ConvexHull loop (same grasps, same run, best of each):")
    ratio = {}
    for n in (3, 4, 5, 10):
        B = 50_000 if n < 10 else 10_000
        Pn = rng.standard_normal((B, n, 3))
        Nn = rng.standard_normal((B, n, 3))
        phi(Pn[:100], Nn[:100])  # untimed first call at this n, as generate()'s above
        t = best_of(lambda: phi(Pn, Nn), args.repeats)
        t_naive = best_of(lambda: naive_loop(Pn[:NAIVE_GRASPS]), args.repeats)
        fast, base = B / t, NAIVE_GRASPS / t_naive
        ratio[n] = fast / base
        print(f"  n={n:<2}  phi {fast:12,.0f} grasps/s   naive {base:10,.0f} grasps/s   x{ratio[n]:7.1f}")

    print(f"HEADLINE: Phi_4 with normals runs at {ratio[4]:.1f}x the naive per-grasp ConvexHull loop (same run); "
          f"{args.grasps:,} grasps generated in {total:.2f} s")

if __name__ == "__main__":
    main()
