"""The jobs: `run_mc` and `run_sobol`, each a study file in, results and report files out.

Both follow SALib's scheme over the store and a backend: sample the rows,
read and check the batches the output folder holds, compute the missing ones
(each written the moment it is done), analyse all rows, report.  A run that
was killed is simply started again.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rvfmu.core.checks import InputError, integer
from rvfmu.core.errors import error_file_values
from rvfmu.core.quasistatic import TECurve, te_curve

from . import montecarlo, report, sobol
from .backends import make_backend
from .sampling import errors_from_unit
from .store import BatchResult, JobStore, open_output
from .study import Study, load_study, sobol_base_samples


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

    @property
    def rate(self) -> float:
        """Reducers computed per second of this run (0 if none were computed)."""
        return self.computed_rows / self.seconds if self.computed_rows and self.seconds > 0 else 0.0

    def summary(self, job: str) -> str:
        rate = f", {self.rate:.1f} reducers/s" if self.computed else ""
        return (f"{job}: {self.batches} batches ({self.reused} reused, {self.computed} computed) "
                f"for {self.Y.shape[0]} reducers in {self.seconds:.1f} s{rate} on {self.backend}")


def compute(study: Study, job: str, n_rows: int, rows, backend=None, progress: bool | None = False,
            log=None, output: Path | None = None) -> Computed:
    """Metrics of rows [0, n_rows) of `job`, reusing the batches already in the output folder.

    rows(start, stop) -> (stop - start, D) sample rows.  Batches are the
    study's batch_size rows each, at fixed boundaries.
    """
    backend = backend or make_backend()
    folder = open_output(study, output)
    store = JobStore(folder, study, job)
    B = study.batch_size
    batches = [(s, min(s + B, n_rows)) for s in range(0, n_rows, B)]
    done = store.load(batches, rows)
    missing = [b for b in batches if b not in done]
    todo_rows = sum(stop - start for start, stop in missing)
    start_time = time.perf_counter()
    if missing:
        bar = _progress_bar(todo_rows, job, progress, len(done))
        try:
            with backend:
                tasks = ((b, rows(*b)) for b in missing)
                for (s, e), X, Y, conv in backend.map(study, tasks):
                    store.write(s, e, X, Y, conv)
                    done[(s, e)] = BatchResult(s, e, Y, conv)
                    if bar is not None:
                        bar.update(e - s)
        finally:
            if bar is not None:
                bar.close()
    seconds = time.perf_counter() - start_time
    Y = np.concatenate([done[b].Y for b in batches]) if batches else \
        np.empty((0, len(study.metrics)))
    converged = np.concatenate([done[b].converged for b in batches]) if batches else \
        np.empty(0, dtype=bool)
    result = Computed(Y, converged, len(batches), len(batches) - len(missing), len(missing),
                      todo_rows, seconds, backend.describe())
    if log is not None:
        log(result.summary(job))
    return result


def _progress_bar(total, job, progress, reused):
    if progress is False:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="reducer", desc=job, file=sys.stderr, dynamic_ncols=True,
                disable=None if progress is None else not progress,
                postfix={"reused batches": reused} if reused else None)


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
    files: dict = field(default_factory=dict)

    def table(self) -> str:
        return report.mc_table(self.study, self.analysis)

    def to_json(self) -> dict:
        return report.mc_json(self.study, self.analysis, {
            "output": str(self.study.output), "files": {k: str(v) for k, v in self.files.items()},
            "run": {"batches": self.computed.batches, "reused": self.computed.reused,
                    "computed": self.computed.computed, "seconds": self.computed.seconds,
                    "backend": self.computed.backend}})


def run_mc(study_path, n: int | None = None, *, output=None, processes: int | None = None,
           workers: int | None = None, scheduler: str | None = None, progress: bool | None = False,
           plots: bool = True, log=None) -> MCResult:
    """Monte Carlo of a study file: n reducers (default: the study's [montecarlo] n).

    Backends: none of processes/workers/scheduler -> in-process; processes=k ->
    k local worker processes; workers=k -> a Dask LocalCluster of k workers;
    scheduler="tcp://host:port" -> that Dask cluster.  Writes to the study's
    output folder (or `output`): the batches, mc_summary.json, mc_samples.csv,
    mc_distribution.png, and the worst reducer's TE curve (mc_worst_te.png /
    .csv) and error file (mc_worst_errors.toml).  log(str) receives the
    one-line run summary.
    """
    study = _load(study_path, output)
    n = study.mc_n if n is None else integer("n", n, 1)
    # Whole batches are computed so that a later, larger n reuses every batch as it is.
    n_rows = math.ceil(n / study.batch_size) * study.batch_size
    computed = compute(study, "mc", n_rows, lambda s, e: montecarlo.rows(study, s, e),
                       make_backend(processes, workers, scheduler), progress, log)
    Y, converged = computed.Y[:n], computed.converged[:n]
    analysis = montecarlo.analyze(study, Y, converged)
    worst_curve = _worst_curve(study, analysis.worst)
    folder = Path(study.output)
    files = {"summary": folder / "mc_summary.json", "samples": folder / "mc_samples.csv",
             "worst_errors": folder / "mc_worst_errors.toml"}
    _write_samples(files["samples"], study, Y, converged)
    worst_errors = errors_from_unit(study, montecarlo.rows(study, analysis.worst, analysis.worst + 1))
    files["worst_errors"].write_text(report.error_file_text(
        error_file_values(worst_errors),
        f"Worst reducer (row {analysis.worst}) of study {study.name!r}, by {analysis.worst_column}.\n"
        f"Reproduce: rvte te {study.design_source or study.design.name} --errors {files['worst_errors']}"
        f" --load {study.load_Nm:g} --points {study.points}"))
    if worst_curve is not None:
        from rvfmu.api import write_te_csv

        files["worst_te_csv"] = write_te_csv(worst_curve, folder / "mc_worst_te.csv")
    if plots:
        files["distribution"] = report.plot_mc(study, Y, analysis, folder / "mc_distribution.png")
        if worst_curve is not None:
            from rvfmu.plots import plot_te

            files["worst_te"] = plot_te(worst_curve, folder / "mc_worst_te.png", title=(
                f"{study.name}: worst of {n} reducers (row {analysis.worst}), "
                f"te_pp {worst_curve.te_pp_arcsec[0]:.2f}″, {study.points} points/rev"))
    result = MCResult(study, n, Y, converged, analysis, worst_curve, computed, files)
    report.write_json(files["summary"], result.to_json())
    return result


def _worst_curve(study: Study, row: int) -> TECurve | None:
    """The TE curve of Monte Carlo row `row`, at the study's operating point."""
    errors = errors_from_unit(study, montecarlo.rows(study, row, row + 1))
    try:
        return te_curve(study.design, errors, tau_load=-study.load_Nm, points=study.points)
    except np.linalg.LinAlgError:
        return None


