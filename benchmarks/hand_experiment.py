"""The paper's hand table: recognise the 10 YCB objects from simulated robot-hand grasps.

Each hand (MuJoCo backend) grasps each object along random approaches; the fingertip contacts (and,
with normals, the torque-derived normals) of each grasp update a belief until its certainty reaches
lambda or ``--max-grasps`` grasps are spent. Methods (the paper's rows): IC, BC-NP, BC-IP, and IC and
BC-NP scored on ``k = 4`` random 3-finger subsets of each grasp (z = 3). A grasp with fewer than 3
touching fingertips carries no information but is spent; an incomplete grasp with 3 <= t < n is scored
by the t-finger model. Every method sees the same grasp sequences (common random numbers). In the hand regime
the BC-NP rows also weigh each grasp's touch pattern (which fingertips touched) by ``--touch-weight``, by default
the hand's registered env's ``touch_weight`` (:mod:`haptic_env.recognizers.touch`); then every grasp carries
information. The paper's BC-IP row does not; the row ``BC-IP, touch`` (hand regime only, not the paper's method)
weighs it as BC-NP does, its classifier prior set by the first grasp the classifier scores.

Two training regimes per hand, both computed from the meshes alone:

* ``surface``: the paper's way, hand-independent: random surface points with Gaussian contact noise
  (``--surface-noise`` m) and normal noise (``--surface-normal-noise`` deg);
* ``hand``: hand-matched: the hand's own MuJoCo model grasping each mesh
  (``DatasetConfig(source="hand")``, ``--approaches`` per object, by default the hand's registered env's
  ``training_grasps``; training seed 0).

Test sequences are fresh hand grasps (pool seeds ``1000 + seed``, never used for training or for
the calibration temperatures, which are fitted on the training grasps' validation split: the KDE's for
beliefs of 1 to ``--calibrate-grasps`` grasps of one object, by default the hand's registered env's setting;
``--kde-bandwidth per-class`` gives each object its own KDE bandwidth instead of the envs' shared one);
``--split validation`` draws them from pool seeds ``500 + seed`` instead, for choosing settings.
``--heights`` appends the contacts' heights above the table to every grasp vector, in training and in the
queries (``DatasetConfig.heights``, the envs' ``grasp_heights``; the objects rest upright as in the pools); the
defaults then come from the hand's ``Heights`` env (:data:`HEIGHTS_ENV_IDS`), which sets ``grasp_heights``.
``--likelihood hgb`` puts gradient boosting in the KDE's place as every BC row's likelihood (opt-in, the envs'
``HapticRecogConfig.likelihood``; its sequence temperature fitted for the same ``K`` grasps); the IC and BC-IP rows'
classifier is the MLP either way.
``--queries`` queries per object and seed; the spread is the std over ``--seeds``.

    python benchmarks/hand_experiment.py [--hands allegro shadow aero] [--queries 10] [--seeds 0 1 2]
        [--max-grasps 30] [--approaches 3000] [--regimes surface hand] [--raw] [--out results/hands]
        [--hand-budget uniform|balanced] [--kde-bandwidth shared|per-class]   # options measured, not the envs'
        [--touch-weight W] [--heights] [--ic-certainty count|share] [--normal-axis t2|ab|frame] [--likelihood kde|hgb]
    python benchmarks/hand_experiment.py --plot results/hands/hand_table.md   # draws a written table, runs nothing

Prints (and with ``--out`` writes ``hand_table.md`` and its plot ``hand_table.png``) the table with the paper's
figure beside each cell; the headline is printed last. ``--plot FILE`` runs no experiment: it draws the table in
``FILE`` (a ``hand_table.md`` this script wrote) as the PNG beside it, so a committed table gets its plot.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from haptic_env import variant_config  # noqa: E402
from haptic_env.cache import atomic_write  # noqa: E402
from haptic_env.cli import distinct, float_in, int_in, output_path, script_command  # noqa: E402
from haptic_env.config import HAND_APPROACHES, HapticRecogConfig  # noqa: E402
from haptic_env.dataset import DatasetConfig, support_frame  # noqa: E402
from haptic_env.grasp_features import NORMAL_AXES, NORMAL_AXIS_WORDS  # noqa: E402
from haptic_env.grasping.hands import HandUnavailableError  # noqa: E402
from haptic_env.hand_grasps import BUDGETS, hand_grasp_pool  # noqa: E402
from haptic_env.objects import data_dir, load_object_set  # noqa: E402
from haptic_env.recognizers import KDEConfig, RecognizerConfig, build_recognizer  # noqa: E402
from haptic_env.recognizers.boosted import LIKELIHOODS, BoostedConfig  # noqa: E402
from haptic_env.recognizers.kde import BANDWIDTHS  # noqa: E402
from haptic_env.recognizers.updaters import (DEFAULT_IC_CERTAINTY, DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD,  # noqa: E402
                                             IC_CERTAINTIES)
from haptic_env.splits import hand_pool_seed  # noqa: E402

#: hand -> (fingers, normals settings); the paper: Allegro with and without normals, 5-finger hands without.
SETUPS = {"allegro": (4, (True, False)), "shadow": (5, (False,)), "aero": (5, (False,))}
#: hand -> its registered env (whose ``calibrate_grasps`` and ``training_grasps`` the table uses unless
#: ``--calibrate-grasps`` / ``--approaches`` are given)
ENV_IDS = {"allegro": "HapticRecogMuJoCo-v0", "shadow": "HapticRecogShadow-v0", "aero": "HapticRecogAero-v0"}
#: the same with the contacts' heights (``--heights``): the hands' ``Heights`` envs (``grasp_heights=True``)
HEIGHTS_ENV_IDS = {name: env_id.replace("-v0", "Heights-v0") for name, env_id in ENV_IDS.items()}
#: label -> (updater kind, z, random subsets per grasp)
METHODS = {"IC": ("ic", None, None), "BC-NP": ("bc-np", None, None), "BC-IP": ("bc-ip", None, None),
           "IC, z=3": ("ic", 3, 4), "BC-NP, z=3": ("bc-np", 3, 4), "BC-IP, touch": ("bc-ip", None, None)}
#: the rows that weigh the touch pattern in the hand regime (the paper's BC-IP row does not; its figure stands beside
#: "BC-IP, touch" too)
TOUCH_ROWS = ("BC-NP", "BC-NP, z=3", "BC-IP, touch")
#: the paper's table (success % / grasps): Pisa/IIT SoftHand (5, w/o), Allegro (4, w/o), Allegro (4, w/)
PAPER = {
    "IC": {"5-": (89, 3.76), "4-": (81, 2.97), "4+": (87, 3.78)},
    "BC-NP": {"5-": (94, 8.15), "4-": (94, 10.45), "4+": (92, 4.80)},
    "BC-IP": {"5-": (90, 4.86), "4-": (92, 9.18), "4+": (93, 4.17)},
    "IC, z=3": {"5-": (51, 1.04), "4-": (52, 1.25), "4+": (49, 1.14)},
    "BC-NP, z=3": {"5-": (92, 4.22), "4-": (93, 4.85), "4+": (94, 1.62)},
}
PAPER["BC-IP, touch"] = PAPER["BC-IP"]
#: rows whose paper figure is another method's (the plot joins them to it without a marker of their own)
BORROWED = ("BC-IP, touch",)


#: method -> its marker in the plot; training regime -> its colour (the paper's figures: hollow, black)
MARKERS = {"IC": "o", "BC-NP": "s", "BC-IP": "D", "IC, z=3": "^", "BC-NP, z=3": "v", "BC-IP, touch": "P"}
REGIME_COLORS = {"hand": "C0", "surface": "0.55"}
#: the table's header, as :func:`main` writes it (the temperature column names the likelihood)
TABLE_HEADER = ("| hand | fingers | normals | training | method | success % | accuracy % | grasps | "
                "paper (success % / grasps) |")


def seed_std(x: np.ndarray) -> float:
    """The sample standard deviation over seeds (ddof = 1): the "+-" of the hand benchmarks; NaN for one seed, which
    has no spread to give (it printed 0 under a caption that says ddof = 1)."""
    x = np.asarray(x, dtype=np.float64)
    return float(np.std(x, ddof=1)) if x.size > 1 else float("nan")


def pm(x, scale: float = 1.0, digits: int = 1) -> str:
    """``x``'s mean and sample std over seeds (:func:`seed_std`), times ``scale``, as "mean +- std"; one seed's cell is
    its value alone (it printed "+- nan"). :func:`read_table` reads both."""
    x = scale * np.asarray(x, dtype=np.float64)
    s = seed_std(x)
    return f"{x.mean():.{digits}f}" if np.isnan(s) else f"{x.mean():.{digits}f} +- {s:.{digits}f}"


def check_pool_seeds(ap: argparse.ArgumentParser, split: str, seeds) -> None:
    """``ap.error`` unless every ``--seeds`` value is given once and lies in ``split``'s pool range (before the first
    pool is built; the hand benchmarks' one check)."""
    distinct(ap, "--seeds", seeds)
    try:
        for s in seeds:
            hand_pool_seed(split, s)
    except ValueError as exc:
        ap.error(f"--seeds: {exc}")


