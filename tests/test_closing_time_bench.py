"""benchmarks/closing_time.py's comparison of two runs of the same approaches (its runs need the hands)."""

from __future__ import annotations

import numpy as np
import pytest


def test_differences_compare_only_fingertips_that_touch_in_both(load_benchmark):
    bench = load_benchmark("closing_time")
    up = np.array([0.0, 0.0, 1.0])
    a = {"touched": np.array([[True, True], [True, False]]),
         "contacts": np.zeros((2, 2, 3)), "normals": np.tile(up, (2, 2, 1))}
    b = {"touched": np.array([[True, True], [True, True]]),
         "contacts": np.zeros((2, 2, 3)), "normals": np.tile(up, (2, 2, 1))}
    b["contacts"][0, 1] = [0.003, 0.004, 0.0]  # 5 mm away
    b["normals"][1, 0] = [1.0, 0.0, 0.0]  # 90 degrees
    b["contacts"][1, 1] = [1.0, 0.0, 0.0]  # finger 1 of grasp 1 touches only in b: not compared
    same, dist, ang = bench.differences(a, b)
    assert same == 0.5
    np.testing.assert_allclose(np.sort(dist), [0.0, 0.0, 0.005])
    np.testing.assert_allclose(np.sort(ang), [0.0, 0.0, 90.0])


def test_bad_arguments_fail_before_any_grasp(load_benchmark):
    bench = load_benchmark("closing_time")
    with pytest.raises(SystemExit, match="unknown hand"):
        bench.main(["--hands", "shadow,nohand"])
    with pytest.raises(SystemExit, match="approaches"):
        bench.main(["--approaches", "0"])
