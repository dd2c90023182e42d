"""Calibrating a design's stiffnesses against measurements: the fit.

The question: which values of a few stiffnesses make the model of this design
reproduce what was measured: the TE peak of each data set (seed 003), whole TE
curves of bench records, or the catalogue's torsional rigidity and lost motion?
How it is answered, and why so:

- Least squares between measured and modelled quantities, seed 003's objective
  1/2 sum (u*_i - u_i)^2, over the logarithms of the fitted values: stiffnesses
  act by ratio and span decades, and a log scale keeps them positive.
  Residuals: peaks and curves in arcsec; catalogue figures relative to the
  catalogue's value, so that rigidity and lost motion weigh alike.
- Global, then local: scipy.optimize.differential_evolution within the bounds
  (the misfit of a contact model need not be convex: pins come in and out of
  contact), from a seeded population so that the same data give the same answer
  next month, then scipy.optimize.least_squares from its best member.  No
  hand-written genetic algorithm (seed 003 uses one).
- Uncertainty: the Jacobian J of the residuals with respect to ln(value) at the
  optimum (central differences), covariance (J^T J)^-1 s^2 with the residual
  variance s^2 = sum r^2 / (n - p); the 1-sigma of a value is value x the sigma of
  its logarithm (linearised).  A direction in which the residuals do not change
  (a singular value of J below SINGULAR_RELATIVE x the largest, or below what the
  solver resolves) is not identifiable from these data: a value that moves along
  it gets sigma = inf; a value whose sigma exceeds itself is reported as not
  determined by the data.
  With as many residuals as values (n = p) there is no variance left: sigma = nan.
- Figures out of reach.  A fit that ends on a default bound is no calibration
  (`out_of_reach`): the default
  bounds (start / and x DEFAULT_BOUND_FACTOR, OUTPUT_STIFFNESS_BOUND_FACTOR,
  MODIFICATION_SCALE_BOUNDS) are a search window around an estimate, not a property of
  the reducer, so a value pressed against one (the misfit still falls beyond it) means a
  figure the design cannot reach: a catalogue rigidity of 1e9 N*m/arcmin or a lost motion
  of 1e-9 arcmin ended at the bounds and was written as a calibrated design.  Its error
  names the figure that presses hardest, its value, the value at its bound and the model's
  figure there (the nearest the window reaches); `rvfmu.api.calibrate` raises it instead of
  writing the design, and a report without a file to write carries it as a warning (a
  study may fit only to read the start values, as studies/seed003_calibration does).
  Bounds the user gives (--bounds) are a statement about the reducer: a value may end on
  them, reported "at bound" (seed 003's own bounds, studies/seed003_calibration, end so).
  A figure far beyond the window may also leave the misfit flat (a rigidity of 1e9 moves
  the relative residual by 1e-7 over the whole window, a TE peak of 1000 arcsec at no
  error hardly moves with the pins' stiffness) and the fit anywhere inside it: so every
  figure (a catalogue figure, a peak, a curve's te_pp) is first held against what the
  design gives at the corners of the default bounds (`beyond_reach`, before the fit):
  each figure rises or falls with each value, the rigidity with every stiffness, the lost
  motion with the clearance, a peak with the compliances, so its extremes over the bounds
  are at corners; REACH_MARGIN covers the values' interplay.  Not with bounds given: seed
  003's peaks on the coarse grid of a quick run lie 10 % above what its bounds reach.

What is fitted: `rvfmu.bench.calibration_values`; to what: `rvfmu.bench.calibration_data`;
the problem and its residuals: `rvfmu.bench.calibration_problem`.  Arrays and plain
records in, a record out (`Calibration`, and the text of its design file): the files
are read and written by `rvfmu.api.calibrate`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.base.checks import InputError, integer
from ..core.reducer.design import RVDesign
from ..core.reducer.errors import toml_text
from .calibration_problem import Problem, evaluate, residuals, residuals_of, values_at
from .calibration_values import setting

# differential_evolution budget: popsize x (number of values) members, maxiter generations.
# Seeded (seed 003's number): the same data give the same fit.
DE_POPSIZE = 10
DE_MAXITER = 30
DE_TOL = 1e-3
DE_SEED = 3
LS_MAX_EVALUATIONS = 200

# Step of ln(value) for the Jacobians: 0.1 % of a stiffness moves a TE by ~1e-4 of itself,
# far above the solver's convergence (~1e-8 arcsec) and small enough to stay linear.
JACOBIAN_STEP = 1e-3
# A singular value of J below this share of the largest, or below SENSITIVITY_FLOOR: that
# direction is not identifiable.  The floor: a residual change under 1e-6 (arcsec, or
# relative) for a factor e in the values is below what the solver resolves (its
# regularisation moves a TE by ~1e-6 of itself, rvfmu/core/statics/metrics.py).
SINGULAR_RELATIVE = 1e-6
SENSITIVITY_FLOOR = 1e-6
# A figure more than this share beyond the range the design gives at the corners
# of the fitted values' bounds is out of reach (`beyond_reach`); the share covers the
# values' interplay, which may put a figure's extreme a little inside the bounds.
REACH_MARGIN = 0.1
# Corners evaluated for it at most: 2^p models of p values (8: 256, against the 10 p x 31
# of the fit's differential evolution, 2480).
REACH_MAX_VALUES = 8


@dataclass(frozen=True)
class Calibration:
    """The fitted values with their uncertainty and the misfit before and after.

    values, sigma: (p,) [N/m] (sigma inf: not identifiable from these data, nan: no
    residual variance left); at_bound: (p,) bool; before, after: the model's quantity of
    each data set at the start and at the fit (as `evaluate`); jacobian: (n, p)
    d residual / d ln(value) at the fit; dof: n - p; evaluations: model evaluations;
    design: the calibrated design; messages: the optimisers' ends; reach_error: the
    InputError of a figure out of the bounds' reach (`beyond_reach`) or of a fit pressed
    against a default bound (`out_of_reach`), None if neither: such a fit is no
    calibration, and `rvfmu.api.calibrate` writes nothing for it.
    """

    problem: Problem
    values: np.ndarray
    sigma: np.ndarray
    at_bound: np.ndarray
    before: list
    after: list
    jacobian: np.ndarray
    dof: int
    evaluations: int
    design: RVDesign
    converged: bool
    messages: tuple[str, ...]
    reach_error: InputError | None = None

    @property
    def residuals_before(self) -> np.ndarray:
        return residuals_of(self.problem, self.before)

    @property
    def residuals_after(self) -> np.ndarray:
        return residuals_of(self.problem, self.after)

    @property
    def v_index(self) -> tuple[float, float]:
        """Mean squared residual before and after: seed 003's V for peaks."""
        return (float(np.mean(self.residuals_before**2)), float(np.mean(self.residuals_after**2)))

    def misfit(self) -> list[dict]:
        """One row per data set: measured, before, after (the quantity: one peak, a curve's
        RMS misfit, catalogue figures) and the misfit before and after with the improvement
        in % ((|before| - |after|) / |before|), as seed 003's table."""
        rows = []
        for d, measured, before, after in zip(
            self.problem.datasets, self.problem.measured(), self.before, self.after
        ):
            if self.problem.target == "peaks":
                b, a = float(before[0] - measured[0]), float(after[0] - measured[0])
                row = {
                    "name": d.name,
                    "measured": float(measured[0]),
                    "before": float(before[0]),
                    "after": float(after[0]),
                    "misfit_before": b,
                    "misfit_after": a,
                }
            elif self.problem.target == "curve":
                b = float(np.sqrt(np.mean((before - measured) ** 2)))
                a = float(np.sqrt(np.mean((after - measured) ** 2)))
                row = {
                    "name": d.name,
                    "measured": float(np.ptp(measured)),
                    "before": float(np.ptp(before)),
                    "after": float(np.ptp(after)),
                    "misfit_before": b,
                    "misfit_after": a,
                }
            else:
                b = float(np.sqrt(np.mean(((before - measured) / measured) ** 2)))
                a = float(np.sqrt(np.mean(((after - measured) / measured) ** 2)))
                row = {
                    "name": d.name,
                    "figures": d.catalogue.labels(),
                    "measured": measured.tolist(),
                    "before": before.tolist(),
                    "after": after.tolist(),
                    "misfit_before": b,
                    "misfit_after": a,
                }
            row["improvement_percent"] = (100.0 * (abs(b) - abs(a)) / abs(b)) if b else float("nan")
            rows.append(row)
        return rows

    def sensitivity(self) -> np.ndarray:
        """(p,) RMS change of the residuals [arcsec, or relative] per +1 % of each value."""
        return np.sqrt(np.mean((0.01 * self.jacobian) ** 2, axis=0))


