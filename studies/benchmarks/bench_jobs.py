"""Wall time of the jobs a newcomer runs first, end to end, as the README runs them.

What it measures: each command run as a process of its own, as a newcomer types it
(the `rvte` installed beside this interpreter; files written to a temporary folder), so
each time holds the interpreter's start, the imports, loading the cached compiled code and
building the models it needs:
- `rvte te RV-40E-121 --errors studies/seed002_errors.toml --plot ...`
  (the default 8 points per pin-passing period, lost motion and rigidity, the figure),
- `rvte mc studies/quick_mc.toml` (2000 reducers, computed in-process as 2048 in whole
  batches of 64, the count the table shows; with its aliasing check, figures and
  files; a fresh output folder (`-o`), so nothing is reused),
- `rvte fmu build RV-40E-121 --errors studies/seed002_errors.toml` (the TE map at
  the default points, the FMU written).
The ratio column is each job's time over the TE curve's, the baseline.  The
README quotes these figures with the machine line printed first.

Run:  python studies/benchmarks/bench_jobs.py
"""

import os
import platform
import subprocess
import sys
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


def rvte(*arguments: str) -> None:
    """Run `rvte arguments...` as a command of its own, as a newcomer types it: the `rvte`
    installed beside this interpreter, its output discarded; a failure stops the benchmark."""
    script = Path(sys.executable).with_name("rvte")
    command = [str(script) if script.exists() else "rvte", *arguments]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr}")


def main() -> None:
    from rvfmu.core.statics.quasistatic import default_points
    from rvfmu.core.steppers.te_map import TORQUE_FRACTIONS
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")  # its design is the RV-40E-121's preset
    points = default_points(study.design)
    reducers = -(-study.mc_n // study.batch_size) * study.batch_size
    poses = 2 * len(TORQUE_FRACTIONS) * points
    print(f"machine: {machine()}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="rvte_bench_jobs_") as tmp:
        tmp = Path(tmp)
        jobs = (
            (
                "rvte te RV-40E-121 --errors seed002 --plot",
                ("te", "RV-40E-121", "--errors", str(ERRORS), "--plot", str(tmp / "te.png")),
                f"{points} points",
                points,
                "points/s",
            ),
            (
                "rvte mc studies/quick_mc.toml",
                ("mc", "studies/quick_mc.toml", "-o", str(tmp / "quick_mc")),
                f"{reducers} reducers",
                reducers,
                "reducers/s",
            ),
            (
                "rvte fmu build RV-40E-121 --errors seed002",
                ("fmu", "build", "RV-40E-121", "--errors", str(ERRORS), "-o", str(tmp / "RVReducer.fmu")),
                f"{poses} poses",
                poses,
                "poses/s",
            ),
        )
        for what, arguments, size, count, unit in jobs:
            seconds, _ = timed(lambda arguments=arguments: rvte(*arguments))
            rows.append((what, size, seconds, f"{count / seconds:.0f} {unit}"))
    baseline = rows[0][2]
    print(f"{'what':<46} {'size':>16} {'time [s]':>9} {'throughput':>18} {'ratio':>7}")
    for what, size, seconds, rate in rows:
        print(f"{what:<46} {size:>16} {seconds:>9.2f} {rate:>18} {seconds / baseline:>7.2f}")


if __name__ == "__main__":
    main()
