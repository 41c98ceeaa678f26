"""``analysis`` sub-command: the paper's recognition analysis on any object set.

Experiments (``--experiments 1,2,...``; all by default):

1. one-shot accuracy of every classifier (+ the KDE's argmax) for n = 3, 4, 5 with/without normals;
2. IC, IC-full, BC-NP and BC-IP at ``lambda``: success rate and grasps (mean/std) for each n, with
   confusion matrices (PNG);
3. z-finger scoring (z = 3, 4; all subsets and k = 4 random ones) of n-finger grasps, and
   incomplete grasps (finger counts z ~ p_n(z), each scored by its z-finger model);
4. scaled objects (random scale in [0.1, 5]) with and without scale normalisation;
5. geometry recognition: train on boxes / elliptic cylinders / ellipsoids, classify held-out
   family members and the objects of ``--objects`` into the three families;
6. success rate vs number of grasps (threshold disregarded);
7. calibration: on fresh test grasps, the expected calibration error (ECE) of the one-shot posteriors
   of BC (softmax of the KDE log-likelihoods) and of the MLP, raw and temperature-scaled, with
   reliability diagrams; success at the stop and mean grasps vs lambda for IC, BC-NP and BC-IP, raw
   and calibrated (``--calib-fingers``, ``--calib-fingers-no-normals``, ``--lambdas``).

Experiments 2-7 score grasps with the calibration temperatures fitted on validation grasps
(:mod:`~haptic_env.recognizers.calibration`; ``--raw``: the paper's raw scores).

Protocol: models train on :func:`~haptic_env.dataset.build_dataset` data (seed ``--seed``); test
grasps are fresh samples from another seed (``seed + 7919``), never training data. A trial picks an
object uniformly, draws test grasps one at a time (without replacement from that object's test
pool) until the updater decides or ``--max-grasps``; success = the prediction at the stop is right.
Model scores of the test pools are computed once in batch; trials replay them through the real
updater classes (:meth:`BeliefUpdater.update_scores`).

Default settings finish in minutes on 2 cores; the paper's protocol is
``--grasps-per-object 200000 --trials 1000``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import softmax
from tqdm.auto import tqdm

from haptic_env.dataset import DatasetConfig, build_dataset, sample_grasps
from haptic_env.recognizers.baselines import CLASSIFIERS, make_classifier
from haptic_env.recognizers.calibration import _finite_rows, expected_calibration_error, reliability
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig
from haptic_env.recognizers.recognizer import RecognizerConfig, build_recognizer
from haptic_env.recognizers.updaters import make_updater

__all__ = ["AnalysisConfig", "run_analysis", "simulate_trials", "add_parser", "PAPER"]

TEST_SEED_OFFSET = 7919
KINDS = ("ic", "ic-full", "bc-np", "bc-ip")

#: Reference numbers quoted from Sintov & Ben-David (kit objects) for the tables.
PAPER = {
    "mlp_oneshot_n3_normals": 86.0,
    "bcnp_grasps_n4_normals": 3.37,
}


@dataclass(frozen=True)
class AnalysisConfig:
    """Settings of :func:`run_analysis` (the CLI flags)."""

    objects: str = "default"
    data_dir: str | None = None
    units: str = "m"
    experiments: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7)
    grasps_per_object: int = 10_000
    test_grasps: int = 400  #: fresh test grasps per object
    trials: int = 200
    max_grasps: int = 30
    threshold: float = 0.85
    fingers: tuple[int, ...] = (2, 3, 4, 5, 6, 7, 8, 9, 10)  #: experiment 2
    oneshot_fingers: tuple[int, ...] = (3, 4, 5)  #: experiment 1
    classifiers: tuple[str, ...] = CLASSIFIERS
    baseline_max_train: int | None = 5_000  #: cap on kernel/tree baselines' training rows (GP: /5)
    zfinger_hands: tuple[int, ...] = (5, 6, 8)  #: experiment 3: n of the hand
    incomplete_pn: tuple[tuple[int, float], ...] = ((3, 0.2), (4, 0.3), (5, 0.5))
    scale_range: tuple[float, float] = (0.1, 5.0)
    family_members: int = 10
    normals: bool = True  #: experiments 2-6
    calibrated: bool = True  #: experiments 2-6 use the validation-fitted temperatures (False: the paper's raw scores)
    calib_fingers: tuple[int, ...] = (3, 4, 5, 8)  #: experiment 7, with normals
    calib_fingers_no_normals: tuple[int, ...] = (4,)  #: experiment 7, without normals
    lambdas: tuple[float, ...] = (0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95)  #: experiment 7
    ece_bins: int = 10  #: experiment 7
    seed: int = 0
    mlp: MLPConfig = field(default_factory=lambda: MLPConfig(max_epochs=20, patience=3, max_train=100_000))
    kde: KDEConfig = field(default_factory=KDEConfig)
    progress: bool = True

    def recognizer_config(self, **kw) -> RecognizerConfig:
        grasps = DatasetConfig(grasps_per_object=self.grasps_per_object, seed=self.seed, **kw)
        return RecognizerConfig(grasps=grasps, mlp=dataclasses.replace(self.mlp, progress=False), kde=self.kde)


# ------------------------------------------------------------------------------------ trials
def simulate_trials(log_lik: list[np.ndarray], proba: list[np.ndarray], kind: str, *, trials: int, max_grasps: int,
                    threshold: float, rng: np.random.Generator, fixed_steps: bool = False) -> dict:
    """Replay precomputed scores of test pools through an updater.

    Args:
        log_lik, proba: per object ``o``, ``(G_o, K)`` scores of its test grasps (rows combined per grasp).
        fixed_steps: disregard the threshold and run ``max_grasps`` grasps (experiment 6).

    Returns:
        dict with ``success (T,) bool`` (prediction right at the stop), ``decided (T,) bool`` (certainty
        reached the threshold), ``grasps (T,) int``, ``truth``, ``pred`` and, when ``fixed_steps``,
        ``correct_at (T, max_grasps) bool`` (prediction right after m grasps).
    """
    n_obj = len(log_lik)
    K = (log_lik[0] if log_lik[0] is not None and len(log_lik[0]) else proba[0]).shape[1]  # classes
    u = make_updater(kind, classifier=_Dummy(K), likelihood=_Dummy(K), threshold=threshold)
    truth = rng.integers(0, n_obj, size=trials)  # object index (= class unless classes are families)
    pred = np.zeros(trials, dtype=np.int64)
    used = np.zeros(trials, dtype=np.int64)
    decided = np.zeros(trials, dtype=bool)
    correct_at = np.zeros((trials, max_grasps), dtype=bool) if fixed_steps else None
    for t, o in enumerate(truth):
        G = len(log_lik[o])
        rows = rng.permutation(G)[:max_grasps] if G >= max_grasps else rng.integers(0, G, size=max_grasps)
        u.reset()
        for m, i in enumerate(rows):
            u.update_scores(log_lik=log_lik[o][i : i + 1], proba=proba[o][i : i + 1])
            if fixed_steps:
                correct_at[t, m] = u.prediction == o
            elif u.decided:
                break
        pred[t] = u.prediction
        used[t] = u.n_grasps
        decided[t] = u.decided
    out = {"success": pred == truth, "decided": decided, "grasps": used, "truth": truth, "pred": pred}
    if fixed_steps:
        out["correct_at"] = correct_at
    return out


class _Dummy:
    def __init__(self, k):
        self.n_classes = k


def _summ(res: dict) -> tuple[float, float, float, float]:
    s = res["success"]
    T = len(s)
    p = float(s.mean())
    return 100 * p, 100 * np.sqrt(p * (1 - p) / max(T, 1)), float(res["grasps"].mean()), float(res["grasps"].std())


# -------------------------------------------------------------------------------------- data
def _test_pool(objects, n: int, normals: bool, cfg: AnalysisConfig, **dkw):
    """Fresh test grasp vectors: list over objects of ``(G, d)`` (another seed than training)."""

    dc = DatasetConfig(n_fingers=n, normals=normals, grasps_per_object=cfg.test_grasps, val_fraction=0.0,
                       seed=cfg.seed + TEST_SEED_OFFSET, **dkw)
    ds = build_dataset(objects, dc, progress=False)
    return [ds.X_train[ds.y_train == k].astype(np.float64) for k in range(len(objects))]


def _scores_label(cfg: AnalysisConfig) -> str:
    return "calibrated scores" if cfg.calibrated else "raw scores (paper)"


def _bank(rec, cfg: AnalysisConfig):
    """The recogniser's :class:`~haptic_env.recognizers.recognizer.ModelBank`, calibrated or raw per ``cfg.calibrated``."""
    return rec.models.with_calibration(cfg.calibrated)


