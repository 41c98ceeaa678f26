"""``haptic-recog sweep SPEC``: run a sweep spec's jobs on Ray (local by default, ``--address`` joins a
cluster), skip the finished ones, retry and report the failed ones, and write the sweep's report.

    haptic-recog sweep sweeps/easy.toml                      # local Ray, all cores
    haptic-recog sweep sweeps/easy.toml --num-cpus 2 --out outputs/sweeps/easy
    ray start --head --port 6379 && haptic-recog sweep sweeps/easy.toml --address 127.0.0.1:6379
    haptic-recog sweep sweeps/hands.toml --match allegro     # only the jobs whose id matches (and what they need)
    haptic-recog sweep sweeps/easy.toml --dry-run            # list the jobs and their state
    haptic-recog sweep sweeps/easy.toml --report-only        # the report from the run folders on disk
    haptic-recog sweep sweeps/hands.toml --report-only --out NEW --prior-report docs/results/leaderboard/hands_5finger
                                        # + an earlier report's episodes for the jobs not run in NEW

Exit status 0 when every job is done, 1 when a job failed (after its retries; the report lists it).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

__all__ = ["add_parser"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    from haptic_env.cli import int_in, output_path

    from .spec import KINDS

    p = subparsers.add_parser("sweep", help="run a sweep spec (train/evaluate/dataset/analysis jobs) on Ray",
                              description=__doc__.split("\n\n")[0],
                              formatter_class=argparse.RawDescriptionHelpFormatter,
                              epilog="\n".join(__doc__.split("\n")[3:]))
    p.add_argument("spec", type=Path, help="TOML sweep spec (see haptic_env/sweep/spec.py; examples in sweeps/)")
    p.add_argument("--out", type=output_path("folder"), default=None, help="sweep folder (default: the spec's out, "
                   "else outputs/sweeps/<name>)")
    p.add_argument("--address", default=None, help="join this Ray cluster (HOST:PORT or 'auto'); default: start "
                   "a local one")
    p.add_argument("--num-cpus", type=int_in(1), default=None, help="CPUs of the local Ray (default: all cores; "
                   "not with --address: a cluster has its own)")
    p.add_argument("--max-retries", type=int_in(0, 1000), default=None, help="retries of a failed job (default: the "
                   "spec's max_retries, else 2)")
    p.add_argument("--only", nargs="+", choices=KINDS, default=None, help="run only these job kinds (and what "
                   "they need)")
    p.add_argument("--match", default=None, metavar="REGEX", help="run only the jobs whose id (as --dry-run lists "
                   "them, e.g. 'train/allegro/ppo/seed0-...') contains a match of REGEX, and what they need; the "
                   "report covers every finished job")
    p.add_argument("--dry-run", action="store_true", help="list the jobs and whether they are done; run nothing")
    p.add_argument("--report-only", action="store_true", help="write the report from the run folders; run nothing")
    p.add_argument("--prior-report", type=Path, default=None, metavar="DIR", help="the folder of an earlier "
                   "report of this spec (report.md + report/<env>/episodes.csv, e.g. a committed one whose run "
                   "folders are gone): its episodes stand in for the evaluate jobs not finished in --out, and the "
                   "report names them")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_main)
    return p


def _main(args) -> int:
    from haptic_env.cli import UsageError

    from .jobs import is_done
    from .report import write_sweep_report
    from .runner import InfeasibleJob, finished_before, ray_available, run_sweep, select_jobs, write_status
    from .spec import SpecError, load_spec

    if not args.spec.is_file():
        raise UsageError(f"spec {args.spec} does not exist" + (" (it is a folder; give the spec's .toml file)"
                                                                 if args.spec.is_dir() else ""))
    if args.dry_run and args.report_only:
        raise UsageError("--dry-run lists the jobs and --report-only writes the report: give one of them")
    if args.num_cpus is not None and args.address not in (None, "local"):  # Ray would ignore it: the cluster's own
        raise UsageError(f"--num-cpus sets the CPUs of a local Ray; the cluster that --address {args.address!r} joins "
                         "has its own (give one of them)")
    try:
        spec = load_spec(args.spec, check_files=not (args.dry_run or args.report_only))  # files: for jobs to run
    except SpecError as exc:
        raise UsageError(str(exc)) from exc
    if args.out is None:  # the spec's own out, checked as --out is (a path under a file failed once Ray had started)
        from haptic_env.cli import output_path

        try:
            output_path("folder")(str(spec.default_out()))
        except argparse.ArgumentTypeError as exc:
            raise UsageError(f"spec out: {exc}") from None
    out = (args.out or spec.default_out()).resolve()
    kinds = set(args.only) if args.only else None
    if args.match is not None:
        try:
            pattern = re.compile(args.match)
        except re.error as exc:
            raise UsageError(f"--match {args.match!r} is not a regular expression: {exc}") from None
        if not any(pattern.search(j.id) for j in spec.jobs):
            raise UsageError(f"--match {args.match!r} matches none of the spec's {len(spec.jobs)} job ids "
                             "(--dry-run lists them)")
    if not select_jobs(spec, kinds, args.match):  # it ran nothing and wrote an empty report, exit status 0
        raise UsageError(f"--only {' '.join(sorted(kinds or ()))}"
                         + (f" with --match {args.match!r}" if args.match else "")
                         + f" selects none of the spec's {len(spec.jobs)} jobs (of kinds "
                         f"{sorted({j.kind for j in spec.jobs})})")
    if args.prior_report is not None:  # checked before anything runs or is written
        from .report import load_prior_records

        if not (args.prior_report / "report").is_dir():
            raise UsageError(f"--prior-report {args.prior_report} is not a sweep report folder (it has no report/ "
                             "folder with report/<env>/episodes.csv)")
        try:
            for env in spec.envs:
                load_prior_records(spec, args.prior_report, env)
        except ValueError as exc:
            raise UsageError(f"--prior-report: {exc}") from None
    if args.dry_run:
        finished = {j.id: is_done(j.run_dir(out)) for j in spec.jobs}
        jobs = select_jobs(spec, kinds, args.match, done=lambda j: finished[j.id])
        for j in jobs:
            state = "done" if finished[j.id] else "todo"
            needs = ", ".join(j.deps) if len(j.deps) <= 2 else f"{j.deps[0]} and {len(j.deps) - 1} more"
            print(f"{state:5} {j.id}  (cpus {j.cpus:g}{', needs ' + needs if j.deps else ''})")
        print(f"{len(jobs)} of the spec's {len(spec.jobs)} jobs; sweep folder {out}")
        return 0
    if args.report_only:
        result = finished_before(spec, out)
        if not result.done and args.prior_report is None:  # a mistyped --out wrote an empty report (and a new folder)
            raise UsageError(f"--report-only: {out} holds no finished job of {spec.name} (and no --prior-report "
                             "stands in for them): nothing to report")
    else:
        if not ray_available():
            raise UsageError("the sweep runs on Ray, which is not installed: pip install 'haptic-recog[sweep]' "
                             "(or pip install 'ray>=2.40')")
        try:
            result = run_sweep(spec, out, address=args.address, num_cpus=args.num_cpus,
                               max_retries=args.max_retries, kinds=kinds, match=args.match, progress=not args.quiet)
        except InfeasibleJob as exc:  # refused before any job or file
            raise UsageError(str(exc)) from None
    write_status(result, spec)
    report = write_sweep_report(spec, result, command=["haptic-recog", "sweep", *sys.argv[2:]]
                                if sys.argv[1:2] == ["sweep"] else None, prior=args.prior_report)
    n_new = len(result.done) - len(result.skipped)
    print(f"[sweep] {spec.name}: {n_new} job(s) done in this run, {len(result.skipped)} skipped (done before), "
          f"{len(result.failed)} failed; {result.seconds / 60:.1f} min; report: {report}", flush=True)
    for jid, err in result.failed.items():
        print(f"[sweep] FAILED {jid}: {err.splitlines()[-1] if err else ''}", file=sys.stderr)
    return 1 if result.failed else 0