def query_pools(objects, hand: str, n: int, split: str, seeds, queries: int, max_grasps: int) -> tuple[list, float] | None:
    """The query pools of ``split`` (``"test"``: pool seeds ``1000 + s``; ``"validation"``: ``500 + s``), one per seed
    with ``queries x max_grasps`` random-approach grasps per object, and their usable rate (>= 3 touching
    fingertips); None (said on stdout) when the hand cannot be loaded."""
    try:
        pools = [hand_grasp_pool(objects, hand, n, queries * max_grasps, seed=hand_pool_seed(split, s)) for s in seeds]
    except HandUnavailableError as exc:
        print(f"skipping {hand}: {exc}")
        return None
    return pools, float(np.mean([(p.touched.sum(-1) >= 3).mean() for p in pools]))


def env_config(name: str, heights: bool = False) -> HapticRecogConfig:
    """The registered env of hand ``name`` (:data:`ENV_IDS`; with ``heights`` :data:`HEIGHTS_ENV_IDS`), whose settings
    are the table's defaults."""
    return variant_config((HEIGHTS_ENV_IDS if heights else ENV_IDS)[name])


def write_table(out: Path, name: str, script: str, argv, seconds: float, text: str) -> None:
    """Write ``text`` to ``out/name`` atomically, headed by the command that made it (``python benchmarks/<script>
    <argv>``; the process's own arguments when ``argv`` is None) and its wall time."""
    with atomic_write(out / name, "w") as fh:
        fh.write(f"`{script_command(script, argv)}` ({seconds:.0f} s)\n\n{text}\n")


