"""Graspable objects, object sets and fast surface sampling.

A :class:`GraspObject` is a named triangle mesh in metres, centred so that the centre of its
axis-aligned bounding box is the origin. Surface samples come with INWARD unit normals (the
direction a fingertip pushes into the object), the convention shared by every grasp backend.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np
import trimesh

from ..numbers import positive_number

__all__ = ["GraspObject", "ObjectSet", "SAMPLING_METHODS", "UP_AXES", "prepare_mesh", "up_rotation"]

#: Surface sampling methods of :meth:`GraspObject.sample_surface`.
SAMPLING_METHODS = ("area", "centroid")

#: A mesh file's up axis (:func:`up_rotation`): the axis that points up when the object stands on a table.
UP_AXES = ("x", "y", "z")
#: how a physics backend collides shipped pieces, in the cache keys of objects that ship them
#: (:func:`haptic_env.grasping.collision.convex_pieces`): since 2026-12-07 a non-convex shipped piece is decomposed
PIECES_RULE = "convex-checked"


def up_rotation(up: str) -> np.ndarray:
    """``(3, 3)`` proper rotation that turns a file's ``up`` axis into +z (the world's up), the identity for "z".

    "y" (e.g. the KIT meshes): a quarter turn about x, ``(x, y, z) -> (x, -z, y)``; "x": a quarter turn about y,
    ``(x, y, z) -> (-z, y, x)``. Proper rotations keep the winding and so the outward normals.
    """
    if up == "z":
        return np.eye(3)
    if up == "y":
        return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    if up == "x":
        return np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    raise ValueError(f"up axis must be one of {UP_AXES}, got {up!r}")


def prepare_mesh(mesh: trimesh.Trimesh, name: str, scale: float = 1.0, up: str = "z") -> tuple[trimesh.Trimesh, np.ndarray]:
    """Validate, scale, stand up (:func:`up_rotation`), orient outward and centre a mesh (a new mesh; the input is
    untouched).

    Returns:
        the prepared mesh and the ``(3,)`` translation applied after scaling and turning (to centre it).

    Raises:
        ValueError: naming ``name`` if the mesh has no faces or non-finite vertices, ``scale`` is not a finite number
            > 0, or the mesh is flat (its vertices in one plane: it has no inside, so no inward normal).
    """
    if not isinstance(mesh, trimesh.Trimesh):
        raise TypeError(f"object {name!r}: expected a trimesh.Trimesh, got {type(mesh).__name__}")
    if len(mesh.faces) == 0:
        raise ValueError(f"object {name!r}: mesh has no faces")
    if not np.isfinite(mesh.vertices).all():
        raise ValueError(f"object {name!r}: mesh has non-finite vertices")
    R = up_rotation(up)  # first: a bad axis is named before any work
    scale = positive_number(scale, f"object {name!r}: scale")
    v = np.asarray(mesh.vertices, dtype=np.float64)[np.unique(mesh.faces)]  # an unused vertex off the plane let
    spread = np.linalg.eigvalsh(np.cov(v.T)) if len(v) > 1 else np.zeros(3)  # a flat sheet through; ascending
    if not spread[0] > 1e-12 * spread[-1]:  # std along the thinnest axis < 1e-6 x along the widest
        raise ValueError(f"object {name!r}: mesh is flat (its vertices lie in one plane, or on a line), so it has no "
                         "inside to grasp and no inward normal")
    m = mesh.copy()
    if scale != 1.0:
        m.apply_scale(scale)
    if up != "z":
        T = np.eye(4)
        T[:3, :3] = R
        m.apply_transform(T)
    m.remove_unreferenced_vertices()
    # Outward winding: faces wound against their neighbours are turned to agree first (without that the volume is
    # meaningless and those faces' normals point inward), then a (nearly) closed mesh has positive signed volume.
    if not m.is_winding_consistent:
        trimesh.repair.fix_winding(m)
    with np.errstate(divide="ignore", invalid="ignore"):  # a flat mesh has volume 0 (its centre of mass: 0 / 0)
        if m.is_winding_consistent and m.volume < 0:
            m.invert()
    offset = -m.bounds.mean(axis=0)
    m.apply_translation(offset)
    return m, offset


def piece_file(path, object_name: str) -> Path:
    """A shipped collision piece's ``path`` as a Path; a ``FileNotFoundError`` naming it and its object when it is
    missing (before its bytes are hashed or its mesh loaded)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"collision piece {p} of object {object_name!r} is missing")
    return p


