"""te_pp of a TE curve from fewer equilibria: a coarse pass, then refinement around the extremes.

te_pp is the largest minus the smallest TE over the P input angles of one
output revolution (`quasistatic.input_angles`).  Only the angles that can hold
the grid's largest or smallest value matter, so this module solves every
`stride`-th angle first and then refines (solves every angle of) each coarse
interval that could still hold a value beyond the extremes found so far.  The
answer is the max - min over the SAME P-point grid as `te_curve` (the solves
of the angles it picks are the same equilibria), not an estimate of a
continuous maximum.

When is refinement complete?  An unrefined interval between coarse values a
and b is taken to hold nothing above max(a, b) + E nor below min(a, b) - E,
where E = safety x the largest excess observed so far in this reducer's
refined intervals (the interior's max over max(a, b), or min(a, b) over the
interior's min).  The observed excesses come from `pilot` intervals spread
evenly over the revolution plus the intervals beside the coarse extremes, and
grow as refinement goes on.  Rounds repeat until no unrefined interval's bound
reaches beyond the current max or min with the current E; every round refines
at least one interval, so it ends.

That rule is statistical, not a proof: E is estimated from a sample of
intervals, and a feature narrower than the stride whose excess is more than
safety x every excess seen is missed.  The no-load TE of the RV-40E-121 with
bearing clearances at 3200 points is not resolved at the grid's scale
(studies/benchmarks/bench_angles.py, 28 reducers of rv40e_121_full): the
floating parts change contacts in steps, a single grid step reaches 12-84
arcsec where the median step is 0.6-1.5 arcsec, the grid's extremes sit on
features 1-5 points wide, and the coarse extremes at stride 2 already lie up to
1361 grid points away from the true ones.  With the default settings no reducer
was missed (within 1e-6 arcsec) and 61-73 % of the solves were needed (0.8-0.95
of the full curve's time); looser ones missed by up to 18.6 arcsec.  So the
gain is a third at most, not a large fraction.  `AdaptiveTEPP.excess_bound_arcsec`
says what E each reducer ended with.

Where the rule misses: a preloaded reducer without clearance at no load, whose TE
jumps at single angles where its contacts change (docs/model.md section 5).  On
studies/quick_mc.toml's reducers (the calibrated RV-40E-121, seed 1's Monte Carlo rows)
with the default settings, at 3200 points 4 of 48 reducers came out short by 0.07-1.2
arcsec with 56 % of the solves, and at the study's 720 points, where the pin-passing
ripple aliases and neighbouring grid points are all but unrelated, 2 of 256 by 0.7 and
1.2 arcsec with 99 % of them.  Such a curve gives no interval a bound that a narrower
spike must respect; its te_pp takes the full curve (`quasistatic.te_curve`), which is
what every study does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..base.checks import InputError, finite_number, integer
from ..base.units import rad_to_arcsec
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet, zero_errors
from ..reducer.limits import check_load
from .equivalent import EquivalentModel
from .quasistatic import NO_LOAD_PROBE, input_angles
from .solver import solve_pairs

STRIDE = 4  # coarse pass: every 4th angle.  On rows 0-11 of rv40e_121_full (no load,
# 3200 points) strides 2, 4 and 8 need 59 %, 61 % and 93 % of the solves
# at safety 2 with the pilot, none missed; on rows 100-115 stride 2 misses
# 2 of 16, stride 4 none (bench_angles.py).
SAFETY = 2.0  # x the largest excess seen: at 1.5, stride 4, 49 % and 63 % of the solves
# but 1 of rows 100-115 missed
PILOT = 64  # intervals refined up front, evenly spread: without them the excess is
# seen only beside the coarse extremes, and 1-8 reducers of 12 or 16 are
# missed at every stride and safety tried


@dataclass(frozen=True)
class AdaptiveTEPP:
    """Grid extremes of S reducers' TE found by refinement, each array (S,).

    te_pp_arcsec, te_max_arcsec, te_min_arcsec [arcsec] over the P-point grid;
    argmax, argmin: grid indices (0 ... P-1) of the extremes; solves: equilibria
    solved per reducer (P for a full curve); excess_bound_arcsec: E of the final
    round [arcsec]; converged: every solved angle converged.  points: P;
    stride, safety, pilot: the rule's settings; rounds: solve calls made.
    """

    te_max_arcsec: np.ndarray
    te_min_arcsec: np.ndarray
    argmax: np.ndarray
    argmin: np.ndarray
    solves: np.ndarray
    excess_bound_arcsec: np.ndarray
    converged: np.ndarray
    points: int
    stride: int
    safety: float
    pilot: int
    rounds: int

    @property
    def te_pp_arcsec(self) -> np.ndarray:
        return self.te_max_arcsec - self.te_min_arcsec


def check_rule(points, stride, safety, pilot, where: str = "") -> tuple[int, int, float, int]:
    """(points, stride, safety, pilot) checked: points >= 8; stride from 2 to points // 2;
    safety finite and >= 1; pilot >= 0 (more than the coarse intervals means all of them)."""
    points = integer("points", points, 8, where=where)
    stride = integer("stride", stride, 2, points // 2, where=where)
    safety = finite_number("safety", safety, where)
    if safety < 1.0:
        raise InputError("safety", safety, "must be >= 1 (a factor on the largest excess seen)", where)
    pilot = integer("pilot", pilot, 0, where=where)
    return points, stride, safety, pilot


def refine_extremes(
    solve: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    samples: int,
    points: int,
    stride: int = STRIDE,
    safety: float = SAFETY,
    pilot: int = PILOT,
) -> AdaptiveTEPP:
    """The grid max and min of S periodic curves of P points, solving as few points as the rule
    of the module docstring allows.

    solve(sample, index) -> (values [arcsec], converged), each (B,), for B pairs of reducer
    and grid index, sorted by reducer then index.  Pure bookkeeping on (S, P) arrays.
    """
    samples = integer("samples", samples, 1)
    points, stride, safety, pilot = check_rule(points, stride, safety, pilot)
    S, P = samples, points
    starts = np.arange(0, P, stride)  # (n,) first index of each interval
    n = starts.size
    ends = np.roll(starts, -1)  # (n,) its right end, periodic
    interval = np.arange(P) // stride  # (P,) interval of each index
    te = np.full((S, P), np.nan)
    known = np.zeros((S, P), dtype=bool)
    ok = np.ones(S, dtype=bool)

    def run(need):
        s, a = np.nonzero(need & ~known)
        if s.size:
            values, converged = solve(s, a)
            te[s, a] = values
            known[s, a] = True
            np.logical_and.at(ok, s, np.asarray(converged, dtype=bool))

    coarse = np.zeros((S, P), dtype=bool)
    coarse[:, starts] = True
    run(coarse)
    left, right = te[:, starts], te[:, ends]  # (S, n)
    hi, lo = np.maximum(left, right), np.minimum(left, right)
    picked = np.zeros((S, n), dtype=bool)  # intervals to refine this round
    if pilot:
        picked[:, np.unique(np.linspace(0, n, min(pilot, n), endpoint=False).astype(int))] = True
    for extreme in (np.argmax(left, axis=1), np.argmin(left, axis=1)):
        # the coarse extreme's two intervals
        picked[np.arange(S), extreme] = True
        picked[np.arange(S), (extreme - 1) % n] = True
    refined = np.zeros((S, n), dtype=bool)
    excess = np.zeros(S)
    rounds = 1
    while picked.any():
        rounds += 1
        refined |= picked
        run(picked[:, interval])
        block_max = np.maximum.reduceat(np.where(known, te, -np.inf), starts, axis=1)
        block_min = np.minimum.reduceat(np.where(known, te, np.inf), starts, axis=1)
        seen = np.where(refined, np.maximum(block_max - hi, lo - block_min), 0.0)
        excess = safety * np.maximum(seen.max(axis=1), 0.0)
        top = np.max(np.where(known, te, -np.inf), axis=1)[:, None]
        bottom = np.min(np.where(known, te, np.inf), axis=1)[:, None]
        bound = excess[:, None]
        picked = ~refined & ((hi + bound > top) | (lo - bound < bottom))
    argmax = np.argmax(np.where(known, te, -np.inf), axis=1)
    argmin = np.argmin(np.where(known, te, np.inf), axis=1)
    reducer = np.arange(S)
    return AdaptiveTEPP(
        te[reducer, argmax],
        te[reducer, argmin],
        argmax,
        argmin,
        known.sum(axis=1),
        excess,
        ok,
        P,
        stride,
        safety,
        pilot,
        rounds,
    )


def te_pp_adaptive(
    design: RVDesign,
    errors: ErrorSet | None = None,
    tau_load: float = 0.0,
    points: int = 3200,
    stride: int = STRIDE,
    safety: float = SAFETY,
    pilot: int = PILOT,
) -> AdaptiveTEPP:
    """te_pp over `points` input angles (`input_angles`) of every reducer in `errors` at output
    torque tau_load [N*m] (docs/model.md section 2 sign; 0: no load), by `refine_extremes`.

    Each solved angle is the equilibrium `quasistatic.equilibria` finds there (the same
    pairs solver, model and no-load limit from a resisting probe), to round-off: the
    solver's warm starts differ (4e-12 arcsec on te_pp measured); only which angles are
    solved differs.  See the module docstring for what the rule guarantees and what not.
    """
    errors = zero_errors(design) if errors is None else errors.check(design)
    tau_load = finite_number("tau_load", tau_load)
    check_load("tau_load", tau_load, design.rated_torque)
    points, stride, safety, pilot = check_rule(points, stride, safety, pilot)
    theta_in = input_angles(design, points)
    # as `equilibria`: a resisting or zero load closes flank +1, a driving one flank -1
    flank = -1 if tau_load > 0 else 1
    probe = NO_LOAD_PROBE * design.rated_torque

    def solve(sample, angle):
        # A model over this round's angles only: neighbouring grid angles get neighbouring
        # indices there, so the solver starts each from the one before (`newton.chain_links`);
        # over the whole grid the coarse pass's would never be (it took 1.5 x as long).
        used, index = np.unique(angle, return_inverse=True)
        model = EquivalentModel(design, theta_in[used], flank=flank)
        eq = solve_pairs(model, errors, sample, index.ravel(), tau_load, no_load_probe=probe)
        te = model.output_angle(eq.q, np.full(sample.size, tau_load))
        return rad_to_arcsec(te), eq.converged

    return refine_extremes(solve, errors.samples, points, stride, safety, pilot)
