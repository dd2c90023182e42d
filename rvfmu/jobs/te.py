"""`rvte te`: the TE curve of one reducer, its lost motion and rigidity."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.reducer.limits import check_load
from ..core.statics import metrics
from ..core.statics.quasistatic import TECurve, Windup, default_points, te_curve, windup
from ..outputs import figure_file, output_file
from ..progress import counter as progress_counter
from .common import resolve_design, resolve_errors, te_frame, write_te_csv

HARMONICS_SHOWN = 5


@dataclass(frozen=True)
class TEReport:
    """A TE curve of one reducer with its catalogue stiffness figures."""

    curve: TECurve
    windup: Windup
    lost_motion_arcmin: float
    torsional_rigidity_Nm_per_arcmin: float
    warnings: tuple[str, ...] = ()

    def summary(self) -> str:
        """The table `rvte te` prints, one figure a line: design, load, points, te_pp, RMS and
        mean [arcsec], the largest orders above the noise floor (up to HARMONICS_SHOWN), lost
        motion [arcmin], torsional rigidity [N*m/arcmin] and the warnings."""
        c = self.curve
        d = c.design
        orders, amplitudes = metrics.significant_orders(c.te_arcsec, HARMONICS_SHOWN)
        nyquist = c.points // 2
        pin_order = d.z_p * d.z_c
        lines = [
            f"design            {d.name} (ratio {d.ratio:g}, z_p {d.z_p}, z_c {d.z_c}, {d.n_c} cranks)",
            f"load              {-c.tau_load:g} N*m resisting"
            + ("  (no-load limit)" if c.tau_load == 0 else ""),
            f"points            {c.points} per output revolution "
            + (
                f"(resolves the pin-passing order {pin_order})"
                if nyquist > pin_order
                else f"(Nyquist order {nyquist} < pin-passing order {pin_order}: that ripple aliases)"
            ),
            f"te_pp             {c.te_pp_arcsec[0]:.3f} arcsec",
            f"rms               {c.rms_arcsec[0]:.3f} arcsec (about the mean)",
            f"mean              {c.mean_arcsec[0]:.3f} arcsec"
            + (
                "  (no load: the output's turn-back from its nominal place to the first contact,"
                " i.e. the free play that the profile modifications, errors and clearances leave)"
                if c.tau_load == 0
                else ""
            ),
            "largest orders    "
            + (
                ", ".join(f"{o}: {a:.3f}\u2033" for o, a in zip(orders[0], amplitudes[0]))
                if len(orders[0])
                else f"none above the noise floor of {metrics.noise_floor(c.te_arcsec)[0]:.3g}\u2033"
                " (the TE is flat)"
            ),
            f"lost motion       {self.lost_motion_arcmin:.3f} arcmin (windup span at +-3 % of "
            f"{d.rated_torque:g} N*m)",
            f"torsional rigidity {self.torsional_rigidity_Nm_per_arcmin:.1f} N*m/arcmin "
            f"(50-100 % rated torque)",
        ]
        if not np.all(c.converged):
            lines.append("warning           the equilibrium did not converge at some angles")
        lines += [f"warning           {text}" for text in self.warnings]
        return "\n".join(lines)

    def to_df(self):
        """The TE curve as a pandas DataFrame (points rows), the columns of its CSV:
        theta_in_rad, theta_out_rad, te_arcsec."""
        return te_frame(self.curve)


def te(
    design,
    errors=None,
    load: float = 0.0,
    points: int | None = None,
    csv_path: str | Path | None = None,
    plot_path: str | Path | None = None,
    progress=None,
) -> TEReport:
    """TE curve of one reducer at a resisting load [N*m] (0: no-load limit), with lost
    motion and torsional rigidity; writes the CSV and the plot if paths are given
    (both checked before any work).  A load beyond 5x the rated torque raises
    InputError; beyond 2.5x the report carries a warning (`rvfmu.core.reducer.limits`).

    progress(total, done): optional, called as the curve's angles are solved.
    """
    csv_path = None if csv_path is None else output_file("csv", csv_path)
    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    note = check_load("load", load, design.rated_torque)
    if points is None:
        points = default_points(design)
    curve = te_curve(
        design, errors, tau_load=-load, points=points, progress=progress_counter(points, progress)
    )
    wind = windup(design, errors)
    report = TEReport(
        curve,
        wind,
        float(wind.lost_motion_arcmin()[0]),
        float(wind.torsional_rigidity_Nm_per_arcmin()[0]),
        (note,) if note else (),
    )
    if csv_path is not None:
        write_te_csv(curve, csv_path)
    if plot_path is not None:
        from ..plots import plot_te

        plot_te(curve, plot_path)
    return report
