"""The paper's hand experiment: recognise the 10 YCB objects with simulated robot hands.

Allegro (4 fingers, with and without normals) and Shadow (5 fingers, without normals) grasp each
object from random approaches in the MuJoCo backend; the fingertip contacts (and torque-derived
normals) of each grasp update a belief with IC, BC-NP, BC-IP and BC-NP scored on 3-finger subsets
(z = 3), trained on the paper's uniform surface grasps (``build_recognizer``). A query ends when the
belief certainty exceeds the threshold or after ``--max-grasps`` grasps. Grasps with fewer than 3
fingertip contacts are discarded (they still count as grasps spent); grasps with fewer contacts than
the hand's fingers are scored with the model of their finger count. Every method sees the same grasp
sequence per query (common random numbers).

    python benchmarks/hand_experiment.py [--queries 10] [--max-grasps 15] [--threshold 0.85]

Prints a markdown table (accuracy mean +- std over objects, grasps per query) - headline last.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.grasping import make_backend  # noqa: E402
from haptic_env.grasping.hands import HandUnavailableError  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402
from haptic_env.dataset import DatasetConfig  # noqa: E402
from haptic_env.recognizers import RecognizerConfig, build_recognizer  # noqa: E402

SETUPS = (("allegro", 4, True), ("allegro", 4, False), ("shadow", 5, False))
METHODS = (("IC", "ic", None), ("BC-NP", "bc-np", None), ("BC-IP", "bc-ip", None), ("BC-NP z=3", "bc-np", 3))


def grasp_sequences(hand: str, n: int, objects, queries: int, max_grasps: int, seed: int) -> dict:
    """{object index: list over queries of list of GraspResult} from random approaches."""
    be = make_backend("mujoco", n, hand=hand)
    out = {}
    for i, obj in enumerate(tqdm(objects, desc=f"grasping with {hand}")):
        be.set_object(obj)
        rng = np.random.default_rng([seed, i])
        out[i] = [[be.grasp(a, rng) for a in rng.uniform(-1, 1, (max_grasps, 4))] for _ in range(queries)]
    return out


def run_query(updater, grasps, normals: bool) -> tuple[int, int, bool]:
    """Feed grasps until decided -> (prediction, grasps used, decided)."""
    updater.reset()
    for k, g in enumerate(grasps, start=1):
        if g.n_touched < 3:
            continue
        updater.update_grasp(g.contacts, g.normals if normals else None, g.touched)
        if updater.decided:
            return updater.prediction, k, True
    return updater.prediction, len(grasps), False


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--queries", type=int, default=10, help="queries per object")
    ap.add_argument("--max-grasps", type=int, default=15, help="grasps per query at most")
    ap.add_argument("--threshold", type=float, default=0.85)
    ap.add_argument("--grasps-per-object", type=int, default=20_000, help="training grasps per object")
    ap.add_argument("--contact-noise", type=float, default=0.0, help="training contact noise std (m)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if data_dir() is None:
        print("the hand experiment needs the YCB meshes (ycb/ in the shared data folder; set HAPTIC_DATA)")
        return 1
    objects = load_object_set("ycb10")
    cfg = RecognizerConfig(grasps=DatasetConfig(grasps_per_object=args.grasps_per_object,
                                                contact_noise=args.contact_noise, seed=args.seed))
    rows = []
    seqs_cache: dict[tuple[str, int], dict] = {}
    for hand, n, normals in SETUPS:
        try:
            if (hand, n) not in seqs_cache:
                seqs_cache[(hand, n)] = grasp_sequences(hand, n, objects, args.queries, args.max_grasps, args.seed)
        except HandUnavailableError as exc:
            print(f"skipping {hand}: {exc}")
            continue
        seqs = seqs_cache[(hand, n)]
        usable = np.mean([g.usable for qs in seqs.values() for q in qs for g in q])
        rec = build_recognizer(objects, n, normals, z_values=tuple(range(3, n)), config=cfg)
        for label, kind, z in METHODS:
            acc, used, undecided = [], [], []
            for i, queries in seqs.items():
                upd = rec.make_updater(kind, threshold=args.threshold, z=z)
                res = [run_query(upd, q, normals) for q in queries]
                acc.append(np.mean([p == i for p, _, _ in res]))
                used.extend(k for _, k, _ in res)
                undecided.extend(not d for _, _, d in res)
            rows.append((hand, n, normals, label, np.array(acc), float(np.mean(used)), float(np.mean(undecided)),
                         usable))
    print(f"\nYCB-10 hand experiment: {args.queries} queries/object, <= {args.max_grasps} random-approach grasps "
          f"per query, threshold {args.threshold}, seed {args.seed}; recognisers trained on "
          f"{args.grasps_per_object} uniform grasps/object (contact noise {args.contact_noise} m).")
    print("\n| hand | fingers | normals | method | accuracy (mean +- std over objects) | grasps/query | "
          "undecided | usable grasps |")
    print("|---|---|---|---|---|---|---|---|")
    for hand, n, normals, label, acc, used, und, usable in rows:
        print(f"| {hand} | {n} | {'yes' if normals else 'no'} | {label} | {acc.mean():.2f} +- {acc.std():.2f} | "
              f"{used:.1f} | {und:.2f} | {usable:.2f} |")
    if rows:
        best = max(rows, key=lambda r: r[4].mean())
        print(f"HEADLINE: best YCB-10 accuracy {best[4].mean():.2f} ({best[0]}, {best[1]} fingers, "
              f"{'with' if best[2] else 'without'} normals, {best[3]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
