"""Least-cost tolerances for a yield target: `allocate(study_path, yield_target=0.9973)`.

The engineering question: which tolerances should the drawing give so that at
least the target share of the reducers we build meets every spec line of the
study at once (e.g. te_pp and lost_motion), at the lowest total cost
(tolerance/cost.py)?  Each factor i gets a scale s_i = t_i / t_i,current within
its process bounds; every error a factor draws is s_i times its value at the
current tolerance (tolerance/cost.py), so a reducer is its unit draws u plus
the scales s.

The yield of a scale vector needs thousands of reducers and the optimiser asks
for it hundreds of times, so the optimiser works on a surrogate, and the true
model has the last word:

1. Training.  Groups of TRAIN_GROUP reducers, each group at its own scale
   vector (a Latin hypercube over the log-scale box), are evaluated through
   the study's own machinery (`tolerance.run.compute` on a Study with the
   scaled tolerances: batches stored in the output folder, an interrupted run
   loses nothing).  The scales are drawn jointly with the unit draws, so the
   training covers every allocation the optimiser may visit.
2. Surrogate.  The inputs of a reducer are, per factor, the size of its drawn
   errors: log(s_i r_i(u) + floor), r_i the RMS of the factor's error values
   [um] at the current tolerance (for the analytic toy: the signed value).  A
   sparse polynomial chaos (OpenTURNS FunctionalChaosAlgorithm, Legendre basis
   of total degree DEGREE, LARS with corrected leave-one-out) gives the mean
   of each spec metric (its log, when it is positive), and a second one the
   log of the squared residual (heteroscedastic noise: the spread of TE at
   given error sizes grows with them).  Polynomial chaos rather than Kriging:
   the training holds thousands to tens of thousands of reducers whose metric
   is a noisy function of its inputs (phases and tooth patterns are not
   inputs); LARS fits that in seconds and its cost grows linearly with the
   samples, where Kriging's grows with their cube and would interpolate the
   noise.
3. Surrogate yield at s: the mean, over a fixed scrambled Sobol' set of
   YIELD_DRAWS unit draws, of the probability that a reducer passes every
   spec line, Phi(margin / sigma) per line with sigma the modelled residual
   (never below SIGMA_FLOOR of the metric's spread): a smooth function of s
   that SLSQP can differentiate.
4. Optimiser (scipy), about a centre: the cheapest verified allocation that
   met the target, else the verified one of highest yield (at first the
   current tolerances).  The surrogate is calibrated there (its probit error
   at the centre removed) and trusted within a trust region about it (TRUST_*
   in ln s): SLSQP minimises the total cost subject to Phi^-1(yield) >=
   Phi^-1(target) + safety; if the region holds no such point, its best
   yield is verified (the search climbs); if even the best yield the
   surrogate finds in the whole box (L-BFGS-B) is below the target, that
   point is verified instead.
5. Verification.  The answer is always checked by a fresh Monte Carlo of the
   true model at the allocated tolerances: the allocated study file's own
   `rvte mc` rows (so that running it again reuses them), n reducers (the
   study's [montecarlo] n, at least MIN_HIGH_YIELD_N for a target >= 0.99).
   It joins the training set and the surrogate is refitted.  The surrogate
   has proven itself where its calibrated prediction and the verification
   agree within STOP_NOISE standard errors (probit units).  The safety starts
   at MARGIN_START and becomes the verification's standard error once the
   surrogate proved itself (its optimism while it has not); the trust region
   doubles when it proved itself and halves when not.  The search stops when
   an allocation meets the target with a proven surrogate and the noise-level
   safety, or after MAX_ROUNDS; the cheapest verified allocation wins.  Its
   yield "meets the target" when the verification's estimate does; the
   printed interval (Wilson, tolerance/montecarlo.py) says how sure that is.
6. Out of reach: the surrogate's best point verified short REACH_TRIES times
   (nothing having met the target): the answer is the best verified yield,
   with the bounds that bind.  Often every tolerance at its tightest, but not
   always: opening a band of tooth errors closes the designed backlash, and
   lost motion falls.

The core (`allocate_scales`) knows nothing of reducers: it takes a
`ScaledModel` (functions of scales and unit draws), so an analytic stack-up
can be allocated and checked against its closed-form solution
(tests/test_allocate.py); `allocate` wires the study's model into it.
"""

from __future__ import annotations

import json
import math
import sys
import tomllib
import types
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.special import ndtr, ndtri

from rvfmu.core.checks import InputError, finite_number, integer

from . import cost as costs
from .montecarlo import wilson_interval

TRAIN_GROUP = 16            # reducers per training scale: the model's per-call cost is ~8 reducers'
TRAIN_GROUPS_PER_FACTOR = 16
MIN_TRAIN_GROUPS = 32       # a degree-2 chaos in F scales needs (F+1)(F+2)/2 well-spread points
YIELD_DRAWS = 2 ** 14       # unit draws of the surrogate yield (scrambled Sobol', a power of 2)
DEGREE = 2                  # total degree of the chaos; 3 fitted no better on the RV-40E studies
SIGMA_FLOOR = 0.02          # residual sigma >= this x the metric's spread: keeps the yield smooth
LOG_FLOOR = 0.05            # of the mean error size: log inputs stay finite for a zero draw
MARGIN_START = 0.25         # probit units, before any verification (0.9973 -> 0.9985)
STOP_NOISE = 2.5            # proven: prediction and verification within this many standard errors
MAX_ROUNDS = 8              # verifications at most (each n reducers)
REACH_TRIES = 2             # the surrogate's best reachable yield verified short twice: out of reach
TRUST_START = 0.5           # trust region about the centre, in ln s (x1.65): the surrogate's
TRUST_MAX = 1.0             # errors differ from place to place, so its calibration only holds
TRUST_MIN = 0.05            # near where it was made; doubled when proven, halved when not
DATA_PER_POINT = 4096       # verification reducers kept for the fit (it grows with each round)
HIGH_YIELD = 0.99           # from this target on, verify with at least MIN_HIGH_YIELD_N reducers
MIN_HIGH_YIELD_N = 10000    # 27 expected failures at 0.9973: the estimate means something
BINDING = 0.005             # a scale within 0.5 % of a bound (the rounding of t) binds it
ROUND_UM = 0.01             # allocated tolerances are written rounded down to 0.01 um
SURROGATE_KIND = ("polynomial chaos (OpenTURNS FunctionalChaosAlgorithm, Legendre degree "
                  f"{DEGREE}, LARS, corrected leave-one-out) of each spec metric and of its "
                  "residual variance")


