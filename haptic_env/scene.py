"""The scene of an episode: the object set, the grasp backend, and the object's identity, pose and scale.

:class:`Scene` is the env's physical world (dm_control's *physics*): it loads the objects and the backend of a
:class:`~haptic_env.config.HapticRecogConfig`, places a drawn object in a random pose (:func:`random_pose`) and
scale at every reset, grasps it and renders it. It knows nothing of beliefs or rewards.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from haptic_env.config import HapticRecogConfig

__all__ = ["Scene", "POSE_MODES", "random_pose", "yaw_pose", "pose_yaw", "reset_options"]

#: "table-yaw": a uniform yaw about the world z axis; "so3": a uniform random rotation.
POSE_MODES = ("table-yaw", "so3")


def yaw_pose(psi: float) -> np.ndarray:
    """The ``(4, 4)`` pose turned by ``psi`` rad about the world z axis, no translation (a "table-yaw" pose)."""
    T = np.eye(4)
    c, s = np.cos(psi), np.sin(psi)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def pose_yaw(T: np.ndarray, who: str = "a yaw") -> float:
    """The turn about the world z axis (rad, in ``[-pi, pi]``) of a "table-yaw" pose ``T (4, 4)``; a ``ValueError``
    naming ``who`` (what needs it) and ``T`` for any other pose (tilted or translated). The inverse of
    :func:`yaw_pose`."""
    T = np.asarray(T, dtype=np.float64)
    R = T[:3, :3]
    if not (np.allclose(R[2], [0.0, 0.0, 1.0], atol=1e-9) and np.allclose(R[:2, 2], 0.0, atol=1e-9)
            and np.allclose(T[:3, 3], 0.0, atol=1e-12)):
        raise ValueError(f"{who} needs a pose turned about the vertical axis only (pose='table-yaw', no translation), "
                         f"got {T.tolist()}")
    return float(np.arctan2(R[1, 0], R[0, 0]))


def random_pose(rng: np.random.Generator, mode: str) -> np.ndarray:
    """A ``(4, 4)`` rigid pose: uniform yaw about z ("table-yaw") or uniform over SO(3) ("so3"); no translation.

    "so3" is :meth:`scipy.spatial.transform.Rotation.random` (four standard normals from ``rng``)."""
    if mode == "table-yaw":
        return yaw_pose(rng.uniform(0.0, 2.0 * np.pi))
    T = np.eye(4)
    if mode == "so3":
        from scipy.spatial.transform import Rotation

        T[:3, :3] = Rotation.random(rng=rng).as_matrix()
    else:
        raise ValueError(f"pose mode must be one of {POSE_MODES}, got {mode!r}")
    return T


class Scene:
    """Objects + backend of ``config``, and the episode's object index, pose, scale and backend generator."""

    def __init__(self, config: HapticRecogConfig):
        from haptic_env.grasping import make_backend
        from haptic_env.objects import load_object_set

        self.config = config
        self.objects = load_object_set(config.objects, **dict(config.object_kwargs))
        self.names: tuple[str, ...] = tuple(self.objects.names)
        try:
            self.backend = make_backend(config.backend, n_fingers=config.n_fingers, **dict(config.backend_kwargs))
        except TypeError as exc:  # an unknown or non-string key of backend_kwargs
            raise TypeError(f"invalid backend_kwargs {dict(config.backend_kwargs)!r} for backend {config.backend!r}: "
                            f"{exc}") from exc
        if int(self.backend.n_fingers) != config.n_fingers:
            raise ValueError(f"backend {config.backend!r} has {self.backend.n_fingers} fingers, config asks {config.n_fingers}")
        prepare = getattr(self.backend, "prepare", None)  # the replay backend records its objects' grasps up front
        if callable(prepare):
            prepare(self.objects)
        self.action_dim = int(self.backend.action_dim)
        #: the largest object diameter at the largest scale (bounds the lengths in a grasp vector)
        scale_hi = config.scale_range[1] if config.scale_range is not None else 1.0
        self.diameter = max(2.0 * float(np.linalg.norm(np.asarray(o.mesh.vertices), axis=1).max())
                            for o in self.objects) * scale_hi
        self.target = 0
        self.pose = np.eye(4)
        self.scale = 1.0
        #: the table top's height under the episode's object (world z, m): what a robot knows of its table; computed
        #: where the grasp vector reads it (``grasp_heights``), else 0
        self.support_z = 0.0
        self.rng: np.random.Generator | None = None  # the backend's generator this episode

    @property
    def n_classes(self) -> int:
        return len(self.objects)

    def support_height(self, k: int, pose, scale: float = 1.0) -> float:
        """The table top's height (world z) under object ``k`` at ``pose`` and ``scale``
        (:func:`~haptic_env.grasping.base.support_height`; every ``support="table"`` backend puts its table there)."""
        from haptic_env.grasping.base import support_height

        return support_height(self.objects[k].mesh.vertices, pose, scale)

    def resolve(self, which) -> int:
        """The index of an object given by name or index (``reset(options={"object": ...})``)."""
        if isinstance(which, (int, np.integer)) and not isinstance(which, bool):
            if not 0 <= int(which) < self.n_classes:
                raise ValueError(f"options['object'] index {which} out of range [0, {self.n_classes})")
            return int(which)
        if isinstance(which, str):
            if which not in self.names:
                raise ValueError(f"options['object'] {which!r} is not in the object set {list(self.names)}")
            return self.names.index(which)
        raise ValueError(f"options['object'] must be an object name or index, got {which!r}")

    def draw(self, rng: np.random.Generator, which=None) -> tuple[int, np.ndarray, float, int]:
        """An episode's ``(object index, pose, scale, seed of the backend's generator)`` drawn from ``rng`` in this
        order (the object unless ``which`` names it); :meth:`reset` and the vector env's sub-envs both draw
        through it (the vector env via :meth:`draw_many`)."""
        return self._draw(rng, which, yaw_angle=False)

    def draw_many(self, rngs, which=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
        """:meth:`draw` from each generator of ``rngs`` (``which[j]``: the object of draw ``j``, or None), the same
        draws in the same order from each (tested equal): ``(targets (m,), poses (m, 4, 4), scales (m,), seeds)``.
        A vector env's resets of one step; the yaw poses' cos / sin in one NumPy call each."""
        m = len(rngs)
        which = [None] * m if which is None else which
        yaw = self.config.pose == "table-yaw"
        targets = np.empty(m, dtype=np.int64)
        poses = np.tile(np.eye(4), (m, 1, 1))
        angles = np.empty(m)
        scales = np.ones(m)
        seeds = [0] * m
        for j, rng in enumerate(rngs):
            targets[j], pose, scales[j], seeds[j] = self._draw(rng, which[j], yaw_angle=yaw)
            if yaw:
                angles[j] = pose
            else:
                poses[j] = pose
        if yaw:  # random_pose's "table-yaw" matrix, for all draws at once
            c, s = np.cos(angles), np.sin(angles)
            poses[:, 0, 0], poses[:, 0, 1], poses[:, 1, 0], poses[:, 1, 1] = c, -s, s, c
        return targets, poses, scales, seeds

    def _draw(self, rng: np.random.Generator, which, yaw_angle: bool):
        """The one draw order of :meth:`draw` and :meth:`draw_many`; with ``yaw_angle`` (pose "table-yaw") the
        pose is returned as its yaw angle (``random_pose``'s one draw), for :meth:`draw_many` to turn into matrices."""
        target = self.resolve(which) if which is not None else int(rng.integers(self.n_classes))
        pose = rng.uniform(0.0, 2.0 * np.pi) if yaw_angle else random_pose(rng, self.config.pose)
        if self.config.scale_range is not None:
            lo, hi = self.config.scale_range
            scale = float(rng.uniform(lo, hi))
        else:
            scale = 1.0
        # child generator for the backend, derived from the env's np_random: same seed -> same episode
        return target, pose, scale, int(rng.integers(2**63))

    def reset(self, rng: np.random.Generator, which=None) -> None:
        """Draw (from ``rng``, :meth:`draw`) the object unless ``which`` names it, its pose, its scale and the
        backend's generator of the episode, and place the object in the backend."""
        self.target, self.pose, self.scale, seed = self.draw(rng, which)
        self.rng = np.random.Generator(np.random.PCG64(seed))
        obj = self.objects[self.target]
        if self.config.grasp_heights:
            self.support_z = self.support_height(self.target, self.pose, self.scale)
        if self.scale != 1.0 and getattr(self.backend, "supports_scale", False):
            # the backend scales the object as a transform: no per-episode mesh copy (nor a new ray-casting scene)
            self.backend.set_object(obj, self.pose.copy(), scale=self.scale)
        else:
            if self.scale != 1.0:
                mesh = obj.mesh.copy()
                mesh.apply_scale(self.scale)
                obj = dataclasses.replace(obj, mesh=mesh)
            self.backend.set_object(obj, self.pose.copy())

    @property
    def yaw(self) -> float:
        """The episode's object turn about the world z axis (rad, :func:`pose_yaw`: a "table-yaw" pose only)."""
        return pose_yaw(self.pose, "the object's yaw")

    def grasp(self, action: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray | None, np.ndarray]:
        """Grasp with ``action``: ``(result, contacts (n, 3), normals (n, 3) or None, touched (n,) bool)``; the
        normals only when ``config.normals`` (sensed, or the backend's ground truth when it senses none)."""
        result = self.backend.grasp(action, self.rng)
        touched = np.asarray(result.touched, dtype=bool).reshape(-1)
        contacts = np.asarray(result.contacts, dtype=np.float64)
        normals = None
        if self.config.normals:
            normals = result.normals if result.normals is not None else getattr(result, "gt_normals", None)
            if normals is None:
                raise ValueError(f"config.normals=True but backend {self.config.backend!r} senses no contact normals; "
                                 "use normals=False")
            normals = np.asarray(normals, dtype=np.float64)
        return result, contacts, normals, touched

    def yaw_belief(self, bins: int = 72):
        """A :class:`~haptic_env.grasping.replay.YawBelief` over the objects' recorded grasps by the env's hand: the
        replay pool of random approaches (cached on disk; recorded first if not), a replay env's own ``approaches``
        if it sets them, with the kernel's default neighbours (at most the records per object). A replay env's
        ``table`` records are not used: the kernel's nearest records would then be one approach at neighbouring yaws,
        not the approaches around the asked one. Nor are a replay env's random-approach records, which answer its
        grasps: each grasp would be one of the belief's own records turned by the true yaw, which the belief finds
        almost exactly (on the generic hand 94 % of its mass within 15 degrees of the truth after 3 grasps, where the
        MuJoCo backend's grasps of the same approaches give 67 %, a review's measurement); its pool is then the
        replay's ``pool_seed`` + 1 (2026-12-07; before, the replay's own records; a ``table`` replay env's belief reads
        the default pool, as before). The pool is the hand's grasps with its default
        physics (``MujocoConfig``'s defaults but ``hand``, ``n_fingers``, ``support`` and ``solid_table``), as the
        hand-trained recogniser's pool (:func:`~haptic_env.hand_grasps.hand_grasp_pool`): an env that changes other
        physics settings (``friction``, ``timestep``, ...) reads its yaw from grasps of the default physics. What it
        needs of the env: :func:`~haptic_env.config.check_yaw_belief`."""
        from haptic_env.config import backend_hand, check_yaw_belief
        from haptic_env.grasping.replay import YAW_NEIGHBOURS, ReplayBackend, ReplayConfig, YawBelief

        cfg = self.config
        check_yaw_belief(cfg, "a yaw belief")
        kw = dict(cfg.backend_kwargs)
        own = {}
        if cfg.backend == "replay":
            if "approaches" in kw:
                own["approaches"] = kw["approaches"]
            if not kw.get("table"):  # a pool apart from the records that answer its grasps
                own["pool_seed"] = int(kw.get("pool_seed", ReplayConfig.pool_seed)) + 1
        replay = ReplayBackend(ReplayConfig(hand=backend_hand(cfg), n_fingers=cfg.n_fingers,
                                            support=kw.get("support", "table"), solid_table=kw.get("solid_table"),
                                            **own))
        replay.prepare(self.objects)
        records = [replay.records(o) for o in self.objects]
        # a small pool (a replay env's own, e.g. in tests) has fewer records than the kernel's default neighbours
        return YawBelief(records, bins, neighbours=min(YAW_NEIGHBOURS, min(len(r[1]) for r in records)))

    def render(self) -> np.ndarray:
        return np.asarray(self.backend.render())

    def close(self) -> None:
        close = getattr(self.backend, "close", None)
        if callable(close):
            close()


def reset_options(options, valid: tuple[str, ...]) -> dict[str, Any]:
    """A ``reset(options=...)`` argument as a new dict: None gives ``{}``; anything but a dict, or a key not in
    ``valid``, is a ``ValueError`` naming it (the single env's and the native vector env's one check)."""
    if options is not None and not isinstance(options, dict):
        raise ValueError(f"reset options must be a dict such as {{'object': 'mug'}} or None, got {options!r}")
    options = dict(options or {})
    unknown = set(options) - set(valid)
    if unknown:
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid: {list(valid)}")
    return options
