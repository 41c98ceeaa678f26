"""MuJoCo backend checks. Angle bound: at equilibrium a fingertip-only contact force lies inside the
friction cone (atan(0.1) = 5.7 deg with the default friction); with settling error we require >= 90%
of touching fingertips of the generic hand within 15 deg of MuJoCo's contact normal (measured: median
~4, 90th percentile ~8 deg), and a median below 20 deg for the Allegro / Shadow / Aero hands (30 deg for the Robotiq
gripper, whose flat pads and loaded joint limits leave the contact wrench under-determined)."""

import numpy as np
import pytest
import trimesh

from haptic_env.grasping import make_backend
from haptic_env.grasping.hands import HandUnavailableError
from haptic_env.objects import GraspObject, load_object_set

ANGLE_DEG = 15.0
MENAGERIE_MEDIAN_DEG = 20.0


def _cyl():
    return GraspObject("cyl", trimesh.creation.cylinder(0.035, 0.12, sections=48))


def _angles(results):
    out = []
    for r in results:
        for i in np.flatnonzero(r.touched):
            out.append(np.degrees(np.arccos(np.clip(r.normals[i] @ r.gt_normals[i], -1, 1))))
    return np.array(out)


@pytest.fixture(scope="module")
def generic():
    # the visual table: these tests are about the contacts and normals of the approaches a table does not block
    # (with the default solid table, 20 of these 30 are usable; test_a_solid_table_keeps_the_fingertips_out_of_it)
    be = make_backend("mujoco", 4, hand="generic", solid_table=False)
    be.set_object(_cyl())
    return be


@pytest.fixture(scope="module")
def generic_results(generic):
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (30, 4))
    return acts, [generic.grasp(a, rng) for a in acts]


def test_torque_normals_agree_with_contact_normals(generic_results):
    """Also the rest test's: with the fingers counted at rest at one check (before 2026-12-07), 5 of these 30 grasps
    ended while a finger swung sideways, their torque normals 26-32 degrees off, and 82 % were within 15 degrees."""
    _, res = generic_results
    ang = _angles(res)
    assert len(ang) >= 60
    assert np.mean(ang < ANGLE_DEG) >= 0.9, np.percentile(ang, [50, 90, 100])


def test_contacts_near_surface_and_results_consistent(generic_results):
    _, res = generic_results
    mesh = _cyl().mesh
    usable = np.mean([r.usable for r in res])
    assert usable > 0.8
    pts = np.concatenate([r.contacts[r.touched] for r in res])
    d = np.abs(trimesh.proximity.signed_distance(mesh, pts))
    assert np.mean(d < 3e-3) >= 0.9, np.percentile(d, [50, 90, 100])
    for r in res:
        assert r.contacts.shape == (4, 3) and r.joint_pos.shape == (16,)
        assert np.all(r.contacts[~r.touched] == 0) and np.all(r.normals[~r.touched] == 0)
        assert np.allclose(np.linalg.norm(r.normals[r.touched], axis=1), 1.0)


def test_same_seed_same_grasp(generic):
    a = np.array([0.2, 0.1, -0.3, 0.5], dtype=np.float32)
    r1 = generic.grasp(a, np.random.default_rng(1))
    generic.grasp(np.array([-0.7, 0.9, 0.3, -1.0]), np.random.default_rng(2))  # state in between
    r2 = generic.grasp(a, np.random.default_rng(1))
    assert np.array_equal(r1.contacts, r2.contacts) and np.array_equal(r1.touched, r2.touched)