def _scores(models, pool):
    """Per object ``(log_lik (G, K), proba (G, K))`` of a test pool."""
    LL = [models.log_likelihood(X) for X in pool]
    PR = [models.predict_proba(X) for X in pool]
    return LL, PR


def _confusion(truth, pred, K) -> np.ndarray:
    C = np.zeros((K, K))
    np.add.at(C, (truth, pred), 1)
    return C / np.maximum(C.sum(1, keepdims=True), 1)


# ------------------------------------------------------------------------------- experiments
class Report:
    def __init__(self, out: Path):
        self.out = out
        self.lines: list[str] = []

    def h(self, text):
        self.lines += ["", f"## {text}", ""]

    def p(self, text):
        self.lines += [text, ""]

    def table(self, header, rows):
        self.lines.append("| " + " | ".join(header) + " |")
        self.lines.append("|" + "|".join("---" for _ in header) + "|")
        for r in rows:
            self.lines.append("| " + " | ".join(str(c) for c in r) + " |")
        self.lines.append("")

    def write(self):
        (self.out / "results.md").write_text("\n".join(self.lines) + "\n")


def _fmt(m, s, digits=1):
    return f"{m:.{digits}f} ± {s:.{digits}f}"


def exp1(objects, cfg, rep, rng):

    rep.h("1. One-shot accuracy (%) on fresh test grasps")
    rows = []
    names = [c for c in cfg.classifiers] + ["kde"]
    for normals in (False, True):
        for n in cfg.oneshot_fingers:
            rc = cfg.recognizer_config()
            ds = build_dataset(objects, rc.dataset_config(n, normals), progress=False)
            pool = _test_pool(objects, n, normals, cfg)
            Xt = np.concatenate(pool)
            yt = np.concatenate([np.full(len(p), k) for k, p in enumerate(pool)])
            row = [n, "yes" if normals else "no"]
            for name in tqdm(names, desc=f"exp1 n={n} normals={normals}", disable=not cfg.progress, leave=False):
                t0 = time.perf_counter()
                if name == "kde":
                    m = KDELikelihood(cfg.kde).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val)
                    acc = np.mean(m.log_likelihood(Xt).argmax(1) == yt)
                elif name == "mlp":
                    m = MLPClassifier(dataclasses.replace(cfg.mlp, progress=False)).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val)
                    acc = m.score(Xt, yt)
                else:
                    cap = cfg.baseline_max_train
                    if cap is not None and name == "gp":
                        cap = max(200, cap // 5)
                    kw = {"max_train": cap, "seed": cfg.seed}
                    if name in ("knn", "random-forest", "decision-tree") and cfg.baseline_max_train is not None:
                        kw["max_train"] = cfg.baseline_max_train * 10
                    m = make_classifier(name, **kw).fit(ds.X_train, ds.y_train, n_classes=len(objects))
                    acc = m.score(Xt, yt)
                row.append(f"{100 * acc:.1f}")
            rows.append(row)
    rep.table(["n", "normals", *names], rows)
    rep.p(f"Test grasps: {cfg.test_grasps} per object (seed {cfg.seed + TEST_SEED_OFFSET}); binomial std of an "
          f"accuracy near 85% is about {100 * np.sqrt(0.85 * 0.15 / (cfg.test_grasps * len(objects))):.1f} points. "
          f"Baselines train on subsamples (GP {max(200, (cfg.baseline_max_train or 0) // 5)}, SVMs "
          f"{cfg.baseline_max_train}, kNN/trees {10 * (cfg.baseline_max_train or 0)} rows).")


def exp2(objects, cfg, rep, rng, plt):
    rep.h(f"2. Sequential recognition at lambda = {cfg.threshold} (normals: {cfg.normals}; {_scores_label(cfg)})")
    rows = []
    curves = {}
    K = len(objects)
    for n in tqdm(cfg.fingers, desc="exp2 fingers", disable=not cfg.progress):
        rec = build_recognizer(objects, n, cfg.normals, config=cfg.recognizer_config(), progress=False)
        LL, PR = _scores(_bank(rec, cfg), _test_pool(objects, n, cfg.normals, cfg))
        oneshot = np.mean(np.concatenate([p.argmax(1) == k for k, p in enumerate(PR)]))
        T = rec.models.temperature(n)
        row = [n, f"{100 * oneshot:.1f}", f"{T['kde']:.2f}", f"{T['classifier']:.2f}"]
        for kind in KINDS:
            res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps, threshold=cfg.threshold, rng=rng)
            sr, se, gm, gs = _summ(res)
            row += [f"{sr:.1f} ± {se:.1f}", _fmt(gm, gs, 2)]
            curves.setdefault(kind, []).append((n, sr, gm))
            if n == 4 and plt is not None:
                _plot_confusion(plt, _confusion(res["truth"], res["pred"], K), objects.names,
                                f"{kind}, n=4, lambda={cfg.threshold}", rep.out / f"confusion_n4_{kind}.png")
        rows.append(row)
    hdr = ["n", "MLP one-shot %", "T KDE", "T MLP"]
    for kind in KINDS:
        hdr += [f"{kind} success %", f"{kind} grasps"]
    rep.table(hdr, rows)
    rep.p(f"{cfg.trials} trials per cell, at most {cfg.max_grasps} grasps; success ± binomial std; grasps mean ± std. "
          "T: the calibration temperatures fitted on validation grasps (" +
          ("applied" if cfg.calibrated else "not applied: `--raw`") + "). Confusion matrices for n = 4: `confusion_n4_<kind>.png`.")
    if plt is not None and curves:
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        for kind, pts in curves.items():
            pts = np.array(pts)
            ax[0].plot(pts[:, 0], pts[:, 1], "o-", label=kind)
            ax[1].plot(pts[:, 0], pts[:, 2], "o-", label=kind)
        ax[0].set(xlabel="fingers n", ylabel="success %", title="success at lambda")
        ax[1].set(xlabel="fingers n", ylabel="grasps", title="mean grasps to decide")
        ax[0].legend()
        fig.tight_layout()
        fig.savefig(rep.out / "sequential_vs_fingers.png", dpi=110)
        plt.close(fig)


