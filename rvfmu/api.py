"""One public function per job; the `rvte` CLI is a thin layer over these.

Each function takes file paths or preset names and plain numbers, checks the
output paths before any work (`rvfmu.outputs`), runs the core, writes the
files it was asked for and returns a small record.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from .core import metrics
from .core.checks import InputError
from .core.limits import check_load
from .core.design import PRESET_NAMES, RVDesign, in_file_units, load_design, preset
from .core.errors import ErrorSet, load_errors, zero_errors
from .core.quasistatic import TECurve, Windup, default_points, te_curve, windup
from .outputs import figure_file, output_file
from .budget import StiffnessReport, stiffness  # noqa: F401  (the job of `rvte stiffness`)
from .efficiency import EfficiencyReport, efficiency  # noqa: F401  (`rvte efficiency`)
from .hysteresis import HysteresisReport, hysteresis  # noqa: F401  (`rvte hysteresis`)
from .progress import counter as progress_counter

HARMONICS_SHOWN = 5


class NothingToWrite(InputError):
    """A job that writes files was given none to write."""

    def __init__(self, message):
        ValueError.__init__(self, message)
        self.field, self.value, self.allowed = "output", None, message


@dataclass(frozen=True)
class TEReport:
    """A TE curve of one reducer with its catalogue stiffness figures."""

    curve: TECurve
    windup: Windup
    lost_motion_arcmin: float
    torsional_rigidity_Nm_per_arcmin: float
    warnings: tuple[str, ...] = ()

    def summary(self) -> str:
        c = self.curve
        d = c.design
        orders, amplitudes = metrics.significant_orders(c.te_arcsec, HARMONICS_SHOWN)
        nyquist = c.points // 2
        pin_order = d.z_p * d.z_c
        lines = [
            f"design            {d.name} (ratio {d.ratio:g}, z_p {d.z_p}, z_c {d.z_c}, "
            f"{d.n_c} cranks)",
            f"load              {-c.tau_load:g} N*m resisting"
            + ("  (no-load limit)" if c.tau_load == 0 else ""),
            f"points            {c.points} per output revolution "
            + (f"(resolves the pin-passing order {pin_order})" if nyquist > pin_order else
               f"(Nyquist order {nyquist} < pin-passing order {pin_order}: that ripple aliases)"),
            f"te_pp             {c.te_pp_arcsec[0]:.3f} arcsec",
            f"rms               {c.rms_arcsec[0]:.3f} arcsec (about the mean)",
            f"mean              {c.mean_arcsec[0]:.3f} arcsec"
            + ("  (no load: the output's turn-back from its nominal place to the first contact,"
               " i.e. the free play that the profile modifications, errors and clearances leave)"
               if c.tau_load == 0 else ""),
            "largest orders    " + (", ".join(
                f"{o}: {a:.3f}\u2033" for o, a in zip(orders[0], amplitudes[0])) if len(orders[0])
                else f"none above the noise floor of {metrics.noise_floor(c.te_arcsec)[0]:.3g}\u2033"
                     " (the TE is flat)"),
            f"lost motion       {self.lost_motion_arcmin:.3f} arcmin (windup span at +-3 % of "
            f"{d.rated_torque:g} N*m)",
            f"torsional rigidity {self.torsional_rigidity_Nm_per_arcmin:.1f} N*m/arcmin "
            f"(50-100 % rated torque)",
        ]
        if not np.all(c.converged):
            lines.append("warning           the equilibrium did not converge at some angles")
        lines += [f"warning           {text}" for text in self.warnings]
        return "\n".join(lines)


def resolve_design(design: str | Path | RVDesign) -> RVDesign:
    return design if isinstance(design, RVDesign) else load_design(design)


def resolve_errors(design: RVDesign, errors: str | Path | ErrorSet | None) -> ErrorSet:
    if errors is None:
        return zero_errors(design)
    if isinstance(errors, ErrorSet):
        return errors.check(design)
    return load_errors(errors, design)


def te(design, errors=None, load: float = 0.0, points: int | None = None,
       csv_path: str | Path | None = None, plot_path: str | Path | None = None,
       progress=None) -> TEReport:
    """TE curve of one reducer at a resisting load [N*m] (0: no-load limit), with lost
    motion and torsional rigidity; writes the CSV and the plot if paths are given
    (both checked before any work).  A load beyond 5x the rated torque raises
    InputError; beyond 2.5x the report carries a warning (`rvfmu.core.limits`).

    progress(total, done): optional, called as the curve's angles are solved.
    """
    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    note = check_load("load", load, design.rated_torque)
    if points is None:
        points = default_points(design)
    curve = te_curve(design, errors, tau_load=-load, points=points,
                     progress=progress_counter(points, progress))
    wind = windup(design, errors)
    report = TEReport(curve, wind, float(wind.lost_motion_arcmin()[0]),
                      float(wind.torsional_rigidity_Nm_per_arcmin()[0]), (note,) if note else ())
    if csv_path is not None:
        write_te_csv(curve, csv_path)
    if plot_path is not None:
        from .plots import plot_te

        plot_te(curve, plot_path)
    return report


def write_columns(path: str | Path, columns: dict) -> Path:
    """A CSV of equal-length columns: {name: (values, format spec)}, a header of the names."""
    path = Path(path)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(list(columns))
        formats = [spec for _, spec in columns.values()]
        for row in zip(*(values for values, _ in columns.values())):
            writer.writerow([format(value, spec) for value, spec in zip(row, formats)])
    return path


def read_columns(field: str, path: str | Path, names: tuple[str, ...]) -> list[np.ndarray]:
    """The columns `names` of a CSV file with a header row, as float arrays; an InputError
    naming the field, the file and the row for a missing file, column or non-number."""
    rows = _csv_rows(field, path)
    header = [name.strip() for name in rows[0]] if rows else []
    missing = [name for name in names if name not in header]
    if missing:
        raise InputError(field, str(path), f"needs a header row with the columns "
                         f"{', '.join(names)} (missing: {', '.join(missing)})")
    out = []
    for name in names:
        k = header.index(name)
        values = []
        for line, row in enumerate(rows[1:], start=2):
            try:
                values.append(float(row[k]))
            except (IndexError, ValueError):
                text = row[k] if k < len(row) else "nothing"
                raise InputError(field, f"{text!r} in column {name} on line {line} of {path}",
                                 "every entry must be a number") from None
        out.append(np.array(values))
    return out


def write_te_csv(curve: TECurve, path: str | Path, sample: int = 0) -> Path:
    """Columns theta_in_rad, theta_out_rad, te_arcsec (names of docs/model.md section 5)."""
    return write_columns(path, {"theta_in_rad": (curve.theta_in, ".12g"),
                                "theta_out_rad": (curve.theta_out[sample], ".12g"),
                                "te_arcsec": (curve.te_arcsec[sample], ".6f")})


@dataclass(frozen=True)
class SimulationReport:
    """A dynamic run with the figures an engineer reads first (after the start ramp)."""

    simulation: object
    peaks: tuple

    def summary(self) -> str:
        sim = self.simulation
        d = sim.design
        te = sim.steady_te_arcsec()
        start, stop = sim.time[sim.steady], sim.time[-1]
        load = -sim.tau_load
        if np.ptp(load) == 0.0:
            load_text = f"load {load[0]:g} N*m resisting"
        else:
            load_text = f"load {load.min():g} to {load.max():g} N*m resisting (in time)"
        sampled = sim.drive == "sampled"
        lines = [
            f"design            {d.name} (ratio {d.ratio:g}), dynamic model",
            f"input             {'sampled angles, mean speed' if sampled else 'speed'} "
            f"{sim.speed_rpm:g} rpm; {load_text}",
            f"interval          {start:.4g} s to {stop:.4g} s "
            + ("(the whole sampled input)" if sampled else "at constant speed (after the start ramp)")
            + f", step {sim.step * 1e6:.4g} us, {sim.time.size} steps",
            f"TE range          {te.min():.3f} to {te.max():.3f} arcsec",
            f"te_pp             {te.max() - te.min():.3f} arcsec",
            "largest peaks     " + (", ".join(f"{f:.1f} Hz: {a:.3f}\u2033" for f, a in self.peaks)
                                    or f"none above {metrics.NOISE_FLOOR_ARCSEC:g}\u2033"),
            f"{'excitation':<24} {'frequency [Hz]':>14} {'TE amplitude [arcsec]':>22}",
        ]
        lines += [f"  {name:<22} {hz:>14.2f} " + (f"{amp:>22.4f}" if amp is not None else
                                                  f"{'above Nyquist':>22}")
                  for name, hz, amp in sim.excitation_amplitudes()]
        power = sim.mean_powers()
        eta = power["efficiency"]
        lines.append(
            f"power (mean)      input {power['input_W']:.4g} W, output {power['output_W']:.4g} W, "
            f"friction {power['friction_W']:.4g} W, damping {power['damping_W']:.3g} W"
            + (f"; efficiency {100 * eta:.1f} %" if eta is not None else ""))
        if sim.failed_steps:
            lines.append(f"warning           {sim.failed_steps} steps did not converge")
        return "\n".join(lines)

    def to_json(self) -> dict:
        sim = self.simulation
        te = sim.steady_te_arcsec()
        return {"design": sim.design.name, "speed_rpm": sim.speed_rpm, "drive": sim.drive,
                "load_Nm": [float(-sim.tau_load.max()), float(-sim.tau_load.min())]
                if np.ptp(sim.tau_load) else float(-sim.tau_load[0]),
                "interval_s": [float(sim.time[sim.steady]),
                                                                   float(sim.time[-1])],
                "step_s": sim.step, "te_range_arcsec": [float(te.min()), float(te.max())],
                "te_pp_arcsec": float(te.max() - te.min()),
                "peaks": [[f, a] for f, a in self.peaks], "failed_steps": sim.failed_steps,
                "excitations": [{"name": name, "frequency_hz": hz, "amplitude_arcsec": amp}
                                for name, hz, amp in sim.excitation_amplitudes()],
                "power_W": {k[:-2]: v for k, v in sim.mean_powers().items() if k.endswith("_W")},
                "efficiency": sim.mean_powers()["efficiency"]}


def simulate(design, errors=None, speed_rpm: float | None = 1600.0, load=0.0,
             duration: float | None = None, revolutions: float | None = None,
             contact: str | None = None, mesh: str = "varying", step: float | None = None,
             csv_path: str | Path | None = None, plot_path: str | Path | None = None,
             progress=None, load_step: tuple[float, float] | None = None,
             load_csv: str | Path | None = None,
             input_csv: str | Path | None = None, friction: bool = True) -> SimulationReport:
    """Dynamic TE of one reducer (docs/model.md section 7) at a constant input speed after a
    start ramp, or along sampled input angles; writes the CSV (time_s, theta_in_rad,
    theta_out_rad, te_arcsec, tau_in_Nm) and the plot if asked.

    load [N*m resisting]: constant; load_step (time [s], load [N*m]): the load
    changes to that value at that time of the run; load_csv: a file of columns
    time_s, load_Nm (linear between rows, held beyond).  input_csv: a file of
    columns time_s, theta_in_rad, used instead of speed_rpm and the ramp.  friction: False
    leaves out the contacts' friction and drag (docs/model.md section 9).
    """
    from .core.simulation import Sampled, simulate as run

    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    given = [name for name, value in (("load_step", load_step), ("load_csv", load_csv))
             if value is not None]
    if len(given) > 1:
        raise InputError(given[1], locals()[given[1]], "give one of --load-step and --load-csv")
    if load_step is not None:
        at, after = load_step
        load = Sampled.step(load, at, after)
    if load_csv is not None:
        time, values = read_columns("load_csv", load_csv, ("time_s", "load_Nm"))
        load = Sampled.checked("load_csv", time, values)
    input_angle = None
    if input_csv is not None:
        time, values = read_columns("input_csv", input_csv, ("time_s", "theta_in_rad"))
        input_angle = Sampled.checked("input_csv", time, values, at_least=4)
        speed_rpm = None
    design = resolve_design(design)
    sim = run(design, resolve_errors(design, errors), speed_rpm=speed_rpm, load=load,
              duration=duration, revolutions=revolutions, contact=contact, mesh=mesh, step=step,
              progress=progress, input_angle=input_angle, friction=friction)
    report = SimulationReport(sim, tuple(sim.peaks_hz()))
    if csv_path is not None:
        write_columns(csv_path, {"time_s": (sim.time, ".9g"), "theta_in_rad": (sim.theta_in, ".12g"),
                                 "theta_out_rad": (sim.theta_out, ".12g"),
                                 "te_arcsec": (sim.te_arcsec, ".6f"), "tau_in_Nm": (sim.tau_in, ".6g")})
    if plot_path is not None:
        from .plots import plot_simulation

        plot_simulation(sim, plot_path)
    return report


@dataclass(frozen=True)
class ModesReport:
    """Natural frequencies at the loaded equilibrium beside the excitations at a speed."""

    modes: object
    design: RVDesign
    speed_rpm: float
    count: int

    def excitations(self):
        from .core.excitations import Excitations

        return Excitations.at(self.design, self.speed_rpm)

    def summary(self) -> str:
        m, ex = self.modes, self.excitations()
        lines = [f"design            {self.design.name}: natural frequencies of the dynamic model "
                 f"linearised at its equilibrium under {-m.tau_load:g} N*m resisting",
                 f"{'mode':>4} {'frequency [Hz]':>15} {'damping':>8}  dominant parts (share of "
                 "kinetic energy)"]
        for k, hz, parts in m.table(self.count, parts=3):
            lines.append(f"{k + 1:>4} {hz:>15.1f} {100 * m.damping_ratios[k]:>7.2f}%  " + ", ".join(
                f"{label} {100 * share:.0f} %" for label, share in parts if share >= 0.005))
        lines.append(f"excitations at {self.speed_rpm:g} rpm: " + ", ".join(
            f"{name} {hz:.1f} Hz" for name, hz in ex.items()))
        near = [(name, hz, float(m.frequencies_hz[np.argmin(np.abs(m.frequencies_hz - hz))]))
                for name, hz in ex.items()]
        close = [(n, hz, f) for n, hz, f in near if abs(f - hz) <= 0.1 * f]
        lines.append("resonance         " + ("; ".join(f"{n} {hz:.1f} Hz is within 10 % of the "
                                                      f"mode at {f:.1f} Hz" for n, hz, f in close)
                                             or "no excitation within 10 % of a natural frequency"))
        if m.dropped:
            lines.append(f"note              {m.dropped} floating modes (parts inside a bearing "
                         "clearance) left out")
        return "\n".join(lines)

    def to_json(self) -> dict:
        m = self.modes
        return {"design": self.design.name, "load_Nm": float(-m.tau_load),
                "modes": [{"hz": hz, "damping_ratio": float(m.damping_ratios[k]),
                           "parts": [[label, share] for label, share in parts]}
                          for k, hz, parts in m.table(self.count, parts=3)],
                "speed_rpm": self.speed_rpm,
                "excitations_hz": {name: hz for name, hz in self.excitations().items()}}


def modes(design, errors=None, load: float = 0.0, speed_rpm: float = 1600.0, count: int = 12,
          plot_path: str | Path | None = None) -> ModesReport:
    """Natural frequencies and mode shapes of the dynamic model at its equilibrium under a
    resisting `load` [N*m], beside the excitations at `speed_rpm`; `plot_path`: a Campbell
    diagram from 0 to 1.25 x that speed."""
    from .core.checks import integer, positive
    from .core.modes import campbell, modes as linearised

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    speed_rpm = positive("speed_rpm", speed_rpm)
    count = integer("count", count, 1)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    result = linearised(design, errors, load=load)
    if plot_path is not None:
        from .plots import plot_campbell

        speeds, lines = campbell(design, errors, load, np.linspace(0.0, 1.25 * speed_rpm, 200))
        plot_campbell(design, result.frequencies_hz[:count], speeds, lines, speed_rpm, plot_path)
    return ModesReport(result, design, speed_rpm, count)


def errors_template(design, output: str | Path | None = None) -> str:
    """A complete, commented error file for `design` (every name of docs/model.md
    section 4, zero values of the right shapes); written to `output` if given."""
    from .core.errors import error_template_text

    output = None if output is None else output_file("output", output, ("toml",))
    text = error_template_text(resolve_design(design))
    if output is not None:
        output.write_text(text)
    return text


@dataclass(frozen=True)
class PresetInfo:
    name: str
    ratio: float
    source: str
    design: RVDesign


def presets() -> list[PresetInfo]:
    """The shipped presets with their ratios and sources."""
    infos = []
    for name in PRESET_NAMES:
        text = resources.files("rvfmu.core.presets").joinpath(f"{name}.toml").read_text()
        first = text.splitlines()[0]
        source = first.split("Source:", 1)[1].strip().rstrip(".") if "Source:" in first else ""
        design = preset(name)
        infos.append(PresetInfo(name, design.ratio, source, design))
    return infos


@dataclass(frozen=True)
class CatalogueReport:
    """The presets against their frames' catalogue figures (`rvfmu.catalogue`)."""

    rows: list

    def summary(self) -> str:
        from . import catalogue

        head = (f"{'preset':<11} {'frame':<8} {'rated N*m':>9}  {'torsional rigidity N*m/arcmin':>31}"
                f"  {'lost motion arcmin':>28}")
        sub = (f"{'':<11} {'':<8} {'':>9}  {'estimate':>9} {'preset':>9} {'catalogue':>11}  "
               f"{'estimate':>9} {'preset':>8} {'catalogue':>9}")
        lines = [head, sub]
        for r in self.rows:
            f = r.frame
            lines.append(
                f"{r.name:<11} {f.name:<8} {r.rated_torque_Nm:>9.0f}  "
                f"{r.estimate.torsional_rigidity_Nm_per_arcmin:>9.1f} "
                f"{r.calibrated.torsional_rigidity_Nm_per_arcmin:>9.1f} "
                f"{f.torsional_rigidity_Nm_per_arcmin:>7.0f} {'ok' if r.rigidity_within else 'NO':>3}  "
                f"{r.estimate.lost_motion_arcmin:>9.3f} {r.calibrated.lost_motion_arcmin:>8.3f} "
                f"{'<= ' + format(f.lost_motion_max_arcmin, 'g'):>6} {'ok' if r.lost_motion_within else 'NO':>2}")
        lines += [
            "estimate: the preset before calibration (<name>-estimate); preset: as shipped, "
            "calibrated to the catalogue",
            f"ok: rigidity within {100 * catalogue.RIGIDITY_TOLERANCE:g} % of the catalogue's, "
            "lost motion within its bound (docs/model.md section 5 test, no errors)",
            f"catalogue: {catalogue.source()}",
        ]
        for r in self.rows:
            c = r.calibration
            if c:
                lines.append(f"{r.name}: output_stiffness {c['output_stiffness']:.4g} N*m/arcmin, "
                             f"modification_scale {c['modification_scale']:.4g} "
                             f"({c['fit'].split(': ')[-1]})")
        return "\n".join(lines)

    def to_json(self) -> dict:
        return _json_safe({"source": self.rows[0].frame.source if self.rows else "", "presets": [
            {"name": r.name, "frame": r.frame.name, "rated_torque_Nm": r.rated_torque_Nm,
             "catalogue": {"rated_torque_Nm": r.frame.rated_torque_Nm,
                           "torsional_rigidity_Nm_per_arcmin": r.frame.torsional_rigidity_Nm_per_arcmin,
                           "lost_motion_max_arcmin": r.frame.lost_motion_max_arcmin,
                           "backlash_max_arcmin": r.frame.backlash_max_arcmin},
             "estimate": vars(r.estimate), "preset": vars(r.calibrated),
             "rigidity_within": r.rigidity_within, "lost_motion_within": r.lost_motion_within,
             "calibration": r.calibration} for r in self.rows]})