def test_the_squeeze_at_first_touch_moves_the_closing_actuators_only(generic):
    """A finger's first touch squeezes its closing actuators; its spread (swivel) actuator keeps its target (until
    2026-12-07 it was pushed 0.15 rad either way by the sign of a residual: the swivels ended a median 0.14 rad off)."""
    from haptic_env.grasping.base import decode_approach

    sc = generic.scene
    swivel = np.array([sc.act_index[k] for k in generic.hand.spread])
    closing = np.flatnonzero(sc.squeezed)
    assert len(swivel) == 3 and len(closing) == 12 and not np.isin(swivel, closing).any()
    rng = np.random.default_rng(3)
    squeezed, off = 0, []
    for a in rng.uniform(-1, 1, (12, 4)):
        r = generic.grasp(a, rng)
        _, close_u = generic._ctrls(float(decode_approach(a, generic.config.support).spread))
        np.testing.assert_array_equal(sc.data.ctrl[swivel], close_u[swivel])
        squeezed += int(np.sum(sc.data.ctrl[closing] != close_u[closing]))
        touched = r.touched[:-1]  # the thumb (last) has no spread actuator
        off.extend(np.abs(sc.data.actuator_length[swivel] - close_u[swivel])[touched])
    assert squeezed > 0 and len(off) >= 10
    assert np.median(off) < 0.02, np.percentile(off, [50, 90, 100])


def test_a_hand_whose_fingertips_close_behind_its_palm_grasps_a_small_ball():
    """The generic hand's closed fingertips meet 3.8 cm behind its palm (``g . n < 0``); the pre-grasp search started
    the palm that far past a small object's centre, already free of it and facing away, so no fingertip ever touched
    a 6.7 cm ball (the default set's). With the visual table every approach reaches it; with the default solid one,
    those that the table leaves room for (14 of 30 here)."""
    for solid, least in ((False, 0.8), (True, 0.3)):
        be = make_backend("mujoco", 4, hand="generic", solid_table=solid)
        be.set_object(GraspObject("ball", trimesh.creation.icosphere(subdivisions=3, radius=0.0335)))
        n, _, g = be._calibrated
        assert g @ n < -0.02  # the case this test is about
        rng = np.random.default_rng(0)
        res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (30, 4))]
        assert np.mean([r.usable for r in res]) >= least, (solid, [r.n_touched for r in res])


def test_a_finger_pressing_on_the_solid_table_is_flagged():
    """``info["table_contact"]``: the fingers any of whose links touch a solid table, whose push biases their torque
    normals as a link's contact with the object does (``link_contact`` counted only the object's); read here from
    the contacts by each finger's chain of bodies up to its tip. A visual table touches nothing."""
    import mujoco

    ring = load_object_set("default")["ring"]
    for solid in (True, False):
        be = make_backend("mujoco", 4, hand="generic", solid_table=solid)
        be.set_object(ring)
        m = be.scene.model
        chains = []  # the bodies from each fingertip up to (not including) the bodies all fingers share
        for t in be.scene.tip_body_ids:
            chain, b = [], int(t)
            while b > 0:
                chain.append(b)
                b = int(m.body_parentid[b])
            chains.append(chain)
        shared = set.intersection(*map(set, chains))
        rng = np.random.default_rng(0)
        flagged = 0
        for a in rng.uniform(-1, 1, (30, 4)):
            r = be.grasp(a, rng)
            d, table = be.scene.data, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "table")
            want = np.zeros(4, bool)
            for c in d.contact[:d.ncon]:
                if c.dist <= 0 and table in (c.geom[0], c.geom[1]):
                    body = int(m.geom_bodyid[c.geom[1] if c.geom[0] == table else c.geom[0]])
                    want |= [body in set(ch) - shared for ch in chains]
            np.testing.assert_array_equal(r.info["table_contact"], want)
            flagged += int(want.any())
        assert (flagged > 0) == solid, (solid, flagged)


