"""MuJoCo grasp backend: a hand on a mocap mount approaches a fixed object and closes its fingers.

Split dm_control-style into

* :class:`GraspScene` - the simulator wrapper: builds the MjSpec scene (object as convex pieces on a
  static body, optional table, hand attached to a mocap body, fingertip sites), owns
  ``MjModel``/``MjData``, and offers physics-level operations (teleport the mount, set controls,
  step, fingertip kinematics, contact queries, rendering). Knows nothing about actions.
* :class:`MujocoBackend` - the task logic behind the :class:`~.base.GraspBackend` protocol: decodes
  an approach, places the open hand outside the object along it (teleport, no simulated approach),
  closes the fingers with their position actuators until they stall on contact or reach their
  targets, and reads the grasp: fingertip positions from forward kinematics, contact normals
  estimated from joint torques through the hand Jacobian, ground-truth normals from MuJoCo contacts.

Torque-derived normals: with the fingers at rest, the joint torques the motors hold against the
object are ``tau = -(qfrc_actuator + qfrc_passive - qfrc_bias)`` (``torque_source="actuator"``,
what a kinesthetic hand senses) or ``qfrc_constraint`` (``"constraint"``). With ``J_h`` the stacked
(3m, nv) fingertip-site position Jacobians of the m touching fingers (``mj_jacSite``),
``tau = J_h^T f`` so ``f = (J_h^T)^+ tau`` (least squares) and each finger's inward normal estimate
is ``-f_i / |f_i|`` (``f_i`` is the force the object exerts on finger i). Friction tilts the force
inside the friction cone, so estimates are within about ``atan(mu)`` of the true normal. Internal
forces of equality constraints (coupled joints of under-actuated hands, closed gripper linkages) are
solved for as extra unknowns; dofs at a joint limit are left out. A finger whose joints are all
parallel (a planar finger without abduction) cannot sense the force component along its joint
axes: its estimate is the normal projected into the finger's plane.

Gravity is off (equivalent to a gravity-compensated hand; the object is fixed anyway). The hand
collides with the object and, with ``support="table"``, with the table (``MujocoConfig.solid_table``, since
2026-12-07; no self-collision). ``solid_table=False`` makes the table a visual plane that only restricts the approach
to the upper hemisphere, the scene of every hand figure before then: a third of the Allegro's random grasps reached a
fingertip into it.
"""

from __future__ import annotations

import os
import time
import warnings
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import mujoco

from haptic_env.cache import KEY_ONLY_WHEN_SET
from haptic_env.numbers import checked_flag, finite_number, whole_number

from .base import (
    ACTION_DIM,
    GraspBatch,
    GraspResult,
    approach_frame,
    check_solid_table,
    check_support,
    decode_approach,
    placement,
    support_height,
    usable_touch,
    validate_action,
    validate_actions,
)
from .collision import CollisionConfig, convex_pieces
from .hands import HandDescription, finger_of_bodies, load_hand

__all__ = ["MujocoConfig", "GraspScene", "MujocoBackend", "quat_from_matrix"]

#: Compiled scenes (one per object mesh) a backend keeps; a reset with a known object only moves it.
MAX_SCENES = 16
HAND_BITS = (1, 2)  # (contype, conaffinity) of hand geoms: collide with the object (and a solid table) only
OBJ_BITS = (2, 1)
#: MuJoCo's constraint solvers by name (``MujocoConfig.solver``; a hand may pick one in ``HandDescription.option``).
#: ``benchmarks/bench_grasp_solver.py``: CG gives the same grasps as Newton on every hand (both stop at MuJoCo's
#: tolerance) and is faster on the Shadow only; PGS is about 2x slower on all.
SOLVERS = {"CG": mujoco.mjtSolver.mjSOL_CG, "Newton": mujoco.mjtSolver.mjSOL_NEWTON, "PGS": mujoco.mjtSolver.mjSOL_PGS}


