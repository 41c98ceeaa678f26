"""Convex collision pieces of an object for MuJoCo (which collides meshes by their convex hulls).

Sources, in order for ``method="auto"``:

1. the object's shipped pieces (``obj.collision_paths``, e.g. YCB ``collision_NN.stl``, in the
   file frame; turned by ``obj.rotation`` and shifted by ``obj.offset`` to the centred mesh frame), when each
   is convex (its hull no more than ``convex_tol`` larger, no face centre deeper than ``convex_tol`` of its size
   inside its hull: :func:`hull_depth`).
   A shipped piece that is not (YCB's 035 power drill and 006 mustard bottle ship their whole mesh as one
   "piece") would be collided as its hull, so the object is decomposed as in 3 instead (logged);
   ``method="files"`` takes the pieces as shipped. The verdict is cached beside the decompositions (a small JSON
   keyed by the pieces' files and ``convex_tol``), so that every process and pool chunk does not test them again;
2. the convex hull, when the mesh is (nearly) convex (hull volume within ``convex_tol`` of the mesh);
3. a ``coacd`` approximate convex decomposition, cached in ``cache_dir("collision")`` keyed by
   the mesh geometry and the config (atomic ``.npz`` writes).
"""

from __future__ import annotations

import hashlib
import json
import logging
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from ..cache import atomic_write, cache_dir, config_key, load_npz, save_npz_atomic
from ..numbers import finite_number, whole_number
from ..objects.base import PIECES_RULE, piece_file

