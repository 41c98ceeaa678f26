"""The one trial runner of the experiments: replay precomputed grasp scores through a real belief updater.

A trial resets an updater and feeds it the scores of one grasp at a time (``update_scores``) until it
decides or the grasps run out; the prediction at the stop is the trial's answer. The experiments differ only
in where each trial's grasps come from, so each has a small generator of score rows around
:func:`run_trial`:

* :func:`simulate_trials`: a uniformly drawn object, its test grasps without replacement (experiments 2-7);
* :func:`incomplete_trials`: per grasp a finger count z ~ p_n(z), scored by the z-finger model (experiment 3);
* :func:`family_trials`: repeated trials on ONE object's grasps, votes per class (experiment 5).

Scores are computed once per test pool, in batch; the updaters are the env's own classes
(:meth:`~haptic_env.recognizers.updaters.BeliefUpdater.update_scores`).
"""

from __future__ import annotations

from typing import Iterable

import numpy as np

from haptic_env.numbers import whole_at_least
from haptic_env.recognizers.updaters import DEFAULT_IC_CERTAINTY, BeliefUpdater, make_updater

__all__ = ["scores_updater", "run_trial", "simulate_trials", "incomplete_trials", "family_trials", "summarize",
           "confusion"]


class _Classes:
    """Stands in for the models of an updater that is only fed precomputed scores."""

    def __init__(self, k: int):
        self.n_classes = k


def scores_updater(kind: str, n_classes: int, threshold: float,
                   ic_certainty: str = DEFAULT_IC_CERTAINTY) -> BeliefUpdater:
    """An updater of ``kind`` over ``n_classes`` classes, fed through ``update_scores`` only; ``ic_certainty``: IC's
    certainty rule (:data:`~haptic_env.recognizers.updaters.IC_CERTAINTIES`; other kinds ignore it)."""
    return make_updater(kind, classifier=_Classes(n_classes), likelihood=_Classes(n_classes), threshold=threshold,
                        ic_certainty=ic_certainty)


def run_trial(u: BeliefUpdater, draws: Iterable[tuple[np.ndarray, np.ndarray]], truth: int | None = None,
              fixed_steps: bool = False) -> list[bool] | None:
    """One trial: ``u`` is reset and fed the ``(log_lik (1, K), proba (1, K))`` rows of ``draws`` until it
    decides (``fixed_steps``: all of them, threshold disregarded). ``draws`` is consumed lazily, so a
    generator drawing from an rng draws only the grasps used.

    Returns, with ``fixed_steps``, whether the prediction was ``truth`` after each grasp, else None; the
    outcome is ``u.prediction``, ``u.n_grasps``, ``u.decided``.
    """
    u.reset()
    hits = [] if fixed_steps else None
    for ll, pr in draws:
        u.update_scores(log_lik=ll, proba=pr)
        if fixed_steps:
            hits.append(u.prediction == truth)
        elif u.decided:
            break
    return hits


def _rows(LL: np.ndarray, PR: np.ndarray, order) -> Iterable[tuple[np.ndarray, np.ndarray]]:
    for i in order:
        yield LL[i : i + 1], PR[i : i + 1]


def simulate_trials(log_lik: list[np.ndarray], proba: list[np.ndarray], kind: str, *, trials: int, max_grasps: int,
                    threshold: float, rng: np.random.Generator, fixed_steps: bool = False,
                    ic_certainty: str = DEFAULT_IC_CERTAINTY) -> dict:
    """Trials on uniformly drawn objects, each drawing test grasps without replacement from its object's pool
    (with replacement when the pool holds fewer than ``max_grasps``).

    Args:
        log_lik, proba: per object ``o``, ``(G_o, K)`` scores of its test grasps (rows combined per grasp).
        fixed_steps: disregard the threshold and run ``max_grasps`` grasps (experiment 6).
        ic_certainty: IC's certainty rule (:func:`scores_updater`).

    Returns:
        dict with ``success (T,) bool`` (prediction right at the stop), ``decided (T,) bool`` (certainty
        reached the threshold), ``grasps (T,) int``, ``truth``, ``pred`` and, when ``fixed_steps``,
        ``correct_at (T, max_grasps) bool`` (prediction right after m grasps).
    """
    whole_at_least(trials, 1, "trials")  # 0 gave nan summaries (and a stop scale of 1 without a word)
    whole_at_least(max_grasps, 1, "max_grasps")
    n_obj = len(log_lik)
    K = (log_lik[0] if log_lik[0] is not None and len(log_lik[0]) else proba[0]).shape[1]  # classes
    u = scores_updater(kind, K, threshold, ic_certainty)
    truth = rng.integers(0, n_obj, size=trials)  # object index (= class unless classes are families)
    pred = np.zeros(trials, dtype=np.int64)
    used = np.zeros(trials, dtype=np.int64)
    decided = np.zeros(trials, dtype=bool)
    correct_at = np.zeros((trials, max_grasps), dtype=bool) if fixed_steps else None
    for t, o in enumerate(truth):
        G = len(log_lik[o])
        order = rng.permutation(G)[:max_grasps] if G >= max_grasps else rng.integers(0, G, size=max_grasps)
        hits = run_trial(u, _rows(log_lik[o], proba[o], order), truth=o, fixed_steps=fixed_steps)
        if fixed_steps:
            correct_at[t] = hits
        pred[t] = u.prediction
        used[t] = u.n_grasps
        decided[t] = u.decided
    out = {"success": pred == truth, "decided": decided, "grasps": used, "truth": truth, "pred": pred}
    if fixed_steps:
        out["correct_at"] = correct_at
    return out


