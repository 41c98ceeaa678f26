"""haptic_env.numbers.finite_number: the configs' one check of a real-number setting, and the configs that use it
(a string, a bool or an int too large for numpy used to end in numpy's own TypeError, naming nothing)."""

import math

import numpy as np
import pytest

from haptic_env.numbers import finite_number


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