def presets_catalogue(plot_path: str | Path | None = None) -> CatalogueReport:
    """Every preset's torsional rigidity and lost motion, before and after its calibration,
    beside its frame's catalogue figures; plot_path: a figure of the windup curves."""
    from . import catalogue

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    report = CatalogueReport(catalogue.against_catalogue())
    if plot_path is not None:
        from .plots import plot_catalogue

        plot_catalogue(report.rows, plot_path)
    return report


def profile(design, csv_path: str | Path | None = None, dxf_path: str | Path | None = None,
            points: int | None = None):
    """The disc profile of a design; writes CSV (mm) and/or DXF (mm)."""
    from .core import profile as prof

    if csv_path is None and dxf_path is None:
        raise NothingToWrite("nothing to write: give --csv FILE and/or --dxf FILE")
    csv_path = None if csv_path is None else output_file("csv", csv_path)
    dxf_path = None if dxf_path is None else output_file("dxf", dxf_path, ("dxf",))
    design = resolve_design(design)
    points = prof.DEFAULT_POINTS if points is None else points
    if csv_path is not None:
        prof.write_profile_csv(design, csv_path, points)
    if dxf_path is not None:
        prof.write_profile_dxf(design, dxf_path, points)
    return prof.disc_profile(design, points)


__all__ = ["te", "presets", "presets_catalogue", "CatalogueReport", "profile", "errors_template", "simulate", "SimulationReport", "modes",
           "ModesReport", "TEReport", "default_points", "write_te_csv"]


