"""Does the paper's contact sampling make kit8 grasps more separable? kNN one-shot accuracy by sampling and mesh.

The paper samples contacts at the centres of uniformly chosen faces of meshes of about 800 faces; this project
samples the 25,000-face KIT meshes uniformly by area. At equal scale a kNN on our grasps is 8 points below the
paper's kNN (RESULTS.md, "kit8 one-shot at paper scale"). This script measures whether the sampling protocol
explains it: the same kNN (``k`` = 1, 15, 50 on standardised grasp vectors) on kit8 grasps of

* the full meshes, area-uniform points (this project's protocol) or face centres;
* the meshes decimated to ``--faces`` faces (quadric decimation, ``fast-simplification``), area-uniform or face
  centres (the paper's protocol).

Training ``--grasps`` per object (seed 1), ``--test-grasps`` fresh ones per object (seed 2), ``n`` fingers with or
without normals. Each row's ``k`` is chosen on as many validation grasps per object (seed 3) and its test accuracy is
the row's figure (bold); the test accuracies of the other ``k`` are shown beside it.

Two more rows use the authors' public code's grasp vector on the paper's protocol (decimated meshes, face
centres): its ``sample_grasp`` sorts the chosen face indices; at ``n = 3`` its ``parameterize_grasp`` takes the
triangle from its longest edge in that cyclic order and appends the normals' angles in that index order
(:func:`authors_n3`), and at ``n >= 4`` it walks a strip of hull facets in Qhull's order from the largest
(:func:`authors_chain`), so the vector depends on the mesh's face order, which this project's Phi_n does not. The
rows compare the face order ("their order") with a random one (shuffled): a difference would be information that a
real hand does not have. ``--force-closure MU`` keeps only grasps in force closure in every row.

``--curve SIZES`` prints, instead of the table, the kNN's accuracy against training grasps per object on the
decimated meshes, face centres against area-uniform points: the paper's candidate contacts are a finite set (one
per face) that its training and test grasps share, which a large training set could cover.

Each finished row of the table is kept in the cache (``<cache>/sampling_protocol/<settings key>.json``, written
atomically), so an interrupted run started again with the same settings and code prints the rows it has and computes
only the rest (a row takes minutes; with ``--force-closure`` the table took 31 minutes).

Needs the shared data (kit/) and ``pip install -e ".[bench]"`` (fast-simplification).

    python benchmarks/sampling_protocol.py [--fingers 3] [--no-normals] [--grasps 20000] [--faces 800] \
        [--force-closure MU] [--curve 5000,20000,50000,200000 [--plot curve.png]]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError


def main(argv=None) -> int:
    from haptic_env.cli import output_path

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fingers", type=int, default=3)
    ap.add_argument("--no-normals", action="store_true")
    ap.add_argument("--grasps", type=int, default=20_000, help="training grasps per object")
    ap.add_argument("--test-grasps", type=int, default=1_000, help="test grasps per object")
    ap.add_argument("--faces", type=int, default=800, help="faces of the decimated meshes")
    ap.add_argument("--force-closure", type=float, default=None, metavar="MU",
                    help="keep only grasps in force closure with this friction, in every row (default: every grasp)")
    ap.add_argument("--curve", default=None, metavar="SIZES",
                    help="instead of the table: kNN accuracy against training grasps per object (comma list), on the "
                         "decimated meshes, face centres against area-uniform points")
    ap.add_argument("--plot", default=None, metavar="PNG", type=output_path(),
                    help="with --curve: also draw the curves, with the paper's kNN, into this PNG file")
    args = ap.parse_args(argv)
    try:
        curve = sorted({int(x) for x in args.curve.split(",")}) if args.curve is not None else None
    except ValueError:
        ap.error(f"--curve: a comma list of grasp counts, got {args.curve!r}")
    if curve is not None and (not curve or curve[0] < 50):
        ap.error(f"--curve: grasp counts >= 50, got {args.curve!r}")
    if args.plot is not None and curve is None:
        ap.error("--plot draws the --curve: give --curve too")
    for flag, value, least in (("--fingers", args.fingers, 3), ("--grasps", args.grasps, 50),
                               ("--test-grasps", args.test_grasps, 1), ("--faces", args.faces, 20)):
        if value < least:
            ap.error(f"{flag} must be >= {least}, got {value}")
    if args.force_closure is not None and not args.force_closure > 0:
        ap.error(f"--force-closure must be > 0, got {args.force_closure}")
    try:
        import fast_simplification
    except ImportError:
        ap.error("the decimated meshes need fast-simplification: pip install -e \".[bench]\"")
    import trimesh
    from haptic_env.dataset import DatasetConfig, draw_held_grasps, grasp_vectors, sample_grasps
    from haptic_env.objects import load_object_set
    from haptic_env.objects.base import GraspObject

    normals = not args.no_normals
    objects = load_object_set("kit8")

    def decimate(obj):
        v, f = fast_simplification.simplify(np.asarray(obj.mesh.vertices, np.float64), np.asarray(obj.mesh.faces),
                                            target_reduction=1 - args.faces / len(obj.mesh.faces))
        return GraspObject(obj.name, trimesh.Trimesh(v, f, process=True))

    decimated = [decimate(o) for o in objects]
    cfg = DatasetConfig(n_fingers=args.fingers, normals=normals)

    def data(objs, method, count, seed):
        rng = np.random.default_rng(seed)
        X, y = [], []
        for k, obj in enumerate(objs):
            if args.force_closure is None:
                C, N = sample_grasps(obj, count, args.fingers, rng, sampling=method)
            else:
                C, N = draw_held_grasps(obj, count, args.fingers, rng, args.force_closure, sampling=method)
            q, valid = grasp_vectors(C, N if normals else None, cfg, rng=rng)
            X.append(q[valid])
            y.append(np.full(int(valid.sum()), k))
        return np.concatenate(X), np.concatenate(y)

    held = "" if args.force_closure is None else f", only grasps in force closure at friction {args.force_closure}"
    if curve is not None:
        return _curve(decimated, curve, data, args, held)
    print(f"kit8, n = {args.fingers}, {'with' if normals else 'without'} normals{held}, {args.grasps:,} training and "
          f"{args.test_grasps:,} test grasps per object; decimated meshes: {[len(o.mesh.faces) for o in decimated]} "
          "faces\n")
    print("| meshes | contacts | kNN k = 1 | k = 15 | k = 50 | k chosen on validation |")
    print("|---|---|---|---|---|---|")
    from tqdm.auto import tqdm

    from haptic_env.cache import cache_dir, config_key, package_fingerprint, resume_state, save_keyed_json

    # the settings and the code (haptic_env's and the benchmarks'): a resume after a code change starts again
    key = {**{k: v for k, v in sorted(vars(args).items()) if k not in ("curve", "plot")},
           "code": package_fingerprint(Path(__file__).parent)}
    state = cache_dir("sampling_protocol") / f"{config_key(key)}.json"
    rows = resume_state(state, key, "rows")  # the rows an interrupted run finished

    def row(name, compute):
        """``(accs, j, n_test, seconds)`` of the row ``name``: kept from an earlier run, or computed and kept."""
        if name not in rows:
            t0 = time.perf_counter()
            accs, j, n_test = compute()
            rows[name] = [[float(a) for a in accs], int(j), int(n_test), time.perf_counter() - t0]
            save_keyed_json(state, key, rows=rows)
        return rows[name]

    chosen = {}
    meshes = (("full (about 25,000 faces)", list(objects)), (f"decimated ({args.faces} faces)", decimated))
    methods = (("area", "area-uniform points"), ("centroid", "centres of uniform faces"))
    orders = ("their order (sorted face indices)", "shuffled")
    bar = tqdm(total=len(meshes) * len(methods) + len(orders), desc="rows", unit="row",  # a row: seconds to minutes
               file=sys.stderr)
    for mesh_label, objs in meshes:
        for method, label in methods:
            def our_row(objs=objs, method=method):
                train, val, test = (data(objs, method, count, seed) for seed, count in
                                    ((1, args.grasps), (3, args.test_grasps), (2, args.test_grasps)))
                return (*validated_knn(train, val, test), len(test[1]))

            accs, j, n_test, seconds = row(f"{mesh_label} | {label}", our_row)
            chosen[mesh_label, label] = accs[j], n_test
            print(f"| {mesh_label} | {label} | {_cells(accs, j)} |  <!-- {seconds:.0f} s -->", flush=True)
            bar.update()
    for order in orders:
        def authors_row(order=order):
            train, val, test = (authors_data(decimated, count, args.fingers, seed, sort=order != "shuffled",
                                             normals=normals, mu=args.force_closure)
                                for seed, count in ((1, args.grasps), (3, args.test_grasps), (2, args.test_grasps)))
            return (*validated_knn(train, val, test), len(test[1]))

        accs, j, _, seconds = row(f"authors | {order}", authors_row)
        print(f"| decimated ({args.faces} faces) | centres of uniform faces, the authors' vector, {order} | "
              f"{_cells(accs, j)} |  <!-- {seconds:.0f} s -->", flush=True)
        bar.update()
    bar.close()
    (ours, n_ours), (paper, n_paper) = (chosen["full (about 25,000 faces)", "area-uniform points"],
                                        chosen[f"decimated ({args.faces} faces)", "centres of uniform faces"])
    se = 100 * np.hypot(*(np.sqrt(p * (1 - p) / m) for p, m in ((ours, n_ours), (paper, n_paper))))
    print(f"\nthe paper's sampling, k chosen on validation grasps: {100 * paper:.1f} % against this project's "
          f"{100 * ours:.1f} % ({100 * (paper - ours):+.1f} +- {se:.1f} points, the binomial standard error of the "
          "difference; one seed)")
    return 0


KS = (1, 15, 50)  # the kNN's candidate neighbour counts


def knn_accuracy(Xtr, ytr, Xte, yte, ks=KS) -> list[float]:
    """One-shot accuracy of the kNN at each ``k`` of ``ks`` on grasp vectors standardised by the training set."""
    return _knn_scores((Xtr, ytr), [(Xte, yte)], ks)[0]


def validated_knn(train, val, test, ks=KS) -> tuple[list[float], int]:
    """The kNN fitted on ``train`` (``(X, y)``) at each ``k`` of ``ks``: the test accuracy at every ``k``, and the
    index of the ``k`` with the best accuracy on ``val`` (the first of ties), so that the figure a row reports,
    ``accs[j]``, is not chosen on the test grasps."""
    val_accs, accs = _knn_scores(train, [val, test], ks)
    return accs, int(np.argmax(val_accs))


def _knn_scores(train, evals, ks) -> list[list[float]]:
    """``[e][i]``: the accuracy on ``evals[e]`` (``(X, y)``) of the kNN with ``ks[i]`` neighbours fitted on ``train``,
    the grasp vectors standardised by the training set."""
    from sklearn.neighbors import KNeighborsClassifier

    (Xtr, ytr) = train
    mu, sd = Xtr.mean(0), Xtr.std(0) + 1e-12
    scores = [[] for _ in evals]
    for k in ks:
        knn = KNeighborsClassifier(k).fit((Xtr - mu) / sd, ytr)
        for row, (X, y) in zip(scores, evals):
            row.append(float((knn.predict((X - mu) / sd) == y).mean()))
    return scores


def _cells(accs: list[float], j: int) -> str:
    """A row's test accuracies, the validated one (index ``j``) bold, then its ``k``."""
    return " | ".join(f"**{100 * a:.1f} %**" if i == j else f"{100 * a:.1f} %" for i, a in enumerate(accs)) + \
        f" | {KS[j]}"


