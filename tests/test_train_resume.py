"""Training loses nothing: a real tiny ``train.py`` run stopped mid-way (SIGTERM, Ctrl-C to the process group,
a killed env worker) saves a checkpoint and exits with one line naming it; ``--resume <run dir>`` with the
same flags ends at the same step count and keeps every earlier file (checkpoints, Monitor CSVs, TensorBoard
events, args) byte for byte."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _args(algo: str, total: int, run: Path, recognizer_kwargs: dict, hyperparams: dict, n_envs: int = 1,
          vec: str = "dummy") -> list[str]:
    return ["--algo", algo, "--total-timesteps", str(total), "--n-envs", str(n_envs), "--vec", vec,
            "--run-dir", str(run), "--checkpoint-freq", "128", "--env.max-grasps", "10",
            "--env-kwargs", json.dumps({"recognizer_kwargs": recognizer_kwargs}),
            "--hyperparams", json.dumps(hyperparams)]


def _start(args: list[str], new_session: bool = False) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "train.py", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=new_session)


def _finish(proc: subprocess.Popen, timeout: float = 240) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"train.py did not exit in {timeout} s:\n{out}\n{err}")
    return proc.returncode, out, err


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 180) -> None:
    t0 = time.monotonic()
    while not path.exists():
        if proc.poll() is not None:
            rc, out, err = _finish(proc)
            pytest.fail(f"train.py exited ({rc}) before {path.name} appeared:\n{out}\n{err}")
        if time.monotonic() - t0 > timeout:
            proc.kill()
            pytest.fail(f"no {path.name} after {timeout} s")
        time.sleep(0.02)


def _snapshot(run: Path) -> dict[str, str]:
    """The run's files and their hashes (the lock, which holds the running training's pid, is no run file)."""
    return {str(p.relative_to(run)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(run.rglob("*")) if p.is_file() and p.name != ".train.lock"}


def _saved_checkpoint(err: str, run: Path, algo: str) -> Path:
    """The checkpoint the one-line stop message names (the message is the last stderr line)."""
    line = err.strip().splitlines()[-1]
    assert line.startswith("[train] ") and f"--resume {run}" in line, err
    path = Path(line.split("saved ", 1)[1].split(";")[0].split(" (+")[0])
    assert path.parent == run / "checkpoints" and path.name.startswith(f"{algo}_") and path.exists(), line
    return path


def _steps(checkpoint: Path) -> int:
    return int(checkpoint.name.split("_")[-2])


def _resume_and_check(args: list[str], run: Path, algo: str, total: int, before: dict[str, str]) -> None:
    """Resume with the same flags plus ``--resume <run dir>``: ends at ``total`` steps, every earlier file
    kept unchanged, the new Monitor segment read after the old one."""
    from agents.evaluate import read_monitor
    from agents.sb3 import load_model

    rc, out, err = _finish(_start(args + ["--resume", str(run)]))
    assert rc == 0, f"{out}\n{err}"
    assert load_model(run / f"{algo}_final.zip").num_timesteps == total
    after = _snapshot(run)
    lost = {k for k in before if after.get(k) != before[k]}
    assert not lost, f"changed or removed by the resumed run: {sorted(lost)}"
    assert (run / "args.part2.json").exists()
    assert json.loads((run / "args.json").read_text())["resume"] == ""
    parts = sorted((run / "monitor").glob("*.part2.monitor.csv"))
    assert parts, sorted(after)
    rows = sum(len(f.read_text().splitlines()) - 2 for f in (run / "monitor").glob("*.monitor.csv"))
    data = read_monitor(run / "monitor")
    assert 0 < len(data["l"]) <= rows and (sorted(data["t"]) == data["t"]).all()
    # the first segment's episodes past the step the resume went on from are left out (played again after it)
    resumed = json.loads((run / "args.part2.json").read_text())["resumed_at_step"]
    first = [f for f in (run / "monitor").glob("*.monitor.csv") if ".part" not in f.name]
    kept = len(data["l"]) - sum(len(f.read_text().splitlines()) - 2 for f in parts)
    first_l = sorted(((float(r[2]) + json.loads(f.read_text().splitlines()[0][1:])["t_start"], float(r[1]))
                      for f in first for r in (line.split(",") for line in f.read_text().splitlines()[2:])))
    assert 0 < resumed < total and sum(l for _, l in first_l[:kept]) <= resumed
    events = sorted((run / "tb").rglob("events.out.tfevents*"))
    assert len(events) >= 2 and len({e.parent for e in events}) == 1  # the same TensorBoard run continues


def test_sigterm_stops_saves_and_resume_ends_at_the_same_step(env_config, small_recognizer_kwargs, tmp_path,
                                                                   capsys):
    """PPO, one in-process env: SIGTERM mid-run -> exit 143, one line naming the checkpoint, which sits at a
    rollout boundary (the unfinished rollout is dropped); the resumed run ends at exactly 1536 steps."""
    run = tmp_path / "ppo"
    args = _args("ppo", 1536, run, small_recognizer_kwargs, {"n_steps": 64, "batch_size": 32, "n_epochs": 2})
    proc = _start(args)
    _wait_for(run / "checkpoints" / "ppo_256_steps.zip", proc)
    proc.send_signal(signal.SIGTERM)
    rc, out, err = _finish(proc)
    assert rc == 128 + signal.SIGTERM, f"{out}\n{err}"
    assert "stopped by SIGTERM" in err.strip().splitlines()[-1]
    ckpt = _saved_checkpoint(err, run, "ppo")
    assert 256 <= _steps(ckpt) < 1536 and _steps(ckpt) % 64 == 0
    assert "Traceback" not in err
    _resume_and_check(args, run, "ppo", 1536, _snapshot(run))
    # resuming a finished run is a no-op that still ends cleanly and writes nothing (in-process: quicker)
    import train

    before = _snapshot(run)
    assert train.main(args + ["--resume", str(run)]) == run / "ppo_final.zip"
    assert "ppo_final.zip is at 1536 steps, --total-timesteps 1536 in all: nothing to train" in capsys.readouterr().out
    assert _snapshot(run) == before


@pytest.mark.slow
def test_ctrl_c_to_the_process_group_saves_sac_with_its_replay_buffer(env_config, small_recognizer_kwargs,
                                                                      tmp_path):
    """SAC, two SubprocVecEnv workers, SIGINT to the whole process group (what Ctrl-C in a terminal does): the
    workers ignore it, the main process saves model + replay buffer and exits 130; the resumed run loads the
    buffer (its fill level matches the step count) and ends at 512 steps."""
    from stable_baselines3.common.save_util import load_from_pkl

    run = tmp_path / "sac"
    args = _args("sac", 512, run, small_recognizer_kwargs,
                 {"learning_starts": 32, "batch_size": 32, "buffer_size": 1000}, n_envs=2, vec="subproc")
    proc = _start(args, new_session=True)
    _wait_for(run / "checkpoints" / "sac_128_steps.zip", proc)
    time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    rc, out, err = _finish(proc)
    assert rc == 128 + signal.SIGINT, f"{out}\n{err}"
    line = err.strip().splitlines()[-1]
    assert "stopped by SIGINT" in line and "(+ replay buffer)" in line, err
    assert "Traceback" not in err
    ckpt = _saved_checkpoint(err, run, "sac")
    n = _steps(ckpt)
    assert 128 <= n < 512
    buf = load_from_pkl(run / "checkpoints" / f"sac_replay_buffer_{n}_steps.pkl")
    assert buf.pos == n // 2  # every counted step is stored (2 envs)
    _resume_and_check(args, run, "sac", 512, _snapshot(run))
    buf = load_from_pkl(run / "checkpoints" / "sac_replay_buffer_384_steps.pkl")
    assert buf.pos == 384 // 2  # the resumed run started from the saved buffer


def _workers(pid: int) -> list[int]:
    """The SubprocVecEnv workers under ``pid``: the children of its multiprocessing forkserver."""
    def children(p: int) -> list[int]:
        out = []
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                out += [int(c) for c in (task / "children").read_text().split()]
            except OSError:
                pass
        return out

    def cmdline(p: int) -> str:
        try:
            return Path(f"/proc/{p}/cmdline").read_bytes().decode(errors="replace")
        except OSError:
            return ""

    servers = [c for c in children(pid) if "forkserver" in cmdline(c)]
    return [w for s in servers for w in children(s)]


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc to find the workers")
def test_a_dead_worker_saves_and_resume_completes(env_config, small_recognizer_kwargs, tmp_path):
    """PPO, two SubprocVecEnv workers, one killed (SIGKILL) mid-run: the main process saves, names the file,
    exits 1 without hanging; the resumed run ends at 1024 steps with every earlier file kept."""
    run = tmp_path / "ppo"
    args = _args("ppo", 1024, run, small_recognizer_kwargs, {"n_steps": 32, "batch_size": 32, "n_epochs": 2},
                 n_envs=2, vec="subproc")
    proc = _start(args)
    _wait_for(run / "checkpoints" / "ppo_128_steps.zip", proc)
    workers = _workers(proc.pid)
    assert len(workers) == 2, workers
    os.kill(workers[0], signal.SIGKILL)
    rc, out, err = _finish(proc, timeout=60)
    assert rc == 1, f"{out}\n{err}"
    assert "an env worker died" in err.strip().splitlines()[-1], err
    ckpt = _saved_checkpoint(err, run, "ppo")
    assert 128 <= _steps(ckpt) < 1024 and _steps(ckpt) % 64 == 0
    _resume_and_check(args, run, "ppo", 1024, _snapshot(run))


def test_vecnormalize_stats_are_checkpointed_and_resumed(env_config, tmp_path):
    """A ``VecNormalize`` run (in-process): every checkpoint has its statistics, and resuming into the caller's
    fresh ``VecNormalize`` continues them instead of starting over; ``latest_checkpoint`` picks the most steps."""
    from stable_baselines3.common.save_util import load_from_pkl
    from stable_baselines3.common.vec_env import VecNormalize

    from agents import sb3

    def venv():
        return VecNormalize(sb3.make_vec_env(env_config.replace(max_grasps=10), n_envs=1, vec="dummy"))

    hp = {"n_steps": 32, "batch_size": 32, "n_epochs": 1}
    v = venv()
    model, _ = sb3.train("ppo", v, 128, tmp_path, checkpoint_freq=64, **hp)
    v.close()
    ckpt = sb3.latest_checkpoint(tmp_path, "ppo")
    assert ckpt.name == "ppo_128_steps.zip" and sb3.latest_checkpoint(tmp_path, "sac") is None
    extras = sb3.checkpoint_extras(ckpt)
    assert set(extras) == {"vecnormalize"} and extras["vecnormalize"].name == "ppo_vecnormalize_128_steps.pkl"
    saved = load_from_pkl(extras["vecnormalize"]).obs_rms.count
    v = venv()
    model, _ = sb3.train("ppo", v, 192, tmp_path, checkpoint_freq=64, resume=ckpt, progress_bar=True, **hp)
    v.close()  # (with SB3's progress bar, which needs rich: train.py shows it in a terminal)
    assert model.num_timesteps == 192
    assert v.obs_rms.count >= saved + 64  # continued from the saved statistics
    assert load_from_pkl(tmp_path / "checkpoints" / "ppo_vecnormalize_192_steps.pkl").obs_rms.count >= saved + 64


@pytest.mark.parametrize("resume", [False, True])
def test_training_envs_keep_their_seeds_when_the_model_is_built_or_loaded(env_config, tmp_path, resume):
    """SB3 seeds a model's env with the model's seed + rank when it builds or loads the model, which would start the
    training envs on the evaluation seeds' episodes (``--seed 0``: test seeds 0 and 1); ``train`` keeps the seeds the
    envs were made with (train.py's ``10000 + 1000 x seed + rank``), for a fresh run and for a resumed one."""
    from agents import sb3

    hp = {"n_steps": 16, "batch_size": 16, "n_epochs": 1}
    ckpt = None
    if resume:
        venv = sb3.make_vec_env(env_config.replace(max_grasps=10), n_envs=2, seed=10000, vec="dummy")
        sb3.train("ppo", venv, 32, tmp_path, seed=0, checkpoint_freq=32, **hp)
        venv.close()
        ckpt = sb3.latest_checkpoint(tmp_path, "ppo")
    venv = sb3.make_vec_env(env_config.replace(max_grasps=10), n_envs=2, seed=10000, vec="dummy")
    first = []
    for env in venv.envs:  # record each env's first reset seed
        def reset(*a, _real=env.reset, **kw):
            first.append(kw.get("seed"))
            return _real(*a, **kw)
        env.reset = reset
    sb3.train("ppo", venv, 64 if resume else 32, tmp_path, seed=7, checkpoint_freq=32, resume=ckpt, **hp)
    venv.close()
    assert first[:2] == [10000, 10001]
    import torch

    assert torch.initial_seed() == 7  # a resumed model is seeded with the caller's seed, not the checkpoint's 0


def test_a_fresh_run_is_refused_a_folder_that_holds_a_run_and_a_resume_says_what_it_changes(
        small_recognizer_kwargs, tmp_path, usage_error, capsys, monkeypatch):
    """A fresh run into a folder that holds another run's checkpoints is refused (a later ``--resume`` would go on
    from that run's model under this run's settings); resuming with other run settings than the run's own
    ``args.json`` (fine-tuning on another env is allowed) says which, and that ``--hyperparams`` are the
    checkpoint's."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train

    run = tmp_path / "run"
    hp = {"n_steps": 64, "batch_size": 64, "n_epochs": 1}
    first = _args("ppo", 128, run, small_recognizer_kwargs, hp)
    train.main(first)
    usage_error(train.main, first, match=r"--run-dir: .*run already holds a run \(ppo_128_steps.zip\); continue it "
                                         r"with --resume")
    capsys.readouterr()
    more = _args("ppo", 192, run, small_recognizer_kwargs, {**hp, "n_epochs": 2})
    more[more.index("--env.max-grasps") + 1] = "8"
    train.main(more + ["--resume", str(run)])
    err = capsys.readouterr().err
    assert "with other settings than its run's: env.max_grasps: 10 -> 8" in err
    assert "hyperparams: " in err and "(--hyperparams: the checkpoint's are kept)" in err
    # the resumed segment draws fresh episodes and numbers (its own seeds, recorded), not its start's again
    part2 = json.loads((run / "args.part2.json").read_text())
    assert part2["segment_env_seed"] == part2["first_env_seed"] + 1 and part2["segment_seed"] != part2["seed"]
    assert train.segment_seeds(train.parse_args(first), 1) == (0, part2["first_env_seed"])


def test_a_fresh_run_replaces_the_monitor_files_of_a_killed_run_that_saved_nothing(
        small_recognizer_kwargs, tmp_path, capsys, monkeypatch):
    """Monitor files (and segment args) left by a run killed before its first checkpoint are removed before a fresh
    run writes its own: a rank the new run does not have would otherwise join its learning curves."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train

    run = tmp_path / "run"
    (run / "monitor").mkdir(parents=True)
    for name in ("0.monitor.csv", "3.monitor.csv", "0.part2.monitor.csv"):
        (run / "monitor" / name).write_text("stale\n")
    (run / "args.part2.json").write_text("{}")
    capsys.readouterr()
    train.main(_args("ppo", 128, run, small_recognizer_kwargs, {"n_steps": 64, "batch_size": 64, "n_epochs": 1}))
    assert "removing 4 file(s) of an earlier run that saved no checkpoint" in capsys.readouterr().err
    assert sorted(p.name for p in (run / "monitor").iterdir()) == ["0.monitor.csv"]
    assert (run / "monitor" / "0.monitor.csv").read_text() != "stale\n" and not (run / "args.part2.json").exists()


def test_a_run_folder_in_use_by_another_training_is_refused(small_recognizer_kwargs, tmp_path, usage_error,
                                                              monkeypatch):
    """Two trainings into one folder at once would mix their Monitor files, args and checkpoints (the held-run check
    sees only checkpoints, which a young run has none of): the second is refused, naming the first's pid, before it
    writes anything; the folder is free again once the first process is gone, however it ended."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train

    run = tmp_path / "run"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time, train; from pathlib import Path\n"
                               f"with train.hold_run_dir(Path({str(run)!r})):\n"
                               "    print('held', flush=True); time.sleep(60)"],
                              cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        args = _args("ppo", 64, run, small_recognizer_kwargs, {"n_steps": 64, "batch_size": 64, "n_epochs": 1})
        usage_error(train.main, args, match=rf"--run-dir: .*run is in use by another training \(pid {holder.pid}\)")
        assert sorted(p.name for p in run.iterdir()) == [".train.lock"]
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    with train.hold_run_dir(run):  # a killed holder leaves no stale lock
        pass


def test_a_resume_goes_on_in_its_own_run_folder(small_recognizer_kwargs, tmp_path, usage_error, monkeypatch):
    """``--resume`` without ``--run-dir`` goes on in the checkpoint's run folder (it wrote into the default
    ``runs/ppo``, replacing another run's checkpoints and final model there); a ``--run-dir`` that holds another run
    is refused."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train

    hp = {"n_steps": 64, "batch_size": 64, "n_epochs": 1}
    run, other = tmp_path / "run", tmp_path / "other"
    first = _args("ppo", 128, run, small_recognizer_kwargs, hp)
    train.main(first)
    train.main(_args("ppo", 128, other, small_recognizer_kwargs, hp))
    more = _args("ppo", 192, run, small_recognizer_kwargs, hp)
    i = more.index("--run-dir")
    without = more[:i] + more[i + 2:]
    assert train.parse_args(without + ["--resume", str(run)]).run_dir == str(run)
    more[i + 1] = str(other)
    usage_error(train.main, more + ["--resume", str(run)], match=r"--run-dir: .*other already holds a run")
    # an earlier checkpoint of a run with later ones: refused (a later --resume would go back to those)
    import shutil

    ckpts = run / "checkpoints"
    shutil.copy(ckpts / "ppo_128_steps.zip", ckpts / "ppo_64_steps.zip")
    usage_error(train.main, without + ["--resume", str(ckpts / "ppo_64_steps.zip")],
                match=r"--resume: .*ppo_64_steps.zip is not its run's latest checkpoint \(ppo_128_steps.zip\)")
    (ckpts / "ppo_64_steps.zip").unlink()
    # a finished run's final model goes on (no checkpoint comes after it), in its own folder, as a later segment
    assert train.main(without + ["--resume", str(run / "ppo_final.zip"), "--total-timesteps", "256"]) == \
        run / "ppo_final.zip"
    assert json.loads((run / "args.part2.json").read_text())["resume"].endswith("ppo_final.zip")
    monkeypatch.chdir(tmp_path)
    assert train.main(without + ["--resume", str(run), "--total-timesteps", "320"]) == run / "ppo_final.zip"
    assert not (tmp_path / "runs").exists()  # nothing written into the default folder
    assert (run / "args.part3.json").is_file()  # the third segment of the run, with seeds of its own
    # its final model is at 320 steps, its latest checkpoint at 256 (the checkpoints' 128 do not divide 320): a rerun
    # with the same --total-timesteps, from the folder or the final model, leaves the run as it is (from the folder it
    # trained 256 -> 320 again and replaced the final model)
    before = _snapshot(run)
    for resume in (run, run / "ppo_final.zip"):
        assert train.main(without + ["--resume", str(resume), "--total-timesteps", "320"]) == run / "ppo_final.zip"
        assert _snapshot(run) == before and not (run / "args.part4.json").exists()
    # a checkpoint named itself is trained from, the final model notwithstanding (as before: the user's choice)
    named = without + ["--resume", str(ckpts / "ppo_256_steps.zip"), "--total-timesteps", "320"]
    _, env, finished = train._parse(named)
    if env is not None:
        env.close()
    assert finished is None
    # the final model's steps are read from its data alone; a damaged one is taken as none (no traceback)
    assert train._final_steps(run / "ppo_final.zip") == 320
    (tmp_path / "damaged.zip").write_bytes(b"PK\x03\x04 not a whole zip")
    assert train._final_steps(tmp_path / "damaged.zip") is None
    # a resume into a new folder is a later segment of its checkpoint's run, not a start: other seeds than the start's
    fork = tmp_path / "fork"
    train.main(more[:i + 1] + [str(fork)] + more[i + 2:] + ["--resume", str(run), "--total-timesteps", "384"])
    seg = json.loads(next(fork.glob("args.part*.json")).read_text())
    assert seg["segment_env_seed"] > seg["first_env_seed"] and seg["segment_seed"] != seg["seed"]
    # resumed again in that folder: the next segment (its files and seeds its own), not that one again
    before = {p.name: p.read_bytes() for p in fork.glob("args.part*.json")}
    train.main(more[:i + 1] + [str(fork)] + more[i + 2:] + ["--resume", str(fork), "--total-timesteps", "448"])
    after = {p.name: p.read_bytes() for p in fork.glob("args.part*.json")}
    assert len(after) == len(before) + 1 and all(after[k] == v for k, v in before.items())
    # a final model older than its run's latest checkpoint (the run went on after it) is refused too: its steps are
    # read from the file (320 here)
    shutil.copy(ckpts / "ppo_128_steps.zip", ckpts / "ppo_9984_steps.zip")
    usage_error(train.main, without + ["--resume", str(run / "ppo_final.zip")],
                match=r"ppo_final.zip is not its run's latest checkpoint \(ppo_9984_steps.zip\)")
    (ckpts / "ppo_9984_steps.zip").unlink()


def test_a_failed_first_reset_still_saves_and_names_its_checkpoint(env_config, tmp_path, monkeypatch):
    """An env worker that dies in the envs' first reset (before stable-baselines3 sets up the callbacks) ends in
    ``TrainingInterrupted`` naming a checkpoint, not in an ``AttributeError`` of the unset callback."""
    from agents import sb3

    venv = sb3.make_vec_env(env_config.replace(max_grasps=10), n_envs=1, vec="dummy")

    def dead(*a, **k):
        raise EOFError("worker gone")

    monkeypatch.setattr(venv, "reset", dead)
    try:
        with pytest.raises(sb3.TrainingInterrupted) as info:
            sb3.train("ppo", venv, 64, tmp_path, n_steps=32, batch_size=32, n_epochs=1)
    finally:
        venv.close()
    assert "an env worker died (EOFError)" in info.value.reason and Path(info.value.path).is_file()


def test_a_second_signal_during_an_update_lets_it_finish_and_a_resume_takes_its_verbose(env_config, tmp_path,
                                                                                         monkeypatch, capsys):
    """Two SIGINTs while PPO learns from a rollout: the second waits for the update's end (it stopped at once
    there, saving a half-updated model under the rollout's starting step count), so the checkpoint is the model an
    uninterrupted run has at that step; a resumed segment logs at its own ``verbose``, not the checkpoint's."""
    import torch
    from stable_baselines3 import PPO

    from agents import sb3

    cfg = env_config.replace(max_grasps=10)
    hp = {"n_steps": 64, "batch_size": 32, "n_epochs": 2}
    venv = sb3.make_vec_env(cfg, n_envs=1, vec="dummy", seed=7)
    ref, _ = sb3.train("ppo", venv, 128, tmp_path / "ref", checkpoint_freq=10_000, **hp)
    venv.close()
    update, calls = PPO.train, []

    def interrupted_update(self):
        calls.append(1)
        if len(calls) == 2:  # Ctrl-C twice as the second update begins
            signal.raise_signal(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)
        return update(self)

    monkeypatch.setattr(PPO, "train", interrupted_update)
    venv = sb3.make_vec_env(cfg, n_envs=1, vec="dummy", seed=7)
    try:
        with pytest.raises(sb3.TrainingInterrupted) as info:
            sb3.train("ppo", venv, 512, tmp_path / "run", checkpoint_freq=10_000, **hp)
    finally:
        venv.close()
    assert "the update in progress finishes first" in capsys.readouterr().err
    assert info.value.num_timesteps == 128 and Path(info.value.path).name == "ppo_128_steps.zip"
    saved = sb3.load_model(info.value.path, "ppo")
    for (k, a), b in zip(ref.policy.state_dict().items(), saved.policy.state_dict().values()):
        assert torch.equal(a, b), k
    monkeypatch.setattr(PPO, "train", update)
    venv = sb3.make_vec_env(cfg, n_envs=1, vec="dummy", seed=8)
    try:
        model, _ = sb3.train("ppo", venv, 192, tmp_path / "run", resume=info.value.path, verbose=1, **hp)
    finally:
        venv.close()
    assert model.verbose == 1 and "rollout/" in capsys.readouterr().out


def test_a_sac_stop_mid_rollout_saves_a_buffer_of_the_counted_steps_only(env_config, tmp_path, monkeypatch):
    """SAC with ``train_freq > 1`` stores a rollout's transitions before a stop mid-way; the stop rewinds
    ``num_timesteps`` to the rollout's start, and the saved replay buffer kept the transitions after it (19 in a
    checkpoint of 16 steps), which a resume stored again. The buffer is rewound with the step count."""
    from agents import sb3

    venv = sb3.make_vec_env(env_config.replace(max_grasps=5), n_envs=1, vec="dummy", seed=0)
    step_wait, calls = venv.step_wait, []

    def stopping_step_wait():
        calls.append(1)
        if len(calls) == 20:  # handled by train's signal handler: the next env step stops learning
            signal.raise_signal(signal.SIGTERM)
        return step_wait()

    monkeypatch.setattr(venv, "step_wait", stopping_step_wait)
    try:
        with pytest.raises(sb3.TrainingInterrupted) as info:
            sb3.train("sac", venv, 10_000, tmp_path / "run", seed=0, checkpoint_freq=10**6, train_freq=8,
                      learning_starts=0, batch_size=4, buffer_size=1000)
    finally:
        venv.close()
    assert info.value.num_timesteps == 16
    model = sb3.load_model(info.value.path, "sac")
    model.load_replay_buffer(str(sb3.checkpoint_extras(info.value.path)["replay_buffer"]))
    assert model.replay_buffer.size() == model.num_timesteps == 16


def test_checkpoints_are_written_whole_extras_first(env_config, tmp_path, monkeypatch):
    """A save killed mid-write leaves no file under a checkpoint's name (``latest_checkpoint`` never picks a torn
    one); the SAC replay buffer is written before the model's zip, so a zip found has its buffer; and resuming SAC
    from a zip without its buffer is refused instead of going on as another run."""
    from agents import sb3

    def torn(fh):  # a saver killed after writing half its file
        fh.write(b"PK\x03\x04half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sb3._save_atomic(tmp_path / "ppo_64_steps.zip", torn)
    assert list(tmp_path.iterdir()) == [] and sb3.latest_checkpoint(tmp_path) is None

    cfg = env_config.replace(max_grasps=10)
    order = []
    real = sb3._save_atomic
    monkeypatch.setattr(sb3, "_save_atomic", lambda path, save: (order.append(Path(path).name), real(path, save)))
    venv = sb3.make_vec_env(cfg, n_envs=1, vec="dummy")
    sb3.train("sac", venv, 64, tmp_path / "run", checkpoint_freq=32, learning_starts=16, batch_size=16,
              buffer_size=500, train_freq=8, gradient_steps=1)
    venv.close()
    assert order[:2] == ["sac_replay_buffer_32_steps.pkl", "sac_32_steps.zip"] and order[-1] == "sac_final.zip"
    ckpt = sb3.latest_checkpoint(tmp_path / "run", "sac")
    assert ckpt.name == "sac_64_steps.zip" and set(sb3.checkpoint_extras(ckpt)) == {"replay_buffer"}
    assert not list((tmp_path / "run").rglob(".*tmp*"))
    sb3.checkpoint_extras(ckpt)["replay_buffer"].unlink()
    venv = sb3.make_vec_env(cfg, n_envs=1, vec="dummy")
    try:
        with pytest.raises(ValueError, match="has no replay buffer beside it"):
            sb3.train("sac", venv, 96, tmp_path / "run", checkpoint_freq=32, resume=ckpt)
    finally:
        venv.close()


def test_a_resume_the_env_or_its_files_cannot_take_is_refused_before_any_file(small_recognizer_kwargs, tmp_path,
                                                                               usage_error, monkeypatch):
    """A checkpoint whose observation space is not the env's (another ``--env.*`` setting) and a SAC checkpoint
    without its replay buffer failed only once the new segment's args and Monitor files were written (and each try
    used up a segment number): both are usage errors before the lock or any file."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train
    from agents import sb3

    run = tmp_path / "run"
    hp = {"n_steps": 64, "batch_size": 64, "n_epochs": 1}
    train.main(_args("ppo", 128, run, small_recognizer_kwargs, hp))
    before = _snapshot(run)
    more = _args("ppo", 192, run, small_recognizer_kwargs, hp) + ["--resume", str(run)]
    usage_error(train.main, more + ["--env.observe-contacts"],
                match=r"--resume: .*ppo_128_steps.zip was trained with a 33-dim observation, this run's env has a "
                      r"57-dim one: resume with the --env-id and --env.\* settings it was trained with")
    assert _snapshot(run) == before
    damaged = run / "checkpoints" / "ppo_999_steps.zip"  # a truncated file: a traceback after the segment's files
    damaged.write_bytes((run / "checkpoints" / "ppo_128_steps.zip").read_bytes()[:100])
    usage_error(train.main, _args("ppo", 1200, run, small_recognizer_kwargs, hp) + ["--resume", str(damaged)],
                match=r"--resume: .*ppo_999_steps.zip is not a model file stable-baselines3 can read")
    damaged.unlink()
    assert _snapshot(run) == before
    from haptic_env.env import HapticRecogEnv

    built, init = [], HapticRecogEnv.__init__
    monkeypatch.setattr(HapticRecogEnv, "__init__", lambda self, *a, **k: built.append(self) or init(self, *a, **k))
    train.main(more)  # the settings it was trained with: the run's second segment
    assert (run / "args.part2.json").is_file() and not (run / "args.part3.json").exists()
    assert len(built) == 1  # the env the spaces were checked in is the training's (one env, in this process)
    monkeypatch.setattr(HapticRecogEnv, "__init__", init)

    sac = tmp_path / "sac"
    venv = sb3.make_vec_env(train.env_config(train.parse_args(more)), n_envs=1, vec="dummy")
    sb3.train("sac", venv, 32, sac, checkpoint_freq=32, learning_starts=16, batch_size=16, buffer_size=500,
              train_freq=8, gradient_steps=1)
    venv.close()
    ckpt = sb3.latest_checkpoint(sac, "sac")
    sb3.checkpoint_extras(ckpt)["replay_buffer"].unlink()
    before = _snapshot(sac)
    usage_error(train.main, _args("sac", 64, sac, small_recognizer_kwargs, {}) + ["--resume", str(ckpt)],
                match=r"--resume: checkpoint .*sac_32_steps.zip has no replay buffer beside it")
    assert _snapshot(sac) == before and not (sac / ".train.lock").exists()


def test_a_sac_resume_with_another_n_envs_is_refused_before_any_file(small_recognizer_kwargs, tmp_path, usage_error,
                                                                    monkeypatch):
    """SAC's replay buffer holds ``n_envs`` transitions per step (stable-baselines3 shapes it so): a checkpoint's
    buffer loaded beside another ``--n-envs`` failed at the first step it stored, after the segment's args and
    Monitor files were written. It is a usage error naming both counts before any file; the same count resumes."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train

    run = tmp_path / "sac"
    hp = {"learning_starts": 16, "batch_size": 16, "buffer_size": 500, "train_freq": 8, "gradient_steps": 1}
    train.main(_args("sac", 128, run, small_recognizer_kwargs, hp))
    before = _snapshot(run)
    usage_error(train.main, _args("sac", 192, run, small_recognizer_kwargs, hp, n_envs=2) + ["--resume", str(run)],
                match=r"--n-envs: .*sac_128_steps.zip was trained with --n-envs 1, got 2 \(SAC's replay buffer")
    assert _snapshot(run) == before  # no args.part2.json, no Monitor segment: the next resume is still part 2
    assert train.main(_args("sac", 192, run, small_recognizer_kwargs, hp) + ["--resume", str(run)]) == \
        run / "sac_final.zip"
    assert (run / "args.part2.json").is_file() and not (run / "args.part3.json").exists()
    from agents import sb3  # train() itself refuses it too, once it has read the buffer

    venv = sb3.make_vec_env(train.env_config(train.parse_args(_args("sac", 256, run, small_recognizer_kwargs, hp))),
                            n_envs=2, vec="dummy")
    try:
        with pytest.raises(ValueError, match=r"sac_\d+_steps.zip was trained with --n-envs 1, got 2"):
            sb3.train("sac", venv, 256, tmp_path / "other", resume=sb3.latest_checkpoint(run, "sac"))
    finally:
        venv.close()


def test_a_resumed_segment_starts_past_every_earlier_segments_env_seeds(small_recognizer_kwargs, tmp_path,
                                                                        monkeypatch):
    """Segment ``k``'s envs started ``(k - 1) x n_envs`` seeds after the run's first with this segment's
    ``n_envs``: a start with 4 envs (seeds 10000-10003) resumed with 2 replayed its ranks 2 and 3 (10002, 10003).
    They start past the last seed any earlier segment had (each one's ``n_envs`` from its args file); with
    ``n_envs`` unchanged that is ``(k - 1) x n_envs`` as before."""
    monkeypatch.syspath_prepend(str(ROOT))
    import train

    run = tmp_path / "run"
    run.mkdir()
    two = train.parse_args(["--run-dir", str(run), "--n-envs", "2"])
    assert [train.segment_seeds(two, k)[1] for k in (1, 2, 3, 4)] == [10000, 10002, 10004, 10006]
    (run / "args.json").write_text(json.dumps({"n_envs": 2, "first_env_seed": 10000}))
    (run / "args.part2.json").write_text(json.dumps({"n_envs": 2, "segment_env_seed": 10002}))
    assert train.used_env_seeds(run) == {1: (10000, 2), 2: (10002, 2)}
    assert train.segment_seeds(two, 3, train.used_env_seeds(run)) == train.segment_seeds(two, 3) == \
        (train.segment_seeds(two, 3)[0], 10004)
    (run / "args.json").write_text(json.dumps({"n_envs": 4, "first_env_seed": 10000}))
    (run / "args.part2.json").unlink()
    assert train.segment_seeds(two, 2, train.used_env_seeds(run))[1] == 10004  # not 10002: part 1's rank 2
    (run / "args.part2.json").write_text(json.dumps({"n_envs": 2, "segment_env_seed": 10004}))
    eight = train.parse_args(["--run-dir", str(run), "--n-envs", "8"])
    assert train.segment_seeds(eight, 3, train.used_env_seeds(run))[1] == 10006

    # a real run: started with 2 envs, resumed with 1
    real = tmp_path / "real"
    hp = {"n_steps": 64, "batch_size": 64, "n_epochs": 1}
    train.main(_args("ppo", 128, real, small_recognizer_kwargs, hp, n_envs=2))
    train.main(_args("ppo", 192, real, small_recognizer_kwargs, hp, n_envs=1) + ["--resume", str(real)])
    start = json.loads((real / "args.json").read_text())["first_env_seed"]
    assert json.loads((real / "args.part2.json").read_text())["segment_env_seed"] == start + 2


def test_the_envs_are_closed_and_a_signal_before_learning_is_one_line(small_recognizer_kwargs, tmp_path, capsys,
                                                                       monkeypatch):
    """The vec env was closed only when learning ended or was interrupted (a failure building or loading the model
    left it, and its workers, open), and a Ctrl-C while the model was built was a KeyboardInterrupt traceback: the
    env is closed however training ends, and SIGINT / SIGTERM before learning exit 130 / 143 with one line."""
    monkeypatch.syspath_prepend(str(ROOT))
    import haptic_env
    import train
    from agents import sb3

    make = haptic_env.make
    made, closed = [], []
    real, close = sb3.make_vec_env, sb3.close_vec_env
    monkeypatch.setattr(sb3, "make_vec_env", lambda *a, **k: made.append(real(*a, **k)) or made[-1])
    monkeypatch.setattr(sb3, "close_vec_env", lambda venv: closed.append(venv) or close(venv))
    hp = {"n_steps": 64, "batch_size": 64, "n_epochs": 1}

    def broken(*a, **k):
        raise RuntimeError("model build failed")

    monkeypatch.setattr(sb3, "build_model", broken)
    with pytest.raises(RuntimeError, match="model build failed"):
        train.main(_args("ppo", 64, tmp_path / "a", small_recognizer_kwargs, hp))
    assert len(made) == 1 and closed == made

    def fallback(signum, frame):  # without train.py's own handler a SIGTERM would end the test run
        raise AssertionError(f"{signal.Signals(signum).name} reached the test's handler, not train.py's")

    sigint_before = signal.getsignal(signal.SIGINT)  # Python's default_int_handler, or SIG_IGN in a background job
    previous = signal.signal(signal.SIGTERM, fallback)
    try:
        for sig, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
            def interrupted(*a, _sig=sig, **k):
                os.kill(os.getpid(), _sig)  # delivered to this (main) thread before the call returns
                raise AssertionError("the signal did not stop the set-up")

            monkeypatch.setattr(sb3, "build_model", interrupted)
            capsys.readouterr()
            with pytest.raises(SystemExit) as exc:
                train.main(_args("ppo", 64, tmp_path / sig.name, small_recognizer_kwargs, hp))
            err = capsys.readouterr().err
            assert exc.value.code == code and closed == made
            assert err.strip() == (f"[train] stopped by {sig.name} before learning began (nothing learned, nothing "
                                   "saved); run the same command again")
            # while the first env is made (a hand env's builds its grasp pool for minutes): the same line, no
            # traceback, no run file
            monkeypatch.setattr(haptic_env, "make", interrupted)
            with pytest.raises(SystemExit) as exc:
                train.main(_args("ppo", 64, tmp_path / f"{sig.name}-probe", small_recognizer_kwargs, hp))
            monkeypatch.setattr(haptic_env, "make", make)
            assert exc.value.code == code and capsys.readouterr().err.strip() == err.strip()
            assert not (tmp_path / f"{sig.name}-probe").exists()
        assert signal.getsignal(signal.SIGTERM) is fallback  # put back
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert signal.getsignal(signal.SIGINT) is sigint_before  # the handlers are put back
