"""Paper-scale one-shot run (issue 10, item 3): MLP one-shot accuracy against training grasps per object and
network size, on kit8 surface grasps as in Sintov & Ben-David, with the wall time of every cell.

A *cell* is one ``(n, normals, grasps per object, model)``; ``model`` is ``mlp-<net>`` (``--nets``: ``default``
3 x 256, ``paper`` 7 x 500) or ``knn`` (the paper's nearest-neighbour row, a cheap check of the data itself:
no training, so what it gains with data is what the data offer). Every cell trains on ``grasps`` valid surface
grasps per object (``--val-fraction`` 15 % of them held out: the MLP's early stopping and calibration) and is
scored on ``--test-grasps`` fresh grasps per object from another seed (never training data). With ``--exp2``
(cells with at most ``--exp2-max-grasps``), the MLP cells also run experiment 2 on those test grasps: IC,
BC-NP and BC-IP at lambda = 0.85, ``--trials-per-object`` x K trials, calibrated scores.

Resumable: each finished cell is written atomically to ``<out>/cells/<cell>-<settings hash>.json``; a re-run
skips the cells whose file exists (``--force`` reruns them). Ctrl-C (or SIGTERM) stops after writing the
finished cells and the report. The report (``results.md``, ``accuracy_vs_grasps.png``, ``results.json``) is
rewritten after every cell from all cell files of the current settings; ``<out>/notes.md``, if present, is
appended to ``results.md`` (hand-written conclusions survive regeneration).

The full paper-scale grid (a bigger machine: 8 x 200,000 grasps, 7 x 500 at ~130 us per training row on one
CPU thread is ~3 min per epoch)::

    python benchmarks/paper_scale.py --out docs/results/paper_scale --fingers 3,4,5 --normals yes,no \\
        --grasps 5000,20000,50000,200000 --nets default,paper --test-grasps 1000 --exp2 --exp2-max-grasps 200000

Reduced grid on a small machine: the same flags, a shorter ``--grasps`` list and ``--time-budget`` (no new
cell starts after it); run the most important cells first (cells run in the order of the flags: fingers,
normals, grasps, nets) and re-run with more cells later.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import signal
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from haptic_env import cli
from haptic_env.cache import atomic_write
from haptic_env.experiments.paper import PAPER_KNN, PAPER_NN
from haptic_env.grasp_features import NORMAL_AXES, NORMAL_AXIS_WORDS
from haptic_env.recognizers.updaters import DEFAULT_MAX_GRASPS, DEFAULT_THRESHOLD
from haptic_env.splits import TEST_SEED_OFFSET

#: Network sizes: hidden layers x units.
NETS = {"default": (3, 256), "paper": (7, 500)}
#: Cell files of another format are ignored.
CELL_VERSION = 1


def _bools(text: str) -> list[bool]:
    out = []
    for w in text.split(","):
        w = w.strip().lower()
        if w in ("yes", "y", "true", "w", "1"):
            out.append(True)
        elif w in ("no", "n", "false", "wo", "0"):
            out.append(False)
        elif w:
            raise argparse.ArgumentTypeError(f"--normals: expected yes/no values, got {w!r}")
    return out


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="\n".join(__doc__.splitlines()[1:]))
    p.add_argument("--out", required=True, help="output folder (cells/, results.md, results.json, PNG)")
    p.add_argument("--objects", default="kit8", help="object set (default kit8: the paper's 8 KIT meshes)")
    p.add_argument("--data-dir", default=None, help="shared data folder (default: $HAPTIC_DATA)")
    p.add_argument("--fingers", type=cli.int_list, default=(3, 4, 5), help="finger counts n (comma list)")
    p.add_argument("--normals", type=_bools, default=[True, False], help="yes,no: with and/or without normals")
    p.add_argument("--grasps", type=cli.int_list, default=(5000, 20000, 50000, 200000),
                   help="training grasps per object (train + validation; paper: 200000)")
    p.add_argument("--nets", default="default,paper", help=f"MLP sizes among {sorted(NETS)} (comma list; empty: none)")
    p.add_argument("--no-knn", action="store_true", help="skip the nearest-neighbour cells")
    p.add_argument("--knn-k", type=cli.int_in(1), default=15, help="neighbours of the kNN cells (distance-weighted)")
    p.add_argument("--test-grasps", type=cli.int_in(1), default=1000, help="fresh test grasps per object (paper: 1000 trials)")
    p.add_argument("--val-fraction", type=cli.float_in(0.0, 1.0, hi_open=True), default=0.15, help="validation share of each object's grasps (paper: 0.15)")
    p.add_argument("--max-epochs", type=cli.int_in(1), default=40)
    p.add_argument("--patience", type=cli.int_in(1), default=4, help="epochs without validation-loss improvement before stopping")
    p.add_argument("--lr", type=cli.float_in(0.0, lo_open=True), default=3e-3)
    p.add_argument("--lr-decay", type=cli.float_in(0.0, 1.0, lo_open=True), default=0.93, help="learning-rate factor per epoch")
    p.add_argument("--batch-size", type=cli.int_in(1), default=1024)
    p.add_argument("--weight-decay", type=cli.float_in(0.0), default=0.0, help="weight decay of the MLP's optimiser (default 0: none)")
    p.add_argument("--decoupled-weight-decay", action="store_true",
                   help="decay the weights apart from the gradient (AdamW) instead of Adam's L2 penalty")
    p.add_argument("--force-closure", type=cli.float_in(0.0, lo_open=True), default=None, metavar="MU",
                   help="train and test on force-closure surface grasps only, at this friction coefficient (not the "
                        "paper's stated protocol; DatasetConfig.force_closure)")
    p.add_argument("--exp2", action="store_true", help="also run experiment 2 (IC, BC-NP, BC-IP) in the MLP cells")
    p.add_argument("--exp2-max-grasps", type=int, default=20000, help="experiment 2 only up to this many grasps/object")
    p.add_argument("--trials-per-object", type=int, default=1000, help="experiment 2 trials per object (paper: 1000)")
    p.add_argument("--threshold", type=float, default=DEFAULT_THRESHOLD)
    p.add_argument("--threads", type=cli.int_in(1), default=1, help="torch intra-op threads")
    p.add_argument("--normal-axis", choices=NORMAL_AXES, default="t2",
                   help="each normal's second angle in Phi_n (n >= 4): to t2's normal (the paper's) or to the edge ab; "
                        "frame: three angles per normal, to the axes of t1's frame")
    p.add_argument("--seed", type=cli.int_in(0), default=0)
    p.add_argument("--time-budget", type=cli.float_in(0.0, lo_open=True), default=None,
                   help="seconds: start no new cell after this")
    p.add_argument("--force", action="store_true", help="rerun cells that are already done")
    p.add_argument("--report-only", action="store_true", help="only rewrite the report from the cell files")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    args = p.parse_args(argv)
    args.nets = [x for x in args.nets.split(",") if x.strip()]
    bad = [x for x in args.nets if x not in NETS]
    if bad:
        p.error(f"--nets: unknown {bad}; choose from {sorted(NETS)}")
    if min(args.fingers, default=3) < 3:
        p.error("--fingers: n >= 3")
    if min(args.grasps, default=1) < 2:  # each cell splits its grasps into training and validation
        p.error(f"--grasps: counts >= 2 per object, got {args.grasps}")
    if args.trials_per_object < 1:
        p.error(f"--trials-per-object: must be >= 1, got {args.trials_per_object}")
    if not 0.0 < args.threshold <= 1.0:
        p.error(f"--threshold: must be in (0, 1], got {args.threshold}")
    from haptic_env.objects.loaders import check_object_spec

    try:
        check_object_spec(args.objects)
    except ValueError as exc:
        p.error(f"--objects: {exc}")
    return args


def settings(args) -> dict:
    """What a cell's result depends on beyond its own coordinates (hashed into its file name)."""
    return {"version": CELL_VERSION, "objects": args.objects, "test_grasps": args.test_grasps,
            "val_fraction": args.val_fraction, "max_epochs": args.max_epochs, "patience": args.patience, "lr": args.lr,
            "lr_decay": args.lr_decay, "batch_size": args.batch_size, "knn_k": args.knn_k, "seed": args.seed,
            "trials_per_object": args.trials_per_object, "threshold": args.threshold,  # --exp2: whether to run, not how
            **({} if args.normal_axis == "t2" else {"normal_axis": args.normal_axis}),  # the defaults keep older hashes
            **({} if not args.weight_decay else {"weight_decay": args.weight_decay}),
            **({} if not args.decoupled_weight_decay else {"decoupled_weight_decay": True}),
            **({} if args.force_closure is None else {"force_closure": args.force_closure})}