def test_a_solid_table_keeps_the_fingertips_out_of_it(load_benchmark):
    """With ``solid_table=False`` the table is a visual plane: fingertips sink into it to touch a ball low down (10 of
    these 12 random approaches reach 2 mm or more under the table top); a solid table stops them, and the ball is
    still grasped from above."""
    from haptic_env.grasping.base import support_height

    depth_below_table = load_benchmark("table_reach").depth_below_table  # its one owner
    ball = GraspObject("ball", trimesh.creation.icosphere(subdivisions=3, radius=0.0335))
    acts = np.random.default_rng(1).uniform(-1, 1, (12, 4))
    below = {}
    for solid in (False, True):
        be = make_backend("mujoco", 4, hand="generic", solid_table=solid)
        be.set_object(ball)
        rng = np.random.default_rng(0)
        res = [be.grasp(a, rng) for a in acts]
        table_z = support_height(ball.mesh.vertices)
        below[solid] = np.array([depth_below_table(r.info["tip_sites"], be.scene.tip_radius, r.touched, table_z)
                                 for r in res])
        if solid:
            assert sum(r.usable for r in res) >= 3
    assert np.mean(below[False] > 2e-3) >= 0.5, below[False]
    assert np.all(below[True] < 2e-3), below[True]
    with pytest.raises(ValueError, match="solid_table needs support='table'"):
        make_backend("mujoco", 4, hand="generic", solid_table=True, support="floating")
    with pytest.raises(ValueError, match="solid_table"):
        make_backend("mujoco", 4, hand="generic", solid_table="yes")


def test_missing_fingers_reported():
    be = make_backend("mujoco", 5, hand="generic")
    be.set_object(GraspObject("pole", trimesh.creation.cylinder(0.006, 0.2, sections=24)))
    rng = np.random.default_rng(3)
    res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (12, 4))]
    touched = np.stack([r.touched for r in res])
    assert (~touched).any()
    for r in res:  # a finger reported untouched has no MuJoCo contact between its tip and the object
        assert np.all(r.contacts[~r.touched] == 0)
        assert np.all(r.gt_normals[~r.touched] == 0)


def test_invalid_action_and_timing(generic):
    """A refused action is not counted; ``timing`` counts this test's own grasps (after ``reset_timing``), their
    physics steps and the time inside ``mj_step``, which is part of the grasp's time."""
    generic.reset_timing()
    with pytest.raises(ValueError, match="outside"):
        generic.grasp(np.array([0, 0, 1.01, 0]), np.random.default_rng(0))
    assert generic.timing["grasps"] == 0
    rng = np.random.default_rng(4)
    steps = [generic.grasp(a, rng).info["steps"] for a in rng.uniform(-1, 1, (3, 4))]
    t = generic.timing
    assert t["grasps"] == 3 and t["steps_per_grasp"] == pytest.approx(np.mean(steps)) and min(steps) > 0
    assert 0 < t["step_time_per_grasp"] <= t["time_per_grasp"]


def test_timing_counts_the_steps_of_every_object_grasped():
    """``timing`` counts the physics of every grasp since ``reset_timing``, whichever object's scene ran it (each
    object has a scene of its own; the counters were once read from the current scene only, so that the steps of
    the other objects' grasps were missing and ``ratio`` came out many times too large)."""
    be = make_backend("mujoco", 4, hand="generic")
    rng = np.random.default_rng(5)
    steps = []
    be.reset_timing()
    for obj in (_cyl(), GraspObject("box", trimesh.creation.box((0.06, 0.05, 0.1)))):
        be.set_object(obj)
        steps += [be.grasp(a, rng).info["steps"] for a in rng.uniform(-1, 1, (2, 4))]
    t = be.timing
    assert t["grasps"] == 4 and t["steps_per_grasp"] == pytest.approx(np.mean(steps))
    assert 0 < t["step_time_per_grasp"] <= t["time_per_grasp"]
    be.close()


def test_another_timestep_keeps_the_hands_closing_time():
    """``max_steps=None`` is the hand's closing time (its step count at its own timestep), not its step count: at
    half the generic hand's 2 ms the fingers get twice the steps to close (they got 200 steps, half the time)."""
    rng = np.random.default_rng(6)
    a = rng.uniform(-1, 1, 4)
    steps = {}
    for dt in (None, 0.001):  # a rest speed no finger reaches: every grasp closes for its whole time
        be = make_backend("mujoco", 4, hand="generic", solid_table=False, timestep=dt, rest_qvel=1e-9)
        be.set_object(_cyl())
        steps[dt] = be.grasp(a, np.random.default_rng(0)).info["steps"]
        be.close()
    assert steps == {None: 200, 0.001: 400}