ANGLE_UNITS = ("deg", "rad", "counts")
ANGLE_ROLES = ("theta_in", "theta_out")


@dataclass(frozen=True)
class MeasureReport:
    """TE of a bench record (`rvfmu.measured.MeasuredTE`) with where it came from."""

    measured: object
    data: str
    columns: tuple            # (theta_in, theta_out, time or None): the file's column names
    units: tuple              # (theta_in, theta_out): deg, rad or counts

    def summary(self) -> str:
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
            + (f"; the {m.rows_after} rows after the last whole revolution are not used"
               if m.rows_after else ""),
            f"sampling          {m.points_per_revolution} rows per output revolution "
            f"(orders below {m.points_per_revolution // 2} resolved)",
            f"ratio             {m.ratio:g} stated, {m.measured_ratio:.6g} measured (least-squares "
            f"slope of {name_in} against {name_out}, {100 * (m.measured_ratio / m.ratio - 1):+.2g} %)",
            f"roll-overs        {m.rollovers[0]} of the input encoder, {m.rollovers[1]} of the "
            "output encoder unwrapped",
            f"offset            {m.offset_arcsec:.3f} arcsec removed (the mean: the encoders' zeros)",
            f"te_pp             {pp[0]:.3f} arcsec measured, {pp[1]:.3f} arcsec without the runout"
            + (f" (each revolution: {by_rev[0].min():.3f} to {by_rev[0].max():.3f} measured, "
               f"{by_rev[1].min():.3f} to {by_rev[1].max():.3f} without)" if m.revolutions > 1
               else ""),
            f"rms               {rms[0]:.3f} arcsec measured, {rms[1]:.3f} arcsec without the runout",
            "runout removed    " + ("; ".join(
                f"{c.shaft} order {c.order}: {c.amplitude_arcsec:.3f}\u2033 at {c.phase_deg:.1f} deg"
                for c in m.components) + "  (A cos(k theta - phase))" if m.components else "none"),
        ]
        measured, reducer = m.largest_orders()
        lines += [f"largest orders    measured: {_lines(measured, 'g')}",
                  f"                  without runout: {_lines(reducer, 'g')}"]
        if m.hz is not None:
            measured, reducer = m.largest_lines_hz()
            lines += [f"output speed      {m.output_speed_hz:.6g} Hz ({60 * m.output_speed_hz:.4g} rpm),"
                      f" mean over the whole revolutions",
                      f"largest lines Hz  measured: {_lines(measured, '.4g', ' Hz')}",
                      f"                  without runout: {_lines(reducer, '.4g', ' Hz')}"]
        lines += [f"warning           {text}" for text in m.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        m = self.measured
        pp, rms = m.te_pp_arcsec, m.te_rms_arcsec
        both = lambda pair: {"measured": pair[0], "without_runout": pair[1]}  # noqa: E731
        hz = m.largest_lines_hz()
        return {
            "data": self.data, "columns": list(self.columns), "units": list(self.units),
            "ratio": m.ratio, "measured_ratio": m.measured_ratio,
            "rows": {"first": m.first_row, "last": m.first_row + m.rows - 1, "used": m.rows,
                     "not_used_after": m.rows_after},
            "revolutions": m.revolutions, "sense": m.sense,
            "points_per_revolution": m.points_per_revolution,
            "rollovers": {"theta_in": m.rollovers[0], "theta_out": m.rollovers[1]},
            "offset_arcsec": m.offset_arcsec,
            "te_pp_arcsec": both([float(v) for v in pp]),
            "te_rms_arcsec": both([float(v) for v in rms]),
            "te_pp_by_revolution_arcsec": both(m.te_pp_by_revolution_arcsec.tolist()),
            "removed": [{"shaft": c.shaft, "order": c.order, "amplitude_arcsec": c.amplitude_arcsec,
                         "phase_deg": c.phase_deg} for c in m.components],
            "largest_orders": both([[list(line) for line in lines] for lines in m.largest_orders()]),
            "output_speed_hz": m.output_speed_hz,
            "largest_lines_hz": None if hz is None else both([[list(line) for line in lines]
                                                             for lines in hz]),
            "warnings": list(m.warnings),
        }


def _lines(lines, spec, unit=""):
    return ", ".join(f"{format(at, spec)}{unit}: {amp:.3f}\u2033" for at, amp in lines)


def measure(data: str | Path, ratio: float, columns=None, units: str | None = None,
            counts_per_rev=None, remove_orders=(1,), remove_input_orders=(), keep_orders=(),
            csv_path: str | Path | None = None,
            plot_path: str | Path | None = None) -> MeasureReport:
    """TE of a bench run from its input and output encoder angles (`rvfmu.measured`),
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
    from .core.checks import positive
    from .measured import angle_rad, check_rows, measure_te, unwrap

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
    result = measure_te(angles[0], angles[1], ratio, values[2], remove_orders=remove_orders,
                        remove_input_orders=remove_input_orders, keep_orders=keep_orders,
                        names=names, first_row=first_row, rollovers=tuple(rollovers))
    report = MeasureReport(result, str(data), tuple(names), tuple(units_of))
    if csv_path is not None:
        time = {} if result.time is None else {"time_s": (result.time, ".9g")}
        write_columns(csv_path, {**time, "theta_in_rad": (result.theta_in, ".12g"),
                                 "theta_out_rad": (result.theta_out, ".12g"),
                                 "te_arcsec": (result.te_arcsec, ".6f"),
                                 "runout_arcsec": (result.runout_arcsec, ".6f"),
                                 "te_reducer_arcsec": (result.te_reducer_arcsec, ".6f")})
    if plot_path is not None:
        from .plots import plot_measured

        plot_measured(result, plot_path, title=f"{Path(data).name}: measured TE, ratio {ratio:g}")
    return report


def _csv_header(field: str, path: str | Path) -> list[str]:
    rows = _csv_rows(field, path, header_only=True)
    return [name.strip() for name in rows[0]] if rows else []


def _csv_rows(field: str, path: str | Path, header_only: bool = False) -> list[list[str]]:
    """The non-empty rows of a CSV file (only the first with header_only), or an InputError
    naming the field and the file when it is missing or not text (UTF-8)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(field, str(path), "must be an existing CSV file")
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = csv.reader(line for line in handle if line.strip())
            return [next(rows, [])] if header_only else list(rows)
    except UnicodeDecodeError as exc:
        raise InputError(field, str(path), f"is not a text (UTF-8) CSV file: byte {exc.start} "
                         f"is {exc.object[exc.start:exc.start + 1]!r}") from None


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
                raise InputError("data", str(data), (f"has {' and '.join(found)}: name the one to "
                                 "use with --columns" if found else f"needs a column {role}_deg, "
                                 f"{role}_rad or {role}_counts (found: {', '.join(header)}), or "
                                 "--columns naming the input and output angle columns"))
            names.append(found[0])
        names.append("time_s" if "time_s" in header else None)
    else:
        names = [str(name).strip() for name in columns]
        if len(names) not in (2, 3) or not all(names):
            raise InputError("columns", list(columns), "give the input angle, output angle and "
                             "(optional) time columns, e.g. enc_in,enc_out,t")
        for name in names:
            if name not in header:
                raise InputError("columns", name, f"is not a column of {data} (its columns: "
                                 f"{', '.join(header)})")
        names += [None] * (3 - len(names))
    units_of = []
    for name in names[:2]:
        suffix = name.rsplit("_", 1)[-1] if "_" in name else ""
        if suffix in ANGLE_UNITS:
            if units is not None and units != suffix:
                raise InputError("units", units, f"the column {name} is in {suffix} by its name")
            units_of.append(suffix)
        elif units is None:
            raise InputError("units", None, f"the column {name} has no unit suffix (_deg, _rad, "
                             "_counts): give --units deg, rad or counts")
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
            raise InputError("counts_per_rev", counts_per_rev, "give one number, or two: the "
                             "input encoder's and the output encoder's")
        if "counts" not in units_of:
            raise InputError("counts_per_rev", counts_per_rev, "applies to columns in counts "
                             "only; these are in " + " and ".join(units_of))
    return tuple(n if unit == "counts" else None for n, unit in zip(given, units_of)) + (None,)


__all__ += ["measure", "MeasureReport"]


# -- measured against modelled: rvte compare, rvte calibrate ---------------------------------

BY_ORDER_SHOWN = 8


@dataclass(frozen=True)
class CompareReport:
    """A bench record beside the model (`rvfmu.compare.Comparison`), with where it came from."""

    comparison: object
    data: str
    errors: str | None

    def summary(self) -> str:
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
            + ("one revolution (the TE repeats every output revolution: whole ratio)"
               if c.periodic else "over the record's input angles")
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
        lines += [f"                  {o:>8g} {a:>9.3f} {b:>9.3f} {x:>9.3f}"
                  for o, a, b, x in c.by_order(BY_ORDER_SHOWN)]
        if not c.converged:
            lines.append("warning           the model's equilibrium did not converge at some angles")
        nyquist = c.points // 2
        if nyquist <= d.z_p * d.z_c:
            lines.append(f"note              {c.points} model points per revolution do not resolve "
                         f"the pin-passing order {d.z_p * d.z_c}")
        lines += [f"warning           {text}" for text in m.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        c = self.comparison
        pp, rms = c.te_pp_arcsec, c.rms_arcsec
        return _json_safe({"design": c.design.name, "data": self.data, "errors": self.errors,
                "load_Nm": c.load_Nm, "model_points_per_revolution": c.points,
                "model_grid": "one periodic output revolution" if c.periodic else "record range",
                "model_at_rows": "linear interpolation from the grid",
                "revolutions": c.measured.revolutions, "rows": c.measured.rows,
                "removed": [{"shaft": x.shaft, "order": x.order} for x in c.measured.components],
                "te_pp_arcsec": {"measured": float(pp[0]), "model": float(pp[1])},
                "rms_arcsec": {"measured": float(rms[0]), "model": float(rms[1])},
                "correlation": c.correlation, "rms_difference_arcsec": c.rms_difference_arcsec,
                "best_shift_deg": c.shift_deg, "best_shift_correlation": c.shift_correlation,
                "by_order": [{"order": o, "measured_arcsec": a, "model_arcsec": b,
                              "difference_arcsec": x} for o, a, b, x in c.by_order(BY_ORDER_SHOWN)],
                "converged": c.converged, "warnings": list(c.measured.warnings)})


def _json_safe(value):
    """`value` with every float that is not finite as text ("inf", "nan"): JSON has neither."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else str(float(value))
    return value


def _design_ratio(design: RVDesign, ratio) -> float:
    """The design's ratio, or a stated one that must agree with it."""
    if ratio is None:
        return design.ratio
    from .core.checks import positive

    ratio = positive("ratio", ratio)
    if abs(ratio / design.ratio - 1.0) > 1e-9:
        raise InputError("ratio", ratio, f"the design {design.name} has ratio {design.ratio:g}: "
                         "leave --ratio out (it is taken from the design) or give that")
    return design.ratio


def compare(design, data, errors=None, load: float = 0.0, ratio: float | None = None,
            columns=None, units: str | None = None, counts_per_rev=None, remove_orders=(1,),
            remove_input_orders=(), keep_orders=(), points: int | None = None,
            csv_path: str | Path | None = None,
            plot_path: str | Path | None = None) -> CompareReport:
    """A bench record (read and processed as `measure` does, the ratio the design's) beside the
    model of `design` with `errors` at the resisting `load` [N*m] the bench ran at: te_pp,
    RMS, correlation and the difference, by angle and by order (`rvfmu.compare`).

    points: the model's grid per output revolution (default 8 per pin-passing period); the
    model is interpolated from it to the record's input angles.  csv_path: theta_in_rad,
    te_measured_arcsec, te_model_arcsec, difference_arcsec; plot_path: the curves, their
    spectra and the difference.  Paths, design, errors, load and points are checked before
    the data are read.
    """
    from .compare import compare_te
    from .core.checks import integer

    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    error_set = resolve_errors(design, errors)
    check_load("load", load, design.rated_torque)
    points = None if points is None else integer("points", points, 8)
    ratio = _design_ratio(design, ratio)
    record = measure(data, ratio, columns=columns, units=units, counts_per_rev=counts_per_rev,
                     remove_orders=remove_orders, remove_input_orders=remove_input_orders,
                     keep_orders=keep_orders).measured
    result = compare_te(record, design, error_set, load, points)
    report = CompareReport(result, str(data), None if errors is None else str(errors))
    if csv_path is not None:
        write_columns(csv_path, {"theta_in_rad": (record.theta_in, ".12g"),
                                 "te_measured_arcsec": (result.measured_arcsec, ".6f"),
                                 "te_model_arcsec": (result.model_arcsec, ".6f"),
                                 "difference_arcsec": (result.difference_arcsec, ".6f")})
    if plot_path is not None:
        from .plots import plot_comparison

        plot_comparison(result, plot_path, title=f"{Path(data).name} against {design.name} at "
                                                 f"{load:g} N·m")
    return report


@dataclass(frozen=True)
class CalibrateReport:
    """A calibration (`rvfmu.calibration.Calibration`) with its inputs and output file."""

    calibration: object
    data: tuple[str, ...]
    output: str | None

    def summary(self) -> str:
        from .calibration import describe, setting

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
            from .calibration import default_points as calibration_points

            full = default_points(d)
            lines.append(f"model             {prob.points} points per output revolution (" + (
                f"the pin-passing order {d.z_p * d.z_c} resolved)" if prob.points // 2 > d.z_p * d.z_c
                else f"32*z_p or more: under load the peaks within ~1 % of the {full}-point "
                     "model's, see rvfmu/calibration.py)" if prob.points >= calibration_points(d)
                else f"fewer than the default {calibration_points(d)}: the peaks may be several % "
                     f"below the {full}-point model's)"))
        lines += [f"fit               least squares on ln(value): differential_evolution, then "
                  f"least_squares; {cal.evaluations} model evaluations"]
        width = max(17, *(len(p.name) + 1 for p in prob.parameters))
        lines.append(f"{'value':<{width}} {'start':>10} {'bounds':>21} {'fitted':>10} "
                     f"{'1-sigma':>9} {'per +1 %':>9}  unit")
        for p, v, s, b, sens in zip(prob.parameters, cal.values, cal.sigma, cal.at_bound,
                                    cal.sensitivity()):
            note = "  at bound" if b else ""
            if not np.isfinite(s):
                note += "  not identifiable" if np.isinf(s) else "  (no variance left)"
            elif s > v:
                note += "  (sigma > value: not determined by these data)"
            lines.append(f"{p.name:<{width}} {p.value:>10.4g} {p.lower:>10.4g}-{p.upper:<10.4g} "
                         f"{v:>10.4g} {s:>9.3g} {sens:>9.3g}  {p.unit}{note}")
        lines.append(f"{'':<{width}} per +1 %: RMS change of the residuals [{unit}]")
        lines += [f"{'':<{width}} {p.name}: {describe(p)}; fitted: {setting(p, v)}"
                  for p, v in zip(prob.parameters, cal.values) if p.name != p.field]
        rows = cal.misfit()
        if prob.target == "peaks":
            lines.append(f"{'data set':<17} {'measured':>9} {'before':>9} {'misfit':>8} {'after':>9} "
                         f"{'misfit':>8} {'improvement':>12}  [arcsec]")
            lines += [f"{r['name']:<17} {r['measured']:>9.3f} {r['before']:>9.3f} "
                      f"{r['misfit_before']:>+8.3f} {r['after']:>9.3f} {r['misfit_after']:>+8.3f} "
                      f"{r['improvement_percent']:>11.2f} %" for r in rows]
        elif prob.target == "curve":
            lines.append(f"{'data set':<17} {'te_pp':>9} {'before':>9} {'after':>9} "
                         f"{'RMS misfit before':>18} {'after':>8} {'improvement':>12}  [arcsec]")
            lines += [f"{r['name']:<17} {r['measured']:>9.3f} {r['before']:>9.3f} {r['after']:>9.3f} "
                      f"{r['misfit_before']:>18.3f} {r['misfit_after']:>8.3f} "
                      f"{r['improvement_percent']:>11.2f} %" for r in rows]
        else:
            lines.append(f"{'figure':<34} {'catalogue':>10} {'before':>10} {'after':>10}")
            for r in rows:
                for name, m, b, a in zip(r["figures"], r["measured"], r["before"], r["after"]):
                    lines.append(f"{name:<34} {m:>10.4g} {b:>10.4g} {a:>10.4g}")
        v0, v1 = cal.v_index
        lines.append(f"V (mean squared misfit) {v0:.4g} before, {v1:.4g} after"
                     + (f" ({100 * (1 - v1 / v0):.2f} % reduction)" if v0 else ""))
        lines += [f"optimiser         {m}" for m in cal.messages]
        if not cal.converged:
            lines.append("warning           the model's equilibrium did not converge at some poses")
        if self.output:
            lines.append(f"wrote design      {self.output} (for rvte te, rvte fmu build and the "
                         "studies)")
        return "\n".join(lines)

    def to_json(self) -> dict:
        cal = self.calibration
        prob = cal.problem
        v0, v1 = cal.v_index
        return _json_safe({"design": prob.design.name, "data": list(self.data), "target": prob.target,
                "points_per_revolution": prob.points, "evaluations": cal.evaluations,
                "fitted": [{"name": p.name, "field": p.field, "unit": p.unit, "start": p.value,
                            "bounds": [p.lower, p.upper], "value": float(v),
                            "sigma": float(s), "at_bound": bool(b),
                            "sets": in_file_units(p.field_values(float(v))),
                            "rms_change_per_percent": float(k)}
                           for p, v, s, b, k in zip(prob.parameters, cal.values, cal.sigma,
                                                    cal.at_bound, cal.sensitivity())],
                "misfit": cal.misfit(), "v_index": {"before": v0, "after": v1},
                "dof": cal.dof, "messages": list(cal.messages), "converged": cal.converged,
                "output": self.output})


def calibrate(design, data, fit, target: str | None = None, errors=None, load: float = 0.0,
              bounds: dict | None = None, ratio: float | None = None, columns=None,
              units: str | None = None, counts_per_rev=None, remove_orders=(1,),
              remove_input_orders=(), keep_orders=(), points: int | None = None,
              maxiter: int | None = None, popsize: int | None = None, seed: int | None = None,
              output: str | Path | None = None, progress=None) -> CalibrateReport:
    """Identify stiffnesses and friction fields of `design` from measurements
    (`rvfmu.calibration`).

    data: files, each a bench CSV (read as `measure` reads it, the design's ratio; at
    `load` with `errors`), a data-set TOML ([[dataset]] tables with te_pp_arcsec or data,
    load_Nm, errors, error_scale) or a catalogue TOML (torsional_rigidity_Nm_per_arcmin,
    lost_motion_arcmin, rated_torque_Nm; [[efficiency]] and [[running_torque]] tables).
    fit: names (R_ca, R_b, R_pd of seed 003, stiffness fields, output_stiffness,
    modification_scale, friction fields); target: peaks, curve or catalogue (default: what
    the data bring); bounds: {name: (lower, upper)} in each value's unit.  maxiter, popsize, seed: differential_evolution's
    budget and seed.  output: the calibrated design TOML to write.  Everything is checked
    before the first model evaluation.  progress(total, done): optional.
    """
    from . import calibration as calib

    output = None if output is None else output_file("output", output, ("toml",))
    resolved = resolve_design(design)
    check_load("load", load, resolved.rated_torque)
    ratio = _design_ratio(resolved, ratio)
    paths = [data] if isinstance(data, (str, Path)) else list(data)
    if not paths:
        raise InputError("data", [], "give one or more data files (bench CSV, data-set or "
                         "catalogue TOML)")
    error_set = None if errors is None else resolve_errors(resolved, errors)

    def read_record(path):
        return measure(path, ratio, columns=columns, units=units, counts_per_rev=counts_per_rev,
                       remove_orders=remove_orders, remove_input_orders=remove_input_orders,
                       keep_orders=keep_orders).measured

    sources = calib.design_sources(design) if isinstance(design, (str, Path)) else \
        calib.design_sources(resolved.name.split(" (")[0])
    # The values and bounds first: a wrong --fit name is reported before any file is read.
    calib.parameters(resolved, fit, bounds, sources)
    datasets = []
    for path in paths:
        path = Path(path)
        if not path.is_file():
            raise InputError("data", str(path), "must be an existing bench CSV, data-set TOML or "
                             "catalogue TOML")
        if path.suffix.lower() == ".toml":
            values = calib.read_toml("data", path)
            if calib.is_catalogue(values):
                datasets.append(calib.catalogue_dataset(path, values, load, error_set))
            else:
                datasets += calib.peaks_datasets(path, values, resolved, load, errors, read_record)
        else:
            datasets.append(calib.DataSet(path.name, float(load), error_set,
                                          measured=read_record(path)))
    prob = calib.problem(resolved, datasets, fit, target, bounds, sources, points)
    budget = {k: v for k, v in (("maxiter", maxiter), ("popsize", popsize), ("seed", seed))
              if v is not None}
    total = ((budget.get("maxiter", calib.DE_MAXITER) + 1) * budget.get("popsize", calib.DE_POPSIZE)
             * len(prob.parameters))
    result = calib.calibrate(prob, progress=None if progress is None else
                             (lambda done: progress(max(total, done), done)), **budget)
    if output is not None:
        output.write_text(calib.design_text(result, [str(p) for p in paths], sources,
                                            str(design) if isinstance(design, (str, Path)) else ""))
    return CalibrateReport(result, tuple(str(p) for p in paths),
                           None if output is None else str(output))


__all__ += ["compare", "CompareReport", "calibrate", "CalibrateReport"]