@dataclass(frozen=True)
class MujocoConfig:
    n_fingers: int | None = 4  # None: the hand's own count (4 for "generic")
    hand: Any = "generic"  # "generic" | "allegro" | ... | MJCF .xml path | Menagerie name | HandDescription
    hand_kwargs: tuple[tuple[str, Any], ...] = ()  # e.g. (("tips", ("a", "b", "c")),) for an MJCF hand
    support: str = "table"  # "table" | "floating" (see base.decode_approach)
    normals: bool = True  # report torque-derived normals
    torque_source: str = "actuator"  # "actuator" | "constraint"
    contact_point: str = "surface"  # "surface": site + r * normal estimate; "site": fingertip site centre
    timestep: float | None = None  # s (None: the hand's own, HandDescription.timestep)
    solver: str | None = None  # MuJoCo constraint solver "CG" | "Newton" | "PGS" (None: the hand's own, else Newton)
    #: closing steps at most. None: the hand's closing time (HandDescription.max_steps steps of its own timestep) in
    #: steps of this config's timestep, so that another ``timestep`` keeps the time the fingers have to close
    max_steps: int | None = None
    min_time: float = 0.08  # s of closing before the rest test may end a grasp
    check_interval: float = 0.02  # s: test for new tip contacts / rest this often (rounded to whole steps)
    squeeze: float = 0.15  # rad past the contact configuration (x moment arm for tendons); 0: close fully
    #: rad/s: fingers at rest below this at two checks in a row (one check until 2026-12-07: a finger swinging
    #: sideways passed it at a turning point, its torque normals 26-32 degrees off, on the generic hand)
    rest_qvel: float = 0.05
    joint_frictionloss: float | None = 0.0  # override the hand's dry joint friction (None: keep the model's)
    friction: float = 0.1  # sliding friction of object and hand geoms (normal error <~ atan(friction))
    march_step: float = 0.01  # m: pre-grasp placement search step along the approach
    standoff: float | None = None  # m: back-off after the closest collision-free pre-grasp pose (None: the hand's)
    contact_noise: float = 0.0  # std (m) on reported contacts
    normal_noise_deg: float = 0.0
    collision: CollisionConfig = CollisionConfig()
    #: the hand collides with the table: no fingertip sinks into it, and the pre-grasp pose is free of it too. None:
    #: solid wherever there is a table (support "table"; :func:`~.base.check_solid_table`, :attr:`table_is_solid`);
    #: False: the visual table of the hand figures before 2026-12-07. Keyed only when set (the pools key the table
    #: themselves, :func:`haptic_env.hand_grasps.pool_cache_path`).
    solid_table: bool | None = field(default=None, metadata={KEY_ONLY_WHEN_SET: True})

    @property
    def table_is_solid(self) -> bool:
        """Whether the hand collides with the table (``solid_table`` resolved for the support)."""
        return check_solid_table(self.solid_table, self.support)

    def __post_init__(self) -> None:
        if self.n_fingers is not None and (whole_number(self.n_fingers) is None or self.n_fingers < 2):
            raise ValueError(f"n_fingers must be an int >= 2 or None, got {self.n_fingers!r}")
        check_support(self.support)
        checked_flag(self.normals, "normals")
        check_solid_table(self.solid_table, self.support)  # refused here, resolved by table_is_solid
        if self.solver is not None and self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {tuple(SOLVERS)}, got {self.solver!r}")
        hk = self.hand_kwargs  # 'abc' was a dict() error at the backend's build, not naming the field
        pairs = hk.items() if isinstance(hk, Mapping) else hk if isinstance(hk, (tuple, list)) else None
        if pairs is None or not all(isinstance(kv, (tuple, list)) and len(kv) == 2 and isinstance(kv[0], str)
                                    for kv in pairs):
            raise ValueError(f"hand_kwargs must be a table or (name, value) pairs, e.g. (('tips', ('a', 'b')),), got "
                             f"{hk!r}")
        if self.torque_source not in ("actuator", "constraint"):
            raise ValueError(f"torque_source must be 'actuator' or 'constraint', got {self.torque_source!r}")
        if self.contact_point not in ("surface", "site"):
            raise ValueError(f"contact_point must be 'surface' or 'site', got {self.contact_point!r}")
        for name in ("timestep", "march_step", "rest_qvel", "min_time", "check_interval"):
            v = getattr(self, name)
            if v is None and name == "timestep":
                continue
            f = finite_number(v)
            if f is None or f <= 0:
                raise ValueError(f"{name} must be > 0, got {v!r}")
        # friction 0 is a frictionless contact (MuJoCo clamps it to its mjMINMU); squeeze 0 closes fully
        for name in ("contact_noise", "normal_noise_deg", "squeeze", "friction", "joint_frictionloss", "standoff"):
            v = getattr(self, name)
            if v is None and name in ("joint_frictionloss", "standoff"):
                continue
            f = finite_number(v)
            if f is None or f < 0:
                none = " or None" if name in ("joint_frictionloss", "standoff") else ""
                raise ValueError(f"{name} must be finite and >= 0{none}, got {v!r}")
        if self.max_steps is not None and (whole_number(self.max_steps) is None or self.max_steps < 1):
            raise ValueError(f"max_steps must be an int >= 1 or None, got {self.max_steps!r}")


def closing_steps(hand, timestep: float) -> int:
    """The steps of ``timestep`` (s) in ``hand``'s closing time, ``hand.max_steps`` steps of ``hand.timestep``
    (:attr:`MujocoConfig.max_steps` None): the hand's own count at its own timestep, at least 1."""
    return max(1, int(round(hand.max_steps * hand.timestep / timestep)))


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=np.float64).ravel())
    return q


def _tip_site_auto(model: mujoco.MjModel, body_id: int) -> tuple[np.ndarray, float]:
    """Centre and radius of the distal end cap of a body's collision geometry (body frame)."""
    gids = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body_id
            and (model.geom_contype[g] or model.geom_conaffinity[g])]
    if not gids:
        raise ValueError(f"fingertip body {model.body(body_id).name!r} has no collision geoms")
    corners = []
    for g in gids:
        c, h = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        local = c + signs * h
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, model.geom_quat[g])
        corners.append(local @ R.reshape(3, 3).T + model.geom_pos[g])
    pts = np.concatenate(corners)
    lo, hi = pts.min(0), pts.max(0)
    reach = np.maximum(np.abs(lo), np.abs(hi))
    k = int(np.argmax(reach))
    others = [i for i in range(3) if i != k]
    r = float(0.5 * min(hi[others] - lo[others]))
    centre = 0.5 * (lo + hi)
    far = hi[k] if abs(hi[k]) >= abs(lo[k]) else lo[k]
    centre[k] = far - np.sign(far) * r
    return centre, r


def servo_equilibrium(gaintype, biastype, gain, b0, b1) -> tuple[np.ndarray, np.ndarray]:
    """``(ctrl_per_length, ctrl_offset)`` of actuators (arrays, or scalars of one ``MjsActuator``) by their gain and
    bias types and ``gainprm[0]``, ``biasprm[0]``, ``biasprm[1]``: a position-like actuator (fixed gain > 0, affine
    bias with ``biasprm[1] < 0``) holds ``ctrl = ctrl_per_length * length + ctrl_offset`` at rest, from
    ``gain * ctrl + b0 + b1 * length = 0``; NaN for any other (a motor's control is a force)."""
    gain, b0, b1 = (np.asarray(x, dtype=np.float64) for x in (gain, b0, b1))
    position_like = ((np.asarray(gaintype) == mujoco.mjtGain.mjGAIN_FIXED)
                     & (np.asarray(biastype) == mujoco.mjtBias.mjBIAS_AFFINE) & (gain > 0) & (b1 < 0))
    safe_gain = np.where(position_like, gain, 1.0)
    return np.where(position_like, -b1 / safe_gain, np.nan), np.where(position_like, -b0 / safe_gain, np.nan)