def calibrate(
    problem: Problem,
    maxiter: int = DE_MAXITER,
    popsize: int = DE_POPSIZE,
    seed: int = DE_SEED,
    progress=None,
    refuse: bool = False,
) -> Calibration:
    """Fit the problem's values: differential evolution on ln(value) within the bounds, then
    least squares from its best member; the uncertainty from the Jacobian at the optimum.

    progress(evaluations done): optional, called after each model evaluation.  refuse: raise
    the InputError of a figure out of reach (`beyond_reach`, before the fit) or of a fit
    pressed against a default bound (`out_of_reach`), as a job that writes the design
    does; else the calibration carries it as `reach_error`.
    """
    from scipy.optimize import differential_evolution, least_squares

    maxiter = integer("maxiter", maxiter, 0)
    popsize = integer("popsize", popsize, 2)
    seed = integer("seed", seed, 0)
    count = [0]

    def r(x):
        count[0] += 1
        if progress is not None:
            progress(count[0])
        return residuals(problem, x)

    lower, upper = problem.log_bounds
    unreachable = beyond_reach(problem)
    if refuse and unreachable is not None:
        raise unreachable
    before, ok_before = evaluate(problem, problem.design)
    messages = []
    start = np.clip(np.zeros(lower.size), lower, upper)
    best = start
    if maxiter > 0:
        de = differential_evolution(
            lambda x: _half_ss(r(x)),
            list(zip(lower, upper)),
            maxiter=maxiter,
            popsize=popsize,
            tol=DE_TOL,
            seed=seed,
            polish=False,
            init="latinhypercube",
            updating="immediate",
        )
        best = de.x
        messages.append(f"differential_evolution: {de.message} ({de.nit} generations)")
        # The design as given may fit better than every member (a flat misfit): start there.
        if np.array_equal(start, np.zeros(lower.size)) and _half_ss(residuals_of(problem, before)) < de.fun:
            best = start
    ls = least_squares(
        r,
        best,
        bounds=(lower, upper),
        jac="2-point",
        diff_step=JACOBIAN_STEP,
        x_scale=1.0,
        max_nfev=LS_MAX_EVALUATIONS,
    )
    messages.append(f"least_squares: {ls.message}")
    x = ls.x
    jac = _jacobian(r, x)
    values = values_at(problem, x)
    design = problem.design_at(values)
    after, ok_after = evaluate(problem, design)
    res = residuals_of(problem, after)
    dof = res.size - x.size
    sigma = values * _sigma_log(jac, res, dof)
    span = upper - lower
    at_lower = x - lower < 1e-6 * np.maximum(span, 1)
    at_upper = upper - x < 1e-6 * np.maximum(span, 1)
    error = unreachable or out_of_reach(problem, at_lower, at_upper, jac, res, after)
    if refuse and error is not None:
        raise error
    return Calibration(
        problem,
        values,
        sigma,
        at_lower | at_upper,
        before,
        after,
        jac,
        dof,
        count[0],
        design,
        ok_before and ok_after,
        tuple(messages),
        error,
    )


