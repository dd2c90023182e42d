"""Tolerance studies: which tolerances decide the TE of the reducers we build, and how many meet the spec.

SALib's scheme over the quasi-static model:

- `load_study(path) -> Study`: the study file, checked; `Study.problem()` is the SALib problem.
- `sample_mc(study, n) -> X`, `sample_sobol(study.problem(), n, second_order, seed) -> X`:
  rows of the unit hypercube; `errors_from_unit(study, X)` turns them into reducers.
- `evaluate(study, X) -> (Y, converged)`: the metrics of those reducers (pure, batched).
- `analyze_mc(study, Y, converged)`, `analyze_sobol(problem, Y, columns, ...)`.
- `run_mc(study_path, n=None, ...)`, `run_sobol(study_path, n=None, ...)`: the whole jobs
  (store, backends, cost estimate, aliasing check, report), behind `rvte mc` and `rvte sobol`.
- `report(output_dir, html_path=None, markdown_path=None)`: one self-contained HTML report and
  a Markdown summary of an output folder (tolerance/html_report.py), behind `rvte report`.

Names other than `evaluate` are imported on first use, so that `rvte te` does
not pay for SALib, pyarrow and Dask.

`tolerance.report` is also the module of the tables and figures
(tolerance/report.py, which the jobs import by that name): so that both hold,
whichever is imported first, that module is made callable, a call being the
report job.
"""

import sys
from importlib import import_module
from types import ModuleType

from .evaluate import evaluate  # eager: the name would otherwise be taken by the submodule

_WHERE = {
    "Study": ("study", "Study"), "load_study": ("study", "load_study"),
    "sample_mc": ("montecarlo", "sample"), "analyze_mc": ("montecarlo", "analyze"),
    "wilson_interval": ("montecarlo", "wilson_interval"),
    "sample_sobol": ("sobol", "sample"), "analyze_sobol": ("sobol", "analyze"),
    "errors_from_unit": ("sampling", "errors_from_unit"),
    "run_mc": ("run", "run_mc"), "run_sobol": ("run", "run_sobol"),
    "MCResult": ("run", "MCResult"), "SobolResult": ("run", "SobolResult"),
}

__all__ = ["evaluate", "report", *_WHERE]


def __getattr__(name):
    if name not in _WHERE:
        raise AttributeError(f"module 'tolerance' has no attribute {name!r}")
    module, attribute = _WHERE[name]
    return getattr(import_module(f".{module}", __name__), attribute)


class _ReportModule(ModuleType):
    """tolerance/report.py, callable: `tolerance.report(output_dir, ...)` is the report job."""

    def __call__(self, output_dir, html_path=None, markdown_path=None, **options):
        """`tolerance.html_report.report`: the HTML report and Markdown summary of an output folder."""
        job = import_module(".html_report", __name__).report
        return job(output_dir, html_path, markdown_path, **options)


class _Package(ModuleType):
    """This package, whose `report` is both the report job and the module of tables and figures."""

    @property
    def report(self):
        module = import_module(".report", __name__)
        if not isinstance(module, _ReportModule):
            module.__class__ = _ReportModule
        return module

    @report.setter
    def report(self, module):
        pass    # the import system binds the submodule here; the getter above serves it


sys.modules[__name__].__class__ = _Package