def test_an_object_scaled_in_place_grasps_as_one_built_at_that_size(tmp_path):
    """``scale_object`` edits the compiled model (no recompile); the object's bounding-volume trees and inertial frame
    must follow, else MuJoCo's midphase skips pieces outside their unscaled boxes (an object of several convex
    pieces at scale > 1 lost touches: 17 of 30 grasps differed). Here every grasp matches a scene built from the
    scaled pieces."""
    a = trimesh.creation.box((0.08, 0.02, 0.06))
    b = trimesh.creation.box((0.02, 0.06, 0.06))
    b.apply_translation((0.03, 0.04, 0))
    s, small, big = 1.8, [], []
    for i, piece in enumerate((a, b)):
        piece.export(tmp_path / f"p{i}.stl")
        small.append(tmp_path / f"p{i}.stl")
        loaded = trimesh.load(small[-1])  # the file's float32 vertices, scaled: the same numbers in both scenes
        loaded.apply_scale(s)
        loaded.export(tmp_path / f"big{i}.stl")
        big.append(tmp_path / f"big{i}.stl")
    whole = trimesh.util.concatenate([a, b])
    in_place, built = make_backend("mujoco", 3, hand="generic"), make_backend("mujoco", 3, hand="generic")
    in_place.set_object(GraspObject("L", whole, collision_paths=tuple(small)), scale=s)
    built.set_object(GraspObject("L_big", whole.copy().apply_scale(s), collision_paths=tuple(big)))
    _assert_same_grasps(in_place, built, np.random.default_rng(0).uniform(-1, 1, (30, 4)), atol=1e-6)


def test_render_offscreen(generic):
    import mujoco

    try:  # whether this machine renders at all, on an empty model: only that skips; a failure of ours fails
        mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), height=8, width=8).close()
    except Exception as exc:
        pytest.skip(f"no OpenGL backend for offscreen rendering: {exc}")
    img = generic.render(96, 64)
    assert img.shape == (64, 96, 3) and img.dtype == np.uint8 and img.std() > 0


@pytest.mark.parametrize("hand, n", [("allegro", 4), ("shadow", 5), ("aero", 5)])
def test_menagerie_hands(hand, n):
    try:
        be = make_backend("mujoco", n, hand=hand)
    except HandUnavailableError as exc:
        pytest.skip(f"{hand} hand unavailable (menagerie data absent, no download): {exc}")
    be.set_object(_cyl())
    rng = np.random.default_rng(0)
    res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (10, 4))]
    assert all(r.contacts.shape == (n, 3) for r in res)
    assert sum(r.n_touched for r in res) > 0
    ang = _angles(res)
    assert np.median(ang) < MENAGERIE_MEDIAN_DEG


def _menagerie_backend(hand, n, **cfg):
    try:
        return make_backend("mujoco", n, hand=hand, **cfg)
    except HandUnavailableError as exc:
        pytest.skip(f"{hand} hand unavailable (menagerie data absent, no download): {exc}")


def test_aero_tendon_actuators_map_to_their_fingers():
    """Spatial-tendon actuators (first wrap object a site) map to the finger whose joints they move;
    the under-actuated hand closes on a cylinder with most fingertips."""
    be = _menagerie_backend("aero", 5)
    be.set_object(_cyl())
    sc = be.scene
    idx = sc.act_index
    for i, f in enumerate(("index", "middle", "ring", "pinky")):
        assert sc.act_finger[idx[f"right_{f}_A_tendon"]] == i
    for a in ("right_thumb_A_cmc_abd", "right_th1_A_tendon", "right_th2_A_tendon"):
        assert sc.act_finger[idx[a]] == 4
    assert sc.moment_scale[idx["right_index_A_tendon"]] < 0.05  # metres of tendon per radian
    rng = np.random.default_rng(0)
    res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (6, 4))]
    assert all(r.joint_pos.shape == (16,) and r.normals.shape == (5, 3) for r in res)
    assert np.mean([r.usable and r.info["usable"] for r in res]) >= 0.5


