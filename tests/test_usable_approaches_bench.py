"""benchmarks/usable_approaches.py's scripted agent (no hand env needed)."""

from __future__ import annotations

import numpy as np
from gymnasium.spaces import Box


class _Env:
    action_space = Box(-1.0, 1.0, (4,), np.float32)


def test_cell_agent_stays_in_its_cell_and_draws_the_azimuth(load_benchmark):
    bench = load_benchmark("usable_approaches")
    bins = 4
    p = np.zeros(bins ** 3)
    p[np.ravel_multi_index((3, 0, 2), (bins,) * 3)] = 1.0
    agent = bench.CellAgent("one", p, bins, seed=0)
    A = np.array([agent.act(None, _Env()) for _ in range(500)])
    assert A.dtype == np.float32 and A.shape == (500, 4)
    lo = -1 + 2 * np.array([3, 0, 2]) / bins
    assert ((A[:, 1:] >= lo - 1e-6) & (A[:, 1:] <= lo + 2 / bins + 1e-6)).all()  # elevation, roll, spread in the cell
    assert A[:, 0].min() < -0.9 and A[:, 0].max() > 0.9  # the azimuth spans the box
