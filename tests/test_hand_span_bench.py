"""benchmarks/hand_span.py: the span filter and a tiny run on the embedded default set (no data needed)."""

from __future__ import annotations

import numpy as np
import pytest


def test_span_mask_keeps_exactly_the_grasps_within_span_and_apart(load_benchmark):
    bench = load_benchmark("hand_span")
    C = np.array([[[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0]],      # span 0.071, separation 0.05
                  [[0, 0, 0], [0.2, 0, 0], [0, 0.05, 0]],       # span 0.206
                  [[0, 0, 0], [0.005, 0, 0], [0, 0.05, 0]]],    # separation 0.005
                 dtype=np.float64)
    assert bench.span_mask(C, np.inf, 0.0).tolist() == [True, True, True]
    assert bench.span_mask(C, 0.1, 0.0).tolist() == [True, False, True]
    assert bench.span_mask(C, 0.1, 0.01).tolist() == [True, False, False]
    with pytest.raises(ValueError, match="shape"):
        bench.span_mask(C[:, :1], 0.1, 0.0)
    with pytest.raises(ValueError, match="min_sep"):
        bench.span_mask(C, 0.1, 0.2)


def test_a_tiny_run_writes_its_table(load_benchmark, tmp_path, capsys, usage_error):
    bench = load_benchmark("hand_span")
    out = tmp_path / "span.md"
    assert bench.main(["--objects", "default", "--fingers", "4", "--grasps", "60", "--test-grasps", "10",
                       "--spans", "inf,0.12", "--min-seps", "0.01", "--out", str(out)]) == 0
    rows = [line for line in out.read_text().splitlines() if line.startswith("| 4 |")]
    assert len(rows) == 2 and "<= 0.12 m" in rows[1] and ">= 0.01 m" in rows[0]
    usage_error(bench.main, ["--spans", "0.1", "--min-seps", "0.2"], match="0 <= --min-seps <= every span")
