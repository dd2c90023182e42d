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
   whose gradient in ln s the chain rule gives exactly (a factor's scale moves
   its own input column only; `Surrogate.probability`), so the optimisers
   never difference it.
4. Correction.  The surrogate is fitted once, to the training alone, and
   each verified allocation tells how far off it is there: delta(s) =
   Phi^-1(surrogate yield) - Phi^-1(verified yield).  A Gaussian process over
   ln s with a fixed kernel (`Correction`: a constant, a share of the drop in
   yield the surrogate predicts, a local part) and each verification's
   binomial noise gives the mean and standard deviation of delta anywhere.
   The standard deviation grows away from the verified points: that is the
   search's trust region, with no radius to tune.
5. Optimiser (scipy).  SLSQP over ln s minimises the total cost subject to
       Phi^-1(yield) - mean(delta) - KAPPA sqrt(var(delta) + e^2) >= z_need,
   z_need = Phi^-1(target) + z_conf e (e: the probit standard error of a
   verification of n reducers at the target, z_conf 1.96 at 95 %): a plan
   that the verification will find meeting the target five times in six, if
   the correction is right.  If no allocation satisfies that (nothing is
   known to meet the target yet), the cheapest one whose corrected surrogate,
   without the margin, meets z_need is verified: it passes about half the
   time, and either way the correction learns where the answer lies; the
   allocation of highest yield would pass more often, but costs far more
   than the answer.  Where not even that exists, the allocation of highest
   yield with the margin (L-BFGS-B) is verified: the search climbs, and
   learns the surrogate's error on the way.
6. Verification.  The allocation is checked by a Monte Carlo of the true
   model: the allocated study file's own `rvte mc`, at most n reducers (the
   study's [montecarlo] n, at least MIN_HIGH_YIELD_N for a target >= 0.99), on
   draws of its own (every verification its own seed: the search never
   compares allocations on the same reducers, so it cannot pick one whose
   reducers happen to flatter it, and the verifications are independent, as
   the correction assumes).  Its yield "meets the target" when the low end of
   its confidence interval (Wilson, tolerance/montecarlo.py) is at or above
   the target, not merely its estimate: an allocation that meets a 0.9973
   target does so with 97.5 % confidence.  The verification is sequential
   (`sequential_yield`): it looks at its yield after n/16, n/8, n/4, n/2
   and n reducers (`look_sizes`; the first rows of a larger run are those of
   a smaller one) and stops at the first look whose interval lies wholly
   above or wholly below the target.  Each look's interval is at the
   confidence 1 - (1 - c) / K for K looks (Bonferroni), so that all K
   intervals hold together with confidence c, and the interval it stops on
   is a valid c-interval whichever look that is: an allocation far from the
   target is decided on a fraction of the reducers, one near it on all n.  The search stops when the next plan would
   save less than IMPROVEMENT of the cheapest allocation that met the target,
   after PATIENCE rounds in a row without a cheaper one, or after MAX_ROUNDS.
   Confirmation: the cheapest allocation that met the target was chosen
   because its Monte Carlo met it, which flatters it a little, so the
   answer's yield is one more Monte Carlo of n reducers on fresh draws; if
   that falls short of the target, the next cheapest verified allocation is
   confirmed, up to MAX_CONFIRMATIONS.
7. Out of reach: the best point verified short REACH_TRIES times, the
   hopeful surrogate (KAPPA deviations above) short of the target there too
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

