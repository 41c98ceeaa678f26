"""Could a hand's MuJoCo grasp end sooner? Closing-step caps below the hand's own, against its default grasps.

Every grasp of the MuJoCo backend closes the fingers for at most ``HandDescription.max_steps`` physics steps (the rest
test, all joint speeds under ``MujocoConfig.rest_qvel`` at two checks in a row, may end it sooner). The 5-finger envs'
first ``make`` is these grasps (60,000 per hand), so a grasp that could stop earlier with the same readout would
shorten it in proportion. This benchmark grasps the same random approaches to ycb10 with the hand's default and with
lower caps (``MujocoConfig.max_steps``), interleaved per object, one process, and reports per cap: the share of grasps
that close until the cap (the others came to rest), the grasps/s as a ratio to the default's from the same run, how
often the same fingertips touch, and how far the touching fingertips' contact points and torque-derived normals move
(median / 90th percentile over fingertips that touch in both).

    OMP_NUM_THREADS=1 python benchmarks/closing_time.py [--approaches 20] [--hands shadow,aero,allegro]

Headline figure last: the speed-up of the fastest cap that keeps the grasps (the same fingertips touch in at least
99 % of them, contacts within 1 mm and normals within 2 degrees at the 90th percentile).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_grasp_solver import N_FINGERS, run  # noqa: E402  (the same approaches per variant, interleaved per object)

from haptic_env.cli import float_list_in  # noqa: E402
from haptic_env.grasping.hands import HandDescription, HandUnavailableError, load_hand  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402
#: caps tried per hand (its default: allegro 60, shadow 75, aero 200, robotiq 300 steps)
CAPS = {"allegro": (30, 40, 50), "shadow": (30, 40, 50, 60), "aero": (60, 100, 140, 170), "robotiq": (100, 200)}
#: caps tried with ``--gains`` (None: the hand's default)
GAIN_CAPS = {"allegro": (None, 40, 30), "shadow": (None, 40, 30), "aero": (None, 120, 100, 60),
             "robotiq": (None, 200, 100)}


def scaled_gains(desc: HandDescription, factor: float) -> HandDescription:
    """A copy of ``desc`` whose position-like actuators (fixed gain, affine bias with ``-kp`` on the length) have
    their stiffness ``kp`` times ``factor``: the same targets, pulled towards harder (whether the fingers then close
    sooner is what the benchmark measures). Velocity terms, force ranges and other actuators are unchanged, and so
    is ``desc``.

    Raises:
        ValueError: ``factor`` is not a finite number > 0.
    """
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"factor must be a finite number > 0, got {factor!r}")
    spec = desc.spec.copy()
    for a in spec.actuators:
        if a.gaintype == mujoco.mjtGain.mjGAIN_FIXED and a.biastype == mujoco.mjtBias.mjBIAS_AFFINE \
                and a.gainprm[0] > 0 and a.biasprm[1] < 0:
            a.gainprm[0] *= factor
            a.biasprm[1] *= factor
    return replace(desc, spec=spec, name=f"{desc.name}_kp{factor:g}")


def touch_shares(touched: np.ndarray) -> tuple[float, float]:
    """``touched (G, n)`` -> the shares of grasps where every fingertip touches and where at least
    ``min(3, n)`` do."""
    k = touched.sum(axis=1)
    return float(np.mean(k == touched.shape[1])), float(np.mean(k >= min(3, touched.shape[1])))


def differences(a: dict, b: dict) -> tuple[float, np.ndarray, np.ndarray]:
    """Between two runs of the same approaches: the share of grasps whose fingertips touch alike, and over the
    fingertips that touch in both the contact-point distances (m) and the normals' angles (degrees)."""
    same = float(np.mean((a["touched"] == b["touched"]).all(axis=1)))
    both = a["touched"] & b["touched"]
    dist = np.linalg.norm(a["contacts"] - b["contacts"], axis=-1)[both]
    cos = np.sum(a["normals"] * b["normals"], axis=-1)[both]
    return same, dist, np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _p90(x: np.ndarray) -> float:
    return float(np.quantile(x, 0.9)) if x.size else float("inf")  # no touch to compare: never "keeps the grasps"


def _q(x: np.ndarray, scale: float, digits: int) -> str:
    return f"{scale * np.median(x):.{digits}f} / {scale * _p90(x):.{digits}f}" if x.size else "-"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--approaches", type=int, default=20, help="random approaches per object")
    ap.add_argument("--hands", default="shadow,aero,allegro")
    ap.add_argument("--gains", type=float_list_in(0.0, lo_open=True), default="",
                    help="comma-separated factors (> 0) on the actuators' kp, e.g. 2,4 (none: off)")
    args = ap.parse_args(argv)
    if args.approaches < 1:
        ap.error(f"--approaches must be >= 1, got {args.approaches}")
    gains = args.gains
    hands = args.hands.split(",")
    bad = [h for h in hands if h not in CAPS]
    if bad:
        ap.error(f"--hands: unknown hand(s) {bad}; choose from {sorted(CAPS)}")
    if data_dir() is None:
        sys.exit("needs the shared data (ycb10 meshes and MuJoCo Menagerie): set HAPTIC_DATA / MENAGERIE_ROOT")
    objects = load_object_set("ycb10")
    print(f"ycb10, {args.approaches} random approaches per object, one process")
    print("| hand | kp | closing steps (cap) | grasps at the cap | grasps/s | speed vs the default | "
          "same fingertips touch | contact diff median / p90 (mm) | normal diff median / p90 (deg) | "
          "complete grasps | >= 3 fingertips |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    headline = []
    for hand in hands:
        variants = {(1.0, c): {"max_steps": c} for c in (None, *CAPS[hand])}
        try:
            if gains:
                desc = load_hand(hand, N_FINGERS[hand])
                variants.update({(g, c): {"hand": scaled_gains(desc, g), "max_steps": c}
                                 for g in gains for c in GAIN_CAPS[hand]})
            res = run(hand, objects, args.approaches, variants)
        except HandUnavailableError as exc:
            print(f"| {hand} | skipped: {exc} |")
            continue
        base = res[(1.0, None)]
        best = (1.0, "default")
        for (g, cap), r in res.items():
            same, dist, ang = differences(r, base)
            ratio = r["gps"] / base["gps"]  # the same approaches: the ratio of their times
            label = f"default ({r['cap']})" if cap is None else str(cap)
            print(f"| {hand} | x{g:g} | {label} | {np.mean(r['steps'] >= r['cap']):.3f} | {r['gps']:.1f} | "
                  f"{ratio:.2f}x | {same:.3f} | {_q(dist, 1000, 2)} | {_q(ang, 1, 1)} | "
                  + " | ".join(f"{x:.3f}" for x in touch_shares(r["touched"])) + " |", flush=True)
            if g == 1.0 and same >= 0.99 and _p90(dist) <= 1e-3 and _p90(ang) <= 2.0 and ratio > best[0]:
                best = (ratio, str(cap))
        headline.append(f"{hand} {best[0]:.2f}x ({best[1]} steps)")
    print("\nspeed-up of the fastest cap that keeps the grasps (same fingertips in >= 99 %, p90 contact diff <= 1 mm, "
          "p90 normal diff <= 2 deg): " + ", ".join(headline))


if __name__ == "__main__":
    main()