def grasp_fields(args) -> dict:
    """The :class:`~haptic_env.dataset.DatasetConfig` fields that the flags set for every grasp of the run: training,
    test and the experiment-2 KDE's alike."""
    return {"normal_axis": args.normal_axis, "force_closure": args.force_closure}


def settings_hash(args) -> str:
    return hashlib.sha256(json.dumps(settings(args), sort_keys=True).encode()).hexdigest()[:10]


def cell_list(args) -> list[tuple[int, bool, int, str]]:
    models = [f"mlp-{n}" for n in args.nets] + ([] if args.no_knn else ["knn"])
    return [(n, nm, g, m) for n in args.fingers for nm in args.normals for g in args.grasps for m in models]


def cell_name(cell) -> str:
    n, normals, g, model = cell
    return f"n{n}-{'w' if normals else 'wo'}-g{g}-{model}"


def cell_path(out: Path, cell, h: str) -> Path:
    return out / "cells" / f"{cell_name(cell)}-{h}.json"


def fit_state_path(out: Path, cell, h: str) -> Path:
    """Where an MLP cell's unfinished fit keeps its epoch state (hidden; removed when the fit ends)."""
    return out / "cells" / f".{cell_name(cell)}-{h}.fit.pt"


def lacks_exp2(cell, out: Path, h: str, args) -> bool:
    """Whether a finished cell lacks the experiment-2 results that ``--exp2`` asks of it (a run without ``--exp2``
    finished it; ``--exp2`` is not part of the settings hash). Its model is not kept, so it is trained again."""
    _, _, g, model = cell
    path = cell_path(out, cell, h)
    if not (args.exp2 and model.startswith("mlp-") and g <= args.exp2_max_grasps and path.exists()):
        return False
    return "exp2" not in json.loads(path.read_text())


