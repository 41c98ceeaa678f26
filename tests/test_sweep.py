"""``haptic-recog sweep``: spec expansion, and real sweeps on a local Ray with 2 CPUs (the smoke spec: random vs
greedy on the default env with a tiny recogniser): the report files, skip-on-rerun, a job that fails once
(retried, done), a job that always fails (retried, reported, exit status 1), a killed worker (retried, done).
Slow: a PPO job whose train.py is killed mid-run (the retry resumes from its checkpoint) and a two-node
``ray start`` cluster on 127.0.0.1."""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

import pytest

from haptic_env.sweep import SpecError, parse_spec

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "sweeps" / "smoke.toml"


def _smoke_doc() -> dict:
    return tomllib.loads(SMOKE.read_text())


def _cmd(code: str) -> list[str]:
    return [sys.executable, "-c", code]


def _fake_train_py(monkeypatch, folder: Path) -> list[list[str]]:
    """The train job's ``train.py`` replaced by a stub that records its command line and writes ``folder /
    ppo_final.zip``, as a finished run would; returns the list of recorded command lines."""
    from haptic_env.sweep import jobs

    runs: list[list[str]] = []

    def run_logged(cmd, log, cwd, pidfile):
        from stable_baselines3.common.save_util import save_to_zip_file

        runs.append(cmd)
        steps = int(cmd[cmd.index("--total-timesteps") + 1]) // (2 if "--max-minutes" in cmd and float(
            cmd[cmd.index("--max-minutes") + 1]) > 0 else 1)  # a time limit stops it half-way
        save_to_zip_file(folder / "ppo_final.zip", data={"num_timesteps": steps})
        return 0

    monkeypatch.setattr(jobs, "_run_logged", run_logged)
    return runs


# ------------------------------------------------------------------------------------------ specs
def test_shipped_specs_expand():
    from haptic_env.sweep import load_spec

    n = {p.stem: len(load_spec(p).jobs) for p in sorted((ROOT / "sweeps").glob("*.toml"))}
    assert n["smoke"] == 2
    assert n["easy"] == 3 * (2 + 2 * 2)  # seeds x (random, greedy, PPO train+eval, SAC train+eval)
    assert n["objects"] == 2 * n["easy"] and n["hands"] == 4 * n["easy"] and n["geometry"] == n["easy"]
    assert n["paper_data"] == 2 * 9 * 2 + 2
    assert n["hands_categorical"] == 3 * (1 + 2)  # seeds x (random, PPO over 64 approaches train+eval)


def test_a_categorical_agent_trains_with_its_approaches_and_evaluates_without_repeats(tmp_path, monkeypatch):
    """``discrete_approaches`` and ``no_repeat`` reach train.py and the evaluate job's agent; a trained agent without
    them keeps the job keys of earlier sweeps (neither key appears in its params)."""
    from haptic_env.sweep import jobs

    doc = {"name": "c", "seeds": [0], "env_ids": ["HapticRecog-v0"],
           "agent": [{"name": "ppo", "algo": "ppo"}, {"name": "p64", "algo": "ppo", "discrete_approaches": 64,
                                                       "no_repeat": True}]}
    train, evaluate, train64, evaluate64 = parse_spec(doc).jobs
    assert "discrete_approaches" not in train.params and "no_repeat" not in evaluate.params
    assert train64.params["discrete_approaches"] == 64 and evaluate64.params["no_repeat"] is True
    runs = _fake_train_py(monkeypatch, tmp_path)
    jobs._train(train64.params, tmp_path, 1, {})
    assert runs[0][-2:] == ["--discrete-approaches", "64"]
    made = []
    monkeypatch.setattr("agents.evaluate.make_agent", lambda spec, seed=0, no_repeat=False: made.append(no_repeat)
                        or (_ for _ in ()).throw(RuntimeError("stop")))
    with pytest.raises(RuntimeError, match="stop"):
        jobs._evaluate(evaluate64.params, tmp_path, 1, {"dep_dirs": [str(tmp_path)]})
    assert made == [True]
    masked = parse_spec({**doc, "agent": [{"name": "m", "algo": "mppo", "discrete_approaches": 64}]}).jobs
    assert [(j.kind, j.params.get("algo"), j.params.get("discrete_approaches")) for j in masked] == [
        ("train", "mppo", 64), ("evaluate", None, None)]
    assert masked[1].params["spec"] == "mppo_final.zip"


