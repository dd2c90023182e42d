"""`rvte measure`: a bench record of input and output angles as TE."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.base.checks import InputError
from ..outputs import figure_file, output_file
from .common import _csv_header, columns_frame, read_columns, write_frame

ANGLE_UNITS = ("deg", "rad", "counts")
ANGLE_ROLES = ("theta_in", "theta_out")
# The columns of the measured TE's CSV and `MeasureReport.to_df`, with their number formats
# (time_s only if the record has a time column).
FORMATS = {
    "time_s": ".9g",
    "theta_in_rad": ".12g",
    "theta_out_rad": ".12g",
    "te_arcsec": ".6f",
    "runout_arcsec": ".6f",
    "te_reducer_arcsec": ".6f",
}


@dataclass(frozen=True)
class MeasureReport:
    """TE of a bench record (`rvfmu.bench.measured.MeasuredTE`) with where it came from."""

    measured: object
    data: str
    columns: tuple  # (theta_in, theta_out, time or None): the file's column names
    units: tuple  # (theta_in, theta_out): deg, rad or counts

    def summary(self) -> str:
        """The table `rvte measure` prints: columns, rows and revolutions used, sampling, the
        stated and measured ratio, roll-overs, the offset, te_pp and RMS [arcsec] with and
        without the runout, the runout removed, the largest orders (and lines in Hz with a
        time column) and the warnings."""
        m = self.measured
        pp, rms = m.te_pp_arcsec, m.te_rms_arcsec
        first, last = m.first_row, m.first_row + m.rows - 1
        name_in, name_out, name_time = self.columns
        by_rev = m.te_pp_by_revolution_arcsec
        lines = [
            f"data              {self.data}: {name_in}, {name_out}"
            + (f", {name_time}" if name_time else " (no time column: no spectrum in Hz)"),
            f"rows              {first} to {last} ({m.rows} rows: {m.revolutions} whole output "
            f"revolution{'s' if m.revolutions > 1 else ''}, "
            f"{'positive' if m.sense > 0 else 'negative'} sense)"
            + (
                f"; the {m.rows_after} rows after the last whole revolution are not used"
                if m.rows_after
                else ""
            ),
            f"sampling          {m.points_per_revolution} rows per output revolution "
            f"(orders below {m.points_per_revolution // 2} resolved)",
            f"ratio             {m.ratio:g} stated, {m.measured_ratio:.6g} measured (least-squares "
            f"slope of {name_in} against {name_out}, {100 * (m.measured_ratio / m.ratio - 1):+.2g} %)",
            f"roll-overs        {m.rollovers[0]} of the input encoder, {m.rollovers[1]} of the "
            "output encoder unwrapped",
            f"offset            {m.offset_arcsec:.3f} arcsec removed (the mean: the encoders' zeros)",
            f"te_pp             {pp[0]:.3f} arcsec measured, {pp[1]:.3f} arcsec without the runout"
            + (
                f" (each revolution: {by_rev[0].min():.3f} to {by_rev[0].max():.3f} measured, "
                f"{by_rev[1].min():.3f} to {by_rev[1].max():.3f} without)"
                if m.revolutions > 1
                else ""
            ),
            f"rms               {rms[0]:.3f} arcsec measured, {rms[1]:.3f} arcsec without the runout",
            "runout removed    "
            + (
                "; ".join(
                    f"{c.shaft} order {c.order}: {c.amplitude_arcsec:.3f}\u2033 at {c.phase_deg:.1f} deg"
                    for c in m.components
                )
                + "  (A cos(k theta - phase))"
                if m.components
                else "none"
            ),
        ]
        measured, reducer = m.largest_orders()
        lines += [
            f"largest orders    measured: {_lines(measured, 'g')}",
            f"                  without runout: {_lines(reducer, 'g')}",
        ]
        if m.hz is not None:
            measured, reducer = m.largest_lines_hz()
            lines += [
                f"output speed      {m.output_speed_hz:.6g} Hz ({60 * m.output_speed_hz:.4g} rpm),"
                f" mean over the whole revolutions",
                f"largest lines Hz  measured: {_lines(measured, '.4g', ' Hz')}",
                f"                  without runout: {_lines(reducer, '.4g', ' Hz')}",
            ]
        lines += [f"warning           {text}" for text in m.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The measured TE for scripts (`--json`): the figures of `summary` under their names
        with units, each TE figure as {measured, without_runout}; largest_lines_hz null
        without a time column."""
        m = self.measured
        pp, rms = m.te_pp_arcsec, m.te_rms_arcsec
        both = lambda pair: {"measured": pair[0], "without_runout": pair[1]}  # noqa: E731
        hz = m.largest_lines_hz()
        return {
            "data": self.data,
            "columns": list(self.columns),
            "units": list(self.units),
            "ratio": m.ratio,
            "measured_ratio": m.measured_ratio,
            "rows": {
                "first": m.first_row,
                "last": m.first_row + m.rows - 1,
                "used": m.rows,
                "not_used_after": m.rows_after,
            },
            "revolutions": m.revolutions,
            "sense": m.sense,
            "points_per_revolution": m.points_per_revolution,
            "rollovers": {"theta_in": m.rollovers[0], "theta_out": m.rollovers[1]},
            "offset_arcsec": m.offset_arcsec,
            "te_pp_arcsec": both([float(v) for v in pp]),
            "te_rms_arcsec": both([float(v) for v in rms]),
            "te_pp_by_revolution_arcsec": both(m.te_pp_by_revolution_arcsec.tolist()),
            "removed": [
                {
                    "shaft": c.shaft,
                    "order": c.order,
                    "amplitude_arcsec": c.amplitude_arcsec,
                    "phase_deg": c.phase_deg,
                }
                for c in m.components
            ],
            "largest_orders": both([[list(line) for line in lines] for lines in m.largest_orders()]),
            "output_speed_hz": m.output_speed_hz,
            "largest_lines_hz": None
            if hz is None
            else both([[list(line) for line in lines] for lines in hz]),
            "warnings": list(m.warnings),
        }

    def to_df(self):
        """The measured TE as a pandas DataFrame (one row per record row used), the columns of
        its CSV: time_s (if the record has a time column), theta_in_rad, theta_out_rad
        (unwrapped), te_arcsec (the offset removed), runout_arcsec (the bench's, fitted),
        te_reducer_arcsec (te_arcsec without the runout)."""
        m = self.measured
        time = {} if m.time is None else {"time_s": m.time}
        return columns_frame(
            {
                **time,
                "theta_in_rad": m.theta_in,
                "theta_out_rad": m.theta_out,
                "te_arcsec": m.te_arcsec,
                "runout_arcsec": m.runout_arcsec,
                "te_reducer_arcsec": m.te_reducer_arcsec,
            }
        )


