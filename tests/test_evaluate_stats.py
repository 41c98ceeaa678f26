"""Statistics of the evaluation reports that need no env: the cluster bootstrap of sweeps."""

from __future__ import annotations

import numpy as np
import pytest

from agents.evaluate import EpisodeRecord, cluster_intervals, rl_aggregates, summarize


def _mean(x):
    return np.array([x.mean()])


def test_a_sweep_resamples_each_situation_with_all_its_replays():
    """Agent seeds that replay the same situations add no independent episodes: three exact replays give the one
    replay's interval (rliable's stratified bootstrap, taking them as 120 runs, gave one about sqrt(3) narrower)."""
    rng = np.random.default_rng(0)
    one = rng.integers(1, 10, size=(40, 3)).astype(float)  # 40 situations x 3 env seeds
    three = np.concatenate([one, one, one])  # replicate r of situation u at row r x 40 + u
    _, ci1 = cluster_intervals({"a": one}, _mean, 40, seed=0)
    point, ci3 = cluster_intervals({"a": three}, _mean, 40, seed=0)
    np.testing.assert_allclose(ci3["a"], ci1["a"])
    assert point["a"][0] == pytest.approx(one.mean())
    _, apart = cluster_intervals({"a": three}, _mean, 120, seed=0)  # each replay its own situation: too narrow
    assert apart["a"][1, 0] - apart["a"][0, 0] < 0.75 * (ci1["a"][1, 0] - ci1["a"][0, 0])
    # paired: an agent and its baseline drawn alike; their difference has no spread when it is constant
    _, d = cluster_intervals({"d": [three + 1.0, three]}, lambda a, b: np.array([a.mean() - b.mean()]), 40)
    np.testing.assert_allclose(d["d"][:, 0], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"replicates x 40"):
        cluster_intervals({"a": three[:-1]}, _mean, 40)


def test_summaries_of_a_sweep_take_the_replays_as_one_situation():
    """summarize / rl_aggregates with ``period``: the intervals of three identical agent seeds equal one seed's."""
    rng = np.random.default_rng(1)
    base = [(s, e, int(rng.integers(1, 8)), bool(rng.random() < 0.9)) for s in (0, 1) for e in range(20)]

    def records(agent, shift, copies):
        return [EpisodeRecord(agent=agent, seed=s, episode=r * 20 + e, object="x", grasps=g + shift, decided=True,
                              correct=c, certainty=0.9, ret=0.0)
                for r in range(copies) for s, e, g, c in base]

    for copies in (1, 3):
        recs = records("random", 1, copies) + records("ppo", 0, copies)
        rows = {r["agent"]: r for r in summarize(recs, period=20)}
        agg = rl_aggregates(recs, 30, period=20, reps=300)["agents"]
        if copies == 1:
            first = (rows, agg)
            continue
        for key in ("success_ci", "grasps_mean_ci", "fewer_than_random_ci"):
            assert rows["ppo"][key] == pytest.approx(first[0]["ppo"][key])
        assert agg["ppo"]["grasps_iqm_ci"] == pytest.approx(first[1]["ppo"]["grasps_iqm_ci"])


def test_one_env_seed_has_no_seed_spread():
    """The spread over env seeds of one seed is not 0 (it was printed 0.00): NaN, shown as "-"."""
    from agents.evaluate import markdown_table

    recs = [EpisodeRecord(agent="random", seed=0, episode=e, object="x", grasps=e % 4 + 1, decided=True, correct=True,
                          certainty=0.9, ret=0.0) for e in range(10)]
    row = summarize(recs)[0]
    assert np.isnan(row["grasps_seed_std"])
    assert "| - |" in markdown_table([row])


def test_learning_curves_drop_the_steps_a_resume_played_again(tmp_path):
    """A segment killed after its last checkpoint went on past the step the next segment resumed at (which played
    those steps again): its episodes past that step are dropped, so each step counts once; a run without the
    recorded step (older runs) keeps every episode."""
    import json

    from agents.evaluate import read_monitor

    mon = tmp_path / "run" / "monitor"
    mon.mkdir(parents=True)

    def monitor(name, t_start, lengths):
        lines = [f'#{{"t_start": {t_start}, "env_id": "x"}}', "r,l,t"] + [f"0.0,{n},{i + 1}.0"
                                                                           for i, n in enumerate(lengths)]
        (mon / name).write_text("\n".join(lines) + "\n")

    monitor("0.monitor.csv", 0.0, [10] * 10)  # steps 10..100; the checkpoint was at 50, then a kill
    monitor("0.part2.monitor.csv", 1000.0, [10] * 5)  # resumed at 50: steps 60..100 again
    assert len(read_monitor(mon)["l"]) == 15  # no step recorded: every episode (as before)
    (tmp_path / "run" / "args.part2.json").write_text(json.dumps({"resumed_at_step": 50}))
    data = read_monitor(mon)
    assert len(data["l"]) == 10 and data["l"].sum() == 100  # 5 + 5 episodes: each step once
    # a third segment resumed from an earlier checkpoint (step 30, the later ones moved away): both before it stop there
    monitor("0.part3.monitor.csv", 2000.0, [10] * 7)
    (tmp_path / "run" / "args.part3.json").write_text(json.dumps({"resumed_at_step": 30}))
    assert read_monitor(mon)["l"].sum() == 30 + 70
    # a last line cut short (a kill or a full disk mid-write) is left out (a TypeError of float(None) before)
    for cut in ("-0.3,4\n", "-0.3,4,\n"):  # before its last field, or right after its last comma
        with open(mon / "0.part3.monitor.csv", "a") as fh:
            fh.write(cut)
        assert read_monitor(mon)["l"].sum() == 30 + 70
