"""Any MJCF hand through the automatic path alone: ``make_backend("mujoco", hand=<file or Menagerie name>)``
with nothing else (fingertips, closing synergy, approach axis, physics options found by
:mod:`haptic_env.grasping.auto_hand`), on random approaches to ycb10.

    python benchmarks/hand_auto.py [--approaches 20] [--hands allegro,shadow,aero,robotiq,generic3,...] [--no-named]

Hands: the Menagerie files of the four named hands (``wonik_allegro/right_hand``, ``shadow_hand/right_hand``,
``tetheria_aero_hand_open/right_hand``, ``robotiq_2f85``) and the generic 3-6-finger hands written to MJCF
files (``generic_hand(n).spec.to_xml()``, no tips, no closing targets). With the named hands' hand-tuned
descriptions for comparison (``--no-named`` leaves them out). Usable: >= 3 fingertip contacts (both pads
for the 2-finger gripper), mean +- std over the 10 objects; normal error: angle between the torque-derived
and MuJoCo's contact normal over every touching fingertip (median / 90th percentile); grasps/s: one core,
backend time per grasp, and its ratio to the hand-tuned description of the same hand in the same run (the probe
and standoff trial, once per hand and cached in ``$HAPTIC_CACHE`` after the first run, are timed separately as the
setup). Headline, last: the range of those same-run speed ratios.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env.cli import int_in  # noqa: E402
from haptic_env.grasping import make_backend  # noqa: E402
from haptic_env.grasping.auto_hand import report  # noqa: E402
from haptic_env.grasping.hands import HandUnavailableError, generic_hand  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402

MENAGERIE = {"allegro": "wonik_allegro/right_hand", "shadow": "shadow_hand/right_hand",
             "aero": "tetheria_aero_hand_open/right_hand", "robotiq": "robotiq_2f85"}
NAMED_FINGERS = {"allegro": 4, "shadow": 5, "aero": 5, "robotiq": 2}


def run_hand(hand, objects, n_approaches: int, seed: int, **cfg) -> dict:
    t = time.perf_counter()
    be = make_backend("mujoco", hand=hand, **cfg)
    setup = time.perf_counter() - t
    usable, angles, times = [], [], []
    for i, obj in enumerate(objects):
        be.set_object(obj)
        rng = np.random.default_rng(seed + i)
        be.reset_timing()
        res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (n_approaches, 4))]
        times.append(be.timing["time_per_grasp"])
        usable.append(np.mean([r.info["usable"] for r in res]))
        for r in res:
            for j in np.flatnonzero(r.touched):
                angles.append(np.degrees(np.arccos(np.clip(r.normals[j] @ r.gt_normals[j], -1, 1))))
    be.close()
    return {"n": be.n_fingers, "usable": np.array(usable), "angles": np.array(angles), "gps": 1.0 / np.mean(times),
            "setup": setup, "report": report(be.hand)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--approaches", type=int_in(1), default=20, help="random approaches per object")
    ap.add_argument("--hands", default="allegro,shadow,aero,robotiq,generic3,generic4,generic5,generic6")
    ap.add_argument("--no-named", action="store_true", help="leave out the hand-tuned named hands")
    ap.add_argument("--seed", type=int_in(0), default=0)
    ap.add_argument("--reports", action="store_true", help="print what the automatic path chose per hand")
    args = ap.parse_args(argv)
    for h in [x for x in args.hands.split(",") if x]:  # every name before the first hand runs
        if not (h in MENAGERIE or (h.startswith("generic") and h.removeprefix("generic").isdigit()
                                   and int(h.removeprefix("generic")) >= 2)):
            ap.error(f"--hands: unknown hand {h!r}; choose from {', '.join(MENAGERIE)} or genericN (N >= 2)")
    warnings.filterwarnings("ignore", message="Attach")  # MuJoCo's notes on attaching specs
    if data_dir() is None:
        print("shared data absent (HAPTIC_DATA): ycb10 and the Menagerie hands are needed")
        return 1
    objects = load_object_set("ycb10")
    tmp = Path(tempfile.mkdtemp(prefix="hand_auto_"))
    rows = []
    for h in [x for x in args.hands.split(",") if x]:
        if h.startswith("generic"):
            n = int(h.removeprefix("generic"))
            src = tmp / f"generic{n}.xml"
            src.write_text(generic_hand(n).spec.to_xml())
            cases = [("automatic", str(src), {}), ("hand-tuned", "generic", {"n_fingers": n})]
        else:
            cases = [("automatic", MENAGERIE[h], {}), ("hand-tuned", h, {"n_fingers": NAMED_FINGERS[h]})]
        for path_kind, hand, cfg in cases:
            if path_kind == "hand-tuned" and args.no_named:
                continue
            try:
                r = run_hand(hand, objects, args.approaches, args.seed, **cfg)
            except HandUnavailableError as exc:
                print(f"skipping {h}: {exc}")
                continue
            rows.append((h, path_kind, hand, r))
            print(f"{h} {path_kind}: usable {r['usable'].mean():.2f}, {r['gps']:.0f} grasps/s", flush=True)
            if args.reports and r["report"] is not None:
                print(f"  {r['report']}")
    print("\n| hand | path | source | fingers | usable ycb10 | normal error median / 90th pct (deg) | grasps/s | "
          "speed vs hand-tuned (same run) | setup s (probe; cached after a first run) |")
    print("|---|---|---|---|---|---|---|---|---|")
    tuned = {h: r["gps"] for h, kind, _, r in rows if kind == "hand-tuned"}
    ratios = []
    for h, kind, hand, r in rows:
        vs = "-"
        if kind == "automatic" and h in tuned:
            ratios.append(r["gps"] / tuned[h])
            vs = f"{ratios[-1]:.2f}x"
        a = r["angles"]
        err = f"{np.median(a):.1f} / {np.percentile(a, 90):.1f} (n={len(a)})" if len(a) else "-"
        src = Path(hand).name if hand.endswith(".xml") else hand
        print(f"| {h} | {kind} | `{src}` | {r['n']} | {r['usable'].mean():.2f} +- {r['usable'].std():.2f} | {err} | "
              f"{r['gps']:.0f} | {vs} | {r['setup']:.1f} |")
    print(f"\nycb10, {args.approaches} random approaches per object (support=table), seed {args.seed}; usable = "
          ">= 3 fingertip contacts (both pads for the 2-finger gripper), mean +- std over objects.")
    if ratios:
        print(f"HEADLINE: the automatic path grasps at {min(ratios):.2f}-{max(ratios):.2f}x the speed of the "
              f"hand-tuned descriptions of the same hands ({len(ratios)} hands, same run)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
