"""Is the KDE what limits one grasp's information on a hand? The env's KDE against scikit-learn classifiers.

The hand envs' BC-NP belief scores each grasp vector (the paper's Phi_n) with a calibrated KDE of the hand's own
MuJoCo grasps of the meshes. If a better classifier of the same vectors told the objects apart more often, the
belief could stop sooner at the same success, and the plain Allegro env's z = 3 row (2.15 grasps against the paper's
1.62) might move. This benchmark trains, on exactly the KDE's training vectors (the env's recogniser data set: pool
seed 0, the env's approaches per object, complete grasps or 3-subsets), four scikit-learn classifiers:

* ``knn``: k-NN, 15 neighbours, distance-weighted;
* ``hgb``: histogram gradient boosting (300 iterations at most, early stopping on 10 % of the training vectors);
* ``extra-trees``: 300 extremely randomised trees, 2 vectors per leaf at least (356-622 MB pickled per finger
  count, about 50 ms per vector);
* ``extra-trees-small``: 50 such trees, 10 vectors per leaf at least;
* ``mlp``: a 3 x 256 ReLU network (Adam, early stopping on 10 % of the training vectors);

(``--classifiers`` defaults to all but ``extra-trees-small``) all on standardised vectors, seed 0. Each is scored one-shot on the hand table's validation pools (pool seeds
500-502, or with ``--split test`` its test pools 1000-1002; 10 queries x 30 random approaches per object each; every
complete grasp, or every 3-subset of the touching
fingertips of every grasp with at least 3) by its accuracy (argmax right) and its log-loss (nats; log 10 = 2.30 for
a uniform guess over ycb10), beside the env's calibrated KDE posterior (uniform prior) on the same vectors.

One-shot accuracy is not what a belief needs: BC-NP multiplies one grasp's likelihood after another, and how far each
moves the belief is a scale that any likelihood can be given. So the second part replays the hand table's
validation queries (``benchmarks/stop_frontier.py``'s: 10 queries of at most 30 grasps per object and pool seed)
with each classifier as the likelihood, ``log p(object | q) - log (the object's share of the training vectors)``
(each class probability floored at 1e-6), one classifier per count of touching fingertips (3 to n), scored as the
env scores the KDE (BC-NP: the touching contacts' vector; z = 3: the 3-subsets' sum, weighted by the env's
``subset_k``; the env's touch-pattern term added alike), and multiplied by each scale ``s``. The KDE's row at
``s = 1`` is the hand table's belief (the env's settings, the KDE summed per object where the env pools its
neighbour search: ``stop_frontier.py``'s docstring). If a classifier's frontier (success at the stop against
grasps) lay above the KDE's, it would tell more per grasp. Nothing is chosen here; the default split uses no test grasp.

    OMP_NUM_THREADS=1 python benchmarks/hand_classifiers.py [--hands allegro aero] [--split validation]
        [--classifiers knn hgb extra-trees mlp] [--frontier hgb extra-trees] [--scales ...] [--out DIR]

Writes ``classifiers.md`` and ``frontier.png`` under ``--out``, and ``classifiers.state.json``, each finished (hand,
normals) block, from which a run started again into the same folder with the same settings and code resumes (without
``--out`` that state is kept in the cache); the headline (per hand and method, the fewest grasps at
the paper's success with each likelihood) is printed last.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.hand_experiment import (PAPER, SETUPS, check_pool_seeds, env_config, query_pools,  # noqa: E402
                                        pm, training_config, write_table)
from benchmarks.stop_frontier import grasp_scores, replay  # noqa: E402
from haptic_env.cli import int_in, output_path  # noqa: E402
from haptic_env.cache import (atomic_write, cache_dir, config_key, package_fingerprint, resume_state,  # noqa: E402
                              save_keyed_json)
from haptic_env.config import HAND_APPROACHES  # noqa: E402
from haptic_env.dataset import build_dataset, support_frame  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402
from haptic_env.recognizers import build_recognizer, models_for  # noqa: E402
from haptic_env.recognizers.updaters import DEFAULT_THRESHOLD  # noqa: E402
from haptic_env.recognizers.zfinger import subset_vectors, subset_weight  # noqa: E402
from haptic_env.splits import hand_pool_seed  # noqa: E402

CLASSIFIERS = ("knn", "hgb", "extra-trees", "extra-trees-small", "mlp")
#: the one-shot comparison's classifiers by default (the small forest only where asked for)
ONE_SHOT = ("knn", "hgb", "extra-trees", "mlp")
#: the likelihoods replayed in the frontier by default (the MLP trains 1-3 min per finger count)
FRONTIER = ("hgb", "extra-trees")
METHODS = ("BC-NP", "BC-NP, z=3")
#: queries per object and pool seed, grasps per query: the hand table's validation queries
QUERIES, MAX_GRASPS = 10, 30
#: floor of a classifier's class probability before its log is taken
P_FLOOR = 1e-6


def make(name: str):
    """A fresh scikit-learn classifier ``name`` (:data:`CLASSIFIERS`), seed 0."""
    from sklearn.ensemble import ExtraTreesClassifier, HistGradientBoostingClassifier
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.neural_network import MLPClassifier

    if name == "knn":
        return KNeighborsClassifier(15, weights="distance")
    if name == "hgb":
        return HistGradientBoostingClassifier(max_iter=300, early_stopping=True, random_state=0)
    if name == "extra-trees":
        return ExtraTreesClassifier(300, min_samples_leaf=2, n_jobs=1, random_state=0)
    if name == "extra-trees-small":
        return ExtraTreesClassifier(50, min_samples_leaf=10, n_jobs=1, random_state=0)
    if name == "mlp":
        return MLPClassifier((256, 256, 256), early_stopping=True, max_iter=200, random_state=0)
    raise ValueError(f"unknown classifier {name!r}; choose from {CLASSIFIERS}")


class ClassifierLikelihood:
    """A classifier of one finger count's grasp vectors as a likelihood: ``log p(k | q) - log prior_k``
    (``prior_k``: object ``k``'s share of the training vectors; probabilities floored at :data:`P_FLOOR`)."""

    def __init__(self, name: str, X: np.ndarray, y: np.ndarray, n_classes: int):
        from sklearn.preprocessing import StandardScaler

        counts = np.bincount(y, minlength=n_classes)
        if len(counts) > n_classes or not counts.all():
            raise ValueError(f"every one of the {n_classes} classes needs training vectors; counts {counts.tolist()}")
        self.scaler = StandardScaler().fit(X)
        self.clf = make(name).fit(self.scaler.transform(X), y)
        self.log_prior = np.log(counts / len(y))

    def proba(self, Q: np.ndarray) -> np.ndarray:
        """``(m, d) -> (m, K)`` class probabilities."""
        return self.clf.predict_proba(self.scaler.transform(Q))

    def log_likelihood(self, Q: np.ndarray) -> np.ndarray:
        return np.log(np.maximum(self.proba(Q), P_FLOOR)) - self.log_prior


def query_vectors(pool, objects, rec, normals: bool, z: int | None) -> tuple[np.ndarray, np.ndarray]:
    """One pool's grasp vectors ``(m, d)`` and labels ``(m,)``: every complete grasp (``z`` None) or every 3-subset
    of the touching fingertips of every grasp with at least 3 (``z = 3``), read as the recogniser's training grasps
    were (:func:`~haptic_env.dataset.support_frame`)."""
    X, y = [], []
    for i in range(pool.touched.shape[0]):
        C = support_frame(pool.contacts[i], objects[i], rec.config.grasps)
        N, T = pool.normals[i], pool.touched[i]
        rows = T.all(1) if z is None else T.sum(1) >= 3
        for g in np.flatnonzero(rows):
            Q = subset_vectors(C[g], N[g] if normals else None, z, touched=T[g], heights=rec.heights,
                               normal_axis=rec.normal_axis)
            X.extend(Q)
            y.extend([i] * len(Q))
    return np.asarray(X), np.asarray(y)


def scores(proba: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Accuracy and log-loss (nats; probabilities clipped at 1e-12) of posteriors ``proba (m, K)``."""
    p = np.clip(proba[np.arange(len(y)), y], 1e-12, 1.0)
    return float(np.mean(proba.argmax(1) == y)), float(-np.mean(np.log(p)))


def kde_proba(rec, X: np.ndarray) -> np.ndarray:
    """The env's calibrated KDE posterior of each vector under a uniform prior, ``(m, K)``."""
    from scipy.special import softmax

    return softmax(rec.models.with_calibration(True).log_likelihood(X), axis=1)


def query_scores(pool, objects, rec, normals: bool, z: int | None, likelihoods: dict, touch_weight: float,
                 subset_k: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Per-grasp log-likelihoods of one pool's queries, ``name -> (Q, G, K)``, and the queries' labels ``(Q,)``:
    ``"KDE"`` by :func:`~benchmarks.stop_frontier.grasp_scores` (the hand table's belief), each classifier of
    ``likelihoods`` (vector dimension -> :class:`ClassifierLikelihood`) the same way, batched per dimension."""
    K, n = pool.touched.shape[0], pool.touched.shape[2]
    kde, labels, rows = [], [], {}  # rows: dim -> (query, grasp, weight, vector) lists
    for i in range(K):
        C = support_frame(pool.contacts[i], objects[i], rec.config.grasps).reshape(QUERIES, MAX_GRASPS, n, 3)
        N = pool.normals[i].reshape(QUERIES, MAX_GRASPS, n, 3)
        T = pool.touched[i].reshape(QUERIES, MAX_GRASPS, n)
        for q in range(QUERIES):
            kde.append(grasp_scores(rec, C[q], N[q], T[q], normals, z, touch_weight, subset_k))
            qi = len(labels)
            labels.append(i)
            for g in np.flatnonzero(T[q].sum(1) >= 3):
                Q = subset_vectors(C[q, g], N[q, g] if normals else None, z, touched=T[q, g], heights=rec.heights,
                                   normal_axis=rec.normal_axis)
                w = 1.0 if z is None else subset_weight(len(Q), subset_k)
                for v in Q:
                    rows.setdefault(len(v), []).append((qi, g, w, v))
    out = {"KDE": np.stack(kde)}
    touch = np.zeros_like(out["KDE"])
    if touch_weight > 0:
        T = pool.touched.reshape(K * QUERIES, MAX_GRASPS, n)
        touch = touch_weight * np.stack([rec.touch.log_likelihood(t) for t in T])
    for name, by_dim in likelihoods.items():
        L = touch.copy()
        for d, items in rows.items():
            qi, g, w = (np.array([it[j] for it in items]) for j in range(3))
            ll = by_dim[d].log_likelihood(np.array([it[3] for it in items]))
            np.add.at(L, (qi, g), w[:, None] * ll)
        out[name] = L
    return out, np.array(labels)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hands", nargs="+", default=["allegro", "aero"], choices=list(SETUPS))
    ap.add_argument("--classifiers", nargs="*", default=list(ONE_SHOT), choices=CLASSIFIERS,
                    help="one-shot comparison")
    ap.add_argument("--frontier", nargs="*", default=list(FRONTIER), choices=CLASSIFIERS,
                    help="classifiers replayed as the belief's likelihood (none: skip the frontier)")
    ap.add_argument("--scales", type=float, nargs="+", default=[0.3, 0.5, 0.7, 1.0, 1.4, 2.0, 3.0])
    ap.add_argument("--split", choices=["validation", "test"], default="validation",
                    help="query pools: validation (pool seeds 500 + s, the default: for choosing) or test (1000 + s)")
    ap.add_argument("--seeds", type=int_in(0), nargs="+", default=[0, 1, 2], help="pool seeds (spread: std over them)")
    ap.add_argument("--out", type=output_path("folder"), default=None, help="write classifiers.md, frontier.png here")
    args = ap.parse_args(argv)
    check_pool_seeds(ap, args.split, args.seeds)
    bad = [s for s in args.scales if not (np.isfinite(s) and s > 0)]
    if bad:
        ap.error(f"--scales must be finite and > 0, got {bad}")
    if data_dir() is None:
        print("needs the YCB meshes and the menagerie hands (set HAPTIC_DATA and MENAGERIE_ROOT)")
        return 1
    t0 = time.perf_counter()
    scales = np.array(sorted(set(args.scales)))
    objects = load_object_set("ycb10")
    K = len(objects)
    names = ["KDE (the env's)", *args.classifiers]
    one = ["| hand | normals | grasp vectors | training vectors | query vectors per pool | " +
           " | ".join(names) + " |", "|---" * (5 + len(names)) + "|"]
    front = ["| hand | normals | method | paper | likelihood | " + " | ".join(f"s = {s:g}" for s in scales) + " |",
             "|---" * (5 + len(scales)) + "|"]
    curves, heads = [], []
    # each finished (hand, normals) block is kept, keyed by the settings, in --out (else in the cache; not committed):
    # a run started again after an interruption (the default run takes about 14 min) computes only the blocks it lacks
    # and by the code (haptic_env's and the benchmarks'): a resume after a code change computes every block again
    key = {**{k: v for k, v in sorted(vars(args).items()) if k != "out"},
           "code": package_fingerprint(Path(__file__).parent)}
    state = (args.out / "classifiers.state.json" if args.out is not None
             else cache_dir("hand_classifiers") / f"{config_key(key)}.json")
    finished = resume_state(state, key, "blocks")
    for hand in args.hands:
        n, normal_settings = SETUPS[hand]
        got = query_pools(objects, hand, n, args.split, args.seeds, QUERIES, MAX_GRASPS)
        if got is None:
            continue
        pools, _ = got
        env = env_config(hand)
        cfg = training_config("hand", hand, argparse.Namespace(hand_budget="uniform", heights=False),
                              env.calibrate_grasps, env.training_grasps or HAND_APPROACHES)
        for normals in normal_settings:
            block = f"{hand} | normals={normals}"
            if block in finished:  # an interrupted run finished it
                b = finished[block]
                one += b["one"]
                front += b["front"]
                heads += b["heads"]
                curves += [(c[0], c[1], np.array(c[2]), np.array(c[3])) for c in b["curves"]]
                print("\n".join(b["one"] + b["front"]), flush=True)
                continue
            mark = (len(one), len(front), len(curves), len(heads))
            rec = build_recognizer(objects, n, normals, z_values=tuple(range(3, n)), config=cfg,
                                   models=models_for("bc-np"), touch=env.touch_weight > 0)
            data = {z: build_dataset(objects, cfg.dataset_config(z, normals, hand_fingers=n)) for z in range(3, n + 1)}
            models: dict[tuple[str, int], ClassifierLikelihood] = {}

            def trained(name: str, z: int) -> ClassifierLikelihood:  # each classifier trained once per finger count
                if (name, z) not in models:
                    models[name, z] = ClassifierLikelihood(name, data[z].X_train, data[z].y_train, K)
                return models[name, z]

            for z in (None, 3):  # one-shot
                ds = data[z or n]
                queries = [query_vectors(p, objects, rec, normals, z) for p in pools]
                acc, nll = {}, {}
                for name in names:
                    t1 = time.perf_counter()
                    if name == names[0]:
                        res = [scores(kde_proba(rec, X), y) for X, y in queries]
                    else:
                        lik = trained(name, z or n)
                        res = [scores(lik.proba(X), y) for X, y in queries]
                    acc[name], nll[name] = [a for a, _ in res], [b for _, b in res]
                    print(f"  {hand} normals={normals} z={z or n} {name}: {100 * np.mean(acc[name]):.1f} % "
                          f"({time.perf_counter() - t1:.0f} s)", flush=True)
                cells = [f"{pm(acc[k], 100)} % / "
                         f"{np.mean(nll[k]):.3f}" for k in names]
                what = "complete" if z is None else "3-subsets"
                one.append(f"| {hand} | {'yes' if normals else 'no'} | {what} | {len(ds.X_train):,} | "
                           f"{int(np.mean([len(y) for _, y in queries])):,} | " + " | ".join(cells) + " |")
                print(one[-1], flush=True)
            if args.frontier:
                liks = {name: {data[z].X_train.shape[1]: trained(name, z) for z in data} for name in args.frontier}
                for method in METHODS:
                    z = 3 if method.endswith("z=3") else None
                    S, G = {}, {}
                    for pool in pools:
                        Ls, labels = query_scores(pool, objects, rec, normals, z, liks, env.touch_weight,
                                                  env.subset_k)
                        for name, L in Ls.items():
                            pred, used, done = replay(L, scales, DEFAULT_THRESHOLD)
                            S.setdefault(name, []).append(np.mean((pred == labels) & done, axis=1))
                            G.setdefault(name, []).append(used.mean(axis=1))
                    paper = PAPER[method][f"{n}{'+' if normals else '-'}"]
                    for name in S:
                        s_, g_ = np.array(S[name]).T, np.array(G[name]).T  # (scales, seeds)
                        cells = [f"{pm(s_[i], 100)} % / {g_[i].mean():.2f}"
                                 for i in range(len(scales))]
                        front.append(f"| {hand} | {'yes' if normals else 'no'} | {method} | {paper[0]} % / "
                                     f"{paper[1]} | {name} | " + " | ".join(cells) + " |")
                        print(front[-1], flush=True)
                        curves.append((f"{hand} {'w/' if normals else 'w/o'} normals, {method}", name,
                                       g_.mean(1), 100 * s_.mean(1)))
                        ok = [i for i in range(len(scales)) if 100 * s_[i].mean() >= paper[0]]
                        best = f"{g_[min(ok, key=lambda i: g_[i].mean())].mean():.2f}" if ok else "none"
                        heads.append(f"{hand} {'w/' if normals else 'w/o'} normals {method}, {name}: {best}")
            finished[block] = {"one": one[mark[0]:], "front": front[mark[1]:], "heads": heads[mark[3]:],
                               "curves": [[c[0], c[1], np.asarray(c[2]).tolist(), np.asarray(c[3]).tolist()]
                                          for c in curves[mark[2]:]]}
            save_keyed_json(state, key, blocks=finished)
    if len(one) == 2:
        return 1
    pool_seeds = [hand_pool_seed(args.split, s) for s in args.seeds]
    text = (f"One-shot accuracy / log-loss (nats; uniform guess 2.303) on the {args.split} pools {pool_seeds} (mean "
            "+- sample std over the pools), every classifier trained on the env recogniser's own training vectors "
            "(pool seed 0).\n\n" + "\n".join(one))
    if len(front) > 2:
        text += ("\n\nThe stop frontier with each likelihood (success at the stop, decided and correct, mean +- sample "
                 f"std over the pools / mean grasps; {QUERIES} queries of at most {MAX_GRASPS} grasps per object and "
                 f"pool, lambda = {DEFAULT_THRESHOLD}; the KDE at s = 1 is the hand table's belief):\n\n"
                 + "\n".join(front))
    if args.out is not None:
        write_table(args.out, "classifiers.md", "hand_classifiers.py", argv, time.perf_counter() - t0, text)
        if curves:
            plot(curves, args.out / "frontier.png")
    oracle = (" (the scale chosen on these test pools themselves: an upper bound, not a result; report the scale "
              "chosen on validation)") if args.split == "test" else ""
    print(f"HEADLINE: fewest mean grasps at the paper's success on {args.split}{oracle}, per likelihood: "
          + ("; ".join(heads) if heads else "(no frontier)"))
    return 0


def plot(curves: list, path: Path) -> None:
    """One panel per hand / normals / method: success at the stop against grasps, one line per likelihood."""
    from matplotlib.figure import Figure  # no pyplot: no global backend switch

    panels = list(dict.fromkeys(c[0] for c in curves))
    cols = min(3, len(panels))
    rows = -(-len(panels) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.6 * rows))
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    for ax, panel in zip(axes, panels):
        for _, name, g, s in (c for c in curves if c[0] == panel):
            ax.plot(g, s, "o-", label=name, ms=3)
        ax.set_title(panel, fontsize=8)
        ax.set_xlabel("mean grasps at the stop")
        ax.set_ylabel("success at the stop, %")
        ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_write(path) as fh:
        fig.savefig(fh, dpi=110, format="png")


if __name__ == "__main__":
    sys.exit(main())
