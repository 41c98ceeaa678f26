"""Hand-matched training grasps: each object mesh grasped by a robot hand's own MuJoCo model.

The recogniser is still trained from the meshes alone (no robot data), but its grasps come from
the same simulated hand, closing law and contact / normal extraction as the MuJoCo backend
(:class:`~haptic_env.grasping.mujoco_backend.MujocoBackend`, object fixed at the identity pose,
uniformly random approaches, or given ones for the replay backend's records). What a hand can touch
(fingertips on convex bulges, never in concavities, a bias towards its own aperture) and its torque-derived
normals with their error are then in the training distribution.

:func:`hand_grasp_pool` returns the raw grasps of every object (contacts, normals, touched
fingers), spread over processes (one task per chunk of approaches, all cores by default), with a
progress bar, and cached in ``cache_dir("hand_grasps")`` keyed by the meshes, the hand and the
settings. A build survives interruption: every finished chunk is saved at once (atomically, in a
``<pool>.parts`` folder next to the pool's file), and the next call with the same settings grasps only
the chunks that are missing; the folder is removed when the pool is saved. :func:`pool_rows` turns a
pool into ``z``-finger training grasps (a random ``z``-subset of the touching fingers of every grasp
with at least ``z``), which the dataset's ``"hand"`` source maps through Phi_n.

Budgets. ``budget="uniform"`` gives every object the same number of approaches. The Aero hand completes a
grasp (every finger touching) on nearly every approach to an apple but on 4 % of those to a plate lying on the
table, so the plate's model is learned from a few hundred grasps and the apple's from thousands.
``budget="balanced"`` keeps the total (``K x approaches``, up to rounding) and spreads it by :func:`balanced_counts`:
the first :func:`balanced_probe` approaches of every object (a quarter of the budget, at most :data:`PROBE`) are
grasped first, its complete-grasp rate measured, and the rest of the budget goes towards the objects whose grasps
rarely complete (weights between 1/2 and 2, then scaled to the total, none below what it already has). The pool does
not depend on :data:`CHUNK` (the cache key holds the probe).
Object ``k``'s approaches are one random stream whatever its count, so a balanced pool's first approaches of
an object are the uniform pool's.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import time
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from multiprocessing import current_process, get_all_start_methods, get_context
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from .cache import CacheError, cache_dir, clean_stale_tmp, config_key, file_stem, load_npz, save_npz_atomic
from .grasping.base import approach_table, check_solid_table, check_support, validate_actions
from .numbers import finite_number, whole_at_least, whole_number
from .processes import die_with_parent

__all__ = ["HandGraspPool", "hand_grasp_pool", "pool_actions", "table_actions", "pool_rows", "pool_cache_path",
           "hand_physics_key", "CHUNK", "BUDGETS", "balanced_counts", "parts_dir", "PROBE", "balanced_probe",
           "budget_key"]

#: the pools' cache version, also in the keys of the data sets built on them (``DatasetConfig.source_key``); v2: the
#: key holds the hand's physics (hand_physics_key)
POOL_VERSION = "hand-grasps-v2"
#: values of ``hand_grasp_pool(budget=...)`` (and ``DatasetConfig.hand_budget``)
BUDGETS = ("uniform", "balanced")
#: Approaches per worker task. A task builds its own backend and scene (0.1-0.5 s for the Menagerie hands, about
#: 1-2 s of grasping at 250 approaches), so a chunk of 1,000 keeps that under 5 % of the task.
CHUNK = 1000
#: The most approaches per object of a balanced budget's first phase (:func:`balanced_probe`).
PROBE = 1000


def balanced_probe(approaches: int) -> int:
    """Approaches per object that a balanced budget of ``approaches`` grasps first to measure each object's
    complete-grasp rate: a quarter of the budget (at least 1), at most :data:`PROBE`; an object's share seldom falls
    below it (weights of at least 1/2 against at most 2), and :func:`balanced_counts` keeps the total when it does."""
    return min(int(PROBE), max(1, int(approaches) // 4))


def budget_key(budget: str, approaches: int) -> list:
    """What a pool's ``budget`` adds to the cache keys of the pool and of the data sets built on it: nothing for
    ``"uniform"`` (the keys of before budgets existed); for ``"balanced"`` its name and :func:`balanced_probe`."""
    return [] if budget == "uniform" else [budget, f"probe={balanced_probe(approaches)}"]


@dataclass(frozen=True)
class HandGraspPool:
    """Raw grasps of ``K`` objects by one hand, ``counts[k]`` random approaches of object ``k`` (at most ``A``).

    Attributes:
        contacts: ``(K, A, n, 3)`` fingertip contacts (object frame, m; 0 where a finger missed).
        normals: ``(K, A, n, 3)`` torque-derived inward unit normals (0 where a finger missed).
        touched: ``(K, A, n)`` bool; rows ``counts[k]:`` of object ``k`` were never grasped (all False).
        names: the objects.
        hand: hand name; ``seconds``: generation wall time; ``from_cache``: read from the cache.
        counts: ``(K,)`` approaches per object (None: ``A`` each).
    """

    contacts: np.ndarray
    normals: np.ndarray
    touched: np.ndarray
    names: tuple[str, ...]
    hand: str
    seconds: float
    from_cache: bool = False
    counts: np.ndarray | None = None

    @property
    def approaches(self) -> np.ndarray:
        """``(K,)`` approaches grasped per object."""
        K, A = self.touched.shape[:2]
        return np.full(K, A) if self.counts is None else np.asarray(self.counts)

    @property
    def grasps_per_second(self) -> float:
        return float(self.approaches.sum() / max(self.seconds, 1e-9))

    def usable(self, z: int) -> np.ndarray:
        """``(K,)`` fraction of each object's grasps with at least ``z`` touching fingers."""
        return (self.touched.sum(-1) >= z).sum(axis=1) / self.approaches


