"""Experiment 5's family KDE on new members: its bandwidth, and an outlier floor on its log-likelihoods.

Experiment 5 (``haptic-recog analysis --experiments 5``) chooses its KDE bandwidth factor as every analysis does, on
held-back grasps of the objects it was trained on: here, of the training MEMBERS. Its task is to recognise the
family of shapes it has never seen, and the temperature it fits afterwards on new validation members is large
(about 20-70, RESULTS.md), a sign that a bandwidth fitted to the training members' own grasps is too sharp for new
shapes. This benchmark measures, on validation data only, how the bandwidth factor (beyond the analyses' grid,
which ends at 1.4) trades recognition of held-back member grasps against new members:

* set A: the new validation members experiment 5 fits its temperatures on (seed + 1000), used here to CHOOSE;
* set B: further new members (seed + 2000), only to CHECK the choice (never used by experiment 5).

For each factor: one-shot accuracy on held-back member grasps, on A and B; BC-NP's vote (argmax of summed
log-likelihoods of m grasps of one member) on A and B; and the NLL on A of the sequence-calibrated posteriors
(the temperature fitted on A for beliefs of 1-30 grasps, as experiment 5 fits it), the selection criterion.
``--floors`` adds the outlier floor experiment 5 now chooses (``families.family_floor``): each log-likelihood lifted to
at least about the ``q``-quantile of the true family's log-likelihood on held-back member grasps, so that a grasp unlike
every family moves the belief little. ``--bias`` adds, per row, a per-family offset on each grasp's floored
log-likelihood (:func:`fit_bias`, fitted jointly with the sequence temperature on A; ellipsoid's fixed at 0), a
correction of a lean towards one family, and B's votes with it. The factor ``hgb`` puts gradient boosting in the
KDE's place (``haptic_env.recognizers.boosted``, the analyses' ``--likelihood hgb``, which experiment 5 does not use),
floored and sequence-calibrated alike. The experiment-5 settings are the reported row's
(Allegro grasps, no normals, 40 members, size factor U(0.7, 1.6), 1,000 approaches per member). Run (the pools are built
once, about 7 minutes on 2 cores per seed, then cached)::

    OMP_NUM_THREADS=1 python benchmarks/family_bandwidth.py --seed 0 --out docs/results/families/bandwidth_seed0.md
    OMP_NUM_THREADS=1 python benchmarks/family_bandwidth.py --seed S --factors auto --floors 0,0.01,0.03,0.1,0.2,0.3
    OMP_NUM_THREADS=1 python benchmarks/family_bandwidth.py --seed S --factors auto --floors 0,0.03,0.1,0.2 --bias
    OMP_NUM_THREADS=1 python benchmarks/family_bandwidth.py --seed S --factors auto,hgb --floors 0,0.01,0.03,0.1,0.2
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np
from scipy.optimize import minimize
from scipy.special import log_softmax

from haptic_env.cache import atomic_write
from haptic_env.cli import int_in, output_path, script_command
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.families import floored, grasp_config, member_grasps, sequence_fit
from haptic_env.objects import FAMILIES, family_set
from haptic_env.recognizers.boosted import BoostedConfig, BoostedLikelihood
from haptic_env.recognizers.kde import KDELikelihood
from haptic_env.splits import FAMILY_VAL_SEED_OFFSET

CHECK_SEED_OFFSET = 2000  # set B: new members no experiment uses
FACTORS = ("auto", 0.18, 0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0)


def labels(members, ds_y) -> np.ndarray:
    idx = {f: i for i, f in enumerate(FAMILIES)}
    return np.array([idx[members.families[n]] for n in members.names])[ds_y]


def votes(LL, fam, member, m, trials, rng) -> float:
    """% of ``trials`` draws of ``m`` grasps of one member whose summed log-likelihoods' argmax is its family."""
    ids = np.unique(member)
    ok = 0
    for _ in range(trials):
        rows = np.flatnonzero(member == rng.choice(ids))
        pick = rng.choice(rows, size=m, replace=len(rows) < m)
        ok += int(LL[pick].sum(0).argmax() == fam[pick[0]])
    return 100.0 * ok / trials


