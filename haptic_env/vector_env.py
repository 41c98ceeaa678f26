r"""``HapticRecogVectorEnv``: ``B`` episodes of :class:`~haptic_env.env.HapticRecogEnv` stepped in one batched call.

Gymnasium's vector entry point of the geometric variants (``HapticRecog-v0``, ``HapticRecogKIT-v0``)::

    envs = gym.make_vec("HapticRecog-v0", num_envs=64, vectorization_mode="vector_entry_point")
    envs = HapticRecogVectorEnv(64, HapticRecogConfig(grasp_cost=0.05))            # the same, directly

The ``B`` episodes live as arrays (object index, pose, scale, log belief, the observation's memory of the latest
grasp). One :meth:`step` is one batched backend call for all ``B`` approaches
(:meth:`~haptic_env.grasping.geometric.GeometricBackend.grasp_placed`: one Embree call per distinct object), one
compiled Phi + pooled-KDE call for the complete grasps (with ``likelihood="hgb"``: Phi compiled, then one walk of
the trees for the batch; :meth:`~haptic_env.recognizers.scorer.GraspScorer.batch`), one batched Phi call per
touched-finger count for the incomplete grasps' observed vectors, and one batched Bayes step
(:func:`~haptic_env.recognizers.updaters.bayes_steps`) for the beliefs. That fast path covers BC-NP on complete
grasps with the pooled KDE (the registered geometric variants) or gradient boosting; any other updater / z-finger
setting keeps one :class:`~haptic_env.belief.Belief` per sub-env, still with one batched backend call.

**Equivalence and seeding.** Sub-env ``i`` is a :class:`HapticRecogEnv` of the same config: ``reset(seed=s)``
seeds it as ``HapticRecogEnv.reset(seed=s + i)`` (Gymnasium's ``SyncVectorEnv`` convention; a list of ``B``
seeds seeds each directly; ``None`` draws fresh entropy for a sub-env that has no generator yet) and every
autoreset calls its ``reset()`` without a seed, continuing its own generator. So with the same actions sub-env
``i`` gives bit for bit the observations, rewards, terminations and truncations of a single env reset with
``seed + i`` and reset again after each episode end, i.e. of ``SyncVectorEnv`` of ``B`` single envs with the
same autoreset mode (``tests/test_vector_env.py``).

**Autoreset** (``metadata["autoreset_mode"]``, Gymnasium's :class:`~gymnasium.vector.AutoresetMode`):
``"next_step"`` (default, as Gymnasium's own vector envs): the step after an episode ended resets that sub-env,
ignores its action and returns its first observation with reward 0 and no termination; ``"same_step"``: the
ending step already returns the next episode's first observation, the last one in ``info["final_obs"]`` and its
vector info in ``info["final_info"]`` (SB3's convention: ``agents/native_vec.py`` adapts it); ``"disabled"``: reset
finished sub-envs yourself with ``reset(options={"reset_mask": mask})``.

``info`` holds the single env's keys as arrays over the sub-envs (``true_object``, ``true_index``,
``predicted``, ``predicted_index``, ``correct``, ``certainty``, ``decided``, ``grasps``, ``usable``,
``belief (B, K)``, ``touched (B, n)``, and on steps ``reward_terms`` ``{"gain", "grasp_cost"}``), each with
Gymnasium's ``_<key>`` mask of the sub-envs that set it. ``reset(options=...)`` takes ``"object"`` (a name or
index for every sub-env, or a sequence of ``B`` of them, None = drawn) and ``"reset_mask"``.
No rendering (``render_mode=None``); the geometric backend only (MuJoCo: use ``SyncVectorEnv``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import utils
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from haptic_env import NATIVE_BACKENDS
from haptic_env.belief import Belief, check_grasp_vectors, get_recognizer
from haptic_env.config import HapticRecogConfig, resolve_env_config
from haptic_env.grasp_features import feature_dim
from haptic_env.scene import Scene, reset_options
from haptic_env.task import Task, entropy, touched_rows
from haptic_env.numbers import whole_at_least

__all__ = ["HapticRecogVectorEnv", "make_vector_env", "NATIVE_BACKENDS"]

#: snake-case names of Gymnasium's autoreset modes (their values, "NextStep" etc., are accepted too)
_MODE_ALIASES = {"next_step": AutoresetMode.NEXT_STEP, "same_step": AutoresetMode.SAME_STEP,
                 "disabled": AutoresetMode.DISABLED}


class HapticRecogVectorEnv(VectorEnv, utils.EzPickle):
    """``num_envs`` episodes of ``HapticRecogEnv(config)`` as one :class:`gymnasium.vector.VectorEnv` (module
    docstring). ``config`` and single-field ``overrides`` as in :class:`~haptic_env.env.HapticRecogEnv`;
    ``autoreset_mode``: ``"next_step"`` (default) | ``"same_step"`` | ``"disabled"``."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, config: HapticRecogConfig | None = None, *,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP, render_mode: str | None = None,
                 max_episode_steps: int | None = None, variant: str | None = None, **overrides: Any):
        utils.EzPickle.__init__(self, num_envs, config, autoreset_mode=autoreset_mode, render_mode=render_mode,
                                max_episode_steps=max_episode_steps, variant=variant, **overrides)
        whole_at_least(num_envs, 1, "num_envs")
        config = resolve_env_config(config, variant, overrides)  # as the single env's (HapticRecogEnv)
        if render_mode is not None:
            raise ValueError("HapticRecogVectorEnv does not render (render_mode=None); render a single HapticRecogEnv")
        if max_episode_steps is not None:
            raise ValueError("the env truncates itself after config.max_grasps grasps: pass max_grasps, not "
                             "max_episode_steps")
        try:
            mode = AutoresetMode(_MODE_ALIASES.get(autoreset_mode, autoreset_mode))
        except ValueError:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in AutoresetMode]}, "
                             f"got {autoreset_mode!r}") from None
        if config.backend not in NATIVE_BACKENDS:  # before the scene: a hand backend would load its hand first
            raise NotImplementedError(f"HapticRecogVectorEnv needs a backend with grasp_placed {NATIVE_BACKENDS}, "
                                      f"got {config.backend!r}; use gymnasium.vector.SyncVectorEnv of HapticRecogEnv")
        self.config = config
        self.num_envs = B = int(num_envs)
        self.autoreset_mode = mode
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.render_mode = None

        self.scene = Scene(config)  # objects + backend; its per-episode state is each sub-env's reset scratch
        self.objects, self.object_names, self.backend = self.scene.objects, self.scene.names, self.scene.backend
        self.n_classes, self.action_dim = self.scene.n_classes, self.scene.action_dim
        self.feature_dim = feature_dim(config.n_fingers, config.normals, heights=config.grasp_heights,
                                       normal_axis=config.normal_axis)
        self.task = Task(config, self.n_classes, self.feature_dim, self.action_dim,
                         q_bound=max(np.pi, self.scene.diameter * 1.01))
        self.observation_structure, self.obs_slices = self.task.observation_structure, self.task.obs_slices
        self.single_observation_space = self.task.observation_space
        self.single_action_space = self.task.action_space
        self.observation_space = batch_space(self.single_observation_space, B)
        self.action_space = batch_space(self.single_action_space, B)
        self._names = np.array(self.object_names, dtype=object)

        n, K, d, A = config.n_fingers, self.n_classes, self.feature_dim, self.action_dim
        self._rngs: list[np.random.Generator | None] = [None] * B  # each sub-env's np_random
        self._seeds: list[int | None] = [None] * B
        self._backend_rngs: list[np.random.Generator | None] = [None] * B
        self._placed = self.backend.placed_objects(list(self.objects), B)  # the B episodes' objects, as arrays
        self.targets = np.zeros(B, dtype=np.int64)
        self.poses = np.tile(np.eye(4), (B, 1, 1))
        self.scales = np.ones(B)
        #: each sub-env's table height under its object (world z; read with ``grasp_heights``)
        self.support_z = np.zeros(B)
        self.grasps = np.zeros(B, dtype=np.int64)
        self.probs = np.full((B, K), 1.0 / K)
        self._log_belief = np.log(self.probs)
        self._n_updates = np.zeros(B, dtype=np.int64)  # grasps that updated each belief (the updater's n_grasps)
        self._last_q = np.zeros((B, d))
        self._last_mask = np.zeros((B, n))
        self._last_usable = np.zeros(B)
        self._last_action = np.zeros((B, A))
        self._last_contacts = np.zeros((B, self.observation_structure.get("contacts", 0)))
        self._last_normals = np.zeros((B, self.observation_structure.get("contact_normals", 0)))
        self._over = np.zeros(B, dtype=bool)  # episode ended at the last step (next_step: reset at this one)
        self._started = np.zeros(B, dtype=bool)
        self._recognizer = None
        self._scorer = None
        self._beliefs: list[Belief] | None = None  # the general path: one Belief per sub-env
        self._prior_log: np.ndarray | None = None
        self._prior_probs: np.ndarray | None = None

    # --------------------------------------------------------------------------------- state
    @property
    def recognizer(self):
        """The shared recogniser (built or loaded from the cache on first access)."""
        if self._recognizer is None:
            self._recognizer = get_recognizer(self.objects, self.config)
        return self._recognizer

    @property
    def fast_path(self) -> bool:
        """Whether beliefs are updated as arrays (BC-NP, complete grasps, pooled KDE or gradient boosting) rather
        than one :class:`Belief` per sub-env (None before the first reset)."""
        return self._scorer is not None

    def _build_beliefs(self) -> None:
        c = self.config
        rec = self.recognizer
        check_grasp_vectors(rec, c)
        # None for a KDE not evaluated "pooled" or scale-normalised grasps: then the general path (gradient boosting
        # has a scorer too)
        scorer = rec.grasp_scorer(c.calibrated) if (c.updater == "bc-np" and c.z_fingers is None
                                                     and not c.score_subsets) else None
        self._scorer = scorer
        if scorer is None:
            self._beliefs = [Belief.from_config(self.objects, c, rec) for _ in range(self.num_envs)]
        else:
            b = Belief(rec, c.updater, c.threshold, calibrated=c.calibrated)  # the prior as the single env has it
            self._prior_log = np.asarray(b.updater.log_belief, dtype=np.float64).copy()
            self._prior_probs = np.asarray(b.probs, dtype=np.float64).copy()
            self._combine = b.updater.combine
            self._max_log_ratio = b.updater.max_log_ratio
            self._threshold = float(b.updater.threshold)

    # ------------------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        """Reset the sub-envs (all, or ``options["reset_mask"]``); seeding scheme in the module docstring."""
        B = self.num_envs
        options = reset_options(options, ("object", "reset_mask"))
        mask = options.get("reset_mask")
        if mask is None:
            mask = np.ones(B, dtype=bool)
        else:
            mask = np.asarray(mask)
            if mask.dtype != np.bool_ or mask.shape != (B,):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({B},), got {mask!r}")
            if not mask.any():
                raise ValueError("options['reset_mask'] resets no sub-env")
        if seed is None:
            seeds = [None] * B
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(B)]
        else:  # a sequence of seeds; anything else (a bool, a float, a string) fails the check as one bad seed
            seeds = list(seed) if hasattr(seed, "__len__") and not isinstance(seed, (str, bytes)) else [seed]
            if not all(x is None or isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))
                       for x in seeds):
                raise ValueError(f"reset: seed must be None, an int or a sequence of {B} ints or None, got {seed!r}")
            seeds = [None if x is None else int(x) for x in seeds]
            if len(seeds) != B:
                raise ValueError(f"reset: {len(seeds)} seeds for {B} sub-envs")
        which = options.get("object")
        if which is None or isinstance(which, (str, int, np.integer, bool, np.bool_)):
            which = [which] * B  # a bool is refused by the scene's check, naming it
        elif not isinstance(which, (list, tuple, np.ndarray)) or len(which) != B:
            raise ValueError(f"options['object'] must be a name, an index or a sequence of {B} of them, got {which!r}")
        if self._scorer is None and self._beliefs is None:
            self._build_beliefs()
        idx = np.flatnonzero(mask)
        self._reset_rows(idx, [seeds[i] for i in idx], [which[i] for i in idx])
        obs = self._observations()
        info = self._info(idx, usable=np.zeros(B, dtype=bool), decided=np.zeros(B, dtype=bool))
        return obs, info

    def _reset_rows(self, idx: np.ndarray, seeds=None, which=None) -> None:
        """Sub-env ``i``'s ``HapticRecogEnv.reset(seed=seeds[j], options={"object": which[j]})`` for each
        ``i = idx[j]`` (no seed: its generator continues; no object: drawn)."""
        noisy = self.backend.config.contact_noise > 0 or self.backend.config.normal_noise_deg > 0
        rows = idx.tolist()
        rngs = self._rngs
        for j, i in enumerate(rows):
            if (seeds is not None and seeds[j] is not None) or rngs[i] is None:  # gym.Env.reset's seeding
                rngs[i], self._seeds[i] = seeding.np_random(None if seeds is None else seeds[j])
        # = each sub-env's Scene.draw(np_random, which)
        k, poses, scales, backend_seeds = self.scene.draw_many([rngs[i] for i in rows], which)
        self.targets[idx], self.poses[idx], self.scales[idx] = k, poses, scales
        for j, i in enumerate(rows):  # the backend's generator draws only noise: built when there is noise
            self._backend_rngs[i] = np.random.Generator(np.random.PCG64(backend_seeds[j])) if noisy else None
        self._placed.place_many(idx, k, poses, scales)  # = the single env's backend.set_object(objects[k], pose, scale)
        if self.config.grasp_heights:  # the table height under each placed object (= Scene.support_height)
            self.support_z[idx] = self._placed.table_z[idx]
        if self._beliefs is not None:
            for i in rows:
                self.probs[i] = self._beliefs[i].reset(support_z=self.support_z[i])
        if self._beliefs is None:
            self._log_belief[idx] = self._prior_log
            self.probs[idx] = self._prior_probs
        self.grasps[idx] = 0
        self._n_updates[idx] = 0
        self._last_q[idx] = 0.0
        self._last_mask[idx] = 0.0
        self._last_usable[idx] = 0.0
        self._last_action[idx] = 0.0
        self._last_contacts[idx] = 0.0
        self._last_normals[idx] = 0.0
        self._started[idx] = True
        self._over[idx] = False

    def step(self, actions):
        if not self._started.all():
            raise RuntimeError("call reset() before step()")
        B = self.num_envs
        a = self._check_actions(actions)
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._over.any():
            i = int(np.flatnonzero(self._over)[0])
            raise RuntimeError(f"sub-env {i}'s episode is over (autoreset_mode='disabled'); reset it with "
                               "reset(options={'reset_mask': mask}) before step()")
        if mode == AutoresetMode.NEXT_STEP and self._over.any():
            resets = np.flatnonzero(self._over)
            live = np.flatnonzero(~self._over)
            self._reset_rows(resets)
        else:
            resets = np.zeros(0, dtype=np.int64)
            live = np.arange(B)

        old = self.probs.copy()
        usable = np.zeros(B, dtype=bool)
        decided = np.zeros(B, dtype=bool)
        if len(live):
            self._step_live(live, a[live], usable, decided)
        rewards = np.zeros(B)
        gain = np.zeros(B)
        if len(live):
            gain[live] = self._gain(old[live], self.probs[live], self.targets[live])
            rewards[live] = gain[live] + (-float(self.config.grasp_cost))
        terminated = decided.copy()
        truncated = np.zeros(B, dtype=bool)
        truncated[live] = ~terminated[live] & (self.grasps[live] >= self.config.max_grasps)
        ended = terminated | truncated
        obs = self._observations()
        stepped = np.zeros(B, dtype=bool)
        stepped[live] = True
        info = self._info(np.arange(B), usable=usable, decided=decided)
        terms = {"gain": gain, "grasp_cost": np.where(stepped, -float(self.config.grasp_cost), 0.0)}
        _set_reward_terms(info, terms, stepped)
        if mode == AutoresetMode.NEXT_STEP:
            if len(resets):  # these sub-envs were reset at this step: their info is the reset's (no reward_terms)
                info["usable"][resets] = False
                info["decided"][resets] = False
            self._over = ended
        elif mode == AutoresetMode.SAME_STEP:
            if ended.any():  # as SyncVectorEnv: final_obs (object array) and final_info (the step's vector info)
                done = np.flatnonzero(ended)
                final_obs = np.full(B, None, dtype=object)
                for i in done:
                    final_obs[i] = obs[i].copy()
                final_info = _masked(info, ended)
                self._reset_rows(done)
                obs[done] = self._observations()[done]
                reset_info = self._info(done, usable=np.zeros(B, dtype=bool), decided=np.zeros(B, dtype=bool))
                for key, value in reset_info.items():
                    if not key.startswith("_"):
                        info[key][done] = value[done]
                _set_reward_terms(info, terms, stepped & ~ended)  # a reset row's info is the reset's
                info["final_obs"], info["_final_obs"] = final_obs, ended.copy()
                info["final_info"], info["_final_info"] = final_info, ended.copy()
        else:
            self._over = ended
        return obs, rewards, terminated, truncated, info

    def _step_live(self, live: np.ndarray, a: np.ndarray, usable: np.ndarray, decided: np.ndarray) -> None:
        """Grasp, score and update the sub-envs ``live`` with actions ``a``."""
        c = self.config
        noisy = self.backend.config.contact_noise > 0 or self.backend.config.normal_noise_deg > 0
        batch = self.backend.grasp_placed(a, self._placed, rows=live,
                                          rngs=[self._backend_rngs[i] for i in live] if noisy else None)
        contacts, touched = batch.contacts, np.asarray(batch.touched, dtype=bool)
        normals = None
        if c.normals:
            normals = batch.normals if batch.normals is not None else batch.gt_normals
            if normals is None:
                raise ValueError(f"config.normals=True but backend {c.backend!r} senses no contact normals")
        self.grasps[live] += 1
        q = np.zeros((len(live), self.feature_dim))
        if self._scorer is None:  # the general path: each sub-env's Belief, exactly as the single env
            for j, i in enumerate(live):
                bel = self._beliefs[i]
                q[j], usable[i] = bel.update(contacts[j], None if normals is None else normals[j], touched[j])
                self.probs[i] = bel.probs
                decided[i] = bel.decided
        else:
            heights = c.grasp_heights
            # the contacts in each sub-env's support frame (on the general path each Belief moves them itself)
            scored_contacts = contacts - np.outer(self.support_z[live], [0.0, 0.0, 1.0])[:, None, :] if heights else contacts
            t = touched.sum(axis=1)
            n = c.n_fingers
            full = np.flatnonzero(t == n)
            if len(full):
                qf, ll, scored = self._scorer.batch(scored_contacts[full], None if normals is None else normals[full])
                q[full] = qf
                rows = full[scored]
                env_rows = live[rows]
                if len(rows):
                    starts = np.arange(len(rows) + 1)
                    post, moved = _bayes(self._log_belief[env_rows], ll[scored], starts, self._combine,
                                         self._max_log_ratio)
                    upd = env_rows[moved]
                    self._log_belief[upd] = post[moved]
                    self.probs[upd] = np.exp(post[moved])
                    self._n_updates[env_rows] += 1
                    usable[env_rows] = True
            for tt in range(2, n):  # incomplete grasps: their touching contacts' vector is observed, not scored
                part = np.flatnonzero(t == tt)
                if len(part):
                    from haptic_env.recognizers.zfinger import grasp_vectors_for

                    m = touched[part]
                    P = scored_contacts[part][m].reshape(len(part), tt, 3)
                    N = None if not self.recognizer.normals else normals[part][m].reshape(len(part), tt, 3)
                    qp, valid = grasp_vectors_for(P, N, heights=heights, normal_axis=self.recognizer.normal_axis)
                    q[part[valid], : qp.shape[1]] = qp[valid]
            maxlog = np.maximum.reduce(self._log_belief[live], axis=1).tolist()
            thr = self._threshold
            nu = self._n_updates[live]
            for j, i in enumerate(live):  # updater.decided: math.exp as BayesianUpdater.certainty
                decided[i] = nu[j] > 0 and math.exp(maxlog[j]) >= thr
        np.minimum(np.maximum(q, -self.task.q_bound, out=q), self.task.q_bound, out=q)
        self._last_q[live] = q
        self._last_mask[live] = touched
        self._last_usable[live] = usable[live]
        self._last_action[live] = a
        if self._last_contacts.shape[1]:
            self._last_contacts[live] = touched_rows(contacts, touched, self.task.q_bound)
            if self._last_normals.shape[1]:
                self._last_normals[live] = touched_rows(normals, touched, 1.0)

    def _gain(self, old: np.ndarray, new: np.ndarray, targets: np.ndarray) -> np.ndarray:
        kind = self.config.reward
        if kind == "true-posterior-gain":
            ar = np.arange(len(targets))
            return new[ar, targets] - old[ar, targets]
        if kind == "max-posterior-gain":
            return new.max(axis=1) - old.max(axis=1)
        return entropy(old) - entropy(new)

    def _observations(self) -> np.ndarray:
        obs = np.empty((self.num_envs,) + self.single_observation_space.shape, dtype=np.float32)
        return self.task.fill(obs, {
            "grasp": self._last_q, "contact_mask": self._last_mask, "usable": self._last_usable[:, None],
            "belief": self.probs, "prev_action": self._last_action,
            "grasp_count": (self.grasps / self.config.max_grasps)[:, None],
            "contacts": self._last_contacts, "contact_normals": self._last_normals,
        })

    def _certainty(self) -> np.ndarray:
        if self._beliefs is not None:
            return np.array([b.certainty for b in self._beliefs])
        return self.probs[np.arange(self.num_envs), self.probs.argmax(axis=1)]

    def _info(self, idx: np.ndarray, *, usable: np.ndarray, decided: np.ndarray) -> dict[str, Any]:
        """The single env's info keys as arrays, set (masked) for the sub-envs ``idx``."""
        B = self.num_envs
        present = np.zeros(B, dtype=bool)
        present[idx] = True
        pred = self.probs.argmax(axis=1)
        values = {
            "true_object": self._names[self.targets],
            "true_index": self.targets.copy(),
            "predicted": self._names[pred],
            "predicted_index": pred,
            "correct": pred == self.targets,
            "certainty": self._certainty(),
            "decided": decided.copy(),
            "grasps": self.grasps.copy(),
            "usable": usable.copy(),
            "belief": self.probs.copy(),
            "touched": self._last_mask.astype(bool),
        }
        info: dict[str, Any] = {}
        for key, value in values.items():
            info[key] = value
            info["_" + key] = present.copy()
        return info

    def _check_actions(self, actions) -> np.ndarray:
        B, A = self.num_envs, self.action_dim
        try:
            a = np.asarray(actions)
        except ValueError as exc:  # a ragged sequence
            raise ValueError(f"actions must be a numeric array of shape ({B}, {A}), got {actions!r}") from exc
        if a.dtype.kind == "c":
            raise ValueError(f"actions must be real numbers, got complex values {actions!r}")
        try:
            if a.dtype.kind not in "fiu":  # strings, bools, objects: numpy would cast them to numbers silently
                raise TypeError(f"non-numeric dtype {a.dtype}")
            a = a.astype(np.float64)
        except (TypeError, OverflowError) as exc:
            raise ValueError(f"actions must be a numeric array of shape ({B}, {A}), got {actions!r}") from exc
        if a.shape != (B, A):
            raise ValueError(f"actions must have shape ({B}, {A}), got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"actions must be finite, got {a.tolist()}")
        if (a < -1.0 - 1e-6).any() or (a > 1.0 + 1e-6).any():
            raise ValueError(f"actions must lie in [-1, 1], got {a.tolist()}")
        return np.clip(a, -1.0, 1.0)

    def close_extras(self, **kwargs: Any) -> None:
        self.scene.close()

    def __repr__(self) -> str:
        return f"HapticRecogVectorEnv(num_envs={self.num_envs}, objects={self.config.objects!r}, " \
               f"autoreset_mode={self.autoreset_mode.value!r})"


def _set_reward_terms(info: dict[str, Any], terms: dict[str, np.ndarray], mask: np.ndarray) -> None:
    """``info["reward_terms"]`` of the sub-envs ``mask`` whose info is a step's, each term with its ``_<term>`` mask
    as ``SyncVectorEnv`` nests them; no key where no sub-env's is (every one was reset at this step)."""
    if mask.any():
        nested: dict[str, np.ndarray] = {}
        for name, value in terms.items():
            nested[name], nested["_" + name] = value, mask.copy()
        info["reward_terms"], info["_reward_terms"] = nested, mask.copy()
    else:
        info.pop("reward_terms", None)
        info.pop("_reward_terms", None)


def _masked(info: dict[str, Any], mask: np.ndarray) -> dict[str, Any]:
    """A copy of a vector info whose every ``_<key>`` mask is ``mask`` (nested dicts too)."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        if key.startswith("_"):
            continue
        out[key] = _masked(value, mask) if isinstance(value, dict) else value.copy()
        out["_" + key] = mask.copy()
    return out


def _bayes(log_beliefs, log_lik, starts, combine, max_log_ratio):
    from haptic_env.recognizers.updaters import bayes_steps

    return bayes_steps(log_beliefs, log_lik, starts, combine=combine, max_log_ratio=max_log_ratio)


def make_vector_env(num_envs: int = 1, config: HapticRecogConfig | None = None, env_id: str = "HapticRecog-v0",
                    **kwargs: Any) -> HapticRecogVectorEnv:
    """``gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", config=config, **kwargs)``; as
    :func:`haptic_env.make`, a ``config`` is the whole setting (the fields its variant sets are taken from it)."""
    import haptic_env

    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", config=config,
                        **haptic_env.config_kwargs(config, env_id, kwargs))


