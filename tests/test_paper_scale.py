"""benchmarks/paper_scale.py on a tiny grid: cells are written, the report is made, a re-run skips finished cells."""

from __future__ import annotations

import json

import numpy as np
import pytest


@pytest.fixture(scope="module")
def paper_scale(load_benchmark):
    return load_benchmark("paper_scale")


TINY = ["--objects", "default", "--fingers", "3", "--normals", "yes", "--nets", "default", "--max-epochs", "1",
        "--test-grasps", "40", "--threads", "1", "--quiet"]


def test_tiny_grid_and_resume(paper_scale, tmp_path, capsys):
    out = tmp_path / "ps"
    assert paper_scale.main([*TINY, "--out", str(out), "--grasps", "300"]) == 0
    cells = sorted((out / "cells").glob("*.json"))
    assert [p.name.rsplit("-", 1)[0] for p in cells] == ["n3-w-g300-knn", "n3-w-g300-mlp-default"]
    res = json.loads((out / "cells" / cells[1].name).read_text())
    assert 0.0 <= res["accuracy"] <= 1.0 and res["epochs"] == 1 and res["train_rows"] > 0 and res["seconds"] > 0
    assert res["val_rows"] > 0 and abs(res["val_rows"] / (res["train_rows"] + res["val_rows"]) - 0.15) < 0.02
    report = (out / "results.md").read_text()
    assert "--grasps 300" in report and "| 3 | yes | MLP 3x256 |" in report and "86.0" in report  # paper's NN cell
    assert (out / "accuracy_vs_grasps.png").stat().st_size > 0
    assert len(json.loads((out / "results.json").read_text())["cells"]) == 2
    stamps = {p.name: p.stat().st_mtime_ns for p in cells}
    capsys.readouterr()

    # same grid again: nothing runs, no cell file is rewritten
    assert paper_scale.main([*TINY, "--out", str(out), "--grasps", "300"]) == 0
    assert "2 cells, 2 done, 0 to run" in capsys.readouterr().out
    assert {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json")} == stamps

    # a bigger grid runs only the new cells; notes.md is appended to the report
    (out / "notes.md").write_text("## Summary\nhand-written")
    assert paper_scale.main([*TINY, "--out", str(out), "--grasps", "300,400"]) == 0
    assert "4 cells, 2 done, 2 to run" in capsys.readouterr().out
    assert {p.name: p.stat().st_mtime_ns for p in cells} == stamps
    report = (out / "results.md").read_text()
    assert "400/obj" in report and report.rstrip().endswith("hand-written")
    assert report.count("python benchmarks/paper_scale.py") == 3  # every command that ran cells


def test_interrupt_keeps_finished_cells(paper_scale, tmp_path, monkeypatch):
    out = tmp_path / "ps"
    real = paper_scale.run_cell
    calls = []

    def flaky(cell, data, args, checkpoint=None):
        calls.append(cell)
        if len(calls) == 2:
            raise KeyboardInterrupt
        assert checkpoint == paper_scale.fit_state_path(out, cell, paper_scale.settings_hash(args))
        return real(cell, data, args, checkpoint=checkpoint)

    monkeypatch.setattr(paper_scale, "run_cell", flaky)
    assert paper_scale.main([*TINY, "--out", str(out), "--grasps", "300", "--no-knn", "--nets", "default"]
                            + ["--grasps", "300,400"]) == 130
    assert [p.name.rsplit("-", 1)[0] for p in (out / "cells").glob("*.json")] == ["n3-w-g300-mlp-default"]
    assert not list((out / "cells").glob(".*tmp"))
    monkeypatch.setattr(paper_scale, "run_cell", real)
    assert paper_scale.main([*TINY, "--out", str(out), "--no-knn", "--grasps", "300,400"]) == 0
    assert len(list((out / "cells").glob("*.json"))) == 2
    assert not list((out / "cells").glob(".*.fit.pt"))  # each fit's epoch state goes when the fit ends


def test_bad_flags(paper_scale, tmp_path, usage_error):
    for flag, bad in (("--nets", "huge"), ("--fingers", "2"), ("--weight-decay", "-1"), ("--lr-decay", "0"),
                      ("--lr-decay", "1.5"), ("--lr", "0"), ("--max-epochs", "0"), ("--patience", "0"),
                      ("--batch-size", "0"), ("--threads", "0"), ("--test-grasps", "0"), ("--knn-k", "0"),
                      ("--val-fraction", "1"), ("--val-fraction", "-0.1"), ("--force-closure", "0"),
                      ("--grasps", "0"), ("--trials-per-object", "0"), ("--threshold", "1.5"), ("--objects", "nope")):
        usage_error(paper_scale.parse_args, ["--out", str(tmp_path), flag, bad], match=f"error: (argument )?{flag}: ")


def test_weight_decay_reaches_the_mlp_and_its_own_cells(paper_scale, tmp_path, monkeypatch):
    """``--weight-decay`` / ``--decoupled-weight-decay`` train the MLP with them, name the optimiser in the report and
    hash into the cell files (a run with them never resumes a run without); the defaults keep the older hash."""
    from haptic_env.recognizers import mlp

    seen = []
    real_fit = mlp.MLPClassifier.fit
    monkeypatch.setattr(mlp.MLPClassifier, "fit", lambda self, *a, **k: seen.append(self.config) or real_fit(self, *a, **k))
    out = tmp_path / "ps"
    base = [*TINY, "--out", str(out), "--grasps", "300", "--no-knn"]
    assert paper_scale.main(base) == 0
    assert paper_scale.main([*base, "--weight-decay", "0.2", "--decoupled-weight-decay"]) == 0
    assert [(c.weight_decay, c.decoupled_weight_decay) for c in seen] == [(0.0, False), (0.2, True)]
    assert len(list((out / "cells").glob("*.json"))) == 2
    assert "AdamW (weight decay 0.2) lr" in (out / "results.md").read_text()
    plain = paper_scale.parse_args(["--out", str(out)])
    assert not {"weight_decay", "decoupled_weight_decay"} & set(paper_scale.settings(plain))


def test_force_closure_reaches_training_and_test_grasps(paper_scale, tmp_path, monkeypatch):
    """``--force-closure MU`` builds the training and the test grasps with ``DatasetConfig.force_closure = MU``, says
    so in the report and hashes into the cell files; unset, the settings keep the older hash."""
    from haptic_env import dataset

    seen = []
    real = dataset.build_dataset
    monkeypatch.setattr(dataset, "build_dataset", lambda objs, cfg, **k: seen.append(cfg) or real(objs, cfg, **k))
    out = tmp_path / "ps"
    assert paper_scale.main([*TINY, "--out", str(out), "--grasps", "200", "--nets", "", "--test-grasps", "20",
                             "--force-closure", "0.5"]) == 0
    assert [c.force_closure for c in seen] == [0.5, 0.5] and {c.grasps_per_object for c in seen} == {200, 20}
    assert "**Force-closure grasps only**" in (out / "results.md").read_text()
    plain = paper_scale.parse_args(["--out", str(out)])
    assert "force_closure" not in paper_scale.settings(plain)
    assert paper_scale.settings_hash(plain) != paper_scale.settings_hash(
        paper_scale.parse_args(["--out", str(out), "--force-closure", "0.5"]))


def test_sampling_protocol_rejects_bad_values_first(load_benchmark, usage_error):
    """Each bad value is refused by its own message (before the decimation, which needs fast-simplification)."""
    protocol = load_benchmark("sampling_protocol")
    for bad, match in ((["--fingers", "2"], "--fingers must be >= 3, got 2"),
                       (["--grasps", "10"], "--grasps must be >= 50, got 10"),
                       (["--faces", "4"], "--faces must be >= 20, got 4"),
                       (["--test-grasps", "0"], "--test-grasps must be >= 1, got 0"),
                       (["--force-closure", "0"], "--force-closure must be > 0"),
                       (["--curve", "a"], "--curve: a comma list"), (["--curve", "10"], "--curve: grasp counts >= 50"),
                       (["--plot", "x.png"], "--plot draws the --curve")):
        usage_error(protocol.main, bad, match=match)


def test_sampling_protocol_resumes_its_finished_rows(load_benchmark, monkeypatch, tmp_path, capsys):
    """Each finished row is kept under the cache, keyed by the settings and the code: a second run with them prints the
    same table without computing a row; other settings, or other code, compute theirs."""
    pytest.importorskip("fast_simplification", reason="the decimated meshes need the bench extra")
    from haptic_env.objects.loaders import data_dir

    if data_dir() is None:
        pytest.skip("shared mesh data absent (kit/; set HAPTIC_DATA or put it in ../shared/data)")
    monkeypatch.setenv("HAPTIC_CACHE", str(tmp_path / "cache"))
    protocol = load_benchmark("sampling_protocol")
    argv = ["--grasps", "60", "--test-grasps", "10", "--faces", "200"]
    calls = []
    knn = protocol.validated_knn
    monkeypatch.setattr(protocol, "validated_knn", lambda *a: calls.append(1) or knn(*a))
    assert protocol.main(argv) == 0
    first = capsys.readouterr().out
    assert len(calls) == 6 and len(list((tmp_path / "cache" / "sampling_protocol").glob("*.json"))) == 1
    assert protocol.main(argv) == 0
    assert len(calls) == 6 and capsys.readouterr().out == first  # every row from the kept state
    assert protocol.main([*argv[:-1], "300"]) == 0 and len(calls) == 12  # other settings: their own rows
    import haptic_env.cache

    monkeypatch.setattr(haptic_env.cache, "source_fingerprint", lambda *packages: "other code")
    assert protocol.main(argv) == 0 and len(calls) == 18  # other code: the rows again, not the kept ones


def test_sampling_protocol_authors_vector(load_benchmark):
    """The authors' 3-finger vector (benchmarks/sampling_protocol.py): their code's arithmetic, grasp by grasp; rigid
    invariant; it starts at the longest edge, so a cyclic shift of the contacts leaves it unchanged, but it depends
    on their order otherwise (reversed: the two angles swap), and its normal angles follow the input order."""
    sp = load_benchmark("sampling_protocol")
    rng = np.random.default_rng(0)
    X = rng.normal(size=(40, 3, 3))
    N = rng.normal(size=(40, 3, 3))
    N /= np.linalg.norm(N, axis=2, keepdims=True)
    q = sp.authors_n3(X, N)
    assert q.shape == (40, 9) and sp.authors_n3(X, None).shape == (40, 3)
    for x, nn, row in zip(X[:5], N[:5], q[:5]):  # their parameterize_grasp for n = 3, written out for one grasp
        D = [np.linalg.norm(x[0] - x[1]), np.linalg.norm(x[1] - x[2]), np.linalg.norm(x[2] - x[0])]
        i = int(np.argmax(D))
        t = np.roll(x, -i, axis=0)
        a0 = np.arccos(np.dot(t[2] - t[0], t[1] - t[0]) / (np.linalg.norm(t[2] - t[0]) * np.linalg.norm(t[1] - t[0])))
        a1 = np.arccos(np.dot(t[0] - t[1], t[2] - t[1]) / (np.linalg.norm(t[0] - t[1]) * np.linalg.norm(t[2] - t[1])))
        v1, v2 = t[1] - t[0], t[2] - t[0]
        tri, edge = np.cross(v1, v2) / (np.linalg.norm(v1) * np.linalg.norm(v2)), v1 / np.linalg.norm(v1)
        ang = [f(v) for v in nn for f in (lambda v: np.arccos(tri @ v), lambda v: np.arccos(edge @ v))]
        np.testing.assert_allclose(row, [a0, a1, D[i], *ang], atol=1e-12)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))  # a rotation (a reflection would flip the triangle's normal)
    np.testing.assert_allclose(sp.authors_n3(X @ R.T + 5.0, N @ R.T), q, atol=1e-9)
    np.testing.assert_allclose(sp.authors_n3(np.roll(X, 1, axis=1), np.roll(N, 1, axis=1))[:, :3], q[:, :3], atol=1e-12)
    rev = sp.authors_n3(X[:, ::-1], N[:, ::-1])
    np.testing.assert_allclose(rev[:, [1, 0, 2]], q[:, :3], atol=1e-12)