# -- the problem the core sees ----------------------------------------------------------------

@dataclass(frozen=True)
class Limit:
    """A spec line on metric column `column` of Y: value <= limit ('max') or >= limit ('min')."""

    column: int
    limit: float
    sense: str

    def passes(self, values):
        return values <= self.limit if self.sense == "max" else values >= self.limit


@dataclass(frozen=True)
class ScaledModel:
    """F factors whose errors scale with s (F,) and a true model of M metrics.

    current (F,): the tolerances at s = 1; costs: one resolved CostModel per
    factor (bounds in the same unit as current).  magnitudes(U (n, D)) -> (n, F):
    each factor's error size in each draw at s = 1 (>= 0 if log_inputs).
    evaluate(s (F,), U (n, D), job) -> Y (n, M), NaN for a failed reducer.
    verify(s, n) -> (U (n, D), Y (n, M)): the Monte Carlo that judges an
    allocation.  snap(s) -> the scales that will be written (rounding).
    """

    names: tuple[str, ...]
    current: np.ndarray
    costs: tuple
    limits: tuple[Limit, ...]
    columns: int
    magnitudes: Callable
    evaluate: Callable
    verify: Callable
    log_inputs: bool = True
    snap: Callable = staticmethod(lambda s: s)
    seed: int = 0
    confidence: float = 0.95

    @property
    def lower(self) -> np.ndarray:
        return np.array([c.tightest_um for c in self.costs]) / self.current

    @property
    def upper(self) -> np.ndarray:
        return np.array([c.loosest_um for c in self.costs]) / self.current

    def cost(self, s) -> np.ndarray:
        """Cost of every factor at scales s (F,)."""
        return np.array([c.cost(t) for c, t in zip(self.costs, np.asarray(s) * self.current)])

    def cost_slope(self, s) -> np.ndarray:
        """d cost_i / d ln s_i at s (F,)."""
        return np.array([c.slope(t) for c, t in zip(self.costs, np.asarray(s) * self.current)])


@dataclass(frozen=True)
class Verified:
    """A Monte Carlo of the true model at scales s: passed of n reducers (finite metrics)."""

    scales: np.ndarray
    passed: int
    n: int
    low: float
    high: float

    @property
    def estimate(self) -> float:
        return self.passed / self.n if self.n else float("nan")

    def probit_noise(self) -> float:
        """Standard error of the estimate in probit units (Phi^-1 of the yield)."""
        p = _clip_yield(self.estimate, self.n)
        return float(math.sqrt(p * (1 - p) / self.n) / _phi(ndtri(p)))


@dataclass(frozen=True)
class Round:
    """One search round: the margin asked for, the allocation, its predicted and verified yield."""

    margin: float
    predicted: float
    verified: Verified
    cost: float


@dataclass(frozen=True)
class ScaleAllocation:
    """What `allocate_scales` found: the scales (F,), whether they meet the target, the evidence."""

    scales: np.ndarray
    feasible: bool
    current: Verified
    allocated: Verified
    rounds: tuple[Round, ...]
    samples: int
    validation: str
    evaluations: int


# -- the surrogate ------------------------------------------------------------------------------