def _figures(problem: Problem, model: list[np.ndarray]) -> list[tuple[str, float, float, slice]]:
    """(name, measured, modelled, its rows of the residuals) of every figure the fit matches:
    each catalogue figure, each data set's peak, each bench curve (its te_pp)."""
    out, row = [], 0
    for d, measured, modelled in zip(problem.datasets, problem.measured(), model):
        if problem.target == "catalogue":
            for name, m, v in zip(d.catalogue.labels(), measured, modelled):
                out.append((name, float(m), float(v), slice(row, row + 1)))
                row += 1
            continue
        if problem.target == "curve":
            out.append(
                (
                    f"te_pp_arcsec of the curve {d.name}",
                    float(np.ptp(measured)),
                    float(np.ptp(modelled)),
                    slice(row, row + measured.size),
                )
            )
        else:
            out.append(
                (f"te_pp_arcsec of {d.name}", float(measured[0]), float(modelled[0]), slice(row, row + 1))
            )
        row += measured.size
    return out


def beyond_reach(problem: Problem) -> InputError | None:
    """The InputError of a figure (`_figures`) that the design cannot reach within the
    default bounds (module docstring), else None: it names the figure, its value, the range
    the design gives over the bounds' corners (2^p models) and the values with their
    bounds.  Only when no bounds were given (a window the user states may be ended on) and
    for p <= REACH_MAX_VALUES."""
    params = problem.parameters
    if any(p.bounds_given for p in params) or len(params) > REACH_MAX_VALUES:
        return None
    corners = (
        np.array(np.meshgrid(*[(p.lower, p.upper) for p in params], indexing="ij")).reshape(len(params), -1).T
    )  # (2^p, p)
    reached = [[f[2] for f in _figures(problem, evaluate(problem, problem.design_at(c))[0])] for c in corners]
    reached = np.array(reached, dtype=float)  # (2^p, F)
    for f, (name, measured, _, _) in enumerate(_figures(problem, problem.measured())):
        column = reached[:, f][np.isfinite(reached[:, f])]
        if column.size == 0:
            continue
        low, high = float(column.min()), float(column.max())
        if not low * (1.0 - REACH_MARGIN) <= measured <= high * (1.0 + REACH_MARGIN):
            window = ", ".join(f"{p.name} {p.lower:.4g} to {p.upper:.4g} {p.unit}" for p in params)
            return InputError(
                name,
                measured,
                f"out of the fit's reach: within the default "
                f"bounds ({window}) the design gives {low:.4g} to {high:.4g}; nothing "
                "written; check the figure, or give --bounds NAME=LOWER:UPPER "
                "if the value truly lies beyond",
            )
    return None