class GraspScene:
    """Simulator wrapper: object + hand on a mocap mount. Physics only, no task logic."""

    def __init__(self, hand: HandDescription, pieces: list | None, pose: np.ndarray, *, table_z: float | None,
                 timestep: float, friction: float, joint_frictionloss: float | None = 0.0,
                 solver: str | None = None, solid_table: bool) -> None:
        # timestep, friction, solid_table: MujocoConfig's (the one default of each; solid_table resolved)
        self.hand = hand
        spec = mujoco.MjSpec()
        spec.modelname = "grasp_scene"
        spec.option.timestep = timestep
        spec.option.gravity = [0.0, 0.0, 0.0]
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        for k, v in hand.option.items():
            setattr(spec.option, k, v)
        if solver is not None:  # the config's choice wins over the hand's
            spec.option.solver = SOLVERS[solver]
        spec.visual.global_.offwidth = 1280
        spec.visual.global_.offheight = 1280
        spec.worldbody.add_light(pos=[0, 0, 2], dir=[0, 0, -1], diffuse=[0.8, 0.8, 0.8])
        if table_z is not None:  # solid: it collides with the hand (as the object does), never with the object
            solid = dict(contype=OBJ_BITS[0], conaffinity=OBJ_BITS[1], friction=[friction, 0.005, 1e-4], condim=3)
            spec.worldbody.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.01],
                                    pos=[0, 0, table_z - 1e-4], rgba=[0.6, 0.55, 0.5, 1],
                                    **(solid if solid_table else dict(contype=0, conaffinity=0)))
        # object: static body at the pose, one mesh geom per convex piece
        obj_body = spec.worldbody.add_body(name="object", pos=pose[:3, 3], quat=quat_from_matrix(pose[:3, :3]))
        self.object_geom_names: list[str] = []
        for i, piece in enumerate(pieces or []):
            spec.add_mesh(name=f"obj_piece{i}", uservert=np.asarray(piece.vertices, dtype=np.float32).ravel(),
                          userface=np.asarray(piece.faces, dtype=np.int32).ravel())
            obj_body.add_geom(name=f"obj{i}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"obj_piece{i}",
                              contype=OBJ_BITS[0], conaffinity=OBJ_BITS[1], friction=[friction, 0.005, 1e-4],
                              rgba=[0.2, 0.5, 0.8, 1], condim=3)
            self.object_geom_names.append(f"obj{i}")
        # hand: fingertip sites, collision bits, attached under a mocap mount
        hspec = hand.spec.copy()
        if hand.tip_sites is None:
            hm = hspec.compile()
            sites = tuple(_tip_site_auto(hm, hm.body(t).id) for t in hand.tips)
        else:
            sites = hand.tip_sites
        self.tip_radius = np.array([r for _, r in sites])
        for i, (t, (pos, r)) in enumerate(zip(hand.tips, sites)):
            hspec.body(t).add_site(name=f"tipsite{i}", pos=np.asarray(pos, dtype=np.float64), size=[r, 0, 0],
                                   rgba=[0, 1, 0, 0.5])
        if joint_frictionloss is not None:  # dry joint friction is invisible to the torque-based estimate
            for j in hspec.joints:
                j.frictionloss = joint_frictionloss
        for g in hspec.geoms:
            if g.contype or g.conaffinity:
                g.contype, g.conaffinity = HAND_BITS
                g.friction = [friction, 0.005, 1e-4]
        # the scene's options win on attach anyway (hand.option carries what the hand needs); copying
        # them into the hand spec first avoids MuJoCo's "attach conflict" warning for hands whose MJCF
        # sets its own <option> (e.g. the Aero hand's timestep/integrator/iterations)
        for k in ("timestep", "integrator", "iterations", "ls_iterations", "cone", "impratio", "jacobian",
                  "solver", "tolerance", "ls_tolerance", "noslip_iterations", "noslip_tolerance",
                  "ccd_iterations", "ccd_tolerance", "disableflags", "enableflags", "gravity"):
            setattr(hspec.option, k, getattr(spec.option, k))
        mount = spec.worldbody.add_body(name="mount", mocap=True)
        mount.add_frame().attach_body(hspec.body(hand.root), "hand/", "")
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.site_ids = np.array([m.site(f"hand/tipsite{i}").id for i in range(len(hand.tips))])
        self.tip_body_ids = np.array([m.body(f"hand/{t}").id for t in hand.tips])
        self.obj_geom_ids = np.array([m.geom(n).id for n in self.object_geom_names], dtype=np.int64)
        self.obj_body_id = m.body("object").id
        self._table_geom = m.geom("table").id if table_z is not None else -1
        # which tip body each body's geoms count for (only the tip body itself)
        self._geom_tip = np.full(m.ngeom, -1)
        for i, b in enumerate(self.tip_body_ids):
            self._geom_tip[m.geom_bodyid == b] = i
        self._is_obj_geom = np.zeros(m.ngeom, dtype=bool)
        self._is_obj_geom[self.obj_geom_ids] = True
        self._tip_pairs = self._pair_owner(self._geom_tip)  # contact geom pair -> fingertip touching the object
        self._blocks_hand = self._is_obj_geom.copy()  # what the pre-grasp pose must be free of
        if solid_table and self._table_geom >= 0:
            self._blocks_hand[self._table_geom] = True
        act_names = [m.actuator(i).name for i in range(m.nu)]
        self.act_index = {n.removeprefix("hand/"): i for i, n in enumerate(act_names)}
        for d in (hand.open_ctrl, hand.close_ctrl, hand.spread):
            bad = [k for k in d if k not in self.act_index]
            if bad:
                raise ValueError(f"hand {hand.name!r}: unknown actuators {bad} (have {list(self.act_index)})")
        # what the squeeze at a finger's first touch moves: its closing actuators, not those that hold a spread or
        # the automatic path's neutral pose (hold_fingers)
        self.squeezed = np.zeros(m.nu, dtype=bool)
        self.squeezed[[self.act_index[k] for k in hand.close_ctrl if k not in hand.spread]] = True
        self.ctrl_lo = m.actuator_ctrlrange[:, 0].copy()
        self.ctrl_hi = m.actuator_ctrlrange[:, 1].copy()
        limited = m.actuator_ctrllimited.astype(bool)
        self.ctrl_lo[~limited], self.ctrl_hi[~limited] = -np.inf, np.inf
        one_dof = (m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE) | (m.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE)
        self._limited_1dof = np.flatnonzero(one_dof & m.jnt_limited.astype(bool))
        # finger of each actuator (via its joint or its tendon's first joint), -1 for none (e.g. wrist)
        body_finger = finger_of_bodies(m, self.tip_body_ids)  # closed linkages join the finger they connect to
        self._geom_finger = body_finger[m.geom_bodyid]  # finger of every geom (any link), -1 palm/none
        self._finger_pairs = self._pair_owner(self._geom_finger)
        if self._table_geom >= 0:  # contact geom pair -> finger touching the table
            table = np.zeros(m.ngeom, dtype=bool)
            table[self._table_geom] = True
            self._table_pairs = self._pair_owner(self._geom_finger, table)
        # fingers each actuator moves: the dofs its transmission acts on (moment arms at qpos0; works
        # for joint, fixed- and spatial-tendon actuators alike). act_fingers[a, i]: actuator a moves
        # finger i; act_finger[a]: its finger when it moves exactly one, else -1 (none, or several as
        # the single actuator of a parallel gripper). moment_scale[a] = max |d length / d q| (length
        # units per radian), ctrl_per_length[a]: ctrl units per length unit (position-like actuators).
        mujoco.mj_forward(m, self.data)
        moment = np.zeros((m.nu, m.nv))
        d0 = self.data
        for a in range(m.nu):
            adr, nnz = d0.moment_rowadr[a], d0.moment_rownnz[a]
            moment[a, d0.moment_colind[adr: adr + nnz]] = d0.actuator_moment[adr: adr + nnz]
        dof_finger = body_finger[m.dof_bodyid]
        n_tips = len(hand.tips)
        self.act_fingers = np.zeros((m.nu, n_tips), dtype=bool)
        for a in range(m.nu):
            f = dof_finger[np.abs(moment[a]) > 1e-9]
            self.act_fingers[a, f[f >= 0]] = True
        self.act_finger = np.where(self.act_fingers.sum(1) == 1, np.argmax(self.act_fingers, axis=1), -1)
        self.act_joint = np.where(m.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT, m.actuator_trnid[:, 0], -1)
        self.moment_scale = np.maximum(np.abs(moment).max(axis=1), 1e-12)
        self.ctrl_per_length, self.ctrl_offset = servo_equilibrium(
            m.actuator_gaintype, m.actuator_biastype, m.actuator_gainprm[:, 0], m.actuator_biasprm[:, 0],
            m.actuator_biasprm[:, 1])
        # reset's joints: those a position-like actuator (finite ctrl_per_length, nonzero gear) drives directly, each
        # set by the last such actuator of it (as a loop over the actuators would), with its limits
        servo = np.flatnonzero((self.act_joint >= 0) & np.isfinite(self.ctrl_per_length) & (m.actuator_gear[:, 0] != 0))
        joint = self.act_joint[servo]
        last = np.array([i for i in range(len(servo)) if joint[i] not in joint[i + 1:]], dtype=np.int64)
        servo, joint = servo[last], joint[last]
        limited = m.jnt_limited[joint].astype(bool)
        self._servo = (servo, m.jnt_qposadr[joint], m.actuator_gear[servo, 0].copy(),
                       np.where(limited, m.jnt_range[joint, 0], -np.inf),
                       np.where(limited, m.jnt_range[joint, 1], np.inf))
        mujoco.mj_resetData(m, self.data)
        self.step_time = 0.0  # seconds spent inside mj_step
        self.steps = 0
        self._renderer = None

    # ------------------------------------------------------------------ physics operations
    def ctrl_vector(self, values: dict[str, float], base: np.ndarray | None = None) -> np.ndarray:
        u = np.zeros(self.model.nu) if base is None else base.copy()
        for k, v in values.items():
            u[self.act_index[k]] = v
        return np.clip(u, self.ctrl_lo, self.ctrl_hi)

    def scale_object(self, scale: float) -> None:
        """Scale the object's collision meshes uniformly about the object body's origin, in the compiled model
        (vertices in each mesh's frame, the mesh frames' offsets, the broad-phase bounds), without recompiling."""
        m = self.model
        if not hasattr(self, "_unscaled"):
            mids = m.geom_dataid[self.obj_geom_ids]
            verts = [slice(m.mesh_vertadr[i], m.mesh_vertadr[i] + m.mesh_vertnum[i]) for i in mids]
            # the bounding-volume trees too: the object body's (the midphase picks the pieces to collide with it,
            # body frame) and each mesh's (mesh frame); left unscaled, touches outside the unscaled boxes were missed
            b = self.obj_body_id
            bvh = np.concatenate([np.arange(m.body_bvhadr[b], m.body_bvhadr[b] + m.body_bvhnum[b])]
                                 + [np.arange(m.mesh_bvhadr[i], m.mesh_bvhadr[i] + m.mesh_bvhnum[i]) for i in mids
                                    if m.mesh_bvhadr[i] >= 0]).astype(np.int64)
            self._unscaled = (verts, [m.mesh_vert[v].copy() for v in verts], m.geom_pos[self.obj_geom_ids].copy(),
                              m.geom_rbound[self.obj_geom_ids].copy(), m.geom_aabb[self.obj_geom_ids].copy(),
                              bvh, m.bvh_aabb[bvh].copy(), m.geom_size[self.obj_geom_ids].copy(),
                              (m.body_ipos[b].copy(), float(m.body_mass[b]), m.body_inertia[b].copy()), 1.0)
        verts, vert0, pos0, rb0, aabb0, bvh, bvh0, size0, (ipos0, mass0, inertia0), current = self._unscaled
        if scale == current:
            return
        for v, v0 in zip(verts, vert0):
            m.mesh_vert[v] = scale * v0
        g = self.obj_geom_ids
        m.geom_pos[g], m.geom_rbound[g], m.geom_aabb[g] = scale * pos0, scale * rb0, scale * aabb0
        m.geom_size[g] = scale * size0  # a mesh geom's size: its box's half-extents
        b = self.obj_body_id  # its inertial frame, which its bounding-volume tree is kept in (mass: a solid's)
        m.body_ipos[b], m.body_mass[b], m.body_inertia[b] = scale * ipos0, scale**3 * mass0, scale**5 * inertia0
        m.bvh_aabb[bvh] = scale * bvh0  # (centre, half-size) rows, both scale about the frame's origin
        if self._renderer is not None:  # it uploaded the meshes at their old size
            self._renderer.close()
            self._renderer = None
        self._unscaled = (*self._unscaled[:9], scale)

    def place_object(self, pose: np.ndarray, table_z: float | None) -> None:
        """Move the (static) object body to ``pose`` and the table plane (visual, or solid with ``solid_table``) to
        ``table_z``, without recompiling: the model's body pose is read by the next kinematics pass."""
        m = self.model
        m.body_pos[self.obj_body_id] = pose[:3, 3]
        m.body_quat[self.obj_body_id] = quat_from_matrix(pose[:3, :3])
        if self._table_geom >= 0 and table_z is not None:
            m.geom_pos[self._table_geom, 2] = table_z - 1e-4

    def reset(self, ctrl: np.ndarray) -> None:
        """Zero state, joints set where a position-like actuator drives one joint directly: to the angle it holds
        for ``ctrl`` (``(ctrl - offset) / ctrl_per_length`` of actuator length, over the gear; ``ctrl`` itself for a
        position servo of gear 1). A motor's control is a force, not an angle: its joint keeps its rest angle."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.ctrl[:] = ctrl
        a, adr, gear, lo, hi = self._servo
        d.qpos[adr] = np.clip((d.ctrl[a] - self.ctrl_offset[a]) / self.ctrl_per_length[a] / gear, lo, hi)

    def export_spec(self, keys: dict[str, dict[str, np.ndarray]] | None = None) -> mujoco.MjSpec:
        """A copy of the scene as an ``MjSpec`` (``.to_xml()`` for MuJoCo's viewer): the object where
        :meth:`place_object` and :meth:`scale_object` put it, and a keyframe per entry of ``keys``
        (name -> ``qpos``, ``ctrl``, ``mpos``, ``mquat`` arrays of this model's sizes). Compiled once, so a bad
        keyframe raises here. The hand's mesh and texture files are referenced by absolute path, so the file
        written by ``to_xml`` opens from any folder."""
        m = self.model
        spec = self.spec.copy()
        home = Path(self.hand.spec.modelfiledir or ".")
        for items, sub in ((spec.meshes, self.hand.spec.meshdir), (spec.textures, self.hand.spec.texturedir)):
            for item in items:
                if item.file and not Path(item.file).is_absolute():
                    item.file = str((home / (sub or "") / item.file).resolve())
        body = spec.body("object")
        body.pos, body.quat = m.body_pos[self.obj_body_id].copy(), m.body_quat[self.obj_body_id].copy()
        scale = self._unscaled[-1] if hasattr(self, "_unscaled") else 1.0
        for i in range(len(self.object_geom_names)):
            spec.mesh(f"obj_piece{i}").scale = [scale] * 3
        if self._table_geom >= 0:
            spec.geom("table").pos = m.geom_pos[self._table_geom].copy()
        for name, key in (keys or {}).items():
            spec.add_key(name=name, **{k: np.asarray(v, dtype=np.float64).ravel() for k, v in key.items()})
        spec.compile()
        return spec

    def set_mount(self, pos: np.ndarray, R: np.ndarray) -> None:
        self.data.mocap_pos[0] = pos
        self.data.mocap_quat[0] = quat_from_matrix(R)

    def hand_blocking_contacts(self) -> int:
        """Run kinematics + collision only and count the hand's contacts with the object (and with the table where it
        is solid): the pre-grasp search's test of a pose."""
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        if d.ncon == 0:
            return 0
        g = d.contact.geom[: d.ncon]
        return int(np.count_nonzero(self._blocks_hand[g[:, 0]] ^ self._blocks_hand[g[:, 1]]))

    def step(self, n: int) -> None:
        t = time.perf_counter()
        mujoco.mj_step(self.model, self.data, nstep=n)
        self.step_time += time.perf_counter() - t
        self.steps += n

    def hold_fingers(self, fingers: np.ndarray, close_u: np.ndarray, squeeze: float,
                     held: np.ndarray | None = None) -> None:
        """Stop closing the given fingers: targets = current actuator length + ``squeeze`` (rad, scaled
        to the actuator's length units by its largest moment arm) towards the closing target (a light,
        constant squeeze instead of driving to full closure). An actuator that moves several fingers
        (a gripper's single motor) is held only once all of them are in ``fingers`` or ``held`` (bool
        mask). Actuators that are not position-like keep closing.

        Only the closing actuators take the squeeze (``squeezed``: those in the hand's ``close_ctrl`` and not in its
        ``spread``); its spread actuators and those the automatic path holds at neutral keep their targets. Until the
        fiftieth session (2026-12-07) every position-like actuator of the finger took it, each ``squeeze`` past its
        current length in the direction of its residual, for an actuator already at its target numerical noise: the
        spread joints and neutral-held joints ended a median 0.14 rad off the pose they were said to hold (RESULTS.md,
        "The squeeze at first touch turns the spread joints too")."""
        d = self.data
        new = np.zeros(self.act_fingers.shape[1], dtype=bool)
        new[np.asarray(fingers, dtype=np.int64)] = True
        done = new if held is None else new | held
        sel = (self.act_fingers[:, new].any(axis=1) & ~(self.act_fingers & ~done).any(axis=1)
               & np.isfinite(self.ctrl_per_length) & self.squeezed)
        if not sel.any():
            return
        k, c0 = self.ctrl_per_length[sel], self.ctrl_offset[sel]
        length = d.actuator_length[sel]
        direction = np.sign((close_u[sel] - c0) / k - length)
        target = length + squeeze * self.moment_scale[sel] * direction
        d.ctrl[sel] = np.clip(k * target + c0, self.ctrl_lo[sel], self.ctrl_hi[sel])

    def tip_positions(self) -> np.ndarray:
        return self.data.site_xpos[self.site_ids].copy()

    def _pair_owner(self, per_geom: np.ndarray, other: np.ndarray | None = None) -> np.ndarray:
        """``(ngeom, ngeom)`` table: for a contact between geoms ``(g0, g1)``, ``per_geom`` of its hand geom (a
        finger index) when exactly one of the two is an ``other`` geom (a mask; None: the object's geoms), else -1
        (:meth:`_object_contacts` reads it)."""
        obj = self._is_obj_geom if other is None else other
        per = np.asarray(per_geom, dtype=np.int16)  # finger indices (a scene keeps two tables of ngeom^2 entries)
        return np.where(obj[:, None] & ~obj[None, :], per[None, :],
                        np.where(obj[None, :] & ~obj[:, None], per[:, None], np.int16(-1)))

    def _object_contacts(self, pairs: np.ndarray) -> np.ndarray:
        """For each current contact: the finger index that ``pairs`` (a :meth:`_pair_owner` table) gives its
        geom pair where it is a touching (``dist <= 0``) hand-object contact (hand-table with the table's
        pairs), else -1."""
        c = self.data.contact
        n = self.data.ncon
        geom = c.geom[:n]
        owner = pairs[geom[:, 0], geom[:, 1]]
        return np.where(c.dist[:n] <= 0, owner, -1)

    def tip_touched(self) -> np.ndarray:
        """``(n,)`` bool: fingertip ``i`` touches the object (``tip_contacts()[0]`` without the points and
        normals; the closing loop asks this every check interval)."""
        touched = np.zeros(len(self.site_ids), dtype=bool)
        if self.data.ncon:
            finger = self._object_contacts(self._tip_pairs)
            touched[finger[finger >= 0]] = True
        return touched

    def tip_contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per finger: touched (n,) bool, mean contact point (n,3), mean INWARD contact normal (n,3)."""
        d = self.data
        n = len(self.site_ids)
        touched = np.zeros(n, dtype=bool)
        pts, nrm = np.zeros((n, 3)), np.zeros((n, 3))
        if d.ncon:
            finger = self._object_contacts(self._tip_pairs)
            obj0 = self._is_obj_geom[d.contact.geom[: d.ncon, 0]]  # then the normal points from the object
            frame = d.contact.frame[: d.ncon, :3]  # normal points from geom[0] to geom[1]
            pos = d.contact.pos[: d.ncon]
            inward = np.where(obj0[:, None], -frame, frame)  # from finger into the object
            for i in np.unique(finger[finger >= 0]):
                sel = finger == i
                touched[i] = True
                pts[i] = pos[sel].mean(0)
                v = inward[sel].sum(0)
                nrm[i] = v / max(np.linalg.norm(v), 1e-12)
        return touched, pts, nrm

    def finger_link_contacts(self, exclude_tip: bool = False) -> np.ndarray:
        """(n,) bool: any link of finger i (tip included unless ``exclude_tip``) touches the object."""
        out = np.zeros(len(self.site_ids), dtype=bool)
        if self.data.ncon:
            f = self._object_contacts(self._finger_pairs)
            keep = f >= 0
            if exclude_tip:
                keep &= self._object_contacts(self._tip_pairs) < 0
            out[np.unique(f[keep])] = True
        return out

    def finger_table_contacts(self) -> np.ndarray:
        """(n,) bool: any link of finger i (the tip included) touches the table (a solid one: a visual table
        collides with nothing). Its push enters the finger's joint torques, so the finger's torque normal is biased,
        as by a link's contact with the object."""
        out = np.zeros(len(self.site_ids), dtype=bool)
        if self.data.ncon and self._table_geom >= 0:
            f = self._object_contacts(self._table_pairs)
            out[np.unique(f[f >= 0])] = True
        return out

    def sensed_torque(self, source: str) -> np.ndarray:
        d = self.data
        if source == "constraint":
            return d.qfrc_constraint.copy()
        return -(d.qfrc_actuator + d.qfrc_passive - d.qfrc_bias)

    def dofs_at_limit(self, tol: float = 0.01, slide_tol: float = 5e-4) -> np.ndarray:
        """(nv,) bool: hinge dofs within ``tol`` (rad) and slide dofs within ``slide_tol`` (m) of (or beyond) a
        joint limit. The slide's own tolerance is about what 0.01 rad moves a 5 cm link's tip (the hinge tolerance
        in metres was 1 cm, a quarter of a gripper's stroke: a free slide dof was dropped from the normal estimate)."""
        m, d = self.model, self.data
        out = np.zeros(m.nv, dtype=bool)
        lim = self._limited_1dof
        q = d.qpos[m.jnt_qposadr[lim]]
        lo, hi = m.jnt_range[lim, 0], m.jnt_range[lim, 1]
        t = np.where(m.jnt_type[lim] == mujoco.mjtJoint.mjJNT_SLIDE, slide_tol, tol)
        out[m.jnt_dofadr[lim]] = (q <= lo + t) | (q >= hi - t)
        return out

    def equality_jacobian(self) -> np.ndarray:
        """(k, nv) Jacobian rows of the active equality constraints (coupled joints, closed linkages)
        after ``mj_forward``. Their forces are internal to the hand and unknown to a torque sensor,
        so the normal estimate solves for them alongside the fingertip forces."""
        m, d = self.model, self.data
        if d.nefc == 0:
            return np.zeros((0, m.nv))
        rows = np.flatnonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        if len(rows) == 0:
            return np.zeros((0, m.nv))
        if mujoco.mj_isSparse(m):
            J = np.zeros((d.nefc, m.nv))
            mujoco.mju_sparse2dense(J, d.efc_J, d.efc_J_rownnz[: d.nefc], d.efc_J_rowadr[: d.nefc],
                                    d.efc_J_colind)
        else:
            J = d.efc_J[: d.nefc * m.nv].reshape(d.nefc, m.nv)
        return J[rows].copy()

    def site_jacobians(self, fingers: np.ndarray) -> np.ndarray:
        """(3 m, nv) stacked fingertip-site position Jacobians of the given fingers."""
        m, d = self.model, self.data
        J = np.zeros((3 * len(fingers), m.nv))
        for k, i in enumerate(fingers):
            mujoco.mj_jacSite(m, d, J[3 * k: 3 * k + 3], None, int(self.site_ids[i]))
        return J

    def render(self, width: int, height: int, lookat: np.ndarray, distance: float) -> np.ndarray:
        if self._renderer is None or (self._renderer.width, self._renderer.height) != (width, height):
            if self._renderer is not None:
                self._renderer.close()
            try:
                self._renderer = mujoco.Renderer(self.model, height=height, width=width)
            except Exception as exc:  # no usable GL platform (mujoco.FatalError, ImportError, ...)
                raise RuntimeError(
                    f"no OpenGL backend for offscreen rendering (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}: "
                    f"{exc}). Headless: set MUJOCO_GL=egl (libegl1) or osmesa (libosmesa6) before importing mujoco "
                    "(the library leaves the process environment alone; haptic-recog and the tests set egl)."
                ) from exc
        cam = mujoco.MjvCamera()
        cam.lookat[:] = lookat
        cam.distance = distance
        cam.azimuth, cam.elevation = 135.0, -25.0
        mujoco.mj_forward(self.model, self.data)
        self._renderer.update_scene(self.data, camera=cam)
        return self._renderer.render().copy()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


class MujocoBackend:
    """Physics grasps (see module docstring). ``set_object`` builds the scene (convex decomposition
    cached on disk); ``grasp(action, rng)`` runs one grasp from a fresh reset."""

    action_dim = ACTION_DIM

    def __init__(self, config: MujocoConfig | None = None) -> None:
        self.config = config or MujocoConfig()
        self.hand = load_hand(self.config.hand, self.config.n_fingers, **dict(self.config.hand_kwargs))
        self.n_fingers = self.hand.n_fingers
        self.scene: GraspScene | None = None
        self._scenes: OrderedDict[tuple[str, str], GraspScene] = OrderedDict()  # LRU, at most MAX_SCENES
        self._calibrated: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.grasp_time = 0.0
        self.n_grasps = 0
        self._step_time = 0.0  # seconds inside mj_step over this backend's grasps, whichever object's scene ran them
        self._steps = 0

    # ------------------------------------------------------------------ scene
    #: ``set_object(..., scale=s)`` scales the object about its origin without a mesh copy (the env's ``scale_range``)
    supports_scale = True

    def set_object(self, obj: Any, pose: np.ndarray | None = None, scale: float = 1.0) -> None:
        mesh, T, scale = placement(obj, pose, scale)
        v = scale * np.asarray(mesh.vertices, dtype=np.float64)
        vw = v @ T[:3, :3].T + T[:3, 3]
        c_obj = 0.5 * (v.min(0) + v.max(0))
        self._centre = T[:3, :3] @ c_obj + T[:3, 3]
        self._radius = float(np.linalg.norm(vw - self._centre, axis=1).max())
        table_z = support_height(mesh.vertices, T, scale) if self.config.support == "table" else None
        key = (obj.name, obj.mesh_hash)  # one compiled scene per mesh: a new pose or scale only edits the model
        scene = self._scenes.pop(key, None)
        if scene is None:
            pieces = convex_pieces(obj, self.config.collision)  # of the unscaled mesh: cached once per mesh
            scene = GraspScene(self.hand, pieces, T, table_z=table_z, timestep=self.config.timestep or self.hand.timestep,
                               friction=self.config.friction, joint_frictionloss=self.config.joint_frictionloss,
                               solver=self.config.solver, solid_table=self.config.table_is_solid)
            while len(self._scenes) >= MAX_SCENES:  # least recently used first
                self._scenes.popitem(last=False)[1].close()
        scene.scale_object(scale)
        scene.place_object(T, table_z)
        self._scenes[key] = scene
        self.scene = scene
        self.obj = obj
        self._hull_vw = scale * np.asarray(mesh.convex_hull.vertices) @ T[:3, :3].T + T[:3, 3]
        if self._calibrated is None:
            self._calibrated = self._calibrate()

    def _require(self) -> GraspScene:
        if self.scene is None:
            raise RuntimeError("call set_object(obj, pose) before grasping")
        return self.scene

    def _ctrls(self, spread: float) -> tuple[np.ndarray, np.ndarray]:
        sc, h = self._require(), self.hand
        sp = {k: lo + spread * (hi - lo) for k, (lo, hi) in h.spread.items()}
        base = sc.ctrl_vector({})
        open_u = sc.ctrl_vector({**h.open_ctrl, **sp}, base)
        close_u = sc.ctrl_vector({**h.close_ctrl, **sp}, open_u)
        return open_u, close_u

    def _calibrate(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hand frame in the mount frame: approach axis n, thumb axis t, grasp centre g (closed fingertips)."""
        sc, h = self._require(), self.hand
        far = np.array([0.0, 0.0, 1e3])  # far away from the object: closes freely
        open_u, close_u = self._ctrls(0.5)
        sc.reset(open_u)
        sc.set_mount(far, np.eye(3))
        mujoco.mj_forward(sc.model, sc.data)
        p_open = sc.tip_positions() - far
        sc.data.ctrl[:] = close_u
        mujoco.mj_step(sc.model, sc.data, nstep=400)
        p_closed = sc.tip_positions() - far
        g = p_closed.mean(0)
        if h.approach_axis is not None:
            n = np.asarray(h.approach_axis, dtype=np.float64)
        else:
            warnings.warn(f"hand {h.name!r} has no approach_axis: estimated from the closing motion, which can miss "
                          "the object; give it (mjcf_hand(..., approach_axis=...)) or let mjcf_hand find it (no "
                          "close_ctrl)", UserWarning, stacklevel=2)
            a = p_open[:-1].mean(0)
            a /= np.linalg.norm(a)
            b = p_closed.mean(0) - p_open.mean(0)
            b -= (b @ a) * a
            n = b / np.linalg.norm(b) if np.linalg.norm(b) > 1e-6 else a
        n = n / np.linalg.norm(n)
        if h.thumb_axis is not None:
            t = np.asarray(h.thumb_axis, dtype=np.float64)
        else:
            t = p_closed[-1] - g
        t = t - (t @ n) * n
        if np.linalg.norm(t) < 1e-9:
            t = np.cross(n, [1.0, 0, 0]) if abs(n[0]) < 0.9 else np.cross(n, [0, 1.0, 0])
        t /= np.linalg.norm(t)
        return n, t, g

    # ------------------------------------------------------------------ grasps
    def grasp(self, action: np.ndarray, rng: np.random.Generator) -> GraspResult:
        a = validate_action(action, self.action_dim)
        sc = self._require()
        cfg = self.config
        t0 = time.perf_counter()
        ap = decode_approach(a, cfg.support)
        F = approach_frame(ap)  # columns e1 (thumb), e2, e3 (into the object)
        n, t, g = self._calibrated
        B = np.stack([t, np.cross(n, t), n], axis=1)
        R = F @ B.T  # mount rotation: n -> e3, t -> e1
        u = -F[:, 2]
        open_u, close_u = self._ctrls(float(ap.spread))
        sc.reset(open_u)
        step_time0, steps0 = sc.step_time, sc.steps
        # pre-grasp: grasp centre on the approach axis, as close to the object as collision-free
        s_max = float(np.max(self._hull_vw @ u - self._centre @ u)) + 0.3
        # start with the palm (the mount) no further in than the object's centre: a hand whose closed fingertips
        # meet behind its palm (g . n < 0) would otherwise start past a small object, free, facing away from it
        start = max(0.0, -float(g @ n))
        s, free = start, False
        while s <= s_max:
            sc.set_mount(self._centre + s * u - R @ g, R)
            if sc.hand_blocking_contacts() == 0:
                free = True
                break
            s += cfg.march_step
        if free and s > start:  # refine between the last colliding and the first free position
            lo, hi = s - cfg.march_step, s
            for _ in range(4):
                mid = 0.5 * (lo + hi)
                sc.set_mount(self._centre + mid * u - R @ g, R)
                if sc.hand_blocking_contacts() == 0:
                    hi = mid
                else:
                    lo = mid
            s = hi
        if free:
            standoff = self.hand.standoff if cfg.standoff is None else cfg.standoff
            sc.set_mount(self._centre + (s + standoff) * u - R @ g, R)
        sc.data.ctrl[:] = close_u
        mujoco.mj_forward(sc.model, sc.data)
        steps = 0
        held = np.zeros(self.n_fingers, dtype=bool)
        dt = sc.model.opt.timestep
        max_steps = cfg.max_steps or closing_steps(self.hand, dt)
        check_every, min_steps = max(1, round(cfg.check_interval / dt)), round(cfg.min_time / dt)
        was_still = False
        while steps < max_steps:
            k = min(check_every, max_steps - steps)
            sc.step(k)
            steps += k
            if cfg.squeeze > 0:  # a finger stops closing at its first fingertip contact
                touched = sc.tip_touched() & ~held
                if touched.any():
                    sc.hold_fingers(np.flatnonzero(touched), close_u, cfg.squeeze, held=held)
                    held |= touched
            still = steps >= min_steps and np.max(np.abs(sc.data.qvel)) < cfg.rest_qvel
            if still and was_still:
                break
            was_still = still
        res = self._read(rng, steps)
        self.grasp_time += time.perf_counter() - t0
        self.n_grasps += 1
        self._step_time += sc.step_time - step_time0
        self._steps += sc.steps - steps0
        return res

    def _read(self, rng: np.random.Generator, steps: int) -> GraspResult:
        sc, cfg = self._require(), self.config
        mujoco.mj_forward(sc.model, sc.data)  # consistent kinematics/forces at the final state
        nf = self.n_fingers
        touched, gt_pts, gt_n = sc.tip_contacts()
        sites = sc.tip_positions()
        est = np.zeros((nf, 3))
        idx = np.flatnonzero(touched)
        if len(idx):
            J = sc.site_jacobians(idx)  # (3m, nv)
            tau = sc.sensed_torque(cfg.torque_source)
            rows = ~sc.dofs_at_limit()  # a joint at its limit also carries an unknown limit reaction
            A = np.concatenate([J.T, sc.equality_jacobian().T], axis=1)  # + unknown equality forces
            x, *_ = np.linalg.lstsq(A[rows], tau[rows], rcond=None)
            f = x[: J.shape[0]].reshape(-1, 3)
            norm = np.linalg.norm(f, axis=1, keepdims=True)
            est[idx] = -f / np.maximum(norm, 1e-12)
            weak = norm[:, 0] < 1e-9  # no force sensed: fall back to the site-to-contact direction
            if weak.any():
                w = idx[weak]
                dvec = gt_pts[w] - sites[w]
                est[w] = dvec / np.maximum(np.linalg.norm(dvec, axis=1, keepdims=True), 1e-12)
        if cfg.normal_noise_deg > 0 and len(idx):
            g = rng.normal(0.0, np.deg2rad(cfg.normal_noise_deg), (len(idx), 3))
            g -= np.sum(g * est[idx], axis=1, keepdims=True) * est[idx]
            v = est[idx] + g
            est[idx] = v / np.linalg.norm(v, axis=1, keepdims=True)
        contacts = np.zeros((nf, 3))
        if cfg.contact_point == "surface":
            contacts[idx] = sites[idx] + sc.tip_radius[idx, None] * est[idx]
        else:
            contacts[idx] = sites[idx]
        if cfg.contact_noise > 0 and len(idx):
            contacts[idx] += rng.normal(0.0, cfg.contact_noise, (len(idx), 3))
        hand_q = sc.data.qpos.copy()
        return GraspResult(contacts=contacts, normals=est if cfg.normals else None, touched=touched,
                           joint_pos=hand_q, gt_normals=gt_n,
                           info={"steps": steps, "gt_contacts": gt_pts, "tip_sites": sites,
                                 # >= 3 fingertips touch (both for a 2-finger gripper)
                                 "usable": bool(usable_touch(touched)),
                                 # fingers touching with other links too: their torque normal is biased
                                 "link_contact": sc.finger_link_contacts(exclude_tip=True),
                                 # fingers pressing on the (solid) table: biased likewise
                                 "table_contact": sc.finger_table_contacts()})

    def scene_spec(self, action: np.ndarray, rng: np.random.Generator) -> tuple[mujoco.MjSpec, GraspResult]:
        """The current object's grasp scene as an ``MjSpec`` (``.to_xml()`` opens in MuJoCo's viewer), with the
        grasp along ``action`` as two keyframes: ``"approach"``, the open hand at its pre-grasp pose with the
        closing targets set (press play: it closes on the object; every finger closes to its target, without the
        backend's stop at the first fingertip contact), and ``"grasp"``, the state this backend read the grasp
        from (the returned result)."""
        a = validate_action(action, self.action_dim)
        res = self.grasp(a, rng)
        sc = self._require()
        d = sc.data
        mount = {"mpos": d.mocap_pos.copy(), "mquat": d.mocap_quat.copy()}
        grasp = {"qpos": d.qpos.copy(), "ctrl": d.ctrl.copy(), **mount}
        open_u, close_u = self._ctrls(float(decode_approach(a, self.config.support).spread))
        sc.reset(open_u)
        approach = {"qpos": d.qpos.copy(), "ctrl": close_u, **mount}
        return sc.export_spec({"approach": approach, "grasp": grasp}), res

    def grasp_batch(self, actions: np.ndarray, rng: np.random.Generator) -> GraspBatch:
        a = validate_actions(actions, self.action_dim)
        return GraspBatch.stack([self.grasp(x, rng) for x in a])

    # ------------------------------------------------------------------ stats / render
    @property
    def timing(self) -> dict[str, float]:
        """Backend time per grasp, raw mj_step time per grasp, and their ratio (>= 1), over the grasps since the
        last :meth:`reset_timing`, of every object (each object's scene counts its own steps)."""
        per = self.grasp_time / max(self.n_grasps, 1)
        step = self._step_time / max(self.n_grasps, 1)
        return {"grasps": self.n_grasps, "time_per_grasp": per, "step_time_per_grasp": step,
                "steps_per_grasp": self._steps / max(self.n_grasps, 1), "ratio": per / max(step, 1e-12)}

    def reset_timing(self) -> None:
        self.grasp_time, self.n_grasps, self._step_time, self._steps = 0.0, 0, 0.0, 0

    def render(self, width: int = 480, height: int = 480) -> np.ndarray:
        """(H, W, 3) uint8 offscreen render of the current scene (mujoco.Renderer; EGL/OSMesa)."""
        sc = self._require()
        return sc.render(width, height, self._centre, 4.0 * max(self._radius, 0.05))

    def close(self) -> None:
        for scene in self._scenes.values():
            scene.close()
        self._scenes.clear()
        if self.scene is not None:
            self.scene.close()
