"""The analysis' PNG plots.

Drawn on :class:`matplotlib.figure.Figure` objects and saved directly, without pyplot: no GUI backend is
chosen or switched, and no figure outlives its function.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from haptic_env.recognizers.calibration import expected_calibration_error, reliability

__all__ = ["plot_confusion", "plot_sequential_vs_fingers", "plot_success_vs_grasps", "plot_reliability",
           "plot_lambda_sweep", "plot_family_votes"]

DPI = 110


def _save(fig: Figure, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)


def plot_confusion(C: np.ndarray, names, title: str, path: Path) -> None:
    """A row-normalised confusion matrix ``C (K, K)``."""
    fig = Figure(figsize=(5.5, 5))
    ax = fig.subplots()
    ax.imshow(C, vmin=0, vmax=1, cmap="Blues")
    ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(names)), names, fontsize=7)
    for i in range(len(names)):
        for j in range(len(names)):
            if C[i, j] > 0.005:
                ax.text(j, i, f"{C[i, j]:.2f}", ha="center", va="center", fontsize=6, color="w" if C[i, j] > 0.5 else "k")
    ax.set(xlabel="predicted", ylabel="true", title=title)
    _save(fig, path)


def plot_sequential_vs_fingers(curves: dict, path: Path, paper: dict | None = None) -> None:
    """Experiment 2: ``curves[kind] = [(n, success %, mean grasps), ...]``; ``paper[kind] = [(n, mean grasps), ...]``,
    the paper's grasps, drawn hollow in the kind's colour (its success rates are plots only)."""
    fig = Figure(figsize=(10, 4))
    ax = fig.subplots(1, 2)
    for kind, pts in curves.items():
        pts = np.array(pts)
        line, = ax[0].plot(pts[:, 0], pts[:, 1], "o-", label=kind)
        ax[1].plot(pts[:, 0], pts[:, 2], "o-", color=line.get_color(), label=kind)
        if paper and paper.get(kind):
            theirs = np.array(paper[kind])
            ax[1].plot(theirs[:, 0], theirs[:, 1], "s", mfc="none", mec=line.get_color(), ms=9,
                       label=f"{kind}, paper (kit8)")
    if paper:
        ax[1].legend(fontsize=8)
    ax[0].set(xlabel="fingers n", ylabel="success %", title="success at lambda")
    ax[1].set(xlabel="fingers n", ylabel="grasps", title="mean grasps to decide")
    ax[0].legend()
    _save(fig, path)


def plot_success_vs_grasps(curves: dict, path: Path) -> None:
    """Experiment 6: ``curves[kind] = (M,)`` success % after 1..M grasps."""
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    for kind, c in curves.items():
        ax.plot(np.arange(1, len(c) + 1), c, "o-", label=kind)
    ax.set(xlabel="grasps", ylabel="success %", title="success vs grasps (n = 4)", ylim=(0, 100))
    ax.legend()
    _save(fig, path)


def plot_reliability(curves: dict, bins: int, title: str, path: Path) -> None:
    """Experiment 7: ``curves[model][variant] = (proba, y, T)``: one panel per model, raw and calibrated on it."""
    fig = Figure(figsize=(5 * len(curves), 4.3))
    axes = fig.subplots(1, len(curves), squeeze=False)
    for ax, (model, variants) in zip(axes[0], curves.items()):
        ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls=":", label="perfect calibration")
        for (variant, (P, y, T)), style in zip(variants.items(), ("s--", "o-")):
            r = reliability(P, y, bins)
            ok = r["count"] > 0
            ece = expected_calibration_error(P, y, bins)
            lab = f"{variant} (T = {T:.2f}): ECE {ece:.3f}" if variant != "raw" else f"raw: ECE {ece:.3f}"
            ax.plot(r["confidence"][ok], r["accuracy"][ok], style, label=lab)
            centres = 0.5 * (r["edges"][1:] + r["edges"][:-1])
            ax.bar(centres, r["count"] / r["count"].sum(), width=1.0 / bins, alpha=0.12,
                   color=ax.lines[-1].get_color(), zorder=0)
        ax.set(xlim=(0, 1), ylim=(0, 1), xlabel="confidence (max posterior)", ylabel="accuracy",
               title=f"{model} one-shot, {title}")
        ax.legend(fontsize=8, loc="upper left")
    fig.text(0.99, 0.01, "bars: fraction of test grasps per confidence bin", ha="right", fontsize=7, color="0.4")
    _save(fig, path)


def plot_lambda_sweep(sweep: dict, lambdas, title: str, path: Path) -> None:
    """Experiment 7: ``sweep[(kind, variant)] = list over lambdas of (decided & correct %, grasps)``."""
    fig = Figure(figsize=(11, 4.3))
    ax = fig.subplots(1, 2)
    lam = np.asarray(lambdas)
    ax[0].plot([lam.min(), 1.0], [100 * lam.min(), 100.0], color="0.5", ls=":", label="success = lambda")
    colors = {}
    for (kind, variant), pts in sweep.items():
        pts = np.asarray(pts)
        style = {"calibrated": "o-", "stop scale": "^-."}.get(variant, "s--")
        kw = {"color": colors[kind]} if kind in colors else {}
        (line,) = ax[0].plot(lam, pts[:, 0], style, label=f"{kind} {variant}", **kw)
        colors.setdefault(kind, line.get_color())
        ax[1].plot(lam, pts[:, 1], style, color=colors[kind], label=f"{kind} {variant}")
    ax[0].set(xlabel="lambda (decision threshold)", ylabel="success at the stop % (decided and correct)",
              title=f"success vs lambda, {title}")
    ax[1].set(xlabel="lambda (decision threshold)", ylabel="mean grasps", yscale="log", title=f"grasps vs lambda, {title}")
    ax[0].legend(fontsize=7)
    _save(fig, path)


def plot_family_votes(names, expected, votes: dict, families, title: str, path: Path) -> None:
    """Experiment 5: one panel per updater, a stacked bar per object of its trials' family votes.

    ``votes[kind]`` is ``(K, F)`` votes (a row of zeros: the object was never grasped, drawn empty); ``expected`` is
    the expected family per object (None: none), marked by a black edge on that family's segment."""
    names, F = list(names), len(families)
    fig = Figure(figsize=(4.2 * len(votes) + 2.0, max(2.5, 1.0 + 0.28 * len(names))))
    axes = fig.subplots(1, len(votes), squeeze=False, sharey=True)[0]
    colors = ("tab:orange", "tab:blue", "tab:green", "tab:red", "tab:purple")
    y = np.arange(len(names))
    for ax, (kind, V) in zip(axes, votes.items()):
        V = np.asarray(V, dtype=float)
        left = np.zeros(len(names))
        for f in range(F):
            edge = ["k" if e == families[f] else "none" for e in expected]
            ax.barh(y, V[:, f], left=left, color=colors[f % len(colors)], edgecolor=edge, linewidth=1.2)
            left += V[:, f]
        for k in np.flatnonzero(V.sum(1) == 0):
            ax.text(0.1, k, "no grasps to vote on" + (f" (expected: {expected[k]})" if expected[k] else ""),
                    va="center", fontsize=6, color="0.4")
        ax.set(xlabel="trials", title=f"{kind} votes, {title}", xlim=(0, max(1.0, V.sum(1).max())))
        ax.set_yticks(y, names, fontsize=7)
        ax.invert_yaxis()
    handles = [Patch(facecolor=colors[f % len(colors)], label=families[f]) for f in range(F)]
    axes[-1].legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.text(0.99, 0.01, "black edge: the family a person would expect", ha="right", fontsize=7, color="0.4")
    _save(fig, path)