def _plot_confusion(plt, C, names, title, path):
    fig, ax = plt.subplots(figsize=(5.5, 5))
    ax.imshow(C, vmin=0, vmax=1, cmap="Blues")
    ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(names)), names, fontsize=7)
    for i in range(len(names)):
        for j in range(len(names)):
            if C[i, j] > 0.005:
                ax.text(j, i, f"{C[i, j]:.2f}", ha="center", va="center", fontsize=6, color="w" if C[i, j] > 0.5 else "k")
    ax.set(xlabel="predicted", ylabel="true", title=title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _raw_pool(objects, n, normals, count, seed):

    out = []
    for k, obj in enumerate(objects):
        C, N = sample_grasps(obj, count, n, np.random.default_rng([seed, k]))
        out.append((C, N if normals else None))
    return out


def _subset_scores(models, C, N, z, k_sub, rng):
    """Per grasp of ``C (G, n, 3)``: summed log-likelihoods and mean probabilities of its z-subsets.

    ``k_sub=None``: every subset; else ``k_sub`` distinct random subsets per grasp. Degenerate
    subsets are left out; grasps without any valid subset are dropped. Returns two ``(G', K)``.
    """
    from itertools import combinations

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
    from haptic_env.recognizers.zfinger import grasp_vectors_for

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


def exp3(objects, cfg, rep, rng):
    rep.h(f"3. z-finger scoring and incomplete grasps (lambda = {cfg.threshold}, normals: {cfg.normals}; {_scores_label(cfg)})")
    zs = (3, 4)
    rows = []
    recs = {z: build_recognizer(objects, z, cfg.normals, config=cfg.recognizer_config(), progress=False) for z in zs}
    for n in tqdm(cfg.zfinger_hands, desc="exp3 hands", disable=not cfg.progress):
        raw = _raw_pool(objects, n, cfg.normals, max(50, cfg.test_grasps // 2), cfg.seed + TEST_SEED_OFFSET + n)
        for z in zs:
            if z >= n:
                continue
            for k_sub in (None, 4):
                srng = np.random.default_rng([cfg.seed, n, z])
                LL, PR = [], []
                for C, N in raw:
                    ll, pr = _subset_scores(_bank(recs[z], cfg), C, N, z, k_sub, srng)
                    LL.append(ll)
                    PR.append(pr)
                row = [n, z, "all" if k_sub is None else f"k={k_sub}"]
                for kind in ("ic", "bc-np", "bc-ip"):
                    sr, se, gm, gs = _summ(simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps,
                                                           threshold=cfg.threshold, rng=rng))
                    row += [f"{sr:.1f} ± {se:.1f}", _fmt(gm, gs, 2)]
                rows.append(row)
    rep.table(["hand n", "z", "subsets", "IC success %", "IC grasps", "BC-NP success %", "BC-NP grasps",
               "BC-IP success %", "BC-IP grasps"], rows)
    rep.p("Per grasp, every (or k = 4 random) z-subset of the n contacts is mapped to Phi_z; BC multiplies the "
          "subsets' KDE likelihoods, IC sums their probability vectors (paper Algorithms 3, 4).")
    # incomplete grasps
    pn = dict(cfg.incomplete_pn)
    zlist = sorted(pn)
    recs_inc = {z: build_recognizer(objects, z, cfg.normals, config=cfg.recognizer_config(), progress=False) for z in zlist}
    pools = {z: _scores(_bank(recs_inc[z], cfg), _test_pool(objects, z, cfg.normals, cfg)) for z in zlist}
    p = np.array([pn[z] for z in zlist]) / sum(pn.values())
    rows = []
    for kind in ("ic", "bc-np", "bc-ip"):
        K = len(objects)
        u = make_updater(kind, classifier=_Dummy(K), likelihood=_Dummy(K), threshold=cfg.threshold)
        succ, used = [], []
        for _t in range(cfg.trials):
            o = int(rng.integers(K))
            u.reset()
            for _g in range(cfg.max_grasps):
                z = zlist[rng.choice(len(zlist), p=p)]
                LL, PR = pools[z]
                i = int(rng.integers(len(LL[o])))
                u.update_scores(log_lik=LL[o][i : i + 1], proba=PR[o][i : i + 1])
                if u.decided:
                    break
            succ.append(u.prediction == o)
            used.append(u.n_grasps)
        sr = 100 * np.mean(succ)
        rows.append([kind, f"{sr:.1f} ± {100 * np.sqrt(np.mean(succ) * (1 - np.mean(succ)) / len(succ)):.1f}",
                     _fmt(np.mean(used), np.std(used), 2)])
    rep.p(f"Incomplete grasps: finger count z ~ p_n(z) = {pn} per grasp, each scored by its z-finger model.")
    rep.table(["updater", "success %", "grasps"], rows)


def exp4(objects, cfg, rep, rng):
    rep.h(f"4. Scaled objects (scale ~ U{cfg.scale_range} per grasp, n = 4, normals: {cfg.normals}; {_scores_label(cfg)})")
    rows = []
    for norm in (False, True):
        kw = {"scale_range": cfg.scale_range, "normalize_scale": norm}
        rec = build_recognizer(objects, 4, cfg.normals, config=cfg.recognizer_config(**kw), progress=False)
        LL, PR = _scores(_bank(rec, cfg), _test_pool(objects, 4, cfg.normals, cfg, **kw))
        oneshot = np.mean(np.concatenate([p.argmax(1) == k for k, p in enumerate(PR)]))
        row = ["yes" if norm else "no", f"{100 * oneshot:.1f}"]
        for kind in ("ic", "bc-np", "bc-ip"):
            sr, se, gm, gs = _summ(simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps,
                                                   threshold=cfg.threshold, rng=rng))
            row += [f"{sr:.1f} ± {se:.1f}", _fmt(gm, gs, 2)]
        rows.append(row)
    rep.table(["scale normalisation", "MLP one-shot %", "IC success %", "IC grasps", "BC-NP success %", "BC-NP grasps",
               "BC-IP success %", "BC-IP grasps"], rows)


#: The family a person would expect for the objects of ``default``, ``ycb10`` and ``kit20`` (None: no clear
#: family; such objects are listed in experiment 5 but left out of its score).
EXPECTED_FAMILY = {
    # default set
    "box": "box", "can": "elliptic_cylinder", "apple": "ellipsoid", "bottle": "elliptic_cylinder",
    "mug": "elliptic_cylinder", "cone": None, "ring": None, "hammer": None, "ball": "ellipsoid",
    # ycb10
    "001_chips_can": "elliptic_cylinder", "002_master_chef_can": "elliptic_cylinder", "006_mustard_bottle": None,
    "013_apple": "ellipsoid", "021_bleach_cleanser": None, "025_mug": "elliptic_cylinder", "029_plate": None,
    "035_power_drill": None, "036_wood_block": "box", "048_hammer": None,
    # kit20
    "Deodorant": "elliptic_cylinder", "GreenCup": "elliptic_cylinder", "HeringTin": "box",
    "HygieneSpray": "elliptic_cylinder", "WhiteCup": "elliptic_cylinder", "cube": "box",
}
#: Trials per object of experiment 5's object table (the paper's GraspNet-style table).
FAMILY_OBJECT_TRIALS = 10
#: Seed offset of the validation family members that experiment 5's calibration temperatures are fitted on
#: (the test members use ``TEST_SEED_OFFSET``).
FAMILY_VAL_SEED_OFFSET = 1000


def _family_trials(LL, PR, kind, *, trials, max_grasps, threshold, rng):
    """``trials`` runs of ``kind`` on ONE object's test pool (``LL``/``PR``: ``(G, 3)``): the family votes
    ``(3,)`` (prediction at the stop), how many decided, and the grasps used ``(trials,)``."""
    u = make_updater(kind, classifier=_Dummy(LL.shape[1]), likelihood=_Dummy(LL.shape[1]), threshold=threshold)
    votes, decided, used = np.zeros(LL.shape[1], dtype=np.int64), 0, []
    for _ in range(trials):
        u.reset()
        for m, i in enumerate(rng.permutation(len(LL))[:max_grasps]):
            u.update_scores(log_lik=LL[i : i + 1], proba=PR[i : i + 1])
            if u.decided:
                break
        votes[u.prediction] += 1
        decided += bool(u.decided)
        used.append(m + 1)
    return votes, decided, np.array(used)


def family_temperatures(kde, clf, X, fam) -> tuple[float, float]:
    """Calibration temperatures ``(T_kde, T_mlp)`` of family models, fitted on grasps ``X`` of NEW validation
    members with families ``fam`` (the models' own temperatures are fitted on held-back grasps of the training
    members, which overstates how well a family model knows an unseen member)."""
    from haptic_env.recognizers.calibration import fit_temperature

    T_kde = fit_temperature(_finite_rows(kde.log_likelihood(X)), fam)
    T_mlp = fit_temperature(np.log(np.maximum(clf.predict_proba(X), 1e-300)), fam)
    return float(T_kde), float(T_mlp)


def exp5(objects, cfg, rep, rng):
    from haptic_env.objects import FAMILIES, family_set

    rep.h("5. Geometry recognition (families: " + ", ".join(FAMILIES) + f"; n = 4, normals: {cfg.normals}, "
          f"scale-normalised; {_scores_label(cfg)})")
    train_set = family_set(cfg.family_members, np.random.default_rng(cfg.seed))
    n_held = max(2, cfg.family_members // 3)
    val_set = family_set(n_held, np.random.default_rng(cfg.seed + FAMILY_VAL_SEED_OFFSET))
    test_set = family_set(n_held, np.random.default_rng(cfg.seed + TEST_SEED_OFFSET))
    fam_idx = {f: i for i, f in enumerate(FAMILIES)}
    per_obj = max(1000, cfg.grasps_per_object * len(objects) // max(len(train_set), 1))
    dc = DatasetConfig(n_fingers=4, normals=cfg.normals, grasps_per_object=per_obj, normalize_scale=True, seed=cfg.seed)
    ds = build_dataset(train_set, dc, progress=False)
    fam_of = np.array([fam_idx[train_set.families[nm]] for nm in train_set.names])
    clf = MLPClassifier(dataclasses.replace(cfg.mlp, progress=False)).fit(ds.X_train, fam_of[ds.y_train], ds.X_val,
                                                                          fam_of[ds.y_val], n_classes=len(FAMILIES))
    kde = KDELikelihood(cfg.kde).fit(ds.X_train, fam_of[ds.y_train], ds.X_val, fam_of[ds.y_val], n_classes=len(FAMILIES))
    # temperatures on new validation members (another seed than training and test)
    vds = build_dataset(val_set, DatasetConfig(n_fingers=4, normals=cfg.normals, grasps_per_object=cfg.test_grasps,
                                               normalize_scale=True, val_fraction=0.0,
                                               seed=cfg.seed + FAMILY_VAL_SEED_OFFSET), progress=False)
    fam_val = np.array([fam_idx[val_set.families[nm]] for nm in val_set.names])
    T_kde, T_mlp = family_temperatures(kde, clf, vds.X_train.astype(np.float64), fam_val[vds.y_train]) \
        if cfg.calibrated else (1.0, 1.0)

    def pool_scores(objs):
        pool = _test_pool(objs, 4, cfg.normals, cfg, normalize_scale=True)
        LL = [kde.log_likelihood(X) / T_kde for X in pool]
        PR = [softmax(np.log(np.maximum(clf.predict_proba(X), 1e-300)) / T_mlp, axis=1) for X in pool]
        return LL, PR

    LL, PR = pool_scores(test_set)
    fam_test = np.array([fam_idx[test_set.families[nm]] for nm in test_set.names])
    rows = []
    for kind in ("ic", "bc-np"):
        res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps, threshold=cfg.threshold, rng=rng)
        ok = fam_test[res["truth"]] == res["pred"]
        rows.append([kind, f"{100 * ok.mean():.1f}", f"{100 * res['decided'].mean():.1f}",
                     _fmt(res["grasps"].mean(), res["grasps"].std(), 2)])
    one = np.mean(np.concatenate([p.argmax(1) == fam_test[k] for k, p in enumerate(PR)]))
    one_kde = np.mean(np.concatenate([L.argmax(1) == fam_test[k] for k, L in enumerate(LL)]))
    rep.p(f"Held-out family members ({len(test_set)} new random boxes/cylinders/ellipsoids, test seed); one-shot "
          f"family accuracy MLP {100 * one:.1f} %, KDE argmax {100 * one_kde:.1f} % (chance 33.3 %). Temperatures "
          f"fitted on {len(val_set)} validation members: KDE {T_kde:.2f}, MLP {T_mlp:.2f}. {cfg.trials} trials, "
          f"lambda = {cfg.threshold}, at most {cfg.max_grasps} grasps; success = family right at the stop.")
    rep.table(["updater", "family success %", "decided %", "grasps"], rows)
    LL, PR = pool_scores(objects)
    ntr = FAMILY_OBJECT_TRIALS
    short = {"box": "box", "elliptic_cylinder": "cyl", "ellipsoid": "ell"}
    rows, hits, labelled, ic_dec, ic_all = [], 0, 0, 0, 0
    for k, nm in enumerate(objects.names):
        out = {}
        for kind in ("ic", "bc-np"):
            out[kind] = _family_trials(LL[k], PR[k], kind, trials=ntr, max_grasps=cfg.max_grasps,
                                       threshold=cfg.threshold, rng=rng)
        ic_dec += out["ic"][1]
        ic_all += ntr
        exp = EXPECTED_FAMILY.get(nm)
        vote = FAMILIES[int(np.argmax(out["bc-np"][0]))]
        if exp is not None:
            labelled += 1
            hits += vote == exp
        rows.append([nm, short.get(exp, "-") if exp else "(none)",
                     " / ".join(str(v) for v in out["ic"][0]), f"{out['ic'][1]}/{ntr}",
                     " / ".join(str(v) for v in out["bc-np"][0]), f"{out['bc-np'][1]}/{ntr}",
                     f"{out['bc-np'][2].mean():.1f}", short[vote],
                     "-" if exp is None else ("yes" if vote == exp else "no")])
    rep.p(f"Objects of '{cfg.objects}' classified into families ({ntr} trials per object; votes = predictions at "
          f"the stop, box / cyl / ell; expected = the family a person would expect, '(none)': no clear family, not "
          f"scored). BC-NP's majority vote is the expected family for {hits}/{labelled} labelled objects; IC decided "
          f"within {cfg.max_grasps} grasps in {ic_dec}/{ic_all} trials.")
    rep.table(["object", "expected", "IC votes", "IC decided", "BC-NP votes", "BC-NP decided", "BC-NP grasps",
               "BC-NP vote", "match"], rows)


def exp6(objects, cfg, rep, rng, plt):
    rep.h(f"6. Success rate vs number of grasps (threshold disregarded; n = 4, normals: {cfg.normals}; {_scores_label(cfg)})")
    rec = build_recognizer(objects, 4, cfg.normals, config=cfg.recognizer_config(), progress=False)
    LL, PR = _scores(_bank(rec, cfg), _test_pool(objects, 4, cfg.normals, cfg))
    M = min(cfg.max_grasps, 15)
    curves = {}
    for kind in KINDS:
        res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=M, threshold=cfg.threshold, rng=rng, fixed_steps=True)
        curves[kind] = 100 * res["correct_at"].mean(0)
    rep.table(["grasps", *KINDS], [[m + 1, *[f"{curves[k][m]:.1f}" for k in KINDS]] for m in range(M)])
    if plt is not None:
        fig, ax = plt.subplots(figsize=(6, 4))
        for kind, c in curves.items():
            ax.plot(np.arange(1, M + 1), c, "o-", label=kind)
        ax.set(xlabel="grasps", ylabel="success %", title="success vs grasps (n = 4)", ylim=(0, 100))
        ax.legend()
        fig.tight_layout()
        fig.savefig(rep.out / "success_vs_grasps.png", dpi=110)
        plt.close(fig)


# ------------------------------------------------------------------------------- calibration
CALIB_KINDS = ("ic", "bc-np", "bc-ip")


def oneshot_posterior(scores) -> np.ndarray:
    """Row-wise softmax of class scores ``(B, K)`` (BC's one-shot posterior under a uniform prior when the
    scores are KDE log-likelihoods). ``-inf`` allowed; a row with no finite score is uniform (the updater
    leaves its belief unchanged)."""
    return softmax(_finite_rows(np.asarray(scores, dtype=np.float64)), axis=1)


def calibration_summary(proba, y, bins: int = 10) -> dict[str, float]:
    """Accuracy, ECE (``bins`` equal-width bins), NLL of the true class and mean confidence of ``proba (B, K)``."""
    P = np.asarray(proba, dtype=np.float64)
    y = np.asarray(y, dtype=np.int64)
    return {"accuracy": float(np.mean(P.argmax(1) == y)), "ece": expected_calibration_error(P, y, bins),
            "nll": float(-np.log(np.maximum(P[np.arange(len(y)), y], 1e-300)).mean()),
            "confidence": float(P.max(1).mean())}


def _cell_name(n: int, normals: bool) -> str:
    return f"n{n}_{'normals' if normals else 'no_normals'}"


def _plot_reliability(plt, curves: dict, bins: int, title: str, path: Path) -> None:
    """``curves[model][variant] = (proba, y, T)``: one panel per model, raw and calibrated on it."""
    fig, axes = plt.subplots(1, len(curves), figsize=(5 * len(curves), 4.3), squeeze=False)
    for ax, (model, variants) in zip(axes[0], curves.items()):
        ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls=":", label="perfect calibration")
        for (variant, (P, y, T)), style in zip(variants.items(), ("s--", "o-")):
            r = reliability(P, y, bins)
            ok = r["count"] > 0
            ece = expected_calibration_error(P, y, bins)
            lab = f"{variant} (T = {T:.2f}): ECE {ece:.3f}" if variant != "raw" else f"raw: ECE {ece:.3f}"
            ax.plot(r["confidence"][ok], r["accuracy"][ok], style, label=lab)
            centres = 0.5 * (r["edges"][1:] + r["edges"][:-1])
            ax.bar(centres, r["count"] / r["count"].sum(), width=1.0 / bins, alpha=0.12,
                   color=ax.lines[-1].get_color(), zorder=0)
        ax.set(xlim=(0, 1), ylim=(0, 1), xlabel="confidence (max posterior)", ylabel="accuracy",
               title=f"{model} one-shot, {title}")
        ax.legend(fontsize=8, loc="upper left")
    fig.text(0.99, 0.01, "bars: fraction of test grasps per confidence bin", ha="right", fontsize=7, color="0.4")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_lambda_sweep(plt, sweep: dict, lambdas, title: str, path: Path) -> None:
    """``sweep[(kind, variant)] = list over lambdas of (decided & correct %, grasps)``."""
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.3))
    lam = np.asarray(lambdas)
    ax[0].plot([lam.min(), 1.0], [100 * lam.min(), 100.0], color="0.5", ls=":", label="success = lambda")
    colors = {}
    for (kind, variant), pts in sweep.items():
        pts = np.asarray(pts)
        style = "o-" if variant == "calibrated" else "s--"
        kw = {"color": colors[kind]} if kind in colors else {}
        (line,) = ax[0].plot(lam, pts[:, 0], style, label=f"{kind} {variant}", **kw)
        colors.setdefault(kind, line.get_color())
        ax[1].plot(lam, pts[:, 1], style, color=colors[kind], label=f"{kind} {variant}")
    ax[0].set(xlabel="lambda (decision threshold)", ylabel="success at the stop % (decided and correct)",
              title=f"success vs lambda, {title}")
    ax[1].set(xlabel="lambda (decision threshold)", ylabel="mean grasps", yscale="log", title=f"grasps vs lambda, {title}")
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def exp7(objects, cfg, rep, rng, plt):
    """Calibration shown on fresh test grasps: one-shot ECE raw vs calibrated, reliability diagrams, and
    success at the stop vs lambda for IC / BC-NP / BC-IP with and without the temperatures."""
    rep.h("7. Calibration of the posteriors on fresh test grasps (raw vs temperature-scaled)")
    cells = [(n, True) for n in cfg.calib_fingers] + [(n, False) for n in cfg.calib_fingers_no_normals]
    ece_rows, stop_rows, sweeps = [], [], {}
    for n, normals in tqdm(cells, desc="exp7 cells", disable=not cfg.progress):
        rec = build_recognizer(objects, n, normals, config=cfg.recognizer_config(), progress=False)
        T = rec.models.temperature(n)
        pool = _test_pool(objects, n, normals, cfg)
        y = np.concatenate([np.full(len(p), k) for k, p in enumerate(pool)])
        scores = {v: _scores(rec.models.with_calibration(v == "calibrated"), pool) for v in ("raw", "calibrated")}
        curves = {}
        for model, Tm in (("BC (KDE)", T["kde"]), ("MLP", T["classifier"])):
            row = [n, "yes" if normals else "no", model, f"{Tm:.2f}"]
            for v in ("raw", "calibrated"):
                LL, PR = scores[v]
                P = oneshot_posterior(np.concatenate(LL)) if model.startswith("BC") else np.concatenate(PR)
                s = calibration_summary(P, y, cfg.ece_bins)
                if v == "raw":
                    row.append(f"{100 * s['accuracy']:.1f}")
                row += [f"{s['ece']:.3f}", f"{s['nll']:.3f}", f"{100 * s['confidence']:.1f}"]
                curves.setdefault(model, {})[v] = (P, y, Tm)
            ece_rows.append(row)
        title = f"n = {n}, {'with' if normals else 'without'} normals"
        if plt is not None:
            _plot_reliability(plt, curves, cfg.ece_bins, title, rep.out / f"reliability_{_cell_name(n, normals)}.png")
        sweep = {}
        for kind in CALIB_KINDS:
            for v in ("raw", "calibrated"):
                LL, PR = scores[v]
                pts = []
                for lam in cfg.lambdas:
                    # one trial rng per cell: every updater, lambda and raw/calibrated sees the same objects and
                    # grasp sequences (paired comparisons, smooth curves)
                    trng = np.random.default_rng([cfg.seed, n, int(normals)])
                    res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps, threshold=lam,
                                          rng=trng)
                    dc = res["success"] & res["decided"]
                    pts.append((100 * dc.mean(), float(res["grasps"].mean()), 100 * res["success"].mean(),
                                float(res["grasps"].std())))
                sweep[(kind, v)] = pts
        sweeps[(n, normals)] = sweep
        if plt is not None:
            _plot_lambda_sweep(plt, {k: [p[:2] for p in v] for k, v in sweep.items()}, cfg.lambdas, title,
                               rep.out / f"lambda_sweep_{_cell_name(n, normals)}.png")
        li = int(np.argmin(np.abs(np.asarray(cfg.lambdas) - cfg.threshold)))
        for kind in CALIB_KINDS:
            r, c = sweep[(kind, "raw")][li], sweep[(kind, "calibrated")][li]
            stop_rows.append([n, "yes" if normals else "no", kind, f"{r[2]:.1f}", f"{r[0]:.1f}", _fmt(r[1], r[3], 2),
                              f"{c[2]:.1f}", f"{c[0]:.1f}", _fmt(c[1], c[3], 2)])
    rep.p(f"Test grasps: {cfg.test_grasps} fresh grasps per object (seed {cfg.seed + TEST_SEED_OFFSET}), never used to "
          f"fit T (T is fitted on the training data's validation split). One-shot posterior: BC = softmax of the KDE "
          f"log-likelihoods (/ T), MLP = softmax(logits / T). ECE over {cfg.ece_bins} equal-width confidence bins; NLL "
          "of the true class; conf = mean max posterior. Accuracy does not depend on T. Reliability diagrams: "
          "`reliability_<cell>.png`.")
    rep.table(["n", "normals", "model", "T", "accuracy %", "ECE raw", "NLL raw", "conf raw %", "ECE cal", "NLL cal",
               "conf cal %"], ece_rows)
    lam0 = cfg.lambdas[int(np.argmin(np.abs(np.asarray(cfg.lambdas) - cfg.threshold)))]
    rep.p(f"Sequential recognition at lambda = {lam0}: success = correct at the stop; d&c = decided (certainty "
          f">= lambda within {cfg.max_grasps} grasps) and correct; grasps mean ± std. {cfg.trials} trials per cell, "
          "the same objects and grasp sequences for every updater, lambda, raw and calibrated (paired).")
    rep.table(["n", "normals", "updater", "raw success %", "raw d&c %", "raw grasps", "cal success %", "cal d&c %",
               "cal grasps"], stop_rows)
    rep.p("Success at the stop (decided and correct, %) / mean grasps vs lambda; plots `lambda_sweep_<cell>.png` "
          "(solid: calibrated, dashed: raw, dotted: success = lambda).")
    hdr = ["n", "normals", "updater", "scores", *[f"λ={lam:g}" for lam in cfg.lambdas]]
    rows = []
    for (n, normals), sweep in sweeps.items():
        for (kind, v), pts in sweep.items():
            rows.append([n, "yes" if normals else "no", kind, v, *[f"{p[0]:.1f} / {p[1]:.2f}" for p in pts]])
    rep.table(hdr, rows)


