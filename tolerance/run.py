"""What the jobs share: `compute`, the batch loop of `run_mc` (tolerance/mc_runs.py),
`run_sobol` (tolerance/sobol_runs.py), the allocation's Monte Carlo runs and the
linearized method's solves, each a study file in and its stored batches out.

It follows SALib's scheme over the store and a backend: sample the rows,
read and check the batches the output folder holds, compute the missing ones
(each written the moment it is done), analyse all rows, report.  A run that
was killed is simply started again.

Before the bulk of the work, the first missing batch is computed and timed:
a run estimated above a day, or above the free disk, stops there unless told
`yes` (`compute`).  A study whose points do not resolve the pin-passing order
recomputes a few of its reducers at full resolution and reports how much that
moves its answers (`aliasing`).
"""

from __future__ import annotations

import shutil
import sys
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rvfmu.core.base.checks import InputError, fits_in_memory
from rvfmu.outputs import output_folder

from . import sobol
from .backends import make_backend
from .error_rows import ErrorRows
from .store import BatchResult, JobStore, open_output
from .study import Study, flag, load_study


@dataclass(frozen=True)
class Computed:
    """Metrics of every row of a job: Y (rows, M), converged (rows,), and what the run did."""

    Y: np.ndarray
    converged: np.ndarray
    batches: int
    reused: int
    computed: int
    computed_rows: int
    seconds: float
    backend: str
    batch_size: int = 0

    @property
    def rate(self) -> float:
        """Reducers computed per second of this run (0 if none were computed)."""
        return self.computed_rows / self.seconds if self.computed_rows and self.seconds > 0 else 0.0

    def summary(self, job: str) -> str:
        """One line: reducers, batches, reused and computed, wall time [s], rate and backend."""
        rate = f", {self.rate:.1f} reducers/s" if self.computed else ""
        return (
            f"{job}: {self.Y.shape[0]} reducers in {self.batches} batches of "
            f"{self.batch_size} ({self.reused} reused, {self.computed} computed) "
            f"in {self.seconds:.1f} s{rate} on {self.backend}"
        )


# Set by the command line's Ctrl-C handler (tolerance/cli.py) beside the KeyboardInterrupt it
# raises: Python only prints an interrupt that lands in a garbage-collector callback or a
# __del__ (Dask's scheduler runs one on every collection), so `compute` also stops at the
# next finished batch when this is set.
STOP = threading.Event()

DAY_SECONDS = 86400.0  # a run estimated above a day needs --yes
DISK_MARGIN = 1.1  # store size + 10 % must fit in the free space without --yes


@dataclass(frozen=True)
class RunPlan:
    """What a job will cost, estimated from the first batch it computed.

    seconds_first: wall time of that batch on one worker; bytes_first: its file size.
    """

    job: str
    rows: int
    batches: int
    missing: int
    batch_size: int
    workers: int
    backend: str
    seconds_first: float
    bytes_first: int
    free_bytes: int

    @property
    def seconds(self) -> float:
        """Estimated wall time of the batches still to compute after the first [s]."""
        return self.seconds_first * (self.missing - 1) / max(1, self.workers)

    @property
    def store_bytes(self) -> int:
        """Estimated disk taken by the batches still to write [bytes]."""
        return self.bytes_first * (self.missing - 1)

    def text(self) -> str:
        """One line: the evaluations still to compute, the estimated time and the store's size
        against the free disk space."""
        return (
            f"{self.job}: {self.rows} evaluations in {self.batches} batches of "
            f"{self.batch_size} ({self.missing} to compute); first batch "
            f"{self.seconds_first:.2f} s -> about {duration_text(self.seconds)} more on "
            f"{self.backend}; the store takes about {size_text(self.store_bytes)} more "
            f"({size_text(self.free_bytes)} free)"
        )

    def refusal(self) -> str | None:
        """Why this run should not start without confirmation, or None."""
        reasons = []
        if self.seconds > DAY_SECONDS:
            reasons.append(f"would take about {duration_text(self.seconds)} on {self.backend}")
        if self.store_bytes * DISK_MARGIN > self.free_bytes:
            reasons.append(
                f"would write about {size_text(self.store_bytes)} with "
                f"{size_text(self.free_bytes)} free on the output's disk"
            )
        if not reasons:
            return None
        return (
            f"{self.rows} evaluations " + " and ".join(reasons) + " (estimated from the first "
            f"batch of {self.batch_size}: {self.seconds_first:.2f} s, "
            f"{size_text(self.bytes_first)}); give --yes to run it anyway, or ask for fewer"
        )