def hand_physics_key(hand: str, n_fingers: int) -> str:
    """What a hand's grasps depend on besides the meshes and approaches: its MJCF (as compiled by MjSpec),
    closing law, physics options and the backend's defaults. A change to any of them gives a new key,
    so cached pools, datasets and recognisers of the old physics are not reused."""
    import dataclasses

    from .grasping.hands import load_hand
    from .grasping.mujoco_backend import MujocoConfig

    h = load_hand(hand, int(n_fingers))
    fields = {f.name: getattr(h, f.name) for f in dataclasses.fields(h) if f.name != "spec"}
    fields["option"] = {k: int(v) if hasattr(v, "value") else v for k, v in h.option.items()}
    # a hand with a joint actuator other than a position servo of gear 1 opens where its actuators hold the joints
    # since 2026-12-06 (GraspScene.reset), so its pools are built again; every other hand keeps its key
    held = [] if all(_plain_servo(a) for a in h.spec.actuators) else ["reset: held angles"]
    # a slide joint counts as at its limit within 0.5 mm since 2026-12-07 (GraspScene.dofs_at_limit; 1 cm before),
    # which moves its torque normals: a hand with one has its pools built again; hinge-only hands keep their key
    import mujoco

    if any(j.type == mujoco.mjtJoint.mjJNT_SLIDE for j in h.spec.joints):
        held.append("slide limits: 0.5 mm")
    # the mesh files' bytes since 2026-12-07: the XML names them only, so a changed mesh (another Menagerie version,
    # an edited STL) kept the pools of the old one; a hand without meshes keeps its key
    meshes = mesh_files_key(h.spec)
    # since 2026-12-07 (fiftieth session) the squeeze at a finger's first touch moves its closing actuators only
    # (GraspScene.hold_fingers: it turned the spread and neutral-held joints too) and the fingers count as at rest
    # at two checks in a row (MujocoConfig.rest_qvel): every hand's grasps change
    held.append("squeeze: closing actuators; rest: two checks")
    return config_key(h.spec.to_xml(), fields, MujocoConfig(n_fingers=int(n_fingers), hand=hand), *held,
                      *([f"meshes: {meshes}"] if meshes else []))


