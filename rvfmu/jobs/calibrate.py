"""`rvte calibrate`: stiffnesses and friction fitted to measurements."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.base.checks import InputError
from ..core.reducer.design import in_file_units
from ..core.reducer.limits import check_load
from ..core.statics.quasistatic import default_points
from ..outputs import output_file
from .common import _design_ratio, _json_safe, resolve_design, resolve_errors
from .measure import measure


@dataclass(frozen=True)
class CalibrateReport:
    """A calibration (`rvfmu.bench.calibration_fit.Calibration`) with its inputs and output file."""

    calibration: object
    data: tuple[str, ...]
    output: str | None

    def summary(self) -> str:
        """The table `rvte calibrate` prints: design, data and target, each fitted value with
        its start, bounds, fitted value, 1-sigma and sensitivity, the misfit per data set
        before and after [arcsec, or relative for a catalogue], the V index, the optimiser's
        messages, the warnings and the design file written."""
        from ..bench.calibration_values import describe, setting

        cal = self.calibration
        prob = cal.problem
        d = prob.design
        unit = "relative" if prob.target == "catalogue" else "arcsec"
        lines = [
            f"design            {d.name} (ratio {d.ratio:g})",
            f"data              {', '.join(self.data)}: {len(prob.datasets)} data set"
            f"{'s' if len(prob.datasets) > 1 else ''}, target {prob.target}",
        ]
        if prob.target != "catalogue":
            from ..bench.calibration_problem import default_points as calibration_points

            full = default_points(d)
            lines.append(
                f"model             {prob.points} points per output revolution ("
                + (
                    f"the pin-passing order {d.z_p * d.z_c} resolved)"
                    if prob.points // 2 > d.z_p * d.z_c
                    else f"32*z_p or more: under load the peaks within ~1 % of the {full}-point "
                    "model's, see rvfmu/bench/calibration_problem.py)"
                    if prob.points >= calibration_points(d)
                    else f"fewer than the default {calibration_points(d)}: the peaks may be several % "
                    f"below the {full}-point model's)"
                )
            )
        lines += [
            f"fit               least squares on ln(value): differential_evolution, then "
            f"least_squares; {cal.evaluations} model evaluations"
        ]
        width = max(17, *(len(p.name) + 1 for p in prob.parameters))
        lines.append(
            f"{'value':<{width}} {'start':>10} {'bounds':>21} {'fitted':>10} "
            f"{'1-sigma':>9} {'per +1 %':>9}  unit"
        )
        for p, v, s, b, sens in zip(prob.parameters, cal.values, cal.sigma, cal.at_bound, cal.sensitivity()):
            note = "  at bound" if b else ""
            if not np.isfinite(s):
                note += "  not identifiable" if np.isinf(s) else "  (no variance left)"
            elif s > v:
                note += "  (sigma > value: not determined by these data)"
            lines.append(
                f"{p.name:<{width}} {p.value:>10.4g} {p.lower:>10.4g}-{p.upper:<10.4g} "
                f"{v:>10.4g} {s:>9.3g} {sens:>9.3g}  {p.unit}{note}"
            )
        lines.append(f"{'':<{width}} per +1 %: RMS change of the residuals [{unit}]")
        lines += [
            f"{'':<{width}} {p.name}: {describe(p)}; fitted: {setting(p, v)}"
            for p, v in zip(prob.parameters, cal.values)
            if p.name != p.field
        ]
        rows = cal.misfit()
        if prob.target == "peaks":
            lines.append(
                f"{'data set':<17} {'measured':>9} {'before':>9} {'misfit':>8} {'after':>9} "
                f"{'misfit':>8} {'improvement':>12}  [arcsec]"
            )
            lines += [
                f"{r['name']:<17} {r['measured']:>9.3f} {r['before']:>9.3f} "
                f"{r['misfit_before']:>+8.3f} {r['after']:>9.3f} {r['misfit_after']:>+8.3f} "
                f"{r['improvement_percent']:>11.2f} %"
                for r in rows
            ]
        elif prob.target == "curve":
            lines.append(
                f"{'data set':<17} {'te_pp':>9} {'before':>9} {'after':>9} "
                f"{'RMS misfit before':>18} {'after':>8} {'improvement':>12}  [arcsec]"
            )
            lines += [
                f"{r['name']:<17} {r['measured']:>9.3f} {r['before']:>9.3f} {r['after']:>9.3f} "
                f"{r['misfit_before']:>18.3f} {r['misfit_after']:>8.3f} "
                f"{r['improvement_percent']:>11.2f} %"
                for r in rows
            ]
        else:
            lines.append(f"{'figure':<34} {'catalogue':>10} {'before':>10} {'after':>10}")
            for r in rows:
                for name, m, b, a in zip(r["figures"], r["measured"], r["before"], r["after"]):
                    lines.append(f"{name:<34} {m:>10.4g} {b:>10.4g} {a:>10.4g}")
        v0, v1 = cal.v_index
        lines.append(
            f"V (mean squared misfit) {v0:.4g} before, {v1:.4g} after"
            + (f" ({100 * (1 - v1 / v0):.2f} % reduction)" if v0 else "")
        )
        lines += [f"optimiser         {m}" for m in cal.messages]
        if not cal.converged:
            lines.append("warning           the model's equilibrium did not converge at some poses")
        lines += [f"warning           {text}" for text in prob.warnings]
        if cal.reach_error is not None:
            lines.append(f"warning           NOT A CALIBRATION: {cal.reach_error}")
        if self.output:
            lines.append(f"wrote design      {self.output} (for rvte te, rvte fmu build and the studies)")
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The calibration for scripts (`--json`): the fitted values (start, bounds, value,
        sigma, at_bound, the design fields they set in file units), the misfit, v_index,
        convergence, warnings, out_of_reach and the output file; floats that are not finite as
        text ("inf", "nan")."""
        cal = self.calibration
        prob = cal.problem
        v0, v1 = cal.v_index
        return _json_safe(
            {
                "design": prob.design.name,
                "data": list(self.data),
                "target": prob.target,
                "points_per_revolution": prob.points,
                "evaluations": cal.evaluations,
                "fitted": [
                    {
                        "name": p.name,
                        "field": p.field,
                        "unit": p.unit,
                        "start": p.value,
                        "bounds": [p.lower, p.upper],
                        "value": float(v),
                        "sigma": float(s),
                        "at_bound": bool(b),
                        "sets": in_file_units(p.field_values(float(v))),
                        "rms_change_per_percent": float(k),
                    }
                    for p, v, s, b, k in zip(
                        prob.parameters, cal.values, cal.sigma, cal.at_bound, cal.sensitivity()
                    )
                ],
                "misfit": cal.misfit(),
                "v_index": {"before": v0, "after": v1},
                "dof": cal.dof,
                "messages": list(cal.messages),
                "converged": cal.converged,
                "warnings": list(prob.warnings),
                "out_of_reach": None if cal.reach_error is None else str(cal.reach_error),
                "output": self.output,
            }
        )


