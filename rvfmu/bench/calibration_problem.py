"""A calibration problem, and the model's residuals against its data.

A `Problem` is plain data: the design, the values to fit
(`rvfmu.bench.calibration_values`), the data sets (`rvfmu.bench.calibration_data`),
the target (peaks, curve or catalogue) and the model's points per output revolution.
`evaluate` gives the model's quantity of each data set for a design, `residuals`
model - measured at x = ln(value / start): what the fit
(`rvfmu.bench.calibration_fit`) minimises.

- Friction (docs/model.md section 9): a catalogue file may also hold efficiency points
  (output speed, resisting torque, efficiency) and no-load running torques at the
  input (output speed, torque), each with its conditions; the friction fields
  (`FRICTION_FIELDS`: the contacts' coefficients, the bearings' drag factor, the
  lubricant's viscosity, the seal's torque) are fitted to them on their logarithms
  like the stiffnesses.  An efficiency's residual is that of its loss share 1 - eta,
  relative, which is what the coefficients set (an efficiency near 1 would hide it).
  The contact loads do not depend on friction (the first-order power balance), so a
  data set's loads are solved once per stiffness state and every friction value
  costs only the losses.
- Speeds of catalogue friction points are checked against the design's allowable output
  speed as every speed is (`rvfmu.core.reducer.limits.check_speed`): refused beyond SPEED_FACTOR x
  it, a warning of the problem above it.
- Cheap evaluations: a data set's model costs its grid, `points` per output
  revolution, not its rows (`rvfmu.bench.compare`); data sets at the same load are
  solved as one batch.  The default for peaks and curves, POINTS_PER_CRANK_TURN
  = 32 points per crank revolution (32 z_p: 1280 on the 40-pin presets, 1/10 of
  the 8 z_p z_c = 12 480 that resolve the pin-passing ripple), resolves the
  errors' low orders and the crank order and their harmonics; the pin-passing
  ripple (order z_p z_c) is sampled, not resolved.  te_pp at 1280 against 12 480
  points, seed 002's errors (x1 to x3.3) at rated torque: RV-20E 1.0 % and 0.4 %
  low, RV-40E-121 0.15 % high and 0.5 % low; at no load, where interference
  makes the peaks sharper, up to 4 % low.  At 640 points (16 z_p) the same
  peaks are 2 to 6 % low, for half the cost.  A fit compares the model with
  itself at one resolution, so the part of such a bias that does not change
  with the fitted values cancels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.base.checks import InputError, integer
from ..core.base.units import RPM
from ..core.reducer.design import RVDesign
from ..core.reducer.errors import stack, zero_errors
from ..core.reducer.limits import check_speed
from ..core.statics.quasistatic import metric_torques, windup
from .calibration_data import DataSet
from .calibration_values import LOAD_FREE_FIELDS, Parameter, parameters
from .compare import as_bench_sees, model_grid, periodic

TARGETS = ("peaks", "curve", "catalogue")
POINTS_PER_CRANK_TURN = 32  # default grid: 32 z_p points per output revolution
# A misfit that is not a number (a pose that did not solve) counts as this, in arcsec.
FAILED_RESIDUAL = 1e6


@dataclass(frozen=True)
class Problem:
    """A calibration problem as plain data: the design, the values to fit, the data sets,
    the target (peaks, curve or catalogue) and the model's points per output revolution;
    warnings: texts for the report (catalogue speeds above the allowable output speed)."""

    design: RVDesign
    parameters: tuple[Parameter, ...]
    datasets: tuple[DataSet, ...]
    target: str
    points: int
    warnings: tuple[str, ...] = ()

    @property
    def start(self) -> np.ndarray:
        return np.array([p.value for p in self.parameters])

    @property
    def log_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of x = ln(value / start)."""
        return (
            np.log([p.lower / p.value for p in self.parameters]),
            np.log([p.upper / p.value for p in self.parameters]),
        )

    def fields_at(self, values) -> dict:
        """The design fields (SI) that the fitted `values` (p,), each in its unit, set."""
        fields = {}
        for p, v in zip(self.parameters, values):
            fields.update(p.field_values(float(v)))
        return fields

    def design_at(self, values) -> RVDesign:
        """The design with the fitted fields set from `values` (p,), each in its unit."""
        return self.design.with_fields(**self.fields_at(values))

    def measured(self) -> list[np.ndarray]:
        return [d.target_value(self.target) for d in self.datasets]


