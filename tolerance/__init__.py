"""Tolerance studies: which tolerances decide the TE of the reducers we build, and how many meet the spec.

SALib's scheme over the quasi-static model:

- `load_study(path) -> Study`: the study file, checked; `Study.problem()` is the SALib problem.
- `sample_mc(study, n) -> X`, `sample_sobol(study.problem(), n, second_order, seed) -> X`:
  rows of the unit hypercube; `errors_from_unit(study, X)` turns them into reducers.
- `evaluate(study, X) -> (Y, converged)`: the metrics of those reducers (pure, batched).
- `analyze_mc(study, Y, converged)`, `analyze_sobol(problem, Y, columns, ...)`.
- `run_mc(study_path, n=None, ...)`, `run_sobol(study_path, n=None, ...)`: the whole jobs
  (store, backends, cost estimate, aliasing check, report), behind `rvte mc` and `rvte sobol`.
- `allocate(study_path, yield_target=0.9973, ...) -> AllocationResult`: the least-cost
  tolerances for a yield target, verified by Monte Carlo, behind `rvte allocate`.
- `MCResult.to_df()`, `SobolResult.to_df()`, `load_results(output_folder, job=None)`: the
  results as pandas DataFrames (tolerance/frames.py): one row per reducer, or per (metric,
  factor) of the Sobol indices.
- `report(output_dir, html_path=None, markdown_path=None)`: one self-contained HTML report and
  a Markdown summary of an output folder (tolerance/html_report.py), behind `rvte report`.

Names other than `evaluate` are imported on first use, so that `rvte te` does
not pay for SALib, pyarrow, pandas and Dask.
"""

from importlib import import_module

from .evaluate import evaluate  # eager: the name would otherwise be taken by the submodule

_WHERE = {
    "Study": ("study", "Study"),
    "load_study": ("study", "load_study"),
    "sample_mc": ("montecarlo", "sample"),
    "analyze_mc": ("montecarlo", "analyze"),
    "wilson_interval": ("montecarlo", "wilson_interval"),
    "sample_sobol": ("sobol", "sample"),
    "analyze_sobol": ("sobol", "analyze"),
    "errors_from_unit": ("sampling", "errors_from_unit"),
    "run_mc": ("mc_runs", "run_mc"),
    "run_sobol": ("sobol_runs", "run_sobol"),
    "MCResult": ("mc_runs", "MCResult"),
    "SobolResult": ("sobol_runs", "SobolResult"),
    "load_results": ("frames", "load_results"),
    "report": ("html_report", "report"),
    "allocate": ("allocation", "allocate"),
    "AllocationResult": ("allocation", "AllocationResult"),
}

__all__ = ["evaluate", *_WHERE]  # noqa: PLE0604 - _WHERE's keys are the lazily loaded names (str)


def __getattr__(name):
    if name not in _WHERE:
        raise AttributeError(f"module 'tolerance' has no attribute {name!r}")
    module, attribute = _WHERE[name]
    return getattr(import_module(f".{module}", __name__), attribute)
