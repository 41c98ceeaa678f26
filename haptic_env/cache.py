"""On-disk cache: where it lives, how keys are made, and atomic writes.

Every cached artefact (grasp datasets, trained recognisers, convex decompositions) is keyed by a
hash of the frozen config that produced it, and written through :func:`atomic_write` so a crash
or a concurrent writer never leaves a half-written file behind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np

__all__ = ["cache_dir", "config_key", "atomic_write", "save_npz_atomic", "load_npz", "CacheError"]


class CacheError(RuntimeError):
    """A cache file exists but cannot be read (corrupted, truncated, wrong format)."""


def cache_dir(sub: str | None = None) -> Path:
    """Root of the cache (``$HAPTIC_CACHE``, default ``~/.cache/haptic_recog``), created on demand."""
    root = Path(os.environ.get("HAPTIC_CACHE", Path.home() / ".cache" / "haptic_recog")).expanduser()
    path = root / sub if sub else root
    path.mkdir(parents=True, exist_ok=True)
    return path


def _jsonable(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in sorted(obj.items())}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return hashlib.sha1(np.ascontiguousarray(obj).tobytes()).hexdigest()
    if isinstance(obj, (np.integer, np.floating)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def config_key(*parts: Any, length: int = 16) -> str:
    """A short stable hex digest of dataclasses / dicts / scalars (the cache key of an artefact)."""
    blob = json.dumps(_jsonable(list(parts)), sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:length]


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb") -> Iterator[Any]:
    """Open a temporary file next to ``path``; on clean exit fsync it and rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def save_npz_atomic(path: str | os.PathLike, **arrays: np.ndarray) -> Path:
    """``np.savez_compressed`` to ``path`` atomically."""
    with atomic_write(path) as fh:
        np.savez_compressed(fh, **arrays)
    return Path(path)


def load_npz(path: str | os.PathLike, required: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Load every array of an ``.npz``; raise :class:`CacheError` naming the file if it is unreadable."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            out = {k: data[k] for k in data.files}
    except FileNotFoundError:
        raise
    except Exception as exc:  # zipfile.BadZipFile, ValueError, EOFError, OSError ...
        raise CacheError(f"cache file {path} is corrupted or unreadable ({exc}); delete it to rebuild") from exc
    missing = [k for k in required if k not in out]
    if missing:
        raise CacheError(f"cache file {path} lacks arrays {missing}; delete it to rebuild")
    return out
