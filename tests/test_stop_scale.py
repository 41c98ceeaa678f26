"""The stop scale of experiment 2 (haptic_env/experiments/stop_scale.py): chosen on validation trials so that a stop
at lambda is right at least lambda of the time with the fewest grasps; and the analysis flag that applies it."""

import numpy as np
import pytest

from haptic_env.experiments.stop_scale import STOP_SCALES, fit_stop_scale, scaled
from haptic_env.experiments.trials import simulate_trials


def _pools(rng, K=4, G=400, margin=0.6, noise=1.0):
    """Per object ``(G, K)`` Gaussian log-likelihood scores whose true class leads by ``margin`` on average:
    each grasp weakly informative, so a belief needs several grasps."""
    LL = []
    for o in range(K):
        S = rng.normal(0.0, noise, size=(G, K))
        S[:, o] += margin
        LL.append(S)
    PR = [np.full((G, K), 1.0 / K) for _ in range(K)]
    return LL, PR


def _rate(LL, PR, s, lam, seed):
    res = simulate_trials(scaled(LL, s), PR, "bc-np", trials=800, max_grasps=30, threshold=lam,
                          rng=np.random.default_rng(seed))
    return (res["success"] & res["decided"]).mean(), res["grasps"].mean()


def test_fit_stop_scale_takes_the_fewest_grasps_that_stop_right_lambda_of_the_time():
    rng = np.random.default_rng(0)
    LL, PR = _pools(rng, margin=1.2)  # an under-confident belief: scores / s with s < 1 stop earlier
    chosen, table = fit_stop_scale(LL, PR, 0.85, trials=800, rng=np.random.default_rng(1))
    s = chosen[0]
    assert [r[0] for r in table] == list(STOP_SCALES)
    qualifying = [r for r in table if r[1] >= 0.85]
    assert qualifying and chosen == min(qualifying, key=lambda r: r[2])
    assert {r[0]: r for r in table}[s][2] <= {r[0]: r for r in table}[1.0][2]
    # the table is what the trials give: the same replay at the chosen scale, rate and grasps
    rate, grasps = _rate(LL, PR, s, 0.85, 1)
    assert (rate, grasps) == pytest.approx({r[0]: r for r in table}[s][1:])
    # sharper beliefs stop earlier: mean grasps fall as s falls
    g = [r[2] for r in table]
    assert g[0] < g[-1]


def test_fit_stop_scale_is_one_when_no_scale_stops_right_often_enough():
    rng = np.random.default_rng(2)
    LL, PR = _pools(rng, margin=0.0)  # no information: no scale is right 85 % of the time
    chosen, table = fit_stop_scale(LL, PR, 0.85, scales=(0.5, 1.0, 2.0), trials=200, rng=np.random.default_rng(3))
    assert chosen == table[1] and chosen[0] == 1.0 and all(r[1] < 0.85 for r in table)
    # without 1 among the scales, the fallback is still 1 (no change), its validation figures unknown
    chosen, _ = fit_stop_scale(LL, PR, 0.85, scales=(0.5, 2.0), trials=200, rng=np.random.default_rng(3))
    assert chosen[0] == 1.0 and np.isnan(chosen[1]) and np.isnan(chosen[2])


def test_fit_stop_scale_refuses_bad_input_by_name():
    LL, PR = _pools(np.random.default_rng(4), G=10)
    with pytest.raises(ValueError, match="threshold"):
        fit_stop_scale(LL, PR, 1.5, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="scales"):
        fit_stop_scale(LL, PR, 0.85, scales=(0.5, -1.0), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="scales"):
        fit_stop_scale(LL, PR, 0.85, scales=(), rng=np.random.default_rng(0))
    # 0 trials or grasps gave a stop scale of 1 (nan figures) without a word, -1 a numpy error
    for kw, match in (({"trials": 0}, "trials must be an int >= 1, got 0"), ({"trials": -1}, "trials must be"),
                      ({"max_grasps": 0}, "max_grasps must be an int >= 1, got 0")):
        with pytest.raises(ValueError, match=match):
            fit_stop_scale(LL, PR, 0.85, rng=np.random.default_rng(0), **kw)


