"""Procedural everyday-like shapes (the embedded ``"default"`` set) and the paper's geometry families.

All meshes are generated deterministically in metres, watertight, refined to a few thousand faces
(so that the paper's face-centroid sampling has enough distinct points) and centred at their
bounding-box centre. Nothing is read from disk.
"""

from __future__ import annotations

import numpy as np
import trimesh

from ..numbers import checked_flag, positive_range, whole_at_least
from .base import GraspObject, ObjectSet, prepare_mesh, up_rotation

__all__ = ["DEFAULT_SHAPES", "default_set", "family_set", "FAMILIES", "make_shape"]

#: Faces a generated mesh is refined to at least (uniform midpoint subdivision keeps it watertight).
MIN_FACES = 2000

#: The paper's geometry families (Sintov & Ben-David, geometry-recognition experiment).
FAMILIES = ("box", "elliptic_cylinder", "ellipsoid")
#: Base size (m) of every family member before the per-axis scale factors.
FAMILY_BASE_SIZE = 0.08
#: Range of the per-axis scale factors of family members.
FAMILY_SCALE_RANGE = (0.5, 1.5)
#: The smallest extent (m) a family member may be drawn with: below it no hand grasps it, and the meshes lose their
#: shape to rounding (``size_range=(1e-9, 1e-9)`` gave members 1e-10 m across).
MIN_FAMILY_MEMBER_SIZE = 1e-3


# ------------------------------------------------------------------------------------ helpers
def _refine(mesh: trimesh.Trimesh, min_faces: int = MIN_FACES) -> trimesh.Trimesh:
    """Midpoint-subdivide every face until the mesh has at least ``min_faces`` faces."""
    while len(mesh.faces) < min_faces:
        mesh = mesh.subdivide()
    return mesh