def _curve(decimated, sizes: list[int], data, args, held: str) -> int:
    """kNN one-shot accuracy against training grasps per object on the decimated meshes, face centres (the paper's
    protocol: a finite set of candidate contacts that training and test grasps share) against area-uniform points;
    each method's largest training set drawn once (seed 1) and cut to each size, the same fresh test grasps (seed
    2), ``k`` chosen at each size on as many validation grasps (seed 3); ``held``: the force-closure words of the
    title."""
    print(f"kit8, n = {args.fingers}, {'without' if args.no_normals else 'with'} normals{held}; meshes decimated to "
          f"{args.faces} faces; {args.test_grasps:,} test grasps per object; kNN one-shot accuracy, k of 1, 15, "
          "50 chosen on as many validation grasps\n")
    print("| contacts | " + " | ".join(f"{m:,} / object" for m in sizes) + " |")
    print("|---|" + "---|" * len(sizes))
    curves = {}
    for method, label in (("area", "area-uniform points"), ("centroid", "centres of uniform faces")):
        Xall, yall = data(decimated, method, sizes[-1], 1)
        val, test = (data(decimated, method, args.test_grasps, seed) for seed in (3, 2))
        cells = []
        for m in sizes:
            rows = np.concatenate([np.flatnonzero(yall == k)[:m] for k in range(len(decimated))])
            accs, j = validated_knn((Xall[rows], yall[rows]), val, test)
            cells.append(accs[j])
        curves[label] = cells
        print(f"| {label} | " + " | ".join(f"{100 * a:.1f} %" for a in cells) + " |", flush=True)
    if args.plot is not None:
        from matplotlib.figure import Figure  # no pyplot: no global backend switch

        from haptic_env.experiments.paper import PAPER_KNN

        fig = Figure(figsize=(6, 4))
        ax = fig.subplots()
        for label, cells in curves.items():
            ax.plot(sizes, [100 * a for a in cells], "o-", label=f"{label} (800-face meshes)")
        paper = PAPER_KNN.get((args.fingers, not args.no_normals))
        if paper is not None:
            ax.axhline(paper, ls="--", color="grey", label="the paper's kNN (200,000 / object)")
        ax.set_xscale("log")
        ax.set_xlabel("training grasps per object")
        ax.set_ylabel("kNN one-shot accuracy, % (k chosen on validation)")
        ax.set_title(f"kit8, n = {args.fingers}, {'without' if args.no_normals else 'with'} normals{held}", fontsize=9)
        ax.legend(fontsize=8)
        fig.tight_layout()
        from haptic_env.cache import atomic_write

        with atomic_write(args.plot) as fh:
            fig.savefig(fh, format="png", dpi=110)
        print(f"\nplot: {args.plot}")
    return 0


