"""Calibrate every shipped preset against its frame's catalogue figures and record it.

    python studies/preset_calibration/calibrate_presets.py [--check]

For each preset: fit the series output stiffness and the modification pair's
size of its estimate (`<name>-estimate`) to its frame's torsional rigidity and
lost motion (rvfmu/bench/catalogue.py), print the figures before and after beside
the catalogue's, and write the fit as the `[calibration]` table of the preset
file in rvfmu/core/reducer/presets/ (the source tree: run it from an editable install).
--check writes nothing and fails when a recorded calibration differs from a
fresh one by more than 0.1 % (the fit is seeded: the same estimate gives the
same answer).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import rvfmu.core.reducer.presets
from rvfmu.bench import catalogue
from rvfmu.core.reducer.design import PRESET_NAMES, preset_file

COMMAND = "python studies/preset_calibration/calibrate_presets.py"
CHECK_RELATIVE = 1e-3


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="write nothing; compare with the files")
    args = parser.parse_args(argv)
    folder = Path(rvfmu.core.reducer.presets.__file__).parent
    print(
        f"{'preset':<11} {'frame':<8} {'rigidity N*m/arcmin':>30} {'lost motion arcmin':>27} "
        f"{'output_stiffness':>17} {'mod. scale':>10} {'evals':>6} {'time':>6}"
    )
    print(
        f"{'':<11} {'':<8} {'estimate':>10}{'fitted':>10}{'catalogue':>10} "
        f"{'estimate':>9}{'fitted':>9}{'aim/max':>9} {'N*m/arcmin':>17}"
    )
    stale = []
    for name in PRESET_NAMES:
        frame = catalogue.frame_of(name)
        start = time.perf_counter()
        cal = catalogue.calibrate_preset(name)
        seconds = time.perf_counter() - start
        before, after = cal.before[0], cal.after[0]
        aim = cal.problem.datasets[0].catalogue.lost_motion_arcmin
        print(
            f"{name:<11} {frame.name:<8} {before[0]:>10.1f}{after[0]:>10.1f}"
            f"{frame.torsional_rigidity_Nm_per_arcmin:>10.4g} {before[1]:>9.3f}{after[1]:>9.3f}"
            f"{f'{aim:.2g}/{frame.lost_motion_max_arcmin:.2g}':>9} {cal.values[0]:>17.4g} "
            f"{cal.values[1]:>10.4f} {cal.evaluations:>6} {seconds:>5.1f}s"
        )
        if args.check:
            recorded = preset_file(name).get("calibration", {})
            fresh = dict(zip(catalogue.CALIBRATION_FIT, cal.values))
            if any(abs(recorded.get(k, 0.0) - v) > CHECK_RELATIVE * abs(v) for k, v in fresh.items()):
                stale.append(name)
            continue
        catalogue.write_calibration(folder / f"{name}.toml", catalogue.calibration_table(cal, frame, COMMAND))
    if stale:
        print(f"recorded calibrations differ from a fresh fit: {', '.join(stale)}", file=sys.stderr)
        return 1
    print(
        "checked: the recorded calibrations are the fresh ones"
        if args.check
        else f"wrote the [calibration] tables of {len(PRESET_NAMES)} presets in {folder}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
