"""Wall time of the jobs a newcomer runs first, end to end, as the README runs them.

What it measures, in this process, through the public functions behind the
commands (files written to a temporary folder):
- `rvte te RV-40E-121 --errors studies/seed002_errors.toml --plot ...`
  (the default 8 points per pin-passing period, lost motion and rigidity, the figure),
- `rvte mc studies/quick_mc.toml` (2000 reducers, computed in-process as 2048 in whole
  batches of 64, the count the table shows; with its aliasing check, figures and
  files; a fresh output folder, so nothing is reused),
- `rvte fmu build RV-40E-121 --errors studies/seed002_errors.toml` (the TE map at
  the default points, the FMU written).
The ratio column is each job's time over the TE curve's, the baseline.  The
README quotes these figures with the machine line printed first.

Run:  python studies/benchmarks/bench_jobs.py
"""

import os
import platform
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ERRORS = ROOT / "studies" / "seed002_errors.toml"


def machine() -> str:
    model = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (
        f"{os.cpu_count()} cores, {model or platform.processor() or 'unknown CPU'}, "
        f"Python {platform.python_version()}"
    )


def timed(job):
    start = time.perf_counter()
    result = job()
    return time.perf_counter() - start, result


def main() -> None:
    from rvfmu import api
    from rvfmu.fmu.api import fmu_build
    from tolerance import run_mc

    print(f"machine: {machine()}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="rvte_bench_jobs_") as tmp:
        tmp = Path(tmp)
        seconds, report = timed(lambda: api.te("RV-40E-121", ERRORS, plot_path=tmp / "te.png"))
        points = report.curve.points
        rows.append(
            (
                "rvte te RV-40E-121 --errors seed002 --plot",
                f"{points} points",
                seconds,
                f"{points / seconds:.0f} points/s",
            )
        )
        seconds, result = timed(lambda: run_mc(ROOT / "studies" / "quick_mc.toml", output=tmp / "quick_mc"))
        reducers = result.computed.Y.shape[0]
        rows.append(
            (
                "rvte mc studies/quick_mc.toml",
                f"{reducers} reducers",
                seconds,
                f"{reducers / seconds:.0f} reducers/s",
            )
        )
        seconds, _ = timed(lambda: fmu_build("RV-40E-121", ERRORS, tmp / "RVReducer.fmu"))
        from rvfmu.core.steppers.te_map import TORQUE_FRACTIONS

        poses = 2 * len(TORQUE_FRACTIONS) * points
        rows.append(
            (
                "rvte fmu build RV-40E-121 --errors seed002",
                f"{poses} poses",
                seconds,
                f"{poses / seconds:.0f} poses/s",
            )
        )
    baseline = rows[0][2]
    print(f"{'what':<46} {'size':>16} {'time [s]':>9} {'throughput':>18} {'ratio':>7}")
    for what, size, seconds, rate in rows:
        print(f"{what:<46} {size:>16} {seconds:>9.2f} {rate:>18} {seconds / baseline:>7.2f}")


if __name__ == "__main__":
    main()
