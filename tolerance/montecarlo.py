"""Monte Carlo: the TE of the reducers we will build, and how many of them meet the spec.

`sample(study, n) -> X` draws n reducers as rows of the unit hypercube; row r
comes from its own generator, seeded with (study seed, r), so a row does not
depend on n, on the batch size or on the backend: a study run again with a
larger n reuses every batch it has.  `analyze(study, Y, converged)` gives the
distribution of each metric and the yield against the spec.

The yield is a binomial proportion; its interval is the Wilson score interval,
which keeps its coverage near 0 and 1 (where a good process lives) unlike the
normal approximation, and never leaves [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

PERCENTILES = (1, 5, 50, 95, 99)


def rows(study, start: int, stop: int) -> np.ndarray:
    """Sample rows [start, stop) of the study's Monte Carlo: (stop - start, D) in [0, 1)."""
    D = len(study.columns)
    return (
        np.stack([np.random.default_rng([study.seed, r]).random(D) for r in range(start, stop)])
        if stop > start
        else np.empty((0, D))
    )


def sample(study, n: int) -> np.ndarray:
    """The study's first n Monte Carlo rows, (n, D)."""
    return rows(study, 0, n)


def wilson_interval(passed, n, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval (low, high) of a proportion passed/n at `confidence`."""
    if n <= 0:
        return 0.0, 1.0
    z = float(ndtri(0.5 + confidence / 2.0))
    p = passed / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))


@dataclass(frozen=True)
class MetricSummary:
    """Distribution of one metric over the evaluated reducers, in the column's unit."""

    column: str
    mean: float
    std: float
    minimum: float
    percentiles: dict
    maximum: float


@dataclass(frozen=True)
class Yield:
    """Share of reducers that meet `label` (one spec limit, or all of them), with its interval."""

    label: str
    passed: int
    n: int
    fraction: float
    low: float
    high: float
    confidence: float
    method: str = "Wilson score"


@dataclass(frozen=True)
class MCAnalysis:
    """Monte Carlo result of n reducers.

    evaluated: reducers with finite metrics; failed = n - evaluated (the solve
    failed: left out of every statistic and of the yield); not_converged:
    reducers whose equilibrium did not converge at some angle (kept, counted).
    worst: row of the worst reducer by `worst_column` (largest, or smallest
    for a minimum spec).
    """

    n: int
    evaluated: int
    failed: int
    not_converged: int
    summaries: tuple
    yields: tuple
    worst: int
    worst_column: str


def analyze(study, Y: np.ndarray, converged: np.ndarray, confidence: float | None = None) -> MCAnalysis:
    """Distribution and yield of Y (n, M) (study metric columns) with converged (n,)."""
    confidence = study.mc_confidence if confidence is None else confidence
    Y = np.asarray(Y, dtype=float)
    ok = np.all(np.isfinite(Y), axis=1)
    good = Y[ok]
    summaries = []
    for j, column in enumerate(study.metric_columns):
        v = good[:, j]
        if v.size == 0:
            summaries.append(MetricSummary(column, *(np.nan,) * 3, {p: np.nan for p in PERCENTILES}, np.nan))
            continue
        summaries.append(
            MetricSummary(
                column,
                float(v.mean()),
                float(v.std(ddof=1)) if v.size > 1 else 0.0,
                float(v.min()),
                {p: float(np.percentile(v, p)) for p in PERCENTILES},
                float(v.max()),
            )
        )
    yields = []
    if study.spec:
        passes_all = np.ones(good.shape[0], dtype=bool)
        for limit in study.spec:
            passes = limit.passes(good[:, study.metric_columns.index(limit.column)])
            passes_all &= passes
            yields.append(_yield(str(limit), passes, confidence))
        if len(study.spec) > 1:
            yields.append(_yield("all limits", passes_all, confidence))
    worst_limit = study.spec[0] if study.spec else None
    worst_column = worst_limit.column if worst_limit else study.metric_columns[0]
    values = np.where(ok, Y[:, study.metric_columns.index(worst_column)], np.nan)
    if not ok.any():
        worst = 0
    elif worst_limit is not None and worst_limit.sense == "min":
        worst = int(np.nanargmin(values))
    else:
        worst = int(np.nanargmax(values))
    return MCAnalysis(
        n=Y.shape[0],
        evaluated=int(ok.sum()),
        failed=int((~ok).sum()),
        not_converged=int((~np.asarray(converged, dtype=bool) & ok).sum()),
        summaries=tuple(summaries),
        yields=tuple(yields),
        worst=worst,
        worst_column=worst_column,
    )


def _yield(label, passes, confidence) -> Yield:
    n, passed = int(passes.size), int(passes.sum())
    low, high = wilson_interval(passed, n, confidence)
    return Yield(label, passed, n, passed / n if n else float("nan"), low, high, confidence)
