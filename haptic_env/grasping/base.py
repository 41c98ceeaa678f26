"""Grasp results, the backend protocol and the approach (action) parameterisation.

The approach
------------
Every backend takes the same action, a ``float32`` vector in ``[-1, 1]^4``:

=====  ==============  =====================================================================
index  name            meaning
=====  ==============  =====================================================================
0      ``azimuth``     approach azimuth ``phi = pi * a[0]`` in ``[-pi, pi]`` (world z-axis)
1      ``elevation``   approach elevation; ``support="table"``: ``(a[1] + 1) / 2 * pi/2`` in
                       ``[0, pi/2]`` (upper hemisphere, object resting on a table);
                       ``support="floating"``: ``a[1] * pi/2`` in ``[-pi/2, pi/2]`` (full sphere)
2      ``roll``        roll of the hand about the approach axis, ``psi = pi * a[2]``
3      ``spread``      grasp shape: finger spread / aperture ``s = (a[3] + 1) / 2`` in ``[0, 1]``
                       (0 = fingers together opposite the thumb, 1 = evenly spread)
=====  ==============  =====================================================================

The hand comes *from* the unit direction ``u = (cos el cos phi, cos el sin phi, sin el)`` (seen
from the object's centre) and moves along ``-u``; :func:`approach_frame` returns the rotation whose
columns are ``(e1, e2, e3)`` with ``e3 = -u`` (the approach axis, into the object) and ``e1`` the
thumb direction after the roll.

Invalid actions (wrong shape, NaN/inf, outside ``[-1, 1]``) raise :class:`ValueError` naming the
offending value. Backends are deterministic given the action and the ``np.random.Generator`` they
are handed (the generator is only used for sensing noise / random surface points).
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from haptic_env.numbers import checked_flag, positive_number, whole_at_least

__all__ = [
    "ACTION_DIM",
    "ACTION_NAMES",
    "approach_table",
    "GraspResult",
    "GraspBatch",
    "GraspBackend",
    "Approach",
    "validate_action",
    "validate_actions",
    "decode_approach",
    "approach_frame",
    "validate_pose",
    "support_height",
    "usable_touch",
    "check_support",
    "make_backend",
    "BACKENDS",
]

ACTION_DIM = 4
ACTION_NAMES = ("azimuth", "elevation", "roll", "spread")
SUPPORTS = ("table", "floating")


def approach_table(n: int, dim: int = ACTION_DIM) -> np.ndarray:
    """``(n, dim)`` float32: ``n`` approaches spread evenly over the action box ``[-1, 1]^dim``, the first ``n``
    points after the origin of the unscrambled Halton sequence (``scipy.stats.qmc.Halton``), so that the table
    depends on ``n`` and ``dim`` alone (a saved model's ``Discrete(n)`` names it; the replay backend records its
    rows, ``ReplayConfig.table``). ``n`` and ``dim`` ints >= 1; a ``ValueError`` names a bad one."""
    from scipy.stats import qmc

    n, dim = whole_at_least(n, 1, "n"), whole_at_least(dim, 1, "dim")
    return (qmc.Halton(d=dim, scramble=False).random(n + 1)[1:] * 2.0 - 1.0).astype(np.float32)


def check_support(support) -> str:
    """``support`` unchanged if it is one of :data:`SUPPORTS`, else a ``ValueError`` naming it (the backends' and the
    dataset's one check)."""
    if support not in SUPPORTS:
        raise ValueError(f"support must be 'table' or 'floating', got {support!r}")
    return support


def check_solid_table(solid_table, support: str) -> bool:
    """Whether the hand collides with the table: ``None`` (the default everywhere) is solid wherever there is a table
    (``support="table"``); a bool is taken as given (``False``: the visual table every hand figure before 2026-12-07
    was measured with), anything else is a ``ValueError``, and ``True`` is refused with any support but ``"table"``
    (there is no table to collide with). The MuJoCo backend's, the hand pools' and the dataset's one check and
    one default."""
    if solid_table is None:
        return support == "table"
    if checked_flag(solid_table, "solid_table") and support != "table":
        raise ValueError(f"solid_table needs support='table', got support={support!r}")
    return bool(solid_table)


def usable_touch(touched: np.ndarray) -> np.ndarray:
    """Which grasps are usable: ``touched (..., n)`` bool -> ``(...)`` bool, at least ``min(3, n)`` fingers touched (a
    grasp the Phi_n features accept: a polyhedron, or the distance of a 2-finger gripper).

    ``touched`` must be a bool array (numpy ``bool`` dtype, or a list of Python bools) with ``n >= 2`` fingers, as
    every backend reports it; anything else (ints, floats, strings, a scalar, ``n < 2``) raises a ``ValueError``
    naming it rather than being read by truthiness. The check reads only the dtype and the shape."""
    t = np.asarray(touched)
    if t.dtype.kind != "b" or t.ndim == 0 or t.shape[-1] < 2:
        raise ValueError(f"touched must be a bool array of shape (..., n) with n >= 2 fingers, got dtype {t.dtype} "
                         f"and shape {t.shape}: {touched!r}")
    return t.sum(axis=-1) >= min(3, t.shape[-1])


@dataclass(frozen=True)
class GraspResult:
    """One grasp. ``n`` fingers; rows of untouched fingers are 0 in ``contacts``/``normals``.

    contacts   (n, 3) float64, world frame (m)
    normals    (n, 3) unit INWARD normals (into the object) or ``None`` when not sensed
    touched    (n,) bool
    joint_pos  (k,) hand joint state (empty for geometric / uniform)
    gt_normals (n, 3) ground-truth inward normals (mujoco backend) or ``None``
    info       free-form extras (e.g. mujoco: steps taken, ground-truth contact points)
    """

    contacts: np.ndarray
    normals: np.ndarray | None
    touched: np.ndarray
    joint_pos: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gt_normals: np.ndarray | None = None
    info: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def n_touched(self) -> int:
        return int(np.count_nonzero(self.touched))

    @property
    def usable(self) -> bool:
        """At least ``min(3, n)`` fingers touched (:func:`usable_touch`)."""
        return bool(usable_touch(self.touched))


@dataclass(frozen=True)
class GraspBatch:
    """``B`` grasps as stacked arrays (the shapes of :class:`GraspResult` with a leading ``B``)."""

    contacts: np.ndarray  # (B, n, 3)
    normals: np.ndarray | None  # (B, n, 3)
    touched: np.ndarray  # (B, n) bool
    joint_pos: np.ndarray  # (B, k)
    gt_normals: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.contacts.shape[0])

    def __getitem__(self, i: int) -> GraspResult:
        return GraspResult(
            contacts=self.contacts[i],
            normals=None if self.normals is None else self.normals[i],
            touched=self.touched[i],
            joint_pos=self.joint_pos[i],
            gt_normals=None if self.gt_normals is None else self.gt_normals[i],
        )

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    @property
    def usable(self) -> np.ndarray:
        """(B,) bool: at least ``min(3, n)`` fingers touched (:func:`usable_touch`)."""
        return usable_touch(self.touched)

    @classmethod
    def stack(cls, results: list[GraspResult]) -> "GraspBatch":
        if not results:
            raise ValueError("GraspBatch.stack needs at least one GraspResult")
        has_n = all(r.normals is not None for r in results)
        has_gt = all(r.gt_normals is not None for r in results)
        return cls(
            contacts=np.stack([r.contacts for r in results]),
            normals=np.stack([r.normals for r in results]) if has_n else None,
            touched=np.stack([r.touched for r in results]),
            joint_pos=np.stack([r.joint_pos for r in results]),
            gt_normals=np.stack([r.gt_normals for r in results]) if has_gt else None,
        )