__all__ = ["CollisionConfig", "convex_pieces", "hull_depth"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CollisionConfig:
    method: str = "auto"  # "auto" | "coacd" | "hull" | "files"
    threshold: float = 0.08  # coacd concavity threshold (smaller = more, tighter pieces)
    max_convex_hull: int = 24  # coacd cap on the number of pieces (-1: none)
    max_ch_vertex: int = 64  # vertices per piece
    preprocess_resolution: int = 30
    resolution: int = 500  # coacd sampling resolution
    mcts_iterations: int = 40  # coacd search effort (defaults tuned: ~12 s for a 25k-face kit mesh)
    mcts_nodes: int = 8
    mcts_max_depth: int = 2
    convex_tol: float = 0.02  # "nearly convex": hull volume <= (1 + tol) * mesh volume
    seed: int = 0

    def __post_init__(self) -> None:
        if self.method not in ("auto", "coacd", "hull", "files"):
            raise ValueError(f"collision method must be auto|coacd|hull|files, got {self.method!r}")
        threshold = finite_number(self.threshold)
        if threshold is None or not 0.0 < threshold <= 1.0:
            raise ValueError(f"coacd threshold must be in (0, 1], got {self.threshold!r}")
        # coacd takes these as C ints (seed unsigned): a larger value would wrap silently
        for name, lo, hi in _INT_FIELDS:
            v = getattr(self, name)
            i = whole_number(v)
            if i is None or not (lo <= i < hi or (name == "max_convex_hull" and i == -1)):
                rng = f"in [{lo}, {hi - 1}]" + (" or -1 (no cap)" if name == "max_convex_hull" else "")
                raise ValueError(f"{name} must be an int {rng}, got {v!r}")
        tol = finite_number(self.convex_tol)
        if tol is None or tol < 0:
            raise ValueError(f"convex_tol must be finite and >= 0, got {self.convex_tol!r}")


#: CollisionConfig's integer fields and their bounds ``[lo, hi)`` (a convex piece needs 4 vertices)
_INT_FIELDS = (("max_convex_hull", 1, 2**31), ("max_ch_vertex", 4, 2**31), ("preprocess_resolution", 1, 2**31),
               ("resolution", 1, 2**31), ("mcts_iterations", 1, 2**31), ("mcts_nodes", 1, 2**31),
               ("mcts_max_depth", 1, 2**31), ("seed", 0, 2**32))


def _mesh_hash(mesh: trimesh.Trimesh) -> str:
    h = hashlib.sha1()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    return h.hexdigest()


def _from_files(obj: Any) -> list[trimesh.Trimesh]:
    offset = np.asarray(getattr(obj, "offset", np.zeros(3)), dtype=np.float64)
    T = np.eye(4)
    T[:3, :3] = np.asarray(getattr(obj, "rotation", np.eye(3)), dtype=np.float64)
    pieces = []
    for p in obj.collision_paths:
        m = trimesh.load(piece_file(p, obj.name), force="mesh")
        m.apply_scale(float(getattr(obj, "unit_scale", 1.0)))  # the file's units, as its mesh's (mm files: 1e-3)
        m.apply_transform(T)
        m.apply_translation(offset)
        pieces.append(m)
    check_pieces_fit(obj, pieces)
    return pieces


#: how far (a share of the mesh's largest extent) the placed pieces' bounding box may lie from the mesh's: the YCB
#: pieces lie within 0.5 %
PIECES_FIT = 0.05


def check_pieces_fit(obj: Any, pieces: list[trimesh.Trimesh]) -> None:
    """A ``ValueError`` naming ``obj`` when its shipped ``pieces``, placed in its mesh's frame, do not cover the mesh:
    their bounding box and the mesh's differ by more than :data:`PIECES_FIT` of the mesh's largest extent. The
    pieces' place comes from the mesh file (its centring offset), which the cache keys do not hold: a mesh file
    re-exported with another origin beside its old pieces would collide the object where it is not."""
    if not pieces:
        return
    lo = np.min([p.bounds[0] for p in pieces], axis=0)
    hi = np.max([p.bounds[1] for p in pieces], axis=0)
    b = np.asarray(obj.mesh.bounds, dtype=np.float64)
    off = float(np.abs(np.concatenate([lo - b[0], hi - b[1]])).max())
    size = float(np.max(obj.mesh.extents))
    if not off <= PIECES_FIT * size:
        raise ValueError(f"object {obj.name!r}: its {len(pieces)} collision pieces, placed in its mesh's frame, span "
                         f"{np.round(lo, 4).tolist()} to {np.round(hi, 4).tolist()} m but its mesh spans "
                         f"{np.round(b[0], 4).tolist()} to {np.round(b[1], 4).tolist()} m ({off * 1e3:.1f} mm off, "
                         f"more than {PIECES_FIT:.0%} of its {size * 1e3:.0f} mm): the pieces are not of this mesh "
                         "file (another origin, units or up axis?)")


def hull_depth(vertices: np.ndarray, hull: trimesh.Trimesh) -> float:
    """Deepest of ``vertices (m, 3)`` inside their convex ``hull`` (same units; 0 for a convex piece, whose every
    vertex lies on its hull): for a point inside a convex polytope, the distance to its boundary is the smallest
    distance to a facet's plane."""
    v = np.asarray(vertices, dtype=np.float64)
    if len(v) == 0:
        return 0.0
    normals = np.asarray(hull.face_normals, dtype=np.float64)  # (F, 3) outward; a zero-area face's is zero
    keep = np.linalg.norm(normals, axis=1) > 0.5  # a zero normal would put every point on its "plane"
    if not keep.any():
        return 0.0
    normals = normals[keep]
    offsets = np.einsum("ij,ij->i", normals, np.asarray(hull.triangles[keep, 0], dtype=np.float64))  # (F,)
    depth = np.full(len(v), np.inf)
    for lo in range(0, len(v), 4096):  # (chunk, F) at a time
        depth[lo:lo + 4096] = (offsets[None, :] - v[lo:lo + 4096] @ normals.T).min(axis=1)
    return float(max(depth.max(), 0.0))


def _non_convex_piece(pieces: list[trimesh.Trimesh], paths, tol: float) -> str | None:
    """A description of the first of ``pieces`` that is not convex, or None when every piece is: a watertight piece
    whose hull's volume exceeds its own by more than ``tol``, or any piece with a face centre deeper than ``tol`` x
    its bounding-box diagonal inside its hull (a non-convex piece's vertices can all lie on its hull's boundary: an
    L-shaped prism's inner corner lies on the hull's top and bottom faces)."""
    for piece, path in zip(pieces, paths):
        ratio = _hull_ratio(piece)
        if ratio is not None and ratio > 1.0 + tol:
            return f"{Path(path).name} (its hull {ratio:.2f}x its volume)"
        size = float(np.linalg.norm(piece.extents))
        depth = hull_depth(piece.triangles_center, piece.convex_hull)
        if size > 0 and depth > tol * size:
            return f"{Path(path).name} ({depth * 1e3:.1f} mm inside its hull, {size * 1e3:.0f} mm across)"
    return None


#: the convexity verdicts' cache version (with :data:`~haptic_env.objects.base.PIECES_RULE` in their key): a change to
#: :func:`_non_convex_piece` bumps it, so that no verdict of the old test is reused
_VERDICT_VERSION = "convexity-v1"


def _shipped_verdict(obj: Any, name: str, cfg: CollisionConfig, cache: bool) -> tuple[str | None, list | None]:
    """``(_non_convex_piece of obj's shipped pieces, the pieces or None)``: the verdict read from its cache file when
    there is one (then the pieces are not loaded), else tested on the loaded pieces and saved (atomically) when
    ``cache``. A cache file that cannot be read is tested again (warned)."""
    digest = getattr(obj, "pieces_hash", None)  # the files' bytes and units (GraspObject); None: no key, test
    key = config_key(_VERDICT_VERSION, PIECES_RULE, digest, float(cfg.convex_tol))
    path = cache_dir("collision") / f"{name}-convexity-{key}.json" if cache and digest is not None else None
    if path is not None and path.is_file():
        try:
            bad = json.loads(path.read_text())["non_convex"]
            if bad is None or isinstance(bad, str):
                return bad, None
            raise TypeError(f"non_convex is {bad!r}")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            warnings.warn(f"convexity verdict {path} unreadable ({exc}); testing the pieces again", RuntimeWarning,
                          stacklevel=3)
    pieces = _from_files(obj)
    bad = _non_convex_piece(pieces, obj.collision_paths, cfg.convex_tol)
    if path is not None:
        with atomic_write(path, "w") as fh:
            json.dump({"object": name, "non_convex": bad}, fh)
    return bad, pieces


def _hull_ratio(mesh: trimesh.Trimesh) -> float | None:
    """The volume of ``mesh``'s convex hull over its own, or None when that is unknown (not watertight, no volume, or
    no hull)."""
    try:
        vol = abs(float(mesh.volume)) if mesh.is_watertight else 0.0
        return float(mesh.convex_hull.volume) / vol if vol > 0 else None
    except Exception:
        return None


def _is_convex(mesh: trimesh.Trimesh, tol: float) -> bool:
    ratio = _hull_ratio(mesh)
    return ratio is not None and ratio <= 1.0 + tol


def _coacd(mesh: trimesh.Trimesh, cfg: CollisionConfig, name: str, cache: bool) -> list[trimesh.Trimesh]:
    """``mesh``'s coacd pieces, read from (and saved to) ``cache_dir("collision")`` when ``cache``; without it the
    cache folder is not touched (nor required to exist or be writable)."""
    path = cache_dir("collision") / f"{name}-{config_key(cfg, _mesh_hash(mesh))}.npz" if cache else None
    if path is not None and path.is_file():
        data = load_npz(path, required=("vertices", "faces", "nv", "nf"))
        out, v0, f0 = [], 0, 0
        for nv, nf in zip(data["nv"], data["nf"]):
            out.append(trimesh.Trimesh(data["vertices"][v0:v0 + nv], data["faces"][f0:f0 + nf], process=False))
            v0, f0 = v0 + nv, f0 + nf
        return out
    import coacd

    coacd.set_log_level("error")
    log.info("convex decomposition of %s (%d faces) with coacd ...", name, len(mesh.faces))
    parts = coacd.run_coacd(
        coacd.Mesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)),
        threshold=cfg.threshold, max_convex_hull=cfg.max_convex_hull, max_ch_vertex=cfg.max_ch_vertex,
        preprocess_resolution=cfg.preprocess_resolution, resolution=cfg.resolution,
        mcts_iterations=cfg.mcts_iterations, mcts_nodes=cfg.mcts_nodes, mcts_max_depth=cfg.mcts_max_depth,
        seed=cfg.seed)
    out = [trimesh.Trimesh(np.asarray(v), np.asarray(f), process=False) for v, f in parts]
    if path is not None:
        save_npz_atomic(path, vertices=np.concatenate([m.vertices for m in out]),
                        faces=np.concatenate([m.faces for m in out]),
                        nv=np.array([len(m.vertices) for m in out]), nf=np.array([len(m.faces) for m in out]))
    return out


def convex_pieces(obj: Any, config: CollisionConfig | None = None, *, cache: bool = True) -> list[trimesh.Trimesh]:
    """Convex pieces (object frame, metres) approximating ``obj.mesh`` for collision."""
    cfg = config or CollisionConfig()
    name = str(getattr(obj, "name", "object")).replace("/", "_")
    mesh = obj.mesh
    if cfg.method == "files" or (cfg.method == "auto" and getattr(obj, "collision_paths", ())):
        if not getattr(obj, "collision_paths", ()):
            raise ValueError(f"object {name!r} ships no collision pieces (collision_paths is empty)")
        if cfg.method == "files":
            return _from_files(obj)
        bad, pieces = _shipped_verdict(obj, name, cfg, cache)
        if bad is None:
            return _from_files(obj) if pieces is None else pieces
        log.info("object %r: shipped collision piece %s is not convex, and MuJoCo would collide it as its hull; "
                 "decomposing the mesh with coacd instead", name, bad)
        return _coacd(mesh, cfg, name, cache)
    if cfg.method == "hull" or (cfg.method == "auto" and _is_convex(mesh, cfg.convex_tol)):
        return [mesh.convex_hull]
    return _coacd(mesh, cfg, name, cache)
