"""``build_recognizer``: train (or load) the MLP + KDE models of an object set; make updaters.

A :class:`Recognizer` holds one :class:`ModelBank` entry (classifier + KDE) per finger count ``z``
it was built for (``n_fingers`` plus ``z_values`` for z-finger scoring and incomplete grasps). The
entries are routed by feature dimension, which is unique per ``z`` for a given ``normals``.

Training data come from :func:`haptic_env.dataset.build_dataset`; trained models are cached under
``cache_dir("recognizers")``, one file per model, keyed by the object meshes, ``z``, ``normals``, the
training grasps and the model's config (atomic writes; an unreadable cache file is rebuilt with a
warning). Only the models an updater needs have to be built (:func:`models_for`: BC-NP needs the
KDE only). Every model carries a calibration temperature fitted on the validation grasps (the KDE also a learned
correction of its scores where it is fitted, ``KDEConfig.correct``); the :class:`ModelBank` applies them unless asked
for the raw scores.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import softmax

from haptic_env.dataset import DatasetConfig
from haptic_env.cache import (KEY_ONLY_WHEN_SET, CacheError, atomic_write, cache_dir, config_key, load_npz,
                               save_npz_atomic)
from haptic_env.grasp_features import feature_dim
from haptic_env.numbers import checked_flag, whole_at_least
from haptic_env.recognizers.boosted import BoostedConfig, BoostedLikelihood, check_likelihood
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood
from haptic_env.recognizers.mlp_config import MLPConfig
from haptic_env.recognizers.touch import TouchModel
from haptic_env.recognizers.updaters import DEFAULT_THRESHOLD, DEFAULT_UPDATER, UPDATERS, make_updater
from haptic_env.recognizers.zfinger import ZFingerUpdater, subset_vectors

__all__ = ["RecognizerConfig", "ModelBank", "Recognizer", "build_recognizer", "models_for", "MODELS", "RECOGNIZER_VERSION"]

RECOGNIZER_VERSION = 4  # 2: calibration temperatures; one cache file per model; 3: the KDE's learned correction;
#                         4: the KDE's training vectors stored in float64, as fitted (float32 copies scored differently)


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

    ``likelihood`` picks what the beliefs' likelihood slot (the model ``"kde"`` of :data:`MODELS`) holds: the KDE
    (``"kde"``, the paper's method and the default) or gradient boosting (``"hgb"``,
    :class:`~haptic_env.recognizers.boosted.BoostedLikelihood` with ``boosted``; opt-in, for the analyses'
    ``--likelihood hgb`` and the envs' ``HapticRecogConfig.likelihood``).
    """

    grasps: DatasetConfig = field(default_factory=DatasetConfig)
    mlp: MLPConfig = field(default_factory=lambda: MLPConfig(max_epochs=15, patience=3, max_train=60_000))
    kde: KDEConfig = field(default_factory=KDEConfig)
    likelihood: str = field(default="kde", metadata={KEY_ONLY_WHEN_SET: True})
    boosted: BoostedConfig = field(default=BoostedConfig(), metadata={KEY_ONLY_WHEN_SET: True})

    def __post_init__(self):
        check_likelihood(self.likelihood)
        for name, cls in (("grasps", DatasetConfig), ("mlp", MLPConfig), ("kde", KDEConfig), ("boosted", BoostedConfig)):
            if not isinstance(getattr(self, name), cls):  # a wrong type failed later, deep in training
                raise ValueError(f"{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}")

    def model_config(self, model: str):
        """The config that keys a cached ``model`` (:data:`MODELS`): the MLP's, or the likelihood slot's."""
        if model == "mlp":
            return self.mlp
        if self.likelihood == "kde":
            return self.kde
        from importlib.metadata import version  # a pickled model is read back by the scikit-learn that wrote it

        return "hgb", self.boosted, version("scikit-learn")

    def dataset_config(self, n_fingers: int, normals: bool, hand_fingers: int | None = None) -> DatasetConfig:
        """The training-grasp config of the ``n_fingers`` model."""
        g = self.grasps
        hand = (g.hand_fingers or hand_fingers) if g.source in ("geometric", "hand") else None
        return dataclasses.replace(g, n_fingers=n_fingers, normals=normals, hand_fingers=hand)


