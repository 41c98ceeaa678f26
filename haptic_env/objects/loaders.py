"""Object sets by name or folder, and where the shared mesh data lives.

Specs understood by :func:`load_object_set`:

``"default"``
    9 everyday-like shapes generated in code (no files).
``"families"`` / ``"families:N"``
    The paper's boxes / elliptic cylinders / ellipsoids, ``N`` (default 10, at most 1,000) per family, seed 0.
``"kit8"``, ``"kit20"``
    KIT meshes from ``<data>/kit/*.stl`` (millimetres, converted to metres; y up in the files, stood up so
    that z is up: a bottle stands on the table instead of lying on its side). ``kit20`` is every file
    of the folder; its ``cube.stl`` is unit size in the file (the data set gives every other KIT mesh in
    millimetres), and is read as a cube of :data:`KIT_CUBE_SIDE` (80 mm), not 1 mm, which no hand can grasp.
``"ycb10"``
    ``<data>/ycb/NNN_name/mesh.stl`` (metres), with the ``collision_NN.stl`` convex pieces listed in
    :attr:`GraspObject.collision_paths`.
any folder
    Every ``*.stl`` / ``*.obj`` / ``*.ply`` in it (names = file stems), scaled by ``units`` and stood up by
    ``up`` (the files' up axis); or, if it has none, every sub-folder holding a ``mesh.stl`` (YCB layout).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import trimesh

from ..numbers import finite_number
from .base import GraspObject, ObjectSet, prepare_mesh, up_rotation
from .primitives import default_set, family_set

__all__ = ["data_dir", "load_object_set", "load_folder", "MeshLoadError", "KIT8", "KIT_CUBE_SIDE", "MESH_SUFFIXES",
           "unit_scale", "object_count", "check_object_spec", "NAMED_SETS"]

#: The KIT meshes' up axis (a bottle's axis, a cup's opening): y, as their extents show.
KIT_UP = "y"
#: The side (m) of kit20's ``cube.stl``, a unit cube in its file (the data set's other KIT meshes are in
#: millimetres): the median of the smallest extents of the 16 KIT object meshes (the primitives left out), 80.3 mm,
#: rounded. Read as millimetres it would be a 1 mm cube, which no hand grasps.
KIT_CUBE_SIDE = 0.08
#: KIT files read in other units than millimetres: file name (in lower case) -> metres per file unit.
KIT_FILE_UNITS = {"cube.stl": KIT_CUBE_SIDE}
#: The 8 KIT objects of the paper's main experiments.
KIT8 = ("CatLying", "GreenCup", "HeringTin", "Shampoo", "ShowerGel", "Sprayflask", "ToyCarYelloq", "Wineglass")
MESH_SUFFIXES = (".stl", ".obj", ".ply")
_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
_DATA_HELP = (
    "put the benchmark meshes (kit/*.stl, ycb/NNN_name/mesh.stl) in ../shared/data next to the "
    "repository, or set HAPTIC_DATA=/path/to/data"
)


class MeshLoadError(ValueError):
    """A mesh file that cannot be read or holds no usable triangles."""


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[2]  # <repo>/haptic_env/objects/loaders.py


def data_dir(required: bool = False) -> Path | None:
    """The shared data folder: ``$HAPTIC_DATA``, else ``<repo>/../shared/data``, else ``./../shared/data``.

    Args:
        required: raise :class:`FileNotFoundError` (saying where to put the files) instead of
            returning ``None`` when no folder is found.
    """
    env = os.environ.get("HAPTIC_DATA")
    if env:
        p = Path(env).expanduser()
        if p.is_dir():
            return p.resolve()
        msg = f"HAPTIC_DATA={env!r} is not a directory; {_DATA_HELP}"
        if required:
            raise FileNotFoundError(msg)
        warnings.warn(msg, stacklevel=2)
        return None
    places = list(dict.fromkeys(base.resolve().parent / "shared" / "data" for base in (_repo_root(), Path.cwd())))
    for p in places:
        if p.is_dir():
            return p.resolve()
    if required:
        raise FileNotFoundError(f"no data folder found (looked at $HAPTIC_DATA, {', '.join(map(str, places))}); "
                                f"{_DATA_HELP}")
    return None


def unit_scale(units: str | float) -> float:
    """Metres per file unit for ``"m"``, ``"cm"``, ``"mm"`` or a positive finite factor."""
    value = units
    if isinstance(units, str):
        if units.strip().lower() in _UNITS:
            return _UNITS[units.strip().lower()]
        try:  # a number given on a command line ("0.001"), which the help offers
            value = float(units)
        except ValueError:
            raise ValueError(f"unknown units {units!r}; expected one of {list(_UNITS)} or a positive number") from None
    elif isinstance(units, (bool, np.bool_)) or not isinstance(units, (int, float, np.integer, np.floating)):
        raise ValueError(f"units must be 'm', 'cm', 'mm' or a positive number, got {units!r}")
    f = finite_number(value)  # None for NaN, inf and ints beyond a float
    if f is None or f <= 0:
        raise ValueError(f"units factor must be positive and finite, got {units!r}")
    return f


#: A loaded object larger than this (m) gets a warning: its file is probably in millimetres (or cm).
MAX_PLAUSIBLE_SIZE = 3.0
#: A loaded object smaller than this (m) gets a warning: its file is probably in metres loaded as millimetres (an
#: object up to 50 cm across read with units="mm").
MIN_PLAUSIBLE_SIZE = 5e-4
#: A file coordinate beyond this (in the file's units) is rejected: no real object file holds one.
MAX_FILE_COORDINATE = 1e9


def _read_mesh(path: Path) -> trimesh.Trimesh:
    try:
        # unprocessed first: processing silently drops NaN / inf vertices and the faces using them
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:
        raise MeshLoadError(f"cannot read mesh file {path}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshLoadError(f"mesh file {path} holds no triangles (not a readable STL / OBJ / PLY mesh?)")
    shape = np.shape(mesh.vertices)
    if len(shape) != 2 or shape[1] != 3:  # a damaged OBJ can give 1-coordinate vertices, which trimesh takes
        raise MeshLoadError(f"mesh file {path}: its vertices have shape {shape}, not (n, 3) (a corrupted file?)")
    bad = ~np.isfinite(np.asarray(mesh.vertices, dtype=np.float64)).all(axis=1)
    if bad.any():
        raise MeshLoadError(f"mesh file {path}: {int(bad.sum())} of {len(bad)} vertices are not finite (NaN or inf), "
                            f"e.g. vertex {int(np.flatnonzero(bad)[0])}")
    reach = float(np.abs(mesh.vertices).max())
    if reach > MAX_FILE_COORDINATE:  # trimesh's vertex merging casts coordinates * 1e8 to int64: they would overflow
        raise MeshLoadError(f"mesh file {path}: a vertex coordinate is {reach:.3g} file units, beyond "
                            f"{MAX_FILE_COORDINATE:.0e} (a corrupted file?)")
    faces = np.asarray(mesh.faces)
    if faces.min() < 0 or faces.max() >= len(bad):  # a corrupted face list (trimesh does not check it)
        raise MeshLoadError(f"mesh file {path}: faces reference vertices outside [0, {len(bad)}), e.g. "
                            f"{int(faces.max() if faces.max() >= len(bad) else faces.min())}")
    try:
        mesh.process()  # merge duplicate vertices (what loading with process=True does)
    except Exception as exc:  # whatever else trimesh trips on in a damaged file, named with the file
        raise MeshLoadError(f"cannot process mesh file {path}: {type(exc).__name__}: {exc}") from exc
    if len(mesh.faces) == 0:
        raise MeshLoadError(f"mesh file {path} holds no triangles")
    return mesh


def load_mesh_object(path: str | Path, *, units: str | float = "m", name: str | None = None,
                     collision_paths: tuple[Path, ...] = (), up: str = "z") -> GraspObject:
    """One :class:`GraspObject` from a mesh file (scaled to metres, its ``up`` axis turned to z, centred)."""
    path = Path(path)
    name = name or path.stem
    R = up_rotation(up)  # a bad axis is named before the file is read
    try:
        mesh, offset = prepare_mesh(_read_mesh(path), name, unit_scale(units), up)
    except MeshLoadError:
        raise
    except ValueError as exc:
        raise MeshLoadError(f"mesh file {path}: {exc}") from exc
    area = float(mesh.area)
    if not (np.isfinite(area) and area > 0.0):  # every face degenerate, or coordinates so large the area overflows
        raise MeshLoadError(f"mesh file {path}: surface area {area} m^2 with units={units!r} (all faces degenerate, "
                            "or coordinates out of range); nothing to grasp")
    size = float(np.max(mesh.extents))
    likely = ("millimetres", "mm") if size > MAX_PLAUSIBLE_SIZE else ("metres", "m") if size < MIN_PLAUSIBLE_SIZE \
        else None
    if likely is not None:
        warnings.warn(f"mesh file {path}: object {name!r} is {size:.3g} m across with units={units!r}; are the file's "
                      f"coordinates in {likely[0]}? (load it with units='{likely[1]}', e.g. object_kwargs={{'units': "
                      f"'{likely[1]}'}})", UserWarning, stacklevel=2)
    return GraspObject(name, mesh, source=path, collision_paths=tuple(collision_paths), offset=offset, rotation=R,
                       unit_scale=unit_scale(units))


def load_folder(folder: str | Path, *, units: str | float = "m", name: str | None = None, up: str = "z") -> ObjectSet:
    """Every STL/OBJ/PLY file of ``folder`` (sorted by name), or its ``*/mesh.stl`` sub-folders, each with its
    ``up`` axis (one of :data:`~haptic_env.objects.base.UP_AXES`) turned to z.

    Raises:
        FileNotFoundError: the folder does not exist.
        ValueError: it contains no mesh files.
        MeshLoadError: a file cannot be read (the message names it).
    """
    folder = Path(folder).expanduser()
    if not folder.is_dir():
        raise FileNotFoundError(f"object folder {folder} does not exist")
    unit_scale(units)  # a bad value is named before any file is read
    up_rotation(up)
    files = _mesh_files(folder)
    set_name = name or folder.name
    if files:
        return ObjectSet(set_name, [load_mesh_object(p, units=units, up=up) for p in files])
    subs = sorted(p for p in folder.iterdir() if (p / "mesh.stl").is_file())
    if subs:
        return ObjectSet(
            set_name,
            [
                load_mesh_object(p / "mesh.stl", units=units, name=p.name, up=up,
                                 collision_paths=_collision_files(p))
                for p in subs
            ],
        )
    raise ValueError(f"object folder {folder} has no mesh files ({', '.join(MESH_SUFFIXES)}) "
                     "and no sub-folders with a mesh.stl")


def _mesh_files(folder: Path) -> list[Path]:
    """``folder``'s mesh files (a suffix of :data:`MESH_SUFFIXES`, in any case), sorted by name."""
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)


