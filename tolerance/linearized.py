"""Sobol indices of a loaded study from its TE curve linearized in the errors, corrected and
checked on a small solved design: far fewer solves than Saltelli's N (G + 2).

Under load every pin that carries torque stays in contact whatever the errors drawn, and
each point of the TE curve moves with the errors nearly as a linear function of them (the
superposition of small errors that tests/test_quasistatic.py holds the model to):

    TE(theta_k; e) ~ TE(theta_k; e0) + J_k . (e - e0)

e: the A error components a study draws (the real and imaginary parts of each phased
error, each tooth's deviation, each clearance), e0 their mean over the study's draws.
J comes from central differences, one component at a time moved up and down by its
standard deviation over the draws (a secant over the range the draws span, not a tangent
at one point; a clearance moves down at most to zero): 2A + 1 reducers solved
(`linearize`).  te_pp, rms and the orders are read off the predicted curves exactly as
off solved ones (`evaluate.metrics_from`): the maximum and minimum over the revolution
are kept, not linearized, and that is what carries te_pp's largest interaction, between
the crank cam eccentricity and the disc's crank holes, which add as vectors.  The windup
and friction metrics are linearized as numbers.

The estimator is a control variate (multifidelity Sobol estimation, Qian, Peherstorfer,
O'Malley, Vesselinov & Willcox 2018, SIAM/ASA J. Uncertainty Quantification 6(2)): with
y the solved model and y^ the linearization, Saltelli's estimators S give

    ST = S_N[y^] + (S_m[y] - S_m[y^])

S_N over the study's n base samples (the linearization evaluated, a matrix product), S_m
over the first m of them (`solved_n`), which are solved: the Saltelli job of n = m, so a
run at the full n later reuses them.  The correction carries what the linearization
misses; its spread is small where y^ follows y, and its bootstrap says how small:
the resamples of the two m-terms use the same base samples (SALib draws them from the
same seed), those of the N-term others, and the interval of each index, and of each
difference of neighbouring ranks (`Indices.order`), is their sum's spread.  Without the
correction the intervals would be those of the linearization alone, narrower than the
model allows.

Its check (`check`): the A and B rows of the solved block are 2m independent reducers of
the study's distribution; a metric whose Q2 = 1 - mean((y - y^)^2) / var(y) on them is
below Q2_MIN does not get its ranking from the linearization: the run says so and solves
Saltelli's whole design for it.  At no load it fails: which pins touch depends on the
errors, so each point of the curve is a maximum over contacts, not a linear function of
them; so do the windup metrics, whose clearances are taken up or not (docs/studies.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from rvfmu.core.base.checks import InputError
from rvfmu.core.reducer.errors import ErrorSet

from . import montecarlo, sobol
from .error_rows import clearance_components, error_vector
from .evaluate import Outputs, metrics_from, output_columns
from .sampling import errors_from_unit

Q2_MIN = 0.95  # the check's floor: the linearization explains 95 % of a metric's variance
SOLVED_N = 64  # base samples solved for the correction and the check (2 x 64 reducers)
MOMENT_DRAWS = 4096  # draws (no solves) whose mean and spread give e0 and the steps
PREDICT_ROWS = 4096  # rows predicted at a time (memory: rows x points x 8 bytes)
JOB = "linearized"


# -- the linearization --------------------------------------------------------------------------


@dataclass(frozen=True)
class Linearization:
    """TE curve and scalar outputs of a study's reducers as linear functions of their errors.

    centre: (P,) e0 [m]; active: (A,) the components the study draws (non-zero spread);
    te0: (K,) the curve at e0 [arcsec] and te_slope: (A, K) [arcsec/m], or None if no
    metric needs the curve; scalar0 {kind: value}, scalar_slope {kind: (A,)}; solves: the
    reducers solved for it (2A + 1); like: an ErrorSet of one reducer, the layout.
    """

    centre: np.ndarray
    active: np.ndarray
    te0: np.ndarray | None
    te_slope: np.ndarray | None
    scalar0: dict
    scalar_slope: dict
    solves: int
    like: ErrorSet
    computed: int = 0  # of the solves, those this run computed (the rest were stored)

    def outputs(self, errors: ErrorSet) -> Outputs:
        """The predicted `Outputs` of the reducers `errors`."""
        delta = (error_vector(errors) - self.centre)[:, self.active]
        te = None if self.te0 is None else self.te0 + delta @ self.te_slope
        scalars = {kind: self.scalar0[kind] + delta @ slope for kind, slope in self.scalar_slope.items()}
        return Outputs(te, scalars, np.ones(errors.samples, dtype=bool))

    def predict(self, study, X: np.ndarray) -> np.ndarray:
        """Y (S, M) of the study's metrics at sample rows X (S, D), predicted in batches."""
        parts = []
        for start in range(0, X.shape[0], PREDICT_ROWS):
            out = self.outputs(errors_from_unit(study, X[start : start + PREDICT_ROWS]))
            parts.append(metrics_from(study, out.te_arcsec, out.scalars))
        return np.concatenate(parts) if parts else np.empty((0, len(study.metrics)))