def check_target(datasets, target: str | None) -> str:
    """The target: as given (checked against what the data sets bring), or the one they all
    bring (catalogue figures, peaks, bench curves) when None."""
    kinds = {
        "catalogue" if d.catalogue else "peaks" if d.te_pp_arcsec is not None else "curve" for d in datasets
    }
    if target is None:
        if len(kinds) > 1:
            raise InputError(
                "target",
                None,
                f"the data bring {' and '.join(sorted(kinds))}: "
                "choose one with --target peaks, curve or catalogue",
            )
        return kinds.pop()
    if target not in TARGETS:
        raise InputError("target", target, "must be one of " + ", ".join(TARGETS))
    for d in datasets:
        ok = (
            d.catalogue is not None
            if target == "catalogue"
            else d.measured is not None
            if target == "curve"
            else d.catalogue is None
        )
        if not ok:
            what = (
                "catalogue figures (a TOML with torsional_rigidity_Nm_per_arcmin, "
                "lost_motion_arcmin, [[efficiency]], [[running_torque]])"
                if target == "catalogue"
                else "a bench record (CSV)"
                if target == "curve"
                else "a TE peak (te_pp_arcsec) or a bench record"
            )
            raise InputError("target", target, f"needs {what} in every data set; {d.name} has none")
    return target


def default_points(design: RVDesign) -> int:
    """Model points per output revolution of a calibration: POINTS_PER_CRANK_TURN per crank
    revolution (module docstring)."""
    return POINTS_PER_CRANK_TURN * design.z_p


def problem(
    design: RVDesign,
    datasets,
    fit,
    target: str | None = None,
    bounds=None,
    sources=None,
    points: int | None = None,
) -> Problem:
    """A checked calibration problem (see `Problem`)."""
    datasets = tuple(datasets)
    if not datasets:
        raise InputError("data", [], "give one or more data files")
    target = check_target(datasets, target)
    points = default_points(design) if points is None else integer("points", points, 8)
    return Problem(
        design,
        parameters(design, fit, bounds, sources),
        datasets,
        target,
        points,
        _speed_warnings(design, datasets),
    )


def _speed_warnings(design: RVDesign, datasets) -> tuple[str, ...]:
    """The warnings of the catalogue friction points' output speeds [rpm]; an InputError
    naming the file and table for one beyond SPEED_FACTOR x the allowable output speed."""
    notes = []
    for d in datasets:
        c = d.catalogue
        if c is None:
            continue
        for key, rows in (("efficiency", c.efficiency), ("running_torque", c.running_torque)):
            for k, row in enumerate(rows):
                note = check_speed(
                    "output_speed_rpm", row[0], row[0] * RPM, design, f"{d.name} {key} {k + 1}"
                )
                if note:
                    notes.append(f"{d.name} {key} {k + 1}: {note}")
    return tuple(notes)


# -- the model and the residuals -------------------------------------------------------------