TRAIN_GROUP = 16  # reducers per training scale: the model's per-call cost is ~8 reducers'
TRAIN_GROUPS_PER_FACTOR = 16
MIN_TRAIN_GROUPS = 32  # a degree-2 chaos in F scales needs (F+1)(F+2)/2 well-spread points
YIELD_DRAWS = 2**14  # unit draws of the surrogate yield (scrambled Sobol', a power of 2)
LOG_FLOOR = 0.05  # of the mean error size: log inputs stay finite for a zero draw
YIELD_CLIP = 1e-15  # a yield is kept this far off 0 and 1 before its probit
MAX_ROUNDS = 8  # verifications at most (each n reducers)
MAX_CONFIRMATIONS = 3  # fresh Monte Carlo runs of the cheapest verified allocations, in turn
REACH_TRIES = 2  # the best reachable yield verified short twice: out of reach
PATIENCE = 2  # rounds in a row that find nothing cheaper meeting the target: stop
IMPROVEMENT = 0.01  # stop when the next allocation would save less than this share
KAPPA = 1.65  # standard deviations of margin the search plans with (95 %)
CORRECTION_CONSTANT = 0.2  # the surrogate's error (Correction), probit units: a constant,
CORRECTION_SLOPE = 0.3  # a share of the drop in yield it predicts,
CORRECTION_LOCAL = 0.2  # and a local part,
CORRECTION_LENGTH = 0.5  # correlated over this change of ln s per factor (x1.65)
HIGH_YIELD = 0.99  # from this target on, verify with at least MIN_HIGH_YIELD_N reducers
MIN_HIGH_YIELD_N = 10000  # 27 expected failures at 0.9973: the estimate means something
LOOKS = 5  # a verification looks at its yield after n/16, n/8, n/4, n/2 and n reducers
MIN_LOOK = 500  # and never after fewer than this (nor on a part of a block)


# -- the problem the core sees ----------------------------------------------------------------


@dataclass(frozen=True)
class Limit:
    """A spec line on metric column `column` of Y: value <= limit ('max') or >= limit ('min')."""

    column: int
    limit: float
    sense: str

    def passes(self, values):
        """(n,) bool: which of `values` (n,), in the column's unit, meet this spec line."""
        return values <= self.limit if self.sense == "max" else values >= self.limit