def test_every_baseline_agent_that_evaluate_builds_is_a_valid_sweep_agent():
    """The sweep checks a baseline agent's name with evaluate's own parser (make_agent): greedy-env, the blind
    look-aheads and greedy:M:S are accepted as they are by ``haptic-recog evaluate``."""
    for name in ("random", "greedy", "greedy:8", "greedy:8:2", "greedy-env", "greedy-blind", "greedy-env-blind:16:4"):
        spec = parse_spec({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": name}]})
        assert [j.params["spec"] for j in spec.jobs] == [name]


def test_grid_expansion_keys_and_dependencies():
    doc = {"name": "g", "seeds": [0, 1], "env_ids": ["HapticRecog-v0", "HapticRecogKIT-v0"],
           "agent": [{"name": "random"}, {"name": "ppo", "algo": "ppo", "total_timesteps": 1000}],
           "dataset": [{"objects": ["default"], "fingers": [3, 4], "normals": [True, False], "grasps_per_object": 50}],
           "analysis": [{"objects": "default", "flags": {"experiments": "2"}}]}
    spec = parse_spec(doc)
    kinds = [j.kind for j in spec.jobs]
    assert kinds.count("train") == 4 and kinds.count("evaluate") == 8 and kinds.count("dataset") == 4
    by_id = spec.by_id()
    for j in spec.jobs:
        for d in j.deps:
            assert d in by_id
        if j.kind == "evaluate" and j.params["trained"]:
            assert by_id[j.deps[0]].kind == "train" and by_id[j.deps[0]].params["seed"] == j.params["seed"]
        if j.kind == "analysis":
            assert len(j.deps) == 4
    # the key is the settings' hash: stable, and a changed setting is another job (another folder)
    assert [j.id for j in parse_spec(copy.deepcopy(doc)).jobs] == [j.id for j in spec.jobs]
    doc["agent"][1]["total_timesteps"] = 2000
    changed = {j.id for j in parse_spec(doc).jobs} - {j.id for j in spec.jobs}
    assert {i.split("/")[0] for i in changed} == {"train", "evaluate"} and len(changed) == 8


def test_a_hand_env_row_may_add_backend_settings_that_keep_its_hand():
    """A mapping keyword updates the variant's mapping (``haptic_env.config.with_keys``), so a row of a hand env that
    adds ``solid_table`` keeps the variant's hand and is that env (it was refused as a change of what it sets)."""
    import haptic_env

    doc = {"name": "x", "env": [{"id": "HapticRecogShadow-v0", "kwargs": {"backend_kwargs": {"solid_table": False}}}],
           "agent": [{"name": "random"}]}
    spec = parse_spec(doc)
    env_id, kwargs = spec.envs["HapticRecogShadow-v0"]
    assert dict(haptic_env.variant_config(env_id, **kwargs).backend_kwargs) == {"hand": "shadow", "solid_table": False}


def test_a_changed_env_variant_is_a_new_job(monkeypatch):
    """What a registered id sets is part of its jobs' keys: a release that changes it re-runs them."""
    import haptic_env

    doc = {"name": "v", "seeds": [0], "env_ids": ["HapticRecog-v0", "HapticRecogKIT-v0"],
           "agent": [{"name": "random"}, {"name": "ppo", "algo": "ppo", "total_timesteps": 1000}]}
    before = {j.id for j in parse_spec(copy.deepcopy(doc)).jobs}
    monkeypatch.setitem(haptic_env.ENV_VARIANTS, "HapticRecogKIT-v0",
                        {**haptic_env.ENV_VARIANTS["HapticRecogKIT-v0"], "training_grasps": 1234})
    changed = {j.id for j in parse_spec(doc).jobs} - before
    assert changed and all("HapticRecogKIT-v0" in i for i in changed) and len(changed) == 3  # train + 2 evaluates


@pytest.mark.parametrize("doc, match", [
    ({"name": "x"}, "no jobs"),
    ({"name": "x", "bogus": 1, "env_ids": ["HapticRecog-v0"], "agent": [{"name": "random"}]}, "unknown key"),
    ({"name": "x", "env_ids": ["Nope-v0"], "agent": [{"name": "random"}]}, "unknown env id"),
    ({"name": "x", "env": [{"id": "HapticRecogKIT-v0", "kwargs": {"objects": "kit20"}}], "agent": [{"name": "random"}]},
     "change what HapticRecogKIT-v0 sets"),
    ({"name": "x", "env": [{"id": "HapticRecogShadow-v0", "kwargs": {"backend_kwargs": {"hand": "allegro"}}}],
      "agent": [{"name": "random"}]}, r"kwargs \['backend_kwargs'\] change what HapticRecogShadow-v0 sets"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "env_kwargs": {"max_grasps": 0}, "agent": [{"name": "random"}]},
     "max_grasps"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "ppo", "algo": "dqn"}]}, "algo"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "typo"}]}, "baseline agent: unknown agent spec"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "greedy:x"}]}, "M and S must be whole numbers"),
    ({"name": "x", "agent": [{"name": "random"}]}, "without any env"),
    ({"name": "x", "dataset": [{"fingers": [1]}]}, "n_fingers"),
    # a trained agent's and an analysis job's settings: refused at load, not on a worker hours later
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "p", "algo": "ppo", "vec": "bogus"}]},
     r"agent\[0\].vec: expected one of \('subproc', 'dummy', 'native'\), got 'bogus'"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "p", "algo": "ppo", "max_minutes": -5}]},
     r"max_minutes: expected a number >= 0 \(0: no limit\), got -5"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"],
      "agent": [{"name": "s", "algo": "sac", "hyperparams": {"bogus_key": 1}}]},
     r"hyperparams: unknown SAC hyperparameter\(s\) \['bogus_key'\]"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "s", "algo": "sac", "discrete_approaches": 8}]},
     r"agent\[0\].discrete_approaches: sac.s policy takes a continuous action only \(got discrete_approaches 8\)"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"],
      "agent": [{"name": "p", "algo": "ppo", "discrete_approaches": 8, "vec": "native"}]}, "got \"native\""),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "p", "algo": "ppo", "no_repeat": True}]},
     r"no_repeat: needs a categorical policy without memory .* discrete_approaches 0"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"],
      "agent": [{"name": "r", "algo": "rppo", "discrete_approaches": 8, "no_repeat": True}]}, r"got algo 'rppo'"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "m", "algo": "mppo"}]},
     r"agent\[0\].discrete_approaches: mppo masks fixed approaches: it needs discrete_approaches >= 1, got 0"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"],
      "agent": [{"name": "p", "algo": "ppo", "discrete_approaches": 8, "no_repeat": "yes"}]},
     "no_repeat: expected true or false, got 'yes'"),
    ({"name": "x", "analysis": [{"flags": {"no_such_flag": 3}}]},
     r"unknown flag\(s\) \['--no-such-flag'\] for haptic-recog analysis"),
    ({"name": "x", "analysis": [{"flags": {"trials": 0}}]}, r"analysis\[0\].flags: trials must be an int >= 1, got 0"),
    ({"name": "x", "analysis": [{"flags": {"experiments": "2", "force_closure": 0.5}}]},
     "force_closure needs every finger count >= 3"),
    # refused at load: each failed on its worker after its retries, crashed the parse, or gave no job without a word
    ({"name": "x", "dataset": [{"objects": ["default", "no_such_set"]}]},
     r"dataset\[0\]\.objects: unknown object set 'no_such_set'"),
    ({"name": "x", "dataset": [{"fingers": []}]}, r"dataset\[0\]\.fingers: expected a value or a non-empty list"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "random"}], "evaluate": {"env_seeds": []}},
     r"evaluate\.env_seeds: expected at least one env seed, got \[\]"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "random", "seeds": []}]},
     r"agent\[0\]\.seeds: expected at least one seed \(its own seeds or the spec's\), got \[\]"),
    ({"name": "x", "seeds": [], "env_ids": ["HapticRecog-v0"], "agent": [{"name": "random"}]},
     r"agent\[0\]\.seeds: expected at least one seed"),
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "r", "spec": 3}]},
     r"agent\[0\]\.spec: expected an agent spec string .*, got 3"),
    ({"name": "x", "env": [{"id": "HapticRecog-v0", "kwargs": [1, 2]}], "agent": [{"name": "random"}]},
     r"env\[0\]\.kwargs: expected a table of HapticRecogConfig fields, got \[1, 2\]"),
    ({"name": "x", "command": [{"name": "c", "run": "true", "env": "FOO=1"}]},
     r"command\[0\]\.env: expected a table of environment variables \(strings or numbers\), got 'FOO=1'"),
    ({"name": "x", "command": [{"name": "c", "run": "true", "env": {"FOO": [1]}}]}, r"command\[0\]\.env"),
    ({"name": "x", "command": [{"name": "c", "run": []}]}, r"command\[0\]\.run: expected a command, got \[\]"),
    ({"name": "x", "command": [{"name": "c", "run": "  "}]}, r"command\[0\]\.run: expected a command, got '  '"),
    ({"name": "x", "command": [{"name": "c", "run": "echo 'open"}]}, r"command\[0\]\.run: No closing quotation"),
    # a TypeError, an IndexError, no job without a word, or a TypeError / FileExistsError once run
    ({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": {"name": "random"}},
     r"\[agent\]: expected \[\[agent\]\] tables \(an array of tables, one per agent\), got a single \[agent\]"),
    ({"name": "x", "dataset": {"objects": "kit8"}}, r"\[dataset\]: expected \[\[dataset\]\] tables"),
    ({"name": "x", "analysis": [{"flags": {"help": True}}]}, r"analysis\[0\]: flags must be a table .* --help"),
    ({"name": "x", "analysis": [{"objects": []}]}, r"analysis\[0\]\.objects: expected a value or a non-empty list"),
    ({"name": "x", "analysis": [{"objects": "no_such_set"}]}, r"analysis\[0\]\.objects: unknown object set"),
    ({"name": "x", "out": 3, "command": [{"name": "c", "run": "true"}]},
     r"out: expected the sweep folder's path \(a string\), got 3"),
    ({"name": "x", "max_retries": 10**19, "command": [{"name": "c", "run": "true"}]},
     r"max_retries: expected an integer in \[0, 1000\]"),
])
def test_bad_specs_are_one_line_errors(doc, match):
    with pytest.raises(SpecError, match=match):
        parse_spec(doc)


