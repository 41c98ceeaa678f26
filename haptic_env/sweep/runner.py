"""Run a sweep's jobs on Ray: one Ray task per job, dependencies as task arguments, retries by Ray.

``ray.init(address="local")`` starts a local cluster (``num_cpus``: default all cores); ``address`` joins an
existing one (``"auto"``, or ``HOST:PORT`` of a ``ray start --head``). Every job asks for its ``cpus``. A job
whose run folder has ``done.json`` is skipped; a failed job is retried ``max_retries`` times (an exception in
the job, or its worker process dying) and, when it still fails, reported with its error, as are the jobs that
needed it. The run folders live under the sweep folder, which must be on a filesystem every node sees (one
machine, or NFS).
"""

from __future__ import annotations

import json
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .jobs import attempts, execute, is_done, read_done
from .spec import Job, SweepSpec

__all__ = ["SweepResult", "run_sweep", "run_jobs_inline", "ray_available", "select_jobs", "finished_before",
           "InfeasibleJob"]

#: environment variables every worker gets from the driver (cache, data, rendering)
FORWARD_ENV = ("HAPTIC_CACHE", "HAPTIC_CACHE_READONLY", "HAPTIC_DATA", "MENAGERIE_ROOT", "MUJOCO_GL")


def ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


class InfeasibleJob(ValueError):
    """A job asks for more CPUs than the local Ray has: Ray would hold it back for ever, without a word (its log does
    not reach the driver)."""


@dataclass
class SweepResult:
    out: Path
    done: dict[str, dict[str, Any]] = field(default_factory=dict)  # job id -> result (this run or earlier)
    skipped: list[str] = field(default_factory=list)  # done before this run
    failed: dict[str, str] = field(default_factory=dict)  # job id -> error
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.failed


def finished_before(spec: SweepSpec, out: Path) -> SweepResult:
    """The result of a run that has not run anything yet: every job of ``spec`` whose run folder under ``out`` holds
    its ``done.json`` (:func:`~.jobs.is_done`) is done and skipped, inside a ``--match`` / ``--only`` selection or
    not, so that the report and ``status.json`` count every finished job as done."""
    done = [j for j in spec.jobs if is_done(j.run_dir(out))]
    return SweepResult(out=out, skipped=[j.id for j in done], done={j.id: read_done(j.run_dir(out)) for j in done})


def select_jobs(spec: SweepSpec, kinds: set[str] | None = None, match: str | None = None,
                done: Callable[[Job], bool] | None = None) -> list[Job]:
    """The jobs of ``kinds`` (all if None) whose id ``re.search``-matches ``match`` (all if None), and the jobs
    they need, in dependency order (a job after the jobs it needs). The needs of a job for which ``done`` is
    true are not followed (a finished evaluation does not need its training again)."""
    by_id = spec.by_id()
    pattern = re.compile(match) if match is not None else None
    out: list[Job] = []
    seen: set[str] = set()

    def visit(j: Job) -> None:
        if j.id not in seen:
            seen.add(j.id)
            if done is None or not done(j):
                for d in j.deps:
                    visit(by_id[d])
            out.append(j)

    for j in spec.jobs:
        if (kinds is None or j.kind in kinds) and (pattern is None or pattern.search(j.id)):
            visit(j)
    return out


def _plan(spec: SweepSpec, out: Path, kinds: set[str] | None, match: str | None = None) -> tuple[list[Job], list[Job]]:
    """(jobs to run in dependency order, jobs already done) of :func:`select_jobs`."""
    finished = {j.id: is_done(j.run_dir(out)) for j in spec.jobs}
    todo, done = [], []
    for j in select_jobs(spec, kinds, match, done=lambda j: finished[j.id]):
        (done if finished[j.id] else todo).append(j)
    return todo, done


def _job_payload(j: Job, out: Path, by_id: dict[str, Job]) -> dict[str, Any]:
    return {**j.to_dict(), "dep_dirs": [str(by_id[d].run_dir(out).resolve()) for d in j.deps]}


def _error_text(exc: BaseException) -> str:
    text = str(exc)
    # RayTaskError repeats the traceback; keep the last lines, which name the job's own error
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return "\n".join(lines[-12:]) if len(lines) > 12 else text


