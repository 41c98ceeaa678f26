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


@pytest.mark.parametrize("argv,word", [(["--fingers", "2"], "--fingers"), (["--fingers", "a"], "--fingers"),
                                       (["--mu", "0"], "--mu"), (["--grasps", "5"], "--grasps"),
                                       (["--min-epsilon", "-1"], "--min-epsilon"), (["--edges", "2"], "--edges"),
                                       (["--frame", "object"], "--frame")])
def test_bad_arguments_are_named(load_benchmark, capsys, argv, word):
    with pytest.raises(SystemExit):
        load_benchmark("force_closure").main(argv)
    assert word in capsys.readouterr().err
