"""Phi_n and the surface area: the compiled (numba) production path against the vectorised NumPy oracle.

Both implement the same algorithm (``haptic_env/_phi_kernels.py``, called by ``haptic_env.grasp_features.phi``
and ``surface_area`` at every batch size; ``tests/phi_numpy.py``, the implementation that served large
batches until issue 8 and is now a test oracle only). Measured in the same run, single-threaded, on random
surface grasps of the default object set (boxes included, so some grasps have planar hull faces, which both
paths triangulate through Qhull, one grasp at a time; ``--source gaussian``: contacts in general position),
with normals, for each n and batch size:

* grasps/s of each path (best of ``--repeats``; the kernels are compiled before timing);
* the largest |q| difference and whether validity, order and reason codes agree (n = 2: the compiled two-pass
  kernel around NumPy's ``arctan2`` replays the NumPy code, so the difference is exactly 0; measured at 50,000
  grasps: 8.1x, 17x at batches of 64, 29x one grasp at a time).

Run: ``python benchmarks/bench_phi.py [--grasps 200000] [--fingers 2,3,4,8] [--batches 1,64,200000]``.
The headline (printed last): the compiled / NumPy speed ratio at 200,000 grasps, per n.
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import int_in, int_list_in  # noqa: E402
from haptic_env.dataset import sample_grasps  # noqa: E402
from haptic_env.grasp_features import phi, surface_area  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from tests.phi_numpy import phi_numpy, surface_area_numpy  # noqa: E402


def grasps(n: int, count: int, seed: int = 0, source: str = "surface") -> tuple[np.ndarray, np.ndarray]:
    """``count`` grasps of ``n`` contacts with normals: random surface grasps of the default set, or Gaussian
    contacts and normals (general position: no planar hull faces, no Qhull)."""
    if source == "gaussian":
        rng = np.random.default_rng([seed, n])
        return rng.normal(size=(count, n, 3)), rng.normal(size=(count, n, 3))
    objects = load_object_set("default")
    per = -(-count // len(objects))
    C, N = zip(*(sample_grasps(o, per, n, np.random.default_rng([seed, n, k])) for k, o in enumerate(objects)))
    perm = np.random.default_rng(seed).permutation(per * len(objects))[:count]
    return np.concatenate(C)[perm], np.concatenate(N)[perm]


def _planar_faced(C: np.ndarray) -> np.ndarray:
    """Which grasps have a hull face of >= 4 coplanar contacts (triangulated through Qhull in both paths)."""
    from haptic_env import _phi_kernels as k
    from haptic_env.grasp_features import DEFAULT_TOL, _topology

    if C.shape[1] < 4:  # no hull face of 4 contacts
        return np.zeros(len(C), dtype=bool)
    out, status = np.empty(len(C)), np.empty(len(C), dtype=np.int64)
    k.surface_area_rows(np.ascontiguousarray(C), _topology(C.shape[1])[0], DEFAULT_TOL, out, status)
    return status == k.AMBIGUOUS


def rate(fn, C, N, batch: int, repeats: int) -> float:
    """Grasps per second of ``fn`` over ``C, N`` in batches of ``batch`` (best of ``repeats``)."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for lo in range(0, len(C), batch):
            fn(C[lo : lo + batch], None if N is None else N[lo : lo + batch])
        best = min(best, time.perf_counter() - t0)
    return len(C) / best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grasps", type=int_in(1), default=200_000, help="grasps per n (the large batch)")
    ap.add_argument("--fingers", type=int_list_in(2), default=(2, 3, 4, 8))
    ap.add_argument("--batches", type=int_list_in(1), default=(1, 64, 200_000),
                    help="batch sizes (small ones timed on fewer grasps)")
    ap.add_argument("--repeats", type=int_in(1), default=3)
    ap.add_argument("--source", default="surface", choices=("surface", "gaussian"),
                    help="surface: grasps of the default set (box faces give planar hull faces: Qhull in both "
                         "paths); gaussian: contacts in general position")
    args = ap.parse_args(argv)
    fingers, batches = list(args.fingers), list(args.batches)
    if max(batches) < args.grasps:  # the headline is the whole batch's speed
        ap.error(f"--batches {args.batches} needs one batch >= --grasps {args.grasps} (the headline's)")
    headline = []
    print(f"{'n':>2} {'batch':>7} {'grasps':>7} | {'numba phi/s':>12} {'NumPy phi/s':>12} {'ratio':>6} | "
          f"{'numba area/s':>12} {'NumPy area/s':>12} {'ratio':>6}")
    for n in fingers:
        C, N = grasps(n, args.grasps, source=args.source)
        f, ref = phi(C, N), phi_numpy(C, N)
        same = (np.array_equal(f.valid, ref[1]) and np.array_equal(f.order, ref[2])
                and np.array_equal(f.reason, ref[3]))
        dq = float(np.abs(f.q - ref[0]).max())
        da = float(np.abs(surface_area(C) - surface_area_numpy(C)).max())
        for batch in batches:
            m = min(len(C), max(batch * 20, 2_000) if batch < len(C) else len(C))  # small batches: fewer grasps
            sub = (C[:m], N[:m])
            rc = rate(lambda c, nn: phi(c, nn), *sub, batch, args.repeats)
            rn = rate(lambda c, nn: phi_numpy(c, nn), *sub, batch, args.repeats)
            ac = rate(lambda c, nn: surface_area(c), sub[0], None, batch, args.repeats)
            an = rate(lambda c, nn: surface_area_numpy(c), sub[0], None, batch, args.repeats)
            print(f"{n:>2} {batch:>7} {m:>7} | {rc:>12,.0f} {rn:>12,.0f} {rc / rn:>5.1f}x | "
                  f"{ac:>12,.0f} {an:>12,.0f} {ac / an:>5.1f}x", flush=True)
            if batch >= len(C):
                headline.append(f"n={n} phi {rc / rn:.1f}x ({rc / 1e3:,.0f}k vs {rn / 1e3:,.0f}k grasps/s), "
                                f"area {ac / an:.1f}x")
        print(f"   n={n}: valid/order/reason identical: {same}; max |dq| {dq:.1e}; max |d area| {da:.1e}; "
              f"valid {f.valid.mean():.3f}; planar hull faces (Qhull) {np.mean(_planar_faced(C)):.3f}", flush=True)
        if not (same and dq <= 1e-9 and da <= 1e-9):  # a speed of a wrong answer is no figure
            raise SystemExit(f"bench_phi: the compiled Phi_{n} / surface area differ from the NumPy oracle")
    print(f"compiled / NumPy speed at {args.grasps:,} {args.source} grasps with normals, one thread: "
          + "; ".join(headline))
    return 0


if __name__ == "__main__":
    sys.exit(main())
