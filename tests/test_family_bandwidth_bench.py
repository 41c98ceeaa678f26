"""benchmarks/family_bandwidth.py's vote count and table cells (its runs need the Allegro and build grasp pools)."""

from __future__ import annotations

import numpy as np


def test_votes_sum_the_grasps_of_one_member(load_benchmark):
    bench = load_benchmark("family_bandwidth")
    member = np.repeat(np.arange(4), 50)
    fam = np.array([0, 1, 2, 2])[member]
    LL = np.zeros((200, 3))
    LL[np.arange(200), fam] = 1.0  # every grasp right: every vote right
    rng = np.random.default_rng(0)
    assert bench.votes(LL, fam, member, 10, 100, rng) == 100.0
    LL[member == 3] = [0.0, 2.0, 0.0]  # member 3 leans to family 1 in every grasp: its votes go wrong
    share = bench.votes(LL, fam, member, 10, 400, rng)
    assert 65.0 < share < 85.0  # about 3 of 4 members right
    LL[np.flatnonzero(member == 0)[:5]] = [0.0, 30.0, 0.0]  # 5 of member 0's 50 grasps mislead strongly
    one = bench.votes(LL, fam, member, 1, 400, np.random.default_rng(1))
    thirty = bench.votes(LL, fam, member, 30, 400, np.random.default_rng(1))
    assert thirty < one  # a sum over 30 grasps nearly always holds one of them


def test_table_cells(load_benchmark):
    bench = load_benchmark("family_bandwidth")
    assert bench.cell("factor", "auto (0.35)") == "auto (0.35)" and bench.cell("floor", 0.03) == "0.03"
    assert bench.cell("A_nll", 0.66441) == "0.664" and bench.cell("B_vote10", 65.8333) == "65.8"


def test_fit_bias_removes_a_lean_towards_one_family(load_benchmark):
    bench = load_benchmark("family_bandwidth")
    rng = np.random.default_rng(0)
    member = np.repeat(np.arange(9), 400)
    fam = member % 3
    LL = rng.normal(0.0, 1.0, (len(member), 3))
    LL[np.arange(len(member)), fam] += 1.0
    LL[:, 0] += 0.8  # every grasp leans towards family 0 (box) by 0.8 nats
    S, K, Y = bench.member_sums(LL, fam, member, 5, 20, np.random.default_rng(1))
    assert S.shape == (9 * 5 * 20, 3) and K.min() == 1 and K.max() == 5 and set(Y) == {0, 1, 2}
    b, T, nll, nll_T = bench.fit_bias(S, K, Y)
    assert b[2] == 0.0 and abs(b[0] + 0.8) < 0.2 and abs(b[1]) < 0.2  # the lean is taken back
    assert T > 0 and nll < nll_T
    assert bench.votes(LL + b, fam, member, 10, 300, np.random.default_rng(2)) > bench.votes(
        LL, fam, member, 10, 300, np.random.default_rng(2))