def _resample(points: np.ndarray, step: float) -> np.ndarray:
    """Resample a 2-D polyline so consecutive points are at most ``step`` apart (corners kept)."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        t = np.linspace(0, 1, k + 1)[1:, None]
        out.append(a + t * (b - a))
    return np.concatenate(out)


def _revolve(profile, sections: int = 64, step: float = 0.006) -> trimesh.Trimesh:
    """Solid of revolution about +z of a closed ``(radius, z)`` profile from axis to axis."""
    prof = _resample(np.asarray(profile, dtype=np.float64), step)
    mesh = trimesh.creation.revolve(prof, sections=sections)
    mesh.merge_vertices()
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _arc(cx: float, cz: float, r: float, a0: float, a1: float, k: int = 12) -> np.ndarray:
    t = np.linspace(a0, a1, k)
    return np.stack([cx + r * np.cos(t), cz + r * np.sin(t)], axis=1)


def _union(*meshes: trimesh.Trimesh) -> trimesh.Trimesh:
    return trimesh.boolean.union(list(meshes), engine="manifold")


# ------------------------------------------------------------------------------------- shapes
def _box() -> trimesh.Trimesh:  # cereal box
    return trimesh.creation.box(extents=(0.07, 0.19, 0.28))


def _can() -> trimesh.Trimesh:  # soda/food can with rolled rims
    r, h, b = 0.033, 0.122, 0.003
    prof = [(0, 0), (r - b, 0), (r, b), (r, h - b), (r - b, h), (0, h)]
    return _revolve(prof, sections=64)


def _apple() -> trimesh.Trimesh:  # slightly squashed sphere with dimples at stem and base
    t = np.linspace(0, np.pi, 48)
    R, Rz = 0.040, 0.035
    x = R * np.sin(t)
    z = -Rz * np.cos(t)
    z = z - 0.010 * np.exp(-((x / 0.012) ** 2)) * np.sign(z)  # dimples pull the poles inward
    x[0] = x[-1] = 0.0
    return _revolve(np.stack([x, z], 1), sections=64)


def _bottle() -> trimesh.Trimesh:  # water bottle: body, shoulder, neck, cap
    r, rn = 0.034, 0.013
    prof = np.concatenate(
        [
            [(0, 0), (r - 0.004, 0)],
            _arc(r - 0.004, 0.004, 0.004, -np.pi / 2, 0, 5)[1:],
            [(r, 0.15)],
            # shoulder: quarter-sine from body radius to neck radius
            np.stack([rn + (r - rn) * np.cos(np.linspace(0, np.pi / 2, 12)), 0.15 + np.linspace(0, 0.05, 12)], 1)[1:],
            [(rn, 0.22), (rn + 0.002, 0.22), (rn + 0.002, 0.235), (0, 0.235)],
        ]
    )
    return _revolve(prof, sections=64)


def _mug() -> trimesh.Trimesh:  # hollow cup + C-shaped handle
    R, H, t, tb = 0.041, 0.095, 0.005, 0.008
    prof = np.concatenate(
        [[(0, 0), (R, 0), (R, H - t / 2)], _arc(R - t / 2, H - t / 2, t / 2, 0, np.pi, 8)[1:-1], [(R - t, H - t / 2), (R - t, tb), (0, tb)]]
    )
    cup = _revolve(prof, sections=72, step=0.005)
    # handle: torus in the xz-plane centred on the outer wall, cut to the part outside the wall
    torus = trimesh.creation.torus(0.030, 0.007, major_sections=48, minor_sections=16)
    torus.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    torus.apply_translation([R, 0, H / 2])
    keep = trimesh.creation.box(extents=(0.1, 0.1, 0.2))
    keep.apply_translation([R - t / 2 + 0.05, 0, H / 2])
    handle = trimesh.boolean.intersection([torus, keep], engine="manifold")
    return _union(cup, handle)


def _cone() -> trimesh.Trimesh:  # traffic-cone / funnel-like cone with a rounded tip
    R, H = 0.05, 0.13
    prof = np.concatenate([[(0, 0), (R, 0)], [(0.006, H - 0.004)], _arc(0, H - 0.006, 0.006, 0.3, np.pi / 2, 5)])
    return _revolve(prof, sections=64)


def _ring() -> trimesh.Trimesh:  # torus: teething ring / doughnut
    return trimesh.creation.torus(0.045, 0.014, major_sections=64, minor_sections=32)


def _hammer() -> trimesh.Trimesh:  # handle along y, head along x
    handle = trimesh.creation.cylinder(radius=0.013, height=0.28, sections=32)
    handle.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    head = trimesh.creation.box(extents=(0.11, 0.03, 0.03))
    head.apply_translation([0.015, 0.14 - 0.012, 0])
    return _union(handle, head)


def _ball() -> trimesh.Trimesh:  # tennis ball
    return trimesh.creation.icosphere(subdivisions=4, radius=0.0335)


#: name -> generator of the embedded default set.
DEFAULT_SHAPES = {
    "box": _box,
    "can": _can,
    "apple": _apple,
    "bottle": _bottle,
    "mug": _mug,
    "cone": _cone,
    "ring": _ring,
    "hammer": _hammer,
    "ball": _ball,
}


def make_shape(name: str, min_faces: int = MIN_FACES) -> trimesh.Trimesh:
    """The generated mesh of one default shape (metres, centred, at least ``min_faces`` faces)."""
    try:
        gen = DEFAULT_SHAPES[name]
    except KeyError:
        raise KeyError(f"unknown default shape {name!r}; have {list(DEFAULT_SHAPES)}") from None
    mesh, _ = prepare_mesh(_refine(gen(), min_faces), name)
    return mesh


def default_set() -> ObjectSet:
    """The embedded ``"default"`` set: 9 everyday-like shapes generated in code."""
    return ObjectSet("default", [GraspObject(n, make_shape(n)) for n in DEFAULT_SHAPES])


# ----------------------------------------------------------------------------------- families
def _family_mesh(family: str, s: np.ndarray) -> trimesh.Trimesh:
    size = FAMILY_BASE_SIZE * s  # (3,) full extents
    if family == "box":
        m = trimesh.creation.box(extents=size)
    elif family == "elliptic_cylinder":
        m = trimesh.creation.cylinder(radius=0.5, height=1.0, sections=64)
        m.apply_scale(size)
    elif family == "ellipsoid":
        m = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
        m.apply_scale(size)
    else:
        raise ValueError(f"unknown family {family!r}; expected one of {FAMILIES}")
    return _refine(m)


def check_member_sizes(scale_range, size_range=None) -> tuple[float, float, float, float]:
    """``(lo, hi, size_lo, size_hi)`` of :func:`family_set`'s ranges (``size_range`` None: ``1, 1``), each a range of
    positive numbers; a ``ValueError`` naming them when the smallest member would be under
    :data:`MIN_FAMILY_MEMBER_SIZE` (checked by the analyses' config too, before any experiment runs)."""
    lo, hi = positive_range(scale_range, "scale_range")
    slo = shi = 1.0
    if size_range is not None:
        slo, shi = positive_range(size_range, "size_range")
    if FAMILY_BASE_SIZE * lo * slo < MIN_FAMILY_MEMBER_SIZE:
        raise ValueError(f"the smallest member would be {FAMILY_BASE_SIZE * lo * slo:.3g} m across (base "
                         f"{FAMILY_BASE_SIZE} m x scale_range {scale_range!r} x size_range {size_range!r}); members "
                         f"must be at least {MIN_FAMILY_MEMBER_SIZE} m")
    return lo, hi, slo, shi


def family_set(n_per_family: int, rng: np.random.Generator, families=FAMILIES,
               scale_range: tuple[float, float] = FAMILY_SCALE_RANGE,
               size_range: tuple[float, float] | None = None, lying: bool = False) -> ObjectSet:
    """The paper's geometry families: boxes, elliptic cylinders and ellipsoids.

    Each member has per-axis scale factors drawn uniformly from ``FAMILY_SCALE_RANGE`` about the
    base size ``FAMILY_BASE_SIZE`` (m). Objects are named ``"<family>_<ii>"`` (e.g. ``"box_03"``)
    and carry ``family``; ``ObjectSet.families`` maps names to families.

    Args:
        n_per_family: members per family (>= 1).
        rng: generator for the scale factors.
        families: subset/order of :data:`FAMILIES`.
        scale_range: ``(lo, hi)`` of the per-axis scale factors (``lo == hi``: cube, round cylinder, sphere).
        size_range: ``(lo, hi)`` of one more factor per member, common to its three axes (its overall size; drawn
            after the per-axis factors, so ``None``, the paper's generator, keeps the members of a seed). A robot hand's
            grasps depend on the object's size even after scale normalisation (its fingers keep their size), so
            hand-matched family grasps need members of the sizes of the objects to be recognised.
        lying: every second elliptic cylinder (odd index) lies on its side, its axis along x instead of z. An object on
            a table rests in one of its stable poses, and a hand that grasps from above touches a standing and a
            lying cylinder differently; a box or an ellipsoid on another face is just another member (its three
            factors are drawn alike). The draws and the other members are those of ``lying=False``.
    """
    whole_at_least(n_per_family, 1, "n_per_family")
    checked_flag(lying, "lying")
    fams = tuple(families) if isinstance(families, (list, tuple)) else ()
    if not fams or not all(isinstance(f, str) and f in FAMILIES for f in fams) or len(set(fams)) != len(fams):
        raise ValueError(f"families must be a non-empty list or tuple of distinct names from {FAMILIES}, "
                         f"got {families!r}")
    lo, hi, slo, shi = check_member_sizes(scale_range, size_range)
    objs = []
    for fam in fams:
        for i in range(int(n_per_family)):
            s = rng.uniform(lo, hi, size=3)
            if size_range is not None:
                s = s * rng.uniform(slo, shi)
            mesh = _family_mesh(fam, s)
            if lying and fam == "elliptic_cylinder" and i % 2 == 1:
                mesh.vertices = mesh.vertices @ up_rotation("x")  # row vectors: z -> x, the inverse of "x is up"
            mesh, _ = prepare_mesh(mesh, f"{fam}_{i:02d}")
            objs.append(GraspObject(f"{fam}_{i:02d}", mesh, family=fam))
    return ObjectSet("families", objs)
