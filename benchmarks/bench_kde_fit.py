"""KDE fit time of the analyses' default against the earlier one, on the same data in one process.

The analyses' KDE (``AnalysisConfig.kde``) chooses its bandwidth factor by the held-out validation NLL of the
calibrated one-shot posterior and weighs two learned corrections (``select="posterior"``, ``correct_candidates=
("matrix", "power")``). The earlier default chose it by the density's validation likelihood and weighed the matrix
correction alone. Both fits (``KDELikelihood.fit``: bandwidth choice, trees, calibration) run on the same cached
training and validation grasps; the dataset build or load is not timed. The earlier default runs twice, before and
after, and the faster of its two CPU times is the baseline.

    OMP_NUM_THREADS=1 python benchmarks/bench_kde_fit.py --objects default --fingers 4 --no-normals \
        --grasps-per-object 200000

Headline (last line): the default's CPU time as a ratio of the earlier default's.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from haptic_env.dataset import build_dataset  # noqa: E402
from haptic_env.experiments.config import AnalysisConfig  # noqa: E402
from haptic_env.objects import load_object_set  # noqa: E402
from haptic_env.recognizers.kde import KDELikelihood  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--objects", default="default")
    p.add_argument("--units", default="m")
    p.add_argument("--fingers", type=int, default=4)
    p.add_argument("--no-normals", action="store_true")
    p.add_argument("--grasps-per-object", type=int, default=10_000)
    a = p.parse_args(argv)
    if a.fingers < 2 or a.grasps_per_object < 100:
        p.error(f"--fingers must be >= 2 and --grasps-per-object >= 100, got {a.fingers} and {a.grasps_per_object}")
    normals = not a.no_normals
    cfg = AnalysisConfig(objects=a.objects, units=a.units, grasps_per_object=a.grasps_per_object, normals=normals,
                         progress=False)
    rc = cfg.recognizer_config()
    objects = load_object_set(a.objects, units=a.units)
    ds = build_dataset(objects, rc.dataset_config(a.fingers, normals, hand_fingers=a.fingers), progress=True)
    earlier = dataclasses.replace(rc.kde, select="likelihood", correct_candidates=("matrix",))
    print(f"{a.objects}, n = {a.fingers}, {'with' if normals else 'without'} normals; {len(ds.X_train)} training, "
          f"{len(ds.X_val)} validation grasps")
    cpu = {}
    for name, kcfg in [("earlier", earlier), ("default", rc.kde), ("earlier again", earlier)]:
        t, w = time.process_time(), time.perf_counter()
        kde = KDELikelihood(kcfg).fit(ds.X_train, ds.y_train, ds.X_val, ds.y_val, n_classes=len(objects))
        cpu[name] = time.process_time() - t
        print(f"{name} (select={kcfg.select}, corrections {','.join(kcfg.correct_candidates)}): CPU "
              f"{cpu[name]:.3f} s, wall {time.perf_counter() - w:.1f} s; factor {float(kde.factor[0]):g}", flush=True)
    base = min(cpu["earlier"], cpu["earlier again"])
    print(f"HEADLINE: the analyses' KDE fit takes {cpu['default'] / base:.1f}x the CPU time of the earlier default's "
          f"({cpu['default']:.2f} s against {base:.2f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
