"""Cache helpers: stable keys, atomic writes, corrupted-file errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from haptic_env.cache import (KEY_AS, KEY_ONLY_WHEN_SET, CacheError, atomic_write, cache_dir, config_key, load_npz,
                               save_npz_atomic)


@dataclasses.dataclass(frozen=True)
class Cfg:
    a: int = 1
    b: tuple[float, float] = (0.1, 5.0)


def test_config_key_is_stable_and_sensitive():
    assert config_key(Cfg()) == config_key(Cfg())
    assert config_key(Cfg()) != config_key(Cfg(a=2))
    assert config_key(Cfg(), np.arange(3)) != config_key(Cfg(), np.arange(4))
    assert len(config_key(Cfg())) == 16
    # numpy scalars key as the Python scalars they stand for (np.bool_ had been keyed by its repr)
    assert config_key(np.int64(3), np.float32(0.5), np.bool_(True)) == config_key(3, 0.5, True)
    assert config_key(np.bool_(True)) != config_key(np.bool_(False))


def test_config_keys_are_the_same_in_another_process():
    """A key built from a value whose text holds a memory address, or from hash order, would differ from process to
    process, so that no cache would ever be found again: the package's own configs key alike in a fresh interpreter
    with another hash seed."""
    import os
    import subprocess
    import sys

    from haptic_env.config import HapticRecogConfig
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers import RecognizerConfig

    code = ("from haptic_env.cache import config_key\n"
            "from haptic_env.config import HapticRecogConfig\n"
            "from haptic_env.dataset import DatasetConfig\n"
            "from haptic_env.recognizers import RecognizerConfig\n"
            "print(config_key(HapticRecogConfig(), DatasetConfig(), RecognizerConfig()))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONHASHSEED": "12345"}).stdout.strip()
    assert out == config_key(HapticRecogConfig(), DatasetConfig(), RecognizerConfig())


def test_a_field_keyed_as_a_fixed_value_does_not_change_the_key():
    from haptic_env.recognizers import MLPConfig

    @dataclasses.dataclass(frozen=True)
    class Shown:
        a: int = 1
        bar: bool = dataclasses.field(default=True, metadata={KEY_AS: False})

    assert config_key(Shown(bar=True)) == config_key(Shown(bar=False)) != config_key(Shown(a=2))
    # the MLP's progress bar: on or off, a recogniser finds the same cached model
    on, off = MLPConfig(progress=True), MLPConfig(progress=False)
    assert config_key(on) == config_key(off) != config_key(MLPConfig(seed=1))


def test_resume_state_gives_back_only_the_same_settings_parts_and_says_where(tmp_path, capsys):
    from haptic_env.cache import resume_state, save_keyed_json

    path = tmp_path / "state.json"
    assert resume_state(path, {"a": 1}, "parts") == {} and capsys.readouterr().err == ""  # no file: nothing said
    save_keyed_json(path, {"a": 1}, parts={"3": [0.5]})
    assert resume_state(path, {"a": 1}, "parts") == {"3": [0.5]}
    assert f"1 finished part(s) kept in {path}" in capsys.readouterr().err
    assert resume_state(path, {"a": 2}, "parts") == {}  # another run's settings
    path.write_text("{not json")
    assert resume_state(path, {"a": 1}, "parts") == {}  # unreadable: computed again


def test_a_resume_key_with_tuples_or_number_keys_matches_itself(tmp_path):
    """A key is compared as JSON gives it back: one with a tuple or a number as a dict key (which JSON turns into a
    list and a string) still finds its own parts, and another key still does not."""
    from haptic_env.cache import resume_state, save_keyed_json

    path, key = tmp_path / "state.json", {"scales": (0.5, 1.0), 3: "fingers"}
    save_keyed_json(path, key, parts={"a": 1})
    assert resume_state(path, key, "parts") == {"a": 1}
    assert resume_state(path, {"scales": (0.5, 2.0), 3: "fingers"}, "parts") == {}


def test_file_stem_keeps_a_cache_file_in_its_folder():
    from haptic_env.cache import file_stem

    assert file_stem("kit8") == "kit8" and file_stem("ycb10", "x") == "ycb10"  # plain names as they are
    assert file_stem("/home/u/my hands/../hand.xml") == "_home_u_my_hands_.._hand.xml"
    assert "/" not in file_stem("../../etc") and file_stem("///", "hand") == "_"
    assert file_stem("", "hand") == "hand" and len(file_stem("x" * 100)) == 40


def test_cache_files_get_the_umask_modes_not_owner_only(tmp_path):
    """A written cache file is readable as the umask allows (a shared cache), not owner-only as mkstemp makes it."""
    import os
    import stat

    umask = os.umask(0)  # the process's umask, read here (not the module's copy of it)
    os.umask(umask)
    path = save_npz_atomic(tmp_path / "a.npz", x=np.arange(3))
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o666 & ~umask
    if umask & 0o044 == 0:  # a umask that lets others read: so must the cache file (mkstemp's default is 0o600)
        assert stat.S_IMODE(os.stat(path).st_mode) & 0o044


def test_stale_temp_files_with_odd_names_do_not_break_the_cache_folder(tmp_path):
    """A hidden ``.tmp`` file whose pid part is not a plain pid (unicode digits, a huge number) is not taken for a
    writer's pid: ``cache_dir`` does not fail on it."""
    from haptic_env.cache import clean_stale_tmp

    for name in (".a.npz.pid\u00b2\u00b3.x.tmp", f".b.npz.pid{2 ** 70}.x.tmp", ".c.npz.pid12.x.tmp"):
        (tmp_path / name).write_bytes(b"")
    assert clean_stale_tmp(tmp_path) == []  # all fresh: nothing removed, nothing raised
    assert clean_stale_tmp(tmp_path, max_age=-1) and not any(tmp_path.iterdir())


