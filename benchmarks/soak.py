"""Soak: long random runs of every env variant; steps/s and resident memory (RSS) must stay flat.

    python benchmarks/soak.py [--steps 100000] [--variants all|geometric|NAME ...] [--max-growth-mb 20]

Variants: every registered env (``haptic_env.ENV_VARIANTS``; the MuJoCo and KIT ones need the shared data,
``../shared/data`` or ``$HAPTIC_DATA``, and are skipped with a message when it is absent) and, on
``HapticRecog-v0``, every option that changes per-episode state: ``scale_range``, ``pose="so3"``,
``z_fingers``, ``updater="ic"`` and ``updater="bc-ip"``. Each variant runs in its own child process (so
a crash is reported as such, and one variant's memory does not count against the next) for ``--steps``
env steps of uniformly random actions, resetting at every termination / truncation. RSS (``VmRSS`` of
``/proc/self/status``) is read after the warm-up (``--warmup`` steps: recogniser built or loaded, caches
filled), at the middle and at the end; steps/s counts everything after the warm-up, resets included.
Runs on ONE core per child (OMP/MKL/torch threads = 1), one child at a time.

With ``--out``, each finished variant is kept beside it (``.<out>.partial.json``) until the table is written: the
same command resumes after an interruption, running only the variants that had not finished.

Target: no crash, RSS growth after the warm-up <= 20 MB per variant over 100,000 steps. Exit status 1
if any variant crashed or grew more. Not in CI (hours for the MuJoCo variant); the short version is the
slow test ``tests/test_soak.py``. The headline is the last line.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import collections  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from haptic_env.cache import atomic_write  # noqa: E402
from haptic_env.cli import float_in, int_in, output_path  # noqa: E402

#: name -> (env id, config overrides); the options run on the default geometric env
OPTION_VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "scale_range": ("HapticRecog-v0", {"scale_range": (0.8, 1.2)}),
    "pose=so3": ("HapticRecog-v0", {"pose": "so3"}),
    "z_fingers=3": ("HapticRecog-v0", {"z_fingers": 3}),
    "updater=ic": ("HapticRecog-v0", {"updater": "ic"}),
    "updater=bc-ip": ("HapticRecog-v0", {"updater": "bc-ip"}),
    "mujoco scale_range": ("HapticRecogMuJoCo-v0", {"scale_range": (0.8, 1.2)}),
}
#: object sets that live in the shared data folder (a variant using one, or a MuJoCo hand, needs it)
DATA_SETS = ("kit8", "kit20", "ycb10")


def variants() -> dict[str, tuple[str, dict[str, Any]]]:
    """Every soak variant: the registered envs, then the per-episode options."""
    from haptic_env import ENV_VARIANTS

    return {**{env_id: (env_id, {}) for env_id in ENV_VARIANTS}, **OPTION_VARIANTS}


def is_geometric(name: str) -> bool:
    from haptic_env import ENV_VARIANTS

    env_id, kw = variants()[name]
    return {**ENV_VARIANTS[env_id], **kw}.get("backend", "geometric") == "geometric"


def rss_mb() -> float:
    """Resident set size of this process in MiB (``VmRSS``; Linux)."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # peak, the best we have


def skip_reason(name: str) -> str | None:
    """Why ``name`` cannot run here (None: it can)."""
    from haptic_env import ENV_VARIANTS

    env_id, kw = variants()[name]
    fields = {**ENV_VARIANTS[env_id], **kw}
    if fields.get("backend") == "mujoco" or fields.get("objects") in DATA_SETS:
        from haptic_env.objects import data_dir

        if data_dir() is None:
            return (f"skipped: {env_id} needs the shared mesh data (../shared/data next to the repository, "
                    "or $HAPTIC_DATA), which is absent")
    return None


