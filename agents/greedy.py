r"""Greedy information-gain policy (one-step look-ahead on simulated grasps).

At every step the agent draws ``M`` candidate approaches uniformly from the action box and scores each by
the expected entropy of the belief after grasping with it,

.. math::  \mathbb{E}[H(b')](a) \approx \sum_k \bar b_k \, \frac1S \sum_{s=1}^S H\big(b \odot p(q_{k,s}(a) \mid \cdot)\big),

where :math:`q_{k,s}(a)` is the grasp vector obtained by *simulating* approach ``a`` on object ``k`` with the
geometric backend (``S`` samples, 1 by default since the geometric backend is deterministic without sensing
noise), :math:`\bar b` is the current belief restricted to the objects with :math:`b_k \ge` ``min_weight``
(renormalised), and the posterior is computed exactly as the env's belief would compute it
(:meth:`haptic_env.belief.Belief.predict_grasps`, batched, without changing the env's belief). It plays the
candidate with the lowest expected entropy (the largest expected entropy reduction).

Approximations (documented, deliberate):

* every hypothesis object is simulated **at the env's current pose** (``env.unwrapped.pose``): the pose of the
  object on the table is treated as known and only its identity as unknown (privileged information a
  learned policy does not get). ``pose_known=False`` marginalises the pose instead: each of the ``S`` samples
  re-places every hypothesis at a fresh pose from the env's pose distribution (``config.pose``, the agent's own
  generator), so the expected entropy averages over where the object might be turned and the look-ahead knows no
  more about the pose than a learned policy (the grasp vector is frame-invariant); this measures how much of the
  greedy gain is the privileged pose; ``infer_pose=True`` (with ``pose_known=False``) draws those poses from each
  hypothesis's posterior over the yaw instead, given the episode's grasps so far: their world-frame contacts
  scored by :func:`haptic_env.grasping.replay.yaw_log_likelihood` against the hand's recorded grasps (the replay
  pool of the env's hand, no robot data), on a grid of ``yaw_bins`` yaws. It needs the envs' upright poses
  (``pose="table-yaw"``) and a hand backend (``mujoco`` or ``replay``): what a pose-blind policy could learn to read
  from the contacts, as a reference between the blind and the privileged look-ahead;
* the per-episode random scale (``scale_range``) is ignored (hypotheses at scale 1);
* ``simulate="geometric"`` (default): the simulation uses the geometric backend, even when the env uses another
  backend (the mujoco hand's contacts differ from the simulated ones, so on a hand env the look-ahead does not know
  which approaches give the hand complete grasps; it takes that backend's ``support``, so an action is the same
  approach in both); ``simulate="env"``: every hypothesis is grasped by a backend of
  the env's own kind and settings (``config.backend``, ``config.backend_kwargs``; one per object), the hand-matched
  look-ahead. On a MuJoCo hand that costs ``M`` simulated hand grasps per hypothesis object and step (Allegro:
  about 0.5-1 s per step with 16 candidates and 10 objects), so it measures what one-step active selection can
  gain on the hand rather than being a cheap baseline;
* simulated grasps are scored exactly as the env scores real ones (:meth:`haptic_env.belief.Belief.rows_batch`:
  incomplete/degenerate grasps carry no information unless the env has ``z_fingers`` models).
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np

from haptic_env.numbers import checked_flag, finite_number, whole_at_least
from haptic_env.task import entropy

__all__ = ["GreedyInfoGainAgent"]


#: The most simulated grasps one decision may take (``n_candidates x n_samples``; the committed runs use 16 x 4).
MAX_LOOKAHEAD = 100_000


class GreedyInfoGainAgent:
    """One-step greedy expected-entropy-reduction policy (see the module docstring)."""

    name = "greedy"

    def __init__(self, n_candidates: int = 16, n_samples: int = 1, min_weight: float = 1e-3,
                 seed: int | None = None, backend_kwargs: dict[str, Any] | None = None, simulate: str = "geometric",
                 pose_known: bool = True, infer_pose: bool = False, yaw_bins: int = 72):
        for name, v in (("n_candidates", n_candidates), ("n_samples", n_samples)):
            whole_at_least(v, 1, name)  # 2.7 is not cut to 2, nor True taken as 1
        if n_candidates * n_samples > MAX_LOOKAHEAD:  # its arrays grow with the product (1e9 x 1e9: 30 GiB)
            raise ValueError(f"n_candidates x n_samples must be <= {MAX_LOOKAHEAD:,} simulated grasps per decision, "
                             f"got {n_candidates} x {n_samples}")
        if simulate not in ("geometric", "env"):
            raise ValueError(f"simulate must be 'geometric' or 'env', got {simulate!r}")
        if simulate == "env" and backend_kwargs is not None:
            raise ValueError("backend_kwargs applies to simulate='geometric' only; simulate='env' uses the env's own")
        self.simulate = simulate
        self.pose_known = checked_flag(pose_known, "pose_known", "True or False")
        self.infer_pose = checked_flag(infer_pose, "infer_pose", "True or False")
        if self.infer_pose and self.pose_known:
            raise ValueError("infer_pose=True draws the poses the look-ahead does not know: it needs pose_known=False")
        whole_at_least(yaw_bins, 4, "yaw_bins")
        self.yaw_bins = int(yaw_bins)
        w = finite_number(min_weight)
        if w is None or not 0 <= w < 1:
            raise ValueError(f"min_weight must be in [0, 1), got {min_weight!r}")
        self.n_candidates = int(n_candidates)
        self.n_samples = int(n_samples)
        self.min_weight = w
        self.backend_kwargs = backend_kwargs
        self._rng = np.random.default_rng(seed)
        self._backends: list[Any] | None = None
        self._env_ref = None  # () -> the env the backends were built for, or None once freed (not its id: reused)
        self.last_scores: np.ndarray | None = None  #: expected posterior entropy of each candidate, last step
        self.yaw_belief = None  #: infer_pose: the episode's :class:`~haptic_env.grasping.replay.YawBelief`
        self._pose: np.ndarray | None = None  # the hypotheses' pose this episode (reset)

    def _built_for(self, base) -> bool:
        """Whether the simulation backends were built for ``base`` (the same env object, still alive)."""
        return self._backends is not None and self._env_ref is not None and self._env_ref() is base

    def _sim_backends(self, base) -> list[Any]:
        if not self._built_for(base):
            from haptic_env.grasping import make_backend

            cfg = base.config
            if self.simulate == "env":
                kind, kw = cfg.backend, dict(cfg.backend_kwargs)
            else:
                kind, kw = "geometric", self.backend_kwargs
                if kw is None:  # another backend's support decodes the approach as the env's does (its elevation)
                    kw = (dict(cfg.backend_kwargs) if cfg.backend == "geometric"
                          else {k: v for k, v in dict(cfg.backend_kwargs).items() if k == "support"})
            if kind == "replay":
                # one replay backend over the env's whole set, as the env's own: an object's recorded approaches
                # depend on its index in the set it was prepared with (a backend per object would record each as
                # object 0 of a set of one); set_object then only picks its table
                shared = make_backend(kind, n_fingers=cfg.n_fingers, **kw)
                shared.prepare(base.objects)
                self._backends = [shared] * len(base.objects)
            else:
                self._backends = [make_backend(kind, n_fingers=cfg.n_fingers, **kw) for _ in base.objects]
            try:
                self._env_ref = weakref.ref(base)
            except TypeError:  # an env-like object without weak references: held
                self._env_ref = lambda env=base: env
            self.yaw_belief = None
        return self._backends

    def _yaw_belief(self, base):
        """infer_pose: the yaw belief over the recorded grasps of every object by the env's hand (the replay pool,
        cached on disk)."""
        if self.yaw_belief is None:
            self.yaw_belief = base.scene.yaw_belief(self.yaw_bins)
        return self.yaw_belief

    def check_config(self, config) -> None:
        """A ``ValueError`` if this agent cannot play an env of ``config`` (a ``HapticRecogConfig``): every look-ahead
        simulates world-frame approaches (``action_frame='world'``), and ``infer_pose`` needs what a yaw belief needs
        (:func:`haptic_env.config.check_yaw_belief`: a hand backend, ``pose='table-yaw'``). :meth:`reset` checks it;
        ``evaluate`` checks it before any episode."""
        if config.action_frame != "world":  # the look-ahead simulates its candidates as world-frame approaches
            raise ValueError("the greedy look-ahead simulates world-frame approaches; it needs action_frame='world', "
                             f"got {config.action_frame!r}")
        if self.infer_pose:
            from haptic_env.config import check_yaw_belief

            check_yaw_belief(config, "infer_pose (the greedy look-ahead's yaw posterior)")

    def reset(self, env: Any, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        base = env.unwrapped
        self.check_config(base.config)
        if self.pose_known:
            pose = base.pose
        else:
            from haptic_env.scene import random_pose

            pose = random_pose(self._rng, base.config.pose)
        for obj, backend in zip(base.objects, self._sim_backends(base)):
            backend.set_object(obj, pose)
        self._pose = pose
        if self.infer_pose:
            self._yaw_belief(base).reset()
        # each hypothesis's table height at that pose: its simulated contacts are measured from it (grasp_heights)
        self._support_z = [base.scene.support_height(k, pose) for k in range(len(base.objects))]

    def act(self, obs: np.ndarray, env: Any) -> np.ndarray:
        base = env.unwrapped
        if not self._built_for(base):
            self.reset(env)
        space = env.action_space
        M, S = self.n_candidates, self.n_samples
        if self.infer_pose:
            yb = self._yaw_belief(base)
            if base.grasp_count < yb.grasps:  # a new episode the agent was not reset for
                yb.reset()
            if base.grasp_count > yb.grasps + 1:
                raise RuntimeError(f"infer_pose scores every grasp of an episode: the env has made {base.grasp_count} "
                                   f"grasps and the agent saw {yb.grasps} (act once per step)")
            if base.grasp_count == yb.grasps + 1:  # the latest grasp
                g = base.last_grasp
                yb.add(base.last_approach, g.contacts, np.asarray(g.touched, dtype=bool))
        cands = self._rng.uniform(space.low, space.high, size=(M,) + space.shape)
        belief = base.belief_state  # the env's Belief: predictions only, its state is not changed
        b = np.asarray(belief.probs, dtype=np.float64)
        H0 = entropy(b)
        active = np.flatnonzero(b >= self.min_weight)
        if active.size == 0:
            active = np.array([int(np.argmax(b))])
        w = b[active] / b[active].sum()
        expected = np.zeros(M)
        acts = np.repeat(cands, S, axis=0).astype(np.float64)  # (M*S, A): sample s of candidate m at row m*S + s
        for wk, k in zip(w, active):
            res = self._grasp(base, k, acts)
            contacts = np.asarray(res.contacts, dtype=np.float64)
            touched = np.asarray(res.touched, dtype=bool)
            normals = None
            if base.config.normals:
                normals = res.normals if res.normals is not None else res.gt_normals
            posteriors, scored = belief.predict_grasps(contacts, normals, touched,  # scored as the env would
                                                       support_z=self._support_z[k])
            H = np.full(M * S, H0)
            if scored.size:
                H[scored] = entropy(posteriors)
            expected += wk * H.reshape(M, S).mean(axis=1)
        self.last_scores = expected
        return cands[int(np.argmin(expected))].astype(space.dtype)

    def _pose_sample(self, base, k: int) -> np.ndarray:
        """A pose of hypothesis ``k`` the look-ahead does not know: from the env's pose distribution, or
        (``infer_pose``) a yaw from its posterior given the episode's grasps (a bin, then uniform within it)."""
        from haptic_env.scene import random_pose, yaw_pose

        if not self.infer_pose:
            return random_pose(self._rng, base.config.pose)
        return yaw_pose(self.yaw_belief.sample(k, self._rng))

    def _grasp(self, base, k: int, acts: np.ndarray):
        """Simulated grasps of hypothesis ``k`` for ``acts (M*S, A)`` (each candidate repeated ``S`` times, rows kept in
        that order): at the known pose, or (``pose_known=False``) sample ``s`` of every candidate at the ``s``-th
        fresh pose."""
        backends = self._sim_backends(base)
        backend = backends[k]
        if self.pose_known:
            if len(backends) > 1 and backends[0] is backends[-1]:  # one backend for every hypothesis (replay)
                backend.set_object(base.objects[k], self._pose)
            return backend.grasp_batch(acts, self._rng)
        from haptic_env.grasping.base import GraspBatch

        S = self.n_samples
        cands = acts[::S]  # (M, A): each candidate once
        M = len(cands)
        parts = []
        for _ in range(S):
            backend.set_object(base.objects[k], self._pose_sample(base, k))
            parts.append(backend.grasp_batch(cands, self._rng))
        order = np.arange(M * S).reshape(S, M).T.ravel()  # (s, m) blocks -> row m*S + s
        fields = {}
        for name in GraspBatch.__dataclass_fields__:
            vals = [getattr(p, name) for p in parts]
            fields[name] = None if vals[0] is None else np.concatenate(vals)[order]
        return GraspBatch(**fields)
