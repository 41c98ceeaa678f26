"""The paper's experiments (haptic_env/experiments): the analysis CLI on a tiny configuration (default objects, generated
in code), the trial runner, calibration summaries; and build_recognizer, which they train through."""

import dataclasses
import json

import numpy as np
import pytest

from haptic_env.cli import main
from haptic_env.dataset import DatasetConfig
from haptic_env.recognizers import MLPConfig, RecognizerConfig, build_recognizer
from haptic_env.experiments import simulate_trials


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_analysis_cli_smoke(tmp_path, cache, usage_error):
    out = tmp_path / "out"
    rc = main(["analysis", "--out", str(out), "--experiments", "1,2,6", "--grasps-per-object", "200",
               "--test-grasps", "20", "--trials", "10", "--fingers", "4", "--oneshot-fingers", "4",
               "--classifiers", "mlp,decision-tree",
               "--mlp-epochs", "1", "--kde-select", "likelihood", "--kde-corrections", "matrix", "--quiet"])
    assert rc == 0
    text = (out / "results.md").read_text()
    for heading in ("## 1.", "## 2.", "## 6."):
        assert heading in text
    assert (out / "success_vs_grasps.png").stat().st_size > 1000
    assert "factor auto by the density's validation likelihood" in text  # the earlier criterion, still offered
    from haptic_env.experiments.config import AnalysisConfig
    kde = AnalysisConfig().kde  # the analyses' default: the posterior criterion, both corrections weighed
    assert (kde.select, kde.correct, kde.correct_candidates) == ("posterior", "auto", ("matrix", "power"))
    usage_error(main, ["analysis", "--out", str(tmp_path / "bad"), "--kde-select", "median"],
                match="--kde-select: invalid choice: 'median'")
    usage_error(main, ["analysis", "--out", str(tmp_path / "bad"), "--kde-corrections", "matrix,isotonic"],
                match=r"--kde-corrections must be distinct names of .*'isotonic'")
    assert not (tmp_path / "bad").exists()


def test_analysis_with_normal_axis_ab_trains_and_tests_on_it(tmp_path, cache, usage_error):
    """``--normal-axis ab`` reaches the training and the fresh test grasps alike (a one-shot cell learns them) and
    the report says so; a bad value is refused before anything is written."""
    from haptic_env.experiments.config import AnalysisConfig
    from haptic_env.experiments.fresh_grasps import fresh_pool
    from haptic_env.objects import load_object_set

    cfg = AnalysisConfig(normal_axis="ab", test_grasps=5)
    assert cfg.recognizer_config().grasps.normal_axis == "ab"
    objs = load_object_set("default")
    pool = fresh_pool(objs, 4, True, cfg)
    ref = fresh_pool(objs, 4, True, AnalysisConfig(test_grasps=5))
    np.testing.assert_array_equal(pool[0][:, :6], ref[0][:, :6])  # the contacts' part is the paper's
    assert not np.allclose(pool[0][:, 6:], ref[0][:, 6:])
    frame = fresh_pool(objs, 4, True, AnalysisConfig(normal_axis="frame", test_grasps=5))
    assert frame[0].shape[1] == 18 and np.allclose(frame[0][:, 6:].reshape(-1, 4, 3)[..., :2].reshape(-1, 8), pool[0][:, 6:])
    out = tmp_path / "out"
    assert main(["analysis", "--out", str(out), "--experiments", "2", "--grasps-per-object", "200", "--test-grasps",
                 "20", "--trials", "10", "--fingers", "4", "--mlp-epochs", "1", "--normal-axis", "ab", "--quiet"]) == 0
    text = (out / "results.md").read_text()
    assert 'normal_axis=\"ab\"' in text
    assert "factor auto by the calibrated posterior's validation NLL" in text  # the analyses' default criterion
    with pytest.raises(ValueError, match="normal_axis must be one of .*'t3'"):
        AnalysisConfig(normal_axis="t3")
    usage_error(main, ["analysis", "--out", str(tmp_path / "bad"), "--normal-axis", "t3"],
                match="--normal-axis: invalid choice: 't3'")
    assert not (tmp_path / "bad").exists()