def test_two_finger_gripper():
    """Robotiq 2F-85: n = 2, one motor for both fingers, usable = both pads touch."""
    be = _menagerie_backend("robotiq", 2)
    be.set_object(_cyl())  # 70 mm across: fits the 85 mm opening
    sc = be.scene
    assert sc.act_fingers.shape == (1, 2) and sc.act_fingers.all() and sc.act_finger[0] == -1
    rng = np.random.default_rng(0)
    res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (10, 4))]
    for r in res:
        assert r.contacts.shape == (2, 3) and r.normals.shape == (2, 3) and r.touched.shape == (2,)
        assert r.info["usable"] == bool(r.touched.all())
        assert np.all(r.contacts[~r.touched] == 0)
        assert np.allclose(np.linalg.norm(r.normals[r.touched], axis=1), 1.0)
    both = [r for r in res if r.info["usable"]]
    assert len(both) >= 4
    gap = [np.linalg.norm(r.contacts[0] - r.contacts[1]) for r in both]
    assert np.all((np.array(gap) > 0.03) & (np.array(gap) < 0.09)), gap  # a grasp vector: the pad distance
    assert np.median(_angles(res)) < 30.0


def test_wrong_finger_count_for_hand():
    with pytest.raises(ValueError, match="fingers"):
        make_backend("mujoco", 7, hand="generic")


@pytest.mark.parametrize("kwargs, match", [
    ({"tip_radius": -0.01}, "tip_radius must be a finite number > 0"),  # failed at compile, naming no parameter
    ({"tip_radius": 0.5}, r"tip_radius must be in \(0, 0.05\]"),
    ({"palm_radius": float("nan")}, "palm_radius"),
    ({"kp": (-1.0, 1.0, 1.0)}, r"kp\[0\] must be a finite number > 0"),  # a destabilising servo compiled
    ({"kp": (1.0, 1.0)}, "kp must be 3 finite numbers"),
    ({"close": (5.0, 5.0, 5.0)}, r"close\[0\] must be within link 0's joint range"),
    ({"finger_length": "long"}, "finger_length"),
])
def test_generic_hand_parameters_are_checked_before_building(kwargs, match):
    from haptic_env.grasping.hands import generic_hand

    with pytest.raises(ValueError, match=match):
        generic_hand(4, **kwargs)


def test_a_named_hand_refuses_keyword_arguments_and_takes_its_own_finger_count():
    """``hand_kwargs`` meant for the generic hand were dropped without a word for a named hand; ``load_hand``'s
    default finger count (4) refused the 5-finger hands by name."""
    from haptic_env.grasping.hands import load_hand

    with pytest.raises(TypeError, match=r"'allegro' takes no keyword arguments, got \['finger_lenght'\]"):
        make_backend("mujoco", 4, hand="allegro", hand_kwargs={"finger_lenght": 0.2})
    with pytest.raises(TypeError, match="'robotiq' takes no keyword arguments"):
        load_hand("robotiq", None, tips=("a", "b"))
    assert load_hand("generic").n_fingers == 4
    try:
        assert load_hand("shadow").n_fingers == 5
    except HandUnavailableError as exc:
        pytest.skip(str(exc))