def _lines(lines, spec, unit=""):
    return ", ".join(f"{format(at, spec)}{unit}: {amp:.3f}\u2033" for at, amp in lines)


def measure(
    data: str | Path,
    ratio: float,
    columns=None,
    units: str | None = None,
    counts_per_rev=None,
    remove_orders=(1,),
    remove_input_orders=(),
    keep_orders=(),
    csv_path: str | Path | None = None,
    plot_path: str | Path | None = None,
) -> MeasureReport:
    """TE of a bench run from its input and output encoder angles (`rvfmu.bench.measured`),
    over whole output revolutions, the bench's runout removed.

    data: a CSV with a header row; by default the columns time_s (optional),
    theta_in_deg, theta_out_deg (or _rad, _counts: the unit from the suffix).
    columns: (theta_in, theta_out) or (theta_in, theta_out, time) names instead;
    units: deg, rad or counts for both angle columns (needed when a name has no unit
    suffix); counts_per_rev: one number or (input, output) for counts.  remove_orders:
    output orders fitted and removed (default 1, the output encoder's eccentricity),
    remove_input_orders: input orders (cycles per input revolution), keep_orders: output
    orders kept after all.  Rows are numbered as the file's lines (the header is row 1),
    as in every message.  Writes the TE curve (csv_path) and a figure (plot_path), both
    paths checked before any work.
    """
    from ..bench.measured import angle_rad, check_rows, measure_te, unwrap
    from ..core.base.checks import positive

    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    ratio = positive("ratio", ratio)
    names, units_of = _measure_columns(data, columns, units)
    per_rev = _counts_per_rev(counts_per_rev, units_of)
    values = read_columns("data", data, tuple(n for n in names if n is not None))
    if names[2] is None:
        values.append(None)
    first_row = 2
    check_rows(dict(zip(names, values)), first_row, names[2])
    angles, rollovers = [], []
    for name, unit, raw, n in zip(names, units_of, values, per_rev):
        angle, count = unwrap(angle_rad(name, raw, unit, n))
        angles.append(angle)
        rollovers.append(count)
    result = measure_te(
        angles[0],
        angles[1],
        ratio,
        values[2],
        remove_orders=remove_orders,
        remove_input_orders=remove_input_orders,
        keep_orders=keep_orders,
        names=names,
        first_row=first_row,
        rollovers=tuple(rollovers),
    )
    report = MeasureReport(result, str(data), tuple(names), tuple(units_of))
    if csv_path is not None:
        write_frame(csv_path, report.to_df(), FORMATS)
    if plot_path is not None:
        from ..plots import plot_measured

        plot_measured(result, plot_path, title=f"{Path(data).name}: measured TE, ratio {ratio:g}")
    return report


