"""Why experiment 5 votes mugs and cups a box: where the Allegro's 4-finger grasps touch them.

A diagnostic on experiment 5's TEST grasps (the family model of ``--seed`` with ``--members`` members, no normals,
the Allegro's own grasps, size factor U(0.7, 1.6): the reported setting); nothing is tuned on it. For each cup (the
default set's mug, kit20's green and white cups, the YCB mug) the body's axis and its radius at each height, R(z),
are read off the mesh (:func:`cup_profile`: a circle fitted to the outermost surface points per 10-degree sector
at mid-height, leaving out the handle's sectors; then the median outermost radius per 4 mm slice). Each 4-finger
grasp goes in one group by its contacts (:func:`cup_contacts`): on the handle (a contact more than 2 mm outside
R(z)), inside the cup (a contact whose nearest mesh face is an inner wall or the inner bottom), or on the outer wall,
rim and bottom only. Per group:
the one-shot family argmax, and the family of 30 grasps' summed calibrated log-likelihoods (BC-NP's belief after 30
grasps; 1,000 draws). The default set's can and bottle are the controls (all their grasps in one group).

    OMP_NUM_THREADS=1 python benchmarks/family_cups.py [--seed 0] [--members 40] [--no-floor]

Uses experiment 5's cached member and object pools when they exist (about 13 minutes on 2 cores otherwise).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import trimesh

from haptic_env.cli import int_in
from haptic_env.dataset import hand_vectors
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.families import family_models, grasp_config
from haptic_env.objects import load_object_set
from haptic_env.splits import TEST_SEED_OFFSET

#: (object set, object, a cup?) in the order of the table
OBJECTS = (("default", "mug", True), ("kit20", "GreenCup", True), ("kit20", "WhiteCup", True), ("ycb10", "025_mug", True),
           ("default", "can", False), ("default", "bottle", False))
SLICE = 0.004  # m, height step of the radius profile


def cup_profile(mesh: trimesh.Trimesh, samples: int = 60_000, seed: int = 0):
    """A cup's axis ``(2,)`` (x, y) and outer radius per height slice: ``(z0 (S,), R (S,))``, slice ``i`` covering
    ``[z0[i], z0[i] + SLICE)``. The axis is a circle fitted (least squares) to the outermost surface point of each
    10-degree sector at mid-height (25-75 % of the height), leaving out sectors more than 10 % beyond the median
    radius (the handle); R is the median over sectors of the outermost radius in each slice."""
    pts, _ = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    lo, hi = mesh.bounds
    h = hi[2] - lo[2]
    mid = pts[(pts[:, 2] > lo[2] + 0.25 * h) & (pts[:, 2] < lo[2] + 0.75 * h), :2]
    c = np.median(mid, axis=0)

    def sectors(xy, c):
        d = xy - c
        return ((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / (2 * np.pi) * 36).astype(int) % 36, np.hypot(d[:, 0], d[:, 1])

    for _ in range(3):  # refit from the new centre
        sec, r = sectors(mid, c)
        far = np.array([mid[sec == i][np.argmax(r[sec == i])] for i in range(36) if (sec == i).any()])
        rf = np.array([r[sec == i].max() for i in range(36) if (sec == i).any()])
        P = far[np.abs(rf - np.median(rf)) < 0.1 * np.median(rf)]
        sol = np.linalg.lstsq(np.c_[2 * P, np.ones(len(P))], (P ** 2).sum(1), rcond=None)[0]
        c = sol[:2]
    sec, r = sectors(pts[:, :2], c)
    z0 = np.arange(lo[2], hi[2], SLICE)
    R = np.full(len(z0), np.nan)
    for i, z in enumerate(z0):
        s = (pts[:, 2] >= z) & (pts[:, 2] < z + SLICE)
        outer = [r[s & (sec == j)].max() for j in range(36) if (s & (sec == j)).any()]
        if outer:
            R[i] = np.median(outer)
    return c, z0, R


def cup_contacts(mesh: trimesh.Trimesh, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which grasps ``C (m, n, 3)`` (contacts in the mesh frame) touch a cup's handle, and which reach inside it:
    ``(handle (m,), inside (m,))`` bool. A contact is on the handle when it lies more than 2 mm outside the body's
    outer radius at its height (:func:`cup_profile`); else inside when the mesh face nearest to it faces the axis
    (an inner wall: outward normal's radial part < -0.5) or faces up below the rim (the inner bottom: normal z > 0.5,
    more than 3 mm under the top). The mesh must be wound outward (:func:`~haptic_env.objects.prepare_mesh`)."""
    c, z0, R = cup_profile(mesh)
    P = C.reshape(-1, 3)
    Rz = np.interp(P[:, 2], z0 + SLICE / 2, np.nan_to_num(R, nan=np.nanmax(R)))  # the body's radius at each height
    radial = P[:, :2] - c
    r = np.linalg.norm(radial, axis=1)
    _, _, face = trimesh.proximity.closest_point(mesh, P)
    nrm = mesh.face_normals[face]
    n_radial = (nrm[:, :2] * radial).sum(1) / np.maximum(r, 1e-9)
    on_handle = r > Rz + 0.002
    in_cup = ~on_handle & ((n_radial < -0.5) | ((nrm[:, 2] > 0.5) & (P[:, 2] < mesh.bounds[1, 2] - 0.003)))
    return on_handle.reshape(C.shape[:2]).any(1), in_cup.reshape(C.shape[:2]).any(1)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int_in(0), default=0)
    p.add_argument("--members", type=int_in(1), default=40)
    p.add_argument("--no-floor", action="store_true", help="without experiment 5's outlier floor (--family-floors 0)")
    a = p.parse_args(argv)
    # experiment 5's reported setting; its MLP is fitted too (family_models), but only the KDE is used: two epochs
    cfg = AnalysisConfig(objects="default", experiments=(5,), grasps_per_object=1000, normals=False,
                         family_source="hand", family_size_range=(0.7, 1.6), family_members=a.members, seed=a.seed,
                         mlp=dataclasses.replace(AnalysisConfig().mlp, max_epochs=2), progress=False,
                         **({"family_floors": (0.0,)} if a.no_floor else {}))
    sets = {spec: load_object_set(spec) for spec, _, _ in OBJECTS}
    models = family_models(cfg, max(len(o) for o in sets.values()))  # the members' budget of the largest set
    dc = grasp_config(cfg, cfg.test_grasps, cfg.seed + TEST_SEED_OFFSET, val_fraction=0.0)  # experiment 5's test grasps
    print(f"seed {a.seed}, {a.members} members per family, KDE temperature {models.T_kde:.2f}, outlier floor "
          f"q = {models.floor_q:g}\n")
    print("| object | grasps | group | share | one-shot box / cyl / ell % | 30-grasp belief box / cyl / ell % |")
    print("|---|---|---|---|---|---|")
    grasps = {}
    for spec, name, cup in OBJECTS:
        objects = sets[spec]
        if spec not in grasps:
            grasps[spec] = hand_vectors(objects, dc, progress=False, contacts=True)
        k = objects.names.index(name)
        X, C = grasps[spec][k]
        S = models.kde.log_likelihood(X.astype(np.float64))
        LL = models.tempered(S)  # experiment 5's BC-NP scores (floored: grasps far below the floor tie there)
        groups = {"all": np.ones(len(C), bool)}
        if cup:
            handle, inside = cup_contacts(objects[k].mesh, C)
            groups.update({"handle": handle, "inside (not the handle)": inside & ~handle,
                           "outer wall / bottom only": ~handle & ~inside})
        draw = np.random.default_rng(a.seed + 5)
        for g, mask in groups.items():
            rows = np.flatnonzero(mask)
            if len(rows) < 5:
                continue
            one = 100 * np.bincount(S[rows].argmax(1), minlength=3) / len(rows)  # the floor keeps the order
            votes = np.array([LL[draw.choice(rows, 30)].sum(0).argmax() for _ in range(1000)])
            bel = 100 * np.bincount(votes, minlength=3) / len(votes)
            print(f"| {spec} {name} | {len(C)} | {g} | {100 * len(rows) / len(C):.0f} % | "
                  f"{' / '.join(f'{v:.0f}' for v in one)} | {' / '.join(f'{v:.0f}' for v in bel)} |")


if __name__ == "__main__":
    main()