def read_table(text: str) -> tuple[list[dict], float]:
    """The rows of a table this script wrote (a ``hand_table.md``'s text) and its lambda.

    Each row: ``hand``, ``fingers`` (int), ``normals`` (bool), ``training``, ``method``, ``success`` and
    ``success_std`` (fractions), ``grasps`` and ``grasps_std``, ``paper`` (success fraction, grasps). ValueError, naming
    what is missing, when ``text`` holds no such table."""
    lines = [ln.strip() for ln in text.splitlines() if ln.startswith("|")]
    if not lines or not lines[0].startswith(TABLE_HEADER):
        raise ValueError(f"no hand table: no line starts with {TABLE_HEADER!r}")
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    m = re.search(r"lambda = ([0-9.]+)", text)
    if m is None:
        raise ValueError("no 'lambda = ...' in the table's caption")

    def mean_std(cell: str) -> tuple[float, float]:
        mean, _, std = cell.partition("+-")
        return float(mean), float(std) if std.strip() else float("nan")  # one seed: the value alone

    rows = []
    for ln in lines[2:]:  # after the header and its |---| line
        c = dict(zip(head, (x.strip() for x in ln.strip("|").split("|"))))
        try:
            if c.get("method") not in METHODS or len(c) != len(head):
                raise ValueError
            (s, s_std), (g, g_std) = mean_std(c["success %"]), mean_std(c["grasps"])
            ps, pg = (float(x) for x in c["paper (success % / grasps)"].split("/"))
        except ValueError:
            raise ValueError(f"not a row of the hand table: {ln!r}") from None
        rows.append({"hand": c["hand"], "fingers": int(c["fingers"]), "normals": c["normals"] == "yes",
                     "training": c["training"], "method": c["method"], "success": s / 100, "success_std": s_std / 100,
                     "grasps": g, "grasps_std": g_std, "paper": (ps / 100, pg)})
    if not rows:
        raise ValueError("the hand table has no rows")
    return rows, float(m.group(1))


