"""Results of tolerance studies as pandas DataFrames: the tables an engineer analyses in a notebook.

After `rvte mc` or `rvte sobol` the questions are tabular: which reducers
failed and what was drawn for them, does te_pp grow with the cam
eccentricity, which factor tops the ST ranking.  pandas answers them in a line
each, so every result that is a table is handed out as a DataFrame (as
SALib's `ProblemSpec.to_df()` does for its indices):

- `results_frame` / `MCResult.to_df()`: one row per reducer, indexed by its
  row number in the study's sample ("row"): a column per tolerance factor with
  the value drawn for it, in the unit of its tolerance (`factor_column`), the
  metric columns (`Study.metric_columns`, their unit in the name), `converged`
  and, with a spec, `passed_<column>` per spec line and `passed` for all of
  them (pandas' nullable boolean: NA for a reducer whose solve failed, which
  the yield leaves out, so `df["passed"].mean()` is the yield).  With
  `errors=True` also every drawn error (`error_columns`), enough to rebuild
  the reducer without the sample row.
- `load_results(folder, job=None)`: the same table from the batches an output
  folder holds, checked as the commands check them.
- `sobol_frame` / `SobolResult.to_df()`: one row per (metric, factor) with
  S1, ST, their intervals, the rank and the notes' flags; `s2_frame` for
  second-order indices.

A factor's value is the deviation an inspection of that tolerance would
measure, so it lies within the tolerance: a zone's position deviation (2 E,
the diameter, of its worst element), a pitch factor's total cumulative pitch
deviation (the span of its worst sequence), a band's width (twice the largest
|value| of a tooth), a clearance's value.  The reducer is the study's fixed
errors (its `errors` file) plus what the factors drew.

`write_samples` writes mc_samples.csv from the Monte Carlo frame, so the file
and the DataFrame cannot drift apart.
"""

from __future__ import annotations

import json
import re
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import UM
from rvfmu.core.reducer.errors import error_shapes

from . import montecarlo
from .sampling import _index, factor_values
from .store import JobStore, check_manifest, read_manifest, study_output_folder
from .study import Study, flag, sobol_base_samples, study_from_store

MC_JOB = "mc"
SOBOL_JOB = re.compile(r"sobol-n([0-9]+)(-second-order)?$")
SAMPLES_FORMAT = "%.6g"  # mc_samples.csv: 6 significant digits, as it always had

# The unit key of each kind's factor column: the tolerance's own key in the study file.
_FACTOR_KEY = {"zone": "position_um", "pitch": "cumulative_um", "band": "band_um", "clearance": "um"}


# -- Monte Carlo and stored rows --------------------------------------------------------------


def factor_column(factor) -> str:
    """The column of a factor's drawn value, named after its tolerance key and unit:
    'crank_cam_eccentricity_position_um', 'pin_pitch_cumulative_um', 'pin_radial_band_um',
    'crank_disc_clearance_um'."""
    return f"{factor.name}_{_FACTOR_KEY[factor.kind]}"


def factor_value_um(factor, values: np.ndarray) -> np.ndarray:
    """(S,) the value of `factor` an inspection of its tolerance measures [um], from its error
    array (S, *shape) [m] (complex for a zone): a zone's position deviation 2 E of its worst
    element; a pitch factor's span of its worst cumulative sequence (the realised F_p); a
    band's width 2 max |value|; a clearance's value."""
    S = values.shape[0]
    if factor.kind in ("zone", "band"):
        return 2.0 * np.abs(values.reshape(S, -1)).max(axis=1) / UM
    if factor.kind == "pitch":
        sequences = values.reshape(S, -1, values.shape[-1])
        return np.ptp(sequences, axis=-1).max(axis=1) / UM
    return values.reshape(S) / UM