def write_json_atomic(path: Path, obj) -> None:
    with atomic_write(path, "w") as fh:
        json.dump(obj, fh, indent=1, sort_keys=True)


# ------------------------------------------------------------------------------------------------ running
class _Data:
    """Datasets and test pools of the run, the last one of each kept in memory (they are also cached on disk
    under ``$HAPTIC_CACHE``)."""

    def __init__(self, objects, args):
        self.objects, self.args = objects, args
        self._train, self._test = {}, {}

    def train(self, n, normals, g):
        from haptic_env.dataset import DatasetConfig, build_dataset

        key = (n, normals, g)
        if key not in self._train:
            self._train.clear()
            dc = DatasetConfig(n_fingers=n, normals=normals, grasps_per_object=g, val_fraction=self.args.val_fraction,
                               seed=self.args.seed, **grasp_fields(self.args))
            t0 = time.perf_counter()
            ds = build_dataset(self.objects, dc, progress=False)
            self._train[key] = (ds, time.perf_counter() - t0)
        return self._train[key]

    def test(self, n, normals):
        from haptic_env.dataset import DatasetConfig, build_dataset

        key = (n, normals)
        if key not in self._test:
            self._test.clear()
            dc = DatasetConfig(n_fingers=n, normals=normals, grasps_per_object=self.args.test_grasps, val_fraction=0.0,
                               seed=self.args.seed + TEST_SEED_OFFSET, **grasp_fields(self.args))
            ds = build_dataset(self.objects, dc, progress=False)
            self._test[key] = (ds.X_train.astype(np.float64), ds.y_train)
        return self._test[key]


