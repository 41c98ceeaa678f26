"""Train PPO, SAC, recurrent PPO (an LSTM policy) or maskable PPO on HapticRecog (CleanRL-style: one readable file,
explicit seeding).

    python train.py --algo ppo --total-timesteps 200000 --n-envs 2 --env.grasp-cost 0.02 --run-dir runs/ppo
    python train.py --algo ppo --total-timesteps 200000 --n-envs 2 --env.grasp-cost 0.02 --run-dir runs/ppo --resume runs/ppo

The command line is :class:`Args` through ``tyro`` (``--help`` shows each field's docstring): the run's own
settings (``--algo``, ``--total-timesteps``, ...) and every env setting as ``--env.<field>`` (a nested
:class:`~haptic_env.config.HapticRecogConfig`: the env's own defaults, e.g. ``--env.grasp-cost 0.02``,
``--env.max-grasps 10``); ``--env-kwargs`` takes the mapping fields (``recognizer_kwargs`` etc.) as JSON. The run
directory gets ``args.json``, ``monitor/*.monitor.csv`` (one per env), ``tb/`` (TensorBoard), ``checkpoints/`` and
``<algo>_final.zip``, and ``.train.lock``, held while a training runs there: a second training into a folder in use
is refused.

Nothing is lost: Ctrl-C / SIGINT or SIGTERM (a second one stops at once) or a dead env worker stop learning,
save a checkpoint (SAC: with its replay buffer) and exit with one line naming it (exit status 130 / 143 / 1); a
signal before learning began (the envs and the model being built or loaded) exits with one line too, nothing saved.
``--resume`` (a checkpoint, or the run directory: its latest checkpoint) continues the step counter up to
``--total-timesteps`` in all (resumed from its folder or its final model, a run whose final model is already there is
left as it is: nothing is written), in the same TensorBoard run; the Monitor CSVs of each resumed segment go to new
files ``monitor/<rank>.part<k>.monitor.csv`` and its flags to ``args.part<k>.json`` (every earlier file and line
is kept; the learning-curve reader merges the segments by wall time and leaves out a killed segment's episodes past
the step the next one resumed at, recorded as ``resumed_at_step``). PPO drops an unfinished rollout (its
steps are not counted; so does recurrent PPO), so the resumed run ends at the same step count as an uninterrupted one.
SAC resumes with the ``--n-envs`` it was trained with (its replay buffer holds that many envs' transitions per step).
It goes on in the checkpoint's run folder (``--run-dir`` defaults to it; a folder that holds another run is
refused), and it draws fresh numbers rather than replaying the start's: its envs start one past the last seed any
earlier segment's envs had (``(k - 1) x n_envs`` seeds after the run's first while ``--n-envs`` stays the same) and
its model is seeded from ``(--seed, k)`` (:func:`segment_seeds`, recorded in its ``args.part<k>.json``), so a
resumed run is not bit-identical to an uninterrupted one.
Evaluate the result with the ``evaluate`` sub-command::

    python -m haptic_env.cli evaluate --agents random greedy ppo=runs/ppo/ppo_final.zip \\
        --env-kwargs '{"grasp_cost": 0.02}' --learning-curves ppo=runs/ppo --out outputs/eval
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import re
import random
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Literal, NoReturn

os.environ.setdefault("OMP_NUM_THREADS", "1")  # before numpy/torch: one thread per env process

import numpy as np

from haptic_env.config import HapticRecogConfig, resolve_env_config
from haptic_env.cli import output_path

ALGOS = ("ppo", "sac", "rppo", "mppo")  # agents.sb3.ALGOS (tests/test_agents.py holds them equal)


@dataclass(frozen=True)
class Args:
    algo: Literal["ppo", "sac", "rppo", "mppo"] = "ppo"
    """The RL algorithm (stable-baselines3; ``rppo``: sb3-contrib's recurrent PPO, an LSTM policy that remembers the
    episode's grasps; ``mppo``: sb3-contrib's maskable PPO over ``--discrete-approaches N``, trained with a mask that
    bars the approaches tried since the belief last changed, ``agents.sb3.RepeatMask``, and evaluated with it)."""
    env_id: str = "HapticRecog-v0"
    """A registered env id (``haptic_env.ENV_VARIANTS``); ``--env.*`` settings apply on top of its variant."""
    total_timesteps: int = 200_000
    """Env steps (grasps) summed over the envs, in all (a resumed run goes on up to this count)."""
    n_envs: int = 2
    """Parallel envs."""
    vec: Literal["subproc", "dummy", "native"] = "subproc"
    """Vector env: one process per env ("subproc"), all in this process ("dummy"), or the native vector env
    (haptic_env.vector_env: all envs stepped in one batched call, geometric backend; "native")."""
    seed: int = 0
    """Seeds python, numpy, torch and the envs (see ``--env-seed``)."""
    env_seed: int = -1
    """The first env's seed (env ``rank`` gets ``env_seed + rank``). -1: ``10000 + 1000 * seed``, apart from the
    evaluation seeds (test 0-4, validation 500-504, sweeps 1000-1002), so that no training env replays an evaluation
    seed's episodes. Runs before 2026-12-06 had ``seed + rank`` in effect (stable-baselines3 re-seeded the envs with
    the model's seed): ``--env-seed SEED`` repeats them."""
    run_dir: str = "runs/ppo"
    """Where the run's files go."""
    checkpoint_freq: int = 20_000
    """Save a checkpoint every this many steps (summed over the envs)."""
    max_minutes: float = 0.0
    """Stop learning after this many wall-clock minutes (0 = no limit); the model is saved either way."""
    resume: str = ""
    """Checkpoint .zip, or a run directory (its latest checkpoint), to continue from ("" = fresh model)."""
    torch_threads: int = 1
    """Torch intra-op threads of the learner."""
    discrete_approaches: int = 0
    """0: the policy acts in the env's continuous approach box. N > 0: it chooses one of N fixed approaches spread
    over the box (``agents.sb3.approach_table``, the first N Halton points), a categorical policy that can put its
    mass on a few separate approaches (PPO, recurrent PPO and maskable PPO, which needs them; the evaluation maps
    the choice back to the approach). A resumed run needs the N it was started with."""
    env: HapticRecogConfig = field(default_factory=HapticRecogConfig)
    """The env's settings (:class:`haptic_env.config.HapticRecogConfig`), starting from the ``--env-id`` variant's
    (``haptic_env.variant_config``): ``--env.backend replay`` on ``HapticRecogMuJoCo-v0`` trains on the Allegro's
    recorded grasps."""
    env_kwargs: str = "{}"
    """JSON dict of further HapticRecogConfig fields, applied on top of ``--env.*`` (for the mapping fields:
    recognizer_kwargs, backend_kwargs, object_kwargs)."""
    hyperparams: str = "{}"
    """JSON dict of algorithm hyper-parameters, merged into ``agents.sb3.DEFAULT_HYPERPARAMS[algo]``."""
    progress_bar: bool = field(default_factory=lambda: sys.stderr.isatty())
    """Show SB3's progress bar (default: when stderr is a terminal, not in a log file)."""
    verbose: int = 0
    """SB3 verbosity."""


