import numpy as np
import pytest
import trimesh

from haptic_env.grasping import GraspBatch, make_backend
from haptic_env.objects import GraspObject


def _sphere(r=0.04):
    return GraspObject("sphere", trimesh.creation.icosphere(subdivisions=4, radius=r))


def _box():
    return GraspObject("box", trimesh.creation.box([0.06, 0.09, 0.12]))


def _dumbbell():
    a = trimesh.creation.icosphere(subdivisions=3, radius=0.02)
    b = a.copy()
    a.apply_translation([0.06, 0, 0])
    b.apply_translation([-0.06, 0, 0])
    return GraspObject("dumbbell", trimesh.util.concatenate([a, b]))


def _pose():
    T = trimesh.transformations.random_rotation_matrix(np.random.default_rng(3).uniform(size=3))
    T[:3, 3] = [0.3, -0.2, 0.5]
    return T


@pytest.mark.parametrize("make_obj", [_sphere, _box])
@pytest.mark.parametrize("posed", [False, True])
def test_exact_contacts_on_surface_with_inward_normals(make_obj, posed):
    obj = make_obj()
    T = _pose() if posed else np.eye(4)
    be = make_backend("geometric", 4, support="floating")
    be.set_object(obj, T)
    rng = np.random.default_rng(0)
    b = be.grasp_batch(rng.uniform(-1, 1, (300, 4)), rng)
    assert isinstance(b, GraspBatch) and b.contacts.shape == (300, 4, 3) and b.touched.shape == (300, 4)
    assert b.touched.mean() > 0.9
    world = obj.mesh.copy().apply_transform(T)
    pts = b.contacts[b.touched]
    _, dist, tri = trimesh.proximity.closest_point(world, pts)
    assert dist.max() < 1e-3
    n = b.normals[b.touched]
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    # inward: agrees with minus the outward face normal at the closest point
    assert np.mean(np.einsum("ij,ij->i", n, -world.face_normals[tri]) > 0.99) > 0.98


def test_fingers_that_miss_are_reported():
    be = make_backend("geometric", 4, support="floating")
    be.set_object(_dumbbell())
    rng = np.random.default_rng(1)
    b = be.grasp_batch(rng.uniform(-1, 1, (400, 4)), rng)
    miss = ~b.touched
    assert miss.any() and b.touched.any()
    assert np.all(b.contacts[miss] == 0) and np.all(b.normals[miss] == 0)


def test_table_support_hides_the_bottom():
    obj = _box()
    be = make_backend("geometric", 4, support="table")
    be.set_object(obj)
    rng = np.random.default_rng(2)
    b = be.grasp_batch(rng.uniform(-1, 1, (300, 4)), rng)
    z = b.contacts[b.touched][:, 2]
    assert z.min() > obj.mesh.bounds[0, 2] + 1e-3 - 1e-9


def test_same_seed_same_grasp_and_batch_matches_single():
    be = make_backend("geometric", 4, contact_noise=0.001, normal_noise_deg=5.0)
    be.set_object(_box())
    a = np.random.default_rng(5).uniform(-1, 1, (10, 4)).astype(np.float32)
    r1 = be.grasp_batch(a, np.random.default_rng(7))
    r2 = be.grasp_batch(a, np.random.default_rng(7))
    assert np.array_equal(r1.contacts, r2.contacts) and np.array_equal(r1.normals, r2.normals)
    exact = make_backend("geometric", 4)
    exact.set_object(_box())
    batch = exact.grasp_batch(a, np.random.default_rng(0))
    single = exact.grasp(a[3], np.random.default_rng(0))
    assert np.array_equal(single.contacts, batch.contacts[3]) and np.array_equal(single.touched, batch.touched[3])
    assert np.array_equal(single.normals, batch.normals[3])


def test_noise_perturbs_only_touched_and_keeps_unit_normals():
    be = make_backend("geometric", 4, contact_noise=0.002, normal_noise_deg=10.0, support="floating")
    be.set_object(_dumbbell())
    exact = make_backend("geometric", 4, support="floating")
    exact.set_object(_dumbbell())
    a = np.random.default_rng(4).uniform(-1, 1, (3000, 4))  # about 7 % of the fingers touch the dumbbell
    b, e = be.grasp_batch(a, np.random.default_rng(5)), exact.grasp_batch(a, np.random.default_rng(5))
    assert np.array_equal(b.touched, e.touched)  # the noise moves what was sensed, not which fingers touched
    t = b.touched
    assert np.all(b.contacts[~t] == 0) and np.all(b.normals[~t] == 0)
    assert np.allclose(np.linalg.norm(b.normals[t], axis=1), 1.0)
    # its size: contacts off by N(0, 2 mm) per axis, normals tilted by N(0, 10 deg) in their tangent plane
    d = b.contacts[t] - e.contacts[t]
    assert d.size > 1500 and 0.0017 < d.std() < 0.0023 and abs(d.mean()) < 5 * 0.002 / np.sqrt(d.size)
    tilt = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", b.normals[t], e.normals[t]), -1.0, 1.0)))
    assert tilt.min() > 0 and 10.0 < np.median(tilt) < 15.0  # Rayleigh(10 deg): median 11.8 deg


