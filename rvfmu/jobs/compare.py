"""`rvte compare`: the model against a bench record."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.reducer.limits import check_load
from ..outputs import figure_file, output_file
from .common import _design_ratio, _json_safe, columns_frame, resolve_design, resolve_errors, write_frame
from .measure import measure

BY_ORDER_SHOWN = 8
# The columns of the comparison's CSV and `CompareReport.to_df`, with their number formats.
FORMATS = {
    "theta_in_rad": ".12g",
    "te_measured_arcsec": ".6f",
    "te_model_arcsec": ".6f",
    "difference_arcsec": ".6f",
}


@dataclass(frozen=True)
class CompareReport:
    """A bench record beside the model (`rvfmu.bench.compare.Comparison`), with where it came from."""

    comparison: object
    data: str
    errors: str | None

    def summary(self) -> str:
        """The table `rvte compare` prints: design, record and model grid, te_pp and RMS
        [arcsec] measured and model, their correlation and difference, the best shift [deg of
        output], the BY_ORDER_SHOWN largest orders of either and the warnings."""
        c = self.comparison
        m, d = c.measured, c.design
        pp, rms = c.te_pp_arcsec, c.rms_arcsec
        removed = ", ".join(f"{x.shaft} order {x.order}" for x in m.components) or "none"
        lines = [
            f"design            {d.name} (ratio {d.ratio:g}), errors: {self.errors or 'none'}, "
            f"load {c.load_Nm:g} N*m resisting" + ("  (no-load limit)" if c.load_Nm == 0 else ""),
            f"data              {self.data}: {m.revolutions} whole output revolution"
            f"{'s' if m.revolutions > 1 else ''}, {m.rows} rows, "
            f"{'positive' if m.sense > 0 else 'negative'} sense",
            f"model             on a grid of {c.points} points per output revolution, "
            + (
                "one revolution (the TE repeats every output revolution: whole ratio)"
                if c.periodic
                else "over the record's input angles"
            )
            + ", linearly interpolated to the record's input angles (the input encoder read as "
            "the model's theta_in)",
            f"bench processing  the mean and the runout orders removed from both curves alike "
            f"(removed: {removed})",
            f"te_pp             {pp[0]:.3f} arcsec measured, {pp[1]:.3f} arcsec model",
            f"rms               {rms[0]:.3f} arcsec measured, {rms[1]:.3f} arcsec model",
            f"correlation       {c.correlation:.4f}",
            f"difference        {c.rms_difference_arcsec:.3f} arcsec RMS, "
            f"{np.ptp(c.difference_arcsec):.3f} arcsec peak-to-peak (measured - model)",
            f"best shift        {c.shift_deg:+.3f} deg of output (model delayed), correlation "
            f"{c.shift_correlation:.4f} there; the figures above are at zero shift",
            f"by order          {'order':>8} {'measured':>9} {'model':>9} {'|diff|':>9}  [arcsec]",
        ]
        lines += [
            f"                  {o:>8g} {a:>9.3f} {b:>9.3f} {x:>9.3f}"
            for o, a, b, x in c.by_order(BY_ORDER_SHOWN)
        ]
        if not c.converged:
            lines.append("warning           the model's equilibrium did not converge at some angles")
        nyquist = c.points // 2
        if nyquist <= d.z_p * d.z_c:
            lines.append(
                f"note              {c.points} model points per revolution do not resolve "
                f"the pin-passing order {d.z_p * d.z_c}"
            )
        lines += [f"warning           {text}" for text in m.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The comparison for scripts (`--json`): the figures of `summary` under their names
        with units (te_pp_arcsec and rms_arcsec as {measured, model}, by_order as a list);
        floats that are not finite as text ("inf", "nan")."""
        c = self.comparison
        pp, rms = c.te_pp_arcsec, c.rms_arcsec
        return _json_safe(
            {
                "design": c.design.name,
                "data": self.data,
                "errors": self.errors,
                "load_Nm": c.load_Nm,
                "model_points_per_revolution": c.points,
                "model_grid": "one periodic output revolution" if c.periodic else "record range",
                "model_at_rows": "linear interpolation from the grid",
                "revolutions": c.measured.revolutions,
                "rows": c.measured.rows,
                "removed": [{"shaft": x.shaft, "order": x.order} for x in c.measured.components],
                "te_pp_arcsec": {"measured": float(pp[0]), "model": float(pp[1])},
                "rms_arcsec": {"measured": float(rms[0]), "model": float(rms[1])},
                "correlation": c.correlation,
                "rms_difference_arcsec": c.rms_difference_arcsec,
                "best_shift_deg": c.shift_deg,
                "best_shift_correlation": c.shift_correlation,
                "by_order": [
                    {"order": o, "measured_arcsec": a, "model_arcsec": b, "difference_arcsec": x}
                    for o, a, b, x in c.by_order(BY_ORDER_SHOWN)
                ],
                "converged": c.converged,
                "warnings": list(c.measured.warnings),
            }
        )

    def to_df(self):
        """The record beside the model as a pandas DataFrame (one row per record row used), the
        columns of its CSV: theta_in_rad (the record's input angle), te_measured_arcsec (its TE
        without the runout), te_model_arcsec (the model as the bench sees it),
        difference_arcsec (measured - model)."""
        c = self.comparison
        return columns_frame(
            {
                "theta_in_rad": c.measured.theta_in,
                "te_measured_arcsec": c.measured_arcsec,
                "te_model_arcsec": c.model_arcsec,
                "difference_arcsec": c.difference_arcsec,
            }
        )


def compare(
    design,
    data,
    errors=None,
    load: float = 0.0,
    ratio: float | None = None,
    columns=None,
    units: str | None = None,
    counts_per_rev=None,
    remove_orders=(1,),
    remove_input_orders=(),
    keep_orders=(),
    points: int | None = None,
    csv_path: str | Path | None = None,
    plot_path: str | Path | None = None,
) -> CompareReport:
    """A bench record (read and processed as `measure` does, the ratio the design's) beside the
    model of `design` with `errors` at the resisting `load` [N*m] the bench ran at: te_pp,
    RMS, correlation and the difference, by angle and by order (`rvfmu.bench.compare`).

    points: the model's grid per output revolution (default 8 per pin-passing period); the
    model is interpolated from it to the record's input angles.  csv_path: theta_in_rad,
    te_measured_arcsec, te_model_arcsec, difference_arcsec; plot_path: the curves, their
    spectra and the difference.  Paths, design, errors, load and points are checked before
    the data are read.
    """
    from ..bench.compare import compare_te
    from ..core.base.checks import integer

    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    error_set = resolve_errors(design, errors)
    check_load("load", load, design.rated_torque)
    points = None if points is None else integer("points", points, 8)
    ratio = _design_ratio(design, ratio)
    record = measure(
        data,
        ratio,
        columns=columns,
        units=units,
        counts_per_rev=counts_per_rev,
        remove_orders=remove_orders,
        remove_input_orders=remove_input_orders,
        keep_orders=keep_orders,
    ).measured
    result = compare_te(record, design, error_set, load, points)
    report = CompareReport(result, str(data), None if errors is None else str(errors))
    if csv_path is not None:
        write_frame(csv_path, report.to_df(), FORMATS)
    if plot_path is not None:
        from ..plots import plot_comparison

        plot_comparison(result, plot_path, title=f"{Path(data).name} against {design.name} at {load:g} N·m")
    return report
