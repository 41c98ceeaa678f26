"""benchmarks/closing_time.py's comparison of two runs of the same approaches (its runs need the hands)."""

from __future__ import annotations

import numpy as np
import pytest


def test_differences_compare_only_fingertips_that_touch_in_both(load_benchmark):
    bench = load_benchmark("closing_time")
    up = np.array([0.0, 0.0, 1.0])
    a = {"touched": np.array([[True, True], [True, False]]),
         "contacts": np.zeros((2, 2, 3)), "normals": np.tile(up, (2, 2, 1))}
    b = {"touched": np.array([[True, True], [True, True]]),
         "contacts": np.zeros((2, 2, 3)), "normals": np.tile(up, (2, 2, 1))}
    b["contacts"][0, 1] = [0.003, 0.004, 0.0]  # 5 mm away
    b["normals"][1, 0] = [1.0, 0.0, 0.0]  # 90 degrees
    b["contacts"][1, 1] = [1.0, 0.0, 0.0]  # finger 1 of grasp 1 touches only in b: not compared
    same, dist, ang = bench.differences(a, b)
    assert same == 0.5
    np.testing.assert_allclose(np.sort(dist), [0.0, 0.0, 0.005])
    np.testing.assert_allclose(np.sort(ang), [0.0, 0.0, 90.0])


@pytest.mark.parametrize("argv, match", [(["--hands", "shadow,nohand"], "unknown hand"),
                                         (["--approaches", "0"], "approaches"),
                                         (["--gains", "2,x"], "gains"), (["--gains", "0"], "gains")])
def test_bad_arguments_fail_before_any_grasp(load_benchmark, usage_error, argv, match):
    usage_error(load_benchmark("closing_time").main, argv, match=match)  # a usage error (exit 2) naming the flag


def test_scaled_gains_stiffens_position_actuators_of_a_copy(load_benchmark):
    bench = load_benchmark("closing_time")
    from haptic_env.grasping.hands import load_hand

    desc = load_hand("generic", 3)
    before = [(a.gainprm[0], a.biasprm[1]) for a in desc.spec.actuators]
    fast = bench.scaled_gains(desc, 2.5)
    after = [(a.gainprm[0], a.biasprm[1]) for a in fast.spec.actuators]
    assert before == [(a.gainprm[0], a.biasprm[1]) for a in desc.spec.actuators]  # the original is untouched
    assert before and all(kp > 0 and b < 0 for kp, b in before)  # the generic hand's actuators are position servos
    np.testing.assert_allclose(np.array(after), 2.5 * np.array(before))
    assert fast.name == f"{desc.name}_kp2.5" and fast.tips == desc.tips
    with pytest.raises(ValueError, match="factor"):
        bench.scaled_gains(desc, 0.0)


def test_touch_shares_count_complete_and_three_finger_grasps(load_benchmark):
    bench = load_benchmark("closing_time")
    touched = np.array([[1, 1, 1, 1], [1, 1, 1, 0], [1, 1, 0, 0], [0, 0, 0, 0]], dtype=bool)
    assert bench.touch_shares(touched) == (0.25, 0.5)
    assert bench.touch_shares(np.array([[1, 1], [1, 0]], dtype=bool)) == (0.5, 0.5)  # a gripper: both pads
