"""The seed plan: training, validation and test streams never meet."""
from __future__ import annotations

import pytest

from haptic_env import splits


def test_hand_pool_seeds_by_split():
    assert [splits.hand_pool_seed("validation", s) for s in (0, 1, 2)] == [500, 501, 502]
    assert [splits.hand_pool_seed("test", s) for s in (0, 1, 2)] == [1000, 1001, 1002]
    with pytest.raises(ValueError, match="'train'"):
        splits.hand_pool_seed("train", 0)


def test_training_env_seeds_miss_every_evaluation_seed():
    evaluation = set(splits.ENV_TEST_SEEDS) | set(splits.ENV_VALIDATION_SEEDS) | set(splits.SWEEP_ENV_SEEDS)
    for seed in range(20):
        first = splits.training_env_seed(seed)
        assert evaluation.isdisjoint(range(first, first + 64))  # up to 64 training envs per run


def test_analysis_offsets_are_distinct():
    offsets = (0, splits.VALIDATION_SEED_OFFSET, splits.FAMILY_VAL_SEED_OFFSET, splits.TEST_SEED_OFFSET)
    assert len(set(offsets)) == len(offsets)


def test_evaluate_reports_on_the_test_seeds_by_default():
    import argparse

    from agents.evaluate import add_parser

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    assert parser.parse_args(["evaluate"]).seeds == list(splits.ENV_TEST_SEEDS) == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("call, match", [
    (lambda: splits.training_env_seed(-10), r"seed must be an int in \[0, inf\), got -10"),
    (lambda: splits.hand_pool_seed("validation", -500), r"seed must be an int in \[0, 500\), got -500"),
    (lambda: splits.hand_pool_seed("validation", 500), r"seed must be an int in \[0, 500\), got 500"),
    (lambda: splits.hand_pool_seed("test", 2.5), r"got 2.5"),
])
def test_a_seed_that_would_land_in_another_split_is_refused(call, match):
    """training_env_seed(-10) was test seed 0, hand_pool_seed("validation", 500) the test pool of seed 0 and
    hand_pool_seed("validation", -500) the envs' training pool."""
    with pytest.raises(ValueError, match=match):
        call()
