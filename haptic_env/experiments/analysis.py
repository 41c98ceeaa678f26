"""The paper's recognition analysis: run the selected experiments into one report (``results.md`` + PNG plots).

Experiments share one rng (seeded by ``cfg.seed``), drawn in the order they run, and the recognisers that
:func:`~haptic_env.recognizers.build_recognizer` caches.

An interrupted run resumes: after each experiment, ``out/.analysis_state.json`` keeps the report so far, the
finished experiments and the rng's state (written atomically). The same settings in the same folder skip the
finished experiments and draw what follows from the saved state, so the report is the one an uninterrupted run
writes. The file is removed when the run completes; other settings start over.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from types import ModuleType

import numpy as np

from haptic_env.cache import config_key, load_keyed_json, save_keyed_json, source_fingerprint
from haptic_env.experiments import calibration, families, oneshot, scaled, sequential, success_vs_grasps, zfinger
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.report import Report
from haptic_env.grasp_features import NORMAL_AXIS_WORDS

__all__ = ["EXPERIMENTS", "run_analysis"]

#: Experiment number -> its module (each has ``run(objects, cfg, report, rng)``).
EXPERIMENTS: dict[int, ModuleType] = {1: oneshot, 2: sequential, 3: zfinger, 4: scaled, 5: families,
                                      6: success_vs_grasps, 7: calibration}


def run_analysis(cfg: AnalysisConfig, out: str | Path, command: str | None = None) -> Path:
    """Run the selected experiments; write ``out/results.md`` and PNG plots. Returns the report path.

    ``command``: the command line that ran it, written at the top of the report."""
    from haptic_env.objects import load_object_set

    for e in cfg.experiments:
        if e not in EXPERIMENTS:
            raise ValueError(f"unknown experiment {e}; choose from {sorted(EXPERIMENTS)}")
    if 5 in cfg.experiments and cfg.family_source == "hand":
        from haptic_env.grasping.hands import load_hand

        load_hand(cfg.family_hand, n_fingers=4)  # a bad name fails now, not after experiments 1-4 (nothing written)
    objects = load_object_set(cfg.objects, data_dir=cfg.data_dir, units=cfg.units, up=cfg.up)  # missing data: now
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rep = Report(out)
    rng = np.random.default_rng(cfg.seed)
    state_path, key = out / STATE_FILE, settings_key(cfg, objects)
    state = load_keyed_json(state_path, key)  # the saved state of an unfinished run with these settings
    if state is not None:
        rep.lines, done = state["lines"], state["done"]
        rng.bit_generator.state = state["rng"]
        if cfg.progress:
            print(f"resuming {out}: experiment(s) {done} finished earlier (delete {state_path} to start over)",
                  flush=True)
        return _run(cfg, objects, rep, rng, done, state_path, key)
    # another settings' unfinished run here: this run starts over and redraws its plots, so that run's state can no
    # longer resume (it would keep the plots this run draws before its first experiment is saved)
    state_path.unlink(missing_ok=True)
    rep.lines = [f"# Recognition analysis: `{cfg.objects}` ({len(objects)} objects: {', '.join(objects.names)})", ""]
    if command:
        rep.lines += ["```", command, "```", ""]
    rep.lines += [f"{cfg.scores_label} in experiments 2-4 and 6; seed {cfg.seed}; {cfg.grasps_per_object} "
                  f"training grasps per object; {cfg.test_grasps} fresh test grasps per object; {cfg.trials} trials; "
                  f"max {cfg.max_grasps} grasps; MLP {cfg.mlp.depth}x{cfg.mlp.width}; "
                  + (f"KDE {cfg.kde.method} (k={cfg.kde.k}, cutoff {cfg.kde.cutoff} h, factor {cfg.kde.factor}"
                     f"{_select_words(cfg.kde)})." if cfg.likelihood == "kde" else
                     f"BC's likelihood {cfg.likelihood} (experiment 5's family models: KDE {cfg.kde.method}).")
                  + ("" if cfg.normal_axis == "t2" else f" Phi_n with `normal_axis=\"{cfg.normal_axis}\"` (not the "
                     f"paper's): {NORMAL_AXIS_WORDS[cfg.normal_axis]}.")
                  + ("" if cfg.force_closure is None else f" **Force-closure grasps only** (not the paper's stated "
                     f"protocol): in experiments 1-4, 6 and 7 every training, validation and test grasp is a random "
                     f"surface grasp in force closure at friction {cfg.force_closure:g}.")
                  + (" Experiment 2's BC beliefs use a stop scale chosen on validation trials (the default)."
                     if cfg.uses_stop_scale else "")]
    return _run(cfg, objects, rep, rng, [], state_path, key)


#: the resume state of an unfinished run, in its output folder
STATE_FILE = ".analysis_state.json"


def settings_key(cfg: AnalysisConfig, objects) -> str:
    """What a run's results depend on, hashed (:func:`~haptic_env.cache.config_key`): every setting but ``progress``,
    the objects' meshes (:attr:`~haptic_env.objects.ObjectSet.identity`: another data folder's files under the same
    names) and the package's code (:func:`~haptic_env.cache.source_fingerprint`); a saved state resumes only a run
    with the same key, so a report never mixes experiments of other meshes or code."""
    import haptic_env

    return config_key(dataclasses.replace(cfg, progress=False), objects.identity,
                      source_fingerprint(Path(haptic_env.__file__).parent))


def _run(cfg, objects, rep: Report, rng, done: list[int], state_path: Path, key: str) -> Path:
    """The experiments not in ``done``, each followed by the report and the resume state; the state file is removed
    at the end."""
    for e in cfg.experiments:
        if e in done:
            continue
        t0 = time.perf_counter()
        EXPERIMENTS[e].run(objects, cfg, rep, rng)
        rep.p(f"_experiment {e}: {time.perf_counter() - t0:.0f} s_")
        rep.write()
        done = [*done, e]
        save_keyed_json(state_path, key, done=done, rng=rng.bit_generator.state, lines=rep.lines)
    path = rep.write()
    state_path.unlink(missing_ok=True)
    return path


def _select_words(kde) -> str:
    """How the report names the KDE's bandwidth choice (``KDEConfig.select``), when it is chosen."""
    if kde.factor != "auto":
        return ""
    return (" by the calibrated posterior's validation NLL" if kde.select == "posterior"
            else " by the density's validation likelihood")