def test_analysis_stop_scale_is_the_default_and_keeps_the_test_trials(tmp_path, monkeypatch):
    """By default experiment 2 reports the validation-chosen stop scale; ``--no-stop-scale`` drops it. IC, which
    has no likelihood, and the trials themselves (same draws) are unchanged."""
    from haptic_env.cli import main

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    base = ["analysis", "--experiments", "2", "--grasps-per-object", "200", "--test-grasps", "20", "--trials", "10",
            "--fingers", "3", "--mlp-epochs", "1", "--quiet"]
    assert main(base + ["--out", str(tmp_path / "plain"), "--no-stop-scale"]) == 0
    assert main(base + ["--out", str(tmp_path / "stop")]) == 0
    plain = (tmp_path / "plain" / "results.md").read_text()
    stop = (tmp_path / "stop" / "results.md").read_text()
    assert "stop scale (validation BC-NP)" in stop and "stop scale" not in plain
    # the equivalent commands spell the setting out
    command = {name: text.split("```")[1] for name, text in (("plain", plain), ("stop", stop))}
    assert " --stop-scale " in command["stop"] and "--no-stop-scale" not in command["stop"]
    assert " --no-stop-scale " in command["plain"]

    def row(text):
        line = next(ln for ln in text.splitlines() if ln.startswith("| 3 |"))
        return [c.strip() for c in line.strip("|").split("|")]

    p, s = row(plain), row(stop)
    assert p[:4] == s[:4]  # n, one-shot accuracy, temperatures
    assert p[4:8] == s[5:9]  # ic and ic-full: the same trials, no likelihood to scale


def test_raw_scores_have_no_stop_scale_and_refuse_one_by_name(tmp_path, monkeypatch, capsys):
    """``--raw`` is the paper's method: no calibration and no stop scale; asking for both is a usage error."""
    from haptic_env.cli import main
    from haptic_env.experiments.config import AnalysisConfig

    assert AnalysisConfig().uses_stop_scale and not AnalysisConfig(calibrated=False).uses_stop_scale
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    base = ["analysis", "--experiments", "2", "--grasps-per-object", "200", "--test-grasps", "20", "--trials", "10",
            "--fingers", "3", "--mlp-epochs", "1", "--quiet", "--raw"]
    with pytest.raises(SystemExit) as exc:
        main(base + ["--out", str(tmp_path / "both"), "--stop-scale"])
    assert exc.value.code == 2 and not (tmp_path / "both").exists()
    assert "error: --stop-scale scales calibrated scores; --raw is the paper's method" in capsys.readouterr().err
    assert main(base + ["--out", str(tmp_path / "raw")]) == 0
    raw = (tmp_path / "raw" / "results.md").read_text()
    assert "stop scale (validation BC-NP)" not in raw and " --no-stop-scale " in raw.split("```")[1]


def test_experiment_7_sweeps_lambda_with_the_stop_scale_of_experiment_2(tmp_path, monkeypatch):
    """By default experiment 7 adds BC-NP and BC-IP with the stop scale, fitted on validation trials at each lambda;
    at experiment 2's lambda it is experiment 2's scale (the same validation grasps and stream). IC has none."""
    from haptic_env.cli import main

    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "out"
    assert main(["analysis", "--out", str(out), "--experiments", "2,7", "--grasps-per-object", "200", "--test-grasps",
                 "20", "--trials", "10", "--fingers", "4", "--calib-fingers", "4", "--calib-fingers-no-normals", "",
                 "--lambdas", "0.6,0.85", "--mlp-epochs", "1", "--quiet"]) == 0
    text = (out / "results.md").read_text()
    exp2 = next(ln for ln in text.splitlines() if ln.startswith("| 4 | ") and " % / " in ln)
    s2 = [c.strip() for c in exp2.strip("|").split("|")][4].split(" (")[0]
    rows = {kind: next((ln for ln in text.splitlines() if ln.startswith(f"| 4 | yes | {kind} | stop scale |")), None)
            for kind in ("ic", "bc-np", "bc-ip")}
    assert rows["ic"] is None and rows["bc-np"] and rows["bc-ip"]
    cells = [c.strip() for c in rows["bc-np"].strip("|").split("|")][4:]
    assert len(cells) == 2 and all("(s " in c for c in cells)
    assert cells[1].split("(s ")[1].rstrip(")") == s2  # lambda = 0.85: experiment 2's scale
    assert "stop-scaled grasps" in text and (out / "lambda_sweep_n4_normals.png").stat().st_size > 1000
