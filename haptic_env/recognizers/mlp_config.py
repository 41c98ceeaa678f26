"""The settings of the MLP classifier (:class:`MLPConfig`), apart from :mod:`~haptic_env.recognizers.mlp` so that a
recogniser's config can be built and read without importing torch (a BC-NP env never trains the MLP)."""

from __future__ import annotations

from dataclasses import dataclass, field

from haptic_env.cache import KEY_AS
from haptic_env.numbers import finite_number, flag, whole_at_least, whole_number

__all__ = ["MLPConfig"]


@dataclass(frozen=True)
class MLPConfig:
    """Architecture and training of :class:`MLPClassifier`."""

    depth: int = 3  #: hidden layers
    width: int = 256  #: units per hidden layer
    lr: float = 3e-3  #: Adam learning rate (decayed by ``lr_decay`` per epoch)
    lr_decay: float = 0.93
    #: L2 penalty on the weights, added to the gradient (Adam's ``weight_decay``); with ``decoupled_weight_decay``
    #: the weights shrink by ``lr * weight_decay`` per step instead (AdamW, Loshchilov & Hutter)
    weight_decay: float = 0.0
    decoupled_weight_decay: bool = False
    batch_size: int = 1024
    max_epochs: int = 40
    patience: int = 4  #: epochs without validation-loss improvement before stopping
    max_train: int | None = None  #: train on a random subsample of at most this many rows
    val_fraction: float = 0.1  #: used only when no explicit validation set is given to ``fit``
    seed: int = 0
    threads: int | None = None  #: torch intra-op threads (None: see :func:`~.mlp.torch_threads`)
    #: a progress bar per epoch; keyed as False (:data:`~haptic_env.cache.KEY_AS`, the analyses' setting, so that
    #: their cached models keep their keys): with it on or off a recogniser finds the same cached model
    progress: bool = field(default=True, metadata={KEY_AS: False})

    def __post_init__(self):
        for name in ("depth", "width", "batch_size", "max_epochs", "patience"):
            v = getattr(self, name)
            n = whole_number(v)
            lo = 0 if name == "depth" else 1  # depth 0: a linear classifier
            if n is None or n < lo:
                raise ValueError(f"MLPConfig.{name} must be an integer >= {lo}, got {v!r}")
        if self.max_train is not None and (whole_number(self.max_train) or 0) < 1:
            raise ValueError(f"MLPConfig.max_train must be None or an int >= 1, got {self.max_train!r}")
        if not (finite_number(self.lr) or 0) > 0:
            raise ValueError(f"MLPConfig.lr must be positive and finite, got {self.lr!r}")
        wd = finite_number(self.weight_decay)
        if wd is None or wd < 0:
            raise ValueError(f"MLPConfig.weight_decay must be >= 0 and finite, got {self.weight_decay!r}")
        if not 0.0 < (finite_number(self.lr_decay) or 0) <= 1.0:
            raise ValueError(f"MLPConfig.lr_decay must be in (0, 1], got {self.lr_decay!r}")
        if not 0.0 < (finite_number(self.val_fraction) or 0) < 1.0:
            raise ValueError(f"MLPConfig.val_fraction must be in (0, 1), got {self.val_fraction!r}")
        whole_at_least(self.seed, 0, "MLPConfig.seed")
        if self.threads is not None and (whole_number(self.threads) or 0) < 1:
            raise ValueError(f"MLPConfig.threads must be None or an int >= 1, got {self.threads!r}")
        for name in ("decoupled_weight_decay", "progress"):
            if flag(getattr(self, name)) is None:
                raise ValueError(f"MLPConfig.{name} must be True or False, got {getattr(self, name)!r}")