def plot_hand_table(rows: list[dict], path: Path, threshold: float = DEFAULT_THRESHOLD) -> None:
    """Success at the stop against mean grasps (log axis), one panel per hand and normals setting (the paper's
    columns): each method's row per training regime (filled, +- seed std; :data:`MARKERS`, :data:`REGIME_COLORS`)
    and the paper's figure (hollow, black), joined to the hand-matched row of the same method by a dashed line; the
    dotted line is lambda - 3 points. ``rows`` as :func:`read_table` gives them; written atomically to ``path``."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    panels = list(dict.fromkeys((r["hand"], r["fingers"], r["normals"]) for r in rows))
    xs = [r["grasps"] for r in rows] + [r["paper"][1] for r in rows]
    fig = Figure(figsize=(4.0 * len(panels) + 0.6, 4.4))
    axes = fig.subplots(1, len(panels), squeeze=False, sharey=True)[0]
    for ax, key in zip(axes, panels):
        mine = [r for r in rows if (r["hand"], r["fingers"], r["normals"]) == key]
        for r in mine:
            ax.errorbar(r["grasps"], 100 * r["success"], xerr=r["grasps_std"], yerr=100 * r["success_std"],
                        fmt=MARKERS[r["method"]], color=REGIME_COLORS.get(r["training"], "C1"), ms=6, capsize=2)
        for method in dict.fromkeys(r["method"] for r in mine):
            ps, pg = next(r["paper"] for r in mine if r["method"] == method)
            if method not in BORROWED:
                ax.plot(pg, 100 * ps, MARKERS[method], mfc="none", mec="k", ms=8)
            matched = next((r for r in mine if r["method"] == method and r["training"] == "hand"), None)
            if matched is not None:
                ax.plot([pg, matched["grasps"]], [100 * ps, 100 * matched["success"]], ls="--", lw=0.8, color="k",
                        alpha=0.45)
        ax.axhline(100 * (threshold - 0.03), ls=":", color="C3", lw=1)
        ax.set_xscale("log")
        ax.set_xlim(min(xs) / 1.3, max(xs) * 1.3)
        ax.set_xticks([1, 2, 3, 5, 10, 20, 30])
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(0, 103)
        hand, n, normals = key
        paper = "Pisa/IIT SoftHand" if n == 5 else "real Allegro"
        ax.set_title(f"{hand}, {n} fingers, {'with' if normals else 'without'} normals\n(paper: {paper})",
                     fontsize=9)
        ax.set_xlabel("mean grasps to the stop")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success at the stop (%): decided and correct")
    methods = list(dict.fromkeys(r["method"] for r in rows))
    regimes = list(dict.fromkeys(r["training"] for r in rows))
    handles = [Line2D([], [], ls="none", marker=MARKERS[m], color="k", label=m) for m in methods]
    handles += [Line2D([], [], ls="none", marker="s", color=REGIME_COLORS.get(g, "C1"), label=f"ours, {g} training")
                for g in regimes]
    handles += [Line2D([], [], ls="none", marker="o", mfc="none", mec="k", label="paper"),
                Line2D([], [], ls=":", color="C3", label=f"lambda - 3 points ({100 * (threshold - 0.03):.0f} %)")]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 5), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.13, 1, 1))
    with atomic_write(path) as fh:
        fig.savefig(fh, format="png", dpi=110)


def run_query(updater, C, N, T, normals: bool, touch=None) -> tuple[int, int, bool]:
    """Feed one query's grasps ``C, N (G, n, 3)``, ``T (G, n)`` until decided -> (prediction, grasps, decided).

    ``touch (G, K)``: each grasp's weighted touch-pattern log-likelihood, added at every grasp in the grasp's one
    Bayes step (BC-NP and BC-IP, as the env's :meth:`haptic_env.belief.Belief.update`), or None."""
    updater.reset()
    for k in range(len(C)):
        evidence = None if touch is None else touch[k:k + 1]
        if T[k].sum() >= 3:
            updater.update_grasp(C[k], N[k] if normals else None, T[k], evidence=evidence)
        elif evidence is not None:
            updater.update_scores(evidence=evidence)
        if updater.decided:
            return updater.prediction, k + 1, True
    return updater.prediction, len(C), False


def training_config(regime: str, hand: str, args, calibrate_grasps: int = 1,
                    approaches: int = HAND_APPROACHES, bandwidth: str = "shared") -> RecognizerConfig:
    heights, axis = bool(getattr(args, "heights", False)), getattr(args, "normal_axis", "t2")
    if regime == "hand":
        g = DatasetConfig(source="hand", hand=hand, grasps_per_object=approaches, seed=0, hand_budget=args.hand_budget,
                          heights=heights, normal_axis=axis)
    else:
        g = DatasetConfig(source="surface", grasps_per_object=args.surface_grasps, contact_noise=args.surface_noise,
                          normal_noise_deg=args.surface_normal_noise, seed=0, heights=heights, normal_axis=axis)
    likelihood = getattr(args, "likelihood", "kde")
    if likelihood == "hgb":  # as the envs' recognizer_kwargs: the sequence temperature for the same K grasps
        return RecognizerConfig(grasps=g, likelihood="hgb", boosted=BoostedConfig(calibrate_grasps=calibrate_grasps))
    return RecognizerConfig(grasps=g, kde=KDEConfig(calibrate_grasps=calibrate_grasps, bandwidth=bandwidth))


def evaluate(rec, pools, objects, n: int, normals: bool, args, touch_weight: float = 0.0) -> dict[str, dict]:
    """label -> {success (S,), accuracy (S,), grasps (S,)} over seeds of the pools of ``objects``; ``touch_weight``:
    the :data:`TOUCH_ROWS`' weight of the touch pattern (``rec.touch``; 0: off, and no "BC-IP, touch" row). The
    queries' contacts are read as the recogniser's training grasps were (:func:`~haptic_env.dataset.support_frame`:
    from each object's table when its vectors carry heights)."""
    out = {}
    for label in args.methods:
        kind, z, k = METHODS[label]
        if label == "BC-IP, touch" and touch_weight == 0:  # the paper's BC-IP row
            print("no 'BC-IP, touch' row without a touch weight (surface training, or --touch-weight 0): "
                  "the BC-IP row is it")
            continue
        succ, acc, used = [], [], []
        for s, pool in zip(args.seeds, pools):  # the seed's value keys its subsets' stream, not its place in --seeds
            rng = np.random.default_rng([7, s])
            upd = rec.make_updater(kind, threshold=args.threshold, z=z, k=k, rng=rng, calibrated=not args.raw,
                                   ic_certainty=args.ic_certainty)
            w = touch_weight if label in TOUCH_ROWS else 0.0
            res = []
            for i in range(pool.touched.shape[0]):
                C = support_frame(pool.contacts[i], objects[i], rec.config.grasps).reshape(args.queries,
                                                                                            args.max_grasps, n, 3)
                N = pool.normals[i].reshape(args.queries, args.max_grasps, n, 3)
                T = pool.touched[i].reshape(args.queries, args.max_grasps, n)
                for q in range(args.queries):
                    touch = w * rec.touch.log_likelihood(T[q]) if w > 0 else None
                    p, g, d = run_query(upd, C[q], N[q], T[q], normals, touch)
                    res.append((p == i, g, d))
            r = np.array(res, dtype=float)
            succ.append(np.mean(r[:, 0] * r[:, 2]))
            acc.append(np.mean(r[:, 0]))
            used.append(np.mean(r[:, 1]))
        out[label] = {"success": np.array(succ), "accuracy": np.array(acc), "grasps": np.array(used)}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hands", nargs="+", default=list(SETUPS),
                    help=f"hands of {list(SETUPS)}; NAME=MODEL grasps with another model of that hand, e.g. "
                         "shadow=shadow_hand/right_hand (the automatic path of the Menagerie file)")
    ap.add_argument("--regimes", nargs="+", default=["surface", "hand"], choices=["surface", "hand"])
    ap.add_argument("--queries", type=int_in(1), default=10, help="queries per object and seed (paper: 10)")
    ap.add_argument("--seeds", type=int_in(0), nargs="+", default=[0, 1, 2], help="test seeds (spread: std over them)")
    ap.add_argument("--split", choices=["test", "validation"], default="test",
                    help="query pools: test (seeds 1000 + s, for reporting) or validation (500 + s, for tuning)")
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--max-grasps", type=int_in(1), default=DEFAULT_MAX_GRASPS, help="grasps per query at most")
    ap.add_argument("--threshold", type=float_in(0.0, 1.0, lo_open=True, hi_open=True), default=DEFAULT_THRESHOLD,
                    help="certainty threshold lambda")
    ap.add_argument("--approaches", type=int_in(1), default=None,
                    help="hand regime: training approaches per object (default: the hand's registered env's "
                         f"setting, HapticRecogConfig.training_grasps, else {HAND_APPROACHES})")
    ap.add_argument("--surface-grasps", type=int_in(1), default=20_000,
                    help="surface regime: training grasps per object")
    ap.add_argument("--surface-noise", type=float_in(0.0), default=0.0, help="surface regime: contact noise std (m)")
    ap.add_argument("--surface-normal-noise", type=float_in(0.0), default=0.0,
                    help="surface regime: normal noise (deg)")
    ap.add_argument("--calibrate-grasps", type=int_in(1), default=None,
                    help="fit the KDE temperature for beliefs of 1..K grasps of one object (1: one-shot; default: "
                         "the hand's registered env's setting, HapticRecogConfig.calibrate_grasps)")
    ap.add_argument("--hand-budget", choices=BUDGETS, default="uniform",
                    help="hand regime: approaches per object, uniform or balanced (DatasetConfig.hand_budget)")
    ap.add_argument("--kde-bandwidth", choices=BANDWIDTHS, default="shared",
                    help="KDE bandwidths (KDEConfig.bandwidth; the envs use shared) (default shared)")
    ap.add_argument("--touch-weight", type=float, default=None,
                    help="hand regime, BC-NP and 'BC-IP, touch' rows: weight of the touch-pattern log-likelihood "
                         "(HapticRecogConfig.touch_weight; default: the hand's registered env's setting; 0: off)")
    ap.add_argument("--raw", action="store_true", help="the paper's raw scores (no calibration temperatures)")
    ap.add_argument("--ic-certainty", choices=IC_CERTAINTIES, default=DEFAULT_IC_CERTAINTY,
                    help="the IC rows' certainty: count (ours, default) or share (the authors' code)")
    ap.add_argument("--heights", action="store_true",
                    help="append the contacts' heights above the table to the grasp vectors (DatasetConfig.heights, "
                         "the envs' grasp_heights)")
    ap.add_argument("--normal-axis", choices=NORMAL_AXES, default="t2",
                    help="each normal's angles in the grasp vectors (DatasetConfig.normal_axis, the envs' normal_axis): "
                         "t2 (the paper's), ab, or frame (three per normal)")
    ap.add_argument("--likelihood", choices=LIKELIHOODS, default="kde",
                    help="BC's likelihood: kde (the paper's, default) or hgb (gradient boosting, opt-in; "
                         "HapticRecogConfig.likelihood)")
    ap.add_argument("--out", type=output_path("folder"), default=None,
                    help="write hand_table.md and its plot, hand_table.png, here")
    ap.add_argument("--plot", type=Path, default=None, metavar="FILE",
                    help="run no experiment: draw the table in FILE (a hand_table.md this script wrote) as FILE's "
                         "name with .png, beside it")
    args = ap.parse_args(argv)
    if args.plot is not None:
        if args.out is not None:
            ap.error(f"--plot draws the table in {args.plot}; --out runs the experiment: give one of them")
        try:
            rows, threshold = read_table(args.plot.read_text())
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            ap.error(f"--plot {args.plot}: {exc}")
        plot_hand_table(rows, args.plot.with_suffix(".png"), threshold)
        print(f"wrote {args.plot.with_suffix('.png')} ({len(rows)} rows)")
        return 0
    if args.likelihood == "hgb" and args.kde_bandwidth != "shared":
        ap.error(f"--kde-bandwidth {args.kde_bandwidth} sets the KDE, which --likelihood hgb replaces")
    if args.touch_weight is not None and not (np.isfinite(args.touch_weight) and args.touch_weight >= 0):
        ap.error(f"--touch-weight must be a finite number >= 0, got {args.touch_weight}")
    check_pool_seeds(ap, args.split, args.seeds)
    for flag, values in (("--hands", args.hands), ("--regimes", args.regimes), ("--methods", args.methods)):
        distinct(ap, flag, values)  # a hand twice wrote its rows twice; a method twice was merged without a word
    for spec in args.hands:  # every name checked before the first hand's pools are built
        if spec.partition("=")[0] not in SETUPS:
            ap.error(f"--hands: unknown hand {spec.partition('=')[0]!r}; choose from {list(SETUPS)}")
    if data_dir() is None:
        print("the hand experiment needs the YCB meshes (ycb/ in the shared data folder; set HAPTIC_DATA)")
        return 1
    objects = load_object_set("ycb10")
    rows, t_start = [], time.perf_counter()
    for spec in args.hands:
        name, _, hand = spec.partition("=")
        hand = hand or name
        n, normal_settings = SETUPS[name]
        got = query_pools(objects, hand, n, args.split, args.seeds, args.queries, args.max_grasps)
        if got is None:
            continue
        pools, usable = got
        env = env_config(name, args.heights)  # the defaults: the hand's env's
        K = args.calibrate_grasps if args.calibrate_grasps is not None else env.calibrate_grasps
        A = args.approaches if args.approaches is not None else (env.training_grasps or HAND_APPROACHES)
        for regime in args.regimes:
            cfg = training_config(regime, hand, args, K, A, args.kde_bandwidth)
            data = cfg.grasps.grasps_per_object
            # the touch pattern needs the hand's own grasps (the hand regime); TOUCH_ROWS only
            w = (args.touch_weight if args.touch_weight is not None else env.touch_weight) \
                if regime == "hand" else 0.0
            for normals in normal_settings:
                rec = build_recognizer(objects, n, normals, z_values=tuple(range(3, n)), config=cfg, touch=w > 0)
                temps = rec.models.temperature(n)
                res = evaluate(rec, pools, objects, n, normals, args, w)
                for label, r in tqdm(res.items(), desc=f"{hand} {regime}", disable=True):
                    rows.append((hand, n, normals, regime, label, r, usable, temps, K, data,
                                 w if label in TOUCH_ROWS else 0.0))
    cols = {(4, True): "4+", (4, False): "4-", (5, False): "5-"}
    lik = "gradient boosting's" if args.likelihood == "hgb" else "the KDE's"
    calib = "raw scores" if args.raw else (f"calibrated scores (temperatures fitted on validation grasps; {lik} "
                                           "for beliefs of 1-K grasps of one object, K in the last column)")
    lines = [
        f"YCB-10, {args.queries} queries per object x {len(args.seeds)} {args.split} seeds ({args.seeds}), <= {args.max_grasps} "
        f"random-approach grasps per query, lambda = {args.threshold}, "
        f"{calib}{'; BC likelihood: gradient boosting (--likelihood hgb)' if args.likelihood == 'hgb' else ''}"
        f"{'; grasp vectors with the contacts heights above the table (--heights)' if args.heights else ''}"
        f"{'' if args.normal_axis == 't2' else f'; Phi_n with normal_axis={args.normal_axis!r}: ' + NORMAL_AXIS_WORDS[args.normal_axis]}. "
        "Success = decided and correct at the stop; accuracy = final prediction correct (decided or not). "
        f"Mean +- sample std (ddof = 1) over the {args.split} seeds. Paper: Pisa/IIT SoftHand for the 5-finger rows, "
        "real Allegro for the 4-finger rows.",
        "",
        f"{TABLE_HEADER} usable grasps | T ({args.likelihood.upper()} / MLP) | K | training grasps / object | "
        "touch w |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for hand, n, normals, regime, label, r, usable, temps, K, data, w in rows:
        paper = PAPER[label].get(cols[(n, normals)])
        lines.append(
            f"| {hand} | {n} | {'yes' if normals else 'no'} | {regime} | {label} | "
            f"{pm(r['success'], 100)} | {pm(r['accuracy'], 100)} | "
            f"{pm(r['grasps'], digits=2)} | {paper[0]} / {paper[1]} | {usable:.2f} | "
            f"{temps['kde']:.2f} / {temps['classifier']:.2f} | {K} | {data:,} | {w:g} |")
    text = "\n".join(lines)
    print("\n" + text)
    if args.out is not None:
        write_table(args.out, "hand_table.md", "hand_experiment.py", argv, time.perf_counter() - t_start, text)
        if rows:
            plot_hand_table(read_table(text)[0], args.out / "hand_table.png", args.threshold)
    if rows:  # a cell fixed in advance: the first BC-NP row (the first hand and regime asked for), not the best one
        head = next((r for r in rows if r[4] == "BC-NP"), rows[0])
        s, g = head[5]["success"], head[5]["grasps"]
        print(f"HEADLINE: {head[4]} success at the stop {pm(s, 100)} % in "
              f"{pm(g, digits=2)} grasps ({head[0]}, {head[3]} training, "
              f"{'with' if head[2] else 'without'} normals; mean +- sample std over {len(s)} seeds)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
