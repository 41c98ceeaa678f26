r"""The recognition task: observation layout, reward kinds, termination and truncation, and ``info``.

:class:`Task` is dm_control's *task*: given what the scene and the belief did in a step, it says what the agent
observes, what it earns and whether the episode is over. It holds the observation's memory of the latest grasp
(its grasp vector, touched fingers, usability and action; with ``observe_contacts`` also its world-frame contacts)
and nothing else.

Rewards (``reward = gain - grasp_cost``; :data:`REWARD_KINDS`):

- ``"true-posterior-gain"``: :math:`b_t[k^*] - b_{t-1}[k^*]`, the gain in the posterior of the true object;
- ``"max-posterior-gain"``: :math:`\max b_t - \max b_{t-1}` (no ground truth needed);
- ``"entropy-reduction"``: :math:`H(b_{t-1}) - H(b_t)` in nats.

Termination: the belief has decided (its certainty reached the threshold). Truncation: ``max_grasps`` grasps,
the one source of the episode length (the registered envs set no ``max_episode_steps``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from haptic_env.numbers import positive_number

if TYPE_CHECKING:
    from haptic_env.config import HapticRecogConfig

__all__ = ["Task", "REWARD_KINDS", "entropy", "touched_rows"]

REWARD_KINDS = ("true-posterior-gain", "max-posterior-gain", "entropy-reduction")


def entropy(p: np.ndarray) -> float | np.ndarray:
    """Shannon entropy (nats) of probability vectors along the last axis of ``p (..., K)``: shape ``(...)``, a float
    for one vector. Zero entries add nothing (``0 log 0 = 0``).

    Each vector must be a probability vector: ``K >= 1`` entries, finite, ``>= 0``, summing to 1 within ``1e-6``;
    a ``ValueError`` names the first row that is not (NaN, inf, a negative entry or a wrong sum would give an entropy
    that is no entropy). An empty batch ``(0, K)`` gives ``(0,)``."""
    p = np.asarray(p, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] == 0:
        raise ValueError(f"p must have shape (..., K) with K >= 1 probabilities, got shape {p.shape}")
    with np.errstate(divide="ignore", invalid="ignore"):
        # NaN and +-inf fail the sum test (a NaN, inf or NaN sum), negative entries the min test
        bad = ~((p.min(axis=-1) >= 0.0) & (np.abs(p.sum(axis=-1) - 1.0) <= 1e-6))
        if bad.any():
            i = tuple(int(j) for j in np.argwhere(bad)[0]) if bad.ndim else ()
            where = f"p[{', '.join(map(str, i))}]" if i else "p"
            raise ValueError(f"entropy needs probability vectors (finite, >= 0, summing to 1 within 1e-6), got {where}"
                             f" = {p[i].tolist()}")
        h = -np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0).sum(axis=-1)
    return float(h) if h.ndim == 0 else h


def touched_rows(x: np.ndarray, touched: np.ndarray, bound: float) -> np.ndarray:
    """``x (..., n, 3)`` with the rows of fingers that did not touch (``touched (..., n)`` False) set to 0, clipped
    to ``[-bound, bound]`` and flattened to ``(..., 3n)`` (a new array; non-finite values of untouched rows are
    dropped, not propagated). An empty batch ``(0, n, 3)`` gives ``(0, 3n)``.

    It runs on every step, so it checks shapes, dtypes and ``bound`` only, never the values: ``x`` of shape
    ``(..., n, 3)``, ``touched`` a bool array of exactly ``x.shape[:-1]`` (no broadcasting, no truthiness of
    numbers), ``bound`` a finite number ``> 0``; a ``ValueError`` names what is not."""
    x = np.asarray(x, dtype=np.float64)
    t = np.asarray(touched)
    if x.ndim < 2 or x.shape[-1] != 3:
        raise ValueError(f"x must have shape (..., n, 3), got shape {x.shape}")
    if t.dtype.kind != "b" or t.shape != x.shape[:-1]:
        raise ValueError(f"touched must be a bool array of shape {x.shape[:-1]} (x's without the last axis), got "
                         f"dtype {t.dtype} and shape {t.shape}")
    b = positive_number(bound, "bound")  # the env's: a plain float, checked at once
    out = np.where(t[..., None], x, 0.0)
    np.clip(out, -b, b, out=out)
    return out.reshape(out.shape[:-2] + (3 * x.shape[-2],))


class Task:
    """Observation space and vector, reward, truncation and ``info`` of ``config``'s recognition task."""

    def __init__(self, config: HapticRecogConfig, n_classes: int, feature_dim: int, action_dim: int, q_bound: float):
        self.config = config
        n, K, d, A = config.n_fingers, n_classes, feature_dim, action_dim
        #: grasp vectors hold angles (rad, |.| <= pi) and lengths (m, <= the largest object diameter); world-frame
        #: contacts lie within the largest diameter of the object's centre (the origin), so the same bound holds them
        self.q_bound = float(q_bound)
        self.observation_structure = {
            "grasp": d, "contact_mask": n, "usable": 1, "belief": K, "prev_action": A, "grasp_count": 1,
        }
        bounds = {
            "grasp": (-self.q_bound, self.q_bound), "contact_mask": (0, 1), "usable": (0, 1), "belief": (0, 1),
            "prev_action": (-1, 1), "grasp_count": (0, 1),
            "contacts": (-self.q_bound, self.q_bound), "contact_normals": (-1, 1), "yaw_certainty": (0, 1),
        }
        if config.observe_contacts:
            self.observation_structure["contacts"] = 3 * n
            if config.normals:
                self.observation_structure["contact_normals"] = 3 * n
        if config.observe_yaw:
            self.observation_structure["yaw_certainty"] = 1
        self.obs_slices: dict[str, slice] = {}
        lows, highs, start = [], [], 0
        for name, size in self.observation_structure.items():
            self.obs_slices[name] = slice(start, start + size)
            start += size
            lows.append(np.full(size, bounds[name][0], np.float32))
            highs.append(np.full(size, bounds[name][1], np.float32))
        self.observation_space = spaces.Box(np.concatenate(lows), np.concatenate(highs), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (A,), dtype=np.float32)
        self.reset()

    def reset(self) -> None:
        """Forget the latest grasp (all zeros before the first grasp)."""
        sizes = self.observation_structure
        self.last_q = np.zeros(sizes["grasp"])
        self.last_mask = np.zeros(sizes["contact_mask"])
        self.last_usable = 0.0
        self.last_action = np.zeros(sizes["prev_action"])
        self.last_contacts = np.zeros(sizes.get("contacts", 0))
        self.last_normals = np.zeros(sizes.get("contact_normals", 0))
        self.yaw_certainty = 0.0  #: observe_yaw: set by the env from its yaw belief after reset and every grasp

    def record(self, q: np.ndarray, touched: np.ndarray, usable: bool, action: np.ndarray,
               contacts: np.ndarray | None = None, normals: np.ndarray | None = None) -> None:
        """The latest grasp: its grasp vector ``q (d,)`` (a fresh array: clipped to the observation bounds in place),
        touched fingers, whether it updated the belief, its action, and (observed with ``observe_contacts``) its
        world-frame ``contacts (n, 3)`` and ``normals (n, 3)``, zeroed where a finger did not touch."""
        np.minimum(np.maximum(q, -self.q_bound, out=q), self.q_bound, out=q)
        self.last_q = q
        self.last_mask = touched.astype(np.float64)
        self.last_usable = float(usable)
        self.last_action = action
        if "contacts" in self.observation_structure:
            self.last_contacts = touched_rows(contacts, touched, self.q_bound)
            if "contact_normals" in self.observation_structure:
                self.last_normals = touched_rows(normals, touched, 1.0)

    def reward(self, old: np.ndarray, new: np.ndarray, target: int) -> tuple[float, dict[str, float]]:
        """``(reward, terms)`` of a step from belief ``old`` to ``new``; the terms sum exactly to the reward."""
        kind = self.config.reward
        if kind == "true-posterior-gain":
            gain = float(new[target] - old[target])
        elif kind == "max-posterior-gain":
            gain = float(new.max() - old.max())
        else:
            gain = entropy(old) - entropy(new)
        terms = {"gain": gain, "grasp_cost": -float(self.config.grasp_cost)}
        return float(sum(terms.values())), terms

    def truncated(self, grasps: int, terminated: bool) -> bool:
        return bool((not terminated) and grasps >= self.config.max_grasps)

    def fill(self, obs: np.ndarray, parts: dict[str, Any]) -> np.ndarray:
        """Write every part of the layout into ``obs (..., D)`` from ``parts`` (name -> value broadcastable to
        ``(..., size)``; a batch of envs passes ``(B, size)`` or ``(B, 1)``); the one place that maps parts to slices,
        used by the single and the native vector env. Returns ``obs``."""
        for name, sl in self.obs_slices.items():
            obs[..., sl] = parts[name]
        return obs

    def observation(self, belief: np.ndarray, grasps: int) -> np.ndarray:
        return self.fill(np.empty(self.observation_space.shape, dtype=np.float32), {
            "grasp": self.last_q, "contact_mask": self.last_mask, "usable": self.last_usable, "belief": belief,
            "prev_action": self.last_action, "grasp_count": grasps / self.config.max_grasps,
            "contacts": self.last_contacts, "contact_normals": self.last_normals, "yaw_certainty": self.yaw_certainty,
        })

    def info(self, names, target: int, belief: np.ndarray, certainty: float, *, grasps: int, usable: bool,
             decided: bool) -> dict[str, Any]:
        pred = int(belief.argmax())
        return {
            "true_object": names[target],
            "true_index": target,
            "predicted": names[pred],
            "predicted_index": pred,
            "correct": pred == target,
            "certainty": certainty,
            "decided": decided,
            "grasps": grasps,
            "usable": usable,
            "belief": belief.copy(),
            "touched": self.last_mask.astype(bool),
        }
