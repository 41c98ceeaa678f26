"""Graspable objects: the embedded default set, the paper's geometry families and mesh folders."""

from .base import SAMPLING_METHODS, GraspObject, ObjectSet, prepare_mesh
from .loaders import KIT8, MeshLoadError, data_dir, load_folder, load_object_set
from .primitives import DEFAULT_SHAPES, FAMILIES, default_set, family_set, make_shape

__all__ = [
    "GraspObject",
    "ObjectSet",
    "SAMPLING_METHODS",
    "prepare_mesh",
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
