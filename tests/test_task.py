"""Tests of haptic_env.task's array functions: entropy and touched_rows."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import entropy as scipy_entropy

from haptic_env.task import entropy, touched_rows


@pytest.mark.parametrize("p, shown", [
    ([np.nan, 0.5], r"p = \[nan, 0.5\]"),  # the NaN used to be dropped: 0.3466
    ([-0.5, 1.5], r"p = \[-0.5, 1.5\]"),  # -0.608
    ([2.0], r"p = \[2.0\]"),  # -1.386
    ([np.inf, 0.5], r"p = \[inf, 0.5\]"),  # -inf
    ([np.inf, -np.inf], r"p = \[inf, -inf\]"),
    ([[0.5, 0.5], [0.2, 0.2]], r"p\[1\] = \[0.2, 0.2\]"),
    ([[[0.5, 0.5]], [[0.5, 0.5 + 2e-6]]], r"p\[1, 0\] = \[0.5, 0.500002\]"),
])
def test_entropy_refuses_what_is_not_a_probability_vector_naming_the_row(p, shown):
    with pytest.raises(ValueError, match=r"entropy needs probability vectors .*, got " + shown):
        entropy(p)


@pytest.mark.parametrize("p", [0.5, [], np.zeros((3, 0))])
def test_entropy_needs_at_least_one_entry(p):
    with pytest.raises(ValueError, match=r"p must have shape \(\.\.\., K\) with K >= 1"):
        entropy(p)


def test_entropy_of_probability_vectors_is_unchanged():
    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.ones(6), 50)
    P[:5, :3] = 0.0
    P[:5] /= P[:5].sum(axis=1, keepdims=True)
    h = entropy(P)
    np.testing.assert_allclose(h, scipy_entropy(P, axis=1), rtol=0, atol=1e-14)
    # the formula itself, bit for bit
    with np.errstate(divide="ignore", invalid="ignore"):
        want = -np.where(P > 0, P * np.log(np.where(P > 0, P, 1.0)), 0.0).sum(axis=-1)
    np.testing.assert_array_equal(h, want)
    assert entropy(np.zeros((0, 4))).shape == (0,)
    assert entropy([0.5, 0.5 + 9e-7]) == pytest.approx(np.log(2), abs=1e-5)  # within the sum's tolerance
    assert entropy([1.0]) == 0.0 and isinstance(entropy([1.0]), float)


@pytest.mark.parametrize("x, touched, match", [
    (np.ones((4, 2)), np.ones(4, bool), r"x must have shape \(\.\.\., n, 3\), got shape \(4, 2\)"),  # was an 8-vector
    (np.ones((2, 4)), np.ones(2, bool), r"x must have shape \(\.\.\., n, 3\), got shape \(2, 4\)"),
    (np.ones(3), np.ones(1, bool), r"x must have shape \(\.\.\., n, 3\), got shape \(3,\)"),
    (np.ones((4, 3)), np.ones(1, bool), r"touched must be a bool array of shape \(4,\).*shape \(1,\)"),  # broadcast
    (np.ones((4, 3)), True, r"touched must be a bool array of shape \(4,\).*shape \(\)"),
    (np.ones((4, 3)), np.array([0.1, np.nan, 0, 0]), r"touched must be a bool array.*dtype float64"),
    (np.ones((4, 3)), np.array([1, 0, 1, 0]), r"touched must be a bool array.*dtype int64"),
    (np.ones((2, 4, 3)), np.ones(4, bool), r"touched must be a bool array of shape \(2, 4\)"),
])
def test_touched_rows_refuses_other_shapes_and_dtypes(x, touched, match):
    with pytest.raises(ValueError, match=match):
        touched_rows(x, touched, 1.0)


@pytest.mark.parametrize("bound", [-1, 0, 0.0, np.nan, np.inf, None, "1", True, np.array([1.0, 2.0])])
def test_touched_rows_refuses_a_bound_that_is_not_positive_and_finite(bound):
    with pytest.raises(ValueError, match="bound must be a finite number > 0"):
        touched_rows(np.ones((4, 3)), np.ones(4, bool), bound)


def test_touched_rows_zeroes_clips_and_flattens():
    x = np.arange(12.0).reshape(4, 3) - 5
    x[1, 0] = np.nan  # an untouched row's NaN is dropped
    t = np.array([True, False, True, True])
    got = touched_rows(x, t, 3.0)
    np.testing.assert_array_equal(got, [-3, -3, -3, 0, 0, 0, 1, 2, 3, 3, 3, 3])
    assert got.shape == (12,) and got.dtype == np.float64
    X = np.random.default_rng(1).normal(size=(5, 2, 4, 3))
    T = np.random.default_rng(2).random((5, 2, 4)) < 0.5
    want = np.clip(np.where(T[..., None], X, 0.0), -0.7, 0.7).reshape(5, 2, 12)
    np.testing.assert_array_equal(touched_rows(X, T, 0.7), want)
    np.testing.assert_array_equal(touched_rows(X, T, np.float32(0.7)), np.clip(np.where(T[..., None], X, 0.0),
                                                                              -np.float32(0.7), np.float32(0.7))
                                  .reshape(5, 2, 12))


def test_touched_rows_of_an_empty_batch():
    """An empty batch used to fail: 'cannot reshape array of size 0'."""
    assert touched_rows(np.zeros((0, 4, 3)), np.zeros((0, 4), bool), 5.0).shape == (0, 12)
    assert touched_rows(np.zeros((2, 0, 3)), np.zeros((2, 0), bool), 5.0).shape == (2, 0)
