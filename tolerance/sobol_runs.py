"""The Sobol job, `run_sobol`: a study file in, every metric's indices and ranking and their
files out, by Saltelli's design or the linearized method, in one go or in rounds that stop
themselves, computed by `run.compute` over the store and a backend."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rvfmu.core.base.checks import InputError

from . import aliasing, frames, linearized, run, sobol, summaries
from .backends import make_backend
from .run import Computed, _check_sample_memory, _flags, _load, _warn_load
from .study import Study, check_sobol_method, flag, sobol_base_samples


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
        solved = run.compute(
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
        computed = run.compute(
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