def duration_text(seconds: float) -> str:
    """A duration in seconds as text in the largest unit it reaches: "12 s", "3.5 min",
    "2.0 h", "1.5 days", "1.1 years"."""
    for unit, size in (("years", 365.25 * DAY_SECONDS), ("days", DAY_SECONDS), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit}"
    return f"{seconds:.0f} s"


def size_text(size: float) -> str:
    """A size in bytes as text in the largest decimal unit it reaches: "512 B" to "1.2 TB"."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.1f} {unit}"
    return f"{size:.0f} B"


def compute(
    study: Study,
    job: str,
    n_rows: int,
    rows,
    backend=None,
    progress: bool | None = False,
    log=None,
    output: Path | None = None,
    yes: bool = False,
    size_field: tuple[str, int] | None = None,
    prefix_jobs=(),
    columns: tuple | None = None,
    like=None,
) -> Computed:
    """Metrics of rows [0, n_rows) of `job`, reusing the batches already in the output folder.

    rows(start, stop) -> (stop - start, D) sample rows.  Batches are the
    study's batch_size rows each, at fixed boundaries.  prefix_jobs: (job,
    rows) of other jobs whose first `rows` rows are the first rows of this
    one's (Sobol' runs at other n): their finished batches are checked against
    this job's rows and copied in, not recomputed.  like: rows are error vectors
    (`error_rows.ErrorRows` of this one-reducer ErrorSet's layout), and the job stores the
    model's outputs in `columns` instead of the metrics.  The first missing
    batch is computed and timed before the others: a run estimated above a day,
    or above the free disk, stops there with an InputError on `size_field`
    (name, value) unless `yes`.  log(str) gets the estimate and the summary.
    """
    backend = backend or make_backend()
    folder = open_output(study, output)
    store = JobStore(folder, study, job)
    if columns is not None:
        store.columns = tuple(columns)
    task = (lambda X: X) if like is None else (lambda X: ErrorRows(X, like))
    B = study.batch_size
    n_batches = -(-n_rows // B)
    done = store.load(n_rows, rows)
    for other, other_rows in prefix_jobs:
        if (folder / other).is_dir():
            _copy_prefix(JobStore(folder, study, other), store, min(other_rows, n_rows), rows, done)
    missing = n_batches - len(done)
    todo_rows = n_rows - sum(r.stop - r.start for r in done.values())
    start_time = time.perf_counter()
    if missing:
        gaps = (b for b in _batches(n_rows, B) if b not in done)
        bar = None
        with backend:
            first = next(gaps)
            clock = time.perf_counter()
            for (s, e), X, Y, conv in backend.map(study, iter([(first, task(rows(*first)))])):
                written = store.write(s, e, _raw(X), Y, conv)
                done[(s, e)] = BatchResult(s, e, Y, conv)
            _stop_if_asked()
            plan = RunPlan(
                job,
                n_rows,
                n_batches,
                missing,
                B,
                backend.workers,
                backend.describe(),
                time.perf_counter() - clock,
                written.stat().st_size,
                shutil.disk_usage(folder).free,
            )
            if log is not None:
                log(plan.text())
            refusal = plan.refusal()
            if refusal and not yes:
                name, value = size_field or ("n", n_rows)
                raise InputError(name, value, refusal)
            bar = _progress_bar(todo_rows, job, progress, len(done))
            try:
                if bar is not None:
                    bar.update(first[1] - first[0])
                tasks = ((b, task(rows(*b))) for b in gaps)
                for (s, e), X, Y, conv in backend.map(study, tasks):
                    store.write(s, e, _raw(X), Y, conv)
                    done[(s, e)] = BatchResult(s, e, Y, conv)
                    if bar is not None:
                        bar.update(e - s)
                    _stop_if_asked()
            finally:
                if bar is not None:
                    bar.close()
    seconds = time.perf_counter() - start_time
    batches = list(_batches(n_rows, B))
    Y = np.concatenate([done[b].Y for b in batches]) if batches else np.empty((0, len(study.metrics)))
    converged = np.concatenate([done[b].converged for b in batches]) if batches else np.empty(0, dtype=bool)
    result = Computed(
        Y, converged, n_batches, n_batches - missing, missing, todo_rows, seconds, backend.describe(), B
    )
    if log is not None:
        log(result.summary(job))
    return result


def _raw(X) -> np.ndarray:
    """The array of a batch's rows: sample rows, or the error vectors of `ErrorRows`."""
    return X.vectors if isinstance(X, ErrorRows) else X


def _stop_if_asked() -> None:
    """Raise the KeyboardInterrupt of a Ctrl-C that Python swallowed (`STOP`)."""
    if STOP.is_set():
        raise KeyboardInterrupt


def _copy_prefix(source: JobStore, target: JobStore, n_rows: int, rows, done: dict) -> None:
    """Copy into `target` the whole batches of `source` below n_rows that `done` lacks.

    Each is read through the store's checks against this job's own rows, so a
    batch of other rows, or of another study or model, is refused as usual.
    """
    size = target.study.batch_size
    whole = n_rows - n_rows % size
    try:
        found = source.load(whole, rows)
    except InputError:
        return  # not a prefix after all, or a damaged file: this job computes its own
    for (start, stop), result in sorted(found.items()):
        if (start, stop) not in done:
            target.write(start, stop, rows(start, stop), result.Y, result.converged)
            done[(start, stop)] = result


def _batches(n_rows: int, size: int):
    """(start, stop) of the batches of rows [0, n_rows): `size` rows each, the last maybe fewer."""
    return ((start, min(start + size, n_rows)) for start in range(0, n_rows, size))


def _progress_bar(total, job, progress, reused):
    if progress is False:
        return None
    from tqdm import tqdm

    return tqdm(
        total=total,
        unit="reducer",
        desc=job,
        file=sys.stderr,
        dynamic_ncols=True,
        disable=None if progress is None else not progress,
        postfix={"reused batches": reused} if reused else None,
    )


def stored_batches(study_path, output=None, job: str | None = None) -> int:
    """Batch files the output folder of a study holds: those of `job` ("mc", "sobol-n1024",
    ...), or with None every batch under the folder (an allocation's Monte Carlo runs and
    training groups too).  What a run interrupted by Ctrl-C keeps for the next one, which
    reads them instead of computing them again; 0 if the folder does not exist yet."""
    folder = Path(_load(study_path, output).output)
    where = folder / job if job is not None else folder
    if not where.is_dir():
        return 0
    return sum(1 for _ in where.rglob("batch-*-*-*.parquet"))


def _check_sample_memory(problem: dict, n: int, second_order: bool) -> None:
    """Refuse a Sobol n whose sample matrix alone would not fit in memory (no --yes helps)."""
    rows = n * sobol.rows_per_base_sample(problem, second_order)
    fits_in_memory(
        "n", n, rows * problem["num_vars"] * 8, f"gives {rows} Sobol rows whose sample matrix alone"
    )


def _flags(progress, plots, yes) -> tuple:
    """The boolean keywords of run_mc and run_sobol, checked (progress may be None: automatic)."""
    return flag("progress", progress, none=True), flag("plots", plots), flag("yes", yes)


def _warn_load(study: Study, log) -> None:
    for warning in study.operating_warnings if log is not None else ():
        log(f"warning: {warning}")


def _load(study_path, output) -> Study:
    """The study (a file or a Study), with `output` as its folder if given; the folder checked."""
    if isinstance(study_path, Study):
        study = study_path if output is None else replace(study_path, output=Path(output))
    elif isinstance(study_path, (str, Path)):
        study = load_study(study_path, output)
    else:
        raise InputError("study", study_path, "must be a study file path or a Study")
    output_folder("output", study.output)
    return study
