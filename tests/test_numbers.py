"""haptic_env.numbers.finite_number: the configs' one check of a real-number setting, and the configs that use it
(a string, a bool or an int too large for numpy used to end in numpy's own TypeError, naming nothing)."""

import math

import numpy as np
import pytest

from haptic_env.numbers import finite_number, flag, positive_range, whole_number


def test_finite_number():
    for ok, want in ((0, 0.0), (-3, -3.0), (2.5, 2.5), (np.int8(4), 4.0), (np.float32(0.5), 0.5), (2**70, 2.0**70)):
        assert finite_number(ok) == want and isinstance(finite_number(ok), float)
    for bad in ("1", True, np.bool_(False), None, [1.0], np.array([1.0]), math.nan, -math.inf, np.float64(np.inf),
                10**400, -(10**400)):
        assert finite_number(bad) is None, bad


@pytest.mark.parametrize("bad", ["x", True, 10**400, -(2**64), math.nan])
def test_configs_name_a_bad_number(bad):
    from haptic_env.config import HapticRecogConfig
    from haptic_env.dataset import DatasetConfig
    from haptic_env.force_closure import check_friction
    from haptic_env.grasping.geometric import GeometricConfig
    from haptic_env.grasping.mujoco_backend import MujocoConfig
    from haptic_env.recognizers.touch import check_touch_weight

    for make, field in ((lambda: DatasetConfig(contact_noise=bad), "contact_noise"),
                        (lambda: DatasetConfig(normal_noise_deg=bad), "normal_noise_deg"),
                        (lambda: GeometricConfig(contact_noise=bad), "contact_noise"),
                        (lambda: GeometricConfig(margin=bad), "margin"),
                        (lambda: GeometricConfig(reach=bad), "reach"),
                        (lambda: MujocoConfig(contact_noise=bad), "contact_noise"),
                        (lambda: MujocoConfig(rest_qvel=bad), "rest_qvel"),
                        (lambda: check_friction(bad), "force_closure"),
                        (lambda: check_touch_weight(bad), "touch_weight"),
                        (lambda: HapticRecogConfig(grasp_cost=bad), "grasp_cost")):
        with pytest.raises(ValueError, match=field) as exc:
            make()
        assert repr(bad) in str(exc.value)


def test_mujoco_config_refuses_negative_noise():
    from haptic_env.grasping.mujoco_backend import MujocoConfig

    for field in ("contact_noise", "normal_noise_deg"):
        with pytest.raises(ValueError, match=f"{field} must be finite and >= 0, got -0.1"):
            MujocoConfig(**{field: -0.1})


def test_positive_range():
    assert positive_range((1, np.float32(2.5)), "r") == (1.0, 2.5) and positive_range([0.5, 0.5], "r") == (0.5, 0.5)
    for bad in ((1,), (1, 2, 3), 3, "ab", None, (True, 2), ("1", 2), (0, 1), (2, 1), (1, math.inf), (math.nan, 1),
                (1, 10**400)):
        with pytest.raises(ValueError, match=r"^r must be \(lo, hi\) with 0 < lo <= hi, got "):
            positive_range(bad, "r")


@pytest.mark.parametrize("bad", [(1.0, math.inf), (True, 2.0), ("1", "2"), 0.5])
def test_every_range_setting_is_checked_alike(bad):
    from haptic_env.config import HapticRecogConfig
    from haptic_env.dataset import DatasetConfig
    from haptic_env.experiments.config import AnalysisConfig
    from haptic_env.objects.primitives import family_set

    rng = np.random.default_rng(0)
    for make, field in ((lambda: HapticRecogConfig(scale_range=bad), "scale_range"),
                        (lambda: DatasetConfig(scale_range=bad), "scale_range"),
                        (lambda: AnalysisConfig(scale_range=bad), "scale_range"),
                        (lambda: AnalysisConfig(family_scale_range=bad), "family_scale_range"),
                        (lambda: AnalysisConfig(family_size_range=bad), "family_size_range"),
                        (lambda: family_set(1, rng, scale_range=bad), "scale_range"),
                        (lambda: family_set(1, rng, size_range=bad), "size_range")):
        with pytest.raises(ValueError, match=rf"^{field} must be \(lo, hi\) with 0 < lo <= hi"):
            make()


def test_whole_number_and_flag():
    for ok in (0, -3, 2**70, np.int8(4), np.uint64(7)):
        assert whole_number(ok) == int(ok) and type(whole_number(ok)) is int
    for bad in (4.0, np.float64(2), "4", True, np.bool_(True), None, [1], np.array([1])):
        assert whole_number(bad) is None, bad
    assert flag(True) is True and flag(np.bool_(False)) is False
    for bad in (0, 1, 1.0, "false", "true", None, [True]):
        assert flag(bad) is None, bad