def _collision_files(folder: Path) -> tuple[Path, ...]:
    """``folder``'s ``collision_*.stl`` files, sorted by name, the suffix in any case (as the meshes': an upper-case
    ``collision_00.STL`` was skipped, and the physics backend decomposed the mesh instead)."""
    return tuple(sorted(q for q in folder.iterdir()
                        if q.is_file() and q.name.lower().startswith("collision_") and q.suffix.lower() == ".stl"))


def _kit(root: Path, names: tuple[str, ...] | None, set_name: str) -> ObjectSet:
    """The KIT meshes ``names`` (None: the whole folder) of a data folder that :func:`check_object_data` checked."""
    kit = root / "kit"
    if names is None:
        files = _mesh_files(kit)
        if not files:
            raise ValueError(f"object folder {kit} has no mesh files ({', '.join(MESH_SUFFIXES)})")
    else:
        files = [kit / f"{n}.stl" for n in names]
    return ObjectSet(set_name, [load_mesh_object(p, units=KIT_FILE_UNITS.get(p.name.lower(), "mm"), up=KIT_UP)
                                for p in files])


def object_count(spec: str | Path = "default", *, data_dir: str | Path | None = None,
                 units: str | float = "m", up: str = "z") -> int | None:
    """How many objects :func:`load_object_set` would return for ``spec``, without reading any mesh (a folder
    listing at most); None when that is not known cheaply (named data sets: loading them raises its own error if
    their data is missing). Takes the same arguments as ``load_object_set``, and rejects a bad ``up`` and an unknown
    spec (:func:`check_object_spec`) as it does."""
    up_rotation(up)
    unit_scale(units)
    s = check_object_spec(spec)
    if s == "default":
        from .primitives import DEFAULT_SHAPES

        return len(DEFAULT_SHAPES)
    if s == "families" or s.startswith("families:"):
        return 3 * _family_members(s)
    if s == "kit8":
        return len(KIT8)
    if s in ("kit20", "ycb10"):
        return None
    p = Path(s).expanduser()  # an existing folder (check_object_spec)
    files = _mesh_files(p)
    if files:
        return len(files)
    return sum(1 for f in p.iterdir() if (f / "mesh.stl").is_file())


