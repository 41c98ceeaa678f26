"""What one sweep job does, in whatever process runs it (a Ray worker, or this process).

:func:`execute` is the one entry point: it logs the attempt to ``attempts.jsonl`` in the job's run folder,
runs the job's kind and, on success, writes ``done.json`` (its result) atomically. A job whose ``done.json``
exists is finished: a re-run of the sweep skips it.

* ``train``: ``train.py`` as a subprocess (its flags are the ones both its argparse and its tyro command lines
  take: ``--algo --env-id --total-timesteps --n-envs --vec --seed --run-dir --checkpoint-freq --max-minutes
  --env-kwargs --hyperparams --resume``). An unfinished run folder with a checkpoint is resumed
  (``--resume <run dir>``). The subprocess gets SIGTERM when its worker dies (``PR_SET_PDEATHSIG``), so it saves
  a checkpoint for the retry; a retry first waits for the previous attempt's ``train.py`` to exit.
* ``evaluate``: :func:`agents.evaluate.run_episodes` of the agent on every env seed, in this process, its random
  numbers seeded by the env seed and the agent seed (so that a baseline's seeds are distinct runs);
  ``episodes.csv``.
* ``dataset``: :func:`haptic_env.dataset.build_dataset` through the shared cache (``$HAPTIC_CACHE``): a cluster
  run and a laptop run write and read the same files. A hand grasp pool it builds runs in as many processes as the
  job's ``cpus`` (at least 1), not on every core of the node.
* ``analysis``: ``haptic-recog analysis --out <run dir>/analysis --objects ... <flags>`` as a subprocess.
* ``command``: any command, run in the job folder (``$SWEEP_RUN_DIR``, ``$SWEEP_ATTEMPT`` set).
"""

from __future__ import annotations

import csv
import json
import os
import shlex
import signal
import socket
import subprocess
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from haptic_env.processes import die_with_parent

__all__ = ["execute", "is_done", "read_done", "attempts", "TRAIN_PY"]

#: train.py of the source checkout this package lives in
TRAIN_PY = Path(__file__).resolve().parents[2] / "train.py"


def is_done(run_dir: Path) -> bool:
    return (Path(run_dir) / "done.json").is_file()


def read_done(run_dir: Path) -> dict[str, Any]:
    return json.loads((Path(run_dir) / "done.json").read_text())


def attempts(run_dir: Path) -> list[dict[str, Any]]:
    """The attempt records of a job folder (``start`` lines, with ``end``/``error`` lines merged in)."""
    path = Path(run_dir) / "attempts.jsonl"
    if not path.is_file():
        return []
    out: list[dict[str, Any]] = []
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if rec.get("event") == "start":
            out.append(rec)
        elif out and rec.get("attempt") == out[-1].get("attempt"):
            out[-1].update({k: v for k, v in rec.items() if k != "event"}, outcome=rec.get("event"))
    return out


def _log(run_dir: Path, **rec: Any) -> None:
    with open(run_dir / "attempts.jsonl", "a") as fh:
        fh.write(json.dumps({"time": time.time(), **rec}, default=str) + "\n")


def _write_json_atomic(path: Path, obj: Any) -> None:
    from haptic_env.cache import atomic_write

    with atomic_write(path, "w") as fh:
        fh.write(json.dumps(obj, indent=2, default=str))


