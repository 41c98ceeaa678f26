r"""Per-object kernel density estimates of grasp vectors: ``log p(q | object)``.

Features are standardised with one global :class:`~haptic_env.recognizers.mlp.Standardizer`
(fitted on all objects' training vectors) and every object gets an isotropic Gaussian KDE with a
bandwidth ``h_c`` in standardised units:

.. math:: \log p(q\mid c) = \operatorname{logsumexp}_i\Big(-\tfrac{\lVert q - x_i\rVert^2}{2h_c^2}\Big)
          - \log N_c - \tfrac d2 \log(2\pi h_c^2) - \textstyle\sum_j \log \sigma_j

``KDEConfig.bandwidth="shared"`` (default): one ``h = factor * N^(-1/(d+4))`` for all objects (Scott's rule
with the mean per-object sample count ``N``); with ``factor="auto"`` the factor is chosen from
``KDEConfig.factor_grid`` by the mean validation log-likelihood of the true object (training data only;
never the test grasps; ``KDEConfig.select="likelihood"``, the default), or (``select="posterior"``) by the
held-out validation NLL of the *calibrated one-shot posterior*: at each factor the full KDE scores the calibration
vectors, both calibrations are fitted on one half of each class's vectors and scored on the other
(:func:`~haptic_env.recognizers.calibration.select_calibration`), and the factor whose calibration (as
``KDEConfig.correct`` would choose it) scores best wins. The density criterion fits each class's density; the
posterior criterion fits what BC uses, the ratios between classes after calibration. In the one cell where the
analyses' calibrated one-shot ECE missed 0.05 (the default set, n = 4 without normals) it picked factor 1.4 instead
of 0.5 with 10,000 grasps per object (test ECE 0.031 instead of 0.056 on 36,000 test grasps), but kept 0.5 with
200,000 (RESULTS.md). ``"per-class"``: each object's ``h_c = factor_c * N_c^(-1/(d+4))``, ``factor_c``
chosen by the mean validation log-likelihood of that object's own validation vectors, i.e. each class
density is fitted by held-out likelihood on its own. Objects whose grasps are compact (a sphere's) get a
narrower kernel and spread ones a wider. On the MuJoCo hands' hand-matched grasps it moved validation BC-NP
by +0.6 to +0.7 points (within the seeds' spread) but lowered the 5-finger hands' z = 3 subset scoring by
3-7 points (RESULTS.md), so nothing uses it by default.

Evaluation (``KDEConfig.method``)
    ``"tree"`` (default): a :class:`scipy.spatial.cKDTree` per object; the sum runs over ``k``
    near training vectors within ``cutoff * h`` (kernels beyond ``4 h`` weigh < ``e^-8`` of the
    nearest), found by an approximate search (``eps``: the j-th vector returned is within
    ``1 + eps`` times the distance of the true j-th neighbour). Exact k-NN in 14 dimensions costs
    ~12 ms per update over 8 x 200,000 vectors; ``eps = 2`` brings it to ~1.5 ms (CPU time) at a
    measured cost of ~5-8 % one-shot argmax disagreement with the dense sum and no measurable loss
    of one-shot accuracy (``benchmarks/bench_recognizers.py``). When an object has no training
    vector within the cutoff, its nearest found vector alone is used (a lower bound of the sum).
    ``k`` is a floor: in few dimensions a kernel covers far more than 32 vectors (``n = 2`` without
    normals, ``d = 1``: 500-2,000 of an object's 8,000 within ``cutoff * h``), and a sum over the 32
    nearest saturates near ``log 32`` wherever the density is high, so it stops telling objects
    apart (measured there: 2.4 nats below the dense sum on the true object, a fitted temperature of
    0.13, BC-NP right at the stop in 65 % of validation trials against the dense sum's 77 %).
    So each object takes ``k_c`` neighbours: the 90th percentile, over up to 256 of its own training
    vectors, of the number of its vectors within ``cutoff * h_c``, raised to at least ``k`` but
    not above ``max(k, k_max)``. Computed from the training vectors and the bandwidth when the index is built, so a
    cached KDE gets the same. In 14 dimensions it stays near ``k`` for most objects (compact ones, such as a
    sphere's grasps, take more).
    ``"pooled"``: ONE k-d tree over the training vectors of all objects
    (:class:`~haptic_env.recognizers.knn.KDTree`: compiled, float32, search and sums in one call); a
    single search finds the ``k`` nearest vectors of any object (same ``eps``). Each object's sum
    runs over its vectors among them within ``cutoff * h`` (none within the cutoff: its nearest one
    alone, as for ``"tree"``); an object with no vector among the ``k`` gets the kernel at the
    ``k``-th distance, an upper bound of its nearest term (its vectors are all at least that far,
    up to ``eps``). Far objects thus tie at a floor instead of being ranked by their own nearest
    vector, which a per-object search finds only slowly (most of ``"tree"``'s cost). About 10-20x
    faster than ``"tree"`` per grasp; the environment's belief update uses it. Agreement with the
    dense sum is measured in ``benchmarks/bench_recognizers.py``. ``k`` is not raised in few dimensions
    as for ``"tree"``: there the 32 nearest cover few of the vectors within the cutoff (argmaxes differ
    from the dense sum's on 15-36 % of probes near the data at d = 3-4, about 1 % at d = 14), yet on the
    Robotiq env (d = 4) k = 128, 256 or the dense sum stopped right as often in 1.8-3.3 more grasps on
    validation (RESULTS.md, "Not a lead: a more exact KDE sum for the Robotiq").
    ``"dense"``: the exact sum over all training vectors (reference; chunked numpy).
    ``"subsample"``: dense over a random subset of ``max_samples`` vectors per object.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import logsumexp
from scipy.spatial import cKDTree

from haptic_env.numbers import finite_number, flag, whole_at_least, whole_number
from haptic_env.recognizers.calibration import (CORRECTIONS, PowerCorrection, ScoreCorrection, calibration_rows,
                                                check_calibrate_grasps, check_corrections, fit_temperature,
                                                select_calibration, sequence_scores)
from haptic_env.recognizers.knn import KDTree, pooled_log_density
from haptic_env.recognizers.preprocess import Standardizer
from haptic_env.recognizers.preprocess import check_validation_pair
from haptic_env.recognizers.preprocess import check_xy as _check_xy
from haptic_env.recognizers.preprocess import class_count

__all__ = ["KDEConfig", "KDELikelihood", "scott_bandwidth", "BANDWIDTHS", "SELECTS"]

_METHODS = ("tree", "pooled", "dense", "subsample")
#: values of ``KDEConfig.bandwidth``
BANDWIDTHS = ("shared", "per-class")
#: values of ``KDEConfig.select`` (how ``factor="auto"`` chooses the bandwidth)
SELECTS = ("likelihood", "posterior")


@dataclass(frozen=True)
class KDEConfig:
    """Bandwidth and evaluation strategy of :class:`KDELikelihood`."""

    factor: float | str = "auto"  #: multiplies Scott's bandwidth; "auto": pick from factor_grid
    factor_grid: tuple[float, ...] = (0.25, 0.35, 0.5, 0.7, 1.0, 1.4)
    #: "shared": one bandwidth for all objects; "per-class": each object's own (with ``factor="auto"``, its factor
    #: chosen on its own validation vectors; a fixed ``factor`` scales each object's Scott's rule)
    bandwidth: str = "shared"
    method: str = "tree"
    k: int = 32  #: neighbours per object ("tree": at least), of all objects together ("pooled")
    #: "tree": the most neighbours per object that covering its kernel may raise ``k`` to (see the module docs)
    k_max: int = 4096
    cutoff: float = 4.0  #: neighbour radius in bandwidths ("tree", "pooled")
    eps: float = 2.0  #: approximate search: the j-th neighbour found is within (1 + eps) x the true one
    max_samples: int = 20_000  #: per object ("subsample")
    select_samples: int = 4_000  #: training vectors per object in the bandwidth-selection KDE
    n_select: int = 500  #: validation vectors per object used to choose the factor (``select="likelihood"``)
    #: how ``factor="auto"`` chooses: "likelihood" (default): the true class's validation log-likelihood of a dense
    #: KDE on ``select_samples`` vectors per object; "posterior": the held-out validation NLL of the calibrated
    #: one-shot posterior of the full KDE (the ``n_calibrate`` calibration vectors, halved; "shared" bandwidth
    #: only), the analyses' setting (``AnalysisConfig.kde``). The envs keep "likelihood": their hand-matched KDEs
    #: were validated with it.
    select: str = "likelihood"
    calibrate: bool = True  #: fit a temperature on validation vectors (see :mod:`.calibration`)
    #: with ``calibrate``: first fit a learned correction of the log-likelihoods on the validation vectors (matrix
    #: scaling, :class:`~.calibration.ScoreCorrection`), then the temperature on the corrected scores. True: always;
    #: "auto": only if it gives held-out validation beliefs a lower NLL (:func:`~.calibration.select_correction`), the
    #: analyses' setting (``AnalysisConfig``; surface-trained KDEs); False (default): never, as in the envs (on the
    #: hand-matched KDEs, whose beliefs mix 3-, 4- and 5-finger models, it lowered validation BC-NP, RESULTS.md; the
    #: geometric env was not validated with it). "power": always the exponent on each class's gap to the best
    #: (:class:`~.calibration.PowerCorrection`) instead. With "auto" the candidates weighed against the temperature
    #: alone are ``correct_candidates`` (:data:`~.calibration.CORRECTIONS`; :func:`~.calibration.select_calibration`).
    correct: bool | str = False
    #: the learned corrections ``correct="auto"`` may choose ("matrix": :class:`~.calibration.ScoreCorrection`,
    #: "power": :class:`~.calibration.PowerCorrection`; the analyses weigh both)
    correct_candidates: tuple[str, ...] = ("matrix",)
    n_calibrate: int = 1_000  #: validation vectors per object used to fit the temperature
    #: grasps per belief the temperature is fitted for: ``T`` minimises the NLL of the posteriors after
    #: ``k = 1 .. calibrate_grasps`` grasps of one object (sums of ``k`` random validation log-likelihoods of
    #: that object). 1: the one-shot temperature. See :func:`~.calibration.sequence_scores`.
    calibrate_grasps: int = 1
    seed: int = 0

    def __post_init__(self):
        if self.method not in _METHODS:
            raise ValueError(f"KDEConfig.method must be one of {_METHODS}, got {self.method!r}")
        correct = flag(self.correct)
        if correct is not None:  # np.bool_ kept as a Python bool: the fit tells True from "matrix" by identity
            object.__setattr__(self, "correct", correct)
        elif not (isinstance(self.correct, str) and self.correct in ("auto", *CORRECTIONS)):
            raise ValueError(f"KDEConfig.correct must be True, False, 'auto' or one of {tuple(CORRECTIONS)}, got "
                             f"{self.correct!r}")
        if flag(self.calibrate) is None:
            raise ValueError(f"KDEConfig.calibrate must be True or False, got {self.calibrate!r}")
        check_corrections(self.correct_candidates, "KDEConfig.correct_candidates", allow_empty=False)
        if self.bandwidth not in BANDWIDTHS:
            raise ValueError(f"KDEConfig.bandwidth must be one of {BANDWIDTHS}, got {self.bandwidth!r}")
        if self.select not in SELECTS:
            raise ValueError(f"KDEConfig.select must be one of {SELECTS}, got {self.select!r}")
        if self.select == "posterior" and self.bandwidth != "shared":
            raise ValueError(f"KDEConfig.select='posterior' chooses one shared factor; it needs bandwidth='shared', "
                             f"got bandwidth={self.bandwidth!r}")
        if isinstance(self.factor, str):
            if self.factor != "auto":
                raise ValueError(f"KDEConfig.factor must be a positive number or 'auto', got {self.factor!r}")
        elif not (finite_number(self.factor) or 0) > 0:
            raise ValueError(f"KDEConfig.factor must be positive and finite, got {self.factor!r}")
        grid = self.factor_grid
        if not (isinstance(grid, (tuple, list)) and grid and all((finite_number(f) or 0) > 0 for f in grid)):
            raise ValueError(f"KDEConfig.factor_grid must hold positive factors, got {self.factor_grid!r}")
        for name in ("n_calibrate", "calibrate_grasps", "k", "k_max", "max_samples", "select_samples", "n_select"):
            whole_at_least(getattr(self, name), 1, f"KDEConfig.{name}")
        check_calibrate_grasps(self.calibrate_grasps, 1, "KDEConfig.calibrate_grasps")
        seed, eps = whole_number(self.seed), finite_number(self.eps)
        if seed is None or seed < 0:
            raise ValueError(f"KDEConfig.seed must be an int >= 0, got {self.seed!r}")
        if not (finite_number(self.cutoff) or 0) > 0:
            raise ValueError(f"KDEConfig.cutoff must be a finite number > 0, got {self.cutoff!r}")
        if eps is None or eps < 0:
            raise ValueError(f"KDEConfig.eps must be a finite number >= 0, got {self.eps!r}")


def scott_bandwidth(n: int, d: int) -> float:
    """Scott's rule ``n^(-1/(d+4))`` for standardised data."""
    return float(n) ** (-1.0 / (d + 4))


