"""benchmarks/hand_experiment.py: the training config of each regime and likelihood, and its command line's errors."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from haptic_env.recognizers.boosted import BoostedConfig


@pytest.fixture(scope="module")
def bench(load_benchmark):
    return load_benchmark("hand_experiment")


def _args(**kw):
    base = dict(hand_budget="uniform", surface_grasps=500, surface_noise=0.0, surface_normal_noise=0.0)
    return SimpleNamespace(**{**base, **kw})


@pytest.mark.parametrize("regime", ["hand", "surface"])
def test_hgb_takes_the_kdes_place_with_the_same_k(bench, regime):
    kde = bench.training_config(regime, "allegro", _args(likelihood="kde"), calibrate_grasps=4, approaches=300)
    hgb = bench.training_config(regime, "allegro", _args(likelihood="hgb"), calibrate_grasps=4, approaches=300)
    assert kde.likelihood == "kde" and kde.kde.calibrate_grasps == 4
    assert hgb.likelihood == "hgb" and hgb.boosted == BoostedConfig(calibrate_grasps=4)
    assert hgb.grasps == kde.grasps  # the same training grasps; only the likelihood differs
    # the callers that pass their own args without the flag (stop_frontier.py, hand_classifiers.py) keep the KDE
    assert bench.training_config(regime, "allegro", _args(), calibrate_grasps=4, approaches=300) == kde


class _Constant:
    """A model that gives every row the same scores (log-likelihoods or probabilities)."""

    def __init__(self, row):
        self.row = np.asarray(row, dtype=float)
        self.n_classes = len(self.row)

    def log_likelihood(self, Q):
        return np.tile(self.row, (len(Q), 1))

    predict_proba = log_likelihood


def test_run_query_gives_bc_ip_the_touch_pattern_at_every_grasp(bench):
    """BC-IP, touch: a grasp with too few touching fingertips adds its pattern's row alone, the first complete grasp
    the classifier's prior and its row, a later one the KDE's row and its own: one Bayes step each."""
    from scipy.special import logsumexp

    from haptic_env.recognizers.updaters import BCIP
    from haptic_env.recognizers.zfinger import ZFingerUpdater

    proba, ll = np.array([0.6, 0.3, 0.1]), np.log([0.2, 0.5, 0.3])
    upd = ZFingerUpdater(BCIP(_Constant(proba), _Constant(ll), threshold=0.999999))
    rng = np.random.default_rng(0)
    C, N = rng.normal(size=(3, 4, 3)), None
    T = np.array([[1, 1, 0, 0], [1, 1, 1, 1], [1, 1, 1, 1]], dtype=bool)
    touch = np.log(rng.dirichlet(np.ones(3), size=3))
    assert bench.run_query(upd, C, N, T, False, touch)[1:] == (3, False)
    lb = touch.sum(0) + np.log(proba) + ll
    np.testing.assert_allclose(upd.belief, np.exp(lb - logsumexp(lb)), rtol=1e-12)
    assert upd.n_grasps == 3 and upd.prior_set
    state = upd.rng, upd.belief.copy()
    for bad, match in ((np.full((1, 3), np.nan), "NaN"), (np.zeros((1, 2)), "evidence")):
        with pytest.raises(ValueError, match=match):  # refused before the grasp's subsets are drawn
            upd.update_grasp(C[1], None, T[1], evidence=bad)
    assert upd.rng is state[0] and np.array_equal(upd.belief, state[1]) and upd.n_grasps == 3
    from haptic_env.recognizers.updaters import IterativeClassification

    with pytest.raises(ValueError, match="no evidence rows"):
        ZFingerUpdater(IterativeClassification(_Constant(proba), 0.9)).update_grasp(C[1], None, T[1],
                                                                                   evidence=touch[:1])


def test_command_line_errors_name_the_bad_value(bench, usage_error):
    usage_error(bench.main, ["--likelihood", "mlp"], match=r"--likelihood: invalid choice: 'mlp'")
    usage_error(bench.main, ["--likelihood", "hgb", "--kde-bandwidth", "per-class"],
                match=r"--kde-bandwidth per-class sets the KDE, which --likelihood hgb replaces")
    # taken before: a hand twice wrote its rows twice, a method twice was merged, a bad noise failed after the pools
    usage_error(bench.main, ["--hands", "aero", "aero"], match=r"--hands: each value once, got \['aero', 'aero'\]")
    usage_error(bench.main, ["--methods", "BC-NP", "BC-NP"], match=r"--methods: each value once")
    usage_error(bench.main, ["--surface-normal-noise", "nan"], match=r"--surface-normal-noise: .*got nan")


def test_the_recorded_command_runs_again_and_one_seed_has_no_spread(bench, tmp_path):
    """The command atop a table is quoted (methods named "BC-NP, z=3" were split into two words); the "+-" of one
    seed is NaN (it printed 0 under "sample std, ddof = 1")."""
    import shlex

    bench.write_table(tmp_path, "t.md", "hand_experiment.py", ["--methods", "BC-NP, z=3", "BC-IP"], 1.0, "x")
    cmd = (tmp_path / "t.md").read_text().split("`")[1]
    assert shlex.split(cmd)[2:] == ["--methods", "BC-NP, z=3", "BC-IP"]
    assert np.isnan(bench.seed_std(np.array([0.9]))) and np.isclose(bench.seed_std(np.array([1.0, 2.0, 3.0])), 1.0)


_TABLE = """`python benchmarks/hand_experiment.py --out somewhere` (9 s)

