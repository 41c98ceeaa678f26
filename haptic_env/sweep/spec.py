"""Sweep specs: a TOML file (``tomllib``) expanded into :class:`Job` objects.

A spec declares envs, agents and seeds (one train job per trained agent x env x seed, one evaluate job per
agent x env x seed), and dataset, analysis and command jobs::

    name = "easy"                          # the sweep folder defaults to outputs/sweeps/<name>
    seeds = [0, 1, 2]                      # agent seeds (training seeds of PPO/SAC; RandomAgent's seed)
    max_retries = 2                        # Ray retries of a failed job (exceptions and dead workers)
    env_kwargs = { grasp_cost = 0.02 }     # HapticRecogConfig fields of every env (under each env's kwargs)

    [[env]]                                # or: env_ids = ["HapticRecog-v0", "HapticRecogKIT-v0"]
    name = "kit20"                         # folder-safe label (default: the id)
    id = "HapticRecog-v0"                  # a registered env id (haptic_env.ENV_VARIANTS)
    kwargs = { objects = "kit20" }         # must not change a field the id's variant sets

    [[agent]]
    name = "greedy"                        # random | greedy | greedy:M (spec = ... to rename)
    [[agent]]
    name = "ppo"
    algo = "ppo"                           # ppo, sac, rppo or mppo: train.py, then evaluation of <algo>_final.zip
    total_timesteps = 200000               # + n_envs, vec, checkpoint_freq, hyperparams, cpus, max_minutes,
                                           # discrete_approaches (train.py --discrete-approaches; ppo / rppo /
                                           # mppo, which needs them) and
                                           # no_repeat (evaluate --no-repeat; with discrete_approaches, ppo;
                                           # mppo acts so anyway); cpus defaults to n_envs with vec = "subproc"
                                           # (the default for n_envs > 1), else 1 (one process)

    [evaluate]
    episodes = 40                          # episodes per env seed
    env_seeds = [1000, 1001, 1002]         # every agent sees the same objects and poses per env seed

    [[dataset]]                            # build_dataset through the shared cache; objects, fingers and
                                           # normals lists are grid axes
    objects = ["kit8", "kit20"]
    fingers = [2, 3, 4, 5]
    normals = [true, false]
    grasps_per_object = 200000             # + any other DatasetConfig field (source, contact_noise, ...)

    [[analysis]]                           # haptic-recog analysis, one job per object set, after its datasets
    objects = ["kit8"]
    flags = { experiments = "2", fingers = "3,4", trials = 100 }

    [[command]]                            # any command, run in its job folder
    name = "hello"
    run = ["python", "-c", "print('hello')"]

Every job has a key, the hash of its settings: its run folder ends with it, so a changed setting gets a new
folder and a finished job with the same settings is skipped.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path
from typing import Any

__all__ = ["Job", "SweepSpec", "SpecError", "load_spec", "parse_spec", "KINDS"]

KINDS = ("dataset", "analysis", "train", "evaluate", "command")

_TOP = {"name", "description", "out", "seeds", "max_retries", "env_kwargs", "env", "env_ids", "agent", "evaluate",
        "dataset", "analysis", "command"}
_ENV = {"name", "id", "kwargs"}
_TRAINED = {"name", "algo", "total_timesteps", "n_envs", "vec", "checkpoint_freq", "hyperparams", "cpus",
            "max_minutes", "seeds", "discrete_approaches", "no_repeat"}
_BASELINE = {"name", "spec", "seeds"}
_EVALUATE = {"episodes", "env_seeds", "cpus"}
_DATASET_KEYS = {"objects", "fingers", "normals", "cpus", "name"}
_ANALYSIS = {"objects", "flags", "cpus", "name"}
_COMMAND = {"name", "run", "cpus", "env"}


class SpecError(ValueError):
    """A sweep spec that cannot be expanded (unknown key, bad value); the message names the spec entry."""


def _key(*parts: Any) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:10]


def _safe(text: str) -> str:
    """``text`` as one folder name: other characters as ``_``, ``:`` as ``-``, at most 60 characters; a name of dots
    only (``.``, ``..``: the folder itself or its parent) as underscores."""
    name = re.sub(r"[^A-Za-z0-9_.=:-]+", "_", str(text)).replace(":", "-")[:60] or "x"
    return name.replace(".", "_") if set(name) == {"."} else name


@dataclass(frozen=True)
class Job:
    """One unit of work: ``kind`` (one of :data:`KINDS`), its JSON-able ``params``, the ids of the jobs it needs
    (``deps``), and the CPUs it asks of Ray. ``id`` is ``<kind>/<label>-<key>``, also its folder under
    ``<sweep>/runs``."""

    kind: str
    label: str
    params: dict[str, Any]
    deps: tuple[str, ...] = ()
    cpus: float = 1.0

    @property
    def key(self) -> str:
        return _key(self.kind, self.params, self.deps)

    @property
    def id(self) -> str:
        return f"{self.kind}/{self.label}-{self.key}"

    def run_dir(self, out: str | Path) -> Path:
        return Path(out) / "runs" / self.id

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "label": self.label, "params": self.params, "deps": list(self.deps),
                "cpus": self.cpus, "id": self.id, "key": self.key}


@dataclass
class SweepSpec:
    name: str
    description: str = ""
    out: str | None = None
    max_retries: int = 2
    jobs: list[Job] = field(default_factory=list)
    #: env label -> (env id, merged kwargs) of the RL part
    envs: dict[str, tuple[str, dict[str, Any]]] = field(default_factory=dict)
    source: str = ""

    def default_out(self) -> Path:
        return Path(self.out).expanduser() if self.out else Path("outputs") / "sweeps" / _safe(self.name)

    def by_id(self) -> dict[str, Job]:
        return {j.id: j for j in self.jobs}


def _check_keys(table: dict, allowed: set, where: str) -> None:
    if not isinstance(table, dict):
        raise SpecError(f"{where}: expected a table, got {table!r}")
    bad = sorted(set(table) - allowed)
    if bad:
        raise SpecError(f"{where}: unknown key(s) {bad}; allowed: {sorted(allowed)}")


def _check_objects(objects, where: str, files: bool) -> None:
    """A job's ``objects`` as the worker will load them, refused now (a :class:`SpecError` naming ``where``): an unknown
    set or a missing folder (:func:`~haptic_env.objects.loaders.check_object_spec`) and, with ``files``, a user's mesh
    folder that does not load (an empty or unreadable mesh; the analysis command reads a folder so before any work).
    Each failed on its worker, after its retries."""
    from haptic_env.objects import load_object_set
    from haptic_env.objects.loaders import NAMED_SETS, check_object_spec

    try:
        check_object_spec(objects)
        if files and objects not in NAMED_SETS and Path(str(objects)).expanduser().is_dir():
            load_object_set(str(objects))
    except (ValueError, FileNotFoundError) as exc:  # MeshLoadError is a ValueError
        raise SpecError(f"{where}.objects: {exc}") from None


def _tables(doc: dict, key: str) -> list[dict]:
    """The spec's ``[[key]]`` tables (an array of tables; none: ``[]``). A single ``[key]`` table was walked as its
    keys (a ``TypeError``, or a misleading message about the first key)."""
    tables = doc.get(key, [])
    if isinstance(tables, dict):
        raise SpecError(f"[{key}]: expected [[{key}]] tables (an array of tables, one per {key}), got a single "
                        f"[{key}] table")
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise SpecError(f"{key}: expected [[{key}]] tables, got {tables!r}")
    return tables


def _as_list(v: Any) -> list:
    return list(v) if isinstance(v, (list, tuple)) else [v]


def _int(v: Any, where: str, lo: int = 0) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise SpecError(f"{where}: expected an integer >= {lo}, got {v!r}")
    return v


def _cpus(table: dict, where: str, default: Any = 1) -> float:
    """A job's ``cpus`` (what it asks of Ray): a number >= 0, fractions allowed (Ray's 0.0001 at the finest)."""
    from haptic_env.numbers import finite_number

    v = table.get("cpus", default)
    f = finite_number(v)
    if f is None or f < 0 or 0 < f < 1e-4:
        raise SpecError(f"{where}.cpus: expected a number >= 0 (fractions down to 0.0001), got {v!r}")
    return f


def _train_vec(v: Any, where: str) -> str:
    """A trained agent's ``vec``: what ``train.py --vec`` takes (checked here, not hours later on a worker)."""
    from agents.sb3 import VEC_KINDS

    if v not in VEC_KINDS:
        raise SpecError(f"{where}.vec: expected one of {VEC_KINDS}, got {v!r}")
    return v