def test_force_closure_reaches_training_test_and_contact_pools(tmp_path, cache, usage_error):
    """``--force-closure MU`` trains and tests on force-closure grasps (the recogniser's dataset, the fresh pools, the
    z-finger experiment's raw contacts) and the report says so; finger counts below 3 are refused before any work."""
    from haptic_env.experiments.config import AnalysisConfig
    from haptic_env.experiments.fresh_grasps import contact_pool, fresh_pool
    from haptic_env.force_closure import force_closure
    from haptic_env.objects import load_object_set

    cfg = AnalysisConfig(force_closure=0.5, fingers=(3, 4), test_grasps=30)
    assert cfg.recognizer_config().grasps.force_closure == 0.5 and AnalysisConfig().recognizer_config().grasps.force_closure is None
    objs = load_object_set("default").subset(["box", "mug"], name="two")
    held = fresh_pool(objs, 3, False, cfg)
    assert [len(x) for x in held] == [30, 30] and not np.allclose(held[0], fresh_pool(objs, 3, False, AnalysisConfig(test_grasps=30))[0])
    (C, N), _ = contact_pool(objs, 4, True, 25, 1, force_closure=0.5)
    assert C.shape == (25, 4, 3) and force_closure(C, N, 0.5).all()
    with pytest.raises(ValueError, match=r"force_closure needs every finger count >= 3.*fingers=\(2, 3\)"):
        AnalysisConfig(force_closure=0.5, fingers=(2, 3))
    AnalysisConfig(force_closure=0.5, fingers=(2, 3), experiments=(1,))  # experiment 2 does not run: its fingers do not count
    with pytest.raises(ValueError, match="force_closure .* must be a finite number > 0 or None, got -1"):
        AnalysisConfig(force_closure=-1)
    for flags, match in ((["--force-closure", "0.5"], r"force_closure needs every finger count >= 3"),  # default: 2..10
                         (["--force-closure", "0", "--fingers", "3"], "--force-closure: must be a finite number")):
        usage_error(main, ["analysis", "--out", str(tmp_path / "bad"), "--experiments", "2", *flags], match=match)
    assert not (tmp_path / "bad").exists()


@pytest.mark.slow
def test_analysis_with_force_closure_end_to_end(tmp_path, cache):
    """Experiment 2 on force-closure grasps runs through and its report says so (about a minute: the default set's
    grasps are drawn until enough are in force closure)."""
    out = tmp_path / "out"
    assert main(["analysis", "--out", str(out), "--experiments", "2", "--grasps-per-object", "150", "--test-grasps",
                 "20", "--trials", "5", "--fingers", "3", "--mlp-epochs", "1", "--force-closure", "0.5", "--quiet"]) == 0
    assert "**Force-closure grasps only**" in (out / "results.md").read_text()


