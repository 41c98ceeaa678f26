"""benchmarks/stop_classifier.py end to end on a small embedded set (slow: it trains a KDE and gradient boosting)."""

from __future__ import annotations

import shlex

import pytest

from haptic_env.experiments.stop_scale import VALIDATION_TRIALS


@pytest.mark.slow
def test_it_fits_a_stop_scale_for_each_likelihood_on_validation_grasps(load_benchmark, tmp_path, monkeypatch):
    bench = load_benchmark("stop_classifier")
    out = tmp_path / "table.md"
    argv = ["--objects", "default", "--no-normals", "--fingers", "3", "--grasps-per-object", "300", "--out", str(out)]
    bench.main(argv)
    text = out.read_text()
    assert f"{VALIDATION_TRIALS} BC-NP trials per cell" in text
    rows = [line.split(" | ") for line in text.splitlines() if line.startswith("| 3 | ")]
    main = [r for r in rows if len(r) == 7]
    assert [r[1] for r in main] == list(bench.LIKELIHOODS)
    for r in main:
        # the scale chosen on set A; the fallback 1 marked when no scale stopped right lambda of the time there
        assert float(r[2].removesuffix(" (none reached lambda)")) in bench.SCALES
        right, grasps = (float(v) for v in r[3].split(" / "))
        assert 0 <= right <= 100 and 1 <= grasps <= 30
    frontier = [r for r in rows if len(r) > 7]
    assert sorted((r[1], r[2]) for r in frontier) == sorted((k, s) for k in bench.LIKELIHOODS for s in "AB")
    # a run started again with the same settings reads each finished finger count back: nothing is trained again
    monkeypatch.setattr(bench, "build_recognizer", lambda *a, **k: pytest.fail("the finished n = 3 was computed again"))
    bench.main(argv)
    again = out.read_text().splitlines()
    assert again[0] == text.splitlines()[0] == f"`{shlex.join(['python', 'benchmarks/stop_classifier.py', *argv])}`"
    assert again[3:] == text.splitlines()[3:]  # all but the caption under the command (its wall time)
    assert (tmp_path / "table.md.state.json").is_file()