def test_jobs_that_can_only_fail_on_a_worker_are_refused_at_load(tmp_path):
    """A baseline's missing model file and a mesh folder with an unreadable mesh were taken at load and failed on
    their workers (the analysis and dataset commands refuse that folder at once)."""
    bad = tmp_path / "objs_bad"
    bad.mkdir()
    (bad / "x.stl").write_text("solid x\nendsolid x\n")
    with pytest.raises(SpecError, match=r"agent\[0\]\.spec: no model file 'nonexistent_model.zip'"):
        parse_spec({"name": "x", "env_ids": ["HapticRecog-v0"],
                    "agent": [{"name": "m", "spec": "nonexistent_model.zip"}]})
    for kind in ("dataset", "analysis"):
        with pytest.raises(SpecError, match=rf"{kind}\[0\]\.objects: .*x.stl"):
            parse_spec({"name": "x", kind: [{"objects": str(bad)}]})
    # a dry run or a report of finished jobs needs neither file (a sweep's model or folder moved since)
    spec = parse_spec({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "m", "spec": "gone.zip"}],
                       "dataset": [{"objects": str(bad)}]}, check_files=False)
    assert len(spec.jobs) == 2


def test_labels_stay_in_their_folders_and_a_file_is_no_sweep_folder(tmp_path):
    """An env named ``..`` wrote its report into the sweep folder and its runs beside the others' (``runs/random``);
    a spec ``out`` that is a file was taken (a FileExistsError once run); a trained agent with ``n_envs`` in one
    process (``vec = "native"`` / ``"dummy"``) asked Ray for ``n_envs`` CPUs, which a 2-core Ray never grants."""
    doc = {"name": "x", "env": [{"name": "..", "id": "HapticRecog-v0"}, {"name": ".", "id": "HapticRecogKIT-v0"}],
           "agent": [{"name": "random"}]}
    spec = parse_spec(doc)
    assert sorted(spec.envs) == ["_", "__"] and all("/./" not in j.id and "/../" not in j.id for j in spec.jobs)
    (tmp_path / "afile").write_text("")
    with pytest.raises(SpecError, match="out: .*afile is a file; give a folder"):
        parse_spec({"name": "x", "out": str(tmp_path / "afile"), "command": [{"name": "c", "run": "true"}]})
    agents = [{"name": f"p{v}", "algo": "ppo", "n_envs": 4, "vec": v} for v in ("native", "dummy", "subproc")]
    spec = parse_spec({"name": "x", "env_ids": ["HapticRecog-v0"], "agent": agents})
    assert {j.label.split("/")[1]: j.cpus for j in spec.jobs if j.kind == "train"} == \
        {"pnative": 1.0, "pdummy": 1.0, "psubproc": 4.0}


def test_a_trained_agent_named_with_an_equals_sign_evaluates_its_own_model(tmp_path, monkeypatch):
    """``make_agent`` splits ``NAME=model.zip`` at the first ``=``: an agent named ``ppo=v2`` had its evaluate job
    load ``v2=<folder>/ppo_final.zip`` after its training (a FileNotFoundError on every retry)."""
    from haptic_env.sweep import jobs

    spec = parse_spec({"name": "e", "seeds": [0], "env_ids": ["HapticRecog-v0"],
                       "agent": [{"name": "ppo=v2", "algo": "ppo", "total_timesteps": 64}]})
    ev = next(j for j in spec.jobs if j.kind == "evaluate")
    (tmp_path / "ppo_final.zip").write_bytes(b"a model")
    loaded = []

    def make_agent(spec, **kw):
        loaded.append(spec)
        raise RuntimeError("stop here")

    monkeypatch.setattr("agents.evaluate.make_agent", make_agent)
    with pytest.raises(RuntimeError, match="stop here"):
        jobs._evaluate(ev.params, tmp_path / "run", 1, {"dep_dirs": [str(tmp_path)]})
    assert loaded == [f"model={tmp_path / 'ppo_final.zip'}"]


def test_a_job_that_asks_for_more_cpus_than_the_local_ray_has_is_refused(tmp_path):
    """Ray holds back a task whose CPUs no node has, for ever and without a word (its log does not reach the driver):
    the sweep waited until killed. It is refused before any job or folder."""
    pytest.importorskip("ray", reason="the sweep runs on Ray: pip install 'haptic-recog[sweep]'")
    from haptic_env.sweep.runner import InfeasibleJob, run_sweep

    spec = parse_spec({"name": "inf", "command": [{"name": "c", "run": [sys.executable, "-c", "pass"], "cpus": 3}]})
    with pytest.raises(InfeasibleJob, match=r"job command/c-\w+ asks for cpus 3, more than the local Ray's 2 CPUs"):
        run_sweep(spec, tmp_path / "out", num_cpus=2, progress=False)
    assert not (tmp_path / "out").exists()


