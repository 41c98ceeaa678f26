"""Hand-matched training grasps: the hand's own MuJoCo model grasping meshes (generic hand: no data needed)."""

from __future__ import annotations

import numpy as np
import pytest

from haptic_env.dataset import DatasetConfig, build_dataset
from haptic_env.grasp_features import feature_dim
from haptic_env.hand_grasps import balanced_counts, hand_grasp_pool, pool_rows
from haptic_env.objects import load_object_set


@pytest.fixture(scope="module")
def two_objects():
    objs = load_object_set("default")
    return objs.subset(("can", "mug"), name="can-mug")


def test_pool_is_cached_and_independent_of_workers(two_objects, monkeypatch, tmp_path):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))  # its own cache: the first build is a build whatever ran before
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
    for k in (-1, 2, 1.0):  # -1 was the last object without a word, 2 an IndexError
        with pytest.raises(ValueError, match=rf"k must be an object index in \[0, 2\), got {k}"):
            pool_rows(pool, k, 2, rng)
    for w in (-3, 0, 1.7, True, "two"):  # taken (-3, 1.7, True; 0 meant all cores) or a bare int() error
        with pytest.raises(ValueError, match=rf"workers must be an int >= 1, got {w!r}"):
            hand_grasp_pool(two_objects, "generic", 3, 12, seed=5, progress=False, workers=w)


def test_a_hands_key_holds_its_mesh_files_bytes(tmp_path):
    """The MJCF names its mesh files, not their contents: a changed mesh (another Menagerie version, an edited STL)
    kept the hand's key, so its old pools, data sets and recognisers were reused."""
    import mujoco

    from haptic_env.hand_grasps import mesh_files_key

    mesh = tmp_path / "assets" / "tip.obj"
    mesh.parent.mkdir()
    tetra = "v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 0 0 0.01\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    mesh.write_text(tetra)
    xml = tmp_path / "hand.xml"
    xml.write_text('<mujoco><compiler meshdir="assets"/><asset><mesh name="tip" file="tip.obj"/></asset>'
                   '<worldbody><body><geom type="mesh" mesh="tip"/></body></worldbody></mujoco>')
    key = mesh_files_key(mujoco.MjSpec.from_file(str(xml)))
    assert len(key) == 64 and mesh_files_key(mujoco.MjSpec.from_file(str(xml))) == key
    mesh.write_text(tetra.replace("0.01 0 0", "0.02 0 0"))
    assert mesh_files_key(mujoco.MjSpec.from_file(str(xml))) not in ("", key)
    assert mesh_files_key(mujoco.MjSpec.from_string("<mujoco><worldbody/></mujoco>")) == ""  # no meshes: no term


def test_the_dataset_summary_reads_a_cached_pool_and_grasps_none(two_objects, monkeypatch, tmp_path):
    """``haptic-recog dataset`` printed the pool's build time by asking for the pool again: a pool gone from the cache
    (or never saved, in a read-only one) was grasped a second time just for that line."""
    import haptic_env.dataset as dataset
    import haptic_env.hand_grasps as hg
    from haptic_env.cli import main

    import os

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(os, "cpu_count", lambda: 1)  # grasped in this process, where the chunks are counted
    monkeypatch.setattr(dataset, "load_object_set", lambda *a, **k: two_objects)
    chunks = []
    real = hg._grasp_chunk
    monkeypatch.setattr(hg, "_grasp_chunk", lambda *a, **k: chunks.append(1) or real(*a, **k))
    argv = ["dataset", "--objects", "default", "--source", "hand", "--hand", "generic", "--fingers", "2",
            "--hand-fingers", "3", "--grasps", "12", "--quiet"]
    assert main(argv) == 0 and chunks
    for f in (tmp_path / "cache" / "hand_grasps").iterdir():
        f.unlink()
    chunks.clear()
    assert main(argv) == 0 and not chunks  # the data set is a hit; its pool is not rebuilt to print a line


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
    with pytest.raises(ValueError, match="hand name"):
        hand_grasp_pool(two_objects, object(), 3, 4)