def difference_points(study) -> tuple[np.ndarray, np.ndarray, np.ndarray, ErrorSet]:
    """(points (2A + 1, P), active (A,), steps (A, 2) [m] up and down, like) of the central
    differences: e0, then e0 + up and e0 - down along each drawn component in turn."""
    draws = errors_from_unit(study, montecarlo.rows(study, 0, MOMENT_DRAWS))
    like = draws.take([0])
    vectors = error_vector(draws)
    centre, spread = vectors.mean(axis=0), vectors.std(axis=0)
    active = np.flatnonzero(spread > 1e-6 * max(spread.max(), 1e-300))
    up = spread[active]
    down = np.where(clearance_components(like)[active], np.minimum(up, centre[active]), up)
    points = np.repeat(centre[None], 2 * active.size + 1, axis=0)
    rows = np.arange(active.size)
    points[1 + 2 * rows, active] += up
    points[2 + 2 * rows, active] -= down
    return points, active, np.column_stack([up, down]), like


def linearize(study, backend=None, progress=None, log=None, yes: bool = False) -> Linearization:
    """The study's `Linearization`: its 2A + 1 reducers solved on `backend` (default in this
    process) in batches of the study's batch_size, each stored in the output folder as it
    finishes (job "linearized"): a run started again reads them instead of solving them."""
    from .run import compute  # the runs' batch loop, shared

    points, active, steps, like = difference_points(study)
    te_columns, kinds = output_columns(study)
    if log is not None:
        log(
            f"linearized: {points.shape[0]} reducers (2A + 1) for the central differences along "
            f"the A = {active.size} error components the study draws"
        )
    computed = compute(
        study,
        JOB,
        points.shape[0],
        lambda s, e: points[s:e],
        backend,
        progress,
        log,
        yes=yes,
        columns=te_columns + tuple(f"scalar_{k}" for k in kinds),
        like=like,
    )
    Y = computed.Y
    if not np.all(computed.converged):
        bad = int(np.flatnonzero(~computed.converged)[0])
        raise RuntimeError(
            f"the reducer of difference point {bad} did not converge: the "
            'linearization needs every one; use method = "saltelli"'
        )
    width = (Y[1::2] - Y[2::2]) / steps.sum(axis=1)[:, None]  # (A, columns)
    K = len(te_columns)
    return Linearization(
        points[0],
        active,
        Y[0, :K] if K else None,
        width[:, :K] if K else None,
        {k: float(Y[0, K + j]) for j, k in enumerate(kinds)},
        {k: width[:, K + j] for j, k in enumerate(kinds)},
        points.shape[0],
        like,
        computed.computed_rows,
    )


# -- the corrected indices and the check -----------------------------------------------------


