"""Replay backend: a hand's recorded MuJoCo grasps, looked up by approach (a fast stand-in to train agents on).

A hand's MuJoCo grasp costs 5-20 ms, so an RL agent on a hand env gets a few hundred thousand grasps in an hour
on two cores. This backend answers an approach with the recorded grasp of the nearest of ``approaches`` random
approaches of the same object, grasped beforehand by the same hand, closing law and contact / normal extraction
(:func:`~haptic_env.hand_grasps.hand_grasp_pool`, object at the identity pose on its support, cached on disk).
A step then costs a nearest-neighbour query, so an agent can train on millions of grasps and be evaluated on
the MuJoCo backend itself, whose observations and actions are the same.

Poses. The table and the approach frame (:func:`~haptic_env.grasping.base.approach_frame`) do not change when
the world turns about its vertical axis, so a grasp of an object turned by a yaw ``psi`` along an approach of
azimuth ``phi`` is the grasp of the unturned object along azimuth ``phi - psi``, turned by ``psi``. The backend
therefore replays any "table-yaw" pose (a rotation about ``z``, no translation) as the physics would (the MuJoCo
Allegro's grasps turn with the object to 1e-16 m in 8 of 8 approaches measured; the generic hand's by up to 15 mm in
2 of 8, cause not measured); other
poses, and another mesh under a prepared object's name (a scaled copy), raise ``ValueError``.

Fidelity. Replayed grasps are real grasps of the object by the hand (so the recogniser sees in-distribution
grasp vectors), but from a nearby approach, not the asked one. With 6,000 approaches per object the Allegro's
nearest recorded approach touches with the same fingertips as the asked one in 57 % of held-out approaches, and
agrees on whether the grasp is usable (>= 3 fingertips) in 85 % (31 % and 71 % for a random record; the 4th and 8th
nearest: 50 % and 47 % the same fingertips). A deterministic nearest record can be exploited: PPO trained on it
found approaches whose records are unusually informative, needing 35-36 % fewer grasps than random on the replay
and 5-10 % fewer on MuJoCo (RESULTS.md). ``neighbours > 1`` answers with one of the nearest records at random, so an
agent learns what an approach tends to give (with 8: 20 % fewer on the replay, -2.5 to 8.5 % on MuJoCo). Judge a
policy trained here on the MuJoCo env. The pool's ``pool_seed`` (default 1) differs from the seed of the recogniser's
own hand-matched training pool (0), so an agent is not trained on the grasps the recogniser was fitted to.

An agent over fixed approaches (``--discrete-approaches N``) only ever asks for those ``N`` approaches, turned by the
object's yaw (relative to the estimated frame's). ``table=N`` records exactly those, each at ``yaws`` evenly spaced
yaws (:func:`~haptic_env.hand_grasps.table_actions`), so each is answered with its own grasp at the nearest recorded
yaw: for the Allegro at ``N=64``, ``yaws=72`` (46,080 grasps of ycb10) the same fingertips as MuJoCo's in 91 % of such
approaches at random yaws, the same usability in 96 %, contacts 2.2 mm apart (``benchmarks/replay_fidelity.py
--table 64``).

Distance between approaches: the actions' four coordinates, with azimuth and roll on their circles
(``cos(pi a) / pi, sin(pi a) / pi``: the chord, about ``|da|`` for small steps).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from haptic_env.numbers import checked_flag, finite_number, whole_at_least, whole_number

from .base import (ACTION_DIM, GraspBatch, GraspResult, check_solid_table, check_support, validate_action,
                   validate_actions, validate_pose)

__all__ = ["ReplayConfig", "ReplayBackend", "approach_embedding", "turned_azimuth", "yaw_log_likelihood", "YawBelief",
           "YAW_SIGMA", "YAW_NEIGHBOURS", "YAW_MISS", "YAW_WINDOW"]

#: :func:`yaw_log_likelihood`'s kernel: std (m) and recorded grasps per yaw (fixed before the look-ahead runs; tied
#: best with 5 mm / 16 on validation pool 500, ``benchmarks/pose_information.py``)
YAW_SIGMA = 0.007
YAW_NEIGHBOURS = 32
YAW_MISS = 0.05  #: its score of a finger that touches in the grasp or the record, not both
YAW_WINDOW = 3  #: YawBelief.certainty: bins either side of the mode (3 of 72: +-15 degrees)


@dataclass(frozen=True)
class ReplayConfig:
    n_fingers: int | None = None  #: None: the hand's own count
    hand: str = "allegro"  #: a hand of :func:`~haptic_env.grasping.hands.load_hand` (name or MJCF path)
    approaches: int = 6000  #: recorded random approaches per object
    pool_seed: int = 1  #: seed of the recorded approaches (the recogniser's hand-matched pool uses 0)
    support: str = "table"
    normals: bool = True  #: report the recorded torque-derived normals (False: ``normals=None``)
    #: answer with one of the ``neighbours`` nearest recorded approaches, drawn with the grasp's generator (1: the
    #: nearest, deterministic). More than one keeps an agent from exploiting single records (see the module docs).
    neighbours: int = 1
    progress: bool = True  #: progress bar while recording a pool that is not cached
    #: 0: record ``approaches`` random approaches per object. N >= 1: record instead the N approaches of a
    #: ``--discrete-approaches N`` agent (:func:`~haptic_env.grasping.base.approach_table`), each at ``yaws`` evenly
    #: spaced yaws (:func:`~haptic_env.hand_grasps.table_actions`; ``approaches`` is then not used), so that each of
    #: those approaches, at any yaw of the object, is answered with its own grasp at the nearest recorded yaw (an
    #: env's yaw belief, ``action_frame="estimated"``, still reads the random-approach pool: ``Scene.yaw_belief``)
    table: int = 0
    yaws: int = 72  #: recorded yaws per approach of ``table`` (72: every 5 degrees)
    #: the recordings' table (``MujocoConfig.solid_table``: None, solid wherever there is one; False: the visual table
    #: of the hand figures before 2026-12-07)
    solid_table: bool | None = None

    def __post_init__(self) -> None:
        if self.n_fingers is not None and (whole_number(self.n_fingers) is None or self.n_fingers < 2):
            raise ValueError(f"n_fingers must be an int >= 2 or None, got {self.n_fingers!r}")
        for name in ("normals", "progress"):
            checked_flag(getattr(self, name), name)
        if isinstance(self.hand, os.PathLike):  # an MJCF file given as a Path, as the MuJoCo backend takes it
            object.__setattr__(self, "hand", os.fspath(self.hand))
        if not isinstance(self.hand, str) or not self.hand:
            raise ValueError(f"hand must be a hand name or an MJCF path, got {self.hand!r}")
        if isinstance(self.approaches, bool) or not (isinstance(self.approaches, (int, np.integer))
                                                      and self.approaches >= 1):
            raise ValueError(f"approaches must be an int >= 1, got {self.approaches!r}")
        if isinstance(self.pool_seed, bool) or not isinstance(self.pool_seed, (int, np.integer)) or self.pool_seed < 0:
            raise ValueError(f"pool_seed must be an int >= 0, got {self.pool_seed!r}")
        check_support(self.support)
        check_solid_table(self.solid_table, self.support)
        whole_at_least(self.table, 0, "table")
        whole_at_least(self.yaws, 1, "yaws")
        if isinstance(self.neighbours, bool) or not (isinstance(self.neighbours, (int, np.integer))
                                                      and 1 <= self.neighbours <= self.records):
            raise ValueError(f"neighbours must be an int in [1, {self.records}] (the records per object), "
                             f"got {self.neighbours!r}")

    @property
    def records(self) -> int:
        """Recorded grasps per object: ``approaches``, or ``table * yaws``."""
        return int(self.table * self.yaws) if self.table else int(self.approaches)


def approach_embedding(actions: np.ndarray) -> np.ndarray:
    """``(..., 4)`` actions in ``[-1, 1]`` -> ``(..., 6)`` points whose Euclidean distance is the replay's distance
    between approaches: azimuth and roll as ``(cos(pi a), sin(pi a)) / pi`` (periodic), elevation and spread as
    they are."""
    a = np.asarray(actions, dtype=np.float64)
    az, ro = np.pi * a[..., 0], np.pi * a[..., 2]
    return np.stack([np.cos(az) / np.pi, np.sin(az) / np.pi, a[..., 1],
                     np.cos(ro) / np.pi, np.sin(ro) / np.pi, a[..., 3]], axis=-1)


def turned_azimuth(actions: np.ndarray, psi) -> np.ndarray:
    """``(..., 4)`` actions with the azimuth turned by ``psi`` rad about the vertical (broadcast against
    ``actions[..., 0]``), wrapped into ``[-1, 1)``: the approach of a world turned by ``psi`` (``-psi``: from the world
    into the frame of an object turned by ``psi``). A new float64 array; the other coordinates are copied."""
    out = np.array(actions, dtype=np.float64)
    out[..., 0] = np.mod(out[..., 0] + np.asarray(psi, dtype=np.float64) / np.pi + 1.0, 2.0) - 1.0
    return out


def yaw_log_likelihood(records: tuple, action: np.ndarray, contacts: np.ndarray, touched: np.ndarray,
                       yaws: np.ndarray, *, sigma: float = YAW_SIGMA, neighbours: int = YAW_NEIGHBOURS,
                       miss: float = YAW_MISS) -> np.ndarray:
    """How well one world-frame grasp fits an object turned by each of ``yaws`` about the vertical: a kernel mixture
    over the object's recorded grasps (the replay's physics, turned as :class:`ReplayBackend` turns them).

    For yaw ``psi`` the grasp's approach in the object's frame is its azimuth less ``psi``; the ``neighbours``
    recorded approaches nearest to it (:func:`approach_embedding`) give their contacts turned by ``psi``, and each
    scores the grasp finger by finger: an isotropic Gaussian kernel of std ``sigma`` (m) on the contact where both
    touch, ``sigma**-3 exp(-d**2 / (2 sigma**2))`` (without the Gaussian's ``(2 pi)**-1.5``), ``miss`` where one
    touches and the other does not, 1 where neither does. The result is the log of the mean score.
    The object's position and its table are known (the "table-yaw" poses: a turn about the vertical through the
    object's origin), so the contacts carry where the object's surface is, which the frame-invariant grasp vector
    drops (``benchmarks/pose_information.py`` measures how much that is).

    Args:
        records: one object's ``(tree, contacts (A, n, 3), normals, touched (A, n))`` (:meth:`ReplayBackend.records`).
        action: ``(4,)`` the grasp's approach in the world frame, in ``[-1, 1]``.
        contacts: ``(n, 3)`` world-frame fingertip contacts (m); rows of fingers that did not touch are ignored.
        touched: ``(n,)`` bool.
        yaws: ``(Y,)`` the object's yaws to score (rad).
        sigma, neighbours, miss: the kernel's std (m), the records per yaw, the score of a touch mismatch.

    Returns:
        ``(Y,)`` log-scores (the same kernel for every object and yaw, so they compare across both).

    Raises:
        ValueError: shapes that do not match the records, non-finite input, or settings out of range.
    """
    tree, C, _, T = records
    n = C.shape[1]
    a = np.asarray(action, dtype=np.float64)
    c = np.asarray(contacts, dtype=np.float64)
    t = np.asarray(touched)
    psi = np.asarray(yaws, dtype=np.float64)
    if a.shape != (ACTION_DIM,) or not np.all(np.isfinite(a)) or np.any(np.abs(a) > 1.0 + 1e-9):
        raise ValueError(f"action must be {ACTION_DIM} finite numbers in [-1, 1], got {action!r}")
    if c.shape != (n, 3) or not np.all(np.isfinite(c)):
        raise ValueError(f"contacts must be ({n}, 3) finite numbers (the records' {n} fingers), got shape {c.shape}")
    if t.shape != (n,) or t.dtype != bool:
        raise ValueError(f"touched must be a bool array of shape ({n},), got {t.dtype} {t.shape}")
    if psi.ndim != 1 or not psi.size or not np.all(np.isfinite(psi)):
        raise ValueError(f"yaws must be a non-empty 1-d array of finite angles, got shape {psi.shape}")
    s, k, m = _kernel(sigma, neighbours, miss, len(C))
    local = turned_azimuth(np.repeat(np.clip(a, -1.0, 1.0)[None], len(psi), axis=0), -psi)
    _, idx = tree.query(approach_embedding(local), k=k)
    idx = np.asarray(idx).reshape(len(psi), -1)  # (Y, k)
    cos, sin = np.cos(psi), np.sin(psi)
    Cr = C[idx]  # (Y, k, n, 3), the object's frame
    x = cos[:, None, None] * Cr[..., 0] - sin[:, None, None] * Cr[..., 1]  # turned by psi
    y = sin[:, None, None] * Cr[..., 0] + cos[:, None, None] * Cr[..., 1]
    d2 = (x - c[:, 0]) ** 2 + (y - c[:, 1]) ** 2 + (Cr[..., 2] - c[:, 2]) ** 2
    Tr = T[idx]  # (Y, k, n)
    both = Tr & t
    ll = np.where(both, -0.5 * d2 / s ** 2 - 3.0 * np.log(s), 0.0) + np.where(Tr != t, np.log(m), 0.0)
    ll = ll.sum(axis=-1)  # (Y, k)
    top = ll.max(axis=1)
    return top + np.log(np.mean(np.exp(ll - top[:, None]), axis=1))


def _kernel(sigma, neighbours, miss, records: int) -> tuple[float, int, float]:
    """:func:`yaw_log_likelihood`'s kernel settings, checked: ``(sigma, neighbours, miss)``, the neighbours at most
    ``records`` (the recorded grasps per object)."""
    s = finite_number(sigma)
    if s is None or s <= 0:
        raise ValueError(f"sigma must be a finite number > 0, got {sigma!r}")
    m = finite_number(miss)
    if m is None or not 0 < m <= 1:
        raise ValueError(f"miss must be in (0, 1], got {miss!r}")
    if whole_number(neighbours) is None or not 1 <= neighbours <= records:
        raise ValueError(f"neighbours must be an int in [1, {records}], got {neighbours!r}")
    return s, int(neighbours), m


def _normalised(lp: np.ndarray) -> np.ndarray:
    """A posterior ``(bins,)`` from its unnormalised log ``lp (bins,)`` (shifted by its maximum: no overflow)."""
    p = np.exp(lp - lp.max())
    return p / p.sum()


class YawBelief:
    """The posterior over each object's yaw given an episode's grasps: a uniform prior on ``bins`` yaws times
    :func:`yaw_log_likelihood` of every grasp, for the object of each of ``records``. An object's posterior is
    computed when first asked for and brought up to date with the grasps added since (each object and grasp scored
    once), so an episode costs one likelihood per grasp for the objects that are asked about.

    Args:
        records: each object's recorded grasps (:meth:`ReplayBackend.records`).
        bins: yaws ``2 pi i / bins``, ``i = 0 .. bins - 1``.
        kernel: :func:`yaw_log_likelihood`'s ``sigma``, ``neighbours``, ``miss``.
    """

    def __init__(self, records: list[tuple], bins: int = 72, **kernel) -> None:
        if whole_number(bins) is None or bins < 4:
            raise ValueError(f"bins must be an int >= 4, got {bins!r}")
        if not records:
            raise ValueError("records must hold at least one object's recorded grasps")
        self.records = list(records)
        self.yaws = np.arange(int(bins)) * 2.0 * np.pi / int(bins)
        unknown = sorted(set(kernel) - {"sigma", "neighbours", "miss"})
        if unknown:
            raise TypeError(f"unknown kernel settings {unknown}; yaw_log_likelihood takes sigma, neighbours, miss")
        # checked now, not at the first grasp, against every object's records
        _kernel(kernel.get("sigma", YAW_SIGMA), kernel.get("neighbours", YAW_NEIGHBOURS), kernel.get("miss", YAW_MISS),
                min(len(r[1]) for r in self.records))
        self.kernel = kernel
        self.reset()

    def reset(self) -> None:
        """A new episode: no grasps, every yaw equally likely."""
        self._grasps: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._log = np.zeros((len(self.records), len(self.yaws)))
        self._upto = np.zeros(len(self.records), dtype=int)

    @property
    def grasps(self) -> int:
        """Grasps added this episode."""
        return len(self._grasps)

    def add(self, action: np.ndarray, contacts: np.ndarray, touched: np.ndarray) -> None:
        """One more grasp of the episode: its world-frame approach ``(4,)``, contacts ``(n, 3)`` and touched fingers
        ``(n,)`` (copied)."""
        self._grasps.append((np.array(action, dtype=np.float64), np.array(contacts, dtype=np.float64),
                             np.array(touched, dtype=bool)))

    def log_likelihood(self, k: int) -> np.ndarray:
        """``(bins,)`` the summed log-likelihood of the episode's grasps under object ``k`` at each yaw (a copy)."""
        if whole_number(k) is None or not 0 <= k < len(self.records):
            raise ValueError(f"k must be an object index in [0, {len(self.records)}), got {k!r}")
        for a, c, t in self._grasps[self._upto[k]:]:
            self._log[k] += yaw_log_likelihood(self.records[k], a, c, t, self.yaws, **self.kernel)
        self._upto[k] = len(self._grasps)
        return self._log[k].copy()

    def probs(self, k: int) -> np.ndarray:
        """``(bins,)`` object ``k``'s posterior over the yaws."""
        return _normalised(self.log_likelihood(k))

    def certainty(self, k: int, window: int = YAW_WINDOW) -> float:
        """How sure object ``k``'s yaw is: its posterior mass within ``window`` bins of its mode, either side (circular;
        ``(2 window + 1) / bins`` before any grasp, 1 when every bit of it lies there)."""
        if whole_number(window) is None or not 0 <= window < len(self.yaws) // 2:
            raise ValueError(f"window must be an int in [0, bins // 2 = {len(self.yaws) // 2}), got {window!r}")
        lp = self.log_likelihood(k)
        near = (int(np.argmax(lp)) + np.arange(-int(window), int(window) + 1)) % len(lp)  # mode()'s bin, its ties
        return float(_normalised(lp)[near].sum())

    def mode(self, k: int) -> float:
        """Object ``k``'s most probable yaw (rad; the first of equals, 0 before any grasp)."""
        return float(self.yaws[int(np.argmax(self.log_likelihood(k)))])

    def sample(self, k: int, rng: np.random.Generator) -> float:
        """A yaw of object ``k`` drawn from its posterior: a bin, then uniformly within it (rad)."""
        p = self.probs(k)
        width = 2.0 * np.pi / len(self.yaws)
        return float(self.yaws[rng.choice(len(p), p=p)] + rng.uniform(-0.5, 0.5) * width)


class ReplayBackend:
    """Recorded grasps of a hand (see the module docstring). :meth:`prepare` records (or reads from the cache) the
    pools of a whole object set at once on all cores; :meth:`set_object` of an object that was not prepared records
    its pool alone."""

    action_dim = ACTION_DIM

    def __init__(self, config: ReplayConfig | None = None) -> None:
        from .hands import load_hand

        self.config = config or ReplayConfig()
        self.n_fingers = int(load_hand(self.config.hand, self.config.n_fingers).n_fingers)
        self._tables: dict[tuple[str, str], tuple] = {}  # (name, mesh hash) -> (tree, contacts, normals, touched)
        self._table = None
        self._obj = None
        self._R = np.eye(3)
        self._yaw = 0.0
        self._geo = None

    def prepare(self, objects) -> None:
        """Record (or read from the cache) the pools of every object of the ``ObjectSet`` ``objects``. An object's
        recorded approaches are drawn from ``SeedSequence([pool_seed, k])``, ``k`` its index among the objects this
        call records: prepare the whole set once (as the env, the yaw belief and the look-ahead do), since a part of it
        prepared first, or an object grasped unprepared (recorded as object 0 of a set of one), gets other records."""
        from scipy.spatial import cKDTree

        from haptic_env.hand_grasps import hand_grasp_pool, pool_actions, table_actions

        cfg = self.config
        todo = [o for o in objects if (o.name, o.mesh_hash) not in self._tables]
        if not todo:
            return
        from haptic_env.objects import ObjectSet

        subset = objects if len(todo) == len(objects) else ObjectSet(objects.name, todo)
        table = table_actions(cfg.table, cfg.yaws) if cfg.table else None
        pool = hand_grasp_pool(subset, cfg.hand, self.n_fingers, cfg.records, support=cfg.support,
                               seed=int(cfg.pool_seed), progress=cfg.progress, actions=table,
                               solid_table=cfg.solid_table)
        shared = None if table is None else cKDTree(approach_embedding(table))  # every object's table is the same
        for k, obj in enumerate(subset):
            tree = shared
            if tree is None:
                tree = cKDTree(approach_embedding(pool_actions(cfg.pool_seed, k, cfg.approaches)))
            self._tables[obj.name, obj.mesh_hash] = (tree, pool.contacts[k], pool.normals[k], pool.touched[k])

    def records(self, obj) -> tuple:
        """The recorded grasps of ``obj`` (recorded first if need be), in the object's frame at the identity pose:
        ``(tree, contacts (A, n, 3), normals (A, n, 3), touched (A, n))``, ``tree`` the k-d tree of the recorded
        approaches' :func:`approach_embedding` (row ``i`` is approach ``i`` of the pool)."""
        from haptic_env.objects import ObjectSet

        key = (obj.name, obj.mesh_hash)
        if key not in self._tables:
            self.prepare(ObjectSet(f"replay-{obj.name}", [obj]))
        return self._tables[key]

    def set_object(self, obj, pose: np.ndarray | None = None) -> None:
        from haptic_env.objects import ObjectSet
        from haptic_env.scene import pose_yaw

        T = validate_pose(pose)
        yaw = pose_yaw(T, "the replay backend (it replays grasps of an object turned about the vertical)")
        key = (obj.name, obj.mesh_hash)
        if key not in self._tables:
            if any(name == obj.name for name, _ in self._tables):  # e.g. the env's scale_range: a scaled copy
                raise ValueError(f"the replay backend has recorded grasps of object {obj.name!r} as prepared, not of "
                                 "another mesh under that name (a scaled copy: use scale_range=None)")
            self.prepare(ObjectSet(f"replay-{obj.name}", [obj]))
        self._table, self._obj, self._R, self._yaw = self._tables[key], obj, T[:3, :3].copy(), yaw

    def grasp_batch(self, actions: np.ndarray, rng: np.random.Generator) -> GraspBatch:
        """``B`` grasps: the recorded grasp of the nearest recorded approach of each, or of one of the ``neighbours``
        nearest drawn from ``rng`` (not used with ``neighbours=1``)."""
        if self._table is None:
            raise RuntimeError("call set_object(obj, pose) before grasping")
        a = validate_actions(actions, self.action_dim).astype(np.float64)
        local = turned_azimuth(a, -self._yaw)  # the approach in the object's frame
        tree, C, N, touched = self._table
        k = int(self.config.neighbours)
        _, idx = tree.query(approach_embedding(local), k=k)
        if k > 1:
            if rng is None:
                raise ValueError(f"neighbours={k} draws from the grasp's generator: pass an np.random.Generator")
            idx = idx[np.arange(len(idx)), rng.integers(0, k, len(idx))]
        R = self._R
        contacts = C[idx] @ R.T  # untouched rows are 0 and stay 0
        normals = N[idx] @ R.T if self.config.normals else None
        B = len(a)
        return GraspBatch(contacts=contacts, normals=normals, touched=touched[idx].copy(), joint_pos=np.zeros((B, 0)))

    def grasp(self, action: np.ndarray, rng: np.random.Generator) -> GraspResult:
        a = validate_action(action, self.action_dim)
        r = self.grasp_batch(a[None], rng)[0]
        r.info["usable"] = r.usable  # as the mujoco backend's results carry it
        return r

    def render(self, width: int = 480, height: int = 480) -> np.ndarray:
        """The geometric backend's matplotlib picture of the object (the replay has no hand to draw)."""
        if self._obj is None:
            raise RuntimeError("call set_object(obj, pose) before rendering")
        if self._geo is None:
            from .geometric import GeometricBackend

            self._geo = GeometricBackend()
        T = np.eye(4)
        T[:3, :3] = self._R
        self._geo.set_object(self._obj, T)
        return self._geo.render(width, height)

    def close(self) -> None:
        self._tables.clear()
        self._table = None