def _minutes(v: Any, where: str) -> float:
    """A trained agent's ``max_minutes``: a number >= 0 (0: no time limit)."""
    from haptic_env.numbers import finite_number

    f = finite_number(v)
    if f is None or f < 0:
        raise SpecError(f"{where}.max_minutes: expected a number >= 0 (0: no limit), got {v!r}")
    return f


def _hyperparams(algo: str, hp: Any, where: str, n_envs: int) -> dict[str, Any]:
    """A trained agent's ``hyperparams``: a table of keys its SB3 class takes (``agents.sb3.check_hyperparams``)."""
    from agents.sb3 import check_hyperparams

    if not isinstance(hp, dict):
        raise SpecError(f"{where}.hyperparams: expected a table, got {hp!r}")
    try:
        check_hyperparams(algo, hp, n_envs=n_envs)
    except ValueError as exc:
        raise SpecError(f"{where}.hyperparams: {exc}") from None
    return hp


def _categorical(a: dict, where: str) -> tuple[int, bool]:
    """A trained agent's ``discrete_approaches`` (an int >= 0; 0: the continuous action) and ``no_repeat`` (a bool),
    checked as ``train.py`` and ``evaluate`` would: a categorical policy is PPO's, recurrent PPO's or maskable
    PPO's (which needs one), and ``no_repeat`` needs one without memory."""
    from agents.sb3 import discrete_approaches_problem
    from haptic_env.numbers import flag

    n = _int(a.get("discrete_approaches", 0), f"{where}.discrete_approaches")
    problem = discrete_approaches_problem(n, a["algo"], a.get("vec"))
    if problem is not None:
        raise SpecError(f"{where}.discrete_approaches: {problem}")
    no_repeat = flag(a.get("no_repeat", False))
    if no_repeat is None:
        raise SpecError(f"{where}.no_repeat: expected true or false, got {a['no_repeat']!r}")
    if no_repeat and (not n or a["algo"] not in ("ppo", "mppo")):
        raise SpecError(f"{where}.no_repeat: needs a categorical policy without memory (algo = \"ppo\" with "
                        f"discrete_approaches >= 1; \"mppo\" acts so anyway), got algo {a['algo']!r}, "
                        f"discrete_approaches {n}")
    return n, no_repeat


