"""Figures for people: the TE curve with its order spectrum, windup curves.

Plotting knows the result records and matplotlib, nothing of the physics.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .core.quasistatic import TECurve, Windup
from .core.units import ARCMIN, rad_to_arcsec


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_te(curve: TECurve, path: str | Path, sample: int = 0, title: str | None = None) -> Path:
    """TE against output angle (top) and its order spectrum (bottom), written to `path`."""
    plt = _pyplot()
    design = curve.design
    te = curve.te_arcsec[sample]
    out_deg = np.degrees(curve.theta_in / design.ratio)
    orders, amplitude = curve.spectrum_arcsec()
    amplitude = amplitude[sample]
    fig, (ax_te, ax_sp) = plt.subplots(2, 1, figsize=(9, 7), constrained_layout=True)
    ax_te.plot(out_deg, te, lw=0.8, color="C0")
    ax_te.axhline(te.mean(), color="0.5", lw=0.6, ls="--", label=f"mean {te.mean():.2f}″")
    ax_te.set_xlabel("output angle θ_out [deg]")
    ax_te.set_ylabel("transmission error [arcsec]")
    ax_te.set_xlim(0, 360)
    load = -curve.tau_load
    ax_te.set_title(title or (f"{design.name}: TE at load {load:g} N·m "
                              f"(te_pp {np.ptp(te):.2f}″, {curve.points} points/rev)"))
    ax_te.legend(loc="upper right", fontsize=8)
    ax_te.grid(alpha=0.3)
    shown = orders[1:]
    ax_sp.vlines(shown, 0, amplitude[1:], color="C1", lw=1.0)
    ax_sp.set_xscale("log")
    ax_sp.set_xlabel("order [cycles per output revolution]")
    ax_sp.set_ylabel("amplitude [arcsec]")
    marks = ((design.z_p, "crank in carrier z_p"), (design.z_p * design.z_c, "pin passing z_p·z_c"))
    for order, label in marks:
        if order <= orders[-1]:
            ax_sp.axvline(order, color="0.6", lw=0.6, ls=":")
            ax_sp.annotate(label, (order, ax_sp.get_ylim()[1] * 0.9), fontsize=7, rotation=90,
                           ha="right", va="top", color="0.4")
    ax_sp.grid(alpha=0.3, which="both")
    path = Path(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def plot_windup(windup: Windup, path: str | Path, sample: int = 0) -> Path:
    """Output windup [arcmin] against output torque [N*m] at each locked input position."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    for p in range(windup.theta_in.size):
        ax.plot(windup.tau_load, windup.windup[sample, :, p] / ARCMIN, "o-", ms=3, lw=0.7, alpha=0.7)
    ax.set_xlabel("output torque τ_load [N·m]")
    ax.set_ylabel("output windup [arcmin]")
    ax.set_title(f"{windup.design.name}: windup, input locked "
                 f"({windup.theta_in.size} positions)")
    ax.grid(alpha=0.3)
    path = Path(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


__all__ = ["plot_te", "plot_windup", "rad_to_arcsec"]