def test_hand_vectors_keep_every_row_and_report_objects_the_hand_cannot_grasp(two_objects):
    """``hand_vectors`` gives each object's rows unsplit (the dataset's train + validation rows); an object too small
    for the hand gets no rows there, where ``build_dataset`` refuses it by name."""
    from haptic_env.dataset import hand_vectors
    from haptic_env.objects import family_set

    cfg = DatasetConfig(n_fingers=3, normals=True, grasps_per_object=12, source="hand", hand="generic", seed=5,
                        val_fraction=0.25)
    V = hand_vectors(two_objects, cfg, progress=False)
    ds = build_dataset(two_objects, cfg, progress=False)
    counts = np.bincount(ds.y_train, minlength=2) + np.bincount(ds.y_val, minlength=2)
    assert [len(v) for v in V] == list(counts) and all(v.dtype == np.float32 and v.shape[1] == 9 for v in V)
    np.testing.assert_allclose(np.sort(V[0], axis=0), np.sort(np.concatenate([ds.X_train[ds.y_train == 0],
                                                                              ds.X_val[ds.y_val == 0]]), axis=0))
    # with contacts: the same rows, each with the contacts it was computed from (object frame, on the object)
    from haptic_env.grasp_features import phi

    VC = hand_vectors(two_objects, cfg, progress=False, contacts=True)
    for (X, C), v, obj in zip(VC, V, two_objects):
        np.testing.assert_array_equal(X, v)
        assert C.shape == (len(X), 3, 3)
        np.testing.assert_allclose(phi(C).q, X[:, :3], rtol=1e-4, atol=1e-6)  # the distances, frame-invariant
        assert np.all(np.abs(C) <= obj.extents / 2 + 0.01)  # within the object's box (contacts on its surface)
    tiny = family_set(1, np.random.default_rng(0), scale_range=(0.05, 0.05), families=("ellipsoid",))  # 4 mm
    assert [len(v) for v in hand_vectors(tiny, cfg, progress=False)] == [0]
    with pytest.raises(RuntimeError,
                       match=r"'ellipsoid_00': 0 of its generic grasps \(budget 'uniform', 12 approaches per object\)"):
        build_dataset(tiny, cfg, cache=False, progress=False)


def test_hand_dataset_leaves_out_the_objects_the_hand_cannot_grasp_and_names_them(two_objects):
    """``hand_dataset`` splits the rows of the objects the hand grasps like ``build_dataset`` does and names those it
    left out (labels stay positions in the set), instead of refusing the whole set."""
    from haptic_env.dataset import hand_dataset
    from haptic_env.objects import ObjectSet, family_set

    cfg = DatasetConfig(n_fingers=3, normals=True, grasps_per_object=12, source="hand", hand="generic", seed=5,
                        val_fraction=0.25)
    tiny = family_set(1, np.random.default_rng(0), scale_range=(0.05, 0.05), families=("ellipsoid",))  # 4 mm
    mixed = ObjectSet("can-tiny-mug", [two_objects["can"], tiny[0], two_objects["mug"]])
    ds, left_out = hand_dataset(mixed, cfg, progress=False)
    ref = build_dataset(two_objects, cfg, progress=False)
    assert left_out == {"ellipsoid_00": 0} and ds.names == mixed.names and ds.cache_path is None
    np.testing.assert_array_equal(np.unique(ds.y_train), [0, 2])  # the mug keeps its label 2
    # the first object's approaches and split do not depend on the set's size: the same rows as in build_dataset
    np.testing.assert_array_equal(ds.X_train[ds.y_train == 0], ref.X_train[ref.y_train == 0])
    np.testing.assert_array_equal(ds.X_val[ds.y_val == 0], ref.X_val[ref.y_val == 0])
    with pytest.raises(RuntimeError, match="none of the 1 objects"):
        hand_dataset(tiny, cfg, progress=False)
    with pytest.raises(ValueError, match="min_rows must be an int >= 1, got 0"):
        hand_dataset(two_objects, cfg, min_rows=0)


