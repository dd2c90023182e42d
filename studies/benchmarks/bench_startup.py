"""How long a command takes to start: fresh interpreters, as a user's shell runs them.

Each row runs one command in a new Python process, `repeat` times, alternating with its
baseline, and prints the median wall time.  The baseline is the same command with the
libraries that rvte now imports on first use imported up front, as every command did
before: scipy.optimize (the lubricant's ASTM D2270 root, `rvfmu/core/laws/lubricant.py`)
and scipy.special (the studies' normal draws, `tolerance/sampling.py`).  What the TE
command itself computes is the same in both (36 points; the compiled code cached by a
first run of each).

Run:  python studies/benchmarks/bench_startup.py [--repeat 7]
"""

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench_jobs import machine

ROOT = Path(__file__).resolve().parents[2]
EAGER = ("scipy.optimize", "scipy.special")

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

JOBS = (
    ("rvte te RV-40E-121 --points 36", ["te", "RV-40E-121", "--points", "36"]),
    ("rvte presets", ["presets"]),
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
    print(f"{'what':<76} {'runs':>5} {'median [s]':>11} {'ratio':>6}")
    for label, args in JOBS:
        wall("", args)  # the compiled code cached, the files in the page cache
        before, now = [], []
        for _ in range(repeat):
            before.append(wall(" ".join(EAGER), args))
            now.append(wall("", args))
        base = statistics.median(before)
        for what, times in ((f"{label}, {' and '.join(EAGER)} up front (before)", before), (label, now)):
            median = statistics.median(times)
            print(f"{what:<76} {len(times):>5} {median:>11.3f} {median / base:>6.2f}")


if __name__ == "__main__":
    main()