class Chaos:
    """A sparse polynomial chaos on inputs in [-1, 1]^d: fitted by OpenTURNS, evaluated by numpy.

    Orthonormal Legendre polynomials (the basis of the uniform measure on
    [-1, 1]), total degree `degree`, terms chosen by LARS with the corrected
    leave-one-out error.  `metamodel` is OpenTURNS's own evaluation (for checks).
    """

    def __init__(self, X: np.ndarray, y: np.ndarray, degree: int = DEGREE):
        import openturns as ot

        d = X.shape[1]
        basis = ot.OrthogonalProductPolynomialFactory([ot.LegendreFactory()] * d)
        enumerate_ = basis.getEnumerateFunction()
        algo = ot.FunctionalChaosAlgorithm(
            ot.Sample(np.ascontiguousarray(X)), ot.Sample(np.ascontiguousarray(y)[:, None]),
            ot.JointDistribution([ot.Uniform(-1.0, 1.0)] * d),
            ot.FixedStrategy(basis, enumerate_.getBasisSizeFromTotalDegree(degree)),
            ot.LeastSquaresStrategy(ot.LeastSquaresMetaModelSelectionFactory(
                ot.LARS(), ot.CorrectedLeaveOneOut())))
        algo.run()
        result = algo.getResult()
        self.degree = degree
        self.alpha = np.array([list(enumerate_(int(i))) for i in result.getIndices()], dtype=int)
        self.coefficients = np.asarray(result.getCoefficients())[:, 0]
        self.metamodel = result.getMetaModel()

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Values at X (n, d) in [-1, 1]: (n,)."""
        X = np.ascontiguousarray(X.T)                   # (d, n): each polynomial row contiguous
        P = np.empty((self.degree + 1,) + X.shape)
        P[0] = 1.0
        if self.degree:
            P[1] = X
        for n in range(1, self.degree):                 # Bonnet's recursion
            P[n + 1] = ((2 * n + 1) * X * P[n] - n * P[n - 1]) / (n + 1)
        P *= np.sqrt(2.0 * np.arange(self.degree + 1) + 1.0)[:, None, None]
        out = np.zeros(X.shape[1])
        for alpha, c in zip(self.alpha, self.coefficients):
            nonzero = np.flatnonzero(alpha)
            if nonzero.size == 0:
                out += c
                continue
            term = c * P[alpha[nonzero[0]], nonzero[0]]
            for i in nonzero[1:]:
                term *= P[alpha[i], i]
            out += term
        return out


class Surrogate:
    """P(a reducer passes every limit | its inputs Z), from the training inputs Z (n, F) and Y (n, M).

    Per metric column: g = log(value) if every value and limit is positive,
    else the value; g = mean(Z) + sigma(Z) * e, mean and log sigma^2 each a
    `Chaos`; e standard normal.  Lines are treated as independent given Z.
    """

    def __init__(self, Z: np.ndarray, Y: np.ndarray, limits: tuple[Limit, ...],
                 degree: int = DEGREE):
        self.limits = limits
        self.low, self.high = Z.min(axis=0), Z.max(axis=0)
        self.high = np.where(self.high > self.low, self.high, self.low + 1.0)
        X = self.unit(Z)
        self.fits = {}
        for column in sorted({limit.column for limit in limits}):
            y = Y[:, column]
            log = bool(np.all(y > 0) and all(l.limit > 0 for l in limits if l.column == column))
            g = np.log(y) if log else y
            spread = float(g.std()) or 1.0
            mean = Chaos(X, g, degree)
            residual = g - mean(X)
            tiny = (1e-3 * spread) ** 2
            log_variance = Chaos(X, np.log(residual ** 2 + tiny), degree)
            # in-sample residuals understate the spread by the terms fitted; E[log chi2_1] = -1.2704
            inflate = X.shape[0] / max(1, X.shape[0] - mean.coefficients.size)
            fitted = log_variance(X)
            self.fits[column] = (log, mean, log_variance, inflate, SIGMA_FLOOR * spread,
                                 (fitted.min(), fitted.max()))

    def unit(self, Z: np.ndarray) -> np.ndarray:
        """Inputs mapped onto [-1, 1] over the training range (clipped: no extrapolation)."""
        return np.clip(2.0 * (Z - self.low) / (self.high - self.low) - 1.0, -1.0, 1.0)

    def transform(self, column: int, values):
        log = self.fits[column][0]
        return np.log(values) if log else np.asarray(values, dtype=float)

    def mean_sigma(self, column: int, X: np.ndarray):
        log, mean, log_variance, inflate, floor, (lo, hi) = self.fits[column]
        variance = np.exp(np.clip(log_variance(X), lo, hi) + 1.2704) * inflate
        return mean(X), np.maximum(np.sqrt(variance), floor)

    def probability(self, Z: np.ndarray) -> np.ndarray:
        """P(pass every limit) of each input row (n,)."""
        X = self.unit(Z)
        p = np.ones(Z.shape[0])
        cache = {}
        for limit in self.limits:
            if limit.column not in cache:
                cache[limit.column] = self.mean_sigma(limit.column, X)
            mu, sigma = cache[limit.column]
            bound = self.transform(limit.column, limit.limit)
            p *= ndtr(((bound - mu) if limit.sense == "max" else (mu - bound)) / sigma)
        return p

    def check(self, Z: np.ndarray, Y: np.ndarray) -> str:
        """Held-out quality: per column Q2 of the mean and mean/sd of the standardised residual."""
        X = self.unit(Z)
        parts = []
        for column in self.fits:
            g = self.transform(column, Y[:, column])
            mu, sigma = self.mean_sigma(column, X)
            q2 = 1.0 - np.mean((g - mu) ** 2) / max(np.var(g), 1e-300)
            e = (g - mu) / sigma
            parts.append(f"column {column}: Q2 {q2:.3f}, standardised residual mean "
                         f"{e.mean():+.2f} sd {e.std():.2f}")
        return "; ".join(parts)


# -- the core: scales -> cheapest verified allocation ---------------------------------------------

def allocate_scales(model: ScaledModel, target: float, n: int, *, groups: int | None = None,
                    draws: int = YIELD_DRAWS, log=None, progress: bool | None = False,
                    column_names: tuple[str, ...] | None = None) -> ScaleAllocation:
    """The least-cost scales with a verified yield >= target (module docstring, steps 1-6).

    n: reducers of each verification Monte Carlo; groups: training groups of
    TRAIN_GROUP reducers (default max(MIN_TRAIN_GROUPS, TRAIN_GROUPS_PER_FACTOR * F)).
    """
    say = log or (lambda text: None)
    F = len(model.names)
    lower, upper = model.lower, model.upper
    ones = np.ones(F)
    z_target = float(ndtri(target))
    evaluations = 0
    data = []                       # (scales (k, F), R (k, F), Y (k, M), training group or -1)

    current, U, Y = _verify(model, ones, n)
    evaluations += n
    data.append((np.tile(ones, (min(n, DATA_PER_POINT), 1)), model.magnitudes(U[:DATA_PER_POINT]),
                 Y[:DATA_PER_POINT], -1))
    say(f"allocate: current tolerances: yield {current.estimate:.5f} "
        f"[{current.low:.5f}, {current.high:.5f}] of {current.n}")

    groups = groups or max(MIN_TRAIN_GROUPS, TRAIN_GROUPS_PER_FACTOR * F)
    from scipy.stats import qmc

    box = qmc.LatinHypercube(d=F, seed=np.random.default_rng([model.seed, 1])).random(groups)
    S = np.exp(np.log(lower) + (np.log(upper) - np.log(lower)) * box)
    bar = _bar(groups * TRAIN_GROUP, "allocate training", progress)
    for g in range(groups):
        U = np.random.default_rng([model.seed, 0x616C6C6F, g]).random((TRAIN_GROUP, model.columns))
        Y = model.evaluate(S[g], U, f"allocation-train-{g}")
        data.append((np.tile(S[g], (TRAIN_GROUP, 1)), model.magnitudes(U), Y, g))
        if bar is not None:
            bar.update(TRAIN_GROUP)
    if bar is not None:
        bar.close()
    evaluations += groups * TRAIN_GROUP

    sobol = qmc.Sobol(d=model.columns, scramble=True, seed=np.random.default_rng([model.seed, 2]))
    R_yield = model.magnitudes(sobol.random_base2(int(math.log2(draws))))
    floor = LOG_FLOOR * np.maximum(R_yield.mean(axis=0), 1e-12)

    def inputs(scales, R):
        Z = scales * R
        return np.log(Z + floor) if model.log_inputs else Z

    def fit(rows):
        Z = np.concatenate([inputs(s, R) for s, R, _, _ in rows])
        Yall = np.concatenate([Y for _, _, Y, _ in rows])
        ok = np.all(np.isfinite(Yall), axis=1)
        return Surrogate(Z[ok], Yall[ok], model.limits), int(ok.sum())

    held = [row for row in data if row[3] >= 0 and row[3] % 5 == 0]
    surrogate, _ = fit([row for row in data if not (row[3] >= 0 and row[3] % 5 == 0)])
    Zh = np.concatenate([inputs(s, R) for s, R, _, _ in held])
    Yh = np.concatenate([Y for _, _, Y, _ in held])
    ok = np.all(np.isfinite(Yh), axis=1)
    validation = f"held-out training groups ({ok.sum()} reducers): " + surrogate.check(Zh[ok], Yh[ok])
    if column_names:
        for j, name in enumerate(column_names):
            validation = validation.replace(f"column {j}:", f"{name}:")
    say(f"allocate: surrogate validation, {validation}")

    def surrogate_yield(surrogate, scales):
        """Surrogate yield at each row of scales (m, F): (m,)."""
        scales = np.atleast_2d(scales)
        return np.array([surrogate.probability(inputs(s, R_yield)).mean() for s in scales])

    # Verified points (the current tolerances first); each round verifies one more.
    points = [Round(float("nan"), float("nan"), current, float(model.cost(ones).sum()))]
    radius, safety, misses = TRUST_START, MARGIN_START, 0
    surrogate, samples = fit(data)
    for r in range(MAX_ROUNDS):
        yield_at = lambda S, surrogate=surrogate: surrogate_yield(surrogate, S)  # noqa: E731
        centre = _centre(points, target)
        c = centre.verified.scales
        z_centre = float(_probit(yield_at(c)[0]))
        bias = z_centre - _observed(centre.verified)    # calibrate the surrogate at the centre
        met = centre.verified.estimate >= target
        # never ask more of a cheaper allocation than the centre that met the target verified
        margin = bias + (min(safety, _observed(centre.verified) - z_target) if met else safety)
        goal = min(z_target + margin, z_centre) if met else z_target + margin
        low = np.maximum(lower, c * np.exp(-radius))    # the trust region about the centre
        high = np.minimum(upper, c * np.exp(radius))
        reaching = False
        if z_centre >= goal:                            # the centre is a feasible start
            scales = optimise(model, yield_at, goal, [c], low, high)
        else:
            # the best the surrogate can reach in the box: often all at the tightest, but not
            # always (opening a band of tooth errors closes the backlash: lost motion falls)
            reach, z_reach = best_reachable(model, yield_at, [lower, ones, upper, c])
            reaching = z_reach < z_target + bias        # even the target itself is out of reach
            if reaching:                                # out of reach? check the best point
                scales = reach
            else:                                       # climb, or the least cost, in the region
                local, z_local = best_reachable(model, yield_at, [c, np.clip(reach, low, high)],
                                                low, high)
                scales = local if z_local < goal else optimise(model, yield_at, goal, [local, c],
                                                               low, high)
        scales = model.snap(scales)
        predicted = float(ndtr(_probit(yield_at(scales)[0]) - bias))
        if any(np.array_equal(scales, done.verified.scales) for done in points):
            say(f"allocate: round {r + 1} gives an allocation already verified: stop")
            break
        verified, U, Y = _verify(model, scales, n)
        evaluations += n
        data.append((np.tile(scales, (min(n, DATA_PER_POINT), 1)),
                     model.magnitudes(U[:DATA_PER_POINT]), Y[:DATA_PER_POINT], -1))
        points.append(Round(margin, predicted, verified, float(model.cost(scales).sum())))
        meets = verified.estimate >= target
        noise = verified.probit_noise()
        optimism = float(_probit(predicted)) - _observed(verified)   # the calibrated error
        proven = abs(optimism) <= STOP_NOISE * noise
        say(f"allocate: round {r + 1}" + (" (the surrogate's best reachable yield)" if reaching
                                          else f" (trust region x{math.exp(radius):.2f})") +
            f": margin {margin:+.3f} -> cost {points[-1].cost:.4g}, predicted "
            f"{predicted:.5f}, verified {verified.estimate:.5f} [{verified.low:.5f}, "
            f"{verified.high:.5f}] of {verified.n}" + ("" if meets else " (below the target)"))
        misses += bool(reaching and not meets)
        feasible = any(done.verified.estimate >= target for done in points)
        if misses >= REACH_TRIES and not feasible:
            break                                       # out of reach, as far as can be told
        if meets and proven and safety < MARGIN_START:
            break                                       # proven, with a margin at the noise level
        radius = min(2 * radius, TRUST_MAX) if proven else max(radius / 2, TRUST_MIN)
        safety = noise if proven else max(noise, min(optimism, MARGIN_START))
        surrogate, samples = fit(data)
    rounds = tuple(points[1:])
    meeting = [done for done in points if done.verified.estimate >= target]   # current included
    if not meeting:                                     # the best verified yield is the answer
        reached = _centre(points, target)
        return ScaleAllocation(reached.verified.scales, False, current, reached.verified,
                               rounds, samples, validation, evaluations)
    best = min(meeting, key=lambda done: done.cost)
    if best is not points[0]:
        validation += (f"; at the allocation: predicted {best.predicted:.5f}, verified "
                       f"{best.verified.estimate:.5f}")
    return ScaleAllocation(best.verified.scales, True, current, best.verified, rounds,
                           samples, validation, evaluations)


def _centre(points, target: float) -> Round:
    """The verified point to search about: the cheapest that meets the target, else the one
    of highest yield (the latest of equals)."""
    meeting = [done for done in points if done.verified.estimate >= target]
    if meeting:
        return min(meeting, key=lambda done: done.cost)
    return max(reversed(points), key=lambda done: done.verified.estimate)


def _observed(verified: Verified) -> float:
    """Phi^-1 of a verified yield (kept off 0 and 1 by half a reducer)."""
    return float(_probit(_clip_yield(verified.estimate, verified.n)))


class _Box:
    """A box of scales in ln s, within the bounds; factors whose bounds coincide are held there."""

    STEP = 1e-4                                         # finite difference in ln s

    def __init__(self, model: ScaledModel, lower=None, upper=None):
        self.lower = model.lower if lower is None else np.asarray(lower, dtype=float)
        self.upper = model.upper if upper is None else np.asarray(upper, dtype=float)
        self.free = self.upper > self.lower * (1.0 + 1e-12)
        self.lo, self.hi = np.log(self.lower), np.log(self.upper)

    def scales(self, v) -> np.ndarray:
        x = self.lo.copy()
        x[self.free] = v
        return np.exp(x)

    def variables(self, scales) -> np.ndarray:
        return np.clip(np.log(scales), self.lo, self.hi)[self.free]

    def bounds(self):
        return list(zip(self.lo[self.free], self.hi[self.free]))

    def probit(self, yield_at, v) -> tuple[float, np.ndarray]:
        """Phi^-1 of the yield at v and its gradient (forward differences, one call)."""
        V = np.vstack([v, v + self.STEP * np.eye(v.size)])
        z = _probit(yield_at(np.array([self.scales(row) for row in V])))
        return float(z[0]), (z[1:] - z[0]) / self.STEP


def best_reachable(model: ScaledModel, yield_at, starts, lower=None,
                   upper=None) -> tuple[np.ndarray, float]:
    """The scales (F,) of the highest yield_at within [lower, upper] (default the bounds), and
    its probit: scipy's L-BFGS-B over ln s from each start (scales (F,)), the best kept."""
    from scipy.optimize import minimize

    box = _Box(model, lower, upper)
    if not box.free.any():
        return box.lower.copy(), float(_probit(yield_at(box.lower[None])[0]))
    best, best_z = None, -math.inf
    for start in starts:
        result = minimize(lambda v: tuple(-x for x in box.probit(yield_at, v)),
                          box.variables(start), jac=True, method="L-BFGS-B", bounds=box.bounds(),
                          options={"maxiter": 50})
        for v in (box.variables(start), np.clip(result.x, box.lo[box.free], box.hi[box.free])):
            z = float(_probit(yield_at(box.scales(v)[None])[0]))
            if z > best_z:
                best, best_z = box.scales(v), z
    return best, best_z