def _changes(given: Any, variants: Any) -> bool:
    """Whether a keyword ``given`` changes a variant's value: a mapping (``backend_kwargs``) only where it gives one
    of the variant's keys another value, since its keys update the variant's (:func:`haptic_env.config.with_keys`);
    any other value where it differs."""
    if isinstance(given, Mapping) and isinstance(variants, Mapping):
        return any(k in given and given[k] != v for k, v in variants.items())
    return given != variants


def _envs(doc: dict) -> dict[str, tuple[str, dict[str, Any]]]:
    from haptic_env import ENV_VARIANTS, variant_config

    common = doc.get("env_kwargs", {})
    if not isinstance(common, dict):
        raise SpecError(f"env_kwargs: expected a table, got {common!r}")
    tables = _tables(doc, "env")
    tables += [{"id": i} for i in _as_list(doc.get("env_ids", []))]
    out: dict[str, tuple[str, dict[str, Any]]] = {}
    for i, t in enumerate(tables):
        where = f"env[{i}]"
        _check_keys(t, _ENV, where)
        env_id = t.get("id", "HapticRecog-v0")
        if env_id not in ENV_VARIANTS:
            raise SpecError(f"{where}: unknown env id {env_id!r}; choose from {list(ENV_VARIANTS)}")
        own = t.get("kwargs", {})
        if not isinstance(own, dict):
            raise SpecError(f"{where}.kwargs: expected a table of HapticRecogConfig fields, got {own!r}")
        kwargs = {**common, **own}
        clash = sorted(k for k in kwargs if k in ENV_VARIANTS[env_id] and _changes(kwargs[k], ENV_VARIANTS[env_id][k]))
        if clash:  # a row named after a registered env is that env (changes beyond its variant: HapticRecog-v0)
            raise SpecError(f"{where}: kwargs {clash} change what {env_id} sets ({ENV_VARIANTS[env_id]}); "
                            "use id = \"HapticRecog-v0\" with the full kwargs instead")
        try:
            variant_config(env_id, **kwargs)
        except (TypeError, ValueError) as exc:
            raise SpecError(f"{where} ({env_id}): {exc}") from None
        label = _safe(t.get("name", env_id))
        if label in out:
            raise SpecError(f"{where}: env name {label!r} used twice")
        out[label] = (env_id, kwargs)
    return out