def test_any_mjcf_hand_from_file(tmp_path):
    from haptic_env.grasping.hands import generic_hand

    desc = generic_hand(3)
    path = tmp_path / "claw.xml"
    path.write_text(desc.spec.to_xml())
    be = make_backend("mujoco", 3, hand=str(path), hand_kwargs=(("tips", desc.tips),), support="floating")
    be.set_object(_cyl())
    rng = np.random.default_rng(0)
    res = [be.grasp(a, rng) for a in rng.uniform(-1, 1, (6, 4))]
    assert sum(r.n_touched for r in res) > 0
    with pytest.raises(ValueError, match="fingertip bodies"):
        make_backend("mujoco", 3, hand=str(path), hand_kwargs=(("tips", ("nope", "f1_tip", "f2_tip")),))
    # a repeated tip (its finger never flagged touching), a scale that is not a number, an object without a mesh,
    # and hand_kwargs that are no table: taken, or errors that did not name them
    for tips in (("f0_tip", "f0_tip", "f2_tip"),):
        with pytest.raises(ValueError, match=r"each fingertip body once, got tips=\('f0_tip', 'f0_tip', 'f2_tip'\)"):
            make_backend("mujoco", 3, hand=str(path), hand_kwargs=(("tips", tips),))
        with pytest.raises(ValueError, match="each fingertip body once"):
            make_backend("mujoco", 3, hand=str(path), hand_kwargs=(("tips", tips), ("close_ctrl", {"a": 1.0})))
    for bad in ("1.5", True, None):
        with pytest.raises(ValueError, match=rf"scale must be a finite number > 0, got {bad!r}"):
            be.set_object(_cyl(), scale=bad)
    with pytest.raises(ValueError, match="has no usable triangle mesh"):
        be.set_object(object())
    with pytest.raises(ValueError, match=r"hand_kwargs must be a table or \(name, value\) pairs.*got 'abc'"):
        make_backend("mujoco", 3, hand=str(path), hand_kwargs="abc")


def test_a_hand_given_with_its_closing_controls_takes_its_approach_axis_and_is_warned_without_one(tmp_path):
    """``mjcf_hand(close_ctrl=...)`` used the backend's estimate of the approach axis from the closing motion, which
    can miss the object (the generic hand given so: 101 degrees off its own axis); it takes ``approach_axis`` now,
    and without one the estimate comes with a warning."""
    from haptic_env.grasping.hands import generic_hand, mjcf_hand
    from haptic_env.grasping.mujoco_backend import MujocoBackend, MujocoConfig

    desc = generic_hand(4)
    path = tmp_path / "claw.xml"
    path.write_text(desc.spec.to_xml())
    given = dict(tips=desc.tips, root=desc.root, open_ctrl=desc.open_ctrl, close_ctrl=desc.close_ctrl)
    hand = mjcf_hand(str(path), **given, approach_axis=(0.0, 0.0, 2.0))
    np.testing.assert_array_equal(hand.approach_axis, [0.0, 0.0, 1.0])
    be = MujocoBackend(MujocoConfig(hand=hand, n_fingers=None))
    be.set_object(_cyl())
    np.testing.assert_array_equal(be._calibrated[0], [0.0, 0.0, 1.0])
    be = MujocoBackend(MujocoConfig(hand=mjcf_hand(str(path), **given), n_fingers=None))
    with pytest.warns(UserWarning, match="has no approach_axis: estimated from the closing motion"):
        be.set_object(_cyl())
    with pytest.raises(ValueError, match="approach_axis must be a finite non-zero 3-vector"):
        mjcf_hand(str(path), **given, approach_axis=(0.0, 0.0))


def test_backends_follow_protocol(generic):
    from haptic_env.grasping import GraspBackend

    assert isinstance(generic, GraspBackend)
    for name in ("geometric", "uniform"):
        assert isinstance(make_backend(name, 4), GraspBackend)


def test_a_known_object_in_a_new_pose_moves_instead_of_recompiling():
    """``set_object`` keeps one compiled scene per mesh: a reset with a new pose moves the object body, and grasps
    equal those of a scene compiled at that pose."""
    from scipy.spatial.transform import Rotation

    cyl, box = _cyl(), GraspObject("box", trimesh.creation.box((0.06, 0.05, 0.1)))
    T1, T2 = np.eye(4), np.eye(4)
    T2[:3, :3] = Rotation.from_euler("xz", [0.4, 1.1]).as_matrix()
    T2[:3, 3] = [0.01, -0.02, 0.0]
    moved = make_backend("mujoco", 4, hand="generic")
    moved.set_object(cyl, T1)
    first = moved.scene
    moved.set_object(box, T1)
    moved.set_object(cyl, T2)
    assert moved.scene is first  # no recompilation
    fresh = make_backend("mujoco", 4, hand="generic")
    fresh.set_object(cyl, T2)
    _assert_same_grasps(moved, fresh, np.random.default_rng(3).uniform(-1, 1, (4, 4)), atol=1e-9)