def test_field_added_later_keeps_older_keys_while_unset():
    @dataclasses.dataclass(frozen=True)
    class Later:
        a: int = 1
        b: tuple[float, float] = (0.1, 5.0)
        c: float | None = dataclasses.field(default=None, metadata={KEY_ONLY_WHEN_SET: True})

    assert config_key(Later()) == config_key(Cfg())  # the same key as the config without the field
    assert config_key(Later(a=2)) == config_key(Cfg(a=2))
    assert config_key(Later(c=0.5)) != config_key(Cfg())  # set, it is part of the key
    assert config_key(Later(c=0.5)) != config_key(Later(c=0.6))


def test_cache_dir_honours_env(tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "c"))
    assert cache_dir("x") == tmp_path / "c" / "x"
    assert (tmp_path / "c" / "x").is_dir()


def test_npz_round_trip(tmp_path):
    """Every array saved comes back under its own name with its values, shape and dtype, and nothing else does."""
    p = save_npz_atomic(tmp_path / "d.npz", x=np.arange(5), y=np.eye(2))
    out = load_npz(p, required=("x", "y"))
    assert sorted(out) == ["x", "y"]
    np.testing.assert_array_equal(out["x"], np.arange(5))
    np.testing.assert_array_equal(out["y"], np.eye(2))
    assert out["x"].dtype == np.arange(5).dtype and out["y"].dtype == np.float64 and out["y"].shape == (2, 2)


def test_failed_write_leaves_nothing(tmp_path):
    target = tmp_path / "d.npz"
    with pytest.raises(RuntimeError):
        with atomic_write(target) as fh:
            fh.write(b"partial")
            raise RuntimeError("crash mid-write")
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_previous_version(tmp_path):
    target = save_npz_atomic(tmp_path / "d.npz", x=np.arange(3))
    with pytest.raises(RuntimeError):
        with atomic_write(target) as fh:
            fh.write(b"garbage")
            raise RuntimeError("crash")
    np.testing.assert_array_equal(load_npz(target)["x"], np.arange(3))


def test_corrupted_and_incomplete_cache_errors(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(CacheError, match="bad.npz is corrupted"):
        load_npz(bad)
    p = save_npz_atomic(tmp_path / "d.npz", x=np.arange(3))
    with pytest.raises(CacheError, match=r"lacks arrays \['y'\]"):
        load_npz(p, required=("x", "y"))
