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
