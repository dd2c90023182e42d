"""`rvte modes`: natural frequencies and damping beside the excitations."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.reducer.design import RVDesign
from ..outputs import figure_file
from .common import resolve_design, resolve_errors


@dataclass(frozen=True)
class ModesReport:
    """Natural frequencies at the loaded equilibrium beside the excitations at a speed."""

    modes: object
    design: RVDesign
    speed_rpm: float
    count: int

    def excitations(self):
        """The excitation frequencies [Hz] at `speed_rpm` (`rvfmu.core.dynamics.excitations.Excitations`):
        input, output, crank rotation, pin passing and stage-1 mesh."""
        from ..core.dynamics.excitations import Excitations

        return Excitations.at(self.design, self.speed_rpm)

    def summary(self) -> str:
        """The table `rvte modes` prints: the first `count` modes with frequency [Hz], damping
        ratio [%] and the parts that carry their kinetic energy, the excitations [Hz] at the
        speed and those within 10 % of a natural frequency."""
        m, ex = self.modes, self.excitations()
        lines = [
            f"design            {self.design.name}: natural frequencies of the dynamic model "
            f"linearised at its equilibrium under {-m.tau_load:g} N*m resisting",
            f"{'mode':>4} {'frequency [Hz]':>15} {'damping':>8}  dominant parts (share of kinetic energy)",
        ]
        for k, hz, parts in m.table(self.count, parts=3):
            lines.append(
                f"{k + 1:>4} {hz:>15.1f} {100 * m.damping_ratios[k]:>7.2f}%  "
                + ", ".join(f"{label} {100 * share:.0f} %" for label, share in parts if share >= 0.005)
            )
        lines.append(
            f"excitations at {self.speed_rpm:g} rpm: "
            + ", ".join(f"{name} {hz:.1f} Hz" for name, hz in ex.items())
        )
        near = [
            (name, hz, float(m.frequencies_hz[np.argmin(np.abs(m.frequencies_hz - hz))]))
            for name, hz in ex.items()
        ]
        close = [(n, hz, f) for n, hz, f in near if abs(f - hz) <= 0.1 * f]
        lines.append(
            "resonance         "
            + (
                "; ".join(f"{n} {hz:.1f} Hz is within 10 % of the mode at {f:.1f} Hz" for n, hz, f in close)
                or "no excitation within 10 % of a natural frequency"
            )
        )
        if m.dropped:
            lines.append(
                f"note              {m.dropped} floating modes (parts inside a bearing clearance) left out"
            )
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The modes for scripts (`--json`): design, load_Nm, per mode hz, damping_ratio and
        parts ([part, share of kinetic energy]), speed_rpm and excitations_hz {name: Hz}."""
        m = self.modes
        return {
            "design": self.design.name,
            "load_Nm": float(-m.tau_load),
            "modes": [
                {
                    "hz": hz,
                    "damping_ratio": float(m.damping_ratios[k]),
                    "parts": [[label, share] for label, share in parts],
                }
                for k, hz, parts in m.table(self.count, parts=3)
            ],
            "speed_rpm": self.speed_rpm,
            "excitations_hz": {name: hz for name, hz in self.excitations().items()},
        }


def modes(
    design,
    errors=None,
    load: float = 0.0,
    speed_rpm: float = 1600.0,
    count: int = 12,
    plot_path: str | Path | None = None,
) -> ModesReport:
    """Natural frequencies and mode shapes of the dynamic model at its equilibrium under a
    resisting `load` [N*m], beside the excitations at `speed_rpm`; `plot_path`: a Campbell
    diagram from 0 to 1.25 x that speed."""
    from ..core.base.checks import integer, positive
    from ..core.dynamics.modes import campbell
    from ..core.dynamics.modes import modes as linearised

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    speed_rpm = positive("speed_rpm", speed_rpm)
    count = integer("count", count, 1)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    result = linearised(design, errors, load=load)
    if plot_path is not None:
        from ..plots import plot_campbell

        speeds, lines = campbell(design, errors, load, np.linspace(0.0, 1.25 * speed_rpm, 200))
        plot_campbell(design, result.frequencies_hz[:count], speeds, lines, speed_rpm, plot_path)
    return ModesReport(result, design, speed_rpm, count)