def execute(job: dict[str, Any], run_dir: str, *deps: Any) -> dict[str, Any]:
    """Run one job (``Job.to_dict()``) in ``run_dir``; returns (and writes to ``done.json``) its result.
    ``deps`` are the results of the jobs it needs (Ray passes them once they are done)."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    if is_done(run_dir):  # finished by an earlier attempt whose result did not get back
        return read_done(run_dir)
    (run_dir / "job.json").write_text(json.dumps(job, indent=2, default=str))
    attempt = len(attempts(run_dir)) + 1
    _log(run_dir, event="start", attempt=attempt, pid=os.getpid(), host=socket.gethostname(), node=_ray_node())
    t0 = time.time()
    try:
        result = _RUNNERS[job["kind"]](job["params"], run_dir, attempt, job)
    except BaseException as exc:
        _log(run_dir, event="error", attempt=attempt, error=f"{type(exc).__name__}: {exc}"[:2000],
             seconds=time.time() - t0)
        raise
    result = {**result, "job": job["id"], "attempt": attempt, "seconds": time.time() - t0}
    _write_json_atomic(run_dir / "done.json", result)
    _log(run_dir, event="end", attempt=attempt, seconds=result["seconds"])
    return result


def _ray_node() -> str | None:
    """The Ray node this runs on (None outside Ray)."""
    try:
        import ray

        return ray.get_runtime_context().get_node_id() if ray.is_initialized() else None
    except Exception:  # noqa: BLE001  (no ray, or no runtime context)
        return None


# ------------------------------------------------------------------------------------- subprocess
def _run_logged(cmd: list[str], log: Path, cwd: Path | None = None, env: dict[str, str] | None = None,
                pidfile: Path | None = None) -> int:
    """Run ``cmd`` with its output appended to ``log``; a stop of this process (task cancelled) is passed on as
    SIGTERM (``train.py`` then saves a checkpoint) before it propagates."""
    with open(log, "a") as fh:
        fh.write(f"\n$ {shlex.join(cmd)}\n")
        fh.flush()
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, cwd=cwd, env=env,
                                preexec_fn=die_with_parent if sys.platform.startswith("linux") else None)
        if pidfile is not None:
            pidfile.write_text(str(proc.pid))
        try:
            return proc.wait()
        except BaseException:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
            raise


def _tail(path: Path, n: int = 15) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-n:])
    except OSError:
        return ""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a zombie (exited, not reaped) is not running
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True


def _wait_previous(pidfile: Path, timeout: float = 300.0) -> None:
    """Wait for the ``train.py`` of an earlier attempt to exit (it saves a checkpoint on SIGTERM)."""
    try:
        pid = int(pidfile.read_text())
    except (OSError, ValueError):
        return
    if pid == os.getpid():
        return
    t0 = time.monotonic()
    while _pid_alive(pid):
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            cmdline = b""
        if b"train.py" not in cmdline or str(pidfile.parent).encode() not in cmdline:
            return  # the pid was reused by another process
        if time.monotonic() - t0 > timeout:
            os.kill(pid, signal.SIGTERM)
            time.sleep(5)
            return
        time.sleep(0.5)


# ------------------------------------------------------------------------------------------ kinds
def _train(p: dict[str, Any], run_dir: Path, attempt: int, job: dict[str, Any]) -> dict[str, Any]:
    from agents.sb3 import latest_checkpoint

    if not TRAIN_PY.is_file():
        raise FileNotFoundError(f"{TRAIN_PY} not found: train jobs need the haptic-recog source checkout")
    _wait_previous(run_dir / "train.pid")
    final = run_dir / f"{p['algo']}_final.zip"
    if final.is_file():  # an earlier attempt finished training but not the job (train.py writes it whole, last)
        return {"model": str(final), "resumed_from": None, "reused_final_model": True, "steps": model_steps(final)}
    cmd = [sys.executable, str(TRAIN_PY), "--algo", p["algo"], "--env-id", p["env_id"],
           "--total-timesteps", str(p["total_timesteps"]), "--n-envs", str(p["n_envs"]), "--vec", p["vec"],
           "--seed", str(p["seed"]), "--env-seed", str(p["env_seed"]), "--run-dir", str(run_dir),
           "--checkpoint-freq", str(p["checkpoint_freq"]),
           "--max-minutes", str(p["max_minutes"]), "--env-kwargs", json.dumps(p["env_kwargs"]),
           "--hyperparams", json.dumps(p["hyperparams"])]
    if p.get("discrete_approaches"):
        cmd += ["--discrete-approaches", str(p["discrete_approaches"])]
    resumed = latest_checkpoint(run_dir, p["algo"])
    if resumed is not None:
        cmd += ["--resume", str(run_dir)]
    log = run_dir / "train.log"
    rc = _run_logged(cmd, log, cwd=TRAIN_PY.parent, pidfile=run_dir / "train.pid")
    if rc != 0 or not final.is_file():
        raise RuntimeError(f"train.py exited with status {rc} (attempt {attempt}); last lines of {log}:\n{_tail(log)}")
    # the steps it learned: fewer than total_timesteps where max_minutes stopped it (the report says so)
    return {"model": str(final), "resumed_from": str(resumed) if resumed is not None and "--resume" in cmd else None,
            "steps": model_steps(final)}


def model_steps(path: Path) -> int | None:
    """The steps a model file was saved at (stable-baselines3's ``num_timesteps``), or None if it does not say (or
    cannot be read)."""
    from agents.sb3 import saved_data

    steps = (saved_data(path) or {}).get("num_timesteps")
    return None if steps is None else int(steps)


def _evaluate(p: dict[str, Any], run_dir: Path, attempt: int, job: dict[str, Any]) -> dict[str, Any]:
    import haptic_env
    from agents.evaluate import make_agent, run_episodes

    spec = p["spec"]
    if p["trained"]:  # the model in the train job's folder (``dep_dirs``, set by the runner)
        model = Path(job["dep_dirs"][0]) / spec
        if not model.is_file():
            raise FileNotFoundError(f"model {model} does not exist (its train job has not finished)")
        spec = f"model={model}"  # the agent's own name may hold "=" (make_agent splits at the first); named below
    if p.get("seeding") != "env+agent":
        raise ValueError(f"evaluate job: unknown seeding {p.get('seeding')!r} (this version writes 'env+agent')")
    agent = make_agent(spec, seed=p["seed"], no_repeat=bool(p.get("no_repeat", False)))
    agent.name = p["agent"]
    records = []
    for s in p["env_seeds"]:
        records += run_episodes(agent, lambda: haptic_env.make(env_id=p["env_id"], **p["env_kwargs"]),
                                p["episodes"], s, agent_seed=p["seed"])
    from haptic_env.cache import atomic_write

    path = run_dir / "episodes.csv"
    with atomic_write(path, "w") as fh:
        w = csv.DictWriter(fh, fieldnames=list(asdict(records[0])))
        w.writeheader()
        for r in records:
            w.writerow(asdict(r))
    return {"episodes": len(records), "csv": str(path)}


def _dataset(p: dict[str, Any], run_dir: Path, attempt: int, job: dict[str, Any]) -> dict[str, Any]:
    from haptic_env.dataset import DatasetConfig, build_dataset
    from haptic_env.objects import load_object_set

    cfg = DatasetConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in p["config"].items()})
    objects = load_object_set(p["objects"])
    t0 = time.time()
    # the processes the job asked Ray for, not every core of the node (Ray would place other jobs on those)
    ds = build_dataset(objects, cfg, cache=True, progress=False, workers=max(1, int(job["cpus"])))
    return {"cache": str(ds.cache_path), "from_cache": bool(ds.from_cache), "objects": len(objects),
            "feature_dim": int(ds.feature_dim), "train": int(len(ds.X_train)), "val": int(len(ds.X_val)),
            "build_seconds": time.time() - t0}


def _analysis(p: dict[str, Any], run_dir: Path, attempt: int, job: dict[str, Any]) -> dict[str, Any]:
    from haptic_env.sweep.spec import analysis_argv

    out = run_dir / "analysis"
    cmd = [sys.executable, "-m", "haptic_env.cli", *analysis_argv(p["objects"], p["flags"], out)]
    log = run_dir / "analysis.log"
    rc = _run_logged(cmd, log)
    if rc != 0:
        raise RuntimeError(f"haptic-recog analysis exited with status {rc}; last lines of {log}:\n{_tail(log)}")
    return {"results": str(out / "results.md")}


def _command(p: dict[str, Any], run_dir: Path, attempt: int, job: dict[str, Any]) -> dict[str, Any]:
    cmd = shlex.split(p["run"]) if isinstance(p["run"], str) else list(p["run"])
    env = {**os.environ, **{k: str(v) for k, v in p.get("env", {}).items()},
           "SWEEP_RUN_DIR": str(run_dir), "SWEEP_ATTEMPT": str(attempt)}
    log = run_dir / "command.log"
    rc = _run_logged(cmd, log, cwd=run_dir, env=env)
    if rc != 0:
        raise RuntimeError(f"command exited with status {rc}; last lines of {log}:\n{_tail(log)}")
    return {"returncode": rc}


_RUNNERS = {"train": _train, "evaluate": _evaluate, "dataset": _dataset, "analysis": _analysis, "command": _command}