def run_cell(cell, data: _Data, args, checkpoint: Path | None = None) -> dict:
    n, normals, g, model = cell
    t_all = time.perf_counter()
    ds, t_data = data.train(n, normals, g)
    Xt, yt = data.test(n, normals)
    K = len(ds.names)
    res = {"cell": cell_name(cell), "n": n, "normals": normals, "grasps_per_object": g, "model": model,
           "train_rows": int(len(ds.X_train)), "val_rows": int(len(ds.X_val)), "test_rows": int(len(Xt)),
           "dataset_seconds": t_data, "dataset_from_cache": bool(ds.from_cache), "settings": settings(args),
           "threads": args.threads, "host": platform.node(), "cpus": os.cpu_count()}
    if model == "knn":
        from haptic_env.recognizers.baselines import make_classifier

        t0 = time.perf_counter()
        clf = make_classifier("knn", max_train=None, n_neighbors=args.knn_k).fit(ds.X_train, ds.y_train, n_classes=K)
        res["train_seconds"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        pred = clf.predict(Xt)
        res["eval_seconds"] = time.perf_counter() - t0
        t0 = time.perf_counter()  # the whole validation split, 30x the test rows at 200k: most of a kNN cell's time
        res["val_accuracy"] = float(np.mean(clf.predict(ds.X_val) == ds.y_val))
        res["val_eval_seconds"] = time.perf_counter() - t0
    else:
        from haptic_env.recognizers.mlp import MLPClassifier, MLPConfig

        depth, width = NETS[model.removeprefix("mlp-")]
        cfg = MLPConfig(depth=depth, width=width, lr=args.lr, lr_decay=args.lr_decay, batch_size=args.batch_size,
                        max_epochs=args.max_epochs, patience=args.patience, max_train=None, seed=args.seed,
                        weight_decay=args.weight_decay, decoupled_weight_decay=args.decoupled_weight_decay,
                        threads=args.threads, progress=not args.quiet)
        t0 = time.perf_counter()
        # an interrupted fit resumes from its last epoch (a 7 x 500 cell at 200k grasps trains for hours)
        # the fit's state stays until main() has written the cell (an interrupt during exp2 keeps the fit)
        clf = MLPClassifier(cfg).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=K, checkpoint=checkpoint,
                                     keep_checkpoint=True)
        res["train_seconds"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        pred = clf.predict(Xt)
        res["eval_seconds"] = time.perf_counter() - t0
        h = clf.history
        res.update(mlp={"depth": depth, "width": width, "params": int(sum(p.numel() for p in clf.net.parameters()))},
                   epochs=len(h["val_loss"]), best_epoch=int(np.argmin(h["val_loss"])) + 1,
                   val_accuracy=float(h["val_acc"][int(np.argmin(h["val_loss"]))]), history=h,
                   temperature=float(clf.temperature))
        if args.exp2 and g <= args.exp2_max_grasps:
            t0 = time.perf_counter()
            res["exp2"] = run_exp2(cell, clf, data, args)
            res["exp2_seconds"] = time.perf_counter() - t0
    res["accuracy"] = float(np.mean(pred == yt))
    res["accuracy_se"] = float(np.sqrt(res["accuracy"] * (1 - res["accuracy"]) / len(yt)))
    res["per_object"] = {name: float(np.mean(pred[yt == k] == k)) for k, name in enumerate(ds.names)}
    res["seconds"] = time.perf_counter() - t_all
    return res


def run_exp2(cell, clf, data: _Data, args) -> dict:
    """Experiment 2 at ``args.threshold`` on the cell's test grasps: IC (the MLP), BC-NP (the KDE) and BC-IP
    (both), calibrated scores, ``trials_per_object x K`` trials of at most 30 grasps."""
    from haptic_env.experiments.fresh_grasps import pool_scores
    from haptic_env.experiments.trials import simulate_trials, summarize
    from haptic_env.dataset import DatasetConfig
    from haptic_env.recognizers.kde import KDEConfig
    from haptic_env.recognizers.recognizer import ModelBank, RecognizerConfig, build_recognizer

    n, normals, g, _ = cell
    rc = RecognizerConfig(grasps=DatasetConfig(grasps_per_object=g, val_fraction=args.val_fraction, seed=args.seed,
                                               **grasp_fields(args)),
                          kde=KDEConfig(seed=args.seed))
    t0 = time.perf_counter()
    kde = build_recognizer(data.objects, n, normals, config=rc, models=("kde",), progress=False).models.model(n)[1]
    t_kde = time.perf_counter() - t0
    Xt, yt = data.test(n, normals)
    K = int(yt.max()) + 1
    bank = ModelBank(normals=normals, n_classes=K, normal_axis=args.normal_axis)
    bank.add(n, clf, kde)
    LL, PR = pool_scores(bank, [Xt[yt == k] for k in range(K)])
    out = {"kde_seconds": t_kde, "kde_oneshot": float(np.mean(np.concatenate([ll.argmax(1) == k for k, ll in enumerate(LL)]))),
           "temperatures": bank.temperature(n)}
    for i, kind in enumerate(("ic", "bc-np", "bc-ip")):
        rng = np.random.default_rng([args.seed, n, int(normals), g, i])
        r = simulate_trials(LL, PR, kind, trials=args.trials_per_object * K, max_grasps=DEFAULT_MAX_GRASPS,
                            threshold=args.threshold, rng=rng)
        sr, se, gm, gs = summarize(r)
        out[kind] = {"success": sr, "success_se": se, "grasps": gm, "grasps_std": gs,
                     "decided": float(np.mean(r["decided"])),
                     "decided_correct": float(np.mean(np.asarray(r["success"], bool) & np.asarray(r["decided"], bool)))}
    return out


# ------------------------------------------------------------------------------------------------ report
def load_cells(out: Path, h: str) -> list[dict]:
    cells = []
    for p in sorted((out / "cells").glob(f"*-{h}.json")):
        try:
            cells.append(json.loads(p.read_text()))
        except (OSError, ValueError) as exc:
            print(f"warning: skipping unreadable {p}: {exc}", file=sys.stderr)
    return cells


def _label(model: str) -> str:
    if model == "knn":
        return "kNN"
    d, w = NETS[model.removeprefix("mlp-")]
    return f"MLP {d}x{w}"


def _threads(cells: list[dict], args) -> str:
    """The torch threads the cells trained with (each cell file records its own), e.g. "1 torch thread (2: 1 cell)"."""
    (main, _), *rest = Counter(c.get("threads", args.threads) for c in cells).most_common() or [(args.threads, 0)]
    plural = lambda k, word: f"{k} {word}{'s' if k != 1 else ''}"  # noqa: E731
    return plural(main, "torch thread") + (f" ({', '.join(f'{t}: ' + plural(k, 'cell') for t, k in rest)})" if rest else "")


def _optimizer(args) -> str:
    """The MLP's optimiser in words, e.g. "AdamW (weight decay 0.2)"."""
    name = "AdamW" if args.decoupled_weight_decay else "Adam"
    return f"{name} (weight decay {args.weight_decay:g})" if args.weight_decay else name


def exp2_table(cells: list[dict], threshold: float, trials_per_object: int) -> list[str]:
    """The report's experiment-2 section (no lines without experiment-2 cells). Its success is the prediction right
    at the stop, decided or not (experiment 2's measure, ``trials.summarize``); each cell gives its decided share
    beside it, and the decided-and-correct share where the cell stored it (cells since 2026-12-07): IC, which seldom
    decides, was right at the 30th grasp in most trials, which read as IC beating BC-NP."""
    e2 = [c for c in cells if "exp2" in c]
    if not e2:
        return []
    L = ["", f"## Experiment 2 at lambda = {threshold} (calibrated scores, {trials_per_object} trials per object, at "
         "most 30 grasps): right at the stop, decided or not, % (± its binomial standard error where stored; in "
         "brackets the share of trials that decided, and decided and correct where stored) / mean grasps", "",
         "| n | normals | model | grasps/obj | KDE one-shot % | IC | BC-NP | BC-IP |", "|---" * 8 + "|"]
    for c in e2:
        x = c["exp2"]

        def f(k):
            se = f" ± {x[k]['success_se']:.1f}" if "success_se" in x[k] else ""  # older results.json: none
            dc = f", d&c {100 * x[k]['decided_correct']:.1f}" if "decided_correct" in x[k] else ""
            return f"{x[k]['success']:.1f}{se} (decided {100 * x[k]['decided']:.1f}{dc}) / {x[k]['grasps']:.2f}"

        L.append(f"| {c['n']} | {'yes' if c['normals'] else 'no'} | {_label(c['model'])} | "
                 f"{c['grasps_per_object']:,} | {100 * x['kde_oneshot']:.1f} | {f('ic')} | {f('bc-np')} | "
                 f"{f('bc-ip')} |")
    return L


def write_report(out: Path, args, command: str) -> Path:
    h = settings_hash(args)
    cells = load_cells(out, h)
    out.mkdir(parents=True, exist_ok=True)
    key = lambda c: (c["n"], not c["normals"], c["model"], c["grasps_per_object"])  # noqa: E731
    cells.sort(key=key)
    log = out / "commands.txt"
    runs = [x for x in (log.read_text().splitlines() if log.exists() else []) if x.strip()] or [command]
    L = ["# Paper-scale one-shot run: accuracy vs training grasps per object and network size", "",
         "The commands that ran the cells (in order; each resumes the same cell folder):", "",
         "```", *runs, "```", "",
         f"Objects `{args.objects}`; surface grasps; {args.test_grasps} fresh test grasps per object (seed "
         f"{args.seed + TEST_SEED_OFFSET}); {100 * args.val_fraction:.0f} % of each object's grasps held out for "
         f"validation (MLP early stopping, patience {args.patience}, at most {args.max_epochs} epochs, {_optimizer(args)} lr {args.lr} "
         f"x {args.lr_decay}/epoch, batch {args.batch_size}, all training rows); {_threads(cells, args)}; "
         f"settings hash `{h}`. Paper: the NN / kNN rows of its kit8 one-shot table.",
         *([] if args.normal_axis == "t2" else ["", f"**Phi_n with `normal_axis=\"{args.normal_axis}\"`** (not the paper's): "
                                                    f"{NORMAL_AXIS_WORDS[args.normal_axis]}."]),
         *([] if args.force_closure is None else ["", f"**Force-closure grasps only** (not the paper's stated protocol): "
                                                      f"training, validation and test grasps are the random surface grasps "
                                                      f"in force closure at friction {args.force_closure:g} "
                                                      "(`DatasetConfig.force_closure`)."]), ""]
    series: dict[tuple, list[dict]] = {}
    for c in cells:
        series.setdefault((c["n"], c["normals"], c["model"]), []).append(c)
    grasps = sorted({c["grasps_per_object"] for c in cells})
    L += ["## Accuracy (%) on fresh test grasps", "",
          "| n | normals | model | " + " | ".join(f"{g:,}/obj" for g in grasps) + " | paper NN | paper kNN | gain last step (points) |",
          "|---" * (6 + len(grasps)) + "|"]
    for (n, nm, model), cs in series.items():
        by = {c["grasps_per_object"]: c for c in cs}
        vals = [f"{100 * by[g]['accuracy']:.1f}" if g in by else "" for g in grasps]
        gain = f"{100 * (cs[-1]['accuracy'] - cs[-2]['accuracy']):+.1f} ({cs[-2]['grasps_per_object']:,} -> " \
               f"{cs[-1]['grasps_per_object']:,})" if len(cs) > 1 else ""
        L.append(f"| {n} | {'yes' if nm else 'no'} | {_label(model)} | " + " | ".join(vals) +
                 f" | {PAPER_NN.get((n, nm), '')} | {PAPER_KNN.get((n, nm), '')} | {gain} |")
    se = max((c["accuracy_se"] for c in cells), default=0.0)
    L += ["", f"Binomial standard error of one cell: at most {100 * se:.1f} points.", "",
          "## Every cell", "",
          "| n | normals | model | grasps/obj | train rows | accuracy % | val acc % | epochs (best) | train s | "
          "dataset s | total s |", "|---" * 11 + "|"]
    for c in cells:
        ep = f"{c['epochs']} ({c['best_epoch']})" if "epochs" in c else ""
        L.append(f"| {c['n']} | {'yes' if c['normals'] else 'no'} | {_label(c['model'])} | {c['grasps_per_object']:,} | "
                 f"{c['train_rows']:,} | {100 * c['accuracy']:.1f} ± {100 * c['accuracy_se']:.1f} | "
                 f"{100 * c['val_accuracy']:.1f} | {ep} | {c['train_seconds']:.0f} | {c['dataset_seconds']:.0f}"
                 f"{' (cached)' if c['dataset_from_cache'] else ''} | {c['seconds']:.0f} |")
    L += exp2_table(cells, args.threshold, args.trials_per_object)
    L += ["", "Plot: `accuracy_vs_grasps.png`; every cell's numbers (training history, per-object accuracy): "
          "`results.json` and `cells/`.", ""]
    notes = out / "notes.md"
    if notes.exists():
        L += ["", notes.read_text().rstrip(), ""]
    with atomic_write(out / "results.md", "w") as fh:
        fh.write("\n".join(L))
    write_json_atomic(out / "results.json", {"command": command, "settings": settings(args), "settings_hash": h,
                                             "paper_nn": {f"n{k[0]}-{'w' if k[1] else 'wo'}": v for k, v in PAPER_NN.items()},
                                             "cells": cells})
    if cells:
        plot(series, out / "accuracy_vs_grasps.png")
    return out / "results.md"


def plot(series: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = sorted({(n, nm) for n, nm, _ in series}, key=lambda p: (not p[1], p[0]))
    cols = min(3, len(panels))
    rows = (len(panels) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.6 * rows), squeeze=False)
    colors = {"mlp-default": "C0", "mlp-paper": "C1", "knn": "C2"}
    xs = [c["grasps_per_object"] for cs in series.values() for c in cs]
    for ax, (n, nm) in zip(axes.flat, panels):
        for (n2, nm2, model), cs in series.items():
            if (n2, nm2) != (n, nm):
                continue
            x = [c["grasps_per_object"] for c in cs]
            y = [100 * c["accuracy"] for c in cs]
            e = [100 * c["accuracy_se"] for c in cs]
            ax.errorbar(x, y, yerr=e, marker="o", ms=4, capsize=2, color=colors.get(model), label=_label(model))
        if (n, nm) in PAPER_NN:
            ax.axhline(PAPER_NN[(n, nm)], ls="--", color="C3", label="paper NN (200k/obj)")
            ax.axhline(PAPER_KNN[(n, nm)], ls=":", color="C2", label="paper kNN (200k/obj)")
        ax.set_xscale("log")
        ax.set_xlim(min(xs) / 1.5, max(xs) * 1.5)  # the same grasps axis in every panel
        ax.set_title(f"n = {n}, {'with' if nm else 'without'} normals")
        ax.set_xlabel("training grasps per object")
        ax.set_ylabel("one-shot accuracy (%)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.tight_layout()
    with atomic_write(path) as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)


# -------------------------------------------------------------------------------------------------- main
def main(argv=None) -> int:
    args = parse_args(argv)
    command = cli.script_command("paper_scale.py", argv)
    out = Path(args.out)
    if args.report_only:
        print(write_report(out, args, command))
        return 0
    import torch
    from tqdm.auto import tqdm

    from haptic_env.objects import load_object_set

    torch.set_num_threads(args.threads)
    h = settings_hash(args)
    cells = cell_list(args)
    todo = [c for c in cells if args.force or not cell_path(out, c, h).exists() or lacks_exp2(c, out, h, args)]
    print(f"{len(cells)} cells, {len(cells) - len(todo)} done, {len(todo)} to run (settings {h})", flush=True)
    if not args.force and (again := sum(cell_path(out, c, h).exists() for c in todo)):
        print(f"{again} finished MLP cells lack the --exp2 results asked for: trained again with them", flush=True)
    objects = load_object_set(args.objects, data_dir=args.data_dir)  # missing data: an error before any file
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "commands.txt", "a") as fh:
        fh.write(command + "\n")
    data = _Data(objects, args)
    t_start = time.perf_counter()
    prev = signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    status = 0
    try:
        bar = tqdm(todo, desc="cells", disable=args.quiet)
        for cell in bar:
            if args.time_budget is not None and time.perf_counter() - t_start > args.time_budget:
                print(f"time budget of {args.time_budget:.0f} s spent: stopping before {cell_name(cell)}", flush=True)
                break
            bar.set_postfix_str(cell_name(cell))
            res = run_cell(cell, data, args, checkpoint=fit_state_path(out, cell, h))
            write_json_atomic(cell_path(out, cell, h), res)
            fit_state_path(out, cell, h).unlink(missing_ok=True)  # the cell is saved: its fit state is not needed
            tqdm.write(f"{cell_name(cell)}: {100 * res['accuracy']:.1f} % ({res['seconds']:.0f} s)")
            write_report(out, args, command)
    except KeyboardInterrupt:
        print("interrupted: finished cells are saved; re-run the same command to resume", file=sys.stderr)
        status = 130
    finally:
        signal.signal(signal.SIGTERM, prev)
    print(write_report(out, args, command))
    return status


if __name__ == "__main__":
    sys.exit(main())
