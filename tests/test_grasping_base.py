import numpy as np
import pytest

from haptic_env.grasping import (
    ACTION_DIM,
    approach_frame,
    decode_approach,
    make_backend,
    validate_action,
    validate_actions,
)


@pytest.mark.parametrize("bad, match", [
    (np.array([0.0, np.nan, 0.0, 0.0]), "nan"),
    (np.array([0.0, 0.0, 1.5, 0.0]), "1.5"),
    (np.array([0.0, 0.0, 0.0, -np.inf]), "inf"),
    (np.zeros(3), r"shape \(4,\)"),
    (np.zeros((1, 4)), r"shape \(4,\)"),
    ("abc", "numeric"),
])
def test_invalid_actions_raise_naming_value(bad, match):
    with pytest.raises(ValueError, match=match):
        validate_action(bad)


def test_invalid_batch_names_row_and_component():
    a = np.zeros((3, ACTION_DIM))
    a[2, 1] = -1.2
    with pytest.raises(ValueError, match=r"action\[2\]\[1\] \(elevation\) = -1.2"):
        validate_actions(a)


def test_decode_ranges_table_and_floating():
    a = np.random.default_rng(0).uniform(-1, 1, (500, ACTION_DIM))
    t = decode_approach(a, "table")
    assert np.all((t.elevation >= 0) & (t.elevation <= np.pi / 2 + 1e-12))
    assert np.all(np.abs(t.azimuth) <= np.pi) and np.all((t.spread >= 0) & (t.spread <= 1))
    f = decode_approach(a, "floating")
    assert f.elevation.min() < 0 < f.elevation.max()
    with pytest.raises(ValueError, match="support"):
        decode_approach(a, "ceiling")


def test_approach_frame_is_rotation_with_axis_into_object():
    a = np.random.default_rng(1).uniform(-1, 1, (200, ACTION_DIM))
    a[:5, 1] = 1.0  # poles (vertical approach) are handled too
    ap = decode_approach(a, "floating")
    F = approach_frame(ap)
    eye = np.einsum("bji,bjk->bik", F, F)
    assert np.allclose(eye, np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(F), 1.0)
    assert np.allclose(F[..., 2], -ap.direction)


def test_roll_rotates_thumb_about_axis():
    a = np.array([[0.3, 0.2, 0.0, 0.0], [0.3, 0.2, 0.5, 0.0]])
    F = approach_frame(decode_approach(a))
    assert np.allclose(F[0, :, 2], F[1, :, 2])
    assert np.isclose(F[0, :, 0] @ F[1, :, 0], np.cos(np.pi / 2), atol=1e-9)


def test_make_backend_unknown_name_and_bad_config():
    with pytest.raises(ValueError, match="unknown grasp backend 'magic'"):
        make_backend("magic")
    with pytest.raises(TypeError, match="unexpected keyword argument 'no_such_option'"):
        make_backend("geometric", 4, no_such_option=1)
    with pytest.raises(ValueError, match="n_fingers"):
        make_backend("geometric", 1)


def test_support_height_is_the_lowest_posed_vertex():
    from scipy.spatial.transform import Rotation

    from haptic_env.grasping.base import support_height

    V = np.array([[0.0, 0.0, -0.1], [0.1, 0.2, 0.3], [-0.2, 0.1, 0.05]])
    assert support_height(V) == pytest.approx(-0.1)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", 0.7).as_matrix()  # a yaw keeps every height
    T[:3, 3] = [1.0, 2.0, 0.25]
    assert support_height(V, T, scale=2.0) == pytest.approx(2.0 * -0.1 + 0.25)
    T[:3, :3] = Rotation.from_euler("x", np.pi).as_matrix()  # upside down: the top vertex is lowest
    assert support_height(V, T) == pytest.approx(-0.3 + 0.25)
    with pytest.raises(ValueError, match="vertices must have shape"):
        support_height(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="4x4"):
        support_height(V, np.eye(3))


def test_validate_pose_agrees_with_numpys_rigid_check_near_its_tolerances():
    """validate_pose checks in Python floats (a reset needs two): it accepts exactly the poses that numpy's
    ``allclose(R R^T, I, atol=1e-6)``, ``det R >= 0`` and ``allclose(T[3], e4)`` accept, also near the tolerances."""
    from scipy.spatial.transform import Rotation

    from haptic_env.grasping.base import validate_pose

    def numpy_accepts(T):
        R = T[:3, :3]
        return bool(np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) >= 0
                    and np.allclose(T[3], [0, 0, 0, 1]))

    rng = np.random.default_rng(0)
    accepted = 0
    for i in range(2000):
        T = np.eye(4)
        T[:3, :3] = Rotation.random(random_state=i).as_matrix()
        T[:3, 3] = rng.normal(size=3)
        kind = i % 5
        if kind == 1:
            T[:3, :3] += rng.normal(size=(3, 3)) * 10 ** rng.uniform(-8, -4)  # around the orthonormality tolerance
        elif kind == 2:
            T[:3, :3] *= -1  # a reflection
        elif kind == 3:
            T[3, :3] += rng.normal(size=3) * 10 ** rng.uniform(-10, -6)
        elif kind == 4:
            T[3, 3] += rng.normal() * 10 ** rng.uniform(-7, -3)
        try:
            validate_pose(T)
            ours = True
        except ValueError as exc:
            assert "rigid transform" in str(exc)
            ours = False
        assert ours == numpy_accepts(T), T
        accepted += ours
    assert 0.3 < accepted / 2000 < 0.7  # both sides of the tolerances were probed


