"""Long runs lose nothing: per-episode state stays bounded (the slow soak lives in benchmarks/soak.py)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from haptic_env.env import HapticRecogEnv


def test_scaled_resets_reuse_one_scene_per_object(env_config):
    """``scale_range``: the backend scales the object as a transform, no per-episode mesh copy or Embree scene
    (those accumulated ~1.8 MB/episode and crashed Embree after ~1000 episodes)."""
    env = HapticRecogEnv(env_config.replace(scale_range=(0.8, 1.2)))
    env.reset(seed=0)
    scales = set()
    for _ in range(60):
        env.reset()
        be = env.backend
        assert be.object is env.objects[env.target]  # the set's own object, not a scaled copy
        assert be.scale == env.scale
        scales.add(env.scale)
        env.step(np.zeros(4, dtype=np.float32))
    assert len(scales) == 60
    assert env.backend.n_scenes <= env.n_classes


#: RSS growth allowed after the warm-up (MiB): the soak benchmark's target for 100,000 steps
MAX_GROWTH_MB = 20.0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["HapticRecog-v0", "scale_range", "pose=so3", "z_fingers=3", "updater=ic",
                                  "updater=bc-ip"])
def test_short_soak_keeps_rss_flat(name, small_recognizer_kwargs, load_benchmark):
    """The short version of ``benchmarks/soak.py`` (geometric variants, small recogniser): 10,000 random steps
    after a 2,000-step warm-up, RSS growth within MAX_GROWTH_MB."""
    soak = load_benchmark("soak")
    env_id, overrides = soak.variants()[name]
    r = soak.soak(env_id, {**overrides, "recognizer_kwargs": small_recognizer_kwargs}, steps=10_000, warmup=2_000)
    assert r["episodes"] > 100
    assert r["growth_mb"] <= MAX_GROWTH_MB, r


def test_soak_benchmark_variants_cover_the_registered_envs(load_benchmark):
    from haptic_env import ENV_VARIANTS

    soak = load_benchmark("soak")
    names = soak.variants()
    assert set(ENV_VARIANTS) <= set(names)
    assert {"scale_range", "pose=so3", "z_fingers=3", "updater=ic", "updater=bc-ip"} <= set(names)
    assert not soak.is_geometric("HapticRecogMuJoCo-v0") and soak.is_geometric("scale_range")


def test_soak_refuses_no_warmup_before_any_step(load_benchmark):
    soak = load_benchmark("soak")
    with pytest.raises(ValueError, match="warmup >= 1, got 10 and 0"):
        soak.soak("HapticRecog-v0", {}, steps=10, warmup=0)


def test_a_variant_child_is_read_and_its_crash_named(load_benchmark, monkeypatch, capsys):
    """``run_variant``: the child's result line is parsed while its stderr (progress bars) passes through; a crash is
    named with the last line of its stderr; a timeout kills it."""
    soak = load_benchmark("soak")
    children = {
        "ok": "import sys; sys.stderr.write('bar 1/2\\rbar 2/2\\n'); print('SOAK-RESULT {\"steps\": 2}')",
        "crash": "import sys; sys.stderr.write('bar 1/2\\rboom\\n'); sys.exit(3)",
        "hang": "import time; time.sleep(30)",
    }
    monkeypatch.setattr(soak, "child_command", lambda name, *a: [sys.executable, "-c", children[name]])
    assert soak.run_variant("ok", 2, 1, 0, None) == {"steps": 2}
    assert "bar 2/2" in capsys.readouterr().err
    assert soak.run_variant("crash", 2, 1, 0, None) == {"error": "crashed (exit status 3): boom"}
    assert soak.run_variant("hang", 2, 1, 0, 0.5) == {"error": "timed out after 0.5 s"}


def test_an_interrupted_soak_resumes_after_its_finished_variants(load_benchmark, monkeypatch, tmp_path):
    """With ``--out`` each finished variant is saved beside it; the same command runs only the others; other settings
    run everything; the saved file is removed with the table written."""
    soak = load_benchmark("soak")
    calls, stop = [], {"at": "z_fingers=3"}

    def run_variant(name, steps, warmup, seed, timeout):
        calls.append(name)
        if name == stop["at"]:
            raise KeyboardInterrupt
        return {"steps": steps, "episodes": 1, "steps_per_s": 10.0, "rss_start_mb": 1.0, "rss_middle_mb": 1.0,
                "rss_end_mb": 1.0, "growth_mb": 0.0}

    monkeypatch.setattr(soak, "run_variant", run_variant)
    out = tmp_path / "soak.md"

    def args(steps=2):
        return ["--variants", "scale_range", "pose=so3", "z_fingers=3", "--steps", str(steps), "--warmup", "1",
                "--out", str(out)]

    argv = args()
    with pytest.raises(KeyboardInterrupt):
        soak.main(argv)
    assert calls == ["scale_range", "pose=so3", "z_fingers=3"] and not out.exists()
    calls.clear()
    stop["at"] = None
    assert soak.main(argv) == 0 and calls == ["z_fingers=3"]
    assert out.exists() and not list(tmp_path.glob(".*partial*")) and out.read_text().count("| +0.0 |") == 3
    calls.clear()
    with pytest.raises(KeyboardInterrupt):
        stop["at"] = "pose=so3"
        soak.main(argv)
    stop["at"] = None
    soak.main(args(steps=3))  # another --steps: nothing reused
    assert calls == ["scale_range", "pose=so3", "scale_range", "pose=so3", "z_fingers=3"]