def load_object_set(spec: str | Path = "default", *, data_dir: str | Path | None = None,
                    units: str | float = "m", up: str = "z") -> ObjectSet:
    """An :class:`ObjectSet` by name (``default``, ``families[:N]``, ``kit8``, ``kit20``, ``ycb10``) or folder.

    Args:
        spec: set name or folder path (see the module docstring).
        data_dir: shared data folder for the named file sets (default: :func:`data_dir`).
        units: units of a folder's files (``"m"``, ``"cm"``, ``"mm"`` or metres per unit); named
            sets use their known units and ignore it.
        up: a folder's files' up axis (``"x"``, ``"y"`` or ``"z"``), turned to z so that the objects stand on a
            table as they should; named sets use their known axis (KIT: y) and ignore it.
    """
    up_rotation(up)  # a bad axis or unit is named first, whatever the spec (named sets ignore a good one)
    unit_scale(units)
    s = check_object_spec(spec)
    if s == "default":
        return default_set()
    if s == "families" or s.startswith("families:"):
        return family_set(_family_members(s), np.random.default_rng(0))
    if s in ("kit8", "kit20", "ycb10"):
        root = check_object_data(s, data_dir)
        if s == "kit8":
            return _kit(root, KIT8, "kit8")
        if s == "kit20":
            return _kit(root, None, "kit20")
        return load_folder(root / "ycb", units="m", name="ycb10")
    return load_folder(Path(s).expanduser(), units=units, up=up)