def test_balanced_counts_spread_the_budget_towards_rarely_complete_objects():
    c = balanced_counts([0.99, 0.45, 0.4, 0.04], 1000)
    assert abs(c.sum() - 4000) <= 4 and c[3] > c[2] > c[1] > c[0]
    assert c[3] / c[0] == pytest.approx(4.0, rel=0.01)  # weights clipped to [1/2, 2]
    np.testing.assert_array_equal(balanced_counts([0.3, 0.3, 0.3], 10), [10, 10, 10])
    assert balanced_counts([0.0, 0.5], 10)[0] > 10  # never completes: the largest weight
    for bad in ([], [1.5], [[0.5]]):
        with pytest.raises(ValueError, match="complete_rate"):
            balanced_counts(bad, 10)
    with pytest.raises(ValueError, match="approaches"):
        balanced_counts([0.5], 0)


def test_balanced_pool_keeps_each_objects_first_approaches(two_objects, monkeypatch, tmp_path):
    """A balanced budget grasps the first chunk of every object, then spreads the rest; an object's first approaches
    are the uniform pool's, approaches beyond its count are never grasped, and the counts survive the cache."""
    import haptic_env.hand_grasps as hg

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))  # a pool of a patched CHUNK stays out of the session's cache
    monkeypatch.setattr(hg, "CHUNK", 4)
    uni = hand_grasp_pool(two_objects, "generic", 3, 8, seed=6, cache=False, workers=1, progress=False)
    bal = hand_grasp_pool(two_objects, "generic", 3, 8, seed=6, budget="balanced", workers=1, progress=False)
    assert bal.counts is not None and bal.counts.min() >= hg.balanced_probe(8) and abs(int(bal.counts.sum()) - 16) <= 2
    np.testing.assert_array_equal(bal.approaches, bal.counts)
    for k in range(2):
        m = min(int(bal.counts[k]), 8)
        np.testing.assert_array_equal(bal.touched[k, :m], uni.touched[k, :m])
        np.testing.assert_allclose(bal.contacts[k, :m], uni.contacts[k, :m], atol=1e-9)
        assert not bal.touched[k, int(bal.counts[k]):].any()
    again = hand_grasp_pool(two_objects, "generic", 3, 8, seed=6, budget="balanced", workers=1, progress=False)
    assert again.from_cache and np.array_equal(again.counts, bal.counts)
    with pytest.raises(ValueError, match="budget"):
        hand_grasp_pool(two_objects, "generic", 3, 8, budget="greedy")
    with pytest.raises(ValueError, match="hand_budget"):
        DatasetConfig(source="hand", hand="generic", hand_budget="greedy")


def test_interrupted_pool_build_resumes_from_its_saved_chunks(two_objects, monkeypatch):
    """A build killed part-way keeps its finished chunks; the next call grasps only the missing ones and gives the
    uninterrupted pool; the chunks' folder is removed once the pool is saved, and an unreadable chunk is regrasped."""
    import haptic_env.hand_grasps as hg

    monkeypatch.setattr(hg, "CHUNK", 4)  # 2 objects x 12 approaches: 6 chunks
    real = hg._grasp_chunk
    calls = []

    def interrupted(*a):
        if len(calls) == 3:
            raise KeyboardInterrupt  # Ctrl-C during the fourth chunk
        calls.append(a[5])  # the chunk's seed
        return real(*a)

    monkeypatch.setattr(hg, "_grasp_chunk", interrupted)
    with pytest.raises(KeyboardInterrupt):
        hand_grasp_pool(two_objects, "generic", 3, 12, seed=7, workers=1, progress=False)
    path = hg.pool_cache_path(two_objects, "generic", 3, 12, "table", 7)
    parts = hg.parts_dir(path)
    assert not path.exists() and len(list(parts.glob("*.npz"))) == 3
    (parts / sorted(p.name for p in parts.glob("*.npz"))[0]).write_bytes(b"not an npz")  # a damaged chunk

    calls.clear()
    monkeypatch.setattr(hg, "_grasp_chunk", lambda *a: calls.append(a[5]) or real(*a))
    with pytest.warns(RuntimeWarning, match="grasping that chunk again"):
        resumed = hand_grasp_pool(two_objects, "generic", 3, 12, seed=7, workers=1, progress=False)
    assert len(calls) == 4  # the 3 chunks never saved and the damaged one
    assert path.exists() and not parts.exists() and not resumed.from_cache
    whole = hand_grasp_pool(two_objects, "generic", 3, 12, seed=7, workers=1, cache=False, progress=False)
    np.testing.assert_array_equal(resumed.touched, whole.touched)
    np.testing.assert_allclose(resumed.contacts, whole.contacts, atol=1e-9)
    np.testing.assert_allclose(resumed.normals, whole.normals, atol=1e-9)
    assert resumed.seconds > 0