def member_sums(LL, fam, member, grasps: int, per: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``per`` sums of ``k`` grasps of ONE member for every member and ``k = 1 .. grasps`` (drawn with replacement):
    the summed scores ``(M, 3)``, ``k (M,)`` and the family ``(M,)``."""
    S, K, Y = [], [], []
    for m in np.unique(member):
        rows = np.flatnonzero(member == m)
        for k in range(1, grasps + 1):
            S.append(LL[rng.choice(rows, (per, k))].sum(axis=1))
            K.append(np.full(per, k))
            Y.append(np.full(per, fam[rows[0]]))
    return np.concatenate(S), np.concatenate(K), np.concatenate(Y)


def fit_bias(S, K, Y) -> tuple[np.ndarray, float, float, float]:
    """Per-family offsets ``b (3,)`` (the last fixed at 0) added to each grasp's score, and a temperature ``T``, that
    minimise the NLL of ``softmax((S + K b) / T)`` over the member sums ``S`` of ``K`` grasps (:func:`member_sums`).
    In ``w = 1 / T`` and ``c = b / T`` the logits ``w S + K c`` are linear, so the NLL is convex there and L-BFGS
    finds its minimum. Returns ``(b, T, nll, nll_T)``, ``nll_T`` the NLL with ``T`` alone (``b = 0``)."""
    S = np.maximum(S, S.max(axis=1, keepdims=True) - 1e4)  # a family a sum rules out: a large finite gap
    idx = np.arange(len(Y))

    def nll(p):  # p = (c_0, c_1, w)
        logits = p[2] * S + K[:, None] * np.array([p[0], p[1], 0.0])
        return float(-log_softmax(logits, axis=1)[idx, Y].mean())

    bounds = [(None, None), (None, None), (1e-4, 1e2)]
    t = minimize(lambda x: nll([0.0, 0.0, x[0]]), [1.0], method="L-BFGS-B", bounds=bounds[2:])
    r = minimize(nll, [0.0, 0.0, t.x[0]], method="L-BFGS-B", bounds=bounds)
    w = float(r.x[2])
    return np.array([r.x[0] / w, r.x[1] / w, 0.0]), 1.0 / w, float(r.fun), float(t.fun)


def cell(key: str, v) -> str:
    if key in ("factor", "bias"):
        return str(v)
    return f"{v:g}" if key == "floor" else f"{v:.3f}" if key.startswith("A_nll") else f"{v:.1f}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int_in(0), default=0)
    p.add_argument("--members", type=int_in(1), default=40)
    p.add_argument("--factors", default=",".join(str(f) for f in FACTORS),
                   help="bandwidth factors (multiples of Scott's rule); 'auto': experiment 5's own choice; 'hgb': "
                        "gradient boosting in the KDE's place")
    p.add_argument("--floors", default="0",
                   help="outlier floors: each log-likelihood becomes logaddexp(LL, c), c the q-quantile of the true "
                        "family's log-likelihood on held-back member grasps (0: no floor); a grasp unlike every "
                        "family then moves the belief little")
    p.add_argument("--bias", action="store_true",
                   help="also fit per-family offsets with the sequence temperature on A (fit_bias) and give B's votes "
                        "with them")
    p.add_argument("--trials", type=int_in(1), default=600, help="vote draws per vote column")
    p.add_argument("--out", type=output_path("file"), default=None, help="also write the table (markdown) here")
    a = p.parse_args(argv)
    try:
        factors = tuple(v if v in ("auto", "hgb") else float(v) for v in a.factors.split(","))
        floors = tuple(float(v) for v in a.floors.split(","))
    except ValueError as exc:
        p.error(f"--factors / --floors: comma lists of numbers ({exc})")
    if bad := [f for f in factors if not isinstance(f, str) and not (np.isfinite(f) and f > 0)]:
        p.error(f"--factors: bandwidth factors are finite and > 0 (or auto, hgb), got {bad}")
    if bad := [q for q in floors if not 0 <= q < 1]:
        p.error(f"--floors: quantiles in [0, 1) (0: no floor), got {bad}")
    t0 = time.time()
    cfg = AnalysisConfig(experiments=(5,), normals=False, family_source="hand", family_members=a.members,
                         family_size_range=(0.7, 1.6), grasps_per_object=1000, seed=a.seed)
    kw = {"scale_range": cfg.family_scale_range, "size_range": cfg.family_size_range}
    train = family_set(cfg.family_members, np.random.default_rng(cfg.seed), **kw)
    n_new = max(2, cfg.family_members // 3)
    ds, _ = member_grasps(train, grasp_config(cfg, 1000, cfg.seed), cfg, "training")
    ytr, yva = labels(train, ds.y_train), labels(train, ds.y_val)
    new = {}
    for name, off in (("A", FAMILY_VAL_SEED_OFFSET), ("B", CHECK_SEED_OFFSET)):
        ms = family_set(n_new, np.random.default_rng(cfg.seed + off), **kw)
        vds, _ = member_grasps(ms, grasp_config(cfg, cfg.test_grasps, cfg.seed + off, val_fraction=0.0), cfg, name)
        new[name] = (vds.X_train.astype(np.float64), labels(ms, vds.y_train), vds.y_train)
    print(f"grasp pools ready in {time.time() - t0:.0f} s: {len(ds.X_train)} training rows, "
          f"A {len(new['A'][0])}, B {len(new['B'][0])}", file=sys.stderr, flush=True)
    rows = []
    for f in factors:
        if f == "hgb":
            kde = BoostedLikelihood(BoostedConfig(seed=a.seed)).fit(ds.X_train, ytr, n_classes=3)
        else:
            kde = KDELikelihood(dataclasses.replace(cfg.kde, factor=f)).fit(ds.X_train, ytr, ds.X_val, yva, n_classes=3)
        held = kde.log_likelihood(ds.X_val)
        raw = {name: kde.log_likelihood(X) for name, (X, _, _) in new.items()}
        for q in floors:
            c = np.quantile(held[np.arange(len(yva)), yva], q) if q > 0 else -np.inf
            r = {"factor": f"auto ({float(kde.factor[0]):g})" if f == "auto" else f, "floor": q,
                 "held_1": 100 * np.mean(held.argmax(1) == yva)}  # the floor keeps the order (its ties would be box)
            for name, (X, fam, member) in new.items():
                LL = floored(raw[name], c)
                r[f"{name}_1"] = 100 * np.mean(raw[name].argmax(1) == fam)  # raw: the floor's far-tail ties
                rng = np.random.default_rng([a.seed, 7])
                for m in (10, 30):
                    r[f"{name}_vote{m}"] = votes(LL, fam, member, m, a.trials, rng)
                if name == "A":  # experiment 5's criterion (family_floor): the sequence-calibrated beliefs' NLL
                    r["A_T"], r["A_nll"] = sequence_fit(LL, fam, member, grasps=cfg.max_grasps,
                                                        seed=[a.seed, FAMILY_VAL_SEED_OFFSET])
                    if a.bias:
                        sums = member_sums(LL, fam, member, cfg.max_grasps, 60, np.random.default_rng([a.seed, 1000]))
                        b, _, r["A_nll_bias"], r["A_nll_T"] = fit_bias(*sums)
                        r["bias"] = "/".join(f"{x:.2f}" for x in b)
            if a.bias:  # B's votes with A's offsets (A comes first in ``new``, so ``b`` is A's)
                X, fam, member = new["B"]
                rng = np.random.default_rng([a.seed, 7])
                for m in (10, 30):
                    r[f"B_vote{m}_bias"] = votes(floored(raw["B"], c) + b, fam, member, m, a.trials, rng)
            rows.append(r)
            print(r, file=sys.stderr, flush=True)
    best = min(rows, key=lambda r: r["A_nll"])
    keys = list(rows[0])
    lines = [f"`{script_command('family_bandwidth.py', argv)}`", "",
             f"seed {a.seed}, {a.members} members, {a.trials} vote draws per cell; chosen on A (lowest A_nll): "
             f"factor {best['factor']}, floor {best['floor']:g}; {time.time() - t0:.0f} s", "",
             "| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(cell(k, r[k]) for k in keys) + " |" for r in rows]
    text = "\n".join(lines)
    print(text)
    if a.out is not None:
        with atomic_write(a.out, "w") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
