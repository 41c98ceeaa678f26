"""Uniform backend: the paper's analysis protocol, n random surface points per grasp.

The action is validated but otherwise ignored (a control condition for active strategies): each
grasp draws ``n`` points with their inward normals from ``obj.sample_surface(n, rng, method)``
(``"area"``: area-weighted uniform; ``"centroid"``: random face centroids as in the paper) and maps
them to the world with the object pose. Every finger touches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from haptic_env.numbers import checked_flag, finite_number

from .base import ACTION_DIM, GraspBatch, GraspResult, validate_action, validate_actions, validate_pose

__all__ = ["UniformConfig", "UniformBackend"]


@dataclass(frozen=True)
class UniformConfig:
    n_fingers: int = 4
    normals: bool = True
    sampling: str = "area"  # "area" | "centroid"
    contact_noise: float = 0.0  # std (m)

    def __post_init__(self) -> None:
        if not (isinstance(self.n_fingers, (int, np.integer)) and 2 <= self.n_fingers <= 16):
            raise ValueError(f"n_fingers must be an integer in [2, 16], got {self.n_fingers!r}")
        checked_flag(self.normals, "normals")
        if self.sampling not in ("area", "centroid"):
            raise ValueError(f"sampling must be 'area' or 'centroid', got {self.sampling!r}")
        noise = finite_number(self.contact_noise)
        if noise is None or noise < 0:
            raise ValueError(f"contact_noise must be finite and >= 0, got {self.contact_noise!r}")


class UniformBackend:
    action_dim = ACTION_DIM

    def __init__(self, config: UniformConfig | None = None) -> None:
        self.config = config or UniformConfig()
        self.n_fingers = int(self.config.n_fingers)
        self._obj: Any = None
        self._geo = None

    def set_object(self, obj: Any, pose: np.ndarray | None = None) -> None:
        if not callable(getattr(obj, "sample_surface", None)):
            raise ValueError(f"object {getattr(obj, 'name', obj)!r} has no sample_surface(count, rng, method)")
        self._T = validate_pose(pose)
        self._obj = obj
        self._geo = None

    def grasp_batch(self, actions: np.ndarray, rng: np.random.Generator) -> GraspBatch:
        if self._obj is None:
            raise RuntimeError("call set_object(obj, pose) before grasping")
        a = validate_actions(actions, self.action_dim)
        B, n = a.shape[0], self.n_fingers
        pts, nrm = self._obj.sample_surface(B * n, rng, self.config.sampling)
        R, t = self._T[:3, :3], self._T[:3, 3]
        contacts = (np.asarray(pts, dtype=np.float64) @ R.T + t).reshape(B, n, 3)
        normals = (np.asarray(nrm, dtype=np.float64) @ R.T).reshape(B, n, 3)
        if self.config.contact_noise > 0:
            contacts = contacts + rng.normal(0.0, self.config.contact_noise, contacts.shape)
        self._last = GraspResult(contacts=contacts[-1], normals=normals[-1], touched=np.ones(n, bool))
        return GraspBatch(contacts=contacts, normals=normals if self.config.normals else None,
                          touched=np.ones((B, n), dtype=bool), joint_pos=np.zeros((B, 0)))

    def grasp(self, action: np.ndarray, rng: np.random.Generator) -> GraspResult:
        a = validate_action(action, self.action_dim)
        return self.grasp_batch(a[None], rng)[0]

    def render(self, width: int = 480, height: int = 480) -> np.ndarray:
        """The geometric backend's matplotlib picture of the posed mesh (the sampled points are not drawn: they come
        from no finger rays, which that picture draws)."""
        from .geometric import GeometricBackend

        if self._obj is None:  # it was an AttributeError on a pose not yet set
            raise RuntimeError("call set_object(obj, pose) before rendering")
        if self._geo is None:
            self._geo = GeometricBackend()
            self._geo.set_object(self._obj, self._T)
        return self._geo.render(width, height)