def _rl_jobs(doc: dict, envs: dict, seeds: list[int], files: bool = True) -> list[Job]:
    from agents.sb3 import ALGOS
    from haptic_env import ENV_VARIANTS
    from haptic_env.splits import SWEEP_ENV_SEEDS, training_env_seed

    agents = _tables(doc, "agent")
    if agents and not envs:
        raise SpecError("[[agent]] given without any env ([[env]] or env_ids)")
    ev = doc.get("evaluate", {})
    _check_keys(ev, _EVALUATE, "evaluate")
    episodes = _int(ev.get("episodes", 20), "evaluate.episodes", 1)
    env_seeds = [_int(s, "evaluate.env_seeds") for s in _as_list(ev.get("env_seeds", list(SWEEP_ENV_SEEDS)))]
    from haptic_env.numbers import repeated

    if repeated(env_seeds):  # a seed twice: the same episodes twice, as twice the evidence
        raise SpecError(f"evaluate.env_seeds: each seed once, got {env_seeds}")
    if agents and not env_seeds:  # an evaluate job without episodes failed on its worker
        raise SpecError(f"evaluate.env_seeds: expected at least one env seed, got {ev['env_seeds']!r}")
    eval_cpus = _cpus(ev, "evaluate")
    jobs: list[Job] = []
    names = set()
    for i, a in enumerate(agents):
        where = f"agent[{i}]"
        if "name" not in a:
            raise SpecError(f"{where}: needs a name")
        name = _safe(a["name"])
        if name in names:
            raise SpecError(f"{where}: agent name {name!r} used twice")
        names.add(name)
        trained = "algo" in a
        _check_keys(a, _TRAINED if trained else _BASELINE, where)
        a_seeds = [_int(s, f"{where}.seeds") for s in _as_list(a.get("seeds", seeds))]
        if repeated(a_seeds):
            raise SpecError(f"{where}.seeds: each seed once, got {a_seeds}")
        if not a_seeds:  # the agent had no jobs, without a word
            raise SpecError(f"{where}.seeds: expected at least one seed (its own seeds or the spec's), got "
                            f"{a.get('seeds', seeds)!r}")
        if trained and a["algo"] not in ALGOS:
            raise SpecError(f"{where}: algo must be one of {ALGOS}, got {a['algo']!r}")
        if not trained:
            spec = a.get("spec", a["name"])
            if not isinstance(spec, str):
                raise SpecError(f"{where}.{'spec' if 'spec' in a else 'name'}: expected an agent spec string "
                                f"(random, greedy, ..., or a model .zip), got {spec!r}")
            if files and spec.endswith(".zip") and not Path(spec.partition("=")[2] or spec).expanduser().is_file():
                raise SpecError(f"{where}.spec: no model file {spec!r} (it failed on its worker)")
            if not spec.endswith(".zip"):  # what the evaluate job will build, checked by the one parser of specs
                from agents.evaluate import make_agent

                try:
                    make_agent(spec)
                except ValueError as exc:
                    raise SpecError(f"{where}: a baseline agent: {exc} (or a model .zip via spec); give an algo "
                                    f"of {ALGOS} for a trained agent") from None
        n_approaches, no_repeat = _categorical(a, where) if trained else (0, False)
        for env, s in product(envs, a_seeds):
            env_id, kwargs = envs[env]
            # the registered variant's own settings belong to the job: when a release changes what an env id
            # sets (e.g. its training grasps), the job's key changes and a re-run trains and evaluates again
            variant = ENV_VARIANTS[env_id]
            deps: tuple[str, ...] = ()
            if trained:
                n_envs = _int(a.get("n_envs", 1), f"{where}.n_envs", 1)
                vec = _train_vec(a.get("vec", "dummy" if n_envs == 1 else "subproc"), where)
                train = Job("train", f"{env}/{name}/seed{s}", {
                    "algo": a["algo"], "env_id": env_id, "env_variant": variant, "env_kwargs": kwargs, "seed": s,
                    # how the training envs are seeded is part of the job: jobs trained the earlier way train again
                    # ("seeding": since 2026-12-06 the envs keep env_seed; before, SB3 re-seeded them seed + rank)
                    "env_seed": training_env_seed(s), "seeding": "env_seed kept",
                    "total_timesteps": _int(a.get("total_timesteps", 200_000), f"{where}.total_timesteps", 1),
                    "n_envs": n_envs, "vec": vec,
                    "checkpoint_freq": _int(a.get("checkpoint_freq", 20_000), f"{where}.checkpoint_freq", 1),
                    "max_minutes": _minutes(a.get("max_minutes", 0.0), where),
                    "hyperparams": _hyperparams(a["algo"], a.get("hyperparams", {}), where, n_envs),
                    # only when set: the keys of jobs without it stay those of earlier sweeps
                    **({"discrete_approaches": n_approaches} if n_approaches else {}),
                }, cpus=_cpus(a, where, n_envs if vec == "subproc" else 1))  # dummy / native: one process
                jobs.append(train)
                deps = (train.id,)
                spec = f"{a['algo']}_final.zip"  # in the train job's folder (resolved by the evaluate job)
            jobs.append(Job("evaluate", f"{env}/{name}/seed{s}", {
                "agent": name, "spec": spec, "trained": trained, "env": env, "env_id": env_id, "env_variant": variant,
                "env_kwargs": kwargs,
                "seed": s, "episodes": episodes, "env_seeds": env_seeds,
                # the agent's random numbers come from (env seed, agent seed): its seeds are distinct runs
                "seeding": "env+agent", **({"no_repeat": True} if no_repeat else {})}, deps=deps, cpus=eval_cpus))
    return jobs