def optimise(model: ScaledModel, yield_at, wanted: float, starts=(), lower=None,
             upper=None) -> np.ndarray:
    """Least-cost scales (F,) in [lower, upper] (default the bounds) with
    Phi^-1(yield_at(s)) >= wanted, by SLSQP over ln s.

    yield_at(S (m, F)) -> (m,); starts: scales (F,) to start from besides the
    current tolerances (clipped) and the uniform scaling that just meets
    `wanted`.  The cheapest feasible result is kept; a feasible start is needed
    (e.g. `best_reachable`'s).  Costs never rise as a tolerance opens, so if
    everything at its loosest is feasible, that is the answer.
    """
    from scipy.optimize import brentq, minimize

    box = _Box(model, lower, upper)
    if not box.free.any():
        return box.lower.copy()
    base = float(model.cost(np.clip(np.ones_like(box.lower), box.lower, box.upper)).sum()) or 1.0

    def objective(v):
        s = box.scales(v)
        return float(model.cost(s).sum()) / base, model.cost_slope(s)[box.free] / base

    def constraint(v):
        return float(_probit(yield_at(box.scales(v)[None])[0]) - wanted)

    def uniform(log_scale):
        return np.clip(np.full(box.lo.size, log_scale), box.lo, box.hi)

    def gap(log_scale):
        return float(_probit(yield_at(np.exp(uniform(log_scale))[None])[0]) - wanted)

    if constraint(box.variables(box.upper)) >= 0:
        return box.upper.copy()
    points = [box.variables(np.ones_like(box.lower))] + [box.variables(s) for s in starts]
    a, b = float(box.lo.min()), float(box.hi.max())
    if gap(a) >= 0:                                     # (gap(b) < 0: the loosest fails)
        points.append(uniform(brentq(gap, a, b, xtol=1e-6) - 2e-6)[box.free])
    best, best_cost = None, math.inf
    for v in points:                                    # a feasible start is an answer already
        if constraint(v) >= 0 and objective(v)[0] < best_cost:
            best, best_cost = box.scales(v), objective(v)[0]
    for x0 in points:
        result = minimize(objective, x0, jac=True, method="SLSQP", bounds=box.bounds(),
                          constraints=[{"type": "ineq", "fun": constraint,
                                        "jac": lambda v: box.probit(yield_at, v)[1]}],
                          options={"maxiter": 100, "ftol": 1e-8})
        v = np.clip(result.x, box.lo[box.free], box.hi[box.free])
        if constraint(v) >= -1e-6 and objective(v)[0] < best_cost:
            best, best_cost = box.scales(v), objective(v)[0]
    if best is None:
        raise RuntimeError("no start point meets the yield on the surrogate (give one)")
    return best


