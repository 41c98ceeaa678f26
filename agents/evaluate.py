"""Evaluate agents on HapticRecog: success at the stop, grasps to the threshold, 95% CIs, plots.

For each agent and each seed ``s`` the env is reset with ``seed=s`` once and then runs ``episodes``
episodes (unseeded resets continue its RNG), so every agent sees the same objects and poses.

Per episode we record the number of grasps at the stop (termination at the threshold, or truncation at
``max_grasps``: censored), whether the recogniser *decided* (reached the threshold) and whether its
prediction at the stop is the true object (``correct``). The summary reports, per agent:

* ``success``: fraction whose prediction at the stop is right (decided or not), with a 95% Wilson interval;
* ``decided``: fraction that reached the threshold;
* ``decided_correct``: fraction decided **and** correct, the open issues' "success at the stop", with a 95% Wilson
  interval (a proportion's bootstrap CI has no width at 0 or 100 %);
* ``grasps``: mean and median grasps at the stop with 95% bootstrap CIs, and the spread over seeds;
* ``fewer_than_random``: relative reduction of mean grasps vs the ``random`` agent, with a bootstrap CI;
* the success-vs-grasps curve: fraction of episodes decided **and** correct within ``g`` grasps.

The other CIs are percentile bootstraps by :func:`scipy.stats.bootstrap`; the reduction's resamples the agent's and
random's episodes independently (conservative: the agents meet the same objects and poses). The RL aggregates come
from ``rliable`` (:func:`rl_aggregates`): the IQM of the grasps at the stop and the success at the stop with
stratified bootstrap CIs (episodes resampled within each env seed), the probability of improvement of each agent over
random, and the performance profile (fraction decided and correct within ``tau`` grasps, with its CI band).

Outputs in ``--out``: ``results.md`` (markdown tables), ``results.json``, ``episodes.csv``,
``success_vs_grasps.png``, ``grasps_boxplot.png``, ``performance_profile.png``, ``confusion.png`` (per agent: the
object predicted at the stop against the true one, each row normalised; the most common errors are listed in
``results.md``) and, with ``--learning-curves``, ``learning_curves.png``.

An interrupted evaluation resumes: the command saves every finished block of episodes (one agent on one env seed)
in ``<out>/.partial/`` at once, and the same command run again, with the same code, evaluates only the missing blocks
(a block saved by other code is played again: :func:`code_fingerprint`; each block resets
the env and the agent with its seed, so its episodes are the same either way); the folder is removed once the
report is written.

The agents' own random numbers under env seed ``s`` (random approaches, the look-ahead's candidates, sampled SB3
actions) come from a stream apart from the env's (:func:`agent_seed_for`); ``--agent-stream env`` draws them from the
env seed's own stream, as every run before the fix of 2026-12-07 did, to repeat a committed run.

Command line (a sub-command of ``python -m haptic_env.cli``)::

    python -m haptic_env.cli evaluate --agents random greedy ppo=runs/ppo/ppo_final.zip \\
        --episodes 40 --seeds 0 1 2 3 4 --out outputs/eval --learning-curves runs/ppo
"""

from __future__ import annotations

import contextlib
import csv
import json
import re
import shutil
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

__all__ = [
    "EpisodeRecord",
    "run_episodes",
    "agent_seed_for",
    "check_agent_stream",
    "AGENT_SPAWN_KEY",
    "AGENT_STREAMS",
    "evaluate_agents",
    "summarize",
    "success_curve",
    "bootstrap_ci",
    "proportion_ci",
    "score_matrix",
    "rl_aggregates",
    "write_report",
    "plot_learning_curves",
    "read_monitor",
    "make_agent",
    "add_parser",
]


@dataclass(frozen=True)
class EpisodeRecord:
    agent: str
    seed: int
    episode: int
    object: str
    grasps: int
    decided: bool
    correct: bool
    certainty: float
    ret: float
    predicted: str = ""  # the object predicted at the stop ("" in episodes.csv files written before it was kept)


def _check_episodes(n_episodes) -> None:
    """``n_episodes`` must be a whole number >= 1 (2.5 is not cut to 2, nor True taken as 1)."""
    from haptic_env.numbers import whole_at_least

    whole_at_least(n_episodes, 1, "n_episodes")


#: spawn key of the agents' random numbers under an env seed (:func:`agent_seed_for`)
AGENT_SPAWN_KEY = 1
#: where an agent's random numbers under env seed ``s`` come from (:func:`agent_seed_for`): ``"apart"`` (the
#: default) a stream apart from the env's; ``"env"`` the env's own, as every ``evaluate`` run before the fix of
#: 2026-12-07 drew them (to repeat a committed run)
AGENT_STREAMS = ("apart", "env")


def check_agent_stream(stream) -> str:
    """``stream`` unchanged if it is one of :data:`AGENT_STREAMS`, else a ``ValueError`` naming it."""
    if stream not in AGENT_STREAMS:
        raise ValueError(f"agent stream must be one of {AGENT_STREAMS}, got {stream!r}")
    return stream


def stream_words(stream: str) -> str:
    """What a report says of where its agents' random numbers came from."""
    if check_agent_stream(stream) == "env":
        return ("the agents' random numbers from the env seeds' own streams (--agent-stream env, as before the fix of "
                "2026-12-07)")
    return "the agents' random numbers apart from the env's (agent_seed_for)"


def agent_seed_for(seed: int, agent_seed: int | None = None, stream: str = "apart") -> int:
    """The seed of an agent's own random numbers for env seed ``seed`` (an int >= 0): the first 64-bit word of
    ``SeedSequence(seed, spawn_key=(AGENT_SPAWN_KEY,))``, a stream apart from the env's. Gymnasium seeds the env with
    ``SeedSequence(seed)``, and so did an agent seeded with ``seed`` itself, as every ``evaluate`` run did before the
    fix of 2026-12-07 (``stream="env"`` repeats it): a random agent's first action then reused the numbers that drew the
    episode's object and its yaw, its elevation a function of the yaw. With ``agent_seed`` (an int >= 0; either
    stream) the first 32-bit word of ``SeedSequence([seed, agent_seed])``, as the sweeps' jobs have always drawn it:
    the runs of one agent with different seeds differ. A ``ValueError`` names a bad seed or stream."""
    from haptic_env.numbers import whole_at_least

    check_agent_stream(stream)
    seed = whole_at_least(seed, 0, "seed")
    if agent_seed is not None:
        agent_seed = whole_at_least(agent_seed, 0, "agent_seed")
        return int(np.random.SeedSequence([seed, agent_seed]).generate_state(1)[0])
    if stream == "env":
        return seed
    return int(np.random.SeedSequence(seed, spawn_key=(AGENT_SPAWN_KEY,)).generate_state(1, np.uint64)[0])