def test_spread_changes_finger_pattern():
    be = make_backend("geometric", 4)
    be.set_object(_sphere())
    rng = np.random.default_rng(0)
    tight = be.grasp(np.array([0.0, 0.0, 0.0, -1.0]), rng).contacts
    wide = be.grasp(np.array([0.0, 0.0, 0.0, 1.0]), rng).contacts
    spread = lambda c: np.linalg.norm(c[:-1] - c[:-1].mean(0), axis=1).mean()  # noqa: E731
    assert spread(wide) > 2 * spread(tight)


def test_requires_object_and_valid_pose():
    be = make_backend("geometric", 3)
    with pytest.raises(RuntimeError, match="set_object"):
        be.grasp(np.zeros(4), np.random.default_rng(0))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match="rigid"):
        be.set_object(_box(), bad)
    with pytest.raises(ValueError, match="nan"):
        be.grasp(np.array([np.nan, 0, 0, 0]), np.random.default_rng(0))


def test_render_matplotlib():
    be = make_backend("geometric", 4)
    be.set_object(_box())
    be.grasp(np.zeros(4), np.random.default_rng(0))
    img = be.render(160, 120)
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8 and img.std() > 0


def test_full_grasps_span_a_polyhedron():
    """The curled closing paths keep 4-finger contacts off a common plane, so Phi_n is defined.

    (A closing pattern in one plane would make every 4-finger grasp coplanar, i.e. degenerate.)
    """
    from haptic_env.grasp_features import phi
    from haptic_env.objects import load_object_set

    objects = load_object_set("default")
    be = make_backend("geometric", n_fingers=4)
    rng = np.random.default_rng(0)
    for name in ("box", "can", "ball", "hammer"):
        be.set_object(objects[name])
        b = be.grasp_batch(rng.uniform(-1, 1, (400, 4)).astype(np.float32), rng)
        full = b.touched.all(axis=1)
        assert full.mean() > 0.5, name
        assert phi(b.contacts[full], b.normals[full]).valid.mean() > 0.99, name


@pytest.mark.parametrize("support", ["table", "floating"])
@pytest.mark.parametrize("make_obj", [_box, _dumbbell])
def test_scale_as_transform_matches_a_scaled_mesh_copy(make_obj, support):
    """``set_object(obj, pose, scale=s)`` grasps exactly like the object with its mesh scaled by ``s``."""
    obj, T = make_obj(), _pose()
    s = 1.37
    scaled = GraspObject(obj.name, obj.mesh.copy().apply_scale(s))
    a_rng = np.random.default_rng(5)
    actions = a_rng.uniform(-1, 1, (400, 4))
    be1 = make_backend("geometric", 4, support=support)
    be1.set_object(obj, T, scale=s)
    be2 = make_backend("geometric", 4, support=support)
    be2.set_object(scaled, T)
    b1 = be1.grasp_batch(actions, np.random.default_rng(0))
    b2 = be2.grasp_batch(actions, np.random.default_rng(0))
    same = (b1.touched == b2.touched).all(axis=1)
    assert same.mean() > 0.99  # float32 Embree may decide a ray grazing an edge differently
    t = b1.touched & same[:, None]
    np.testing.assert_allclose(b1.contacts[t], b2.contacts[t], atol=1e-9)
    np.testing.assert_allclose(b1.normals[t], b2.normals[t], atol=1e-9)
    assert be1.scale == s and be1._radius == pytest.approx(be2._radius)
    assert be1.n_scenes == 1  # the unscaled mesh's scene
    for bad in (0.0, -1.0, float("nan"), "big"):
        with pytest.raises(ValueError, match="scale"):
            be1.set_object(obj, T, scale=bad)


def test_scene_cache_is_bounded_and_keyed_by_mesh():
    """Scenes are reused per mesh and at most MAX_SCENES live: >1013 distinct meshes crashed Embree before."""
    from haptic_env.grasping.geometric import MAX_SCENES

    be = make_backend("geometric", 4)
    obj = _box()
    rng = np.random.default_rng(0)
    for s in rng.uniform(0.8, 1.2, 50):  # one mesh, many scales and poses: one scene
        be.set_object(obj, _pose(), scale=s)
    assert be.n_scenes == 1
    for i in range(1100):  # distinct meshes (e.g. scaled copies): bounded, no crash
        be.set_object(GraspObject("b", obj.mesh.copy()), np.eye(4))
        assert be.n_scenes <= MAX_SCENES
    assert be.grasp(np.zeros(4), rng).touched.any()
    mesh = obj.mesh.copy()
    o = GraspObject("b", mesh)
    be.set_object(o, np.eye(4))
    r0 = be._radius
    mesh.apply_scale(2.0)  # edited in place: the cached tables are rebuilt
    be.set_object(o, np.eye(4))
    assert be._radius == pytest.approx(2 * r0)
    be.close()
    assert be.n_scenes == 1 and be.grasp(np.zeros(4), rng).touched.any()