def _verify(model: ScaledModel, scales, n: int):
    """The true model's Monte Carlo at scales: (Verified, U (n, D), Y (n, M))."""
    U, Y = model.verify(np.asarray(scales, dtype=float), n)
    ok = np.all(np.isfinite(Y), axis=1)
    passes = ok.copy()
    for limit in model.limits:
        passes[ok] &= limit.passes(Y[ok, limit.column])
    evaluated, passed = int(ok.sum()), int(passes.sum())
    low, high = wilson_interval(passed, evaluated, model.confidence)
    return Verified(np.asarray(scales, dtype=float).copy(), passed, evaluated, low, high), U, Y


def _clip_yield(p: float, n: int) -> float:
    """A yield estimate kept off 0 and 1 by half a reducer, so that its probit is finite."""
    half = 0.5 / max(n, 1)
    return min(max(p, half), 1.0 - half)


def _probit(p):
    return ndtri(np.clip(p, 1e-15, 1.0 - 1e-15))


def _phi(z: float) -> float:
    return math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)


def _bar(total, label, progress):
    if progress is False:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="reducer", desc=label, file=sys.stderr, dynamic_ncols=True,
                disable=None if progress is None else not progress)


# -- the study: the reducer model wired into the core ---------------------------------------------

@dataclass(frozen=True)
class FactorAllocation:
    """One allocated tolerance: `name` is 'error.key' (e.g. crank_cam_eccentricity.position_um)."""

    name: str
    unit: str
    current: float
    allocated: float
    lower: float
    upper: float
    cost_current: float
    cost_allocated: float
    binding: str            # "none", "lower" (at its tightest) or "upper" (at its loosest)


