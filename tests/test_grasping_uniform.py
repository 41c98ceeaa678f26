import numpy as np
import pytest
import trimesh

from haptic_env.grasping import make_backend
from haptic_env.objects import GraspObject


def test_uniform_points_on_surface_ignore_action_and_are_seeded():
    obj = GraspObject("box", trimesh.creation.box([0.05, 0.07, 0.1]))
    T = np.eye(4)
    T[:3, 3] = [0.1, 0.2, 0.3]
    be = make_backend("uniform", 5)
    be.set_object(obj, T)
    a = np.zeros((50, 4))
    b1 = be.grasp_batch(a, np.random.default_rng(3))
    b2 = be.grasp_batch(a + 0.5, np.random.default_rng(3))  # action ignored
    assert np.array_equal(b1.contacts, b2.contacts)
    assert b1.contacts.shape == (50, 5, 3) and b1.touched.all()
    d = np.abs(trimesh.proximity.signed_distance(obj.mesh.copy().apply_transform(T), b1.contacts.reshape(-1, 3)))
    assert d.max() < 1e-6
    with pytest.raises(ValueError, match="outside"):
        be.grasp(np.array([2.0, 0, 0, 0]), np.random.default_rng(0))


def test_grasping_or_rendering_before_set_object_names_the_call():
    """``render`` before ``set_object`` was an AttributeError on the missing pose; ``grasp_batch`` named the call."""
    be = make_backend("uniform", 4)
    for call in (lambda: be.grasp_batch(np.zeros((1, 4)), np.random.default_rng(0)), lambda: be.render(64, 64)):
        with pytest.raises(RuntimeError, match=r"call set_object\(obj, pose\) before"):
            call()
