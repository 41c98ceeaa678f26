"""Shared fixtures: a per-session cache directory, a small, fast recogniser for env/agent tests, and the
benchmark scripts as modules."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest
from hypothesis import settings

# mujoco picks its OpenGL platform when first imported: headless tests render offscreen through EGL (the library
# itself leaves the process environment alone)
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

# CI runs the property tests with a fixed example sequence (reproducible, never flaky); locally
# hypothesis explores new examples on every run.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session", autouse=True)
def haptic_cache(tmp_path_factory):
    """Point ``$HAPTIC_CACHE`` at a fresh session directory (no test reads or pollutes ~/.cache)."""
    path = tmp_path_factory.mktemp("haptic_cache")
    with pytest.MonkeyPatch.context() as mp:  # the session's monkeypatch: the variable is put back at the end
        mp.setenv("HAPTIC_CACHE", str(path))
        yield path


@pytest.fixture(scope="session", autouse=True)
def no_menagerie_download(tmp_path_factory):
    """No test downloads a Menagerie hand or reads the user's ``mujoco-menagerie`` cache: the package's download URL
    points at a folder that does not exist and its cache at a session directory. A hand is then read from
    ``$MENAGERIE_ROOT`` or the data folder's ``menagerie/``, or it is unavailable at once (the tests skip) instead
    of after a download attempt that depends on the network."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MENAGERIE_BASE_URL", (tmp_path_factory.mktemp("menagerie_offline") / "absent").as_uri())
        mp.setenv("MENAGERIE_CACHE_DIR", str(tmp_path_factory.mktemp("menagerie_cache")))
        yield


@pytest.fixture(scope="session")
def small_recognizer_kwargs():
    """``recognizer_kwargs`` (JSON-style) of a recogniser that builds in seconds (small dataset, tiny MLP)."""
    return {"config": {"grasps": {"grasps_per_object": 1500},
                       "mlp": {"depth": 1, "width": 32, "max_epochs": 1, "progress": False}},
            "progress": False}


@pytest.fixture(scope="session")
def env_config(small_recognizer_kwargs, haptic_cache):
    """The default env config with the small recogniser, built once per session."""
    from haptic_env.env import HapticRecogConfig, get_recognizer
    from haptic_env.objects import load_object_set

    cfg = HapticRecogConfig(recognizer_kwargs=small_recognizer_kwargs)
    get_recognizer(load_object_set(cfg.objects), cfg)  # build once, shared by every env of the session
    return cfg


@pytest.fixture(scope="session")
def load_benchmark():
    """``load_benchmark("soak")``: ``benchmarks/soak.py`` imported as a module (the benchmarks are scripts, not a
    package), for tests of their functions."""
    def load(name: str):
        path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(f"{name}_bench", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod

    return load


@pytest.fixture
def usage_error(capsys):
    """``usage_error(fn, *args, match=REGEX)``: ``fn(*args)`` must exit as a command line's usage error (argparse's
    exit status 2) whose message matches ``match``; so a crash for another reason, or another flag's error, fails.
    Returns the message."""
    import re

    def check(fn, *args, match: str) -> str:
        capsys.readouterr()  # drop what came before
        with pytest.raises(SystemExit) as exc:
            fn(*args)
        err = capsys.readouterr().err
        assert exc.value.code == 2, (exc.value.code, err)
        # the message from its "error:" on: the usage block above it names every flag, so a pattern that is a flag's
        # name matched any usage error of the script
        message = err[err.rfind("\n", 0, err.find("error:")) + 1:] if "error:" in err else err  # from its line
        assert re.search(match, message), (match, err)
        return err

    return check
