"""Hand-matched training grasps: the hand's own MuJoCo model grasping meshes (generic hand: no data needed)."""

from __future__ import annotations

import numpy as np
import pytest

from haptic_env.dataset import DatasetConfig, build_dataset
from haptic_env.grasp_features import feature_dim
from haptic_env.hand_grasps import hand_grasp_pool, pool_rows
from haptic_env.objects import load_object_set


@pytest.fixture(scope="module")
def two_objects():
    objs = load_object_set("default")
    return objs.subset(("can", "mug"), name="can-mug")


def test_pool_is_cached_and_independent_of_workers(two_objects):
    a = hand_grasp_pool(two_objects, "generic", 3, 12, seed=5, workers=1, progress=False)
    assert a.contacts.shape == (2, 12, 3, 3) and a.touched.shape == (2, 12, 3) and not a.from_cache
    assert a.touched.any() and 0 < a.grasps_per_second
    b = hand_grasp_pool(two_objects, "generic", 3, 12, seed=5, workers=2, cache=False, progress=False)
    np.testing.assert_allclose(a.contacts, b.contacts, atol=1e-9)  # the chunking does not change the grasps
    np.testing.assert_array_equal(a.touched, b.touched)
    again = hand_grasp_pool(two_objects, "generic", 3, 12, seed=5, progress=False)
    assert again.from_cache
    np.testing.assert_array_equal(again.touched, a.touched)
    # touching fingers have unit normals, the others zero rows
    nrm = np.linalg.norm(a.normals, axis=-1)
    np.testing.assert_allclose(nrm[a.touched], 1.0, atol=1e-6)
    assert not a.contacts[~a.touched].any()


def test_pool_rows_take_touching_fingers_only(two_objects):
    pool = hand_grasp_pool(two_objects, "generic", 3, 12, seed=5, progress=False)
    rng = np.random.default_rng(0)
    for z in (2, 3):
        C, N = pool_rows(pool, 0, z, rng)
        assert C.shape == (int((pool.touched[0].sum(1) >= z).sum()), z, 3) and N.shape == C.shape
        np.testing.assert_allclose(np.linalg.norm(N, axis=-1), 1.0, atol=1e-6)  # never a missed finger's zero row
    with pytest.raises(ValueError, match="z must be"):
        pool_rows(pool, 0, 4, rng)


def test_hand_source_dataset(two_objects):
    cfg = DatasetConfig(n_fingers=3, normals=True, grasps_per_object=12, source="hand", hand="generic", seed=5,
                        val_fraction=0.25)
    ds = build_dataset(two_objects, cfg, progress=False)
    assert ds.feature_dim == feature_dim(3, True) and set(ds.y_train) <= {0, 1}
    assert len(ds.X_train) + len(ds.X_val) <= 2 * 12
    assert build_dataset(two_objects, cfg, progress=False).from_cache
    with pytest.raises(ValueError, match="hand"):
        DatasetConfig(source="hand")
    with pytest.raises(ValueError, match="hand"):
        DatasetConfig(source="surface", hand="allegro")
    with pytest.raises(TypeError, match="hand name"):
        hand_grasp_pool(two_objects, object(), 3, 4)
