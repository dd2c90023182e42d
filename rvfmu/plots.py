"""Figures for people: the TE curve with its order spectrum, windup curves.

Plotting knows the result records and matplotlib, nothing of the physics.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .core.base.units import ARCMIN, rad_to_arcsec
from .core.statics import metrics
from .core.statics.quasistatic import TECurve, Windup


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _saved(plt, fig, path: str | Path, dpi: int) -> Path:
    """Write `fig` to `path` and free it."""
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


SPECTRUM_MARGIN = 1.4  # the order axis ends this factor beyond the last order or marker shown


def marker_orders(curve: TECurve) -> list[tuple[int, str]]:
    """The orders an engineer looks for, with their labels, as they show in the spectrum.

    The crank order z_p (once per crank turn: z_p crank turns per output turn)
    and the pin-passing order z_p*z_c; an order above the Nyquist order
    (points/2) shows aliased at |k - points * round(k / points)|, and is labelled so.
    """
    design = curve.design
    nyquist = curve.points // 2
    out = []
    for order, label in (
        (design.z_p, "crank order (z_p)"),
        (design.z_p * design.z_c, "pin-passing order (z_p·z_c)"),
    ):
        if order <= nyquist:
            out.append((order, f"{label} = {order}"))
        else:
            alias = abs(order - curve.points * round(order / curve.points))
            if alias > 0:
                out.append((alias, f"{label} = {order}, aliased to {alias}"))
    return out


ZOOM_PERIODS = 4  # pin-passing periods the zoom panel shows
ZOOM_MIN_POINTS = 4  # points per pin-passing period below which the ripple is not drawn
RIPPLE_SHARE = 0.25  # the ripple dominates when its peak to peak is this share of te_pp


def ripple(curve: TECurve, sample: int = 0) -> tuple[float, bool]:
    """(peak to peak [arcsec] of the TE's orders from half the pin-passing order up, whether
    the curve resolves them: at least ZOOM_MIN_POINTS points per pin-passing period)."""
    order = curve.design.z_p * curve.design.z_c
    te = curve.te_arcsec[sample]
    spectrum = np.fft.rfft(te)
    spectrum[: order // 2] = 0.0
    return float(np.ptp(np.fft.irfft(spectrum, te.size))), curve.points >= ZOOM_MIN_POINTS * order


def figure_te(curve: TECurve, sample: int = 0, title: str | None = None, zoom: bool | None = None):
    """TE against output angle (top) and its order spectrum (bottom): a matplotlib Figure.

    zoom: a middle panel over ZOOM_PERIODS pin-passing periods, where the ripple's shape
    can be read (over a whole revolution it is drawn as a solid band); None: where the
    curve resolves the ripple and it dominates the curve (`ripple`: RIPPLE_SHARE of te_pp
    or more), True: wherever it is resolved.

    The spectrum shows only the orders above the noise floor
    (`metrics.significant_spectrum`): below it the amplitudes are round-off,
    invisible on the linear amplitude axis anyway, and a line there would claim
    an order that is not there.  The order axis ends a little beyond the highest
    significant order or the crank and pin-passing markers, whichever is higher,
    not at the Nyquist order; a TE with no order above the floor is said to be flat.
    """
    from matplotlib.figure import Figure

    design = curve.design
    te = curve.te_arcsec[sample]
    out_deg = np.degrees(curve.theta_in / design.ratio)
    orders, amplitude, significant = metrics.significant_spectrum(te)
    amplitude, significant = amplitude[0], significant[0]
    floor = float(metrics.noise_floor(te)[0])
    share, resolved = ripple(curve, sample)
    zoom = resolved and (share >= RIPPLE_SHARE * np.ptp(te) if zoom is None else bool(zoom))
    fig = Figure(figsize=(9, 10 if zoom else 7), layout="constrained")
    if zoom:
        ax_te, ax_zoom, ax_sp = fig.subplots(3, 1, height_ratios=(1.0, 0.8, 1.0))
    else:
        ax_te, ax_sp = fig.subplots(2, 1)
    ax_te.plot(out_deg, te, lw=0.8, color="C0")
    ax_te.axhline(te.mean(), color="0.5", lw=0.6, ls="--", label=f"mean {te.mean():.2f}″")
    ax_te.set_xlabel("output angle θ_out [deg]")
    ax_te.set_ylabel("transmission error [arcsec]")
    ax_te.set_xlim(0, 360)
    if np.ptp(te) <= 2 * floor:
        # Flat: round-off alone would be blown up to fill the axis, with an offset.
        ax_te.set_ylim(te.mean() - 0.5, te.mean() + 0.5)
    ax_te.ticklabel_format(axis="y", useOffset=False)
    load = -curve.tau_load
    ax_te.set_title(
        title
        or (f"{design.name}: TE at load {load:g} N·m (te_pp {np.ptp(te):.2f}″, {curve.points} points/rev)")
    )
    ax_te.legend(loc="upper right", fontsize=8)
    ax_te.grid(alpha=0.3)
    if zoom:
        period = 360.0 / (design.z_p * design.z_c)
        start = float(out_deg[np.argmax(te)]) - 0.5 * ZOOM_PERIODS * period
        start = min(max(start, 0.0), 360.0 - ZOOM_PERIODS * period)
        inside = (out_deg >= start) & (out_deg <= start + ZOOM_PERIODS * period)
        ax_te.axvspan(start, start + ZOOM_PERIODS * period, color="C3", alpha=0.35, lw=0)
        ax_te.annotate(
            "zoom",
            (start + 0.5 * ZOOM_PERIODS * period, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(0, 2),
            textcoords="offset points",
            ha="center",
            va="bottom",
            fontsize=7,
            color="C3",
        )
        ax_zoom.plot(out_deg[inside], te[inside], ".-", lw=0.8, ms=3, color="C0")
        ax_zoom.set_xlim(start, start + ZOOM_PERIODS * period)
        ax_zoom.set_xlabel("output angle θ_out [deg]")
        ax_zoom.set_ylabel("transmission error [arcsec]")
        ax_zoom.ticklabel_format(axis="both", useOffset=False)
        ax_zoom.set_title(
            f"zoom (shaded above): {ZOOM_PERIODS} pin-passing periods of "
            f"{period * 3600:.1f}″ at the TE's peak, ripple {share:.3f}″ peak to "
            "peak",
            fontsize=8,
        )
        ax_zoom.grid(alpha=0.3)

    shown = orders[significant]
    ax_sp.vlines(shown, 0, amplitude[significant], color="C1", lw=1.0, zorder=3)
    ax_sp.set_xscale("log")
    ax_sp.set_xlabel("order [cycles per output revolution]")
    ax_sp.set_ylabel("amplitude [arcsec]")
    marks = marker_orders(curve)
    last = max([int(shown.max()) if shown.size else 1] + [order for order, _ in marks])
    ax_sp.set_xlim(0.8, SPECTRUM_MARGIN * last)
    top = 1.1 * float(amplitude[significant].max()) if shown.size else 1.0
    ax_sp.set_ylim(0, top)
    for order, label in marks:
        ax_sp.axvline(order, color="0.6", lw=0.6, ls=":")
        ax_sp.annotate(
            label,
            (order, 0.97 * top),
            xytext=(-3, 0),
            textcoords="offset points",
            fontsize=7,
            rotation=90,
            ha="right",
            va="top",
            color="0.3",
            zorder=1,
            bbox=dict(fc="white", ec="none", alpha=0.7, pad=0.5),
        )
    if shown.size:
        ax_sp.set_title(
            f"orders above the noise floor of {floor:.3g}″ ({shown.size} of {orders.size - 1})", fontsize=8
        )
    else:
        ax_sp.text(
            0.5,
            0.5,
            f"flat TE: no order above the noise floor of {floor:.3g}″",
            transform=ax_sp.transAxes,
            ha="center",
            va="center",
            fontsize=10,
            color="0.3",
        )
    ax_sp.grid(alpha=0.3, which="both")
    return fig


def plot_te(curve: TECurve, path: str | Path, sample: int = 0, title: str | None = None) -> Path:
    """TE against output angle (top) and its order spectrum (bottom), written to `path`."""
    path = Path(path)
    figure_te(curve, sample, title).savefig(path, dpi=130)
    return path


def plot_windup(windup: Windup, path: str | Path, sample: int = 0) -> Path:
    """Output windup [arcmin] against output torque [N*m] at each locked input position."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    for p in range(windup.theta_in.size):
        ax.plot(windup.tau_load, windup.windup[sample, :, p] / ARCMIN, "o-", ms=3, lw=0.7, alpha=0.7)
    ax.set_xlabel("output torque τ_load [N·m]")
    ax.set_ylabel("output windup [arcmin]")
    ax.set_title(f"{windup.design.name}: windup, input locked ({windup.theta_in.size} positions)")
    ax.grid(alpha=0.3)
    return _saved(plt, fig, path, dpi=130)