#: (field, minimum) of the run settings checked at parse time
_MINIMUM = {"total_timesteps": 1, "n_envs": 1, "checkpoint_freq": 1, "max_minutes": 0.0, "torch_threads": 1, "seed": 0,
            "env_seed": -1, "discrete_approaches": 0}
#: numpy's legacy seeding takes seeds below 2**32
_MAXIMUM = {"seed": 2**32 - 1, "env_seed": 2**32 - 1}


def env_seed(args: Args) -> int:
    """The first training env's seed: ``--env-seed``, or by default ``haptic_env.splits.training_env_seed(seed)``, apart
    from every evaluation seed."""
    from haptic_env.splits import training_env_seed

    return args.env_seed if args.env_seed >= 0 else training_env_seed(args.seed)


def segment_seeds(args: Args, part: int, used: dict[int, tuple[int, int]] | None = None) -> tuple[int, int]:
    """``(model seed, first env seed)`` of run segment ``part`` (1: the run's start; ``k > 1``: a resume).
    The start has ``--seed`` and :func:`env_seed`; a resumed segment draws fresh numbers instead of replaying the
    start's (stable-baselines3's load would reseed the model with ``--seed``, and the envs would begin again at their
    first episodes): its envs start one past the last seed any earlier segment's envs had, still inside the run's
    block of training env seeds, and its model seed is drawn from ``(seed, k)``. ``used``: ``{j: (first env seed,
    n_envs)}`` of earlier segments ``j`` (their args files: :func:`used_env_seeds`); one not in it is taken to have
    had this segment's ``n_envs``, so with ``n_envs`` unchanged segment ``k``'s envs start ``(k - 1) x n_envs``
    seeds after the run's first."""
    if part == 1:
        return args.seed, env_seed(args)
    model_seed = int(np.random.SeedSequence([args.seed, part]).generate_state(1)[0] % 2**31)
    used = used or {}
    ends = [used[j][0] + used[j][1] if j in used else env_seed(args) + j * args.n_envs for j in range(1, part)]
    return model_seed, max(ends)


