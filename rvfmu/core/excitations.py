"""The reducer's excitation frequencies at an input speed, and a signal's amplitude at one.

Kinematics only (docs/model.md section 7): what turns at which frequency when the
input turns at a given speed, and the amplitude a sampled signal (a TE record)
has at such a frequency.  The dynamic run (`simulation`), the modes' Campbell
lines (`modes`) and the reports all read them from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .design import RVDesign

HARMONICS = (1, 2)         # the excitations' orders whose TE amplitude a run reports


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
        return (("input rotation", self.input), ("crank rotation", self.crank),
                ("pin passing", self.pin_passing), ("stage-1 mesh", self.mesh))

    def with_harmonics(self, orders=HARMONICS):
        """((name, frequency [Hz]), ...): each excitation and its harmonics (name "x2", ...)."""
        return tuple((name if k == 1 else f"{name} x{k}", k * hz)
                     for name, hz in self.items() for k in orders)


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
