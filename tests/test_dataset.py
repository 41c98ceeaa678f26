"""Tests of haptic_env.dataset: grasp sampling, sensing model, dataset building, cache, CLI."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from haptic_env import cache as cache_mod
from haptic_env.cli import main as cli_main
from haptic_env.dataset import (
    DatasetConfig,
    build_dataset,
    dataset_cache_path,
    grasp_vectors,
    held_grasps,
    sample_grasps,
)
from haptic_env.force_closure import force_closure
from haptic_env.grasp_features import feature_dim, phi
from haptic_env.objects import load_object_set


@pytest.fixture(scope="module")
def objects():
    return load_object_set("default").subset(["box", "mug", "ball"], name="tiny")


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))


def test_sample_grasps_shapes_and_determinism(objects):
    mug = objects["mug"]
    C, N = sample_grasps(mug, 100, 5, np.random.default_rng(0))
    assert C.shape == N.shape == (100, 5, 3)
    C2, N2 = sample_grasps(mug, 100, 5, np.random.default_rng(0))
    np.testing.assert_array_equal(C, C2)
    np.testing.assert_array_equal(N, N2)
    Cc, Nc = sample_grasps(mug, 10, 3, np.random.default_rng(0), sampling="centroid")
    assert Cc.shape == (10, 3, 3)
    # the paper's protocol: every contact is the centre of a face, with that face's normal (inward or outward)
    centres, normals = mug.mesh.triangles_center, mug.mesh.face_normals
    d = np.linalg.norm(Cc.reshape(-1, 1, 3) - centres[None], axis=-1)
    face = d.argmin(1)
    assert d.min(1).max() < 1e-9
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", Nc.reshape(-1, 3), normals[face])), 1.0, atol=1e-9)


@pytest.mark.parametrize("n,normals", [(3, False), (4, True), (5, True), (2, True)])
def test_grasp_vectors_dim_and_noise_free_equals_phi(objects, n, normals):
    cfg = DatasetConfig(n_fingers=n, normals=normals)
    C, N = sample_grasps(objects["box"], 200, n, np.random.default_rng(1))
    X, valid = grasp_vectors(C, N, cfg)
    assert X.shape == (200, feature_dim(n, normals)) and valid.shape == (200,)
    ref = phi(C, N if normals else None)
    np.testing.assert_array_equal(X, ref.q)
    np.testing.assert_array_equal(valid, ref.valid)


def test_grasp_vectors_sensing_model(objects):
    C, N = sample_grasps(objects["mug"], 300, 4, np.random.default_rng(2))
    base = DatasetConfig(n_fingers=4, normals=True)
    X0, v0 = grasp_vectors(C, N, base)
    # noise changes vectors, reproducibly with the same rng seed
    noisy = DatasetConfig(n_fingers=4, contact_noise=1e-3, normal_noise_deg=5.0)
    Xa, _ = grasp_vectors(C, N, noisy, rng=np.random.default_rng(3))
    Xb, _ = grasp_vectors(C, N, noisy, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(Xa, Xb)
    assert not np.allclose(Xa, X0)
    # a random object scale changes lengths but normalisation removes it (Theorem 2)
    sc = DatasetConfig(n_fingers=4, scale_range=(0.5, 3.0), normalize_scale=True)
    Xs, vs = grasp_vectors(C, N, sc, rng=np.random.default_rng(4))
    Xn, vn = grasp_vectors(C, N, DatasetConfig(n_fingers=4, normalize_scale=True))
    ok = vs & vn
    np.testing.assert_allclose(Xs[ok], Xn[ok], atol=1e-8)
    Xu, _ = grasp_vectors(C, N, DatasetConfig(n_fingers=4, scale_range=(2.0, 2.0)))
    assert np.allclose(Xu[v0, 0], 2.0 * X0[v0, 0])  # first value is a length
    with pytest.raises(ValueError, match="normals"):
        grasp_vectors(C, None, base)
    with pytest.raises(ValueError, match=r"\(G, 5, 3\)"):
        grasp_vectors(C, N, DatasetConfig(n_fingers=5))


def test_tilted_normals_keep_unit_length_and_angle(objects):
    from haptic_env.dataset import _tilt

    _, N = sample_grasps(objects["ball"], 2000, 1, np.random.default_rng(5))
    N = N[:, 0]
    T = _tilt(N, np.deg2rad(10.0), np.random.default_rng(6))
    np.testing.assert_allclose(np.linalg.norm(T, axis=1), 1.0, atol=1e-12)
    ang = np.degrees(np.arccos(np.clip(np.sum(T * N, 1), -1, 1)))
    assert 6.0 < np.sqrt(np.mean(ang**2)) < 14.0  # rms tilt ~ 10 deg


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"n_fingers": 1}, "n_fingers"),
        ({"grasps_per_object": 0}, "grasps_per_object"),
        ({"contact_noise": float("nan")}, "contact_noise"),
        ({"normal_noise_deg": -1.0}, "normal_noise_deg"),
        ({"scale_range": (2.0, 1.0)}, "scale_range"),
        ({"sampling": "vertex"}, "sampling"),
        ({"val_fraction": 1.0}, "val_fraction"),
        ({"force_closure": 0.0}, "force_closure"),
        ({"force_closure": float("inf")}, "force_closure"),
        ({"force_closure": "0.5"}, "force_closure"),
        ({"force_closure": 0.5, "n_fingers": 2}, "n_fingers"),
        ({"force_closure": 0.5, "source": "geometric"}, "source"),
    ],
)
def test_config_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        DatasetConfig(**kwargs)


def test_build_dataset_shapes_split_and_cache(objects):
    cfg = DatasetConfig(n_fingers=4, normals=True, grasps_per_object=500, val_fraction=0.2, seed=3)
    ds = build_dataset(objects, cfg, progress=False)
    d = feature_dim(4, True)
    assert ds.X_train.shape == (1200, d) and ds.X_val.shape == (300, d)
    assert ds.X_train.dtype == np.float32 and ds.y_train.dtype == np.int64
    assert ds.counts() == {n: (400, 100) for n in objects.names}
    assert np.isfinite(ds.X_train).all() and not (ds.X_train == 0).all(axis=1).any()  # no invalid rows
    assert not ds.from_cache and ds.cache_path.exists()
    assert ds.cache_path == dataset_cache_path(objects, cfg)
    hit = build_dataset(objects, cfg, progress=False)
    assert hit.from_cache
    np.testing.assert_array_equal(hit.X_train, ds.X_train)
    np.testing.assert_array_equal(hit.y_val, ds.y_val)
    # a different config or object set is a miss
    other = build_dataset(objects, DatasetConfig(n_fingers=4, grasps_per_object=500, seed=4), progress=False)
    assert not other.from_cache and other.cache_path != ds.cache_path
    assert not np.array_equal(other.X_train, ds.X_train)
    sub = objects.subset(["box", "mug"], name="tiny")
    assert dataset_cache_path(sub, cfg) != ds.cache_path
    # no cache: same data, nothing written
    nc = build_dataset(objects, cfg, cache=False, progress=False)
    assert nc.cache_path is None
    np.testing.assert_array_equal(nc.X_train, ds.X_train)


def test_corrupted_cache_is_rebuilt_with_warning(objects):
    cfg = DatasetConfig(n_fingers=3, normals=False, grasps_per_object=200)
    path = dataset_cache_path(objects, cfg)
    path.write_bytes(b"PK\x03\x04 truncated garbage")
    with pytest.warns(RuntimeWarning, match="corrupted"):
        ds = build_dataset(objects, cfg, progress=False)
    assert not ds.from_cache and ds.X_train.shape == (480, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert build_dataset(objects, cfg, progress=False).from_cache  # repaired file


def test_cache_with_wrong_shapes_is_rebuilt(objects):
    cfg = DatasetConfig(n_fingers=3, normals=False, grasps_per_object=100)
    path = dataset_cache_path(objects, cfg)
    z = np.zeros((5, 7), np.float32)
    cache_mod.save_npz_atomic(path, X_train=z, y_train=np.zeros(5, np.int64), X_val=z, y_val=np.zeros(5, np.int64),
                              names=np.array(objects.names))
    with pytest.warns(RuntimeWarning, match="X_train"):
        ds = build_dataset(objects, cfg, progress=False)
    assert ds.X_train.shape[1] == 3


def test_failed_write_leaves_no_partial_file(objects, monkeypatch):
    cfg = DatasetConfig(n_fingers=4, grasps_per_object=50)
    path = dataset_cache_path(objects, cfg)

    def boom(fh, **arrays):
        fh.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(cache_mod.np, "savez_compressed", boom)
    with pytest.raises(OSError, match="disk full"):
        build_dataset(objects, cfg, progress=False)
    assert list(path.parent.iterdir()) == []


def test_cli_dataset_smoke(tmp_path, capsys):
    out = tmp_path / "ds.npz"
    argv = ["dataset", "--objects", "default", "--fingers", "3", "--grasps", "60", "--noise", "0.001",
            "--normalize-scale", "--scale-range", "0.5", "2", "--out", str(out), "--seed", "1", "--quiet"]
    assert cli_main(argv) == 0
    text = capsys.readouterr().out
    assert "X_train (432, 9)" in text and "mug" in text and "(written)" in text and "seconds:" in text
    with np.load(out) as z:
        assert z["X_train"].shape == (432, 9) and list(z["names"])[:2] == ["box", "can"]
    assert cli_main(argv) == 0
    assert "(hit)" in capsys.readouterr().out


def test_cli_dataset_force_closure(capsys, usage_error):
    argv = ["dataset", "--objects", "default", "--fingers", "3", "--grasps", "40", "--no-cache", "--quiet"]
    assert cli_main([*argv, "--force-closure", "0.5"]) == 0
    assert "X_train (288, 9)" in capsys.readouterr().out
    usage_error(cli_main, [*argv, "--force-closure", "0"],
                match=r"error: argument --force-closure: must be a finite number in \(0.0, inf\], got 0")
    with pytest.raises(SystemExit):
        cli_main([*argv[:3], "--fingers", "2", "--force-closure", "0.5"])
    assert "n_fingers >= 3" in capsys.readouterr().err
    # taken and ignored before: surface sampling for other sources, normal noise without normals
    usage_error(cli_main, [*argv, "--source", "geometric", "--sampling", "centroid"],
                match=r"--sampling centroid samples surface points: it needs --source surface, got --source geometric")
    usage_error(cli_main, [*argv, "--no-normals", "--normal-noise", "5"],
                match=r"--normal-noise 5 tilts the normals that --no-normals leaves out")


def test_cli_dataset_folder_and_no_normals(tmp_path, capsys):
    import trimesh

    folder = tmp_path / "meshes"
    folder.mkdir()
    trimesh.creation.box(extents=(40, 60, 80)).export(folder / "block.stl")
    trimesh.creation.icosphere(radius=30).export(folder / "orb.stl")
    assert cli_main(["dataset", "--objects", str(folder), "--units", "mm", "--no-normals", "--fingers", "4",
                     "--grasps", "50", "--no-cache", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "X_train (80, 6)" in text and "orb" in text and "(disabled)" in text
    assert not (Path(tmp_path) / "cache" / "datasets").exists() or not any((tmp_path / "cache" / "datasets").iterdir())


def test_geometric_source_matches_approach_model(tmp_path, monkeypatch):
    """source="geometric": contacts are where the geometric hand touches, on the surface, with subsets."""
    import trimesh

    from haptic_env.dataset import approach_grasps

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))
    objects = load_object_set("default").subset(["box", "ball"])
    rng = np.random.default_rng(0)
    C, N = approach_grasps(objects["box"], 400, 3, rng, hand_fingers=5)
    assert C.shape[1:] == (3, 3) and N.shape == C.shape and 0.3 * 400 < len(C) <= 400
    d = np.abs(trimesh.proximity.signed_distance(objects["box"].mesh, C.reshape(-1, 3) * 1.0))
    assert np.quantile(d, 0.99) < 1e-4
    cfg = DatasetConfig(n_fingers=3, grasps_per_object=300, source="geometric", hand_fingers=5, seed=1)
    ds = build_dataset(objects, cfg, progress=False)
    assert ds.X_train.shape[1] == cfg.feature_dim and np.isfinite(ds.X_train).all()
    assert sum(ds.counts()["box"]) == 300
    surf = build_dataset(objects, DatasetConfig(n_fingers=3, grasps_per_object=300, seed=1), progress=False)
    assert surf.cache_path != ds.cache_path  # the source is part of the cache key
    with pytest.raises(ValueError, match="hand_fingers must be an int >= n_fingers=3"):
        DatasetConfig(n_fingers=3, source="geometric", hand_fingers=2)
    with pytest.raises(ValueError, match="source must be one of"):
        DatasetConfig(source="robot")


def test_heights_dataset_measures_contacts_from_the_table(objects):
    """DatasetConfig(heights=True): every vector ends with its contacts' heights above the table the object rests on
    (the lowest mesh vertex), in Phi's chain order; the rest is the plain dataset's vector."""
    from haptic_env.dataset import support_frame

    mug = objects["mug"]
    cfg = DatasetConfig(n_fingers=4, normals=True, heights=True, grasps_per_object=60)
    assert cfg.feature_dim == feature_dim(4, True) + 4
    C, N = sample_grasps(mug, 50, 4, np.random.default_rng(3))
    S = support_frame(C, mug, cfg)
    zmin = np.asarray(mug.mesh.vertices)[:, 2].min()
    np.testing.assert_allclose(S[..., 2], C[..., 2] - zmin)
    assert support_frame(C, mug, DatasetConfig(n_fingers=4)) is C
    X, valid = grasp_vectors(S, N, cfg)
    f = phi(C, N)
    np.testing.assert_allclose(X[:, :f.q.shape[1]], f.q, atol=1e-9)
    np.testing.assert_allclose(X[valid, f.q.shape[1]:], np.take_along_axis(C[..., 2] - zmin, f.order, 1)[valid])
    assert (X[valid, f.q.shape[1]:] >= -1e-9).all()  # nothing below the table
    ds = build_dataset(objects, cfg, progress=False)
    assert ds.X_train.shape[1] == cfg.feature_dim
    with pytest.raises(ValueError, match="heights must be a bool"):
        DatasetConfig(heights="yes")


def test_force_closure_dataset_keeps_held_grasps_and_older_keys(objects):
    # unset, the new field leaves the cache key of every config made before it existed
    plain = DatasetConfig(n_fingers=3, grasps_per_object=300, seed=2)
    assert "force_closure" not in cache_mod._jsonable(plain)
    assert dataset_cache_path(objects, plain) == dataset_cache_path(objects, DatasetConfig(
        n_fingers=3, grasps_per_object=300, seed=2, force_closure=None))
    held = DatasetConfig(n_fingers=3, grasps_per_object=300, seed=2, force_closure=0.5)
    assert held.force_closure == 0.5 and dataset_cache_path(objects, held) != dataset_cache_path(objects, plain)
    # held_grasps returns only grasps in force closure, fewer than asked
    C, N = held_grasps(objects[1], 2000, 3, np.random.default_rng(0), 0.5, chunk=700)
    assert 0 < len(C) < 2000 and C.shape[1:] == (3, 3) and N.shape == C.shape
    assert force_closure(C, N, 0.5).all()
    C16, N16 = held_grasps(objects[1], 2000, 3, np.random.default_rng(0), 0.5, edges=16)  # finer pyramids
    assert force_closure(C16, N16, 0.5, 16).all() and len(C16) != len(C)
    # the dataset gets its full count from them, and other vectors than the plain one
    ds, ref = build_dataset(objects, held, progress=False), build_dataset(objects, plain, progress=False)
    assert ds.counts() == ref.counts() and ds.X_train.shape == ref.X_train.shape
    assert np.isfinite(ds.X_train).all() and not np.allclose(ds.X_train, ref.X_train)


def test_an_interrupted_force_closure_dataset_resumes_at_its_first_unfinished_object(objects, tmp_path, monkeypatch):
    """Force-closure grasps are slow, so each object's split is kept while the set builds: a build interrupted at the
    third object resumes there and gives the uninterrupted build's arrays; the parts are gone once the set is saved."""
    import haptic_env.dataset as dataset

    cfg = DatasetConfig(n_fingers=3, grasps_per_object=120, seed=4, force_closure=0.5)
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "whole"))
    whole = build_dataset(objects, cfg, progress=False)
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cut"))
    real, made = dataset._object_grasps, []

    def grasps(obj, config, rng):
        if len(made) == 2 and not made_once:
            raise KeyboardInterrupt
        made.append(obj.name)
        return real(obj, config, rng)

    made_once = False
    monkeypatch.setattr(dataset, "_object_grasps", grasps)
    with pytest.raises(KeyboardInterrupt):
        build_dataset(objects, cfg, progress=False)
    path = dataset_cache_path(objects, cfg)
    assert not path.exists() and sorted(p.name for p in path.parent.glob(f".{path.stem}.obj*.npz")) == [
        f".{path.stem}.obj0.npz", f".{path.stem}.obj1.npz"]
    made_once = True
    made.clear()
    ds = build_dataset(objects, cfg, progress=False)
    assert made == list(objects.names[2:])  # the first two came from their parts
    for a in ("X_train", "y_train", "X_val", "y_val"):
        np.testing.assert_array_equal(getattr(ds, a), getattr(whole, a))
    assert path.exists() and not list(path.parent.glob(".*obj*.npz"))


