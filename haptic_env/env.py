r"""``HapticRecog``: active kinesthetic haptic object recognition as a Gymnasium environment.

The environment owns no geometry: it composes an object set (:mod:`haptic_env.objects`), a grasp
backend (:mod:`haptic_env.grasping`), the grasp parameterisation :math:`\Phi_n`
(:mod:`haptic_env.grasp_features`) and a Bayesian belief updater (:mod:`haptic_env.recognizers`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces, utils

from haptic_env.grasp_features import feature_dim

__all__ = [
    "HapticRecogConfig",
    "HapticRecogEnv",
    "REWARD_KINDS",
    "UPDATER_KINDS",
    "POSE_MODES",
    "get_recognizer",
    "random_pose",
]

REWARD_KINDS = ("true-posterior-gain", "max-posterior-gain", "entropy-reduction")
UPDATER_KINDS = ("bc-np", "bc-ip", "ic")
POSE_MODES = ("table-yaw", "so3")
RECOGNIZER_SOURCES = ("auto", "hand", "geometric", "surface")
#: Random approaches per object of the default ``"hand"`` training grasps.
HAND_APPROACHES = 3_000


@dataclass(frozen=True)
class HapticRecogConfig:
    """Every setting of :class:`HapticRecogEnv` (see the env docstring, section *Arguments*)."""

    objects: str = "default"
    """Object-set spec for :func:`haptic_env.objects.load_object_set` ("default", "families", "kit8", "ycb10", a folder)."""
    object_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Extra keyword arguments of ``load_object_set`` (``data_dir``, ``units``)."""
    backend: str = "geometric"
    """Grasp backend for :func:`haptic_env.grasping.make_backend`: "geometric" | "uniform" | "mujoco"."""
    backend_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Extra keyword arguments of ``make_backend`` (e.g. ``hand="allegro"`` for mujoco)."""
    n_fingers: int = 4
    normals: bool = True
    """Use contact normals in the grasp vector (``5n - 6`` values instead of ``3n - 6``)."""
    updater: str = "bc-np"
    """Belief update: "bc-np" | "bc-ip" | "ic" (``Recognizer.make_updater(kind=...)``)."""
    z_fingers: int | None = None
    """If set (``2 <= z < n_fingers``), the recogniser also gets models for ``z .. n_fingers - 1`` fingers and an
    incomplete grasp with ``t >= z`` touching fingers updates the belief through the ``t``-finger model (its
    touching contacts as one grasp); None: only complete grasps (all ``n`` fingers touching) are scored."""
    score_subsets: bool = False
    """z-finger scoring (paper, Alg. 3): score every grasp with ``t >= z_fingers`` touching fingers through all
    its ``z_fingers``-subsets of contacts with the ``z``-finger model (likelihoods multiplied), instead of the
    ``t``-finger model. Needs ``z_fingers``."""
    threshold: float = 0.85
    """Certainty :math:`\\lambda` at which the episode terminates (the recogniser has decided)."""
    reward: str = "true-posterior-gain"
    """"true-posterior-gain" | "max-posterior-gain" | "entropy-reduction"."""
    grasp_cost: float = 0.0
    """Subtracted from the reward at every grasp (usable or not)."""
    pose: str = "table-yaw"
    """"table-yaw": uniform yaw about the world z axis; "so3": uniform random rotation."""
    scale_range: tuple[float, float] | None = None
    """Uniform random object scale per episode, or None (scale 1)."""
    max_grasps: int = 30
    """Grasps per episode before truncation; also normalises the grasp count in the observation."""
    recognizer_source: str = "auto"
    """Training grasps of the recogniser (``DatasetConfig.source``) unless ``recognizer_kwargs`` sets its own:
    "hand" (the MuJoCo backend's own hand grasping each mesh, :mod:`haptic_env.hand_grasps`; mujoco backend
    only), "geometric" (the geometric hand's approach grasps), "surface" (random surface points, the paper's
    protocol), or "auto": "hand" for the mujoco backend, else "geometric". All are computed from the meshes
    alone."""
    kde_method: str = "pooled"
    """How the belief update evaluates the per-object KDEs (``KDEConfig.method``) unless ``recognizer_kwargs``
    sets its own: "pooled" (one neighbour search over all objects' training vectors: a compiled k-d tree, ~25 us per grasp),
    "tree" (a search per object, as the recogniser analyses use: ~0.45 ms), or "dense" (exact, slow)."""
    calibrated: bool = True
    """Scale the recogniser's scores by the temperatures fitted on its validation grasps
    (:mod:`haptic_env.recognizers.calibration`); False: the paper's raw likelihoods and probabilities."""
    recognizer_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Extra keyword arguments of :func:`haptic_env.recognizers.build_recognizer`, e.g.
    ``{"config": RecognizerConfig(grasps=DatasetConfig(grasps_per_object=5000))}``; ``config`` may also be a
    JSON-style dict (``{"grasps": {"grasps_per_object": 5000}, "mlp": {"max_epochs": 5}}``)."""

    def __post_init__(self) -> None:
        for name in ("normals", "score_subsets", "calibrated"):  # bool("no") is True: take real booleans only
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if not isinstance(self.n_fingers, (int, np.integer)) or self.n_fingers < 2:
            raise ValueError(f"n_fingers must be an int >= 2 (2: a gripper, q is the contact distance), "
                             f"got {self.n_fingers!r}")
        if self.recognizer_source not in RECOGNIZER_SOURCES:
            raise ValueError(f"recognizer_source must be one of {RECOGNIZER_SOURCES}, got {self.recognizer_source!r}")
        if self.recognizer_source == "hand" and self.backend != "mujoco":
            raise ValueError(f"recognizer_source='hand' needs the mujoco backend, got backend={self.backend!r}")
        if self.updater not in UPDATER_KINDS:
            raise ValueError(f"updater must be one of {UPDATER_KINDS}, got {self.updater!r}")
        if self.reward not in REWARD_KINDS:
            raise ValueError(f"reward must be one of {REWARD_KINDS}, got {self.reward!r}")
        if self.pose not in POSE_MODES:
            raise ValueError(f"pose must be one of {POSE_MODES}, got {self.pose!r}")
        if not (isinstance(self.threshold, (int, float)) and 0.0 < self.threshold <= 1.0):
            raise ValueError(f"threshold must be in (0, 1], got {self.threshold!r}")
        if not (isinstance(self.grasp_cost, (int, float, np.integer, np.floating))
                and math.isfinite(self.grasp_cost) and self.grasp_cost >= 0.0):
            raise ValueError(f"grasp_cost must be a finite number >= 0, got {self.grasp_cost!r}")
        if not isinstance(self.max_grasps, (int, np.integer)) or self.max_grasps < 1:
            raise ValueError(f"max_grasps must be an int >= 1, got {self.max_grasps!r}")
        if self.z_fingers is not None and not (isinstance(self.z_fingers, (int, np.integer))
                                               and 2 <= self.z_fingers < self.n_fingers):
            raise ValueError(f"z_fingers must be None or in [2, n_fingers={self.n_fingers}), got {self.z_fingers!r}")
        if self.score_subsets and self.z_fingers is None:
            raise ValueError("score_subsets=True needs z_fingers (the subset size)")
        if self.scale_range is not None:
            try:
                lo, hi = (float(v) for v in self.scale_range)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"scale_range must be (lo, hi) with 0 < lo <= hi, got {self.scale_range!r}") from exc
            if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
                raise ValueError(f"scale_range must be (lo, hi) with 0 < lo <= hi, got {self.scale_range!r}")
        if self.kde_method not in ("pooled", "tree", "dense"):
            raise ValueError(f"kde_method must be 'pooled', 'tree' or 'dense', got {self.kde_method!r}")
        for name in ("recognizer_kwargs", "object_kwargs", "backend_kwargs"):
            if not isinstance(getattr(self, name), Mapping):
                raise TypeError(f"{name} must be a mapping (dict), got {getattr(self, name)!r}")
        if self.recognizer_kwargs:  # checked here, at make, not at the first reset (imports the recognisers)
            import inspect

            from haptic_env.recognizers import build_recognizer

            params = inspect.signature(build_recognizer).parameters
            valid = sorted(k for k, p in params.items() if p.kind == p.KEYWORD_ONLY and k != "z_values")
            unknown = sorted(set(self.recognizer_kwargs) - set(valid))
            if unknown:
                raise ValueError(f"unknown recognizer_kwargs {unknown}; valid: {valid}")
            try:
                _recognizer_kwargs(self)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"invalid recognizer_kwargs (or backend_kwargs 'support' / 'hand', which its "
                                 f"training grasps take): {exc}") from exc
        from haptic_env.objects.loaders import object_count

        try:
            k = object_count(self.objects, **dict(self.object_kwargs))
        except TypeError as exc:
            raise ValueError(f"invalid object_kwargs {sorted(self.object_kwargs)}: load_object_set takes "
                             "data_dir and units") from exc
        if k is not None and k < 2:
            raise ValueError(f"object set {self.objects!r} has {k} object(s); recognising one needs at least 2")

    def replace(self, **changes: Any) -> "HapticRecogConfig":
        """A copy with ``changes`` applied; unknown names raise a ``TypeError`` listing the valid ones."""
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise TypeError(f"unknown HapticRecogConfig field(s) {unknown}; valid: {sorted(names)}")
        return dataclasses.replace(self, **changes)


# ------------------------------------------------------------------------------ recogniser memo
_RECOGNIZERS: dict[str, Any] = {}


def get_recognizer(objects, config: HapticRecogConfig):
    """The recogniser for ``objects`` and ``config`` (built/cached on disk once, then memoised per process)."""
    from haptic_env.cache import config_key

    z_values = tuple(range(config.z_fingers, config.n_fingers)) if config.z_fingers is not None else ()
    kwargs = _recognizer_kwargs(config)  # torch: imported on first use only
    from haptic_env.recognizers import build_recognizer, models_for

    kwargs.setdefault("models", models_for(config.updater))  # BC-NP: the KDE only
    key = config_key(objects.name, tuple(objects.names), config.n_fingers, config.normals, z_values, kwargs)
    if key not in _RECOGNIZERS:

        _RECOGNIZERS[key] = build_recognizer(objects, config.n_fingers, config.normals, z_values=z_values, **kwargs)
    return _RECOGNIZERS[key]


def _recognizer_kwargs(config: HapticRecogConfig) -> dict[str, Any]:
    """``recognizer_kwargs`` with a JSON-style ``{"config": {"grasps": {...}, "mlp": {...}, "kde": {...}}}``
    turned into ``RecognizerConfig`` (so the command line can pass recogniser settings as JSON); without a
    config, or a JSON config whose ``grasps`` has no ``source``, the recogniser trains on
    ``config.recognizer_source`` grasps (with ``support`` from the backend's ``support`` setting, default
    "table"), and its KDE is evaluated by ``config.kde_method`` unless the JSON ``kde`` names a method."""
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers import KDEConfig, MLPConfig, RecognizerConfig

    kw = dict(config.recognizer_kwargs)
    rc = kw.get("config", {})
    if isinstance(rc, Mapping):
        rc = dict(rc)
        grasps = dict(rc.get("grasps", {}))
        source = config.recognizer_source
        if source == "auto":
            source = "hand" if config.backend == "mujoco" else "geometric"
        grasps.setdefault("source", source)
        if grasps["source"] == "hand":  # the backend's own hand, HAND_APPROACHES random approaches per object
            hand = dict(config.backend_kwargs).get("hand", "generic")
            if not isinstance(hand, str):
                raise ValueError(f"recognizer_source 'hand' needs backend_kwargs['hand'] as a hand name or MJCF path "
                                 f"(a cache key), got {type(hand).__name__}")
            grasps.setdefault("hand", hand)
            grasps.setdefault("grasps_per_object", HAND_APPROACHES)
        if grasps["source"] in ("geometric", "hand"):
            grasps.setdefault("support", dict(config.backend_kwargs).get("support", "table"))
        if isinstance(grasps.get("scale_range"), list):
            grasps["scale_range"] = tuple(grasps["scale_range"])
        rc["grasps"] = DatasetConfig(**grasps)
        if isinstance(rc.get("mlp"), Mapping):
            rc["mlp"] = MLPConfig(**rc["mlp"])
        kde = rc.get("kde", {})
        if isinstance(kde, Mapping):
            rc["kde"] = KDEConfig(**{"method": config.kde_method, **kde})
        kw["config"] = RecognizerConfig(**rc)
    return kw


def random_pose(rng: np.random.Generator, mode: str) -> np.ndarray:
    """A ``(4, 4)`` rigid pose: uniform yaw about z ("table-yaw") or uniform over SO(3) ("so3"); no translation."""
    T = np.eye(4)
    if mode == "table-yaw":
        a = rng.uniform(0.0, 2.0 * np.pi)
        c, s = np.cos(a), np.sin(a)
        T[:2, :2] = [[c, -s], [s, c]]
    elif mode == "so3":
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        w, x, y, z = q
        T[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    else:
        raise ValueError(f"pose mode must be one of {POSE_MODES}, got {mode!r}")
    return T


def _entropy(p: np.ndarray) -> float:
    p = np.asarray(p, dtype=np.float64)
    nz = p[p > 0]
    return float(-(nz * np.log(nz)).sum())


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
    grasps of the geometric hand model, ``recognizer_source``). The task is to become certain of the object's identity in as
    few grasps as possible. The agent does not see the object or its pose.

    ## Action Space
    ``Box(-1, 1, (A,), float32)`` where ``A = backend.action_dim``: the approach parameters of one grasp,
    defined by the backend; every backend takes ``A = 4``: approach azimuth, elevation (upper hemisphere with
    ``support="table"``), roll of the hand about the approach axis, finger spread (see
    :mod:`haptic_env.grasping.base`). Actions outside ``[-1, 1]``, of the wrong shape or non-finite raise
    ``ValueError``.

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
    belief at the uniform prior.

    ## Episode End
    ### Termination
    When the belief's certainty (its maximum) reaches ``threshold`` (:math:`\lambda = 0.85`): the
    recogniser has decided; ``info["correct"]`` says whether the decision is the true object.
    ### Truncation
    After ``max_grasps`` grasps (30; registered as ``max_episode_steps``; the env also truncates itself at
    ``max_grasps`` so a changed value is honoured without the wrapper).

    Grasps where fewer than all ``n`` fingers touched are *incomplete*. With ``z_fingers=z`` the recogniser
    also has ``z .. n-1``-finger models and an incomplete grasp with ``t >= z`` touching fingers is scored by
    the ``t``-finger model; otherwise (default ``z_fingers=None``, or ``t < z``, or degenerate contacts such
    as coplanar ones) the grasp carries no information: the belief is unchanged. Either way it costs a grasp.
    With ``score_subsets=True`` every grasp with ``t >= z`` touching fingers is scored through all its
    ``z``-subsets by the ``z``-finger model instead (the paper's z-finger scoring).

    ## Arguments
    One frozen dataclass :class:`HapticRecogConfig` holds every setting. Pass it as ``config=`` and/or
    override single fields as flat keyword arguments (applied on top of ``config``)::

        env = gym.make("HapticRecog-v0")                                  # defaults
        env = gym.make("HapticRecog-v0", config=HapticRecogConfig(n_fingers=3, normals=False))
        env = gym.make("HapticRecog-v0", grasp_cost=0.01, reward="entropy-reduction")
        env = haptic_env.make(HapticRecogConfig(max_grasps=50))            # also sets max_episode_steps

    | Field              | Default                 | Meaning                                                    |
    | ------------------ | ----------------------- | ---------------------------------------------------------- |
    | objects            | "default"               | object-set spec (``load_object_set``)                      |
    | object_kwargs      | {}                      | ``data_dir``, ``units`` for ``load_object_set``            |
    | backend            | "geometric"             | "geometric" / "uniform" / "mujoco"                         |
    | backend_kwargs     | {}                      | passed to ``make_backend``                                 |
    | n_fingers          | 4                       | fingers (>= 2)                                             |
    | normals            | True                    | contact normals in :math:`\Phi`                            |
    | updater            | "bc-np"                 | "bc-np" / "bc-ip" / "ic"                                   |
    | z_fingers          | None                    | sub-grasp model for incomplete grasps                      |
    | score_subsets      | False                   | score grasps by their z_fingers-subsets (paper Alg. 3)     |
    | threshold          | 0.85                    | certainty to terminate                                     |
    | reward             | "true-posterior-gain"   | see *Rewards*                                              |
    | grasp_cost         | 0.0                     | per-grasp cost                                             |
    | pose               | "table-yaw"             | "table-yaw" / "so3"                                        |
    | scale_range        | None                    | (lo, hi) random scale                                      |
    | max_grasps         | 30                      | truncation and count normalisation                         |
    | recognizer_source  | "auto"                  | training grasps: "hand" (mujoco) / "geometric" / "surface" |
    | kde_method         | "pooled"                | KDE evaluation: "pooled" (fast) / "tree" / "dense"         |
    | calibrated         | True                    | temperature-scaled scores (fitted on validation grasps)    |
    | recognizer_kwargs  | {}                      | passed to ``build_recognizer``                             |

    The recogniser is built (or loaded from the cache, ``$HAPTIC_CACHE``) on the first ``reset`` and shared
    by every env of the process with the same objects/fingers/normals/recogniser settings.

    ``render_mode``: ``"rgb_array"`` returns the backend's image of the hand and object; ``"human"`` shows it
    in a matplotlib window (no-op under a non-interactive matplotlib backend).

    ## Version History
    * v0: initial version.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 4}

    def __init__(self, config: HapticRecogConfig | None = None, render_mode: str | None = None, **overrides: Any):
        utils.EzPickle.__init__(self, config, render_mode, **overrides)
        config = config if config is not None else HapticRecogConfig()
        if not isinstance(config, HapticRecogConfig):
            raise TypeError(f"config must be a HapticRecogConfig, got {type(config).__name__}")
        if overrides:
            config = config.replace(**overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.config = config
        self.render_mode = render_mode

        from haptic_env.grasping import make_backend
        from haptic_env.objects import load_object_set

        self.objects = load_object_set(config.objects, **dict(config.object_kwargs))
        self.object_names: tuple[str, ...] = tuple(self.objects.names)
        try:
            self.backend = make_backend(config.backend, n_fingers=config.n_fingers, **dict(config.backend_kwargs))
        except TypeError as exc:  # an unknown or non-string key of backend_kwargs
            raise TypeError(f"invalid backend_kwargs {dict(config.backend_kwargs)!r} for backend {config.backend!r}: "
                            f"{exc}") from exc
        if int(self.backend.n_fingers) != config.n_fingers:
            raise ValueError(f"backend {config.backend!r} has {self.backend.n_fingers} fingers, config asks {config.n_fingers}")

        n, K, A = config.n_fingers, len(self.objects), int(self.backend.action_dim)
        d = feature_dim(n, config.normals)
        self.n_classes, self.feature_dim, self.action_dim = K, d, A
        self.observation_structure = {
            "grasp": d, "contact_mask": n, "usable": 1, "belief": K, "prev_action": A, "grasp_count": 1,
        }
        self.obs_slices: dict[str, slice] = {}
        lows, highs, start = [], [], 0
        # grasp vectors hold angles (rad, |.| <= pi) and lengths (m, <= the largest object diameter)
        scale_hi = config.scale_range[1] if config.scale_range is not None else 1.0
        diam = max(2.0 * float(np.linalg.norm(np.asarray(o.mesh.vertices), axis=1).max()) for o in self.objects)
        self._q_bound = float(max(np.pi, diam * scale_hi * 1.01))
        bounds = {
            "grasp": (-self._q_bound, self._q_bound), "contact_mask": (0, 1), "usable": (0, 1), "belief": (0, 1),
            "prev_action": (-1, 1), "grasp_count": (0, 1),
        }
        for name, size in self.observation_structure.items():
            self.obs_slices[name] = slice(start, start + size)
            start += size
            lows.append(np.full(size, bounds[name][0], np.float32))
            highs.append(np.full(size, bounds[name][1], np.float32))
        self.observation_space = spaces.Box(np.concatenate(lows), np.concatenate(highs), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (A,), dtype=np.float32)

        self._recognizer = None
        self._updater = None
        self._scorer = None  # compiled scorer of complete grasps (set with the updater)
        self._backend_rng: np.random.Generator | None = None
        self._target: int = 0
        self._pose = np.eye(4)
        self._scale = 1.0
        self._belief = np.full(K, 1.0 / K)
        self._grasps = 0
        self._last_q = np.zeros(d)
        self._last_mask = np.zeros(n)
        self._last_usable = 0.0
        self._last_action = np.zeros(A)
        self._last_result = None
        self._fig = None

    # ----------------------------------------------------------------------------- properties
    @property
    def recognizer(self):
        """The shared recogniser (built or loaded from the cache on first access)."""
        if self._recognizer is None:
            self._recognizer = get_recognizer(self.objects, self.config)
        return self._recognizer

    @property
    def updater(self):
        """The episode's belief updater (``None`` before the first ``reset``); read-only use, please."""
        return self._updater

    @property
    def belief(self) -> np.ndarray:
        """Current posterior over the objects, ``(K,)`` (a copy)."""
        return self._belief.copy()

    @property
    def target(self) -> int:
        """Index of the true object of the episode."""
        return self._target

    @property
    def pose(self) -> np.ndarray:
        """``(4, 4)`` pose of the object in the world frame this episode (a copy)."""
        return self._pose.copy()

    @property
    def scale(self) -> float:
        return self._scale

    @property
    def grasp_count(self) -> int:
        return self._grasps

    # ------------------------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"object"}
        if unknown:
            raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid: ['object']")
        K = self.n_classes
        rng = self.np_random
        self._target = self._resolve_object(options["object"]) if "object" in options else int(rng.integers(K))
        self._pose = random_pose(rng, self.config.pose)
        if self.config.scale_range is not None:
            lo, hi = self.config.scale_range
            self._scale = float(rng.uniform(lo, hi))
        else:
            self._scale = 1.0
        # child generator for the backend, derived from np_random: same seed -> same episode
        self._backend_rng = np.random.Generator(np.random.PCG64(int(rng.integers(2**63))))

        obj = self.objects[self._target]
        if self._scale != 1.0 and getattr(self.backend, "supports_scale", False):
            # the backend scales the object as a transform: no per-episode mesh copy (nor a new ray-casting scene)
            self.backend.set_object(obj, self._pose.copy(), scale=self._scale)
        else:
            if self._scale != 1.0:
                mesh = obj.mesh.copy()
                mesh.apply_scale(self._scale)
                obj = dataclasses.replace(obj, mesh=mesh)
            self.backend.set_object(obj, self._pose.copy())

        if self._updater is None:
            self._updater = self.recognizer.make_updater(kind=self.config.updater, threshold=self.config.threshold,
                                                         calibrated=self.config.calibrated)
            # complete grasps scored in one compiled call (Bayesian updates from a pooled KDE; None otherwise)
            bayes = self.config.updater in ("bc-np", "bc-ip") and not self.config.score_subsets
            self._scorer = self.recognizer.grasp_scorer(self.config.calibrated) if bayes else None
        self._belief = self._as_belief(self._updater.reset(None))
        self._grasps = 0
        self._episode_over = False
        self._last_q = np.zeros(self.feature_dim)
        self._last_mask = np.zeros(self.config.n_fingers)
        self._last_usable = 0.0
        self._last_action = np.zeros(self.action_dim)
        self._last_result = None
        if self.render_mode == "human":
            self.render()
        return self._obs(), self._info(usable=False, decided=False)

    def step(self, action):
        if self._updater is None:
            raise RuntimeError("call reset() before step()")
        if self._episode_over:  # Gymnasium: stepping a finished episode is undefined; refuse it clearly
            raise RuntimeError(f"the episode is over (it ended after grasp {self._grasps}: terminated at the threshold or "
                               f"truncated at max_grasps={self.config.max_grasps}); call reset() before step()")
        a = self._check_action(action)
        old = self._belief
        result = self.backend.grasp(a, self._backend_rng)
        self._last_result = result
        self._grasps += 1
        self._last_action = a  # a fresh float64 array from _check_action

        touched = np.asarray(result.touched, dtype=bool).reshape(-1)
        contacts = np.asarray(result.contacts, dtype=np.float64)
        normals = self._normals_of(result) if self.config.normals else None
        if (self._scorer is not None and np.count_nonzero(touched) == touched.size
                and (self.config.updater == "bc-np" or self._updater.n_grasps > 0)):  # BC-IP: prior from the classifier
            q_obs, log_lik = self._scorer(contacts, normals)  # = grasp_rows + the likelihood of updater.update
            np.minimum(np.maximum(q_obs, -self._q_bound, out=q_obs), self._q_bound, out=q_obs)  # q_obs is fresh
            usable = log_lik is not None
            if usable:
                self._belief = self._as_belief(self._updater.update_scores(log_lik=log_lik))
        else:
            q_obs, update_arg = self.grasp_rows(contacts, normals, touched)
            usable = update_arg is not None
            if usable:
                self._belief = self._as_belief(self._updater.update(update_arg))
                if self.config.updater == "ic":  # IC's belief S / k is sub-stochastic: report S / sum(S), which sums
                    total = self._belief.sum()  # to 1 (the certainty stays IC's own max S / k, see _info)
                    if total > 0:
                        self._belief /= total
        self._last_q = q_obs
        self._last_mask = touched.astype(np.float64)
        self._last_usable = float(usable)

        gain = self._gain(old, self._belief)
        terms = {"gain": gain, "grasp_cost": -float(self.config.grasp_cost)}
        reward = float(sum(terms.values()))
        decided = bool(self._updater.decided)
        terminated = decided
        truncated = (not terminated) and self._grasps >= self.config.max_grasps
        self._episode_over = terminated or truncated
        info = self._info(usable=usable, decided=decided)
        info["reward_terms"] = terms
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human' to make()")
            return None
        frame = np.asarray(self.backend.render())
        if self.render_mode == "rgb_array":
            return frame
        import matplotlib

        if matplotlib.get_backend().lower() in ("agg", "pdf", "ps", "svg", "cairo", "template"):
            return None  # non-interactive backend: nothing to show
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
        close = getattr(self.backend, "close", None)
        if callable(close):
            close()

    # ------------------------------------------------------------------------------ helpers
    def _resolve_object(self, which) -> int:
        if isinstance(which, (int, np.integer)) and not isinstance(which, bool):
            if not 0 <= int(which) < self.n_classes:
                raise ValueError(f"options['object'] index {which} out of range [0, {self.n_classes})")
            return int(which)
        if isinstance(which, str):
            if which not in self.object_names:
                raise ValueError(f"options['object'] {which!r} is not in the object set {list(self.object_names)}")
            return self.object_names.index(which)
        raise ValueError(f"options['object'] must be an object name or index, got {which!r}")

    def _check_action(self, action) -> np.ndarray:
        try:
            a = np.asarray(action)
            is_complex = a.dtype.kind == "c"  # a float cast would silently drop the imaginary part
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

    def _normals_of(self, result) -> np.ndarray:
        N = result.normals if result.normals is not None else getattr(result, "gt_normals", None)
        if N is None:
            raise ValueError(
                f"config.normals=True but backend {self.config.backend!r} senses no contact normals; "
                "use normals=False"
            )
        return np.asarray(N, dtype=np.float64)

    def grasp_rows(self, contacts, normals, touched) -> tuple[np.ndarray, np.ndarray | None]:
        """Observation vector of the touching contacts and the rows to score (None: no information).

        ``contacts``/``normals`` ``(n, 3)`` and ``touched`` ``(n,)`` of one grasp. Returns ``q_obs (d,)`` (the
        observation slice) and ``Q (m, d_z)`` for ``updater.update`` or None. Both come from
        ``Recognizer.features`` (a recogniser trained scale-normalised sees normalised vectors): the touching
        contacts as one grasp, or their ``z``-subsets with ``score_subsets``. Agents that simulate grasps
        (:mod:`agents.greedy`) use it to score them exactly as the env does.
        """
        n = self.config.n_fingers
        t = np.count_nonzero(touched)
        q_obs = np.zeros(self.feature_dim)
        if t < 2:
            return q_obs, None
        Q = self.recognizer.features(contacts, normals, touched=touched)
        if len(Q):
            q_obs[: Q.shape[1]] = np.minimum(np.maximum(Q[0], -self._q_bound), self._q_bound)
        z = self.config.z_fingers
        if self.config.score_subsets and t >= z:
            Q = self.recognizer.features(contacts, normals, touched=touched, z=z)
            return q_obs, (Q if len(Q) else None)
        scored = t == n or (z is not None and t >= z)
        return q_obs, (Q if scored and len(Q) else None)

    def grasp_rows_batch(self, contacts, normals, touched) -> tuple[list[np.ndarray], np.ndarray]:
        """:meth:`grasp_rows` for ``B`` grasps ``(B, n, 3)`` / ``(B, n)``: ``(rows, scored)`` with ``scored (G,)`` the
        batch indices of the grasps that update the belief and ``rows[g] (m_g, d_g)`` the score rows of grasp
        ``scored[g]``. Vectorised when only complete grasps are scored by one model (the default)."""
        contacts = np.asarray(contacts, dtype=np.float64)
        touched = np.asarray(touched, dtype=bool)
        rc = getattr(self.recognizer, "config", None)
        if self.config.z_fingers is None and not getattr(rc, "normalize_scale", False):
            from haptic_env.grasp_features import phi

            full = np.flatnonzero(touched.all(axis=1))
            if full.size == 0:
                return [], full
            f = phi(contacts[full], None if normals is None else np.asarray(normals, dtype=np.float64)[full])
            return list(f.q[f.valid][:, None, :]), full[f.valid]
        rows, scored = [], []
        for i in range(len(contacts)):
            _, Q = self.grasp_rows(contacts[i], None if normals is None else normals[i], touched[i])
            if Q is not None:
                rows.append(Q)
                scored.append(i)
        return rows, np.asarray(scored, dtype=np.int64)

    def _gain(self, old: np.ndarray, new: np.ndarray) -> float:
        kind = self.config.reward
        if kind == "true-posterior-gain":
            return float(new[self._target] - old[self._target])
        if kind == "max-posterior-gain":
            return float(new.max() - old.max())
        return _entropy(old) - _entropy(new)

    def _as_belief(self, b) -> np.ndarray:
        if not (isinstance(b, np.ndarray) and b.dtype == np.float64 and b.ndim == 1):
            b = np.asarray(b, dtype=np.float64).reshape(-1)
        if b.shape != (self.n_classes,) or not math.isfinite(np.add.reduce(b)):  # NaN / inf propagate to the sum
            raise RuntimeError(f"belief updater returned an invalid belief {b!r} (expected {self.n_classes} finite values)")
        return b.copy()

    def _obs(self) -> np.ndarray:
        sl = self.obs_slices
        obs = np.empty(self.observation_space.shape, dtype=np.float32)
        obs[sl["grasp"]] = self._last_q
        obs[sl["contact_mask"]] = self._last_mask
        obs[sl["usable"]] = self._last_usable
        obs[sl["belief"]] = self._belief
        obs[sl["prev_action"]] = self._last_action
        obs[sl["grasp_count"]] = self._grasps / self.config.max_grasps
        return obs

    def _info(self, *, usable: bool, decided: bool) -> dict[str, Any]:
        pred = int(self._belief.argmax())
        certainty = float(self._belief[pred])
        if self.config.updater == "ic" and self._updater is not None:
            certainty = float(self._updater.certainty)  # IC: winning score / grasps (the belief is normalised)
        return {
            "true_object": self.object_names[self._target],
            "true_index": self._target,
            "predicted": self.object_names[pred],
            "predicted_index": pred,
            "correct": pred == self._target,
            "certainty": certainty,
            "decided": decided,
            "grasps": self._grasps,
            "usable": usable,
            "belief": self._belief.copy(),
            "touched": self._last_mask.astype(bool),
        }