def test_a_hand_given_as_a_file_keeps_its_pool_in_the_cache(two_objects):
    """A hand named by its MJCF path caches its pool in the cache's folder (the path made a file name), not next to
    the user's file."""
    from pathlib import Path

    import haptic_env.assets as assets
    from haptic_env.cache import cache_dir
    from haptic_env.hand_grasps import pool_cache_path

    hand = str(Path(assets.__file__).parent / "generic_hand_4.xml")
    path = pool_cache_path(two_objects, hand, 4, 12, "table", 0)
    assert path.parent == cache_dir("hand_grasps") and path.name.endswith(".npz") and "generic_hand_4" in path.name


def test_a_failing_chunk_stops_a_parallel_build_without_grasping_the_rest(two_objects, monkeypatch, tmp_path):
    """An error in one worker's chunk (or an interrupt) cancels the chunks not yet started instead of grasping them
    all and throwing them away (a pool executor's exit waits for every queued task)."""
    import haptic_env.hand_grasps as hg

    monkeypatch.setattr(hg, "CHUNK", 1)  # 2 objects x 12 approaches: 24 chunks
    log = tmp_path / "chunks.log"
    monkeypatch.setenv("HAPTIC_TEST_CHUNK_LOG", str(log))
    monkeypatch.setattr(hg, "_grasp_chunk", _failing_chunk)  # the forked workers see it too
    with pytest.raises(RuntimeError, match="a MuJoCo error in one chunk"):
        hand_grasp_pool(two_objects, "generic", 3, 12, seed=9, workers=2, cache=False, progress=False)
    # the 2 chunks running at the cancel and the executor's call queue (workers + 1) run; without it all 23 others
    assert len(log.read_text()) <= 2 + 3


