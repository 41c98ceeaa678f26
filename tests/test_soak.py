"""Long runs lose nothing: per-episode state stays bounded (the slow soak lives in benchmarks/soak.py)."""

from __future__ import annotations

import numpy as np

from haptic_env.env import HapticRecogEnv


def test_scaled_resets_reuse_one_scene_per_object(env_config):
    """``scale_range``: the backend scales the object as a transform, no per-episode mesh copy or Embree scene
    (those accumulated ~1.8 MB/episode and crashed Embree after ~1000 episodes)."""
    env = HapticRecogEnv(env_config.replace(scale_range=(0.8, 1.2)))
    env.reset(seed=0)
    scales = set()
    for _ in range(60):
        env.reset()
        be = env.backend
        assert be.object is env.objects[env.target]  # the set's own object, not a scaled copy
        assert be.scale == env.scale
        scales.add(env.scale)
        env.step(np.zeros(4, dtype=np.float32))
    assert len(scales) == 60
    assert env.backend.n_scenes <= env.n_classes
