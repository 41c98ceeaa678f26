"""Every setting of the env in one frozen dataclass, :class:`HapticRecogConfig`: defaults, validation, and the
JSON-style recogniser settings it carries (:func:`recognizer_kwargs`).

Each field's docstring is its documentation: ``train.py --help`` shows them (``--env.grasp-cost`` etc.).
Defaults that other modules share come from their owners: the threshold and the updater kinds from
:mod:`haptic_env.recognizers.updaters`, the reward kinds from :mod:`haptic_env.task`, the pose modes from
:mod:`haptic_env.scene`.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from haptic_env.grasp_features import check_normal_axis
from haptic_env.numbers import check_flag_fields, finite_number, positive_range, whole_at_least, whole_number
from haptic_env.recognizers.boosted import check_likelihood
from haptic_env.recognizers.calibration import check_calibrate_grasps
from haptic_env.recognizers.touch import check_touch_updater, check_touch_weight
from haptic_env.recognizers.updaters import (DEFAULT_IC_CERTAINTY, DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD,
                                             DEFAULT_UPDATER, UPDATERS, check_ic_certainty, check_threshold)
from haptic_env.recognizers.zfinger import DEFAULT_SUBSET_K, check_min_fingers, check_subset_k, check_z_fingers
from haptic_env.scene import POSE_MODES
from haptic_env.task import REWARD_KINDS

__all__ = ["HapticRecogConfig", "recognizer_kwargs", "backend_hand", "check_yaw_belief", "RECOGNIZER_SOURCES",
           "HAND_APPROACHES", "KDE_METHODS", "HAND_BACKENDS", "ACTION_FRAMES"]

RECOGNIZER_SOURCES = ("auto", "hand", "geometric", "surface")
#: How the env's belief update may evaluate the KDE (``KDEConfig.method``).
KDE_METHODS = ("pooled", "tree", "dense")
#: Backends whose grasps are a MuJoCo hand's (``backend_kwargs["hand"]``): the physics, or its recorded grasps.
HAND_BACKENDS = ("mujoco", "replay")
#: Frames of the action's azimuth (``HapticRecogConfig.action_frame``).
ACTION_FRAMES = ("world", "estimated", "oracle")
#: Random approaches per object of the default ``"hand"`` training grasps.
HAND_APPROACHES = 3_000


@dataclass(frozen=True)
class HapticRecogConfig:
    """Every setting of :class:`HapticRecogEnv` (see the env docstring, section *Arguments*)."""

    objects: str = "default"
    """Object-set spec for :func:`haptic_env.objects.load_object_set` ("default", "families" or "families:N", "kit8",
    "kit20", "ycb10", a folder)."""
    object_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Extra keyword arguments of ``load_object_set`` (``data_dir``, ``units``, ``up``)."""
    backend: str = "geometric"
    """Grasp backend for :func:`haptic_env.grasping.make_backend`: "geometric" | "uniform" | "mujoco" | "replay" (the
    hand's recorded MuJoCo grasps of the nearest recorded approach: the same env, far faster, to train agents on)."""
    backend_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Extra keyword arguments of ``make_backend`` (e.g. ``hand="allegro"`` for mujoco)."""
    n_fingers: int = 4
    """Fingers of the hand (>= 2; 2: a gripper, q is the contact distance, with normals also their two angles to
    the line between the contacts and their twist: 4 values); the backend must have as many."""
    normals: bool = True
    """Use contact normals in the grasp vector (``5n - 6`` values instead of ``3n - 6``)."""
    updater: str = DEFAULT_UPDATER
    """Belief update, one of ``haptic_env.recognizers.UPDATERS``: "bc-np" | "bc-ip" | "ic" | "ic-full"
    (``Recognizer.make_updater(kind=...)``)."""
    ic_certainty: str = DEFAULT_IC_CERTAINTY
    """With ``updater="ic"``: how IC's scores become its certainty, "count" (``max S / k``) or "share" (the last
    winner's share of the winners' scores once it reaches 0.6, from the second grasp on: the authors' public code;
    ``IterativeClassification``). Other updaters ignore it."""
    z_fingers: int | None = None
    """If set (``2 <= z < n_fingers``), the recogniser also gets models for ``z .. n_fingers - 1`` fingers and an
    incomplete grasp with ``t >= z`` touching fingers updates the belief through the ``t``-finger model (its
    touching contacts as one grasp); None: only complete grasps (all ``n`` fingers touching) are scored."""
    score_subsets: bool = False
    """z-finger scoring (paper, Alg. 3): score every grasp with ``t >= z_fingers`` touching fingers through all
    its ``z_fingers``-subsets of contacts with the ``z``-finger model (likelihoods multiplied), instead of the
    ``t``-finger model. Needs ``z_fingers``."""
    min_fingers: int | None = None
    """With ``score_subsets``: also score a grasp of ``min_fingers <= t < z_fingers`` touching fingers, by the
    ``t``-finger model (its touching contacts as one grasp; the recogniser then also has those models). None: such
    grasps carry no contact information, as in the paper's z-finger scoring. Without ``score_subsets`` this is what
    ``z_fingers=min_fingers`` does, so it is refused there."""
    subset_k: int | None = DEFAULT_SUBSET_K
    """With ``score_subsets``: the subsets one Bayes step counts at most. The ``C(t, z)`` subsets of a grasp share its
    contacts; their summed log-likelihood is multiplied by ``min(1, subset_k / m)``, ``m`` the subsets scored
    (``C(t, z)`` unless some are degenerate), the expectation of the paper's Algorithm 4 (``k = 4`` random subsets)
    without the draw. 4 (the paper's): no change for 4 fingers and z = 3; None: the product over all subsets
    (over-confident with 5 fingers: RESULTS.md)."""
    threshold: float = DEFAULT_THRESHOLD
    """Certainty :math:`\\lambda` at which the episode terminates (the recogniser has decided)."""
    reward: str = "true-posterior-gain"
    """"true-posterior-gain" | "max-posterior-gain" | "entropy-reduction"."""
    grasp_cost: float = 0.0
    """Subtracted from the reward at every grasp (usable or not)."""
    pose: str = "table-yaw"
    """"table-yaw": uniform yaw about the world z axis; "so3": uniform random rotation."""
    scale_range: tuple[float, float] | None = None
    """Uniform random object scale per episode, or None (scale 1)."""
    max_grasps: int = DEFAULT_MAX_GRASPS
    """Grasps per episode before truncation (the env truncates itself: the one source of the episode length; the
    registered envs have no ``max_episode_steps``); also normalises the grasp count in the observation."""
    recognizer_source: str = "auto"
    """Training grasps of the recogniser (``DatasetConfig.source``) unless ``recognizer_kwargs`` sets its own:
    "hand" (the MuJoCo backend's own hand grasping each mesh, :mod:`haptic_env.hand_grasps`; mujoco and replay
    backends only), "geometric" (the geometric hand's approach grasps), "surface" (random surface points, the paper's
    protocol), or "auto": "hand" for the mujoco and replay backends, else "geometric". All are computed from the meshes
    alone."""
    training_grasps: int | None = None
    """Training grasps per object of the recogniser (``DatasetConfig.grasps_per_object``; for "hand" grasps, random
    approaches per object) unless ``recognizer_kwargs`` sets its own; None: the source's default
    (:data:`HAND_APPROACHES` for "hand", ``DatasetConfig``'s for the others). The Allegro env uses 6,000: twice the
    default lifted BC-NP's success at the stop on validation grasps in fewer grasps (RESULTS.md); its first make
    and reset take about 2 to over 5 minutes on 2 cores, depending on the machine's MuJoCo speed. The Shadow and
    Aero envs use 6,000 too (validated the same way); theirs take about 4 to 11.5 minutes (RESULTS.md, "Speed and
    build time of the hand envs"; half the approaches cost the KDE validation success, and README gives the
    opt-in half-pool recipe with gradient boosting that keeps it)."""
    kde_method: str = "pooled"
    """How the belief update evaluates the per-object KDEs (``KDEConfig.method``) unless ``recognizer_kwargs``
    sets its own: "pooled" (one neighbour search over all objects' training vectors: a compiled k-d tree, ~25 us per grasp),
    "tree" (a search per object, as the recogniser analyses use: ~0.45 ms), or "dense" (exact, slow)."""
    likelihood: str = "kde"
    """What BC's likelihood is (``RecognizerConfig.likelihood``) unless ``recognizer_kwargs`` sets its own: the KDE
    ("kde", the paper's method) or gradient boosting ("hgb", opt-in: one scikit-learn histogram gradient-boosting
    classifier per finger count, ``log p(object | q)`` minus its prior as the log-likelihood, with a temperature
    fitted for ``calibrate_grasps``-grasp beliefs on validation grasps and the trees walked by a compiled kernel;
    :mod:`haptic_env.recognizers.boosted`). On the hand envs' test episodes BC-NP stopped after 23-25 % fewer grasps
    at the same or higher success (RESULTS.md, "Latest: gradient boosting as the hand envs' likelihood")."""
    calibrated: bool = True
    """Scale the recogniser's scores by the temperatures fitted on its validation grasps
    (:mod:`haptic_env.recognizers.calibration`); False: the paper's raw likelihoods and probabilities."""
    calibrate_grasps: int = 1
    """The KDE's temperature is fitted for beliefs of ``k = 1 .. calibrate_grasps`` grasps of one object
    (``KDEConfig.calibrate_grasps``, unless ``recognizer_kwargs`` sets its own; 1: the one-shot temperature).
    The Allegro and Aero envs use 5, the Shadow env 10 (5 until 2026-12-07, and its ``Heights`` env's): their grasps
    of one object share the KDE's systematic errors, and a belief multiplied over grasps with the one-shot temperature
    stops wrong more often. Chosen per hand on validation grasps (RESULTS.md); the Aero's together with its
    ``touch_weight`` (without the touch pattern its belief needed twice the grasps at 5 for no more success, and it
    kept 1), the Shadow's 10 on 600 validation episodes for a margin over its 94 % target."""
    touch_weight: float = 0.0
    """Weight ``w`` of the hand's touch-pattern log-likelihood ``w log P(pattern | object)`` that BC-NP (or BC-IP)
    adds at every grasp (which fingertips touched: :mod:`haptic_env.recognizers.touch`, estimated from the same
    hand-matched training grasps as the KDE); 0: off, the paper's method. Needs a Bayesian updater ("bc-np", or
    "bc-ip", whose classifier prior then comes with the first grasp the classifier scores) and "hand" training
    grasps (the mujoco or replay backend). The Shadow and Aero envs use 0.5, chosen per hand on validation
    grasps (RESULTS.md; the Shadow's 0.25 before the solid table); the Allegro 0.75 since 2026-12-07, chosen with
    ``z_fingers=2`` on validation grasps with the solid table (with the visual table its success at the stop did not
    change, and it kept 0). The ``Heights`` envs use 1.0 / 0.5 / 1.0 / 1.0 (Allegro / Shadow / Aero / Robotiq),
    chosen for them on validation."""
    grasp_heights: bool = False
    """Append the contacts' heights above the table to the grasp vector (``n`` more values, in the chain order of
    :math:`\\Phi_n`; ``DatasetConfig.heights``, ``phi(heights=True)``), for the recogniser and the observation. The
    object rests on the table turned only about the vertical (``pose="table-yaw"``), so how high the fingertips
    touch it is known to the robot and does not depend on the unknown yaw. False: the paper's frame-invariant
    vector. Needs ``pose="table-yaw"`` and the table support."""
    normal_axis: str = "t2"
    """Each contact normal's second angle in :math:`\\Phi_n` (``n >= 4``, with normals), for the recogniser and the
    observation: to the normal of the triangle on ``ab`` and the chain's fourth contact (``"t2"``, the paper's; the
    chain's second facet ``t2`` when that lies on ``ab``) or to the edge ``ab`` of its first facet (``"ab"``: both
    angles in ``t1``'s frame, the paper's rule for ``n = 3``; ``DatasetConfig.normal_axis``, ``phi(normal_axis=)``).
    ``"ab"`` carries more about the object: kit8 one-shot at n = 4 rises by about 10 points (RESULTS.md). Same vector
    length. ``"frame"``: three angles per normal, to the three axes of ``t1``'s frame (``6n - 6`` values at ``n >= 3``),
    so that no side of the normal is lost."""
    observe_contacts: bool = False
    """Add the latest grasp's contact points (``"contacts"``, ``3n`` values, m) and, with ``normals``, its contact
    normals (``"contact_normals"``, ``3n``) in the world frame to the observation; 0 for fingers that did not touch.
    A kinesthetic hand knows where its fingertips stopped, and where they stopped tells a policy where the object's
    surface is, i.e. its pose, which the frame-invariant grasp vector hides. False: the paper's observation."""
    action_frame: str = "world"
    """The frame of the action's azimuth: the world's (``"world"``), or the estimated frame of the most probable
    object (``"estimated"``: the azimuth is turned by that object's most probable yaw given the episode's grasps, a
    :class:`~haptic_env.grasping.replay.YawBelief` over the hand's recorded grasps of the meshes, the replay pool),
    so that a policy can aim at a part of an object whose yaw the grasps have told. The observation's
    ``prev_action`` is the policy's own action, in that frame; the estimate itself is not observed (only how sure it
    is, with ``observe_yaw``), and
    ``observe_contacts`` stays in the world frame. Needs ``pose="table-yaw"``, a hand backend ("mujoco" or "replay")
    given by name or MJCF path, and no ``scale_range`` (the records are of the meshes as they are); the first
    ``reset`` also records the replay pool if it is not cached. The look-ahead agents simulate world-frame actions,
    so they refuse it.
    ``"oracle"``: the estimated frame with a perfect estimate, for training only (it reads the hidden pose): the
    first grasp in the world frame (as ``"estimated"``'s, before any grasp), every later one turned by the object's
    true yaw. A policy trained so learns approaches relative to the object, and acts with ``"estimated"``
    (privileged training). Needs what ``"estimated"`` needs (it builds no yaw belief, but a policy trained so is
    meant to act with ``"estimated"``, so the same settings are asked of it).
    ``"world"``: the paper's setting."""
    observe_yaw: bool = False
    """Add how sure the estimated frame is to the observation (``"yaw_certainty"``, 1 value): the most probable
    object's yaw posterior mass within +-15 degrees of its most probable yaw (``YawBelief.certainty``; 7/72 before
    any grasp, 1 when sure), so that a policy can tell an approach aimed in a known frame from one aimed in a guessed
    one. Needs ``action_frame="estimated"`` (its yaw belief; ``"oracle"`` has none, so a policy that observes it is
    trained with ``"estimated"``). False: the paper's observation."""
    recognizer_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Extra keyword arguments of :func:`haptic_env.recognizers.build_recognizer`, e.g.
    ``{"config": {"grasps": {"grasps_per_object": 5000}, "mlp": {"max_epochs": 5}}}``: a JSON-style ``config`` updates
    the recogniser this env would build (its ``recognizer_source``, ``training_grasps``, ``kde_method``,
    ``calibrate_grasps`` and ``likelihood`` fill in what it leaves out). A ``RecognizerConfig`` object as ``config``
    is used whole, as given: those env fields do not apply to it (its own defaults: surface grasps, the tree KDE)."""

    def __post_init__(self) -> None:
        check_flag_fields(self, ("normals", "score_subsets", "calibrated", "observe_contacts", "grasp_heights",
                                 "observe_yaw"),
                          "True or False")
        check_calibrate_grasps(self.calibrate_grasps, 1, "calibrate_grasps")
        if self.training_grasps is not None and (whole_number(self.training_grasps) or 0) < 1:
            raise ValueError(f"training_grasps must be None or an int >= 1, got {self.training_grasps!r}")
        if (whole_number(self.n_fingers) or 0) < 2:
            raise ValueError(f"n_fingers must be an int >= 2 (2: a gripper, q is the contact distance), "
                             f"got {self.n_fingers!r}")
        if self.recognizer_source not in RECOGNIZER_SOURCES:
            raise ValueError(f"recognizer_source must be one of {RECOGNIZER_SOURCES}, got {self.recognizer_source!r}")
        if self.recognizer_source == "hand" and self.backend not in HAND_BACKENDS:
            raise ValueError(f"recognizer_source='hand' needs a hand backend {HAND_BACKENDS}, got backend={self.backend!r}")
        if self.updater not in UPDATERS:
            raise ValueError(f"updater must be one of {UPDATERS}, got {self.updater!r}")
        check_ic_certainty(self.ic_certainty)
        w = check_touch_weight(self.touch_weight)
        check_touch_updater(w, self.updater)
        if w > 0 and (self.backend not in HAND_BACKENDS or self.recognizer_source not in ("auto", "hand")):
            raise ValueError(f"touch_weight={w} needs hand-matched training grasps (backend {HAND_BACKENDS} with "
                             f"recognizer_source 'auto' or 'hand'), got backend={self.backend!r}, "
                             f"recognizer_source={self.recognizer_source!r}")
        if self.reward not in REWARD_KINDS:
            raise ValueError(f"reward must be one of {REWARD_KINDS}, got {self.reward!r}")
        if self.pose not in POSE_MODES:
            raise ValueError(f"pose must be one of {POSE_MODES}, got {self.pose!r}")
        check_threshold(self.threshold, "threshold")  # a numpy value is stored as Python's below, as every field's
        cost = finite_number(self.grasp_cost)
        if cost is None or cost < 0.0:
            raise ValueError(f"grasp_cost must be a finite number >= 0, got {self.grasp_cost!r}")
        whole_at_least(self.max_grasps, 1, "max_grasps")
        check_z_fingers(self.z_fingers, self.n_fingers)
        if self.score_subsets and self.z_fingers is None:
            raise ValueError("score_subsets=True needs z_fingers (the subset size)")
        check_min_fingers(self.min_fingers, self.z_fingers, self.score_subsets)
        check_subset_k(self.subset_k)
        if self.scale_range is not None:
            positive_range(self.scale_range, "scale_range")
        if self.grasp_heights and (self.pose != "table-yaw"
                                   or dict(self.backend_kwargs).get("support", "table") != "table"):
            raise ValueError(f"grasp_heights=True needs objects resting on the table, turned about the vertical only "
                             f"(pose='table-yaw', support 'table'), got pose={self.pose!r}, support="
                             f"{dict(self.backend_kwargs).get('support', 'table')!r}")
        check_normal_axis(self.normal_axis)
        if self.action_frame not in ACTION_FRAMES:
            raise ValueError(f"action_frame must be one of {ACTION_FRAMES}, got {self.action_frame!r}")
        if self.action_frame != "world":
            check_yaw_belief(self, f"action_frame={self.action_frame!r}")
        if self.observe_yaw and self.action_frame != "estimated":
            raise ValueError(f"observe_yaw=True observes the estimated frame's yaw belief: it needs "
                             f"action_frame='estimated', got action_frame={self.action_frame!r}")
        if self.kde_method not in KDE_METHODS:
            raise ValueError(f"kde_method must be 'pooled', 'tree' or 'dense', got {self.kde_method!r}")
        check_likelihood(self.likelihood)
        for name in MAPPING_FIELDS:
            if not isinstance(getattr(self, name), Mapping):
                raise TypeError(f"{name} must be a mapping (dict), got {getattr(self, name)!r}")
        self._check_backend()
        if self.recognizer_kwargs:  # checked here, at make, not at the first reset (imports the recognisers)
            import inspect

            from haptic_env.recognizers import build_recognizer

            params = inspect.signature(build_recognizer).parameters
            valid = sorted(k for k, p in params.items() if p.kind == p.KEYWORD_ONLY and k != "z_values")
            unknown = sorted(set(self.recognizer_kwargs) - set(valid))
            if unknown:
                raise ValueError(f"unknown recognizer_kwargs {unknown}; valid: {valid}")
            self._check_recognizer_settings()
            try:
                recognizer_kwargs(self)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"invalid recognizer_kwargs (or backend_kwargs 'support' / 'hand', which its "
                                 f"training grasps take): {exc}") from exc
        from haptic_env.objects.loaders import object_count

        try:
            k = object_count(self.objects, **dict(self.object_kwargs))
        except TypeError as exc:
            raise ValueError(f"invalid object_kwargs {sorted(self.object_kwargs)}: load_object_set takes "
                             "data_dir, units and up") from exc
        if k is not None and k < 2:
            raise ValueError(f"object set {self.objects!r} has {k} object(s); recognising one needs at least 2")
        for f in dataclasses.fields(self):  # a numpy scalar as the Python value it stands for (checked above): a
            v = getattr(self, f.name)       # np.int64 max_grasps made `truncated` a numpy bool
            if isinstance(v, np.generic):
                object.__setattr__(self, f.name, v.item())

    def _check_backend(self) -> None:
        """``backend`` and ``backend_kwargs`` checked at make through the backend's own config (they failed when the
        scene built the backend; a hand's finger count is still checked when the hand is loaded), and what the
        backend needs of the env: normals it can sense, the replay's upright objects at their own scale."""
        from haptic_env.grasping.base import BACKENDS, backend_config

        if not isinstance(self.backend, str) or self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {self.backend!r}")
        if "n_fingers" in self.backend_kwargs:
            raise ValueError(f"backend_kwargs must not set n_fingers ({self.backend_kwargs['n_fingers']!r}): it is the "
                             f"config's own n_fingers field (now {self.n_fingers!r})")
        try:
            bc = backend_config(self.backend, self.n_fingers, **dict(self.backend_kwargs))
        except TypeError as exc:
            raise ValueError(f"invalid backend_kwargs for backend {self.backend!r} ({exc})") from exc
        # refused here, not at the first step (after the recogniser was built): only the physics has ground-truth
        # normals to give when its sensed ones are off
        if self.normals and not getattr(bc, "normals", True) and self.backend != "mujoco":
            raise ValueError(f"normals=True but backend {self.backend!r} with backend_kwargs normals=False senses no "
                             "contact normals; use normals=False")
        if self.backend == "replay" and (self.pose != "table-yaw" or self.scale_range is not None):
            raise ValueError("the replay backend replays the hand's recorded grasps of each object turned about the "
                             "vertical, at its own scale: it needs pose='table-yaw' and scale_range=None, got "
                             f"pose={self.pose!r}, scale_range={self.scale_range!r}")

    def _check_recognizer_settings(self) -> None:
        """``recognizer_kwargs`` that contradict the env's own settings, refused at make (they failed at the first
        reset, after the recogniser was trained): the grasp vectors' ``normal_axis`` and ``heights``, and a touch
        pattern switched off under a ``touch_weight``."""
        kw = self.recognizer_kwargs
        if self.touch_weight > 0 and "touch" in kw and not kw["touch"]:
            raise ValueError(f"touch_weight={self.touch_weight} weighs the touch pattern, but recognizer_kwargs "
                             f"switches it off (touch={kw['touch']!r}); drop one of them")
        rc = kw.get("config", {})
        grasps = rc.get("grasps", {}) if isinstance(rc, Mapping) else getattr(rc, "grasps", None)
        if grasps is None:
            return
        get = grasps.get if isinstance(grasps, Mapping) else lambda k, d=None: getattr(grasps, k, d)
        axis, heights = get("normal_axis", self.normal_axis), get("heights", self.grasp_heights)
        if axis != self.normal_axis:
            raise ValueError(f"recognizer_kwargs' grasps take each normal's second angle to {axis!r} but the config "
                             f"has normal_axis={self.normal_axis!r}; set both alike (or leave it out of the JSON: it "
                             "follows normal_axis)")
        if bool(heights) != bool(self.grasp_heights):
            raise ValueError(f"recognizer_kwargs' grasps have heights={heights!r} but the config has grasp_heights="
                             f"{self.grasp_heights}; set both alike (or leave it out of the JSON: it follows "
                             "grasp_heights)")

    def replace(self, **changes: Any) -> "HapticRecogConfig":
        """A copy with ``changes`` applied; unknown names raise a ``TypeError`` listing the valid ones."""
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise TypeError(f"unknown HapticRecogConfig field(s) {unknown}; valid: {sorted(names)}")
        return dataclasses.replace(self, **changes)


#: The config fields that are mappings of settings: a keyword argument of one updates the mapping (:func:`with_keys`)
MAPPING_FIELDS = ("object_kwargs", "backend_kwargs", "recognizer_kwargs")


class WholeMapping(dict):
    """A mapping field's keyword value that is the field's whole value, not laid over another mapping
    (:func:`with_keys`): :func:`haptic_env.config_kwargs` passes a given config's own mappings so."""


def with_keys(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``overrides`` (keyword arguments of config fields) with each mapping field of :data:`MAPPING_FIELDS` given as
    a mapping laid over ``base``'s mapping of that field (its keys win): ``backend_kwargs={"solid_table": False}``
    on the Shadow env keeps the variant's ``"hand": "shadow"`` (a whole replacement fell back to the generic hand).
    A :class:`WholeMapping` is taken as it is. To drop a key, build the whole config, ``replace`` the field and make
    it with ``haptic_env.make(config, env_id=...)``."""
    out = dict(overrides)
    for k in MAPPING_FIELDS:
        if isinstance(out.get(k), WholeMapping):
            out[k] = dict(out[k])
        elif isinstance(out.get(k), Mapping) and isinstance(base.get(k), Mapping):
            out[k] = {**dict(base[k]), **dict(out[k])}
    return out


def resolve_env_config(config: HapticRecogConfig | None = None, variant: str | None = None,
                       overrides: Mapping[str, Any] | None = None) -> HapticRecogConfig:
    """The config an env is built with: ``config`` (None: the defaults), the registered ``variant``'s fields
    (``haptic_env.ENV_VARIANTS[variant]``; ``gym.make(id)`` passes ``variant=id``) over it, then ``overrides`` (the
    keyword arguments) over both; a mapping field given as a keyword argument (``backend_kwargs``, ...) updates the
    mapping it would get otherwise, its keys winning (:func:`with_keys`).

    A ``config`` that set a field of the variant to something else (not its default, not the variant's value) and
    no keyword argument naming that field is refused by name: the variant's value would silently replace the
    config's choice (``gym.make("HapticRecogShadow-v0", config=HapticRecogConfig(z_fingers=2))`` ran with z = 3).
    A field left at its default takes the variant's value (so a field set to its default value, e.g.
    ``touch_weight=0.0``, cannot be told apart and takes the variant's); ``haptic_env.make(config, env_id=...)``
    keeps the whole config."""
    config = config if config is not None else HapticRecogConfig()
    if not isinstance(config, HapticRecogConfig):
        raise TypeError(f"config must be a HapticRecogConfig, got {type(config).__name__}")
    overrides = dict(overrides or {})
    maps = {k: getattr(config, k) for k in MAPPING_FIELDS}  # the mappings keywords update: the config's, or where
    if variant is not None:
        from haptic_env import ENV_VARIANTS

        if variant not in ENV_VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; choose from {list(ENV_VARIANTS)}")
        fields = ENV_VARIANTS[variant]
        default = HapticRecogConfig()

        def same(a, b) -> bool:
            return dict(a) == dict(b) if isinstance(a, Mapping) and isinstance(b, Mapping) else a == b

        lost = {k: (getattr(config, k), v) for k, v in fields.items() if k not in overrides
                and not same(getattr(config, k), getattr(default, k)) and not same(getattr(config, k), v)}
        if lost:
            said = ", ".join(f"{k}={mine!r} (the variant's {v!r})" for k, (mine, v) in lost.items())
            raise ValueError(
                f"{variant} sets {', '.join(lost)} over the given config: {said}. Build the whole config with "
                f"haptic_env.variant_config({variant!r}, ...) and make it with haptic_env.make(config, "
                f"env_id={variant!r}), or pass those fields as keyword arguments")
        maps.update({k: v for k, v in fields.items() if k in MAPPING_FIELDS})  # the variant sets one, the variant's
        overrides = {**fields, **with_keys(maps, overrides)}  # one replace: no in-between config to fail the checks
    else:
        overrides = with_keys(maps, overrides)
    return config.replace(**overrides) if overrides else config


def backend_hand(config: HapticRecogConfig) -> Any:
    """The hand of a hand backend's env: ``backend_kwargs["hand"]``, else the backend's own default
    (``MujocoConfig.hand``, ``ReplayConfig.hand``)."""
    kw = dict(config.backend_kwargs)
    if "hand" in kw:
        return os.fspath(kw["hand"]) if isinstance(kw["hand"], os.PathLike) else kw["hand"]  # a Path: its text
    if config.backend == "replay":
        from haptic_env.grasping.replay import ReplayConfig

        return ReplayConfig.hand
    from haptic_env.grasping.mujoco_backend import MujocoConfig

    return MujocoConfig.hand


def check_yaw_belief(config: HapticRecogConfig, what: str) -> None:
    """What a yaw belief (:meth:`~haptic_env.scene.Scene.yaw_belief`, over the hand's recorded grasps) needs of an
    env: a hand backend whose hand is given by name or MJCF path, objects turned about the vertical only
    (``pose="table-yaw"``) and no per-episode scale. A ``ValueError`` naming ``what`` and the settings otherwise."""
    if (config.pose != "table-yaw" or config.backend not in HAND_BACKENDS or config.scale_range is not None
            or not isinstance(backend_hand(config), str)):
        raise ValueError(f"{what} needs a hand backend with a hand given by name or MJCF path, and objects turned "
                         "about the vertical only, at their own scale (pose='table-yaw', backend 'mujoco' or 'replay', "
                         f"scale_range=None), got pose={config.pose!r}, backend={config.backend!r}, "
                         f"scale_range={config.scale_range!r}, "
                         f"hand={dict(config.backend_kwargs).get('hand', '(default)')!r}")


def recognizer_kwargs(config: HapticRecogConfig) -> dict[str, Any]:
    """``recognizer_kwargs`` with a JSON-style ``{"config": {"grasps": {...}, "mlp": {...}, "kde": {...}}}``
    turned into ``RecognizerConfig`` (so the command line can pass recogniser settings as JSON); without a
    config, or a JSON config whose ``grasps`` has no ``source``, the recogniser trains on
    ``config.recognizer_source`` grasps (``config.training_grasps`` per object when set, with ``support`` from the
    backend's ``support`` setting, default "table"), and its KDE is evaluated by ``config.kde_method`` and calibrated for ``config.calibrate_grasps``
    grasps unless the JSON ``kde`` sets them; with ``"likelihood": "hgb"`` (gradient boosting in the KDE's place,
    opt-in) its temperature is fitted for ``config.calibrate_grasps`` grasps unless the JSON ``boosted`` sets
    ``calibrate_grasps``."""
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers import KDEConfig, MLPConfig, RecognizerConfig
    from haptic_env.recognizers.recognizer import check_build_options

    kw = dict(config.recognizer_kwargs)
    if config.touch_weight > 0:
        kw.setdefault("touch", True)
    rc = kw.get("config", {})
    if isinstance(rc, Mapping):
        rc = dict(rc)
        grasps = dict(rc.get("grasps", {}))
        source = config.recognizer_source
        if source == "auto":
            source = "hand" if config.backend in HAND_BACKENDS else "geometric"
        grasps.setdefault("source", source)
        if config.training_grasps is not None:
            grasps.setdefault("grasps_per_object", int(config.training_grasps))
        if grasps["source"] == "hand":  # the backend's own hand, HAND_APPROACHES random approaches per object
            hand = backend_hand(config)
            if not isinstance(hand, str):
                raise ValueError(f"recognizer_source 'hand' needs backend_kwargs['hand'] as a hand name or MJCF path "
                                 f"(a cache key), got {type(hand).__name__}")
            grasps.setdefault("hand", hand)
            grasps.setdefault("grasps_per_object", HAND_APPROACHES)
            grasps.setdefault("solid_table", dict(config.backend_kwargs).get("solid_table"))  # None: the default
        if grasps["source"] in ("geometric", "hand"):
            grasps.setdefault("support", dict(config.backend_kwargs).get("support", "table"))
        grasps.setdefault("heights", bool(config.grasp_heights))
        grasps.setdefault("normal_axis", config.normal_axis)
        if isinstance(grasps.get("scale_range"), list):
            grasps["scale_range"] = tuple(grasps["scale_range"])
        rc["grasps"] = DatasetConfig(**grasps)
        if kw.get("touch") and rc["grasps"].source != "hand":
            what = (f"touch_weight={config.touch_weight}" if config.touch_weight > 0
                    else f"recognizer_kwargs['touch']={kw['touch']!r}")
            raise ValueError(f"{what} needs hand-matched training grasps (source 'hand'), "
                             f"got source {rc['grasps'].source!r}")
        if isinstance(rc.get("mlp"), Mapping):
            rc["mlp"] = MLPConfig(**rc["mlp"])
        rc.setdefault("likelihood", config.likelihood)
        boosted = rc.get("boosted", {})
        if isinstance(boosted, Mapping) and (boosted or rc["likelihood"] == "hgb"):  # recognizers/boosted.py
            from haptic_env.recognizers.boosted import BoostedConfig

            # gradient boosting's temperature for the env's calibrate_grasps, as the KDE's, unless the JSON sets it
            env = {"calibrate_grasps": int(config.calibrate_grasps)} if rc["likelihood"] == "hgb" else {}
            rc["boosted"] = BoostedConfig(**{**env, **boosted})
        kde = rc.get("kde", {})
        if isinstance(kde, Mapping):
            rc["kde"] = KDEConfig(**{"method": config.kde_method, "calibrate_grasps": int(config.calibrate_grasps),
                                     **kde})
        kw["config"] = RecognizerConfig(**rc)
    elif not isinstance(rc, RecognizerConfig):
        raise ValueError(f"recognizer_kwargs['config'] must be a RecognizerConfig or a JSON-style dict, got {rc!r}")
    elif kw.get("touch") and rc.grasps.source != "hand":  # refused at make as the JSON form is (it failed at reset)
        what = (f"touch_weight={config.touch_weight}" if config.touch_weight > 0
                else f"recognizer_kwargs['touch']={kw['touch']!r}")
        raise ValueError(f"{what} needs hand-matched training grasps (source 'hand'), got the RecognizerConfig's "
                         f"source {rc.grasps.source!r}")
    check_build_options(**{k: kw[k] for k in ("models", "touch", "cache", "progress") if k in kw})
    return kw
