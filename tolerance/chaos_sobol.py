"""Group Sobol indices from a sparse polynomial chaos of the study's unit draws.

The engineering question is the one of tolerance/sobol.py (which tolerances
decide the TE variance), answered from fewer reducers.  Saltelli's estimators
need G+2 model runs per base sample and hundreds of base samples; a polynomial
chaos fitted to plain random rows gives every group index at once from its
coefficients (Sudret 2008, Reliab. Eng. Syst. Saf. 93, 964-979): with
orthonormal Legendre polynomials psi_alpha of the inputs x = 2u - 1,

    y ~ sum_alpha c_alpha psi_alpha(x),   V = sum_{alpha != 0} c_alpha^2,
    S1_g = sum over alpha whose nonzero exponents all lie in g (at least one) of c_alpha^2 / V,
    ST_g = sum over alpha with any nonzero exponent in g of c_alpha^2 / V.

The chaos is `tolerance.surrogate.Chaos` (OpenTURNS, Legendre basis of total
degree p, terms kept by LARS with the corrected leave-one-out error), one per
output column.

Which variance.  V is the variance of the expansion, not of the data.  The
indices are then shares of one sum of squares: each lies in [0, 1], S1 <= ST
and the S1 add up to at most 1, exactly, for any fit.  The data's variance
also holds what the expansion misses (noise, a step, terms beyond degree p),
which belongs to no group; dividing by it would lower every index by that
unexplained share and mix the fit's error into the ranking.  How much of the
data's variance the expansion explains is the check below, reported beside.

The check.  Q2 = 1 - (corrected leave-one-out error) / Var(y) per output.
Below Q2_MIN the indices describe a polynomial that misses more of the TE
variance than a ranking may ignore: the result says so (`ChaosIndices.checked`,
`check_text`, a note in `flags()`), and no neighbouring ranks are settled, so
`order_groups()` is one undecided run.  Q2 is computed on the rows LARS chose
the terms from, so it flatters the fit a little; Q2_MIN leaves room for that.

Intervals.  The whole fit (LARS included) is repeated on R bootstrap
resamples of the rows (the reducers), the same resamples for every group and
output, and the half-widths follow SALib's normal rule, z * sd over the
resamples (`SALib.analyze.sobol`); ST over the resamples (R, G) decides which
neighbouring ranks are settled, as in `sobol.Indices.order`.  A resample holds
repeated rows, which a leave-one-out error cannot see as repeats: it keeps a
few more terms than the full fit, which widens the interval slightly.

Degree.  `degree=None` fits every total degree of DEGREES whose basis has at
most MAX_TERMS terms and keeps the one of least leave-one-out error per output
(Blatman & Sudret 2011, J. Comput. Phys. 230, degree-adaptive chaos); the
bootstrap refits that degree.  With the ~100 columns of a 15-tolerance study
(phases and tooth patterns are columns) only degree 2 fits under MAX_TERMS:
hyperbolic (q-norm) truncation would admit higher degrees per column, but
OpenTURNS's HyperbolicAnisotropicEnumerateFunction did not size a degree-3
basis of 100 inputs within 5 minutes, so it is not offered.

Cost, measured (studies/benchmarks/bench_chaos_sobol.py and 100-column fits
on a 2-core machine).  Ishigami's and the grouped G-function's ST within 0.02
took 80-130 rows against Saltelli's 5120 runs (N = 1024).  With 100 columns
at degree 2 (5151 candidate terms) one LARS fit took 1.6-16 s at n = 500 and
about 170 s at n = 1000, and the bootstrap repeats it R times: the refits, not
the model, then dominate.  A degree-2 chaos also misses a term cos(2 pi u) of
a phase column (Q2 about 0.74 on such a toy): the check refuses it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from rvfmu.core.base.checks import InputError, finite_array, integer

from .sobol import Indices, RankStep, group_names
from .surrogate import Chaos

DEGREES = (2, 3, 4)  # total degrees tried when none is given (degree-adaptive)
MAX_TERMS = 6000  # candidate terms of one fit: degree 2 of up to 108 columns; degree 2
# of 100 (5151) already takes ~170 s per LARS fit at n = 1000, and the
# bootstrap refits R times
MAX_DEGREE = 20  # no smooth metric needs more; a step needs every degree (the check says so)
Q2_MIN = 0.95  # = 1 - sobol.CONVERGED_CHANGE: an expansion that misses more than 5 %
# of the variance could hide a change of ST that the Saltelli path
# would already call unconverged
RESAMPLES = 100  # bootstrap refits: the half-width of a 95 % interval to ~7 % of itself
MIN_RESAMPLES = 10  # fewer give a standard deviation off by more than a quarter
WHERE = "chaos Sobol"


@dataclass(frozen=True)
class ChaosRankStep(RankStep):
    """A `RankStep` that is settled only if the chaos passed its check (`checked`)."""

    checked: bool = True

    @property
    def settled(self) -> bool:
        return self.checked and super().settled


@dataclass(frozen=True)
class ChaosIndices(Indices):
    """Group Sobol indices of one output from a polynomial chaos of n rows (see `Indices`).

    q2: leave-one-out Q2 of the chaos on the data (NaN where nothing was fitted: a
    constant output or the whole input in one group); q2_min: the threshold of the
    check; degree: total degree kept; terms: terms kept by LARS.  n is the number of
    rows (reducers).
    """

    q2: float = math.nan
    q2_min: float = Q2_MIN
    degree: int = 0
    terms: int = 0

    def __post_init__(self):
        if not 0.0 < self.q2_min <= 1.0:
            raise InputError("q2_min", self.q2_min, "must be in (0, 1]", WHERE)

    @property
    def checked(self) -> bool:
        """The chaos explains the data well enough to rank on (Q2 >= q2_min); also True
        where nothing had to be fitted (constant output, whole input)."""
        if self.constant or self.whole_input:
            return True
        return bool(self.q2 >= self.q2_min)

    def check_text(self) -> str:
        """One line: the check, with Q2, degree and terms, and what follows from it."""
        if self.constant or self.whole_input:
            return "chaos check: nothing fitted (" + (
                "constant output)" if self.constant else "the only group is the whole input)"
            )
        head = (
            f"chaos check: Q2 {self.q2:.3f} {'>=' if self.checked else '<'} {self.q2_min:.2f} "
            f"(degree {self.degree}, {self.terms} terms, n {self.n})"
        )
        if self.checked:
            return head + ": passed"
        return head + (
            ": FAILED, the expansion misses too much of the variance; the ranking is "
            "not settled, raise n or the degree, or use Saltelli's estimators"
        )

    def flags(self) -> list[list[str]]:
        """Per group, the notes of `SobolIndices.flags`, plus the chaos check line when the
        check failed (`checked` False)."""
        notes = super().flags()
        if not self.checked:
            for group in notes:
                group.append(self.check_text())
        return notes

    def order(self) -> list[RankStep] | None:
        """`Indices.order`, every step unsettled if the check failed."""
        steps = super().order()
        if steps is None:
            return None
        return [
            ChaosRankStep(s.upper, s.lower, s.difference, s.half_width, s.kept, checked=self.checked)
            for s in steps
        ]


def group_shares(
    alpha: np.ndarray, coefficients: np.ndarray, column_group: np.ndarray, G: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """S1 (G,), ST (G,) and the variance of a chaos with exponents alpha (P, D), coefficients
    (P,) [output units] and columns in groups column_group (D,) of 0..G-1 (variance in output
    units squared).  A chaos of zero variance gives zeros."""
    one_hot = np.zeros((alpha.shape[1], G))
    one_hot[np.arange(alpha.shape[1]), column_group] = 1.0
    member = ((alpha > 0).astype(float) @ one_hot) > 0  # (P, G): term involves group g
    square = np.asarray(coefficients, dtype=float) ** 2
    square = np.where(member.any(axis=1), square, 0.0)  # the mean term is no variance
    variance = float(square.sum())
    if variance == 0.0:
        return np.zeros(G), np.zeros(G), 0.0
    alone = member & (member.sum(axis=1) == 1)[:, None]  # terms of one group only
    return square @ alone / variance, square @ member / variance, variance


def column_groups(problem: dict) -> tuple[tuple[str, ...], np.ndarray]:
    """The group names in SALib's order and the group of each column (D,) of a SALib problem
    (names, optional groups)."""
    names = tuple(str(name) for name in group_names(problem))
    labels = problem.get("groups") or problem["names"]
    if len(labels) != problem["num_vars"]:
        raise InputError(
            "problem groups", len(labels), f"must name one group per column ({problem['num_vars']})", WHERE
        )
    index = {name: g for g, name in enumerate(names)}
    return names, np.array([index[label] for label in labels], dtype=int)


def chaos_indices(
    X: np.ndarray,
    Y: np.ndarray,
    problem: dict,
    degree: int | None = None,
    resamples: int = RESAMPLES,
    confidence: float = 0.95,
    seed: int = 0,
    q2_min: float = Q2_MIN,
) -> tuple[ChaosIndices, ...]:
    """Group Sobol indices of every output from a sparse Legendre chaos of unit rows.

    X: (n, D) unit draws in [0, 1) (any design: random, Sobol', a Monte Carlo study's
    rows); Y: (n,) or (n, M) outputs of those rows, in any unit; problem: SALib problem
    of the D columns (names, optional groups).  degree: total degree of the chaos, or
    None to keep the best of DEGREES by leave-one-out error.  Returns one `ChaosIndices`
    per output column (M of them; one for Y (n,)), with bootstrap intervals at
    `confidence` from `resamples` refits on resampled rows (the same for every output);
    resamples=0 gives the estimates alone (NaN intervals, no `order()`).
    """
    X = np.asarray(X)
    if X.ndim != 2:
        raise InputError("X", X.shape, "must be rows of unit draws shaped n x D", WHERE)
    n, D = X.shape
    X = finite_array("X", X, (n, D), WHERE)
    if np.any((X < 0.0) | (X >= 1.0)):
        bad = X[(X < 0.0) | (X >= 1.0)][0]
        raise InputError("X", float(bad), "unit draws must lie in [0, 1)", WHERE)
    if problem.get("num_vars") != D:
        raise InputError(
            "problem num_vars", problem.get("num_vars"), f"must equal the {D} columns of X", WHERE
        )
    Y = np.asarray(Y)
    if Y.ndim not in (1, 2) or Y.shape[0] != n:
        raise InputError("Y", Y.shape, f"must be shaped {n} or {n} x M (one row per row of X)", WHERE)
    Y = finite_array("Y", Y, Y.shape, WHERE).reshape(n, -1)
    resamples = integer("resamples", resamples, 0, where=WHERE)
    if 0 < resamples < MIN_RESAMPLES:
        raise InputError("resamples", resamples, f"must be 0 (no intervals) or >= {MIN_RESAMPLES}", WHERE)
    if isinstance(confidence, bool) or not isinstance(confidence, (int, float)) or not 0.0 < confidence < 1.0:
        raise InputError("confidence", confidence, "must be in (0, 1)", WHERE)
    if isinstance(q2_min, bool) or not isinstance(q2_min, (int, float)) or not 0.0 < q2_min <= 1.0:
        raise InputError("q2_min", q2_min, "must be in (0, 1]", WHERE)
    if degree is None:
        # beyond 108 columns only the linear terms fit: no interactions, S1 = ST
        degrees = tuple(p for p in DEGREES if math.comb(D + p, p) <= MAX_TERMS) or (1,)
    else:
        degree = integer("degree", degree, 1, MAX_DEGREE, WHERE)
        if math.comb(D + degree, degree) > MAX_TERMS:
            raise InputError(
                "degree",
                degree,
                f"gives {math.comb(D + degree, degree)} candidate terms over {D} "
                f"columns, more than {MAX_TERMS}: choose a lower degree",
                WHERE,
            )
        degrees = (degree,)
    names, column_group = column_groups(problem)
    G = len(names)
    if n < D + 2:
        raise InputError(
            "rows of X",
            n,
            f"must be >= {D + 2} for {D} columns: the chaos's "
            "leave-one-out check needs more rows than its linear terms",
            WHERE,
        )

    x = 2.0 * X - 1.0  # Legendre's interval [-1, 1]
    rows = np.random.default_rng(seed).integers(0, n, size=(resamples, n))
    z = norm.ppf(0.5 + confidence / 2)  # SALib's normal rule
    out = []
    for column in Y.T:
        if np.ptp(column) == 0.0:
            zero = np.zeros(G)
            out.append(
                ChaosIndices(
                    names, n, zero, zero, zero, zero, None, None, confidence, constant=True, q2_min=q2_min
                )
            )
            continue
        if G == 1:  # the group is the whole input: S1 = ST = 1 by definition (sobol.py)
            one, zero = np.ones(1), np.zeros(1)
            out.append(
                ChaosIndices(
                    names,
                    n,
                    one,
                    zero,
                    one,
                    zero,
                    None,
                    None,
                    confidence,
                    ST_resamples=np.ones((resamples, 1)) if resamples else None,
                    whole_input=True,
                    q2_min=q2_min,
                )
            )
            continue
        fits = [Chaos(x, column, p) for p in degrees]
        best = min(range(len(fits)), key=lambda k: fits[k].loo_error)
        chaos, p = fits[best], degrees[best]
        S1, ST, _ = group_shares(chaos.alpha, chaos.coefficients, column_group, G)
        boot_S1, boot_ST = np.full((resamples, G), np.nan), np.full((resamples, G), np.nan)
        for r, picked in enumerate(rows):
            sample_y = column[picked]
            if np.ptp(sample_y) == 0.0:  # a resample of one value
                boot_S1[r], boot_ST[r] = 0.0, 0.0
                continue
            refit = Chaos(x[picked], sample_y, p)
            boot_S1[r], boot_ST[r], _ = group_shares(refit.alpha, refit.coefficients, column_group, G)
        S1_conf, ST_conf = (
            (z * boot_S1.std(axis=0, ddof=1), z * boot_ST.std(axis=0, ddof=1))
            if resamples
            else (np.full(G, np.nan), np.full(G, np.nan))
        )
        out.append(
            ChaosIndices(
                names,
                n,
                S1,
                S1_conf,
                ST,
                ST_conf,
                None,
                None,
                confidence,
                ST_resamples=boot_ST if resamples else None,
                q2=1.0 - chaos.loo_error,
                q2_min=q2_min,
                degree=p,
                terms=int(chaos.coefficients.size),
            )
        )
    return tuple(out)