def test_cli_dry_run_and_bad_spec(tmp_path, capsys):
    from haptic_env.cli import main

    # a binary file as the spec, a spec out under a file, a retry count Ray cannot take: tracebacks once run
    binary = tmp_path / "spec.npz"
    binary.write_bytes(b"\x93NUMPY\xff\xfe")
    (tmp_path / "afile").write_text("x")
    under = tmp_path / "under.toml"
    under.write_text(f'name = "u"\nout = "{tmp_path / "afile" / "sweep"}"\n[[command]]\nname = "c"\nrun = "true"\n')
    for argv, why in (([str(binary), "--dry-run"], "not a TOML text file (not UTF-8)"),
                      ([str(under), "--dry-run"], "spec out: "),
                      ([str(SMOKE), "--max-retries", str(10**19)], "--max-retries: must be in [0, 1000]")):
        with pytest.raises(SystemExit) as exc:
            main(["sweep", *argv])
        assert exc.value.code == 2 and why in capsys.readouterr().err, why

    assert main(["sweep", str(SMOKE), "--dry-run", "--out", str(tmp_path)]) == 0
    assert "todo  evaluate/default/greedy/seed0-" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\nseeds = 'zero'\n")
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(bad)])
    assert exc.value.code == 2
    assert "seeds" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:  # --prior-report must be a report folder, checked before anything runs
        main(["sweep", str(SMOKE), "--report-only", "--out", str(tmp_path / "new"), "--prior-report", str(tmp_path)])
    assert exc.value.code == 2 and "is not a sweep report folder" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    # a report of a folder without finished jobs (a mistyped --out) was an empty report in a new folder, exit 0
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(SMOKE), "--report-only", "--out", str(tmp_path / "typo")])
    assert exc.value.code == 2 and "holds no finished job of smoke" in capsys.readouterr().err
    assert not (tmp_path / "typo").exists()
    for argv, said in ((["sweep", str(SMOKE), "--dry-run", "--report-only"], "give one of them"),
                       (["sweep", str(SMOKE), "--address", "auto", "--num-cpus", "2"],
                        "--num-cpus sets the CPUs of a local Ray; the cluster that --address 'auto' joins has its own"),
                       (["sweep", str(tmp_path)], "(it is a folder; give the spec's .toml file)")):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2 and said in capsys.readouterr().err


def test_match_selects_jobs_and_what_they_need(tmp_path, capsys):
    from haptic_env.cli import main
    from haptic_env.sweep.runner import _plan

    spec = parse_spec({"name": "m", "seeds": [0, 1], "env_ids": ["HapticRecog-v0"],
                       "agent": [{"name": "random"}, {"name": "ppo", "algo": "ppo", "total_timesteps": 64}]})
    todo, done = _plan(spec, tmp_path, None, "evaluate/.*/ppo/seed1")
    assert [j.id.rsplit("-", 1)[0] for j in todo] == ["train/HapticRecog-v0/ppo/seed1",
                                                      "evaluate/HapticRecog-v0/ppo/seed1"]
    assert done == []
    assert len(_plan(spec, tmp_path, None, None)[0]) == len(spec.jobs) == 6

    assert main(["sweep", str(SMOKE), "--dry-run", "--out", str(tmp_path), "--match", "greedy"]) == 0
    listed = capsys.readouterr().out
    assert "evaluate/default/greedy/seed0-" in listed and "/random/" not in listed
    assert "1 of the spec's 2 jobs" in listed
    for bad, why in (("(", "not a regular expression"), ("nothing-like-this", "matches none")):
        with pytest.raises(SystemExit) as exc:
            main(["sweep", str(SMOKE), "--dry-run", "--match", bad])
        assert exc.value.code == 2
        assert why in capsys.readouterr().err
    # --only a kind the spec has no job of ran nothing, wrote an empty report and exited 0; an --out that is a file
    # was a traceback
    (tmp_path / "file").write_text("x")
    for argv, why in ((["--only", "train", "--out", str(tmp_path / "o")], "--only train selects none of the spec's"),
                      (["--out", str(tmp_path / "file")], "is a file; give a folder")):
        with pytest.raises(SystemExit) as exc:
            main(["sweep", str(SMOKE), *argv])
        assert exc.value.code == 2 and why in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------------------------ Ray
@pytest.fixture(scope="module")
def local_ray(haptic_cache, env_config, small_recognizer_kwargs):
    """A local Ray with 2 CPUs; the smoke spec's recogniser is the session's small one, already in the cache."""
    ray = pytest.importorskip("ray", reason="the sweep runs on Ray: pip install 'haptic-recog[sweep]'")
    assert _smoke_doc()["env_kwargs"]["recognizer_kwargs"] == small_recognizer_kwargs
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"HAPTIC_CACHE": str(haptic_cache)}})
    yield ray
    ray.shutdown()


