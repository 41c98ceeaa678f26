"""Clear errors at the first chance: bad actions, finished episodes, bad configs, bad meshes, bad caches."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import trimesh

import haptic_env  # noqa: F401  (registers the envs)
from haptic_env.cache import CacheNotWritableError, atomic_write, cache_dir, clean_stale_tmp
from haptic_env.env import HapticRecogConfig, HapticRecogEnv
from haptic_env.objects import MeshLoadError, load_folder
from haptic_env.objects.loaders import load_mesh_object


# ------------------------------------------------------------------------------------------- env
def test_step_after_the_episode_ended_raises(env_config):
    """Gymnasium leaves stepping a finished episode undefined: the env refuses it (the grasp count would leave
    the observation space), then runs again after reset."""
    env = HapticRecogEnv(env_config.replace(threshold=1.0, max_grasps=2))
    env.reset(seed=0)
    for _ in range(2):
        obs, _, term, trunc, _ = env.step(np.zeros(4, dtype=np.float32))
    assert trunc and env.observation_space.contains(obs)
    with pytest.raises(RuntimeError, match="episode is over.*reset"):
        env.step(np.zeros(4, dtype=np.float32))
    obs, _ = env.reset()
    assert env.step(np.zeros(4, dtype=np.float32))[0][env.obs_slices["grasp_count"]] == pytest.approx(0.5)
    # terminated (the threshold reached) likewise, also through gym.make's wrappers
    wrapped = gym.make("HapticRecog-v0", config=env_config.replace(threshold=0.2))
    wrapped.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(30):
        _, _, term, trunc, _ = wrapped.step(rng.uniform(-1, 1, 4).astype(np.float32))
        if term or trunc:
            break
    assert term
    with pytest.raises(RuntimeError, match="episode is over"):
        wrapped.step(np.zeros(4, dtype=np.float32))


@pytest.mark.parametrize("action", [np.array([0.1 + 0.5j, 0, 0, 0]), [1j, 0, 0, 0], np.zeros(4, dtype=np.complex64)])
def test_complex_actions_are_rejected_naming_the_value(env_config, action):
    env = HapticRecogEnv(env_config)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"complex values .*j"):
        env.step(action)


@pytest.mark.parametrize("action", [["0", "0", "0", "0"], [True, False, True, False], np.array([None] * 4)])
def test_non_numeric_actions_are_rejected_not_cast(env_config, action):
    env = HapticRecogEnv(env_config)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must be a numeric array of shape \(4,\)"):
        env.step(action)


def test_bad_reset_arguments_are_named(env_config):
    from haptic_env.vector_env import HapticRecogVectorEnv

    env = HapticRecogEnv(env_config)
    with pytest.raises(ValueError, match="reset options must be a dict .* got 'mug'"):
        env.reset(options="mug")
    venv = HapticRecogVectorEnv(2, config=env_config)
    for seed in (True, [1.5, 2], "ab"):
        with pytest.raises(ValueError, match="seed must be None, an int or a sequence of 2 ints"):
            venv.reset(seed=seed)
    first = venv.reset(seed=np.array([3, 4]))[0]  # numpy integers are seeds too
    assert np.array_equal(first, venv.reset(seed=3)[0])
    with pytest.raises(ValueError, match=r"actions must be a numeric array of shape \(2, 4\)"):
        venv.step(np.ones((2, 4), dtype=bool))
    venv.close()


def test_a_copy_keeps_the_settings_and_says_it_has_no_episode(env_config):
    import copy
    import pickle

    env = HapticRecogEnv(env_config.replace(grasp_cost=0.07))
    env.reset(seed=4)
    env.step(np.zeros(4, np.float32))
    for clone in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
        assert clone.config == env.config
        with pytest.raises(RuntimeError, match="copy or an unpickled env.*keep the settings, not the episode"):
            clone.step(np.zeros(4, np.float32))
        clone.reset(seed=4)
        clone.step(np.zeros(4, np.float32))
    with pytest.raises(RuntimeError, match=r"^call reset\(\) before step\(\)$"):
        HapticRecogEnv(env_config).step(np.zeros(4, np.float32))


def test_ic_belief_sums_to_one_and_keeps_its_certainty(env_config):
    env = HapticRecogEnv(env_config.replace(updater="ic", threshold=0.95))
    obs, info = env.reset(seed=0)
    assert info["belief"].sum() == pytest.approx(1.0)
    rng = np.random.default_rng(0)
    usable = 0
    for _ in range(200):
        obs, _, term, trunc, info = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        usable += info["usable"]
        assert info["belief"].sum() == pytest.approx(1.0, abs=1e-9)
        assert obs[env.obs_slices["belief"]].sum() == pytest.approx(1.0, abs=1e-5)
        u = env.updater
        assert info["certainty"] == pytest.approx(u.scores.max() / u.n_grasps if u.n_grasps else 1 / env.n_classes)
        assert info["predicted_index"] == int(np.argmax(u.scores)) or u.n_grasps == 0
        assert term == (info["certainty"] >= 0.95)
        if term or trunc:
            env.reset()
    assert usable > 10


@pytest.mark.parametrize("bad, match", [
    ({"kde_method": "nope"}, "kde_method"),
    ({"recognizer_kwargs": {"nope": 1}}, r"unknown recognizer_kwargs \['nope'\]"),
    ({"recognizer_kwargs": {"config": {"mlp": {"depthh": 2}}}}, "depthh"),
    ({"recognizer_kwargs": {"config": {"kde": {"method": "nope"}}}}, "method"),
    ({"object_kwargs": {"colour": "red"}}, "object_kwargs"),
])
def test_bad_recognizer_settings_fail_at_make(bad, match):
    with pytest.raises(ValueError, match=match):
        HapticRecogConfig(**bad)
    with pytest.raises(ValueError, match=match):
        gym.make("HapticRecog-v0", **bad)


@pytest.mark.parametrize("cls, bad, match", [
    ("DatasetConfig", {"seed": -1}, "seed must be an int >= 0, got -1"),
    ("MLPConfig", {"max_train": 0}, "MLPConfig.max_train must be None or an int >= 1, got 0"),
])
def test_bad_grasp_and_mlp_settings_fail_when_made(cls, bad, match):
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers.mlp_config import MLPConfig

    with pytest.raises(ValueError, match=match):
        {"DatasetConfig": DatasetConfig, "MLPConfig": MLPConfig}[cls](**bad)


def test_kde_methods_accepted_by_the_env_exist():
    from haptic_env.recognizers.kde import _METHODS

    for m in ("pooled", "tree", "dense"):
        assert m in _METHODS and HapticRecogConfig(kde_method=m).kde_method == m


def test_one_object_set_fails_at_make(tmp_path, haptic_cache):
    folder = tmp_path / "one"
    folder.mkdir()
    trimesh.creation.box([0.05, 0.06, 0.07]).export(folder / "box.stl")
    before = sorted(p.name for p in haptic_cache.rglob("*"))
    with pytest.raises(ValueError, match="1 object.*at least 2"):
        gym.make("HapticRecog-v0", objects=str(folder))
    with pytest.raises(ValueError, match=r"bad families spec 'families:0'.*1 <= N <= 1000"):
        HapticRecogConfig(objects="families:0")
    with pytest.raises(ValueError, match=r"bad families spec 'families:100000000'.*1 <= N <= 1000"):
        HapticRecogConfig(objects="families:100000000")  # it generated members without end
    with pytest.raises(ValueError, match=r"unknown units 'furlong'"):
        HapticRecogConfig(object_kwargs={"units": "furlong"})  # a named set ignores a good unit, not a bad one
    for bad in ("0", "-1", "nan", "inf"):  # a number given as text, as the command lines give it
        with pytest.raises(ValueError, match=rf"units factor must be positive and finite, got '{bad}'"):
            HapticRecogConfig(object_kwargs={"units": bad})
    from haptic_env.objects import load_object_set

    with pytest.raises(ValueError, match=r"data_dir must be a folder path or None, got 5"):  # was a bare TypeError
        load_object_set("kit8", data_dir=5)
    assert sorted(p.name for p in haptic_cache.rglob("*")) == before  # nothing trained or cached


# ---------------------------------------------------------------------------------------- meshes
def _box_ascii_stl() -> bytes:
    return trimesh.exchange.stl.export_stl_ascii(trimesh.creation.box([0.05, 0.06, 0.07])).encode()


def test_random_bytes_stl_is_a_clear_mesh_error(tmp_path):
    p = tmp_path / "noise.stl"
    p.write_bytes(np.random.default_rng(0).bytes(3000))
    with pytest.raises(MeshLoadError, match="noise.stl") as exc:
        load_mesh_object(p)
    assert "No module named" not in str(exc.value)


def test_ascii_stl_with_a_latin1_header_loads(tmp_path):
    # charset-normalizer is a dependency (pyproject.toml): trimesh guesses the header's encoding with it, and the
    # load fails without it, so its absence fails here rather than skipping
    p = tmp_path / "latin.stl"
    p.write_bytes(_box_ascii_stl().replace(b"solid", b"solid caf\xe9 \xb0C", 1))
    obj = load_mesh_object(p)
    np.testing.assert_allclose(obj.extents, [0.05, 0.06, 0.07], atol=1e-9)


def test_obj_with_a_nan_vertex_is_rejected_naming_the_file(tmp_path):
    text = trimesh.exchange.obj.export_obj(trimesh.creation.box([0.05, 0.06, 0.07]))
    lines = text.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("v "))
    lines[i] = "v nan 0.0 0.0"
    p = tmp_path / "holey.obj"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeshLoadError, match=r"holey\.obj.*not finite"):
        load_mesh_object(p)


def test_obj_with_a_broken_vertex_line_is_rejected_naming_the_file(tmp_path):
    """A vertex line split in two (found by the fuzz test) gives trimesh (n, 1) vertices, whose vertex merging
    overflowed with an OverflowError: now a MeshLoadError naming the file and the shape."""
    text = trimesh.exchange.obj.export_obj(trimesh.creation.box([0.08, 0.05, 0.03]))
    lines = text.splitlines()
    i = [k for k, line in enumerate(lines) if line.startswith("v ")][2]
    lines[i:i + 1] = [lines[i][:4], lines[i][5:]]  # "v -0" and the rest of the line on the next
    p = tmp_path / "split.obj"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeshLoadError, match=r"split\.obj: its vertices have shape \(8, 1\), not \(n, 3\)"):
        load_mesh_object(p)


def test_millimetres_loaded_as_metres_warn(tmp_path):
    box = trimesh.creation.box([50.0, 60.0, 70.0])  # a 5-7 cm box written in millimetres
    box.export(tmp_path / "mm_box.stl")
    trimesh.creation.box([0.05, 0.06, 0.07]).export(tmp_path / "m_box.stl")
    with pytest.warns(UserWarning, match=r"mm_box.stl.*70 m across.*millimetres"):
        load_folder(tmp_path, units="m")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_mesh_object(tmp_path / "mm_box.stl", units="mm")  # right units: silent


# ---------------------------------------------------------------------------------------- caches
def test_read_only_cache_fails_before_any_work(tmp_path, monkeypatch):
    from haptic_env.dataset import DatasetConfig, build_dataset
    from haptic_env.objects import load_object_set

    root = tmp_path / "ro"
    (root / "datasets").mkdir(parents=True)
    monkeypatch.setenv("HAPTIC_CACHE", str(root))
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p).startswith(str(root)) else real_access(p, mode))
    with pytest.raises(CacheNotWritableError, match=r"ro/datasets is not writable.*HAPTIC_CACHE"):
        cache_dir("datasets")
    objs = load_object_set("default")
    import haptic_env.dataset as dataset

    def must_not_run(*a, **k):
        raise AssertionError("grasps were generated before the unwritable cache was refused")

    with monkeypatch.context() as m:
        m.setattr(dataset, "_object_grasps", must_not_run)
        with pytest.raises(PermissionError, match="not writable"):
            build_dataset(objs.subset(objs.names[:2]), DatasetConfig(grasps_per_object=100_000), progress=False)
    monkeypatch.setenv("HAPTIC_CACHE_READONLY", "1")  # a complete read-only cache may still be read
    assert cache_dir("datasets") == root / "datasets"
    # ... and what it lacks is computed and used, not saved (it failed when saving the result, after the work)
    real_mkstemp = tempfile.mkstemp

    def read_only(*a, dir=None, **k):
        if str(dir).startswith(str(root)):
            raise PermissionError(13, "Read-only file system")
        return real_mkstemp(*a, dir=dir, **k)

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    with pytest.warns(UserWarning, match=r"not saved: .*ro/datasets/.*Read-only file system.*HAPTIC_CACHE_READONLY"):
        ds = build_dataset(objs.subset(objs.names[:2]), DatasetConfig(grasps_per_object=50), progress=False)
    assert len(ds.X_train) + len(ds.X_val) == 100 and not any(root.rglob("*.npz"))
    # a read-only cache without a folder (here: recognizers/) is read as one that holds none of its files (it raised)
    real_mkdir = Path.mkdir

    def no_new_folders(self, *a, **k):
        if str(self).startswith(str(root)) and not self.is_dir():
            raise OSError(30, "Read-only file system", str(self))
        return real_mkdir(self, *a, **k)

    with monkeypatch.context() as m:
        m.setattr(Path, "mkdir", no_new_folders)
        with pytest.warns(UserWarning, match=r"the read-only cache has no .*ro/recognizers .*computed each time"):
            assert cache_dir("recognizers") == root / "recognizers"
        assert not (root / "recognizers").exists()
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "elsewhere"))
    with pytest.raises(CacheNotWritableError, match=r"cannot write .*out.json"):  # outside the cache: an error still
        with atomic_write(root / "out.json", "w") as fh:
            fh.write("{}")
    monkeypatch.setenv("HAPTIC_CACHE", str(root))
    # a cache path that cannot even be created
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.delenv("HAPTIC_CACHE_READONLY")
    monkeypatch.setenv("HAPTIC_CACHE", str(blocker / "cache"))
    with pytest.raises(CacheNotWritableError, match="cannot create the cache folder"):
        cache_dir("recognizers")


def test_temp_file_of_a_killed_writer_is_cleaned(tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))
    folder = cache_dir("datasets")
    code = ("import os, signal\nfrom haptic_env.cache import atomic_write\n"
            f"with atomic_write({str(folder / 'd.npz')!r}) as fh:\n"
            "    fh.write(b'half'); fh.flush(); os.kill(os.getpid(), signal.SIGKILL)\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=os.getcwd())
    assert proc.returncode == -signal.SIGKILL
    (orphan,) = [p for p in folder.iterdir()]
    assert orphan.name.startswith(".d.npz.pid") and orphan.name.endswith(".tmp")
    assert cache_dir("datasets") and orphan.exists()  # a fresh temp file may belong to a slow writer elsewhere
    old = time.time() - 120
    os.utime(orphan, (old, old))
    mine = folder / f".e.npz.pid{os.getpid()}.x.tmp"  # a live writer's (this process) is kept
    mine.write_bytes(b"")
    os.utime(mine, (old, old))
    cache_dir("datasets")
    assert not orphan.exists() and mine.exists()
    assert clean_stale_tmp(folder, max_age=60) == [mine]  # very old: removed whoever wrote it
    with atomic_write(folder / "ok.bin") as fh:
        fh.write(b"1")
    assert [p.name for p in folder.iterdir()] == ["ok.bin"]


def test_truncated_recognizer_json_is_rebuilt(tmp_path, monkeypatch):
    from haptic_env.dataset import DatasetConfig
    from haptic_env.objects import load_object_set
    from haptic_env.recognizers import RecognizerConfig, build_recognizer

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path))
    objs = load_object_set("default")
    objs = objs.subset(objs.names[:3], name="three")
    cfg = RecognizerConfig(grasps=DatasetConfig(grasps_per_object=200))
    build_recognizer(objs, 4, True, config=cfg, models=("kde",), progress=False)
    (meta,) = (tmp_path / "recognizers").glob("*.json")
    meta.write_text(meta.read_text()[: len(meta.read_text()) // 2])  # cut mid-write
    with pytest.warns(UserWarning, match="rebuilding recogniser"):
        rec = build_recognizer(objs, 4, True, config=cfg, models=("kde",), progress=False)
    assert rec.n_classes == 3
    import json

    json.loads(meta.read_text())  # rewritten whole


# ------------------------------------------------------------------------------------------- CLI
@pytest.mark.parametrize("argv, match", [
    (["dataset", "--fingers", "50"], "argument --fingers: must be in [2, 20], got 50"),
    (["dataset", "--grasps", "0"], "argument --grasps: must be >= 1"),
    (["dataset", "--val-fraction", "1.5"], "argument --val-fraction"),
    (["dataset", "--noise", "nan"], "argument --noise"),
    (["dataset", "--objects", "/no/such/folder"], "unknown object set '/no/such/folder'"),
    (["dataset", "--source", "hand", "--hand", "/no/hand.xml"], "MJCF hand file /no/hand.xml does not exist"),
    (["evaluate", "--env-kwargs", "notjson"], "argument --env-kwargs: not valid JSON"),
    (["evaluate", "--env-kwargs", "[1, 2]"], "argument --env-kwargs: expected a JSON object"),
    (["evaluate", "--env-kwargs", '{"nope": 1}'], r"--env-kwargs: unknown HapticRecogConfig field\(s\) \['nope'\]"),
    (["evaluate", "--env-kwargs", '{"kde_method": "nope"}'], "--env-kwargs: kde_method"),
    (["evaluate", "--env-kwargs", '{"objects": "nosuch"}'], "--env-kwargs: unknown object set 'nosuch'"),
    (["analysis", "--out", "outputs/never", "--objects", "nosuch"], "unknown object set 'nosuch'"),
    (["evaluate", "--agents", "robot"], "--agents: unknown agent spec 'robot'"),
    (["evaluate", "--agents", "ppo=/no/model.zip"], "model file /no/model.zip does not exist"),
    (["evaluate", "--episodes", "0"], "argument --episodes: must be >= 1"),
    (["evaluate", "--agents", "ppo=results/hands/ppo_frame_models/ppo_frame_s0.zip", "--out", "outputs/never"],
     "the model observes 38 values, but HapticRecog-v0 with --env-kwargs {} gives 33"),
    (["evaluate", "--agents", "greedy:abc"], "agent spec 'greedy:abc': M and S must be whole numbers"),
    # these three failed after episodes had run (or ran out of memory)
    (["evaluate", "--agents", "greedy:1000000000:1000000000"], "n_candidates x n_samples must be <= 100,000"),
    (["evaluate", "--out", "README.md/sub"], "argument --out: cannot create README.md/sub: "),
    (["evaluate", "--learning-curves", "x=tests"], "--learning-curves x=tests: no *.monitor.csv in tests"),
    (["evaluate", "--learning-curves", "runA/ppo", "runB/ppo"], "--learning-curves: ['ppo'] named more than once"),
    (["evaluate", "--env-id", "Nope-v0"], "argument --env-id: invalid choice"),
    # an agent the env does not suit raised a ValueError traceback at its first episode, after the others had run
    (["evaluate", "--agents", "random", "greedy-env-infer", "--episodes", "1", "--seeds", "0",
      "--out", "outputs/never"],
     r"--agents greedy-env-infer: infer_pose \(the greedy look-ahead's yaw posterior\) needs a hand backend"),
    (["evaluate", "--agents", "random", "greedy-blind", "--episodes", "1", "--seeds", "0", "--out", "outputs/never",
      "--env-kwargs", '{"backend": "mujoco", "action_frame": "oracle"}'],
     r"--agents greedy-blind: the greedy look-ahead simulates world-frame approaches; it needs action_frame='world', "
     r"got 'oracle'"),
    (["analysis", "--out", "outputs/never", "--trials", "-1"], "trials must be an int >= 1, got -1"),
    # these failed after work, or with a traceback (missing data), or were taken (a repeated experiment ran twice)
    (["analysis", "--out", "outputs/never", "--experiments", "1,1"], r"experiments must be .* each once, got \(1, 1\)"),
    (["analysis", "--out", "outputs/never", "--fingers", "2-100"], r"fingers must be a tuple of ints in \[2, 20\]"),
    (["analysis", "--out", "README.md/x"], "argument --out: cannot create README.md/x: "),
    (["analysis", "--out", "outputs/never", "--objects", "kit8", "--data-dir", "/nonexistent"],
     "--objects kit8: data folder /nonexistent does not exist"),
    (["analysis", "--out", "outputs/never", "--max-grasps", "0"], "max_grasps must be an int >= 1, got 0"),
    (["analysis", "--out", "outputs/never", "--classifiers", "mlp,svm"], r"unknown classifier\(s\) \['svm'\]"),
    (["analysis", "--out", "outputs/never", "--threshold", "2"], r"threshold must be in \(0, 1\], got 2.0"),
    # these were accepted: a late traceback after the recognisers were built, a traceback (or a failed sweep job), or
    # a setting silently ignored
    (["analysis", "--out", "outputs/never", "--baseline-max-train", "1"],
     "baseline_max_train must be None or an int >= 100"),
    (["analysis", "--out", "outputs/never", "--experiments", "5", "--family-source", "hand", "--family-hand", "bogus"],
     "--family-hand bogus: unknown hand 'bogus'"),
    (["analysis", "--out", "outputs/never", "--family-hand", "shadow"],
     "--family-hand shadow needs --family-source hand"),
    (["analysis", "--out", "outputs/never", "--no-correction", "--kde-corrections", "power"],
     "--kde-corrections power weighs corrections that --no-correction turns off"),
    (["analysis", "--out", "outputs/never", "--experiments", "1", "--oneshot-fingers", ""],  # a header-only table
     "experiment 1 needs finger counts, but oneshot_fingers is empty"),
    (["analysis", "--out", "outputs/never", "--experiments", "7", "--calib-fingers", "", "--calib-fingers-no-normals",
      ""], "experiment 7 needs finger counts, but calib_fingers and calib_fingers_no_normals are empty"),
    (["analysis", "--out", "outputs/never", "--raw", "--family-floors", "0.5"],  # taken and ignored before
     "--family-floors 0.5 chooses experiment 5's outlier floor on calibrated scores; --raw has neither"),
])
def test_cli_bad_values_are_one_line_usage_errors(argv, match, capsys):
    import re

    from haptic_env.cli import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"haptic-recog {argv[0]}: error: ") and re.search(match if "\\" in match or "(" in match
                                                                             else re.escape(match), last), err


def test_analysis_object_folders_without_readable_meshes_are_usage_errors(tmp_path, capsys):
    """A folder with no meshes, or with a mesh that cannot be read, was a traceback (evaluate named it in one line);
    nothing is written to --out."""
    from haptic_env.cli import main

    (tmp_path / "empty").mkdir()
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "junk.obj").write_text("junk")
    for folder, match in (("empty", "has no mesh files"), ("bad", "junk.obj holds no triangles")):
        with pytest.raises(SystemExit) as exc:
            main(["analysis", "--objects", str(tmp_path / folder), "--out", str(tmp_path / "out"), "--quiet"])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and "Traceback" not in err and match in err.strip().splitlines()[-1]
    assert not (tmp_path / "out").exists()


def test_dataset_out_folder_fails_before_the_work(tmp_path, capsys, monkeypatch):
    import haptic_env.dataset as dataset
    from haptic_env.cli import main

    def must_not_run(*a, **k):
        raise AssertionError("grasps were generated before the bad --out was refused")

    monkeypatch.setattr(dataset, "_object_grasps", must_not_run)
    with pytest.raises(SystemExit) as exc:
        main(["dataset", "--grasps", "1000000", "--out", str(tmp_path), "--no-cache", "--quiet"])
    assert exc.value.code == 2 and "is a folder" in capsys.readouterr().err
    for argv, said in ((["--out", str(tmp_path / "file" / "g.npz")], "is not a writable folder"),  # after the work
                       (["--source", "surface", "--hand-fingers", "5"], "hand_fingers=5 would be ignored")):
        (tmp_path / "file").write_text("x")
        with pytest.raises(SystemExit) as exc:
            main(["dataset", "--grasps", "1000000", "--no-cache", "--quiet", *argv])
        assert exc.value.code == 2 and said in capsys.readouterr().err


@pytest.mark.parametrize("argv, match", [
    (["--algo", "nope"], "invalid choice 'nope' for argument '--algo'"),  # tyro's own message (a box)
    (["--env.reward", "money"], "reward must be one of"),
    (["--total-timesteps", "0"], "argument --total-timesteps: must be >= 1, got 0"),
    (["--n-envs", "0"], "argument --n-envs: must be >= 1, got 0"),
    (["--env-kwargs", "notjson"], "argument --env-kwargs: not valid JSON"),
    (["--hyperparams", "[]"], "argument --hyperparams: expected a JSON object"),
    (["--env-kwargs", '{"reward": "money"}'], "env settings: reward must be one of"),
    (["--resume", "/no/ckpt.zip"], "argument --resume: checkpoint /no/ckpt.zip does not exist"),
    (["--hyperparams", '{"lr": 1}'], "argument --hyperparams: unknown PPO hyperparameter(s) ['lr']"),
    (["--env.objects", "nosuch"], "unknown object set 'nosuch'"),
    # an env that cannot be built: a traceback after args.json, monitor/ and the lock were written
    (["--env-id", "HapticRecogMuJoCo-v0", "--env-kwargs", '{"backend_kwargs": {"hand": "bogus"}}'],
     "env settings: unknown hand 'bogus'"),
])
def test_train_bad_flags_fail_at_once_without_run_files(argv, match, tmp_path):
    run_dir = tmp_path / "run"
    proc = subprocess.run([sys.executable, "train.py", *argv, "--run-dir", str(run_dir)], capture_output=True,
                          text=True, timeout=120, cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    tyro_box = lines[-1].startswith("╰")  # tyro's own parse errors: a box ending in "--help"
    assert "Traceback" not in proc.stderr and (match in lines[-1] or tyro_box and match in proc.stderr), proc.stderr
    assert not run_dir.exists()


@pytest.mark.parametrize("under", [False, True])
def test_train_run_dir_that_is_a_file_is_a_usage_error(under, tmp_path):
    """An existing file as --run-dir (or a folder under one) was a FileExistsError / NotADirectoryError traceback."""
    (tmp_path / "f").write_text("x")
    run_dir = tmp_path / "f" / "sub" if under else tmp_path / "f"
    proc = subprocess.run([sys.executable, "train.py", "--run-dir", str(run_dir)], capture_output=True, text=True,
                          timeout=120, cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("train.py: error: argument --run-dir: ")


def test_ctrl_c_in_a_subcommand_is_one_line_saying_what_a_rerun_keeps(monkeypatch, capsys):
    import agents.evaluate as ev
    from haptic_env.cli import main

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(ev, "_main", interrupted)  # the parser is built inside main, so it takes this one
    assert main(["evaluate", "--episodes", "1"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == ("haptic-recog evaluate: interrupted; every finished agent-seed block is saved; the same "
                           "command resumes from them")


@pytest.mark.parametrize("bench, argv, match", [
    ("bench_env", ["--steps", "0"], r"argument --steps: must be >= 1, got 0"),
    ("geometry_families", ["--sweep", "sizes", "--lying", "--trials", "5"],
     r"--sweep sizes does not use --lying, --trials"),  # they were ignored
    ("geometry_families", ["--models", "svm"], r"--models: unknown \['svm'\]; choose among member, mlp, rf, or none"),
    ("bench_vector_env", ["--seconds", "0"], r"argument --seconds: must be a finite number in \(0.0, inf\], got 0"),
    ("bench_vector_env", ["--sizes", "8", "0"], r"argument --sizes: must be >= 1, got 0"),
    ("bench_recognizers", ["--grasps", "1000"], r"--queries 300 is more than the 160 held-out grasps of --grasps 1000"),
    ("bench_recognizers", ["--dense-queries", "400"], r"--dense-queries 400 must be <= --queries 300"),
    ("bench_grasping", ["--seed", "-1"], r"argument --seed: must be >= 0, got -1"),
    ("bench_grasp_solver", ["--approaches", "0"], r"argument --approaches: must be >= 1, got 0"),
    ("bench_grasp_solver", ["--solvers", "Newton,XX"], r"--solvers: got 'Newton,XX'; give distinct names from CG"),
    ("bench_grasp_solver", ["--hands", "shadow,shadow"], r"--hands: got 'shadow,shadow'; give distinct names"),
    ("bench_knn", ["--grasps", "2.5"], r"argument --grasps: expected an integer, got '2.5'"),
    ("bench_phi", ["--repeats", "0"], r"argument --repeats: must be >= 1, got 0"),
    ("geometry_families", ["--lo", "2"], r"--lo 2.0 must be <= --hi 1.5"),
    ("family_bandwidth", ["--members", "0"], r"argument --members: must be >= 1, got 0"),
    ("stop_floor", ["--threshold", "1.5"], r"argument --threshold: must be a finite number in \(0.0, 1.0\], got 1.5"),
    ("hand_auto", ["--approaches", "0"], r"argument --approaches: must be >= 1, got 0"),
    ("hand_auto", ["--hands", "allegro,foo"], r"--hands: unknown hand 'foo'"),
    ("hand_experiment", ["--seeds", "0", "0"], r"--seeds: each value once, got \[0, 0\] \(0 more than once\)"),
    ("hand_experiment", ["--split", "validation", "--seeds", "600"], r"--seeds: seed must be an int in \[0, 500\)"),
    ("hand_experiment", ["--queries", "0"], r"argument --queries: must be >= 1, got 0"),
    ("hand_experiment", ["--threshold", "1.5"], r"argument --threshold: must be a finite number in \(0.0, 1.0\)"),
    ("stop_frontier", ["--seeds", "1", "1"], r"--seeds: each value once"),
    ("stop_frontier", ["--seeds", "0", "500"], r"--seeds: seed must be an int in \[0, 500\)"),
    ("hand_classifiers", ["--seeds", "0", "500"], r"--seeds: seed must be an int in \[0, 500\)"),
    ("hand_classifiers", ["--seeds", "2", "2"], r"--seeds: each value once"),
    ("family_bandwidth", ["--floors", "0,1.5"], r"--floors: quantiles in \[0, 1\) \(0: no floor\), got \[1.5\]"),
    ("family_bandwidth", ["--factors", "0"], r"--factors: bandwidth factors are finite and > 0"),
    ("geometry_families", ["--models", "mlp,xx"], r"--models: unknown \['xx'\]"),
    ("geometry_families", ["--ms", "0,3"], r"--ms: grasp counts >= 1"),
    ("stop_floor", ["--fingers", "1,3"], r"argument --fingers: expected a comma list of whole numbers >= 2"),
    ("correction_validation", ["--fingers", "x"], r"argument --fingers: expected a comma list"),
    ("bench_phi", ["--batches", "1,64"], r"--batches \(1, 64\) needs one batch >= --grasps 200000"),
    ("likelihood_bound", ["--trials", "0"], r"argument --trials: must be >= 1, got 0"),
    ("family_cups", ["--seed", "-1"], r"argument --seed: must be >= 0, got -1"),
    ("heights_information", ["--validation-seeds", "0"],
     r"argument --validation-seeds: must be in \[500, 999\], got 0"),
    ("heights_information", ["--validation-seeds", "500", "500"], r"--validation-seeds: each value once"),
])
def test_benchmarks_refuse_bad_counts_before_any_work(load_benchmark, usage_error, monkeypatch, bench, argv, match):
    mod = load_benchmark(bench)

    def work(*args, **kwargs):
        raise AssertionError("the benchmark started work before refusing its arguments")

    for name in ("data_dir", "load_object_set", "build_dataset", "hand_grasp_pool", "make_backend", "build_recognizer",
                 "family_set", "member_grasps"):  # the work the scripts start with: a check after it fails here
        if hasattr(mod, name):
            monkeypatch.setattr(mod, name, work)
    usage_error(mod.main, argv, match=match)


def test_an_existing_output_folder_is_checked_itself_and_a_huge_range_is_refused(tmp_path, monkeypatch):
    """``output_path("folder")`` of an existing folder asks that folder's rights (a run writes into it), not its
    parent's; ``parse_int_list`` refuses a range of more than ``MAX_RANGE`` numbers (``1-1e12``) instead of building
    it."""
    import argparse
    import os

    from haptic_env.cli import MAX_RANGE, output_path, parse_int_list

    out = tmp_path / "out"
    out.mkdir()
    asked = []
    monkeypatch.setattr(os, "access", lambda p, mode: asked.append(Path(p)) or Path(p) != out)
    with pytest.raises(argparse.ArgumentTypeError, match=r"out is not a writable folder"):
        output_path("folder")(str(out))
    assert asked == [out]
    with pytest.raises(ValueError, match=r"holds more than 100,000 numbers"):
        parse_int_list("1-1e12")
    assert len(parse_int_list(f"1-{MAX_RANGE}")) == MAX_RANGE


def test_a_benchmarks_recorded_command_reruns_as_written(monkeypatch):
    """``script_command`` (every benchmark's recorded command): shell-quoted, so an argument with a space or a JSON
    object splits back into the arguments given; without ``argv``, the process's own."""
    import shlex

    from haptic_env.cli import script_command

    argv = ["--env-kwargs", '{"hand": "shadow"}', "--methods", "BC-NP, z=3", "--seeds", 0, 1]
    cmd = script_command("hand_experiment.py", argv)
    assert shlex.split(cmd) == ["python", "benchmarks/hand_experiment.py", *map(str, argv)]
    monkeypatch.setattr(sys, "argv", ["x.py", "--out", "a b"])
    assert script_command("x.py") == "python benchmarks/x.py --out 'a b'"


def test_env_settings_that_contradict_the_recognisers_are_refused_at_make():
    """recognizer_kwargs' grasp settings against the env's (normal_axis, grasp_heights) and a touch pattern switched
    off under a touch_weight failed at the first reset, after training; a hand given as a Path is its path."""
    from haptic_env.config import HapticRecogConfig, recognizer_kwargs

    with pytest.raises(ValueError, match=r"second angle to 't2' but the config has normal_axis='ab'"):
        HapticRecogConfig(normal_axis="ab", recognizer_kwargs={"config": {"grasps": {"normal_axis": "t2"}}})
    with pytest.raises(ValueError, match=r"heights=False but the config has grasp_heights=True"):
        HapticRecogConfig(grasp_heights=True, recognizer_kwargs={"config": {"grasps": {"heights": False}}})
    with pytest.raises(ValueError, match=r"touch_weight=0.5 weighs the touch pattern, but recognizer_kwargs switches"):
        HapticRecogConfig(backend="replay", touch_weight=0.5, recognizer_kwargs={"touch": False})
    with pytest.raises(ValueError, match=r"recognizer_kwargs\['touch'\]=True needs hand-matched training grasps"):
        HapticRecogConfig(recognizer_kwargs={"touch": True})
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers import RecognizerConfig

    whole = RecognizerConfig(grasps=DatasetConfig(grasps_per_object=500))  # surface grasps: taken, failed at reset
    with pytest.raises(ValueError, match=r"touch_weight=0.5 needs hand-matched .* the RecognizerConfig's source 'surf"):
        HapticRecogConfig(backend="replay", touch_weight=0.5, recognizer_kwargs={"config": whole})
    hand = Path(__file__).resolve().parents[1] / "assets" / "generic_hand_4.xml"
    cfg = HapticRecogConfig(backend="mujoco", backend_kwargs={"hand": hand}, n_fingers=4)
    assert recognizer_kwargs(cfg)["config"].grasps.hand == str(hand)


def test_output_path_refuses_what_a_long_run_could_not_write_at_its_end(tmp_path):
    """``cli.output_path``: a file output that is a folder, a folder output that is a file, or a path under a file,
    is refused when parsed (nothing is created); a path in folders still to make is accepted."""
    import argparse

    from haptic_env.cli import output_path

    a_file = tmp_path / "f.txt"
    a_file.write_text("x")
    with pytest.raises(argparse.ArgumentTypeError, match="is a folder; give a file name"):
        output_path("file")(str(tmp_path))
    with pytest.raises(argparse.ArgumentTypeError, match="is a file; give a folder"):
        output_path("folder")(str(a_file))
    with pytest.raises(argparse.ArgumentTypeError, match=r"cannot create .*f.txt is not a writable folder"):
        output_path("file")(str(a_file / "sub" / "out.md"))
    assert output_path("file")(str(tmp_path / "new" / "deeper" / "out.md")) == tmp_path / "new" / "deeper" / "out.md"
    assert not (tmp_path / "new").exists()
    with pytest.raises(ValueError, match="kind must be"):
        output_path("dir")


def test_int_lists_have_one_parser_that_refuses_what_is_not_whole():
    """``cli.parse_int_list``: the analyses' and paper_scale's comma lists ("2-4,7", "2e5"); "3.5" is refused instead
    of being cut to 3 (paper_scale's own parser did that), and so are words and backward ranges."""
    import argparse

    from haptic_env.cli import int_list, parse_int_list

    assert parse_int_list("2-4,7") == (2, 3, 4, 7) and parse_int_list("2e5, 3") == (200000, 3)
    for bad in ("3.5", "x", "1-x", "4-2"):
        with pytest.raises(ValueError, match=re.escape(repr(bad))):
            parse_int_list(bad)
    with pytest.raises(argparse.ArgumentTypeError, match="whole numbers"):
        int_list("3.5")


@pytest.mark.parametrize("bench, argv, match", [
    # each was taken, then failed with a traceback or ran on a nonsense value (nan passed every soak variant)
    ("soak", ["--max-growth-mb", "nan"], r"--max-growth-mb: must be a finite number in \[0.0, inf\], got nan"),
    ("soak", ["--timeout", "-1"], r"--timeout: must be a finite number in \[0.0, inf\], got -1"),
    ("hand_experiment", ["--surface-grasps", "0"], r"--surface-grasps: must be >= 1, got 0"),
    ("hand_experiment", ["--surface-noise", "-1"], r"--surface-noise: must be a finite number in \[0.0, inf\]"),
    ("relative_approaches", ["--seeds", "-1"], r"--seeds: must be >= 0, got -1"),
    ("relative_approaches", ["--turns", "nan"], r"--turns: must be a finite number"),
    ("ece_bandwidth", ["--factors", "0.5,nan"], r"--factors: must be a finite number in \(0.0, inf\], got nan"),
    ("ece_bandwidth", ["--factors", "abc"], r"--factors: expected a number, got 'abc'"),
    ("ece_bandwidth", ["--test-grasps", "0"], r"--test-grasps: must be >= 1, got 0"),
    ("paper_scale", ["--seed", "-1"], r"--seed: must be >= 0, got -1"),
    ("paper_scale", ["--time-budget", "-5"], r"--time-budget: must be a finite number in \(0.0, inf\], got -5"),
    ("bench_sweep", ["--fingers", "-3"], r"--fingers: must be in \[2, 20\], got -3"),
    ("closing_time", ["--approaches", "-1"], r"error: --approaches must be >= 1, got -1"),
    ("obs_ablation", ["--model", "/nonexistent.zip"], r"error: --model '/nonexistent.zip' is not a file"),
    ("obs_ablation", ["--model", "x", "--env-kwargs", "{"], r"error: --env-kwargs is not valid JSON"),
])
def test_benchmark_flags_are_usage_errors_before_any_work(bench, argv, match, load_benchmark, usage_error):
    usage_error(load_benchmark(bench).main, argv, match=match)


def test_too_few_hand_grasps_for_an_envs_settings_is_one_line(monkeypatch, usage_error):
    """An env whose settings leave its hand too few grasps of an object to train on (an object that no approach
    grasps with every finger) stopped evaluate with a TooFewGraspsError traceback at its first make."""
    import agents.evaluate
    from haptic_env.cli import main
    from haptic_env.dataset import TooFewGraspsError

    def too_few(args):
        raise TooFewGraspsError("object '029_plate': 0 of its aero grasps (budget 'uniform', 6000 approaches per "
                                "object) touched it with >= 5 fingers (non-degenerate)")

    monkeypatch.setattr(agents.evaluate, "_main", too_few)
    usage_error(main, ["evaluate", "--agents", "random", "--episodes", "1", "--seeds", "0"],
                match=r"evaluate: error: object '029_plate': 0 of its aero grasps .* change the settings")
