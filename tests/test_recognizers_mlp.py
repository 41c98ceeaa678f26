"""Torch MLP: learns a separable toy problem, save/load round trip, corrupted files rejected."""

import numpy as np
import pytest
import torch

from haptic_env.cache import CacheError
from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig


def _toy(rng, n=1500):
    X = rng.normal(size=(n, 4)) * [1.0, 1.0, 100.0, 0.01]  # badly scaled on purpose
    y = (X[:, 0] + X[:, 1] > 0).astype(int) + 2 * (X[:, 2] > 0)
    return X, y


@pytest.fixture(scope="module")
def trained():
    X, y = _toy(np.random.default_rng(0))
    cfg = MLPConfig(depth=2, width=32, max_epochs=40, patience=40, batch_size=128, lr=1e-2, progress=False, threads=1)
    return MLPClassifier(cfg).fit(X, y), cfg


def test_learns_separable_problem(trained):
    clf, _ = trained
    Xt, yt = _toy(np.random.default_rng(1), 1000)
    assert clf.score(Xt, yt) > 0.95
    P = clf.predict_proba(Xt)
    assert P.shape == (1000, 4) and np.allclose(P.sum(1), 1.0)


def test_training_is_seeded_and_leaves_global_rng_alone(trained):
    clf, cfg = trained
    X, y = _toy(np.random.default_rng(0))
    state = torch.random.get_rng_state()
    again = MLPClassifier(cfg).fit(X, y)
    assert torch.equal(state, torch.random.get_rng_state())
    assert np.allclose(again.predict_proba(X[:50]), clf.predict_proba(X[:50]), atol=1e-5)
    loaded = MLPClassifier.from_dict(clf.to_dict())  # a load (a warm cache) too: it drew from it, a fit did not
    assert torch.equal(state, torch.random.get_rng_state())
    assert np.array_equal(loaded.predict_proba(X[:50]), clf.predict_proba(X[:50]))


def test_fit_trains_on_its_threads_and_gives_the_callers_back(monkeypatch):
    import haptic_env.recognizers.mlp as mlp

    seen = []
    train_epoch = MLPClassifier._fit
    monkeypatch.setattr(MLPClassifier, "_fit", lambda self, *a, **k: (seen.append(torch.get_num_threads()),
                                                                      train_epoch(self, *a, **k))[1])
    before = torch.get_num_threads()
    want = 1 if before != 1 else 2
    X, y = _toy(np.random.default_rng(0), 300)
    MLPClassifier(MLPConfig(depth=1, width=8, max_epochs=1, progress=False, threads=want)).fit(X, y)
    assert seen == [want] and torch.get_num_threads() == before
    with pytest.raises(ValueError, match="torch threads must be >= 1, got 0"):
        with mlp.torch_threads(0):
            pass
    assert torch.get_num_threads() == before


def test_save_load_round_trip(trained, tmp_path):
    clf, _ = trained
    path = clf.save(tmp_path / "m.pt")
    back = MLPClassifier.load(path)
    X, _ = _toy(np.random.default_rng(2), 100)
    assert np.allclose(back.predict_proba(X), clf.predict_proba(X), atol=1e-6)
    assert back.config == clf.config


def test_corrupt_and_wrong_version_rejected(trained, tmp_path):
    clf, _ = trained
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a torch file at all")
    with pytest.raises(CacheError, match="corrupted"):
        MLPClassifier.load(bad)
    blob = clf.to_dict()
    blob["version"] = 999
    old = tmp_path / "old.pt"
    torch.save(blob, old)
    with pytest.raises(CacheError, match="version 999"):
        MLPClassifier.load(old)
    with pytest.raises(FileNotFoundError):
        MLPClassifier.load(tmp_path / "missing.pt")


def test_input_checks(trained):
    clf, _ = trained
    with pytest.raises(ValueError, match="features"):
        clf.predict_proba(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="not finite"):
        clf.predict_proba(np.array([[0, np.inf, 0, 0]]))
    with pytest.raises(ValueError, match="depth"):
        MLPConfig(depth=-1)
    with pytest.raises(RuntimeError, match="not fitted"):
        MLPClassifier().predict_proba(np.zeros((1, 2)))


