"""The reducer's excitation frequencies at an input speed, and a signal's amplitude at one.

Kinematics only (docs/model.md section 7): what turns at which frequency when the
input turns at a given speed, and the amplitude a sampled signal (a TE record)
has at such a frequency.  The dynamic run (`simulation`), the modes' Campbell
lines (`modes`) and the reports all read them from here.

An amplitude is read from a record of finite length T, and a short record
cannot tell an excitation from its neighbours: through the Hann window's
sidelobes a component df away leaks into it (`amplitude_at`), and so do the
record's mean and its slow content near 0 Hz (the output rotation's orders at
f_in / i, what the start leaves settling).  `read_amplitudes` therefore reads an
excitation only where the record is long enough (`record_needed`) and says
why not elsewhere, rather than print a number that depends on the record's
length more than on the reducer (seed 002 at 1600 rpm, 0.05 s after the ramp:
3.6 arcsec at the crank rotation, 9.0 over 1 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..reducer.design import RVDesign

HARMONICS = (1, 2)  # the excitations' orders whose TE amplitude a run reports
# What a record of length T must hold to read an excitation at f (`record_needed`), from the
# Hann window's leakage as `amplitude_at` reads it (a unit sine df away reads at most 2.7 % of
# itself for df*T from 2 to 3 bins, at most 0.85 % from 3 bins on, measured over every offset):
RESOLUTION_BINS = 3  # every other listed excitation at least 3 bins (3 / T) away: < 1 % of it
MIN_PERIODS = 4  # and f at least 4 bins from 0 Hz (4 periods of f): the record's mean
# and slow content sit there, not one line at a known frequency (the
# output rotation's orders, what the start leaves settling), so one
# bin more than RESOLUTION_BINS.  On
# seed 002 at 1600 rpm the crank rotation (9.06 arcsec over 4.6 s)
# reads 9.2 +- 0.4 over windows of 4 periods, 8.6 +- 1.2 over windows
# of 0.9 period (20 windows each)


@dataclass(frozen=True)
class Excitations:
    """Excitation frequencies [Hz] at an input speed (docs/model.md section 7)."""

    input: float
    output: float
    crank: float
    pin_passing: float
    mesh: float

    @classmethod
    def at(cls, design: RVDesign, speed_rpm: float) -> "Excitations":
        f_in = speed_rpm / 60.0
        f_out = f_in / design.ratio
        crank = (f_in - f_out) * design.z_s / design.z_pl
        return cls(f_in, f_out, crank, design.z_c * crank, design.z_s * (f_in - f_out))

    def items(self):
        return (
            ("input rotation", self.input),
            ("crank rotation", self.crank),
            ("pin passing", self.pin_passing),
            ("stage-1 mesh", self.mesh),
        )

    def with_harmonics(self, orders=HARMONICS):
        """((name, frequency [Hz]), ...): each excitation and its harmonics (name "x2", ...)."""
        return tuple(
            (name if k == 1 else f"{name} x{k}", k * hz) for name, hz in self.items() for k in orders
        )


def amplitude_at(signal, step: float, frequency: float) -> float:
    """Amplitude of the sine at `frequency` [Hz] in `signal` (its unit) sampled every `step` [s]:
    the Hann-windowed Fourier sum of the signal less its mean, evaluated at exactly that
    frequency (not at the nearest bin, so no scalloping and no interpolation), times
    2 / sum(window).  A neighbouring component at df leaks into it by the Hann window's
    sidelobes, below 1 % from 3 / T (T the record's length) on, where a sine at a bin
    frequency and one half a bin off read the same."""
    x = np.asarray(signal, dtype=float)
    x = x - x.mean()
    window = np.hanning(x.size)
    phase = np.exp(-2j * np.pi * frequency * step * np.arange(x.size))
    return float(2.0 * abs(np.sum(window * x * phase)) / window.sum())


def record_needed(frequency: float, others) -> float:
    """[s] the shortest record from which `amplitude_at` reads `frequency` [Hz] (> 0):
    MIN_PERIODS of its periods, and a bin width 1/T of at most 1/RESOLUTION_BINS of the
    distance to the nearest of `others` [Hz] (the other excitations listed with it).
    inf where one of them coincides with it (within 1e-9 relative): no record separates them."""
    gaps = np.abs(np.asarray(others, dtype=float) - frequency)
    nearest = float(gaps.min()) if gaps.size else math.inf
    if nearest <= 1e-9 * frequency:
        return math.inf
    return max(MIN_PERIODS / frequency, RESOLUTION_BINS / nearest)


def read_amplitudes(signal, step: float, listed) -> list[tuple[str, float, float | None, str | None]]:
    """[(name, frequency [Hz], amplitude (the signal's unit) or None, why it is None or None)]
    of every (name, frequency [Hz]) in `listed` (`Excitations.with_harmonics`), read from
    `signal` (N,) sampled every `step` [s] by `amplitude_at` where the record (T = N * step)
    resolves the frequency (`record_needed`, each against the others listed): else None and
    the reason, "needs >= X s of record" (X rounded up, so that X seconds do), "coincides
    with NAME" or "above the step's Nyquist frequency"."""
    x = np.asarray(signal, dtype=float)
    length, nyquist = x.size * step, 0.5 / step
    listed = tuple(listed)
    rows = []
    for name, hz in listed:
        others = [f for other, f in listed if other != name]
        needed = record_needed(hz, others)
        if hz >= nyquist:
            reason = f"above the step's Nyquist frequency {nyquist:.4g} Hz"
        elif math.isinf(needed):
            twin = next(other for other, f in listed if other != name and abs(f - hz) <= 1e-9 * hz)
            reason = f"coincides with {twin}"
        elif length < needed:
            reason = f"needs \u2265 {_round_up(needed)} s of record"
        else:
            reason = None
        rows.append((name, hz, None if reason else amplitude_at(x, step, hz), reason))
    return rows


def _round_up(value: float, digits: int = 3) -> str:
    """`value` > 0 rounded up to `digits` significant digits, as text."""
    scale = 10.0 ** (math.floor(math.log10(value)) - digits + 1)
    return f"{math.ceil(value / scale - 1e-9) * scale:.{digits}g}"