@runtime_checkable
class GraspBackend(Protocol):
    """What every grasp backend offers (see module docstring for the action layout)."""

    n_fingers: int
    action_dim: int

    def set_object(self, obj: Any, pose: np.ndarray | None = None) -> None: ...

    def grasp(self, action: np.ndarray, rng: np.random.Generator) -> GraspResult: ...

    def grasp_batch(self, actions: np.ndarray, rng: np.random.Generator) -> GraspBatch: ...

    def render(self, width: int = 480, height: int = 480) -> np.ndarray: ...


@dataclass(frozen=True)
class Approach:
    """A decoded action. Angles in radians, ``spread`` in [0, 1]; arrays for batches."""

    azimuth: np.ndarray
    elevation: np.ndarray
    roll: np.ndarray
    spread: np.ndarray

    @property
    def direction(self) -> np.ndarray:
        """(..., 3) unit vector from the object centre towards the hand (``u``)."""
        ce = np.cos(self.elevation)
        return np.stack([ce * np.cos(self.azimuth), ce * np.sin(self.azimuth), np.sin(self.elevation)], axis=-1)


def _real_array(value: Any, name: str) -> np.ndarray:
    """``value`` as a float64 array; a ``ValueError`` naming ``name`` and the value where it is not real numbers
    (complex values, whose imaginary part a cast would drop; strings; ints beyond a float's range)."""
    if type(value) is np.ndarray and value.dtype == np.float64:  # the env's own actions: nothing to cast
        return value
    try:
        arr = np.asarray(value)
        is_complex = arr.dtype.kind == "c"
        if not is_complex:
            arr = arr.astype(np.float64, copy=False)
    except OverflowError as exc:
        raise ValueError(f"{name} must be finite real numbers, got a value too large for a float: {value!r}") from exc
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {value!r}") from exc
    if is_complex:
        raise ValueError(f"{name} must be real numbers, got complex values {value!r}")
    return arr


