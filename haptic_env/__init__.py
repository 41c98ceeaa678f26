"""haptic-recog: kinesthetic haptic object recognition as a Gymnasium active-perception benchmark.

``import haptic_env`` registers the environments (cheap: no torch or mujoco import):

=========================  ==========================================================================
``HapticRecog-v0``         geometric backend, default embedded object set, 4 fingers + normals, BC-NP
``HapticRecogMuJoCo-v0``   MuJoCo backend, Allegro hand (4 fingers + normals), YCB-10 (needs shared data)
``HapticRecogShadow-v0``   MuJoCo, Shadow hand (5 fingers, no normals), YCB-10
``HapticRecogAero-v0``     MuJoCo, TetherIA Aero Hand Open (5 tendon-driven fingers, 7 actuators; no normals)
``HapticRecogRobotiq-v0``  MuJoCo, Robotiq 2F-85 gripper (2 fingers: q = contact distance + normal angles)
``HapticRecogKIT-v0``      geometric backend, KIT-8 objects (``make`` raises if the data is absent)
=========================  ==========================================================================

All take ``config=HapticRecogConfig(...)`` and/or single config fields as keyword arguments, see
:class:`haptic_env.env.HapticRecogEnv`.
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

#: Grasps per episode of the registered envs (``max_episode_steps``; = ``HapticRecogConfig.max_grasps``).
MAX_GRASPS = 30

_ENTRY = "haptic_env.env:HapticRecogEnv"
#: id -> flat config overrides of each registered variant
ENV_VARIANTS: dict[str, dict[str, Any]] = {
    "HapticRecog-v0": {},
    "HapticRecogMuJoCo-v0": {"backend": "mujoco", "backend_kwargs": {"hand": "allegro"}, "objects": "ycb10",
                             "z_fingers": 3},
    "HapticRecogShadow-v0": {"backend": "mujoco", "backend_kwargs": {"hand": "shadow"}, "objects": "ycb10",
                             "n_fingers": 5, "normals": False, "z_fingers": 3},
    "HapticRecogAero-v0": {"backend": "mujoco", "backend_kwargs": {"hand": "aero"}, "objects": "ycb10",
                           "n_fingers": 5, "normals": False, "z_fingers": 3},
    "HapticRecogRobotiq-v0": {"backend": "mujoco", "backend_kwargs": {"hand": "robotiq"}, "objects": "ycb10",
                              "n_fingers": 2},
    "HapticRecogKIT-v0": {"objects": "kit8"},
}

for _id, _kwargs in ENV_VARIANTS.items():
    if _id not in registry:
        register(id=_id, entry_point=_ENTRY, max_episode_steps=MAX_GRASPS, kwargs=dict(_kwargs))


def make(config=None, env_id: str = "HapticRecog-v0", **kwargs):
    """``gymnasium.make(env_id, config=config, **kwargs)`` with ``max_episode_steps`` set to the config's
    ``max_grasps`` (so a non-default ``max_grasps`` is honoured by the ``TimeLimit`` wrapper)."""
    import gymnasium as gym

    from haptic_env.env import HapticRecogConfig

    base = config if config is not None else HapticRecogConfig()
    fields = {k: v for k, v in {**ENV_VARIANTS[env_id], **kwargs}.items() if k in HapticRecogConfig.__dataclass_fields__}
    max_grasps = base.replace(**fields).max_grasps
    kwargs.setdefault("max_episode_steps", max_grasps)
    return gym.make(env_id, config=config, **kwargs)
