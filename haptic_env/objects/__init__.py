"""Graspable objects: the embedded default set, the paper's geometry families and mesh folders."""

from .base import SAMPLING_METHODS, UP_AXES, GraspObject, ObjectSet, prepare_mesh, up_rotation
from .loaders import KIT8, MeshLoadError, data_dir, load_folder, load_object_set
from .primitives import DEFAULT_SHAPES, FAMILIES, default_set, family_set, make_shape

__all__ = [
    "GraspObject",
    "ObjectSet",
    "SAMPLING_METHODS",
    "prepare_mesh",
    "UP_AXES",
    "up_rotation",
    "load_object_set",
    "load_folder",
    "data_dir",
    "MeshLoadError",
    "KIT8",
    "DEFAULT_SHAPES",
    "FAMILIES",
    "default_set",
    "family_set",
    "make_shape",
]