def evaluate(problem: Problem, design: RVDesign) -> tuple[list[np.ndarray], bool]:
    """(the model's quantity of each data set for `design`, as `DataSet.target_value` gives
    the measured one; every pose converged).  Data sets at one load (and sense) are one batch."""
    out = [None] * len(problem.datasets)
    converged = True
    if problem.target == "catalogue":
        for k, d in enumerate(problem.datasets):
            c = d.catalogue
            parts = []
            if c.figures():
                model = (
                    design
                    if c.rated_torque_Nm is None
                    else design.with_fields(rated_torque=c.rated_torque_Nm)
                )
                w = windup(model, _errors(design, d), metric_torques(model))
                figures = {
                    "torsional_rigidity_Nm_per_arcmin": w.torsional_rigidity_Nm_per_arcmin()[0],
                    "lost_motion_arcmin": w.lost_motion_arcmin()[0],
                }
                parts.append(np.array([figures[key] for key in c.figures()]))
                converged &= bool(w.converged[0])
            if c.efficiency or c.running_torque:
                values, ok = _friction_figures(design, d)
                parts.append(values)
                converged &= ok
            out[k] = np.concatenate(parts)
        return out, converged
    groups = {}
    for k, d in enumerate(problem.datasets):
        sense = d.measured.sense if d.measured is not None else 1
        batch = periodic(design) or d.measured is None
        groups.setdefault((d.load_Nm, sense, k if not batch else -1), []).append(k)
    for (load, sense, _), members in groups.items():
        sets = [problem.datasets[k] for k in members]
        span = None
        if sets[0].measured is not None:
            span = (float(sets[0].measured.theta_in.min()), float(sets[0].measured.theta_in.max()))
        grid = model_grid(
            design, stack([_errors(design, d) for d in sets]), load, problem.points, sense, span
        )
        converged &= bool(np.all(grid.converged))
        for row, (k, d) in enumerate(zip(members, sets)):
            if d.measured is None:
                out[k] = np.array([np.ptp(grid.te_arcsec[row])])
                continue
            curve = as_bench_sees(d.measured, grid.at(d.measured.theta_in)[row])[0]
            out[k] = curve if problem.target == "curve" else np.array([np.ptp(curve)])
    return out, converged


def _errors(design, dataset):
    return zero_errors(design) if dataset.errors is None else dataset.errors


_LOADS: dict = {}


def _friction_figures(design: RVDesign, dataset: DataSet) -> tuple[np.ndarray, bool]:
    """(the model's 1 - efficiency at each efficiency point and running torque at each
    speed of the data set's catalogue, every equilibrium converged), from the power
    balance (`friction.efficiency_from_loads`) on the data set's contact loads, solved
    once for each state of the fields that set them (module docstring)."""
    from ..core.losses.friction import contact_loads, crank_turn_angles, efficiency_from_loads

    c = dataset.catalogue
    speeds = sorted({row[0] for row in c.efficiency + c.running_torque})
    loads = sorted({row[1] for row in c.efficiency})
    key = (id(dataset), design.with_fields(**{f: 0.0 for f in LOAD_FREE_FIELDS}), tuple(loads))
    hit = _LOADS.get(key)
    if hit is None or hit[0] is not dataset:
        if len(_LOADS) > 32:
            _LOADS.clear()
        forward = contact_loads(
            design,
            _errors(design, dataset),
            np.concatenate([[0.0], -np.asarray(loads, dtype=float)]),
            crank_turn_angles(design),
        )
        hit = _LOADS[key] = (dataset, forward)
    emap = efficiency_from_loads(design, hit[1], speeds, loads)
    efficiency = [emap.efficiency[speeds.index(v), loads.index(t)] for v, t, _ in c.efficiency]
    running = [emap.no_load_running_torque_Nm[speeds.index(v)] for v, _ in c.running_torque]
    return np.array([1.0 - e for e in efficiency] + running), emap.converged


def residuals_of(problem: Problem, model: list[np.ndarray]) -> np.ndarray:
    """(n,) model - measured, every data set's in turn: arcsec for peaks and curves, relative
    to the catalogue's figure for catalogue figures."""
    parts = []
    for measured, modelled in zip(problem.measured(), model):
        r = modelled - measured
        parts.append(r / measured if problem.target == "catalogue" else r)
    r = np.concatenate(parts)
    return np.where(np.isfinite(r), r, FAILED_RESIDUAL)


def values_at(problem: Problem, x) -> np.ndarray:
    """(p,) values (each in its unit) at x = ln(value / start)."""
    return problem.start * np.exp(np.asarray(x, dtype=float))


def residuals(problem: Problem, x) -> np.ndarray:
    """(n,) residuals at x = ln(value / start), (p,)."""
    return residuals_of(problem, evaluate(problem, problem.design_at(values_at(problem, x)))[0])


__all__ = [
    "TARGETS",
    "Problem",
    "check_target",
    "default_points",
    "problem",
    "evaluate",
    "residuals_of",
    "values_at",
    "residuals",
]
