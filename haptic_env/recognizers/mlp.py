"""Torch MLP grasp classifier: ``q (B, d) -> P(object | q) (B, K)``.

A plain ReLU multi-layer perceptron with the feature standardisation stored in the model, trained
with Adam on cross-entropy, a held-out validation split and early stopping on validation loss
(``MLPConfig(weight_decay=w, decoupled_weight_decay=True)``: AdamW).

Defaults (:class:`MLPConfig`): 3 hidden layers of 256 units, batch 1024. The paper used 7 x 500
for 14 inputs; on 2 CPU cores that costs tens of seconds per epoch over 160k grasps, ~10x the
default, so the paper's size is available as ``MLPConfig(depth=7, width=500)`` but is not the
default (RESULTS.md compares both where time allowed).

Everything random (initialisation, validation split, mini-batch order) comes from a
``torch.Generator`` / ``np.random.Generator`` seeded by ``MLPConfig.seed``; no global RNG is used.
"""

from __future__ import annotations

import dataclasses
import io
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

from haptic_env.cache import CacheError, atomic_write, config_key
from haptic_env.numbers import whole_number
from haptic_env.recognizers.calibration import fit_temperature
from haptic_env.recognizers.mlp_config import MLPConfig
from haptic_env.recognizers.preprocess import Standardizer
from haptic_env.recognizers.preprocess import check_validation_pair
from haptic_env.recognizers.preprocess import check_xy as _check_xy
from haptic_env.recognizers.preprocess import class_count

__all__ = ["MLPConfig", "MLPClassifier", "FORMAT_VERSION", "torch_threads", "Standardizer"]

#: Version of the file written by :meth:`MLPClassifier.save`.
FORMAT_VERSION = 1


@contextmanager
def torch_threads(n: int | None = None) -> Iterator[int]:
    """Run the block with ``n`` torch intra-op threads (default: ``$HAPTIC_TORCH_THREADS`` or all cores, at most 8),
    then give the process back the count it had: a fit does not change its caller's threads."""
    if n is None:
        env = os.environ.get("HAPTIC_TORCH_THREADS")
        try:
            n = min(8, os.cpu_count() or 1) if env is None else int(env)
        except ValueError:
            raise ValueError(f"HAPTIC_TORCH_THREADS must be an int >= 1, got {env!r}") from None
    if (whole_number(n) or 0) < 1:
        raise ValueError(f"torch threads must be >= 1, got {n!r}")
    before = torch.get_num_threads()
    if before != n:
        torch.set_num_threads(n)
    try:
        yield n
    finally:
        if torch.get_num_threads() != before:
            torch.set_num_threads(before)


def _network(d: int, k: int, depth: int, width: int) -> nn.Sequential:
    """The MLP's layers; ``nn.Linear`` initialises them from torch's global RNG, whose state is put back (a fit
    draws its own initialisation, a load its saved weights: neither may move the caller's random numbers)."""
    state = torch.random.get_rng_state()
    layers: list[nn.Module] = []
    last = d
    for _ in range(depth):
        layers += [nn.Linear(last, width), nn.ReLU()]
        last = width
    layers.append(nn.Linear(last, k))
    torch.random.set_rng_state(state)
    return nn.Sequential(*layers)


def _fit_key(cfg: MLPConfig, X, y, X_val, y_val, n_classes: int) -> str:
    """What a fit's result depends on: its config and its data (their shapes, dtypes and bytes), hashed
    (:func:`~haptic_env.cache.config_key`), for :meth:`MLPClassifier.fit`'s ``checkpoint``."""
    data = [np.asarray(a) for a in (X, y, X_val, y_val)]
    return config_key(cfg, n_classes, [(a.shape, str(a.dtype)) for a in data], *data)


def _save_fit_state(path: Path, state: dict) -> None:
    """``torch.save`` of a fit's state, atomically."""
    with atomic_write(path) as fh:
        torch.save(state, fh)


def _load_fit_state(path: Path, key: str) -> dict | None:
    """The saved state of a fit with this key, or None (none, another fit's, unreadable)."""
    if not path.exists():
        return None
    try:
        state = torch.load(path, weights_only=False)
    except Exception:  # a file torch cannot read: start the fit over
        return None
    return state if isinstance(state, dict) and state.get("key") == key else None