def test_a_daemonic_process_builds_its_pool_in_process(two_objects):
    """In a daemonic process (an SB3 ``SubprocVecEnv`` worker), which may not start children, a pool is grasped in
    that process instead of failing on the process pool's start."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    out = ctx.Queue()
    worker = ctx.Process(target=_pool_in_a_daemon, args=(two_objects, out), daemon=True)
    worker.start()
    worker.join(180)
    assert out.get(timeout=10) == (2, 4, 3)


def _pool_in_a_daemon(objects, out) -> None:
    try:
        pool = hand_grasp_pool(objects, "generic", 3, 4, seed=11, workers=2, cache=False, progress=False)
        out.put(pool.touched.shape)
    except BaseException as exc:  # noqa: BLE001 - reported to the test
        out.put(repr(exc))


def _failing_chunk(obj, hand, n, support, actions, seed, solid_table=False):
    """A stand-in for ``_grasp_chunk`` (module level: a worker's task is pickled by name): the first chunk of object
    0 fails; every other one takes 0.5 s (long beside the main process's reaction to the failure, even on a loaded
    machine) and leaves a mark in the log."""
    import os
    import time

    if seed[1:] == [0, 0]:
        raise RuntimeError("a MuJoCo error in one chunk")
    time.sleep(0.5)
    with open(os.environ["HAPTIC_TEST_CHUNK_LOG"], "a") as fh:
        fh.write("x")
    m = len(actions)
    return np.zeros((m, n, 3)), np.zeros((m, n, 3)), np.zeros((m, n), bool), 0.05


def test_heights_information_benchmark_features(load_benchmark):
    """benchmarks/heights_information.py: its three feature sets of a pool, from the same grasps (synthetic pool)."""
    from haptic_env.grasp_features import feature_dim
    from haptic_env.hand_grasps import HandGraspPool
    from haptic_env.objects import load_object_set

    bench = load_benchmark("heights_information")
    objects = load_object_set("default").subset(["box", "mug"], name="two")
    rng = np.random.default_rng(0)
    C = rng.normal(0, 0.03, (2, 40, 4, 3))
    N = rng.normal(size=C.shape)
    T = rng.random((2, 40, 4)) < 0.8
    pool = HandGraspPool(C, N, T, tuple(objects.names), "generic", 0.0)
    X, y = bench.features(pool, objects, 0, 4, True, np.random.default_rng(1))
    assert set(X) == set(bench.FEATURES) and len(y) == len(X["phi"]) == int(T.all(-1).sum())
    d = feature_dim(4, True)
    assert X["phi"].shape[1] == d and X["phi+heights"].shape[1] == d + 4 and X["phi+approach"].shape[1] == d + 4
    np.testing.assert_array_equal(X["phi+heights"][:, :d], X["phi"])
    X3, y3 = bench.features(pool, objects, 0, 3, False, np.random.default_rng(1))
    assert "phi+approach" not in X3 and X3["phi+heights"].shape[1] == feature_dim(3, False) + 3
    acc = bench.one_shot((X, y), [(X, y)], "phi+heights")
    assert acc.shape == (1,) and acc[0] == 1.0  # its own grasps: distance-weighted neighbours are exact


def test_pose_information_benchmark_scores_turned_pairs(load_benchmark):
    """benchmarks/pose_information.py: each pair of a validation pool's grasps is turned by one yaw (contacts and
    approach azimuth alike), and records that are the pool's own grasps identify the object and put the yaw posterior
    on the turn (synthetic pool, distinct objects)."""
    from scipy.spatial import cKDTree

    from haptic_env.grasping.replay import approach_embedding
    from haptic_env.hand_grasps import HandGraspPool, pool_actions

    bench = load_benchmark("pose_information")
    rng = np.random.default_rng(0)
    C = rng.normal(0, 0.04, (2, 12, 4, 3))
    C[1] += [0.1, 0.0, 0.05]  # the second object's contacts sit elsewhere
    T = np.ones((2, 12, 4), dtype=bool)
    pool = HandGraspPool(C, np.zeros_like(C), T, ("a", "b"), "generic", 0.0)
    pairs = list(bench.turned_queries(pool, 7, 1, np.random.default_rng(3)))
    assert len(pairs) == 6
    psi, ((a0, c0, t0), (a1, c1, t1)) = pairs[0]
    acts = pool_actions(7, 1, 12)
    R = np.array([[np.cos(psi), -np.sin(psi), 0], [np.sin(psi), np.cos(psi), 0], [0, 0, 1]])
    np.testing.assert_allclose(c0, C[1, 0] @ R.T)
    np.testing.assert_allclose(c1, C[1, 1] @ R.T)
    np.testing.assert_allclose(np.mod(a0[0] - acts[0, 0] - psi / np.pi + 1.0, 2.0) - 1.0, 0.0, atol=1e-12)
    np.testing.assert_array_equal(a0[1:], acts[0, 1:])
    records = [(cKDTree(approach_embedding(pool_actions(7, k, 12))), C[k], np.zeros_like(C[k]), T[k]) for k in (0, 1)]
    out = bench.score_pool(records, pool, 7, np.arange(360) * np.pi / 180, 0.005, 1)
    assert out["one"] == out["one_complete"] == out["naive2"] == out["joint2"] == 1.0
    assert out["mass2"].shape == (2,) and np.all(out["mass2"] > 0.9)


def test_an_uncached_hand_dataset_neither_reads_nor_writes_its_pool_and_too_few_grasps_are_a_usage_error(
        two_objects, monkeypatch, usage_error):
    """``build_dataset(cache=False)`` (``dataset --no-cache``) with the hand source asks for its pool uncached (it read
    and wrote the pool cache), and too few grasps for ``--grasps`` / ``--fingers`` are a one-line usage error, not a
    traceback (synthetic pool: no grasping)."""
    import haptic_env.hand_grasps as hg
    from haptic_env.cli import main
    from haptic_env.hand_grasps import HandGraspPool

    asked = []

    def fake_pool(objects, hand, n_fingers, approaches, *, cache=True, **kw):
        asked.append(cache)
        T = np.zeros((len(objects), approaches, n_fingers), bool)
        T[1:, :1] = True  # the first object never grasped with every finger, the others once
        C = np.random.default_rng(0).normal(0, 0.03, T.shape + (3,))
        return HandGraspPool(C, np.tile([0.0, 0.0, 1.0], T.shape + (1,)), T, tuple(objects.names), hand, 0.0)

    monkeypatch.setattr(hg, "hand_grasp_pool", fake_pool)
    cfg = DatasetConfig(n_fingers=3, grasps_per_object=12, source="hand", hand="generic")
    with pytest.raises(RuntimeError, match=f"'{two_objects.names[0]}': 0 of its generic grasps"):
        build_dataset(two_objects, cfg, cache=False, progress=False)
    assert asked == [False]
    usage_error(main, ["dataset", "--objects", "default", "--fingers", "3", "--source", "hand", "--hand", "generic",
                       "--grasps", "12", "--no-cache", "--quiet"],
                match=r"error: object '\w+': 0 of its generic grasps .* use more approaches or fewer fingers "
                      r"\(--grasps, --fingers\)")
    assert asked == [False, False]


def test_an_object_with_one_complete_grasp_keeps_it_for_training(two_objects, monkeypatch):
    """The Aero's plate on a solid table: 1 complete grasp in 6,000 approaches. The data set keeps it (training only,
    no validation row) instead of refusing the object; an object with none is still refused (test above)."""
    import haptic_env.hand_grasps as hg
    from haptic_env.hand_grasps import HandGraspPool

    def fake_pool(objects, hand, n_fingers, approaches, *, cache=True, **kw):
        T = np.zeros((len(objects), approaches, n_fingers), bool)
        T[0, :1] = True
        T[1, :] = True
        C = np.random.default_rng(0).normal(0, 0.03, T.shape + (3,))
        return HandGraspPool(C, np.tile([0.0, 0.0, 1.0], T.shape + (1,)), T, tuple(objects.names), hand, 0.0)

    monkeypatch.setattr(hg, "hand_grasp_pool", fake_pool)
    cfg = DatasetConfig(n_fingers=3, grasps_per_object=20, source="hand", hand="generic")
    ds = build_dataset(two_objects, cfg, cache=False, progress=False)
    assert np.bincount(ds.y_train, minlength=2)[0] == 1 and 0 not in ds.y_val
    assert np.bincount(ds.y_train, minlength=2)[1] + np.bincount(ds.y_val, minlength=2)[1] == 20
    # however large the validation share, an object keeps a training row (round(0.9 x 1) sent its one row away)
    wide = build_dataset(two_objects, DatasetConfig(n_fingers=3, grasps_per_object=20, source="hand", hand="generic",
                                                    val_fraction=0.9), cache=False, progress=False)
    assert np.bincount(wide.y_train, minlength=2).tolist() == [1, 2] and 0 not in wide.y_val


def _rate_chunk(obj, hand, n, support, actions, seed, solid_table=False):
    """A stand-in for ``_grasp_chunk``: a grasp is complete where its first action value is below the object's rate
    (``can`` 1.0, else 0.1 of the range [-1, 1]), so the rates are known and no hand grasps anything."""
    m = len(actions)
    T = np.repeat((actions[:, :1] < (1.0 if obj.name == "can" else -0.8)), n, axis=1)
    return np.zeros((m, n, 3)), np.zeros((m, n, 3)), T, 0.01


@pytest.mark.parametrize("approaches", [40, 1200])
def test_a_balanced_budget_keeps_its_total_whatever_the_chunk(two_objects, monkeypatch, approaches):
    """A balanced pool keeps the total (K x approaches): its first phase grasped min(CHUNK, approaches) of every object
    and no count went below it, so 2 x 40 approaches became 96 (CHUNK 1000; 80 at CHUNK 20, under the same key).
    The counts do not depend on CHUNK now, and the cache keys of the pool and of its data set hold the probe."""
    import haptic_env.hand_grasps as hg

    monkeypatch.setattr(hg, "_grasp_chunk", _rate_chunk)
    counts = []
    for chunk in (1000, 20, 7):
        monkeypatch.setattr(hg, "CHUNK", chunk)
        pool = hand_grasp_pool(two_objects, "generic", 3, approaches, seed=1, budget="balanced", workers=1,
                               cache=False, progress=False)
        counts.append(pool.counts)
    assert all(np.array_equal(c, counts[0]) for c in counts), counts
    assert abs(int(counts[0].sum()) - 2 * approaches) <= 2 and counts[0][0] < approaches < counts[0][1]
    cfg = DatasetConfig(n_fingers=3, grasps_per_object=approaches, source="hand", hand="generic",
                        hand_budget="balanced")
    keys = [(hg.pool_cache_path(two_objects, "generic", 3, approaches, "table", 0, "balanced"), cfg.source_key())]
    monkeypatch.setattr(hg, "PROBE", 3)  # another first phase: other pools, other keys
    keys.append((hg.pool_cache_path(two_objects, "generic", 3, approaches, "table", 0, "balanced"), cfg.source_key()))
    assert keys[0][0] != keys[1][0] and keys[0][1] != keys[1][1]
    uniform = DatasetConfig(n_fingers=3, grasps_per_object=approaches, source="hand", hand="generic")
    # the uniform budget's: the pools' version and the hand's physics (a new pool version gives new data sets too)
    assert uniform.source_key() == f"{hg.POOL_VERSION}:{hg.hand_physics_key('generic', 3)}"


_KILLED_BUILD = """
import os, sys, time
import haptic_env.grasping.collision as collision
import haptic_env.hand_grasps as hg
from haptic_env.objects import load_object_set

