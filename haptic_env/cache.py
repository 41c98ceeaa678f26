"""On-disk cache: where it lives, how keys are made, and atomic writes.

Every cached artefact (grasp datasets, trained recognisers, convex decompositions) is keyed by a
hash of the frozen config that produced it, and written through :func:`atomic_write` so a crash
or a concurrent writer never leaves a half-written file behind. A writer killed mid-write (``kill -9``)
leaves its hidden temporary file (``.<name>.pid<PID>.<random>.tmp``); :func:`cache_dir` removes such
files once their writer is gone (or after :data:`STALE_TMP_SECONDS`). :func:`cache_dir` also checks that
the folder is writable, so a read-only cache fails before any work is done, not when saving its result
(``HAPTIC_CACHE_READONLY=1`` allows a read-only cache; what it lacks is computed and, with a warning, not saved).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import re
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, Iterator

import numpy as np

__all__ = ["cache_dir", "config_key", "KEY_ONLY_WHEN_SET", "KEY_AS", "atomic_write", "save_npz_atomic", "load_npz",
           "CacheError", "CacheNotWritableError", "clean_stale_tmp", "STALE_TMP_SECONDS", "save_keyed_json",
           "load_keyed_json", "resume_state", "file_stem", "source_fingerprint", "package_fingerprint"]

#: A temporary file older than this is removed even if its writer's process id is still in use (6 h).
STALE_TMP_SECONDS = 6 * 3600.0
#: A temporary file whose writer's pid is not running here is removed once untouched this long (s): another
#: host or container sharing the folder may be writing it (its pid means nothing here), but not that slowly.
ORPHAN_TMP_SECONDS = 60.0
_HELP = "set HAPTIC_CACHE to a writable folder, or build without the cache (cache=False / --no-cache)"


class CacheError(RuntimeError):
    """A cache file exists but cannot be read (corrupted, truncated, wrong format)."""


class CacheNotWritableError(CacheError, PermissionError):
    """The cache folder cannot be created or written."""


def _cache_root() -> Path:
    return Path(os.environ.get("HAPTIC_CACHE", Path.home() / ".cache" / "haptic_recog")).expanduser()


def _readonly_ok() -> bool:
    return os.environ.get("HAPTIC_CACHE_READONLY", "") not in ("", "0")


def _in_readonly_cache(path: Path) -> bool:
    """Whether ``path`` lies in the cache while ``HAPTIC_CACHE_READONLY`` allows it to be read-only."""
    return _readonly_ok() and Path(os.path.abspath(path)).is_relative_to(os.path.abspath(_cache_root()))


def cache_dir(sub: str | None = None) -> Path:
    """Root of the cache (``$HAPTIC_CACHE``, default ``~/.cache/haptic_recog``), created on demand.

    Raises :class:`CacheNotWritableError` (naming the folder) if it cannot be created or is not writable,
    unless ``$HAPTIC_CACHE_READONLY`` is set (then a folder the cache lacks is returned all the same, with a warning:
    every file in it is a miss); removes stale temporary files of killed writers."""
    root = _cache_root()
    path = root / sub if sub else root
    readonly_ok = _readonly_ok()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if not readonly_ok:
            raise CacheNotWritableError(f"cannot create the cache folder {path} ({exc.strerror or exc}); {_HELP}") from exc
        if not path.is_dir():  # a read-only cache without this folder: it holds none of its files (each one a miss)
            warnings.warn(f"the read-only cache has no {path} ({exc.strerror or exc}; HAPTIC_CACHE_READONLY): what "
                          "belongs there is computed each time it is needed", stacklevel=2)
            return path
    if not readonly_ok:
        if not os.access(path, os.W_OK | os.X_OK):
            raise CacheNotWritableError(f"the cache folder {path} is not writable; {_HELP} "
                                        "(HAPTIC_CACHE_READONLY=1 reads a read-only cache and computes what it lacks "
                                        "without saving it)")
        clean_stale_tmp(path)
    return path


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: exists, owned by someone else
        return True
    return True


def clean_stale_tmp(folder: str | os.PathLike, max_age: float = STALE_TMP_SECONDS) -> list[Path]:
    """Remove the temporary files of :func:`atomic_write` in ``folder`` whose writer process is gone (untouched for
    :data:`ORPHAN_TMP_SECONDS`), or that are older than ``max_age`` seconds; returns the removed paths."""
    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        if not (e.name.startswith(".") and e.name.endswith(".tmp")) or not e.is_file(follow_symlinks=False):
            continue
        pid = None
        for part in e.name.split("."):
            if part.startswith("pid") and part[3:].isascii() and part[3:].isdigit() and len(part) <= 12:
                pid = int(part[3:])  # ascii digits only (int() refuses some that isdigit() accepts), pids fit int32
        try:
            age = now - e.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        orphan = pid is not None and pid != os.getpid() and age > ORPHAN_TMP_SECONDS and not _pid_alive(pid)
        if orphan or age > max_age:
            try:
                os.unlink(e.path)
                removed.append(Path(e.path))
            except OSError:
                pass
    return removed


#: Metadata flag of a dataclass field that is left out of :func:`config_key` while it holds its default, so that a
#: field added to a config later keeps the keys (and the cached files) of everything made before it existed.
KEY_ONLY_WHEN_SET = "key_only_when_set"
#: Metadata of a dataclass field that cannot change the artefact (a progress bar): :func:`config_key` keys it as the
#: value given here, whatever it holds, so that turning it on or off finds the same cached files.
KEY_AS = "key_as"


def _jsonable(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _jsonable(f.metadata[KEY_AS] if KEY_AS in f.metadata else getattr(obj, f.name))
                for f in dataclasses.fields(obj)
                if not (f.metadata.get(KEY_ONLY_WHEN_SET) and getattr(obj, f.name) == f.default)}
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in sorted(obj.items())}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return hashlib.sha1(np.ascontiguousarray(obj).tobytes()).hexdigest()
    if isinstance(obj, (np.integer, np.floating, np.bool_)):  # the key of the Python scalar
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def file_stem(name: str, default: str = "cache", length: int = 40) -> str:
    """``name`` (an object set's, a hand's: possibly a path) as the start of a cache file's name: each run of
    characters outside ``[A-Za-z0-9_.-]`` becomes one ``_``, cut to ``length`` characters (``default`` if nothing is
    left), so that the file stays in its cache folder whatever the name holds (a path's ``/``); the ``-<key>`` that
    follows it tells files apart."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name))[:length] or default


def config_key(*parts: Any, length: int = 16) -> str:
    """A short stable hex digest of dataclasses / dicts / scalars (the cache key of an artefact)."""
    blob = json.dumps(_jsonable(list(parts)), sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:length]


def source_fingerprint(*packages: str | os.PathLike) -> str:
    """sha256 of the Python sources of the package folders ``packages`` (each file's ``<package>/<relative path>``
    and bytes, in order): the code that made a saved partial result, so that a resume after a code change starts
    those parts again instead of mixing them with the new code's."""
    h = hashlib.sha256()
    for pkg in map(Path, packages):
        for f in sorted(pkg.rglob("*.py")):
            h.update(f"{pkg.name}/{f.relative_to(pkg).as_posix()}\0".encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def package_fingerprint(*more: str | os.PathLike) -> str:
    """:func:`source_fingerprint` of the ``haptic_env`` package and the folders ``more`` (a script's own, say): the
    code a kept result depends on, for the key of a run that resumes."""
    return source_fingerprint(Path(__file__).parent, *more)


def _umask() -> int:
    """The process's umask (read by setting it and putting it back: once, at import)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _umask()


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb") -> Iterator[Any]:
    """Open a temporary file next to ``path``; on clean exit fsync it and rename it into place.

    In a read-only cache that ``HAPTIC_CACHE_READONLY`` allows, a file that cannot be written there (a miss: the
    cache did not hold everything) is not saved: the writer's result is used all the same, and a warning names the
    file, which is computed again next time."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # hidden, with the writer's pid: clean_stale_tmp removes it if this process is killed mid-write
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.pid{os.getpid()}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        if not _in_readonly_cache(path):
            raise CacheNotWritableError(f"cannot write {path} ({exc.strerror or exc}); is its folder writable?") from exc
        warnings.warn(f"not saved: {path} ({exc.strerror or exc}; the cache is read-only, HAPTIC_CACHE_READONLY): "
                      "it is computed again each time it is needed", stacklevel=3)
        with open(os.devnull, mode) as fh:
            yield fh
        return
    try:
        with os.fdopen(fd, mode) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes it owner-only; a shared cache wants the umask's modes
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def save_keyed_json(path: str | os.PathLike, key: Any, **fields: Any) -> None:
    """Write ``{"key": key, **fields}`` as JSON to ``path`` atomically: the resume state of a long run, which
    :func:`load_keyed_json` gives back only to a run with the same ``key`` (its settings)."""
    with atomic_write(path, "w") as fh:
        json.dump({"key": key, **fields}, fh)


def load_keyed_json(path: str | os.PathLike, key: Any) -> dict | None:
    """The document :func:`save_keyed_json` wrote at ``path`` with this ``key``, or None (no file, unreadable, or
    another key: another run's settings)."""
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    # the key as JSON gives it back (tuples as lists, dict keys as strings), so that a key compares equal to itself
    return doc if isinstance(doc, dict) and doc.get("key") == json.loads(json.dumps(key)) else None


def resume_state(path: str | os.PathLike, key: Any, field: str) -> dict:
    """The finished parts (``field`` of the document :func:`save_keyed_json` wrote at ``path``) that an interrupted
    run with these settings (``key``) kept, or ``{}``; when there are some, says so on stderr with the path: a state
    kept by older code would be read back too unless ``key`` holds the code's :func:`source_fingerprint` (as the
    analyses' and the benchmarks' keys do: :func:`package_fingerprint`), and deleting the file computes them again."""
    parts = (load_keyed_json(path, key) or {}).get(field) or {}
    if parts:
        print(f"resuming: {len(parts)} finished part(s) kept in {path} (delete it to compute them again)",
              file=sys.stderr, flush=True)
    return parts


def save_npz_atomic(path: str | os.PathLike, **arrays: np.ndarray) -> Path:
    """``np.savez_compressed`` to ``path`` atomically."""
    with atomic_write(path) as fh:
        np.savez_compressed(fh, **arrays)
    return Path(path)


def load_npz(path: str | os.PathLike, required: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Load every array of an ``.npz``; raise :class:`CacheError` naming the file if it is unreadable."""
    path = Path(path)
    try:
        # the file is opened here, not by np.load: np.load leaks its handle when a corrupted zip fails to open
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as data:
            out = {k: data[k] for k in data.files}
    except FileNotFoundError:
        raise
    except Exception as exc:  # zipfile.BadZipFile, ValueError, EOFError, OSError ...
        raise CacheError(f"cache file {path} is corrupted or unreadable ({exc}); delete it to rebuild") from exc
    missing = [k for k in required if k not in out]
    if missing:
        raise CacheError(f"cache file {path} lacks arrays {missing}; delete it to rebuild")
    return out