def _dataset_jobs(doc: dict, files: bool = True) -> list[Job]:
    from haptic_env.dataset import DatasetConfig
    from haptic_env.numbers import flag

    fields = set(DatasetConfig.__dataclass_fields__) - {"n_fingers", "normals"}
    jobs = []
    for i, t in enumerate(_tables(doc, "dataset")):
        where = f"dataset[{i}]"
        _check_keys(t, _DATASET_KEYS | fields, where)
        rest = {k: v for k, v in t.items() if k in fields}
        axes = {k: _as_list(t.get(k, d)) for k, d in (("objects", "default"), ("fingers", 4), ("normals", True))}
        empty = [k for k, v in axes.items() if not v]
        if empty:  # the entry had no jobs, without a word
            raise SpecError(f"{where}.{empty[0]}: expected a value or a non-empty list, got []")
        for objects in axes["objects"]:
            _check_objects(objects, where, files)
        for objects, n, normals in product(axes["objects"], axes["fingers"], axes["normals"]):
            b = flag(normals)
            if b is None:  # bool("false") is True
                raise SpecError(f"{where}.normals: expected true or false (or a list of them), got {normals!r}")
            cfg = {**rest, "n_fingers": n, "normals": b}
            try:
                DatasetConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in cfg.items()})
            except (TypeError, ValueError) as exc:
                raise SpecError(f"{where}: {exc}") from None
            label = f"{_safe(objects)}/n{n}-{'normals' if normals else 'no-normals'}"
            label = f"{_safe(t['name'])}/{label}" if "name" in t else label
            jobs.append(Job("dataset", label, {"objects": objects, "config": cfg}, cpus=_cpus(t, where)))
    return jobs