def test_a_part_removed_by_another_build_is_generated_again(tmp_path, monkeypatch):
    """Two builds of one dataset: the other one finishes and removes the per-object parts between this build's
    exists() and its load; the part is then generated again, not a crash (FileNotFoundError)."""
    import haptic_env.dataset as dataset

    part = tmp_path / ".kit8.obj0.npz"
    part.write_bytes(b"")

    def gone(path, required=()):
        raise FileNotFoundError(path)

    monkeypatch.setattr(dataset, "load_npz", gone)
    assert dataset._load_part(part) is None


def test_cache_keys_are_normalised_and_keep_the_keys_of_configs_at_their_defaults(objects):
    """A TOML ``contact_noise = 0`` keyed apart from the command line's 0.0, and settings a source ignores (the
    sampling of the geometric and hand sources, the normal noise without normals) gave other keys for the same grasps;
    configs at the defaults of those settings (the envs' and the command line's) keep their keys as before."""
    import haptic_env
    from haptic_env.cache import config_key
    from haptic_env.config import recognizer_kwargs
    from haptic_env.dataset import _CACHE_VERSION

    def key(**kw):
        return dataset_cache_path(objects, DatasetConfig(**kw)).name

    assert DatasetConfig(contact_noise=0, normal_noise_deg=np.int64(2), val_fraction=0).contact_noise.__class__ is float
    assert key(contact_noise=0) == key(contact_noise=0.0) == key() and key(contact_noise=1) == key(contact_noise=1.0)
    assert key(normal_noise_deg=0, val_fraction=0) == key(normal_noise_deg=0.0, val_fraction=0.0)
    assert key(normals=False, normal_noise_deg=5.0) == key(normals=False) != key(normal_noise_deg=5.0)
    for axis in ("ab", "frame"):  # no normals: no normal axis to read (since 2026-12-07)
        assert key(normals=False, normal_axis=axis) == key(normals=False) and key(normal_axis=axis) != key()
    for source in ("geometric", "hand"):
        hand = {"hand": "generic"} if source == "hand" else {}
        assert key(source=source, sampling="centroid", **hand) == key(source=source, **hand)
    assert key(sampling="centroid") != key()  # the surface source samples by it
    for source in ("geometric", "hand"):  # hand_fingers None is n_fingers, as the envs key it
        hand = {"hand": "generic"} if source == "hand" else {}
        assert key(source=source, **hand) == key(source=source, hand_fingers=4, **hand) != key(
            source=source, hand_fingers=5, **hand)
    # the keys of configs at those defaults are the pre-normalisation key of the config itself
    rc = recognizer_kwargs(haptic_env.variant_config("HapticRecog-v0"))["config"]
    # (a geometric config with hand_fingers None is keyed as hand_fingers=n_fingers since 2026-12-07, the envs' key)
    for cfg in (DatasetConfig(), DatasetConfig(normals=False),
                DatasetConfig(source="geometric", contact_noise=0.001, hand_fingers=4),
                rc.dataset_config(4, True, hand_fingers=4), rc.dataset_config(3, False, hand_fingers=4)):
        assert cfg.key_config() is cfg
        before = config_key(_CACHE_VERSION, objects.identity, cfg)
        assert dataset_cache_path(objects, cfg).name.endswith(f"-{before}.npz")