@dataclass(eq=False)
class KDELikelihood:
    """Gaussian KDE per class on standardised grasp vectors (see module docs)."""

    config: KDEConfig = field(default_factory=KDEConfig)
    bandwidth: np.ndarray | None = None  #: ``(K,)`` each class's h in standardised units (after fit; equal if shared)
    factor: np.ndarray | None = None  #: ``(K,)`` each class's multiple of Scott's rule
    #: factor -> the selection criterion: mean validation log-likelihood (all classes; ``select="likelihood"``) or
    #: held-out validation NLL of the calibrated one-shot posterior (``select="posterior"``)
    selection: dict = field(default_factory=dict)
    temperature: float = 1.0  #: calibration temperature T (fitted on validation vectors; 1: none)
    correction: ScoreCorrection | PowerCorrection | None = None  #: learned correction applied before T (None: none)

    def __post_init__(self):
        self.scaler: Standardizer | None = None
        self.data: list[np.ndarray] = []
        self.trees: list[cKDTree] = []
        self.pooled: KDTree | None = None  # "pooled": one compiled tree over all classes' vectors
        self.pooled_labels: np.ndarray | None = None  # (N,) class of each pooled vector, in tree order
        self.tree_k: np.ndarray = np.zeros(0, int)  # "tree": (K,) neighbours each class's sum takes
        self.n_classes = 0
        self._log_norms: np.ndarray | None = None  # (K,) class normalisers, filled on first use

    @property
    def classes_(self) -> np.ndarray:
        return np.arange(self.n_classes)

    @property
    def n_features(self) -> int:
        return int(self.scaler.mean.shape[0])

    # --------------------------------------------------------------------------------- fit
    def fit(self, X, y, X_val=None, y_val=None, *, n_classes: int | None = None) -> KDELikelihood:
        """Store the training vectors ``X (N, d)`` of each class ``y (N,)``; choose the bandwidth.

        With ``config.factor == "auto"`` a validation set is needed; without ``X_val`` a random
        10 % of each class of ``X`` (of one with at least 2 vectors) is held out of the KDE that chooses, and
        scored by it (a vector scored by a KDE that holds it favours the narrowest bandwidth); the fitted KDE
        keeps all of ``X``. With
        ``config.calibrate`` and ``X_val`` given, :attr:`temperature` is fitted on at most
        ``n_calibrate`` validation vectors per class (:func:`~.calibration.fit_temperature` of the
        log-likelihoods evaluated by ``config.method``); without ``X_val`` it stays 1.
        """
        cfg = self.config
        X, y = _check_xy(X, y)
        check_validation_pair(X_val, y_val)
        rng = np.random.default_rng(cfg.seed)
        self.n_classes = class_count(n_classes, y, y_val)
        self.scaler = Standardizer.fit(X)
        Z = self.scaler(X)
        self.data = [Z[y == c] for c in range(self.n_classes)]
        self.trees, self.pooled, self.pooled_labels = [], None, None  # a refit builds its own index
        empty = [c for c, z in enumerate(self.data) if len(z) == 0]
        if empty:
            raise ValueError(f"KDELikelihood.fit: no training vectors for classes {empty}")
        if cfg.method == "subsample":
            self.data = self._capped(self.data, rng)
        scott = self._scott([len(z) for z in self.data], X.shape[1])
        given_val = X_val is not None
        if cfg.factor == "auto":
            full = None
            if X_val is None:
                held = np.zeros(len(X), dtype=bool)
                for c in range(self.n_classes):
                    rows = np.flatnonzero(y == c)
                    if len(rows) >= 2:
                        held[rng.choice(rows, max(1, len(rows) // 10), replace=False)] = True
                if not held.any():
                    raise ValueError("KDELikelihood.fit: choosing the bandwidth needs X_val, or a class of X with at "
                                     "least 2 vectors to hold one out")
                X_val, y_val = X[held], y[held]
                kept = [Z[(y == c) & ~held] for c in range(self.n_classes)]
                if cfg.method == "subsample":  # the choosing KDE as capped as the fitted one
                    kept = self._capped(kept, rng)
                full, self.data = self.data, kept
                sel_scott = self._scott([len(z) for z in self.data], X.shape[1])
            else:
                X_val, y_val = _check_xy(X_val, y_val, X.shape[1], "X_val")
                sel_scott = scott
            try:
                if cfg.select == "posterior":
                    self.factor = self._select_posterior(X_val, np.asarray(y_val), sel_scott)
                else:
                    self.factor = self._select(self.scaler(X_val), np.asarray(y_val), rng)
            finally:
                if full is not None:  # the KDE keeps every vector (a failed choice too)
                    self.data = full
                    self.trees, self.pooled, self.pooled_labels = [], None, None
        else:
            self.factor = np.full(self.n_classes, float(cfg.factor))
        self._set_bandwidth(self.factor * scott)
        self.temperature, self.correction = 1.0, None
        if cfg.calibrate and given_val:
            Xv, yv = _check_xy(X_val, y_val, X.shape[1], "X_val")
            keep = calibration_rows(yv, self.n_classes, cfg.n_calibrate, rng)
            if len(keep):
                S, Y = self.log_likelihood(Xv[keep]), yv[keep]
                use = cfg.correct
                counts = np.bincount(Y, minlength=self.n_classes)
                if use and counts.min() < (2 if use == "auto" else 1):
                    warnings.warn(f"KDELikelihood.fit: validation vectors per class {counts.tolist()} (at most "
                                  f"n_calibrate={cfg.n_calibrate} each); the learned "
                                  "correction needs every class (twice for 'auto') and is skipped (temperature only)",
                                  RuntimeWarning, stacklevel=2)
                    use = False
                if use == "auto":  # its own random stream: the fit below is the same whichever way this goes
                    use = select_calibration(S, Y, cfg.correct_candidates, calibrate_grasps=cfg.calibrate_grasps,
                                             rng=np.random.default_rng([cfg.seed, 1]))[0]
                if use:
                    self.correction = CORRECTIONS["matrix" if use is True else use](S, Y)
                    S = self.correction(S)
                if cfg.calibrate_grasps > 1:
                    S, Y = sequence_scores(S, Y, cfg.calibrate_grasps, rng)
                self.temperature = fit_temperature(S, Y)
        return self

    def _capped(self, data: list[np.ndarray], rng: np.random.Generator) -> list[np.ndarray]:
        """Each class's vectors, a random ``max_samples`` of them where it has more (``method="subsample"``)."""
        m = self.config.max_samples
        return [z[rng.choice(len(z), m, replace=False)] if len(z) > m else z for z in data]

    def with_method(self, method: str) -> KDELikelihood:
        """This fitted KDE evaluated by another method ("tree", "pooled" or "dense"); shares the training vectors."""
        if method not in ("tree", "pooled", "dense"):
            raise ValueError(f"with_method: method must be 'tree', 'pooled' or 'dense', got {method!r}")
        if self.scaler is None:
            raise RuntimeError("KDELikelihood is not fitted; call fit() first")
        other = KDELikelihood(replace(self.config, method=method), self.bandwidth, self.factor, dict(self.selection),
                              self.temperature, self.correction)
        other.scaler, other.data, other.n_classes = self.scaler, self.data, self.n_classes
        other._build_index()
        return other

    def _build_index(self) -> None:
        """The search trees of ``config.method`` over ``self.data``."""
        self.trees, self.pooled, self.pooled_labels = [], None, None
        self.tree_k = np.zeros(0, int)
        if self.config.method == "tree":
            self.trees = [_tree(z) for z in self.data]
            self.tree_k = self._tree_neighbours()
        elif self.config.method == "pooled":
            self.pooled = KDTree(np.concatenate(self.data), leafsize=_LEAFSIZE)
            self.pooled_labels = np.repeat(np.arange(self.n_classes), [len(z) for z in self.data])[self.pooled.indices]

    def _set_bandwidth(self, bandwidth: np.ndarray) -> None:
        """Set ``(K,)`` bandwidths; the search index is built once (it does not depend on them), the "tree"
        neighbour counts and the normalisers follow them."""
        self.bandwidth = np.asarray(bandwidth, float)
        self._log_norms = None
        if self.trees:
            self.tree_k = self._tree_neighbours()
        elif self.pooled is None:
            self._build_index()

    def _tree_neighbours(self, probes: int = 256) -> np.ndarray:
        """``(K,)`` neighbours the "tree" sum takes per class: ``config.k``, raised to the 90th percentile of the
        number of the class's training vectors within ``cutoff * h_c`` of ``probes`` of its own vectors (evenly
        spaced, so deterministic) but not above ``max(k, k_max)``, and at most the class size."""
        cfg = self.config
        out = np.empty(self.n_classes, int)
        for c, (z, tree) in enumerate(zip(self.data, self.trees)):
            probe = z[np.linspace(0, len(z) - 1, min(probes, len(z))).astype(int)]
            counts = tree.query_ball_point(probe, cfg.cutoff * float(self.bandwidth[c]), return_length=True)
            out[c] = min(max(cfg.k, min(int(np.ceil(np.quantile(counts, 0.9))), cfg.k_max)), tree.n)
        return out

    def _scott(self, sizes: list[int], d: int) -> np.ndarray:
        """``(K,)`` Scott's rule for classes of ``sizes`` vectors: at their mean size for all ("shared"), or each at
        its own ("per-class")."""
        if self.config.bandwidth == "shared":
            return np.full(len(sizes), scott_bandwidth(int(np.mean(sizes)), d))
        return np.array([scott_bandwidth(n, d) for n in sizes])

    def _select(self, Zv: np.ndarray, yv: np.ndarray, rng) -> np.ndarray:
        """``(K,)`` factors of the grid with the highest mean true-class validation log-likelihood (dense): one
        for all classes ("shared"), or each class's own ("per-class"; a class without validation vectors gets
        the shared choice)."""
        cfg = self.config
        m = cfg.select_samples
        sub = [z[rng.choice(len(z), m, replace=False)] if len(z) > m else z for z in self.data]
        # the factor multiplies Scott's rule, which carries the N-dependence: on a subsample of m
        # vectors it is evaluated at factor * m^(-1/(d+4)) and then transfers to the full N
        d = Zv.shape[1]
        scott = self._scott([len(z) for z in sub], d)
        grid = tuple(cfg.factor_grid)
        sums, counts = np.zeros((self.n_classes, len(grid))), np.zeros(self.n_classes)
        for c in range(self.n_classes):
            zc = Zv[yv == c]
            if len(zc) > cfg.n_select:
                zc = zc[rng.choice(len(zc), cfg.n_select, replace=False)]
            if len(zc) == 0:
                continue
            d2 = _sqdist(zc, sub[c])
            for j, f in enumerate(grid):
                h = f * float(scott[c])
                ll = logsumexp(-0.5 * d2 / h**2, axis=1) - np.log(len(sub[c])) - 0.5 * d * np.log(2 * np.pi * h * h)
                sums[c, j] = float(ll.sum())
            counts[c] = len(zc)
        total = sums.sum(0) / max(counts.sum(), 1)
        self.selection = dict(zip(grid, total.tolist()))
        shared = grid[int(np.argmax(total))]
        if cfg.bandwidth == "shared":
            return np.full(self.n_classes, float(shared))
        return np.array([grid[int(np.argmax(sums[c]))] if counts[c] else shared for c in range(self.n_classes)], float)

    def _select_posterior(self, X_val: np.ndarray, y_val: np.ndarray, scott: np.ndarray) -> np.ndarray:
        """``(K,)`` the shared factor of the grid whose calibrated one-shot posterior has the lowest held-out
        validation NLL (``select="posterior"``). Up to ``n_calibrate`` validation vectors per class (its own random
        stream) are scored by the full KDE at each factor; :func:`~.calibration.select_calibration` halves them per
        class, fits the temperature alone and each correction then the temperature on one half and scores the other;
        the calibration that ``config.correct`` would keep gives the factor's NLL."""
        cfg = self.config
        rng = np.random.default_rng([cfg.seed, 2])
        keep = calibration_rows(y_val, self.n_classes, cfg.n_calibrate, rng)
        counts = np.bincount(y_val[keep], minlength=self.n_classes)
        if counts.min() < 2:
            raise ValueError(f"KDEConfig.select='posterior' needs >= 2 validation vectors of every class, got "
                             f"{counts.tolist()} (at most n_calibrate={cfg.n_calibrate} per class are used)")
        Xs, Ys = X_val[keep], y_val[keep]
        fixed = {False: None, True: "matrix"}.get(cfg.correct, cfg.correct)
        cands = cfg.correct_candidates if fixed == "auto" else tuple(filter(None, [fixed]))
        nll = {}
        for f in cfg.factor_grid:
            self._set_bandwidth(np.full(self.n_classes, float(f)) * scott)
            choice, held = select_calibration(self.log_likelihood(Xs), Ys, cands, calibrate_grasps=cfg.calibrate_grasps,
                                              rng=np.random.default_rng([cfg.seed, 1]))
            nll[float(f)] = held[choice if fixed == "auto" else fixed]
        self.selection = nll
        return np.full(self.n_classes, min(nll, key=nll.get))

    # ---------------------------------------------------------------------------- evaluate
    def _norm(self, c: int) -> float:
        d = self.n_features
        h = float(self.bandwidth[c])
        return -np.log(len(self.data[c])) - 0.5 * d * np.log(2 * np.pi * h * h) - float(np.log(self.scaler.std).sum())

    def log_likelihood(self, q, method: str | None = None) -> np.ndarray:
        """``q (B, d)`` or ``(d,)`` -> ``(B, K)`` log densities ``log p(q | class)``."""
        if self.scaler is None:
            raise RuntimeError("KDELikelihood is not fitted; call fit() first")
        Q = np.asarray(q, dtype=np.float64)
        if Q.ndim == 1:
            Q = Q[None]
        Z = (Q - self.scaler.mean) / self.scaler.std if Q.ndim == 2 and Q.shape[1] == self.n_features else None
        if Z is None or not np.isfinite(Z).all():
            _check_xy(Q, d=self.n_features, what="q")  # raises, naming the bad shape or row
        method = method or self.config.method
        if method not in _METHODS:  # a typo was the dense sum, without a word
            raise ValueError(f"KDELikelihood.log_likelihood: method must be one of {_METHODS}, got {method!r}")
        if (method == "tree" and not self.trees) or (method == "pooled" and self.pooled is None):
            method = "dense"
        inv = 0.5 / self.bandwidth**2
        if method == "pooled":
            return self._pooled_logsum(Z, inv)
        out = np.empty((len(Z), self.n_classes))
        for c in range(self.n_classes):
            if method == "tree":
                out[:, c] = self._tree_logsum(c, Z, float(inv[c]))
            else:
                out[:, c] = _dense_logsum(Z, self.data[c], float(inv[c]))
        return out + self._norms()

    def calibrate_scores(self, log_lik: np.ndarray) -> np.ndarray:
        """Raw log-likelihoods ``(B, K)`` -> the calibrated scores Bayes updates use: the learned correction (if
        fitted), then divided by the temperature."""
        S = self.correction(log_lik) if self.correction is not None else log_lik
        return S / self.temperature if self.temperature != 1.0 else S

    @property
    def calibrated(self) -> bool:
        """Whether :meth:`calibrate_scores` changes anything."""
        return self.correction is not None or self.temperature != 1.0

    def _norms(self) -> np.ndarray:
        """``(K,)`` log normalisers of the class densities (computed once per fit / load)."""
        if self._log_norms is None:
            self._log_norms = np.array([self._norm(c) for c in range(self.n_classes)])
        return self._log_norms

    def _tree_logsum(self, c: int, Z: np.ndarray, inv: float, chunk: int = 1 << 21) -> np.ndarray:
        k = int(self.tree_k[c])
        step = max(1, chunk // k)  # rows per query: at most ``chunk`` neighbour distances in memory (k can be 4096)
        if len(Z) > step:
            return np.concatenate([self._tree_logsum(c, Z[i:i + step], inv, chunk) for i in range(0, len(Z), step)])
        cfg = self.config
        tree = self.trees[c]
        dist, _ = tree.query(Z, k=k, eps=cfg.eps, distance_upper_bound=cfg.cutoff * float(self.bandwidth[c]))
        dist = dist.reshape(len(Z), k)
        found = np.isfinite(dist[:, 0])
        res = np.empty(len(Z))
        if found.any():
            x = -inv * dist[found] ** 2  # missing neighbours are at distance inf -> x = -inf
            m = x[:, 0]  # neighbours come sorted by distance: the first is the largest term
            res[found] = m + np.log(np.exp(x - m[:, None]).sum(axis=1))
        if not found.all():
            d1, _ = tree.query(Z[~found], k=1, eps=cfg.eps)
            res[~found] = -inv * d1**2
        return res

    def _pooled_logsum(self, Z: np.ndarray, inv: np.ndarray) -> np.ndarray:
        cfg = self.config
        k = min(cfg.k, self.pooled.n)
        return pooled_log_density(*self.pooled.arrays(), self.pooled_labels, Z, k, float(cfg.eps), self._norms(), inv,
                                  cfg.cutoff * self.bandwidth)

    # ---------------------------------------------------------------------------- storage
    def state(self) -> dict[str, np.ndarray]:
        """Arrays that reproduce this KDE (for :func:`haptic_env.cache.save_npz_atomic`)."""
        out = {"kde_mean": self.scaler.mean, "kde_std": self.scaler.std,
               "kde_bandwidth": np.asarray(self.bandwidth, float), "kde_factor": np.asarray(self.factor, float),
               "kde_temperature": np.array(self.temperature)}
        if isinstance(self.correction, PowerCorrection):
            out.update(kde_power_p=np.array(self.correction.p), kde_power_cap=np.array(self.correction.cap))
        elif self.correction is not None:
            out.update(kde_corr_W=self.correction.W, kde_corr_b=self.correction.b,
                       kde_corr_floor=np.array(self.correction.floor))
        # the vectors as fitted (float64), so that a loaded KDE scores exactly as this one: with float32 copies the
        # approximate searches built other trees and found other neighbours
        for c, z in enumerate(self.data):
            out[f"kde_data_{c}"] = z
        return out

    @classmethod
    def from_state(cls, config: KDEConfig, arrays: dict[str, np.ndarray]) -> KDELikelihood:
        kde = cls(config)
        kde.scaler = Standardizer(arrays["kde_mean"], arrays["kde_std"])
        kde.temperature = float(arrays.get("kde_temperature", 1.0))
        if "kde_corr_W" in arrays:
            kde.correction = ScoreCorrection(np.asarray(arrays["kde_corr_W"], dtype=np.float64),
                                             np.asarray(arrays["kde_corr_b"], dtype=np.float64),
                                             float(arrays["kde_corr_floor"]))
        elif "kde_power_p" in arrays:
            kde.correction = PowerCorrection(float(arrays["kde_power_p"]), float(arrays["kde_power_cap"]))
        c = 0
        while f"kde_data_{c}" in arrays:
            kde.data.append(np.asarray(arrays[f"kde_data_{c}"], dtype=np.float64))  # stored float64: no copy
            c += 1
        kde.n_classes = c
        # (K,) per class; a cache written before per-class bandwidths holds one shared value
        kde.bandwidth = np.broadcast_to(np.asarray(arrays["kde_bandwidth"], float), (c,)).copy()
        kde.factor = np.broadcast_to(np.asarray(arrays["kde_factor"], float), (c,)).copy()
        kde._build_index()
        return kde


_LEAFSIZE = 32


def _tree(z: np.ndarray) -> cKDTree:
    """A cKDTree over ``z`` whose points are stored in tree order (``"tree"``: one per object).

    cKDTree keeps its input order and reaches the points of a leaf through an index array, so a query
    touches scattered rows; rebuilding on the points sorted by the first tree's order (the sliding-midpoint
    splits do not depend on the input order) makes every leaf a contiguous block, with fewer cache misses
    per query. The KDE sums need distances only, so the order is not kept."""
    order = cKDTree(z, leafsize=_LEAFSIZE, balanced_tree=False, compact_nodes=False).indices
    return cKDTree(z[order], leafsize=_LEAFSIZE, balanced_tree=False, compact_nodes=False)


def _sqdist(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``(a, d), (b, d) -> (a, b)`` squared Euclidean distances (clipped at 0)."""
    d2 = (A * A).sum(1)[:, None] + (B * B).sum(1)[None] - 2.0 * A @ B.T
    return np.maximum(d2, 0.0)


def _dense_logsum(Z: np.ndarray, data: np.ndarray, inv: float, chunk: int = 1 << 22) -> np.ndarray:
    """``logsumexp_i(-inv * |z - x_i|^2)`` over all ``data`` for each row of ``Z`` (exact, chunked)."""
    out = np.full(len(Z), -np.inf)
    step = max(1, chunk // max(len(Z), 1))
    for lo in range(0, len(data), step):
        part = logsumexp(-inv * _sqdist(Z, data[lo : lo + step]), axis=1)
        out = np.logaddexp(out, part)
    return out