def authors_n3(X: np.ndarray, N: np.ndarray | None) -> np.ndarray:
    """The authors' public ``parameterize_grasp`` for 3 fingers, vectorised: ``X, N (B, 3, 3)`` in their order ->
    ``(B, 3)`` (two angles and the longest edge) or ``(B, 9)`` with the six normal angles in the input order.

    The triangle starts at the longest edge in the input's cyclic order; the normals are measured against the
    triangle's normal (``(v1 - v0) x (v2 - v0) / (|v1 - v0| |v2 - v0|)``, not unit length, as in their code) and
    the unit longest edge, for the contacts in their input order."""
    B = len(X)
    D = np.linalg.norm(X - np.roll(X, -1, axis=1), axis=2)  # |v0 v1|, |v1 v2|, |v2 v0|
    i = np.argmax(D, axis=1)
    Xr = X[np.arange(B)[:, None], (np.arange(3)[None] + i[:, None]) % 3]

    def angle(a, b):
        c = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1) + 1e-300)
        return np.arccos(np.clip(c, -1.0, 1.0))

    e01, e02 = Xr[:, 1] - Xr[:, 0], Xr[:, 2] - Xr[:, 0]
    q = [angle(e02, e01), angle(Xr[:, 0] - Xr[:, 1], Xr[:, 2] - Xr[:, 1]), np.linalg.norm(e01, axis=1)]
    if N is not None:
        tri = np.cross(e01, e02) / (np.linalg.norm(e01, axis=1) * np.linalg.norm(e02, axis=1) + 1e-300)[:, None]
        edge = e01 / (np.linalg.norm(e01, axis=1)[:, None] + 1e-300)
        for j in range(3):
            q += [np.arccos(np.clip((ref * N[:, j]).sum(-1), -1, 1)) for ref in (tri, edge)]
    return np.stack(q, axis=1)


