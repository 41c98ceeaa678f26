"""Grasp backends: where a hand's fingertips touch an object for a chosen approach.

``make_backend("geometric" | "uniform" | "mujoco", n_fingers, **cfg)``; see :mod:`.base` for the
approach (action) layout and :class:`GraspResult`.
"""

import os as _os

# mujoco picks its OpenGL backend when it is first imported: default to EGL offscreen rendering on
# headless machines, only when the user chose nothing.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"

from .base import (  # noqa: E402
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
    "validate_action",
    "validate_actions",
]
