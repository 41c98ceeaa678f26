"""Experiment 2's BC-NP belief with an outlier floor on each grasp's calibrated posterior (validation only).

Experiment 5's family KDE gained from an outlier floor (``families.floored``: each log-likelihood lifted to at least
a constant, so that one grasp cannot rule a class out), because its test objects are unlike its training members.
This benchmark asks whether the same treatment helps experiment 2, where the cells that miss their target are
kit8 without normals at n = 3-5 (too many BC-NP grasps; RESULTS.md). Each grasp's calibrated one-shot posterior
``p`` (experiment 2's scores: the KDE's correction and temperature) becomes ``p + eps`` before BC-NP multiplies
them (``floored(log_softmax(LL), log eps)``), i.e. each grasp is taken as uninformative with a small probability;
then experiment 2's stop scale is fitted on top, exactly as experiment 2 fits it (``stop_scale.fit_stop_scale``:
the scale with the fewest grasps whose validation stops are decided and right in at least lambda of the trials).

* set A: experiment 2's own validation grasps (seed + 500, 1,500 per object) and trial stream, used to CHOOSE;
* set B: further fresh grasps (seed + ``CHECK_SEED_OFFSET``), only to CHECK, with the scale chosen on A.

No test grasp is used. Each finished finger count is kept beside ``--out`` (``<out>.state.json``; without ``--out`` in
the cache), and a run started again with the same settings and code resumes from it. Run (the training data and KDEs are
built once and cached; 200,000 grasps per object is experiment 2's reported setting)::

    OMP_NUM_THREADS=1 python benchmarks/stop_floor.py --objects kit8 --no-normals --fingers 3,4,5 \\
        --grasps-per-object 200000 --out docs/results/stop_floor/kit8_no_normals_200k.md
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
from scipy.special import log_softmax

from haptic_env.cache import atomic_write, cache_dir, config_key, package_fingerprint, resume_state, save_keyed_json
from haptic_env.cli import float_in, float_list_in, int_in, int_list_in, output_path, script_command
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.families import floored
from haptic_env.experiments.fresh_grasps import fresh_pool
from haptic_env.experiments.stop_scale import STOP_SCALES, VALIDATION_GRASPS, VALIDATION_TRIALS, fit_stop_scale
from haptic_env.objects import load_object_set
from haptic_env.recognizers.recognizer import build_recognizer
from haptic_env.recognizers.updaters import DEFAULT_THRESHOLD
from haptic_env.splits import VALIDATION_SEED_OFFSET

CHECK_SEED_OFFSET = 2500  # set B: fresh grasps no experiment uses
EPS = (0.0, 0.001, 0.003, 0.01, 0.03, 0.1)


def posterior_floor(LL: np.ndarray, eps: float) -> np.ndarray:
    """``(G, K)`` scores -> ``log(softmax(LL) + eps)`` (``eps == 0``: ``LL`` itself, the belief unchanged)."""
    if eps < 0 or not np.isfinite(eps):
        raise ValueError(f"eps must be finite and >= 0, got {eps!r}")
    return np.asarray(LL) if eps == 0 else floored(log_softmax(np.asarray(LL, dtype=np.float64), axis=1), np.log(eps))


def _fingers(text: str) -> str:
    """argparse ``type`` of ``--fingers``: checked as a comma list of counts >= 2, kept as text (the resume key)."""
    int_list_in(2)(text)
    return text


def finger_counts(a: argparse.Namespace) -> tuple[int, ...]:
    """``--fingers`` as numbers (``"3-5"`` is 3, 4, 5)."""
    return int_list_in(2)(a.fingers)


def experiment2_parser(description: str) -> argparse.ArgumentParser:
    """The arguments every experiment-2 validation benchmark takes (:func:`analysis_config` reads them)."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--objects", default="kit8")
    p.add_argument("--no-normals", action="store_true")
    p.add_argument("--fingers", default="3,4,5", type=_fingers, help="comma list of finger counts (>= 2)")
    p.add_argument("--grasps-per-object", type=int_in(10), default=200_000)
    p.add_argument("--threshold", type=float_in(0.0, 1.0, lo_open=True), default=DEFAULT_THRESHOLD)
    p.add_argument("--seed", type=int_in(0), default=0)
    p.add_argument("--out", type=output_path("file"), default=None, help="also write the table (markdown) here")
    return p


def analysis_config(a: argparse.Namespace) -> AnalysisConfig:
    """Experiment 2's settings from the parsed ``--objects --no-normals --grasps-per-object --threshold --seed``."""
    cfg = AnalysisConfig(objects=a.objects, grasps_per_object=a.grasps_per_object, normals=not a.no_normals,
                         threshold=a.threshold, seed=a.seed, progress=False)
    return dataclasses.replace(cfg, kde=dataclasses.replace(cfg.kde, seed=a.seed))  # as `haptic-recog analysis` sets it


