"""Geometric (physics-free) grasp backend: fingertips close along rays until they hit the mesh.

The hand pattern: ``n - 1`` fingers opposite a thumb around the approach axis ``e3`` (see
:mod:`.base`). In the approach frame the thumb sits at angle 0 along ``e1``; finger ``j = 0..n-2``
sits at ``pi + (j - (n-2)/2) * delta`` with ``delta = (min_spread + (1 - min_spread) * s) * 2 pi / n``
for the spread ``s`` in [0, 1] (``s = 1``: all n fingertips evenly spaced). Fingertip ``i`` closes
along a straight path through the object's centre ``c`` (its centre of mass when the mesh is a
closed volume, else its bounding-box centre), tilted by its curl
angle ``beta_i`` (``GeometricConfig.curl_deg``, one per finger, the thumb last) out of the plane
perpendicular to the approach: it starts on the palm side at ``c - R d_i`` with
``R = margin * r_bound`` (outside the bounding sphere) and direction
``d_i = -cos(beta_i) r_i + sin(beta_i) e3`` (``r_i`` its radial direction), i.e. it reaches in and
down around the object like a curling finger. Distinct curl angles keep the contacts off a common
plane (a planar closing pattern would make every grasp of ``n >= 4`` coplanar, hence degenerate
for Phi_n). Each fingertip stops at its first intersection with the mesh within ``reach * R`` of
its start (default 2: it may sweep across the whole bounding sphere); a fingertip that passes the
object without hitting (or, with ``support="table"``, would touch below the table top) reports no
contact. Rays are cast in the object frame (the rays are transformed, not the mesh) with Embree
when ``embreex`` is installed, else trimesh's triangle intersector. A uniform object scale
(``set_object(obj, pose, scale=s)``) is applied the same way, as a transform of the rays: the
ray-casting scene of a mesh is built once and reused for every pose and scale, and at most
:data:`MAX_SCENES` scenes are kept (least recently used first out), so a long run over randomly
scaled objects holds a bounded number of Embree scenes.

Fingertip order: fingers ``0..n-2`` then the thumb last (like the Allegro hand: ff, mf, rf, th).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import trimesh

from haptic_env.numbers import checked_flag, finite_number

from . import _geometric_kernels as gk
from .base import (
    ACTION_DIM,
    GraspBatch,
    GraspResult,
    approach_frame,
    check_support,
    decode_approach,
    placement,
    support_height,
    validate_action,
    validate_actions,
)

__all__ = ["GeometricConfig", "GeometricBackend", "make_intersector", "MAX_SCENES", "PlacedObjects"]

#: Ray-casting scenes (one per distinct mesh) a :class:`GeometricBackend` keeps, least recently used
#: evicted first. Embree crashes the process after ~1000 live scenes; object sets are far smaller.
MAX_SCENES = 64


@dataclass(frozen=True)
class GeometricConfig:
    """n_fingers >= 2; noise std in metres / degrees; ``margin`` > 1 scales the start circle."""

    n_fingers: int = 4
    support: str = "table"  # "table": upper hemisphere + table top; "floating": full sphere
    normals: bool = True  # report normals (else GraspResult.normals is None)
    contact_noise: float = 0.0  # std (m) of Gaussian noise added to each touched contact
    normal_noise_deg: float = 0.0  # approx. std (deg) of the angular noise on each normal
    margin: float = 1.05
    min_spread: float = 0.15  # finger spacing at spread 0, as a fraction of 2 pi / n
    table_clearance: float = 1e-3  # contacts lower than table top + this are unreachable (m)
    #: curl (tilt) angle of each fingertip's closing path in degrees: fingers first, the thumb last
    #: (the first n - 1 entries are the fingers' angles, the last entry the thumb's)
    curl_deg: tuple[float, ...] = (10.0, 20.0, 30.0, 40.0, 50.0, 0.0)
    reach: float = 2.0  # path length of a closing fingertip, in units of its start distance R

    def __post_init__(self) -> None:
        if not (isinstance(self.n_fingers, (int, np.integer)) and 2 <= self.n_fingers <= 16):
            raise ValueError(f"n_fingers must be an integer in [2, 16], got {self.n_fingers!r}")
        check_support(self.support)
        checked_flag(self.normals, "normals")
        for name in ("contact_noise", "normal_noise_deg", "table_clearance"):
            v = getattr(self, name)
            f = finite_number(v)
            if f is None or f < 0:
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
        margin = finite_number(self.margin)
        if margin is None or margin <= 1.0:
            raise ValueError(f"margin must be > 1, got {self.margin!r}")
        reach = finite_number(self.reach)
        if reach is None or reach <= 0:
            raise ValueError(f"reach must be > 0, got {self.reach!r}")
        spread = finite_number(self.min_spread)
        if spread is None or not 0.0 < spread <= 1.0:
            raise ValueError(f"min_spread must be in (0, 1], got {self.min_spread!r}")
        # a sequence (the backend slices it) of finite numbers: not strings, which np.asarray would take, nor bools
        v = self.curl_deg
        seq = isinstance(v, Sequence) and not isinstance(v, (str, bytes))
        seq = seq or (isinstance(v, np.ndarray) and v.ndim == 1)
        curl = [finite_number(a) for a in v] if seq else []
        if len(curl) < self.n_fingers or not all(a is not None and 0 <= a < 90 for a in curl):
            raise ValueError(f"curl_deg needs >= n_fingers={self.n_fingers} angles in [0, 90) degrees "
                             f"(fingers first, thumb last), got {self.curl_deg!r}")


def make_intersector(mesh: trimesh.Trimesh):
    """Embree intersector when ``embreex`` imports, else trimesh's pure-python triangle intersector."""
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        return RayMeshIntersector(mesh)
    except Exception:  # embreex missing or unusable on this platform
        from trimesh.ray.ray_triangle import RayMeshIntersector

        return RayMeshIntersector(mesh)