def _measure_columns(data, columns, units):
    """((theta_in, theta_out, time or None) column names, (unit of theta_in, of theta_out))."""
    if units is not None and units not in ANGLE_UNITS:
        raise InputError("units", units, "must be one of " + ", ".join(ANGLE_UNITS))
    header = _csv_header("data", data)
    if columns is None:
        names = []
        for role in ANGLE_ROLES:
            found = [f"{role}_{u}" for u in ANGLE_UNITS if f"{role}_{u}" in header]
            if len(found) != 1:
                raise InputError(
                    "data",
                    str(data),
                    (
                        f"has {' and '.join(found)}: name the one to use with --columns"
                        if found
                        else f"needs a column {role}_deg, "
                        f"{role}_rad or {role}_counts (found: {', '.join(header)}), or "
                        "--columns naming the input and output angle columns"
                    ),
                )
            names.append(found[0])
        names.append("time_s" if "time_s" in header else None)
    else:
        names = [str(name).strip() for name in columns]
        if len(names) not in (2, 3) or not all(names):
            raise InputError(
                "columns",
                list(columns),
                "give the input angle, output angle and (optional) time columns, e.g. enc_in,enc_out,t",
            )
        for name in names:
            if name not in header:
                raise InputError(
                    "columns", name, f"is not a column of {data} (its columns: {', '.join(header)})"
                )
        names += [None] * (3 - len(names))
    units_of = []
    for name in names[:2]:
        suffix = name.rsplit("_", 1)[-1] if "_" in name else ""
        if suffix in ANGLE_UNITS:
            if units is not None and units != suffix:
                raise InputError("units", units, f"the column {name} is in {suffix} by its name")
            units_of.append(suffix)
        elif units is None:
            raise InputError(
                "units",
                None,
                f"the column {name} has no unit suffix (_deg, _rad, "
                "_counts): give --units deg, rad or counts",
            )
        else:
            units_of.append(units)
    return names, units_of


def _counts_per_rev(counts_per_rev, units_of):
    """(input, output) counts per revolution, None where a column is not in counts."""
    if counts_per_rev is None:
        given = (None, None)
    else:
        given = tuple(np.atleast_1d(np.asarray(counts_per_rev, dtype=object)).tolist())
        if len(given) == 1:
            given = given * 2
        if len(given) != 2:
            raise InputError(
                "counts_per_rev",
                counts_per_rev,
                "give one number, or two: the input encoder's and the output encoder's",
            )
        if "counts" not in units_of:
            raise InputError(
                "counts_per_rev",
                counts_per_rev,
                "applies to columns in counts only; these are in " + " and ".join(units_of),
            )
    return tuple(n if unit == "counts" else None for n, unit in zip(given, units_of)) + (None,)
