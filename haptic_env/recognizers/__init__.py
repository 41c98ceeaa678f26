"""Object recognisers: MLP / scikit-learn classifiers, KDE likelihoods and belief updaters.

See :func:`build_recognizer` for the entry point used by the Gymnasium environment.
"""

from haptic_env.recognizers.baselines import CLASSIFIERS, Classifier, SklearnClassifier, make_classifier
from haptic_env.recognizers.kde import KDEConfig, KDELikelihood, scott_bandwidth
from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig
from haptic_env.recognizers.calibration import expected_calibration_error, fit_temperature, reliability
from haptic_env.recognizers.recognizer import MODELS, ModelBank, Recognizer, RecognizerConfig, build_recognizer, models_for
from haptic_env.recognizers.updaters import (
    BCIP,
    BCNP,
    UPDATERS,
    BayesianUpdater,
    BeliefUpdater,
    IterativeClassification,
    make_updater,
)
from haptic_env.recognizers.zfinger import ZFingerUpdater, sample_finger_counts, subset_vectors, subsets

__all__ = [
    "CLASSIFIERS", "Classifier", "SklearnClassifier", "make_classifier", "KDEConfig", "KDELikelihood",
    "scott_bandwidth", "MLPClassifier", "MLPConfig", "ModelBank", "Recognizer", "RecognizerConfig",
    "build_recognizer", "models_for", "MODELS", "fit_temperature", "expected_calibration_error", "reliability",
    "BCIP", "BCNP", "UPDATERS", "BayesianUpdater", "BeliefUpdater",
    "IterativeClassification", "make_updater", "ZFingerUpdater", "sample_finger_counts", "subset_vectors", "subsets",
]