@dataclass(eq=False)
class ModelBank:
    """Classifier + likelihood per finger count, dispatched by the feature dimension of ``Q``.

    With ``calibrated`` (the default) the scores are calibrated as each model was fitted
    (:mod:`~haptic_env.recognizers.calibration`): ``log_likelihood`` returns the KDE's learned correction of
    ``log p(q | c)`` (where one was fitted, ``KDEConfig.correct``), divided by ``T_kde``
    (:meth:`KDELikelihood.calibrate_scores`), and ``predict_proba`` returns ``softmax(log p_clf / T_clf)``.
    :meth:`with_calibration` gives the raw view (the paper's method).
    A model that was not built (``models=`` of :func:`build_recognizer`) is ``None``.
    """

    normals: bool
    n_classes: int
    entries: dict[int, tuple[int, object, KDELikelihood]] = field(default_factory=dict)  # d -> (z, clf, kde)
    calibrated: bool = True
    #: the grasp vectors carry the contacts' heights (``DatasetConfig.heights``)
    heights: bool = False
    #: each normal's angles in the grasp vectors (``DatasetConfig.normal_axis``; "frame" has three per normal)
    normal_axis: str = "t2"

    def add(self, z: int, classifier, kde: KDELikelihood | None) -> None:
        self.entries[feature_dim(z, self.normals, heights=self.heights, normal_axis=self.normal_axis)] = (z, classifier, kde)

    def with_calibration(self, calibrated: bool) -> ModelBank:
        """The same models (shared, not copied), scored with or without the calibration temperatures."""
        return self if bool(calibrated) == self.calibrated else dataclasses.replace(self, calibrated=bool(calibrated))

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
        return self.entries[feature_dim(z, self.normals, heights=self.heights, normal_axis=self.normal_axis)][1:]

    def temperature(self, z: int) -> dict[str, float]:
        """The calibration temperatures of the ``z``-finger models: ``{"kde": T, "classifier": T}`` (1: none)."""
        clf, kde = self.model(z)
        return {"kde": float(getattr(kde, "temperature", 1.0)), "classifier": float(getattr(clf, "temperature", 1.0))}

    def predict_proba(self, Q) -> np.ndarray:
        Q, (z, clf, _) = self._get(Q)
        if clf is None:
            raise ValueError(f"the {z}-finger classifier was not built (build_recognizer(models=...) without 'mlp'); "
                             "IC and BC-IP need it")
        T = float(getattr(clf, "temperature", 1.0)) if self.calibrated else 1.0
        if T == 1.0:
            return clf.predict_proba(Q)
        L = clf.predict_log_proba(Q) if hasattr(clf, "predict_log_proba") else np.log(np.maximum(clf.predict_proba(Q), 1e-300))
        return softmax(L / T, axis=1)

    def log_likelihood(self, Q) -> np.ndarray:
        Q, (z, _, kde) = self._get(Q)
        if kde is None:
            raise ValueError(f"the {z}-finger KDE was not built (build_recognizer(models=...) without 'kde'); "
                             "BC-NP and BC-IP need it")
        ll = kde.log_likelihood(Q)
        return kde.calibrate_scores(ll) if self.calibrated else ll