def test_settings_that_left_a_build_empty_stuck_or_crashing_are_refused_or_bounded(objects, usage_error):
    """A ``val_fraction`` near 1 keeps a training row per object (it left none); ``draw_held_grasps`` refuses two
    contacts and stops after its rounds (it looped forever); heights above a table that a floating support lacks are
    refused; the dataset command names a hand whose finger count is not ``--fingers`` as a usage error (a
    traceback)."""
    from haptic_env.dataset import _MAX_TOPUP_ROUNDS, draw_held_grasps

    ds = build_dataset(objects, DatasetConfig(grasps_per_object=4, val_fraction=0.9), cache=False)
    assert all(tr == 1 and va == 3 for tr, va in ds.counts().values())
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"force closure needs n_fingers >= 3 .*got 2"):
        draw_held_grasps(objects[0], 10, 2, rng, 0.5)
    with pytest.raises(RuntimeError, match=rf"only 0 of 5 random 3-contact grasps in force closure \(mu=0.0\) after "
                                           rf"{_MAX_TOPUP_ROUNDS} rounds of 20"):
        draw_held_grasps(objects[0], 5, 3, rng, 0.0)  # no friction: three contacts never hold
    C, N = draw_held_grasps(objects[0], 5, 3, np.random.default_rng(0), 0.5)
    assert C.shape == N.shape == (5, 3, 3) and force_closure(C, N, 0.5).all()
    with pytest.raises(ValueError, match=r"heights=True measures the contacts above the table .*support 'floating'"):
        DatasetConfig(heights=True, source="geometric", support="floating")
    from haptic_env.grasping.hands import HandUnavailableError, load_hand

    try:
        load_hand("allegro")
    except HandUnavailableError as exc:
        pytest.skip(f"allegro hand unavailable (menagerie data absent, no download): {exc}")
    usage_error(cli_main, ["dataset", "--source", "hand", "--hand", "allegro", "--fingers", "3", "--grasps", "2",
                           "--no-cache", "--quiet"], match=r"hand 'allegro_right' has 4 fingers but n_fingers=3")
