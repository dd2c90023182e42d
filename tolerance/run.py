"""The jobs: `run_mc` and `run_sobol`, each a study file in, results and report files out.

Both follow SALib's scheme over the store and a backend: sample the rows,
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

import math
import shutil
import sys
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rvfmu.core.base.checks import InputError, fits_in_memory, integer
from rvfmu.core.reducer.errors import error_file_values, toml_text
from rvfmu.core.statics.quasistatic import TECurve, te_curve
from rvfmu.outputs import output_folder

from . import aliasing, frames, linearized, montecarlo, sobol, summaries
from .backends import make_backend
from .error_rows import ErrorRows
from .sampling import errors_from_unit
from .store import BatchResult, JobStore, open_output
from .study import Study, check_sobol_method, flag, load_study, sobol_base_samples


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


# -- Monte Carlo ------------------------------------------------------------------------------


@dataclass(frozen=True)
class MCResult:
    """A Monte Carlo study: the metrics of every reducer, their analysis and the files written.

    Y: (n, M) in the study's metric columns; converged: (n,); worst_curve: the
    TE curve of the worst reducer (`analysis.worst`).
    """

    study: Study
    n: int
    Y: np.ndarray
    converged: np.ndarray
    analysis: montecarlo.MCAnalysis
    worst_curve: TECurve | None
    computed: Computed
    aliasing: aliasing.AliasingCheck | None = None
    files: dict = field(default_factory=dict)

    def table(self) -> str:
        """The printed summary: per metric the distribution, the yields, warnings and the
        aliasing check (`summaries.mc_table`)."""
        return summaries.mc_table(self.study, self.analysis, self.computed, self.aliasing)

    def to_df(self, errors: bool = False):
        """One row per reducer as a pandas DataFrame, indexed by its row in the sample ("row"):
        each factor's drawn value [um] (e.g. crank_cam_eccentricity_position_um), with
        `errors` every drawn error (NAME[i,j].E_um, NAME[i,j].beta_deg, NAME[k]_um), the
        metric columns, converged, and with a spec passed_<column> per line and passed
        (nullable booleans, NA for a failed reducer).  See tolerance/frames.py."""
        return frames.mc_frame(self.study, self.Y, self.converged, errors)

    def to_json(self) -> dict:
        """The JSON summary (`summaries.mc_json`) with the run's rows, batches, timings,
        backend, aliasing check and the files written."""
        return summaries.mc_json(
            self.study,
            self.analysis,
            {
                "computed_rows": int(self.computed.Y.shape[0]),
                "batch_size": self.study.batch_size,
                "aliasing": None if self.aliasing is None else self.aliasing.to_json(),
                "output": str(self.study.output),
                "files": {k: str(v) for k, v in self.files.items()},
                "run": {
                    "batches": self.computed.batches,
                    "reused": self.computed.reused,
                    "computed": self.computed.computed,
                    "seconds": self.computed.seconds,
                    "backend": self.computed.backend,
                },
            },
        )


def run_mc(
    study_path,
    n: int | None = None,
    *,
    output=None,
    processes: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | None = False,
    plots: bool = True,
    log=None,
    yes: bool = False,
) -> MCResult:
    """Monte Carlo of a study file: n reducers (default: the study's [montecarlo] n).

    Rows are computed in whole batches (n rounded up to a multiple of the batch
    size, so that a later, larger n reuses every batch); the first n are analysed.
    Backends: none of processes/workers/scheduler -> in-process; processes=k ->
    k local worker processes; workers=k -> a Dask LocalCluster of k workers;
    scheduler="tcp://host:port" -> that Dask cluster.  Writes to the study's
    output folder (or `output`): the batches, mc_summary.json, mc_samples.csv,
    the worst reducer's error file (mc_worst_errors.toml) and TE curve
    (mc_worst_te.csv), and with `plots` mc_distribution.png and mc_worst_te.png.
    If the study aliases, its first aliasing.CHECK_ROWS reducers are recomputed
    at full resolution (`aliasing.check`).  log(str) receives the load warning,
    the cost estimate and the one-line run summary; a run estimated above a day
    or above the free disk stops after its first batch unless `yes` (see `compute`).
    """
    progress, plots, yes = _flags(progress, plots, yes)
    study = _load(study_path, output)
    n = study.mc_n if n is None else integer("n", n, 1)
    backend = make_backend(processes, workers, scheduler)  # its options checked before any work
    _warn_load(study, log)
    # Whole batches are computed so that a later, larger n reuses every batch as it is.
    n_rows = math.ceil(n / study.batch_size) * study.batch_size
    computed = compute(
        study,
        "mc",
        n_rows,
        lambda s, e: montecarlo.rows(study, s, e),
        backend,
        progress,
        log,
        yes=yes,
        size_field=("n", n),
    )
    Y, converged = computed.Y[:n], computed.converged[:n]
    analysis = montecarlo.analyze(study, Y, converged)
    check_rows = min(n, aliasing.CHECK_ROWS)
    alias = aliasing.check(
        study, montecarlo.rows(study, 0, check_rows), Y[:check_rows], Path(study.output) / "mc", Y, study.spec
    )
    worst_curve = _worst_curve(study, analysis.worst)
    folder = Path(study.output)
    files = {
        "summary": folder / "mc_summary.json",
        "samples": folder / "mc_samples.csv",
        "worst_errors": folder / "mc_worst_errors.toml",
    }
    frames.write_samples(files["samples"], frames.mc_frame(study, Y, converged), study)
    worst_errors = errors_from_unit(study, montecarlo.rows(study, analysis.worst, analysis.worst + 1))
    files["worst_errors"].write_text(
        toml_text(
            error_file_values(worst_errors),
            f"Worst reducer (row {analysis.worst}) of study {study.name!r}, by {analysis.worst_column}.\n"
            f"Reproduce: rvte te {study.design_source or study.design.name} --errors {files['worst_errors']}"
            f" --load {study.load_Nm:g} --points {study.points}",
        )
    )
    if worst_curve is not None:
        from rvfmu.api import write_te_csv

        files["worst_te_csv"] = write_te_csv(worst_curve, folder / "mc_worst_te.csv")
    if plots:
        files["distribution"] = summaries.plot_mc(study, Y, analysis, folder / "mc_distribution.png")
        if worst_curve is not None:
            from rvfmu.plots import plot_te

            files["worst_te"] = plot_te(
                worst_curve,
                folder / "mc_worst_te.png",
                title=(
                    f"{study.name}: worst of {n} reducers (row {analysis.worst}), "
                    f"te_pp {worst_curve.te_pp_arcsec[0]:.2f}″, {study.points} points/rev"
                ),
            )
    result = MCResult(study, n, Y, converged, analysis, worst_curve, computed, alias, files)
    summaries.write_json(files["summary"], result.to_json())
    return result


def _worst_curve(study: Study, row: int) -> TECurve | None:
    """The TE curve of Monte Carlo row `row`, at the study's operating point."""
    errors = errors_from_unit(study, montecarlo.rows(study, row, row + 1))
    try:
        return te_curve(study.design, errors, tau_load=-study.load_Nm, points=study.points)
    except np.linalg.LinAlgError:
        return None


# -- Sobol ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SobolResult:
    """A Sobol study: the sample, the outputs, the indices of every metric and the files written."""

    study: Study
    n: int
    second_order: bool
    X: np.ndarray
    Y: np.ndarray
    analyses: dict
    computed: Computed
    aliasing: aliasing.AliasingCheck | None = None
    files: dict = field(default_factory=dict)
    method: str = "saltelli"
    check: linearized.Check | None = None
    rounds: tuple = ()

    def table(self) -> str:
        """The printed summary: the indices of every metric (`summaries.sobol_table`), then the
        linearized check, the rounds and the aliasing check where they exist."""
        text = summaries.sobol_table(self.study, self.analyses, self.n, self.Y.shape[0], self.second_order)
        lines = [
            text,
            *(self.check.lines() if self.check is not None else ()),
            *(r.text(self.method) for r in self.rounds),
        ]
        return "\n".join([*lines, *(self.aliasing.lines() if self.aliasing else ())])

    def to_df(self, second_order: bool = False):
        """The indices as a long pandas DataFrame, one row per (metric, factor), each metric's
        factors by rank: metric, factor, rank, S1, S1_conf, ST, ST_conf, S1_reported,
        ST_reported, not_converged, ci_wide, S1_above_ST, notes, ranking_converged
        (`frames.sobol_frame`).  second_order: the S2 of every pair instead (metric,
        factor_a, factor_b, S2, S2_conf), for a run that computed them."""
        if not flag("second_order", second_order):
            return frames.sobol_frame(self.analyses)
        if not self.second_order:
            raise InputError(
                "second_order",
                True,
                "this Sobol run computed no second-order "
                "indices: run it with second_order=True (rvte sobol --second-order)",
            )
        return frames.s2_frame(self.analyses)

    def to_json(self) -> dict:
        """The JSON summary (`summaries.sobol_json`) with the method, rounds, checks, the
        files written and the run's batches, timings and backend."""
        return summaries.sobol_json(
            self.study,
            self.analyses,
            self.n,
            self.Y.shape[0],
            self.second_order,
            {
                "method": self.method,
                "rounds": [r.to_json() for r in self.rounds],
                "linearized_check": None if self.check is None else self.check.to_json(),
                "aliasing": None if self.aliasing is None else self.aliasing.to_json(),
                "output": str(self.study.output),
                "files": {k: str(v) for k, v in self.files.items()},
                "run": {
                    "batches": self.computed.batches,
                    "reused": self.computed.reused,
                    "computed": self.computed.computed,
                    "seconds": self.computed.seconds,
                    "backend": self.computed.backend,
                },
            },
        )


def sobol_job(n: int, second_order: bool) -> str:
    """Name of the job folder: its rows depend on n and on second order."""
    return f"sobol-n{n}" + ("-second-order" if second_order else "")


def other_sobol_jobs(problem: dict, n: int, second_order: bool) -> list:
    """(job, rows) of the study's Sobol' runs at every other n, for `compute`'s prefix_jobs.

    A scrambled Sobol' sequence of n points begins with the one of n/2: a run
    that raises n (the convergence check asks for it) reuses the smaller runs'
    reducers, and a run that lowers it (a quick look, a comparison) the larger
    runs' first rows.
    """
    per_base = sobol.rows_per_base_sample(problem, second_order)
    return [(sobol_job(m, second_order), m * per_base) for m in (1 << k for k in range(31)) if m != n]


def run_sobol(
    study_path,
    n: int | None = None,
    *,
    second_order: bool | None = None,
    output=None,
    processes: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | None = False,
    plots: bool = True,
    log=None,
    yes: bool = False,
    method: str | None = None,
    solved_n: int | None = None,
    rounds: bool | None = None,
) -> SobolResult:
    """Sobol indices of every metric of a study file over its tolerance factors.

    n: base samples (a power of 2; default the study's [sobol] n); with
    method "saltelli" (the reference) the model runs n * (G + 2) times, or
    n * (2G + 2) with second_order, G Sobol groups (one per factor unless
    factors share a `group`).  With method "linearized" it runs 2A + 1 times
    for the study's A error components plus Saltelli's design of `solved_n` base samples (default the study's
    [sobol] solved_n), which corrects and checks it; the design of n is
    evaluated on it, and a metric whose check fails gets its indices from the
    whole design solved (`tolerance.linearized`).  Default: the study's
    [sobol] method.  rounds (default the study's [sobol] rounds): start at
    ROUND_START base samples (Saltelli's n, or the linearized method's solved
    ones) and double them, reusing every reducer solved, until the order
    groups of every metric are those of the two rounds before (and every
    check passed), or n (resp. solved_n) is reached.  An n
    whose sample matrix would not fit in memory is refused, `yes` or not.
    Backends, the cost estimate, `yes`, `log` and the aliasing check as for
    `run_mc`.  Writes sobol_indices.json and sobol_ranking.txt, and with
    `plots` sobol_bars.png and sobol_convergence.png, to the output folder.
    """
    progress, plots, yes = _flags(progress, plots, yes)
    second_order = flag("second_order", second_order, none=True)
    study = _load(study_path, output)
    n = study.sobol_n if n is None else sobol_base_samples("n", n)
    method = study.sobol_method if method is None else check_sobol_method("method", method)
    solved_n = study.sobol_solved_n if solved_n is None else sobol_base_samples("solved_n", solved_n)
    rounds = study.sobol_rounds if rounds is None else flag("rounds", rounds)
    second_order = study.second_order if second_order is None else second_order
    backend = make_backend(processes, workers, scheduler)  # its options checked before any work
    _warn_load(study, log)
    problem = study.problem()
    _check_sample_memory(problem, n, second_order)
    start = time.perf_counter()
    if method == "linearized" and study.load_Nm == 0.0 and log is not None:
        log(
            "warning: method linearized at no load: which pins touch depends on the errors, so "
            "its check usually fails there and the run then solves Saltelli's whole design too "
            "(docs/studies.md section 4.6)"
        )
    linear = linearized.linearize(study, backend, progress, log, yes) if method == "linearized" else None
    # the rounds: Saltelli's n, or the linearized method's solved base samples, doubled from
    # ROUND_START until the order groups stop changing or n (the budget) is reached
    last = min(solved_n, n) if linear is not None else n
    sizes = [last]
    if rounds:
        sizes = [size for size in (1 << k for k in range(31)) if ROUND_START <= size < last] + [last]
    history = []
    solved = linear.computed if linear is not None else 0
    for size in sizes:
        estimate = _estimate(
            study,
            problem,
            n if linear is not None else size,
            size,
            linear,
            second_order,
            backend,
            progress,
            log,
            yes,
        )
        groups = {column: a.indices.order_groups() for column, a in estimate[2].items()}
        settled = len(history) >= SETTLED_ROUNDS - 1 and all(
            r.order_groups == groups for r in history[-(SETTLED_ROUNDS - 1) :]
        )
        checks = estimate[4].passed() if estimate[4] is not None else np.ones(1, dtype=bool)
        solved += estimate[3].computed_rows
        history.append(SobolRound(size, solved, groups, settled and bool(np.all(checks))))
        if log is not None and rounds:
            log(history[-1].text(method))
        if history[-1].settled:
            break
    X, n_used, analyses, computed, check, alias_rows = estimate
    computed = replace(computed, computed_rows=solved, seconds=time.perf_counter() - start)
    alias = aliasing.check(study, *alias_rows)
    folder = Path(study.output)
    files = {"indices": folder / "sobol_indices.json", "ranking": folder / "sobol_ranking.txt"}
    if plots:
        files["bars"] = summaries.plot_sobol(study, analyses, folder / "sobol_bars.png")
        files["convergence"] = summaries.plot_convergence(study, analyses, folder / "sobol_convergence.png")
    result = SobolResult(
        study,
        n_used,
        second_order,
        X,
        computed.Y,
        analyses,
        computed,
        alias,
        files,
        method,
        check,
        tuple(history) if rounds else (),
    )
    files["ranking"].write_text(result.table() + "\n")
    summaries.write_json(files["indices"], result.to_json())
    return result


ROUND_START = 64  # base samples of the first round (rounds = true)
SETTLED_ROUNDS = 3  # rounds in a row with the same order groups: settled (two doublings)


@dataclass(frozen=True)
class SobolRound:
    """One round of a Sobol run that stops itself: `size` base samples (Saltelli's n, or
    the linearized method's solved_n), `solved` reducers solved up to it in this run,
    order_groups {column: groups} and whether they settled (the same in SETTLED_ROUNDS
    rounds in a row, every check passed)."""

    size: int
    solved: int
    order_groups: dict
    settled: bool

    def text(self, method: str) -> str:
        """One line: the round's size and solves, the order groups per column and whether they
        settled; `method` names the sample ('linearized' counts solved base samples)."""
        what = "solved base samples" if method == "linearized" else "base samples"
        groups = "; ".join(
            f"{column}: {summaries.order_text(g) if g else '-'}" for column, g in self.order_groups.items()
        )
        return f"round of {self.size} {what} ({self.solved} reducers solved in this run): {groups}" + (
            " -> settled, stop" if self.settled else ""
        )

    def to_json(self) -> dict:
        """The round for the JSON summary: size, solved, order_groups, settled."""
        return {
            "size": self.size,
            "solved": self.solved,
            "order_groups": self.order_groups,
            "settled": self.settled,
        }


def _estimate(study, problem, n, m, linear, second_order, backend, progress, log, yes):
    """(X, n, analyses, computed, check, aliasing rows) of one Sobol estimate: Saltelli's
    design of n base samples solved, or with a linearization (`linear`) evaluated on it and
    corrected by its first m base samples solved; a metric whose check fails gets Saltelli's
    whole design, solved."""
    X = sobol.sample(problem, n, second_order, seed=study.seed)
    job = sobol_job(n, second_order)
    analyses, check = {}, None
    if linear is not None:
        rows_m = m * sobol.rows_per_base_sample(problem, second_order)
        solved = compute(
            study,
            sobol_job(m, second_order),
            rows_m,
            lambda s, e: X[s:e],
            backend,
            progress,
            log,
            yes=yes,
            prefix_jobs=other_sobol_jobs(problem, m, second_order),
        )
        Y = linear.predict(study, X)
        pairs = linearized.independent_rows(problem, rows_m, second_order)
        check = linearized.check(study, solved.Y[pairs], Y[pairs], linear.solves)
        for j, (column, q2) in enumerate(zip(study.metric_columns, check.q2)):
            if q2 >= linearized.Q2_MIN:
                final = linearized.corrected_indices(
                    problem,
                    Y[:, j],
                    solved.Y[:, j],
                    second_order,
                    study.resamples,
                    study.sobol_confidence,
                    study.seed,
                )
                conv = sobol.convergence(
                    problem, Y[:, j], second_order, study.resamples, study.sobol_confidence, study.seed
                )
                analyses[column] = sobol.SobolAnalysis(column, final, conv, "linearized", float(q2))
        computed = replace(solved, Y=Y, converged=np.ones(Y.shape[0], dtype=bool))
        alias_rows = (
            X[: aliasing.CHECK_ROWS],
            solved.Y[: aliasing.CHECK_ROWS],
            Path(study.output) / sobol_job(m, second_order),
        )
    if len(analyses) < len(study.metric_columns):
        computed = compute(
            study,
            job,
            X.shape[0],
            lambda s, e: X[s:e],
            backend,
            progress,
            log,
            yes=yes,
            size_field=("n", n),
            prefix_jobs=other_sobol_jobs(problem, n, second_order),
        )
        bad = np.flatnonzero(~np.all(np.isfinite(computed.Y), axis=1))
        if bad.size:
            raise RuntimeError(
                f"the model failed on {bad.size} of {X.shape[0]} Sobol rows (first: "
                f"row {bad[0]}); Sobol indices need every row: check the tolerances"
            )
        solved_analyses = sobol.analyze(
            problem,
            computed.Y,
            study.metric_columns,
            second_order,
            study.resamples,
            study.sobol_confidence,
            study.seed,
        )
        q2 = dict(zip(study.metric_columns, check.q2)) if check is not None else {}
        analyses = {
            column: analyses.get(column) or replace(result, check_q2=q2.get(column))
            for column, result in solved_analyses.items()
        }
        check_rows = min(X.shape[0], aliasing.CHECK_ROWS)
        alias_rows = (X[:check_rows], computed.Y[:check_rows], Path(study.output) / job)
    return X, n, analyses, computed, check, alias_rows


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