def run_analysis(cfg: AnalysisConfig, out: str | Path, command: str | None = None) -> Path:
    """Run the selected experiments; write ``out/results.md`` and PNG plots. Returns the report path.

    ``command``: the command line that ran it, written at the top of the report."""
    from haptic_env.objects import load_object_set

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover
        plt = None
    objects = load_object_set(cfg.objects, data_dir=cfg.data_dir, units=cfg.units)
    rep = Report(out)
    rep.lines = [f"# Recognition analysis: `{cfg.objects}` ({len(objects)} objects: {', '.join(objects.names)})", ""]
    if command:
        rep.lines += ["```", command, "```", ""]
    rep.lines += [f"{_scores_label(cfg)} in experiments 2-6; seed {cfg.seed}; {cfg.grasps_per_object} training grasps "
                  f"per object; {cfg.test_grasps} fresh test grasps per object; {cfg.trials} trials; max {cfg.max_grasps} "
                  f"grasps; MLP {cfg.mlp.depth}x{cfg.mlp.width}; "
                  f"KDE {cfg.kde.method} (k={cfg.kde.k}, cutoff {cfg.kde.cutoff} h, factor {cfg.kde.factor})."]
    rng = np.random.default_rng(cfg.seed)
    steps = {1: lambda: exp1(objects, cfg, rep, rng), 2: lambda: exp2(objects, cfg, rep, rng, plt),
             3: lambda: exp3(objects, cfg, rep, rng), 4: lambda: exp4(objects, cfg, rep, rng),
             5: lambda: exp5(objects, cfg, rep, rng), 6: lambda: exp6(objects, cfg, rep, rng, plt),
             7: lambda: exp7(objects, cfg, rep, rng, plt)}
    for e in cfg.experiments:
        if e not in steps:
            raise ValueError(f"unknown experiment {e}; choose from {sorted(steps)}")
        t0 = time.perf_counter()
        steps[e]()
        rep.p(f"_experiment {e}: {time.perf_counter() - t0:.0f} s_")
        rep.write()
    rep.write()
    return out / "results.md"


