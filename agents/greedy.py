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
* a simulated grasp that is incomplete or degenerate counts as "no information" (entropy unchanged), also
  when the env has a ``z_fingers`` model.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
from scipy.special import logsumexp

from haptic_env.grasp_features import phi

__all__ = ["GreedyInfoGainAgent", "predicted_beliefs", "entropy_rows"]


def entropy_rows(P: np.ndarray) -> np.ndarray:
    """Shannon entropy (nats) of each row of ``P (B, K)``."""
    P = np.asarray(P, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(P > 0, P * np.log(np.where(P > 0, P, 1.0)), 0.0)
    return -t.sum(axis=-1)


def predicted_beliefs(updater, Q: np.ndarray) -> np.ndarray:
    """Beliefs ``(B, K)`` the updater would hold after ONE more grasp with each row of ``Q (B, d)``.

    The updater is not modified. Bayesian updaters (BC-NP, and BC-IP after its first grasp) are computed
    in one batched likelihood call; any other updater through a copy per row.
    """
    Q = np.asarray(Q, dtype=np.float64)
    if len(Q) == 0:
        return np.zeros((0, updater.n_classes))
    bayes = hasattr(updater, "likelihood") and hasattr(updater, "log_belief")
    if bayes and not (getattr(updater, "kind", "") == "bc-ip" and updater.n_grasps == 0):
        L = np.asarray(updater.likelihood.log_likelihood(Q), dtype=np.float64)  # (B, K)
        top = L.max(axis=1, keepdims=True)
        ok = np.isfinite(top[:, 0])
        mlr = getattr(updater, "max_log_ratio", None)
        if mlr is not None:
            L = np.maximum(L, top - mlr)
        post = updater.log_belief[None, :] + np.where(ok[:, None], L - np.where(ok[:, None], top, 0.0), 0.0)
        post = post - logsumexp(post, axis=1, keepdims=True)
        return np.exp(post)
    out = np.empty((len(Q), updater.n_classes))
    for i, q in enumerate(Q):
        u = copy.deepcopy(updater)
        out[i] = u.update(q)
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
        n = base.config.n_fingers
        expected = np.zeros(M)
        acts = np.repeat(cands, S, axis=0).astype(np.float64)  # (M*S, A)
        for wk, k in zip(w, active):
            res = self._sim_backends(base)[k].grasp_batch(acts, self._rng)
            contacts = np.asarray(res.contacts, dtype=np.float64)
            touched = np.asarray(res.touched, dtype=bool)
            normals = None
            if base.config.normals:
                normals = res.normals if res.normals is not None else res.gt_normals
            H = np.full(M * S, H0)
            full = touched.sum(axis=1) == n
            if full.any():
                f = phi(contacts[full], None if normals is None else np.asarray(normals)[full])
                rows = np.flatnonzero(full)[f.valid]
                if rows.size:
                    H[rows] = entropy_rows(predicted_beliefs(updater, f.q[f.valid]))
            expected += wk * H.reshape(M, S).mean(axis=1)
        self.last_scores = expected
        return cands[int(np.argmin(expected))].astype(space.dtype)