def soak(env_id: str, overrides: dict[str, Any], steps: int, warmup: int = 2000, seed: int = 0,
         samples: int = 2) -> dict[str, Any]:
    """Run ``steps`` random steps (after ``warmup`` more) of ``haptic_env.make(env_id, **overrides)`` in this
    process; returns RSS (MiB) after the warm-up / at the middle / at the end, steps/s, episodes."""
    import numpy as np
    import torch

    torch.set_num_threads(1)
    import haptic_env

    if steps < 2 or warmup < 1:  # the start mark is the last warm-up step
        raise ValueError(f"soak needs steps >= 2 and warmup >= 1, got {steps} and {warmup}")
    env = haptic_env.make(env_id=env_id, **overrides)
    rng = np.random.default_rng(seed)
    low, high = env.action_space.low, env.action_space.high
    t0 = time.perf_counter()
    env.reset(seed=seed)
    ready_s = time.perf_counter() - t0
    episodes = 0
    marks = {warmup: "start", warmup + steps // 2: "middle", warmup + steps: "end"}
    out: dict[str, Any] = {"env_id": env_id, "overrides": overrides, "steps": steps, "warmup": warmup,
                           "ready_s": ready_s}
    t_start = time.perf_counter()
    for i in range(1, warmup + steps + 1):
        _, _, term, trunc, _ = env.step(rng.uniform(low, high).astype(np.float32))
        if term or trunc:
            env.reset()
            episodes += 1
        if i in marks:
            out[f"rss_{marks[i]}_mb"] = rss_mb()
            if marks[i] == "start":
                t_start, ep_start = time.perf_counter(), episodes
    dt = time.perf_counter() - t_start
    env.close()
    out.update(steps_per_s=steps / dt if dt > 0 else float("nan"), episodes=episodes - ep_start, seconds=dt,
               growth_mb=out["rss_end_mb"] - out["rss_start_mb"])
    return out


def _child(name: str, steps: int, warmup: int, seed: int) -> None:
    env_id, kw = variants()[name]
    print("SOAK-RESULT " + json.dumps(soak(env_id, kw, steps, warmup, seed)), flush=True)


def child_command(name: str, steps: int, warmup: int, seed: int) -> list[str]:
    """The command line of one variant's child process."""
    return [sys.executable, str(Path(__file__).resolve()), "--child", name, "--steps", str(steps),
            "--warmup", str(warmup), "--seed", str(seed)]


def run_variant(name: str, steps: int, warmup: int, seed: int, timeout: float | None) -> dict[str, Any]:
    """One variant in a child process: its result, or ``{"error": ...}`` (crash, timeout). The child's stderr (its
    progress bars) is passed through as it comes."""
    with subprocess.Popen(child_command(name, steps, warmup, seed), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, cwd=ROOT) as proc:  # the with closes the pipes
        return _read_child(proc, timeout)


def _read_child(proc: subprocess.Popen, timeout: float | None) -> dict[str, Any]:
    """``run_variant``'s reading of a started child: its ``SOAK-RESULT`` line, or what ended it."""
    out, err = [], collections.deque(maxlen=200)  # the child's stdout; the end of its stderr, for a crash's line

    def pump(stream, keep, echo):
        for chunk in iter(lambda: stream.read(512), ""):
            keep.append(chunk)
            if echo:  # the child's progress bars (a hand's grasp pool takes minutes) reach the terminal
                sys.stderr.write(chunk)
                sys.stderr.flush()

    threads = [threading.Thread(target=pump, args=a, daemon=True)
               for a in ((proc.stdout, out, False), (proc.stderr, err, True))]
    for t in threads:
        t.start()
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return {"error": f"timed out after {timeout:g} s"}
    finally:
        for t in threads:
            t.join(timeout=5)
    for line in "".join(out).splitlines():
        if line.startswith("SOAK-RESULT "):
            return json.loads(line[len("SOAK-RESULT "):])
    tail = ("".join(err).replace("\r", "\n").strip().splitlines() or ["(no output)"])[-1]
    what = f"killed by signal {-proc.returncode}" if proc.returncode < 0 else f"exit status {proc.returncode}"
    return {"error": f"crashed ({what}): {tail}"}


def _load_partial(path: Path | None, key: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The variants an interrupted run with the same settings finished (``{}``: none, other settings, unreadable)."""
    from haptic_env.cache import load_keyed_json

    return (load_keyed_json(path, key) or {}).get("results", {}) if path is not None else {}


def _save_partial(path: Path, key: dict[str, Any], results: dict[str, dict[str, Any]]) -> None:
    from haptic_env.cache import save_keyed_json

    save_keyed_json(path, key, results=results)


def table(rows: list[tuple[str, dict[str, Any]]]) -> str:
    lines = ["| variant | steps | episodes | steps/s | RSS start (MiB) | RSS middle | RSS end | growth (MiB) |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name, r in rows:
        if "error" in r or "skipped" in r:
            lines.append(f"| {name} | - | - | - | - | - | - | {r.get('error') or r['skipped']} |")
            continue
        lines.append(f"| {name} | {r['steps']} | {r['episodes']} | {r['steps_per_s']:.0f} | {r['rss_start_mb']:.1f} "
                     f"| {r['rss_middle_mb']:.1f} | {r['rss_end_mb']:.1f} | {r['growth_mb']:+.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--steps", type=int_in(1), default=100_000, help="measured steps per variant (default 100000)")
    p.add_argument("--warmup", type=int_in(0), default=2000, help="steps before the first RSS reading (default 2000)")
    p.add_argument("--variants", nargs="+", default=["all"],
                   help="'all', 'geometric' (all but the MuJoCo env) or variant names")
    p.add_argument("--max-growth-mb", type=float_in(0.0), default=20.0, help="RSS growth bound after the warm-up (MiB)")
    p.add_argument("--seed", type=int_in(0), default=0)  # -1 was reported as a crash of the env
    p.add_argument("--timeout", type=float_in(0.0), default=0.0, help="seconds per variant (0: none)")
    p.add_argument("--out", type=output_path("file"), default=None, help="also write the markdown table here")
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.steps < 2 or args.warmup < 1:  # the RSS and time marks start at the last warm-up step
        p.error(f"--steps must be >= 2 and --warmup >= 1, got {args.steps} and {args.warmup}")
    allv = variants()
    if args.child:
        _child(args.child, args.steps, args.warmup, args.seed)
        return 0
    names: list[str] = []
    for v in args.variants:
        if v == "all":
            names += list(allv)
        elif v == "geometric":
            names += [n for n in allv if is_geometric(n)]
        elif v in allv:
            names.append(v)
        else:
            p.error(f"unknown variant {v!r}; choose from all, geometric, {', '.join(allv)}")
    names = list(dict.fromkeys(names))
    rows: list[tuple[str, dict[str, Any]]] = []
    # with --out, each finished variant is kept beside it: the same command resumes after an interruption
    partial = None if args.out is None else args.out.with_name(f".{args.out.name}.partial.json")
    run_key = {"steps": args.steps, "warmup": args.warmup, "seed": args.seed, "timeout": args.timeout}
    saved = _load_partial(partial, run_key)
    for name in names:
        reason = skip_reason(name)
        if reason:
            print(f"[soak] {name}: {reason}", flush=True)
            rows.append((name, {"skipped": reason}))
            continue
        if name in saved:
            print(f"[soak] {name}: finished earlier ({partial})", flush=True)
            rows.append((name, saved[name]))
            continue
        print(f"[soak] {name}: {args.steps} steps after {args.warmup} warm-up ...", flush=True)
        r = run_variant(name, args.steps, args.warmup, args.seed, args.timeout or None)
        if partial is not None and "error" not in r:
            saved[name] = r
            _save_partial(partial, run_key, saved)
        if "error" in r:
            print(f"[soak] {name}: {r['error']}", flush=True)
        else:
            print(f"[soak] {name}: {r['steps_per_s']:.0f} steps/s, RSS {r['rss_start_mb']:.1f} -> "
                  f"{r['rss_end_mb']:.1f} MiB ({r['growth_mb']:+.1f})", flush=True)
        rows.append((name, r))
    md = table(rows)
    print()
    print(md)
    if args.out is not None:
        with atomic_write(args.out, "w") as fh:
            fh.write(md + "\n")
        partial.unlink(missing_ok=True)
    ran = [(n, r) for n, r in rows if "skipped" not in r]
    crashed = [n for n, r in ran if "error" in r]
    ok = [(n, r) for n, r in ran if "error" not in r]
    over = [n for n, r in ok if r["growth_mb"] > args.max_growth_mb]
    worst = max(ok, key=lambda nr: nr[1]["growth_mb"]) if ok else None
    slowest = min(ok, key=lambda nr: nr[1]["steps_per_s"]) if ok else None
    print()
    head = (f"soak: {len(ok)}/{len(ran)} variants ran {args.steps} steps without a crash"
            + (f" ({len(rows) - len(ran)} skipped)" if len(rows) > len(ran) else ""))
    if worst:
        head += (f"; max RSS growth after warm-up {worst[1]['growth_mb']:+.1f} MiB ({worst[0]}; bound "
                 f"{args.max_growth_mb:g}); slowest {slowest[1]['steps_per_s']:.0f} steps/s ({slowest[0]})")
    if crashed:
        head += f"; CRASHED: {', '.join(crashed)}"
    if over:
        head += f"; OVER BOUND: {', '.join(over)}"
    print(head)
    return 1 if (crashed or over) else 0


if __name__ == "__main__":
    sys.exit(main())