def validate_actions(actions: Any, action_dim: int = ACTION_DIM) -> np.ndarray:
    """Check a batch of actions: returns ``(B, action_dim)`` float64; ValueError naming the bad value (complex values
    and ints beyond a float's range too)."""
    arr = _real_array(actions, "actions")
    if arr.ndim != 2 or arr.shape[1] != action_dim:
        raise ValueError(f"actions must have shape (B, {action_dim}), got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        b, j = np.argwhere(bad)[0]
        raise ValueError(f"action[{b}][{j}] ({ACTION_NAMES[j] if j < len(ACTION_NAMES) else j}) is {float(arr[b, j])}, "
                         "must be finite")
    out = np.abs(arr) > 1.0 + 1e-6
    if out.any():
        b, j = np.argwhere(out)[0]
        raise ValueError(f"action[{b}][{j}] ({ACTION_NAMES[j] if j < len(ACTION_NAMES) else j}) = {float(arr[b, j])!r} "
                         "is outside [-1, 1]")
    return np.clip(arr, -1.0, 1.0)


def validate_action(action: Any, action_dim: int = ACTION_DIM) -> np.ndarray:
    """Check one action: returns ``(action_dim,)`` float64; ValueError naming the bad value."""
    arr = _real_array(action, "action")
    if arr.shape != (action_dim,):
        raise ValueError(f"action must have shape ({action_dim},), got shape {arr.shape}: {action!r}")
    return validate_actions(arr[None], action_dim)[0]


def decode_approach(actions: np.ndarray, support: str = "table") -> Approach:
    """Map validated actions ``(..., 4)`` in [-1, 1] to angles (see the table in the module docstring).

    The backends call it on every grasp with actions :func:`validate_actions` has already checked, so it checks only
    the shape (``(..., 4)``; a ``ValueError`` otherwise), not the values: NaN, inf or values outside ``[-1, 1]`` decode
    to angles outside the table's ranges. Pass other actions through :func:`validate_actions` first."""
    if support not in SUPPORTS:
        raise ValueError(f"support must be one of {SUPPORTS}, got {support!r}")
    a = np.asarray(actions, dtype=np.float64)
    if a.shape[-1:] != (ACTION_DIM,):
        raise ValueError(f"actions must have shape (..., {ACTION_DIM}), got shape {a.shape}")
    el = (a[..., 1] + 1.0) * (np.pi / 4.0) if support == "table" else a[..., 1] * (np.pi / 2.0)
    return Approach(azimuth=np.pi * a[..., 0], elevation=el, roll=np.pi * a[..., 2], spread=(a[..., 3] + 1.0) / 2.0)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (..., 3) arrays (np.cross is slow on small arrays)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def approach_frame(approach: Approach) -> np.ndarray:
    """(..., 3, 3) rotations with columns ``(e1, e2, e3)``: ``e3 = -u`` the approach axis (into the object),
    ``e1`` the thumb direction (rolled by ``approach.roll`` about ``e3``), ``e2 = e3 x e1``.

    Before the roll ``e1`` is world z projected onto the plane normal to ``e3``. At the poles (a vertical approach)
    that projection vanishes and its limit is taken instead, ``sign(e3_z)`` times the azimuth's horizontal direction
    ``(cos phi, sin phi, 0)`` (away from it at the upper pole, towards it at the lower), so the frame is continuous in
    the elevation at both poles."""
    u = approach.direction
    e3 = -u
    # reference perpendicular: world z projected, degenerate at the poles -> its limit there, +-azimuth direction
    zref = np.broadcast_to(np.array([0.0, 0.0, 1.0]), e3.shape)
    ref = zref - np.sum(zref * e3, axis=-1, keepdims=True) * e3
    nref = np.linalg.norm(ref, axis=-1, keepdims=True)
    ref = ref / np.maximum(nref, 1e-12)
    pole = ~(nref[..., 0] > 1e-6)
    if pole.any():  # only there: the common case costs one test
        az = np.broadcast_to(np.asarray(approach.azimuth, dtype=np.float64), pole.shape)[pole]
        e3p = e3[pole]
        horiz = np.stack([np.cos(az), np.sin(az), np.zeros_like(az)], axis=-1)
        horiz *= np.copysign(1.0, e3p[:, 2:])  # e3_z = -1 at the upper pole, +1 at the lower
        alt = horiz - np.sum(horiz * e3p, axis=-1, keepdims=True) * e3p
        ref[pole] = alt / np.maximum(np.linalg.norm(alt, axis=-1, keepdims=True), 1e-12)
    b1 = ref
    b2 = _cross(e3, b1)
    c, s = np.cos(approach.roll)[..., None], np.sin(approach.roll)[..., None]
    e1 = c * b1 + s * b2
    e2 = _cross(e3, e1)
    return np.stack([e1, e2, e3], axis=-1)


def support_height(vertices, pose=None, scale: float = 1.0) -> float:
    """The table top's height (world z, m) under an object resting on it: the lowest z of its ``vertices (V, 3)``
    (object frame), scaled by ``scale`` about the object's origin, then posed by ``pose (4, 4)`` (identity when
    None). Every backend with ``support="table"`` puts its table there; contacts minus it are in the support frame
    that :func:`~haptic_env.grasp_features.phi` ``(heights=True)`` reads.

    ``vertices`` must be finite and ``scale`` a finite number ``> 0`` (a real scalar: :func:`~haptic_env.numbers.
    finite_number`; a negative scale would reflect the object); a ``ValueError`` names what is not."""
    f = positive_number(scale, "scale")
    v = _real_array(vertices, "vertices")
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"vertices must have shape (V, 3) with V >= 1, got {v.shape}")
    if not np.isfinite(v).all():
        i = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise ValueError(f"vertices must be finite, got vertices[{i}] = {v[i].tolist()}")
    v = f * v
    T = validate_pose(pose)
    return float((v @ T[2, :3]).min() + T[2, 3])


