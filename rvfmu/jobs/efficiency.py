"""`rvte efficiency`: the catalogue's efficiency chart of a reducer, and where its power goes.

The job over `rvfmu.core.losses.friction`: forward and backdriving efficiency at every output
speed and resisting torque, the motor's torque, the no-load running torque against speed,
the starting torque at the input and the backdriving torque at the output; a table for
people, JSON for scripts and a figure like the catalogue's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..core.laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature
from ..core.losses.friction import (
    AVERAGE_POINTS,
    DEFAULT_LOAD_FRACTIONS,
    LOSS_NAMES,
    EfficiencyMap,
    efficiency_map,
)
from ..outputs import figure_file
from ..progress import counter as progress_counter

# The figure's charts: the catalogue's efficiency against output torque (light loads included,
# where the load-free losses weigh most) and its low-temperature characteristic (-10 to 40 C).
CHART_LOAD_FRACTIONS = (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
CHART_TEMPERATURES_C = (-10.0, 0.0, 10.0, 20.0, 30.0, 40.0)


@dataclass(frozen=True)
class Characteristics:
    """What the figure shows beyond the map, each a `friction.EfficiencyMap` of the same
    reducer and speeds: `by_torque` at CHART_LOAD_FRACTIONS x rated torque, the lubricant at
    the report's temperature; `by_temperature` {temperature [C]: map} at CHART_TEMPERATURES_C,
    at the map's loads."""

    by_torque: EfficiencyMap
    by_temperature: dict

    def to_json(self) -> dict:
        """The charts' values: forward efficiency over speed x torque, and per temperature
        the efficiency at the map's loads and the no-load running torque at the input."""
        m = self.by_torque
        return {
            "efficiency_by_torque": {
                "output_speed_rpm": m.output_speed_rpm.tolist(),
                "load_Nm": m.load_Nm.tolist(),
                "efficiency": m.efficiency.tolist(),
            },
            "by_temperature": [
                {
                    "temperature_C": t,
                    "load_Nm": c.load_Nm.tolist(),
                    "output_speed_rpm": c.output_speed_rpm.tolist(),
                    "efficiency": c.efficiency.tolist(),
                    "no_load_running_torque_Nm": c.no_load_running_torque_Nm.tolist(),
                }
                for t, c in self.by_temperature.items()
            ],
        }