def test_build_recognizer_caches_and_updates(cache):
    from haptic_env.objects import load_object_set

    objs = load_object_set("default")
    objs = objs.subset(objs.names[:3], name="three")
    cfg = RecognizerConfig(grasps=DatasetConfig(grasps_per_object=300), mlp=MLPConfig(max_epochs=2, progress=False))
    rec = build_recognizer(objs, 4, True, z_values=(3,), config=cfg, progress=False)
    files = sorted(p.name for p in (cache / "recognizers").iterdir())
    assert len(files) == 8  # per z = 3 and 4: the mlp and the kde, each with its json
    kde_only = build_recognizer(objs, 4, True, z_values=(3,), config=cfg, models=("kde",), progress=False)
    assert kde_only.models.model(4)[0] is None and len(list((cache / "recognizers").iterdir())) == 8  # from the cache
    with pytest.raises(ValueError, match="needs the \\['mlp'\\] model"):
        kde_only.make_updater("ic")
    again = build_recognizer(objs, 4, True, z_values=(3,), config=cfg, progress=False)
    rng = np.random.default_rng(0)
    pts, nrm = objs[0].sample_surface(4, rng)
    q = rec.features(pts, nrm)
    assert np.allclose(rec.models.log_likelihood(q), again.models.log_likelihood(q), atol=1e-4)
    for kind in ("bc-np", "bc-ip", "ic", "ic-full"):
        u = rec.make_updater(kind)
        b = u.update_grasp(pts, nrm)
        assert b.shape == (3,) and u.n_grasps == 1 and np.all(b >= 0)
        if kind == "ic":  # the winner's score only
            assert np.count_nonzero(b) == 1 and 0 < b.max() <= 1
        else:  # a posterior
            assert b.sum() == pytest.approx(1.0)
    assert rec.make_updater("bc-np").update_grasp(pts, nrm).max() > 0.5  # one grasp moves the KDE's belief
    uz = rec.make_updater("bc-np", z=3, k=2, rng=rng)
    bz = uz.update_grasp(pts, nrm)
    assert bz.shape == (3,) and bz.sum() == pytest.approx(1.0)
    inc = rec.make_updater("bc-np")  # incomplete grasp routed to the 3-finger model: as a grasp of its 3 contacts
    touched = np.array([True, True, False, True])
    np.testing.assert_allclose(inc.update_grasp(pts, nrm, touched=touched),
                               rec.make_updater("bc-np").update_grasp(pts[touched], nrm[touched]), rtol=1e-12)
    (cache / "recognizers" / next(f for f in files if f.endswith("_mlp.pt"))).write_bytes(b"garbage")
    with pytest.warns(UserWarning, match="rebuilding"):
        build_recognizer(objs, 4, True, z_values=(3,), config=cfg, progress=False)


def test_simulate_trials_counts_and_success():
    # object 0 is recognised on the first grasp; object 1 never separates from 0
    LL = [np.log([[0.99, 0.01]] * 5), np.log([[0.5, 0.5]] * 5)]
    res = simulate_trials(LL, [np.exp(x) for x in LL], "bc-np", trials=40, max_grasps=5, threshold=0.85,
                          rng=np.random.default_rng(0))
    zero = res["truth"] == 0
    assert np.all(res["grasps"][zero] == 1) and np.all(res["success"][zero])
    assert np.all(res["grasps"][~zero] == 5)


def test_analysis_calibration_experiment(tmp_path, cache):
    out = tmp_path / "out"
    rc = main(["analysis", "--out", str(out), "--experiments", "2,7", "--grasps-per-object", "200",
               "--test-grasps", "20", "--trials", "10", "--fingers", "4", "--calib-fingers", "4",
               "--calib-fingers-no-normals", "3", "--lambdas", "0.6,0.85", "--mlp-epochs", "1", "--raw", "--quiet"])
    assert rc == 0
    text = (out / "results.md").read_text()
    assert "haptic-recog analysis --objects default" in text and "--raw" in text  # the command at the top
    assert "## 2. Sequential recognition at lambda = 0.85 (normals: True; raw scores (paper))" in text
    assert "## 7. Calibration" in text
    for model in ("BC (KDE)", "MLP"):
        assert f"| 4 | yes | {model} |" in text and f"| 3 | no | {model} |" in text
    # each variant's own accuracy beside its confidence (a learned correction moves the argmax; T does not)
    assert "| acc raw % | ECE raw | NLL raw | conf raw % | acc cal % | ECE cal | NLL cal | conf cal % |" in text
    mlp = next(line for line in text.splitlines() if line.startswith("| 4 | yes | MLP |")).split("|")
    assert mlp[5] == mlp[9]  # the MLP's calibration is a temperature only: the same argmax
    for kind in ("ic", "bc-np", "bc-ip"):
        for scores in ("raw", "calibrated"):
            assert f"| 4 | yes | {kind} | {scores} |" in text
    for cell in ("n4_normals", "n3_no_normals"):
        assert (out / f"reliability_{cell}.png").stat().st_size > 1000
        assert (out / f"lambda_sweep_{cell}.png").stat().st_size > 1000