def test_smoke_sweep_report_rerun_and_retries(local_ray, tmp_path, capsys, monkeypatch):
    """Random vs greedy + a job that fails once + one that always fails, twice over (the second run skips)."""
    import functools

    import agents.evaluate

    # rliable's bootstrap takes ~10 s at its 2000 resamples even on 4 episodes: 100 here
    monkeypatch.setattr(agents.evaluate, "rl_aggregates", functools.partial(agents.evaluate.rl_aggregates, reps=100))
    from haptic_env.cli import main
    from haptic_env.sweep.jobs import attempts
    from haptic_env.sweep.report import write_sweep_report
    from haptic_env.sweep.runner import run_sweep, write_status

    doc = _smoke_doc()
    doc["command"] = [
        {"name": "flaky", "run": _cmd("import os, sys; sys.exit(3 if os.environ['SWEEP_ATTEMPT'] == '1' else 0)")},
        {"name": "broken", "run": _cmd("import sys; print('boom'); sys.exit(7)")},
    ]
    spec = parse_spec(doc, source="smoke + commands")
    out = tmp_path / "sweep"
    res = run_sweep(spec, out, max_retries=1, progress=False)
    ids = {j.label: j.id for j in spec.jobs}
    dirs = {j.label: j.run_dir(out) for j in spec.jobs}
    assert set(res.failed) == {ids["broken"]} and "status 7" in res.failed[ids["broken"]]
    assert set(res.done) == {ids[k] for k in ("default/random/seed0", "default/greedy/seed0", "flaky")}
    assert len(attempts(dirs["flaky"])) == 2 and len(attempts(dirs["broken"])) == 2  # 1 + max_retries
    assert "error" in attempts(dirs["flaky"])[0] and "error" not in attempts(dirs["flaky"])[1]
    write_status(res, spec)
    report = write_sweep_report(spec, res)
    text = report.read_text()
    for f in ("leaderboard.png", "report/default/performance_profile.png", "report/default/results.md",
              "report/default/success_vs_grasps.png", "status.json"):
        assert (out / f).is_file() and (out / f).stat().st_size > 0, f
    assert "IQM grasps at the stop" in text and "P(fewer grasps than random)" in text
    assert "### Failed jobs" in text and ids["broken"] in text and "### Retried jobs" in text
    agg = json.loads((out / "report/default/results.json").read_text())["rliable"]["agents"]
    assert set(agg) == {"random", "greedy"} and "p_fewer_grasps" in agg["greedy"]
    episodes = (dirs["default/greedy/seed0"] / "episodes.csv").read_text().splitlines()
    assert len(episodes) == 1 + 2  # header + 2 episodes x 1 env seed
    status = {r["id"]: r for r in json.loads((out / "status.json").read_text())["jobs"]}
    assert status[ids["broken"]]["state"] == "failed" and status[ids["broken"]]["attempts"] == 2
    # a spec with a second agent seed: its seed-0 jobs are the ones done, and the report names the seed not run
    from haptic_env.sweep.runner import SweepResult

    two = write_sweep_report(parse_spec({**doc, "seeds": [0, 1]}), SweepResult(out=out)).read_text()
    assert "agent seeds: random [0], greedy [0]. Not run (or not finished): random [1], greedy [1]." in two
    # an earlier report stands in for run folders that are gone (--prior-report): the same episodes, the same
    # aggregates, and the report says where they came from; a report of another spec is refused before writing
    out2 = tmp_path / "sweep2"
    merged = write_sweep_report(parse_spec({**doc, "seeds": [0, 1]}), SweepResult(out=out2), prior=out).read_text()
    assert f"From the earlier report `{out}` (run folders not here): random [0], greedy [0]." in merged
    assert "Not run (or not finished): random [1], greedy [1]." in merged
    assert (out2 / "report/default/episodes.csv").read_text() == (out / "report/default/episodes.csv").read_text()
    assert json.loads((out2 / "report/default/agent_seeds.json").read_text()) == {"random": [0, 1], "greedy": [0, 1]}
    rl = [json.loads((o / "report/default/results.json").read_text())["rliable"]["agents"] for o in (out, out2)]
    assert rl[0] == rl[1]
    only_random = {**doc, "agent": [a for a in doc["agent"] if a["name"] == "random"]}
    with pytest.raises(ValueError, match="agent 'greedy' is not evaluated on env 'default'"):
        write_sweep_report(parse_spec(only_random), SweepResult(out=tmp_path / "sweep3"), prior=out)
    assert not (tmp_path / "sweep3").exists()

    # the same sweep again through the CLI: the finished jobs are skipped, the failed one is tried again
    spec_file = tmp_path / "spec.toml"
    spec_file.write_text(_toml(doc))
    capsys.readouterr()
    rc = main(["sweep", str(spec_file), "--out", str(out), "--max-retries", "0", "--quiet"])
    assert rc == 1
    assert "3 skipped" in capsys.readouterr().out
    assert len(attempts(dirs["default/greedy/seed0"])) == 1 and len(attempts(dirs["flaky"])) == 2
    assert len(attempts(dirs["broken"])) == 3


def test_killed_worker_is_retried(local_ray, tmp_path):
    """SIGKILL the Ray worker running a job: Ray retries it (max_retries) and the sweep completes."""
    from haptic_env.sweep.jobs import attempts, is_done
    from haptic_env.sweep.runner import run_sweep

    code = "import os, time; time.sleep(60 if os.environ['SWEEP_ATTEMPT'] == '1' else 0)"
    spec = parse_spec({"name": "kill", "command": [{"name": "sleeper", "run": _cmd(code)}]})
    out = tmp_path / "sweep"
    run_dir = spec.jobs[0].run_dir(out)
    killed = []

    def killer():
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            a = attempts(run_dir)
            if a and (run_dir / "command.log").is_file():
                time.sleep(0.5)
                os.kill(a[0]["pid"], signal.SIGKILL)
                killed.append(a[0]["pid"])
                return
            time.sleep(0.1)

    th = threading.Thread(target=killer)
    th.start()
    res = run_sweep(spec, out, max_retries=2, progress=False)
    th.join()
    assert killed and res.ok and is_done(run_dir)
    a = attempts(run_dir)
    assert len(a) == 2 and a[0]["pid"] != a[1]["pid"] and "outcome" not in a[0]  # the killed attempt never ended
    assert a[1]["time"] - a[0]["time"] < 60  # the retry began before the first attempt's `sleep 60` could end


def _toml(doc: dict) -> str:
    """A minimal TOML writer for the test specs (tables of scalars, lists, inline tables)."""
    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"

    lines, arrays = [], []
    for k, v in doc.items():
        if isinstance(v, list) and v and isinstance(v[0], dict):
            arrays.append((k, v))
        elif isinstance(v, dict) and k != "env_kwargs":
            arrays.append((k, v))
        else:
            lines.append(f"{k} = {val(v)}")
    for k, v in arrays:
        for t in (v if isinstance(v, list) else [v]):
            lines += [f"[[{k}]]" if isinstance(v, list) else f"[{k}]", *(f"{a} = {val(b)}" for a, b in t.items())]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------ slow
def _killpg(pgid: int, sig: int) -> None:
    try:
        os.killpg(pgid, sig)
    except ProcessLookupError:
        pass


