r"""Training grasps: random surface contacts per object, mapped to grasp vectors :math:`\Phi_n`.

A training grasp of an object is ``n`` independent random surface points (with their inward
normals), as in Sintov & Ben-David. :func:`grasp_vectors` applies the sensing model (object scale,
contact and normal noise, optional scale normalisation) and :func:`~haptic_env.grasp_features.phi`.
:func:`build_dataset` does this for every object of a set, with a stratified train/validation split,
and caches the result in ``cache_dir("datasets")`` keyed by the object meshes and the config.

CLI::

    python -m haptic_env.cli dataset --objects default --fingers 4 --grasps 20000 [--no-normals]
        [--noise 0.001] [--normal-noise 5] [--normalize-scale] [--scale-range 0.1 5]
        [--sampling area|centroid] [--force-closure 0.5] [--val-fraction 0.2] [--out file.npz] [--seed 0]
        [--no-cache]
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from .cache import KEY_ONLY_WHEN_SET, CacheError, cache_dir, config_key, file_stem, load_npz, save_npz_atomic
from .force_closure import DEFAULT_EDGES, FRAMES, check_friction, force_closure
from .grasp_features import check_normal_axis, feature_dim, normalize_scale, phi
from .grasping.base import SUPPORTS, check_solid_table, check_support, support_height
from .hand_grasps import BUDGETS
from .numbers import check_flag_fields, check_whole_fields, finite_number, positive_range, whole_at_least, whole_number
from .objects import SAMPLING_METHODS, UP_AXES, GraspObject, ObjectSet, load_object_set

__all__ = [
    "DatasetConfig",
    "GraspDataset",
    "sample_grasps",
    "held_grasps",
    "draw_held_grasps",
    "approach_grasps",
    "SOURCES",
    "grasp_vectors",
    "support_frame",
    "build_dataset",
    "hand_vectors",
    "hand_dataset",
    "dataset_cache_path",
    "TooFewGraspsError",
    "add_parser",
]

_CACHE_VERSION = "grasp-dataset-v1"
#: in :meth:`DatasetConfig.source_key` of two-contact vectors with heights: their heights ordered lower first where
#: the normals do not order the contacts (since 2026-12-07)
_PHI2_HEIGHTS = "phi2-heights-sorted"
#: Values of :attr:`DatasetConfig.source`.
SOURCES = ("surface", "geometric", "hand")
#: The most contacts per grasp the command lines take (``dataset --fingers``, ``analysis --fingers``).
MAX_CLI_FINGERS = 20
_ARRAYS = ("X_train", "y_train", "X_val", "y_val", "names")
#: Resampling rounds used to replace degenerate grasps before giving up.
_MAX_TOPUP_ROUNDS = 20


class TooFewGraspsError(RuntimeError):
    """A hand's grasps of an object gave too few training rows for its settings (approaches, fingers): the dataset
    command reports it as a one-line usage error."""


@dataclass(frozen=True)
class DatasetConfig:
    """How training grasps are generated (frozen: it is the cache key).

    Attributes:
        n_fingers: contacts per grasp (>= 2).
        normals: include contact normals in the grasp vector (``5n - 6`` instead of ``3n - 6``).
        grasps_per_object: valid grasps per object (train + validation).
        contact_noise: std (m) of isotropic Gaussian noise added to every contact.
        normal_noise_deg: std (degrees) of the tilt of every normal, in a uniform random direction.
        normalize_scale: divide contacts by the square root of the grasp polyhedron's area.
        scale_range: ``(lo, hi)``: every grasp sees the object scaled by ``U(lo, hi)``; ``None``: 1.
        sampling: surface sampling method, ``"area"`` or ``"centroid"`` (see ``GraspObject``).
        val_fraction: fraction of each object's grasps held out for validation, in ``[0, 1)`` (at least one of an
            object's grasps stays for training).
        seed: seed of everything random in the dataset.
        source: where contacts come from. ``"surface"`` (the paper's analysis protocol): ``n``
            independent random surface points. ``"geometric"``: grasps of the geometric approach
            model (:mod:`haptic_env.grasping.geometric`) under uniformly random approaches, still
            computed from the mesh alone (no robot data), so the training distribution matches
            what a hand closing along an approach touches.
            ``"hand"``: grasps of a robot hand's own MuJoCo model (``hand``) under uniformly random
            approaches, object fixed (:mod:`haptic_env.hand_grasps`; still from the meshes alone),
            with the backend's contact and torque-derived normal extraction. Then
            ``grasps_per_object`` counts *approaches*: every grasp with at least ``n_fingers``
            touching fingers gives one row, so objects get different row counts.
        hand_fingers: with ``source="geometric"`` or ``"hand"``, the fingers of the simulated hand
            (default ``n_fingers``, which with ``"hand"`` must then be the hand's own count); each training grasp is a
            random ``n_fingers``-subset of the fingers that touched, which models incomplete grasps / z-finger subsets
            of a bigger hand.
        support: with ``source="geometric"`` or ``"hand"``, ``"table"`` (approaches from the upper
            hemisphere) or ``"floating"`` (the full sphere).
        hand: with ``source="hand"``, the hand (a name of
            :func:`~haptic_env.grasping.hands.load_hand` or an MJCF path).
        hand_budget: with ``source="hand"``, ``"uniform"`` (``grasps_per_object`` approaches for every object) or
            ``"balanced"`` (the same total, spread towards the objects whose grasps rarely complete;
            :func:`~haptic_env.hand_grasps.balanced_counts`).
        solid_table: with ``source="hand"``, whether the hand collides with the table (``MujocoConfig.solid_table``:
            None, the default, wherever there is one, ``support="table"``; ``False``: the visual table of the hand
            figures before 2026-12-07). Settable with the hand source only.
        heights: append the contacts' heights above the table the object rests on (``phi(heights=True)``:
            ``n`` more values; contacts are taken in the support frame of the object at its identity pose,
            :func:`~haptic_env.grasping.base.support_height`). Only for objects that keep that resting pose
            (the envs' ``"table-yaw"`` poses).
        normal_axis: with normals and ``n >= 4``, each normal's second angle is to ``t2``'s normal (``"t2"``, the
            paper's) or to the edge ``ab`` (``"ab"``: both angles in ``t1``'s frame, as the paper does for
            ``n = 3``); ``"frame"``: three angles per normal, to all three axes of ``t1``'s frame (``6n - 6`` values
            at ``n >= 3``; :func:`~haptic_env.grasp_features.phi`).
        force_closure: with ``source="surface"``, keep only the grasps in force closure at this Coulomb friction
            coefficient (``> 0``; :func:`~haptic_env.force_closure.force_closure`, its contacts' own normals; needs
            ``n_fingers >= 3``), training and validation alike. ``None`` (default): every grasp, the paper's stated
            protocol (``benchmarks/force_closure.py`` compares the two).
    """

    n_fingers: int = 4
    normals: bool = True
    grasps_per_object: int = 20_000
    contact_noise: float = 0.0
    normal_noise_deg: float = 0.0
    normalize_scale: bool = False
    scale_range: tuple[float, float] | None = None
    sampling: str = "area"
    val_fraction: float = 0.2
    seed: int = 0
    source: str = "surface"
    hand_fingers: int | None = None
    support: str = "table"
    hand: str | None = None
    hand_budget: str = "uniform"
    heights: bool = False
    normal_axis: str = "t2"
    force_closure: float | None = field(default=None, metadata={KEY_ONLY_WHEN_SET: True})
    solid_table: bool | None = field(default=None, metadata={KEY_ONLY_WHEN_SET: True})

    def __post_init__(self) -> None:
        check_whole_fields(self, (("n_fingers", 2), ("grasps_per_object", 1), ("seed", 0)))
        check_flag_fields(self, ("normals", "normalize_scale", "heights"))
        for fname in ("contact_noise", "normal_noise_deg"):
            v = getattr(self, fname)
            f = finite_number(v)
            if f is None or f < 0:
                raise ValueError(f"{fname} must be finite and >= 0, got {v!r}")
            object.__setattr__(self, fname, f)  # stored as the float: a TOML 0 keys as the command line's 0.0
        if self.scale_range is not None:
            object.__setattr__(self, "scale_range", positive_range(self.scale_range, "scale_range"))
        check_normal_axis(self.normal_axis)
        if self.sampling not in SAMPLING_METHODS:
            raise ValueError(f"sampling must be one of {SAMPLING_METHODS}, got {self.sampling!r}")
        vf = finite_number(self.val_fraction)
        if vf is None or not 0.0 <= vf < 1.0:
            raise ValueError(f"val_fraction must be in [0, 1), got {self.val_fraction!r}")
        object.__setattr__(self, "val_fraction", vf)
        if self.source not in SOURCES:
            raise ValueError(f"source must be one of {SOURCES}, got {self.source!r}")
        if self.hand_fingers is not None:
            hf = whole_number(self.hand_fingers)
            if hf is None or hf < self.n_fingers:
                raise ValueError(f"hand_fingers must be an int >= n_fingers={self.n_fingers}, "
                                 f"got {self.hand_fingers!r}")
            object.__setattr__(self, "hand_fingers", hf)
        check_support(self.support)
        check_solid_table(self.solid_table, self.support)
        if self.heights and self.support != "table":
            raise ValueError(f"heights=True measures the contacts above the table an object rests on; support "
                             f"{self.support!r} has none (use support='table')")
        if self.hand_budget not in BUDGETS:
            raise ValueError(f"hand_budget must be one of {BUDGETS}, got {self.hand_budget!r}")
        # settings of other sources were taken and ignored (the dataset command refused only --hand)
        ignored = [f"{k}={getattr(self, k)!r}" for k, default, sources in (
            ("hand_fingers", None, ("geometric", "hand")), ("support", "table", ("geometric", "hand")),
            ("hand_budget", "uniform", ("hand",)), ("solid_table", None, ("hand",)))
            if getattr(self, k) != default and self.source not in sources]
        if ignored:
            raise ValueError(f"{', '.join(ignored)} would be ignored with source={self.source!r}: hand_fingers and "
                             "support apply to the geometric and hand sources, hand_budget and solid_table to the hand "
                             "source")
        if (self.source == "hand") != (self.hand is not None):
            raise ValueError(f"hand (got {self.hand!r}) is required with source='hand' and only then "
                             f"(source={self.source!r})")
        if self.hand is not None and not isinstance(self.hand, str):
            raise ValueError(f"hand must be a hand name or an MJCF path, got {self.hand!r}")
        if self.force_closure is not None:
            mu = check_friction(self.force_closure)
            if self.source != "surface":
                raise ValueError(f"force_closure filters surface grasps (source='surface'), got source={self.source!r}")
            if self.n_fingers < 3:
                raise ValueError(f"force_closure needs n_fingers >= 3 (two point contacts never are), "
                                 f"got n_fingers={self.n_fingers}")
            object.__setattr__(self, "force_closure", mu)

    def key_config(self) -> DatasetConfig:
        """This config as the cache keys read it: the settings its grasps ignore at their defaults (``sampling`` with
        the geometric and hand sources, ``normal_noise_deg`` and ``normal_axis`` without normals, the latter since
        2026-12-07), so that configs that give the same grasps share their cached files. A config at those defaults
        is itself (its keys are as before).
        ``hand_fingers`` None (the geometric and hand sources: ``n_fingers``) is keyed as ``n_fingers``, as the envs
        give it, which gives the same grasps (since 2026-12-07; before, the dataset command's and the hand benchmarks'
        None kept files apart from the envs'). The hand source's table is keyed as its pool keys it: a solid one (the
        default, ``None``, resolved) as ``True``, the visual one unkeyed, as before 2026-12-07."""
        fields = type(self).__dataclass_fields__
        keyed_as = ([("sampling", fields["sampling"].default)] if self.source != "surface" else []) + (
            [] if self.normals else [("normal_noise_deg", fields["normal_noise_deg"].default),
                                     ("normal_axis", fields["normal_axis"].default)])
        if self.source != "surface":
            keyed_as.append(("hand_fingers", self.hand_fingers or self.n_fingers))
        if self.source == "hand":
            keyed_as.append(("solid_table", True if check_solid_table(self.solid_table, self.support) else None))
        changed = {k: v for k, v in keyed_as if getattr(self, k) != v}
        return replace(self, **changed) if changed else self

    def source_key(self) -> str:
        """The identity of the grasp source beyond this config (and, for two contacts with heights, of their grasp
        vectors' code: ``_PHI2_HEIGHTS``): for ``source="hand"`` the pools' cache version
        (:data:`~haptic_env.hand_grasps.POOL_VERSION`: a new pool format gives new data sets too), the hand's physics
        (:func:`~haptic_env.hand_grasps.hand_physics_key`) and, for a balanced budget, how its pool is spread
        (:func:`~haptic_env.hand_grasps.budget_key`), else empty. Part of every cache key built on it."""
        # two contacts' heights in finger order where their normals do not order them: before 2026-12-07 (now lower
        # first, finger-order invariant), so such vectors are keyed apart from the files made before
        phi2 = [_PHI2_HEIGHTS] if self.n_fingers == 2 and self.heights else []
        if self.source != "hand":
            return ":".join(phi2)
        from .hand_grasps import POOL_VERSION, budget_key, hand_physics_key

        return ":".join([POOL_VERSION, hand_physics_key(self.hand, self.hand_fingers or self.n_fingers),
                         *budget_key(self.hand_budget, self.grasps_per_object), *phi2])

    @property
    def feature_dim(self) -> int:
        """Length ``d`` of a grasp vector."""
        return feature_dim(self.n_fingers, self.normals, heights=self.heights, normal_axis=self.normal_axis)


@dataclass(frozen=True)
class GraspDataset:
    """Grasp vectors and object labels, split per object into train and validation.

    Rows are grouped by object (label order = ``names`` order), not shuffled.

    Attributes:
        X_train: ``(N, d)`` float32; y_train: ``(N,)`` int64 labels into ``names``.
        X_val: ``(M, d)`` float32; y_val: ``(M,)`` int64.
        names: object names (class ``k`` is ``names[k]``).
        config: the :class:`DatasetConfig` that produced it.
        cache_path: the ``.npz`` it was read from / written to, if cached.
        from_cache: whether it was read from the cache.
    """

    X_train: np.ndarray
    y_train: np.ndarray
    X_val: np.ndarray
    y_val: np.ndarray
    names: tuple[str, ...]
    config: DatasetConfig
    cache_path: Path | None = None
    from_cache: bool = False

    @property
    def n_classes(self) -> int:
        return len(self.names)

    @property
    def feature_dim(self) -> int:
        return self.X_train.shape[1]

    def counts(self) -> dict[str, tuple[int, int]]:
        """``{name: (train rows, validation rows)}``."""
        tr = np.bincount(self.y_train, minlength=self.n_classes)
        va = np.bincount(self.y_val, minlength=self.n_classes)
        return {n: (int(tr[k]), int(va[k])) for k, n in enumerate(self.names)}


# ------------------------------------------------------------------------------------- grasps
def sample_grasps(
    obj: GraspObject, count: int, n_fingers: int, rng: np.random.Generator, *, sampling: str = "area"
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` random grasps of ``n_fingers`` independent surface contacts.

    Returns:
        ``contacts (count, n, 3)`` in metres and inward unit ``normals (count, n, 3)``.
    """
    n, c = whole_at_least(n_fingers, 1, "n_fingers"), whole_at_least(count, 0, "count")
    pts, nrm = obj.sample_surface(c * n, rng, sampling)
    shape = (c, n, 3)
    return pts.reshape(shape), nrm.reshape(shape)


def held_grasps(
    obj: GraspObject, count: int, n_fingers: int, rng: np.random.Generator, mu: float, *, sampling: str = "area",
    chunk: int = 200_000, edges: int = DEFAULT_EDGES, frame: str = FRAMES[0],
) -> tuple[np.ndarray, np.ndarray]:
    """The grasps among ``count`` random ones (:func:`sample_grasps`) that are in force closure with friction ``mu``
    (:func:`~haptic_env.force_closure.force_closure`, pyramids of ``edges`` edges turned by ``frame``), drawn
    ``chunk`` at a time to bound the memory.

    Returns:
        ``contacts (m, n, 3)`` and inward ``normals (m, n, 3)`` with ``m <= count``.
    """
    Cs, Ns = [], []
    for lo in range(0, int(count), int(chunk)):
        C, N = sample_grasps(obj, min(int(chunk), int(count) - lo), n_fingers, rng, sampling=sampling)
        held = force_closure(C, N, mu, edges, frame=frame)
        Cs.append(C[held])
        Ns.append(N[held])
    if not Cs:
        return np.zeros((0, int(n_fingers), 3)), np.zeros((0, int(n_fingers), 3))
    return np.concatenate(Cs), np.concatenate(Ns)


def draw_held_grasps(
    obj: GraspObject, count: int, n_fingers: int, rng: np.random.Generator, mu: float, *, sampling: str = "area",
    edges: int = DEFAULT_EDGES, frame: str = FRAMES[0],
) -> tuple[np.ndarray, np.ndarray]:
    """Exactly ``count`` grasps in force closure with friction ``mu``: :func:`held_grasps` of ``4 * count`` random
    grasps at a time until there are enough (the first ``count`` kept; ``sampling``: the surface sampling method;
    ``edges``, ``frame``: the pyramids'). A ``ValueError`` for ``n_fingers < 3`` (two point contacts are never in
    closure) and a ``RuntimeError`` after ``_MAX_TOPUP_ROUNDS`` rounds without enough (it looped forever).

    Returns:
        ``contacts (count, n, 3)`` and inward ``normals (count, n, 3)``.
    """
    count = whole_at_least(count, 0, "count")
    if whole_at_least(n_fingers, 1, "n_fingers") < 3:
        raise ValueError(f"force closure needs n_fingers >= 3 (two point contacts never are), got {n_fingers}")
    parts, have = [], 0
    for _ in range(_MAX_TOPUP_ROUNDS):
        if have >= count and parts:
            break
        parts.append(held_grasps(obj, 4 * count, n_fingers, rng, mu, sampling=sampling, edges=edges, frame=frame))
        have += len(parts[-1][0])
    else:
        if have < count:
            raise RuntimeError(f"object {obj.name!r}: only {have} of {count} random {n_fingers}-contact grasps in "
                               f"force closure (mu={mu}) after {_MAX_TOPUP_ROUNDS} rounds of {4 * count}")
    C, N = (np.concatenate(a)[:count] for a in zip(*parts))
    return C, N


def approach_grasps(
    obj: GraspObject, count: int, n_fingers: int, rng: np.random.Generator, *,
    hand_fingers: int | None = None, support: str = "table",
) -> tuple[np.ndarray, np.ndarray]:
    """Grasps of the geometric approach model under ``count`` uniformly random approaches.

    A ``hand_fingers``-finger geometric hand (default ``n_fingers``) closes on ``obj`` (identity
    pose) along random approaches; grasps where fewer than ``n_fingers`` fingers touched are
    dropped, and of the others a random ``n_fingers``-subset of the touching fingers is kept.

    Returns:
        ``contacts (m, n, 3)`` and inward ``normals (m, n, 3)`` with ``m <= count``.
    """
    from .grasping import make_backend

    hand_n = int(hand_fingers or n_fingers)
    backend = make_backend("geometric", n_fingers=hand_n, support=support, normals=True)
    backend.set_object(obj)
    actions = rng.uniform(-1.0, 1.0, size=(int(count), backend.action_dim)).astype(np.float32)
    batch = backend.grasp_batch(actions, rng)
    ok = batch.touched.sum(axis=1) >= n_fingers
    keys = rng.random(batch.touched.shape) + 2.0 * ~batch.touched  # touching fingers sort first
    pick = np.argsort(keys, axis=1)[ok, :n_fingers, None]
    C = np.take_along_axis(batch.contacts[ok], pick, axis=1)
    N = np.take_along_axis(batch.normals[ok], pick, axis=1)
    return C, N


def _tilt(normals: np.ndarray, std_rad: float, rng: np.random.Generator) -> np.ndarray:
    """Rotate each unit normal by ``|N(0, std)|`` towards a uniformly random perpendicular direction."""
    r = rng.standard_normal(normals.shape)
    t = r - np.sum(r * normals, -1, keepdims=True) * normals
    tn = np.linalg.norm(t, axis=-1, keepdims=True)
    t = t / np.where(tn > 0, tn, 1.0)
    ang = std_rad * rng.standard_normal(normals.shape[:-1])[..., None]
    return np.cos(ang) * normals + np.sin(ang) * t


def grasp_vectors(
    contacts: np.ndarray,
    normals: np.ndarray | None,
    config: DatasetConfig,
    *,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Apply the sensing model of ``config`` and map grasps to grasp vectors.

    In order: object scale ``U(scale_range)`` per grasp (about the object's centre, which is the
    origin), Gaussian contact noise, normal tilt noise, optional scale normalisation, then
    :func:`~haptic_env.grasp_features.phi`.

    Args:
        contacts: ``(G, n, 3)`` contacts in metres (with ``config.heights``: in the support frame, z up and
            ``z = 0`` on the table top; :func:`support_frame`).
        normals: ``(G, n, 3)`` inward unit normals; required when ``config.normals``, ignored otherwise.
        config: the dataset config (``n`` must equal ``config.n_fingers``).
        rng: randomness of scale and noise (default ``default_rng(config.seed)``).

    Returns:
        ``X (G, d)`` float64 grasp vectors (zero rows where invalid) and ``valid (G,)`` bool
        (False for degenerate grasps: coincident / collinear / coplanar contacts).
    """
    P = np.asarray(contacts, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] != (config.n_fingers, 3):
        raise ValueError(f"contacts must have shape (G, {config.n_fingers}, 3), got {P.shape}")
    N = None
    if config.normals:
        if normals is None:
            raise ValueError("config.normals is True but no normals were given")
        N = np.asarray(normals, dtype=np.float64)
        if N.shape != P.shape:
            raise ValueError(f"normals must have the shape of contacts {P.shape}, got {N.shape}")
    rng = np.random.default_rng(config.seed) if rng is None else rng
    if config.scale_range is not None:
        lo, hi = config.scale_range
        P = P * rng.uniform(lo, hi, size=(P.shape[0], 1, 1))
    if config.contact_noise > 0:
        P = P + rng.normal(0.0, config.contact_noise, size=P.shape)
    if N is not None and config.normal_noise_deg > 0:
        N = _tilt(N, np.deg2rad(config.normal_noise_deg), rng)
    if config.normalize_scale:
        P, _ = normalize_scale(P)
    feats = phi(P, N, heights=config.heights, normal_axis=config.normal_axis)
    return feats.q, feats.valid


def support_frame(contacts: np.ndarray, obj: GraspObject, config: DatasetConfig) -> np.ndarray:
    """Contacts ``(G, n, 3)`` of ``obj`` at its identity pose (object frame) in the frame ``grasp_vectors`` reads:
    with ``config.heights`` moved down by the table top's height (:func:`~haptic_env.grasping.base.support_height`),
    otherwise unchanged (the same array)."""
    if not config.heights:
        return contacts
    return contacts - np.array([0.0, 0.0, support_height(obj.mesh.vertices)])


def _object_grasps(obj: GraspObject, config: DatasetConfig, rng: np.random.Generator) -> np.ndarray:
    """Exactly ``grasps_per_object`` valid grasp vectors of one object, ``(G, d)`` float32."""
    need = config.grasps_per_object
    parts: list[np.ndarray] = []
    have = 0
    asked = 0
    for _ in range(_MAX_TOPUP_ROUNDS):
        # ask for what is missing, scaled by the yield seen so far (approach grasps can miss often)
        rate = max(have / asked, 0.01) if asked else 1.0
        batch = max(64, int(np.ceil(1.2 * (need - have) / rate))) if parts else need
        asked += batch
        if config.source == "geometric":
            C, N = approach_grasps(obj, batch, config.n_fingers, rng, hand_fingers=config.hand_fingers,
                                   support=config.support)
        elif config.force_closure is not None:
            C, N = held_grasps(obj, batch, config.n_fingers, rng, config.force_closure, sampling=config.sampling)
        else:
            C, N = sample_grasps(obj, batch, config.n_fingers, rng, sampling=config.sampling)
        X, valid = grasp_vectors(support_frame(C, obj, config), N if config.normals else None, config, rng=rng)
        X = X[valid][: need - have]
        parts.append(X.astype(np.float32))
        have += len(X)
        if have >= need:
            return np.concatenate(parts)
    raise RuntimeError(
        f"object {obj.name!r}: only {have} of {need} {config.source} {config.n_fingers}-contact grasps are "
        f"non-degenerate after {_MAX_TOPUP_ROUNDS} rounds (is the mesh flat or tiny, or does the hand miss it?)"
    )


def dataset_cache_path(objects: ObjectSet, config: DatasetConfig) -> Path:
    """Where :func:`build_dataset` caches the dataset of ``objects`` under ``config``."""
    key = config_key(_CACHE_VERSION, objects.identity, config.key_config(), *filter(None, [config.source_key()]))
    return cache_dir("datasets") / f"{file_stem(objects.name, 'objects')}-{key}.npz"


def _from_arrays(arrays: dict, objects: ObjectSet, config: DatasetConfig, path: Path) -> GraspDataset:
    d = config.feature_dim
    names = tuple(str(n) for n in arrays["names"])
    if names != objects.names:
        raise CacheError(f"cache file {path} holds objects {names}, expected {objects.names}")
    for x, y in (("X_train", "y_train"), ("X_val", "y_val")):
        X, Y = arrays[x], arrays[y]
        if X.ndim != 2 or X.shape[1] != d or Y.shape != (X.shape[0],):
            raise CacheError(f"cache file {path}: {x} has shape {X.shape}, {y} {Y.shape}; expected (N, {d}), (N,)")
    return GraspDataset(
        arrays["X_train"].astype(np.float32, copy=False),
        arrays["y_train"].astype(np.int64, copy=False),
        arrays["X_val"].astype(np.float32, copy=False),
        arrays["y_val"].astype(np.int64, copy=False),
        names,
        config,
        cache_path=path,
        from_cache=True,
    )


def build_dataset(
    objects: ObjectSet, config: DatasetConfig, *, cache: bool = True, progress: bool = True, workers: int | None = None
) -> GraspDataset:
    """Grasp vectors of every object of ``objects``, split per object into train and validation.

    Every object gets exactly ``config.grasps_per_object`` valid grasps (degenerate ones are
    resampled); the first ``round(val_fraction * G)`` of a random permutation go to validation.
    Object ``k`` draws from its own stream ``SeedSequence(seed).spawn(K)[k]``.

    Args:
        objects: the object set (labels follow its order).
        config: generation config.
        cache: read/write ``cache_dir("datasets")/<set>-<key>.npz`` (key: object names + mesh hashes
            + config). A corrupted cache file is rebuilt with a warning.
        progress: tqdm bar over objects.
        workers: processes that build a ``source="hand"`` grasp pool (:func:`hand_pool`; default: all cores). Not
            in the cache key: the pool and the data set do not depend on it.
    """
    if not isinstance(objects, ObjectSet):
        raise TypeError(f"objects must be an ObjectSet, got {type(objects).__name__}")
    path = dataset_cache_path(objects, config) if cache else None
    if path is not None and path.exists():
        try:
            return _from_arrays(load_npz(path, required=_ARRAYS), objects, config, path)
        except CacheError as exc:
            warnings.warn(f"{exc}; rebuilding it", RuntimeWarning, stacklevel=2)
    if config.source == "hand":
        ds = _hand_dataset(objects, config, path, progress, workers)
        _save_dataset(ds)
        return ds
    streams = np.random.SeedSequence(config.seed).spawn(len(objects))
    G = config.grasps_per_object
    n_val = min(int(round(config.val_fraction * G)), G - 1)  # one row at least for training, as the hand source
    Xtr, Ytr, Xva, Yva = [], [], [], []
    # force-closure grasps are slow (hours at the paper's scale): each object's split is kept until the set is saved,
    # so an interrupted build resumes at the first object not done (each object has its own random stream)
    parts = path is not None and config.force_closure is not None
    bar = tqdm(objects, desc=f"grasps ({config.n_fingers} fingers)", unit="obj", disable=not progress)
    for k, (obj, ss) in enumerate(zip(bar, streams)):
        part = _part_path(path, k) if parts else None
        done = _load_part(part)
        if done is not None:
            xtr, xva = done
        else:
            rng = np.random.default_rng(ss)
            X = _object_grasps(obj, config, rng)
            perm = rng.permutation(G)
            xva, xtr = X[perm[:n_val]], X[perm[n_val:]]
            if part is not None:
                save_npz_atomic(part, X_train=xtr, X_val=xva)
        Xva.append(xva)
        Xtr.append(xtr)
        Yva.append(np.full(n_val, k, dtype=np.int64))
        Ytr.append(np.full(G - n_val, k, dtype=np.int64))
    ds = GraspDataset(
        np.concatenate(Xtr),
        np.concatenate(Ytr),
        np.concatenate(Xva),
        np.concatenate(Yva),
        objects.names,
        config,
        cache_path=path,
    )
    _save_dataset(ds)
    if parts:
        for k in range(len(objects)):
            _part_path(path, k).unlink(missing_ok=True)
    return ds


def _part_path(path: Path, k: int) -> Path:
    """Where object ``k``'s finished split waits while the data set at ``path`` is built (hidden, beside it)."""
    return path.with_name(f".{path.stem}.obj{k}.npz")


def _load_part(part: Path | None) -> tuple[np.ndarray, np.ndarray] | None:
    """An object's saved ``(X_train, X_val)``, or None (none, or unreadable: then it is generated again)."""
    if part is None or not part.exists():
        return None
    try:
        arrays = load_npz(part, required=("X_train", "X_val"))
    except FileNotFoundError:  # another process finished the dataset and removed its parts since the check
        return None
    except CacheError as exc:
        warnings.warn(f"{exc}; generating that object again", RuntimeWarning, stacklevel=3)
        return None
    return arrays["X_train"], arrays["X_val"]


def _save_dataset(ds: GraspDataset) -> None:
    if ds.cache_path is not None:
        save_npz_atomic(ds.cache_path, X_train=ds.X_train, y_train=ds.y_train, X_val=ds.X_val, y_val=ds.y_val,
                        names=np.array(ds.names, dtype=str))


def hand_pool(objects: ObjectSet, config: DatasetConfig, progress: bool = True, *, cache: bool = True,
              workers: int | None = None):
    """The hand grasp pool (:func:`~haptic_env.hand_grasps.hand_grasp_pool`, cached unless ``cache`` is false) that
    ``source="hand"`` training grasps of ``config`` come from: its hand, ``hand_fingers`` (default ``n_fingers``),
    approaches, support, seed and budget. The training grasps and the recogniser's touch model read this one pool.
    ``workers``: the processes that build it (default: all cores; the pool does not depend on them)."""
    from .hand_grasps import hand_grasp_pool

    return hand_grasp_pool(objects, **_pool_settings(config), progress=progress, cache=cache, workers=workers)


def _pool_settings(config: DatasetConfig) -> dict:
    """The settings of ``config``'s hand grasp pool, as :func:`~haptic_env.hand_grasps.hand_grasp_pool` and
    :func:`~haptic_env.hand_grasps.pool_cache_path` take them (one mapping for the pool and its cache file)."""
    if config.source != "hand":
        raise ValueError(f"only source='hand' grasps come from a hand grasp pool, got source={config.source!r}")
    return {"hand": config.hand, "n_fingers": config.hand_fingers or config.n_fingers,
            "approaches": config.grasps_per_object, "support": config.support, "seed": config.seed,
            "budget": config.hand_budget, "solid_table": config.solid_table}


def _hand_rows(objects: ObjectSet, config: DatasetConfig, progress: bool, cache: bool = True,
               workers: int | None = None):
    """Yield ``(k, X, rng, C)`` per object: the valid ``n_fingers``-finger grasp vectors (float32) of ``source="hand"``,
    the object's generator, positioned for the train/validation split, and the rows' contacts ``(G_k, n, 3)`` in the
    object's frame."""
    from .hand_grasps import pool_rows

    pool = hand_pool(objects, config, progress, cache=cache, workers=workers)
    streams = np.random.SeedSequence([config.seed, 1]).spawn(len(objects))
    for k, ss in enumerate(streams):
        rng = np.random.default_rng(ss)
        C, N = pool_rows(pool, k, config.n_fingers, rng)
        X, valid = grasp_vectors(support_frame(C, objects[k], config), N if config.normals else None, config, rng=rng)
        yield k, X[valid].astype(np.float32), rng, C[valid]


def hand_vectors(objects: ObjectSet, config: DatasetConfig, progress: bool = True, *,
                 contacts: bool = False) -> list[np.ndarray] | list[tuple[np.ndarray, np.ndarray]]:
    """``source="hand"``: every object's valid grasp vectors ``(G_k, d)`` float32, unsplit; an object that the hand
    never touched with ``n_fingers`` fingers gets ``G_k = 0`` rows (where :func:`build_dataset` raises), so a caller can
    report which objects a hand cannot grasp. With ``contacts``, ``(X, C)`` per object: also each row's contacts
    ``(G_k, n_fingers, 3)`` in the object's (mesh) frame, to ask where on the object a grasp touched."""
    return [(X, C) if contacts else X for _, X, _, C in _hand_rows(objects, config, progress)]


def hand_dataset(objects: ObjectSet, config: DatasetConfig, *, progress: bool = True,
                 min_rows: int = 2) -> tuple[GraspDataset, dict[str, int]]:
    """``source="hand"``: the rows of a hand grasp pool split per object (as :func:`build_dataset`, uncached: the pool
    is), leaving out each object that the hand touched with ``n_fingers`` fingers fewer than ``min_rows`` times.

    Returns the dataset (labels stay the positions in ``objects``; a left-out object has no rows) and the left-out
    objects with their row counts, so that a caller can report them (a family of random members, say, where the
    hand cannot grasp every member). Raises if no object is left."""
    whole_at_least(min_rows, 1, "hand_dataset: min_rows")
    ds, left_out = _split_hand_rows(objects, config, progress, min_rows)
    if ds is None:
        raise TooFewGraspsError(f"none of the {len(objects)} objects was touched with >= {config.n_fingers} fingers "
                                f"(non-degenerate) in {min_rows} of its {config.hand} grasps (budget "
                                f"{config.hand_budget!r}, {config.grasps_per_object} approaches per object)")
    return ds, left_out


def _split_hand_rows(objects: ObjectSet, config: DatasetConfig, progress: bool, min_rows: int, cache: bool = True,
                     workers: int | None = None) -> tuple[GraspDataset | None, dict[str, int]]:
    Xtr, Ytr, Xva, Yva, left_out = [], [], [], [], {}
    for k, X, rng, _ in _hand_rows(objects, config, progress, cache, workers):
        if len(X) < min_rows:
            left_out[objects.names[k]] = len(X)
            continue
        n_val = min(int(round(config.val_fraction * len(X))), len(X) - 1)  # one row at least for training
        perm = rng.permutation(len(X))
        Xva.append(X[perm[:n_val]])
        Xtr.append(X[perm[n_val:]])
        Yva.append(np.full(n_val, k, dtype=np.int64))
        Ytr.append(np.full(len(X) - n_val, k, dtype=np.int64))
    if not Xtr:
        return None, left_out
    return GraspDataset(np.concatenate(Xtr), np.concatenate(Ytr), np.concatenate(Xva), np.concatenate(Yva),
                        objects.names, config), left_out


def _hand_dataset(objects: ObjectSet, config: DatasetConfig, path: Path | None, progress: bool,
                  workers: int | None = None) -> GraspDataset:
    """``source="hand"`` for :func:`build_dataset`: every object must have a row (its hand pool cached when the
    dataset is, ``path`` not None). An object with one (the Aero's 5-finger grasps of the plate on a solid table: 1 in
    6,000 approaches) keeps it for training and has no validation rows: its density is that one kernel, and its touch
    pattern (:mod:`~haptic_env.recognizers.touch`) says how rarely such a grasp happens."""
    ds, left_out = _split_hand_rows(objects, config, progress, 1, cache=path is not None, workers=workers)
    if left_out:
        name, n = next(iter(left_out.items()))
        raise TooFewGraspsError(f"object {name!r}: {n} of its {config.hand} grasps (budget {config.hand_budget!r}, "
                                f"{config.grasps_per_object} approaches per object) touched it with >= "
                                f"{config.n_fingers} fingers (non-degenerate); use more approaches or fewer fingers")
    return replace(ds, cache_path=path)


# ---------------------------------------------------------------------------------------- CLI
def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``dataset`` sub-command."""
    p = subparsers.add_parser("dataset", help="generate (or load cached) training grasp vectors",
                              description="Generate training grasp vectors for an object set.")
    p.add_argument("--objects", default="default",
                   help="default | families[:N] | kit8 | kit20 | ycb10 | a folder of STL/OBJ/PLY (default: default)")
    p.add_argument("--units", default="m", help="units of a folder's mesh files: m, cm, mm or metres per unit")
    p.add_argument("--up", default="z", choices=UP_AXES,
                   help="a folder's mesh files' up axis, turned to z (named sets know theirs: KIT y)")
    from haptic_env.cli import float_in, int_in, output_path

    p.add_argument("--fingers", type=int_in(2, MAX_CLI_FINGERS), default=4,
                   help=f"contacts per grasp, 2..{MAX_CLI_FINGERS} (default 4)")
    p.add_argument("--no-normals", action="store_true", help="grasp vectors without contact normals")
    p.add_argument("--grasps", type=int_in(1), default=20_000, help="grasps per object (default 20000)")
    p.add_argument("--noise", type=float_in(0.0), default=0.0, help="contact noise std in metres (default 0)")
    p.add_argument("--normal-noise", type=float_in(0.0), default=0.0,
                   help="normal tilt noise std in degrees (default 0)")
    p.add_argument("--normalize-scale", action="store_true", help="scale-normalise every grasp (Theorem 2)")
    p.add_argument("--scale-range", type=float_in(0.0, lo_open=True), nargs=2, metavar=("LO", "HI"), default=None,
                   help="random per-grasp object scale U(LO, HI)")
    p.add_argument("--sampling", choices=SAMPLING_METHODS, default="area", help="surface sampling (default area)")
    p.add_argument("--force-closure", type=float_in(0.0, lo_open=True), default=None, metavar="MU",
                   help="surface source: keep only grasps in force closure at this friction coefficient (default: all)")
    p.add_argument("--val-fraction", type=float_in(0.0, 1.0, hi_open=True), default=0.2,
                   help="validation fraction in [0, 1) (default 0.2)")
    p.add_argument("--source", choices=SOURCES, default="surface",
                   help="surface: n random surface points (paper); geometric: random approaches of the "
                        "geometric hand model; hand: random approaches of a robot hand's MuJoCo model (--hand; "
                        "--grasps then counts approaches per object) (default surface)")
    p.add_argument("--hand", default=None,
                   help="hand source: allegro | shadow | aero | robotiq | generic | an MJCF path")
    p.add_argument("--hand-fingers", type=int_in(2, MAX_CLI_FINGERS), default=None,
                   help="geometric / hand source: fingers of the simulated hand (default --fingers)")
    p.add_argument("--support", choices=SUPPORTS, default="table",
                   help="geometric / hand source: approaches from the upper hemisphere (table) or the sphere")
    p.add_argument("--hand-budget", choices=BUDGETS, default=DatasetConfig.hand_budget,
                   help="hand source: the same approaches for every object, or the same total spread towards the "
                        "objects whose grasps rarely complete (default %(default)s)")
    p.add_argument("--visual-table", action="store_true",
                   help="hand source: a visual table the hand can reach into, the scene of the hand figures before "
                        "2026-12-07 (default: the hand collides with the table)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=output_path("file"), default=None, help="also write the dataset to this .npz")
    p.add_argument("--no-cache", action="store_true",
                   help="neither read nor write the data set's cache (nor, for the hand source, its grasp pool's); "
                        "the MuJoCo hand's collision pieces of a mesh are still read from and written to "
                        "$HAPTIC_CACHE/collision (a decomposition, a shipped piece's convexity verdict)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_run_cli)
    return p


def _run_cli(args: argparse.Namespace) -> int:
    from haptic_env.cli import UsageError

    t0 = time.perf_counter()
    try:
        objects = load_object_set(args.objects, units=args.units, up=args.up)
        config = _cli_config(args)
        if config.source == "hand":  # an unknown --hand is named before any grasp
            from haptic_env.grasping.hands import load_hand

            load_hand(config.hand, config.hand_fingers or config.n_fingers)  # and its finger count
    except (ValueError, TypeError, FileNotFoundError) as exc:  # bad --objects / --units / --hand / combinations
        raise UsageError(str(exc)) from exc
    try:
        ds = build_dataset(objects, config, cache=not args.no_cache, progress=not args.quiet)
    except TooFewGraspsError as exc:  # --grasps / --fingers too few for the hand (found once it has grasped)
        raise UsageError(f"{exc} (--grasps, --fingers)") from None
    if args.out is not None:
        save_npz_atomic(args.out, X_train=ds.X_train, y_train=ds.y_train, X_val=ds.X_val, y_val=ds.y_val,
                        names=np.array(ds.names, dtype=str))
    _print_summary(args, objects, config, ds, time.perf_counter() - t0)
    return 0


def _cli_config(args: argparse.Namespace) -> DatasetConfig:
    # flags the config keys as fixed where they change nothing: taken and ignored on the command line before
    if args.sampling != "area" and args.source != "surface":
        raise ValueError(f"--sampling {args.sampling} samples surface points: it needs --source surface, got --source "
                         f"{args.source}")
    if args.normal_noise > 0 and args.no_normals:
        raise ValueError(f"--normal-noise {args.normal_noise:g} tilts the normals that --no-normals leaves out (drop "
                         "one of them)")
    return DatasetConfig(
        n_fingers=args.fingers,
        normals=not args.no_normals,
        grasps_per_object=args.grasps,
        contact_noise=args.noise,
        normal_noise_deg=args.normal_noise,
        normalize_scale=args.normalize_scale,
        scale_range=tuple(args.scale_range) if args.scale_range else None,
        sampling=args.sampling,
        val_fraction=args.val_fraction,
        seed=args.seed,
        source=args.source,
        hand_fingers=args.hand_fingers,
        support=args.support,
        hand=args.hand,
        hand_budget=args.hand_budget,
        force_closure=args.force_closure,
        solid_table=False if args.visual_table else None,
    )


def _print_summary(args: argparse.Namespace, objects, config: DatasetConfig, ds, dt: float) -> None:
    print(f"objects: {objects.name} ({len(objects)})  fingers: {config.n_fingers}  normals: {config.normals}  "
          f"d = {ds.feature_dim}")
    print(f"X_train {ds.X_train.shape}  X_val {ds.X_val.shape}")
    width = max(len(n) for n in ds.names)
    for name, (tr, va) in ds.counts().items():
        print(f"  {name:<{width}}  train {tr:>7}  val {va:>7}")
    from .hand_grasps import pool_cache_path

    if config.source == "hand" and not args.no_cache and pool_cache_path(objects, **_pool_settings(config)).is_file():
        # reading the cached pool back gives its build time (a pool not in the cache, e.g. a read-only one, was
        # grasped a second time here just to print it)
        pool = hand_pool(objects, config, progress=False)
        print(f"hand grasps ({config.hand}): {pool.touched.shape[1]} approaches x {len(objects)} objects built in "
              f"{pool.seconds:.1f} s ({pool.grasps_per_second:.0f} grasps/s on all cores)")
    src = "hit" if ds.from_cache else ("written" if ds.cache_path else "disabled")
    print(f"cache: {ds.cache_path if ds.cache_path else '-'} ({src})")
    if args.out is not None:
        print(f"written: {args.out}")
    print(f"seconds: {dt:.2f}")
