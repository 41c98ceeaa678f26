"""``build_recognizer``: train (or load) the MLP + KDE models of an object set; make updaters.

A :class:`Recognizer` holds one :class:`ModelBank` entry (classifier + KDE) per finger count ``z``
it was built for (``n_fingers`` plus ``z_values`` for z-finger scoring and incomplete grasps). The
entries are routed by feature dimension, which is unique per ``z`` for a given ``normals``.

Training data come from :func:`haptic_env.dataset.build_dataset`; trained models are cached under
``cache_dir("recognizers")`` keyed by the object meshes, ``z``, ``normals`` and the
:class:`RecognizerConfig` (atomic writes; an unreadable cache file is rebuilt with a warning).
"""

from __future__ import annotations

import dataclasses
import json
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from haptic_env.dataset import DatasetConfig
from haptic_env.cache import CacheError, atomic_write, cache_dir, config_key, load_npz, save_npz_atomic
from haptic_env.grasp_features import feature_dim
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig
from haptic_env.recognizers.updaters import UPDATERS, make_updater
from haptic_env.recognizers.zfinger import ZFingerUpdater, subset_vectors

__all__ = ["RecognizerConfig", "ModelBank", "Recognizer", "build_recognizer", "RECOGNIZER_VERSION"]

RECOGNIZER_VERSION = 1


@dataclass(frozen=True)
class RecognizerConfig:
    """Training data and models of a :class:`Recognizer`.

    ``grasps`` is the :class:`~haptic_env.dataset.DatasetConfig` of the training grasps (count,
    noise, scale, source, seed); its ``n_fingers`` and ``normals`` are set per model by
    :func:`build_recognizer` (and, for ``source="geometric"``, ``hand_fingers`` defaults to the
    recogniser's ``n_fingers``, so z-finger models learn z-subsets of that hand's grasps).

    The default (20,000 grasps per object; MLP 3 x 256 trained on <= 60,000 of them for <= 15
    epochs; tree KDE on all training grasps with an auto-selected bandwidth) builds the default set
    in about a minute on 2 idle cores; the paper's protocol is
    ``grasps=DatasetConfig(grasps_per_object=200_000)`` (and optionally ``MLPConfig(depth=7, width=500)``).
    """

    grasps: DatasetConfig = field(default_factory=DatasetConfig)
    mlp: MLPConfig = field(default_factory=lambda: MLPConfig(max_epochs=15, patience=3, max_train=60_000))
    kde: KDEConfig = field(default_factory=KDEConfig)

    def dataset_config(self, n_fingers: int, normals: bool, hand_fingers: int | None = None) -> DatasetConfig:
        """The training-grasp config of the ``n_fingers`` model."""
        g = self.grasps
        hand = (g.hand_fingers or hand_fingers) if g.source == "geometric" else None
        return dataclasses.replace(g, n_fingers=n_fingers, normals=normals, hand_fingers=hand)


@dataclass(eq=False)
class ModelBank:
    """Classifier + likelihood per finger count, dispatched by the feature dimension of ``Q``."""

    normals: bool
    n_classes: int
    entries: dict[int, tuple[int, object, KDELikelihood]] = field(default_factory=dict)  # d -> (z, clf, kde)

    def add(self, z: int, classifier, kde: KDELikelihood) -> None:
        self.entries[feature_dim(z, self.normals)] = (z, classifier, kde)

    @property
    def finger_counts(self) -> tuple[int, ...]:
        return tuple(sorted(z for z, _, _ in self.entries.values()))

    def _get(self, Q: np.ndarray):
        if not (isinstance(Q, np.ndarray) and Q.ndim == 2 and Q.dtype == np.float64):
            Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        try:
            return Q, self.entries[Q.shape[1]]
        except KeyError:
            raise ValueError(
                f"no model for {Q.shape[1]}-dimensional grasp vectors (normals={self.normals}); this recogniser "
                f"has finger counts {self.finger_counts}: pass z_values to build_recognizer for others"
            ) from None

    def model(self, z: int):
        """``(classifier, kde)`` of the ``z``-finger model."""
        return self.entries[feature_dim(z, self.normals)][1:]

    def predict_proba(self, Q) -> np.ndarray:
        Q, (_, clf, _) = self._get(Q)
        return clf.predict_proba(Q)

    def log_likelihood(self, Q) -> np.ndarray:
        Q, (_, _, kde) = self._get(Q)
        return kde.log_likelihood(Q)


