"""Grasp backends: speed (grasps/s, ratio to a raw baseline measured in the same run) and quality
(fraction of random approaches giving a usable grasp, >= 3 fingertip contacts, both pads for the
2-finger gripper; agreement of the
torque-derived normals with MuJoCo's contact normals) per backend and hand on kit8 and ycb10.

    python benchmarks/bench_grasping.py [--approaches 20] [--hands generic,allegro,shadow,aero,robotiq] [--quick]

Baselines: geometric = Embree ray casting of the same rays alone (``scene.run``); mujoco = the raw
``mj_step`` time of the steps the backend takes. Usable fractions are averaged over objects
(mean +- std over objects; one seed of random approaches per object). Headline figure last.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import int_in  # noqa: E402
from haptic_env.grasping import make_backend  # noqa: E402
from haptic_env.grasping.hands import HandUnavailableError  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402

N_FINGERS = {"generic": 4, "allegro": 4, "shadow": 5, "aero": 5, "robotiq": 2}


def _sets(quick: bool):
    if data_dir() is None:
        print("shared data absent: using the embedded default object set only")
        return {"default": load_object_set("default")}
    sets = {"kit8": load_object_set("kit8"), "ycb10": load_object_set("ycb10")}
    if quick:
        sets = {k: v.subset(v.names[:3]) for k, v in sets.items()}
    return sets


def bench_geometric(obj, n_grasps: int, rng) -> dict:
    be = make_backend("geometric", 4)
    be.set_object(obj)
    acts = rng.uniform(-1, 1, (n_grasps, 4)).astype(np.float32)
    be.grasp_batch(acts[:10], rng)  # warm-up
    batch_s = np.inf
    for _ in range(3):  # best of 3, as the baseline
        t = time.perf_counter()
        be.grasp_batch(acts, rng)
        batch_s = min(batch_s, time.perf_counter() - t)
    k = min(n_grasps, 2000)
    t = time.perf_counter()
    for a in acts[:k]:
        be.grasp(a, rng)
    single_s = (time.perf_counter() - t) / k
    o, d = be.rays(acts.astype(np.float64))
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    be._intersector._scene.run(o[:1000], d[:1000])  # warm-up, as the backend had
    raw_s = np.inf
    for _ in range(3):  # baseline: raw Embree casts of the same rays, best of 3
        t = time.perf_counter()
        be._intersector._scene.run(o, d)
        raw_s = min(raw_s, time.perf_counter() - t)
    return {"batch_gps": n_grasps / batch_s, "single_gps": 1.0 / single_s, "ratio": batch_s / raw_s,
            "faces": len(obj.mesh.faces)}


def usable_fraction(backend: str, objects, n_approaches: int, seed: int, **cfg) -> dict:
    be = make_backend(backend, cfg.pop("n_fingers", 4), **cfg)
    fracs, angles, clean, times, ratios = [], [], [], [], []
    for i, obj in enumerate(tqdm(objects, desc=f"{backend}/{cfg.get('hand', '-')}", leave=False)):
        be.set_object(obj)
        rng = np.random.default_rng(seed + i)
        acts = rng.uniform(-1, 1, (n_approaches, 4))
        if backend == "mujoco":
            be.reset_timing()
            res = [be.grasp(a, rng) for a in acts]
            fracs.append(np.mean([r.info["usable"] for r in res]))  # >= min(3, n) fingertips
            tm = be.timing
            times.append(tm["time_per_grasp"])
            ratios.append(tm["ratio"])
            for r in res:
                for j in np.flatnonzero(r.touched):
                    angles.append(np.degrees(np.arccos(np.clip(r.normals[j] @ r.gt_normals[j], -1, 1))))
                    # fingertip-only: no other link on the object, nothing of the finger on the (solid) table
                    clean.append(not (r.info["link_contact"][j] or r.info["table_contact"][j]))
        else:
            fracs.append(float(be.grasp_batch(acts, rng).usable.mean()))
    out = {"usable": np.array(fracs)}
    if backend == "mujoco":
        out.update(gps=1.0 / np.mean(times), ratio=float(np.mean(ratios)), angles=np.array(angles),
                   clean=np.array(clean, dtype=bool))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--approaches", type=int_in(1), default=20, help="random approaches per object (mujoco)")
    ap.add_argument("--geo-approaches", type=int_in(1), default=500, help="random approaches per object (geometric)")
    ap.add_argument("--hands", default="generic,allegro,shadow,aero,robotiq")
    ap.add_argument("--seed", type=int_in(0), default=0)
    ap.add_argument("--quick", action="store_true", help="3 objects per set")
    args = ap.parse_args(argv)
    sets = _sets(args.quick)
    rng = np.random.default_rng(args.seed)

    # --- geometric speed on a 25k-face mesh
    big = max((o for s in sets.values() for o in s), key=lambda o: len(o.mesh.faces))
    geo = bench_geometric(big, 20_000, rng)

    rows = []
    for backend, cfgs in (("uniform", [{}]), ("geometric", [{}]),
                          ("mujoco", [{"hand": h} for h in args.hands.split(",") if h])):
        for cfg in cfgs:
            hand = cfg.get("hand")
            nf = N_FINGERS.get(hand, 4)
            n_app = args.approaches if backend == "mujoco" else args.geo_approaches
            row = {"backend": backend, "hand": hand or "-", "n": nf}
            try:
                for set_name, objs in sets.items():
                    r = usable_fraction(backend, objs, n_app, args.seed, n_fingers=nf, **cfg)
                    row[set_name] = r["usable"]
                    if backend == "mujoco":
                        row.setdefault("gps", []).append(r["gps"])
                        row.setdefault("ratio", []).append(r["ratio"])
                        row.setdefault("angles", []).append(r["angles"])
                        row.setdefault("clean", []).append(r["clean"])
            except HandUnavailableError as exc:
                print(f"skipping {hand}: {exc}")
                continue
            rows.append(row)

    print(f"\nGeometric backend, 4 fingers, {big.name} ({geo['faces']} faces), one core:")
    print(f"  batched {geo['batch_gps']:,.0f} grasps/s, single-call {geo['single_gps']:,.0f} grasps/s, "
          f"backend/raw-Embree time ratio {geo['ratio']:.2f}")
    names = list(sets)
    head = "| backend | hand | fingers | grasps/s | time / raw mj_step | " + " | ".join(
        f"usable {s}" for s in names) + " | normal err median / 90th pct (deg), all | same, fingertip-only contacts |"
    print("\n" + head)
    print("|" + "---|" * (head.count("|") - 1))
    for r in rows:
        if r["backend"] == "mujoco":
            gps, ratio = f"{np.mean(r['gps']):.0f}", f"{np.mean(r['ratio']):.2f}"
            ang, cl = np.concatenate(r["angles"]), np.concatenate(r["clean"])
            err = f"{np.median(ang):.1f} / {np.percentile(ang, 90):.1f} (n={len(ang)})" if len(ang) else "-"
            if cl.any():
                err += f" | {np.median(ang[cl]):.1f} / {np.percentile(ang[cl], 90):.1f} (n={int(cl.sum())})"
        elif r["backend"] == "geometric":
            gps, ratio, err = f"{geo['batch_gps']:,.0f} (batch) / {geo['single_gps']:,.0f}", "-", "exact | exact"
        else:
            gps, ratio, err = "-", "-", "exact | exact"
        cells = [f"{r[s].mean():.2f} +- {r[s].std():.2f}" for s in names]
        print(f"| {r['backend']} | {r['hand']} | {r['n']} | {gps} | {ratio} | " + " | ".join(cells) + f" | {err} |")
    n_obj = {s: len(v) for s, v in sets.items()}
    print(f"\nusable = fraction of random approaches with >= 3 fingertip contacts (2 for the gripper); mean +- std over objects "
          f"{n_obj}; {args.approaches} approaches/object (mujoco), {args.geo_approaches} (geometric/uniform); "
          f"seed {args.seed}.")
    allegro = [r for r in rows if r["hand"] == "allegro"]
    tail = f"; mujoco Allegro {np.mean(allegro[0]['gps']):.0f} grasps/s" if allegro else ""
    mj = [r for r in rows if r["backend"] == "mujoco" and r["hand"] == "allegro"]
    mj_ratio = f"; mujoco Allegro grasp / its raw mj_step time {np.mean(mj[0]['ratio']):.2f}" if mj else ""
    print(f"HEADLINE: geometric 4-finger batched grasp / raw Embree casts of the same rays {geo['ratio']:.2f} "
          f"(same run; {geo['batch_gps']:,.0f} grasps/s batched, {geo['single_gps']:,.0f} single, on a "
          f"{geo['faces']}-face mesh{tail}){mj_ratio}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
