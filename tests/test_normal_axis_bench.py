"""benchmarks/normal_axis.py on the embedded default set (no shared data needed)."""

from __future__ import annotations

import pytest


def _rows(out: str) -> dict[str, list[float]]:
    rows = {}
    for line in out.splitlines():
        if line.startswith(("| t2", "| ab", "| frame")):
            cells = [c.strip() for c in line.strip("|").split("|")]
            rows[cells[0].split()[0]] = [float(c) for c in cells[1:]]
    return rows


def test_three_fingers_read_the_same_either_way(load_benchmark, capsys):
    """At n = 3 "t2" and "ab" give the same vectors (the paper's n = 3 rule), so every model scores the same;
    "frame" has its own row."""
    load_benchmark("normal_axis").main(["--objects", "default", "--fingers", "3", "--grasps", "300",
                                        "--test-grasps", "40", "--models", "knn,kde"])
    rows = _rows(capsys.readouterr().out)
    assert set(rows) == {"t2", "ab", "frame"} and rows["t2"] == rows["ab"] and len(rows["frame"]) == 2


def test_four_fingers_differ_and_bad_arguments_are_named(load_benchmark, capsys):
    bench = load_benchmark("normal_axis")
    bench.main(["--objects", "default", "--fingers", "4", "--grasps", "300", "--test-grasps", "40", "--models", "knn"])
    rows = _rows(capsys.readouterr().out)
    assert rows["t2"] != rows["ab"] and all(0.0 <= v <= 100.0 for r in rows.values() for v in r)
    with pytest.raises(SystemExit):
        bench.main(["--models", "svm"])
    assert "svm" in capsys.readouterr().err