def out_of_reach(problem: Problem, at_lower, at_upper, jac, res, after) -> InputError | None:
    """The InputError of a fit that ends on a default bound which the misfit presses against
    (module docstring), else None.  at_lower, at_upper (p,) bool: the fitted values on a bound; jac
    (n, p): d residual / d ln(value) at the fit; res (n,): the residuals there; after: the
    model's quantities there (as `evaluate`).  It names the figure that presses hardest on
    a bound, its value, each value on its bound with the bound, and the model's figure
    there: the nearest the search window reaches."""
    figures = _figures(problem, after)
    pressed = []
    for k, p in enumerate(problem.parameters):
        if p.bounds_given or not (at_lower[k] or at_upper[k]):
            continue
        outward = 1.0 if at_upper[k] else -1.0
        best = None
        for f, (_, measured, modelled, rows) in enumerate(figures):
            # minus the figure's share of the misfit's slope along ln(value), outward: > 0
            # where its misfit still falls beyond the bound
            if -outward * float(jac[rows, k] @ res[rows]) <= 0.0:
                continue
            # of the figures that press, the one the value moves most, relative to itself (a
            # relative residual's slope is d(model)/d ln(value) / measured)
            slope = np.linalg.norm(jac[rows, k]) * (abs(measured) if problem.target == "catalogue" else 1.0)
            moves = slope / max(abs(modelled), 1e-300)
            if best is None or moves > best[0]:
                best = (moves, k, f)
        if best is not None:
            pressed.append(best)
    if not pressed:
        return None
    pressed.sort(key=lambda item: -item[0])
    name, measured, _, _ = figures[pressed[0][2]]
    parts = []
    for _, k, f in pressed:
        p = problem.parameters[k]
        side, bound = ("upper", p.upper) if at_upper[k] else ("lower", p.lower)
        figure = figures[f]
        parts.append(
            f"{p.name} ends at its {side} bound {bound:.4g} {p.unit} (the default "
            f"search range {p.lower:.4g} to {p.upper:.4g}), where the model gives "
            f"{figure[0]} = {figure[2]:.4g}" + ("" if f == pressed[0][2] else f" against {figure[1]:.4g}")
        )
    return InputError(
        name,
        measured,
        "out of the fit's reach: "
        + "; ".join(parts)
        + ": nothing written; check the figure, or give --bounds NAME=LOWER:UPPER "
        "if the value truly lies beyond",
    )


