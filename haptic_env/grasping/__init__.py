"""Grasp backends: where a hand's fingertips touch an object for a chosen approach.

``make_backend("geometric" | "uniform" | "mujoco" | "replay", n_fingers, **cfg)``; see :mod:`.base` for the
approach (action) layout and :class:`GraspResult`.
"""

from .base import (
    ACTION_DIM,
    ACTION_NAMES,
    BACKENDS,
    Approach,
    GraspBackend,
    GraspBatch,
    GraspResult,
    approach_frame,
    decode_approach,
    make_backend,
    usable_touch,
    validate_action,
    validate_actions,
)

__all__ = [
    "ACTION_DIM",
    "ACTION_NAMES",
    "BACKENDS",
    "Approach",
    "GraspBackend",
    "GraspBatch",
    "GraspResult",
    "approach_frame",
    "decode_approach",
    "make_backend",
    "usable_touch",
    "validate_action",
    "validate_actions",
]
