"""benchmarks/bench_boosted.py on the embedded default set (no shared data needed)."""

from __future__ import annotations

import re

import pytest


def test_both_paths_agree_and_the_headline_is_their_ratio(load_benchmark, capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    rc = load_benchmark("bench_boosted").main(["--fingers", "3", "--grasps-per-object", "300", "--max-iter", "5",
                                                "--singles", "5", "--batch", "50", "--repeats", "1",
                                                "--evict-mb", "1"])
    out = capsys.readouterr().out
    assert rc == 0
    gap = float(re.search(r"log-likelihoods on 50 vectors: ([\d.e+-]+)", out).group(1))
    assert gap <= 1e-9
    one = {m[0].strip(): float(m[1]) for m in re.findall(r"^(scikit-learn again|scikit-learn|compiled) +one vector per "
                                                         r"call +([\d.]+) us", out, re.M)}
    assert set(one) == {"scikit-learn", "compiled", "scikit-learn again"}
    cold = re.findall(r"^(scikit-learn|compiled) +one vector per call, cold cache "
                      r"\(1 MB written before each\): +[\d.]+ us", out, re.M)
    assert cold == ["scikit-learn", "compiled"]
    head = out.strip().splitlines()[-1]
    assert head.startswith("HEADLINE:")
    ratio = float(re.search(r"in ([\d.]+)x", head).group(1))
    assert ratio == pytest.approx(one["compiled"] / min(one["scikit-learn"], one["scikit-learn again"]), rel=0.02,
                                  abs=1e-3)


def test_bad_arguments_are_named(load_benchmark, capsys):
    with pytest.raises(SystemExit):
        load_benchmark("bench_boosted").main(["--singles", "0"])
    assert "--singles is too small: 0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        load_benchmark("bench_boosted").main(["--evict-mb", "-1"])
    assert "--evict-mb must be >= 0, got -1" in capsys.readouterr().err
