"""benchmarks/force_closure.py on the embedded default set (no shared data needed)."""

from __future__ import annotations

import pytest


def test_tables_and_headline(load_benchmark, capsys):
    load_benchmark("force_closure").main(["--objects", "default", "--fingers", "3", "--grasps", "100",
                                          "--test-grasps", "20", "--speed-grasps", "100"])
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| 3 |")]
    assert len(rows) == 2  # without and with normals
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert all(0.0 <= float(v) <= 100.0 for v in cells[2:4]) and cells[4] == "-"  # no paper figure off kit8
    assert "the same answer on every grasp" in out
    assert out.strip().splitlines()[-1].startswith("HEADLINE: the force-closure test (n = 3) is ")


def test_epsilon_column(load_benchmark, capsys):
    load_benchmark("force_closure").main(["--objects", "default", "--fingers", "4", "--grasps", "60",
                                          "--test-grasps", "15", "--speed-grasps", "30", "--min-epsilon", "0.05",
                                          "--edges", "6", "--frame", "grasp"])
    out = capsys.readouterr().out
    assert "(6-edge pyramids, grasp frame)" in out
    assert "| force closure, epsilon quality >= 0.05 |" in out
    rows = [line for line in out.splitlines() if line.startswith("| 4 |")]
    assert len(rows) == 2
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert len(cells) == 6 and all(0.0 <= float(v) <= 100.0 for v in cells[2:5]) and cells[5] == "-"


def test_an_epsilon_no_grasp_reaches_is_named(load_benchmark):
    with pytest.raises(SystemExit, match="--min-epsilon 5"):
        load_benchmark("force_closure").main(["--objects", "default", "--fingers", "3", "--grasps", "50",
                                              "--test-grasps", "10", "--speed-grasps", "10", "--min-epsilon", "5"])


@pytest.mark.parametrize("argv,match", [
    (["--fingers", "2"], r"error: --fingers: finger counts >= 3 .*got '2'"),
    (["--fingers", "a"], r"error: --fingers: a comma list of integers, got 'a'"),
    (["--mu", "0"], r"error: argument --mu: must be a finite number in \(0.0, inf\], got 0"),
    (["--grasps", "5"], r"error: argument --grasps: must be >= 50, got 5"),
    (["--min-epsilon", "-1"], r"error: argument --min-epsilon: must be a finite number in \[0.0, inf\], got -1"),
    (["--edges", "2"], r"error: argument --edges: must be >= 3, got 2"),
    (["--frame", "object"], r"error: argument --frame: invalid choice: 'object'")])
def test_bad_arguments_are_named(load_benchmark, usage_error, argv, match):
    # the message itself: the usage line above it names every flag
    usage_error(load_benchmark("force_closure").main, argv, match=match)
