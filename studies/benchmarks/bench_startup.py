"""How long a command takes to start: fresh interpreters, as a user's shell runs them.

Each row runs one command in a new Python process, `repeat` times, alternating with its
baseline, and prints the median wall time.  The baseline is the same command with the
libraries that rvte now imports on first use imported up front, as the command did
before: scipy.optimize (the lubricant's ASTM D2270 root, `rvfmu/core/laws/lubricant.py`),
scipy.special (the studies' normal draws, `tolerance/sampling.py`) and SALib's Sobol
analysis with scipy.stats (`tolerance/sobol.py`, which `rvte mc` imported for two
constants).  What each command computes is the same in both: the TE at 36 points, and
quick_mc's first batch of 64 reducers, computed once and then reused, without figures
(the compiled code cached by a first run of each).

Run:  python studies/benchmarks/bench_startup.py [--repeat 7]
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_jobs import machine

ROOT = Path(__file__).resolve().parents[2]
OPTIMIZE_SPECIAL = ("scipy.optimize", "scipy.special")

COMMAND = """
import runpy, sys
for name in sys.argv[1].split():
    __import__(name)
sys.argv = ["rvte", *sys.argv[2:]]
try:
    runpy.run_module("rvfmu.cli", run_name="__main__")
except SystemExit as stop:
    assert not stop.code, stop.code
"""


def jobs(folder: Path) -> tuple:
    """(label, arguments, what the command imported before) of every row."""
    quick_mc = [str(ROOT / "studies" / "quick_mc.toml"), "-n", "64", "--no-plots", "-o", str(folder / "qmc")]
    return (
        ("rvte te RV-40E-121 --points 36", ["te", "RV-40E-121", "--points", "36"], OPTIMIZE_SPECIAL),
        ("rvte presets", ["presets"], OPTIMIZE_SPECIAL),
        (
            "rvte mc studies/quick_mc.toml -n 64 --no-plots, reused",
            ["mc", *quick_mc],
            ("scipy.optimize", "SALib.analyze.sobol"),
        ),
    )


def wall(eager: str, args: list) -> float:
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", COMMAND, eager, *args],
        cwd=ROOT,
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    repeat = parser.parse_args().repeat
    print(f"machine: {machine()}")
    print(f"{'what':<104} {'runs':>5} {'median [s]':>11} {'ratio':>6}")
    with tempfile.TemporaryDirectory(prefix="rvte_bench_startup_") as folder:
        for label, args, eager in jobs(Path(folder)):
            wall("", args)  # the compiled code cached, the batch computed, the files in the page cache
            before, now = [], []
            for _ in range(repeat):
                before.append(wall(" ".join(eager), args))
                now.append(wall("", args))
            base = statistics.median(before)
            for what, times in ((f"{label}, {' and '.join(eager)} up front (before)", before), (label, now)):
                median = statistics.median(times)
                print(f"{what:<104} {len(times):>5} {median:>11.3f} {median / base:>6.2f}")


if __name__ == "__main__":
    main()