def run_episodes(agent, make_env: Callable[[], Any], n_episodes: int, seed: int,
                 progress: Callable[[int], None] | None = None, agent_seed: int | None = None,
                 agent_stream: str = "apart") -> list[EpisodeRecord]:
    """Run ``n_episodes`` of ``agent`` on a fresh env from ``make_env()``, seeded with ``seed``.

    The agent's own randomness (random actions, greedy's candidates, sampled SB3 actions) is seeded with
    :func:`agent_seed_for` of ``seed``, so that agents compared on one env seed share their random numbers, which are
    apart from the env's (``agent_stream="env"``: the env's own, as ``evaluate`` before the fix of 2026-12-07); with
    ``agent_seed`` the runs of one agent with different agent seeds differ (the objects and poses still depend on
    ``seed`` alone). Bad settings fail before the env is made."""
    _check_episodes(n_episodes)
    own = agent_seed_for(seed, agent_seed, agent_stream)
    env = make_env()
    records = []
    try:
        for ep in range(n_episodes):
            obs, info = env.reset(seed=seed if ep == 0 else None)
            agent.reset(env, seed=own if ep == 0 else None)
            ret, done = 0.0, False
            while not done:
                obs, r, terminated, truncated, info = env.step(agent.act(obs, env))
                ret += float(r)
                done = terminated or truncated
            records.append(EpisodeRecord(
                agent=agent.name, seed=int(seed), episode=ep, object=str(info["true_object"]),
                grasps=int(info["grasps"]), decided=bool(info["decided"]), correct=bool(info["correct"]),
                certainty=float(info["certainty"]), ret=ret, predicted=str(info["predicted"]),
            ))
            if progress is not None:
                progress(1)
    finally:
        env.close()
    return records


def repeated_names(agents: Sequence[Any]) -> list[str]:
    """The names (``agent.name``) that more than one of ``agents`` carries, sorted: a summary would pool them."""
    from haptic_env.numbers import repeated

    return repeated(a.name for a in agents)


def evaluate_agents(agents: Sequence[Any], make_env: Callable[[], Any], n_episodes: int,
                    seeds: Iterable[int], progress: bool = True, store: str | Path | None = None,
                    keys: Sequence[str] | None = None, agent_stream: str = "apart") -> list[EpisodeRecord]:
    """Every agent x every seed x ``n_episodes`` episodes (tqdm progress; ``agent_stream``: :func:`agent_seed_for`).

    With ``store`` (a folder) every finished block (one agent on one seed) is saved there at once, as
    ``<key>-seed<s>.json``, and blocks already saved there are read instead of run, so that an interrupted
    evaluation resumes. ``keys[i]`` names agent ``i``'s blocks: it must change whenever what the agent does (its
    ``agent_stream`` too) or the env it runs in changes (:func:`_main` hashes the command's arguments and model files
    into it)."""
    from tqdm.auto import tqdm

    from haptic_env.numbers import repeated

    _check_episodes(n_episodes)
    check_agent_stream(agent_stream)
    seeds = list(seeds)
    for s in seeds:  # a bad seed fails here, before any episode
        agent_seed_for(s, stream=agent_stream)
    if repeated(seeds):  # the same episodes twice would count as twice the evidence
        raise ValueError(f"seeds must be distinct, got {seeds}")
    twice = repeated_names(agents)
    if twice:  # the summary groups episodes by name: two agents of one name would be pooled into one row
        raise ValueError(f"agents must have distinct names, got {twice} more than once (name a model NAME=model.zip)")
    if store is not None and (keys is None or len(keys) != len(agents)):
        raise ValueError(f"store needs one key per agent ({len(agents)}), got {keys!r}")
    out: list[EpisodeRecord] = []
    with tqdm(total=len(agents) * len(seeds) * n_episodes, desc="evaluate", disable=not progress) as bar:
        for i, agent in enumerate(agents):
            for s in seeds:
                block = None if store is None else _block_path(store, keys[i], s)
                saved = _read_block(block, n_episodes) if block is not None else None
                if saved is not None:
                    out += saved
                    bar.update(len(saved))
                    continue
                bar.set_postfix_str(f"{agent.name} seed={s}")
                recs = run_episodes(agent, make_env, n_episodes, s, progress=bar.update, agent_stream=agent_stream)
                if block is not None:
                    from haptic_env.cache import atomic_write

                    with atomic_write(block, "w") as fh:
                        json.dump([asdict(r) for r in recs], fh)
                out += recs
    return out


def _block_path(store: str | Path, key: str, seed: int) -> Path:
    """Where :func:`evaluate_agents` saves the block of the agent keyed ``key`` on env seed ``seed``."""
    return Path(store) / f"{key}-seed{int(seed)}.json"


def _read_block(path: Path, n_episodes: int) -> list[EpisodeRecord] | None:
    """A saved block's records, or None (not saved, or unreadable: then it is run again)."""
    if not path.is_file():
        return None
    try:
        recs = [EpisodeRecord(**r) for r in json.loads(path.read_text())]
    except (ValueError, TypeError, OSError) as exc:
        warnings.warn(f"cannot read the saved episodes {path} ({exc}); running them again", RuntimeWarning,
                      stacklevel=3)
        return None
    return recs if len(recs) == n_episodes else None


