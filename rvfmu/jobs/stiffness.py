"""`rvte stiffness`: the torsional rigidity and lost motion of a reducer with its compliance budget.

The job over `rvfmu.core.statics.budget`: the catalogue figures from the windup test
(`quasistatic.windup`) beside those its frame's catalogue prints (for a preset,
`bench.catalogue`), every elastic element of the model with its stiffness,
count and share of the windup between 50 % and 100 % of the rated torque (or of
`load`), a table for people, JSON for scripts and a figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.base.checks import InputError
from ..core.statics.budget import WEAK_SHARE_VISIBLE, ComplianceBudget, compliance_budget
from ..core.statics.quasistatic import Windup, windup
from ..outputs import figure_file

if TYPE_CHECKING:
    from ..bench.catalogue import Frame


@dataclass(frozen=True)
class StiffnessReport:
    """Catalogue rigidity and lost motion of one reducer, and its compliance budget; catalogue:
    the figures its frame's catalogue prints (a preset's frame, `bench.catalogue`), None for
    a design that is no preset."""

    budget: ComplianceBudget
    windup: Windup
    torsional_rigidity_Nm_per_arcmin: float
    lost_motion_arcmin: float
    catalogue: Frame | None = None

    def summary(self) -> str:
        """The table `rvte stiffness` prints: torsional rigidity [N*m/arcmin], lost motion
        [arcmin] and the compliance budget, each elastic element with its count, stiffness
        and share of the windup, largest first, and the warnings."""
        b, d, c = self.budget, self.budget.design, self.catalogue
        rigidity = "" if c is None else f", catalogue {c.torsional_rigidity_Nm_per_arcmin:g}"
        lost = "" if c is None else f", catalogue at most {c.lost_motion_max_arcmin:g}"
        lines = [
            f"design             {d.name} (ratio {d.ratio:g}, rated torque {d.rated_torque:g} N*m)",
            f"torsional rigidity {self.torsional_rigidity_Nm_per_arcmin:.1f} N*m/arcmin "
            f"(50-100 % rated torque, both senses, input locked{rigidity})",
            f"lost motion        {self.lost_motion_arcmin:.3f} arcmin (windup span at +-3 % rated{lost})",
            "catalogue          "
            + (
                "none: the design is no preset, so it has no catalogue frame"
                if c is None
                else f"{c.name} frame, {c.source}"
            ),
            f"compliance budget  shares of the windup between {b.torque_low:g} and "
            f"{b.torque_high:g} N*m (element strain energy / output work; "
            f"{b.torsional_rigidity_Nm_per_arcmin:.1f} N*m/arcmin there)",
            f"  {'element':<36} {'count':>5} {'stiffness each':>16}  {'share':>6}",
        ]
        for e in sorted(b.elements, key=lambda e: -e.share):
            k = "rigid" if math.isinf(e.stiffness) else f"{e.stiffness:.4g} {e.unit}"
            lines.append(f"  {e.name:<36} {e.count:>5} {k:>16}  {100 * e.share:>5.1f} %")
        lines.append(f"  {'sum':<36} {'':>5} {'':>16}  {100 * b.share_sum:>5.1f} %")
        if not b.converged or not self.windup.converged.all():
            lines.append("warning            the equilibrium did not converge at some positions")
        weak = b.elements[-1].share
        if abs(weak) > WEAK_SHARE_VISIBLE:
            lines.append(
                f"warning            the solver's weak springs carry {100 * weak:.1f} % of "
                "the windup: these figures are the solver's, not the reducer's"
            )
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The figures for scripts (`--json`): torsional rigidity, lost motion, the budget's
        torques [N*m] and its elements (name, count, stiffness in its unit or null if rigid,
        unit, share), in the model's order, and whether every equilibrium converged."""
        b = self.budget
        return {
            "design": b.design.name,
            "torsional_rigidity_Nm_per_arcmin": self.torsional_rigidity_Nm_per_arcmin,
            "lost_motion_arcmin": self.lost_motion_arcmin,
            "catalogue": None
            if self.catalogue is None
            else {
                "frame": self.catalogue.name,
                "torsional_rigidity_Nm_per_arcmin": self.catalogue.torsional_rigidity_Nm_per_arcmin,
                "lost_motion_max_arcmin": self.catalogue.lost_motion_max_arcmin,
                "source": self.catalogue.source,
            },
            "budget_torque_Nm": [b.torque_low, b.torque_high],
            "elements": [
                {
                    "name": e.name,
                    "count": e.count,
                    "stiffness": None if math.isinf(e.stiffness) else e.stiffness,
                    "unit": e.unit,
                    "share": e.share,
                }
                for e in b.elements
            ],
            "converged": bool(b.converged and self.windup.converged.all()),
        }


def stiffness(
    design, errors=None, load: float | None = None, plot_path: str | Path | None = None
) -> StiffnessReport:
    """Torsional rigidity, lost motion and the compliance budget of one reducer.

    design: preset name, design file or RVDesign; errors: error file or ErrorSet (default
    none); load [N*m]: the budget spans 50 % to 100 % of it (default the rated torque,
    the catalogue's range); plot_path: a figure of the shares and the windup curve
    (checked before any work).
    """
    from .common import resolve_design, resolve_errors

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    budget = compliance_budget(design, errors, torque=load)
    wind = windup(design, errors)
    report = StiffnessReport(
        budget,
        wind,
        float(wind.torsional_rigidity_Nm_per_arcmin()[0]),
        float(wind.lost_motion_arcmin()[0]),
        _catalogue_frame(design.name),
    )
    if plot_path is not None:
        from ..plots import plot_budget

        plot_budget(report, plot_path)
    return report


def _catalogue_frame(name: str) -> Frame | None:
    """The catalogue figures of preset `name`'s frame (estimate or calibrated), None for a
    design of another name: a design file's reducer is compared with no catalogue."""
    from ..bench.catalogue import frame_of  # the calibration's modules: loaded when asked

    try:
        return frame_of(name)
    except InputError:
        return None
