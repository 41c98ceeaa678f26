"""The sweep's one aggregate report: ``<sweep>/report.md`` and its PNGs, from the run folders on disk.

Per env of the RL part, the episodes of every agent's evaluate jobs go through
:func:`agents.evaluate.write_report` (``report/<env>/``: results.md, results.json, episodes.csv, the success
curve, the box plot and rliable's performance profile); its ``rliable`` section (:func:`agents.evaluate.
rl_aggregates`: IQM of the grasps at the stop and success at the stop with stratified bootstrap CIs, probability
of improvement over random) becomes the env's table in ``report.md`` and one row of ``leaderboard.png`` (IQM
grasps, success, P(fewer grasps than random), with their 95% CIs).

Strata and runs: the env seeds are rliable's tasks (every agent sees the same objects and poses per env seed),
the episodes of all agent seeds (training seeds) on an env seed its runs. Every agent seed replays the same episodes
of an env seed, so the intervals resample those episodes (situations) with all their replays together
(:func:`agents.evaluate.cluster_intervals`), not each replay as an independent run.

An earlier report of the same spec can stand in for run folders that are gone (``--prior-report``,
:func:`load_prior_records`): its ``report/<env>/episodes.csv`` fills the evaluate jobs not finished here.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import shlex
from pathlib import Path
from typing import Any

from haptic_env.cache import atomic_write

from .jobs import attempts, is_done, model_steps, read_done
from .runner import SweepResult
from .spec import SweepSpec

__all__ = ["write_sweep_report", "load_records"]


def _read_episodes(path: Path, offset: int = 0) -> list:
    """The :class:`~agents.evaluate.EpisodeRecord` rows of an ``episodes.csv``, episode indices + ``offset``."""
    from agents.evaluate import EpisodeRecord

    with open(path, newline="") as fh:
        return [EpisodeRecord(agent=row["agent"], seed=int(row["seed"]), episode=int(row["episode"]) + offset,
                              object=row["object"], grasps=int(row["grasps"]), decided=row["decided"] == "True",
                              correct=row["correct"] == "True", certainty=float(row["certainty"]),
                              ret=float(row["ret"]), predicted=row.get("predicted") or "")
                for row in csv.DictReader(fh)]


#: beside a report's ``episodes.csv``: each agent's seed list, whose order its episode offsets follow
AGENT_SEEDS = "agent_seeds.json"


def _agent_seeds(spec: SweepSpec, env: str) -> dict[str, list[int]]:
    """agent -> its sorted agent (training) seeds among the evaluate jobs of ``env``."""
    seeds: dict[str, set[int]] = {}
    for j in spec.jobs:
        if j.kind == "evaluate" and j.params["env"] == env:
            seeds.setdefault(j.params["agent"], set()).add(j.params["seed"])
    return {a: sorted(s) for a, s in seeds.items()}


def load_records(spec: SweepSpec, out: Path, env: str) -> list:
    """The :class:`~agents.evaluate.EpisodeRecord` of every finished evaluate job of ``env``. A record's ``seed``
    is the env seed (rliable's stratum); its episode index is offset by the agent seed's index x episodes, so
    that all agent seeds' episodes of one env seed are that stratum's runs."""
    seeds = _agent_seeds(spec, env)
    records = []
    for j in spec.jobs:
        if j.kind != "evaluate" or j.params["env"] != env or not is_done(j.run_dir(out)):
            continue
        offset = seeds[j.params["agent"]].index(j.params["seed"]) * j.params["episodes"]
        records += _read_episodes(j.run_dir(out) / "episodes.csv", offset)
    return records


def load_prior_records(spec: SweepSpec, prior: Path, env: str) -> dict[tuple[str, int], list]:
    """(agent, agent seed) -> its episodes of ``env`` in an earlier report of this spec
    (``prior/report/<env>/episodes.csv`` as :func:`write_sweep_report` wrote it, e.g. one committed after its
    run folders were gone); the agent seed is read back from the episode offset (see :func:`load_records`), which
    counts in the earlier spec's seed list of each agent: the one in ``agent_seeds.json`` beside the file (written
    since 2026-12-07; a report without it is read with this spec's lists, which filed episodes under other seeds
    when the lists had changed), and the episodes are offset again as this spec's list counts. Empty if the earlier
    report has no such file.

    Raises ``ValueError`` if an agent of the file is not evaluated on ``env`` by this spec, if an episode index
    lies beyond its agent's seeds, if an agent seed of the file is not among this spec's, or if an agent seed's
    episodes are not ``episodes`` on each of the spec's ``env_seeds``: the file is of another spec (its episodes
    would be taken for other runs)."""
    from collections import Counter

    path = prior / "report" / env / "episodes.csv"
    if not path.is_file():
        return {}
    seeds = _agent_seeds(spec, env)
    p = next(j.params for j in spec.jobs if j.kind == "evaluate" and j.params["env"] == env)
    episodes, env_seeds = p["episodes"], p["env_seeds"]
    listed = path.with_name(AGENT_SEEDS)
    theirs = {**seeds, **(json.loads(listed.read_text()) if listed.is_file() else {})}
    rows = _read_episodes(path)
    unknown = next((r.agent for r in rows if r.agent not in seeds), None)
    if unknown is not None:
        raise ValueError(f"{path}: agent {unknown!r} is not evaluated on env {env!r} by this spec (the earlier "
                         "report is of another spec)")
    by_job: dict[tuple[str, int], list] = {}
    for r in rows:
        idx, e = divmod(r.episode, episodes)
        if idx >= len(theirs[r.agent]):
            raise ValueError(f"{path}: episode {r.episode} of agent {r.agent!r} lies beyond its "
                             f"{len(theirs[r.agent])} agent seed(s) x {episodes} episodes (the earlier report is of "
                             "another spec)")
        seed = theirs[r.agent][idx]
        if seed not in seeds[r.agent]:
            raise ValueError(f"{path}: agent {r.agent!r} seed {seed} is not among this spec's agent seeds "
                             f"{seeds[r.agent]} (the earlier report is of another spec)")
        # offset as this spec's seed list counts (load_records), where the earlier list may have counted otherwise
        by_job.setdefault((r.agent, seed), []).append(
            dataclasses.replace(r, episode=seeds[r.agent].index(seed) * episodes + e))
    for (agent, seed), recs in by_job.items():
        got = Counter(r.seed for r in recs)
        if got != dict.fromkeys(env_seeds, episodes):
            raise ValueError(f"{path}: agent {agent!r} seed {seed} has episodes per env seed "
                             f"{dict(sorted(got.items()))}, this spec {episodes} on each of env seeds {env_seeds} "
                             "(the earlier report is of another spec)")
    return by_job


def _max_grasps(env_id: str, kwargs: dict[str, Any]) -> int:
    import haptic_env

    return haptic_env.variant_config(env_id, **kwargs).max_grasps


def _leaderboard_png(aggs: dict[str, dict[str, Any]], path: Path) -> Path:
    from matplotlib.figure import Figure

    envs = list(aggs)
    fig = Figure(figsize=(13, 0.6 + 2.2 * len(envs)))
    axes = fig.subplots(len(envs), 3, squeeze=False)
    cols = [("grasps_iqm", "IQM grasps at the stop", 1.0), ("success", "success at the stop", 100.0),
            ("p_fewer_grasps", "P(fewer grasps than random)", 1.0)]
    for r, env in enumerate(envs):
        agents = list(aggs[env]["agents"].items())
        for c, (key, title, scale) in enumerate(cols):
            ax = axes[r][c]
            names, vals, lo, hi = [], [], [], []
            for name, row in agents:
                if key not in row:
                    continue
                v, (a, b) = row[key], row[f"{key}_ci"]
                names.append(name)
                vals.append(scale * v)
                lo.append(scale * (v - a))
                hi.append(scale * (b - v))
            y = range(len(names))
            order = [a for a, _ in agents]  # one colour per agent in every panel
            ax.barh(list(y), vals, xerr=[lo, hi], color=[f"C{order.index(n)}" for n in names], alpha=0.75, capsize=3)
            ax.set_yticks(list(y), names)
            ax.invert_yaxis()
            if key == "p_fewer_grasps":
                ax.axvline(0.5, color="k", lw=0.8, ls="--")
                ax.set_xlim(0, 1)
            ax.grid(alpha=0.3, axis="x")
            ax.set_title(f"{env}: {title}" + (" (%)" if scale == 100.0 else ""), fontsize=9)
    fig.suptitle("sweep leaderboard (95% stratified bootstrap CIs)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def _jobs_table(spec: SweepSpec, result: SweepResult) -> str:
    lines = ["| kind | jobs | done (this run) | done before (skipped) | failed | not run | retried |", "|" + "---|" * 7]
    for kind in dict.fromkeys(j.kind for j in spec.jobs):
        js = [j for j in spec.jobs if j.kind == kind]
        n_run = sum(j.id in result.done and j.id not in result.skipped for j in js)
        n_skip = sum(j.id in result.skipped for j in js)
        n_fail = sum(j.id in result.failed for j in js)
        retried = sum(len(attempts(j.run_dir(result.out))) > 1 for j in js)
        lines.append(f"| {kind} | {len(js)} | {n_run} | {n_skip} | {n_fail} | {len(js) - n_run - n_skip - n_fail} "
                     f"| {retried} |")
    return "\n".join(lines)


def write_sweep_report(spec: SweepSpec, result: SweepResult, command: list[str] | None = None,
                       prior: Path | None = None) -> Path:
    """Write ``<sweep>/report.md`` (+ ``leaderboard.png`` and ``report/<env>/``) from the run folders.

    ``prior``: the folder of an earlier report of this spec (``haptic-recog sweep --prior-report``); its episodes
    stand in for the evaluate jobs not finished here (a job finished here takes precedence), and the report names
    the agent seeds taken from it."""
    from agents.evaluate import rl_markdown_table, write_report

    out = result.out
    # read (and check) the earlier report before anything is written
    prior_records = {env: load_prior_records(spec, prior, env) for env in spec.envs} if prior is not None else {}
    lines = [f"# Sweep `{spec.name}`", ""]
    if spec.description:
        lines += [spec.description, ""]
    if command:
        lines += ["Command:", "", "```", shlex.join(command), "```", ""]
    lines += [f"Spec: `{spec.source}`; sweep folder: `{out}`; this run: {result.seconds / 60:.1f} min.", "",
              "## Jobs", "", _jobs_table(spec, result), ""]
    if result.failed:
        lines += ["### Failed jobs", "", "Each was retried (Ray `max_retries`) and still failed; re-run the sweep to "
                  "try them again (finished jobs are skipped).", ""]
        for jid, err in result.failed.items():
            a = attempts(spec.by_id()[jid].run_dir(out))
            lines += [f"- `{jid}` ({len(a)} attempt(s)):", "", "  ```", *["  " + ln for ln in err.splitlines()[-8:]],
                      "  ```"]
        lines.append("")
    short = []  # trainings that max_minutes stopped before total_timesteps: done, and ranked, with fewer steps
    for j in spec.jobs:
        if j.kind == "train" and is_done(j.run_dir(out)):
            d = read_done(j.run_dir(out))
            steps = d.get("steps")
            if "steps" not in d and Path(d["model"]).is_file():  # a job done before its steps were recorded
                steps = model_steps(Path(d["model"]))
            if steps is not None and steps < j.params["total_timesteps"]:
                short.append(f"- `{j.id}`: {steps} of {j.params['total_timesteps']} steps (its time limit, "
                             f"max_minutes = {j.params['max_minutes']:g})")
    if short:
        lines += ["### Trainings stopped by their time limit", "",
                  "Each is done (a later run does not continue it) and its agent is evaluated as trained:", "",
                  *short, ""]
    retried = [(j, attempts(j.run_dir(out))) for j in spec.jobs]
    retried = [(j, a) for j, a in retried if len(a) > 1]
    if retried:
        lines += ["### Retried jobs", ""]
        for j, a in retried:
            errs = "; ".join(x.get("error", "worker died") .splitlines()[0] if x.get("error") else
                             ("worker died / stopped" if "outcome" not in x else x["outcome"]) for x in a[:-1])
            state = ("done" if is_done(j.run_dir(out)) else "failed" if j.id in result.failed
                     else "not finished (not run this time, or stopped)")
            lines.append(f"- `{j.id}`: {len(a)} attempts, {state}; earlier attempts: {errs}")
        lines.append("")

    aggs: dict[str, dict[str, Any]] = {}
    for env, (env_id, kwargs) in spec.envs.items():
        records = load_records(spec, out, env)
        jobs = [j for j in spec.jobs if j.kind == "evaluate" and j.params["env"] == env]
        finished: dict[str, list[int]] = {}
        missing: dict[str, list[int]] = {}  # agent -> seeds, in the spec's order
        for j in jobs:
            (finished if is_done(j.run_dir(out)) else missing).setdefault(j.params["agent"], []).append(j.params["seed"])
        from_prior: dict[str, list[int]] = {}
        if prior is not None:
            for (agent, seed), recs in prior_records[env].items():
                if seed in missing.get(agent, []):
                    records += recs
                    missing[agent].remove(seed)
                    from_prior.setdefault(agent, []).append(seed)
                    finished.setdefault(agent, []).append(seed)
            missing = {a: s for a, s in missing.items() if s}
        if not records:
            continue
        present = {r.agent for r in records}
        agents = [a for a in dict.fromkeys(j.params["agent"] for j in jobs) if a in present]  # the spec's order
        if "random" in agents:  # the baseline first: the tables read as "vs random"
            agents.remove("random")
            agents.insert(0, "random")
        records = sorted(records, key=lambda r: agents.index(r.agent))
        env_out = out / "report" / env
        p = jobs[0].params
        seeds = {a: sorted(finished.get(a, [])) for a in agents}
        extra = (f"env `{env_id}` with `{kwargs}`; {p['episodes']} episodes x env seeds {p['env_seeds']} per agent "
                 f"seed; agent seeds: " + ", ".join(f"{a} {s}" for a, s in seeds.items()) + ".")
        if from_prior:
            extra += (f" From the earlier report `{prior}` (run folders not here): "
                      + ", ".join(f"{a} {sorted(s)}" for a, s in from_prior.items()) + ".")
        if missing:
            extra += " Not run (or not finished): " + ", ".join(f"{a} {s}" for a, s in missing.items()) + "."
        write_report(records, env_out, _max_grasps(env_id, kwargs), title=f"Sweep {spec.name}: {env}", extra=extra,
                     period=p["episodes"])  # every agent seed replays the same episodes per env seed: clusters
        with atomic_write(env_out / AGENT_SEEDS, "w") as fh:  # the seed lists episodes.csv's offsets count in
            json.dump(_agent_seeds(spec, env), fh)
        agg = json.loads((env_out / "results.json").read_text())["rliable"]
        aggs[env] = agg
        rel = env_out.relative_to(out)
        lines += [f"## {env}", "", extra, "", rl_markdown_table(agg), "",
                  f"![performance profile]({rel}/performance_profile.png) "
                  f"![success vs grasps]({rel}/success_vs_grasps.png)", "",
                  f"Full tables (mean grasps, median, fewer than random): [{rel}/results.md]({rel}/results.md).", ""]
    if aggs:
        _leaderboard_png(aggs, out / "leaderboard.png")
        lines[lines.index("## Jobs")] = ("![leaderboard](leaderboard.png)\n\nIQM: interquartile mean of the grasps at "
                                          "the stop; success at the stop (mean over episodes); P: probability of "
                                          "improvement over random; 95% stratified cluster bootstrap CIs "
                                          f"({next(iter(aggs.values()))['reps']} resamples; strata = env "
                                          "seeds; clusters = the episodes that every agent seed replays, resampled "
                                          "with all their replays).\n\n## Jobs")

    ds = [j for j in spec.jobs if j.kind == "dataset" and is_done(j.run_dir(out))]
    if ds:
        lines += ["## Datasets (shared cache)", "", "| objects | fingers | normals | train | val | built in | cache file |",
                  "|" + "---|" * 7]
        for j in ds:
            d = read_done(j.run_dir(out))
            c = j.params["config"]
            how = "cache hit" if d["from_cache"] else f"{d['build_seconds']:.1f} s"
            lines.append(f"| {j.params['objects']} | {c['n_fingers']} | {c['normals']} | {d['train']} | {d['val']} "
                         f"| {how} | `{Path(d['cache']).name}` |")
        lines.append("")
    an = [j for j in spec.jobs if j.kind == "analysis" and is_done(j.run_dir(out))]
    if an:
        lines += ["## Analysis", ""]
        for j in an:
            rel = (j.run_dir(out) / "analysis" / "results.md").relative_to(out)
            lines.append(f"- {j.params['objects']}: [{rel}]({rel})")
        lines.append("")
    path = out / "report.md"
    path.write_text("\n".join(lines).rstrip() + "\n")
    return path