@functools.cache
def _analysis_options() -> tuple[frozenset[str], frozenset[str]]:
    """``haptic-recog analysis``'s option strings, and those with a ``--no-`` form (``--stop-scale`` /
    ``--no-stop-scale``), whose ``false`` must be spelled out: their default may be on (read from the parser once)."""
    import argparse

    from haptic_env.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices["analysis"]
    return (frozenset(sub._option_string_actions),
            frozenset(a.option_strings[0] for a in sub._actions if isinstance(a, argparse.BooleanOptionalAction)))


def analysis_argv(objects: str, flags: dict[str, Any], out) -> list[str]:
    """``haptic-recog`` arguments of an analysis job: ``analysis --out OUT --objects OBJECTS`` and its ``flags``
    (``key = true``: the bare flag; ``false``: ``--no-<key>`` for an option with that form, else left out, as its
    default is off; a list: comma-joined), ``--quiet`` unless the flags say otherwise."""
    argv = ["analysis", "--out", str(out), "--objects", str(objects)]
    toggles = _analysis_options()[1] if any(v is False for v in flags.values()) else set()
    for k, v in flags.items():
        flag = "--" + k.replace("_", "-")
        if v is True:
            argv.append(flag)
        elif v is False:
            if flag in toggles:
                argv.append("--no-" + flag[2:])
        else:
            argv += [flag, ",".join(map(str, v)) if isinstance(v, list) else str(v)]
    return argv if "quiet" in flags else [*argv, "--quiet"]


def _check_analysis_flags(objects: str, flags: dict[str, Any], where: str) -> None:
    """The job's flags parsed and turned into an ``AnalysisConfig`` as ``haptic-recog analysis`` will, so that a
    bad flag or value is a :class:`SpecError` now, not a failed job after its retries."""
    import contextlib
    import io

    from haptic_env.cli import UsageError, build_parser
    from haptic_env.experiments.cli import config_from_args

    err = io.StringIO()
    # every key must name an option, a false one too (it is left out of the command, so parsing would not see it)
    options = _analysis_options()[0]
    unknown = sorted(f for f in ("--" + k.replace("_", "-") for k in flags) if f not in options)
    if unknown:
        raise SpecError(f"{where}.flags: unknown flag(s) {unknown} for haptic-recog analysis")
    try:
        with contextlib.redirect_stderr(err):
            args = build_parser().parse_args(analysis_argv(objects, flags, "unused"))
        config_from_args(args)
    except SystemExit:
        raise SpecError(f"{where}.flags: {err.getvalue().strip().splitlines()[-1]}") from None
    except UsageError as exc:
        raise SpecError(f"{where}.flags: {exc}") from None


def _analysis_jobs(doc: dict, datasets: list[Job], files: bool = True) -> list[Job]:
    """One job per object set; it waits for the spec's dataset jobs of that set (the analysis then reads their
    grasps from the cache instead of generating them a second time)."""
    jobs = []
    for i, t in enumerate(_tables(doc, "analysis")):
        where = f"analysis[{i}]"
        _check_keys(t, _ANALYSIS, where)
        flags = t.get("flags", {})
        if not isinstance(flags, dict) or "out" in flags or "objects" in flags or "help" in flags:
            raise SpecError(f"{where}: flags must be a table of `haptic-recog analysis` flags other than "
                            f"--out, --objects and --help, got {flags!r}")
        sets = _as_list(t.get("objects", "default"))
        if not sets:  # the entry had no jobs, without a word
            raise SpecError(f"{where}.objects: expected a value or a non-empty list, got []")
        for objects in sets:
            _check_objects(objects, where, files)  # before the flags' check, which named an unknown set as theirs
            _check_analysis_flags(objects, flags, where)
            label = _safe(t.get("name", objects)) + ("" if "name" not in t else f"/{_safe(objects)}")
            deps = tuple(d.id for d in datasets if d.params["objects"] == objects)
            jobs.append(Job("analysis", label, {"objects": objects, "flags": flags}, deps=deps,
                            cpus=_cpus(t, where)))
    return jobs


