"""Sweep speed-up: 4 independent jobs one after another (in this process, no Ray) against the same 4 jobs as a
sweep on a local Ray with ``--num-cpus`` CPUs (Ray's start-up included), in one run. Target (issue 14): the
sweep takes <= 0.6x the sequential time on a 2-core machine.

The jobs are dataset jobs (``build_dataset`` of the default set, ``--fingers`` contacts, ``--grasps`` grasps
per object, seeds 0..3): CPU-bound, single-threaded, equal in size. Each mode writes into its own fresh
``$HAPTIC_CACHE`` (so both compute everything). ``--rounds R`` (default 2) repeats the pair, the order alternating
(sequential first, then the sweep first), and the figure is the median of the rounds' ratios: a single pair is
at the mercy of whatever else the machine does at the time::

    python benchmarks/bench_sweep.py                    # 4 jobs x 100,000 grasps per object, 2 CPUs
    python benchmarks/bench_sweep.py --grasps 20000 --jobs 4 --num-cpus 2 --out docs/results/sweep/bench.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from haptic_env.cli import int_in, output_path  # noqa: E402
from haptic_env.dataset import MAX_CLI_FINGERS  # noqa: E402


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int_in(1), default=4)
    ap.add_argument("--grasps", type=int_in(1), default=100_000, help="grasps per object of each dataset job")
    ap.add_argument("--fingers", type=int_in(2, MAX_CLI_FINGERS), default=4)
    ap.add_argument("--num-cpus", type=int_in(1), default=2)
    ap.add_argument("--rounds", type=int_in(1), default=2,
                    help="pairs of runs, the order alternating; the median ratio")
    ap.add_argument("--out", type=output_path("file"), default=None, help="also write the numbers to this JSON file")
    args = ap.parse_args(argv)

    from haptic_env.cache import atomic_write
    from haptic_env.sweep import parse_spec
    from haptic_env.sweep.runner import run_jobs_inline, run_sweep

    spec = parse_spec({"name": "bench", "max_retries": 0, "dataset": [
        {"objects": "default", "fingers": args.fingers, "grasps_per_object": args.grasps, "seed": s, "name": f"s{s}"}
        for s in range(args.jobs)]})
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    times: dict = {"load_before": os.getloadavg()}  # other processes on the machine take CPU time from both modes
    rounds = []
    try:
        for r in range(args.rounds):
            t = {}
            for mode in ("sequential", "sweep") if r % 2 == 0 else ("sweep", "sequential"):
                run = tmp / f"{mode}_{r}"
                os.environ["HAPTIC_CACHE"] = str(tmp / f"cache_{mode}_{r}")
                t0 = time.perf_counter()
                if mode == "sequential":
                    res = run_jobs_inline(spec, run)
                else:
                    res = run_sweep(spec, run, num_cpus=args.num_cpus, progress=False)
                t[mode] = time.perf_counter() - t0
                assert res.ok and len(res.done) == args.jobs, res.failed
                t[f"{mode}_jobs"] = job_s = sorted(d["seconds"] for d in res.done.values())
                print(f"round {r + 1} {mode:10s} {t[mode]:7.1f} s  (jobs {', '.join(f'{s:.1f}' for s in job_s)} s)",
                      flush=True)
            t["ratio"] = t["sweep"] / t["sequential"]
            rounds.append(t)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    times["load_after"] = os.getloadavg()
    ratio = float(np.median([t["ratio"] for t in rounds]))
    print(f"load average (1, 5, 15 min) before {times['load_before']}, after {times['load_after']}")
    out = {"jobs": args.jobs, "grasps_per_object": args.grasps, "fingers": args.fingers, "num_cpus": args.num_cpus,
           "cores": os.cpu_count(), "platform": platform.platform(), **times, "rounds": rounds, "ratio": ratio,
           "target": 0.6, "met": ratio <= 0.6}
    if args.out:
        with atomic_write(args.out, "w") as fh:
            json.dump(out, fh, indent=2)
    per_round = ", ".join(f"{t['ratio']:.2f}" for t in rounds)
    print(f"sweep / sequential = {ratio:.2f}, the median of {args.rounds} round(s): "
          f"{per_round} (target <= 0.6: {'met' if ratio <= 0.6 else 'missed'})")
    return out


if __name__ == "__main__":
    main()
