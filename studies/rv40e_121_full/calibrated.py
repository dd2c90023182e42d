"""The complete study's ranking on the calibrated RV-40E-121 beside the estimate's.

The study files of this folder use `RV-40E-121`, the preset as shipped,
calibrated to the catalogue: the estimate from geometry (`RV-40E-121-estimate`)
with a series output compliance (which leaves te_pp as it is) and a tip and
root clearance scaled to 0.24 of the estimate's (which changes the no-load TE
under errors and the lost motion).  This runs the Sobol job of both study
files as they are and with `design = "RV-40E-121-estimate"` (a copy of each
beside its output), on the same Saltelli rows, and prints every metric's
values and indices side by side.  Stored runs are reused; a stopped run
carries on.

    python studies/rv40e_121_full/calibrated.py [STUDY ...] [-n 1024] [--processes 2] [--windup-only]

STUDY: study files to compare (default: the rated one, then the no-load one).
--windup-only: lost motion and torsional rigidity alone, on copies of both
designs (the windup test needs no TE curve: minutes instead of the no-load
TE's 45 to 80).
"""

import argparse
from pathlib import Path

from compare_points import STUDIES, Job, side_by_side, variant

WINDUP_ONLY = '["lost_motion", "torsional_rigidity"]'


def compare(study, n: int, processes: int, windup_only: bool = False) -> str:
    if windup_only:
        study = variant(study, "windup", metrics=WINDUP_ONLY, te_pp_arcsec=None)
    calibrated = Job(study, n, processes)
    estimate = Job(variant(study, "estimate", design='"RV-40E-121-estimate"'), n, processes)
    lines = [f"### {study.name}: N = {n} ({estimate.X.shape[0]} reducers, the same rows on both designs)", ""]
    lines += side_by_side(estimate, calibrated, "estimate", "calibrated", windup=True)
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "studies",
        nargs="*",
        type=Path,
        default=[STUDIES / "rv40e_121_full_rated.toml", STUDIES / "rv40e_121_full.toml"],
        help="study files (default: both of this folder)",
    )
    parser.add_argument("-n", type=int, default=1024, help="Sobol base samples (a power of 2)")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument(
        "--windup-only", action="store_true", help="lost motion and torsional rigidity alone (no TE curve)"
    )
    args = parser.parse_args(argv)
    for study in args.studies:
        print(compare(study, args.n, args.processes, args.windup_only), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