@dataclass(frozen=True)
class EfficiencyReport:
    """The efficiency map of one reducer (`friction.EfficiencyMap`), and the charts of its
    figure (`Characteristics`, None unless a figure was asked for)."""

    map: EfficiencyMap
    characteristics: Characteristics | None = None

    def summary(self) -> str:
        """The table `rvte efficiency` prints: design and lubricant, forward / backdriving
        efficiency [%] at each output speed (rows) and resisting torque (columns), where the
        power goes [W] at the map's first speed and last torque, the no-load running torque,
        starting and backdriving torque [N*m], and the warnings."""
        m, d = self.map, self.map.design
        lines = [
            f"design             {d.name} (ratio {d.ratio:g}, rated torque {d.rated_torque:g} N*m)",
            f"lubricant          {m.temperature_C:g} C, "
            f"{m.lubricant_viscosity_cSt:.4g} mm^2/s "
            + (
                f"(ISO VG {d.lubricant_iso_vg}, VI {d.lubricant_viscosity_index:g})"
                if d.lubricant_viscosity == 0.0
                else "(stated, at every temperature)"
            ),
            "efficiency         forward / backdriving [%] at output speed (rows, rpm) and "
            "resisting torque (columns, N*m)",
            "  rpm   " + "".join(f"{t:>16.4g}" for t in m.load_Nm),
        ]
        for v, speed in enumerate(m.output_speed_rpm):
            cells = "".join(
                f"{100 * m.efficiency[v, t]:>9.1f} / {100 * m.backdriving_efficiency[v, t]:>4.1f}"
                for t in range(m.load_Nm.size)
            )
            lines.append(f"  {speed:<6.4g}" + cells)
        v, t = 0, m.load_Nm.size - 1
        lines.append(
            f"where the power goes at {m.output_speed_rpm[v]:g} rpm and {m.load_Nm[t]:g} N*m "
            f"({m.loss_W[v, t]:.3g} W lost):"
        )
        for name in LOSS_NAMES:
            share = m.losses[name][v, t] / m.loss_W[v, t] if m.loss_W[v, t] > 0 else 0.0
            lines.append(f"  {name:<30} {m.losses[name][v, t]:>9.3g} W  {100 * share:>5.1f} %")
        lines.append(
            "no-load running torque at the input [N*m]: "
            + ", ".join(
                f"{r:.3g} at {s:g} rpm" for s, r in zip(m.output_speed_rpm, m.no_load_running_torque_Nm)
            )
        )
        lines.append(
            f"starting torque    {m.starting_torque_input_Nm:.4g} N*m at the input; "
            f"backdriving torque {m.backdriving_torque_output_Nm:.4g} N*m at the output"
        )
        if not m.converged:
            lines.append("warning            the equilibrium did not converge at some angles")
        lines += [f"warning            {text}" for text in m.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The map for scripts (`--json`): per (output speed, load) point the efficiency,
        backdriving efficiency, input torque [N*m] and losses [W] by loss; the no-load running
        torque per speed, the starting and backdriving torque, lubricant, convergence and the
        warnings."""
        m = self.map
        return {
            "design": m.design.name,
            "temperature_C": m.temperature_C,
            "lubricant_viscosity_cSt": m.lubricant_viscosity_cSt,
            "map": [
                {
                    "output_speed_rpm": float(s),
                    "load_Nm": float(t),
                    "efficiency": float(m.efficiency[v, j]),
                    "backdriving_efficiency": float(m.backdriving_efficiency[v, j]),
                    "input_torque_Nm": float(m.input_torque_Nm[v, j]),
                    "losses_W": {name: float(m.losses[name][v, j]) for name in LOSS_NAMES},
                }
                for v, s in enumerate(m.output_speed_rpm)
                for j, t in enumerate(m.load_Nm)
            ],
            "no_load_running_torque": [
                {"output_speed_rpm": float(s), "input_torque_Nm": float(r)}
                for s, r in zip(m.output_speed_rpm, m.no_load_running_torque_Nm)
            ],
            "starting_torque_input_Nm": m.starting_torque_input_Nm,
            "backdriving_torque_output_Nm": m.backdriving_torque_output_Nm,
            "converged": m.converged,
            "warnings": list(m.warnings),
            **(
                {"characteristics": self.characteristics.to_json()}
                if self.characteristics is not None
                else {}
            ),
        }


def efficiency(
    design,
    errors=None,
    speeds=None,
    loads=None,
    plot_path: str | Path | None = None,
    progress=None,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
) -> EfficiencyReport:
    """Efficiency map, running, starting and backdriving torque of one reducer.

    design: preset name, design file or RVDesign; errors: error file or ErrorSet (default
    none); speeds: output speeds [rpm] (default 5 to 60; beyond 2 x the design's allowable
    output speed refused, above 1 x warned, `rvfmu.core.reducer.limits.check_speed`); loads:
    resisting output torques [N*m] (default 25 % to 100 % of rated); plot_path: the
    catalogue's chart (checked before any work); progress(total, done): optional, called as
    the equilibria are solved; temperature_C: the lubricant's [C], -40 to 150 (default 40,
    its ISO VG grade's temperature; a design that states lubricant_viscosity_cSt keeps that
    viscosity at every temperature).
    """
    from .common import resolve_design, resolve_errors

    temperature_C = check_temperature(temperature_C)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    count = len(DEFAULT_LOAD_FRACTIONS) if loads is None else len(loads)
    report = EfficiencyReport(
        efficiency_map(
            design,
            errors,
            speeds,
            loads,
            progress=progress_counter((1 + 2 * count) * AVERAGE_POINTS, progress),
            temperature_C=temperature_C,
        )
    )
    if plot_path is not None:
        from ..plots import plot_efficiency

        report = replace(report, characteristics=characteristics(design, errors, report.map))
        plot_efficiency(report, plot_path)
    return report


def characteristics(design, errors, m: EfficiencyMap) -> Characteristics:
    """The charts of `m`'s reducer at `m`'s speeds (`Characteristics`): the efficiency over
    CHART_LOAD_FRACTIONS of rated torque at `m`'s temperature, and the map over
    CHART_TEMPERATURES_C at `m`'s loads."""
    loads = design.rated_torque * np.array(CHART_LOAD_FRACTIONS)
    by_torque = efficiency_map(design, errors, m.output_speed_rpm, loads, temperature_C=m.temperature_C)
    by_temperature = {
        t: efficiency_map(design, errors, m.output_speed_rpm, m.load_Nm, temperature_C=t)
        for t in CHART_TEMPERATURES_C
    }
    return Characteristics(by_torque, by_temperature)