def _assert_same_grasps(one, other, actions, atol: float) -> None:
    """Both backends grasp each action alike (the same fingers touch, contacts within ``atol``); closes both."""
    for x in actions:
        r1, r2 = one.grasp(x, np.random.default_rng(0)), other.grasp(x, np.random.default_rng(0))
        np.testing.assert_array_equal(r1.touched, r2.touched)
        np.testing.assert_allclose(r1.contacts, r2.contacts, atol=atol)
    one.close()
    other.close()


def test_scale_without_a_mesh_copy_matches_a_scaled_object():
    """``set_object(obj, pose, scale=s)`` (the env's ``scale_range``) grasps like an object whose mesh was scaled."""
    cyl = _cyl()
    big_mesh = cyl.mesh.copy()
    big_mesh.apply_scale(1.3)
    scaled = make_backend("mujoco", 4, hand="generic")
    scaled.set_object(cyl, np.eye(4), scale=1.3)
    copied = make_backend("mujoco", 4, hand="generic")
    copied.set_object(GraspObject("cyl_big", big_mesh), np.eye(4))
    for a in np.random.default_rng(4).uniform(-1, 1, (4, 4)):
        r1, r2 = scaled.grasp(a, np.random.default_rng(0)), copied.grasp(a, np.random.default_rng(0))
        np.testing.assert_array_equal(r1.touched, r2.touched)
        np.testing.assert_allclose(r1.contacts, r2.contacts, atol=1e-6)
    with pytest.raises(ValueError, match="scale"):
        scaled.set_object(cyl, np.eye(4), scale=0.0)
    scaled.close()
    copied.close()


def test_scene_spec_is_the_moved_scaled_scene_with_the_grasp_as_keyframes():
    """``scene_spec`` exports the scene as the backend last placed it (a known mesh moved and scaled in the compiled
    model only): the exported model's "grasp" keyframe is the backend's final state, fingertip sites included."""
    import mujoco
    from scipy.spatial.transform import Rotation

    cyl = _cyl()
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", 0.7).as_matrix()
    T[:3, 3] = [0.02, -0.01, 0.0]
    be = make_backend("mujoco", 4, hand="generic")
    be.set_object(cyl, np.eye(4))
    be.set_object(cyl, T, scale=1.2)  # the same compiled scene, moved and scaled
    a = np.array([0.2, 0.4, -0.3, 0.5])
    spec, res = be.scene_spec(a, np.random.default_rng(0))
    m = spec.compile()
    d = mujoco.MjData(m)
    sc = be.scene
    np.testing.assert_allclose(m.body_pos[m.body("object").id], T[:3, 3])
    np.testing.assert_allclose(m.body_quat[m.body("object").id], sc.model.body_quat[sc.obj_body_id])
    np.testing.assert_allclose(m.geom_aabb[sc.obj_geom_ids], sc.model.geom_aabb[sc.obj_geom_ids], atol=1e-6)
    mujoco.mj_resetDataKeyframe(m, d, m.key("grasp").id)
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(d.site_xpos[sc.site_ids], res.info["tip_sites"], atol=1e-9)
    assert [m.key(i).name for i in range(m.nkey)] == ["approach", "grasp"]
    assert be.grasp(a, np.random.default_rng(0)).touched.tolist() == res.touched.tolist()  # the backend is unchanged
    be.close()