def corrected_indices(
    problem: dict,
    predicted: np.ndarray,
    solved: np.ndarray,
    second_order: bool = False,
    resamples: int = 200,
    confidence: float = 0.95,
    seed: int = 0,
) -> sobol.Indices:
    """Indices of one output: Saltelli's estimators on the linearization's `predicted`
    outputs (n * rows_per_base_sample,) corrected by the first m base samples' `solved`
    outputs (m * rows_per_base_sample,): S_n[y^] + S_m[y] - S_m[y^] (module docstring),
    with intervals and resamples from the three bootstraps summed resample by resample."""
    rows = np.asarray(solved).size
    big = sobol.indices(problem, predicted, second_order, resamples, confidence, seed)
    small = sobol.indices(problem, solved, second_order, resamples, confidence, seed)
    small_hat = sobol.indices(
        problem, np.asarray(predicted)[:rows], second_order, resamples, confidence, seed
    )
    if small.constant or small.whole_input or big.constant or small_hat.constant:
        return small if small.whole_input or small.constant else big
    z = norm.ppf(0.5 + confidence / 2)
    st = big.ST_resamples + small.ST_resamples - small_hat.ST_resamples
    s1 = big.S1_resamples + small.S1_resamples - small_hat.S1_resamples
    square = np.full_like(big.S2, np.nan) if second_order else None
    return sobol.Indices(
        big.names,
        big.n,
        big.S1 + small.S1 - small_hat.S1,
        z * s1.std(axis=0, ddof=1),
        big.ST + small.ST - small_hat.ST,
        z * st.std(axis=0, ddof=1),
        square,
        square,
        confidence,
        ST_resamples=st,
        S1_resamples=s1,
    )


@dataclass(frozen=True)
class Check:
    """The linearization against solved reducers: per metric column, Q2 (1 - the share of
    the variance it misses) and the largest |error| in the metric's unit, on `rows`
    reducers; `solves` the linearization's own (2A + 1)."""

    columns: tuple
    q2: np.ndarray
    largest_error: np.ndarray
    rows: int
    solves: int = 0

    def passed(self) -> np.ndarray:
        """(M,) bool: Q2 >= Q2_MIN."""
        return self.q2 >= Q2_MIN

    def lines(self) -> list[str]:
        """What was solved, then one line per metric: the check, passed or failed, and what the
        run does then."""
        out = [
            f"linearized: {self.solves} reducers solved for the linearization; its check on "
            f"{self.rows} solved reducers (the A and B rows of the solved design), floor "
            f"Q2 >= {Q2_MIN}:"
        ]
        for column, q2, error, ok in zip(self.columns, self.q2, self.largest_error, self.passed()):
            verdict = (
                "passed: its ranking is the corrected linearization's"
                if ok
                else "FAILED: its ranking comes from Saltelli's whole design, solved"
            )
            out.append(f"  {column}: Q2 = {q2:.4f}, largest error {error:.3g}: {verdict}")
        return out

    def to_json(self) -> dict:
        """The check for the JSON summary: rows, solves, the Q2 floor, and Q2 and the largest
        error per metric column."""
        return {
            "rows": self.rows,
            "solves": self.solves,
            "q2_min": Q2_MIN,
            "q2": dict(zip(self.columns, map(float, self.q2))),
            "largest_error": dict(zip(self.columns, map(float, self.largest_error))),
        }


def q2_score(y: np.ndarray, predicted: np.ndarray) -> float:
    """1 - mean((y - predicted)^2) / var(y); 1 for a constant y predicted exactly, -inf if not."""
    residual = float(np.mean((y - predicted) ** 2))
    variance = float(np.var(y))
    if variance == 0.0:
        return 1.0 if residual == 0.0 else -np.inf
    return 1.0 - residual / variance


def independent_rows(problem: dict, rows: int, second_order: bool = False) -> np.ndarray:
    """Indices of the A and B rows among the first `rows` rows of a Saltelli sample: one pair
    per base sample, each an independent draw of the inputs."""
    per = sobol.rows_per_base_sample(problem, second_order)
    starts = np.arange(0, rows, per)
    return np.sort(np.concatenate([starts, starts + per - 1]))


def check(study, solved: np.ndarray, predicted: np.ndarray, solves: int = 0) -> Check:
    """The `Check` of a linearization from the solved metrics (S, M) of S independent
    reducers and its predictions of them."""
    if solved.shape[0] < 2:
        raise InputError("solved rows", solved.shape[0], "the check needs at least 2 reducers")
    q2 = np.array([q2_score(solved[:, j], predicted[:, j]) for j in range(solved.shape[1])])
    return Check(
        study.metric_columns, q2, np.max(np.abs(solved - predicted), axis=0), solved.shape[0], solves
    )
