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
    with pytest.raises(TypeError):
        make_backend("geometric", 4, no_such_option=1)
    with pytest.raises(ValueError, match="n_fingers"):
        make_backend("geometric", 1)