@dataclass(frozen=True, eq=False)
class GraspObject:
    """A named rigid object to grasp.

    Attributes:
        name: unique name within its :class:`ObjectSet`.
        mesh: triangle mesh in metres, bounding-box centre at the origin, outward winding.
        family: optional geometry family label (``"box"``, ``"elliptic_cylinder"``,
            ``"ellipsoid"`` for :func:`~haptic_env.objects.family_set`).
        source: file the mesh was read from (``None`` for generated meshes).
        collision_paths: convex pieces of a decomposition (YCB ``collision_NN.stl``, metres, in
            the file's frame: NOT re-centred) for physics backends; empty when none is shipped.
        offset: ``(3,)`` translation that was applied to the file's coordinates (scaled and turned by
            :attr:`rotation`) to centre the mesh.
        rotation: ``(3, 3)`` rotation that stood the file's coordinates up (:func:`up_rotation`; the identity for
            a z-up file). ``collision_paths`` geometry matches :attr:`mesh` as
            ``(unit_scale * p) @ rotation.T + offset``.
        unit_scale: metres per unit of the files (:attr:`source` and :attr:`collision_paths`; 1 for metre files).
    """

    name: str
    mesh: trimesh.Trimesh
    family: str | None = None
    source: Path | None = None
    collision_paths: tuple[Path, ...] = ()
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    unit_scale: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"object name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.mesh, trimesh.Trimesh) or len(self.mesh.faces) == 0:
            raise ValueError(f"object {self.name!r}: mesh must be a trimesh.Trimesh with faces")
        if not np.isfinite(self.mesh.vertices).all():
            raise ValueError(f"object {self.name!r}: mesh has non-finite vertices")

    # ------------------------------------------------------------------ cached geometry tables
    @cached_property
    def _tables(self) -> dict[str, np.ndarray]:
        tri = np.asarray(self.mesh.triangles, dtype=np.float64)  # (F, 3, 3)
        e1 = tri[:, 1] - tri[:, 0]
        e2 = tri[:, 2] - tri[:, 0]
        cr = np.cross(e1, e2)
        dbl = np.linalg.norm(cr, axis=1)
        ok = dbl > 0
        if not ok.any():
            raise ValueError(f"object {self.name!r}: every face has zero area")
        inward = np.zeros_like(cr)
        inward[ok] = -cr[ok] / dbl[ok, None]
        area = 0.5 * dbl
        return {
            # rows: first vertex, two edges, inward normal -> one gather per sample
            "table": np.ascontiguousarray(np.stack([tri[:, 0], e1, e2, inward], axis=1)),
            "p": area / area.sum(),
            "area": float(area.sum()),
            "good": np.flatnonzero(ok),
            "centroid": tri.mean(axis=1),
        }

    @cached_property
    def mesh_hash(self) -> str:
        """SHA-1 of the vertices and faces (identity of the geometry for cache keys)."""
        h = hashlib.sha1()
        h.update(np.ascontiguousarray(self.mesh.vertices, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(self.mesh.faces, dtype=np.int64).tobytes())
        return h.hexdigest()

    @cached_property
    def pieces_hash(self) -> str | None:
        """SHA-1 of the shipped collision pieces (:attr:`unit_scale` and each file's bytes, in order), or None when
        none are shipped: what a physics backend collides, for cache keys."""
        if not self.collision_paths:
            return None
        h = hashlib.sha1(repr(float(self.unit_scale)).encode())
        for p in self.collision_paths:
            p = piece_file(p, self.name)
            h.update(p.name.encode())
            h.update(p.read_bytes())
        return h.hexdigest()

    @property
    def area(self) -> float:
        """Surface area in m^2."""
        return self._tables["area"]

    @property
    def extents(self) -> np.ndarray:
        """``(3,)`` bounding-box size in metres."""
        return np.array(self.mesh.extents, dtype=np.float64)  # a writable copy

    # ------------------------------------------------------------------------------ sampling
    def sample_surface(
        self, count: int, rng: np.random.Generator, method: str = "area"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Random surface points with INWARD unit normals.

        Args:
            count: number of points.
            rng: the random generator (the only source of randomness).
            method: ``"area"``: uniform over the surface (area-weighted face choice, uniform
                barycentric point); ``"centroid"``: centroids of uniformly chosen faces (the
                paper's sampling; faces of zero area are never chosen).

        Returns:
            ``points (count, 3)`` float64 and ``normals (count, 3)`` float64 unit, pointing into
            the object.
        """
        count = _check_count(count)
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        t = self._tables
        if method == "area":
            # iid area-weighted faces = multinomial face counts in a uniformly random order
            # (exactly the same distribution as per-point categorical draws, ~10x faster than
            # searchsorted on a cumulative-area table)
            counts = rng.multinomial(count, t["p"])
            idx = rng.permutation(np.repeat(np.arange(len(counts)), counts))
            g = np.take(t["table"], idx, axis=0)  # (count, 4, 3)
            r = rng.random((2, count, 1))
            lo = np.minimum(r[0], r[1])
            hi = np.maximum(r[0], r[1])
            # barycentrics (lo, hi - lo, 1 - hi) of two sorted uniforms are uniform on the triangle
            pts = g[:, 0] + (hi - lo) * g[:, 1] + (1.0 - hi) * g[:, 2]
            return pts, g[:, 3]
        if method == "centroid":
            idx = t["good"][rng.integers(0, len(t["good"]), size=count)]
            return t["centroid"][idx], t["table"][idx, 3]
        raise ValueError(f"unknown sampling method {method!r}; expected one of {SAMPLING_METHODS}")

    def __repr__(self) -> str:
        ext = "x".join(f"{e:.3f}" for e in self.extents)
        fam = f", family={self.family!r}" if self.family else ""
        return f"GraspObject({self.name!r}, {len(self.mesh.faces)} faces, {ext} m{fam})"


def _check_count(count) -> int:
    if isinstance(count, (bool, np.bool_)) or not isinstance(count, (int, np.integer)):
        raise TypeError(f"count must be an int, got {count!r}")
    if count < 0:
        raise ValueError(f"count must be >= 0, got {count}")
    return int(count)


class ObjectSet:
    """An immutable, ordered collection of :class:`GraspObject` with unique names.

    Index with an int (position = class label) or a name. ``families`` maps object name to its
    family label for sets whose objects carry one.
    """

    __slots__ = ("_name", "_objects", "_index")

    def __init__(self, name: str, objects) -> None:
        objs = tuple(objects)
        if not objs:
            raise ValueError(f"object set {name!r} is empty")
        for o in objs:
            if not isinstance(o, GraspObject):
                raise TypeError(f"object set {name!r}: expected GraspObject, got {type(o).__name__}")
        index: dict[str, int] = {}
        for i, o in enumerate(objs):
            if o.name in index:
                raise ValueError(f"object set {name!r}: duplicate object name {o.name!r}")
            index[o.name] = i
        self._name = str(name)
        self._objects = objs
        self._index = index

    @property
    def name(self) -> str:
        return self._name

    @property
    def objects(self) -> tuple[GraspObject, ...]:
        return self._objects

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self._objects)

    @property
    def families(self) -> Mapping[str, str]:
        """``{object name: family}`` for the objects that carry a family label."""
        return {o.name: o.family for o in self._objects if o.family is not None}

    @property
    def identity(self) -> list[tuple[str, str]]:
        """``[(name, mesh hash), ...]``: what a cache key of anything built from this set needs; an object that ships
        collision pieces adds ``"pieces <hash>"`` (:attr:`GraspObject.pieces_hash`, the files and their units, with
        :data:`PIECES_RULE`: how a physics backend chooses between them and a decomposition)."""
        return [(o.name, o.mesh_hash) + ((f"pieces {o.pieces_hash[:16]} {PIECES_RULE}",) if o.collision_paths else ())
                for o in self._objects]

    def index(self, name: str) -> int:
        """Position (class label) of the object called ``name``."""
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no object {name!r} in set {self._name!r}; have {list(self._index)}") from None

    def subset(self, names, name: str | None = None) -> "ObjectSet":
        """A new set with the named objects, in the given order."""
        return ObjectSet(name or f"{self._name}-subset", [self[n] for n in names])

    def __len__(self) -> int:
        return len(self._objects)

    def __iter__(self) -> Iterator[GraspObject]:
        return iter(self._objects)

    def __getitem__(self, key: int | str) -> GraspObject:
        if isinstance(key, str):
            return self._objects[self.index(key)]
        return self._objects[key]

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __repr__(self) -> str:
        return f"ObjectSet({self._name!r}, {list(self.names)})"
