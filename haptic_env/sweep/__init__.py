"""Sweeps: declarative grids of train + evaluate, dataset, analysis and command jobs, run on Ray.

``haptic-recog sweep SPEC`` (:mod:`haptic_env.sweep.cli`) reads a TOML spec (:mod:`~haptic_env.sweep.spec`),
runs every job that is not finished yet as a Ray task (:mod:`~haptic_env.sweep.runner`; each job in its own run
folder, :mod:`~haptic_env.sweep.jobs`) and writes one aggregate report (:mod:`~haptic_env.sweep.report`).
Shipped specs (the benchmark tiers and a smoke spec) are in ``sweeps/`` of the source tree.
"""

from .spec import Job, SpecError, SweepSpec, load_spec, parse_spec

__all__ = ["Job", "SpecError", "SweepSpec", "load_spec", "parse_spec"]