# ------------------------------------------------------------------------------------ stats
def bootstrap_ci(x: np.ndarray, stat: Callable[[np.ndarray], float] = np.mean, n_boot: int = 2000,
                 alpha: float = 0.05, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap ``(lo, hi)`` of ``stat`` over the entries of ``x`` (:func:`scipy.stats.bootstrap`;
    ``stat`` is called with ``axis=`` when it is ``np.mean`` or ``np.median``)."""
    from scipy.stats import bootstrap

    x = np.asarray(x, dtype=np.float64)
    if x.size == 0:
        return (float("nan"), float("nan"))
    if x.size == 1 or np.all(x == x[0]):  # no spread: every resample gives the same value
        v = float(stat(x))
        return (v, v)
    vectorized = stat is np.mean or stat is np.median
    res = bootstrap((x,), stat, n_resamples=n_boot, confidence_level=1 - alpha, method="percentile",
                    vectorized=vectorized, rng=np.random.default_rng(seed))
    ci = res.confidence_interval
    return float(ci.low), float(ci.high)


def proportion_ci(successes: int, n: int, alpha: float = 0.05) -> tuple[float, float]:
    """The Wilson score interval ``(lo, hi)`` of ``successes`` out of ``n`` 0/1 outcomes
    (:meth:`scipy.stats.binomtest(...).proportion_ci <scipy.stats.binomtest>`); ``(nan, nan)`` for ``n = 0``. Unlike a
    bootstrap it keeps its width at 0 and 100 % (40 of 40: [91.2, 100] %)."""
    from scipy.stats import binomtest

    if n == 0:
        return (float("nan"), float("nan"))
    ci = binomtest(int(successes), int(n)).proportion_ci(confidence_level=1 - alpha, method="wilson")
    return float(ci.low), float(ci.high)


def _ratio_ci(a: np.ndarray, b: np.ndarray, n_boot: int = 2000, seed: int = 1) -> tuple[float, float, float]:
    """``1 - mean(a) / mean(b)`` and its percentile bootstrap CI (:func:`scipy.stats.bootstrap`, a and b resampled
    independently)."""
    from scipy.stats import bootstrap

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    value = float(1.0 - a.mean() / b.mean())
    if (a.size < 2 or np.all(a == a[0])) and (b.size < 2 or np.all(b == b[0])):
        return value, value, value
    if a.size < 2 or b.size < 2:  # one episode on a side: no interval (the bootstrap needs two per sample)
        return value, float("nan"), float("nan")

    def fewer(x, y, axis=-1):
        return 1.0 - x.mean(axis=axis) / y.mean(axis=axis)

    res = bootstrap((a, b), fewer, n_resamples=n_boot, method="percentile", vectorized=True, paired=False,
                    rng=np.random.default_rng(seed))
    return value, float(res.confidence_interval.low), float(res.confidence_interval.high)


def success_curve(records: Sequence[EpisodeRecord], max_grasps: int) -> np.ndarray:
    """``(max_grasps,)``: fraction of episodes decided and correct within ``g = 1..max_grasps`` grasps."""
    g = np.array([r.grasps if (r.decided and r.correct) else np.inf for r in records])
    return np.array([(g <= k).mean() for k in range(1, max_grasps + 1)]) if len(g) else np.zeros(max_grasps)


def summarize(records: Sequence[EpisodeRecord], baseline: str = "random",
              period: int | None = None) -> list[dict[str, Any]]:
    """One summary dict per agent (in order of first appearance); see the module docstring. With ``period`` (a
    sweep: each agent seed played the same ``period`` episodes per env seed) every interval is a paired stratified
    cluster bootstrap (:func:`cluster_intervals`) instead: the replays of one situation by an agent's seeds are not
    independent episodes, so Wilson intervals and episode bootstraps over them would be too narrow."""
    names = list(dict.fromkeys(r.agent for r in records))
    by = {n: [r for r in records if r.agent == n] for n in names}
    base = np.array([r.grasps for r in by.get(baseline, [])], dtype=np.float64)
    rows = []
    for n in names:
        rs = by[n]
        g = np.array([r.grasps for r in rs], dtype=np.float64)
        c = np.array([r.correct for r in rs], dtype=np.float64)
        d = np.array([r.decided for r in rs], dtype=np.float64)
        seeds = sorted({r.seed for r in rs})
        seed_means = [np.mean([r.grasps for r in rs if r.seed == s]) for s in seeds]
        against = baseline if base.size and n != baseline else None
        ci = (_clustered_summary(records, n, against, period) if period is not None
              else _episode_intervals(c, d, g, base if against else None))
        row = {
            "agent": n, "episodes": len(rs), "seeds": len(seeds),
            "success": float(c.mean()), "success_ci": ci["success_ci"],
            "decided": float(d.mean()),
            "decided_correct": float((c * d).mean()), "decided_correct_ci": ci["decided_correct_ci"],
            "grasps_mean": float(g.mean()), "grasps_mean_ci": ci["grasps_mean_ci"],
            "grasps_median": float(np.median(g)), "grasps_median_ci": ci["grasps_median_ci"],
            # over the env seeds' means; one seed has no spread to give (NaN, shown as "-"), not 0
            "grasps_seed_std": float(np.std(seed_means, ddof=1)) if len(seeds) > 1 else float("nan"),
            "return_mean": float(np.mean([r.ret for r in rs])),
        }
        if against:
            row["fewer_than_random"] = float(1.0 - g.mean() / base.mean())
            row["fewer_than_random_ci"] = ci["fewer_than_random_ci"]
        rows.append(row)
    return rows


def _episode_intervals(c: np.ndarray, d: np.ndarray, g: np.ndarray, base: np.ndarray | None) -> dict[str, Any]:
    """:func:`summarize`'s intervals over independent episodes (correct ``c``, decided ``d``, grasps ``g``; the
    fewer-grasps ratio against the baseline's grasps ``base``): Wilson intervals of the shares, percentile bootstraps
    of the grasps."""
    out = {"success_ci": proportion_ci(int(c.sum()), len(c)),
           "decided_correct_ci": proportion_ci(int((c * d).sum()), len(c)),
           "grasps_mean_ci": bootstrap_ci(g), "grasps_median_ci": bootstrap_ci(g, np.median)}
    if base is not None:
        out["fewer_than_random_ci"] = _ratio_ci(g, base)[1:]
    return out


def _clustered_summary(records: Sequence[EpisodeRecord], agent: str, baseline: str | None,
                       period: int) -> dict[str, Any]:
    """:func:`summarize`'s intervals of ``agent`` by the paired stratified cluster bootstrap (:func:`cluster_intervals`;
    the fewer-grasps ratio with ``baseline``'s episodes resampled by the same draws)."""
    G = score_matrix(records, agent, lambda r: r.grasps)
    C = score_matrix(records, agent, lambda r: float(r.correct))
    DC = score_matrix(records, agent, lambda r: float(r.correct and r.decided))
    scores = {"success": C, "decided_correct": DC, "grasps_mean": G, "grasps_median": G}
    fns = {"success": np.mean, "decided_correct": np.mean, "grasps_mean": np.mean, "grasps_median": np.median}
    out = {}
    for k, (key, m) in enumerate(scores.items()):
        _, ci = cluster_intervals({key: m}, lambda x, f=fns[key]: np.array([f(x)]), period, seed=10 + k)
        out[f"{key}_ci"] = tuple(map(float, ci[key][:, 0]))
    if baseline is not None:
        B = score_matrix(records, baseline, lambda r: r.grasps)
        _, ci = cluster_intervals({"r": [G, B]}, lambda a, b: np.array([1.0 - a.mean() / b.mean()]), period, seed=20)
        out["fewer_than_random_ci"] = tuple(map(float, ci["r"][:, 0]))
    return out


# ----------------------------------------------------------------------------- RL aggregates
def score_matrix(records: Sequence[EpisodeRecord], agent: str, value: Callable[[EpisodeRecord], float]) -> np.ndarray:
    """``(episodes per seed, seeds)`` matrix of ``value(record)`` of one agent, in rliable's ``(runs, tasks)``
    layout: the env seeds are the strata (every agent sees the same objects and poses per seed), the episodes
    of a seed its runs. Seeds with more episodes than the others are cut to the smallest count."""
    by_seed: dict[int, list[EpisodeRecord]] = {}
    for r in records:
        if r.agent == agent:
            by_seed.setdefault(r.seed, []).append(r)
    if not by_seed:
        raise ValueError(f"no episodes of agent {agent!r}")
    cols = [sorted(by_seed[s], key=lambda r: r.episode) for s in sorted(by_seed)]
    E = min(len(c) for c in cols)
    return np.array([[value(c[e]) for c in cols] for e in range(E)], dtype=np.float64)


def cluster_intervals(scores: dict[str, Any], fn: Callable[..., np.ndarray], period: int, reps: int = 2000,
                      seed: int = 0, alpha: float = 0.05) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Point estimates and ``1 - alpha`` percentile intervals of ``fn`` by a stratified cluster bootstrap, in
    rliable's ``get_interval_estimates`` layout (``(point, {name: (2, k) array})``).

    ``scores[name]`` is a :func:`score_matrix` ``(R, T)`` (or a list of them, passed to ``fn`` together, e.g. an
    agent's and the baseline's for the probability of improvement) whose row ``r x period + u`` is replicate ``r`` of
    situation ``u`` of its env seed: the episodes of several agent (training) seeds on one env seed play the same
    ``period`` situations (objects and poses), so they are not independent runs. Each resample draws ``period``
    situations with replacement per env seed and keeps every replicate of each; the draws are the same for every
    name and every matrix of a name (paired). With one replicate per situation this is rliable's stratified bootstrap
    with draws shared across agents."""
    if not (isinstance(period, (int, np.integer)) and period >= 1):
        raise ValueError(f"period must be an int >= 1, got {period!r}")
    mats = {n: [np.asarray(m, dtype=np.float64) for m in (v if isinstance(v, list) else [v])]
            for n, v in scores.items()}
    T = next(iter(mats.values()))[0].shape[1]
    for n, ms in mats.items():
        for m in ms:
            if m.ndim != 2 or m.shape[1] != T or m.shape[0] % period or m.shape[0] == 0:
                raise ValueError(f"{n}: a score matrix of (replicates x {period}, {T}) rows and env seeds, got "
                                 f"{m.shape}")
    point = {n: np.atleast_1d(np.asarray(fn(*ms), dtype=np.float64)) for n, ms in mats.items()}
    rng = np.random.default_rng(seed)
    cols = np.arange(T)
    draws = {n: [] for n in mats}
    for _ in range(reps):
        D = rng.integers(0, period, size=(period, T))  # the situations drawn per env seed, shared by all

        def pick(m: np.ndarray) -> np.ndarray:
            k = m.shape[0] // period
            rows = (np.arange(k)[:, None, None] * period + D[None]).reshape(k * period, T)
            return m[rows, cols]

        for n, ms in mats.items():
            draws[n].append(np.atleast_1d(np.asarray(fn(*(pick(m) for m in ms)), dtype=np.float64)))
    ci = {n: np.percentile(np.stack(d), [100 * alpha / 2, 100 * (1 - alpha / 2)], axis=0) for n, d in draws.items()}
    return point, ci


def _grasps_to_success(r: EpisodeRecord) -> float:
    return float(r.grasps) if (r.decided and r.correct) else np.inf


def rl_aggregates(records: Sequence[EpisodeRecord], max_grasps: int, baseline: str = "random", reps: int = 2000,
                  seed: int = 0, period: int | None = None) -> dict[str, Any]:
    """rliable aggregates of each agent (Agarwal et al. 2021), with 95% stratified bootstrap CIs (``reps``
    resamples of the episodes within each env seed; :func:`score_matrix`). With ``period`` (a sweep: each agent seed
    played the same ``period`` episodes per env seed) the situations are resampled with all their replicates
    (:func:`cluster_intervals`), since an agent's seeds replaying one situation are not independent runs:

    * ``grasps_iqm``: interquartile mean of the grasps at the stop (robust to the episodes censored at
      ``max_grasps``);
    * ``success_iqm_seeds``: IQM over the env seeds of the success rate at the stop (the IQM of a 0/1 outcome
      per episode would be 0 or 1 whenever success is below 25 % or above 75 %; its interval resamples the
      episodes, then takes each seed's rate), and ``success``, the mean over episodes;
    * ``p_fewer_grasps``: probability of improvement over ``baseline``: P(an episode of the agent stops after
      fewer grasps than an episode of the baseline on the same seed), ties counted half; ``p_success``: the same
      for correct at the stop;
    * ``profile``: the performance profile, the fraction of episodes decided and correct within ``tau`` grasps
      for ``tau = 1..max_grasps``, with its CI band.
    """
    from rliable import library as rly
    from rliable import metrics

    names = list(dict.fromkeys(r.agent for r in records))
    grasps = {n: score_matrix(records, n, lambda r: r.grasps) for n in names}
    correct = {n: score_matrix(records, n, lambda r: float(r.correct)) for n in names}
    to_success = {n: score_matrix(records, n, _grasps_to_success) for n in names}
    tau = np.arange(1, max_grasps + 1)
    def est(scores, fn, k):
        if period is not None:
            return cluster_intervals(scores, fn, period, reps=reps, seed=seed + k)
        # rliable's StratifiedBootstrap draws its resamples from NumPy's global RNG, whatever random_state says:
        # seed it for this call and put the caller's state back, so that a report is the same every time
        state = np.random.get_state()
        np.random.seed(seed + k)
        try:
            with warnings.catch_warnings():  # rliable hands arch a RandomState through arch's deprecated keyword
                warnings.filterwarnings("ignore", category=FutureWarning, module=r"arch\.")
                return rly.get_interval_estimates(scores, fn, reps=reps, random_state=np.random.RandomState(seed + k))
        finally:
            np.random.set_state(state)

    g_iqm, g_ci = est(grasps, lambda x: np.array([metrics.aggregate_iqm(x)]), 0)
    s_mean, s_ci = est(correct, lambda x: np.array([metrics.aggregate_mean(x)]), 1)
    # per-seed success rates: one run per seed, one task
    # the episodes resampled within each seed, then each seed's rate and their IQM (resampling the 3-5 seed rates
    # themselves, as before, covered about 83-92 % in simulation, not 95 %)
    s_iqm, s_iqm_ci = est(correct, lambda x: np.array([metrics.aggregate_iqm(x.mean(0, keepdims=True).T)]), 2)
    prof, prof_ci = est(to_success, lambda x: np.array([np.mean(x <= t) for t in tau]), 3)
    out: dict[str, Any] = {"reps": reps, "tau": tau.tolist(), "agents": {}, "period": period}
    for n in names:
        row = {"grasps_iqm": float(g_iqm[n][0]), "grasps_iqm_ci": tuple(map(float, g_ci[n][:, 0])),
               "success": float(s_mean[n][0]), "success_ci": tuple(map(float, s_ci[n][:, 0])),
               "success_iqm_seeds": float(s_iqm[n][0]), "success_iqm_seeds_ci": tuple(map(float, s_iqm_ci[n][:, 0])),
               "profile": prof[n].tolist(), "profile_ci": prof_ci[n].tolist()}
        if n != baseline and baseline in grasps:
            pairs = {"grasps": {n: [-grasps[n], -grasps[baseline]]}, "success": {n: [correct[n], correct[baseline]]}}
            for key, k in (("grasps", 4), ("success", 5)):
                p, ci = est(pairs[key], metrics.probability_of_improvement, k)
                row[f"p_{'fewer_grasps' if key == 'grasps' else 'success'}"] = float(np.ravel(p[n])[0])
                row[f"p_{'fewer_grasps' if key == 'grasps' else 'success'}_ci"] = tuple(map(float, np.ravel(ci[n])))
        out["agents"][n] = row
    return out


def rl_markdown_table(agg: dict[str, Any], baseline: str = "random") -> str:
    head = (f"| agent | IQM grasps at the stop [95% CI] | success at the stop [95% CI] | IQM over seeds of success "
            f"[95% CI] | P(fewer grasps than {baseline}) [95% CI] | P(success improves on {baseline}) [95% CI] |")
    lines = [head, "|" + "---|" * 6]
    for n, r in agg["agents"].items():
        pg = _fmt_ci(r["p_fewer_grasps"], r["p_fewer_grasps_ci"]) if "p_fewer_grasps" in r else "—"
        ps = _fmt_ci(r["p_success"], r["p_success_ci"]) if "p_success" in r else "—"
        lines.append(f"| {n} | {_fmt_ci(r['grasps_iqm'], r['grasps_iqm_ci'])} "
                     f"| {_fmt_ci(r['success'], r['success_ci'], pct=True)} "
                     f"| {_fmt_ci(r['success_iqm_seeds'], r['success_iqm_seeds_ci'], pct=True)} | {pg} | {ps} |")
    return "\n".join(lines)


def _fmt_ci(v, ci, pct=False):
    if pct:
        return f"{100 * v:.1f}% [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]"
    return f"{v:.2f} [{ci[0]:.2f}, {ci[1]:.2f}]"


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    head = ("| agent | episodes (seeds) | success at stop [95% CI] | decided | decided and correct [95% CI] "
            "| mean grasps [95% CI] | median grasps [95% CI] | seed std | fewer grasps than random [95% CI] |")
    lines = [head, "|" + "---|" * 9]
    for r in rows:
        fewer = _fmt_ci(r["fewer_than_random"], r["fewer_than_random_ci"], pct=True) if "fewer_than_random" in r else "—"
        lines.append(
            f"| {r['agent']} | {r['episodes']} ({r['seeds']}) | {_fmt_ci(r['success'], r['success_ci'], pct=True)} "
            f"| {100 * r['decided']:.1f}% | {_fmt_ci(r['decided_correct'], r['decided_correct_ci'], pct=True)} "
            f"| {_fmt_ci(r['grasps_mean'], r['grasps_mean_ci'])} "
            f"| {_fmt_ci(r['grasps_median'], r['grasps_median_ci'])} | "
            f"{'-' if np.isnan(r['grasps_seed_std']) else format(r['grasps_seed_std'], '.2f')} | {fewer} |"
        )
    return "\n".join(lines)


def write_report(records: Sequence[EpisodeRecord], out: str | Path, max_grasps: int,
                 title: str = "HapticRecog evaluation", extra: str = "", period: int | None = None) -> dict[str, Path]:
    """Write results.md / results.json / episodes.csv and the PNG plots; returns their paths. ``period``: the
    episodes per env seed that each agent seed replays (a sweep), for cluster bootstrap intervals
    (:func:`summarize`, :func:`rl_aggregates`)."""
    from matplotlib.figure import Figure  # no pyplot: no global backend switch, no window

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = summarize(records, period=period)
    agg = rl_aggregates(records, max_grasps, period=period)
    paths = {"md": out / "results.md", "json": out / "results.json", "csv": out / "episodes.csv",
             "curve": out / "success_vs_grasps.png", "box": out / "grasps_boxplot.png",
             "profile": out / "performance_profile.png"}
    conf = confusion(records)
    md = (
        f"# {title}\n\n{extra}\n\n{markdown_table(rows)}\n\n"
        + (f"## Errors at the stop\n\n{errors_markdown(conf)}\n\n" if conf else "")
        + f"## RL aggregates (rliable)\n\n{rl_markdown_table(agg)}\n\n"
        + (f"95% stratified bootstrap CIs ({agg['reps']} resamples of the episodes within each env seed). "
           if period is None else
           f"95% stratified cluster bootstrap CIs ({agg['reps']} resamples of the {period} situations within each "
           "env seed, each with its replays by every agent seed, the same draws for every agent; so are the first "
           "table's intervals: the agent seeds replay the same objects and poses, so their episodes are not "
           "independent). ")
        + "IQM: "
        "interquartile mean. Success at the stop is a 0/1 outcome per episode, so its IQM is taken over the seeds' "
        "success rates. P(...): probability of improvement over random (an episode of the agent against an "
        "episode of random on the same seed, ties counted half). Performance profile (`performance_profile.png`): "
        "the fraction of episodes decided and correct within tau grasps.\n")
    curves = {r["agent"]: success_curve([e for e in records if e.agent == r["agent"]], max_grasps).tolist()
              for r in rows}
    from haptic_env.cache import atomic_write

    # whole or not at all: a later sweep report reads these back (--prior-report)
    with atomic_write(paths["json"], "w") as fh:
        fh.write(json.dumps({"summary": rows, "success_vs_grasps": curves, "rliable": agg}, indent=2))
    with atomic_write(paths["csv"], "w") as fh:
        w = csv.DictWriter(fh, fieldnames=list(asdict(records[0]).keys()))
        w.writeheader()
        for r in records:
            w.writerow(asdict(r))

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    g = np.arange(1, max_grasps + 1)
    for name, c in curves.items():
        ax.step(g, c, where="post", label=name)
    ax.set_xlabel("grasps")
    ax.set_ylabel("fraction decided and correct")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("success vs grasps")
    fig.tight_layout()
    fig.savefig(paths["curve"], dpi=120)

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    names = [r["agent"] for r in rows]
    ax.boxplot([[e.grasps for e in records if e.agent == n] for n in names], showmeans=True)
    ax.set_xticks(range(1, len(names) + 1), names)
    ax.set_ylabel("grasps at the stop")
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(paths["box"], dpi=120)

    from rliable import plot_utils

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    tau = np.asarray(agg["tau"])
    plot_utils.plot_performance_profiles(
        {n: np.asarray(r["profile"]) for n, r in agg["agents"].items()}, tau,
        performance_profile_cis={n: np.asarray(r["profile_ci"]) for n, r in agg["agents"].items()}, ax=ax,
        xlabel=r"grasps $\tau$", ylabel=r"fraction decided and correct within $\tau$")
    ax.legend(loc="lower right")
    ax.set_title("performance profile (95% stratified " + ("cluster " if period is not None else "") + "bootstrap CIs)")
    fig.tight_layout()
    fig.savefig(paths["profile"], dpi=120)

    if conf:
        paths["confusion"] = out / "confusion.png"
        plot_confusion(conf, paths["confusion"])
    with atomic_write(paths["md"], "w") as fh:  # last and whole: a stop before it keeps the md of an earlier run
        fh.write(md)
    return paths


def confusion(records: Sequence[EpisodeRecord]) -> dict[str, tuple[list[str], np.ndarray]]:
    """agent -> ``(labels, counts (L, L))``: rows the true object, columns the one predicted at the stop
    (:func:`sklearn.metrics.confusion_matrix`), labels the sorted objects of all agents' episodes; empty when any
    episode has no prediction (an ``episodes.csv`` written before predictions were kept)."""
    from sklearn.metrics import confusion_matrix

    if not records or any(not r.predicted for r in records):
        return {}
    labels = sorted({r.object for r in records} | {r.predicted for r in records})
    out = {}
    for name in dict.fromkeys(r.agent for r in records):
        rs = [r for r in records if r.agent == name]
        out[name] = (labels, confusion_matrix([r.object for r in rs], [r.predicted for r in rs], labels=labels))
    return out


def errors_markdown(conf: dict[str, tuple[list[str], np.ndarray]], top: int = 5) -> str:
    """Per agent, its ``top`` most common errors at the stop (true -> predicted, count and share of that object's
    episodes), as a markdown table."""
    lines = ["| agent | errors | most common (true -> predicted: episodes, share of the true object's) |",
             "|---|---|---|"]
    for name, (labels, M) in conf.items():
        off = M.copy()
        np.fill_diagonal(off, 0)
        idx = np.dstack(np.unravel_index(np.argsort(-off, axis=None, kind="stable"), off.shape))[0]
        worst = [f"{labels[i]} -> {labels[j]}: {off[i, j]} ({100 * off[i, j] / M[i].sum():.0f} %)"
                 for i, j in idx[:top] if off[i, j] > 0]
        lines.append(f"| {name} | {int(off.sum())} of {int(M.sum())} | {'; '.join(worst) or '-'} |")
    return "\n".join(lines)


def plot_confusion(conf: dict[str, tuple[list[str], np.ndarray]], path: Path) -> None:
    """One row-normalised confusion matrix per agent, side by side."""
    from matplotlib.figure import Figure

    k = len(conf)
    labels = next(iter(conf.values()))[0]
    size = 1.2 + 0.35 * len(labels)
    fig = Figure(figsize=(size * k + 1.0, size + 0.8))
    axes = np.atleast_1d(fig.subplots(1, k, sharey=True))
    for ax, (name, (labels, M)) in zip(axes, conf.items()):
        P = M / np.maximum(M.sum(axis=1, keepdims=True), 1)
        im = ax.imshow(P, vmin=0.0, vmax=1.0, cmap="Blues")
        for i, j in zip(*np.nonzero(M)):
            ax.text(j, i, str(M[i, j]), ha="center", va="center", fontsize=6,
                    color="white" if P[i, j] > 0.5 else "black")
        ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=6)
        ax.set_yticks(range(len(labels)), labels, fontsize=6)
        ax.set_xlabel("predicted at the stop")
        ax.set_title(name, fontsize=9)
    axes[0].set_ylabel("true object")
    fig.colorbar(im, ax=list(axes), shrink=0.8, label="share of the true object's episodes")
    fig.savefig(path, dpi=120, bbox_inches="tight")


#: a resumed training segment's files: ``<rank>.part<k>.monitor.csv`` and ``args.part<k>.json`` (``train.py``)
_SEGMENT = re.compile(r"\.part(\d+)\.(?:monitor\.csv|json)$")


def segment_suffix(k: int) -> str:
    """The file-name suffix of a training run's segment ``k``: none for its start (``args.json``,
    ``monitor/<rank>.monitor.csv``), ``.part<k>`` for a resume (``args.part<k>.json``,
    ``<rank>.part<k>.monitor.csv``)."""
    return "" if k == 1 else f".part{k}"


def run_segment(name: str) -> int:
    """The segment ``k`` of a training run that a file of that run (a Monitor CSV, an args file) belongs to
    (:func:`segment_suffix`)."""
    m = _SEGMENT.search(name)
    return int(m[1]) if m else 1


def read_monitor(folder: str | Path) -> dict[str, np.ndarray]:
    """All ``*.monitor.csv`` of ``folder`` (SB3 ``Monitor`` format) merged and sorted by wall time:
    ``{"r", "l", "t", ...info keywords}`` as float arrays.

    A resumed run's segments (``<rank>.part<k>.monitor.csv``) overlap: segment ``k`` went on past the checkpoint the
    next one resumed from (up to a checkpoint interval after a kill), and the next segment played those steps again.
    Where the run folder's ``args.part<k>.json`` records the step its segment resumed at (``resumed_at_step``,
    written by ``train.py`` since 2026-12-06), the episodes of the segment before it past that step are dropped, so
    the steps count each step once and the curve is of the line the final model learned from. The step of an episode
    is the sum of the finished episodes' lengths, which lags the trainer's count by the steps of the other envs'
    episodes in progress (at most ``(n_envs - 1) x max_grasps``), so up to that many steps past the resume point
    may be kept."""
    files = sorted(Path(folder).glob("*monitor.csv"))
    if not files:
        raise FileNotFoundError(f"no *.monitor.csv in {folder} (train with agents.sb3.make_vec_env(log_dir=...))")
    segments: dict[int, list[dict[str, str]]] = {}
    for f in files:
        k = run_segment(f.name)
        segments.setdefault(k, [])  # a segment with no finished episode yet still marks where the one before stops
        with open(f) as fh:
            first = fh.readline()
            if not first.startswith("#"):
                raise ValueError(f"{f} is not a Monitor log (no '#{{...}}' header line)")
            t0 = float(json.loads(first[1:]).get("t_start", 0.0))
            for row in csv.DictReader(fh):
                if None in row or any(v is None or v == "" for v in row.values()):
                    continue  # a line cut short (a kill or a full disk mid-write)
                row["t"] = str(float(row["t"]) + t0)
                segments[k].append(row)
    run = Path(folder).parent if Path(folder).name == "monitor" else Path(folder)  # where the args files are
    starts = {1: 0}
    for k in set(segments) - {1}:
        with contextlib.suppress(OSError, ValueError, KeyError, TypeError):
            starts[k] = int(json.loads((run / f"args{segment_suffix(k)}.json").read_text())["resumed_at_step"])
    rows: list[dict[str, str]] = []
    for k in sorted(segments):
        seg = sorted(segments[k], key=lambda r: float(r["t"]))
        after = [s for j, s in starts.items() if j > k]
        if k in starts and after:  # keep this segment's episodes up to the earliest step a later one resumed at
            steps = starts[k] + np.cumsum([float(r["l"]) for r in seg])
            seg = [r for r, s in zip(seg, steps) if s <= min(after)]
        rows += seg
    if not rows:
        return {"r": np.zeros(0), "l": np.zeros(0), "t": np.zeros(0)}
    keys = [k for k in rows[0] if all(k in r for r in rows)]
    out = {k: np.array([float(r[k] == "True") if r[k] in ("True", "False") else float(r[k]) for r in rows])
           for k in keys}
    order = np.argsort(out["t"], kind="stable")
    return {k: v[order] for k, v in out.items()}


def _rolling_mean(x: np.ndarray, window: int) -> np.ndarray:
    c = np.cumsum(np.insert(np.asarray(x, dtype=np.float64), 0, 0.0))
    i = np.arange(1, len(x) + 1)
    lo = np.maximum(0, i - window)
    return (c[i] - c[lo]) / (i - lo)


def monitor_folder(log_dir: str | Path) -> Path:
    """Where a training run's Monitor CSVs are: ``<log_dir>/monitor`` (:func:`agents.sb3.make_vec_env`'s layout), else
    ``log_dir`` itself."""
    d = Path(log_dir)
    return d / "monitor" if (d / "monitor").is_dir() else d


def plot_learning_curves(log_dirs: dict[str, str | Path], out: str | Path, window: int = 200) -> Path:
    """Episode length (= grasps), return and success vs env steps from the ``Monitor`` CSVs of each run
    (``<log_dir>/monitor/*.monitor.csv``, as written by :func:`agents.sb3.make_vec_env`)."""
    return _plot_curves({name: read_monitor(monitor_folder(d)) for name, d in log_dirs.items()}, out, window)


def _plot_curves(runs: dict[str, dict[str, np.ndarray]], out: str | Path, window: int = 200) -> Path:
    """:func:`plot_learning_curves` of runs already read (``name -> read_monitor(...)``)."""
    from matplotlib.figure import Figure  # no pyplot: no global backend switch, no window

    fig = Figure(figsize=(13, 3.8))
    axes = fig.subplots(1, 3)
    for name, data in runs.items():
        steps = np.cumsum(data["l"])
        for ax, col in zip(axes, ["l", "r", "correct"]):
            if col in data:
                ax.plot(steps, _rolling_mean(data[col], window), label=name)
    for ax, lab in zip(axes, ["grasps per episode", "episode return", "correct at stop"]):
        ax.set_xlabel("env steps (grasps)")
        ax.set_ylabel(f"{lab} (rolling mean, {window} ep.)")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out


# --------------------------------------------------------------------------------------- CLI
def make_agent(spec: str, seed: int = 0, stochastic: bool = False, no_repeat: bool = False):
    """An agent from its spec:

    * ``random``;
    * ``greedy[:<n_candidates>]``, or ``greedy-env[:<n_candidates>]`` (the look-ahead simulates the env's own
      backend, e.g. the MuJoCo hand); a ``-blind`` suffix (``greedy-blind``, ``greedy-env-blind``) hides the
      object's pose from the look-ahead (``pose_known=False``), and ``-infer`` (``greedy-env-infer``) hides it too
      but draws the look-ahead's poses from the yaw posterior of the episode's grasps (``infer_pose=True``, the hand
      envs); ``:M:S`` sets ``S`` samples per candidate (blind and infer: ``S`` poses);
    * ``<name>=<model.zip>``: PPO / SAC / recurrent PPO / maskable PPO, the algorithm from the file name or from a
      name ``ppo``, ``sac``, ``rppo`` or ``mppo``; a model trained with ``--discrete-approaches`` acts with the
      approach of its choice (maskable PPO always with its mask, :class:`agents.sb3.RepeatMask`).

    ``stochastic``: SB3 agents sample their actions (named ``<name>-stochastic``) instead of taking the mean
    action (a categorical policy's most probable approach). ``no_repeat``: a categorical SB3 agent does not try an
    approach twice while its belief stays the same (:class:`agents.sb3.SB3Agent`; named ``<name>-norepeat``);
    baselines ignore it, and an SB3 model whose policy is not categorical and memoryless is refused (``ValueError``)."""
    if spec == "random":
        from agents.random_policy import RandomAgent

        return RandomAgent(seed)
    if "=" in spec or spec.endswith(".zip"):  # before greedy: a model may be named greedy-ft=... or greedy_ppo.zip
        from agents.sb3 import ALGOS, SB3Agent, algo_of_file, load_model

        name, _, path = spec.partition("=") if "=" in spec else (Path(spec).stem, "", spec)
        # the file's own name first (a sweep's <algo>_final.zip), then an agent named after an algorithm
        algo = algo_of_file(path) or (name.lower() if name.lower() in ALGOS else None)
        name += "-stochastic" * bool(stochastic) + "-norepeat" * bool(no_repeat)
        return SB3Agent(load_model(path, algo), name=name, deterministic=not stochastic, no_repeat=no_repeat)
    if spec.startswith("greedy"):
        from agents.greedy import GreedyInfoGainAgent

        kind, _, rest = spec.partition(":")
        m, _, samples = rest.partition(":")
        if kind not in ("greedy", "greedy-env", "greedy-blind", "greedy-env-blind", "greedy-env-infer"):
            raise ValueError(f"unknown agent spec {spec!r}; use greedy[-env][-blind][:M[:S]] or "
                             "greedy-env-infer[:M[:S]]")
        if not all(v.isdigit() for v in (m, samples) if v):
            raise ValueError(f"agent spec {spec!r}: M and S must be whole numbers (greedy[-env][-blind][:M[:S]])")
        agent = GreedyInfoGainAgent(n_candidates=int(m) if m else 16, n_samples=int(samples) if samples else 1, seed=seed,
                                    simulate="env" if kind.startswith("greedy-env") else "geometric",
                                    pose_known=kind.endswith(("greedy", "-env")), infer_pose=kind.endswith("-infer"))
        agent.name = spec
        return agent
    raise ValueError(f"unknown agent spec {spec!r}; use random, greedy[-env][-blind][:M[:S]], "
                     "greedy-env-infer[:M[:S]] or NAME=path/to/model.zip")


def code_fingerprint() -> str:
    """sha256 of the Python sources of ``haptic_env`` and ``agents`` (paths and bytes): the code that played a block
    (:func:`haptic_env.cache.source_fingerprint`)."""
    from haptic_env.cache import package_fingerprint

    return package_fingerprint(Path(__file__).parent)


def _block_key(spec: str, args, kwargs: dict, code: str) -> str:
    """What one agent's saved blocks of ``evaluate`` depend on: the agent spec (with its model file's bytes), the env
    and its overrides, the episodes per seed, ``--stochastic``, ``--no-repeat``, ``--agent-stream`` and the code
    (:func:`code_fingerprint`: a run resumed after the code changed plays its saved blocks again instead of mixing
    them with the new code's)."""
    import hashlib

    from haptic_env.cache import config_key

    path = spec.partition("=")[2] if "=" in spec else (spec if spec.endswith(".zip") else "")
    model = hashlib.sha256(Path(path).read_bytes()).hexdigest() if path else ""
    name = spec.partition("=")[0] if "=" in spec else Path(spec).stem
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in name)[:40]
    return f"{safe}-" + config_key(spec, model, args.env_id, kwargs, int(args.episodes), bool(args.stochastic),
                                  *(["no-repeat"] if args.no_repeat else []),
                                  *([] if args.agent_stream == "apart" else [f"stream-{args.agent_stream}"]), code)


def add_parser(subparsers) -> None:
    from haptic_env import ENV_VARIANTS
    from haptic_env.cli import int_in, json_object, output_path
    from haptic_env.splits import ENV_TEST_SEEDS

    p = subparsers.add_parser("evaluate", help="evaluate agents on HapticRecog (table + plots)",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("--agents", nargs="+", default=["random", "greedy"],
                   help="random | greedy[-env][-blind][:M[:S]] (-env: look-ahead with the env's own backend; "
                        "-blind: without the object's pose) | greedy-env-infer[:M[:S]] (the pose drawn from the yaw "
                        "posterior of the episode's grasps, on the hand envs) | "
                        "NAME=model.zip (ppo=..., sac=..., rppo=..., mppo=...)")
    p.add_argument("--episodes", type=int_in(1), default=40, help="episodes per seed")
    p.add_argument("--seeds", type=int_in(0), nargs="+", default=list(ENV_TEST_SEEDS))
    p.add_argument("--stochastic", action="store_true",
                   help="SB3 agents sample actions from their policy (seeded per env seed) instead of the mean "
                   "action (a categorical policy's most probable approach)")
    p.add_argument("--no-repeat", action="store_true",
                   help="SB3 agents with a categorical policy (trained with --discrete-approaches) do not choose an "
                        "approach twice while the belief stays the same (a grasp that touches too few fingers leaves "
                        "it unchanged, and the policy may repeat it up to the cap); named <name>-norepeat (an mppo "
                        "model acts so always, as it was trained: for it the flag only adds the suffix)")
    p.add_argument("--agent-stream", choices=AGENT_STREAMS, default="apart",
                   help="where the agents' random numbers under an env seed come from: apart (default) a stream apart "
                        "from the env's; env the env seed's own, as every evaluate run before the fix of 2026-12-07 "
                        "drew them (to repeat a committed run; a random agent's first action then reused the numbers "
                        "of the episode's object and yaw)")
    p.add_argument("--env-id", default="HapticRecog-v0", choices=list(ENV_VARIANTS))
    p.add_argument("--env-kwargs", type=json_object, default={}, help="JSON dict of HapticRecogConfig fields")
    p.add_argument("--out", type=output_path("folder"), default="outputs/eval")
    p.add_argument("--learning-curves", nargs="*", default=[], metavar="NAME=LOG_DIR",
                   help="training log dirs (agents/sb3 layout) to plot learning curves from")
    p.set_defaults(func=_main, interrupt_note="every finished agent-seed block is saved; the same command resumes "
                                             "from them")


def _command(args, kwargs: dict) -> str:
    """The ``haptic-recog evaluate`` command line of ``args`` with every setting spelled out (the report's first
    line: the agents' model files and the overrides as JSON, so that it reruns the evaluation)."""
    import shlex

    words = ["haptic-recog", "evaluate", "--env-id", args.env_id]
    words += ["--env-kwargs", json.dumps(kwargs)] if kwargs else []
    words += ["--agents", *args.agents, "--episodes", str(args.episodes), "--seeds", *map(str, args.seeds),
              "--agent-stream", args.agent_stream]
    words += ["--stochastic"] if args.stochastic else []
    words += ["--no-repeat"] if args.no_repeat else []
    words += ["--learning-curves", *args.learning_curves] if args.learning_curves else []
    return shlex.join(words + ["--out", str(args.out)])


def _main(args) -> int:
    import haptic_env
    from haptic_env.cli import UsageError
    from haptic_env.numbers import repeated

    kwargs = args.env_kwargs if isinstance(args.env_kwargs, dict) else json.loads(args.env_kwargs)
    try:
        config = haptic_env.variant_config(args.env_id, **kwargs)  # --env-id is one of its choices
    except (TypeError, ValueError, FileNotFoundError) as exc:
        raise UsageError(f"--env-kwargs: {exc}") from exc
    out = Path(args.out)  # a folder, checked by its argparse type (cli.output_path)
    if repeated(args.seeds):  # a seed twice would count its episodes twice (narrower intervals)
        raise UsageError(f"--seeds: each seed once, got {args.seeds}")
    curves = {}
    named = [spec.partition("=") if "=" in spec else (Path(spec).name, "", spec) for spec in args.learning_curves]
    twice = repeated(name for name, _, _ in named)
    if twice:  # the later run's curve replaced the earlier one's, silently
        raise UsageError(f"--learning-curves: {twice} named more than once; give each a name, NAME=LOG_DIR")
    for spec, (name, _, path) in zip(args.learning_curves, named):
        if not Path(path).is_dir():
            raise UsageError(f"--learning-curves {spec}: {path} is not a folder")
        try:  # read now, not after every episode has run (and once: the plot at the end draws these)
            curves[name] = read_monitor(monitor_folder(path))
        except (FileNotFoundError, ValueError) as exc:
            raise UsageError(f"--learning-curves {spec}: {exc}") from exc
    agents = []
    for spec in args.agents:
        if "=" in spec or spec.endswith(".zip"):
            path = spec.partition("=")[2] if "=" in spec else spec
            if not Path(path).is_file():
                raise UsageError(f"--agents {spec}: model file {path} does not exist")
        try:
            agents.append(make_agent(spec, stochastic=args.stochastic, no_repeat=args.no_repeat))
        except ValueError as exc:
            raise UsageError(f"--agents: {exc}") from exc
    twice = repeated_names(agents)
    if twice:  # before any episode: evaluate_agents would refuse them after the env is built
        raise UsageError(f"--agents: {twice} named more than once; give each a name, NAME=model.zip")
    for spec, agent in zip(args.agents, agents):  # an agent the env does not suit: before any episode, not at its first
        try:
            getattr(agent, "check_config", lambda _: None)(config)
        except ValueError as exc:
            raise UsageError(f"--agents {spec}: {exc}") from exc
    make_env = lambda: haptic_env.make(env_id=args.env_id, **kwargs)  # noqa: E731  (overrides the variant's fields)
    models = [(spec, a.model) for spec, a in zip(args.agents, agents) if hasattr(a, "model")]
    if models:  # a model trained on another env or other settings: said before any episode
        probe = make_env()
        shape = probe.observation_space.shape
        probe.close()
        for spec, model in models:
            if model.observation_space.shape != shape:
                raise UsageError(f"--agents {spec}: the model observes {model.observation_space.shape[0]} values, but "
                                 f"{args.env_id} with --env-kwargs {kwargs} gives {shape[0]} (trained on another env "
                                 f"or other settings?)")
    t0 = time.time()
    store = out / ".partial"
    code = code_fingerprint()
    keys = [_block_key(spec, args, kwargs, code) for spec in args.agents]
    with warnings.catch_warnings():  # an unreadable block is run again (evaluate_agents says so): not counted here
        warnings.simplefilter("ignore", RuntimeWarning)
        resumed = sum(_read_block(_block_path(store, k, s), args.episodes) is not None
                      for k in keys for s in args.seeds)
    records = evaluate_agents(agents, make_env, args.episodes, args.seeds, store=store, keys=keys,
                              agent_stream=args.agent_stream)
    note = f" (resumed: {resumed} of {len(keys) * len(args.seeds)} agent-seed blocks read from an interrupted run)" \
        if resumed else ""
    paths = write_report(records, args.out, config.max_grasps,
                         extra=f"`{_command(args, kwargs)}`\n\n"
                               f"env `{args.env_id}`, config overrides `{json.dumps(kwargs)}`; {args.episodes} "
                               f"episodes x seeds {args.seeds}; {time.time() - t0:.0f} s{note}; "
                               f"{stream_words(args.agent_stream)}.")
    shutil.rmtree(store, ignore_errors=True)
    plot = Path(args.out) / "learning_curves.png"
    if curves:
        _plot_curves(curves, plot)
    else:  # an earlier run's plot beside this run's report would read as this run's
        plot.unlink(missing_ok=True)
    print(paths["md"].read_text())
    return 0