def run_sweep(spec: SweepSpec, out: str | Path | None = None, *, address: str | None = None,
              num_cpus: int | None = None, max_retries: int | None = None, kinds: set[str] | None = None,
              match: str | None = None, progress: bool = True, poll: float = 1.0) -> SweepResult:
    """Run the jobs of ``spec`` that are not done yet on Ray, then return what is done and what failed (the
    report is :func:`haptic_env.sweep.report.write_sweep_report`). Uses the running Ray if there is one
    (``ray.is_initialized()``), else ``ray.init(address or "local", num_cpus=...)`` and shuts it down after."""
    import ray
    from tqdm.auto import tqdm

    out = Path(out or spec.default_out()).resolve()
    retries = spec.max_retries if max_retries is None else max_retries
    by_id = spec.by_id()
    todo, done_before = _plan(spec, out, kinds, match)
    result = finished_before(spec, out)
    t0 = time.time()
    if not todo:
        return result

    own = not ray.is_initialized()
    if own:
        env_vars = {k: os.environ[k] for k in FORWARD_ENV if k in os.environ}
        kw: dict[str, Any] = {"runtime_env": {"env_vars": env_vars}, "log_to_driver": False}
        if address in (None, "local"):
            kw.update(address="local", num_cpus=num_cpus, include_dashboard=False)
        else:
            kw.update(address=address)
        ray.init(**kw)
    remote = ray.remote(execute)
    refs: dict[str, Any] = {}  # job id -> ObjectRef
    try:
        if own and address in (None, "local"):  # a cluster may add nodes; a local Ray never does
            cpus = float(ray.cluster_resources().get("CPU", 0.0))
            big = [j for j in todo if j.cpus > cpus]
            if big:
                raise InfeasibleJob(f"job {big[0].id} asks for cpus {big[0].cpus:g}, more than the local Ray's "
                                    f"{cpus:g} CPUs (--num-cpus), so it would never start"
                                    + (f" ({len(big) - 1} more jobs too)" if len(big) > 1 else "")
                                    + ": lower its cpus in the spec or give more CPUs")
        out.mkdir(parents=True, exist_ok=True)
        for j in todo:
            deps = [refs[d] for d in j.deps if d in refs]  # a dependency done earlier needs no wait
            refs[j.id] = remote.options(num_cpus=j.cpus, max_retries=retries, retry_exceptions=True,
                                        name=j.id).remote(_job_payload(j, out, by_id), str(j.run_dir(out)), *deps)
        pending = {ref: jid for jid, ref in refs.items()}
        bar = tqdm(total=len(todo) + len(done_before), initial=len(done_before), desc=f"sweep {spec.name}",
                   unit="job", disable=not progress, dynamic_ncols=True)
        with bar:
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=poll)
                for ref in ready:
                    jid = pending.pop(ref)
                    try:
                        result.done[jid] = ray.get(ref)
                    except Exception as exc:  # noqa: BLE001  (RayTaskError, WorkerCrashedError, ...)
                        result.failed[jid] = _error_text(exc)
                    bar.update(1)
                running = sum(1 for jid in pending.values() if _running(by_id[jid].run_dir(out)))
                bar.set_postfix_str(f"done {len(result.done)} running {running} failed {len(result.failed)}",
                                    refresh=True)
    except KeyboardInterrupt:
        for ref in refs.values():
            ray.cancel(ref)  # the jobs' subprocesses get SIGTERM (train.py saves a checkpoint)
        raise
    finally:
        if own:
            ray.shutdown()
        result.seconds = time.time() - t0
    return result


def _running(run_dir: Path) -> bool:
    """Its latest attempt started and has not ended (the job is on a worker now)."""
    a = attempts(run_dir)
    return bool(a) and "outcome" not in a[-1]


def run_jobs_inline(spec: SweepSpec, out: str | Path | None = None, *, kinds: set[str] | None = None,
                    match: str | None = None, on_done: Callable[[str], None] | None = None) -> SweepResult:
    """The same jobs one after another in this process, without Ray (the sequential reference of the
    benchmark; no retries)."""
    out = Path(out or spec.default_out()).resolve()
    by_id = spec.by_id()
    todo, _ = _plan(spec, out, kinds, match)
    result = finished_before(spec, out)
    t0 = time.time()
    for j in todo:
        if any(d in result.failed for d in j.deps):
            result.failed[j.id] = "a job it needs failed"
            continue
        try:
            result.done[j.id] = execute(_job_payload(j, out, by_id), str(j.run_dir(out)))
        except Exception as exc:  # noqa: BLE001
            result.failed[j.id] = f"{type(exc).__name__}: {exc}"
        if on_done is not None:
            on_done(j.id)
    result.seconds = time.time() - t0
    return result


def write_status(result: SweepResult, spec: SweepSpec) -> Path:
    """``<sweep>/status.json``: every job's state, attempts and error (failed jobs are listed, never dropped)."""
    rows = []
    for j in spec.jobs:
        rd = j.run_dir(result.out)
        a = attempts(rd)
        state = ("failed" if j.id in result.failed else "skipped" if j.id in result.skipped
                 else "done" if is_done(rd) else "not run")
        rows.append({"id": j.id, "kind": j.kind, "state": state, "attempts": len(a),
                     "errors": [x.get("error") for x in a if x.get("error")],
                     "error": result.failed.get(j.id), "run_dir": str(rd)})
    from haptic_env.cache import atomic_write

    path = result.out / "status.json"
    with atomic_write(path, "w") as fh:  # makes the folder (a --report-only into a new --out has none yet)
        fh.write(json.dumps({"sweep": spec.name, "seconds": result.seconds, "jobs": rows}, indent=2))
    return path
