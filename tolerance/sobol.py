"""Sobol ranking: which tolerances decide the TE variance of the reducers we build.

A first-order index S1 is the share of the output variance that one factor
(one error source, or a group of them) explains alone; the total index ST
adds all its interactions.  Tightening a tolerance with a small ST changes
little; the factors at the top of the ST ranking are the ones worth paying
for.  Indices are estimated with SALib: Saltelli's cross-sampling of a
scrambled Sobol' sequence (`SALib.sample.sobol.sample`) and the Saltelli
(2010) estimators with bootstrap confidence intervals
(`SALib.analyze.sobol.analyze`), over the groups of the problem.

Reading the estimates:

- Negative estimates.  True indices are >= 0; an estimate below zero is
  sampling noise around an index that is (nearly) zero.  As SALib's
  maintainers advise (SALib issues #102 and #135), an index whose confidence
  interval includes zero is treated as zero: it is reported as 0 and flagged.
  A negative estimate whose interval excludes zero means too few samples:
  it is also reported as 0, flagged "not converged".  Totals above 1 are
  clipped to 1 the same way.
- S1 above ST.  ST adds a factor's interactions to its S1, so S1 <= ST
  holds for the true indices; an estimated S1 above ST beyond both intervals
  (S1 - S1_conf > ST + ST_conf) is sampling noise: flagged, raise n.
- Wide intervals.  An index known only to +-WIDE_CI cannot rank factors whose
  indices differ by less; it is flagged.
- The order of two neighbouring ranks.  Their intervals overlap long before
  their order is in doubt: both estimates come from the same rows and move
  together, so what decides the order is the interval of their difference.
  SALib's bootstrap resamples the base samples once for every group
  (`keep_resamples`); the difference of two groups' ST over those resamples
  gives its interval, at the same confidence and by the same normal rule as
  SALib's own.  The order is settled where that interval excludes zero
  (`Indices.order`); neighbouring ranks whose order is not settled form one
  group (`Indices.order_groups`), within which the ranking says nothing.
- Convergence.  The indices are computed again from the first N/4 and N/2
  base samples (each base sample owns a block of G+2, or 2G+2, consecutive
  rows of the Saltelli matrix, G the groups, and the first N/4 points of a
  Sobol' sequence are themselves balanced); the largest change of ST from N/2
  to N is reported, and the study is called converged if it is below
  CONVERGED_CHANGE.
- One group.  A problem whose variables form a single group (one tolerance
  spanning several columns, or every factor in one `group`) has S1 = ST = 1
  by definition: the group is the whole input, so it explains the whole
  variance, alone.  They are reported exactly, with zero-width intervals and
  a note (`Indices.whole_input`), not estimated.  SALib treats a single group
  as no groups at all (`SALib.util._check_groups`) and would sample D+2 rows
  per base sample over the D variables; the sample here is the grouped
  design's own, G+2 = 3 rows (A, AB = B, B), or 2G+2 = 4 with second order,
  built from the same scrambled Sobol' base sequence SALib draws, so that
  sampling, analysis and `rows_per_base_sample` agree for every G.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

WIDE_CI = 0.1  # half-width of an index's interval above which its rank is uncertain
CONVERGED_CHANGE = 0.05  # largest |ST(N) - ST(N/2)| of a converged study (5 % of the variance)
CONVERGENCE_FRACTIONS = (4, 2, 1)
WHOLE_INPUT_NOTE = (
    "the only group holds every factor: S1 = ST = 1 by definition (it is the whole input), exact, no interval"
)


# SALib and scipy.stats (which SALib imports) are imported where they are used: 1.1 s that
# `rvte mc` and everything else importing this module's constants need not pay.


def group_names(problem: dict) -> list[str]:
    """The problem's groups (or variables, if it has no groups), in SALib's order."""
    from SALib.util import extract_group_names

    return list(extract_group_names(problem)[0])


def rows_per_base_sample(problem: dict, second_order: bool = False) -> int:
    """Rows of the Saltelli matrix per base sample: G+2, or 2G+2 with second order (G groups)."""
    G = len(group_names(problem))
    return 2 * G + 2 if second_order else G + 2


def sample(problem: dict, n: int, second_order: bool = False, seed: int = 0) -> np.ndarray:
    """Saltelli sample matrix (n * rows_per_base_sample, num_vars) on the problem's bounds.

    The design of `SALib.sample.sobol.sample` (scrambled, no points skipped), built with
    whole-array copies: SALib's base sequence (scipy's scrambled Sobol' sequence of 2D
    dimensions, A its first D columns, B the others), its row order (per base sample A, the
    rows A_B^(i) that take group i's columns from B, with second order the rows B_A^(i), then
    B) and its scaling to the bounds.  SALib copies the matrix element by element in Python
    (1.4 s for the 10 240 rows of 279 columns of studies/rv40e_121_sobol.toml); the numbers
    are the same to the bit (tests/test_tolerance_sobol.py, against SALib's).  For one group
    SALib drops the grouping and crosses the variables one by one; here the group is crossed
    whole (A_B is then B), as the grouped indices need."""
    from SALib.util import scale_samples
    from scipy.stats import qmc

    D = problem["num_vars"]
    names = group_names(problem)
    groups = problem.get("groups") or problem["names"]
    member = np.array([[g == name for g in groups] for name in names])[None]  # (1, G, D)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # n is checked to be a power of 2 upstream
        base = qmc.Sobol(d=2 * D, scramble=True, seed=seed).random(n)
    A, B = base[:, None, :D], base[:, None, D:]
    crossed = [np.where(member, B, A)] + ([np.where(member, A, B)] if second_order else [])
    rows = np.concatenate([A, *crossed, B], axis=1).reshape(-1, D)  # base sample by base sample
    return scale_samples(rows, problem)


@dataclass(frozen=True)
class Indices:
    """Sobol indices of one output over the G groups `names`, from n base samples.

    S1, S1_conf, ST, ST_conf: (G,) estimates and the half-widths of their
    bootstrap intervals at `confidence`; S2, S2_conf: (G, G) upper triangles
    (NaN elsewhere) or None.  constant: the output did not vary (all zero).
    ST_resamples: (R, G) ST over each of SALib's R bootstrap resamples, the same
    base samples for every group, or None (indices read back from a file); S1_resamples
    the same of S1.
    whole_input: the only group holds every variable: S1 = ST = 1 exactly (G = 1).
    """

    names: tuple
    n: int
    S1: np.ndarray
    S1_conf: np.ndarray
    ST: np.ndarray
    ST_conf: np.ndarray
    S2: np.ndarray | None
    S2_conf: np.ndarray | None
    confidence: float
    constant: bool = False
    ST_resamples: np.ndarray | None = None
    whole_input: bool = False
    S1_resamples: np.ndarray | None = None

    @property
    def S1_reported(self) -> np.ndarray:
        """S1 clipped to [0, 1] (see the module docstring)."""
        return np.clip(self.S1, 0.0, 1.0)

    @property
    def ST_reported(self) -> np.ndarray:
        return np.clip(self.ST, 0.0, 1.0)

    def flags(self) -> list[list[str]]:
        """Per group, the notes a reader needs: clipped, not converged, S1 > ST, wide interval."""
        out = []
        for g in range(len(self.names)):
            notes = [WHOLE_INPUT_NOTE] if self.whole_input else []
            for label, value, conf in (
                ("S1", self.S1[g], self.S1_conf[g]),
                ("ST", self.ST[g], self.ST_conf[g]),
            ):
                if value < 0:
                    notes.append(
                        f"{label} {value:.3f} < 0 beyond its CI: not converged, raise n"
                        if _beyond_unit_interval(value, conf)
                        else f"{label} {value:.3f} < 0 within its CI: reported as 0"
                    )
                elif value > 1:
                    notes.append(
                        f"{label} {value:.3f} > 1: reported as 1"
                        + (", not converged, raise n" if _beyond_unit_interval(value, conf) else "")
                    )
                if conf > WIDE_CI:
                    notes.append(f"{label} CI wide (+-{conf:.2f})")
            if self.S1_above_ST[g]:
                notes.append(
                    f"S1 {self.S1[g]:.3f} > ST {self.ST[g]:.3f} beyond their CIs: sampling noise, raise n"
                )
            out.append(notes)
        return out

    @property
    def not_converged(self) -> np.ndarray:
        """(G,) bool: S1 or ST lies outside [0, 1] beyond its interval (the note "not
        converged, raise n")."""
        return _beyond_unit_interval(self.S1, self.S1_conf) | _beyond_unit_interval(self.ST, self.ST_conf)

    @property
    def ci_wide(self) -> np.ndarray:
        """(G,) bool: the interval of S1 or of ST is wider than +-WIDE_CI (the note "CI wide")."""
        return (self.S1_conf > WIDE_CI) | (self.ST_conf > WIDE_CI)

    @property
    def S1_above_ST(self) -> np.ndarray:
        """(G,) bool: S1 above ST beyond both intervals, S1 - S1_conf > ST + ST_conf (sampling
        noise: the true S1 never exceeds ST)."""
        return self.S1 - self.S1_conf > self.ST + self.ST_conf

    def ranking(self) -> np.ndarray:
        """Group indices from the most to the least important: by reported ST, then S1."""
        return np.lexsort((-self.S1_reported, -self.ST_reported))

    def order(self) -> list[RankStep] | None:
        """For each pair of neighbouring ranks, the difference of their ST with its bootstrap
        interval (`RankStep`), from the top down; None without the resamples or for a
        constant output."""
        if self.ST_resamples is None or self.constant:
            return None
        from scipy.stats import norm

        z = norm.ppf(0.5 + self.confidence / 2)
        ranked = self.ranking()
        steps = []
        for upper, lower in zip(ranked[:-1], ranked[1:]):
            spread = self.ST_resamples[:, upper] - self.ST_resamples[:, lower]
            steps.append(
                RankStep(
                    int(upper),
                    int(lower),
                    float(self.ST[upper] - self.ST[lower]),
                    float(z * spread.std(ddof=1)),
                    float(np.mean(spread > 0.0)),
                )
            )
        return steps

    def order_groups(self) -> list[list[int]] | None:
        """The ranks (1 = first) in runs whose order is not settled: [[1], [2], [3, 4], ...].
        Two neighbouring ranks share a run unless their order is settled (`order`)."""
        steps = self.order()
        if steps is None:
            return None
        groups = [[1]]
        for rank, step in enumerate(steps, start=2):
            if step.settled:
                groups.append([rank])
            else:
                groups[-1].append(rank)
        return groups


@dataclass(frozen=True)
class RankStep:
    """The order of two neighbouring ranks: groups `upper` (ranked first) and `lower`,
    difference = ST[upper] - ST[lower], half_width of its bootstrap interval at the
    indices' confidence, kept: the share of resamples in which upper's ST exceeds lower's."""

    upper: int
    lower: int
    difference: float
    half_width: float
    kept: float

    @property
    def settled(self) -> bool:
        """The interval of the difference excludes zero on upper's side."""
        return self.difference - self.half_width > 0.0


def _beyond_unit_interval(value, conf):
    """An estimate outside [0, 1] by more than its interval's half-width: not converged."""
    return (np.asarray(value) + conf < 0) | (np.asarray(value) - conf > 1)


def indices(
    problem: dict,
    y: np.ndarray,
    second_order: bool = False,
    resamples: int = 200,
    confidence: float = 0.95,
    seed: int = 0,
) -> Indices:
    """Sobol indices of one output y (n * rows_per_base_sample,) from a Saltelli sample."""
    names = tuple(group_names(problem))
    G = len(names)
    y = np.asarray(y, dtype=float)
    per = rows_per_base_sample(problem, second_order)
    if y.ndim != 1 or y.size % per:
        raise ValueError(f"y must hold n * {per} values from a Saltelli sample, got {y.shape}")
    n = y.size // per
    if not np.all(np.isfinite(y)):
        raise ValueError("y has NaN or inf values: Sobol indices need every row's output")
    square = np.full((G, G), np.nan) if second_order else None
    if np.ptp(y) == 0.0:
        zero = np.zeros(G)
        return Indices(names, n, zero, zero, zero, zero, square, square, confidence, constant=True)
    if G == 1:
        # The group is the whole input: V_1 = V, so S1 = ST = 1 whatever the sample; SALib's
        # estimators would only add noise around it.  Every resample gives 1 too.
        one, zero = np.ones(1), np.zeros(1)
        return Indices(
            names,
            n,
            one,
            zero,
            one,
            zero,
            square,
            square,
            confidence,
            ST_resamples=np.ones((resamples, 1)),
            whole_input=True,
        )
    # SALib seeds its bootstrap only for a truthy seed: 0 would give different CIs each run.
    from SALib.analyze import sobol as salib_analyze

    si = salib_analyze.analyze(
        problem,
        y,
        calc_second_order=second_order,
        num_resamples=resamples,
        conf_level=confidence,
        seed=int(seed) + 1,
        keep_resamples=True,
    )
    S2 = np.asarray(si["S2"], dtype=float) if second_order else None
    S2_conf = np.asarray(si["S2_conf"], dtype=float) if second_order else None
    return Indices(
        names,
        n,
        np.asarray(si["S1"], dtype=float),
        np.asarray(si["S1_conf"], dtype=float),
        np.asarray(si["ST"], dtype=float),
        np.asarray(si["ST_conf"], dtype=float),
        S2,
        S2_conf,
        confidence,
        ST_resamples=np.asarray(si["ST_conf_all"], dtype=float).reshape(resamples, G),
        S1_resamples=np.asarray(si["S1_conf_all"], dtype=float).reshape(resamples, G),
    )


@dataclass(frozen=True)
class Convergence:
    """Indices from the first n/4, n/2 and n base samples: n (3,), S1 and ST (3, G)."""

    n: tuple
    S1: np.ndarray
    ST: np.ndarray

    @property
    def max_change(self) -> float:
        """Largest |ST(n) - ST(n/2)| over the groups."""
        return float(np.max(np.abs(self.ST[-1] - self.ST[-2])))

    @property
    def converged(self) -> bool:
        return self.max_change <= CONVERGED_CHANGE


def convergence(
    problem: dict,
    y: np.ndarray,
    second_order: bool = False,
    resamples: int = 200,
    confidence: float = 0.95,
    seed: int = 0,
    final: Indices | None = None,
) -> Convergence:
    """Indices from the first n/4, n/2 and all n base samples of a Saltelli sample's outputs y."""
    per = rows_per_base_sample(problem, second_order)
    n = np.asarray(y).size // per
    ns, S1, ST = [], [], []
    for divisor in CONVERGENCE_FRACTIONS:
        m = n // divisor
        result = (
            final
            if (divisor == 1 and final is not None)
            else indices(problem, np.asarray(y)[: m * per], second_order, resamples, confidence, seed)
        )
        ns.append(m)
        S1.append(result.S1)
        ST.append(result.ST)
    return Convergence(tuple(ns), np.array(S1), np.array(ST))


@dataclass(frozen=True)
class SobolAnalysis:
    """Indices and convergence of one output (a metric column)."""

    column: str
    indices: Indices
    convergence: Convergence
    method: str = "saltelli"  # or "linearized" (tolerance/linearized.py)
    check_q2: float | None = None  # the linearization's check on this metric, if it ran


def analyze(
    problem: dict,
    Y: np.ndarray,
    columns,
    second_order: bool = False,
    resamples: int = 200,
    confidence: float = 0.95,
    seed: int = 0,
) -> dict:
    """{column: SobolAnalysis} for every output column of Y (rows, len(columns))."""
    Y = np.asarray(Y, dtype=float).reshape(-1, len(columns))
    out = {}
    for j, column in enumerate(columns):
        final = indices(problem, Y[:, j], second_order, resamples, confidence, seed)
        conv = convergence(problem, Y[:, j], second_order, resamples, confidence, seed, final)
        out[column] = SobolAnalysis(column, final, conv)
    return out
