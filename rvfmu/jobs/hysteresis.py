"""`rvte hysteresis`: the catalogue's hysteresis loop of a reducer, with its contacts' friction.

The job over `rvfmu.core.hysteresis`: the windup test swept to +-max load and back with the
input locked, the lost motion, torsional rigidity and hysteresis loss read off the loop,
the friction work of a cycle by contact; a table for people, JSON for scripts and the
loop as a figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..core.friction import LOSS_NAMES
from ..core.hysteresis import HysteresisLoop, hysteresis as hysteresis_loop, sweep_torques
from ..core.quasistatic import WINDUP_POSITIONS
from ..core.units import ARCMIN
from ..outputs import figure_file
from ..progress import counter as progress_counter


@dataclass(frozen=True)
class HysteresisReport:
    """The hysteresis loop of one reducer (`core.hysteresis.HysteresisLoop`)."""

    loop: HysteresisLoop

    def summary(self) -> str:
        h, d = self.loop, self.loop.design
        top = h.tau_load[-1]
        total = sum(h.friction_work_J.values())
        lines = [
            f"design             {d.name} (ratio {d.ratio:g}, rated torque {d.rated_torque:g} N*m)",
            f"loop               input locked, output swept to +-{top:g} N*m and back "
            f"({h.tau_load.size} torques, mean over the locked positions)",
            f"lost motion        {_figure(h.lost_motion_arcmin, '.3f', 'arcmin')} "
            "(the loop's middle at +-3 % rated)",
            f"torsional rigidity {_figure(h.torsional_rigidity_Nm_per_arcmin, '.1f', 'N*m/arcmin')} "
            "(the loop's middle, 50-100 % rated)",
            f"hysteresis loss    {h.hysteresis_loss_arcmin:.3f} arcmin (the loop's width at zero torque)",
            f"friction torque    {h.friction_torque.max():.3g} N*m at most at the output "
            f"(the loop's half-width in torque)",
            f"friction work      {total:.4g} J a cycle (the loop's area {h.area_J:.4g} J):",
        ]
        for name in LOSS_NAMES:
            share = h.friction_work_J[name] / total if total > 0 else 0.0
            lines.append(f"  {name:<30} {h.friction_work_J[name]:>10.4g} J  {100 * share:>5.1f} %")
        # a loop that did not converge is refused (`core.hysteresis.check_loop`): no line here
        lines += [f"warning            {text}" for text in h.warnings]
        return "\n".join(lines)

    def to_json(self) -> dict:
        h = self.loop
        return {
            "design": h.design.name,
            "lost_motion_arcmin": _number(h.lost_motion_arcmin),
            "torsional_rigidity_Nm_per_arcmin": _number(h.torsional_rigidity_Nm_per_arcmin),
            "hysteresis_loss_arcmin": h.hysteresis_loss_arcmin,
            "friction_work_J": h.friction_work_J,
            "loop": [{"torque_Nm": float(t), "angle_arcmin": float(a / ARCMIN)} for t, a in h.loop],
            "converged": h.converged,
            "warnings": list(h.warnings),
        }


def _figure(value: float, spec: str, unit: str) -> str:
    """A catalogue figure, or why there is none: the sweep stops short of its torques."""
    return "not reached by the sweep" if math.isnan(value) else f"{value:{spec}} {unit}"


def _number(value: float) -> float | None:
    return None if math.isnan(value) else value


def hysteresis(design, errors=None, max_load: float | None = None,
               plot_path: str | Path | None = None, progress=None) -> HysteresisReport:
    """The windup test's hysteresis loop of one reducer.

    design: preset name, design file or RVDesign; errors: error file or ErrorSet (default
    none); max_load [N*m]: the sweep's end (default the rated torque; at least 3 % of it,
    the catalogue's lost-motion test torque); plot_path: the loop as a figure (checked before
    any work); progress(total, done): optional, called as the equilibria are solved.  A loop
    that did not converge, or whose friction torque exceeds the sweep or whose area is not
    its friction work, raises InputError (`rvfmu.core.hysteresis.check_loop`).
    """
    from .common import resolve_design, resolve_errors

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    top = design.rated_torque if max_load is None else max_load
    total = (sweep_torques(design, top).size * WINDUP_POSITIONS
             if isinstance(top, (int, float)) and math.isfinite(top) and top > 0 else 0)
    report = HysteresisReport(hysteresis_loop(design, errors, max_load,
                                              progress=progress_counter(total, progress)))
    if plot_path is not None:
        from ..plots import plot_hysteresis

        plot_hysteresis(report, plot_path)
    return report