@dataclass(frozen=True)
class ScaledModel:
    """F factors whose errors scale with s (F,) and a true model of M metrics.

    current (F,): the tolerances at s = 1; costs: one resolved CostModel per
    factor (bounds in the same unit as current).  magnitudes(U (n, D)) -> (n, F):
    each factor's error size in each draw at s = 1 (>= 0 if log_inputs).
    evaluate(s (F,), U (n, D), job) -> Y (n, M), NaN for a failed reducer;
    evaluate_groups(tasks), optional: the same for a list of (s, U, job), Y in
    order as an iterator (e.g. on worker processes).
    verify(s, n, draw) -> Y (n, M): the Monte Carlo that judges an
    allocation, on the draw-th set of unit draws (0: the study's own; each
    other number independent of every other: the search never judges two
    allocations on the same reducers, so it cannot pick one whose draws
    happen to flatter it; the first rows of a larger n are those of a smaller
    one, which a sequential verification relies on).  snap(s) -> the scales that
    will be written (rounding).  block: the verification's n rounds up to whole
    blocks of this many reducers (the study's batches), which it reuses.
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
    block: int = 1  # verify's n is best a multiple of this (its batches: see look_sizes)

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
    """A Monte Carlo of the true model at scales s, on draws number `draw`: passed of n reducers
    (finite metrics)."""

    scales: np.ndarray
    passed: int
    n: int
    low: float
    high: float
    draw: int = 0

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
    looks: tuple[int, ...] = ()  # the reducers after which each verification looked


# -- the core: scales -> cheapest verified allocation ---------------------------------------------


def allocate_scales(
    model: ScaledModel,
    target: float,
    n: int,
    *,
    groups: int | None = None,
    draws: int = YIELD_DRAWS,
    log=None,
    progress: bool | None = False,
    column_names: tuple[str, ...] | None = None,
    looks: int = LOOKS,
) -> ScaleAllocation:
    """The least-cost scales with a verified yield >= target (module docstring, steps 1-7).

    n: reducers of each verification Monte Carlo at most; looks: the
    sequential verification's looks at most (1: every verification is one
    Monte Carlo of n reducers); groups: training groups of TRAIN_GROUP reducers
    (default max(MIN_TRAIN_GROUPS, TRAIN_GROUPS_PER_FACTOR * F)).
    """
    say = log or (lambda text: None)
    F = len(model.names)
    lower, upper = model.lower, model.upper
    ones = np.ones(F)
    z_target = float(ndtri(target))
    sizes = look_sizes(n, model.block, looks)
    level = look_confidence(model.confidence, len(sizes))
    # what a verification of n reducers must show for the low end of its interval to reach
    # the target: the target plus z_conf binomial standard errors, in probit units
    z_need = z_target + float(ndtri(0.5 + 0.5 * level)) * _binomial_probit_noise(target, n)
    evaluations = 0
    data = []  # (scales (k, F), R (k, F), Y (k, M), training group)

    def verify(scales, draw) -> Verified:
        """The sequential verification at scales on draws number `draw` (counted)."""
        nonlocal evaluations
        verified, rows = sequential_yield(model, scales, target, sizes, draw, level)
        evaluations += rows
        return verified

    current = verify(ones, 0)
    say(
        f"allocate: current tolerances: yield {current.estimate:.5f} "
        f"[{current.low:.5f}, {current.high:.5f}] of {current.n}"
        + (f" (verifications look after {', '.join(map(str, sizes))} reducers)" if len(sizes) > 1 else "")
    )

    groups = groups or max(MIN_TRAIN_GROUPS, TRAIN_GROUPS_PER_FACTOR * F)
    from scipy.stats import qmc

    box = qmc.LatinHypercube(d=F, seed=np.random.default_rng([model.seed, 1])).random(groups)
    S = np.exp(np.log(lower) + (np.log(upper) - np.log(lower)) * box)
    bar = _bar(groups * TRAIN_GROUP, "allocate training", progress)
    tasks = [
        (
            S[g],
            np.random.default_rng([model.seed, 0x616C6C6F, g]).random((TRAIN_GROUP, model.columns)),
            f"allocation-train-{g}",
        )
        for g in range(groups)
    ]
    results = (
        model.evaluate_groups(tasks)
        if model.evaluate_groups is not None
        else (model.evaluate(*task) for task in tasks)
    )
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

    held = [row for row in data if row[3] % 5 == 0]
    surrogate, _ = fit([row for row in data if row[3] % 5 != 0])
    Zh = np.concatenate([inputs(s, R) for s, R, _, _ in held])
    Yh = np.concatenate([Y for _, _, Y, _ in held])
    ok = np.all(np.isfinite(Yh), axis=1)
    validation = f"held-out training groups ({ok.sum()} reducers): " + surrogate.check(Zh[ok], Yh[ok])
    if column_names:
        for j, name in enumerate(column_names):
            validation = validation.replace(f"column {j}:", f"{name}:")
    say(f"allocate: surrogate validation, {validation}")

    surrogate, samples = fit(data)

    def surrogate_probit(S, gradient=False):
        """The uncorrected surrogate's Phi^-1(yield) at each row of scales S (m, F), and with
        `gradient` its gradient with respect to ln s (m, F), by the chain rule: a factor's
        scale moves its own input column only."""
        S = np.atleast_2d(S)
        z, dz = np.empty(len(S)), np.zeros(S.shape)
        for k, s in enumerate(S):
            Z = inputs(s, R_yield)
            if not gradient:
                z[k] = _probit(surrogate.probability(Z).mean())
                continue
            p, dp = surrogate.probability(Z, gradient=True)
            size = s * R_yield
            dZ = size / (size + floor) if model.log_inputs else Z  # dZ / d ln s
            y = p.mean()
            z[k] = _probit(y)
            if YIELD_CLIP < y < 1.0 - YIELD_CLIP:
                dz[k] = (dp * dZ).mean(axis=0) / _phi(z[k])
        return (z, dz) if gradient else z

    z_now = float(surrogate_probit(ones)[0])

    # Every Monte Carlo of the true model, each on draws of its own: the current tolerances,
    # one per round (`points`, as Rounds), and the confirmations; all of them teach the
    # correction.  e: the probit standard error of a Monte Carlo of n reducers at the target.
    points = [Round(float("nan"), float("nan"), current, float(model.cost(ones).sum()))]
    every = [current]
    confirmations, refuted = [], set()
    e = _binomial_probit_noise(target, n)
    draw, misses, stale = 1, 0, 0

    def monte_carlo(scales) -> Verified:
        """The true model's Monte Carlo of at most n reducers at scales, on the next draws of
        its own."""
        nonlocal draw
        verified = verify(scales, draw)
        draw += 1
        every.append(verified)
        return verified

    while True:
        correction = Correction(every, surrogate_probit, z_now)

        def cautious(S, gradient=False, correction=correction):
            """Phi^-1 of the yield the search plans with: KAPPA standard deviations below the
            corrected surrogate (its own uncertainty and that of the Monte Carlo that will
            judge it); with `gradient`, also its gradient in ln s."""
            return correction.planned(S, -KAPPA, e * e, gradient)

        def expected(S, gradient=False, correction=correction):
            return correction.planned(S, 0.0, 0.0, gradient)

        def hopeful(S, gradient=False, correction=correction):
            return correction.planned(S, KAPPA, 0.0, gradient)

        candidates = [k for k, done in enumerate(points) if done.verified.meets(target) and k not in refuted]
        rounds_left = len(points) - 1 < MAX_ROUNDS
        # patience runs out only with a candidate better than the current tolerances
        cost, again, reaching, expecting = math.inf, False, False, False
        stuck = stale >= PATIENCE and any(k > 0 for k in candidates)
        if rounds_left:
            verified_scales = [done.verified.scales for done in points]
            reach, z_reach = best_reachable(model, cautious, [lower, ones, upper] + verified_scales)
            reaching = z_reach < z_need
            if reaching:
                # nothing meets the target for sure yet: the cheapest allocation the corrected
                # surrogate expects to meet it, or else the best the search can count on (it
                # climbs); out of reach when even the hopeful surrogate misses there
                likely, z_likely = best_reachable(model, expected, [reach])
                expecting = z_likely >= z_need
                if expecting:
                    scales = optimise(model, expected, z_need, [likely])
                else:
                    scales = reach
                    hope = best_reachable(model, hopeful, [reach])[1]
            else:
                scales = optimise(
                    model, cautious, z_need, [reach] + [points[k].verified.scales for k in candidates]
                )
            scales = model.snap(scales)
            cost = float(model.cost(scales).sum())
            again = any(np.array_equal(scales, done.verified.scales) for done in points)
        best = min(candidates, key=lambda k: points[k].cost, default=None)
        search_over = (
            not rounds_left
            or again
            or stuck
            or (best is not None and cost >= (1.0 - IMPROVEMENT) * points[best].cost)
        )
        if search_over:
            if best is None or len(confirmations) >= MAX_CONFIRMATIONS:
                break
            if rounds_left:
                say(
                    f"allocate: the next allocation would cost {cost:.4g}"
                    + (
                        ", one already verified"
                        if again
                        else f": {PATIENCE} rounds without a cheaper one that meets the target"
                        if stuck
                        else f", no less than the cheapest verified one ({points[best].cost:.4g})"
                    )
                )
            # Confirmation: that allocation was chosen because its Monte Carlo met the target,
            # which flatters it a little: the answer's yield is a fresh one
            done = points[best]
            confirmed = monte_carlo(done.verified.scales)
            confirmations.append(confirmed)
            say(
                f"allocate: confirmation on fresh draws at cost {done.cost:.4g}: yield "
                f"{confirmed.estimate:.5f} [{confirmed.low:.5f}, {confirmed.high:.5f}] of "
                f"{confirmed.n}"
                + ("" if confirmed.meets(target) else " (below the target: the search goes on)")
            )
            if confirmed.meets(target):
                validation += (
                    f"; at the allocation: predicted {done.predicted:.5f}, verified "
                    f"{done.verified.estimate:.5f}, confirmed on fresh draws "
                    f"{confirmed.estimate:.5f}"
                    if best
                    else "; the current tolerances are the cheapest that met the target"
                )
                return ScaleAllocation(
                    done.verified.scales,
                    True,
                    current,
                    confirmed,
                    tuple(points[1:]),
                    samples,
                    validation,
                    evaluations,
                    tuple(confirmations),
                    sizes,
                )
            refuted.add(best)
            stale = 0
            continue
        z, mean, var = (float(v[0]) for v in correction.at(scales[None]))
        predicted = float(ndtr(z - mean))
        verified = monte_carlo(scales)
        points.append(Round(float(KAPPA * math.sqrt(var + e * e)), predicted, verified, cost))
        meets = verified.meets(target)
        say(
            f"allocate: round {len(points) - 1}"
            + (
                " (the cheapest the corrected surrogate expects to meet the target)"
                if expecting
                else " (the best yield the search can count on)"
                if reaching
                else ""
            )
            + f": cost {cost:.4g}, predicted {predicted:.5f} (+/- {math.sqrt(var):.3f} probit), "
            f"verified {verified.estimate:.5f} [{verified.low:.5f}, {verified.high:.5f}] of "
            f"{verified.n}" + ("" if meets else " (below the target)")
        )
        misses += bool(reaching and not expecting and not meets and hope < z_target)
        if misses >= REACH_TRIES and not candidates and not meets:
            break  # out of reach, as far as can be told
        cheaper = meets and all(cost < points[k].cost for k in candidates)
        stale = 0 if cheaper else stale + bool(candidates or meets)
    rounds = tuple(points[1:])
    if confirmations:
        best = max(confirmations, key=lambda c: c.estimate)
        validation += "; no verified allocation was confirmed on fresh draws"
        return ScaleAllocation(
            best.scales,
            False,
            current,
            best,
            rounds,
            samples,
            validation,
            evaluations,
            tuple(confirmations),
            sizes,
        )
    reached = max(reversed(points), key=lambda done: done.verified.estimate)
    return ScaleAllocation(
        reached.verified.scales,
        False,
        current,
        reached.verified,
        rounds,
        samples,
        validation,
        evaluations,
        (),
        sizes,
    )


class Correction:
    """The surrogate's error in probit units, learnt from the verified points.

    delta(s) = z_S(s) - Phi^-1(verified yield at s), a Gaussian process over
    x = ln s with a fixed kernel (no hyperparameters are fitted to a handful of
    points) and each verification's binomial noise:
        k(x, x') = A^2 + B^2 d(x) d(x') + C^2 exp(-|x - x'|^2 / (2 F L^2)),
    d(x) = z_S(current) - z_S(x), the drop in yield the surrogate predicts.  A:
    a constant error; B: the surrogate's sensitivity off by a fraction (its
    drop too small or too large, the commonest error of a smoothed model); C, L:
    what is left, local (L in ln s per factor).  Away from every verified point
    the standard deviation grows, so the search asks for more margin there:
    that is its trust region.  A handful of points: a Cholesky solve of
    scipy's does it.
    """

    def __init__(self, verified, surrogate_probit, z_now: float):
        from scipy.linalg import cho_factor, cho_solve

        self.surrogate_probit, self.z_now = surrogate_probit, z_now
        S = np.array([v.scales for v in verified])
        self.X = np.log(S)
        z = surrogate_probit(S)
        self.d = z_now - z
        delta = z - np.array([_observed(v) for v in verified])
        noise = np.array([v.probit_noise() for v in verified]) ** 2
        self.factor = cho_factor(self._kernel(self.X, self.d, self.X, self.d) + np.diag(noise))
        self._solve = lambda b: cho_solve(self.factor, b)
        self.weights = self._solve(delta)

    def _kernel(self, X1, d1, X2, d2):
        F = X1.shape[1]
        squared = ((X1[:, None, :] - X2[None, :, :]) ** 2).sum(axis=2)
        return (
            CORRECTION_CONSTANT**2
            + CORRECTION_SLOPE**2 * np.outer(d1, d2)
            + CORRECTION_LOCAL**2 * np.exp(-squared / (2.0 * F * CORRECTION_LENGTH**2))
        )

    def at(self, S, gradient=False):
        """(z_S, mean of delta, variance of delta) at each row of scales S (m, F); with
        `gradient`, followed by their gradients with respect to ln s (each (m, F))."""
        S = np.atleast_2d(S)
        x = np.log(S)
        if gradient:
            z, dz = self.surrogate_probit(S, gradient=True)
        else:
            z = self.surrogate_probit(S)
        d = self.z_now - z
        k = self._kernel(x, d, self.X, self.d)  # (m, k)
        prior = CORRECTION_CONSTANT**2 + CORRECTION_SLOPE**2 * d * d + CORRECTION_LOCAL**2
        solved = self._solve(k.T)  # (k, m)
        var = prior - np.einsum("ij,ji->i", k, solved)
        if not gradient:
            return z, k @ self.weights, np.maximum(var, 0.0)
        F = x.shape[1]
        local = np.exp(
            -((x[:, None, :] - self.X[None]) ** 2).sum(axis=2) / (2.0 * F * CORRECTION_LENGTH**2)
        )  # (m, k)
        # dk / dx: the slope part through d = z_now - z_S, the local part through x
        dk = -(CORRECTION_SLOPE**2) * self.d[None, :, None] * dz[:, None, :] - CORRECTION_LOCAL**2 * local[
            ..., None
        ] * (x[:, None, :] - self.X[None]) / (F * CORRECTION_LENGTH**2)  # (m, k, F)
        d_mean = np.einsum("mkf,k->mf", dk, self.weights)
        d_var = -2.0 * CORRECTION_SLOPE**2 * d[:, None] * dz - 2.0 * np.einsum("mkf,km->mf", dk, solved)
        d_var[var <= 0.0] = 0.0
        return z, k @ self.weights, np.maximum(var, 0.0), dz, d_mean, d_var

    def planned(self, S, kappa: float, extra: float, gradient=False):
        """z_S - mean(delta) + kappa sqrt(var(delta) + extra) at each row of S (m,), the
        corrected surrogate's Phi^-1(yield) shifted by kappa standard deviations; with
        `gradient`, also its gradient with respect to ln s (m, F)."""
        if not gradient:
            z, mean, var = self.at(S)
            return z - mean + kappa * np.sqrt(var + extra)
        z, mean, var, dz, d_mean, d_var = self.at(S, gradient=True)
        spread = np.sqrt(var + extra)
        d_spread = np.where(spread > 0.0, 0.5 / np.maximum(spread, 1e-300), 0.0)[:, None] * d_var
        return z - mean + kappa * spread, dz - d_mean + kappa * d_spread


def _observed(verified: Verified) -> float:
    """Phi^-1 of a verified yield (kept off 0 and 1 by half a reducer)."""
    return float(_probit(_clip_yield(verified.estimate, verified.n)))


class _Box:
    """A box of scales in ln s, within the bounds; factors whose bounds coincide are held there."""

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

    def probit(self, probit_at, v) -> tuple[float, np.ndarray]:
        """Phi^-1 of the yield at v and its gradient in v."""
        z, dz = probit_at(self.scales(v)[None], gradient=True)
        return float(z[0]), dz[0, self.free]


def best_reachable(model: ScaledModel, probit_at, starts, lower=None, upper=None) -> tuple[np.ndarray, float]:
    """The scales (F,) of the highest yield within [lower, upper] (default the bounds), and
    its probit: scipy's L-BFGS-B over ln s from each start (scales (F,)), the best kept.

    probit_at(S (m, F), gradient=False) -> Phi^-1 of the yield (m,), and with
    `gradient` also its gradient with respect to ln s (m, F)."""
    from scipy.optimize import minimize

    box = _Box(model, lower, upper)
    if not box.free.any():
        return box.lower.copy(), float(probit_at(box.lower[None])[0])
    best, best_z = None, -math.inf
    for start in starts:
        result = minimize(
            lambda v: tuple(-x for x in box.probit(probit_at, v)),
            box.variables(start),
            jac=True,
            method="L-BFGS-B",
            bounds=box.bounds(),
            options={"maxiter": 50},
        )
        for v in (box.variables(start), np.clip(result.x, box.lo[box.free], box.hi[box.free])):
            z = float(probit_at(box.scales(v)[None])[0])
            if z > best_z:
                best, best_z = box.scales(v), z
    return best, best_z


def optimise(model: ScaledModel, probit_at, wanted: float, starts=(), lower=None, upper=None) -> np.ndarray:
    """Least-cost scales (F,) in [lower, upper] (default the bounds) with
    probit_at(s) >= wanted, by SLSQP over ln s.

    probit_at: Phi^-1 of the yield, as for `best_reachable`; starts: scales (F,) to start from besides the
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
        return float(probit_at(box.scales(v)[None])[0] - wanted)

    def uniform(log_scale):
        return np.clip(np.full(box.lo.size, log_scale), box.lo, box.hi)

    def gap(log_scale):
        return float(probit_at(np.exp(uniform(log_scale))[None])[0] - wanted)

    if constraint(box.variables(box.upper)) >= 0:
        return box.upper.copy()
    points = [box.variables(np.ones_like(box.lower))] + [box.variables(s) for s in starts]
    a, b = float(box.lo.min()), float(box.hi.max())
    if gap(a) >= 0:  # (gap(b) < 0: the loosest fails)
        points.append(uniform(brentq(gap, a, b, xtol=1e-6) - 2e-6)[box.free])
    best, best_cost = None, math.inf
    for v in points:  # a feasible start is an answer already
        if constraint(v) >= 0 and objective(v)[0] < best_cost:
            best, best_cost = box.scales(v), objective(v)[0]
    for x0 in points:
        result = minimize(
            objective,
            x0,
            jac=True,
            method="SLSQP",
            bounds=box.bounds(),
            constraints=[{"type": "ineq", "fun": constraint, "jac": lambda v: box.probit(probit_at, v)[1]}],
            options={"maxiter": 100, "ftol": 1e-8},
        )
        v = np.clip(result.x, box.lo[box.free], box.hi[box.free])
        if constraint(v) >= -1e-6 and objective(v)[0] < best_cost:
            best, best_cost = box.scales(v), objective(v)[0]
    if best is None:
        raise RuntimeError("no start point meets the yield on the surrogate (give one)")
    return best