def placement(obj: Any, pose: Any = None, scale: Any = 1.0) -> tuple[Any, np.ndarray, float]:
    """A backend's ``set_object(obj, pose, scale)`` arguments checked: ``(obj.mesh, pose (4, 4), scale)``; a
    ``ValueError`` naming an object without a usable triangle mesh, a bad pose (:func:`validate_pose`) or a scale
    that is not a finite number > 0."""
    import trimesh

    mesh = getattr(obj, "mesh", None)
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"object {getattr(obj, 'name', obj)!r} has no usable triangle mesh")
    return mesh, validate_pose(pose), positive_number(scale, "scale")


def validate_pose(pose: Any) -> np.ndarray:
    """A 4x4 rigid transform (identity when ``None``); ValueError naming what is wrong."""
    if pose is None:
        return np.eye(4)
    T = _real_array(pose, "object pose")
    if T.shape != (4, 4):
        raise ValueError(f"object pose must be a 4x4 matrix, got shape {T.shape}")
    rows = T.tolist()  # a 4x4 check in Python floats: numpy's allclose and det cost ~40 us, a reset needs two
    if not all(math.isfinite(v) for row in rows for v in row):
        raise ValueError(f"object pose contains non-finite values: {rows}")
    R = [row[:3] for row in rows[:3]]
    # R R^T = I and T[3] = (0, 0, 0, 1) within np.allclose's tolerances (atol 1e-6 / 1e-8, rtol 1e-5), det R > 0
    orthonormal = all(abs(sum(a * b for a, b in zip(R[i], R[j])) - (i == j)) <= 1e-6 + 1e-5 * (i == j)
                      for i in range(3) for j in range(3))
    det = (R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1]) - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0])
           + R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0]))
    last = all(abs(v - b) <= 1e-8 + 1e-5 * b for v, b in zip(rows[3], (0.0, 0.0, 0.0, 1.0)))
    if not (orthonormal and det >= 0 and last):
        raise ValueError(f"object pose must be a rigid transform (rotation + translation), got {rows}")
    return T