def _segment(args: Args) -> tuple[int, dict[int, tuple[int, int]]]:
    """``(part, used)`` of this run: its segment number (1: a start; a resume counts the segments of its run folder
    and of its checkpoint's run, since a resume into a new folder is not that run's start) and the earlier segments'
    env seeds (:func:`used_env_seeds`)."""
    if not args.resume:
        return 1, {}
    run_dir, home = Path(args.run_dir), run_folder(Path(args.resume))
    return max(2, _next_part(run_dir), _next_part(home)), used_env_seeds(run_dir, home)


def _check_env_seed_block(args: Args) -> None:
    """A usage error when this segment's envs would leave the run's block of default training env seeds (into the next
    ``--seed``'s envs: ``--n-envs`` past the block, or many resumed segments); none with ``--env-seed``."""
    if args.env_seed >= 0:
        return
    from haptic_env.splits import TRAINING_ENV_SEED_BLOCK, training_env_seed

    part, used = _segment(args)
    first = segment_seeds(args, part, used)[1]
    end = training_env_seed(args.seed) + TRAINING_ENV_SEED_BLOCK
    if first + args.n_envs > end:
        _usage_error(f"argument --n-envs: this segment's envs would have seeds {first}..{first + args.n_envs - 1}, "
                     f"past the {TRAINING_ENV_SEED_BLOCK} training env seeds of --seed {args.seed} (up to {end - 1}; "
                     "the next --seed's envs start there): use fewer --n-envs, or give --env-seed")


def used_env_seeds(*folders: Path) -> dict[int, tuple[int, int]]:
    """``{segment: (first env seed, n_envs)}`` of the run segments whose args files in ``folders`` say them
    (``args.json``: ``first_env_seed``; ``args.part<k>.json``: ``segment_env_seed``); an unreadable one is left out.
    A segment in two folders (a run resumed into another) counts with the later of its seed ranges' ends."""
    from haptic_env.numbers import whole_number

    used: dict[int, tuple[int, int]] = {}
    for folder in folders:
        for k, path in _parts(folder).items():
            try:
                record = json.loads(path.read_text()) if path is not None else {}
            except (OSError, ValueError):
                continue
            first = whole_number(record.get("first_env_seed" if k == 1 else "segment_env_seed"))
            n = whole_number(record.get("n_envs"))
            if first is not None and n is not None and n >= 1 and (k not in used or first + n > sum(used[k])):
                used[k] = (first, n)
    return used


def _usage_error(message: str):
    """A one-line usage error (exit status 2) before any run file is written."""
    print(f"usage: train.py [-h] [OPTIONS]\ntrain.py: error: {message}", file=sys.stderr, flush=True)
    raise SystemExit(2)


def parse_args(argv: list[str] | None = None) -> Args:
    """The flags as :class:`Args`; bad values (unknown algorithm, zero steps or envs, JSON that is not an object,
    env settings ``HapticRecogConfig`` rejects, a missing ``--resume`` file or one this run cannot go on from:
    :func:`_resume_problem`) exit with a one-line usage error."""
    args, env, _ = _parse(argv)
    if env is not None:
        env.close()
    return args


