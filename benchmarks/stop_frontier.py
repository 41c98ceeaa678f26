"""Success at the stop against grasps, as the belief's evidence is scaled: how fast can BC-NP stop on a hand?

The hand table's BC-NP stops when the posterior's largest entry reaches lambda. Its speed is set by how much one
grasp moves the belief: the calibrated log-likelihood of the grasp (divided by the KDE's temperature, fitted on
validation grasps). This script multiplies that per-grasp log-likelihood by a scale ``s`` (``s > 1``: sharper, as an
uncalibrated or over-confident belief; ``s < 1``: more cautious) and replays the same grasp sequences, so that the
whole trade-off between success at the stop and grasps is measured at once, on validation pools by default. (The
analyses' stop scale, :mod:`haptic_env.experiments.stop_scale`, divides like a temperature: its scale is ``1 / s``
here.) It answers whether any temperature reaches a target such as the paper's real Allegro BC-NP z=3 (94 % in
1.62 grasps), and shows the floor no stopping rule can pass: a grasp with fewer than 3 touching fingertips carries no contact
information, so the first usable grasp comes after ``1 / usable rate`` grasps on average.

Each query is a sequence of random-approach grasps of one object (the hand table's pools: pool seeds ``500 + s``
with ``--split validation``, ``1000 + s`` with ``--split test``). Per grasp the belief adds (before the scale)

* ``BC-NP``: the touching contacts' log-likelihood under the model of their count;
* ``BC-NP, z=3``: the 3-finger subsets' summed log-likelihoods times ``min(1, k / m)`` for ``m`` scored subsets,
  ``k`` the env's ``subset_k`` (4), its ``score_subsets`` rule (:func:`~haptic_env.recognizers.zfinger.subset_weight`;
  with 4 fingers all 4 subsets, as the hand table);

both plus the touch pattern's log-likelihood weighted as in the hand's env (``touch_weight``; the Allegro's 0.75 since
2026-12-07, 0 when this frontier was measured).

With ``--heights`` the grasp vectors carry the contacts' heights above the table, and the settings are the hand's
``Heights`` env's (``hand_experiment.py --heights``).

Scale 1 is the hand table's belief: the registered env's settings, with the KDE summed per object (``method="tree"``)
where the env pools one neighbour search over all objects (``kde_method="pooled"``), so far-tail scores and the fitted
temperature differ a little from the env's. The script checks that its replay reproduces the hand table's updaters
exactly there (the same stops and predictions), before it reports anything, for every hand without z-subsets and for
the 4-finger Allegro with them. A 5-finger hand's z = 3 replay is not checked: the env counts its C(5, 3) = 10 subsets
as the paper's k = 4 (``subset_k``), which the hand table's updater (the product over all subsets) does not.

    python benchmarks/stop_frontier.py [--hands allegro] [--split validation] [--seeds 0 1 2] [--queries 10]
        [--scales 0.5 0.7 1 1.4 2 3 4 6 10] [--heights] [--out docs/results/stop_frontier]

Writes ``frontier.md`` and ``frontier.png`` under ``--out``; the headline is printed last.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.hand_experiment import (PAPER, SETUPS, check_pool_seeds, env_config, query_pools,  # noqa: E402
                                        pm, run_query, training_config, write_table)
from haptic_env.cache import atomic_write  # noqa: E402
from haptic_env.cli import int_in, output_path  # noqa: E402
from haptic_env.config import HAND_APPROACHES  # noqa: E402
from haptic_env.dataset import support_frame  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402
from haptic_env.recognizers import build_recognizer, models_for  # noqa: E402
from haptic_env.recognizers.updaters import DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD  # noqa: E402
from haptic_env.recognizers.zfinger import subset_vectors, subset_weight  # noqa: E402
from haptic_env.splits import hand_pool_seed  # noqa: E402

METHODS = ("BC-NP", "BC-NP, z=3")


def grasp_scores(rec, C, N, T, normals: bool, z: int | None, touch_weight: float,
                 subset_k: int | None = None) -> np.ndarray:
    """Per-grasp calibrated log-likelihoods ``(G, K)`` of one query's grasps ``C, N (G, n, 3)``, ``T (G, n)``
    (``z``: scored through its z-subsets, weighted as the env's with ``subset_k``).

    A grasp with fewer than 3 touching fingertips adds only its touch pattern's term (0 without one); a row whose
    every class is -inf is left as it is (the replay skips it, as the updaters do)."""
    models = rec.models.with_calibration(True)
    G, n = T.shape
    L = np.zeros((G, rec.n_classes))
    if touch_weight > 0:
        L += touch_weight * rec.touch.log_likelihood(T)
    for g in range(G):
        if T[g].sum() < 3:
            continue
        Q = subset_vectors(C[g], N[g] if normals else None, z, touched=T[g], heights=rec.heights,
                           normal_axis=rec.normal_axis)
        if len(Q) == 0:
            continue
        w = 1.0 if z is None else subset_weight(len(Q), subset_k)
        L[g] += w * models.log_likelihood(Q).sum(axis=0)
    return L


def replay(L: np.ndarray, scales: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replay queries' per-grasp scores ``L (Q, G, K)`` for each scale -> prediction, grasps, decided, each ``(S, Q)``.

    The belief starts uniform; each grasp adds ``s * L[g]`` in log space (a grasp under which every class is
    impossible leaves it unchanged); a query stops at the first grasp whose posterior's largest entry reaches
    ``threshold``, else after its last grasp."""
    S, (Qn, G, K) = len(scales), L.shape
    logb = np.full((S, Qn, K), -math.log(K))
    pred = np.zeros((S, Qn), dtype=np.int64)
    used = np.full((S, Qn), G, dtype=np.int64)
    done = np.zeros((S, Qn), dtype=bool)
    with np.errstate(invalid="ignore"):
        for g in range(G):
            new = logb + scales[:, None, None] * L[None, :, g]
            ok = np.isfinite(new.max(axis=2, keepdims=True))
            logb = np.where(ok & ~done[..., None], new, logb)
            m = logb.max(axis=2, keepdims=True)
            post = np.exp(logb - m)
            post /= post.sum(axis=2, keepdims=True)
            stop = (post.max(axis=2) >= threshold) & ~done
            used[stop] = g + 1
            pred[stop] = post.argmax(axis=2)[stop]
            done |= stop
        pred[~done] = logb.argmax(axis=2)[~done]
    return pred, used, done


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hands", nargs="+", default=["allegro"], choices=list(SETUPS))
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    ap.add_argument("--split", choices=["validation", "test"], default="validation",
                    help="query pools: validation (pool seeds 500 + s, the default: for choosing) or test (1000 + s)")
    ap.add_argument("--seeds", type=int_in(0), nargs="+", default=[0, 1, 2], help="pool seeds (spread: std over them)")
    ap.add_argument("--queries", type=int_in(1), default=10, help="queries per object and seed")
    ap.add_argument("--max-grasps", type=int_in(1), default=DEFAULT_MAX_GRASPS)
    ap.add_argument("--threshold", type=float, default=DEFAULT_THRESHOLD, help="certainty threshold lambda")
    ap.add_argument("--scales", type=float, nargs="+", default=[0.5, 0.7, 1.0, 1.4, 2.0, 3.0, 4.0, 6.0, 10.0],
                    help="multipliers of the calibrated per-grasp log-likelihood (1: the hand table's belief)")
    ap.add_argument("--heights", action="store_true",
                    help="grasp vectors with the contacts' heights above the table (the hands' Heights envs)")
    ap.add_argument("--out", type=output_path("folder"), default=None, help="write frontier.md and frontier.png here")
    args = ap.parse_args(argv)
    bad = [s for s in args.scales if not (np.isfinite(s) and s > 0)]
    if bad:
        ap.error(f"--scales must be finite and > 0, got {bad}")
    if 1.0 not in args.scales:
        ap.error("--scales must include 1 (the hand table's belief, checked against its updaters)")
    if not 0 < args.threshold < 1:
        ap.error(f"--threshold must be in (0, 1), got {args.threshold}")
    check_pool_seeds(ap, args.split, args.seeds)
    if data_dir() is None:
        print("the stop frontier needs the YCB meshes (ycb/ in the shared data folder; set HAPTIC_DATA)")
        return 1
    scales = np.array(sorted(set(args.scales)))
    objects = load_object_set("ycb10")
    t0 = time.perf_counter()
    results = []  # (hand, normals, method, usable, success (scales, seeds), grasps (scales, seeds))
    cfg_args = argparse.Namespace(hand_budget="uniform", heights=args.heights)
    for hand in args.hands:
        n, normal_settings = SETUPS[hand]
        got = query_pools(objects, hand, n, args.split, args.seeds, args.queries, args.max_grasps)
        if got is None:
            continue
        pools, usable = got
        env = env_config(hand, args.heights)
        A = env.training_grasps or HAND_APPROACHES
        cfg = training_config("hand", hand, cfg_args, env.calibrate_grasps, A)
        for normals in normal_settings:
            rec = build_recognizer(objects, n, normals, z_values=tuple(range(3, n)), config=cfg,
                                   models=models_for("bc-np"), touch=env.touch_weight > 0)
            for method in args.methods:
                z = 3 if method.endswith("z=3") else None
                w = env.touch_weight
                succ, grasps = [], []
                for s, pool in enumerate(pools):
                    K = pool.touched.shape[0]
                    Ls, labels, checks = [], [], []
                    for i in range(K):
                        # read as the recogniser's training grasps were (from the object's table with heights)
                        C = support_frame(pool.contacts[i], objects[i], rec.config.grasps).reshape(
                            args.queries, args.max_grasps, n, 3)
                        N = pool.normals[i].reshape(args.queries, args.max_grasps, n, 3)
                        T = pool.touched[i].reshape(args.queries, args.max_grasps, n)
                        for q in range(args.queries):
                            Ls.append(grasp_scores(rec, C[q], N[q], T[q], normals, z, w, env.subset_k))
                            labels.append(i)
                            checks.append((C[q], N[q], T[q]))
                    L, labels = np.stack(Ls), np.array(labels)
                    pred, used, done = replay(L, scales, args.threshold)
                    if z is None or n == 4:  # scale 1 must be the hand table's updater, stop for stop
                        s1 = int(np.flatnonzero(scales == 1.0)[0])
                        upd = rec.make_updater("bc-np", threshold=args.threshold, z=z, k=None)
                        for j, (C, N, T) in enumerate(checks):
                            touch = w * rec.touch.log_likelihood(T) if w > 0 else None
                            p, g, d = run_query(upd, C, N, T, normals, touch)
                            if (p, g, d) != (pred[s1, j], used[s1, j], done[s1, j]):
                                raise AssertionError(f"{hand} {method} query {j}: replay {pred[s1, j], used[s1, j], done[s1, j]} "
                                                     f"!= updater {(p, g, d)}")
                    succ.append(np.mean((pred == labels) & done, axis=1))
                    grasps.append(used.mean(axis=1))
                results.append((hand, normals, method, usable, np.array(succ).T, np.array(grasps).T))
    if not results:
        return 1
    cols = {(4, True): "4+", (4, False): "4-", (5, False): "5-"}
    pool_seeds = [hand_pool_seed(args.split, sd) for sd in args.seeds]  # the pools' own seeds (500 + s: validation)
    lines = [f"YCB-10, {args.queries} queries per object x {len(args.seeds)} {args.split} pool seeds {pool_seeds}, "
             f"<= {args.max_grasps} random-approach grasps per query, lambda = {args.threshold}. Scale s multiplies "
             "the calibrated per-grasp log-likelihood of the hand's registered env (s = 1; checked against the hand "
             "table's updaters). Success = decided and correct at the stop, mean +- sample std over the pool seeds. "
             "Floor: 1 / usable rate, the mean grasps to the first grasp with >= 3 touching fingertips.", "",
             "| hand | normals | method | paper (success % / grasps) | floor (grasps) | " +
             " | ".join(f"s = {s:g}" for s in scales) + " |",
             "|---|---|---|---|---|" + "---|" * len(scales)]
    for hand, normals, method, usable, S, Gr in results:
        paper = PAPER[method][cols[(SETUPS[hand][0], normals)]]
        cells = [f"{pm(S[i], 100)} % / {Gr[i].mean():.2f}"
                 for i in range(len(scales))]
        lines.append(f"| {hand} | {'yes' if normals else 'no'} | {method} | {paper[0]} / {paper[1]} | "
                     f"{1 / usable:.2f} | " + " | ".join(cells) + " |")
    text = "\n".join(lines)
    print("\n" + text)
    if args.out is not None:
        write_table(args.out, "frontier.md", "stop_frontier.py", argv, time.perf_counter() - t0, text)
        from matplotlib.figure import Figure  # no pyplot: no global backend switch

        fig = Figure(figsize=(7, 4.5))
        ax = fig.subplots()
        for hand, normals, method, usable, S, Gr in results:
            label = f"{hand} {'w/' if normals else 'w/o'} normals, {method}"
            line, = ax.plot(Gr.mean(1), 100 * S.mean(1), "o-", label=label)
            for i, s in enumerate(scales):
                ax.annotate(f"{s:g}", (Gr[i].mean(), 100 * S[i].mean()), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
            paper = PAPER[method][cols[(SETUPS[hand][0], normals)]]
            ax.plot(paper[1], paper[0], "*", ms=12, color=line.get_color())
            ax.axvline(1 / usable, ls=":", color=line.get_color(), lw=1)
        ax.axhline(100 * (args.threshold - 0.03), ls="--", color="grey", lw=1)
        ax.set_xlabel("mean grasps at the stop")
        ax.set_ylabel("success at the stop (decided and correct), %")
        ax.set_title(f"belief scaled by s ({args.split} queries)\nstars: the paper; dotted: 1 / usable rate; dashed: lambda - 3",
                     fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        with atomic_write(args.out / "frontier.png") as fh:
            fig.savefig(fh, format="png", dpi=120)
    best = []
    for hand, normals, method, usable, S, Gr in results:
        paper = PAPER[method][cols[(SETUPS[hand][0], normals)]]
        ok = [i for i in range(len(scales)) if 100 * S[i].mean() >= paper[0]]
        fastest = min(ok, key=lambda i: Gr[i].mean()) if ok else None
        best.append(f"{hand} {'w/' if normals else 'w/o'} {method}: "
                    + (f"fewest grasps at >= the paper's {paper[0]} %: {Gr[fastest].mean():.2f} (s = {scales[fastest]:g}; "
                       f"paper {paper[1]})" if fastest is not None else f"no scale reaches the paper's {paper[0]} %"))
    oracle = ("(the scale chosen on these test pools themselves: an upper bound, not a result; report the scale "
              "chosen on validation) ") if args.split == "test" else ""
    print("HEADLINE: " + oracle + "; ".join(best))
    return 0


if __name__ == "__main__":
    sys.exit(main())
