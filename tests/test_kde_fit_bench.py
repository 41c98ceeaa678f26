"""benchmarks/bench_kde_fit.py on the embedded default set (no shared data needed)."""

from __future__ import annotations

import re

import pytest


def test_times_both_settings_on_the_same_data(load_benchmark, capsys, tmp_path, monkeypatch):
    """It fits the earlier KDE twice and the analyses' KDE once, each by its own criterion, and its headline is the
    ratio of the CPU times it printed."""
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    load_benchmark("bench_kde_fit").main(["--fingers", "4", "--grasps-per-object", "300"])
    out = capsys.readouterr().out
    assert "select=likelihood, corrections matrix)" in out and "select=posterior, corrections matrix,power)" in out
    cpu = {m[0]: float(m[1]) for m in re.findall(r"^(earlier again|earlier|default) .*CPU ([\d.]+) s", out, re.M)}
    assert set(cpu) == {"earlier", "default", "earlier again"}
    head = out.strip().splitlines()[-1]
    assert head.startswith("HEADLINE:")
    ratio = float(re.search(r"takes ([\d.]+)x", head).group(1))
    assert ratio == pytest.approx(cpu["default"] / min(cpu["earlier"], cpu["earlier again"]), rel=0.03, abs=0.06)


def test_bad_arguments_are_named(load_benchmark, capsys):
    with pytest.raises(SystemExit):
        load_benchmark("bench_kde_fit").main(["--fingers", "1"])
    assert "--fingers must be >= 2" in capsys.readouterr().err