def calibrate(
    design,
    data,
    fit,
    target: str | None = None,
    errors=None,
    load: float = 0.0,
    bounds: dict | None = None,
    ratio: float | None = None,
    columns=None,
    units: str | None = None,
    counts_per_rev=None,
    remove_orders=(1,),
    remove_input_orders=(),
    keep_orders=(),
    points: int | None = None,
    maxiter: int | None = None,
    popsize: int | None = None,
    seed: int | None = None,
    output: str | Path | None = None,
    progress=None,
) -> CalibrateReport:
    """Identify stiffnesses and friction fields of `design` from measurements
    (`rvfmu.bench.calibration_fit`).

    data: files, each a bench CSV (read as `measure` reads it, the design's ratio; at
    `load` with `errors`), a data-set TOML ([[dataset]] tables with te_pp_arcsec or data,
    load_Nm, errors, error_scale) or a catalogue TOML (torsional_rigidity_Nm_per_arcmin,
    lost_motion_arcmin, rated_torque_Nm; [[efficiency]] and [[running_torque]] tables).
    fit: names (R_ca, R_b, R_pd of seed 003, stiffness fields, output_stiffness,
    modification_scale, friction fields); target: peaks, curve or catalogue (default: what
    the data bring); bounds: {name: (lower, upper)} in each value's unit.  maxiter, popsize, seed: differential_evolution's
    budget and seed.  output: the calibrated design TOML to write.  Everything is checked
    before the first model evaluation.  progress(total, done): optional.  A figure out of
    the bounds' reach or a fit pressed against a default bound raises InputError instead of
    writing `output` (the first before the fit); without `output` the report carries it as
    a warning (`rvfmu.bench.calibration_fit.beyond_reach`, `out_of_reach`).
    """
    from ..bench import calibration_fit
    from ..bench.calibration_data import (
        DataSet,
        catalogue_dataset,
        design_sources,
        is_catalogue,
        peaks_datasets,
        read_toml,
    )
    from ..bench.calibration_problem import problem
    from ..bench.calibration_values import parameters

    output = None if output is None else output_file("output", output, ("toml",))
    resolved = resolve_design(design)
    check_load("load", load, resolved.rated_torque)
    ratio = _design_ratio(resolved, ratio)
    paths = [data] if isinstance(data, (str, Path)) else list(data)
    if not paths:
        raise InputError("data", [], "give one or more data files (bench CSV, data-set or catalogue TOML)")
    error_set = None if errors is None else resolve_errors(resolved, errors)

    def read_record(path):
        return measure(
            path,
            ratio,
            columns=columns,
            units=units,
            counts_per_rev=counts_per_rev,
            remove_orders=remove_orders,
            remove_input_orders=remove_input_orders,
            keep_orders=keep_orders,
        ).measured

    sources = (
        design_sources(design)
        if isinstance(design, (str, Path))
        else design_sources(resolved.name.split(" (")[0])
    )
    # The values and bounds first: a wrong --fit name is reported before any file is read.
    parameters(resolved, fit, bounds, sources)
    datasets = []
    for path in paths:
        path = Path(path)
        if not path.is_file():
            raise InputError(
                "data", str(path), "must be an existing bench CSV, data-set TOML or catalogue TOML"
            )
        if path.suffix.lower() == ".toml":
            values = read_toml("data", path)
            if is_catalogue(values):
                datasets.append(catalogue_dataset(path, values, load, error_set))
            else:
                datasets += peaks_datasets(path, values, resolved, load, errors, read_record)
        else:
            datasets.append(DataSet(path.name, float(load), error_set, measured=read_record(path)))
    prob = problem(resolved, datasets, fit, target, bounds, sources, points)
    budget = {k: v for k, v in (("maxiter", maxiter), ("popsize", popsize), ("seed", seed)) if v is not None}
    total = (
        (budget.get("maxiter", calibration_fit.DE_MAXITER) + 1)
        * budget.get("popsize", calibration_fit.DE_POPSIZE)
        * len(prob.parameters)
    )
    # a fit that is no calibration writes nothing (`bench.calibration_fit.out_of_reach`)
    result = calibration_fit.calibrate(
        prob,
        progress=None if progress is None else (lambda done: progress(max(total, done), done)),
        refuse=output is not None,
        **budget,
    )
    if output is not None:
        output.write_text(
            calibration_fit.design_text(
                result,
                [str(p) for p in paths],
                sources,
                str(design) if isinstance(design, (str, Path)) else "",
            )
        )
    return CalibrateReport(result, tuple(str(p) for p in paths), None if output is None else str(output))