def check_object_data(spec: str | Path, data_dir: str | Path | None = None) -> Path | None:
    """Whether the files of a named file set (``kit8``, ``kit20``, ``ycb10``) are there, without reading a mesh:
    a ``FileNotFoundError`` says what is missing and where to put it; returns the data folder (None for the other
    specs, which need no shared data)."""
    s = check_object_spec(spec)
    if s not in ("kit8", "kit20", "ycb10"):
        return None
    if data_dir is not None and not isinstance(data_dir, (str, os.PathLike)):
        raise ValueError(f"data_dir must be a folder path or None, got {data_dir!r}")
    root = Path(data_dir).expanduser() if data_dir is not None else globals()["data_dir"](required=True)
    if not root.is_dir():
        raise FileNotFoundError(f"data folder {root} does not exist; {_DATA_HELP}")
    sub = root / ("ycb" if s == "ycb10" else "kit")
    if not sub.is_dir():
        raise FileNotFoundError(f"{'YCB' if s == 'ycb10' else 'KIT'} meshes missing: {sub} does not exist; "
                                f"{_DATA_HELP}")
    missing = [f"{n}.stl" for n in KIT8 if not (sub / f"{n}.stl").is_file()] if s == "kit8" else []
    if missing:
        raise FileNotFoundError(f"KIT meshes missing from {sub}: {missing}; {_DATA_HELP}")
    return root


def _family_members(spec: str) -> int:
    """The members per family of a checked ``families[:N]`` spec (:func:`check_object_spec`): ``N``, else 10."""
    return int(spec.split(":", 1)[1]) if ":" in spec else 10


#: The most members per family ``families:N`` takes (3 N objects; the experiments use up to 40).
MAX_FAMILY_MEMBERS = 1000

#: The object sets :func:`load_object_set` knows by name (besides ``families:N`` and folders).
NAMED_SETS = ("default", "families", "kit8", "kit20", "ycb10")


def check_object_spec(spec: str | Path) -> str:
    """``spec`` as :func:`load_object_set` reads it, checked without loading anything: a named set, ``families:N``
    (``1 <= N <= MAX_FAMILY_MEMBERS``) or an existing folder; otherwise a ``ValueError`` that names it. (Whether a
    named file set's data is there is checked when it loads.)"""
    s = str(spec)
    if s in NAMED_SETS:
        return s
    if s.startswith("families:"):
        n = s.split(":", 1)[1]
        if not (n.isascii() and n.isdigit() and 1 <= int(n) <= MAX_FAMILY_MEMBERS):  # "²".isdigit() is True
            raise ValueError(f"bad families spec {s!r}; expected 'families' or 'families:N' with "
                             f"1 <= N <= {MAX_FAMILY_MEMBERS}")
        return s
    if Path(s).expanduser().is_dir():
        return s
    raise ValueError(f"unknown object set {s!r}: expected 'default', 'families[:N]', 'kit8', 'kit20', "
                     "'ycb10' or an existing folder of STL/OBJ/PLY files")
