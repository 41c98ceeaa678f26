"""Do hand-like contact sets make kit8 grasps without normals more separable? kNN one-shot accuracy by contact span.

At n = 4 and 5 without normals the paper's kNN reaches 56.1 / 61.8 % on kit8, this project's 31-38 % (RESULTS.md,
"The n = 4 and 5 gap without normals"). A real hand's fingertips lie within its span and never on top of each
other, which random surface points need not. This script draws the paper's kind of grasps (independent area-uniform
surface points) and keeps only those whose contacts are all within ``--spans`` of each other (largest pairwise
distance, m) and at least ``--min-seps`` apart (smallest pairwise distance, m), training and test grasps alike, then
scores the kNN (``k`` = 15 and 50 on grasp vectors standardised by the training set, Phi_n without normals).

    python benchmarks/hand_span.py [--fingers 4,5] [--grasps 20000] [--test-grasps 1000] \
        [--spans inf,0.15,0.12,0.10] [--min-seps 0,0.02] [--objects kit8] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.sampling_protocol import knn_accuracy  # noqa: E402
from haptic_env.cache import atomic_write  # noqa: E402
from haptic_env.cli import output_path  # noqa: E402


def span_mask(contacts: np.ndarray, max_span: float, min_sep: float) -> np.ndarray:
    """``(B,)`` bool: grasp ``b``'s contacts ``(B, n, 3)`` are pairwise at most ``max_span`` and at least ``min_sep``
    apart (``n >= 2``; ``max_span = inf`` and ``min_sep = 0`` keep every grasp)."""
    C = np.asarray(contacts, dtype=np.float64)
    if C.ndim != 3 or C.shape[1] < 2 or C.shape[2] != 3:
        raise ValueError(f"contacts must be (B, n >= 2, 3), got shape {C.shape}")
    if not (max_span > 0 and min_sep >= 0 and min_sep <= max_span):
        raise ValueError(f"need max_span > 0 and 0 <= min_sep <= max_span, got {max_span!r}, {min_sep!r}")
    i, j = np.triu_indices(C.shape[1], 1)
    d = np.linalg.norm(C[:, i] - C[:, j], axis=-1)
    return (d.max(axis=1) <= max_span) & (d.min(axis=1) >= min_sep)


def draw(obj, count: int, n: int, rng: np.random.Generator, max_span: float, min_sep: float, cfg) -> np.ndarray:
    """``count`` valid grasp vectors of ``obj`` whose contacts pass :func:`span_mask` (rejection sampling)."""
    from haptic_env.dataset import grasp_vectors, sample_grasps

    out, got = [], 0
    for _ in range(1000):
        C, _ = sample_grasps(obj, 4 * count, n, rng)
        C = C[span_mask(C, max_span, min_sep)]
        q, valid = grasp_vectors(C, None, cfg, rng=rng)
        out.append(q[valid])
        got += int(valid.sum())
        if got >= count:
            return np.concatenate(out)[:count]
    raise RuntimeError(f"{obj.name}: under {count} grasps within span {max_span} m and separation {min_sep} m "
                       f"after 1000 rounds; the object is too large or too small for them")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fingers", default="4,5", help="finger counts, comma list (>= 3)")
    ap.add_argument("--grasps", type=int, default=20_000, help="training grasps per object")
    ap.add_argument("--test-grasps", type=int, default=1_000, help="test grasps per object")
    ap.add_argument("--spans", default="inf,0.15,0.12,0.10", help="largest pairwise contact distances (m), comma list")
    ap.add_argument("--min-seps", default="0,0.02", help="smallest pairwise contact distances (m), comma list")
    ap.add_argument("--objects", default="kit8")
    ap.add_argument("--out", type=output_path("file"), default=None, help="also write the table to this markdown file")
    args = ap.parse_args(argv)
    try:
        fingers = [int(x) for x in args.fingers.split(",")]
        spans = [float(x) for x in args.spans.split(",")]
        seps = [float(x) for x in args.min_seps.split(",")]
    except ValueError:
        ap.error(f"--fingers, --spans and --min-seps are comma lists of numbers; got {args.fingers!r}, "
                 f"{args.spans!r}, {args.min_seps!r}")
    if min(fingers) < 3 or args.grasps < 50 or args.test_grasps < 1:
        ap.error(f"need --fingers >= 3, --grasps >= 50, --test-grasps >= 1; got {vars(args)}")
    if any(x != x for x in spans + seps) or min(spans) <= 0 or min(seps) < 0 or max(seps) > min(spans):  # NaN too
        ap.error(f"need --spans > 0 and 0 <= --min-seps <= every span (numbers, not nan); got {args.spans!r}, "
                 f"{args.min_seps!r}")
    from tqdm import tqdm

    from haptic_env.dataset import DatasetConfig
    from haptic_env.experiments.paper import PAPER_KNN  # imports the analyses (torch): only when run
    from haptic_env.objects import load_object_set

    objects = load_object_set(args.objects)
    lines = [f"`python benchmarks/hand_span.py {' '.join(argv if argv is not None else sys.argv[1:])}`", "",
             f"{args.objects}, without normals, {args.grasps:,} training and {args.test_grasps:,} test grasps per "
             "object (independent area-uniform surface points, kept if within the span and apart by the separation)",
             "", "| n | largest contact distance (span) | smallest contact distance | kNN k = 15 | k = 50 | paper's kNN |",
             "|---|---|---|---|---|---|"]
    cells = [(n, s, m) for n in fingers for s in spans for m in seps]
    for n, span, sep in tqdm(cells, desc="span cells", unit="cell"):
        t0 = time.perf_counter()
        cfg = DatasetConfig(n_fingers=n, normals=False)
        rng = np.random.default_rng([n, 1])
        Xtr, Xte, ytr, yte = [], [], [], []
        for k, obj in enumerate(objects):
            X = draw(obj, args.grasps + args.test_grasps, n, rng, span, sep, cfg)
            Xtr.append(X[: args.grasps])
            Xte.append(X[args.grasps:])
            ytr.append(np.full(args.grasps, k))
            yte.append(np.full(args.test_grasps, k))
        Xtr, Xte, ytr, yte = map(np.concatenate, (Xtr, Xte, ytr, yte))
        acc = [100 * a for a in knn_accuracy(Xtr, ytr, Xte, yte, ks=(15, 50))]
        paper = PAPER_KNN.get((n, False)) if args.objects == "kit8" else None
        lines.append(f"| {n} | {'any' if np.isinf(span) else f'<= {span:g} m'} | {'any' if sep == 0 else f'>= {sep:g} m'}"
                     f" | {acc[0]:.1f} % | {acc[1]:.1f} % | {'-' if paper is None else f'{paper} %'} |"
                     f"  <!-- {time.perf_counter() - t0:.0f} s -->")
    text = "\n".join(lines) + "\n"
    if args.out is not None:
        with atomic_write(args.out, "w") as fh:
            fh.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