@dataclass(eq=False)
class Recognizer:
    """Trained models of one object set and the factory of belief updaters."""

    names: tuple[str, ...]
    n_fingers: int
    normals: bool
    config: RecognizerConfig
    models: ModelBank

    @property
    def n_classes(self) -> int:
        return len(self.names)

    def features(self, contacts, normals=None, *, touched=None, z: int | None = None, k: int | None = None,
                 rng: np.random.Generator | None = None) -> np.ndarray:
        """Grasp vectors ``(m, d)`` of one grasp ``contacts (n, 3)`` (see :func:`subset_vectors`)."""
        if self.normals and normals is None:
            raise ValueError("this recogniser was trained with normals; pass the contact normals")
        return subset_vectors(contacts, normals if self.normals else None, z, k=k, rng=rng, touched=touched,
                              normalize=self.config.grasps.normalize_scale)

    def grasp_scorer(self):
        """:class:`~haptic_env.recognizers.scorer.GraspScorer` of complete ``n_fingers`` grasps (Phi and the KDE
        log-likelihoods in one compiled call), or None if the KDE is not evaluated ``"pooled"`` or grasps are
        scale-normalised (then use :meth:`features` and ``updater.update``)."""
        if self.config.grasps.normalize_scale:
            return None
        if not hasattr(self, "_scorer"):
            from haptic_env.recognizers.scorer import GraspScorer

            kde = self.models.model(self.n_fingers)[1]
            self._scorer = GraspScorer(self.n_fingers, self.normals, kde) if getattr(kde, "pooled", None) else None
        return self._scorer

    def make_updater(self, kind: str = "bc-np", threshold: float = 0.85, z: int | None = None, *,
                     k: int | None = None, rng: np.random.Generator | None = None, **kw) -> ZFingerUpdater:
        """A belief updater over this recogniser's models.

        ``kind``: one of ``"bc-np" | "bc-ip" | "ic" | "ic-full"``. ``z``: score each grasp through its
        z-finger subsets (all, or ``k`` random ones drawn from ``rng``); ``None`` scores the touching
        contacts as one grasp with the model of their count. The returned updater has
        ``update(q)`` (grasp vectors) and ``update_grasp(contacts, normals, touched)`` (raw contacts).
        """
        if kind not in UPDATERS:
            raise ValueError(f"unknown updater kind {kind!r}; choose one of {UPDATERS}")
        if z is not None and z not in self.models.finger_counts:
            raise ValueError(f"no {z}-finger model; built finger counts: {self.models.finger_counts}")
        base = make_updater(kind, classifier=self.models, likelihood=self.models, threshold=threshold,
                            n_classes=self.n_classes, **kw)
        return ZFingerUpdater(base, z, k=k, rng=rng, normalize=self.config.grasps.normalize_scale)


def _objects_key(objects) -> list:
    if hasattr(objects, "identity"):
        return list(objects.identity)
    return [(o.name, np.asarray(o.mesh.vertices, dtype=np.float64), np.asarray(o.mesh.faces)) for o in objects]


def _train_one(ds, z: int, cfg: RecognizerConfig, progress: bool):
    k = len(ds.names)
    clf = MLPClassifier(dataclasses.replace(cfg.mlp, progress=progress and cfg.mlp.progress))
    clf.fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=k)
    kde = KDELikelihood(cfg.kde).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=k)
    return clf, kde


def build_recognizer(objects, n_fingers: int, normals: bool = True, *, z_values=(), config: RecognizerConfig | None = None,
                     cache: bool = True, progress: bool = True, dataset_fn=None) -> Recognizer:
    """Train or load the models for ``objects`` (an ``ObjectSet``) and return a :class:`Recognizer`.

    Args:
        n_fingers: fingers of the hand (the main model).
        z_values: further finger counts to build models for (z-finger scoring, incomplete grasps).
        config: data and model settings (default :class:`RecognizerConfig`).
        cache: load/save trained models under ``cache_dir("recognizers")``.
        dataset_fn: ``(objects, DatasetConfig) -> GraspDataset`` (default
            :func:`haptic_env.dataset.build_dataset`; tests inject synthetic data here).
    """
    config = config or RecognizerConfig()
    if n_fingers < 2:
        raise ValueError(f"n_fingers must be >= 2, got {n_fingers}")
    zs = sorted({int(n_fingers), *map(int, z_values)})
    if zs[0] < 2 or zs[-1] > n_fingers:
        raise ValueError(f"z_values must lie in [2, n_fingers={n_fingers}], got {tuple(z_values)}")
    if dataset_fn is None:
        from haptic_env.dataset import build_dataset

        def dataset_fn(objs, dcfg):
            return build_dataset(objs, dcfg, cache=cache, progress=progress)

    names = tuple(o.name for o in objects)
    bank = ModelBank(normals=bool(normals), n_classes=len(names))
    okey = config_key(_objects_key(objects)) if cache else ""
    for z in zs:
        key = config_key("recognizer", RECOGNIZER_VERSION, okey, z, bool(normals), config)
        root = cache_dir("recognizers") if cache else None
        loaded = None
        if cache:
            loaded = _load(root, key, config)
        if loaded is None:
            t0 = time.perf_counter()
            ds = dataset_fn(objects, config.dataset_config(z, bool(normals), hand_fingers=int(n_fingers)))
            if tuple(ds.names) != names:
                raise ValueError(f"dataset names {tuple(ds.names)} differ from the object set's {names}")
            clf, kde = _train_one(ds, z, config, progress)
            if cache:
                _save(root, key, clf, kde, {"names": list(names), "z": z, "normals": bool(normals),
                                            "train_seconds": time.perf_counter() - t0})
        else:
            clf, kde = loaded
        bank.add(z, clf, kde)
    return Recognizer(names, int(n_fingers), bool(normals), config, bank)


def _save(root, key, clf: MLPClassifier, kde: KDELikelihood, meta: dict) -> None:
    clf.save(root / f"{key}_mlp.pt")
    save_npz_atomic(root / f"{key}_kde.npz", **kde.state())
    with atomic_write(root / f"{key}.json", "w") as fh:
        json.dump(meta, fh)


def _load(root, key, config: RecognizerConfig):
    files = [root / f"{key}_mlp.pt", root / f"{key}_kde.npz", root / f"{key}.json"]
    if not all(f.exists() for f in files):
        return None
    try:
        clf = MLPClassifier.load(files[0])
        kde = KDELikelihood.from_state(config.kde, load_npz(files[1], ("kde_mean", "kde_std", "kde_bandwidth")))
    except CacheError as exc:
        warnings.warn(f"rebuilding recogniser models: {exc}", stacklevel=3)
        return None
    return clf, kde