def _parse(argv: list[str] | None) -> tuple[Args, object | None, tuple[Path, int] | None]:
    """:func:`parse_args`, the env a ``--resume``'s spaces were checked in (None when none was built), which
    :func:`main` hands to the training's envs rather than build it again, and, when a run resumed from its folder or
    its final model has that model at ``--total-timesteps`` already, ``(final model, its steps)`` (nothing is to
    train, and no env is built; None otherwise)."""
    import tyro

    from haptic_env import ENV_VARIANTS, variant_config

    argv = sys.argv[1:] if argv is None else list(argv)
    env_id = _env_id(argv)
    if env_id not in ENV_VARIANTS:
        _usage_error(f"argument --env-id: unknown env {env_id!r}; choose from {list(ENV_VARIANTS)}")
    try:  # --env.* start from the variant's whole config, so that a flag changes a field the variant sets too
        args = tyro.cli(Args, args=argv, default=Args(env_id=env_id, env=variant_config(env_id)),
                        description=__doc__.split("\n\n")[0])
    except (TypeError, ValueError, FileNotFoundError) as exc:  # HapticRecogConfig's validation of --env.*
        _usage_error(f"env settings: {exc}")
    for name, lo in _MINIMUM.items():
        value = getattr(args, name)
        if not value >= lo:  # NaN too (--max-minutes nan was no limit)
            _usage_error(f"argument --{name.replace('_', '-')}: must be >= {lo}, got {value}")
    for name, hi in _MAXIMUM.items():
        value = getattr(args, name)
        if value > hi:
            _usage_error(f"argument --{name.replace('_', '-')}: must be <= {hi}, got {value}")
    if not np.isfinite(args.max_minutes):  # inf was taken as a limit never reached
        _usage_error(f"argument --max-minutes: must be finite (0: no limit), got {args.max_minutes}")
    if not args.run_dir.strip():
        _usage_error("argument --run-dir: must name a folder, got ''")
    try:  # an existing file, or a path under one, was a traceback after the env settings were checked
        output_path("folder")(args.run_dir)
    except argparse.ArgumentTypeError as exc:
        _usage_error(f"argument --run-dir: {exc}")
    from agents.sb3 import discrete_approaches_problem

    problem = discrete_approaches_problem(args.discrete_approaches, args.algo, args.vec)
    if problem is not None:
        _usage_error(f"argument --discrete-approaches: {problem}")
    for flag, text in (("--env-kwargs", args.env_kwargs), ("--hyperparams", args.hyperparams)):
        try:
            value = json.loads(text)
        except json.JSONDecodeError as exc:
            _usage_error(f"argument {flag}: not valid JSON ({exc.msg}): {text!r}")
        if not isinstance(value, dict):
            _usage_error(f"argument {flag}: expected a JSON object ({{...}}), got {text!r}")
    from agents.sb3 import check_hyperparams

    try:
        check_hyperparams(args.algo, json.loads(args.hyperparams), n_envs=args.n_envs)
    except ValueError as exc:
        _usage_error(f"argument --hyperparams: {exc}")
    try:
        config = env_config(args)
    except (TypeError, ValueError, FileNotFoundError) as exc:
        _usage_error(f"env settings: {exc}")
    from haptic_env import NATIVE_BACKENDS

    if args.vec == "native" and config.backend not in NATIVE_BACKENDS:
        _usage_error(f"argument --vec: the native vector env steps the backends {NATIVE_BACKENDS}, got "
                     f"--env.backend {config.backend!r}; use --vec subproc or dummy")
    if args.resume:
        from agents.sb3 import latest_checkpoint

        resume = Path(args.resume)
        from_folder = resume.is_dir()
        if from_folder:
            found = latest_checkpoint(resume, args.algo)
            if found is None:
                _usage_error(f"argument --resume: no {args.algo}_<steps>_steps.zip checkpoint in {resume}")
            args = dataclasses.replace(args, resume=str(found))
        elif not resume.is_file():
            _usage_error(f"argument --resume: checkpoint {args.resume} does not exist")
        other = next((a for a in ALGOS if a != args.algo and Path(args.resume).name.startswith(a + "_")), None)
        if other is not None:
            _usage_error(f"argument --resume: {args.resume} is a {other} checkpoint, not {args.algo} (pass --algo {other})")
        from agents.sb3 import checkpoint_steps

        home = run_folder(Path(args.resume))
        if _flag(argv, "run-dir") is None:
            # a resumed run goes on in its own folder, not in the default one (which may hold another run)
            args = dataclasses.replace(args, run_dir=str(home))
        later = latest_checkpoint(home, args.algo)
        data = _saved_data(Path(args.resume))  # read once: its steps (a final model's) and its action space
        if data is None:  # refused before any file is written (a segment's files, a segment number used up)
            _usage_error(f"argument --resume: {args.resume} is not a model file stable-baselines3 can read (a damaged "
                         "or truncated checkpoint?); resume from an earlier checkpoint of its run")
        steps = _saved_steps(Path(args.resume), data)
        if (Path(args.run_dir).resolve() == home.resolve() and later is not None and steps is not None
                and checkpoint_steps(later) > steps):
            # in its run's folder the resumed run's checkpoints would sit beside the later ones of the line it
            # leaves, and a later --resume of the folder would go on from those (another --run-dir: a new line)
            _usage_error(f"argument --resume: {args.resume} is not its run's latest checkpoint ({later.name}); go on "
                         "from it into another --run-dir, move the later checkpoints away, or resume from the latest")
        saved = _saved_approaches(data)
        if saved != args.discrete_approaches:
            _usage_error(f"argument --discrete-approaches: {args.resume} was trained with --discrete-approaches "
                         f"{saved}, got {args.discrete_approaches} (resume with the N it was started with)")
        from agents.sb3 import replay_envs_problem

        problem = replay_envs_problem(args.algo, data.get("n_envs"), args.n_envs)
        if problem is not None:
            _usage_error(f"argument --n-envs: {args.resume} {problem}")
        final = home / f"{args.algo}_final.zip"
        if (from_folder or Path(args.resume).resolve() == final.resolve()) and final.is_file() \
                and Path(args.run_dir).resolve() == home.resolve():
            done = _final_steps(final)
            if done is not None and done >= max(args.total_timesteps, steps or 0):
                # a finished run (a job run again after it got there, say): nothing to train, no segment written (it
                # added one that trained nothing, and from a folder whose latest checkpoint was short of the final
                # model trained that part again and replaced the final model); a checkpoint named itself trains
                return args, None, (final, done)
        _check_env_seed_block(args)
        problem, env = _resume_problem(args, data, config)
        if problem is not None:
            _usage_error(f"argument --resume: {problem}")
        return args, env, None
    _check_env_seed_block(args)
    return args, None, None


