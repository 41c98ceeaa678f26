"""The settings of the paper's analysis (:class:`AnalysisConfig`, one field per ``haptic-recog analysis`` flag)
and the constants its experiments share."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from haptic_env.cache import KEY_ONLY_WHEN_SET
from haptic_env.dataset import MAX_CLI_FINGERS, DatasetConfig
from haptic_env.force_closure import check_friction
from haptic_env.grasp_features import check_normal_axis
from haptic_env.numbers import (check_flag_fields, check_whole_fields, finite_number, items, positive_range, repeated,
                                whole_number)
from haptic_env.objects.base import up_rotation
from haptic_env.objects.loaders import check_object_spec, unit_scale
from haptic_env.objects.primitives import FAMILY_SCALE_RANGE
from haptic_env.recognizers.baselines import CLASSIFIERS
from haptic_env.recognizers.boosted import BoostedConfig, check_likelihood
from haptic_env.recognizers.kde import KDEConfig
from haptic_env.recognizers.mlp import MLPConfig
from haptic_env.recognizers.recognizer import RecognizerConfig
from haptic_env.recognizers.updaters import (DEFAULT_IC_CERTAINTY, DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD, UPDATERS,
                                             check_ic_certainty, check_threshold)

__all__ = ["AnalysisConfig", "KINDS", "MAIN_KINDS", "FAMILY_SOURCES"]

#: The updaters of experiments 2 and 6: every kind.
KINDS = UPDATERS
#: IC, BC-NP and BC-IP: the updaters of experiments 3, 4 and 7.
MAIN_KINDS = ("ic", "bc-np", "bc-ip")
#: The fewest training rows :attr:`AnalysisConfig.baseline_max_train` may give a scikit-learn baseline (a cap of 1
#: was accepted and failed after the recognisers were built: kNN needs its 15 neighbours, an SVM two classes).
MIN_BASELINE_TRAIN = 100

#: Values of :attr:`AnalysisConfig.family_source`: experiment 5's grasps are independent surface points (the
#: paper's analysis protocol), the geometric hand's grasps under random approaches over the full sphere, or a robot
#: hand's own MuJoCo grasps (:attr:`AnalysisConfig.family_hand`) under random approaches, the object on the table.
FAMILY_SOURCES = ("surface", "geometric", "hand")

#: The finger-count lists of the config and the experiment whose grasps each gives (experiment 7 takes two).
FINGER_LISTS = {"fingers": 2, "oneshot_fingers": 1, "zfinger_hands": 3, "calib_fingers": 7,
                "calib_fingers_no_normals": 7}


@dataclass(frozen=True)
class AnalysisConfig:
    """Settings of :func:`~haptic_env.experiments.run_analysis` (the CLI flags)."""

    objects: str = "default"
    data_dir: str | None = None
    units: str = "m"
    up: str = "z"  #: a folder's files' up axis (named sets know theirs; KIT: y)
    experiments: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7)
    grasps_per_object: int = 10_000
    test_grasps: int = 400  #: fresh test grasps per object
    trials: int = 200
    max_grasps: int = DEFAULT_MAX_GRASPS
    threshold: float = DEFAULT_THRESHOLD
    fingers: tuple[int, ...] = (2, 3, 4, 5, 6, 7, 8, 9, 10)  #: experiment 2
    oneshot_fingers: tuple[int, ...] = (3, 4, 5)  #: experiment 1
    classifiers: tuple[str, ...] = CLASSIFIERS
    baseline_max_train: int | None = 5_000  #: cap on kernel/tree baselines' training rows (GP: /5)
    zfinger_hands: tuple[int, ...] = (5, 6, 8)  #: experiment 3: n of the hand
    incomplete_pn: tuple[tuple[int, float], ...] = ((3, 0.2), (4, 0.3), (5, 0.5))
    scale_range: tuple[float, float] = (0.1, 5.0)
    family_members: int = 10  #: experiment 5: training members per family
    #: experiment 5's grasps, of the family members and of the objects alike (one of :data:`FAMILY_SOURCES`):
    #: ``"surface"``, independent surface points (the paper's analysis protocol), or ``"geometric"``, what the
    #: geometric hand touches when it closes along a random approach (still from the meshes alone)
    family_source: str = "surface"
    #: with ``family_source="hand"``: the hand (a name of :func:`~haptic_env.grasping.hands.load_hand`); grasps are
    #: random 4-subsets of the fingers that touched
    family_hand: str = "allegro"
    #: experiment 5: the per-axis scale factors of the family members about 0.08 m (the paper's U(0.5, 1.5))
    family_scale_range: tuple[float, float] = FAMILY_SCALE_RANGE
    #: experiment 5: a factor per member on all three axes (its overall size), ``None``: none (the paper's). A robot
    #: hand's grasps depend on size after scale normalisation, so ``family_source="hand"`` wants members of the
    #: objects' sizes (``family_set(size_range=)``)
    family_size_range: tuple[float, float] | None = None
    #: experiment 5 with ``family_source="hand"``: append each contact's height above the table (``phi(heights=True)``,
    #: scaled with the contacts by the scale normalisation); the objects rest on the table in their own pose, so a
    #: robot senses the heights as it senses the contacts. Off: the paper's frame-invariant Phi_n
    family_heights: bool = False
    #: experiment 5: every second elliptic cylinder member lies on its side (``family_set(lying=True)``); the paper's
    #: generator stands them all on an end. Matters where the pose on the table does (a hand source)
    family_lying: bool = False
    #: experiment 5 with ``family_source="surface"``: keep only the grasps in force closure at this friction coefficient
    #: (``DatasetConfig.force_closure``), of the members and the objects alike; ``None``: every grasp (the paper's)
    family_force_closure: float | None = field(default=None, metadata={KEY_ONLY_WHEN_SET: True})
    #: experiment 5 with calibrated scores: the outlier floors of the family KDE to choose from on the validation
    #: members (``families.family_floor``): each the quantile ``q`` of the true family's log-likelihood on held-back
    #: training-member grasps below which a grasp's log-likelihoods are lifted (``families.floored``), so that a grasp
    #: unlike every family moves the belief little; ``q = 0``: no floor. ``(0.0,)``: never (before 2026-12-04; raw
    #: scores never have one)
    family_floors: tuple[float, ...] = (0.0, 0.01, 0.03, 0.1, 0.2)
    normals: bool = True  #: experiments 2-6
    #: each normal's second angle in Phi_n (n >= 4): to t2's normal ("t2", the paper's) or to the edge ab ("ab"), or
    #: three angles, to the axes of t1's frame ("frame", n >= 3; ``phi(normal_axis=)``), in every experiment's
    #: training and test grasps
    normal_axis: str = "t2"
    #: experiments 1-4, 6 and 7: train and test on the surface grasps in force closure at this friction coefficient
    #: only (``DatasetConfig.force_closure``; every finger count >= 3); ``None``: every random grasp (the paper's stated
    #: protocol). Experiment 5 has its own (:attr:`family_force_closure`)
    force_closure: float | None = field(default=None, metadata={KEY_ONLY_WHEN_SET: True})
    #: experiments 2-6 use the validation-fitted calibration (False: the paper's raw scores, and no stop scale)
    calibrated: bool = True
    #: experiment 2: BC-NP and BC-IP divide their calibrated log-likelihoods by a stop scale chosen on validation
    #: trials so that a stop at lambda is right about lambda of the time (:mod:`~haptic_env.experiments.stop_scale`);
    #: off: the calibrated one-shot scores as they are. Only with ``calibrated`` (see :attr:`uses_stop_scale`).
    stop_scale: bool = True
    #: IC's certainty rule in every experiment (:data:`~haptic_env.recognizers.updaters.IC_CERTAINTIES`): ``"count"``,
    #: ``max S / k``; ``"share"``, the winner's share of the summed winner scores as the authors' public code has it
    ic_certainty: str = DEFAULT_IC_CERTAINTY
    #: the beliefs' likelihood in every experiment that trains through :meth:`recognizer_config`
    #: (``RecognizerConfig.likelihood``): the KDE (``"kde"``, the paper's) or gradient boosting (``"hgb"``, opt-in)
    likelihood: str = field(default="kde", metadata={KEY_ONLY_WHEN_SET: True})
    calib_fingers: tuple[int, ...] = (3, 4, 5, 8)  #: experiment 7, with normals
    calib_fingers_no_normals: tuple[int, ...] = (4,)  #: experiment 7, without normals
    lambdas: tuple[float, ...] = (0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95)  #: experiment 7
    ece_bins: int = 10  #: experiment 7
    #: the trials' and the grasps' seed; the models' are ``mlp.seed`` and ``kde.seed`` (the CLI's ``--seed`` sets all
    #: three; through the API set them too for runs of several seeds, else their models share one draw)
    seed: int = 0
    mlp: MLPConfig = field(default_factory=lambda: MLPConfig(max_epochs=20, patience=3, max_train=100_000))
    #: the analyses' KDE, calibrated on validation grasps: the bandwidth factor chosen by the held-out validation NLL
    #: of the calibrated one-shot posterior (``KDEConfig.select="posterior"``), and a learned correction of its scores
    #: (matrix scaling or the power on each class's gap to the best) where it lowers that NLL, then the temperature
    #: (``correct="auto"``, ``correct_candidates=("matrix", "power")``). With them every experiment-7 one-shot ECE at
    #: 200,000 grasps per object is at or below 0.044, and experiment 2 meets every cell that the density-likelihood
    #: bandwidth with the matrix correction alone met (RESULTS.md). ``haptic-recog analysis --kde-select likelihood
    #: --kde-corrections matrix`` gives that earlier setting; ``--no-correction`` the temperature alone.
    kde: KDEConfig = field(default_factory=lambda: KDEConfig(correct="auto", select="posterior",
                                                             correct_candidates=("matrix", "power")))
    progress: bool = True

    def __post_init__(self):
        up_rotation(self.up)  # names a bad axis
        unit_scale(self.units)  # names bad units
        check_object_spec(self.objects)  # names an unknown set before any work
        check_normal_axis(self.normal_axis)
        self._check_counts()
        check_flag_fields(self, ("normals", "calibrated", "stop_scale", "progress", "family_heights", "family_lying"))
        check_ic_certainty(self.ic_certainty)
        check_likelihood(self.likelihood)
        if self.family_source not in FAMILY_SOURCES:
            raise ValueError(f"family_source must be one of {FAMILY_SOURCES}, got {self.family_source!r}")
        if not isinstance(self.family_hand, str) or not self.family_hand:
            raise ValueError(f"family_hand must be a hand name, got {self.family_hand!r}")
        object.__setattr__(self, "family_scale_range", positive_range(self.family_scale_range, "family_scale_range"))
        if self.family_size_range is not None:
            object.__setattr__(self, "family_size_range", positive_range(self.family_size_range, "family_size_range"))
        if 5 in self.experiments:  # members too small: refused now, not in experiment 5 after the others ran
            from haptic_env.objects.primitives import check_member_sizes

            try:
                check_member_sizes(self.family_scale_range, self.family_size_range)
            except ValueError as exc:
                raise ValueError(f"family_scale_range / family_size_range: {exc}") from None
        fl = tuple(finite_number(q) for q in items(self.family_floors) or ())
        if not fl or not all(q is not None and 0.0 <= q < 1.0 for q in fl):
            raise ValueError(f"family_floors must be a non-empty tuple of quantiles in [0, 1), "
                             f"got {self.family_floors!r}")
        object.__setattr__(self, "family_floors", fl)
        if self.force_closure is not None:
            check_friction(self.force_closure)
            for name, exp in FINGER_LISTS.items():
                if exp in self.experiments and min(getattr(self, name), default=3) < 3:
                    raise ValueError(f"force_closure needs every finger count >= 3 (two point contacts are never in "
                                     f"force closure), got {name}={getattr(self, name)}")
            if 3 in self.experiments and min(int(z) for z, _ in self.incomplete_pn) < 3:  # experiment 3's grasps
                raise ValueError(f"force_closure needs every finger count >= 3 (two point contacts are never in "
                                 f"force closure), got incomplete_pn={self.incomplete_pn}")
        if self.family_force_closure is not None:
            check_friction(self.family_force_closure, "family_force_closure")
            if self.family_source != "surface":
                raise ValueError(f"family_force_closure filters surface grasps (family_source='surface'), got "
                                 f"family_source={self.family_source!r}")
        if self.family_heights and self.family_source != "hand":
            raise ValueError(f"family_heights needs family_source='hand' (objects on the table), got "
                             f"family_source={self.family_source!r}")

    def _check_counts(self) -> None:
        """The counts, tuples and probabilities, each named with its bad value (before any grasp is made)."""
        from haptic_env.experiments.analysis import EXPERIMENTS  # here: analysis imports this module

        check_whole_fields(self, (("grasps_per_object", 1), ("test_grasps", 1), ("trials", 1), ("max_grasps", 1),
                                  ("ece_bins", 1), ("family_members", 1), ("seed", 0)))
        t = check_threshold(self.threshold, "threshold")
        if isinstance(self.threshold, np.generic):  # a Python int or float stays as given
            object.__setattr__(self, "threshold", t)
        cap = self.baseline_max_train
        if cap is not None and (whole_number(cap) or 0) < MIN_BASELINE_TRAIN:  # kNN's 15 neighbours, SVMs' 2 classes
            raise ValueError(f"baseline_max_train must be None or an int >= {MIN_BASELINE_TRAIN} (fewer rows leave a "
                             f"baseline too few neighbours or classes to fit), got {self.baseline_max_train!r}")
        if (not items(self.experiments) or not all(whole_number(e) in EXPERIMENTS for e in self.experiments)
                or repeated(self.experiments)):
            raise ValueError(f"experiments must be a non-empty tuple of experiment numbers {sorted(EXPERIMENTS)}, "
                             f"each once, got {self.experiments!r}")
        # experiment 3 scores 3- and 4-finger subsets of an n-finger hand, so a hand needs n >= 4
        for name, lo in (("fingers", 2), ("oneshot_fingers", 2), ("calib_fingers", 2), ("calib_fingers_no_normals", 2),
                         ("zfinger_hands", 4)):
            ns = items(getattr(self, name))  # empty: the experiment skips it
            if ns is None or not all(lo <= (whole_number(n) or 0) <= MAX_CLI_FINGERS for n in ns) or repeated(ns):
                raise ValueError(f"{name} must be a tuple of ints in [{lo}, {MAX_CLI_FINGERS}], each once, got "
                                 f"{getattr(self, name)!r}")
        # a selected experiment whose finger lists are all empty wrote a table of its header only, exit 0
        for e in sorted(set(FINGER_LISTS.values())):
            names = [n for n, x in FINGER_LISTS.items() if x == e]
            if e in self.experiments and not any(items(getattr(self, n)) for n in names):
                raise ValueError(f"experiment {e} needs finger counts, but {' and '.join(names)} "
                                 f"{'is' if len(names) == 1 else 'are'} empty (leave the experiment out instead)")
        cl = items(self.classifiers) or ()
        bad = [c for c in cl if c not in CLASSIFIERS]
        if not cl or bad:
            raise ValueError(f"classifiers: unknown classifier(s) {bad}; choose from {CLASSIFIERS}" if bad else
                             f"classifiers must name at least one of {CLASSIFIERS}, got {self.classifiers!r}")
        pn = [items(zp) or () for zp in items(self.incomplete_pn) or ()]
        if (not pn or not all(len(zp) == 2 and (whole_number(zp[0]) or 0) >= 2 and (finite_number(zp[1]) or 0) > 0
                              for zp in pn)
                or len({zp[0] for zp in pn}) != len(pn)):
            raise ValueError(f"incomplete_pn must be (finger count >= 2, probability > 0) pairs, one per finger count, "
                             f"got {self.incomplete_pn!r}")
        positive_range(self.scale_range, "scale_range")
        lam = [finite_number(v) for v in items(self.lambdas) or ()]
        if not lam or not all(v is not None and 0.0 < v <= 1.0 for v in lam):
            raise ValueError(f"lambdas must be a non-empty tuple of thresholds in (0, 1], got {self.lambdas!r}")
        from haptic_env.recognizers.calibration import MAX_CALIBRATE_GRASPS

        if 5 in self.experiments and self.calibrated and self.max_grasps > MAX_CALIBRATE_GRASPS:
            # experiment 5 fits its family temperature and floor on beliefs of up to max_grasps grasps (it failed
            # there, after experiments 1-4 and its own models)
            raise ValueError(f"max_grasps must be <= {MAX_CALIBRATE_GRASPS} with experiment 5 on calibrated scores "
                             f"(the longest calibrated belief), got {self.max_grasps}")

    @property
    def family_grasps(self) -> dict:
        """The :class:`DatasetConfig` fields of experiment 5's grasps (:attr:`family_source`)."""
        if self.family_source == "geometric":
            return {"source": "geometric", "support": "floating"}
        if self.family_source == "hand":
            return {"source": "hand", "hand": self.family_hand, "support": "table", "heights": self.family_heights}
        return {} if self.family_force_closure is None else {"force_closure": self.family_force_closure}

    def recognizer_config(self, **kw) -> RecognizerConfig:
        """The :class:`RecognizerConfig` every experiment trains its object models with (``kw``: more
        :class:`DatasetConfig` fields, e.g. experiment 4's scale range)."""
        grasps = DatasetConfig(grasps_per_object=self.grasps_per_object, seed=self.seed,
                               **{"normal_axis": self.normal_axis, "force_closure": self.force_closure, **kw})
        hgb = {"likelihood": "hgb", "boosted": BoostedConfig(seed=self.seed)} if self.likelihood == "hgb" else {}
        return RecognizerConfig(grasps=grasps, mlp=dataclasses.replace(self.mlp, progress=False), kde=self.kde, **hgb)

    @property
    def uses_stop_scale(self) -> bool:
        """Whether experiment 2's BC beliefs use the stop scale: asked for, on calibrated scores (the paper's raw
        method has none)."""
        return self.stop_scale and self.calibrated

    @property
    def ic_label(self) -> str:
        """IC's certainty rule as the headings name it when it is not the default ('' otherwise)."""
        return ("; IC certainty: the winner's share of the winners' scores (the authors' code)"
                if self.ic_certainty == "share" else "")

    @property
    def family_scores_label(self) -> str:
        """How experiment 5 scores grasps: its family KDE and MLP, whatever ``likelihood`` and the KDE's correction
        say for the other experiments."""
        if not self.calibrated:
            return "raw scores (paper)" + self.ic_label
        return ("calibrated scores: the family KDE's log-likelihoods with an outlier floor (or none), tempered for "
                f"beliefs of 1-{self.max_grasps} grasps of one member, and the MLP's temperature, each chosen on "
                "validation members" + self.ic_label)

    @property
    def scores_label(self) -> str:
        """How experiments 2-4 and 6 score grasps (and IC's certainty, if not the default), as the report's headings
        say it (experiment 5's family models: :attr:`family_scores_label`)."""
        ic = self.ic_label
        if self.likelihood == "hgb":
            return ("BC's likelihood: gradient boosting (`--likelihood hgb`, not the paper's; no correction or "
                    "temperature of its own), " + ("raw scores" if not self.calibrated else
                                                   "the MLP's calibration temperature") + ic)
        if not self.calibrated:
            return "raw scores (paper)" + ic
        k = self.kde.calibrate_grasps
        label = f"calibrated scores (KDE for beliefs of 1-{k} grasps)" if k > 1 else "calibrated scores"
        if self.kde.correct == "auto":
            label += ": the KDE's learned correction where it helps held-out validation beliefs, then its temperature"
        elif self.kde.correct:
            label += ": the KDE's learned correction, then its temperature"
        return label + ic
