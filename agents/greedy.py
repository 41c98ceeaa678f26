r"""Greedy information-gain policy (one-step look-ahead on simulated grasps).

At every step the agent draws ``M`` candidate approaches uniformly from the action box and scores each by
the expected entropy of the belief after grasping with it,

.. math::  \mathbb{E}[H(b')](a) \approx \sum_k \bar b_k \, \frac1S \sum_{s=1}^S H\big(b \odot p(q_{k,s}(a) \mid \cdot)\big),

where :math:`q_{k,s}(a)` is the grasp vector obtained by *simulating* approach ``a`` on object ``k`` with the
geometric backend (``S`` samples, 1 by default since the geometric backend is deterministic without sensing
noise), :math:`\bar b` is the current belief restricted to the objects with :math:`b_k \ge` ``min_weight``
(renormalised), and the posterior is computed exactly as the env's updater would compute it. It plays the
candidate with the lowest expected entropy (the largest expected entropy reduction).

Approximations (documented, deliberate):

* every hypothesis object is simulated **at the env's current pose** (``env.unwrapped.pose``): the pose of the
  object on the table is treated as known and only its identity as unknown (privileged information a
  learned policy does not get);
* the per-episode random scale (``scale_range``) is ignored (hypotheses at scale 1);
* the simulation always uses the geometric backend, even when the env uses another backend (the mujoco
  hand's contacts differ from the simulated ones);
* simulated grasps are scored exactly as the env scores real ones (:meth:`HapticRecogEnv.grasp_rows`:
  incomplete/degenerate grasps carry no information unless the env has ``z_fingers`` models).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
from scipy.special import logsumexp


__all__ = ["GreedyInfoGainAgent", "predicted_beliefs", "predicted_beliefs_rows", "entropy_rows"]


def entropy_rows(P: np.ndarray) -> np.ndarray:
    """Shannon entropy (nats) of each row of ``P (B, K)``."""
    P = np.asarray(P, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(P > 0, P * np.log(np.where(P > 0, P, 1.0)), 0.0)
    return -t.sum(axis=-1)


def predicted_beliefs(updater, Q: np.ndarray, groups: np.ndarray | None = None) -> np.ndarray:
    """Beliefs ``(G, K)`` the updater would hold after ONE more grasp, for each of ``G`` candidate grasps.

    ``Q (R, d)`` are score rows; ``groups (R,)`` (sorted, ``0..G-1``) says which grasp each row belongs to
    (several rows per grasp for z-subset scoring; default: one row per grasp). The updater is not modified.
    Bayesian updaters (BC-NP, and BC-IP after its first grasp) are computed with ONE batched likelihood call;
    any other updater through a copy per grasp.
    """
    Q = np.asarray(Q, dtype=np.float64)
    groups = np.arange(len(Q)) if groups is None else np.asarray(groups)
    G = int(groups.max()) + 1 if len(groups) else 0
    if G == 0:
        return np.zeros((0, updater.n_classes))
    bayes = hasattr(updater, "likelihood") and hasattr(updater, "log_belief")
    if bayes and not (getattr(updater, "kind", "") == "bc-ip" and updater.n_grasps == 0):
        L = np.asarray(updater.likelihood.log_likelihood(Q), dtype=np.float64)  # (R, K)
        combine = getattr(updater, "combine", "product")
        starts = np.flatnonzero(np.r_[True, groups[1:] != groups[:-1]])
        ll = np.add.reduceat(L, starts, axis=0)  # (G, K) product of the rows' likelihoods
        if combine == "mean":
            ll = ll / np.diff(np.r_[starts, len(groups)])[:, None]
        top = ll.max(axis=1, keepdims=True)
        ok = np.isfinite(top[:, 0])
        mlr = getattr(updater, "max_log_ratio", None)
        if mlr is not None:
            ll = np.maximum(ll, top - mlr)
        step = np.where(ok[:, None], ll - np.where(ok[:, None], top, 0.0), 0.0)
        post = updater.log_belief[None, :] + step
        return np.exp(post - logsumexp(post, axis=1, keepdims=True))
    base = getattr(updater, "base", updater)
    out = np.empty((G, updater.n_classes))
    for g in range(G):
        u = copy.copy(base)  # shallow copy; copy the mutable state arrays, share the models
        for name, value in vars(u).items():
            if isinstance(value, np.ndarray):
                setattr(u, name, value.copy())
        out[g] = u.update(Q[groups == g])
    return out


def predicted_beliefs_rows(updater, rows: list[np.ndarray]) -> np.ndarray:
    """:func:`predicted_beliefs` for ``G`` grasps given as a list of score rows ``(m_g, d_g)`` (the row width
    may differ between grasps, e.g. 3- and 4-finger models): one batched call per width."""
    out = np.zeros((len(rows), updater.n_classes))
    dims = np.array([r.shape[1] for r in rows])
    for d in np.unique(dims):
        idx = np.flatnonzero(dims == d)
        Q = np.concatenate([rows[i] for i in idx])
        groups = np.repeat(np.arange(idx.size), [len(rows[i]) for i in idx])
        out[idx] = predicted_beliefs(updater, Q, groups)
    return out


class GreedyInfoGainAgent:
    """One-step greedy expected-entropy-reduction policy (see the module docstring)."""

    name = "greedy"

    def __init__(self, n_candidates: int = 16, n_samples: int = 1, min_weight: float = 1e-3,
                 seed: int | None = None, backend_kwargs: dict[str, Any] | None = None):
        if n_candidates < 1 or n_samples < 1:
            raise ValueError(f"n_candidates and n_samples must be >= 1, got {n_candidates}, {n_samples}")
        if not 0 <= min_weight < 1:
            raise ValueError(f"min_weight must be in [0, 1), got {min_weight}")
        self.n_candidates = int(n_candidates)
        self.n_samples = int(n_samples)
        self.min_weight = float(min_weight)
        self.backend_kwargs = backend_kwargs
        self._rng = np.random.default_rng(seed)
        self._backends: list[Any] | None = None
        self._env_id: int | None = None
        self.last_scores: np.ndarray | None = None  #: expected posterior entropy of each candidate, last step

    def _sim_backends(self, base) -> list[Any]:
        if self._backends is None or self._env_id != id(base):
            from haptic_env.grasping import make_backend

            cfg = base.config
            kw = self.backend_kwargs
            if kw is None:
                kw = dict(cfg.backend_kwargs) if cfg.backend == "geometric" else {}
            self._backends = [make_backend("geometric", n_fingers=cfg.n_fingers, **kw) for _ in base.objects]
            self._env_id = id(base)
        return self._backends

    def reset(self, env: Any, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        base = env.unwrapped
        pose = base.pose
        for obj, backend in zip(base.objects, self._sim_backends(base)):
            backend.set_object(obj, pose)

    def act(self, obs: np.ndarray, env: Any) -> np.ndarray:
        base = env.unwrapped
        if self._backends is None or self._env_id != id(base):
            self.reset(env)
        space = env.action_space
        M, S = self.n_candidates, self.n_samples
        cands = self._rng.uniform(space.low, space.high, size=(M,) + space.shape)
        updater = base.updater
        b = np.asarray(updater.belief, dtype=np.float64)
        H0 = float(entropy_rows(b[None])[0])
        active = np.flatnonzero(b >= self.min_weight)
        if active.size == 0:
            active = np.array([int(np.argmax(b))])
        w = b[active] / b[active].sum()
        expected = np.zeros(M)
        acts = np.repeat(cands, S, axis=0).astype(np.float64)  # (M*S, A)
        for wk, k in zip(w, active):
            res = self._sim_backends(base)[k].grasp_batch(acts, self._rng)
            contacts = np.asarray(res.contacts, dtype=np.float64)
            touched = np.asarray(res.touched, dtype=bool)
            normals = None
            if base.config.normals:
                normals = res.normals if res.normals is not None else res.gt_normals
            rows, scored = base.grasp_rows_batch(contacts, normals, touched)  # scored as the env would
            H = np.full(M * S, H0)
            if scored.size:
                H[scored] = entropy_rows(predicted_beliefs_rows(updater, rows))
            expected += wk * H.reshape(M, S).mean(axis=1)
        self.last_scores = expected
        return cands[int(np.argmin(expected))].astype(space.dtype)