def _formula_frame(az, el, roll):
    """The approach frame away from the poles, from the module docstring: e3 = -u, e1 world z projected onto the plane
    normal to e3 and rolled by ``roll`` about e3, e2 = e3 x e1."""
    u = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    e3 = -u
    b1 = np.array([0.0, 0.0, 1.0]) - e3[2] * e3
    b1 /= np.linalg.norm(b1)
    e1 = np.cos(roll) * b1 + np.sin(roll) * np.cross(e3, b1)
    return np.stack([e1, np.cross(e3, e1), e3], axis=-1)


@pytest.mark.parametrize("support", ["table", "floating"])
def test_frame_away_from_the_poles_follows_the_formula(support):
    a = np.random.default_rng(3).uniform(-1, 1, (300, ACTION_DIM))
    a[:, 1] = np.clip(a[:, 1], -0.99, 0.99)
    ap = decode_approach(a, support)
    F = approach_frame(ap)
    for i in range(len(a)):
        np.testing.assert_allclose(F[i], _formula_frame(ap.azimuth[i], ap.elevation[i], ap.roll[i]), atol=1e-12)


@pytest.mark.parametrize("support", ["table", "floating"])
def test_frame_is_continuous_at_the_poles(support):
    """At the upper pole the frame used to turn 180 degrees: [0.3, 1, 0.1, 0] gave the thumb e1 = (0.81, 0.59, 0),
    [0.3, 0.99999, 0.1, 0] e1 = (-0.81, -0.59, 0)."""
    rng = np.random.default_rng(4)
    base = rng.uniform(-1, 1, (40, ACTION_DIM))
    poles = [1.0] + ([-1.0] if support == "floating" else [])  # the table's lower end (el = 0) is no pole
    for pole in poles:
        for gap in (1e-3, 1e-5, 1e-7, 1e-9, 1e-12):  # both sides of the fallback's threshold
            at, near = base.copy(), base.copy()
            at[:, 1], near[:, 1] = pole, pole - np.sign(pole) * gap
            F_at, F_near = (approach_frame(decode_approach(x, support)) for x in (at, near))
            assert np.abs(F_at - F_near).max() < 4 * gap, (pole, gap)
    F = approach_frame(decode_approach(np.array([0.3, 1.0, 0.1, 0.0]), support))
    # e1 = -(cos(az - roll), sin(az - roll), 0): away from the azimuth, as just below the pole
    np.testing.assert_allclose(F[:, 0], [-np.cos(0.2 * np.pi), -np.sin(0.2 * np.pi), 0.0], atol=1e-12)
    np.testing.assert_allclose(F[:, 2], [0.0, 0.0, -1.0], atol=1e-12)


def test_support_height_refuses_non_finite_vertices_and_bad_scales():
    from haptic_env.grasping.base import support_height

    for V, shown in (([[0, 0, np.nan], [0, 0, 1]], r"vertices\[0\] = \[0.0, 0.0, nan\]"),
                     ([[0, 0, 1], [0, 0, -np.inf]], r"vertices\[1\] = \[0.0, 0.0, -inf\]"),
                     ([[np.inf, 0, 0], [0, 0, 1]], r"vertices\[0\] = \[inf")):
        with pytest.raises(ValueError, match=r"vertices must be finite, got " + shown):
            support_height(V)
    for scale in (np.nan, np.inf, -1, 0, -0.0, np.array([1, 2, 3.0]), np.array(2.0), "2", True, None, 10 ** 400):
        with pytest.raises(ValueError, match=r"scale must be a finite number > 0"):
            support_height([[0, 0, 1.0]], scale=scale)
    V = np.array([[0.0, 0.0, -0.1], [0.1, 0.2, 0.3]])
    assert support_height(V, scale=2) == support_height(V, scale=np.float32(2.0)) == 2.0 * -0.1