def error_columns(factor, shape: tuple, values: np.ndarray) -> dict:
    """{column: (S,)} every drawn error of `factor` in file units (docs/model.md section 4).

    Zones: 'NAME[i,j].E_um' and 'NAME[i,j].beta_deg' (beta in [0, 360), in the frame
    section 4 names) per element; per-tooth errors: 'NAME[j,k]_um'.  A clearance has
    none: its factor column is its error.  values: (S, *shape) [m], as `factor_values`.
    """
    S = values.shape[0]
    flat = values.reshape(S, -1)
    columns = {}
    if factor.kind == "clearance":
        return columns
    for k, index in enumerate(np.ndindex(shape)):
        name = f"{factor.name}{_index(index)}"
        if factor.kind == "zone":
            columns[f"{name}.E_um"] = np.abs(flat[:, k]) / UM
            columns[f"{name}.beta_deg"] = np.degrees(np.angle(flat[:, k])) % 360.0
        else:
            columns[f"{name}_um"] = flat[:, k].real / UM
    return columns


def results_frame(
    study: Study, rows, X: np.ndarray, Y: np.ndarray, converged: np.ndarray, errors: bool = False
) -> pd.DataFrame:
    """One row per reducer: its factors' drawn values, metrics, convergence and spec checks.

    rows (S,): the reducers' row numbers in the study's sample (the index, "row");
    X (S, D): their sample rows; Y (S, M): their metrics in `study.metric_columns`;
    converged (S,).  Columns, in order: `factor_column` of every factor [um]; with
    `errors` the `error_columns` of every factor; the metric columns; converged (bool);
    with a spec, passed_<column> per spec line and passed (all lines), nullable
    booleans, NA where a metric is not finite (a failed solve, left out of the yield).
    """
    errors = flag("errors", errors)
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float).reshape(len(rows), len(study.metrics))
    shapes = error_shapes(study.design)
    drawn, details = {}, {}
    for factor, start, stop in study.layout:
        values = factor_values(factor, study.design, X[:, start:stop])
        drawn[factor_column(factor)] = factor_value_um(factor, values)
        if errors:
            details.update(error_columns(factor, shapes[factor.name], values))
    metrics = {column: Y[:, j] for j, column in enumerate(study.metric_columns)}
    data = {
        **drawn,
        **details,
        **metrics,
        "converged": np.asarray(converged, dtype=bool),
        **_passed(study, Y),
    }
    index = pd.Index(np.asarray(rows, dtype=np.int64), name="row")
    return pd.DataFrame(data, index=index)


def _passed(study: Study, Y: np.ndarray) -> dict:
    """{passed_<column>: ..., passed: ...} nullable booleans (S,), NA where a metric is not
    finite; {} without a spec."""
    if not study.spec:
        return {}
    failed = ~np.all(np.isfinite(Y), axis=1)
    out, every = {}, np.ones(Y.shape[0], dtype=bool)
    for limit in study.spec:
        passes = np.asarray(limit.passes(Y[:, study.metric_columns.index(limit.column)]))
        every &= passes
        out[f"passed_{limit.column}"] = pd.arrays.BooleanArray(passes, failed.copy())
    out["passed"] = pd.arrays.BooleanArray(every, failed.copy())
    return out


def mc_frame(study: Study, Y: np.ndarray, converged: np.ndarray, errors: bool = False) -> pd.DataFrame:
    """`results_frame` of the study's first n Monte Carlo reducers, Y (n, M), converged (n,)."""
    errors = flag("errors", errors)  # before drawing the rows
    n = np.asarray(Y).shape[0]
    return results_frame(study, np.arange(n), montecarlo.rows(study, 0, n), Y, converged, errors)


def write_samples(path: Path, frame: pd.DataFrame, study: Study) -> Path:
    """mc_samples.csv from a Monte Carlo frame: row, the metric columns (6 significant digits),
    converged (0/1)."""
    columns = frame[list(study.metric_columns)].assign(converged=frame["converged"].astype(np.int64))
    columns.to_csv(path, float_format=SAMPLES_FORMAT, na_rep="nan", lineterminator="\n")
    return Path(path)