#: backend name -> (its module, config class, backend class, ``n_fingers`` when none is given: None is the hand's own)
_KINDS = {"geometric": (".geometric", "GeometricConfig", "GeometricBackend", 4),
          "uniform": (".uniform", "UniformConfig", "UniformBackend", 4),
          "mujoco": (".mujoco_backend", "MujocoConfig", "MujocoBackend", None),
          "replay": (".replay", "ReplayConfig", "ReplayBackend", None)}  # a hand's recorded MuJoCo grasps
BACKENDS = tuple(_KINDS)


def make_backend(name: str = "geometric", n_fingers: int | None = None, **cfg: Any) -> GraspBackend:
    """Build a backend by name: ``"geometric"`` | ``"uniform"`` | ``"mujoco"`` | ``"replay"``.

    ``cfg`` are the fields of that backend's config dataclass (:class:`GeometricConfig`,
    :class:`UniformConfig`, :class:`MujocoConfig`, :class:`~.replay.ReplayConfig`); unknown keys raise TypeError
    naming them. For ``"mujoco"``, ``hand="generic"|"allegro"|"shadow"|"<path to .xml>"`` picks the hand; the
    Allegro hand has 4 fingers, Shadow 5 (``n_fingers`` must agree); any other MJCF file or MuJoCo
    Menagerie name is described automatically (:mod:`.auto_hand`). ``"replay"`` answers with that hand's
    recorded MuJoCo grasps of the nearest recorded approach (:mod:`.replay`: fast, to train agents on).
    ``n_fingers=None``: 4, or for ``"mujoco"`` and ``"replay"`` the hand's own count.
    """
    config = backend_config(name, n_fingers, **cfg)
    module, _, backend, _ = _KINDS[name]
    return getattr(importlib.import_module(module, __package__), backend)(config)


def backend_config(name: str = "geometric", n_fingers: int | None = None, **cfg: Any) -> Any:
    """The config dataclass that :func:`make_backend` builds backend ``name`` from, its values checked (cheap: no
    hand or mesh is loaded; whether a hand has ``n_fingers`` fingers is checked when it is). A ValueError names an
    unknown backend, a TypeError the ``cfg`` keys its config does not have."""
    if not isinstance(name, str) or name not in BACKENDS:
        raise ValueError(f"unknown grasp backend {name!r}; choose one of {BACKENDS}")
    if "n_fingers" in cfg:  # it would reach the config twice
        raise TypeError("n_fingers is make_backend's own argument, not one of the config's keyword arguments")
    module, config, _, default_fingers = _KINDS[name]
    n = default_fingers if n_fingers is None else n_fingers
    return getattr(importlib.import_module(module, __package__), config)(n_fingers=n, **cfg)