def authors_chain(X: np.ndarray, N: np.ndarray | None) -> np.ndarray | None:
    """The authors' public ``parameterize_grasp`` (``normalize=False``) for ``n >= 4`` contacts, one grasp: ``X, N
    (n, 3)`` in their order -> ``(3n - 6,)`` or ``(5n - 6,)``, or None where their code rejects the grasp (Qhull
    fails, or the hull has fewer than ``n`` facets: a contact inside it).

    Written from the description of their code, not copied: the facets in Qhull's order, starting at the
    largest; its vertices turned to start at its longest edge ``v0 v1`` in Qhull's cyclic order; then a strip of
    facets, each the other facet on the edge ``(c1, c2)`` of the current ``(c0, c1, c2)`` (on ``v0 v1`` first, which
    gives ``(v0, v1, k)``). Each facet adds its interior angles at ``c0`` and ``c1``, the first its longest edge, every
    later one the dot product of its scaled normal with the previous facet's (the scaled normal is ``(c1 - c0) x
    (c2 - c0) / (|c1 - c0| |c2 - c0|)``, as in their code). With normals, each contact *in the input order* adds the
    angles of its normal to the first two facets' scaled normals. So the vector depends on the input order through
    Qhull's facet order and orientation, and its normal part directly."""
    n = len(X)
    try:
        tris = ConvexHull(X).simplices
    except QhullError:
        return None
    if len(tris) < n:
        return None

    def scaled_normal(P):
        a, b = P[1] - P[0], P[2] - P[0]
        return np.cross(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))

    def angle(a, b):
        return np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))

    def other_facet(i, j, cur):
        """The facet on edge ``(i, j)`` that is not ``cur``, and its vertex off that edge."""
        on_edge = [t for t in tris if i in t and j in t]
        t = on_edge[1] if set(on_edge[0]) == set(cur) else on_edge[0]
        return int(next(v for v in t if v != i and v != j))

    P = X[tris]
    areas = np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    tris = np.roll(tris, -int(np.argmax(areas)), axis=0)
    cur = tris[0]
    D = np.linalg.norm(X[cur] - X[np.roll(cur, -1)], axis=1)
    cur = np.roll(cur, -int(np.argmax(D)))
    q, axes, prev = [], [], None
    for j in range(n - 2):
        P = X[cur]
        q += [angle(P[2] - P[0], P[1] - P[0]), angle(P[0] - P[1], P[2] - P[1])]
        nt = scaled_normal(P)
        axes.append(nt)
        if j == 0:
            q.append(D.max())
            cur = np.array([cur[0], cur[1], other_facet(cur[0], cur[1], cur)])
        else:
            q.append(nt @ prev)
            cur = np.array([cur[1], cur[2], other_facet(cur[1], cur[2], cur)])
        prev = nt
    if N is not None:
        for m in range(n):
            q += [np.arccos(np.clip(axes[0] @ N[m], -1, 1)), np.arccos(np.clip(axes[1] @ N[m], -1, 1))]
    return np.asarray(q)