def test_calibration_lowers_ece_of_overconfident_scores():
    from haptic_env.experiments import calibration_summary, oneshot_posterior
    from haptic_env.recognizers.calibration import fit_temperature

    rng = np.random.default_rng(0)
    K, B = 5, 4000
    y = rng.integers(0, K, size=B)
    logits = rng.normal(size=(B, K))
    logits[np.arange(B), y] += 1.0  # honest logits: softmax(logits) is roughly calibrated
    over = 6.0 * logits  # an over-confident model: the same ranking, far sharper posteriors
    over[:3, 1] = -np.inf  # a ruled-out class is allowed
    val, test = slice(0, B // 2), slice(B // 2, B)
    T = fit_temperature(over[val], y[val])
    assert T > 3
    raw = calibration_summary(oneshot_posterior(over[test]), y[test])
    cal = calibration_summary(oneshot_posterior(over[test] / T), y[test])
    assert raw["accuracy"] == cal["accuracy"]
    assert cal["ece"] < 0.05 < raw["ece"] and cal["nll"] < raw["nll"]
    assert np.allclose(oneshot_posterior(np.full((2, 3), -np.inf)), 1 / 3)  # no information: uniform
    for bad in (np.inf, np.nan):  # put at the floor before: a class scored +inf got probability 0
        with pytest.raises(ValueError, match=r"NaN or \+inf"):
            oneshot_posterior([[bad, 0.0]])


def test_simulate_trials_reports_decided():
    LL = [np.log([[0.99, 0.01]] * 5), np.log([[0.5, 0.5]] * 5)]
    res = simulate_trials(LL, [np.exp(x) for x in LL], "bc-np", trials=40, max_grasps=5, threshold=0.85,
                          rng=np.random.default_rng(0))
    assert np.array_equal(res["decided"], res["truth"] == 0)


def test_ic_certainty_reaches_the_trials_and_is_checked(tmp_path, usage_error):
    """``AnalysisConfig.ic_certainty`` / ``--ic-certainty``: the authors' share rule stops IC sooner than the count
    rule on the same draws; a bad rule is refused by name before any work."""
    from haptic_env.experiments.config import AnalysisConfig

    PR = [np.array([[0.7, 0.3]] * 10), np.array([[0.2, 0.8]] * 10)]
    LL = [np.log(p) for p in PR]
    kw = dict(trials=20, max_grasps=10, threshold=0.85)
    count = simulate_trials(LL, PR, "ic", rng=np.random.default_rng(0), **kw)
    share = simulate_trials(LL, PR, "ic", rng=np.random.default_rng(0), ic_certainty="share", **kw)
    assert not count["decided"].any() and share["decided"].all() and (share["grasps"] == 2).all()
    assert share["success"].all()
    assert "IC certainty: the winner's share" in AnalysisConfig(ic_certainty="share").scores_label
    assert "IC certainty" not in AnalysisConfig().scores_label
    with pytest.raises(ValueError, match=r"ic_certainty must be one of \('count', 'share'\), got 'sum'"):
        AnalysisConfig(ic_certainty="sum")
    usage_error(main, ["analysis", "--out", str(tmp_path / "bad"), "--ic-certainty", "sum"],
                match="--ic-certainty: invalid choice: 'sum'")
    assert not (tmp_path / "bad").exists()


def _incomplete_reference(pools, p, kind, trials, max_grasps, threshold, rng):
    """Experiment 3's incomplete-grasp loop as first written (before the shared trial runner): the oracle of
    the rng draws (one object per trial, then per grasp a finger count and a row, only until the decision)."""
    from haptic_env.recognizers.updaters import make_updater

    class C:
        n_classes = len(next(iter(pools.values()))[0])

    zlist = sorted(pools)
    u = make_updater(kind, classifier=C(), likelihood=C(), threshold=threshold)
    succ, used = [], []
    for _t in range(trials):
        o = int(rng.integers(C.n_classes))
        u.reset()
        for _g in range(max_grasps):
            LL, PR = pools[zlist[rng.choice(len(zlist), p=p)]]
            i = int(rng.integers(len(LL[o])))
            u.update_scores(log_lik=LL[o][i : i + 1], proba=PR[o][i : i + 1])
            if u.decided:
                break
        succ.append(u.prediction == o)
        used.append(u.n_grasps)
    return np.array(succ), np.array(used)


@pytest.mark.parametrize("kind", ["ic", "bc-np", "bc-ip"])
def test_incomplete_trials_draw_like_the_reference_loop(kind):
    from haptic_env.experiments import incomplete_trials

    g = np.random.default_rng(1)
    K = 4
    pools = {}
    for z, G in ((3, 7), (4, 11)):
        LL = [g.normal(size=(G, K)) * 1.5 for _ in range(K)]
        pools[z] = (LL, [np.exp(x) / np.exp(x).sum(1, keepdims=True) for x in LL])
    p = np.array([0.4, 0.6])
    got = incomplete_trials(pools, p, kind, trials=50, max_grasps=6, threshold=0.8, rng=np.random.default_rng(3))
    succ, used = _incomplete_reference(pools, p, kind, 50, 6, 0.8, np.random.default_rng(3))
    assert np.array_equal(got["success"], succ) and np.array_equal(got["grasps"], used)
    assert 1 < used.mean() < 6  # some trials stop early, some run out


@pytest.mark.parametrize("kw, message", [
    ({"trials": -1}, r"trials must be an int >= 1, got -1"),
    ({"max_grasps": 0}, r"max_grasps must be an int >= 1, got 0"),
    ({"test_grasps": 2.5}, r"test_grasps must be an int >= 1, got 2.5"),
    ({"grasps_per_object": True}, r"grasps_per_object must be an int >= 1, got True"),
    ({"seed": -3}, r"seed must be an int >= 0, got -3"),
    ({"threshold": 1.5}, r"threshold must be in \(0, 1\], got 1.5"),
    ({"experiments": ()}, r"experiments must be a non-empty tuple"),
    ({"fingers": (1, 4)}, r"fingers must be a tuple of ints in \[2, 20\], each once, got \(1, 4\)"),
    ({"fingers": (4, 4)}, r"fingers must be a tuple of ints in \[2, 20\], each once, got \(4, 4\)"),
    ({"zfinger_hands": (3,)}, r"zfinger_hands must be a tuple of ints in \[4, 20\], each once, got \(3,\)"),
    ({"classifiers": ("mlp", "svm")}, r"unknown classifier\(s\) \['svm'\]"),
    ({"incomplete_pn": ((3, 0.5), (3, 0.5))}, r"incomplete_pn must be .* one per finger count"),
    ({"scale_range": (2.0, 1.0)}, r"scale_range must be \(lo, hi\) with 0 < lo <= hi, got \(2.0, 1.0\)"),
    ({"lambdas": (0.5, 2.0)}, r"lambdas must be .* in \(0, 1\], got \(0.5, 2.0\)"),
    ({"ece_bins": 0}, r"ece_bins must be an int >= 1, got 0"),
    ({"baseline_max_train": 0}, r"baseline_max_train must be None or an int >= 100 .*, got 0"),
    ({"baseline_max_train": 1}, r"baseline_max_train must be None or an int >= 100 .*, got 1"),  # was a late crash
    ({"units": "furlong"}, r"unknown units 'furlong'"),
    ({"force_closure": 0.5, "fingers": (3, 4), "oneshot_fingers": (3,), "calib_fingers": (3,),
      "calib_fingers_no_normals": (4,), "incomplete_pn": ((2, 0.5), (4, 0.5))},
     r"force_closure needs every finger count >= 3 .* got incomplete_pn=\(\(2, 0.5\), \(4, 0.5\)\)"),
])
def test_analysis_config_names_a_bad_setting(kw, message):
    """Every count, tuple and probability of the analysis is checked when its config is made, before any grasp."""
    from haptic_env.experiments.config import AnalysisConfig

    with pytest.raises(ValueError, match=message):
        AnalysisConfig(**kw)



def test_the_papers_sequential_figures_only_at_its_lambda():
    """The paper's grasps and success rates are at lambda = 0.85: the sequential experiments print them beside ours
    only there (the one-shot accuracies do not depend on lambda)."""
    from haptic_env.experiments import paper

    assert paper.applies("kit8") and paper.applies("kit8", 0.85) and not paper.applies("kit8", 0.9)
    assert not paper.applies("default", 0.85)


def test_an_interrupted_analysis_resumes_after_its_finished_experiments(tmp_path, monkeypatch):
    """After each experiment the report, the finished experiments and the rng's state are saved; the same settings
    in the same folder skip what finished and give the report of an uninterrupted run (the rng continues from the
    saved state); other settings start over; a completed run leaves no state behind."""
    import haptic_env.experiments.analysis as analysis
    from haptic_env.experiments.config import AnalysisConfig

    calls, fail = [], {"at": None}

    def fake(e):
        def run(objects, cfg, rep, rng):
            calls.append(e)
            if fail["at"] == e:
                raise KeyboardInterrupt
            rep.h(f"experiment {e}")
            rep.p(f"draw {rng.random():.12f}")  # what an rng restored wrongly would change
        return type("Fake", (), {"run": staticmethod(run)})

    monkeypatch.setattr(analysis, "EXPERIMENTS", {e: fake(e) for e in (1, 2, 3)})
    monkeypatch.setattr(analysis.time, "perf_counter", lambda: 0.0)  # the report's "_experiment e: 0 s_" lines
    cfg = AnalysisConfig(experiments=(1, 2, 3), progress=False)
    whole = analysis.run_analysis(cfg, tmp_path / "whole").read_text()
    assert calls == [1, 2, 3] and not (tmp_path / "whole" / analysis.STATE_FILE).exists()

    calls.clear()
    fail["at"] = 3
    with pytest.raises(KeyboardInterrupt):
        analysis.run_analysis(cfg, tmp_path / "cut")
    state = json.loads((tmp_path / "cut" / analysis.STATE_FILE).read_text())
    assert calls == [1, 2, 3] and state["done"] == [1, 2]
    calls.clear()
    fail["at"] = None
    assert analysis.run_analysis(cfg, tmp_path / "cut").read_text() == whole and calls == [3]
    assert not (tmp_path / "cut" / analysis.STATE_FILE).exists()

    def cut_then_again(folder: str, at: int, again) -> list[int]:
        """Interrupt a run in experiment ``at``, then run ``again()`` in the same folder: the experiments it ran."""
        calls.clear()
        fail["at"] = at
        with pytest.raises(KeyboardInterrupt):
            analysis.run_analysis(cfg, tmp_path / folder)
        calls.clear()
        fail["at"] = None
        again(tmp_path / folder)
        return list(calls)

    # another seed: nothing of the saved run is reused
    seed1 = dataclasses.replace(cfg, seed=1)
    assert cut_then_again("other", 2, lambda out: analysis.run_analysis(seed1, out)) == [1, 2, 3]

    # other code than the saved run's (the key holds the meshes' identity alike): started over, not mixed in
    def other_code(out):
        monkeypatch.setattr(analysis, "source_fingerprint", lambda *packages: "other code")
        analysis.run_analysis(cfg, out)

    assert cut_then_again("code", 3, other_code) == [1, 2, 3]
    monkeypatch.undo()
    monkeypatch.setattr(analysis, "EXPERIMENTS", {e: fake(e) for e in (1, 2, 3)})
    monkeypatch.setattr(analysis.time, "perf_counter", lambda: 0.0)

    # run A cut after experiment 1, run B (other settings) cut in its first experiment (its plots drawn over A's):
    # A cannot resume any more (it kept B's plots), it starts over
    def other_settings_cut_in_its_first(out):
        fail["at"] = 1
        with pytest.raises(KeyboardInterrupt):
            analysis.run_analysis(seed1, out)
        fail["at"] = None
        calls.clear()
        analysis.run_analysis(cfg, out)

    assert cut_then_again("ab", 2, other_settings_cut_in_its_first) == [1, 2, 3]


def test_analysis_refuses_a_bad_family_hand_before_writing_anything(tmp_path):
    """Experiment 5's hand is resolved before any experiment runs or the output folder is made."""
    from haptic_env.experiments.analysis import run_analysis
    from haptic_env.experiments.config import AnalysisConfig

    cfg = AnalysisConfig(experiments=(1, 5), family_source="hand", family_hand="no_such_hand", progress=False)
    with pytest.raises(ValueError, match="no_such_hand"):
        run_analysis(cfg, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_reports_of_the_papers_set_put_its_figures_beside_ours(tmp_path, cache, monkeypatch):
    """Experiments 1-4 on the paper's object set print the paper's figures beside ours (``experiments.paper``): each
    classifier's one-shot accuracy in brackets, IC's and BC-NP's grasps, the z-finger rows of 4 random subsets, the
    incomplete grasps and the scaled objects; on any other set they print none. The paper's set is kit8 (shared
    data); here the default set stands in for it."""
    from haptic_env.experiments import paper

    args = ["analysis", "--experiments", "1,2,3,4", "--grasps-per-object", "200", "--test-grasps", "20",
            "--trials", "10", "--fingers", "3,4", "--oneshot-fingers", "3", "--zfinger-hands", "5",
            "--classifiers", "mlp,knn", "--mlp-epochs", "1", "--no-stop-scale", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "plain")]) == 0
    plain = (tmp_path / "plain" / "results.md").read_text()
    assert not any(s in plain for s in ("(86.0)", "paper ic grasps", "Paper:", "paper IC", "paper success"))
    monkeypatch.setattr(paper, "PAPER_SET", "default")
    assert main([*args, "--out", str(tmp_path / "paper")]) == 0
    text = (tmp_path / "paper" / "results.md").read_text()
    rows = {line.split(" | ")[0] + "|" + line.split(" | ")[1]: line for line in text.splitlines()
            if line.startswith("| ")}
    assert "(86.0) |" in rows["| 3|yes"] and "(70.8) |" in rows["| 3|yes"]  # mlp and knn, with normals
    assert "(47.0) |" in rows["| 3|no"] and "(45.6) |" in rows["| 3|no"]
    exp2 = [line for line in text.splitlines() if line.startswith("| 3 | ") and "3.57 ± 4.57" in line]
    assert len(exp2) == 1 and exp2[0].endswith("| 3.57 ± 4.57 | 3.53 ± 2.07 |")
    assert "| paper ic grasps | paper bc-np grasps |" in text
    assert (tmp_path / "paper" / "sequential_vs_fingers.png").stat().st_size > 1000  # with the paper's grasps drawn
    zrows = [line for line in text.splitlines() if line.startswith("| 5 | 3 | ")]
    assert zrows[0].endswith("| - | - |") and zrows[1].endswith("| 96.7 / 1.57 | 91.7 / 1.27 |")  # all, then k=4
    assert "| bc-np | " in text and "| 93.3 / 2.87 |" in text  # incomplete grasps of a 5-finger hand
    scaled = [line for line in text.splitlines() if line.startswith("| yes | ")]
    assert scaled[-1].endswith("| 90.2 / 92.2 / 91 |")
