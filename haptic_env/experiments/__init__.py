"""The paper's experiments (``haptic-recog analysis``): its recognition analysis on any object set.

One module per experiment (``--experiments 1,2,...``; all by default), each with ``run(objects, cfg, report, rng)``:

1. :mod:`.oneshot`: one-shot accuracy of every classifier (+ the KDE's argmax) for n = 3, 4, 5 with/without normals;
2. :mod:`.sequential`: IC, IC-full, BC-NP and BC-IP at ``lambda``: success rate and grasps (mean/std) for each n,
   with confusion matrices (PNG);
3. :mod:`.zfinger`: z-finger scoring (z = 3, 4; all subsets and k = 4 random ones) of n-finger grasps, and
   incomplete grasps (finger counts z ~ p_n(z), each scored by its z-finger model);
4. :mod:`.scaled`: scaled objects (random scale in [0.1, 5]) with and without scale normalisation;
5. :mod:`.families`: geometry recognition: train on boxes / elliptic cylinders / ellipsoids, classify held-out
   family members and the objects of ``--objects`` into the three families;
6. :mod:`.success_vs_grasps`: success rate vs number of grasps (threshold disregarded);
7. :mod:`.calibration`: on fresh test grasps, the expected calibration error (ECE) of the one-shot posteriors
   of BC (softmax of the KDE log-likelihoods) and of the MLP, raw and temperature-scaled, with reliability
   diagrams; success at the stop and mean grasps vs lambda for IC, BC-NP and BC-IP, raw and calibrated
   (``--calib-fingers``, ``--calib-fingers-no-normals``, ``--lambdas``).

Shared parts: :mod:`.config` (:class:`AnalysisConfig`, the CLI's settings), :mod:`.fresh_grasps` (test grasp
pools and their model scores), :mod:`.trials` (the trial runner), :mod:`.report` (the markdown report),
:mod:`.plots`, :mod:`.analysis` (:func:`run_analysis`) and :mod:`.cli` (the ``analysis`` sub-command).

Experiments 2-7 score grasps with the calibration temperatures fitted on validation grasps
(:mod:`~haptic_env.recognizers.calibration`; ``--raw``: the paper's raw scores).

Protocol: models train on :func:`~haptic_env.dataset.build_dataset` data (seed ``--seed``) through
:func:`~haptic_env.recognizers.build_recognizer` (experiment 5's family models excepted); test grasps are fresh
samples from another seed (``seed + 7919``), never training data. A trial picks an object uniformly, draws test
grasps one at a time (without replacement from that object's test pool) until the updater decides or
``--max-grasps``; success = the prediction at the stop is right. Model scores of the test pools are computed
once in batch; trials replay them through the real updater classes
(:meth:`~haptic_env.recognizers.updaters.BeliefUpdater.update_scores`).

Default settings finish in minutes on 2 cores; the paper's protocol is
``--grasps-per-object 200000 --trials 1000``.
"""

from haptic_env.experiments.analysis import EXPERIMENTS, run_analysis
from haptic_env.experiments.calibration import calibration_summary, oneshot_posterior
from haptic_env.experiments.cli import add_parser
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.paper import PAPER
from haptic_env.experiments.families import EXPECTED_FAMILY, family_temperatures
from haptic_env.experiments.trials import family_trials, incomplete_trials, run_trial, simulate_trials
from haptic_env.splits import TEST_SEED_OFFSET

__all__ = [
    "AnalysisConfig", "run_analysis", "EXPERIMENTS", "add_parser", "PAPER", "TEST_SEED_OFFSET",
    "run_trial", "simulate_trials", "incomplete_trials", "family_trials",
    "calibration_summary", "oneshot_posterior", "EXPECTED_FAMILY", "family_temperatures",
]