def finger_angles(spread: np.ndarray, n: int, min_spread: float) -> np.ndarray:
    """(..., n) angles of the fingertips about the approach axis (thumb last, at angle 0)."""
    s = np.asarray(spread, dtype=np.float64)[..., None]
    delta = (min_spread + (1.0 - min_spread) * s) * (2.0 * np.pi / n)
    j = np.arange(n - 1, dtype=np.float64) - (n - 2) / 2.0
    fingers = np.pi + j * delta
    return np.concatenate([fingers, np.zeros_like(s)], axis=-1)


class _MeshScene(NamedTuple):
    """A mesh's ray-casting scene and the geometry tables a grasp needs (object frame, unscaled)."""

    mesh: trimesh.Trimesh
    data_hash: int
    intersector: Any
    face_normals: np.ndarray
    face_v0: np.ndarray
    vertices: np.ndarray
    centre: np.ndarray
    radius: float


class GeometricBackend:
    """Ray-casting grasps. ``set_object(obj, pose)`` first; then ``grasp`` / ``grasp_batch``; or
    ``grasp_placed`` for ``B`` grasps of ``B`` differently placed objects (a vector env's episodes) at once."""

    action_dim = ACTION_DIM
    #: ``set_object`` takes ``scale=`` (the env passes its random scale instead of a scaled mesh copy)
    supports_scale = True

    def __init__(self, config: GeometricConfig | None = None) -> None:
        self.config = config or GeometricConfig()
        self.n_fingers = int(self.config.n_fingers)
        # cos and sin of the fingertips' curl angles beta (n,): the rays' out-of-plane tilt (rays, grasp_placed)
        beta = np.deg2rad(np.r_[np.asarray(self.config.curl_deg[: self.n_fingers - 1]), self.config.curl_deg[-1]])
        self._curl_cos, self._curl_sin = np.cos(beta), np.sin(beta)
        self._obj: Any = None
        self._last: tuple[np.ndarray, np.ndarray, GraspResult] | None = None
        self._scale = 1.0
        # id(mesh) -> its scene and geometry tables (holding the mesh, so the id cannot be reused)
        self._scenes: OrderedDict[int, _MeshScene] = OrderedDict()

    # ------------------------------------------------------------------ object
    def set_object(self, obj: Any, pose: np.ndarray | None = None, scale: float = 1.0) -> None:
        """``obj`` has ``.mesh`` (trimesh, metres, object frame); ``pose`` (4, 4) object-to-world; ``scale`` > 0
        a uniform scale of the mesh about its frame origin (applied before the pose; the mesh is not copied)."""
        mesh, T, s = placement(obj, pose, scale)
        sc = self._scene_of(mesh)
        self._obj = obj
        self._mesh = mesh
        self._T = T
        self._R = T[:3, :3].copy()
        self._t = T[:3, 3].copy()
        self._scale = s
        self._intersector = sc.intersector
        self._face_normals = sc.face_normals
        self._face_v0 = sc.face_v0
        self._radius = s * sc.radius  # world units
        self._centre = self._R @ (s * sc.centre) + self._t
        self._table_z = support_height(sc.vertices, T, s)
        self._last = None

    def _scene_of(self, mesh: trimesh.Trimesh) -> "_MeshScene":
        """The cached scene of ``mesh`` (built on first use; the least recently used one is released when
        more than :data:`MAX_SCENES` are held)."""
        key = id(mesh)
        sc = self._scenes.get(key)
        if sc is not None and sc.mesh is mesh and sc.data_hash == hash(mesh):  # hash: changes if edited in place
            self._scenes.move_to_end(key)
            return sc
        v = np.asarray(mesh.vertices, dtype=np.float64)
        c_obj = 0.5 * (v.min(axis=0) + v.max(axis=0))
        if mesh.is_volume and mesh.volume > 0:
            c_obj = np.asarray(mesh.center_mass, dtype=np.float64)
        sc = _MeshScene(mesh=mesh, data_hash=hash(mesh), intersector=make_intersector(mesh),
                        face_normals=np.asarray(mesh.face_normals, dtype=np.float64),
                        face_v0=np.asarray(mesh.triangles[:, 0, :], dtype=np.float64),
                        vertices=v, centre=c_obj, radius=float(np.linalg.norm(v - c_obj, axis=1).max()))
        self._scenes[key] = sc
        self._scenes.move_to_end(key)
        while len(self._scenes) > MAX_SCENES:
            self._scenes.popitem(last=False)  # dropping the last reference frees the Embree scene
        return sc

    @property
    def n_scenes(self) -> int:
        """Ray-casting scenes currently held (at most :data:`MAX_SCENES`)."""
        return len(self._scenes)

    @property
    def scale(self) -> float:
        """The current object's uniform scale."""
        return self._scale

    def close(self) -> None:
        """Release every cached ray-casting scene but the current object's."""
        cur = self._scenes.get(id(self._mesh)) if self._obj is not None else None
        self._scenes.clear()
        if cur is not None:
            self._scenes[id(self._mesh)] = cur

    @property
    def object(self) -> Any:
        return self._obj

    def _require_object(self) -> None:
        if self._obj is None:
            raise RuntimeError("call set_object(obj, pose) before grasping")

    # ------------------------------------------------------------------ grasps
    def rays(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World-frame ray origins and unit directions, each (B, n, 3), for validated actions (B, 4)."""
        cfg = self.config
        ap = decode_approach(actions, cfg.support)
        frame = approach_frame(ap)  # (B, 3, 3)
        ang = finger_angles(ap.spread, self.n_fingers, cfg.min_spread)  # (B, n)
        e1, e2 = frame[:, None, :, 0], frame[:, None, :, 1]
        radial = np.cos(ang)[..., None] * e1 + np.sin(ang)[..., None] * e2  # (B, n, 3)
        e3 = frame[:, None, :, 2]
        d = -self._curl_cos[:, None] * radial + self._curl_sin[:, None] * e3  # (B, n, 3) unit
        R0 = cfg.margin * self._radius
        return self._centre - R0 * d, d

    def grasp_batch(self, actions: np.ndarray, rng: np.random.Generator) -> GraspBatch:
        """(B, 4) actions -> :class:`GraspBatch` (contacts/normals (B, n, 3), touched (B, n))."""
        self._require_object()
        a = validate_actions(actions, self.action_dim)
        origins, dirs = self.rays(a)
        contacts, normals, touched = self._cast(origins.reshape(-1, 3), dirs.reshape(-1, 3))
        B, n = a.shape[0], self.n_fingers
        contacts, normals, touched = contacts.reshape(B, n, 3), normals.reshape(B, n, 3), touched.reshape(B, n)
        contacts, normals = self._noise(contacts, normals, touched, rng)
        batch = GraspBatch(contacts=contacts, normals=normals if self.config.normals else None, touched=touched,
                           joint_pos=np.zeros((B, 0)))
        self._last = (origins[-1], dirs[-1], batch[B - 1])
        return batch

    def grasp(self, action: np.ndarray, rng: np.random.Generator) -> GraspResult:
        """(4,) action -> :class:`GraspResult`."""
        a = validate_action(action, self.action_dim)
        return self.grasp_batch(a[None], rng)[0]

    def placed_objects(self, objects, size: int) -> "PlacedObjects":
        """``size`` slots for objects of ``objects`` (each with ``.mesh``) placed independently, for
        :meth:`grasp_placed` (a vector env's episodes): ``placed.place(b, k, pose, scale)`` puts object ``k`` in
        slot ``b`` as ``set_object(objects[k], pose, scale)`` would."""
        return PlacedObjects([self._scene_of(o.mesh) for o in objects], size)

    def grasp_placed(self, actions: np.ndarray, placed: "PlacedObjects", rows=None, rngs=None) -> GraspBatch:
        """``B`` grasps at once, grasp ``j`` of the object in slot ``rows[j]`` of ``placed`` (default: slot ``j``)
        with action ``actions[j]``; ``rngs[j]`` draws its noise (needed only with contact or normal noise). One
        Embree call per distinct object among the slots.

        Grasp ``j`` equals ``set_object`` to that slot's object, pose and scale followed by
        ``grasp(actions[j], rngs[j])``, bit for bit (``tests/test_vector_env.py``). The current object and
        ``render`` are left alone."""
        a = validate_actions(actions, self.action_dim)
        B, n, cfg = a.shape[0], self.n_fingers, self.config
        rows = np.arange(B) if rows is None else np.asarray(rows, dtype=np.int64)
        if rows.shape != (B,):
            raise ValueError(f"grasp_placed: {B} actions but {rows.shape} rows")
        if (placed.index[rows] < 0).any():
            raise RuntimeError("grasp_placed: a slot has no object placed (PlacedObjects.place first)")
        # rays exactly as rays(), with each grasp's own centre and start radius (compiled: _geometric_kernels,
        # bit for bit the NumPy reference; the trig and the matmuls stay NumPy's)
        th = np.empty((B, 3 + n))
        gk.ray_angles(a, cfg.support == "table", n, float(cfg.min_spread), th)
        R, t, scale, radius = placed.R[rows], placed.t[rows], placed.scale[rows], placed.radius[rows]
        d_w = np.empty((B, n, 3))
        o_t = np.empty((B, n, 3))  # o_w - t
        gk.ray_frames(np.cos(th), np.sin(th), self._curl_cos, self._curl_sin, placed.centre[rows], t, radius,
                      float(cfg.margin), d_w, o_t)
        # _cast, per grasp: the rays in the unscaled object frame (batched matmul: one (n, 3) @ (3, 3) per grasp)
        o = np.matmul(o_t, R)
        o /= scale[:, None, None]
        d = np.matmul(d_w, R)
        o, d = o.reshape(-1, 3), d.reshape(-1, 3)
        kind = np.repeat(placed.index[rows], n)  # object of each ray
        K = len(placed.scenes)
        order = np.empty(B * n, dtype=np.int64)  # rays grouped by object (stable): one contiguous block each
        starts = np.empty(K + 1, dtype=np.int64)
        o32 = np.empty((B * n, 3), dtype=np.float32)  # trimesh's _EmbreeWrap.run inputs
        d32 = np.empty((B * n, 3), dtype=np.float32)
        gk.embree_inputs(o, d, kind, K, placed.embree_origin, placed.embree_scale, order, starts, o32, d32)
        tri_s = np.empty(B * n, dtype=np.int64)  # first-hit triangle of each grouped ray, in its object (-1: none)
        bounds = starts.tolist()
        for k in range(K):  # one Embree call per object
            lo, hi = bounds[k], bounds[k + 1]
            if hi == lo:
                continue
            scene = placed.embree[k]
            if scene is not None:
                tri_s[lo:hi] = scene.scene.run(o32[lo:hi], d32[lo:hi])
            else:
                rr = order[lo:hi]
                tri_s[lo:hi] = placed.scenes[k].intersector.intersects_first(o[rr], d[rr])
        L = np.empty((B * n, 3))  # the hit maths of _cast on all rays at once (row-wise: the same bits per ray)
        Nf = np.empty((B * n, 3))
        ok = np.empty(B * n, dtype=bool)
        reach = cfg.reach * cfg.margin * radius / scale
        gk.hit_maths(tri_s, order, placed.face_offset, kind, placed.face_normals, placed.face_v0, o, d, reach, n, L,
                     Nf, ok)
        # to the world frame: one (n, 3) @ (3, 3) per grasp (misses are zero rows)
        RT = R.transpose(0, 2, 1)
        pw = np.matmul(L.reshape(B, n, 3) * scale[:, None, None], RT)
        nw = np.matmul(Nf.reshape(B, n, 3), RT)
        contacts = np.zeros((B, n, 3))
        normals = np.zeros((B, n, 3))
        touched = np.zeros((B, n), dtype=bool)
        gk.hit_results(pw, nw, t, ok, cfg.support == "table", placed.table_z[rows], float(cfg.table_clearance), n,
                       contacts, normals, touched)
        if cfg.contact_noise > 0 or (cfg.normal_noise_deg > 0 and cfg.normals):
            if rngs is None or len(rngs) != B:
                raise ValueError("grasp_placed with contact or normal noise needs one generator per grasp (rngs)")
            for b in range(B):  # each grasp draws from its own generator, as grasp() would
                c, nn = self._noise(contacts[b:b + 1], normals[b:b + 1], touched[b:b + 1], rngs[b])
                contacts[b], normals[b] = c[0], nn[0]
        return GraspBatch(contacts=contacts, normals=normals if cfg.normals else None, touched=touched,
                          joint_pos=np.zeros((B, 0)))

    def _cast(self, o_w: np.ndarray, d_w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        R, t, s = self._R, self._t, self._scale
        o = (o_w - t) @ R  # R^T (o - t), row-wise: the scaled object's frame
        if s != 1.0:
            o /= s  # the unscaled mesh's frame (directions stay unit: distances shrink by 1 / s)
        d = d_w @ R
        m = o.shape[0]
        contacts = np.zeros((m, 3))
        normals = np.zeros((m, 3))
        touched = np.zeros(m, dtype=bool)
        scene = getattr(self._intersector, "_scene", None)
        if scene is not None:  # embree: first-hit triangle ids, the hit point recomputed in float64
            tri = np.asarray(scene.run(o, d), dtype=np.int64)
        else:
            tri = np.asarray(self._intersector.intersects_first(o, d), dtype=np.int64)
        idx_ray = np.flatnonzero(tri >= 0)
        if len(idx_ray):
            idx_tri = tri[idx_ray]
            fn = self._face_normals[idx_tri]
            dn = np.einsum("ij,ij->i", fn, d[idx_ray])
            safe = np.where(np.abs(dn) > 1e-12, dn, 1e-12)
            tdist = np.einsum("ij,ij->i", self._face_v0[idx_tri] - o[idx_ray], fn) / safe
            locs = o[idx_ray] + tdist[:, None] * d[idx_ray]
            # stopped within the finger's reach (a finger sweeping past the object touched nothing)
            reach = self.config.reach * self.config.margin * self._radius / s
            ok = (tdist >= 0.0) & (tdist <= reach + 1e-9) & (np.abs(dn) > 1e-12)
            # inward normal = face normal oriented along the finger's motion (robust to face winding)
            sign = np.where(dn >= 0.0, 1.0, -1.0)
            pw = (locs * s if s != 1.0 else locs) @ R.T + t
            nw = (sign[:, None] * fn) @ R.T
            if self.config.support == "table":
                ok &= pw[:, 2] > self._table_z + self.config.table_clearance
            r = idx_ray[ok]
            contacts[r], normals[r], touched[r] = pw[ok], nw[ok], True
        return contacts, normals, touched

    def _noise(self, contacts: np.ndarray, normals: np.ndarray, touched: np.ndarray,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        if cfg.contact_noise > 0:
            contacts = contacts + rng.normal(0.0, cfg.contact_noise, contacts.shape) * touched[..., None]
        if cfg.normal_noise_deg > 0 and cfg.normals:
            g = rng.normal(0.0, np.deg2rad(cfg.normal_noise_deg), normals.shape)
            g -= np.sum(g * normals, axis=-1, keepdims=True) * normals  # tangent perturbation
            nn = normals + g
            norm = np.linalg.norm(nn, axis=-1, keepdims=True)
            normals = np.where(touched[..., None], nn / np.maximum(norm, 1e-12), 0.0)
        return contacts, normals

    # ------------------------------------------------------------------ render
    def render(self, width: int = 480, height: int = 480) -> np.ndarray:
        """(H, W, 3) uint8 matplotlib picture: mesh, last grasp's finger rays, contacts and normals."""
        self._require_object()
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # an off-screen canvas: no global backend switch
        from matplotlib.figure import Figure
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        fig = Figure(figsize=(width / 100, height / 100), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(projection="3d")
        faces = np.asarray(self._mesh.faces)
        if len(faces) > 4000:  # keep rendering fast: a random subset of faces
            faces = faces[np.random.default_rng(0).choice(len(faces), 4000, replace=False)]
        tri = ((self._scale * np.asarray(self._mesh.vertices)[faces]) @ self._R.T) + self._t
        ax.add_collection3d(Poly3DCollection(tri, alpha=0.25, facecolor="tab:blue", edgecolor="none"))
        r = self._radius * self.config.margin
        lo, hi = self._centre - r, self._centre + r
        if self._last is not None:
            origins, dirs, res = self._last
            for o, dvec, c, t in zip(origins, dirs, res.contacts, res.touched):
                end = c if t else o + dvec * r
                ax.plot(*np.stack([o, end]).T, color="tab:green" if t else "tab:red", lw=1)
            pts = res.contacts[res.touched]
            if len(pts):
                ax.scatter(*pts.T, color="k", s=20)
                if res.normals is not None:
                    nv = res.normals[res.touched] * 0.3 * r
                    ax.quiver(*pts.T, *nv.T, color="tab:orange")
        ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
        ax.set_title(f"geometric grasp: {getattr(self._obj, 'name', '')}")
        fig.canvas.draw()
        img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
        return img


class PlacedObjects:
    """``size`` slots, each holding one object of a set in its own pose and scale, as arrays (what
    :meth:`GeometricBackend.grasp_placed` reads); built by :meth:`GeometricBackend.placed_objects`. The objects'
    face tables are concatenated once (``face_offset[k]``: object ``k``'s first face)."""

    def __init__(self, scenes: list[_MeshScene], size: int):
        self.scenes = scenes  # holding them keeps their Embree scenes alive
        #: each object's Embree scene (None: trimesh's intersector), looked up once (the intersector re-hashes
        #: the mesh at every lookup)
        self.embree = [getattr(sc.intersector, "_scene", None) for sc in scenes]
        #: the Embree wrappers' ray transform (trimesh's ``_EmbreeWrap.run``: ``(o - origin) * scale``, float32)
        self.embree_origin = np.array([np.zeros(3) if e is None else np.asarray(e.origin, dtype=np.float64)
                                       for e in self.embree]).reshape(-1, 3)
        self.embree_scale = np.array([1.0 if e is None else float(e.scale) for e in self.embree])
        #: lowest vertex z of each object (the table height of an unscaled object whose pose keeps z upright)
        self._zmin = [float(sc.vertices[:, 2].min()) for sc in scenes]
        self._radius = np.array([sc.radius for sc in scenes], dtype=np.float64)
        self.face_offset = np.concatenate([[0], np.cumsum([len(sc.face_normals) for sc in scenes])[:-1]]).astype(np.int64)
        self.face_normals = np.concatenate([sc.face_normals for sc in scenes])
        self.face_v0 = np.concatenate([sc.face_v0 for sc in scenes])
        self.index = np.full(size, -1, dtype=np.int64)  # object of each slot (-1: empty)
        self.R = np.tile(np.eye(3), (size, 1, 1))
        self.t = np.zeros((size, 3))
        self.scale = np.ones(size)
        self.centre = np.zeros((size, 3))
        self.radius = np.zeros(size)
        self.table_z = np.zeros(size)

    def place(self, b: int, k: int, pose: np.ndarray, scale: float = 1.0) -> None:
        """Object ``k`` in slot ``b`` with a rigid ``pose (4, 4)`` (not re-validated) and a positive ``scale``:
        the numbers of ``GeometricBackend.set_object`` (same expressions, same bits)."""
        self.place_many([b], [k], np.asarray(pose, dtype=np.float64)[None], [scale])

    def place_many(self, slots, ks, poses: np.ndarray, scales) -> None:
        """:meth:`place` of object ``ks[j]`` in slot ``slots[j]`` with ``poses[j] (4, 4)`` and ``scales[j]``, for
        each ``j`` (a vector env's resets of one step)."""
        slots = np.asarray(slots, dtype=np.int64)
        ks = np.asarray(ks, dtype=np.int64)
        s_all = np.asarray(scales, dtype=np.float64)
        R_all = np.ascontiguousarray(poses[:, :3, :3])
        t_all = np.ascontiguousarray(poses[:, :3, 3])
        self.index[slots] = ks
        self.R[slots], self.t[slots], self.scale[slots] = R_all, t_all, s_all
        self.radius[slots] = s_all * self._radius[ks]
        for j, (b, k, s) in enumerate(zip(slots.tolist(), ks.tolist(), s_all.tolist())):
            sc, R, t = self.scenes[k], R_all[j], t_all[j]
            self.centre[b] = R @ (s * sc.centre) + t
            if s == 1.0 and R[2, 0] == 0.0 and R[2, 1] == 0.0 and R[2, 2] == 1.0:  # a yaw: the same number, exactly
                self.table_z[b] = float(self._zmin[k] + t[2])
            else:
                self.table_z[b] = float(((s * sc.vertices) @ R[2]).min() + t[2])