def incomplete_trials(pools: dict[int, tuple[list[np.ndarray], list[np.ndarray]]], p: np.ndarray, kind: str, *,
                      trials: int, max_grasps: int, threshold: float, rng: np.random.Generator,
                      ic_certainty: str = DEFAULT_IC_CERTAINTY) -> dict:
    """Trials of incomplete grasps: per trial a uniformly drawn object; per grasp a finger count ``z`` drawn
    with probabilities ``p`` over ``sorted(pools)`` and one of the object's ``z``-finger test grasps (with
    replacement). ``pools[z] = (log_lik, proba)`` per object, as for :func:`simulate_trials`.

    Returns ``success (T,) bool`` and ``grasps (T,) int``.
    """
    zlist = sorted(pools)
    K = len(pools[zlist[0]][0])
    u = scores_updater(kind, K, threshold, ic_certainty)

    def draws(o):
        for _ in range(max_grasps):
            LL, PR = pools[zlist[rng.choice(len(zlist), p=p)]]
            i = int(rng.integers(len(LL[o])))
            yield LL[o][i : i + 1], PR[o][i : i + 1]

    succ, used = [], []
    for _ in range(trials):
        o = int(rng.integers(K))
        run_trial(u, draws(o))
        succ.append(u.prediction == o)
        used.append(u.n_grasps)
    return {"success": np.array(succ, dtype=bool), "grasps": np.array(used, dtype=np.int64)}


def family_trials(LL: np.ndarray, PR: np.ndarray, kind: str, *, trials: int, max_grasps: int, threshold: float,
                  rng: np.random.Generator,
                  ic_certainty: str = DEFAULT_IC_CERTAINTY) -> tuple[np.ndarray, int, np.ndarray]:
    """``trials`` runs of ``kind`` on ONE object's test pool (``LL``/``PR``: ``(G, C)``, at most ``max_grasps``
    of its grasps without replacement per trial): the class votes ``(C,)`` (prediction at the stop), how many
    decided, and the grasps used ``(trials,)``."""
    whole_at_least(trials, 1, "trials")
    whole_at_least(max_grasps, 1, "max_grasps")
    u = scores_updater(kind, LL.shape[1], threshold, ic_certainty)
    votes, decided, used = np.zeros(LL.shape[1], dtype=np.int64), 0, []
    for _ in range(trials):
        run_trial(u, _rows(LL, PR, rng.permutation(len(LL))[:max_grasps]))
        votes[u.prediction] += 1
        decided += bool(u.decided)
        used.append(u.n_grasps)
    return votes, decided, np.array(used)


def summarize(res: dict) -> tuple[float, float, float, float]:
    """``(success %, its binomial std %, mean grasps, std of grasps)`` of trial results; success is the prediction
    right at the stop, the decision or the last grasp (an undecided trial counts when right; experiments 2-4's
    measure, not the decided-and-correct share of the hand table and experiment 7's d&c)."""
    s = res["success"]
    T = len(s)
    p = float(s.mean())
    return 100 * p, 100 * np.sqrt(p * (1 - p) / max(T, 1)), float(res["grasps"].mean()), float(res["grasps"].std())


def confusion(truth: np.ndarray, pred: np.ndarray, K: int) -> np.ndarray:
    """Row-normalised ``(K, K)`` confusion matrix (rows: true class)."""
    C = np.zeros((K, K))
    np.add.at(C, (truth, pred), 1)
    return C / np.maximum(C.sum(1, keepdims=True), 1)