YCB-10, 10 queries per object x 3 test seeds ([0, 1, 2]), <= 30 random-approach grasps per query, lambda = 0.9, \
calibrated scores. Success = decided and correct at the stop.

| hand | fingers | normals | training | method | success % | accuracy % | grasps | paper (success % / grasps) | \
usable grasps | T (KDE / MLP) | K | training grasps / object | touch w |
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
| allegro | 4 | yes | hand | BC-NP | 98.0 +- 0.5 | 98.0 +- 0.0 | 3.31 +- 0.14 | 92 / 4.8 | \
 0.73 | 5.58 / 1.04 | 5 | 6,000 | 0 |
| shadow | 5 | no | surface | IC, z=3 | 0.0 +- 0.0 | 10.0 +- 0.0 | 30.00 +- 0.00 | 51 / 1.04 | \
 0.82 | 1.37 / 1.11 | 5 | 20,000 | 0 |
"""


def test_read_table_gives_the_rows_the_script_wrote(bench):
    rows, threshold = bench.read_table(_TABLE)
    assert threshold == 0.9
    assert rows[0] == {"hand": "allegro", "fingers": 4, "normals": True, "training": "hand", "method": "BC-NP",
                       "success": pytest.approx(0.98), "success_std": pytest.approx(0.005), "grasps": 3.31,
                       "grasps_std": 0.14, "paper": (pytest.approx(0.92), 4.8)}
    assert rows[1]["hand"] == "shadow" and rows[1]["normals"] is False and rows[1]["method"] == "IC, z=3"
    assert rows[1]["grasps"] == 30.0 and rows[1]["paper"] == (pytest.approx(0.51), 1.04)
    one, _ = bench.read_table(_TABLE.replace("| 3.31 +- 0.14 |", "| 3.31 |"))  # a one-seed cell (bench.pm)
    assert one[0]["grasps"] == 3.31 and np.isnan(one[0]["grasps_std"])


def test_the_committed_hand_table_reads_with_the_papers_figures(bench):
    """results/hands/hand_table.md, which this script wrote: 40 rows in the paper's four columns, each with the
    paper's figure of its method and column as the script holds it (:data:`PAPER`)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "results" / "hands" / "hand_table.md").read_text()
    rows, threshold = bench.read_table(text)
    assert threshold == 0.85 and len(rows) == 40
    assert list(dict.fromkeys((r["hand"], r["fingers"], r["normals"]) for r in rows)) == [
        ("allegro", 4, True), ("allegro", 4, False), ("shadow", 5, False), ("aero", 5, False)]
    for r in rows:
        s, g = bench.PAPER[r["method"]][f"{r['fingers']}{'+' if r['normals'] else '-'}"]
        assert r["paper"] == (pytest.approx(s / 100), g)


def test_plot_draws_a_table_beside_it(bench, tmp_path, capsys):
    table = tmp_path / "hand_table.md"
    table.write_text(_TABLE)
    assert bench.main(["--plot", str(table)]) == 0
    png = tmp_path / "hand_table.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hand_table.md", "hand_table.png"]  # no temporary left
    assert "wrote" in capsys.readouterr().out


def test_plot_errors_name_the_file_and_the_problem(bench, tmp_path, usage_error):
    missing = tmp_path / "nothing.md"
    usage_error(bench.main, ["--plot", str(missing)], match=r"--plot .*nothing\.md: .*No such file")
    other = tmp_path / "other.md"
    other.write_text("# results\n\n| a | b |\n|---|---|\n| 1 | 2 |\n")
    usage_error(bench.main, ["--plot", str(other)], match=r"--plot .*other\.md: no hand table")
    broken = tmp_path / "broken.md"
    broken.write_text(_TABLE.replace("| IC, z=3 |", "| IC, z=9 |"))
    usage_error(bench.main, ["--plot", str(broken)], match=r"not a row of the hand table: .*IC, z=9")
    broken.write_text(_TABLE.replace("| 3.31 +- 0.14 |", "| n/a |"))
    usage_error(bench.main, ["--plot", str(broken)], match=r"not a row of the hand table: .*BC-NP .*n/a")
    usage_error(bench.main, ["--plot", str(other), "--out", str(tmp_path / "out")],
                match=r"--plot draws the table in .*other\.md; --out runs the experiment")
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob("*.png"))