def test_sampling_protocol_authors_chain(load_benchmark):
    """The authors' vector for n >= 4 (``authors_chain``): 3n - 6 / 5n - 6 values; the largest hull facet from its
    longest edge, then the other facet on that edge, with the dot product of the two scaled facet normals (written
    out here for both cyclic orientations Qhull may give the first facet); rejected when Qhull fails (coplanar
    contacts) or a contact lies inside the hull, as their code rejects it."""
    sp = load_benchmark("sampling_protocol")
    rng = np.random.default_rng(3)

    def ang(a, b):
        return np.arccos(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))

    def scaled(P):
        return np.cross(P[1] - P[0], P[2] - P[0]) / (np.linalg.norm(P[1] - P[0]) * np.linalg.norm(P[2] - P[0]))

    for _ in range(20):
        X = rng.normal(size=(4, 3))
        N = rng.normal(size=(4, 3))
        N /= np.linalg.norm(N, axis=1, keepdims=True)
        q = sp.authors_chain(X, None)
        assert q.shape == (6,) and sp.authors_chain(X, N).shape == (14,)
        t1 = max(((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)),
                 key=lambda f: np.linalg.norm(np.cross(X[f[1]] - X[f[0]], X[f[2]] - X[f[0]])))
        a, b = max(((i, j) for i in t1 for j in t1 if i < j), key=lambda e: np.linalg.norm(X[e[0]] - X[e[1]]))
        c, k = next(v for v in t1 if v not in (a, b)), next(v for v in range(4) if v not in t1)
        candidates = []
        for v0, v1 in ((a, b), (b, a)):  # the first facet's cyclic orientation is Qhull's
            P1, P2 = X[[v0, v1, c]], X[[v0, v1, k]]
            candidates.append([ang(P1[2] - P1[0], P1[1] - P1[0]), ang(P1[0] - P1[1], P1[2] - P1[1]),
                               np.linalg.norm(X[a] - X[b]), ang(P2[2] - P2[0], P2[1] - P2[0]),
                               ang(P2[0] - P2[1], P2[2] - P2[1]), scaled(P2) @ scaled(P1)])
        assert any(np.allclose(q, cand, atol=1e-10) for cand in candidates)
    square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert sp.authors_chain(square, None) is None  # coplanar: Qhull fails
    inside = np.array([[2.0, 0, 0], [0, 2, 0], [0, 0, 2], [-1, -1, -1], [0, 0, 0]])
    assert sp.authors_chain(inside, None) is None  # the fifth contact lies inside the hull of the other four