def load_results(output_folder, job: str | None = None, *, errors: bool = False) -> pd.DataFrame:
    """The reducers an output folder holds, as `results_frame`: equal to the `to_df()` of the
    run that wrote them.

    job: "mc" (default) or a Sobol job "sobol-n<N>" / "sobol-n<N>-second-order" (its rows
    are the Saltelli sample's).  Every batch file of the job is read and checked as the
    commands check it (checksum, study, model version, sample rows), whatever n the runs
    asked for: a Monte Carlo job holds whole batches, so its rows beyond a run's n are the
    rest of its last batch (`.iloc[:n]` gives that run's), and a killed run's gaps are
    missing rows.  The study is the one the folder records (inputs.json, and its spec from
    study.toml, as last run).  InputError naming the folder for a missing folder, one
    without a manifest or without batches of the job, or one written by another model
    version.
    """
    errors = flag("errors", errors)
    folder = study_output_folder(output_folder)
    manifest = read_manifest(folder)
    study = _stored_study(folder, manifest)
    check_manifest(folder, manifest, study)
    job = MC_JOB if job is None else str(job)
    rows = cache(_job_rows(study, job, folder))
    if not (folder / job).is_dir():
        raise InputError(
            "job",
            job,
            f"has no results in {folder} (jobs there: "
            f"{', '.join(_jobs(folder)) or 'none'}); run rvte mc or rvte sobol first",
        )
    found = JobStore(folder, study, job).load_all(rows)
    if not found:
        raise InputError(
            "job",
            job,
            f"has no batch files in {folder / job}: run it (rvte mc / "
            "rvte sobol) until at least one batch is written",
        )
    batches = sorted(found)
    return results_frame(
        study,
        np.concatenate([np.arange(start, stop) for start, stop in batches]),
        np.concatenate([rows(*b) for b in batches]),
        np.concatenate([found[b].Y for b in batches]),
        np.concatenate([found[b].converged for b in batches]),
        errors,
    )


def _stored_study(folder: Path, manifest: dict) -> Study:
    """The study of the folder (`study_from_store`) from its inputs.json and study.toml."""
    try:
        inputs = json.loads((folder / "inputs.json").read_bytes().decode("utf-8"))
    except (OSError, ValueError) as exc:  # UnicodeDecodeError is a ValueError
        raise InputError(
            "inputs.json",
            str(folder / "inputs.json"),
            "cannot be read: it is not "
            f"a readable UTF-8 JSON file ({_reason(exc)}), so the folder is not a "
            "complete study output folder",
        ) from None
    copy = folder / "study.toml"
    text = ""
    if copy.is_file():
        try:
            text = copy.read_bytes().decode("utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(
                "study.toml",
                str(copy),
                "is not a readable UTF-8 TOML study file "
                f"({_reason(exc)}): restore it, or run the study again to rewrite "
                "it",
            ) from None
    return study_from_store(folder, str(manifest.get("study", folder.name)), inputs, text)


def _reason(exc: Exception) -> str:
    """The first line of an exception's message, at most 120 characters (a one-line error)."""
    text = (str(exc).splitlines() or [type(exc).__name__])[0]
    return text if len(text) <= 120 else text[:117] + "..."


def _job_rows(study: Study, job: str, folder: Path):
    """rows(start, stop) -> the sample rows of `job` (Monte Carlo or a Saltelli sample)."""
    if job == MC_JOB:
        return lambda start, stop: montecarlo.rows(study, start, stop)
    match = SOBOL_JOB.match(job)
    if match is None:
        raise InputError(
            "job",
            job,
            f"must be {MC_JOB} or a Sobol job sobol-n<N> or "
            f"sobol-n<N>-second-order (jobs in {folder}: "
            f"{', '.join(_jobs(folder)) or 'none'})",
        )
    from . import sobol

    n = sobol_base_samples("job", int(match.group(1)))
    sample = cache(
        lambda: sobol.sample(study.problem(), n, match.group(2) is not None, seed=study.seed)
    )  # drawn once, when a batch is read
    return lambda start, stop: sample()[start:stop]


