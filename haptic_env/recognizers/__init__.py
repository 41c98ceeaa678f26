"""Object recognisers: MLP / scikit-learn classifiers, KDE likelihoods and belief updaters.

See :func:`build_recognizer` for the entry point used by the Gymnasium environment. The names below are
imported on first use: ``import haptic_env.recognizers.kde`` (or ``.updaters``) does not load torch, which
only the MLP needs.
"""

from __future__ import annotations

import importlib

#: name -> the submodule that defines it
_EXPORTS = {
    **dict.fromkeys(("CLASSIFIERS", "Classifier", "SklearnClassifier", "make_classifier"), "baselines"),
    **dict.fromkeys(("KDEConfig", "KDELikelihood", "scott_bandwidth"), "kde"),
    "MLPClassifier": "mlp",
    "MLPConfig": "mlp_config",
    **dict.fromkeys(("expected_calibration_error", "fit_temperature", "reliability", "sequence_scores"),
                    "calibration"),
    **dict.fromkeys(("MODELS", "ModelBank", "Recognizer", "RecognizerConfig", "build_recognizer", "models_for"),
                    "recognizer"),
    **dict.fromkeys(("BCIP", "BCNP", "UPDATERS", "DEFAULT_UPDATER", "DEFAULT_THRESHOLD", "DEFAULT_MAX_GRASPS",
                     "BayesianUpdater", "BeliefUpdater", "IterativeClassification", "make_updater", "bayes_steps"),
                    "updaters"),
    **dict.fromkeys(("ZFingerUpdater", "sample_finger_counts", "subset_vectors", "subsets"), "zfinger"),
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