def plot_catalogue(rows, path: str | Path) -> Path:
    """One panel per preset: output windup [arcmin] against output torque [N*m] (input
    locked, mean over the positions) before and after calibration, and the catalogue's
    torsional rigidity as a line through the calibrated curve at half the rated torque.
    rows: `rvfmu.bench.catalogue.PresetAgainstCatalogue` records with their windups."""
    plt = _pyplot()
    columns = 2
    lines = (len(rows) + columns - 1) // columns
    fig, axes = plt.subplots(lines, columns, figsize=(10, 4 * lines), constrained_layout=True, squeeze=False)
    for ax, row in zip(axes.ravel(), rows):
        for w, label, style in (
            (
                row.windups[0],
                f"estimate ({row.estimate.torsional_rigidity_Nm_per_arcmin:.0f} N·m/arcmin)",
                "o--",
            ),
            (
                row.windups[1],
                f"preset ({row.calibrated.torsional_rigidity_Nm_per_arcmin:.0f} N·m/arcmin)",
                "o-",
            ),
        ):
            ax.plot(w.tau_load, w.windup[0].mean(axis=-1) / ARCMIN, style, ms=3, lw=1.0, label=label)
        w = row.windups[1]
        rated = w.design.rated_torque
        half = int(np.argmin(np.abs(w.tau_load - 0.5 * rated)))
        anchor = w.windup[0, half].mean() / ARCMIN
        torque = np.array([0.5, 1.0]) * rated
        k = row.frame.torsional_rigidity_Nm_per_arcmin
        ax.plot(
            torque,
            anchor + (torque - 0.5 * rated) / k,
            "k:",
            lw=2,
            label=f"catalogue {row.frame.name} ({k:g} N·m/arcmin)",
        )
        ax.plot(-torque, -anchor - (torque - 0.5 * rated) / k, "k:", lw=2)
        ax.set_title(
            f"{row.name}: lost motion {row.estimate.lost_motion_arcmin:.2f} → "
            f"{row.calibrated.lost_motion_arcmin:.2f} arcmin (≤ {row.frame.lost_motion_max_arcmin:g})"
        )
        ax.set_xlabel("output torque τ_load [N·m]")
        ax.set_ylabel("output windup [arcmin]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    for ax in axes.ravel()[len(rows) :]:
        ax.set_visible(False)
    return _saved(plt, fig, path, dpi=110)


def plot_budget(report, path: str | Path) -> Path:
    """The compliance budget (`rvfmu.jobs.stiffness.StiffnessReport`): each element's share of the
    windup as bars (left) and the windup curve, input locked, at each position and their
    mean, with the torsional rigidity's slope between 50 % and 100 % rated (right)."""
    plt = _pyplot()
    budget, wind = report.budget, report.windup
    fig, (bars, curve) = plt.subplots(
        1, 2, figsize=(12, 4.8), constrained_layout=True, gridspec_kw={"width_ratios": [1, 1.2]}
    )
    elements = sorted(budget.elements, key=lambda e: e.share)
    shares = [100 * e.share for e in elements]
    bars.barh([f"{e.name} (×{e.count})" for e in elements], shares, color="tab:blue")
    for y, share in enumerate(shares):
        bars.text(share, y, f" {share:.1f} %", va="center", fontsize=8)
    bars.set_xlim(0, max(shares) * 1.2 + 1)
    bars.set_xlabel(f"share of the windup, {budget.torque_low:g} to {budget.torque_high:g} N·m [%]")
    bars.set_title(f"{budget.design.name}: compliance budget")
    bars.grid(axis="x", alpha=0.3)
    mean = wind.windup[0].mean(axis=-1) / ARCMIN
    for p in range(wind.theta_in.size):
        curve.plot(wind.tau_load, wind.windup[0, :, p] / ARCMIN, "-", color="0.7", lw=0.6)
    curve.plot(wind.tau_load, mean, "o-", ms=3, color="tab:blue", label="mean over the positions")
    rated = wind.design.rated_torque
    k = report.torsional_rigidity_Nm_per_arcmin
    half = int(np.argmin(np.abs(wind.tau_load - 0.5 * rated)))
    torque = np.array([0.5, 1.0]) * rated
    curve.plot(
        torque,
        mean[half] + (torque - 0.5 * rated) / k,
        "k:",
        lw=2,
        label=f"torsional rigidity {k:.1f} N·m/arcmin",
    )
    curve.set_xlabel("output torque τ_load [N·m]")
    curve.set_ylabel("output windup [arcmin]")
    curve.set_title(f"windup, input locked; lost motion {report.lost_motion_arcmin:.3f} arcmin")
    curve.grid(alpha=0.3)
    curve.legend(fontsize=8, loc="upper left")
    return _saved(plt, fig, path, dpi=120)


__all__ = [
    "figure_te",
    "marker_orders",
    "plot_te",
    "plot_windup",
    "plot_catalogue",
    "plot_budget",
    "rad_to_arcsec",
]


def plot_simulation(sim, path: str | Path) -> Path:
    """TE against time (top, the start ramp shaded) and its spectrum in Hz after the ramp
    (bottom) with the crank, pin-passing and stage-1 mesh frequencies marked (not where the
    input reverses)."""
    from .core.dynamics.excitations import Excitations

    plt = _pyplot()
    fig, (ax_te, ax_sp) = plt.subplots(2, 1, figsize=(9, 7), constrained_layout=True)
    ax_te.plot(sim.time, sim.te_arcsec, lw=0.6, color="C0")
    ax_te.axvspan(0.0, sim.time[sim.steady], color="0.9", label="start ramp")
    ax_te.set_xlabel("time [s]")
    ax_te.set_ylabel("transmission error [arcsec]")
    ax_te.set_xlim(0.0, sim.time[-1])
    ax_te.set_title(
        f"{sim.design.name}: dynamic TE at {sim.speed_rpm:g} rpm, load "
        f"{-sim.tau_load[0]:g} N·m (te_pp {sim.te_pp_arcsec:.2f}″ after the ramp)"
    )
    ax_te.legend(loc="upper right", fontsize=8)
    ax_te.grid(alpha=0.3)
    f, a = sim.spectrum_hz()
    ex = Excitations.at(sim.design, sim.speed_rpm)
    top = 3.0 * max(ex.mesh, ex.pin_passing)
    keep = (f > 0) & (f <= top)  # the mean is not a vibration
    ax_sp.plot(f[keep], a[keep], lw=0.8, color="C1")
    ax_sp.set_xscale("log")
    ax_sp.set_xlabel("frequency [Hz]")
    ax_sp.set_ylabel("amplitude [arcsec]")
    ax_sp.set_xlim(f[1], top)
    # an input that reverses has no single speed: no excitation frequency to mark
    for name, hz in () if sim.input_reverses else ex.items():
        if hz <= top:
            ax_sp.axvline(hz, color="0.6", lw=0.6, ls=":")
            ax_sp.annotate(
                f"{name} {hz:.1f} Hz",
                (hz, ax_sp.get_ylim()[1] * 0.95),
                fontsize=7,
                rotation=90,
                ha="right",
                va="top",
                color="0.4",
            )
    ax_sp.grid(alpha=0.3)
    return _saved(plt, fig, path, dpi=130)


def plot_campbell(
    design, frequencies_hz, speeds_rpm, lines: dict, speed_rpm: float, path: str | Path
) -> Path:
    """Campbell diagram: the natural frequencies (horizontal) against the excitation lines over
    input speed, the chosen speed marked; a crossing is a speed that excites a resonance."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(9, 6), constrained_layout=True)
    # up to the third harmonic of the fastest excitation, and at least the lowest mode
    fastest = max(float(v.max()) for v in lines.values())
    top = 1.15 * max(3.0 * fastest, float(np.min(frequencies_hz)))
    for k, hz in enumerate(frequencies_hz):
        if hz <= top:
            ax.axhline(hz, color="0.55", lw=0.7, ls="--")
            ax.annotate(
                f"mode {k + 1}: {hz:.0f} Hz",
                (speeds_rpm[-1], hz),
                fontsize=7,
                ha="right",
                va="bottom",
                color="0.35",
            )
    for n, (name, hz) in enumerate(lines.items()):
        ax.plot(speeds_rpm, hz, lw=1.2, color=f"C{n}", label=name)
        if name in ("pin passing", "stage-1 mesh"):
            for harmonic in (2, 3):
                ax.plot(
                    speeds_rpm, harmonic * hz, lw=0.7, ls="-.", color=f"C{n}", label=f"{harmonic} x {name}"
                )
    ax.axvline(speed_rpm, color="C3", lw=0.8, ls=":", label=f"{speed_rpm:g} rpm")
    ax.set_xlim(speeds_rpm[0], speeds_rpm[-1])
    ax.set_ylim(0.0, top)
    ax.set_xlabel("input speed [rpm]")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title(f"{design.name}: Campbell diagram (modes at the loaded equilibrium)")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    return _saved(plt, fig, path, dpi=130)


def plot_measured(measured, path: str | Path, title: str | None = None) -> Path:
    """A bench record's TE (`rvfmu.bench.measured.MeasuredTE`): the measured TE, the removed
    runout and the TE without it against the output angle turned (top), both spectra by
    order with the removed orders marked (middle) and, with a time column, in Hz (bottom)."""
    plt = _pyplot()
    m = measured
    panels = 3 if m.hz is not None else 2
    fig, axes = plt.subplots(panels, 1, figsize=(9, 3.3 * panels), constrained_layout=True)
    ax_te, ax_sp = axes[0], axes[1]
    out_deg = np.degrees(m.output_angle)
    pp = m.te_pp_arcsec
    ax_te.plot(out_deg, m.te_arcsec, lw=0.6, color="0.6", label=f"measured (te_pp {pp[0]:.2f}″)")
    ax_te.plot(out_deg, m.runout_arcsec, lw=0.9, ls="--", color="C3", label="removed runout")
    ax_te.plot(
        out_deg, m.te_reducer_arcsec, lw=0.7, color="C0", label=f"without the runout (te_pp {pp[1]:.2f}″)"
    )
    ax_te.set_xlabel("output angle turned, θ_in / i [deg]")
    ax_te.set_ylabel("transmission error [arcsec]")
    ax_te.set_xlim(0, 360 * m.revolutions)
    ax_te.set_title(
        title
        or f"measured TE, ratio {m.ratio:g}: {m.revolutions} output "
        f"revolution{'s' if m.revolutions > 1 else ''}, "
        f"{m.points_per_revolution} rows per revolution"
    )
    ax_te.legend(loc="upper right", fontsize=8)
    ax_te.grid(alpha=0.3)

    def spectrum(ax, axis, amplitude, unit):
        ax.vlines(axis[1:], 0, amplitude[0, 1:], color="0.6", lw=0.8, label="measured")
        ax.vlines(axis[1:], 0, amplitude[1, 1:], color="C1", lw=1.0, label="without the runout")
        ax.set_xscale("log")
        ax.set_xlim(0.8 * axis[1], axis[-1])
        ax.set_ylim(0, 1.1 * float(amplitude[:, 1:].max()) or 1.0)
        ax.set_xlabel(unit)
        ax.set_ylabel("amplitude [arcsec]")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3, which="both")

    spectrum(ax_sp, m.orders, m.spectrum, "order [cycles per output revolution]")
    top = ax_sp.get_ylim()[1]
    for c in m.components:
        order = c.order if c.shaft == "output" else c.order * m.ratio
        ax_sp.axvline(order, color="0.6", lw=0.6, ls=":")
        ax_sp.annotate(
            f"removed: {c.shaft} order {c.order}",
            (order, 0.97 * top),
            xytext=(-3, 0),
            textcoords="offset points",
            fontsize=7,
            rotation=90,
            ha="right",
            va="top",
            color="0.3",
        )
    if m.hz is not None:
        spectrum(axes[2], m.hz, m.spectrum_hz, "frequency [Hz]")
        axes[2].set_title(f"output speed {m.output_speed_hz:.4g} Hz (mean)", fontsize=8)
    return _saved(plt, fig, path, dpi=130)


def plot_comparison(comparison, path: str | Path, title: str | None = None) -> Path:
    """A bench record beside the model (`rvfmu.bench.compare.Comparison`): both TE curves against
    the output angle turned (top), their difference (middle) and both spectra by order with
    the difference's (bottom)."""
    plt = _pyplot()
    c = comparison
    m = c.measured
    fig, (ax_te, ax_diff, ax_sp) = plt.subplots(3, 1, figsize=(9, 9.5), constrained_layout=True)
    out_deg = np.degrees(m.output_angle)
    pp = c.te_pp_arcsec
    ax_te.plot(
        out_deg, c.measured_arcsec, lw=1.6, color="C0", alpha=0.5, label=f"measured (te_pp {pp[0]:.2f}″)"
    )
    ax_te.plot(out_deg, c.model_arcsec, lw=0.7, color="C1", label=f"model (te_pp {pp[1]:.2f}″)")
    ax_te.set_xlabel("output angle turned, θ_in / i [deg]")
    ax_te.set_ylabel("TE, mean and runout orders removed [arcsec]")
    ax_te.set_xlim(0, 360 * m.revolutions)
    ax_te.set_title(title or f"measured against {c.design.name} at {c.load_Nm:g} N·m")
    ax_te.legend(loc="upper right", fontsize=8)
    ax_te.grid(alpha=0.3)
    ax_diff.plot(out_deg, c.difference_arcsec, lw=0.7, color="C3")
    ax_diff.set_xlim(0, 360 * m.revolutions)
    ax_diff.set_xlabel("output angle turned, θ_in / i [deg]")
    ax_diff.set_ylabel("measured − model [arcsec]")
    ax_diff.set_title(
        f"correlation {c.correlation:.4f}, difference {c.rms_difference_arcsec:.3f}″ "
        f"RMS; model on {c.points} points per revolution",
        fontsize=8,
    )
    ax_diff.grid(alpha=0.3)
    for k, (label, color, width) in enumerate(
        (("measured", "C0", 1.6), ("model", "C1", 1.0), ("difference", "C3", 0.6))
    ):
        ax_sp.vlines(c.orders[1:], 0, c.spectrum[k, 1:], color=color, lw=width, label=label, alpha=0.8)
    ax_sp.set_xscale("log")
    ax_sp.set_xlim(0.8 * c.orders[1], c.orders[-1])
    ax_sp.set_ylim(0, 1.1 * float(c.spectrum[:, 1:].max()) or 1.0)
    ax_sp.set_xlabel("order [cycles per output revolution]")
    ax_sp.set_ylabel("amplitude [arcsec]")
    ax_sp.legend(loc="upper right", fontsize=8)
    ax_sp.grid(alpha=0.3, which="both")
    return _saved(plt, fig, path, dpi=130)


def plot_efficiency(report, path: str | Path) -> Path:
    """`figure_efficiency` of `report` written to `path` (PNG, 120 dpi)."""
    return _saved(_pyplot(), figure_efficiency(report), path, dpi=120)


def figure_efficiency(report):
    """The catalogue's efficiency charts (`rvfmu.jobs.efficiency.EfficiencyReport`), five panels:
    efficiency against output speed, one curve per resisting torque, forward (solid) and
    backdriving (dashed); efficiency against output torque, one curve per speed (light loads
    included); efficiency against the lubricant's temperature at each of the map's torques and
    its middle speed; the no-load running torque at the input against the temperature at each
    speed (the catalogue's low-temperature characteristic); and against input speed at each
    temperature.  Without `report.characteristics` the first panel and the running torque at
    the report's temperature only.  A matplotlib Figure."""
    plt = _pyplot()
    m, c = report.map, report.characteristics
    fig, panels = plt.subplot_mosaic(
        [["speed", "torque"], ["temperature", "cold"], ["running", "running"]],
        figsize=(12, 13),
        constrained_layout=True,
    )
    by_speed, by_torque, by_temperature, cold, running = (
        panels[k] for k in ("speed", "torque", "temperature", "cold", "running")
    )
    for j, torque in enumerate(m.load_Nm):
        (line,) = by_speed.plot(
            m.output_speed_rpm, 100 * m.efficiency[:, j], "o-", ms=3, label=f"{torque:g} N·m"
        )
        by_speed.plot(
            m.output_speed_rpm, 100 * m.backdriving_efficiency[:, j], "--", color=line.get_color(), lw=1
        )
    by_speed.set_xlabel("output speed [rpm]")
    by_speed.set_title(
        f"{m.design.name}, {m.temperature_C:g} °C: efficiency (solid forward, dashed backdriving)"
    )
    by_speed.legend(fontsize=8, title="resisting torque")
    ratio = m.design.ratio
    if c is None:
        for ax in (by_torque, by_temperature, cold):
            ax.set_visible(False)
        running.plot(
            m.output_speed_rpm * ratio,
            m.no_load_running_torque_Nm,
            "o-",
            ms=3,
            color="tab:red",
            label=f"{m.temperature_C:g} °C",
        )
    else:
        t = c.by_torque
        for v, speed in enumerate(t.output_speed_rpm):
            by_torque.plot(t.load_Nm, 100 * t.efficiency[v], "o-", ms=3, label=f"{speed:g} rpm")
        by_torque.axvline(m.design.rated_torque, color="0.5", lw=0.8, ls=":")
        by_torque.set_xlabel("resisting output torque [N·m] (dotted: rated)")
        by_torque.set_xlim(left=0)
        by_torque.set_title(f"efficiency against torque, {m.temperature_C:g} °C")
        by_torque.legend(fontsize=8, title="output speed")
        temperatures = np.array(list(c.by_temperature))
        middle = len(m.output_speed_rpm) // 2
        for j, torque in enumerate(m.load_Nm):
            by_temperature.plot(
                temperatures,
                [100 * x.efficiency[middle, j] for x in c.by_temperature.values()],
                "o-",
                ms=3,
                label=f"{torque:g} N·m",
            )
        by_temperature.set_xlabel("lubricant temperature [°C]")
        by_temperature.set_title(f"efficiency against temperature, {m.output_speed_rpm[middle]:g} rpm output")
        by_temperature.legend(fontsize=8, title="resisting torque")
        for v, speed in enumerate(m.output_speed_rpm):
            cold.plot(
                temperatures,
                [x.no_load_running_torque_Nm[v] for x in c.by_temperature.values()],
                "o-",
                ms=3,
                label=f"{speed * ratio:.0f} rpm in ({speed:g} out)",
            )
        cold.set_xlabel("lubricant temperature [°C]")
        cold.set_ylabel("no-load running torque at the input [N·m]")
        cold.set_yscale("log")
        cold.set_title("running torque against temperature (low-temperature characteristic)", fontsize=10)
        cold.legend(fontsize=7, title="input speed")
        for temperature, x in c.by_temperature.items():
            running.plot(
                x.output_speed_rpm * ratio,
                x.no_load_running_torque_Nm,
                "o-",
                ms=3,
                label=f"{temperature:g} °C",
            )
    running.set_xlabel("input speed [rpm]")
    running.set_ylabel("no-load running torque at the input [N·m]")
    running.set_title(
        f"running torque; starting {m.starting_torque_input_Nm:.3g} N·m (input), "
        f"backdriving {m.backdriving_torque_output_Nm:.3g} N·m (output)",
        fontsize=10,
    )
    running.set_ylim(bottom=0)
    running.legend(fontsize=8, title="lubricant")
    for ax in (by_speed, by_torque, by_temperature):
        ax.set_ylabel("efficiency [%]")
    for ax in panels.values():
        ax.grid(alpha=0.3)
    return fig


INSET_FRICTION_TORQUES = 5  # the inset's torque half-span, x the friction torque at zero:
# the branches cross the clearance at +-T_f, well inside it


def figure_hysteresis(report):
    """The hysteresis loop (`rvfmu.jobs.hysteresis.HysteresisReport`) as a matplotlib Figure:
    output angle against output torque with the input locked, the loop with friction and its
    frictionless middle (top left); the middle around zero torque with the lost motion's span
    marked, and an inset over +-INSET_FRICTION_TORQUES friction torques where the two branches
    cross the clearance apart (top right); the loop's width, the unloading branch's angle less
    the loading one's at the same torque [arcsec], against torque (bottom).  Drawn over
    +-rated the branches are one line (they are 2 T_f ~ 4 N*m apart): the width and the inset
    are what show friction."""
    plt = _pyplot()
    h = report.loop
    fig, axes = plt.subplot_mosaic(
        [["whole", "middle"], ["width", "width"]], figsize=(12, 8.4), constrained_layout=True
    )
    whole, middle = axes["whole"], axes["middle"]
    for ax in (whole, middle):
        ax.plot(h.loop[:, 0], h.loop[:, 1] / ARCMIN, "-", color="tab:red", lw=1.2, label="with friction")
        ax.plot(h.tau_load, h.windup / ARCMIN, ":", color="0.3", lw=1, label="without friction")
        ax.set_xlabel("output torque τ_load [N·m]")
        ax.set_ylabel("output angle [arcmin]")
        ax.grid(alpha=0.3)
    whole.set_title(f"{h.design.name}: rigidity {h.torsional_rigidity_Nm_per_arcmin:.1f} N·m/arcmin")
    whole.legend(fontsize=8, loc="upper left")
    span = 0.1 * h.design.rated_torque
    middle.set_xlim(-span, span)
    near = np.abs(h.tau_load) <= span
    if near.any():
        lo, hi = h.windup[near].min() / ARCMIN, h.windup[near].max() / ARCMIN
        middle.set_ylim(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo))
    rated = h.design.rated_torque
    for sign in (-1, 1):
        middle.axvline(sign * 0.03 * rated, color="tab:blue", lw=0.8, ls="--")
    middle.set_title(
        f"lost motion {h.lost_motion_arcmin:.3f} arcmin (±3 % rated, dashed), "
        f"hysteresis loss {h.hysteresis_loss_arcmin:.3f} arcmin",
        fontsize=10,
    )
    _branches_inset(middle, h)
    _width_panel(axes["width"], report)
    return fig