@dataclass(eq=False)
class Recognizer:
    """Trained models of one object set and the factory of belief updaters."""

    names: tuple[str, ...]
    n_fingers: int
    normals: bool
    config: RecognizerConfig
    models: ModelBank
    #: the hand's touch-pattern likelihood (:mod:`~haptic_env.recognizers.touch`; ``build_recognizer(touch=True)``)
    touch: TouchModel | None = None

    @property
    def n_classes(self) -> int:
        return len(self.names)

    def features(self, contacts, normals=None, *, touched=None, z: int | None = None, k: int | None = None,
                 rng: np.random.Generator | None = None) -> np.ndarray:
        """Grasp vectors ``(m, d)`` of one grasp ``contacts (n, 3)`` (see :func:`subset_vectors`; with
        :attr:`heights`, the contacts in the support frame)."""
        if self.normals and normals is None:
            raise ValueError("this recogniser was trained with normals; pass the contact normals")
        return subset_vectors(contacts, normals if self.normals else None, z, k=k, rng=rng, touched=touched,
                              normalize=self.config.grasps.normalize_scale, heights=self.heights,
                              normal_axis=self.normal_axis)

    @property
    def heights(self) -> bool:
        """Whether its grasp vectors carry the contacts' heights above the support (``DatasetConfig.heights``)."""
        return bool(self.config.grasps.heights)

    @property
    def normal_axis(self) -> str:
        """Each normal's second angle in its grasp vectors (``DatasetConfig.normal_axis``, ``phi(normal_axis=)``)."""
        return self.config.grasps.normal_axis

    def grasp_scorer(self, calibrated: bool = True):
        """:class:`~haptic_env.recognizers.scorer.GraspScorer` of complete ``n_fingers`` grasps (Phi and the KDE
        log-likelihoods in one compiled call, or Phi compiled and then gradient boosting's walk with
        ``likelihood="hgb"``; divided by the likelihood's temperature when ``calibrated``), or None if the KDE is not
        evaluated ``"pooled"`` or grasps are scale-normalised (then use :meth:`features` and ``updater.update``)."""
        if self.config.grasps.normalize_scale or self.n_fingers < 3:  # the compiled Phi kernels need a polyhedron
            return None
        scorers = self.__dict__.setdefault("_scorers", {})
        if calibrated not in scorers:
            from haptic_env.recognizers.scorer import GraspScorer

            kde = self.models.model(self.n_fingers)[1]
            ok = kde is not None and GraspScorer.handles(kde)
            post = kde.calibrate_scores if ok and calibrated and kde.calibrated else None
            scorers[calibrated] = (GraspScorer(self.n_fingers, self.normals, kde, post=post, heights=self.heights,
                                               normal_axis=self.normal_axis) if ok else None)
        return scorers[calibrated]

    def make_updater(self, kind: str = DEFAULT_UPDATER, threshold: float = DEFAULT_THRESHOLD, z: int | None = None, *,
                     k: int | None = None, rng: np.random.Generator | None = None, calibrated: bool = True,
                     **kw) -> ZFingerUpdater:
        """A belief updater over this recogniser's models.

        ``kind``: one of ``"bc-np" | "bc-ip" | "ic" | "ic-full"``. ``z``: score each grasp through its
        z-finger subsets (all, or ``k`` random ones drawn from ``rng``); ``None`` scores the touching
        contacts as one grasp with the model of their count. ``calibrated``: scores calibrated on validation
        grasps (the KDE's learned correction where fitted, and the temperatures; default); False: the paper's raw
        scores. The returned updater has ``update(q)`` (grasp vectors) and ``update_grasp(contacts, normals,
        touched)`` (raw contacts).
        """
        if kind not in UPDATERS:
            raise ValueError(f"unknown updater kind {kind!r}; choose one of {UPDATERS}")
        if z is not None and z not in self.models.finger_counts:
            raise ValueError(f"no {z}-finger model; built finger counts: {self.models.finger_counts}")
        missing = [m for m in models_for(kind) if any(e[1 if m == "mlp" else 2] is None for e in self.models.entries.values())]
        if missing:
            raise ValueError(f"updater {kind!r} needs the {missing} model(s), which this recogniser was built without "
                             f"(build_recognizer(models={models_for(kind)!r}))")
        models = self.models.with_calibration(calibrated)
        base = make_updater(kind, classifier=models, likelihood=models, threshold=threshold,
                            n_classes=self.n_classes, **kw)
        return ZFingerUpdater(base, z, k=k, rng=rng, normalize=self.config.grasps.normalize_scale, heights=self.heights,
                              normal_axis=self.normal_axis)


def _objects_key(objects) -> list:
    if hasattr(objects, "identity"):
        return list(objects.identity)
    return [(o.name, np.asarray(o.mesh.vertices, dtype=np.float64), np.asarray(o.mesh.faces)) for o in objects]


#: Models :func:`build_recognizer` can build: the classifier (IC, BC-IP's prior) and the KDE (BC-NP, BC-IP).
MODELS = ("mlp", "kde")