def choose_and_check(sets: dict, n: int, cfg: AnalysisConfig, scales=STOP_SCALES
                     ) -> tuple[float, dict, dict, bool]:
    """Experiment 2's stop scale chosen on ``sets["A"]`` (per object ``(G, K)`` scores, its trial stream) and checked
    on ``sets["B"]``: ``(s, {set: "right / grasps" at s}, {set: {scale: "right / grasps"}}, reached)``; ``reached``:
    some scale stopped right ``lambda`` of the time on A (else ``s`` is :func:`fit_stop_scale`'s fallback, 1)."""
    at, every, s, reached = {}, {}, None, False
    for name, LL in sets.items():
        PR = [np.full(x.shape, 1.0 / x.shape[1]) for x in LL]  # BC-NP does not use the classifier
        rng = np.random.default_rng([cfg.seed, n, VALIDATION_SEED_OFFSET])  # experiment 2's stream on A
        chosen, table = fit_stop_scale(LL, PR, cfg.threshold, scales=scales, trials=VALIDATION_TRIALS, rng=rng)
        if name == "A":
            s, reached = chosen[0], bool(chosen[1] >= cfg.threshold)
        every[name] = {t[0]: f"{100 * t[1]:.1f} / {t[2]:.2f}" for t in table}
        at[name] = every[name][s]  # B: at the scale chosen on A
    return s, at, every, reached


def chosen_cell(r: dict) -> str:
    """A row's chosen scale as the tables print it, marked when no scale reached lambda on A (the fallback s = 1)."""
    return f"{r['s']:g}" + ("" if r.get("reached", True) else " (none reached lambda)")


def md_table(head: list[str], rows: list[list[str]]) -> list[str]:
    """A markdown table's lines: the header, its rule, one line per row of cells."""
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + ["| " + " | ".join(r) + " |" for r in rows]


def emit(lines: list[str], out, script: str = "stop_floor.py", argv=None) -> None:
    """Print the report's ``lines`` and write them to ``out`` (a path, or None: print only), atomically, under the
    command that made them (``python benchmarks/<script> <argv>``; ``argv`` None: this process's)."""
    text = "\n".join([f"`{script_command(script, argv)}`", "", *lines])
    print(text)
    if out is not None:
        with atomic_write(out, "w") as fh:
            fh.write(text + "\n")


def kept_parts(a: argparse.Namespace, name: str) -> tuple[Path, dict, dict]:
    """Where a run with the settings ``a`` keeps each finished finger count (beside ``--out``, else in the cache),
    its key, and the parts an interrupted run with them kept (:func:`~haptic_env.cache.resume_state`)."""
    # the settings and the code (haptic_env's and the benchmarks'): a resume after a code change starts again
    key = {**{k: v for k, v in sorted(vars(a).items()) if k != "out"},
           "code": package_fingerprint(Path(__file__).parent)}
    path = a.out.with_name(a.out.name + ".state.json") if a.out is not None else \
        cache_dir(name) / f"{config_key(key)}.json"
    return path, key, resume_state(path, key, "parts")


def main(argv=None):
    p = experiment2_parser(__doc__.split("\n\n")[0])
    p.add_argument("--eps", type=float_list_in(0.0), default=",".join(f"{e:g}" for e in EPS),
                   help="posterior floors, finite and >= 0 (0: none)")  # 'abc' and -1 were tracebacks
    a = p.parse_args(argv)
    eps_grid = tuple(a.eps)
    if not eps_grid:
        p.error("--eps: expected at least one posterior floor, got none")
    t0 = time.time()
    objects = load_object_set(a.objects)
    cfg = analysis_config(a)
    rows, frontier = [], []
    state, key, parts = kept_parts(a, "stop_floor")
    for n in finger_counts(a):
        if str(n) in parts:  # an interrupted run finished it
            rows += parts[str(n)]["rows"]
            frontier += parts[str(n)]["frontier"]
            continue
        mark = len(rows), len(frontier)
        rec = build_recognizer(objects, n, cfg.normals, config=cfg.recognizer_config(), models=("kde",),
                               progress=False)
        models = rec.models.with_calibration(True)
        sets = {}
        for name, off in (("A", VALIDATION_SEED_OFFSET), ("B", CHECK_SEED_OFFSET)):
            pool = fresh_pool(objects, n, cfg.normals, cfg, seed_offset=off, grasps=VALIDATION_GRASPS)
            sets[name] = [models.log_likelihood(X) for X in pool]
        for eps in eps_grid:
            floored_sets = {k: [posterior_floor(x, eps) for x in LL] for k, LL in sets.items()}
            s, at, every, reached = choose_and_check(floored_sets, n, cfg)
            r = {"n": n, "eps": eps, "s": s, "reached": reached, **at}
            frontier += [[str(n), f"{eps:g}", k] + [by_s[v] for v in STOP_SCALES if v <= 1.0]
                         for k, by_s in every.items()]
            rows.append(r)
            print(r, file=sys.stderr, flush=True)
        parts[str(n)] = {"rows": rows[mark[0]:], "frontier": frontier[mark[1]:]}
        save_keyed_json(state, key, parts=parts)
    head = ["n", "eps", "s chosen on A", "A at s: right / grasps", "B at s"]
    lines = [f"{a.objects}, normals: {cfg.normals}, {a.grasps_per_object} grasps per object, seed {a.seed}, lambda "
             f"{a.threshold}; {VALIDATION_GRASPS} validation grasps per object, {VALIDATION_TRIALS} BC-NP trials per "
             f"cell (right = decided and right at the stop); {time.time() - t0:.0f} s", ""]
    lines += md_table(head, [[str(r["n"]), f"{r['eps']:g}", chosen_cell(r), r["A"], r["B"]] for r in rows])
    head = ["n", "eps", "set"] + [f"s = {s:g}" for s in STOP_SCALES if s <= 1.0]
    lines += ["", "Every scale (the frontier of right stops against grasps; s > 1 only adds grasps here):", ""]
    emit(lines + md_table(head, frontier), a.out, argv=argv)


if __name__ == "__main__":
    main()