def mesh_files_key(spec) -> str:
    """sha256 over the bytes of the mesh files an ``MjSpec`` names (each under ``modelfiledir / meshdir`` or among its
    in-memory ``assets``; a file found in neither is keyed by its name), '' for a spec without mesh files."""
    names = sorted((m.name, m.file) for m in spec.meshes if m.file)
    if not names:
        return ""
    folder = Path(spec.modelfiledir or ".") / (spec.meshdir or "")
    assets = dict(getattr(spec, "assets", {}) or {})
    h = hashlib.sha256()
    for name, file in names:
        h.update(f"{name}\0{file}\0".encode())
        path = folder / file
        data = assets.get(file)
        if data is None and path.is_file():
            data = path.read_bytes()
        h.update(b"?" if data is None else hashlib.sha256(data).digest())
    return h.hexdigest()


def _plain_servo(act) -> bool:
    """An ``MjsActuator`` that is not on a joint, or a position servo of gear 1 on one whose control is the joint's
    angle (:func:`~.grasping.mujoco_backend.servo_equilibrium`: one control per unit of length, no offset)."""
    import mujoco

    from .grasping.mujoco_backend import servo_equilibrium

    if act.trntype != mujoco.mjtTrn.mjTRN_JOINT:
        return True
    per_length, offset = servo_equilibrium(act.gaintype, act.biastype, act.gainprm[0], act.biasprm[0], act.biasprm[1])
    return bool(act.gear[0] == 1.0 and per_length == 1.0 and offset == 0.0)


def pool_cache_path(objects, hand: str, n_fingers: int, approaches: int, support: str, seed: int,
                    budget: str = "uniform", actions: np.ndarray | None = None,
                    solid_table: bool | None = None) -> Path:
    given = [] if actions is None else [hashlib.sha256(np.ascontiguousarray(actions, np.float64)).hexdigest()]
    # a marker for the solid table only: the visual table's pools (the default before 2026-12-07) keep their keys
    key = config_key(POOL_VERSION, objects.identity, hand, int(n_fingers), int(approaches), support, int(seed),
                     hand_physics_key(hand, n_fingers), *budget_key(budget, approaches), *given,
                     *(["solid_table"] if check_solid_table(solid_table, support) else []))
    return cache_dir("hand_grasps") / f"{file_stem(hand, 'hand')}-{key}.npz"  # a hand may be an MJCF path


def balanced_counts(complete_rate, approaches: int, *, lo: float = 0.5, hi: float = 2.0, minimum: int = 1) -> np.ndarray:
    """Approaches per object for a budget of ``K x approaches`` spread towards objects whose grasps rarely complete.

    Object ``k``'s weight is ``median(rate) / rate_k`` clipped to ``[lo, hi]`` (a rate of 0 takes ``hi``), so
    each object's expected number of complete grasps moves towards the median object's; the counts are the
    weights scaled to the total, at least ``minimum`` each: an object whose share falls below it gets ``minimum``
    and the others share the rest of the total by their weights.

    Args:
        complete_rate: ``(K,)`` fraction of each object's approaches that gave a complete grasp, in ``[0, 1]``.
        approaches: the uniform count (the total is ``K * approaches``, up to rounding).
        minimum: an int in ``[0, approaches]``.

    Returns:
        ``(K,)`` int approaches per object.
    """
    r = np.asarray(complete_rate, dtype=np.float64)
    if r.ndim != 1 or len(r) == 0 or not np.all((r >= 0) & (r <= 1)):
        raise ValueError(f"complete_rate must be a non-empty (K,) array of fractions in [0, 1], got {complete_rate!r}")
    whole_at_least(approaches, 1, "approaches")
    if not (finite_number(lo) is not None and finite_number(hi) is not None and 0 < lo <= 1 <= hi):
        raise ValueError(f"need 0 < lo <= 1 <= hi, both finite, got lo={lo!r}, hi={hi!r}")
    if whole_at_least(minimum, 0, "minimum") > approaches:
        raise ValueError(f"minimum must be <= approaches={approaches} (the total is K x approaches), got {minimum!r}")
    med = float(np.median(r))
    with np.errstate(divide="ignore"):
        w = np.where(r > 0, med / np.where(r > 0, r, 1.0), hi) if med > 0 else np.ones_like(r)
    w = np.clip(w, lo, hi)
    total, low = len(r) * int(approaches), np.zeros(len(r), bool)
    while True:  # the objects whose share is below the minimum get it; the others share the rest (at most K rounds)
        share = (total - int(minimum) * int(low.sum())) * w / w[~low].sum()
        below = ~low & (share < minimum)
        if not below.any():
            return np.where(low, int(minimum), np.rint(share)).astype(np.int64)
        low |= below