def _branches_inset(ax, h) -> None:
    """The loop's two branches apart, over +-INSET_FRICTION_TORQUES friction torques at zero
    (upper left of `ax`, where the loop leaves the panel empty)."""
    mid = 0.5 * (h.tau_load[1:] + h.tau_load[:-1])
    held = float(np.interp(0.0, mid, h.friction_torque))
    if not held > 0.0:  # no friction: one branch, nothing to tell apart
        return
    half = h.loop.shape[0] // 2
    window = INSET_FRICTION_TORQUES * held
    inset = ax.inset_axes([0.05, 0.5, 0.42, 0.42])
    for branch, colour, label in (
        (h.loop[:half], "tab:red", "loading"),
        (h.loop[half:], "tab:blue", "unloading"),
    ):
        inset.plot(branch[:, 0], branch[:, 1] / ARCMIN, "-", color=colour, lw=1.2, label=label)
    inset.plot(h.tau_load, h.windup / ARCMIN, ":", color="0.3", lw=1)
    inset.set_xlim(-window, window)
    inside = np.abs(h.loop[:, 0]) <= window
    lo, hi = h.loop[inside, 1].min() / ARCMIN, h.loop[inside, 1].max() / ARCMIN
    inset.set_ylim(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo))
    inset.set_title(f"±{window:.2g} N·m: friction torque {held:.2g} N·m at zero", fontsize=7)
    inset.tick_params(labelsize=7)
    inset.legend(fontsize=6, loc="lower right")
    inset.grid(alpha=0.3)


