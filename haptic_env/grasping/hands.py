"""Robot hands for the MuJoCo backend, each described as an :class:`HandDescription`.

* :func:`generic_hand` - an n-finger hand (n = 3..6) built with ``mujoco.MjSpec``: a disc palm
  (normal +z), fingers on a circle around it (a thumb at +x opposite n-1 fingers), each with a
  swivel joint (finger spread) and 3 flexion joints, capsule links, a sphere fingertip with a site,
  position actuators. No data files needed; the default.
* :func:`allegro_hand` / :func:`shadow_hand` - the Wonik Allegro (4 fingers) and Shadow E3M5
  (5 fingers) hands of MuJoCo Menagerie via the ``mujoco-menagerie`` package. Offline they load
  from ``$MENAGERIE_ROOT``; when that is unset and ``<data_dir>/menagerie`` exists it is used.
* :func:`aero_hand` - the TetherIA Aero Hand Open (5 tendon-driven fingers, 16 joints, 7 actuators:
  under-actuated like the Pisa/IIT SoftHand) and :func:`robotiq_hand` - the Robotiq 2F-85 parallel
  gripper (2 fingers, 1 actuator: the n = 2 case), from the same menagerie.
* :func:`mjcf_hand` - any MJCF hand (a file or a Menagerie name): fingertips, closing synergy, approach
  axis and physics options found automatically (:mod:`.auto_hand`), or given by hand.

Fingertip sites (the kinesthetic contact points) are added with MjSpec: at the centre of the
distal end cap of the fingertip body's collision geometry (auto-detected), radius = that cap's
radius. Fingertip order: fingers, thumb last.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import mujoco
import numpy as np

from haptic_env.numbers import finite_number, items, positive_number

__all__ = [
    "HandDescription",
    "HandUnavailableError",
    "generic_hand",
    "allegro_hand",
    "shadow_hand",
    "aero_hand",
    "robotiq_hand",
    "mjcf_hand",
    "load_hand",
    "HANDS",
]

HANDS = ("generic", "allegro", "shadow", "aero", "robotiq")


class HandUnavailableError(RuntimeError):
    """A hand model cannot be loaded: its menagerie data is missing and no download possible. (A hand whose files
    are there but do not load, e.g. after a MuJoCo upgrade, is a plain ``RuntimeError``: tests that skip on this
    error must not skip a broken hand.)"""


@dataclass
class HandDescription:
    """A hand ready to be mounted in a grasp scene.

    spec        the hand alone (an ``MjSpec``); ``root`` is its base body (attached to a mocap mount)
    tips        fingertip body names (thumb last); ``tip_sites[i] = (pos (3,) in the tip body, radius)``
    open_ctrl   actuator name -> control in the pre-grasp (open) pose
    close_ctrl  actuator name -> control target while closing
    spread      actuator name -> (ctrl at spread 0, ctrl at spread 1), held during the grasp (the squeeze at a
                finger's first touch moves the closing actuators only:
                :meth:`~haptic_env.grasping.mujoco_backend.GraspScene.hold_fingers`)
    approach_axis / thumb_axis (3,) in the mount frame, or None to calibrate them (see
                :class:`~haptic_env.grasping.mujoco_backend.GraspScene`)
    Actuators not named in any dict are held at 0 (clipped to their range).
    """

    name: str
    spec: mujoco.MjSpec
    root: str
    tips: tuple[str, ...]
    tip_sites: tuple[tuple[np.ndarray, float], ...] | None = None
    open_ctrl: dict[str, float] = field(default_factory=dict)
    close_ctrl: dict[str, float] = field(default_factory=dict)
    spread: dict[str, tuple[float, float]] = field(default_factory=dict)
    approach_axis: np.ndarray | None = None
    thumb_axis: np.ndarray | None = None
    option: dict[str, object] = field(default_factory=dict)  # e.g. {"cone": elliptic}
    timestep: float = 0.002  # s: the hand's physics step (``MujocoConfig.timestep=None`` uses it)
    max_steps: int = 200  # closing steps (of ``timestep``) after which the fingers have settled
    standoff: float = 0.02  # m: back-off from the closest collision-free pre-grasp pose before closing

    @property
    def n_fingers(self) -> int:
        return len(self.tips)


# --------------------------------------------------------------------------------------- generic
#: The generic hand's joint ranges (rad) of its three links per finger, base to tip.
_GENERIC_LINK_RANGES = ((-0.8, 1.6), (-0.2, 1.6), (-0.2, 1.6))


def generic_hand(n_fingers: int = 4, *, finger_length: float = 0.12, palm_radius: float = 0.045,
                 tip_radius: float = 0.01, kp: tuple[float, float, float] = (1.0, 1.0, 1.0),
                 close: tuple[float, float, float] = (1.6, 1.6, 1.6)) -> HandDescription:
    """An n-finger hand (3 <= n <= 6) built with MjSpec; palm normal +z, thumb towards +x."""
    if not (isinstance(n_fingers, (int, np.integer)) and 3 <= n_fingers <= 6):
        raise ValueError(f"the generic hand has 3..6 fingers, got n_fingers={n_fingers!r}")
    f = finite_number(finger_length)
    if f is None or not 0.03 <= f <= 0.4:
        raise ValueError(f"finger_length must be in [0.03, 0.4] m, got {finger_length!r}")
    for name, v, hi in (("palm_radius", palm_radius, 0.2), ("tip_radius", tip_radius, 0.05)):
        if not positive_number(v, name) <= hi:
            raise ValueError(f"{name} must be in (0, {hi}] m, got {v!r}")
    for name, v in (("kp", kp), ("close", close)):
        if len(items(v) or ()) != 3 or any(finite_number(x) is None for x in v):
            raise ValueError(f"{name} must be 3 finite numbers (one per finger link), got {v!r}")
    for k, x in enumerate(kp):
        positive_number(x, f"kp[{k}]")
    for k, (x, (lo, hi)) in enumerate(zip(close, _GENERIC_LINK_RANGES)):
        if not lo <= x <= hi:
            raise ValueError(f"close[{k}] must be within link {k}'s joint range [{lo}, {hi}] rad, got {x!r}")
    spec = mujoco.MjSpec()
    spec.modelname = f"generic_hand_{n_fingers}"
    spec.compiler.degree = False
    palm = spec.worldbody.add_body(name="palm")
    palm.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[palm_radius, 0.01, 0], pos=[0, 0, -0.01],
                  rgba=[0.3, 0.3, 0.35, 1], density=500)
    n = int(n_fingers)
    # fingers j = 0..n-2 evenly around pi, thumb (last) at angle 0
    angles = [np.pi + (j - (n - 2) / 2.0) * 2.0 * np.pi / n for j in range(n - 1)] + [0.0]
    lengths = np.array([0.42, 0.33, 0.25]) * finger_length
    cap_r = 0.8 * tip_radius
    base_r = 0.75 * palm_radius
    tips, open_ctrl, close_ctrl, spread = [], {}, {}, {}
    for i, a in enumerate(angles):
        f = f"f{i}"
        q = [np.cos(a / 2), 0, 0, np.sin(a / 2)]
        body = palm.add_body(name=f"{f}_base", pos=[base_r * np.cos(a), base_r * np.sin(a), 0.0], quat=q)
        body.add_joint(name=f"{f}_swivel", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1], range=[-0.6, 0.6],
                       damping=0.05, armature=0.002)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[cap_r, 0, 0], contype=0, conaffinity=0,
                      rgba=[0.3, 0.3, 0.35, 1], density=800)  # knuckle (mass for the swivel joint)
        parent = body
        ranges = [list(r) for r in _GENERIC_LINK_RANGES]
        for k, L in enumerate(lengths):
            link = parent.add_body(name=f"{f}_l{k}", pos=[0, 0, 0 if k == 0 else lengths[k - 1]])
            link.add_joint(name=f"{f}_j{k}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, -1, 0], range=ranges[k],
                           damping=0.05, armature=0.002)
            link.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0, 0, 0, L], size=[cap_r, 0, 0],
                          rgba=[0.8, 0.6, 0.4, 1], density=800)
            parent = link
        tip = parent.add_body(name=f"{f}_tip", pos=[0, 0, lengths[-1]])
        tip.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[tip_radius, 0, 0], rgba=[0.9, 0.3, 0.3, 1], density=800)
        tips.append(f"{f}_tip")
        for k in range(3):
            spec.add_actuator(name=f"{f}_a{k}", target=f"{f}_j{k}", trntype=mujoco.mjtTrn.mjTRN_JOINT,
                              ctrlrange=ranges[k]).set_to_position(kp=kp[k])
            close_ctrl[f"{f}_a{k}"] = close[k]
        open_ctrl[f"{f}_a0"] = -0.4
        spec.add_actuator(name=f"{f}_aswivel", target=f"{f}_swivel", trntype=mujoco.mjtTrn.mjTRN_JOINT,
                          ctrlrange=[-0.6, 0.6]).set_to_position(kp=kp[0])
        if i < n - 1:  # spread 0: fingers lean towards the middle one; spread 1: straight
            lean = 0.3 * (i - (n - 2) / 2.0)
            spread[f"{f}_aswivel"] = (float(np.clip(lean, -0.6, 0.6)), 0.0)
    return HandDescription(
        name=f"generic{n}", spec=spec, root="palm", tips=tuple(tips),
        tip_sites=tuple((np.zeros(3), tip_radius) for _ in tips),
        open_ctrl=open_ctrl, close_ctrl=close_ctrl, spread=spread,
        approach_axis=np.array([0.0, 0.0, 1.0]), thumb_axis=np.array([1.0, 0.0, 0.0]),
    )


# ------------------------------------------------------------------------------------- menagerie
def _menagerie_spec(robot: str, entry: str) -> mujoco.MjSpec:
    """``robot``'s MJCF ``entry`` through ``mujoco-menagerie``: from ``$MENAGERIE_ROOT`` if set, else from the data
    folder's ``menagerie/`` if it holds the robot (passed to the package, not put into the process environment), else
    as the package finds it (its cache, or a download)."""
    root = None
    if not os.environ.get("MENAGERIE_ROOT"):
        from ..objects import data_dir

        d = data_dir()
        if d is not None and (d / "menagerie" / robot).is_dir():
            root = d / "menagerie"
    local = Path(os.environ["MENAGERIE_ROOT"]).expanduser() if os.environ.get("MENAGERIE_ROOT") else root
    try:
        import mujoco_menagerie as mm

        return mm.get(robot).spec(entry, None if root is None else mm.Cache(root=root))
    except Exception as exc:  # missing data + no network, unknown robot, bad files ...
        if local is not None and (local / robot).is_dir():  # there, and it does not load: an error, not "absent"
            raise RuntimeError(f"MuJoCo Menagerie hand {robot!r}/{entry!r} is in {local / robot} but does not load "
                               f"({type(exc).__name__}: {exc})") from exc
        raise HandUnavailableError(
            f"cannot load MuJoCo Menagerie hand {robot!r}/{entry!r} ({type(exc).__name__}: {exc}). "
            f"Set MENAGERIE_ROOT to a menagerie folder containing {robot}/ (e.g. <data_dir>/menagerie), "
            "or allow mujoco-menagerie to download it.") from exc


def allegro_hand(side: str = "right") -> HandDescription:
    """Wonik Allegro V3 (4 fingers: ff, mf, rf, thumb on the right hand; the left hand's fingertips come in the
    automatic path's order, rf, mf, ff, thumb; 16 position actuators).

    The closing synergy, open pose, approach axis and standoff are the automatic path's
    (:func:`~haptic_env.grasping.auto_hand.auto_hand` on the Menagerie file), as for the Shadow: every
    flexion actuator closes to the top of its range and the thumb opposes, so fingers close until they
    touch. On 400 ycb10 approaches (one core; with the visual table of the scene before 2026-12-07) that gives
    complete 4-finger grasps on 0.40 of them against 0.26 for the earlier hand-written synergy (proximal joints
    stopped at 1.1 rad), and >= 3 fingertips on 0.75 against 0.65. Physics: a 4 ms step with the earlier
    description's 0.24 s of closing (60 steps; contacts checked every 20 ms) keeps those rates of the 2 ms step at
    1.4x its grasps/s (192 against 135 grasps/s; the earlier synergy at 2 ms: 157)."""
    if side not in ("right", "left"):
        raise ValueError(f"side must be 'right' or 'left', got {side!r}")
    from .auto_hand import auto_hand

    d = auto_hand(f"wonik_allegro/{side}_hand")
    out = replace(d, name=f"allegro_{side}", timestep=0.004, max_steps=60)
    out.auto = d.auto  # what auto_hand chose (report()), which replace does not copy
    return out


def shadow_hand(side: str = "right") -> HandDescription:
    """Shadow E3M5 (5 fingers: ff, mf, rf, lf, thumb; 20 actuators, coupled distal joints).

    The closing synergy, open pose, approach axis and standoff are the automatic path's
    (:func:`~haptic_env.grasping.auto_hand.auto_hand` on the Menagerie file): every flexion actuator closes
    to the top of its range and the thumb opposes, so fingers close until they touch. On 240 ycb10
    approaches (with the visual table of the scene before 2026-12-07) that gives complete 5-finger grasps on 0.54
    of them against 0.30 for the earlier hand-written synergy (flexion stopped at 1.3 / 2.2 rad), and >= 3
    fingertips on 0.85 against 0.75. On validation hand grasps (pool seeds 500-502, 3,000 training approaches per
    object) BC-NP without normals stops correct in 87.0 % of queries after 4.9 grasps, against 79-83 % after 8.1-8.4
    with the earlier synergy.

    Physics: a 4 ms step with 0.3 s of closing (75 steps; contacts checked every 20 ms): on 400 approaches
    a 4 ms step keeps the usable and complete rates and the contact error of 2 ms at about twice the
    grasps/s. Pyramidal friction cones would be faster still but lose complete grasps (0.26 vs 0.32 with the
    earlier synergy), and with them recognition (validation BC-NP 79 % in 10.8 grasps against 83 % in 8.3).
    The CG solver gives the same grasps as MuJoCo's default Newton at 1.3x the grasps/s (a Newton step
    factorises the Hessian of the hand's 24 dofs; ``benchmarks/bench_grasp_solver.py``)."""
    if side not in ("right", "left"):
        raise ValueError(f"side must be 'right' or 'left', got {side!r}")
    from .auto_hand import auto_hand

    d = auto_hand(f"shadow_hand/{side}_hand")
    out = replace(d, name=f"shadow_{side}", timestep=0.004, max_steps=75,
                  option={**d.option, "solver": mujoco.mjtSolver.mjSOL_CG})
    out.auto = d.auto  # what auto_hand chose (report()), which replace does not copy
    return out


def aero_hand(side: str = "right") -> HandDescription:
    """TetherIA Aero Hand Open (5 fingers: index, middle, ring, pinky, thumb; 16 joints, 7 actuators).

    Under-actuated like the Pisa/IIT SoftHand: one tendon flexes each finger (its PIP and DIP joints
    coupled by an equality, return springs as spring tendons); the thumb has an abduction motor
    (opposition) and two flexion tendons. Tendons close by shortening: the bottom of their ctrlrange
    closes, the top opens (straight). Open pose: fingers straight, thumb abducted flat beside the
    index finger (abduction 0; an opposed thumb would block the approach). Closing synergy: the thumb
    swings into full opposition while the thumb tendons shorten most of their range and the finger
    tendons about half of theirs (full flexion wraps the fingers so other links touch first).
    Approach axis: the fingers' flexion direction at the open pose (the palm normal), in the frame of
    ``tetheria_mount``. The planar fingers have no abduction joint, so their torque-derived normals
    miss the component along the joint axes (see :mod:`~haptic_env.grasping.mujoco_backend`). The
    thumb is slow to settle: up to 0.8 s of closing (200 steps of 4 ms). The 4 ms step keeps the usable
    (0.85) and complete (0.56) grasp rates (the visual table, before 2026-12-07) and the contact error of 2 ms on 400
    ycb10 approaches at 1.3x the grasps/s, and the recognition: validation BC-NP (pool seeds 500-502, 3,000 training
    approaches) 85.0 +- 2.2 % in 5.94 grasps against 85.3 +- 2.6 % in 5.96 at 2 ms."""
    if side not in ("right", "left"):
        raise ValueError(f"side must be 'right' or 'left', got {side!r}")
    spec = _menagerie_spec("tetheria_aero_hand_open", f"{side}_hand")
    p = side
    fingers = ("index", "middle", "ring", "pinky")
    # tendon ctrlranges: fingers [0.05852, 0.110387], th1 [0.026152, 0.038389], th2 [0.081568, 0.112138] m
    open_ctrl = {f"{p}_{f}_A_tendon": 0.110387 for f in fingers}
    open_ctrl.update({f"{p}_thumb_A_cmc_abd": 0.0, f"{p}_th1_A_tendon": 0.038389, f"{p}_th2_A_tendon": 0.112138})
    close = {f"{p}_{f}_A_tendon": 0.08 for f in fingers}
    close.update({f"{p}_thumb_A_cmc_abd": 1.75, f"{p}_th1_A_tendon": 0.03, f"{p}_th2_A_tendon": 0.09})
    return HandDescription(name=f"aero_{side}", spec=spec, root="tetheria_mount",
                           tips=tuple(f"{p}_{f}_distal_link" for f in (*fingers, "thumb")),
                           open_ctrl=open_ctrl, close_ctrl=close,
                           approach_axis=np.array([0.285, 0.0, 0.958]),  # palm normal (mirror-symmetric in y)
                           option={"cone": mujoco.mjtCone.mjCONE_ELLIPTIC, "impratio": 10.0},
                           timestep=0.004, max_steps=200)


def robotiq_hand() -> HandDescription:
    """Robotiq 2F-85 parallel gripper (2 fingers: right pad, left pad as the "thumb"; 1 actuator).

    One motor (``fingers_actuator``, ctrl 0 = open .. 255 = closed, force limited to 5 N) drives both
    4-bar linkages through a tendon that splits its force equally; each finger adapts through its
    spring link. Fingertips: the pads, sites at the centre of the pad blocks (radius = half their
    thickness, so ``site + r * normal`` lies on the pad face). Approach axis: the gripper's +z (base
    towards the pinch point); thumb axis calibrated (towards the left pad).

    Two hand-specific choices, both because the object is fixed and the mount rigid: the equality
    that mirrors the left driver onto the right one is removed, so a pad that touches first stops
    while the other closes on (what the gripper or arm being pushed sideways to centre the object
    would give; with the coupling one pad touching first stalls both), and there is no standoff
    (the pinch point starts where the approach first becomes collision-free: objects narrower than
    the 85 mm opening then sit between the pad faces instead of 2 cm short of them). The n = 2
    case: a grasp is usable when both pads touch (``GraspResult.info["usable"]``)."""
    spec = _menagerie_spec("robotiq_2f85", "2f85")
    for eq in list(spec.equalities):
        if eq.type == mujoco.mjtEq.mjEQ_JOINT:  # right_driver_joint == left_driver_joint
            spec.delete(eq)
    pad_centre = np.array([0.0, -0.0026, 0.01875])  # pad_box1 + pad_box2: z 0 .. 0.0375, y -0.0066 .. 0.0014
    return HandDescription(name="robotiq_2f85", spec=spec, root="base_mount", tips=("right_pad", "left_pad"),
                           tip_sites=((pad_centre, 0.004), (pad_centre, 0.004)),
                           open_ctrl={"fingers_actuator": 0.0}, close_ctrl={"fingers_actuator": 255.0},
                           approach_axis=np.array([0.0, 0.0, 1.0]),
                           option={"cone": mujoco.mjtCone.mjCONE_ELLIPTIC, "impratio": 10.0}, max_steps=300,
                           standoff=0.0)


def mjcf_hand(path: str | Path, tips: tuple[str, ...] | list[str] | None = None, *, root: str | None = None,
              open_ctrl: dict[str, float] | None = None, close_ctrl: dict[str, float] | None = None,
              spread: dict[str, tuple[float, float]] | None = None,
              approach_axis: tuple[float, float, float] | None = None) -> HandDescription:
    """Any MJCF hand (a file or a MuJoCo Menagerie name): ``tips`` are its fingertip bodies (thumb last;
    None: detected). Without ``close_ctrl`` the fingertips, closing synergy, approach axis and physics
    options are found automatically (:func:`~.auto_hand.auto_hand`); ``open_ctrl``/``spread`` override
    its open pose / add spread actuators. With ``close_ctrl`` the hand is used as given (several
    top-level bodies are still wrapped into one root, its own ``<option>`` cone/impratio/noslip kept), and
    ``approach_axis`` (the direction from the palm to where the closing fingertips meet, in the root's frame) should
    be given too: without it the grasp backend estimates one from the closing motion alone, with a warning, which
    can miss the object (on the Allegro given so, 86 degrees off the automatic path's axis, and no usable grasp)."""
    from .auto_hand import auto_hand, hand_options, load_mjcf, single_root

    if close_ctrl is None:
        if root is not None:  # it was dropped without a word
            raise ValueError(f"MJCF hand {path}: root={root!r} is for a hand used as given (with close_ctrl=); the "
                             "automatic path mounts the hand at the root it finds (leave root out, or give close_ctrl)")
        if approach_axis is not None:  # dropped without a word too: the automatic path finds its own
            raise ValueError(f"MJCF hand {path}: approach_axis={approach_axis!r} is for a hand used as given (with "
                             "close_ctrl=); the automatic path finds the axis from its closing synergy (leave it out, "
                             "or give close_ctrl)")
        desc = auto_hand(path, tips)
        if open_ctrl:
            desc.open_ctrl = {**desc.open_ctrl, **open_ctrl}
        desc.spread = dict(spread or {})
        return desc
    if tips is None:
        raise ValueError(f"MJCF hand {path}: close_ctrl= given by hand needs tips= (fingertip body names, thumb last)")
    if len(set(tips)) != len(tips):  # a repeated tip: its finger was never flagged touching
        raise ValueError(f"MJCF hand {path}: each fingertip body once, got tips={tuple(tips)}")
    spec, name, src = load_mjcf(path)
    spec, auto_root, _ = single_root(spec)
    names = [spec.bodies[i].name for i in range(len(spec.bodies))]
    missing = [t for t in tips if t not in names]
    if missing:
        raise ValueError(f"fingertip bodies {missing} not in {src} (bodies: {names})")
    if root is None:
        root = auto_root
    elif root not in names:
        raise ValueError(f"root body {root!r} not in {src} (bodies: {names})")
    option, timestep = hand_options(spec)
    axis = None
    if approach_axis is not None:
        axis = np.asarray(approach_axis, dtype=np.float64)
        if axis.shape != (3,) or not np.isfinite(axis).all() or np.linalg.norm(axis) < 1e-9:
            raise ValueError(f"approach_axis must be a finite non-zero 3-vector, got {approach_axis!r}")
        axis = axis / np.linalg.norm(axis)
    return HandDescription(name=name, spec=spec, root=root, tips=tuple(tips), open_ctrl=open_ctrl or {},
                           close_ctrl=close_ctrl, spread=spread or {}, option=option, timestep=timestep,
                           approach_axis=axis)


def finger_of_bodies(m: mujoco.MjModel, tip_ids) -> np.ndarray:
    """``(nbody,)`` finger index of every body of a compiled hand or scene (-1: the palm and above, or none).

    A body belongs to finger ``i`` when it lies on the chain from tip ``tip_ids[i]`` to the world below the
    bodies every chain shares; bodies of a closed linkage (a ``connect``/``weld`` equality, e.g. a gripper's
    driver and coupler bars) belong to the finger they connect to."""
    chains = []
    for b in tip_ids:
        chain, x = [], int(b)
        while x != 0:
            chain.append(x)
            x = int(m.body_parentid[x])
        chains.append(chain)
    shared = set.intersection(*(set(c) for c in chains)) if chains else set()
    finger = np.full(m.nbody, -1)
    for i, c in enumerate(chains):
        for b in c:
            if b not in shared:
                finger[b] = i
    for e in range(m.neq):
        if int(m.eq_type[e]) not in (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)) or \
                int(m.eq_objtype[e]) != int(mujoco.mjtObj.mjOBJ_BODY):
            continue
        for a_, b_ in ((m.eq_obj1id[e], m.eq_obj2id[e]), (m.eq_obj2id[e], m.eq_obj1id[e])):
            x = int(b_)
            if finger[a_] < 0:
                continue
            while x != 0 and x not in shared and finger[x] < 0:
                finger[x] = finger[a_]
                x = int(m.body_parentid[x])
    return finger