class MLPClassifier:
    """ReLU MLP with stored standardisation; ``fit``/``predict_proba``/``save``/``load``."""

    def __init__(self, config: MLPConfig | None = None, **overrides):
        config = config or MLPConfig()
        self.config = dataclasses.replace(config, **overrides) if overrides else config
        self.net: nn.Sequential | None = None
        self.scaler: Standardizer | None = None
        self.n_classes: int = 0
        self.history: dict[str, list[float]] = {}
        self.temperature = 1.0  #: calibration temperature of the logits, fitted on the validation set by fit()

    @property
    def classes_(self) -> np.ndarray:
        return np.arange(self.n_classes)

    @property
    def n_features(self) -> int:
        self._check_fitted()
        return int(self.scaler.mean.shape[0])

    def _check_fitted(self):
        if self.net is None:
            raise RuntimeError("MLPClassifier is not fitted; call fit() or MLPClassifier.load()")

    # ------------------------------------------------------------------------------ training
    def fit(self, X, y, X_val=None, y_val=None, *, n_classes: int | None = None,
            checkpoint: str | os.PathLike | None = None, keep_checkpoint: bool = False) -> MLPClassifier:
        """Train on ``X (N, d)``, ``y (N,)`` (class indices); early stopping on ``(X_val, y_val)``.

        Without an explicit validation set, ``config.val_fraction`` of ``X`` is held out. After training,
        :attr:`temperature` is fitted on the validation logits (:func:`~.calibration.fit_temperature`);
        ``predict_proba`` stays raw, :class:`~.recognizer.ModelBank` applies the temperature.

        ``checkpoint``: a file that keeps the training state after every epoch (written atomically; removed when
        the fit ends). A fit interrupted and called again with the same file, config and data goes on from its last
        finished epoch and ends with the weights an uninterrupted fit gives. A file of another config or data (its
        fingerprint differs) is ignored and overwritten. ``keep_checkpoint=True`` leaves the finished fit's file for
        the caller to remove once it has saved what it made of the model (a fit called again with it then runs no
        epoch), so an interrupt between the fit and that save does not lose the fit.
        """
        with torch_threads(self.config.threads):
            self._fit(X, y, X_val, y_val, n_classes=n_classes, checkpoint=checkpoint)
        if checkpoint is not None and not keep_checkpoint:
            Path(checkpoint).unlink(missing_ok=True)
        return self

    def _fit(self, X, y, X_val, y_val, *, n_classes: int | None, checkpoint: str | os.PathLike | None) -> MLPClassifier:
        cfg = self.config
        X, y = _check_xy(X, y)
        check_validation_pair(X_val, y_val)
        rng = np.random.default_rng(cfg.seed)
        if cfg.max_train is not None and len(X) > cfg.max_train:
            keep = rng.choice(len(X), cfg.max_train, replace=False)
            X, y = X[keep], y[keep]
        if X_val is None:
            if len(X) < 2:
                raise ValueError(f"MLP fit without X_val holds out validation rows: it needs >= 2 training rows, got "
                                 f"{len(X)}")
            perm = rng.permutation(len(X))
            n_val = min(max(1, int(round(cfg.val_fraction * len(X)))), len(X) - 1)
            X_val, y_val = X[perm[:n_val]], y[perm[:n_val]]
            X, y = X[perm[n_val:]], y[perm[n_val:]]
        else:
            X_val, y_val = _check_xy(X_val, y_val, X.shape[1], "X_val")
        self.n_classes = class_count(n_classes, y, y_val)
        self.scaler = Standardizer.fit(X)
        gen = torch.Generator().manual_seed(cfg.seed)
        self.net = _network(X.shape[1], self.n_classes, cfg.depth, cfg.width)  # the global RNG's state kept
        with torch.no_grad():  # He-uniform initialisation from our own generator
            for m in self.net:
                if isinstance(m, nn.Linear):
                    bound = float(np.sqrt(6.0 / m.in_features))
                    m.weight.uniform_(-bound, bound, generator=gen)
                    m.bias.zero_()
        Xt = torch.as_tensor(self.scaler(X), dtype=torch.float32)
        yt = torch.as_tensor(y)
        Xv = torch.as_tensor(self.scaler(X_val), dtype=torch.float32)
        yv = torch.as_tensor(y_val)
        opt = torch.optim.Adam(self.net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay,
                               decoupled_weight_decay=cfg.decoupled_weight_decay)
        sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma=cfg.lr_decay)
        lossf = nn.CrossEntropyLoss()
        best, best_state, bad = np.inf, None, 0
        self.history = {"train_loss": [], "val_loss": [], "val_acc": []}
        start, key = 0, None
        if checkpoint is not None:
            checkpoint = Path(checkpoint)
            key = _fit_key(cfg, X, y, X_val, y_val, self.n_classes)
            saved = _load_fit_state(checkpoint, key)
            if saved is not None:
                self.net.load_state_dict(saved["net"])
                opt.load_state_dict(saved["opt"])
                sched.load_state_dict(saved["sched"])
                gen.set_state(saved["gen"])
                best, best_state, bad, self.history = saved["best"], saved["best_state"], saved["bad"], saved["history"]
                start = saved["epoch"] + 1
        stopped = start > 0 and bad >= cfg.patience  # the saved run had stopped early already
        bar = tqdm(range(start, cfg.max_epochs) if not stopped else (), desc=f"MLP {cfg.depth}x{cfg.width}",
                   disable=not cfg.progress, leave=False, initial=start, total=cfg.max_epochs)
        for epoch in bar:
            self.net.train()
            order = torch.randperm(len(Xt), generator=gen)
            tot = 0.0
            for lo in range(0, len(Xt), cfg.batch_size):
                idx = order[lo : lo + cfg.batch_size]
                opt.zero_grad(set_to_none=True)
                loss = lossf(self.net(Xt[idx]), yt[idx])
                loss.backward()
                opt.step()
                tot += float(loss.detach()) * len(idx)
            sched.step()
            vl, va = self._evaluate(Xv, yv)
            self.history["train_loss"].append(tot / len(Xt))
            self.history["val_loss"].append(vl)
            self.history["val_acc"].append(va)
            bar.set_postfix(val_loss=f"{vl:.3f}", val_acc=f"{va:.3f}")
            if vl < best - 1e-4:
                best, bad = vl, 0
                best_state = {k: v.detach().clone() for k, v in self.net.state_dict().items()}
            else:
                bad += 1
            if checkpoint is not None:
                _save_fit_state(checkpoint, {"key": key, "epoch": epoch, "net": self.net.state_dict(),
                                             "opt": opt.state_dict(), "sched": sched.state_dict(),
                                             "gen": gen.get_state(), "best": best, "best_state": best_state,
                                             "bad": bad, "history": self.history})
            if bad >= cfg.patience:
                break
        if best_state is not None:
            self.net.load_state_dict(best_state)
        self.net.eval()
        with torch.no_grad():  # temperature scaling on the validation logits (calibration.fit_temperature)
            logits = torch.cat([self.net(Xv[lo : lo + 65536]) for lo in range(0, len(Xv), 65536)])
        self.temperature = fit_temperature(logits.double().numpy(), y_val)
        return self

    @torch.no_grad()
    def _evaluate(self, Xv: torch.Tensor, yv: torch.Tensor) -> tuple[float, float]:
        self.net.eval()
        logits = torch.cat([self.net(Xv[lo : lo + 65536]) for lo in range(0, len(Xv), 65536)])
        return float(nn.functional.cross_entropy(logits, yv)), float((logits.argmax(1) == yv).float().mean())

    # ----------------------------------------------------------------------------- inference
    @torch.no_grad()
    def predict_log_proba(self, X) -> np.ndarray:
        """``(B, d) -> (B, K)`` log class probabilities (a single ``(d,)`` vector gives ``(1, K)``)."""
        self._check_fitted()
        X = _check_xy(np.atleast_2d(X), d=self.n_features)
        xt = torch.as_tensor(self.scaler(X), dtype=torch.float32)
        out = [torch.log_softmax(self.net(xt[lo : lo + 65536]), dim=1) for lo in range(0, len(xt), 65536)]
        return torch.cat(out).double().numpy() if out else np.zeros((0, self.n_classes))

    def predict_proba(self, X) -> np.ndarray:
        """``(B, d) -> (B, K)`` class probabilities (rows sum to 1)."""
        return np.exp(self.predict_log_proba(X))

    def predict(self, X) -> np.ndarray:
        return self.predict_log_proba(X).argmax(axis=1)

    def score(self, X, y) -> float:
        return float(np.mean(self.predict(X) == np.asarray(y)))

    # ------------------------------------------------------------------------------- storage
    def to_dict(self) -> dict:
        self._check_fitted()
        return {
            "format": "haptic_env.MLPClassifier",
            "version": FORMAT_VERSION,
            "config": dataclasses.asdict(self.config),
            "n_classes": self.n_classes,
            "state_dict": self.net.state_dict(),
            "scaler_mean": torch.as_tensor(self.scaler.mean),
            "scaler_std": torch.as_tensor(self.scaler.std),
            "history": self.history,
            "temperature": float(self.temperature),
        }

    @classmethod
    def from_dict(cls, blob: dict, where: str = "<dict>") -> MLPClassifier:
        if not isinstance(blob, dict) or blob.get("format") != "haptic_env.MLPClassifier":
            raise CacheError(f"{where} is not a saved MLPClassifier")
        if blob.get("version") != FORMAT_VERSION:
            raise CacheError(
                f"{where} has MLPClassifier format version {blob.get('version')!r}, this code reads "
                f"version {FORMAT_VERSION}; delete it to retrain"
            )
        try:
            model = cls(MLPConfig(**blob["config"]))
            model.n_classes = int(blob["n_classes"])
            model.scaler = Standardizer(blob["scaler_mean"].numpy(), blob["scaler_std"].numpy())
            d = model.scaler.mean.shape[0]
            model.net = _network(d, model.n_classes, model.config.depth, model.config.width)
            model.net.load_state_dict(blob["state_dict"])
            model.net.eval()
            model.history = blob.get("history", {})
            model.temperature = float(blob.get("temperature", 1.0))
        except (KeyError, TypeError, RuntimeError, ValueError) as exc:
            raise CacheError(f"{where} is a corrupted MLPClassifier file ({exc}); delete it to retrain") from exc
        return model

    def save(self, path: str | os.PathLike) -> Path:
        """Write config, weights, scaler and format version to one file (atomically)."""
        buf = io.BytesIO()
        torch.save(self.to_dict(), buf)
        with atomic_write(path) as fh:
            fh.write(buf.getvalue())
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> MLPClassifier:
        """Read a file written by :meth:`save`; :class:`~haptic_env.cache.CacheError` if unusable."""
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"no saved MLPClassifier at {path}")
        try:
            blob = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:
            raise CacheError(f"{path} is corrupted or not a torch file ({exc}); delete it to retrain") from exc
        return cls.from_dict(blob, str(path))
