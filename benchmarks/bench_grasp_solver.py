"""The grasp scene's constraint solver (``MujocoConfig.solver``; the Shadow's description picks CG, the other
hands keep MuJoCo's Newton): CG and PGS against Newton, on the same random approaches to ycb10, one core, one run.

    python benchmarks/bench_grasp_solver.py [--approaches 30] [--hands shadow,allegro,aero,robotiq]

Per hand and solver: grasps/s, its ratio to Newton's from the same run (interleaved per object, so load
drifts hit both), and how far the grasps are from Newton's: the fraction of approaches whose fingertips
touch exactly as with Newton, and the contact-point difference over fingertips that touch in both
(median / 90th percentile, mm). Headline figure last: CG's speed-up over Newton on the slowest hand (over the
first of ``--solvers`` if it is not Newton; the last solver's if CG is not among the others).
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
from haptic_env.grasping.mujoco_backend import SOLVERS, closing_steps  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402

N_FINGERS = {"allegro": 4, "shadow": 5, "aero": 5, "robotiq": 2}


def run(hand: str, objects, approaches: int, variants: dict) -> dict:
    """The same random approaches (``approaches`` per object) grasped by one MuJoCo backend per variant (label ->
    more ``make_backend`` keywords, e.g. ``{"solver": "CG"}``, ``{"max_steps": 40}``, or ``{"hand": desc}`` for a
    modified :class:`HandDescription` of the hand), interleaved per object so that load drifts hit every variant
    alike. Per label: ``touched (G, n)``, ``contacts (G, n, 3)``, ``normals (G, n, 3)``, ``steps (G,)`` (closing
    steps taken), ``cap`` (the closing-step cap), ``seconds`` and ``gps``."""
    nf = N_FINGERS[hand]
    backends = {v: make_backend("mujoco", **{"n_fingers": nf, "hand": hand, "support": "table", "normals": True, **kw})
                for v, kw in variants.items()}
    keys = ("touched", "contacts", "normals", "steps")
    out = {v: {"seconds": 0.0, **{k: [] for k in keys}} for v in variants}
    for k in tqdm(range(len(objects)), desc=hand, leave=False):
        acts = np.random.default_rng([7, k]).uniform(-1, 1, (approaches, 4))
        for v, be in backends.items():
            be.set_object(objects[k])
            be.grasp(acts[0], np.random.default_rng(0))  # warm-up (scene build)
            t = time.perf_counter()
            for a in acts:
                r = be.grasp(a, np.random.default_rng(0))
                for key, x in zip(keys, (r.touched, r.contacts, r.normals, r.info["steps"])):
                    out[v][key].append(x)
            out[v]["seconds"] += time.perf_counter() - t
    for v, be in backends.items():
        cap = be.config.max_steps or closing_steps(be.hand, be.config.timestep or be.hand.timestep)
        out[v].update({key: np.array(out[v][key]) for key in keys}, cap=cap)
        out[v]["gps"] = len(out[v]["touched"]) / out[v]["seconds"]
        be.close()
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--approaches", type=int_in(1), default=30, help="random approaches per object and solver")
    ap.add_argument("--hands", default="shadow,allegro,aero,robotiq")
    ap.add_argument("--solvers", default="Newton,CG,PGS", help="the first is the baseline")
    args = ap.parse_args(argv)
    solvers, hands = tuple(args.solvers.split(",")), tuple(args.hands.split(","))
    for flag, names, known in (("--solvers", solvers, SOLVERS), ("--hands", hands, N_FINGERS)):
        bad = [x for x in names if x not in known]
        if bad or len(set(names)) < len(names):
            ap.error(f"{flag}: got {','.join(names)!r}; give distinct names from {', '.join(known)}")
    if data_dir() is None:
        sys.exit("needs the shared data (ycb10 meshes and MuJoCo Menagerie): set HAPTIC_DATA / MENAGERIE_ROOT")
    objects = load_object_set("ycb10")
    print(f"ycb10, {args.approaches} random approaches per object and solver, one process")
    print("| hand | solver | grasps/s | speed vs " + solvers[0] + " | same fingertips touch | contact diff median / p90 (mm) |")
    print("|---|---|---|---|---|---|")
    headline = []
    # the headline's solver: CG unless it is not among the challengers (None: only the baseline runs)
    challenger = "CG" if "CG" in solvers[1:] else (solvers[-1] if len(solvers) > 1 else None)
    for hand in hands:
        try:
            res = run(hand, objects, args.approaches, {s: {"solver": s} for s in solvers})
        except HandUnavailableError as exc:
            print(f"| {hand} | skipped: {exc} |")
            continue
        base = res[solvers[0]]
        for s in solvers:
            r = res[s]
            same = (r["touched"] == base["touched"]).all(axis=1).mean()
            both = r["touched"] & base["touched"]
            d = np.linalg.norm(r["contacts"] - base["contacts"], axis=-1)[both] * 1000
            med, p90 = (np.median(d), np.quantile(d, 0.9)) if d.size else (np.nan, np.nan)
            ratio = r["gps"] / base["gps"]
            print(f"| {hand} | {s} | {r['gps']:.1f} | {ratio:.2f}x | {same:.3f} | {med:.2f} / {p90:.2f} |", flush=True)
            if s == challenger:
                headline.append((base["gps"], hand, ratio))
    if headline:
        _, hand, ratio = min(headline)
        print(f"\n{challenger} speed-up over {solvers[0]} on the slowest hand ({hand}): {ratio:.2f}x")
    else:
        print("\nno speed-up to give: " + ("only one solver" if challenger is None else "no hand could be loaded"))


if __name__ == "__main__":
    main()
