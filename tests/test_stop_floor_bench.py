"""benchmarks/stop_floor.py's posterior floor (its runs train kit8 models on the shared meshes)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import log_softmax


def test_posterior_floor_mixes_each_grasp_posterior_with_eps(load_benchmark):
    bench = load_benchmark("stop_floor")
    LL = np.array([[0.0, -50.0, -3.0], [2.0, 2.0, 2.0]])
    assert np.array_equal(bench.posterior_floor(LL, 0.0), LL)  # eps = 0: the belief unchanged
    out = bench.posterior_floor(LL, 0.01)
    np.testing.assert_allclose(np.exp(out), np.exp(log_softmax(LL, axis=1)) + 0.01)
    # a class the grasp all but rules out keeps about eps: one grasp cannot veto it
    assert out[0, 1] == pytest.approx(np.log(0.01), abs=1e-9)
    # an uninformative grasp stays uninformative
    assert np.ptp(out[1]) == 0.0


@pytest.mark.parametrize("eps", [-0.1, float("nan"), float("inf")])
def test_posterior_floor_rejects_bad_eps(load_benchmark, eps):
    bench = load_benchmark("stop_floor")
    with pytest.raises(ValueError, match="eps"):
        bench.posterior_floor(np.zeros((1, 2)), eps)
