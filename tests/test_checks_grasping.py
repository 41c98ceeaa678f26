"""Input checks of the grasp backends' configs, the force-closure filter, the hand-grasp pools and the object
helpers: a bad setting is a ``ValueError`` naming the field and the value, raised when the config is made (or at
the function's start). Every bad case here was accepted before (a bool, a float where an int belongs, NaN, a
string numpy turned into a number) or ended in an error naming neither (numpy's ``isfinite`` ``TypeError``, an
``OverflowError``, a crash in a later grasp)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from haptic_env.cache import config_key
from haptic_env.force_closure import force_closure, primitive_wrenches
from haptic_env.grasping.collision import CollisionConfig
from haptic_env.grasping.geometric import GeometricConfig
from haptic_env.grasping.mujoco_backend import MujocoConfig
from haptic_env.grasping.replay import ReplayConfig
from haptic_env.grasping.uniform import UniformConfig
from haptic_env.hand_grasps import balanced_counts, hand_grasp_pool
from haptic_env.objects.loaders import unit_scale
from haptic_env.objects.primitives import family_set

# three contacts of a unit cube's faces and their inward normals (a valid grasp for the force-closure checks)
C3 = np.array([[0.5, 0.0, 0.0], [-0.5, 0.1, 0.0], [0.0, 0.5, 0.1]])
N3 = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _cfg(cls, field):
    return lambda v: cls(**{field: v})


CASES = [  # (what is called with the bad value, bad values, regex naming the field)
    (_cfg(GeometricConfig, "normals"), ["no", 1, None], r"normals must be a bool"),
    (_cfg(GeometricConfig, "min_spread"), [True, "0.5"], r"min_spread must be in \(0, 1\]"),
    (_cfg(GeometricConfig, "curl_deg"), [("10", 20.0, 30.0, 40.0, 50.0, 0.0), (True,) * 6, (np.True_,) * 6,
                                         ("1", "2", "3", "4")], r"curl_deg needs >= n_fingers"),
    (_cfg(UniformConfig, "normals"), ["no", 0, None], r"normals must be a bool"),
    (_cfg(UniformConfig, "contact_noise"), ["0.01", None, 10**309, True], r"contact_noise must be finite and >= 0"),
    (_cfg(MujocoConfig, "normals"), ["no", 0, None], r"normals must be a bool"),
    (_cfg(MujocoConfig, "friction"), [math.nan, -1, "x", True, None], r"friction must be finite and >= 0"),
    (_cfg(MujocoConfig, "squeeze"), [math.nan, -1, "x", True, None], r"squeeze must be finite and >= 0"),
    (_cfg(MujocoConfig, "joint_frictionloss"), [math.nan, -1, "x", True],
     r"joint_frictionloss must be finite and >= 0 or None"),
    (_cfg(MujocoConfig, "standoff"), [math.nan, -1, "x", True, math.inf], r"standoff must be finite and >= 0 or None"),
    (_cfg(MujocoConfig, "max_steps"), [4.0, True, math.nan, math.inf, "x"], r"max_steps must be an int >= 1 or None"),
    (_cfg(MujocoConfig, "n_fingers"), [0, -3, 2.5, "x", True], r"n_fingers must be an int >= 2 or None"),
    (_cfg(ReplayConfig, "normals"), ["no", 0], r"normals must be a bool"),
    (_cfg(ReplayConfig, "progress"), ["no", 0, None], r"progress must be a bool"),
    (_cfg(ReplayConfig, "n_fingers"), [0, -3, 2.5, "x", True], r"n_fingers must be an int >= 2 or None"),
    (_cfg(CollisionConfig, "convex_tol"), [math.nan, -1, "x"], r"convex_tol must be finite and >= 0"),
    (_cfg(CollisionConfig, "threshold"), [True, "0.1"], r"coacd threshold must be in \(0, 1\]"),
    (_cfg(CollisionConfig, "max_convex_hull"), ["x", -2, 0, 2.5, True, 2**40], r"max_convex_hull must be an int"),
    (_cfg(CollisionConfig, "resolution"), ["x", -1, 500.0, 2**31], r"resolution must be an int"),
    (_cfg(CollisionConfig, "max_ch_vertex"), ["x", -1, 2], r"max_ch_vertex must be an int"),
    (_cfg(CollisionConfig, "preprocess_resolution"), ["x", -1], r"preprocess_resolution must be an int"),
    (_cfg(CollisionConfig, "mcts_iterations"), ["x", -1], r"mcts_iterations must be an int"),
    (_cfg(CollisionConfig, "mcts_nodes"), ["x", 0], r"mcts_nodes must be an int"),
    (_cfg(CollisionConfig, "mcts_max_depth"), ["x", 0], r"mcts_max_depth must be an int"),
    (_cfg(CollisionConfig, "seed"), ["x", -1, 1.0, 2**32], r"seed must be an int"),
    (lambda v: primitive_wrenches(C3, N3, mu=v), ["0.5", True, None], r"mu \(the friction coefficient\) must be"),
    (lambda v: force_closure(C3, N3, mu=v), ["0.5", True], r"mu \(the friction coefficient\) must be"),
    (lambda v: primitive_wrenches(C3, N3, 0.5, edges=v), [4.0, "x", math.nan, math.inf, None],
     r"edges must be an int >= 3"),
    (lambda v: balanced_counts([0.5, 0.2], v), [True, 4.0, "x", math.nan], r"approaches must be an int >= 1"),
    # the check comes first: the objects are never looked at
    (lambda v: hand_grasp_pool(None, "generic", 4, v, cache=False), [True, 4.0, "x"],
     r"approaches must be an int >= 1"),
    (lambda v: hand_grasp_pool(None, "generic", v, 10, cache=False), [4.0, True, "4"],
     r"n_fingers must be an int >= 2"),
    (lambda v: hand_grasp_pool(None, "generic", 4, 10, seed=v, cache=False), [-1, 1.5, "0"],
     r"seed must be an int >= 0"),
    (lambda v: balanced_counts([0.5, 0.2], 10, hi=v), [math.inf, "2", math.nan], r"need 0 < lo <= 1 <= hi"),
    (lambda v: balanced_counts([0.5, 0.2], 10, minimum=v), [-1, 0.5, True], r"minimum must be an int >= 0"),
    (lambda v: balanced_counts([0.5, 0.2], 10, minimum=v), [11], r"minimum must be <= approaches=10"),
    (lambda v: family_set(v, np.random.default_rng(0)), [1.9, "3", True], r"n_per_family must be an int >= 1"),
    (unit_scale, [True, np.True_], r"units must be 'm', 'cm', 'mm' or a positive number"),
    (unit_scale, [10**310], r"units factor must be positive and finite"),
]


@pytest.mark.parametrize("call, bad, pattern", [(c, b, p) for c, bads, p in CASES for b in bads],
                         ids=[f"{p.split(' ')[0]}-{b!r}"[:60] for _, bads, p in CASES for b in bads])
def test_bad_input_names_the_field_and_the_value(call, bad, pattern):
    with pytest.raises(ValueError, match=pattern) as exc:
        call(bad)
    assert repr(bad) in str(exc.value)


def test_valid_forms_are_accepted_and_kept():
    # numpy scalars and np.bool_ flags are taken, and stored as given
    cfg = GeometricConfig(normals=np.False_, min_spread=np.float32(0.5), curl_deg=np.array([5.0, 6, 7, 8]))
    assert cfg.normals is np.False_ and cfg.min_spread == np.float32(0.5) and len(cfg.curl_deg) == 4
    assert GeometricConfig(curl_deg=[np.int64(10), 20, 30.5, 0]).curl_deg[2] == 30.5
    assert GeometricConfig().curl_deg == (10.0, 20.0, 30.0, 40.0, 50.0, 0.0) and GeometricConfig().normals is True
    u = UniformConfig(normals=np.True_, contact_noise=np.float64(0.01))
    assert u.normals is np.True_ and u.contact_noise == 0.01 and UniformConfig(contact_noise=0).contact_noise == 0
    r = ReplayConfig(n_fingers=np.int64(4), normals=np.False_, progress=False)
    assert r.n_fingers == 4 and r.normals is np.False_ and ReplayConfig().n_fingers is None
    c = CollisionConfig(max_convex_hull=-1, seed=np.uint32(2**32 - 1), threshold=np.float32(0.5), convex_tol=0,
                        resolution=np.int64(100))
    assert c.max_convex_hull == -1 and c.resolution == 100 and isinstance(c.resolution, np.int64)
    # zero friction (frictionless contacts) and zero squeeze (close fully) stay valid
    m = MujocoConfig(friction=0, squeeze=0.0, joint_frictionloss=None, standoff=0.0, max_steps=1, n_fingers=None)
    assert m.friction == 0 and m.squeeze == 0.0 and m.standoff == 0.0 and m.max_steps == 1 and m.n_fingers is None
    W = primitive_wrenches(C3, N3, mu=np.float32(0.5), edges=np.int64(4))
    np.testing.assert_array_equal(W, primitive_wrenches(C3, N3, 0.5, 4))
    assert primitive_wrenches(C3, N3, mu=0, edges=3).shape == (9, 6)
    np.testing.assert_array_equal(balanced_counts([0.5, 0.2], np.int64(10)), balanced_counts([0.5, 0.2], 10))
    assert len(family_set(np.int64(1), np.random.default_rng(0))) == 3
    assert unit_scale(np.float32(0.5)) == 0.5 and unit_scale(2) == 2.0 and isinstance(unit_scale(2), float)
    assert unit_scale("mm") == 0.001


DEFAULTS = {"n_fingers": 4, "hand": "generic", "hand_kwargs": (), "support": "table", "normals": True,
            "torque_source": "actuator", "contact_point": "surface", "timestep": None, "solver": None,
            "max_steps": None,
            "min_time": 0.08, "check_interval": 0.02, "squeeze": 0.15, "rest_qvel": 0.05, "joint_frictionloss": 0.0,
            "friction": 0.1, "march_step": 0.01, "standoff": None, "contact_noise": 0.0, "normal_noise_deg": 0.0,
            "collision": CollisionConfig(), "solid_table": None}
COLLISION_DEFAULTS = {"method": "auto", "threshold": 0.08, "max_convex_hull": 24, "max_ch_vertex": 64,
                      "preprocess_resolution": 30, "resolution": 500, "mcts_iterations": 40, "mcts_nodes": 8,
                      "mcts_max_depth": 2, "convex_tol": 0.02, "seed": 0}


def test_mujoco_config_defaults_and_numpy_scalars_unchanged():
    """The hand grasp pools are cached under keys of these configs: the defaults, their types and the keys of
    numpy-scalar settings stay those of the plain-Python ones."""
    m = MujocoConfig()
    for f in dataclasses.fields(m):
        got, want = getattr(m, f.name), DEFAULTS[f.name]
        assert got == want and type(got) is type(want), f.name
    c = CollisionConfig()
    for f in dataclasses.fields(c):
        got, want = getattr(c, f.name), COLLISION_DEFAULTS[f.name]
        assert got == want and type(got) is type(want), f.name
    plain = dict(n_fingers=4, max_steps=60, squeeze=0.2, friction=0.3, joint_frictionloss=0.01, standoff=0.005,
                 timestep=0.004, contact_noise=0.001)
    numpy = {k: (np.int64(v) if isinstance(v, int) else np.float64(v)) for k, v in plain.items()}
    a, b = MujocoConfig(**plain), MujocoConfig(**numpy, normals=np.True_)
    for f in dataclasses.fields(a):
        assert getattr(a, f.name) == getattr(b, f.name), f.name
    assert a == b and config_key(a) == config_key(MujocoConfig(**numpy))
    for k, v in plain.items():  # stored as given: an int stays an int, a float a float
        assert type(getattr(a, k)) is type(v) and type(getattr(b, k)) is type(numpy[k])