@pytest.mark.slow
def test_killed_training_resumes_from_checkpoint(tmp_path, haptic_cache):
    """A 2,048-step PPO job whose train.py is SIGKILLed after its first checkpoint: the retry resumes from it
    (--resume), the evaluation of the final model follows, and the report has PPO against random."""
    pytest.importorskip("ray", reason="the sweep runs on Ray: pip install 'haptic-recog[sweep]'")
    from haptic_env.sweep.jobs import attempts, read_done

    doc = _smoke_doc()
    doc["agent"] = [{"name": "random"}, {"name": "ppo", "algo": "ppo", "total_timesteps": 2048,
                                         "checkpoint_freq": 256,
                                         "hyperparams": {"n_steps": 128, "batch_size": 64, "n_epochs": 2}}]
    spec_file = tmp_path / "spec.toml"
    spec_file.write_text(_toml(doc))
    spec = parse_spec(doc)
    out = tmp_path / "sweep"
    train = next(j for j in spec.jobs if j.kind == "train").run_dir(out)
    proc = subprocess.Popen([sys.executable, "-m", "haptic_env.cli", "sweep", str(spec_file), "--out", str(out),
                             "--num-cpus", "2", "--quiet"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    t0 = time.monotonic()
    while not list(train.glob("checkpoints/ppo_*_steps.zip")):
        assert proc.poll() is None and time.monotonic() - t0 < 240, "no checkpoint"
        time.sleep(0.2)
    pid = int((train / "train.pid").read_text())
    os.kill(pid, signal.SIGKILL)
    stdout, _ = proc.communicate(timeout=400)
    assert proc.returncode == 0, stdout[-3000:]
    a = attempts(train)
    assert len(a) == 2 and "status -9" in a[0]["error"]
    assert read_done(train)["resumed_from"] is not None
    assert (train / "args.part2.json").is_file()  # train.py's own record of the resumed segment
    text = (out / "report.md").read_text()
    assert "| ppo |" in text and "| random |" in text


@pytest.mark.slow
def test_two_node_cluster(tmp_path, haptic_cache):
    """``ray start --head`` on 127.0.0.1 plus a second ``ray start --address``: the smoke sweep (+ two 3 s jobs
    that need a CPU each at the same time, so they run on both nodes) completes through ``--address``."""
    pytest.importorskip("ray", reason="the sweep runs on Ray: pip install 'haptic-recog[sweep]'")
    from haptic_env.sweep.jobs import attempts

    import socket

    with socket.socket() as s:  # a free port below Ray's worker port range (10002-19999)
        for port in range(6400, 9000):
            try:
                s.bind(("127.0.0.1", port))
                break
            except OSError:
                continue
    ray_exe = str(Path(sys.executable).with_name("ray"))
    env = {**os.environ, "RAY_AUTH_MODE": "token", "HAPTIC_CACHE": str(haptic_cache)}
    import shutil
    import tempfile

    temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))  # Ray's socket paths must stay under 107 bytes
    nodes: list[subprocess.Popen] = []
    logs = []  # the nodes' log files, closed with the nodes

    def start(args: list[str], log: Path) -> None:
        logs.append(open(log, "w"))
        p = subprocess.Popen([ray_exe, "start", *args, "--num-cpus", "1", "--object-store-memory", "100000000",
                              "--block"], stdout=logs[-1], stderr=subprocess.STDOUT, env=env,
                             start_new_session=True)
        nodes.append(p)
        t0 = time.monotonic()
        while "Ray runtime started" not in log.read_text(errors="replace"):
            assert p.poll() is None, log.read_text()[-2000:]
            assert time.monotonic() - t0 < 120, "ray start timed out"
            time.sleep(0.5)

    doc = _smoke_doc()
    code = "import time; time.sleep(3)"
    doc["command"] = [{"name": f"sleep{i}", "run": _cmd(code)} for i in range(2)]
    spec_file = tmp_path / "spec.toml"
    spec_file.write_text(_toml(doc))
    out = tmp_path / "sweep"
    try:
        start(["--head", "--port", str(port), "--include-dashboard=false", "--temp-dir", str(temp)],
              tmp_path / "head.log")
        start(["--address", f"127.0.0.1:{port}"], tmp_path / "worker.log")
        r = subprocess.run([sys.executable, "-m", "haptic_env.cli", "sweep", str(spec_file), "--out", str(out),
                            "--address", f"127.0.0.1:{port}", "--quiet"], cwd=ROOT, env=env, capture_output=True,
                           text=True, timeout=400)
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    finally:  # the nodes' process groups (ray start --block, its GCS, raylet and workers), by their ids
        for p in nodes:
            _killpg(p.pid, signal.SIGTERM)
        for p in nodes:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
            _killpg(p.pid, signal.SIGKILL)
            p.wait()
        for fh in logs:
            fh.close()
        shutil.rmtree(temp, ignore_errors=True)
    spec = parse_spec(doc)
    node_ids = {attempts(j.run_dir(out))[0]["node"] for j in spec.jobs if j.kind == "command"}
    assert len(node_ids) == 2, node_ids
    assert (out / "report.md").is_file() and (out / "leaderboard.png").is_file()


def test_a_retried_train_job_reuses_a_finished_model_and_resumes_otherwise(tmp_path, monkeypatch):
    """A train job whose earlier attempt saved the final model (but died before the job's ``done.json``) returns it
    without training again; with only checkpoints, the retry runs train.py with ``--resume``."""
    from haptic_env.sweep import jobs

    p = {"algo": "ppo", "env_id": "HapticRecog-v0", "total_timesteps": 256, "n_envs": 1, "vec": "dummy", "seed": 0,
         "env_seed": 10_000, "checkpoint_freq": 128, "max_minutes": 0, "env_kwargs": {}, "hyperparams": {}}
    runs = _fake_train_py(monkeypatch, tmp_path)
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "ppo_128_steps.zip").write_bytes(b"checkpoint")
    out = jobs._train(p, tmp_path, 2, {})
    assert len(runs) == 1 and runs[0][-2:] == ["--resume", str(tmp_path)]
    assert out["resumed_from"].endswith("ppo_128_steps.zip")
    assert out["steps"] == 256
    out = jobs._train(p, tmp_path, 3, {})
    assert len(runs) == 1 and out == {"model": str(tmp_path / "ppo_final.zip"), "resumed_from": None,
                                      "reused_final_model": True, "steps": 256}
    # a time limit that stopped it early: done, with its steps (the report lists it)
    (tmp_path / "ppo_final.zip").unlink()
    assert jobs._train({**p, "max_minutes": 0.5}, tmp_path, 4, {})["steps"] == 128