def chunk(obj, hand, n, support, actions, seed, solid_table=False):  # a worker marks itself and grasps for good
    with open(sys.argv[1], "a") as fh:
        fh.write(f"{os.getpid()}\\n")
    time.sleep(600)

hg._grasp_chunk = chunk  # the forked workers see it
collision.convex_pieces = lambda obj: None
hg.hand_grasp_pool(load_object_set("default").subset(("can", "mug"), name="two"), "generic", 3, 4, workers=2,
                   cache=False, progress=False)
"""


def test_the_workers_of_a_build_killed_alone_end_with_it(tmp_path):
    """A parallel pool build whose process is killed alone (SIGKILL: no clean-up runs) leaves no worker grasping: the
    workers get SIGTERM from the kernel when their parent dies (they ran on forever)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    marks = tmp_path / "workers"
    proc = subprocess.Popen([sys.executable, "-c", _KILLED_BUILD, str(marks)])
    pids: list[int] = []
    try:
        t0 = time.monotonic()
        while len(pids) < 2 and time.monotonic() - t0 < 120:
            time.sleep(0.2)
            pids = [int(p) for p in marks.read_text().split()] if marks.exists() else []
        assert len(pids) == 2, "the workers did not start"
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        t0 = time.monotonic()
        while any(_alive(p) for p in pids) and time.monotonic() - t0 < 10:
            time.sleep(0.1)
        assert not any(_alive(p) for p in pids), "a worker outlived its killed parent"
    finally:
        proc.kill()
        for p in pids:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


