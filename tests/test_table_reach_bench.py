"""benchmarks/table_reach.py: how far fingertips reach into the visual table and into a solid one."""

from __future__ import annotations

import numpy as np
import pytest


def test_depth_is_the_lowest_touching_fingertip_under_the_table(load_benchmark):
    bench = load_benchmark("table_reach")
    sites = np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.004], [0.0, 0.0, -0.02]])
    radius = np.array([0.01, 0.01, 0.01])
    touched = np.array([True, True, False])
    assert bench.depth_below_table(sites, radius, touched, 0.0) == pytest.approx(0.006)  # the untouched one is deeper
    assert bench.depth_below_table(sites, radius, np.array([True, False, False]), 0.0) == 0.0
    assert bench.depth_below_table(sites, radius, np.zeros(3, bool), 0.0) == 0.0


def test_a_small_run_reports_both_tables_with_the_headline_last(load_benchmark, capsys):
    bench = load_benchmark("table_reach")
    assert bench.main(["--hands", "generic", "--objects", "default", "--approaches", "2"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    rows = [line for line in out if line.startswith("| generic |")]
    assert [r.split(" | ")[1] for r in rows] == ["visual", "solid"]
    assert out[-1].startswith("HEADLINE: generic grasps reaching into the table:")


def test_bad_arguments_are_usage_errors(load_benchmark, usage_error):
    bench = load_benchmark("table_reach")
    usage_error(bench.main, ["--hands", "allegro,nohand"], match="unknown hand nohand")
    usage_error(bench.main, ["--approaches", "0"], match="approaches")
    usage_error(bench.main, ["--depth", "-1"], match="depth")
    usage_error(bench.main, ["--objects", "nosuchset"], match="objects")