def test_the_report_lists_the_trainings_that_their_time_limit_stopped(tmp_path, monkeypatch):
    """A train job that ``max_minutes`` stopped before ``total_timesteps`` is done (a later run does not go on with
    it) and was ranked as if trained to the end, unsaid: the report lists it with its steps, from ``done.json`` or,
    for a job done before the steps were recorded, from its model."""
    from haptic_env.sweep import jobs
    from haptic_env.sweep.report import write_sweep_report
    from haptic_env.sweep.runner import SweepResult

    doc = {"name": "t", "seeds": [0, 1], "env_ids": ["HapticRecog-v0"],
           "agent": [{"name": "ppo", "algo": "ppo", "total_timesteps": 256, "max_minutes": 1}]}
    spec = parse_spec(doc)
    out = tmp_path / "sweep"
    trains = [j for j in spec.jobs if j.kind == "train"]
    for j in trains:
        j.run_dir(out).mkdir(parents=True)
    runs = _fake_train_py(monkeypatch, trains[0].run_dir(out))
    (trains[0].run_dir(out) / "done.json").write_text(json.dumps(jobs._train(trains[0].params, trains[0].run_dir(
        out), 1, {})))
    assert len(runs) == 1
    from stable_baselines3.common.save_util import save_to_zip_file

    save_to_zip_file(trains[1].run_dir(out) / "ppo_final.zip", data={"num_timesteps": 256})  # trained to the end
    (trains[1].run_dir(out) / "done.json").write_text(json.dumps({"model": str(trains[1].run_dir(out) /
                                                                               "ppo_final.zip")}))
    text = write_sweep_report(spec, SweepResult(out=out)).read_text()
    assert "### Trainings stopped by their time limit" in text
    assert f"- `{trains[0].id}`: 128 of 256 steps (its time limit, max_minutes = 1)" in text
    assert trains[1].id not in text.split("### Trainings stopped by their time limit")[1].split("###")[0]


def test_a_dataset_job_builds_its_hand_grasp_pool_in_as_many_processes_as_its_cpus(tmp_path, monkeypatch):
    """A dataset job asked Ray for ``cpus`` CPUs but built a hand grasp pool on every core of the node (the pool's
    default): it builds it in ``max(1, int(cpus))`` processes, and the worker count is in no key."""
    import haptic_env.hand_grasps
    from haptic_env.sweep import jobs

    class Built(Exception):
        pass

    asked = []

    def pool(*args, workers=None, **kwargs):
        asked.append(workers)
        raise Built  # the job ends here: no grasps, no hand model needed

    monkeypatch.setattr(haptic_env.hand_grasps, "hand_grasp_pool", pool)
    monkeypatch.setattr(haptic_env.hand_grasps, "hand_physics_key", lambda hand, n: f"{hand}-{n}")  # a cache key
    ids = set()
    for cpus in (1, 2.5, 0):
        doc = {"name": "x", "dataset": [{"objects": "default", "fingers": 3, "normals": False, "source": "hand",
                                         "hand": "allegro", "grasps_per_object": 10, "cpus": cpus}]}
        (job,) = parse_spec(doc).jobs
        ids.add(job.id)
        with pytest.raises(Built):
            jobs.execute(job.to_dict(), str(tmp_path / str(cpus)))
    assert asked == [1, 2, 1] and len(ids) == 1


def test_a_false_toggle_is_spelled_out_and_an_unknown_flag_is_refused_even_when_false():
    """``stop_scale = false`` runs ``--no-stop-scale`` (left out, the analysis kept its default, on); a flag that
    ``haptic-recog analysis`` does not have is refused at load, ``false`` or not."""
    from haptic_env.sweep.spec import SpecError, _check_analysis_flags, analysis_argv

    assert "--no-stop-scale" in analysis_argv("kit8", {"stop_scale": False}, "/o")
    _check_analysis_flags("kit8", {"stop_scale": False, "raw": False, "force_closure": False}, "analysis[0]")
    with pytest.raises(SpecError, match=r"analysis\[0\]\.flags: unknown flag\(s\) \['--no-such-flag'\]"):
        _check_analysis_flags("kit8", {"no_such_flag": False}, "analysis[0]")


def test_a_seed_given_twice_is_refused():
    """An env seed twice would evaluate the same episodes twice (counted as twice the evidence); an agent's seed twice
    would train the same model twice."""
    from haptic_env.sweep.spec import SpecError, parse_spec

    base = {"name": "s", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "random", "spec": "random"}]}
    with pytest.raises(SpecError, match=r"evaluate.env_seeds: each seed once, got \[1000, 1000\]"):
        parse_spec({**base, "evaluate": {"env_seeds": [1000, 1000]}})
    with pytest.raises(SpecError, match=r"agent\[0\].seeds: each seed once, got \[0, 0\]"):
        parse_spec({**base, "agent": [{"name": "random", "spec": "random", "seeds": [0, 0]}]})


def test_analysis_argv_spells_the_flags_as_the_job_runs_them():
    """An analysis job's flags as ``haptic-recog`` arguments: true -> the bare flag, false -> left out, a list ->
    comma-joined, ``--quiet`` added unless given (the same list the spec checks at load)."""
    from haptic_env.sweep.spec import analysis_argv

    flags = {"experiments": "2", "fingers": [3, 4], "no_normals": True, "raw": False}
    assert analysis_argv("kit8", flags, "/o") == ["analysis", "--out", "/o", "--objects", "kit8", "--experiments", "2",
                                                  "--fingers", "3,4", "--no-normals", "--quiet"]
    assert analysis_argv("kit8", {"quiet": True}, "/o")[-1] == "--quiet"
    assert analysis_argv("kit8", {"quiet": True}, "/o").count("--quiet") == 1


def test_a_train_jobs_key_holds_how_its_envs_are_seeded():
    """Train jobs carry their envs' seeding (since 2026-12-06 the envs keep env_seed; SB3 had re-seeded them seed +
    rank), so that a sweep folder's jobs trained the earlier way train again instead of being reused."""
    from haptic_env.sweep.spec import parse_spec

    spec = parse_spec({"name": "s", "env_ids": ["HapticRecog-v0"], "agent": [{"name": "ppo", "algo": "ppo"}]})
    train = next(j for j in spec.jobs if j.kind == "train")
    assert train.params["seeding"] == "env_seed kept" and train.params["env_seed"] == 10_000


def test_status_of_a_report_only_run_into_a_new_folder_is_written(tmp_path):
    """``--report-only --out NEW --prior-report OLD``: NEW does not exist yet; its status.json is written (it crashed
    with FileNotFoundError before the report)."""
    from haptic_env.sweep.runner import SweepResult, write_status

    spec = parse_spec(_smoke_doc(), source="smoke")
    path = write_status(SweepResult(out=tmp_path / "new" / "sweep"), spec)
    assert path.is_file() and json.loads(path.read_text())["sweep"] == spec.name