def _named_hand(hand) -> Callable[[], HandDescription] | None:
    """The builder of a named Menagerie hand's hand-written description (``"allegro"``, ``"shadow"``, ``"aero"``, each
    with an optional ``_right`` / ``_left``, or ``"robotiq"``), None for any other ``hand``. The one list of those
    names."""
    sided = {"allegro": allegro_hand, "shadow": shadow_hand, "aero": aero_hand}
    if not isinstance(hand, str):
        return None
    if hand == "robotiq":
        return robotiq_hand
    base, _, side = hand.partition("_")
    if base in sided and side in ("", "right", "left"):
        return lambda: sided[base](side or "right")
    return None


def load_hand(hand: str | Path | HandDescription, n_fingers: int | None = None, **kw) -> HandDescription:
    """``"generic"`` (n fingers), ``"allegro"`` (4), ``"shadow"`` (5), ``"aero"`` (5), ``"robotiq"`` (2),
    a HandDescription, an MJCF path or a MuJoCo Menagerie name (``robot`` or ``robot/entry``): those go
    through :func:`mjcf_hand` (``tips=`` optional: detected when absent, with the closing synergy found
    automatically). ``_right``/``_left`` suffixes pick the side of the Allegro, Shadow and Aero hands.
    ``n_fingers=None``: the hand's own count (4 for ``"generic"``). Keyword arguments go to :func:`generic_hand` or
    :func:`mjcf_hand`; the named Menagerie hands and a HandDescription take none (a TypeError names them)."""
    named = _named_hand(hand)
    if kw and (isinstance(hand, HandDescription) or named is not None):
        raise TypeError(f"hand {hand if isinstance(hand, str) else hand.name!r} takes no keyword arguments, got "
                        f"{sorted(kw)} (they are for the generic hand and for MJCF files)")
    if isinstance(hand, HandDescription):
        desc = hand
    elif hand == "generic":
        desc = generic_hand(4 if n_fingers is None else n_fingers, **kw)
    elif named is not None:
        desc = named()
    elif isinstance(hand, (str, Path)) and str(hand):
        desc = mjcf_hand(hand, **kw)  # a file or a Menagerie name; ValueError naming it when it is neither
    else:
        raise ValueError(f"unknown hand {hand!r}; use one of {HANDS}, an MJCF .xml path, a MuJoCo Menagerie name "
                         "or a HandDescription")
    if n_fingers is not None and desc.n_fingers != n_fingers:
        raise ValueError(f"hand {desc.name!r} has {desc.n_fingers} fingers but n_fingers={n_fingers}")
    return desc