@dataclass(frozen=True)
class YieldEstimate:
    """A Monte Carlo yield against all spec lines: estimate, Wilson interval, reducers."""

    estimate: float
    low: float
    high: float
    n: int

    @classmethod
    def of(cls, verified: Verified) -> "YieldEstimate":
        return cls(verified.estimate, verified.low, verified.high, verified.n)


@dataclass(frozen=True)
class AllocationResult:
    """The least-cost tolerances of a study for a yield target, and the evidence for them."""

    study: str
    study_file: str
    allocated_study_file: str
    target_yield: float
    feasible: bool
    factors: tuple[FactorAllocation, ...]
    total_cost_current: float
    total_cost_allocated: float
    yield_current: YieldEstimate
    yield_allocated: YieldEstimate
    surrogate_kind: str
    surrogate_samples: int
    surrogate_validation: str
    model_evaluations: int
    spec: tuple[str, ...] = ()
    confidence: float = 0.95
    rounds: tuple[Round, ...] = ()
    files: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The allocation.json document (its schema is read by the HTML report: keep it)."""
        def yield_json(y):
            return {"estimate": y.estimate, "low": y.low, "high": y.high, "n": y.n}

        return {
            "study": self.study, "study_file": self.study_file,
            "allocated_study_file": self.allocated_study_file,
            "target_yield": self.target_yield, "feasible": self.feasible,
            "factors": [{"name": f.name, "unit": f.unit, "current": f.current,
                         "allocated": f.allocated, "lower": f.lower, "upper": f.upper,
                         "cost_current": f.cost_current, "cost_allocated": f.cost_allocated,
                         "binding": f.binding} for f in self.factors],
            "total_cost": {"current": self.total_cost_current,
                           "allocated": self.total_cost_allocated},
            "yield": {"current": yield_json(self.yield_current),
                      "allocated": yield_json(self.yield_allocated)},
            "surrogate": {"kind": self.surrogate_kind, "samples": self.surrogate_samples,
                          "validation": self.surrogate_validation},
            "model_evaluations": self.model_evaluations,
        }

    def table(self) -> str:
        """The printed answer: per factor current vs allocated tolerance and cost; the yields."""
        width = max(len(f.name) for f in self.factors)
        lines = [f"allocation of {self.study} for a yield >= {self.target_yield:g} against "
                 f"{' and '.join(self.spec)} (all at once)",
                 f"{'tolerance [um]':<{width}}  {'current':>8} {'allocated':>9} {'tightest':>8} "
                 f"{'loosest':>8}  {'cost now':>9} {'allocated':>9}  binding"]
        for f in self.factors:
            lines.append(f"{f.name:<{width}}  {f.current:8.3f} {f.allocated:9.3f} {f.lower:8.3f} "
                         f"{f.upper:8.3f}  {f.cost_current:9.4g} {f.cost_allocated:9.4g}  "
                         f"{'-' if f.binding == 'none' else f.binding}")
        lines.append(f"{'total cost':<{width}}  {'':37}  {self.total_cost_current:9.4g} "
                     f"{self.total_cost_allocated:9.4g}")
        c = f"{100 * self.confidence:g} %"
        for label, y in (("current", self.yield_current), ("allocated", self.yield_allocated)):
            lines.append(f"yield, {label:<9} {y.estimate:.5f}  ({c} interval {y.low:.5f} - "
                         f"{y.high:.5f}, Monte Carlo of {y.n} reducers of the true model)")
        if self.feasible:
            lines.append(f"target {self.target_yield:g}: met by the verification's estimate")
        else:
            bound = [f"{f.name} ({'tightest' if f.binding == 'lower' else 'loosest'})"
                     for f in self.factors if f.binding != "none"]
            lines.append(f"target {self.target_yield:g}: OUT OF REACH within the bounds; the best "
                         "yield found is the one above, at the tolerances above; bounds that "
                         f"bind: {', '.join(bound) or 'none'}")
        lines.append(f"surrogate: {self.surrogate_kind}, {self.surrogate_samples} reducers; "
                     f"{self.surrogate_validation}")
        lines.append(f"model evaluations: {self.model_evaluations} in {len(self.rounds)} "
                     "verification rounds plus training and the current tolerances")
        return "\n".join(lines)


def allocate(study_path, yield_target: float = 0.9973, output=None, progress: bool | None = None,
             *, n: int | None = None, processes: int | None = None, log=None,
             yes: bool = False) -> AllocationResult:
    """The least-cost tolerances of a study file with a verified yield >= yield_target.

    The yield is that of all spec lines at once; costs and bounds come from the
    [tolerances.NAME.cost] tables (tolerance/cost.py).  n: reducers of each
    verification Monte Carlo (default the study's [montecarlo] n, at least
    MIN_HIGH_YIELD_N for a target >= HIGH_YIELD); processes: worker processes
    for those Monte Carlo runs.  Everything is stored in the output folder
    (default the study's; it must be this study's or new): the current
    tolerances' Monte Carlo as `rvte mc` would store it, the training and the
    verifications under allocation/, and `<study name>_allocated.toml` (ready
    to run: its `rvte mc` reuses the verification) and allocation.json.
    log(str) gets the progress of the search; `yes` as for `run_mc`.
    """
    from .run import _load, _warn_load
    from .store import open_output

    study = _load(study_path, output)
    target = finite_number("yield", yield_target)
    if not 0.0 < target < 1.0:
        raise InputError("yield", target, "must be between 0 and 1 (e.g. 0.9973)")
    if not study.spec:
        raise InputError("spec", None, "an allocation needs at least one spec line: give the "
                         "study a [spec] table")
    if n is None:
        n = max(study.mc_n, MIN_HIGH_YIELD_N) if target >= HIGH_YIELD else study.mc_n
    n = integer("n", n, 1)
    folder = open_output(study, study.output)
    allocated_path = folder / f"{_file_name(study.name)}_allocated.toml"
    if study.path is not None and allocated_path.resolve() == Path(study.path).resolve():
        raise InputError("output", str(folder), f"would overwrite the study file {study.path} with "
                         "its allocation: choose another output folder")
    _warn_load(study, log)
    factors = [f for f in study.factors if costs.current_um(f) > 0]   # an exact source stays exact
    if not factors:
        raise InputError("tolerances", None, "every tolerance is zero: nothing to allocate")
    wiring = _StudyWiring(study, factors, folder, progress, log, yes, processes)
    result = allocate_scales(wiring.model(), target, n, log=log, progress=progress,
                             column_names=study.metric_columns)
    return wiring.report(result, target, allocated_path)


class _StudyWiring:
    """The study's reducer model as a ScaledModel: scaled studies, computed through the store."""

    def __init__(self, study, factors, folder: Path, progress, log, yes, processes):
        self.study, self.factors, self.folder = study, factors, folder
        self.progress, self.log, self.yes, self.processes = progress, log, yes, processes
        self.models = tuple(costs.resolved(f) for f in factors)
        self.current = np.array([costs.current_um(f) for f in factors])
        self.layout = [(f, start, stop) for f, start, stop in study.layout if f in factors]

    def model(self) -> ScaledModel:
        study = self.study
        limits = tuple(Limit(study.metric_columns.index(l.column), l.limit, l.sense)
                       for l in study.spec)
        return ScaledModel(
            names=tuple(f"{f.name}.{costs.ALLOCATED[f.kind]}" for f in self.factors),
            current=self.current, costs=self.models, limits=limits,
            columns=len(study.columns), magnitudes=self.magnitudes, evaluate=self.evaluate,
            verify=self.verify, log_inputs=True, snap=self.snap, seed=study.seed,
            confidence=study.mc_confidence)

    def magnitudes(self, U: np.ndarray) -> np.ndarray:
        """RMS of each allocated factor's error values [um] at the current tolerances: (n, F)."""
        from rvfmu.core.units import UM

        from .sampling import factor_values

        out = np.empty((U.shape[0], len(self.layout)))
        for j, (factor, start, stop) in enumerate(self.layout):
            values = np.abs(factor_values(factor, self.study.design, U[:, start:stop])) / UM
            out[:, j] = np.sqrt(np.mean(values.reshape(U.shape[0], -1) ** 2, axis=1))
        return out

    def snap(self, scales: np.ndarray) -> np.ndarray:
        """Tolerances rounded down to ROUND_UM (never looser than asked), within the bounds."""
        t = np.floor(scales * self.current / ROUND_UM + 1e-9) * ROUND_UM
        low = np.array([m.tightest_um for m in self.models])
        high = np.array([m.loosest_um for m in self.models])
        return np.clip(t, low, high) / self.current

    def scaled_factors(self, scales, with_cost: bool) -> tuple:
        """The study's factors with the allocated ones at scales (their resolved costs, or none).

        The allocated tolerance is kept within its bounds to the last bit and
        written to 1e-9 um; the keys that follow it to 1e-4 um.
        """
        scaled = dict(zip((f.name for f in self.factors), zip(scales, self.models, self.current)))
        out = []
        for f in self.study.factors:
            if f.name in scaled:
                s, model, t0 = scaled[f.name]
                t = min(max(round(float(s) * t0, 9), model.tightest_um), model.loosest_um)
                values = {key: round(value, 4) for key, value in
                          costs.scaled_values(f, t / t0).items()}
                values[costs.ALLOCATED[f.kind]] = t
                f = replace(f, **values, cost=model if with_cost else None)
            out.append(f)
        return tuple(out)

    def evaluate(self, scales, U, job) -> np.ndarray:
        """Metrics of training reducers U at scales, stored in their scaled study's folder."""
        from .backends import make_backend
        from .run import compute

        study = replace(self.study, factors=self.scaled_factors(scales, False),
                        batch_size=U.shape[0], text="")
        study = replace(study, output=self.folder / "allocation" / study.inputs_hash[:12])
        computed = compute(study, job, U.shape[0], lambda a, b: U[a:b], make_backend(),
                           progress=False, output=study.output, yes=True)
        return np.where(np.isfinite(computed.Y), computed.Y, np.nan)

    def verify(self, scales, n: int):
        """The Monte Carlo of the study file with these tolerances: its `rvte mc` rows and store.

        At the current tolerances it is `rvte mc` of the study itself (summary,
        samples and worst reducer written, no figures), so that the output
        folder is ready for `rvte report`.
        """
        from . import montecarlo
        from .backends import make_backend
        from .run import compute, run_mc

        if np.all(scales == 1.0):
            result = run_mc(self.study, n, output=self.folder, processes=self.processes,
                            progress=self.progress, plots=False, log=self.log, yes=self.yes)
            return montecarlo.rows(self.study, 0, n), result.Y
        study = self.candidate(scales)[1]
        rows = math.ceil(n / study.batch_size) * study.batch_size
        computed = compute(study, "mc", rows, lambda a, b: montecarlo.rows(study, a, b),
                           make_backend(self.processes), self.progress, self.log,
                           output=study.output, yes=self.yes, size_field=("n", n))
        return montecarlo.rows(study, 0, n), computed.Y[:n]

    def candidate(self, scales, header: str = ""):
        """(text, Study) of the study file with the allocated tolerances at scales.

        The file is written beside allocation.json; its output folder is the
        verification's (allocation/<inputs hash>), so its `rvte mc` reuses it.
        """
        from .study import study_from_values

        path = self.folder / f"{_file_name(self.study.name)}_allocated.toml"
        factors = self.scaled_factors(scales, True)
        probe = replace(self.study, factors=factors)
        same = probe.inputs_hash == self.study.inputs_hash
        text = allocated_text(self.study, factors, "." if same else
                              f"allocation/{probe.inputs_hash[:12]}", header)
        study = study_from_values(tomllib.loads(text), path, text)
        assert study.inputs_hash == probe.inputs_hash, "the allocated file must be what was verified"
        return text, study

    def report(self, result: ScaleAllocation, target: float, path: Path) -> AllocationResult:
        """Write the allocated study file and allocation.json; the result record."""
        study = self.study
        factors = []
        for f, model, t0, s, lo, hi in zip(self.factors, self.models, self.current, result.scales,
                                           np.log(self.model().lower), np.log(self.model().upper)):
            t = float(s * t0)
            binding = ("lower" if abs(math.log(s) - lo) <= BINDING else
                       "upper" if abs(math.log(s) - hi) <= BINDING else "none")
            factors.append(FactorAllocation(f"{f.name}.{costs.ALLOCATED[f.kind]}", "um", float(t0),
                                            round(t, 6), float(model.tightest_um),
                                            float(model.loosest_um), float(model.cost(t0)),
                                            float(model.cost(t)), binding))
        current, allocated = result.current, result.allocated
        header = (f"Allocated by `rvte allocate` from {study.path or study.name} for a yield >= "
                  f"{target:g} against {', '.join(str(l) for l in study.spec)} (all at once).\n"
                  + (f"Verified: yield {allocated.estimate:.5f} ({100 * study.mc_confidence:g} % "
                     f"interval {allocated.low:.5f} - {allocated.high:.5f}) of {allocated.n} "
                     "reducers" if result.feasible else
                     f"OUT OF REACH within the bounds: the best yield found, {allocated.estimate:.5f} "
                     f"({allocated.low:.5f} - {allocated.high:.5f}) of {allocated.n} reducers, with "
                     "these tolerances") +
                  f"; total cost {sum(f.cost_allocated for f in factors):.4g} (was "
                  f"{sum(f.cost_current for f in factors):.4g}).\n"
                  f"Run: rvte mc {path.name} -n {allocated.n}   (reuses the verification)")
        text, _ = self.candidate(result.scales, header)
        path.write_text(text)
        record = AllocationResult(
            study=study.name, study_file=str(study.path or ""), allocated_study_file=str(path),
            target_yield=target, feasible=result.feasible, factors=tuple(factors),
            total_cost_current=float(sum(f.cost_current for f in factors)),
            total_cost_allocated=float(sum(f.cost_allocated for f in factors)),
            yield_current=YieldEstimate.of(current), yield_allocated=YieldEstimate.of(allocated),
            surrogate_kind=SURROGATE_KIND, surrogate_samples=result.samples,
            surrogate_validation=result.validation, model_evaluations=result.evaluations,
            spec=tuple(str(l) for l in study.spec), confidence=study.mc_confidence,
            rounds=result.rounds,
            files={"allocated_study": path, "allocation": self.folder / "allocation.json"})
        (self.folder / "allocation.json").write_text(json.dumps(record.to_json(), indent=1) + "\n")
        return record


