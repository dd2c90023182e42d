"""`rvte simulate`: the dynamic model in time (docs/model.md section 7)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.base.checks import InputError
from ..core.laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature
from ..core.statics import metrics
from ..outputs import figure_file, output_file
from .common import columns_frame, read_columns, resolve_design, resolve_errors, write_frame

# The columns of the simulation's CSV and `SimulationReport.to_df`, with their number formats.
FORMATS = {
    "time_s": ".9g",
    "theta_in_rad": ".12g",
    "theta_out_rad": ".12g",
    "te_arcsec": ".6f",
    "tau_in_Nm": ".6g",
}


@dataclass(frozen=True)
class SimulationReport:
    """A dynamic run with the figures an engineer reads first (after the start ramp): an
    excitation the record does not resolve shows why instead of an amplitude
    (`Simulation.excitation_rows`), and the inputs beyond their rated class a warning."""

    simulation: object
    peaks: tuple

    def summary(self) -> str:
        """The table `rvte simulate` prints: design, input and load, the interval after the
        start ramp and the step, the TE range and te_pp [arcsec], the largest peaks [Hz,
        arcsec], the TE amplitude at each excitation, the mean powers [W] and efficiency, and
        the warnings."""
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
            f"{sim.speed_rpm:g} rpm"
            + (" (the input reverses)" if sim.input_reverses else "")
            + f"; {load_text}",
            f"interval          {start:.4g} s to {stop:.4g} s "
            + ("(the whole sampled input)" if sampled else "at constant speed (after the start ramp)")
            + f", step {sim.step * 1e6:.4g} us, {sim.time.size} steps",
            f"TE range          {te.min():.3f} to {te.max():.3f} arcsec",
            f"te_pp             {te.max() - te.min():.3f} arcsec",
            "largest peaks     "
            + (
                ", ".join(f"{f:.1f} Hz: {a:.3f}\u2033" for f, a in self.peaks)
                or f"none above {metrics.NOISE_FLOOR_ARCSEC:g}\u2033"
            ),
            f"{'excitation':<24} {'frequency [Hz]':>14} {'TE amplitude [arcsec]':>22}",
        ]
        lines += [
            f"  {name:<22} {hz:>14.2f} " + (f"{amp:>22.4f}" if amp is not None else f"  not resolved: {why}")
            for name, hz, amp, why in sim.excitation_rows()
        ]
        power = sim.mean_powers()
        eta = power["efficiency"]
        lines.append(
            f"power (mean)      input {power['input_W']:.4g} W, output {power['output_W']:.4g} W, "
            f"friction {power['friction_W']:.4g} W, damping {power['damping_W']:.3g} W"
            + (f"; efficiency {100 * eta:.1f} %" if eta is not None else "")
        )
        if sim.failed_steps:
            lines.append(f"warning           {sim.failed_steps} steps did not converge")
        lines += [f"warning           {text}" for text in sim.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The run for scripts (`--json`): the figures of `summary` under their names with
        units (load_Nm one number, or [min, max] for a load that changes; an excitation not
        resolved has amplitude null and says why)."""
        sim = self.simulation
        te = sim.steady_te_arcsec()
        return {
            "design": sim.design.name,
            "speed_rpm": sim.speed_rpm,
            "drive": sim.drive,
            "load_Nm": [float(-sim.tau_load.max()), float(-sim.tau_load.min())]
            if np.ptp(sim.tau_load)
            else float(-sim.tau_load[0]),
            "interval_s": [float(sim.time[sim.steady]), float(sim.time[-1])],
            "step_s": sim.step,
            "te_range_arcsec": [float(te.min()), float(te.max())],
            "te_pp_arcsec": float(te.max() - te.min()),
            "peaks": [[f, a] for f, a in self.peaks],
            "failed_steps": sim.failed_steps,
            "input_reverses": sim.input_reverses,
            "excitations": [
                {"name": name, "frequency_hz": hz, "amplitude_arcsec": amp, "not_resolved": why}
                for name, hz, amp, why in sim.excitation_rows()
            ],
            "power_W": {k[:-2]: v for k, v in sim.mean_powers().items() if k.endswith("_W")},
            "efficiency": sim.mean_powers()["efficiency"],
            "warnings": list(sim.warnings),
        }

    def to_df(self):
        """The run in time as a pandas DataFrame (one row per step), the columns of its CSV:
        time_s, theta_in_rad, theta_out_rad, te_arcsec, tau_in_Nm (the start ramp included)."""
        sim = self.simulation
        return columns_frame(
            {
                "time_s": sim.time,
                "theta_in_rad": sim.theta_in,
                "theta_out_rad": sim.theta_out,
                "te_arcsec": sim.te_arcsec,
                "tau_in_Nm": sim.tau_in,
            }
        )


def simulate(
    design,
    errors=None,
    speed_rpm: float | None = 1600.0,
    load=0.0,
    duration: float | None = None,
    revolutions: float | None = None,
    contact: str | None = None,
    mesh: str = "varying",
    step: float | None = None,
    csv_path: str | Path | None = None,
    plot_path: str | Path | None = None,
    progress=None,
    load_step: tuple[float, float] | None = None,
    load_csv: str | Path | None = None,
    input_csv: str | Path | None = None,
    friction: bool = True,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
) -> SimulationReport:
    """Dynamic TE of one reducer (docs/model.md section 7) at a constant input speed after a
    start ramp, or along sampled input angles; writes the CSV (time_s, theta_in_rad,
    theta_out_rad, te_arcsec, tau_in_Nm) and the plot if asked.

    load [N*m resisting]: constant; load_step (time [s], load [N*m]): the load
    changes to that value at that time of the run; load_csv: a file of columns
    time_s, load_Nm (linear between rows, held beyond).  input_csv: a file of
    columns time_s, theta_in_rad, used instead of speed_rpm and the ramp.  friction: False
    leaves out the contacts' friction and drag (docs/model.md section 9); temperature_C: the
    lubricant's [C], -40 to 150 (default 40), the viscosity of the drag and the churning
    (checked before any work).  Speeds, loads,
    a load step outside the run and runs too long to compute are refused as
    `rvfmu.core.dynamics.simulation.simulate` says.
    """
    from ..core.dynamics.simulation import Sampled
    from ..core.dynamics.simulation import simulate as run

    temperature_C = check_temperature(temperature_C)
    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    given = [name for name, value in (("load_step", load_step), ("load_csv", load_csv)) if value is not None]
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
    sim = run(
        design,
        resolve_errors(design, errors),
        speed_rpm=speed_rpm,
        load=load,
        duration=duration,
        revolutions=revolutions,
        contact=contact,
        mesh=mesh,
        step=step,
        progress=progress,
        input_angle=input_angle,
        friction=friction,
        temperature_C=temperature_C,
    )
    report = SimulationReport(sim, tuple(sim.peaks_hz()))
    if csv_path is not None:
        write_frame(csv_path, report.to_df(), FORMATS)
    if plot_path is not None:
        from ..plots import plot_simulation

        plot_simulation(sim, plot_path)
    return report