def test_tip_touched_is_tip_contacts_touched(generic):
    """The closing loop's cheap check agrees with the full contact read, with and without contacts."""
    sc = generic._require()
    seen = 0
    for a in np.random.default_rng(4).uniform(-1, 1, (6, 4)):
        generic.grasp(a, np.random.default_rng(0))  # ends at the grasp's final state
        for _ in range(3):
            full = sc.tip_contacts()[0]
            assert np.array_equal(sc.tip_touched(), full)
            seen += int(full.sum())
            sc.step(5)
    assert seen > 0  # fingertips touched, so the comparison covered contacts
    sc.reset(sc.data.ctrl.copy())
    sc.set_mount(np.array([0.0, 0.0, 5.0]), np.eye(3))  # far from the object: no contact at all
    sc.step(1)
    assert not sc.tip_touched().any() and np.array_equal(sc.tip_touched(), sc.tip_contacts()[0])


def test_solver_choice_gives_the_same_grasps():
    """CG and Newton both solve to MuJoCo's tolerance: same fingertips, contacts within 0.1 mm."""
    res = {}
    for solver in ("Newton", "CG"):
        be = make_backend("mujoco", 4, hand="generic", solver=solver)
        be.set_object(_cyl())
        assert be._require().model.opt.solver == {"Newton": 2, "CG": 1}[solver]
        res[solver] = [be.grasp(a, np.random.default_rng(0)) for a in np.random.default_rng(5).uniform(-1, 1, (8, 4))]
    for a, b in zip(res["Newton"], res["CG"]):
        assert np.array_equal(a.touched, b.touched)
        assert np.allclose(a.contacts, b.contacts, atol=1e-4)
    with pytest.raises(ValueError, match="solver must be one of"):
        make_backend("mujoco", 4, hand="generic", solver="cg")


def test_a_menagerie_hand_from_the_data_folder_leaves_the_environment_alone(monkeypatch):
    """With ``MENAGERIE_ROOT`` unset, a Menagerie hand is read from the data folder's ``menagerie/`` and the folder
    is passed to ``mujoco-menagerie`` directly: the process environment (and so every later subprocess) is unchanged."""
    import os

    from haptic_env.grasping.hands import load_hand
    from haptic_env.objects import data_dir

    d = data_dir()
    if d is None or not (d / "menagerie" / "wonik_allegro").is_dir():
        pytest.skip("needs the shared data's menagerie/ (../shared/data or $HAPTIC_DATA)")
    monkeypatch.delenv("MENAGERIE_ROOT", raising=False)
    assert load_hand("allegro", None).n_fingers == 4
    assert "MENAGERIE_ROOT" not in os.environ


def test_a_menagerie_hand_that_is_there_but_does_not_load_is_an_error_not_unavailable(tmp_path, monkeypatch):
    """``HandUnavailableError`` (on which the hand tests skip, "menagerie data absent") means absent: a hand whose
    folder is there but whose MJCF does not load (a MuJoCo upgrade, a changed file) is a ``RuntimeError`` that names
    the folder. It was ``HandUnavailableError`` too, so such a break skipped the hand tests instead of failing them."""
    import shutil

    from haptic_env.grasping.hands import _menagerie_spec
    from haptic_env.objects import data_dir

    d = data_dir()
    if d is None or not (d / "menagerie" / "wonik_allegro").is_dir():
        pytest.skip("needs the shared data's menagerie/ (../shared/data or $HAPTIC_DATA)")
    shutil.copytree(d / "menagerie" / "wonik_allegro", tmp_path / "wonik_allegro")
    xml = tmp_path / "wonik_allegro" / "right_hand.xml"
    xml.write_text(xml.read_text().replace("<mujoco", '<mujoco bogus_attribute="1"', 1))
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    with pytest.raises(RuntimeError, match=r"'wonik_allegro'/'right_hand' is in .*wonik_allegro but does not load") \
            as exc:
        _menagerie_spec("wonik_allegro", "right_hand")
    assert not isinstance(exc.value, HandUnavailableError)
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path / "empty"))  # absent (and no download in the tests)
    with pytest.raises(HandUnavailableError, match="cannot load MuJoCo Menagerie hand 'wonik_allegro'"):
        _menagerie_spec("wonik_allegro", "right_hand")
