"""Progress reporting shared by the jobs and the command line.

The jobs (`rvfmu.api`, `rvfmu.fmu.api`) report progress as calls
progress(total, done); `ProgressCounter` turns the solver's per-chunk counts
into such calls, and `ProgressBar` shows them as a tqdm bar on stderr.  Both
live here, below the CLI modules, so that every command can use them without
one CLI module importing another.
"""

from __future__ import annotations

import sys


class ProgressCounter:
    """Turns the solver's per-chunk counts into progress(total, done) calls."""

    def __init__(self, total, report):
        self.total, self.done, self.report = total, 0, report

    def __call__(self, count):
        self.done += count
        self.report(self.total, self.done)


def counter(total, progress):
    """A `ProgressCounter` over `progress`, or None when no progress is wanted."""
    return None if progress is None else ProgressCounter(total, progress)


class ProgressBar:
    """A tqdm bar on stderr for progress(total, done) callbacks; silent when not a terminal."""

    def __init__(self, description, unit="pose"):
        self.description, self.unit, self.bar = description, unit, None

    def __call__(self, total, done):
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total,
                desc=self.description,
                unit=self.unit,
                file=sys.stderr,
                disable=None,
                dynamic_ncols=True,
                leave=False,
            )
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