def _half_ss(r):
    return 0.5 * float(r @ r)


def _jacobian(r, x):
    """(n, p) central differences of r at x, step JACOBIAN_STEP in each ln(value)."""
    columns = []
    for k in range(x.size):
        step = np.zeros(x.size)
        step[k] = JACOBIAN_STEP
        columns.append((r(x + step) - r(x - step)) / (2.0 * JACOBIAN_STEP))
    return np.stack(columns, axis=1)


def _sigma_log(jac, res, dof):
    """(p,) 1-sigma of ln(value): sqrt(diag((J^T J)^-1) s^2), inf along directions that J does
    not see, nan without residual variance (dof <= 0)."""
    p = jac.shape[1]
    s2 = float(res @ res) / dof if dof > 0 else float("nan")
    _, singular, vt = np.linalg.svd(jac, full_matrices=False)
    largest = singular.max() if singular.size else 0.0
    seen = singular > max(SINGULAR_RELATIVE * largest, SENSITIVITY_FLOOR)
    cov = (vt[seen].T / singular[seen] ** 2) @ vt[seen] * s2
    sigma = np.sqrt(np.abs(np.diag(cov)))
    blind = np.sum(vt[~seen] ** 2, axis=0) > 1e-6 if np.any(~seen) else np.zeros(p, dtype=bool)
    return np.where(blind, np.inf, sigma)


# -- the calibrated design file --------------------------------------------------------------


def design_text(
    calibration: Calibration, data_names, sources: dict | None = None, from_design: str = ""
) -> str:
    """A complete design TOML of the calibrated design, loadable by `rvte te`: a header saying
    what was fitted to what, every design key, and the [sources] table (for R_pd)."""
    cal = calibration
    lines = [
        f"Calibrated by rvte calibrate ({cal.problem.target}) from {from_design or cal.problem.design.name}",
        "against " + ", ".join(str(n) for n in data_names) + ".",
        "Fitted (1-sigma from the Jacobian at the optimum; inf: not identifiable from the data):",
    ]
    for p, v, s in zip(cal.problem.parameters, cal.values, cal.sigma):
        lines.append(f"  {p.name} = {v:.6g} +- {s:.3g} {p.unit} ({setting(p, v)})")
    lines.append("Every other value as in the design calibrated.")
    values = cal.design.file_values()
    values["name"] = f"{cal.problem.design.name} calibrated"
    text = toml_text(values, header="\n".join(lines))
    if sources:
        text += "\n[sources]\n" + toml_text({k: v for k, v in sources.items()})
    return text


__all__ = ["Calibration", "calibrate", "beyond_reach", "out_of_reach", "design_text"]