def _jobs(folder: Path) -> list[str]:
    """The job folders of an output folder (those holding batch files)."""
    return sorted(p.name for p in folder.iterdir() if p.is_dir() and any(p.glob("batch-*.parquet")))


# -- Sobol --------------------------------------------------------------------------------------


def sobol_frame(analyses: dict) -> pd.DataFrame:
    """One row per (metric, factor) of {column: SobolAnalysis}, metric by metric, each ranked.

    Columns: metric (its column), factor (Sobol group), rank (1 = largest reported ST,
    then S1), S1, S1_conf, ST, ST_conf (estimates and half-widths of their bootstrap
    intervals), S1_reported, ST_reported (clipped to [0, 1]), the notes' flags
    not_converged, ci_wide, S1_above_ST (bool), notes (the table's text),
    ranking_converged (the metric's ST moved by at most CONVERGED_CHANGE from N/2 to N),
    and the order over the next rank (`sobol.Indices.order`): ST_above_next (the ST
    difference), ST_above_next_conf (the half-width of its bootstrap interval),
    order_settled (that interval excludes 0); NaN and False on the last rank and where the
    indices carry no resamples; method ("saltelli" or "linearized") and check_q2 (the
    linearization's check on the metric, `tolerance.linearized`; NaN where none ran).
    """
    parts = []
    for column, result in analyses.items():
        ind = result.indices
        order = ind.ranking()
        notes = ind.flags()
        above, above_conf = np.full(order.size, np.nan), np.full(order.size, np.nan)
        settled = np.zeros(order.size, dtype=bool)
        for rank, step in enumerate(ind.order() or ()):
            above[rank], above_conf[rank], settled[rank] = (step.difference, step.half_width, step.settled)
        parts.append(
            pd.DataFrame(
                {
                    "metric": column,
                    "factor": [ind.names[g] for g in order],
                    "rank": np.arange(1, len(order) + 1, dtype=np.int64),
                    "S1": ind.S1[order],
                    "S1_conf": ind.S1_conf[order],
                    "ST": ind.ST[order],
                    "ST_conf": ind.ST_conf[order],
                    "S1_reported": ind.S1_reported[order],
                    "ST_reported": ind.ST_reported[order],
                    "not_converged": ind.not_converged[order],
                    "ci_wide": ind.ci_wide[order],
                    "S1_above_ST": ind.S1_above_ST[order],
                    "notes": ["; ".join(notes[g]) for g in order],
                    "ranking_converged": bool(result.convergence.converged),
                    "ST_above_next": above,
                    "ST_above_next_conf": above_conf,
                    "order_settled": settled,
                    "method": result.method,
                    "check_q2": np.nan if result.check_q2 is None else float(result.check_q2),
                }
            )
        )
    return pd.concat(parts, ignore_index=True)


def s2_frame(analyses: dict) -> pd.DataFrame:
    """One row per (metric, pair of factors a < b in the study's order) of second-order
    indices: metric, factor_a, factor_b, S2, S2_conf (half-width of its interval)."""
    parts = []
    for column, result in analyses.items():
        ind = result.indices
        pairs = [(a, b) for a in range(len(ind.names)) for b in range(a + 1, len(ind.names))]
        parts.append(
            pd.DataFrame(
                {
                    "metric": column,
                    "factor_a": [ind.names[a] for a, _ in pairs],
                    "factor_b": [ind.names[b] for _, b in pairs],
                    "S2": np.array([ind.S2[a, b] for a, b in pairs], dtype=float),
                    "S2_conf": np.array([ind.S2_conf[a, b] for a, b in pairs], dtype=float),
                }
            )
        )
    return pd.concat(parts, ignore_index=True)