@pytest.mark.parametrize("touched", [
    ["no", "no", "no", "no"], ["False"] * 3, [np.nan, np.nan, np.nan, 0.0], [0.4, 0.4, 0.4, 0.0], np.ones(4),
    np.array([1, 1, 1, 0]), np.zeros((3, 0), bool), [True], np.ones((5, 1), bool), True, None,
])
def test_usable_touch_refuses_what_is_not_a_bool_array_of_two_or_more_fingers(touched):
    from haptic_env.grasping import usable_touch

    with pytest.raises(ValueError, match=r"touched must be a bool array of shape \(\.\.\., n\) with n >= 2"):
        usable_touch(touched)


def test_usable_touch_counts_touching_fingers():
    from haptic_env.grasping import GraspBatch, GraspResult, usable_touch

    assert usable_touch([True, True, True, False]) and not usable_touch([True, True, False, False])
    assert usable_touch([True, True]) and not usable_touch([True, False])  # a 2-finger gripper: both
    T = np.array([[1, 1, 1, 0, 0], [1, 1, 0, 0, 0], [1, 1, 1, 1, 1]], dtype=bool)
    np.testing.assert_array_equal(usable_touch(T), [True, False, True])
    np.testing.assert_array_equal(usable_touch(T[None]), [[True, False, True]])
    batch = GraspBatch(np.zeros((3, 5, 3)), None, T, np.zeros((3, 0)))
    np.testing.assert_array_equal(batch.usable, [True, False, True])
    assert GraspResult(np.zeros((5, 3)), None, T[0]).usable is True


@pytest.mark.parametrize("bad", [np.zeros(5), np.zeros((3, 2)), np.zeros(3), 0.0, np.zeros((2, 3))])
def test_decode_approach_refuses_other_shapes(bad):
    """A (5,) action silently lost its 5th value; (3,) and (3, 2) raised an IndexError."""
    with pytest.raises(ValueError, match=r"actions must have shape \(\.\.\., 4\), got shape"):
        decode_approach(bad)


def test_decode_approach_of_valid_actions_follows_the_table():
    a = np.array([[0.5, -1.0, -0.25, 1.0], [-1.0, 1.0, 1.0, -1.0]])
    t, f = decode_approach(a, "table"), decode_approach(a, "floating")
    np.testing.assert_array_equal(t.azimuth, np.pi * a[:, 0])
    np.testing.assert_array_equal(t.elevation, (a[:, 1] + 1) * (np.pi / 4))
    np.testing.assert_array_equal(f.elevation, a[:, 1] * (np.pi / 2))
    np.testing.assert_array_equal(t.roll, np.pi * a[:, 2])
    np.testing.assert_array_equal(t.spread, (a[:, 3] + 1) / 2)
    assert decode_approach(a[0]).azimuth.shape == ()


def test_complex_and_huge_values_are_refused():
    """Complex values used to pass with a ComplexWarning (imaginary part dropped); ints beyond a float's range raised
    an OverflowError."""
    from haptic_env.grasping.base import validate_pose

    with pytest.raises(ValueError, match="actions must be real numbers, got complex"):
        validate_actions(np.array([[0.5 + 0.5j, 0, 0, 0]]))
    with pytest.raises(ValueError, match="action must be real numbers, got complex"):
        validate_action(np.array([0.5 + 0j, 0, 0, 0]))
    with pytest.raises(ValueError, match="action must be"):
        validate_action([0.5j, 0, 0, 0])
    with pytest.raises(ValueError, match="object pose must be real numbers, got complex"):
        validate_pose(np.eye(4) + 0j)
    with pytest.raises(ValueError, match="actions must be finite real numbers, got a value too large for a float"):
        validate_actions([[10 ** 400, 0, 0, 0]])
    with pytest.raises(ValueError, match="action must be finite real numbers, got a value too large for a float"):
        validate_action([10 ** 400, 0, 0, 0])
    pose = np.eye(4).tolist()
    pose[0][3] = 10 ** 400
    with pytest.raises(ValueError, match="object pose must be finite real numbers, got a value too large for a float"):
        validate_pose(pose)


def test_valid_actions_and_poses_pass_unchanged():
    from haptic_env.grasping.base import validate_pose

    a = np.array([[0.5, -1.0, 1.0, 0.0], [1 + 5e-7, 0.25, -0.75, 1]])
    got = validate_actions(a)
    assert got.dtype == np.float64 and got is not a
    np.testing.assert_array_equal(got, np.clip(a, -1, 1))
    np.testing.assert_array_equal(validate_actions(a.astype(np.float32)), np.clip(a.astype(np.float32), -1, 1))
    np.testing.assert_array_equal(validate_actions([[1, 0, -1, 0]]), [[1.0, 0.0, -1.0, 0.0]])
    np.testing.assert_array_equal(validate_action(a[0]), a[0])
    T = np.eye(4)
    T[:3, 3] = [1, 2, 3]
    np.testing.assert_array_equal(validate_pose(T.tolist()), T)
    assert validate_pose(T) is T