def _width_panel(ax, report) -> None:
    """The loop's width [arcsec] against output torque, on a log scale where friction opens
    the whole loop: the clearance's ~30 arcsec at zero and the few arcsec friction gives
    loaded on one axis."""
    torques, width = report.width_torques_Nm, 60.0 * report.width_arcmin()
    ax.plot(torques, width, "-", color="tab:purple", lw=1.2)
    # log where friction opens the loop everywhere: not on the round-off of a frictionless one
    if width.min() > 1e-9 * 60.0 * float(np.abs(report.loop.windup).max()) / ARCMIN:
        ax.set_yscale("log")
    ax.plot([0.0], [60.0 * report.width_at_zero_arcmin], "o", color="tab:purple", ms=4)
    ax.set_xlabel("output torque τ_load [N·m]")
    ax.set_ylabel("loop width [arcsec]")
    ax.set_title(
        f"the loop's width: unloading less loading branch at the same torque; "
        f"{60 * report.width_at_zero_arcmin:.3g} arcsec at zero torque (dot), "
        f"{60 * report.width_max_arcmin:.3g} at most "
        f"({report.width_max_torque_Nm:.3g} N·m)",
        fontsize=10,
    )
    ax.grid(alpha=0.3, which="both")


def plot_hysteresis(report, path: str | Path) -> Path:
    """The hysteresis loop and its width (`figure_hysteresis`), written to `path`."""
    return _saved(_pyplot(), figure_hysteresis(report), path, dpi=120)