def _alive(pid: int) -> bool:
    """The process runs (not gone, not a zombie awaiting its reaper)."""
    from pathlib import Path

    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.parametrize("cache", [False, True])
def test_a_bad_hand_or_support_is_named_before_any_work(two_objects, monkeypatch, cache):
    """An unknown hand or a bad support is refused before the meshes are decomposed and the workers start (without
    the cache both were found only in the workers, with it the support)."""
    import haptic_env.grasping.collision as collision
    import haptic_env.hand_grasps as hg

    def work(*a, **kw):
        raise AssertionError("the work started")

    monkeypatch.setattr(collision, "convex_pieces", work)
    monkeypatch.setattr(hg, "_grasp_chunk", work)
    for kw, why in (({"hand": "no_such_hand"}, "unknown hand 'no_such_hand'"),
                    ({"support": "wall"}, "support must be 'table' or 'floating', got 'wall'")):
        with pytest.raises(ValueError, match=why):
            hand_grasp_pool(two_objects, **{"hand": "generic", **kw}, n_fingers=3, approaches=4, workers=2,
                            cache=cache, progress=False)


def test_the_table_is_solid_by_default_and_the_visual_one_keeps_its_keys(two_objects, monkeypatch, tmp_path):
    """The table is solid by default (since 2026-12-07) in the pool's grasps (the hand no longer reaches into it),
    its cache key (the visual table's pools, the default before, keep their keys, and the solid table's keep the keys
    they had when it was opt-in), the hand data set and an env's hand-matched recogniser."""
    import json

    from haptic_env.cache import _jsonable, config_key
    from haptic_env.config import HapticRecogConfig, recognizer_kwargs
    from haptic_env.dataset import dataset_cache_path
    from haptic_env.hand_grasps import POOL_VERSION, hand_physics_key, pool_cache_path

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))
    mug = two_objects.subset(("mug",), name="mug")
    visual = hand_grasp_pool(mug, "generic", 3, 10, seed=5, workers=1, cache=False, progress=False, solid_table=False)
    solid = hand_grasp_pool(mug, "generic", 3, 10, seed=5, workers=1, cache=False, progress=False)
    assert not np.array_equal(visual.touched, solid.touched) or not np.allclose(visual.contacts, solid.contacts)
    key = pool_cache_path(mug, "generic", 3, 10, "table", 5)
    assert pool_cache_path(mug, "generic", 3, 10, "table", 5, solid_table=True) == key
    visual_key = pool_cache_path(mug, "generic", 3, 10, "table", 5, solid_table=False)
    assert visual_key != key and visual_key.name.endswith(config_key(  # the key it had as the default
        POOL_VERSION, mug.identity, "generic", 3, 10, "table", 5, hand_physics_key("generic", 3)) + ".npz")
    assert pool_cache_path(mug, "generic", 3, 10, "floating", 5) == pool_cache_path(
        mug, "generic", 3, 10, "floating", 5, solid_table=False)  # no table to make solid
    with pytest.raises(ValueError, match="solid_table needs support='table'"):
        hand_grasp_pool(mug, "generic", 3, 10, support="floating", solid_table=True, cache=False, progress=False)
    cfg = DatasetConfig(n_fingers=3, source="hand", hand="generic", grasps_per_object=10)
    assert dataset_cache_path(mug, cfg) == dataset_cache_path(mug, DatasetConfig(
        n_fingers=3, source="hand", hand="generic", grasps_per_object=10, solid_table=True))
    visual_cfg = DatasetConfig(n_fingers=3, source="hand", hand="generic", grasps_per_object=10, solid_table=False)
    assert dataset_cache_path(mug, cfg) != dataset_cache_path(mug, visual_cfg)
    assert "solid_table" not in json.dumps(_jsonable(visual_cfg.key_config()))  # unkeyed, as when it was the default
    for bad in ({"solid_table": True}, {"solid_table": False},
                {"source": "hand", "hand": "generic", "support": "floating", "solid_table": True},
                {"source": "hand", "hand": "generic", "solid_table": 1}):
        with pytest.raises(ValueError, match="solid_table"):
            DatasetConfig(**bad)
    env = HapticRecogConfig(backend="mujoco", backend_kwargs={"hand": "allegro", "solid_table": False}, objects="ycb10")
    assert recognizer_kwargs(env)["config"].grasps.solid_table is False
    plain = HapticRecogConfig(backend="mujoco", backend_kwargs={"hand": "allegro"}, objects="ycb10")
    grasps = recognizer_kwargs(plain)["config"].grasps
    assert grasps.solid_table is None and grasps.key_config().solid_table is True


def test_the_dataset_commands_visual_table_flag_reaches_the_pool(monkeypatch):
    """``haptic-recog dataset --source hand --visual-table`` asks for the visual table's pool; without it the default
    (solid wherever there is a table). Synthetic pool: no grasping."""
    import haptic_env.hand_grasps as hg
    from haptic_env.cli import main

    asked = []

    def fake_pool(objects, hand, n_fingers, approaches, **kw):
        asked.append(kw.get("solid_table"))
        raise RuntimeError("pooled")

    monkeypatch.setattr(hg, "hand_grasp_pool", fake_pool)
    base = ["dataset", "--objects", "default", "--fingers", "3", "--source", "hand", "--hand", "generic", "--grasps",
            "4", "--no-cache", "--quiet"]
    for extra in ([], ["--visual-table"]):
        with pytest.raises(RuntimeError, match="pooled"):
            main([*base, *extra])
    assert asked == [None, False]
