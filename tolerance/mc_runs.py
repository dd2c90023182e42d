"""The Monte Carlo job, `run_mc`: a study file in, the yield, the distributions, the worst
reducer and their files out, computed by `run.compute` over the store and a backend, with
the aliasing check where the study's points do not resolve the pin-passing order."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rvfmu.core.base.checks import integer
from rvfmu.core.reducer.errors import error_file_values, toml_text
from rvfmu.core.statics.quasistatic import TECurve, te_curve

from . import aliasing, frames, montecarlo, run, summaries
from .backends import make_backend
from .run import Computed, _flags, _load, _warn_load
from .sampling import errors_from_unit
from .study import Study


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
    computed = run.compute(
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
