"""Which seeds train, which choose settings (validation) and which report (test): the project's one owner of them.

Settings are chosen on validation seeds only; test seeds are for reporting, run once after the choice. Every
stream below is apart from the others, so no validation or test draw is ever a training one:

* an analysis' grasps: training ``AnalysisConfig.seed``, validation ``seed + VALIDATION_SEED_OFFSET``, test
  ``seed + TEST_SEED_OFFSET``;
* experiment 5's family members: training ``seed``, validation ``seed + FAMILY_VAL_SEED_OFFSET``, test
  ``seed + TEST_SEED_OFFSET``;
* the hand benchmarks' query pools: the envs' training pool is pool seed 0; validation and test pools are
  :func:`hand_pool_seed` (500 + s and 1000 + s);
* env episodes: RL training envs :func:`training_env_seed`; validation :data:`ENV_VALIDATION_SEEDS`, test
  :data:`ENV_TEST_SEEDS`.

Sweeps evaluate on :data:`SWEEP_ENV_SEEDS` (their leaderboard's own test seeds).
"""

from __future__ import annotations

from haptic_env.numbers import whole_number

__all__ = ["TEST_SEED_OFFSET", "VALIDATION_SEED_OFFSET", "FAMILY_VAL_SEED_OFFSET", "ENV_TEST_SEEDS",
           "ENV_VALIDATION_SEEDS", "SWEEP_ENV_SEEDS", "HAND_POOL_SPLITS", "hand_pool_seed", "training_env_seed"]

#: An analysis' test grasps are fresh samples from seed ``seed + TEST_SEED_OFFSET`` (and experiment 5's test members).
TEST_SEED_OFFSET = 7919
#: An analysis' validation grasps (the stop scale's trials) are fresh samples from seed ``seed + VALIDATION_SEED_OFFSET``.
VALIDATION_SEED_OFFSET = 500
#: Experiment 5's validation members (the outlier floor, the temperatures) come from ``seed + FAMILY_VAL_SEED_OFFSET``.
FAMILY_VAL_SEED_OFFSET = 1000
#: The env seeds every reported env result is measured on (``haptic-recog evaluate``'s default).
ENV_TEST_SEEDS = (0, 1, 2, 3, 4)
#: The env seeds settings are chosen on.
ENV_VALIDATION_SEEDS = (500, 501, 502, 503, 504)
#: The env seeds a sweep's agents are evaluated on (``[evaluate] env_seeds`` of a sweep spec).
SWEEP_ENV_SEEDS = (1000, 1001, 1002)
#: The query pools of the hand benchmarks: split -> the first pool seed (pool seed ``base + s`` for seed ``s``).
HAND_POOL_SPLITS = {"validation": 500, "test": 1000}


def hand_pool_seed(split: str, seed: int) -> int:
    """The hand grasp pool seed of ``split`` ("validation" or "test") for seed ``seed`` (the hand benchmarks' query
    pools; the envs train on pool seed 0). A ``ValueError`` names a bad split."""
    if split not in HAND_POOL_SPLITS:
        raise ValueError(f"split must be one of {tuple(HAND_POOL_SPLITS)}, got {split!r}")
    return HAND_POOL_SPLITS[split] + _seed_in(seed, SPLIT_SPAN, "seed")


def training_env_seed(seed: int) -> int:
    """The first training env's seed for training seed ``seed`` (env ``rank`` gets it ``+ rank``): apart from every
    evaluation seed (test 0-4, validation 500-504, sweeps 1000-1002), so that no training env replays the episode
    draws of an evaluation seed. Its run's envs (every segment's) keep to ``TRAINING_ENV_SEED_BLOCK`` seeds from it,
    apart from the next training seed's."""
    return 10_000 + TRAINING_ENV_SEED_BLOCK * _seed_in(seed, None, "seed")


#: the env seeds of one training seed's run, from :func:`training_env_seed` on
TRAINING_ENV_SEED_BLOCK = 1_000


#: how many seeds a split's offsets leave apart (validation 500 + s must stay below the test pools' 1000)
SPLIT_SPAN = 500


def _seed_in(seed, span: int | None, name: str) -> int:
    """``seed`` as an int in ``[0, span)`` (no upper bound for ``None``): a negative seed (or one past the span) would
    land in another split's range, e.g. ``training_env_seed(-10)`` on test seed 0."""
    s = whole_number(seed)
    if s is None or s < 0 or (span is not None and s >= span):
        raise ValueError(f"{name} must be an int in [0, {span if span is not None else 'inf'}), got {seed!r}")
    return s