def _probe(args: Args, config: HapticRecogConfig):
    """The run's first env, built before any file is written (by :func:`main` for a fresh run, by
    :func:`_resume_problem` for a resumed one; the training's envs take it over): an env that cannot be made (an
    unknown hand, say) is a usage error, not a traceback after the run folder's ``args.json`` and ``monitor/``. (The
    recogniser is built at the first reset, by the training's set-up.)"""
    import haptic_env

    try:
        with _signals_stop_the_set_up():  # a hand env's first make builds its grasp pool: minutes
            return haptic_env.make(config, env_id=args.env_id)
    except (TypeError, ValueError, FileNotFoundError) as exc:
        _usage_error(f"env settings: {exc}")
    except _SetUpStopped as exc:
        _exit_set_up_stopped(exc)


def _resume_problem(args: Args, data: dict, config: HapticRecogConfig) -> tuple[str | None, object | None]:
    """Why ``args.resume`` (its :func:`_saved_data` ``data``) cannot go on in this run's env (``config``), or None:
    a SAC checkpoint without its replay buffer (``agents.sb3.replay_buffer_problem``), or a model whose observation
    (or continuous action) space is not the env's, which stable-baselines3's load refuses only once the segment's
    files are written. With the env built to compare the spaces (closed, and None, when there is a problem), for the
    training to take over."""
    from agents.sb3 import replay_buffer_problem

    problem = replay_buffer_problem(args.resume, args.algo)
    if problem is not None:
        return problem, None
    env = _probe(args, config)
    problem = _space_problem(args, data, env)
    if problem is not None:
        env.close()
        return problem, None
    return None, env


def _space_problem(args: Args, data: dict, env) -> str | None:
    """Why ``args.resume`` (its saved ``data``) cannot go on in ``env``: another observation (or continuous action)
    space, or None."""
    spaces = [("observation", data.get("observation_space"), env.observation_space)]
    if not args.discrete_approaches:  # the fixed approaches' count is checked above
        spaces.append(("action", data.get("action_space"), env.action_space))
    for what, saved, now in spaces:
        if saved is not None and saved != now:
            size = lambda space: "x".join(map(str, getattr(space, "shape", None) or ())) + "-dim"  # noqa: E731
            other = (f"a {size(saved)} {what}, this run's env has a {size(now)} one" if size(saved) != size(now)
                     else f"another {what} space than this run's env ({saved} != {now})")
            return (f"{args.resume} was trained with {other}: resume with the --env-id and --env.* settings it was "
                    "trained with (its run's args.json)")
    return None


def run_folder(checkpoint: Path) -> Path:
    """The run folder a checkpoint belongs to: the one above its ``checkpoints/``, else its own (the path resolved:
    ``--resume ppo_64_steps.zip`` from inside ``checkpoints/`` names the run above it)."""
    checkpoint = Path(os.path.abspath(checkpoint))  # not resolve(): a linked file belongs to its link's run
    return checkpoint.parent.parent if checkpoint.parent.name == "checkpoints" else checkpoint.parent


def refuse_a_held_run_dir(args: Args) -> None:
    """A run into a ``--run-dir`` that holds another run's checkpoints or final model is a usage error before any
    file is written: a fresh run there would mix with it (a later ``--resume`` would go on from that run's model
    under this run's settings), and a resumed one would replace its checkpoints and final model. A resumed run in
    its own folder (the default with ``--resume``) goes on. A run still training there is refused by
    :func:`hold_run_dir` (which :func:`main` enters first, so a run that began meanwhile is seen here)."""
    from agents.sb3 import latest_checkpoint

    run_dir = Path(args.run_dir)
    if args.resume and run_dir.resolve() == run_folder(Path(args.resume)).resolve():
        return
    checkpoint = latest_checkpoint(run_dir)
    final = next(iter(sorted(run_dir.glob("*_final.zip"))), None)
    if checkpoint is not None:
        _usage_error(f"argument --run-dir: {run_dir} already holds a run ({checkpoint.name}); continue it with "
                     f"--resume {run_dir}, or choose another --run-dir")
    if final is not None:
        _usage_error(f"argument --run-dir: {run_dir} already holds a finished run ({final.name}); choose another "
                     "--run-dir")