def _write_samples(path: Path, study: Study, Y, converged) -> None:
    header = ",".join(("row",) + study.metric_columns + ("converged",))
    with open(path, "w") as handle:
        handle.write(header + "\n")
        for r in range(Y.shape[0]):
            values = ",".join(f"{v:.6g}" for v in Y[r])
            handle.write(f"{r},{values},{int(converged[r])}\n")


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
    files: dict = field(default_factory=dict)

    def table(self) -> str:
        return report.sobol_table(self.study, self.analyses, self.n, self.Y.shape[0],
                                  self.second_order)

    def to_json(self) -> dict:
        return report.sobol_json(self.study, self.analyses, self.n, self.Y.shape[0],
                                 self.second_order, {
                                     "output": str(self.study.output),
                                     "files": {k: str(v) for k, v in self.files.items()},
                                     "run": {"batches": self.computed.batches,
                                             "reused": self.computed.reused,
                                             "computed": self.computed.computed,
                                             "seconds": self.computed.seconds,
                                             "backend": self.computed.backend}})


def sobol_job(n: int, second_order: bool) -> str:
    """Name of the job folder: its rows depend on n and on second order."""
    return f"sobol-n{n}" + ("-second-order" if second_order else "")


def run_sobol(study_path, n: int | None = None, *, second_order: bool | None = None, output=None,
              processes: int | None = None, workers: int | None = None,
              scheduler: str | None = None, progress: bool | None = False, plots: bool = True,
              log=None) -> SobolResult:
    """Sobol indices of every metric of a study file over its tolerance factors.

    n: base samples (a power of 2; default the study's [sobol] n); the model
    runs n * (G + 2) times, or n * (2G + 2) with second_order, G factors.
    Backends as for `run_mc`.  Writes sobol_indices.json, sobol_ranking.txt,
    sobol_bars.png and sobol_convergence.png to the output folder.
    """
    study = _load(study_path, output)
    n = study.sobol_n if n is None else sobol_base_samples("n", n)
    second_order = study.second_order if second_order is None else bool(second_order)
    problem = study.problem()
    X = sobol.sample(problem, n, second_order, seed=study.seed)
    computed = compute(study, sobol_job(n, second_order), X.shape[0], lambda s, e: X[s:e],
                       make_backend(processes, workers, scheduler), progress, log)
    bad = np.flatnonzero(~np.all(np.isfinite(computed.Y), axis=1))
    if bad.size:
        raise RuntimeError(f"the model failed on {bad.size} of {X.shape[0]} Sobol rows (first: row "
                           f"{bad[0]}); Sobol indices need every row: check the tolerances")
    analyses = sobol.analyze(problem, computed.Y, study.metric_columns, second_order,
                             study.resamples, study.sobol_confidence, study.seed)
    folder = Path(study.output)
    files = {"indices": folder / "sobol_indices.json", "ranking": folder / "sobol_ranking.txt"}
    if plots:
        files["bars"] = report.plot_sobol(study, analyses, folder / "sobol_bars.png")
        files["convergence"] = report.plot_convergence(study, analyses,
                                                       folder / "sobol_convergence.png")
    result = SobolResult(study, n, second_order, X, computed.Y, analyses, computed, files)
    files["ranking"].write_text(result.table() + "\n")
    report.write_json(files["indices"], result.to_json())
    return result


def _load(study_path, output) -> Study:
    if isinstance(study_path, Study):
        if output is None:
            return study_path
        from dataclasses import replace

        return replace(study_path, output=Path(output))
    if not isinstance(study_path, (str, Path)):
        raise InputError("study", study_path, "must be a study file path or a Study")
    return load_study(study_path, output)