def models_for(updater: str) -> tuple[str, ...]:
    """The models an updater kind needs: ``"bc-np"`` the KDE only, ``"ic"``/``"ic-full"`` the MLP, ``"bc-ip"`` both."""
    if updater not in UPDATERS:
        raise ValueError(f"unknown updater kind {updater!r}; choose one of {UPDATERS}")
    return {"bc-np": ("kde",), "bc-ip": MODELS}.get(updater, ("mlp",))


def check_build_options(*, models: Any = MODELS, touch: Any = False, cache: Any = True,
                        progress: Any = True) -> tuple[str, ...]:
    """:func:`build_recognizer`'s options checked (a ValueError names the bad one); returns ``models`` as a tuple.
    The env's config checks its ``recognizer_kwargs`` with it at make."""
    for name, value in (("progress", progress), ("touch", touch), ("cache", cache)):
        checked_flag(value, name, "True or False")
    if isinstance(models, str):  # tuple("kde") would be its letters
        raise ValueError(f"models must be a sequence of model names from {MODELS} (e.g. ['kde']), got {models!r}")
    models = tuple(models)
    bad = [m for m in models if m not in MODELS]
    if bad or not models:
        raise ValueError(f"models must be a non-empty subset of {MODELS}, got {models!r}")
    return models


def build_recognizer(objects, n_fingers: int, normals: bool = True, *, z_values=(), config: RecognizerConfig | None = None,
                     models: tuple[str, ...] = MODELS, touch: bool = False, cache: bool = True, progress: bool = True,
                     dataset_fn=None) -> Recognizer:
    """Train or load the models for ``objects`` (an ``ObjectSet``) and return a :class:`Recognizer`.

    Args:
        n_fingers: fingers of the hand (the main model).
        z_values: further finger counts to build models for (z-finger scoring, incomplete grasps).
        config: data and model settings (default :class:`RecognizerConfig`).
        models: which of :data:`MODELS` to build (:func:`models_for` an updater); the others are None.
        touch: also estimate the hand's touch-pattern likelihood (:class:`~haptic_env.recognizers.touch.TouchModel`)
            from the same hand grasp pool as the training grasps (``config.grasps.source`` must be ``"hand"``).
        cache: load/save trained models under ``cache_dir("recognizers")``, one file per model (keyed by the
            objects, ``z``, ``normals``, the training grasps and that model's config).
        dataset_fn: ``(objects, DatasetConfig) -> GraspDataset`` (default
            :func:`haptic_env.dataset.build_dataset`; tests inject synthetic data here).
    """
    config = config or RecognizerConfig()
    whole_at_least(n_fingers, 2, "n_fingers")
    models = check_build_options(models=models, touch=touch, cache=cache, progress=progress)
    if touch and config.grasps.source != "hand":
        raise ValueError(f"touch=True needs hand-matched training grasps (config.grasps.source='hand'), got "
                         f"source={config.grasps.source!r}: only a hand's own grasps give its touch patterns")
    zs = sorted({int(n_fingers), *map(int, z_values)})
    if zs[0] < 2 or zs[-1] > n_fingers:
        raise ValueError(f"z_values must lie in [2, n_fingers={n_fingers}], got {tuple(z_values)}")
    if len(objects) < 2:
        raise ValueError(f"a recogniser needs at least 2 objects to tell apart, got {len(objects)}")
    if dataset_fn is None:
        from haptic_env.dataset import build_dataset

        def dataset_fn(objs, dcfg):
            return build_dataset(objs, dcfg, cache=cache, progress=progress)

    names = tuple(o.name for o in objects)
    bank = ModelBank(normals=bool(normals), n_classes=len(names), heights=bool(config.grasps.heights),
                     normal_axis=config.grasps.normal_axis)
    okey = config_key(_objects_key(objects)) if cache else ""
    root = cache_dir("recognizers") if cache else None
    for z in zs:
        dcfg = config.dataset_config(z, bool(normals), hand_fingers=int(n_fingers))
        key = config_key("recognizer", RECOGNIZER_VERSION, okey, z, bool(normals), dcfg.key_config(),
                         *filter(None, [dcfg.source_key()]))
        built = {m: _load(root, f"{key}-{config_key(config.model_config(m))}", m, config) if cache else None
                 for m in MODELS if m in models}
        if any(v is None for v in built.values()):
            t0 = time.perf_counter()
            ds = dataset_fn(objects, dcfg)
            if tuple(ds.names) != names:
                raise ValueError(f"dataset names {tuple(ds.names)} differ from the object set's {names}")
            for m in [m for m, v in built.items() if v is None]:
                built[m] = _train(m, ds, config, progress)
                if cache:
                    _save(root, f"{key}-{config_key(config.model_config(m))}", m, built[m],
                          {"names": list(names), "z": z, "normals": bool(normals), "model": m,
                           "likelihood": config.likelihood,
                           "train_seconds": time.perf_counter() - t0}, config)
        bank.add(z, built.get("mlp"), built.get("kde"))
    return Recognizer(names, int(n_fingers), bool(normals), config, bank,
                      touch=_touch_model(objects, config, int(n_fingers), progress) if touch else None)


