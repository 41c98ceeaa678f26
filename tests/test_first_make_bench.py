"""benchmarks/bench_first_make.py: a registered env's first make from an empty cache, and a later one."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("argv, match", [(["--env-id", "NoSuchEnv-v0"], "--env-id.*NoSuchEnv"),
                                         (["--env-kwargs", "[1]"], "--env-kwargs"),
                                         (["--env-kwargs", "{bad"], "--env-kwargs"),
                                         (["--env-kwargs", '{"no_such_field": 1}'], "--env-kwargs"),
                                         (["--baseline-approaches", "0"], "--baseline-approaches")])
def test_bad_arguments_fail_before_any_make(load_benchmark, usage_error, argv, match):
    usage_error(load_benchmark("bench_first_make").main, argv, match=match)


def test_a_cache_that_is_not_empty_is_refused_and_left_alone(load_benchmark, usage_error, tmp_path):
    (tmp_path / "kept.txt").write_text("x")
    usage_error(load_benchmark("bench_first_make").main, ["--env-id", "HapticRecog-v0", "--cache", str(tmp_path)],
                match="--cache.*not an empty folder")
    assert (tmp_path / "kept.txt").read_text() == "x"


@pytest.mark.slow
def test_the_geometric_env_first_and_later_make(load_benchmark, tmp_path, capsys):
    """The default env (no grasp pool, so no baseline) from a new folder, which is kept (a given --cache is)."""
    cache = tmp_path / "new"
    load_benchmark("bench_first_make").main(["--env-id", "HapticRecog-v0", "--cache", str(cache)])
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-1].startswith("HEADLINE: HapticRecog-v0: first make ") and "later make" in out[-1]
    assert any(line.startswith("later make + reset:") for line in out)
    assert (cache / "datasets").is_dir() and not (cache / "hand_grasps").exists()
