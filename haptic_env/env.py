r"""``HapticRecog``: active kinesthetic haptic object recognition as a Gymnasium environment.

The env only composes four parts, each the one owner of its concept (dm_control's split):

- :mod:`haptic_env.config`: every setting (:class:`HapticRecogConfig`) and its validation;
- :mod:`haptic_env.scene`: the objects, the grasp backend, and the episode's object, pose and scale;
- :mod:`haptic_env.belief`: grasp -> :math:`\Phi_n` -> likelihood -> posterior (:class:`~haptic_env.belief.Belief`);
- :mod:`haptic_env.task`: observation layout, reward kinds, termination and truncation, ``info``.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import utils

from haptic_env.belief import Belief, get_recognizer
from haptic_env.config import HapticRecogConfig, resolve_env_config
from haptic_env.grasp_features import feature_dim
from haptic_env.recognizers.updaters import UPDATERS
from haptic_env.scene import POSE_MODES, Scene, random_pose, reset_options
from haptic_env.task import REWARD_KINDS, Task

__all__ = [
    "HapticRecogConfig",
    "HapticRecogEnv",
    "REWARD_KINDS",
    "UPDATERS",
    "POSE_MODES",
    "get_recognizer",
    "random_pose",
]

_NON_INTERACTIVE = ("agg", "pdf", "ps", "svg", "cairo", "template", "pgf")


class HapticRecogEnv(gym.Env, utils.EzPickle):
    r"""
    ## Description
    Active kinesthetic haptic object recognition (Sintov & Ben-David, "Simple Kinesthetic Haptics for
    Object Recognition"). An unknown object from a known set of ``K`` objects lies in front of a robot hand
    in a random pose. Each step the agent chooses how to approach it; the hand closes its ``n`` fingers
    and the only sensing is *where* the fingertips stopped (kinesthetic haptics: contact points from
    joint angles, optionally contact normals). The contacts are mapped to the pose-invariant grasp vector
    :math:`q = \Phi_n(\text{contacts})` and a Bayesian belief over the ``K`` objects is updated with a
    learned likelihood (BC-NP by default; the models are trained from the object meshes alone, by default on
    grasps of the backend's own hand model, the geometric or the MuJoCo hand's, ``recognizer_source``). The task
    is to become certain of the object's identity in as few grasps as possible. The agent does not see the object
    or its pose.

    ## Action Space
    ``Box(-1, 1, (A,), float32)`` where ``A = backend.action_dim``: the approach parameters of one grasp,
    defined by the backend; every backend takes ``A = 4``: approach azimuth, elevation (upper hemisphere with
    ``support="table"``), roll of the hand about the approach axis, finger spread (see
    :mod:`haptic_env.grasping.base`). Actions outside ``[-1, 1]``, of the wrong shape or non-finite raise
    ``ValueError``. With ``action_frame="estimated"`` (hand envs) the azimuth is read in the most probable object's
    estimated frame: turned by that object's most probable yaw given the episode's grasps (:attr:`last_approach`
    is the approach as executed). ``action_frame="oracle"`` reads it in the true object's frame from the second
    grasp on (training only: it reads the hidden pose).

    ## Observation Space
    ``Box(float32)`` of length ``d + n + 1 + K + A + 1`` (``env.observation_structure`` gives each part's
    size and ``env.obs_slices`` its slice), in order:

    | Slice        | Size | Content                                                                     | Range       |
    | ------------ | ---- | --------------------------------------------------------------------------- | ----------- |
    | grasp        | d    | :math:`\Phi` of the latest grasp's touching contacts (lengths in m, angles  | +-max(pi,   |
    |              |      | in rad), zero-padded to ``d = feature_dim(n, normals)``; all 0 if < 2 touched | diameter)   |
    | contact_mask | n    | 1 for each finger of the latest grasp that touched the object               | {0, 1}      |
    | usable       | 1    | 1 if the latest grasp updated the belief                                    | {0, 1}      |
    | belief       | K    | current posterior over the objects (sums to 1)                              | [0, 1]      |
    | prev_action  | A    | the latest action (0 before the first grasp)                                | [-1, 1]     |
    | grasp_count  | 1    | grasps so far / ``max_grasps``                                              | [0, 1]      |

    With ``grasp_heights=True`` the grasp part also holds the touching contacts' heights above the table (after
    :math:`\Phi`, in its chain order): ``d = feature_dim(n, normals, heights=True)``.

    With ``observe_contacts=True`` two parts follow (the length grows by ``3n``, or ``6n`` with normals):

    | Slice           | Size | Content                                                                  | Range       |
    | --------------- | ---- | ------------------------------------------------------------------------ | ----------- |
    | contacts        | 3n   | the latest grasp's contact points in the world frame (m), finger by      | +-max(pi,   |
    |                 |      | finger; 0 for a finger that did not touch                                | diameter)   |
    | contact_normals | 3n   | their contact normals (only with ``normals``), 0 where not touched       | [-1, 1]     |

    With ``observe_yaw=True`` (needs ``action_frame="estimated"``) one value follows last:

    | Slice         | Size | Content                                                                    | Range       |
    | ------------- | ---- | -------------------------------------------------------------------------- | ----------- |
    | yaw_certainty | 1    | the most probable object's yaw posterior mass within +-15 degrees of its   | [0, 1]      |
    |               |      | most probable yaw, the frame the next azimuth is read in (7/72 at reset)   |             |

    ## Rewards
    ``reward = gain - grasp_cost`` with ``gain`` chosen by ``reward``:

    - ``"true-posterior-gain"`` (default): :math:`b_t[k^*] - b_{t-1}[k^*]`, the gain in the posterior of the
      true object :math:`k^*` (the episode return telescopes to :math:`b_T[k^*] - 1/K - T\,c`);
    - ``"max-posterior-gain"``: :math:`\max b_t - \max b_{t-1}` (no ground truth needed);
    - ``"entropy-reduction"``: :math:`H(b_{t-1}) - H(b_t)` in nats.

    ``info["reward_terms"] = {"gain": ..., "grasp_cost": -c}``; its values sum exactly to the reward.

    ``info`` (reset and step): ``true_object``/``true_index``, ``predicted``/``predicted_index`` (belief argmax),
    ``correct``, ``certainty``, ``decided``, ``grasps``, ``usable`` (the grasp updated the belief),
    ``belief (K,)``, ``touched (n,)``; step adds ``reward_terms``.

    ## Starting State
    An object drawn uniformly from the set (or ``options={"object": name_or_index}``), a random pose
    (``pose="table-yaw"``: a uniform yaw about the world z axis with the object's bounding-box centre at the
    origin; ``"so3"``: a uniform rotation), an optional uniform random scale (``scale_range``), and the
    belief at the uniform prior. A forced object skips the object draw, so ``reset(seed=s, options={"object": o})``
    gives another pose than ``reset(seed=s)`` even where that draws ``o``.

    ## Copies
    ``pickle`` and ``copy.deepcopy`` rebuild the env from its constructor arguments (Gymnasium's ``EzPickle``, which
    :class:`~gymnasium.vector.AsyncVectorEnv` relies on): the settings are kept, the episode is not, so a copy
    needs its own ``reset`` before ``step`` (its error says so). Branching rollouts from mid-episode are not
    supported.

    ## Episode End
    ### Termination
    When the updater's certainty reaches ``threshold`` (:math:`\lambda`, default
    :data:`~haptic_env.recognizers.updaters.DEFAULT_THRESHOLD`) after at least one scored grasp (the uniform prior
    alone never decides, even under a threshold below ``1 / K``): the recogniser has decided;
    ``info["correct"]`` says whether the decision is the true object. The certainty is the belief's maximum for
    BC-NP and BC-IP and for IC's default ``ic_certainty="count"``; with ``"share"`` it is the last winner's score
    share (the authors' code), and IC decides from the second grasp on.
    ### Truncation
    After ``max_grasps`` grasps (default 30). The env truncates itself: ``max_grasps`` is the one source of the
    episode length (the registered envs set no ``max_episode_steps``, so no ``TimeLimit`` wrapper is added).

    Grasps where fewer than all ``n`` fingers touched are *incomplete*. With ``z_fingers=z`` the recogniser
    also has ``z .. n-1``-finger models and an incomplete grasp with ``t >= z`` touching fingers is scored by
    the ``t``-finger model; otherwise (default ``z_fingers=None``, or ``t < z``, or degenerate contacts such
    as coplanar ones) the grasp carries no information: the belief is unchanged. Either way it costs a grasp.
    With ``score_subsets=True`` every grasp with ``t >= z`` touching fingers is scored through all its
    ``z``-subsets by the ``z``-finger model instead (the paper's z-finger scoring; a Bayes step counts them as
    at most ``subset_k = 4`` subsets, the paper's Algorithm 4); with ``min_fingers=m`` a grasp of ``m <= t < z``
    touching fingers is then scored by the ``t``-finger model, where the paper's scoring drops it. With
    ``touch_weight=w > 0`` (every registered hand env, ``Heights`` or not) every grasp,
    incomplete or not, also adds ``w log P(pattern | object)`` of its touch pattern (which fingertips touched),
    estimated from the hand's own grasps of the meshes (:mod:`haptic_env.recognizers.touch`); such a grasp always
    updates the belief (BC-NP, or BC-IP, whose classifier prior then comes with the first grasp it scores).

    ## Arguments
    One frozen dataclass :class:`HapticRecogConfig` holds every setting. Pass it as ``config=`` and/or
    override single fields as flat keyword arguments (applied on top of ``config``). A registered variant
    (``HapticRecogShadow-v0``, ...) puts its own fields over ``config`` (keyword arguments go over both):
    ``make`` refuses a ``config`` that set one of them otherwise without a keyword argument for it
    (:func:`~haptic_env.config.resolve_env_config`); build such a config with
    ``haptic_env.variant_config(id, ...)`` and make it with ``haptic_env.make(config, env_id=id)``::

        env = gym.make("HapticRecog-v0")                                  # defaults
        env = gym.make("HapticRecog-v0", config=HapticRecogConfig(n_fingers=3, normals=False))
        env = gym.make("HapticRecog-v0", grasp_cost=0.01, reward="entropy-reduction")
        env = haptic_env.make(HapticRecogConfig(max_grasps=50))            # the env truncates after 50 grasps

    Every field, its default and its meaning: :class:`~haptic_env.config.HapticRecogConfig` (each field's
    docstring; ``python train.py --help`` lists them as ``--env.<field>``, with hyphens: ``--env.grasp-cost``).

    The recogniser is built (or loaded from the cache, ``$HAPTIC_CACHE``) on the first ``reset`` and shared
    by every env of the process with the same objects/fingers/normals/recogniser settings.

    ``render_mode``: ``"rgb_array"`` returns the backend's image of the hand and object; ``"human"`` shows it
    in a matplotlib window (``make`` raises a ``RuntimeError`` when matplotlib has no interactive backend, e.g.
    without a display).

    ## Version History
    * v0: initial version.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 4}

    def __init__(self, config: HapticRecogConfig | None = None, render_mode: str | None = None,
                 variant: str | None = None, **overrides: Any):
        utils.EzPickle.__init__(self, config, render_mode, variant, **overrides)
        config = resolve_env_config(config, variant, overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        if render_mode == "human":
            _require_display()
        self.config = config
        self.render_mode = render_mode

        self.scene = Scene(config)
        self.objects, self.object_names, self.backend = self.scene.objects, self.scene.names, self.scene.backend
        self.n_classes, self.action_dim = self.scene.n_classes, self.scene.action_dim
        self.feature_dim = feature_dim(config.n_fingers, config.normals, heights=config.grasp_heights,
                                       normal_axis=config.normal_axis)
        self.task = Task(config, self.n_classes, self.feature_dim, self.action_dim,
                         q_bound=max(np.pi, self.scene.diameter * 1.01))
        self.observation_structure, self.obs_slices = self.task.observation_structure, self.task.obs_slices
        self.observation_space, self.action_space = self.task.observation_space, self.task.action_space

        self._recognizer = None
        self._belief: Belief | None = None  # built on the first reset (the recogniser is trained or loaded then)
        self._probs = np.full(self.n_classes, 1.0 / self.n_classes)
        self._grasps = 0
        self._episode_over = False
        self._last_result = None
        self._last_approach: np.ndarray | None = None
        self._yaw_belief = None  # action_frame="estimated": built on the first reset (may record the replay pool)
        self._fig = None

    # ----------------------------------------------------------------------------- properties
    @property
    def recognizer(self):
        """The shared recogniser (built or loaded from the cache on first access)."""
        if self._recognizer is None:
            self._recognizer = get_recognizer(self.objects, self.config)
        return self._recognizer

    @property
    def belief_state(self) -> Belief | None:
        """The episode's :class:`~haptic_env.belief.Belief` (None before the first ``reset``); read-only use, please."""
        return self._belief

    @property
    def updater(self):
        """The belief's updater (its posterior maths; None before the first ``reset``); read-only use, please."""
        return None if self._belief is None else self._belief.updater

    @property
    def belief(self) -> np.ndarray:
        """Current posterior over the objects, ``(K,)`` (a copy)."""
        return self._probs.copy()

    @property
    def target(self) -> int:
        """Index of the true object of the episode."""
        return self.scene.target

    @property
    def pose(self) -> np.ndarray:
        """``(4, 4)`` pose of the object in the world frame this episode (a copy)."""
        return self.scene.pose.copy()

    @property
    def scale(self) -> float:
        return self.scene.scale

    @property
    def grasp_count(self) -> int:
        return self._grasps

    @property
    def last_grasp(self):
        """The latest step's grasp result of the backend (world frame: ``contacts``, ``touched``, ...; its approach is
        :attr:`last_approach`), None before an episode's first step; read-only use, please."""
        return self._last_result

    @property
    def last_approach(self) -> np.ndarray | None:
        """The world-frame approach of the latest grasp (a copy; None before an episode's first step): the action as
        executed, turned by the estimated yaw with ``action_frame="estimated"`` (by the true yaw from the second
        grasp on with ``"oracle"``)."""
        return None if self._last_approach is None else self._last_approach.copy()

    def _frame_yaw(self) -> float | None:
        """The yaw the next action's azimuth is read in (``action_frame``): the most probable object's estimated yaw
        (``"estimated"``), the object's true yaw from the second grasp on (``"oracle"``), or None (the world frame)."""
        if self._yaw_belief is not None:
            return self._yaw_belief.mode(int(np.argmax(self._probs)))
        if self.config.action_frame == "oracle" and self._grasps:
            return self.scene.yaw
        return None

    def _observe_yaw(self) -> None:
        """``observe_yaw``: hand the task how sure the most probable object's estimated yaw is now."""
        if self.config.observe_yaw:
            self.task.yaw_certainty = self._yaw_belief.certainty(int(np.argmax(self._probs)))

    # ------------------------------------------------------------------------------- gym API
    def __setstate__(self, state):
        super().__setstate__(state)  # EzPickle: a new env from the constructor arguments
        self._rebuilt = True

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = reset_options(options, ("object",))
        self.scene.reset(self.np_random, options.get("object"))
        if self._belief is None:
            self._belief = Belief.from_config(self.objects, self.config, self.recognizer)
        self._probs = self._belief.reset(support_z=self.scene.support_z)
        self._grasps = 0
        self._episode_over = False
        self._last_result = self._last_approach = None
        if self.config.action_frame == "estimated":
            if self._yaw_belief is None:
                self._yaw_belief = self.scene.yaw_belief()
            self._yaw_belief.reset()
        self.task.reset()
        self._observe_yaw()
        if self.render_mode == "human":
            self.render()
        return self.task.observation(self._probs, 0), self._info(usable=False, decided=False)

    def step(self, action):
        if self._belief is None:
            raise RuntimeError("call reset() before step()" + (
                " (this env is a copy or an unpickled env: those are rebuilt from the constructor arguments and keep "
                "the settings, not the episode)" if getattr(self, "_rebuilt", False) else ""))
        if self._episode_over:  # Gymnasium: stepping a finished episode is undefined; refuse it clearly
            raise RuntimeError(f"the episode is over (it ended after grasp {self._grasps}: terminated at the threshold or "
                               f"truncated at max_grasps={self.config.max_grasps}); call reset() before step()")
        a = self._check_action(action)
        old = self._probs
        psi = self._frame_yaw()
        if psi is None:
            approach = a
        else:
            from haptic_env.grasping.replay import turned_azimuth

            approach = turned_azimuth(a, psi)
        result, contacts, normals, touched = self.scene.grasp(approach)
        if self._yaw_belief is not None:
            self._yaw_belief.add(approach, contacts, touched)
        self._last_result, self._last_approach = result, approach
        self._grasps += 1
        q, usable = self._belief.update(contacts, normals, touched)
        self._probs = self._belief.probs
        self.task.record(q, touched, usable, a, contacts, normals)  # a: a fresh float64 array from _check_action
        self._observe_yaw()
        reward, terms = self.task.reward(old, self._probs, self.scene.target)
        terminated = decided = self._belief.decided
        truncated = self.task.truncated(self._grasps, terminated)
        self._episode_over = terminated or truncated
        info = self._info(usable=usable, decided=decided)
        info["reward_terms"] = terms
        if self.render_mode == "human":
            self.render()
        return self.task.observation(self._probs, self._grasps), reward, terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human' to make()")
            return None
        frame = self.scene.render()
        if self.render_mode == "rgb_array":
            return frame
        import matplotlib.pyplot as plt

        if self._fig is None:
            plt.ion()
            self._fig, ax = plt.subplots()
            self._im = ax.imshow(frame)
            ax.set_axis_off()
        else:
            self._im.set_data(frame)
        self._fig.canvas.draw_idle()
        plt.pause(1.0 / self.metadata["render_fps"])
        return None

    def close(self):
        if self._fig is not None:
            import matplotlib.pyplot as plt

            plt.close(self._fig)
            self._fig = None
        self.scene.close()

    # ------------------------------------------------------------------------------ helpers
    def grasp_rows(self, contacts, normals, touched) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`Belief.rows <haptic_env.belief.Belief.rows>` with the grasp vector clipped as observed."""
        q, Q = self._require_belief().rows(contacts, normals, touched)
        return np.minimum(np.maximum(q, -self.task.q_bound), self.task.q_bound), Q

    def grasp_rows_batch(self, contacts, normals, touched) -> tuple[list[np.ndarray], np.ndarray]:
        """:meth:`Belief.rows_batch <haptic_env.belief.Belief.rows_batch>`."""
        return self._require_belief().rows_batch(contacts, normals, touched)

    def _require_belief(self) -> Belief:
        if self._belief is None:
            raise RuntimeError("call reset() first: the belief is built with the recogniser on the first reset")
        return self._belief

    def _check_action(self, action) -> np.ndarray:
        try:
            a = np.asarray(action)
            is_complex = a.dtype.kind == "c"  # a float cast would silently drop the imaginary part
            if a.dtype.kind not in "fiuc":  # strings, bools, objects: numpy would cast them to numbers silently
                raise TypeError(f"non-numeric dtype {a.dtype}")  # -> the ValueError below, naming the action
            if not is_complex:
                a = a.astype(np.float64, copy=False)
        except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: a Python int beyond float range
            raise ValueError(f"action must be a numeric array of shape ({self.action_dim},), got {action!r}") from exc
        if is_complex:
            raise ValueError(f"action must be real numbers, got complex values {action!r}")
        if a.shape != (self.action_dim,):
            raise ValueError(f"action must have shape ({self.action_dim},), got {a.shape}: {action!r}")
        values = a.tolist()
        lo, hi = min(values), max(values)
        total = sum(values)  # NaN if any value is NaN (min/max may skip it)
        if not (-1.0 - 1e-6 <= lo and hi <= 1.0 + 1e-6 and total == total):
            if not all(math.isfinite(v) for v in values):
                raise ValueError(f"action must be finite, got {values}")
            raise ValueError(f"action must lie in [-1, 1], got {values}")
        return a.clip(-1.0, 1.0) if (lo < -1.0 or hi > 1.0) else (a if a is not action else a.copy())

    def _info(self, *, usable: bool, decided: bool) -> dict[str, Any]:
        certainty = self._belief.certainty if self._belief is not None else float(self._probs.max())
        return self.task.info(self.object_names, self.scene.target, self._probs, certainty, grasps=self._grasps,
                              usable=usable, decided=decided)


def _require_display() -> None:
    """``render_mode="human"`` needs an interactive matplotlib backend (a display); raise a clear error if not."""
    import matplotlib
    import matplotlib.pyplot  # noqa: F401  (resolves the default backend: an interactive one if a display is found)

    backend = matplotlib.get_backend().lower()
    if backend in _NON_INTERACTIVE or backend.startswith("module://matplotlib_inline"):
        raise RuntimeError(f"render_mode='human' needs a display: matplotlib's backend is {backend!r}, which shows no "
                           "window (no $DISPLAY?). Use render_mode='rgb_array' and save or show the frames yourself, or "
                           "select an interactive backend (MPLBACKEND=TkAgg / QtAgg) with a display.")