def look_sizes(n: int, block: int = 1, looks: int = LOOKS) -> tuple[int, ...]:
    """The reducers after which a verification of at most n looks at its yield.

    n / 2^j for j < looks, each rounded up to whole blocks (so that the next
    look reuses every batch of this one) and kept if at least MIN_LOOK and
    below n; then n itself.  n = 10 000 in blocks of 64: 640, 1280, 2560,
    5056, 10 000.
    """
    sizes = {n}
    for j in range(1, looks):
        size = -(-math.ceil(n / 2**j) // block) * block
        if MIN_LOOK <= size < n:
            sizes.add(size)
    return tuple(sorted(sizes))


def look_confidence(confidence: float, looks: int) -> float:
    """The confidence of each look's interval for `looks` looks to hold together with
    `confidence` (Bonferroni: the chance that any of them misses the yield is at most
    looks x (1 - this))."""
    return 1.0 - (1.0 - confidence) / looks


def sequential_yield(
    model: ScaledModel, scales, target: float, sizes, draw: int, level: float
) -> tuple[Verified, int]:
    """(the verification, the reducers it ran): the true model's Monte Carlo at scales on
    draws number `draw`, looking after each of `sizes` reducers and stopping at the first
    look whose interval (at `level`) lies wholly above or wholly below the target."""
    scales = np.asarray(scales, dtype=float)
    for size in sizes:
        verified = judge(model, scales, model.verify(scales, size, draw), draw, level)
        if verified.low >= target or verified.high < target:
            break
    return verified, size


def judge(model: ScaledModel, scales, Y, draw: int = 0, confidence: float | None = None) -> Verified:
    """The yield of metrics Y (n, M) against every limit, with its interval at `confidence`
    (default the model's)."""
    ok = np.all(np.isfinite(Y), axis=1)
    passes = ok.copy()
    for limit in model.limits:
        passes[ok] &= limit.passes(Y[ok, limit.column])
    evaluated, passed = int(ok.sum()), int(passes.sum())
    low, high = wilson_interval(passed, evaluated, model.confidence if confidence is None else confidence)
    return Verified(np.asarray(scales, dtype=float).copy(), passed, evaluated, low, high, draw)


def _binomial_probit_noise(p: float, n: int) -> float:
    """Standard error, in probit units, of a yield estimate p from n reducers."""
    p = _clip_yield(p, n)
    return float(math.sqrt(p * (1 - p) / n) / _phi(ndtri(p)))


def _clip_yield(p: float, n: int) -> float:
    """A yield estimate kept off 0 and 1 by half a reducer, so that its probit is finite."""
    half = 0.5 / max(n, 1)
    return min(max(p, half), 1.0 - half)


def _probit(p):
    return ndtri(np.clip(p, YIELD_CLIP, 1.0 - YIELD_CLIP))


def _phi(z: float) -> float:
    return math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)


def _bar(total, label, progress):
    if progress is False:
        return None
    from tqdm import tqdm

    return tqdm(
        total=total,
        unit="reducer",
        desc=label,
        file=sys.stderr,
        dynamic_ncols=True,
        disable=None if progress is None else not progress,
    )