def allocated_text(study, factors, output: str, header: str = "") -> str:
    """The study file of `study` with `factors`, every value explicit, paths absolute.

    Relative paths of the original are resolved (the file is written
    elsewhere); `output` is written as given (relative to the new file).
    Loading it gives the same inputs hash as replace(study, factors=factors).
    """
    errors = ""
    if study.errors_source:
        errors = Path(study.errors_source)
        if not errors.is_absolute() and study.path is not None:
            errors = Path(study.path).resolve().parent / errors
    tables = {
        "study": {"name": f"{study.name}_allocated",
                  "design": study.design_source or study.design.name,
                  "errors": str(errors) if errors else None, "seed": study.seed,
                  "metrics": list(study.metrics), "batch_size": study.batch_size,
                  "output": output},
        "operating": {"load_Nm": study.load_Nm, "points": study.points,
                      "windup_positions": study.windup_positions},
        "spec": {l.column: l.limit for l in study.spec},
        "montecarlo": {"n": study.mc_n, "confidence": study.mc_confidence},
        "sobol": {"n": study.sobol_n, "second_order": study.second_order,
                  "resamples": study.resamples, "confidence": study.sobol_confidence},
    }
    for f in factors:
        tables[f"tolerances.{f.name}"] = f.file_values()
        if f.cost is not None:
            tables[f"tolerances.{f.name}.cost"] = costs.file_values(f.cost)
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    for name, values in tables.items():
        lines += ["" if lines else None, f"[{name}]"]
        lines += [f"{key} = {_toml_value(value)}" for key, value in values.items()
                  if value is not None]
    return "\n".join(line for line in lines if line is not None) + "\n"


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)                  # a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(float(value))                 # round-trips exactly (also a numpy float)
    return str(value)


def _file_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


class _CallableModule(types.ModuleType):
    """`tolerance.allocate` is both this module and its function.

    Importing a submodule makes the package attribute of the same name the
    module (the import system sets it), which would hide the function that
    `tolerance/__init__.py` exports lazily; calling the module calls it.
    """

    def __call__(self, *args, **kwargs):
        return allocate(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule

__all__ = ["allocate", "AllocationResult", "FactorAllocation", "YieldEstimate", "ScaledModel",
           "Limit", "allocate_scales", "optimise", "Chaos", "Surrogate", "allocated_text"]
