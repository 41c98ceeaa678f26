"""``haptic-recog analysis``: the paper's recognition analysis on any object set (the flags of
:class:`~haptic_env.experiments.config.AnalysisConfig`)."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from haptic_env.cli import float_in, output_path, parse_int_list
from haptic_env.grasp_features import NORMAL_AXES
from haptic_env.objects.base import UP_AXES
from haptic_env.experiments.config import FAMILY_SOURCES, AnalysisConfig
from haptic_env.recognizers.boosted import LIKELIHOODS
from haptic_env.recognizers.calibration import CORRECTIONS, check_corrections
from haptic_env.recognizers.kde import SELECTS
from haptic_env.recognizers.updaters import IC_CERTAINTIES

__all__ = ["add_parser"]


def _corrections(text: str) -> tuple[str, ...]:
    """``"matrix,power"`` -> ``("matrix", "power")``, each a name of ``calibration.CORRECTIONS``, once."""
    from haptic_env.cli import UsageError

    try:
        return check_corrections([c.strip() for c in text.split(",") if c.strip()], "--kde-corrections",
                                 allow_empty=False)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _numbers(text: str, flag: str) -> tuple[float, ...]:
    """``"a,b,..."`` -> ``(a, b, ...)``: a usage error naming ``flag`` if a value is not a number or none is given."""
    from haptic_env.cli import UsageError

    try:
        out = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise UsageError(f"{flag}: expected comma-separated numbers, got {text!r}") from None
    if not out:
        raise UsageError(f"{flag}: expected comma-separated numbers, got {text!r}")
    return out


def _lambdas(text: str) -> tuple[float, ...]:
    from haptic_env.cli import UsageError

    out = _numbers(text, "--lambdas")
    if any(not 0 < x <= 1 for x in out):
        raise UsageError(f"--lambdas: thresholds must be in (0, 1], got {text!r}")
    return out


def _range(text: str, flag: str) -> tuple[float, float]:
    """``"LO,HI"`` -> ``(LO, HI)`` (checked by :class:`AnalysisConfig`)."""
    from haptic_env.cli import UsageError

    try:
        out = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UsageError(f"{flag}: expected LO,HI, got {text!r}") from None
    if len(out) != 2:
        raise UsageError(f"{flag}: expected LO,HI, got {text!r}")
    return out


def _equivalent_command(args) -> str:
    """The ``haptic-recog analysis`` command line with every setting spelled out (defaults included)."""
    parser = getattr(args, "_cli_parser", None)
    if parser is None:
        return ""
    words = ["haptic-recog", "analysis"]
    for action in parser._actions:
        if not action.option_strings or action.dest == "help":
            continue
        v = getattr(args, action.dest, None)
        flag = action.option_strings[-1]
        if isinstance(action, argparse._StoreTrueAction):
            words += [flag] if v else []
        elif isinstance(action, argparse.BooleanOptionalAction):  # --x / --no-x
            words += [] if v is None else [action.option_strings[0] if v else action.option_strings[1]]
        elif v is not None:
            words += [flag, str(v)]
    return shlex.join(words)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``analysis`` sub-command."""
    import haptic_env.experiments as experiments

    d = AnalysisConfig()
    p = subparsers.add_parser("analysis", help="reproduce the paper's recognition analysis on an object set",
                              description=experiments.__doc__.split("\n\n")[0])
    p.add_argument("--objects", default=d.objects, help="default | families[:N] | kit8 | kit20 | ycb10 | folder")
    p.add_argument("--data-dir", default=None, help="shared data folder (default: $HAPTIC_DATA or ../shared/data)")
    p.add_argument("--units", default="m", help="units of a folder's meshes")
    p.add_argument("--up", default=d.up, choices=UP_AXES,
                   help="a folder's meshes' up axis, turned to z so that they stand on the table (named sets know "
                        "theirs: KIT y)")
    p.add_argument("--out", type=output_path("folder"), required=True, help="output folder for results.md and PNG plots")
    p.add_argument("--experiments", default="1,2,3,4,5,6,7", help="comma list / ranges of 1..7 (default all)")
    p.add_argument("--grasps-per-object", type=int, default=d.grasps_per_object, help="training grasps per object (paper: 200000)")
    p.add_argument("--test-grasps", type=int, default=d.test_grasps, help="fresh test grasps per object")
    p.add_argument("--trials", type=int, default=d.trials, help="trials per cell (paper: 1000)")
    p.add_argument("--max-grasps", type=int, default=d.max_grasps)
    p.add_argument("--threshold", type=float, default=d.threshold, help="lambda_s")
    p.add_argument("--fingers", default="2-10", help="finger counts of experiment 2 (e.g. 2-10 or 3,4,5)")
    p.add_argument("--oneshot-fingers", default="3,4,5", help="finger counts of experiment 1")
    p.add_argument("--classifiers", default=",".join(d.classifiers), help="experiment 1 classifiers")
    p.add_argument("--baseline-max-train", type=int, default=d.baseline_max_train)
    p.add_argument("--zfinger-hands", default="5,6,8", help="experiment 3 hand sizes n")
    p.add_argument("--no-normals", action="store_true", help="experiments 2-6 without normals")
    p.add_argument("--family-source", default=d.family_source, choices=FAMILY_SOURCES,
                   help="experiment 5's grasps of the family members and the objects: independent surface points "
                        "(surface, the paper's), the geometric hand closing along random approaches (geometric), or "
                        "the --family-hand's own MuJoCo grasps under random approaches, objects on the table (hand)")
    p.add_argument("--family-hand", default=d.family_hand,
                   help="experiment 5 with --family-source hand: the hand (a load_hand name, e.g. allegro)")
    p.add_argument("--family-scale-range", default=",".join(str(v) for v in d.family_scale_range),
                   help="experiment 5: LO,HI of the family members' per-axis scale factors about 0.08 m (the paper's "
                        "0.5,1.5)")
    p.add_argument("--family-size-range", default=None,
                   help="experiment 5: LO,HI of a factor per family member on all three axes, its overall size "
                        "(default none, the paper's); a hand's grasps depend on size, so with --family-source hand let the "
                        "members span the objects' sizes, e.g. 0.7,1.6")
    p.add_argument("--family-heights", action="store_true",
                   help="experiment 5 with --family-source hand: append each contact's height above the table to the "
                        "grasp vector (the objects rest on the table in their own pose; default: the paper's Phi_n)")
    p.add_argument("--family-lying", action="store_true",
                   help="experiment 5: every second elliptic cylinder member lies on its side (default: all stand, the "
                        "paper's generator); with --family-source hand the pose on the table changes the grasps")
    p.add_argument("--force-closure", type=float_in(0.0, lo_open=True), default=None, metavar="MU",
                   help="experiments 1-4, 6, 7: only surface grasps in force closure at this friction coefficient, in "
                        "training and test alike (default: every grasp, the paper's stated protocol; finger counts >= 3)")
    p.add_argument("--family-force-closure", type=float_in(0.0, lo_open=True), default=None, metavar="MU",
                   help="experiment 5 with --family-source surface: only the grasps in force closure at this friction "
                        "coefficient, of the members and the objects alike (default: every grasp, the paper's)")
    p.add_argument("--family-floors", default=",".join(f"{q:g}" for q in d.family_floors), metavar="Q,...",
                   help="experiment 5 (calibrated scores): the family KDE's outlier floors to choose from on the "
                        "validation members, as quantiles of the true family's log-likelihood on held-back member "
                        "grasps (0: none; '0' turns the floor off)")
    p.add_argument("--family-members", type=int, default=d.family_members,
                   help="experiment 5: training members per family (a third as many validation and test members)")
    p.add_argument("--normal-axis", default=d.normal_axis, choices=NORMAL_AXES,
                   help="each normal's second angle in Phi_n (n >= 4): to t2's normal (t2, the paper's) or to the "
                        "edge ab (ab); or three angles per normal, to the axes of t1's frame (frame, n >= 3)")
    p.add_argument("--raw", action="store_true",
                   help="experiments 2-6 on the raw scores (the paper's method), without the calibration temperatures")
    p.add_argument("--ic-certainty", choices=IC_CERTAINTIES, default=d.ic_certainty,
                   help="IC's certainty: count, the winner's summed probability over the grasp count (default); share, "
                        "its share of the summed winner scores once it reaches 0.6, from the second grasp on (the "
                        "authors' public code)")
    p.add_argument("--likelihood", choices=LIKELIHOODS, default=d.likelihood,
                   help="the beliefs' likelihood (experiments 1-4, 6, 7): kde, the paper's KDE (default); hgb, "
                        "scikit-learn's histogram gradient boosting on at most 50,000 training grasps per object "
                        "(haptic_env.recognizers.boosted; not the paper's method)")
    p.add_argument("--stop-scale", action=argparse.BooleanOptionalAction, default=None,
                   help="experiment 2: divide BC's calibrated log-likelihoods by a stop scale chosen on validation "
                        "trials so that a stop at lambda is right about lambda of the time (fewest BC-NP grasps among "
                        "the scales that are; haptic_env.experiments.stop_scale). Default: on, off with --raw")
    p.add_argument("--no-correction", action="store_true",
                   help="calibrate the KDE by its temperature alone, without the learned correction of its scores "
                        "(KDEConfig.correct; by default it is used where it lowers the held-out validation NLL of "
                        "BC-NP's beliefs; --raw turns off both)")
    p.add_argument("--kde-select", default=d.kde.select, choices=SELECTS,
                   help="how the KDE's bandwidth factor is chosen on validation grasps: by the calibrated one-shot "
                        "posterior's held-out NLL (posterior) or by the density's log-likelihood (likelihood, the "
                        "envs' choice)")
    p.add_argument("--kde-corrections", default=",".join(d.kde.correct_candidates),
                   help="the learned corrections of the KDE's scores that are weighed against its temperature alone "
                        f"on held-out validation grasps (KDEConfig.correct_candidates; of {','.join(CORRECTIONS)})")
    p.add_argument("--calibrate-grasps", type=int, default=d.kde.calibrate_grasps,
                   help="fit the KDE's temperature for beliefs of 1..K grasps of one object (1: one-shot; the hand "
                        "envs use 5, the Shadow env 10)")
    p.add_argument("--calib-fingers", default=",".join(map(str, d.calib_fingers)),
                   help="experiment 7: finger counts with normals")
    p.add_argument("--calib-fingers-no-normals", default=",".join(map(str, d.calib_fingers_no_normals)),
                   help="experiment 7: finger counts without normals (empty: none)")
    p.add_argument("--lambdas", default=",".join(f"{x:g}" for x in d.lambdas), help="experiment 7: thresholds swept")
    p.add_argument("--mlp-depth", type=int, default=d.mlp.depth)
    p.add_argument("--mlp-width", type=int, default=d.mlp.width)
    p.add_argument("--mlp-epochs", type=int, default=d.mlp.max_epochs)
    p.add_argument("--mlp-max-train", type=int, default=d.mlp.max_train)
    p.add_argument("--kde-method", default=d.kde.method, choices=("tree", "pooled", "dense", "subsample"))
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_run_cli, interrupt_note="finished experiments are saved; the same command resumes after them")
    return p


