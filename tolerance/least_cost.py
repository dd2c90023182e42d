"""Least-cost scales for a yield target, verified by Monte Carlo: `allocate_scales(model, target, n)`.

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
   Phi^-1(target) + z_conf e(target, n) + safety (e: the standard error of a
   verification of n reducers, z_conf 1.96 at 95 %); if the region holds no such point, its best
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
   safety, after PATIENCE rounds in a row that found nothing cheaper meeting
   the target (once something has met it), or after MAX_ROUNDS; the cheapest
   verified allocation wins.  Its
   yield "meets the target" when the low end of the verification's
   confidence interval (Wilson, tolerance/montecarlo.py) is at or above the
   target, not merely its estimate: an allocation that meets a 0.9973 target
   does so with 97.5 % confidence, and a second Monte Carlo of the allocated
   study agrees.
   Confirmation: the verifications share their draws (common random numbers:
   differences between allocations are not noise), so the search chooses
   among them with those draws and the chosen one's yield is flattered.  The
   answer's yield is therefore a last, fresh Monte Carlo of n reducers with
   other draws (`confirm`); if that falls short of the target, the next
   cheapest verified allocation is confirmed, up to MAX_CONFIRMATIONS.
6. Out of reach: the surrogate's best point verified short REACH_TRIES times
   (nothing having met the target): the answer is the best verified yield,
   with the bounds that bind.  Often every tolerance at its tightest, but not
   always: opening a band of tooth errors closes the designed backlash, and
   lost motion falls.

The core (`allocate_scales`) knows nothing of reducers: it takes a
`ScaledModel` (functions of scales and unit draws), so an analytic stack-up
can be allocated and checked against its closed-form solution
(tests/test_allocate.py); tolerance/allocation.py wires the study's model into it.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.special import ndtr, ndtri

from .montecarlo import wilson_interval
from .surrogate import Surrogate

TRAIN_GROUP = 16            # reducers per training scale: the model's per-call cost is ~8 reducers'
TRAIN_GROUPS_PER_FACTOR = 16
MIN_TRAIN_GROUPS = 32       # a degree-2 chaos in F scales needs (F+1)(F+2)/2 well-spread points
YIELD_DRAWS = 2 ** 14       # unit draws of the surrogate yield (scrambled Sobol', a power of 2)
LOG_FLOOR = 0.05            # of the mean error size: log inputs stay finite for a zero draw
MARGIN_START = 0.25         # probit units, before any verification (0.9973 -> 0.9985)
STOP_NOISE = 2.5            # proven: prediction and verification within this many standard errors
MAX_ROUNDS = 8              # verifications at most (each n reducers)
MAX_CONFIRMATIONS = 3       # fresh Monte Carlo runs of the cheapest verified allocations, in turn
REACH_TRIES = 2             # the surrogate's best reachable yield verified short twice: out of reach
PATIENCE = 2                # rounds in a row that find nothing cheaper meeting the target: stop
TRUST_START = 0.5           # trust region about the centre, in ln s (x1.65): the surrogate's
TRUST_MAX = 1.0             # errors differ from place to place, so its calibration only holds
TRUST_MIN = 0.05            # near where it was made; doubled when proven, halved when not
DATA_PER_POINT = 4096       # verification reducers kept for the fit (it grows with each round)
HIGH_YIELD = 0.99           # from this target on, verify with at least MIN_HIGH_YIELD_N reducers
MIN_HIGH_YIELD_N = 10000    # 27 expected failures at 0.9973: the estimate means something


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
    evaluate(s (F,), U (n, D), job) -> Y (n, M), NaN for a failed reducer;
    evaluate_groups(tasks), optional: the same for a list of (s, U, job), Y in
    order as an iterator (e.g. on worker processes).  confirm(s, n), optional:
    as verify, but other draws than every verify's: the fresh Monte Carlo whose
    yield is the answer's (the search chose among the verified points with
    verify's draws, so their yields flatter the one it chose).
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
    evaluate_groups: Callable | None = None
    confirm: Callable | None = None

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

    def meets(self, target: float) -> bool:
        """The target is met when the whole confidence interval is at or above it."""
        return self.low >= target

    def probit_noise(self) -> float:
        """Standard error of the estimate in probit units (Phi^-1 of the yield)."""
        return _binomial_probit_noise(self.estimate, self.n)


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
    confirmations: tuple[Verified, ...] = ()

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
    # what a verification of n reducers must show for the low end of its interval to reach
    # the target: the target plus z_conf binomial standard errors, in probit units
    z_need = z_target + float(ndtri(0.5 + 0.5 * model.confidence)) * _binomial_probit_noise(target, n)
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
    tasks = [(S[g], np.random.default_rng([model.seed, 0x616C6C6F, g]).random(
        (TRAIN_GROUP, model.columns)), f"allocation-train-{g}") for g in range(groups)]
    results = (model.evaluate_groups(tasks) if model.evaluate_groups is not None else
               (model.evaluate(*task) for task in tasks))
    for g, ((scales, U, _), Y) in enumerate(zip(tasks, results)):
        data.append((np.tile(scales, (TRAIN_GROUP, 1)), model.magnitudes(U), Y, g))
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
    stale = 0                                           # rounds since the cheapest met allocation
    surrogate, samples = fit(data)
    for r in range(MAX_ROUNDS):
        yield_at = lambda S, surrogate=surrogate: surrogate_yield(surrogate, S)  # noqa: E731
        centre = _centre(points, target)
        c = centre.verified.scales
        z_centre = float(_probit(yield_at(c)[0]))
        bias = z_centre - _observed(centre.verified)    # calibrate the surrogate at the centre
        met = centre.verified.meets(target)
        # never ask more of a cheaper allocation than the centre that met the target verified
        margin = bias + (min(safety, _observed(centre.verified) - z_need) if met else safety)
        goal = min(z_need + margin, z_centre) if met else z_need + margin
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
        meets = verified.meets(target)
        noise = verified.probit_noise()
        optimism = float(_probit(predicted)) - _observed(verified)   # the calibrated error
        proven = abs(optimism) <= STOP_NOISE * noise
        say(f"allocate: round {r + 1}" + (" (the surrogate's best reachable yield)" if reaching
                                          else f" (trust region x{math.exp(radius):.2f})") +
            f": margin {margin:+.3f} -> cost {points[-1].cost:.4g}, predicted "
            f"{predicted:.5f}, verified {verified.estimate:.5f} [{verified.low:.5f}, "
            f"{verified.high:.5f}] of {verified.n}" + ("" if meets else " (below the target)"))
        misses += bool(reaching and not meets)
        met_before = [done.cost for done in points[:-1] if done.verified.meets(target)]
        feasible = bool(met_before) or meets
        if misses >= REACH_TRIES and not feasible:
            break                                       # out of reach, as far as can be told
        stale = 0 if meets and (not met_before or points[-1].cost < min(met_before)) else stale + 1
        if feasible and stale >= PATIENCE:
            say(f"allocate: {PATIENCE} rounds without a cheaper allocation that meets the "
                "target: stop")
            break                                       # the surrogate finds nothing better here
        if meets and proven and safety < MARGIN_START:
            break                                       # proven, with a margin at the noise level
        radius = min(2 * radius, TRUST_MAX) if proven else max(radius / 2, TRUST_MIN)
        safety = noise if proven else max(noise, min(optimism, MARGIN_START))
        surrogate, samples = fit(data)
    rounds = tuple(points[1:])
    meeting = [done for done in points if done.verified.meets(target)]   # current included
    if not meeting:                                     # the best verified yield is the answer
        reached = _centre(points, target)
        return ScaleAllocation(reached.verified.scales, False, current, reached.verified,
                               rounds, samples, validation, evaluations)
    meeting.sort(key=lambda done: done.cost)
    if model.confirm is None:
        best = meeting[0]
        if best is not points[0]:
            validation += (f"; at the allocation: predicted {best.predicted:.5f}, verified "
                           f"{best.verified.estimate:.5f}")
        return ScaleAllocation(best.verified.scales, True, current, best.verified, rounds,
                               samples, validation, evaluations)
    # Confirmation: the cheapest verified point that met the target, on fresh draws; if
    # those fall short, the next cheapest, and so on.
    confirmations = []
    for done in meeting[:MAX_CONFIRMATIONS]:
        _, Y = model.confirm(done.verified.scales, n)
        evaluations += n
        confirmed = judge(model, done.verified.scales, Y)
        confirmations.append(confirmed)
        say(f"allocate: confirmation on fresh draws at cost {done.cost:.4g}: yield "
            f"{confirmed.estimate:.5f} [{confirmed.low:.5f}, {confirmed.high:.5f}] of "
            f"{confirmed.n}" + ("" if confirmed.meets(target) else " (below the target)"))
        if confirmed.meets(target):
            validation += (f"; at the allocation: predicted {done.predicted:.5f}, verified "
                           f"{done.verified.estimate:.5f}, confirmed on fresh draws "
                           f"{confirmed.estimate:.5f}")
            return ScaleAllocation(done.verified.scales, True, current, confirmed, rounds,
                                   samples, validation, evaluations, tuple(confirmations))
    best = max(confirmations, key=lambda c: c.estimate)
    validation += "; no verified allocation was confirmed on fresh draws"
    return ScaleAllocation(best.scales, False, current, best, rounds, samples, validation,
                           evaluations, tuple(confirmations))


def _centre(points, target: float) -> Round:
    """The verified point to search about: the cheapest that meets the target, else the one
    of highest yield (the latest of equals)."""
    meeting = [done for done in points if done.verified.meets(target)]
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
    return judge(model, scales, Y), U, Y


def judge(model: ScaledModel, scales, Y) -> Verified:
    """The yield of metrics Y (n, M) against every limit, with its interval."""
    ok = np.all(np.isfinite(Y), axis=1)
    passes = ok.copy()
    for limit in model.limits:
        passes[ok] &= limit.passes(Y[ok, limit.column])
    evaluated, passed = int(ok.sum()), int(passes.sum())
    low, high = wilson_interval(passed, evaluated, model.confidence)
    return Verified(np.asarray(scales, dtype=float).copy(), passed, evaluated, low, high)


def _binomial_probit_noise(p: float, n: int) -> float:
    """Standard error, in probit units, of a yield estimate p from n reducers."""
    p = _clip_yield(p, n)
    return float(math.sqrt(p * (1 - p) / n) / _phi(ndtri(p)))


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
