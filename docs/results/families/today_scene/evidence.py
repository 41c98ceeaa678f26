"""Experiment 5's per-grasp family evidence on each object of a set (a diagnosis; its output is in this folder).

Trains experiment 5's family models exactly as the reported command does (40 members, size factor U(0.7, 1.6), no
normals, the Allegro's own grasps, the outlier floor and temperatures chosen on validation members) and prints, for
each object, how many of its test approaches give a 4-finger grasp, the KDE's one-shot argmax shares and the mean of
the tempered, floored log-likelihoods that BC-NP sums (:meth:`FamilyModels.tempered`).

Run with the code to measure on the path (``PYTHONPATH=<worktree>``; an editable install resolves to its own
checkout otherwise), ``OMP_NUM_THREADS=1``::

    python docs/results/families/today_scene/evidence.py default|ycb10|kit20 SEED
"""
import argparse
import sys

import numpy as np

from haptic_env.experiments import cli as ecli
from haptic_env.experiments.families import EXPECTED_FAMILY, family_models, family_vectors, grasp_config
from haptic_env.objects import FAMILIES, load_object_set
from haptic_env.splits import TEST_SEED_OFFSET


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("objects")
    p.add_argument("seed", type=int)
    a = p.parse_args(argv)
    ap = argparse.ArgumentParser()
    ecli.add_parser(ap.add_subparsers(dest="cmd"))
    cfg = ecli.config_from_args(ap.parse_args([
        "analysis", "--objects", a.objects, "--experiments", "5", "--no-normals", "--family-source", "hand",
        "--family-members", "40", "--family-size-range", "0.7,1.6", "--grasps-per-object", "1000",
        "--seed", str(a.seed), "--quiet", "--out", "unused"]))
    objects = load_object_set(cfg.objects, data_dir=cfg.data_dir, units=cfg.units, up=cfg.up)
    m = family_models(cfg, len(objects))
    dc = grasp_config(cfg, cfg.test_grasps, cfg.seed + TEST_SEED_OFFSET, val_fraction=0.0)
    pool = family_vectors(objects, dc, cfg)
    print(f"{a.objects}, seed {a.seed}: KDE temperature {m.T_kde:.2f}, outlier floor quantile {m.floor_q:g} "
          f"({m.floor:.2f}); {cfg.test_grasps} test approaches per object\n")
    print("| object | expected | 4-finger grasps | one-shot argmax box / cyl / ell % | mean tempered log-likelihood "
          "box / cyl / ell | expected minus the best other |")
    print("|---|---|---|---|---|---|")
    for k, nm in enumerate(objects.names):
        exp = EXPECTED_FAMILY.get(nm)
        if len(pool[k]) == 0:
            print(f"| {nm} | {exp or '-'} | 0 | - | - | - |")
            continue
        S = m.kde.log_likelihood(pool[k])
        mt = m.tempered(S).mean(0)
        share = 100 * np.bincount(S.argmax(1), minlength=3) / len(S)
        margin = "-" if exp is None else f"{mt[FAMILIES.index(exp)] - np.delete(mt, FAMILIES.index(exp)).max():+.3f}"
        print(f"| {nm} | {exp or '-'} | {len(S)} | {share[0]:.0f} / {share[1]:.0f} / {share[2]:.0f} | "
              f"{mt[0]:.2f} / {mt[1]:.2f} / {mt[2]:.2f} | {margin} |")


if __name__ == "__main__":
    sys.exit(main())