def test_sampling_protocol_chooses_k_on_validation(load_benchmark):
    """A row's ``k`` is the one best on the validation grasps, not on the test grasps: one class-1 training point
    inside class 0's interval makes k = 1 right on a validation query labelled 1 there and wrong on a test query
    labelled 0 at the same place, where k = 15 and 50 are right."""
    sp = load_benchmark("sampling_protocol")
    rng = np.random.default_rng(0)
    X = np.concatenate([rng.uniform(0, 1, 100), [0.5], rng.uniform(5, 6, 100)])[:, None]
    y = np.array([0] * 100 + [1] * 101)
    here = np.array([[0.5]])
    accs, j = sp.validated_knn((X, y), (here, np.array([1])), (here, np.array([0])))
    assert (accs, j) == ([0.0, 1.0, 1.0], 0)  # k = 1 chosen, and its test accuracy is the row's figure
    assert sp.knn_accuracy(X, y, here, np.array([0])) == accs
    assert "**0.0 %** | 100.0 % | 100.0 % | 1" == sp._cells(accs, j)


def test_exp2_asked_of_finished_cells_trains_them_again(paper_scale, tmp_path, capsys):
    """--exp2 is not in the settings hash: MLP cells finished without it are trained again with it (they were
    skipped as done, so --exp2 gave no experiment-2 results); the kNN cell and cells with them stay."""
    out = tmp_path / "ps"
    base = [*TINY, "--out", str(out), "--grasps", "300", "--trials-per-object", "2"]
    assert paper_scale.main(base) == 0
    mlp = next((out / "cells").glob("n3-w-g300-mlp-default-*.json"))
    knn = next((out / "cells").glob("n3-w-g300-knn-*.json"))
    assert "exp2" not in json.loads(mlp.read_text())
    stamp = knn.stat().st_mtime_ns
    capsys.readouterr()
    assert paper_scale.main([*base, "--exp2"]) == 0
    said = capsys.readouterr().out
    assert "2 cells, 1 done, 1 to run" in said and "1 finished MLP cells lack the --exp2 results" in said
    assert "exp2" in json.loads(mlp.read_text()) and knn.stat().st_mtime_ns == stamp
    capsys.readouterr()
    assert paper_scale.main([*base, "--exp2"]) == 0
    assert "2 cells, 2 done, 0 to run" in capsys.readouterr().out