def table_actions(table: int, yaws: int) -> np.ndarray:
    """``(table * yaws, 4)`` float64: each row of :func:`~haptic_env.grasping.base.approach_table` ``(table)`` turned
    about the vertical by ``yaws`` evenly spaced yaws (``2 pi j / yaws``, ``j = 0..yaws-1``; row ``i * yaws + j``), as
    the replay backend records them (``ReplayConfig.table``). ``table`` and ``yaws`` ints >= 1."""
    from .grasping.replay import turned_azimuth

    t = approach_table(whole_at_least(table, 1, "table")).astype(np.float64)
    psi = 2 * np.pi * np.arange(whole_at_least(yaws, 1, "yaws")) / yaws
    return turned_azimuth(np.repeat(t, len(psi), axis=0), np.tile(psi, len(t)))


def pool_actions(seed: int, k: int, count: int) -> np.ndarray:
    """``(count, 4)``: the first ``count`` random approaches of object ``k`` in a pool of ``seed`` (its stream
    ``SeedSequence([seed, k])``, the same whatever the object's count), as :func:`hand_grasp_pool` grasps them."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(k)])).uniform(-1, 1, (int(count), 4))


def _grasp_chunk(obj, hand: str, n_fingers: int, support: str, actions: np.ndarray, seed,
                 solid_table: bool | None = None) -> tuple:
    """Worker: grasp ``obj`` along ``actions (m, 4)`` -> contacts, normals, touched, seconds."""
    from .grasping import make_backend

    t0 = time.perf_counter()
    be = make_backend("mujoco", n_fingers=n_fingers, hand=hand, support=support, normals=True, solid_table=solid_table)
    try:
        be.set_object(obj)
        rng = np.random.default_rng(seed)
        m = len(actions)
        C, N, T = np.zeros((m, n_fingers, 3)), np.zeros((m, n_fingers, 3)), np.zeros((m, n_fingers), bool)
        for i, a in enumerate(actions):
            r = be.grasp(a, rng)
            C[i], N[i], T[i] = r.contacts, r.normals, r.touched
    finally:
        be.close()
    return C, N, T, time.perf_counter() - t0


def parts_dir(path: Path) -> Path:
    """The folder holding the finished chunks of an unfinished build of the pool cached at ``path``."""
    return path.with_name(path.stem + ".parts")


def _part_name(k: int, lo: int, hi: int) -> str:
    return f"k{int(k)}-{int(lo)}-{int(hi)}.npz"


def _load_parts(folder: Path, n_fingers: int) -> tuple[dict[tuple[int, int, int], tuple], float]:
    """The chunks an interrupted build saved in ``folder``: ``{(k, lo, hi): (C, N, T, seconds)}``, and the wall time
    those builds had spent when they saved their last chunk (summed over the builds). A part that cannot be read
    (a build killed while the disk was full, ...) is dropped with a warning and grasped again."""
    parts: dict[tuple[int, int, int], tuple] = {}
    spent: dict[str, float] = {}
    if not folder.is_dir():
        return parts, 0.0
    clean_stale_tmp(folder)
    for f in sorted(folder.glob("k*-*-*.npz")):
        try:
            k, lo, hi = (int(v) for v in f.stem[1:].split("-"))
            a = load_npz(f, ("contacts", "normals", "touched", "seconds", "build", "elapsed"))
            if a["touched"].shape != (hi - lo, n_fingers):
                raise CacheError(f"cache file {f} holds {a['touched'].shape[0]} grasps of {a['touched'].shape[1]} "
                                 f"fingers, not {hi - lo} of {n_fingers}")
        except FileNotFoundError:  # another build of the same pool finished and removed the folder meanwhile
            continue
        except (CacheError, ValueError) as exc:
            warnings.warn(f"{exc}; grasping that chunk again", RuntimeWarning, stacklevel=3)
            with contextlib.suppress(OSError):
                f.unlink()
            continue
        parts[k, lo, hi] = (a["contacts"], a["normals"], a["touched"].astype(bool), float(a["seconds"]))
        build = str(a["build"])
        spent[build] = max(spent.get(build, 0.0), float(a["elapsed"]))
    return parts, float(sum(spent.values()))


def hand_grasp_pool(objects, hand: str, n_fingers: int, approaches: int, *, support: str = "table", seed: int = 0,
                    budget: str = "uniform", workers: int | None = None, cache: bool = True, progress: bool = True,
                    actions: np.ndarray | None = None, solid_table: bool | None = None) -> HandGraspPool:
    """Grasp every object of ``objects`` with ``hand`` along uniformly random approaches (or along given ones).

    Args:
        objects: an ``ObjectSet`` (its collision pieces are used, as in the env).
        hand: a hand name of :func:`~haptic_env.grasping.hands.load_hand` ("allegro", "shadow", ...) or an
            MJCF path; ``n_fingers`` its fingers.
        approaches: random approaches per object ("uniform"), or their mean ("balanced"); with ``actions``, their
            count.
        budget: "uniform" or "balanced" (:func:`balanced_counts` of the complete-grasp rates of every object's first
            :func:`balanced_probe` approaches; see the module docstring).
        workers: processes (default: all cores); 1 runs in this process.
        cache: read / write ``cache_dir("hand_grasps")``.
        actions: ``(approaches, 4)`` approaches in ``[-1, 1]`` to grasp every object along, in this order, instead
            of the random ones (e.g. :func:`table_actions`); the cache key holds them. Needs ``budget="uniform"``.
        solid_table: whether the hand collides with the table (``MujocoConfig.solid_table``: by default wherever
            there is one; ``False``: the visual table of the hand figures before 2026-12-07).

    Object ``k``'s approaches come from ``SeedSequence([seed, k])`` (or are ``actions``) and chunk ``lo`` grasps with
    the random stream ``[seed, k, lo]``, so the pool does not depend on ``workers``, and an object's first
    approaches do not depend on its count. For the same reason an interrupted build (``cache=True``) resumes from
    its saved chunks (:func:`parts_dir`) and gives the pool an uninterrupted one gives; ``seconds`` then sums the
    builds' wall times up to their last saved chunk.
    """
    if not isinstance(hand, str):
        raise ValueError(f"hand must be a hand name or an MJCF path (a cache key), got {hand!r}")
    whole_at_least(approaches, 1, "approaches")
    whole_at_least(n_fingers, 2, "n_fingers")
    whole_at_least(seed, 0, "seed")
    if workers is not None:  # -3 and 1.7 were taken, 'two' a bare int() error
        whole_at_least(workers, 1, "workers")
    if budget not in BUDGETS:
        raise ValueError(f"budget must be one of {BUDGETS}, got {budget!r}")
    check_support(support)
    solid_table = check_solid_table(solid_table, support)
    if not cache:  # the cache key reads the hand (hand_physics_key); without it, an unknown one is named here too
        from .grasping.hands import load_hand

        load_hand(hand, int(n_fingers))
    if actions is not None:
        actions = validate_actions(actions, 4)
        if len(actions) != approaches or budget != "uniform":
            raise ValueError(f"given actions need approaches == len(actions) and budget='uniform', got {len(actions)} "
                             f"actions, approaches={approaches!r}, budget={budget!r}")
    path = pool_cache_path(objects, hand, n_fingers, approaches, support, seed, budget, actions,
                           solid_table) if cache else None
    if path is not None and path.exists():
        try:
            a = load_npz(path, ("contacts", "normals", "touched", "names", "seconds"))
            counts = a.get("counts")
            A = approaches if counts is None else int(counts.max())
            if tuple(str(n) for n in a["names"]) != tuple(objects.names) or a["touched"].shape[1:] != (A, n_fingers):
                raise CacheError(f"cache file {path} holds another pool")
            return HandGraspPool(a["contacts"], a["normals"], a["touched"].astype(bool), tuple(objects.names), hand,
                                 float(a["seconds"]), from_cache=True, counts=counts)
        except CacheError as exc:
            warnings.warn(f"{exc}; rebuilding it", RuntimeWarning, stacklevel=2)
    K = len(objects)
    first = balanced_probe(approaches)
    results: dict[tuple[int, int], tuple] = {}
    workers = min(K * -(-int(approaches) // CHUNK), int(workers or os.cpu_count() or 1))
    if workers > 1 and current_process().daemon:  # e.g. an SB3 SubprocVecEnv worker: it may not start processes
        workers = 1
    parts = parts_dir(path) if path is not None else None
    saved, spent = _load_parts(parts, n_fingers) if parts is not None else ({}, 0.0)
    build = f"{os.getpid()}-{time.time_ns()}"  # this build's id in its saved chunks
    t0 = time.perf_counter()
    bar = tqdm(total=K * approaches, desc=f"{hand} grasps", unit="grasp", disable=not progress, smoothing=0.1)
    if saved:
        bar.write(f"{hand} grasps: resuming an interrupted build, {sum(len(r[0]) for r in saved.values())} grasps "
                  f"saved in {parts}")

    def args(k, lo, hi):  # object k's approach stream, whatever its length, starts the same
        chunk = pool_actions(seed, k, hi)[lo:] if actions is None else actions[lo:hi]
        return (objects[k], hand, n_fingers, support, chunk, [seed, k, lo], solid_table)

    def chunks(counts, start=0):
        return [(k, lo, min(lo + CHUNK, int(counts[k]))) for k in range(K) for lo in range(start, int(counts[k]), CHUNK)]

    def phases():
        """Yields each phase's tasks ``(k, lo, hi)``; the balanced budget reads the first phase's results."""
        if budget == "uniform":
            yield chunks(np.full(K, approaches))
            return
        yield chunks(np.full(K, first))
        rate = np.array([np.concatenate([r[2] for (j, _), r in results.items() if j == k]).all(axis=1).mean()
                         for k in range(K)])  # over the first phase's chunks (all the results so far)
        counts = balanced_counts(rate, approaches, minimum=first)
        bar.total = int(counts.sum())
        bar.refresh()
        yield chunks(counts, start=first)

    def put(k, lo, hi, res, save=True):
        results[k, lo] = res
        if save and parts is not None:  # saved at once: an interrupted build resumes from here
            c, n, t, sec = res
            try:
                save_npz_atomic(parts / _part_name(k, lo, hi), contacts=c, normals=n, touched=t,
                                seconds=np.array(sec), build=np.array(build),
                                elapsed=np.array(time.perf_counter() - t0))
            except OSError as exc:  # only a resume aid (another build of the same pool may have just finished)
                warnings.warn(f"could not save a finished chunk in {parts} ({exc}); an interrupted build would grasp "
                              "it again", RuntimeWarning, stacklevel=2)
        bar.update(len(res[0]))

    def todo(tasks):
        """The tasks not saved by an earlier build (those are put from their saved chunks)."""
        for k, lo, hi in tasks:
            if (k, lo, hi) in saved:
                put(k, lo, hi, saved[k, lo, hi], save=False)
        return [t for t in tasks if t not in saved]

    try:
        _run(phases, todo, put, args, workers, objects)
    finally:
        bar.close()
    seconds = spent + time.perf_counter() - t0
    counts = np.array([sum(len(r[0]) for (j, _), r in results.items() if j == k) for k in range(K)])
    A = int(counts.max())
    C = np.zeros((K, A, n_fingers, 3))
    N = np.zeros_like(C)
    T = np.zeros((K, A, n_fingers), dtype=bool)
    for (k, lo), (c, n, t, _) in results.items():
        C[k, lo:lo + len(c)], N[k, lo:lo + len(c)], T[k, lo:lo + len(c)] = c, n, t
    counts = None if budget == "uniform" else counts
    pool = HandGraspPool(C, N, T, tuple(objects.names), hand, seconds, counts=counts)
    if path is not None:
        extra = {} if counts is None else {"counts": counts}
        save_npz_atomic(path, contacts=C, normals=N, touched=T, names=np.array(objects.names, dtype=str),
                        seconds=np.array(seconds), **extra)
        shutil.rmtree(parts, ignore_errors=True)
    return pool


def _run(phases, todo, put, args, workers: int, objects) -> None:
    """Grasp every phase's chunks that no earlier build saved (``todo``), in this process (``workers <= 1``) or over
    ``workers`` processes, handing each finished chunk to ``put`` as it comes. On an error or an interrupt the
    chunks not yet started are cancelled (those already saved stay: the same build resumes from them)."""
    if workers <= 1:
        for tasks in phases():
            for k, lo, hi in todo(tasks):
                put(k, lo, hi, _grasp_chunk(*args(k, lo, hi)))
        return
    # fork (Linux): workers need not re-import the caller's script, which "spawn" does (a script without a
    # __main__ guard would then run again in every worker); the workers use MuJoCo and numpy only.
    # Decompose the meshes here first: a forked worker that starts CoACD inherits its thread runtime from
    # this process without the threads and deadlocks (seen in the test suite); workers then read the pieces
    # from the collision cache.
    from .grasping.collision import convex_pieces

    for obj in objects:
        convex_pieces(obj)
    ctx = get_context("fork" if "fork" in get_all_start_methods() else "spawn")
    # the workers end with this process: a build killed alone (SIGKILL) left them grasping for good
    ex = ProcessPoolExecutor(workers, mp_context=ctx, initializer=die_with_parent, initargs=(os.getpid(),))
    try:
        for tasks in phases():
            futs = {ex.submit(_grasp_chunk, *args(k, lo, hi)): (k, lo, hi) for k, lo, hi in todo(tasks)}
            for f in as_completed(futs):
                put(*futs[f], f.result())
    finally:  # on an error or an interrupt the chunks not started are dropped (done: none is left), running ones finish
        ex.shutdown(wait=True, cancel_futures=True)


def pool_rows(pool: HandGraspPool, k: int, z: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``z``-finger grasps of object ``k``: every grasp with at least ``z`` touching fingers, reduced to a random
    ``z``-subset of them (fingers kept in hand order). Returns ``contacts (m, z, 3)``, ``normals (m, z, 3)``."""
    if whole_number(k) is None or not 0 <= k < len(pool.touched):  # -1 was the last object without a word
        raise ValueError(f"k must be an object index in [0, {len(pool.touched)}), got {k!r}")
    T = pool.touched[k]
    n = T.shape[1]
    if not 2 <= z <= n:
        raise ValueError(f"z must be in [2, {n}] for a {n}-finger hand, got {z!r}")
    ok = T.sum(1) >= z
    keys = rng.random(T[ok].shape) + 2.0 * ~T[ok]  # touching fingers sort first, in random order
    pick = np.sort(np.argsort(keys, axis=1)[:, :z], axis=1)[:, :, None]
    return (np.take_along_axis(pool.contacts[k][ok], pick, axis=1),
            np.take_along_axis(pool.normals[k][ok], pick, axis=1))