def test_decoupled_weight_decay():
    """``decoupled_weight_decay`` shrinks the weights (smaller than without decay) by another update than the coupled
    L2 penalty of the same size; a file saved before the option existed loads with it off."""
    X, y = _toy(np.random.default_rng(3), 600)
    base = dict(depth=1, width=16, max_epochs=3, patience=3, batch_size=100, lr=1e-2, progress=False, threads=1)
    plain = MLPClassifier(MLPConfig(**base)).fit(X, y)
    adamw = MLPClassifier(MLPConfig(**base, weight_decay=0.5, decoupled_weight_decay=True)).fit(X, y)
    coupled = MLPClassifier(MLPConfig(**base, weight_decay=0.5)).fit(X, y)
    norm = lambda clf: sum(float(p.detach().norm()) ** 2 for p in clf.net.parameters())  # noqa: E731
    assert norm(adamw) < norm(plain)
    assert not np.allclose(adamw.predict_proba(X[:20]), coupled.predict_proba(X[:20]))
    blob = adamw.to_dict()
    del blob["config"]["decoupled_weight_decay"]
    assert MLPClassifier.from_dict(blob).config.decoupled_weight_decay is False


@pytest.mark.parametrize("field, value", [("weight_decay", -0.1), ("weight_decay", float("nan")),
                                          ("lr_decay", 0.0), ("lr_decay", 1.5)])
def test_bad_optimizer_settings_named(field, value):
    with pytest.raises(ValueError, match=f"MLPConfig.{field}.*{value}"):
        MLPConfig(**{field: value})


def test_an_interrupted_fit_resumes_from_its_epoch_checkpoint(tmp_path, monkeypatch):
    """``fit(checkpoint=...)`` keeps the training state after every epoch: a fit interrupted in its third epoch and
    called again goes on from the second and ends with the uninterrupted fit's weights and history; the file is gone
    at the end, and a file of other data is not used."""
    import haptic_env.recognizers.mlp as mlp_mod

    rng = np.random.default_rng(0)
    X, y = rng.normal(size=(600, 5)), rng.integers(0, 3, 600)
    X[np.arange(600), y] += 1.5
    cfg = MLPConfig(depth=1, width=16, max_epochs=5, patience=10, batch_size=64, progress=False, seed=3)
    whole = MLPClassifier(cfg).fit(X, y)
    ckpt = tmp_path / "fit.pt"
    real, seen = MLPClassifier._evaluate, []

    def evaluate(self, Xv, yv):
        seen.append(1)
        if len(seen) == 3 and not resumed:
            raise KeyboardInterrupt  # in the third epoch, after its training
        return real(self, Xv, yv)

    resumed = False
    monkeypatch.setattr(MLPClassifier, "_evaluate", evaluate)
    with pytest.raises(KeyboardInterrupt):
        MLPClassifier(cfg).fit(X, y, checkpoint=ckpt)
    assert torch.load(ckpt, weights_only=False)["epoch"] == 1
    resumed, seen[:] = True, []
    again = MLPClassifier(cfg).fit(X, y, checkpoint=ckpt)
    assert len(seen) == 3 and not ckpt.exists()  # epochs 3-5 only
    assert again.history == whole.history
    for k, v in whole.net.state_dict().items():
        torch.testing.assert_close(again.net.state_dict()[k], v, rtol=0, atol=0)
    mlp_mod._save_fit_state(ckpt, {"key": "another fit", "epoch": 4})
    seen[:] = []
    MLPClassifier(cfg).fit(X, y, checkpoint=ckpt)
    assert len(seen) == 5
    # keep_checkpoint: the finished fit's file stays for the caller (paper_scale removes it once its cell is saved);
    # the fit called again with it runs no epoch and gives the same model
    seen[:] = []
    kept = MLPClassifier(cfg).fit(X, y, checkpoint=ckpt, keep_checkpoint=True)
    assert len(seen) == 5 and ckpt.exists()
    seen[:] = []
    again = MLPClassifier(cfg).fit(X, y, checkpoint=ckpt, keep_checkpoint=True)
    assert not seen and again.temperature == kept.temperature
    for k, v in kept.net.state_dict().items():
        torch.testing.assert_close(again.net.state_dict()[k], v, rtol=0, atol=0)


def test_a_fit_without_validation_rows_needs_two_rows_and_keeps_one_for_training():
    """Without ``X_val`` the MLP holds out validation rows; one row is refused by name (it trained on none and
    divided by zero), two keep one row each."""
    from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig

    cfg = MLPConfig(depth=1, width=4, max_epochs=1, progress=False)
    with pytest.raises(ValueError, match="needs >= 2 training rows, got 1"):
        MLPClassifier(cfg).fit(np.zeros((1, 3)), np.array([0]), n_classes=2)
    m = MLPClassifier(cfg).fit(np.array([[0.0, 0, 0], [1, 1, 1]]), np.array([0, 1]))
    assert m.predict_proba(np.zeros((1, 3))).shape == (1, 2)