# ---------------------------------------------------------------------------------------- CLI
def _ints(text: str) -> tuple[int, ...]:
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out += list(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return tuple(out)


def _lambdas(text: str) -> tuple[float, ...]:
    from haptic_env.cli import UsageError

    try:
        out = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise UsageError(f"--lambdas: expected comma-separated numbers, got {text!r}") from None
    if not out or any(not 0 < x <= 1 for x in out):
        raise UsageError(f"--lambdas: thresholds must be in (0, 1], got {text!r}")
    return out


def _equivalent_command(args) -> str:
    """The ``haptic-recog analysis`` command line with every setting spelled out (defaults included)."""
    import shlex

    parser = getattr(args, "_cli_parser", None)
    if parser is None:
        return ""
    words = ["haptic-recog", "analysis"]
    for action in parser._actions:
        if not action.option_strings or action.dest == "help":
            continue
        v = getattr(args, action.dest, None)
        flag = action.option_strings[-1]
        if isinstance(action, argparse._StoreTrueAction):
            words += [flag] if v else []
        elif v is not None:
            words += [flag, str(v)]
    return shlex.join(words)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``analysis`` sub-command."""
    d = AnalysisConfig()
    p = subparsers.add_parser("analysis", help="reproduce the paper's recognition analysis on an object set",
                              description=__doc__.splitlines()[0])
    p.add_argument("--objects", default=d.objects, help="default | families[:N] | kit8 | kit20 | ycb10 | folder")
    p.add_argument("--data-dir", default=None, help="shared data folder (default: $HAPTIC_DATA or ../shared/data)")
    p.add_argument("--units", default="m", help="units of a folder's meshes")
    p.add_argument("--out", required=True, help="output folder for results.md and PNG plots")
    p.add_argument("--experiments", default="1,2,3,4,5,6,7", help="comma list / ranges of 1..7 (default all)")
    p.add_argument("--grasps-per-object", type=int, default=d.grasps_per_object, help="training grasps per object (paper: 200000)")
    p.add_argument("--test-grasps", type=int, default=d.test_grasps, help="fresh test grasps per object")
    p.add_argument("--trials", type=int, default=d.trials, help="trials per cell (paper: 1000)")
    p.add_argument("--max-grasps", type=int, default=d.max_grasps)
    p.add_argument("--threshold", type=float, default=d.threshold, help="lambda_s")
    p.add_argument("--fingers", default="2-10", help="finger counts of experiment 2 (e.g. 2-10 or 3,4,5)")
    p.add_argument("--oneshot-fingers", default="3,4,5", help="finger counts of experiment 1")
    p.add_argument("--classifiers", default=",".join(d.classifiers), help="experiment 1 classifiers")
    p.add_argument("--baseline-max-train", type=int, default=d.baseline_max_train)
    p.add_argument("--zfinger-hands", default="5,6,8", help="experiment 3 hand sizes n")
    p.add_argument("--no-normals", action="store_true", help="experiments 2-6 without normals")
    p.add_argument("--raw", action="store_true",
                   help="experiments 2-6 on the raw scores (the paper's method), without the calibration temperatures")
    p.add_argument("--calib-fingers", default=",".join(map(str, d.calib_fingers)),
                   help="experiment 7: finger counts with normals")
    p.add_argument("--calib-fingers-no-normals", default=",".join(map(str, d.calib_fingers_no_normals)),
                   help="experiment 7: finger counts without normals (empty: none)")
    p.add_argument("--lambdas", default=",".join(f"{x:g}" for x in d.lambdas), help="experiment 7: thresholds swept")
    p.add_argument("--mlp-depth", type=int, default=d.mlp.depth)
    p.add_argument("--mlp-width", type=int, default=d.mlp.width)
    p.add_argument("--mlp-epochs", type=int, default=d.mlp.max_epochs)
    p.add_argument("--mlp-max-train", type=int, default=d.mlp.max_train)
    p.add_argument("--kde-method", default=d.kde.method, choices=("tree", "pooled", "dense", "subsample"))
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_run_cli)
    return p


def _run_cli(args) -> int:
    cfg = AnalysisConfig(
        objects=args.objects, data_dir=args.data_dir, units=args.units, experiments=_ints(args.experiments),
        grasps_per_object=args.grasps_per_object, test_grasps=args.test_grasps, trials=args.trials,
        max_grasps=args.max_grasps, threshold=args.threshold, fingers=_ints(args.fingers),
        oneshot_fingers=_ints(args.oneshot_fingers),
        classifiers=tuple(c for c in args.classifiers.split(",") if c), baseline_max_train=args.baseline_max_train,
        zfinger_hands=_ints(args.zfinger_hands), normals=not args.no_normals, calibrated=not args.raw,
        calib_fingers=_ints(args.calib_fingers), calib_fingers_no_normals=_ints(args.calib_fingers_no_normals),
        lambdas=_lambdas(args.lambdas), seed=args.seed,
        mlp=MLPConfig(depth=args.mlp_depth, width=args.mlp_width, max_epochs=args.mlp_epochs, patience=3,
                      max_train=args.mlp_max_train, seed=args.seed),
        kde=KDEConfig(method=args.kde_method, seed=args.seed), progress=not args.quiet,
    )
    for c in cfg.classifiers:
        if c not in CLASSIFIERS:
            raise SystemExit(f"unknown classifier {c!r}; choose from {CLASSIFIERS}")
    path = run_analysis(cfg, args.out, command=_equivalent_command(args))
    print(path.read_text())
    print(f"wrote {path}")
    return 0