def _command_jobs(doc: dict) -> list[Job]:
    import shlex

    from haptic_env.numbers import finite_number

    jobs = []
    for i, t in enumerate(_tables(doc, "command")):
        where = f"command[{i}]"
        _check_keys(t, _COMMAND, where)
        if "name" not in t or "run" not in t:
            raise SpecError(f"{where}: needs name and run")
        run = t["run"]
        if not (isinstance(run, str) or (isinstance(run, list) and all(isinstance(w, str) for w in run))):
            raise SpecError(f"{where}: run must be a string or a list of strings")
        try:
            words = shlex.split(run) if isinstance(run, str) else run
        except ValueError as exc:  # an unclosed quote: the shell's words of it cannot be told
            raise SpecError(f"{where}.run: {exc} in {run!r}") from None
        if not words:  # no command to run: it failed on its worker
            raise SpecError(f"{where}.run: expected a command, got {run!r}")
        env = t.get("env", {})
        if not isinstance(env, dict) or not all(isinstance(v, str) or finite_number(v) is not None
                                                for v in env.values()):
            raise SpecError(f"{where}.env: expected a table of environment variables (strings or numbers), "
                            f"got {env!r}")
        jobs.append(Job("command", _safe(t["name"]), {"run": run, "env": env}, cpus=_cpus(t, where)))
    return jobs


def parse_spec(doc: dict[str, Any], source: str = "", *, check_files: bool = True) -> SweepSpec:
    """A parsed TOML document as a :class:`SweepSpec` with its jobs expanded (raises :class:`SpecError`).
    ``check_files``: also refuse a baseline's model file that is not there and a mesh folder that does not load
    (jobs that could only fail on a worker); a dry run or a report of finished jobs needs neither."""
    _check_keys(doc, _TOP, "spec")
    if "name" not in doc:
        raise SpecError("spec: needs a name")
    seeds = [_int(s, "seeds") for s in _as_list(doc.get("seeds", [0]))]
    envs = _envs(doc)
    datasets = _dataset_jobs(doc, check_files)
    jobs = (datasets + _analysis_jobs(doc, datasets, check_files) + _rl_jobs(doc, envs, seeds, check_files)
            + _command_jobs(doc))
    ids = [j.id for j in jobs]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise SpecError(f"spec: the same job twice: {dup}")
    if not jobs:
        raise SpecError("spec: no jobs (give [[agent]] with envs, [[dataset]], [[analysis]] or [[command]])")
    out = doc.get("out")
    if out is not None and (not isinstance(out, str) or not out.strip()):
        raise SpecError(f"out: expected the sweep folder's path (a string), got {out!r}")
    if out is not None and Path(out).expanduser().is_file():
        raise SpecError(f"out: {out} is a file; give a folder")
    retries = _int(doc.get("max_retries", 2), "max_retries")
    if retries > 1000:  # Ray's retry count is a C long: a huge one failed at the first submission
        raise SpecError(f"max_retries: expected an integer in [0, 1000], got {retries}")
    return SweepSpec(name=str(doc["name"]), description=str(doc.get("description", "")), out=out,
                     max_retries=retries, jobs=jobs, envs=envs, source=source)


def load_spec(path: str | Path, *, check_files: bool = True) -> SweepSpec:
    """Read and expand a TOML spec file."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:  # a binary file given as the spec: a traceback before
        raise SpecError(f"{path}: not a TOML text file (not UTF-8)") from None
    return parse_spec(doc, source=str(path), check_files=check_files)
