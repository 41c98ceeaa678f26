"""Why experiment 5 votes the default set's mug a box: where the Allegro's 4-finger grasps touch it.

A diagnostic on experiment 5's TEST grasps of the default set (the family model of ``--seed`` with ``--members``
members, no normals, the Allegro's own grasps, size factor U(0.7, 1.6): the reported setting), nothing is tuned on
it. Each 4-finger grasp of the mug is put in one group by its contacts: on the handle (a contact farther than 2 mm
outside the cup's wall), inside the cup (a contact more than 6 mm inside the wall, above the bottom), or on the
outer wall and bottom only (the can and the bottle, the controls, are cylinders without handle or opening: all
their grasps in one group). For each group: the one-shot family argmax and the family of 30 grasps' summed
calibrated log-likelihoods (BC-NP's belief after 30 grasps, 1,000 draws).

    OMP_NUM_THREADS=1 python benchmarks/family_mug.py [--seed 0] [--members 40]

Uses experiment 5's cached member and object pools when they exist (about 13 minutes on 2 cores otherwise).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from haptic_env.dataset import DatasetConfig, grasp_vectors, hand_pool, support_frame
from haptic_env.experiments import families as F
from haptic_env.experiments.config import TEST_SEED_OFFSET, AnalysisConfig
from haptic_env.hand_grasps import pool_rows
from haptic_env.objects import FAMILIES, family_set, load_object_set
from haptic_env.recognizers.kde import KDELikelihood
from haptic_env.recognizers.mlp import MLPClassifier

WALL = 0.041  # the default mug's outer radius (objects/primitives.py, _mug)


def grasp_config(cfg: AnalysisConfig, grasps: int, seed: int, **kw) -> DatasetConfig:
    """Experiment 5's grasps: 4 fingers, scale-normalised, the family source of ``cfg``."""
    return DatasetConfig(n_fingers=4, normals=cfg.normals, grasps_per_object=grasps, normalize_scale=True, seed=seed,
                         normal_axis=cfg.normal_axis, **cfg.family_grasps, **kw)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--members", type=int, default=40)
    a = p.parse_args(argv)
    cfg = AnalysisConfig(objects="default", experiments=(5,), grasps_per_object=1000, normals=False,
                         family_source="hand", family_size_range=(0.7, 1.6), family_members=a.members, seed=a.seed,
                         progress=False)
    objects = load_object_set("default")
    kw = {"scale_range": cfg.family_scale_range, "size_range": cfg.family_size_range, "lying": cfg.family_lying}
    train = family_set(cfg.family_members, np.random.default_rng(cfg.seed), **kw)
    val = family_set(max(2, cfg.family_members // 3), np.random.default_rng(cfg.seed + F.FAMILY_VAL_SEED_OFFSET), **kw)
    idx = {f: i for i, f in enumerate(FAMILIES)}
    per_obj = max(1000, cfg.grasps_per_object * len(objects) // len(train))  # as experiment 5
    ds, _ = F.member_grasps(train, grasp_config(cfg, per_obj, cfg.seed), cfg, "training")
    fam = np.array([idx[train.families[n]] for n in train.names])
    kde = KDELikelihood(cfg.kde).fit(ds.X_train, fam[ds.y_train], ds.X_val, fam[ds.y_val], n_classes=len(FAMILIES))
    vds, _ = F.member_grasps(val, grasp_config(cfg, cfg.test_grasps, cfg.seed + F.FAMILY_VAL_SEED_OFFSET,
                                               val_fraction=0.0), cfg, "validation")
    fval = np.array([idx[val.families[n]] for n in val.names])
    # family_temperatures also fits the MLP's; only the KDE's is used here, so a short MLP is enough
    clf = MLPClassifier(dataclasses.replace(cfg.mlp, progress=False, max_epochs=2)).fit(
        ds.X_train, fam[ds.y_train], ds.X_val, fam[ds.y_val], n_classes=len(FAMILIES))
    T, _ = F.family_temperatures(kde, clf, vds.X_train.astype(np.float64), fval[vds.y_train], member=vds.y_train,
                                 grasps=cfg.max_grasps, rng=np.random.default_rng([cfg.seed, F.FAMILY_VAL_SEED_OFFSET]))
    dc = grasp_config(cfg, cfg.test_grasps, cfg.seed + TEST_SEED_OFFSET, val_fraction=0.0)  # experiment 5's test grasps
    pool = hand_pool(objects, dc, False)
    streams = np.random.SeedSequence([dc.seed, 1]).spawn(len(objects))  # the rows hand_vectors gives
    print(f"seed {a.seed}, {a.members} members per family, KDE temperature {T:.2f}\n")
    print("| object | grasps | group | share | one-shot box / cyl / ell % | 30-grasp belief box / cyl / ell % |")
    print("|---|---|---|---|---|---|")
    for name in ("mug", "can", "bottle"):
        k = objects.names.index(name)
        rng = np.random.default_rng(streams[k])
        C, _ = pool_rows(pool, k, 4, rng)
        X, valid = grasp_vectors(support_frame(C, objects[k], dc), None, dc, rng=rng)
        C, LL = C[valid], kde.log_likelihood(X[valid].astype(np.float64)) / T
        lo, hi = objects[k].mesh.bounds
        R = (hi[1] - lo[1]) / 2  # y is symmetric about the axis; a handle, if any, sticks out along +x
        r = np.linalg.norm(C[..., :2] - [lo[0] + R, (lo[1] + hi[1]) / 2], axis=-1)
        handle = (r > R + 0.002).any(1)
        inside = ((r < R - 0.006) & (C[..., 2] > lo[2] + 0.012)).any(1)
        draw = np.random.default_rng(a.seed + 5)
        groups = {"all": np.ones(len(C), bool)}
        if name == "mug":  # on the can and the bottle these radii would only mark rims and shoulders
            groups.update({"handle": handle, "inside (not the handle)": inside & ~handle,
                           "outer wall / bottom only": ~handle & ~inside})
        for g, m in groups.items():
            rows = np.flatnonzero(m)
            if len(rows) < 5:
                continue
            one = 100 * np.bincount(LL[rows].argmax(1), minlength=3) / len(rows)
            votes = np.array([LL[draw.choice(rows, 30)].sum(0).argmax() for _ in range(1000)])
            bel = 100 * np.bincount(votes, minlength=3) / len(votes)
            print(f"| {name} | {len(C)} | {g} | {100 * len(rows) / len(C):.0f} % | "
                  f"{' / '.join(f'{v:.0f}' for v in one)} | {' / '.join(f'{v:.0f}' for v in bel)} |")


if __name__ == "__main__":
    main()