@contextlib.contextmanager
def hold_run_dir(run_dir: Path) -> Iterator[None]:
    """Hold ``run_dir`` for this training (created if missing): a second training into the same folder while this
    one runs is a usage error, since their Monitor files, args and checkpoints would mix. An advisory lock
    (``fcntl.flock``) on ``run_dir/.train.lock``, which holds the holder's pid; the system releases it when the
    process ends, however it ends (a killed run leaves no stale lock). Where ``fcntl`` is missing (Windows) the
    folder is not held."""
    run_dir.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    fd = os.open(run_dir / ".train.lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            _usage_error(f"argument --run-dir: {run_dir} is in use by another training (pid {holder}); wait for it "
                         "or choose another --run-dir")
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _saved_data(path: Path) -> dict | None:
    """:func:`agents.sb3.saved_data` (None for a file SB3 cannot read: :func:`_parse` refuses to resume from it)."""
    from agents.sb3 import saved_data

    return saved_data(path)


def _saved_steps(path: Path, data: dict | None = None) -> int | None:
    """The steps a model file was saved at: a checkpoint's name says (``ppo_20000_steps.zip``), a final model's data
    holds them (``data``: its :func:`_saved_data`, read here if not given); None if neither does."""
    from agents.sb3 import checkpoint_steps

    steps = checkpoint_steps(path)
    if steps is not None:
        return steps
    data = _saved_data(path) if data is None else data
    return None if data is None or data.get("num_timesteps") is None else int(data["num_timesteps"])