def test_a_matched_run_counts_every_finished_job_as_done(tmp_path):
    """A run of ``--match`` counts the jobs finished outside its selection as done (before), as status.json does: the
    report's table called them "not run"."""
    from haptic_env.sweep.report import _jobs_table
    from haptic_env.sweep.runner import run_jobs_inline, write_status

    spec = parse_spec({"name": "abc", "command": [{"name": n, "run": _cmd("pass")} for n in "abc"]})
    out = tmp_path / "sweep"
    assert run_jobs_inline(spec, out, match="command/[ab]-").ok
    res = run_jobs_inline(spec, out, match="command/c-")
    assert res.ok and sorted(res.skipped) == sorted(j.id for j in spec.jobs[:2]) and set(res.done) == {
        j.id for j in spec.jobs}
    row = _jobs_table(spec, res).splitlines()[-1]
    assert row.startswith("| command | 3 | 1 | 2 | 0 | 0 |"), row
    states = [r["state"] for r in json.loads(write_status(res, spec).read_text())["jobs"]]
    assert states == ["skipped", "skipped", "done"]


def test_a_prior_report_of_other_episodes_or_env_seeds_is_refused(tmp_path, usage_error):
    """``--prior-report`` from a spec with other ``episodes`` or ``env_seeds``: its episodes were taken for other
    runs (only an index beyond the agent seeds was refused); now each agent seed must have ``episodes`` episodes on
    each of the spec's env seeds."""
    import csv

    from haptic_env.cli import main
    from haptic_env.sweep.report import load_prior_records

    doc = {**_smoke_doc(), "seeds": [0, 1], "agent": [{"name": "random"}], "evaluate": {"episodes": 2,
                                                                                       "env_seeds": [1000, 1001]}}
    spec = parse_spec(doc)

    def prior(rows) -> Path:
        folder = tmp_path / f"prior{len(list(tmp_path.iterdir()))}"
        (folder / "report" / "default").mkdir(parents=True)
        with open(folder / "report" / "default" / "episodes.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=["agent", "seed", "episode", "object", "grasps", "decided", "correct",
                                               "certainty", "ret", "predicted"])
            w.writeheader()
            for env_seed, episode in rows:
                w.writerow({"agent": "random", "seed": env_seed, "episode": episode, "object": "ball", "grasps": 3,
                            "decided": True, "correct": True, "certainty": 0.9, "ret": 0.5, "predicted": "ball"})
        return folder

    same = [(s, i * 2 + e) for i in (0, 1) for s in (1000, 1001) for e in (0, 1)]
    got = load_prior_records(spec, prior(same), "default")
    assert sorted(got) == [("random", 0), ("random", 1)] and all(len(r) == 4 for r in got.values())
    # the offsets count in the earlier spec's seed list (agent_seeds.json): a seed this spec does not evaluate is
    # refused (its episodes were filed under this spec's seed at that index), the others offset as this spec counts
    other = prior(same)
    (other / "report" / "default" / "agent_seeds.json").write_text(json.dumps({"random": [0, 2]}))
    with pytest.raises(ValueError, match=r"agent 'random' seed 2 is not among this spec's agent seeds \[0, 1\]"):
        load_prior_records(spec, other, "default")
    (other / "report" / "default" / "agent_seeds.json").write_text(json.dumps({"random": [1, 0]}))
    swapped = load_prior_records(spec, other, "default")
    assert sorted(swapped) == sorted(got) and [r.episode for r in swapped["random", 1]] == [2, 3, 2, 3]
    assert [r.episode for r in swapped["random", 0]] == [0, 1, 0, 1]
    wider = parse_spec({**doc, "seeds": [0, 1, 2]})  # more seeds than the earlier report's: its own stay theirs
    (other / "report" / "default" / "agent_seeds.json").write_text(json.dumps({"random": [0, 2]}))
    assert sorted(load_prior_records(wider, other, "default")) == [("random", 0), ("random", 2)]
    assert [r.episode for r in load_prior_records(wider, other, "default")["random", 2]] == [4, 5, 4, 5]
    for rows, why in (([(s, i * 2 + e) for i in (0, 1) for s in (1000, 1002) for e in (0, 1)],  # another env seed
                       r"agent 'random' seed 0 has episodes per env seed \{1000: 2, 1002: 2\}, this spec 2 on each "
                       r"of env seeds \[1000, 1001\]"),
                      ([(s, i * 2 + e) for i in (0, 1) for s in (1000,) for e in (0, 1)], "seed 0 has episodes"),
                      ([(s, 0) for s in (1000, 1001)] + [(s, 2 + e) for s in (1000, 1001) for e in (0, 1)],
                       r"seed 0 has episodes per env seed \{1000: 1, 1001: 1\}")):  # 1 episode per seed, of 2
        folder = prior(rows)
        with pytest.raises(ValueError, match=why):
            load_prior_records(spec, folder, "default")
    spec_file = tmp_path / "spec.toml"
    spec_file.write_text(_toml(doc))
    usage_error(main, ["sweep", str(spec_file), "--report-only", "--out", str(tmp_path / "new"), "--prior-report",
                       str(folder)], match="--prior-report: .* seed 0 has episodes per env seed")
    assert not (tmp_path / "new").exists()


def test_a_retried_job_that_did_not_fail_in_this_run_is_not_called_failed(tmp_path):
    """The report's retried jobs: a job with earlier attempts that neither finished nor failed in this run (left out
    by --match, or stopped) was labelled failed."""
    from haptic_env.sweep.report import write_sweep_report
    from haptic_env.sweep.runner import SweepResult

    spec = parse_spec({"name": "r", "command": [{"name": n, "run": _cmd("pass")} for n in "ab"]})
    out = tmp_path / "sweep"
    for j in spec.jobs:
        j.run_dir(out).mkdir(parents=True)
        (j.run_dir(out) / "attempts.jsonl").write_text("\n".join(json.dumps(r) for r in (
            {"event": "start", "attempt": 1}, {"event": "error", "attempt": 1, "error": "boom"},
            {"event": "start", "attempt": 2})) + "\n")
    a, b = spec.jobs
    text = write_sweep_report(spec, SweepResult(out=out, failed={a.id: "boom"})).read_text()
    assert f"- `{a.id}`: 2 attempts, failed;" in text
    assert f"- `{b.id}`: 2 attempts, not finished (not run this time, or stopped);" in text
