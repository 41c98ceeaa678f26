"""Geometry families (issue 6, item 4): why 4-finger grasps without normals barely tell the families apart.

Trains on ``family_set`` members (boxes, elliptic cylinders, ellipsoids) and measures, on VALIDATION data
only (held-back grasps of the training members and new members drawn from a validation seed):

* one-shot family accuracy of the KDE (one KDE per family), the MLP and a random forest;
* the family vote after m grasps of one object (BC-NP: summed KDE log-likelihoods; "member" BC-NP: a
  posterior over the training *members*, summed per family, so all grasps of an object must come from
  ONE member shape -- the aspect ratio is shared between grasps instead of re-drawn per grasp);

for a sweep of generator aspect spreads (per-axis scale range), with/without scale normalisation and
with/without normals.

Run (one process, nice)::

    OMP_NUM_THREADS=1 nice -n 10 python benchmarks/geometry_families.py --sweep spread
    OMP_NUM_THREADS=1 nice -n 10 python benchmarks/geometry_families.py --sweep norm
    OMP_NUM_THREADS=1 nice -n 10 python benchmarks/geometry_families.py --sweep sizes --source hand [--size-range 0.7,1.6]
    OMP_NUM_THREADS=1 nice -n 10 python benchmarks/geometry_families.py --sweep members --source hand --members 20 \
        --grasps 1000 --size-range 0.7,1.6 [--heights] [--lying]

``--heights`` and ``--lying`` are experiment 5's ``--family-heights`` (each contact's height above the table) and
``--family-lying`` (every second cylinder member on its side).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np
from scipy.special import logsumexp

from haptic_env.cli import float_in, int_in
from haptic_env.dataset import DatasetConfig
from haptic_env.experiments.config import FAMILY_SOURCES, AnalysisConfig
from haptic_env.experiments.families import family_vectors, grasp_config, member_grasps
from haptic_env.objects import FAMILIES, family_set
from haptic_env.recognizers.baselines import make_classifier
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig
from haptic_env.splits import FAMILY_VAL_SEED_OFFSET

VAL_MEMBER_SEED = FAMILY_VAL_SEED_OFFSET  # new members for validation (experiment 5's; its test members: + 7919)


def fam_labels(objs) -> np.ndarray:
    idx = {f: i for i, f in enumerate(FAMILIES)}
    return np.array([idx[objs.families[n]] for n in objs.names])


def grasps(cfg: AnalysisConfig, G: int, seed: int, normals: bool, normalize: bool, **kw) -> DatasetConfig:
    """Experiment 5's grasps (:func:`~haptic_env.experiments.families.grasp_config`) with this benchmark's sweeps over
    normals and scale normalisation (which experiment 5 fixes)."""
    return dataclasses.replace(grasp_config(cfg, G, seed, **kw), normals=normals, normalize_scale=normalize)


def member_dataset(objs, dc: DatasetConfig, cfg: AnalysisConfig):
    """The training members' grasps as experiment 5 takes them (:func:`~haptic_env.experiments.families.member_grasps`):
    with a hand source a member the hand never grasps with 4 fingers is left out and named, and a family left without
    members is an error."""
    ds, left_out = member_grasps(objs, dc, cfg, "training")
    if left_out:
        print(f"left out (never grasped with 4 fingers): {sorted(left_out)}", file=sys.stderr)
    return ds


def pool(objs, G, normals, normalize, seed, cfg: AnalysisConfig):
    """Per-object grasp vectors (float64) from ``cfg``'s family source
    (:func:`~haptic_env.experiments.families.family_vectors`); with a hand source an object it never grasps with 4
    fingers has 0 rows."""
    return family_vectors(objs, grasps(cfg, G, seed, normals, normalize, val_fraction=0.0), cfg)


def family_config(source: str, lo=0.5, hi=1.5, size_range=None, heights=False, lying=False) -> AnalysisConfig:
    """Experiment 5's settings of the family grasps (source, members' ranges and poses, heights): the one place that
    turns them into DatasetConfig fields is ``AnalysisConfig.family_grasps``."""
    return AnalysisConfig(family_source=source, family_scale_range=(lo, hi), family_size_range=size_range,
                          family_heights=heights, family_lying=lying)


def member_family_ll(LLm, fam_m, T=1.0):
    """(m, M) member log-likelihoods of m grasps of ONE object -> (3,) family log-likelihood of the
    whole sequence under "the object is one member of the family" (uniform over members)."""
    s = LLm.sum(0) / T
    return np.array([logsumexp(s[fam_m == f]) - np.log((fam_m == f).sum()) for f in range(len(FAMILIES))])


def votes(score_fn, P, fam_true, ms, trials, rng):
    """Accuracy of the family argmax after m grasps, for m in ms; P: per object pools."""
    out = {}
    for m in ms:
        ok = []
        for _ in range(trials):
            o = rng.integers(len(P))
            rows = rng.choice(len(P[o]), size=m, replace=len(P[o]) < m)  # a hand may grasp a member rarely
            ok.append(np.argmax(score_fn(o, rows)) == fam_true[o])
        out[m] = 100 * np.mean(ok)
    return out


def run_cell(lo, hi, normals, normalize, members, G, seed, ms, trials, models, source="surface", size_range=None,
             heights=False, lying=False):
    t0 = time.time()
    cfg = family_config(source, lo, hi, size_range, heights, lying)
    tr = family_set(members, np.random.default_rng(seed), scale_range=(lo, hi), size_range=size_range, lying=lying)
    va = family_set(max(3, members // 2), np.random.default_rng(seed + VAL_MEMBER_SEED), scale_range=(lo, hi),
                    size_range=size_range, lying=lying)
    ds = member_dataset(tr, grasps(cfg, G, seed, normals, normalize), cfg)
    fm = fam_labels(tr)
    ytr, yva = fm[ds.y_train], fm[ds.y_val]
    new = pool(va, max(200, G // 5), normals, normalize, seed + VAL_MEMBER_SEED, cfg)  # new members
    kept = [k for k, X in enumerate(new) if len(X)]  # a hand may never grasp a small member with 4 fingers
    new, fnew = [new[k] for k in kept], fam_labels(va)[kept]
    rng = np.random.default_rng(seed + 1)
    row = {"spread": f"{lo:g}-{hi:g}", "normals": normals, "norm": normalize, "source": source}
    if heights:
        row["heights"] = True
    if lying:
        row["lying"] = True
    if size_range is not None:
        row["size_range"] = f"{size_range[0]:g}-{size_range[1]:g}"
    kde = KDELikelihood(KDEConfig()).fit(ds.X_train, ytr, ds.X_val, yva, n_classes=3)
    row["kde_1_held"] = 100 * np.mean(kde.log_likelihood(ds.X_val).argmax(1) == yva)
    LLn = [kde.log_likelihood(X) for X in new]
    row["kde_1_new"] = 100 * np.mean(np.concatenate([L.argmax(1) == fnew[k] for k, L in enumerate(LLn)]))
    for m, a in votes(lambda o, r: LLn[o][r].sum(0), LLn, fnew, ms, trials, rng).items():
        row[f"bcnp_{m}_new"] = a
    if "member" in models:
        mem = np.unique(ds.y_train)  # the members with grasps (a hand may leave some out), as classes 0..M-1
        kdem = KDELikelihood(KDEConfig()).fit(ds.X_train, np.searchsorted(mem, ds.y_train), ds.X_val,
                                              np.searchsorted(mem, ds.y_val), n_classes=len(mem))
        LLm, fmem = [kdem.log_likelihood(X) for X in new], fm[mem]
        row["mem_1_new"] = 100 * np.mean(np.concatenate(
            [np.array([member_family_ll(L[i:i + 1], fmem).argmax() for i in range(len(L))]) == fnew[k] for k, L in enumerate(LLm)]))
        for m, a in votes(lambda o, r: member_family_ll(LLm[o][r], fmem, kdem.temperature), LLm, fnew, ms, trials, rng).items():
            row[f"memvote_{m}_new"] = a  # not mem_1_new: that is the one-shot accuracy above
    if "mlp" in models:
        mlp = MLPClassifier(MLPConfig(max_epochs=20, patience=3, progress=False)).fit(ds.X_train, ytr, ds.X_val, yva, n_classes=3)
        row["mlp_1_held"] = 100 * mlp.score(ds.X_val, yva)
        row["mlp_1_new"] = 100 * np.mean(np.concatenate([mlp.predict(X) == fnew[k] for k, X in enumerate(new)]))
        LP = [np.log(np.maximum(mlp.predict_proba(X), 1e-12)) for X in new]  # votes: summed log-posteriors
        for m, a in votes(lambda o, r: LP[o][r].sum(0), LP, fnew, ms, trials, rng).items():
            row[f"mlpvote_{m}_new"] = a
    if "rf" in models:
        rf = make_classifier("random-forest", n_jobs=1, max_train=50_000).fit(ds.X_train, ytr)
        row["rf_1_held"] = 100 * np.mean(rf.predict_proba(ds.X_val).argmax(1) == yva)
        row["rf_1_new"] = 100 * np.mean(np.concatenate([rf.predict_proba(X).argmax(1) == fnew[k] for k, X in enumerate(new)]))
    row["s"] = time.time() - t0
    return row


def size_cell(members, G, seed, size_range, sizes, source, heights=False):
    """One-shot family accuracy (KDE, no normals, scale-normalised) on the three FIXED shapes (cube, round cylinder,
    sphere) at each overall size in ``sizes`` (m), trained on ``members`` per family with per-axis factors
    U(0.5, 1.5) and, if given, a size factor per member (``size_range``). With a hand's grasps a sphere gives one
    contact pattern whatever the approach, and that pattern moves with the sphere's size (the fingers keep theirs)."""
    t0 = time.time()
    cfg = family_config(source, size_range=size_range, heights=heights)
    tr = family_set(members, np.random.default_rng(seed), size_range=size_range)
    ds = member_dataset(tr, grasps(cfg, G, seed, False, True), cfg)
    fm = fam_labels(tr)
    kde = KDELikelihood(KDEConfig()).fit(ds.X_train, fm[ds.y_train], ds.X_val, fm[ds.y_val], n_classes=3)
    row = {"members": members, "size_range": "-" if size_range is None else f"{size_range[0]:g}-{size_range[1]:g}",
           "source": source}
    if heights:
        row["heights"] = True
    for size in sizes:
        shapes = family_set(1, np.random.default_rng(seed), scale_range=(size / 0.08, size / 0.08))
        P = pool(shapes, 300, False, True, seed + VAL_MEMBER_SEED, cfg)  # a shape too small for a hand: 0 rows (nan)
        for k, X in enumerate(P):
            hit = kde.log_likelihood(X.astype(np.float64)).argmax(1) == k if len(X) else np.array([np.nan])
            row[f"{('cube', 'cyl', 'sphere')[k]}_{100 * size:g}cm"] = 100 * float(np.mean(hit))
    row["s"] = time.time() - t0
    return row


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sweep", choices=("spread", "norm", "members", "one", "sizes"), default="spread")
    p.add_argument("--members", type=int_in(1), default=10)
    p.add_argument("--grasps", type=int_in(5), default=3000, help="grasps per training member (20 %% held back)")
    p.add_argument("--seed", type=int_in(0), default=0)
    p.add_argument("--trials", type=int_in(1), default=300)
    p.add_argument("--ms", default="1,3,5,10,30")
    p.add_argument("--models", default="member,mlp,rf",
                   help="the models beside the KDE and its BC-NP votes: a comma list of member, mlp, rf, or none")
    p.add_argument("--lo", type=float_in(0.0, lo_open=True), default=0.5)
    p.add_argument("--hi", type=float_in(0.0, lo_open=True), default=1.5)
    p.add_argument("--source", choices=FAMILY_SOURCES, default="surface",
                   help="training and validation grasps: independent surface points (the paper's), the geometric "
                        "hand's grasps under random approaches, or the Allegro's own MuJoCo grasps (hand; "
                        "grasps = approaches per member, of which the 4-finger ones are kept)")
    p.add_argument("--size-range", default=None,
                   help="LO,HI of a size factor per member (family_set(size_range=); default none, the paper's)")
    p.add_argument("--heights", action="store_true",
                   help="with --source hand: append the contacts' heights above the table (experiment 5's "
                        "--family-heights)")
    p.add_argument("--lying", action="store_true",
                   help="every second cylinder member lies on its side (experiment 5's --family-lying)")
    p.add_argument("--sizes", default="0.05,0.067,0.08,0.1,0.12", help="--sweep sizes: the fixed shapes' sizes (m)")
    a = p.parse_args(argv)
    if a.lo > a.hi:
        p.error(f"--lo {a.lo} must be <= --hi {a.hi}")
    try:
        ms = tuple(int(v) for v in a.ms.split(","))
    except ValueError:
        p.error(f"--ms: a comma list of grasp counts, got {a.ms!r}")
    if min(ms) < 1:
        p.error(f"--ms: grasp counts >= 1, got {a.ms!r}")
    models = set() if a.models == "none" else set(a.models.split(","))  # none: the KDE alone (committed commands)
    if unknown := models - {"member", "mlp", "rf"}:
        p.error(f"--models: unknown {sorted(unknown)}; choose among member, mlp, rf, or none")
    if a.sweep == "sizes":  # size_cell: the KDE on the fixed shapes, its members' per-axis factors U(0.5, 1.5)
        ignored = [f"--{k}" for k in ("lying", "lo", "hi", "models", "trials", "ms")
                   if getattr(a, k) != p.get_default(k)]
        if ignored:
            p.error(f"--sweep sizes does not use {', '.join(ignored)} (it scores the KDE on the fixed shapes, its "
                    "members' factors U(0.5, 1.5), standing)")
    if a.sweep == "spread":
        cells = [(lo, hi, False, True) for lo, hi in ((1, 1), (0.9, 1.1), (0.75, 1.25), (0.5, 1.5))]
    elif a.sweep == "norm":
        cells = [(a.lo, a.hi, nrm, nz) for nrm in (False, True) for nz in (True, False)]
    elif a.sweep == "members":
        cells = [(a.lo, a.hi, False, True)]
    else:  # "one" and "sizes": the given spread
        cells = [(a.lo, a.hi, False, True)]
    sr = None if a.size_range is None else tuple(float(v) for v in a.size_range.split(","))
    if a.sweep == "sizes":
        rows = [size_cell(a.members, a.grasps, a.seed, sr, tuple(float(v) for v in a.sizes.split(",")), a.source,
                          a.heights)]
    else:
        rows = []
        for lo, hi, nrm, nz in cells:  # each cell's row on stderr as it finishes (a cell takes minutes)
            rows.append(run_cell(lo, hi, nrm, nz, a.members, a.grasps, a.seed, ms, a.trials, models, a.source, sr,
                                 a.heights, a.lying))
            print(rows[-1], file=sys.stderr, flush=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(f"{r[k]:.1f}" if isinstance(r.get(k), float) else str(r.get(k, "")) for k in keys) + " |",
              flush=True)


if __name__ == "__main__":
    main()