def _run_cli(args) -> int:
    from haptic_env.experiments.analysis import run_analysis

    from haptic_env.cli import UsageError
    from haptic_env.objects import load_object_set
    from haptic_env.objects.loaders import NAMED_SETS, check_object_data

    cfg = config_from_args(args)
    try:
        check_object_data(cfg.objects, cfg.data_dir)  # missing data: a usage error before any work
        if Path(cfg.objects).expanduser().is_dir() and cfg.objects not in NAMED_SETS:
            # a folder with no meshes or an unreadable one: a usage error too (run_analysis reads it again; a
            # folder of the user's few meshes loads in moments)
            load_object_set(cfg.objects, units=cfg.units, up=cfg.up)
    except (FileNotFoundError, ValueError) as exc:  # MeshLoadError is a ValueError
        raise UsageError(f"--objects {cfg.objects}: {exc}") from exc
    path = run_analysis(cfg, args.out, command=_equivalent_command(args))
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def config_from_args(args) -> AnalysisConfig:
    """The :class:`AnalysisConfig` of parsed ``analysis`` arguments; a bad setting is a
    :class:`~haptic_env.cli.UsageError` (also used by sweep specs, to check an analysis job's flags at load)."""
    from haptic_env.cli import UsageError
    from haptic_env.recognizers.kde import KDEConfig
    from haptic_env.recognizers.mlp import MLPConfig

    if args.raw and args.stop_scale:
        raise UsageError("--stop-scale scales calibrated scores; --raw is the paper's method, with neither "
                         "(drop one of them)")
    args.stop_scale = not args.raw if args.stop_scale is None else args.stop_scale  # spelled out in the command
    try:  # a bad setting gets the usage message, not a traceback
        cfg = AnalysisConfig(
            objects=args.objects, data_dir=args.data_dir, units=args.units, up=args.up,
            experiments=parse_int_list(args.experiments),
            grasps_per_object=args.grasps_per_object, test_grasps=args.test_grasps, trials=args.trials,
            max_grasps=args.max_grasps, threshold=args.threshold, fingers=parse_int_list(args.fingers),
            oneshot_fingers=parse_int_list(args.oneshot_fingers),
            classifiers=tuple(c for c in args.classifiers.split(",") if c), baseline_max_train=args.baseline_max_train,
            zfinger_hands=parse_int_list(args.zfinger_hands), normals=not args.no_normals, normal_axis=args.normal_axis,
            family_source=args.family_source, family_members=args.family_members, family_hand=args.family_hand,
            family_scale_range=_range(args.family_scale_range, "--family-scale-range"),
            family_size_range=None if args.family_size_range is None else _range(args.family_size_range,
                                                                                 "--family-size-range"),
            family_heights=args.family_heights, family_lying=args.family_lying,
            family_floors=_numbers(args.family_floors, "--family-floors"),
            family_force_closure=args.family_force_closure, force_closure=args.force_closure,
            calibrated=not args.raw, stop_scale=args.stop_scale, ic_certainty=args.ic_certainty,
            likelihood=args.likelihood,
            calib_fingers=parse_int_list(args.calib_fingers),
            calib_fingers_no_normals=parse_int_list(args.calib_fingers_no_normals),
            lambdas=_lambdas(args.lambdas), seed=args.seed,
            mlp=MLPConfig(depth=args.mlp_depth, width=args.mlp_width, max_epochs=args.mlp_epochs, patience=3,
                          max_train=args.mlp_max_train, seed=args.seed),
            kde=KDEConfig(method=args.kde_method, calibrate_grasps=args.calibrate_grasps, seed=args.seed,
                          correct=False if args.no_correction else "auto", select=args.kde_select,
                          correct_candidates=_corrections(args.kde_corrections)),
            progress=not args.quiet,
        )
    except UsageError:
        raise
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    d = AnalysisConfig()
    if cfg.family_source != "hand" and cfg.family_hand != d.family_hand:  # it was accepted and ignored
        raise UsageError(f"--family-hand {cfg.family_hand} needs --family-source hand (got --family-source "
                         f"{cfg.family_source})")
    if not cfg.calibrated and cfg.family_floors != d.family_floors:  # raw scores have no floor: it was ignored
        raise UsageError(f"--family-floors {args.family_floors} chooses experiment 5's outlier floor on calibrated "
                         "scores; --raw has neither (drop one of them)")
    if args.no_correction and cfg.kde.correct_candidates != d.kde.correct_candidates:
        raise UsageError(f"--kde-corrections {args.kde_corrections} weighs corrections that --no-correction turns off "
                         "(drop one of them)")
    if 5 in cfg.experiments and cfg.family_source == "hand":
        from haptic_env.grasping.hands import load_hand

        try:  # a bad name is a usage error now (a sweep's spec check too), not a traceback or a failed job
            load_hand(cfg.family_hand, n_fingers=4)
        except ValueError as exc:
            raise UsageError(f"--family-hand {cfg.family_hand}: {exc}") from None
    return cfg  # AnalysisConfig checked the experiment numbers