def authors_data(objs, count: int, n: int, seed: int, *, sort: bool, normals: bool,
                 mu: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``count`` grasps of ``n`` contacts per object sampled as the authors' code does (``n`` distinct uniformly chosen
    faces, their centres and inward normals; indices sorted when ``sort``, else in random order; with ``mu`` only
    grasps in force closure, :func:`~haptic_env.force_closure.force_closure`) through :func:`authors_n3` (``n = 3``)
    or :func:`authors_chain` (grasps that it rejects are drawn again, as their loop does)."""
    from haptic_env.force_closure import force_closure

    rng = np.random.default_rng(seed)
    X, y = [], []
    for k, obj in enumerate(objs):
        F = len(obj.mesh.faces)
        centres, inward = np.asarray(obj.mesh.triangles_center), -np.asarray(obj.mesh.face_normals)
        rows, rejects = [], n > 3 or mu is not None  # whether a drawn grasp can be dropped
        while (missing := count - sum(len(r) for r in rows)) > 0:
            # exactly the missing grasps where none is dropped: the earlier n = 3 version's draw, so its committed
            # rows reproduce; twice as many (and 100) where some are
            idx = _distinct(rng, F, 2 * missing + 100 if rejects else missing, n)
            if sort:
                idx = np.sort(idx, axis=1)
            C, Nn = centres[idx], inward[idx]
            if mu is not None:
                held = force_closure(C, Nn, mu)
                C, Nn = C[held], Nn[held]
            if n == 3:
                rows.append(authors_n3(C, Nn if normals else None))
            else:
                vs = [authors_chain(c, nn if normals else None) for c, nn in zip(C, Nn)]
                rows.append(np.array([v for v in vs if v is not None]).reshape(-1, (5 if normals else 3) * n - 6))
        X.append(np.concatenate(rows)[:count])
        y.append(np.full(count, k))
    return np.concatenate(X), np.concatenate(y)


def _distinct(rng: np.random.Generator, F: int, m: int, n: int) -> np.ndarray:
    """``(m, n)`` face indices, distinct within each row, uniform (rows with a repeat drawn again)."""
    idx = rng.integers(0, F, size=(m, n))
    while True:
        s = np.sort(idx, axis=1)
        bad = (s[:, 1:] == s[:, :-1]).any(axis=1)
        if not bad.any():
            return idx
        idx[bad] = rng.integers(0, F, size=(int(bad.sum()), n))


if __name__ == "__main__":
    sys.exit(main())