def _touch_model(objects, config: RecognizerConfig, n_fingers: int, progress: bool) -> TouchModel:
    """The touch-pattern likelihood from the hand grasp pool of the training grasps (cached with them)."""
    from haptic_env.dataset import hand_pool

    return TouchModel.from_pool(hand_pool(objects, config.dataset_config(n_fingers, True, hand_fingers=n_fingers),
                                          progress))


def _train(model: str, ds, cfg: RecognizerConfig, progress: bool):
    k = len(ds.names)
    if model == "mlp":
        from haptic_env.recognizers.mlp import MLPClassifier  # torch: only where an MLP is trained or loaded

        clf = MLPClassifier(dataclasses.replace(cfg.mlp, progress=progress and cfg.mlp.progress))
        return clf.fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=k)
    if cfg.likelihood == "hgb":
        return BoostedLikelihood(cfg.boosted).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=k)
    return KDELikelihood(cfg.kde).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=k)


def _model_path(root, key: str, model: str, config: RecognizerConfig):
    if model == "mlp":
        return root / f"{key}_mlp.pt"
    return root / (f"{key}_kde.npz" if config.likelihood == "kde" else f"{key}_hgb.pkl")


def _save(root, key: str, model: str, obj, meta: dict, config: RecognizerConfig) -> None:
    path = _model_path(root, key, model, config)
    if model == "mlp":
        obj.save(path)
    elif isinstance(obj, BoostedLikelihood):
        with atomic_write(path) as fh:
            fh.write(obj.to_bytes())
    else:
        save_npz_atomic(path, **obj.state())
    # the model file's digest: a flipped weight byte still loads (torch does not check its zip CRCs)
    with atomic_write(root / f"{key}.json", "w") as fh:
        json.dump({**meta, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}, fh)


def _load(root, key: str, model: str, config: RecognizerConfig):
    """The cached ``model`` under ``key``, or None (missing, or unreadable: rebuilt with a warning)."""
    path = _model_path(root, key, model, config)
    meta = root / f"{key}.json"
    if not (path.exists() and meta.exists()):
        return None
    try:
        info = json.loads(meta.read_text())
        names = info.get("names") if isinstance(info, dict) else None
        if not isinstance(names, list):
            raise CacheError(f"{meta} lacks the list of object names")
        if info.get("sha256") != hashlib.sha256(path.read_bytes()).hexdigest():
            raise CacheError(f"{path} does not match the digest in {meta.name} (damaged or replaced)")
        if model == "mlp":
            from haptic_env.recognizers.mlp import MLPClassifier

            loaded = MLPClassifier.load(path)
        elif config.likelihood == "hgb":  # unpickled only after the digest check above
            loaded = BoostedLikelihood.from_bytes(config.boosted, path.read_bytes())
        else:  # every class's data: a file missing one would load as a KDE of fewer objects
            required = ("kde_mean", "kde_std", "kde_bandwidth", "kde_factor", *(f"kde_data_{c}" for c in range(len(names))))
            loaded = KDELikelihood.from_state(config.kde, load_npz(path, required))
        if loaded.n_classes != len(names):
            raise CacheError(f"{path} holds {loaded.n_classes} classes, {meta.name} names {len(names)} objects")
        return loaded
    except (CacheError, ValueError, OSError) as exc:  # json.JSONDecodeError is a ValueError
        warnings.warn(f"rebuilding recogniser model {path.name}: {exc}", stacklevel=3)
        return None