def _final_steps(path: Path) -> int | None:
    """The steps in a model file's ``data`` member (stable-baselines3's zip), read without its parameters; None when
    the file or that member cannot be read (the resume then goes on as if there were no final model)."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            steps = json.loads(z.read("data")).get("num_timesteps")
    except (OSError, zipfile.BadZipFile, KeyError, ValueError, AttributeError):
        return None
    return int(steps) if isinstance(steps, int) and not isinstance(steps, bool) else None


def _saved_approaches(data: dict) -> int:
    """The ``--discrete-approaches`` a model file (its :func:`_saved_data` ``data``) was trained with (0: the
    continuous action)."""
    import gymnasium as gym

    space = data.get("action_space")
    return int(space.n) if isinstance(space, gym.spaces.Discrete) else 0


def _flag(argv: list[str], name: str) -> str | None:
    """The value of flag ``--<name>`` in ``argv`` (its last one, as tyro reads it; ``--a-b`` or ``--a_b``, with a
    space or ``=``), or None when it is not given."""
    spellings = (f"--{name}", f"--{name.replace('-', '_')}")
    value = None
    for i, a in enumerate(argv):
        if a in spellings and i + 1 < len(argv):
            value = argv[i + 1]
        elif a.startswith(tuple(s + "=" for s in spellings)):
            value = a.split("=", 1)[1]
    return value


def _env_id(argv: list[str]) -> str:
    """The ``--env-id`` of ``argv`` (its last one, as tyro reads it), or the default."""
    env_id = _flag(argv, "env-id")
    return Args.env_id if env_id is None else env_id


def env_config(args: Args) -> HapticRecogConfig:
    """``--env.*`` with ``--env-kwargs`` on top (a mapping field there updates the ``--env-id`` variant's, e.g. its
    ``backend_kwargs``' hand: :func:`haptic_env.config.with_keys`)."""
    return resolve_env_config(args.env, None, json.loads(args.env_kwargs))


#: What a resumed segment may change without note: its length, its checkpoints, its output and its machine's threads
_SEGMENT_ONLY = ("total_timesteps", "max_minutes", "checkpoint_freq", "progress_bar", "verbose", "torch_threads",
                 "resume", "run_dir", "segment_seed", "segment_env_seed", "resumed_at_step")


def settings_changed(record: dict, checkpoint: Path) -> list[str]:
    """On ``--resume``: ``"name: old -> new"`` for each run setting of ``record`` (what this segment writes to its
    ``args*.json``) that differs from the ``args.json`` of the run ``checkpoint`` belongs to (its folder, or the one
    above ``checkpoints/``; a folder a run was resumed into: its earliest segment's ``args.part<k>.json``); nothing
    when there is none or it is unreadable. Fine-tuning a checkpoint on another env
    is allowed; it is said, not silent."""
    folder = run_folder(checkpoint)
    parts = {k: p for k, p in _parts(folder).items() if p is not None}
    try:  # the run's start, or (a run resumed into this folder from another) its earliest segment here
        old = json.loads(parts[min(parts)].read_text())
    except (OSError, ValueError):  # none (min of nothing), unreadable, not JSON
        return []
    new = json.loads(json.dumps(record, default=str))
    out = []
    for name in sorted(set(old) | set(new)):
        if name in _SEGMENT_ONLY or old.get(name) == new.get(name):
            continue
        if name == "env_config" and isinstance(old.get(name), dict) and isinstance(new.get(name), dict):
            a, b = old[name], new[name]
            out += [f"env.{k}: {a.get(k)!r} -> {b.get(k)!r}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
        else:
            out.append(f"{name}: {old.get(name)!r} -> {new.get(name)!r}")
    return out


def _parts(run_dir: Path) -> dict[int, Path | None]:
    """The run segments with files in ``run_dir``: ``k -> its args file`` (None if only its Monitor CSVs are there);
    segment 1 writes ``args.json`` + ``monitor/<rank>.monitor.csv``, segment ``k`` ``args.part<k>.json`` +
    ``monitor/<rank>.part<k>.monitor.csv``."""
    from agents.evaluate import run_segment

    found: dict[int, Path | None] = {}
    for p in (run_dir / "monitor").glob("*.monitor.csv"):
        found.setdefault(run_segment(p.name), None)
    for p in run_dir.glob("args*.json"):
        if re.fullmatch(r"args(\.part\d+)?\.json", p.name):
            found[run_segment(p.name)] = p
    return found


def _drop_stale_monitors(run_dir: Path) -> None:
    """Remove the Monitor files (and segment args) that a run killed before its first checkpoint left in ``run_dir``,
    before a fresh run writes its own there: its envs' files would otherwise sit beside the new run's (another
    ``--n-envs`` leaves ranks the new run does not write) and join its learning curves. Called only once
    :func:`refuse_a_held_run_dir` has found no checkpoint or final model in the folder; says what it removed."""
    stale = sorted((run_dir / "monitor").glob("*.monitor.csv")) + sorted(
        p for k, p in _parts(run_dir).items() if k > 1 and p is not None)
    if stale:
        print(f"[train] {run_dir}: removing {len(stale)} file(s) of an earlier run that saved no checkpoint "
              f"({', '.join(p.name for p in stale[:4])}{', ...' if len(stale) > 4 else ''})", file=sys.stderr,
              flush=True)
        for p in stale:
            p.unlink()


def _next_part(run_dir: Path) -> int:
    """One past the last run segment with files in ``run_dir`` (:func:`_parts`; 1 in a new folder): a segment's
    files are never written over, and its seeds are its own (:func:`segment_seeds`)."""
    return max(_parts(run_dir), default=0) + 1


class _SetUpStopped(Exception):
    """SIGINT / SIGTERM before learning began (:func:`_signals_stop_the_set_up`)."""

    def __init__(self, signum: int):
        import signal

        super().__init__(signal.Signals(signum).name)
        self.signum, self.name = signum, signal.Signals(signum).name


def _exit_set_up_stopped(exc: _SetUpStopped) -> NoReturn:
    """One line and exit status 130 / 143: a signal before learning began (nothing learned, nothing saved)."""
    print(f"[train] stopped by {exc.name} before learning began (nothing learned, nothing saved); run the same "
          "command again", file=sys.stderr, flush=True)
    raise SystemExit(128 + exc.signum) from None


@contextlib.contextmanager
def _signals_stop_the_set_up() -> Iterator[None]:
    """SIGINT / SIGTERM while the envs and the model are built or loaded raise :class:`_SetUpStopped` (which
    :func:`_exit_set_up_stopped` turns into one line and exit status 130 / 143, not a traceback; the first env, in
    :func:`_probe`, too); ``agents.sb3.train`` puts its own handlers over these while it learns (stop at the next
    step, save a checkpoint) and puts these back after."""
    from agents.sb3 import handling_signals

    def handler(signum, frame):
        raise _SetUpStopped(signum)

    with handling_signals(handler):
        yield


def main(argv: list[str] | None = None) -> Path:
    args, env, finished = _parse(argv)  # env: a --resume's, built once: the training's envs take it over
    if finished is not None:  # the folder held all the same: a training running there is named
        final, steps = finished
        with hold_run_dir(Path(args.run_dir)):
            print(f"[train] {final} is at {steps} steps, --total-timesteps {args.total_timesteps} in all: nothing to "
                  "train (raise --total-timesteps to go on)", flush=True)
        return final
    if env is None:  # a fresh run: its folder's refusals first (cheap; checked again once held), then its env
        refuse_a_held_run_dir(args)
        env = _probe(args, env_config(args))
    try:
        with hold_run_dir(Path(args.run_dir)):  # checked held: a run that began meanwhile has its files there now
            refuse_a_held_run_dir(args)
            return _train(args, env)
    finally:
        if env is not None:  # refused, stopped before the envs were built, or closed with them (again: harmless)
            env.close()


def _train(args: Args, probe=None) -> Path:
    """Train in ``args.run_dir``, which :func:`main` holds. ``probe``: an env of the run's config already built
    (:func:`_parse`'s), which the vec env takes over rather than build another."""
    import torch

    from agents import sb3

    run_dir = Path(args.run_dir)
    config = env_config(args)
    first_env_seed = env_seed(args)
    # a resumed run keeps the earlier args and Monitor files; its segment number counts the segments of its
    # checkpoint's run too (a resume into a new folder is not that run's start: other seeds than the start's)
    part, used = _segment(args)
    from agents.evaluate import segment_suffix

    suffix = segment_suffix(part)
    seed, segment_env_seed = segment_seeds(args, part, used)
    # explicit seeding: python, numpy, torch; env rank r is seeded segment_env_seed + r by make_vec_env
    random.seed(seed)
    np.random.seed(seed)  # only for third-party code that still uses the global RNG
    torch.manual_seed(seed)
    torch.set_num_threads(args.torch_threads)
    record = {**{f.name: getattr(args, f.name) for f in dataclasses.fields(args) if f.name != "env"},
              "first_env_seed": first_env_seed,
              **({} if part == 1 else {"segment_seed": seed, "segment_env_seed": segment_env_seed,
                                       "resumed_at_step": _saved_steps(Path(args.resume))}),
              "env_config": {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(config).items()}}
    if args.resume:
        changed = settings_changed(record, Path(args.resume))
        if changed:  # the model keeps the checkpoint's hyperparameters whatever --hyperparams says
            print(f"[train] resuming {args.resume} with other settings than its run's: {'; '.join(changed)}"
                  + (" (--hyperparams: the checkpoint's are kept)" if any(c.startswith("hyperparams") for c in changed)
                     else ""), file=sys.stderr, flush=True)
    from haptic_env.cache import atomic_write

    if part == 1:  # a fresh run: Monitor files here are a killed run's that saved nothing (refuse_a_held_run_dir)
        _drop_stale_monitors(run_dir)
    with atomic_write(run_dir / f"args{suffix}.json", "w") as fh:  # whole or absent: a resume compares with it
        fh.write(json.dumps(record, indent=2, default=str))

    venv = None
    try:
        with _signals_stop_the_set_up():  # learn() has its own (a checkpoint); this covers building the envs and model
            t0 = time.time()
            venv = sb3.make_vec_env(config, n_envs=args.n_envs, seed=segment_env_seed, log_dir=run_dir, vec=args.vec,
                                    env_id=args.env_id, monitor_suffix=suffix,
                                    discrete_approaches=args.discrete_approaches,
                                    probe=probe)
            action = (f"one of {args.discrete_approaches} approaches" if args.discrete_approaches
                      else f"{venv.action_space.shape[0]}-dim action")
            print(f"[train] {args.algo} on {args.env_id} ({args.n_envs} envs, {venv.observation_space.shape[0]}-dim "
                  f"obs, {action}); envs ready in {time.time() - t0:.1f} s", flush=True)
            t0 = time.time()
            model, path = sb3.train(
                args.algo, venv, args.total_timesteps, run_dir, seed=seed, checkpoint_freq=args.checkpoint_freq,
                resume=args.resume or None, progress_bar=args.progress_bar, verbose=args.verbose,
                max_minutes=args.max_minutes or None,
                **json.loads(args.hyperparams),
            )
    except _SetUpStopped as exc:
        _exit_set_up_stopped(exc)
    except sb3.TrainingInterrupted as exc:
        extra = " (+ replay buffer)" if sb3.checkpoint_extras(exc.path).get("replay_buffer") else ""
        print(f"[train] {exc.reason} at {exc.num_timesteps} steps; saved {exc.path}{extra}; "
              f"continue with the same flags plus --resume {run_dir}", file=sys.stderr, flush=True)
        raise SystemExit(exc.exit_code) from None
    finally:
        if venv is not None:  # however training ended (its env workers are ended with it)
            sb3.close_vec_env(venv)
    dt = time.time() - t0
    steps = int(model.num_timesteps)
    new = steps - int(getattr(model, "_num_timesteps_at_start", 0)) if args.resume else steps
    short = (f", stopped by --max-minutes {args.max_minutes:g} before --total-timesteps {args.total_timesteps}"
             if steps < args.total_timesteps else "")
    print(f"[train] {steps} steps ({new} in this run{short}) in {dt / 60:.1f} min ({new / dt:.0f} steps/s); "
          f"saved {path}", flush=True)
    return path


if __name__ == "__main__":
    main()
