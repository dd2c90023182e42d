"""Measured against modelled TE: does the model of this design reproduce the bench's curve?

The question is asked of one bench record (`rvfmu.bench.measured.MeasuredTE`) and one
design with its errors at the record's load.  How the two are put side by side,
and why so:

- The model is evaluated where the bench was, at the record's input angles: on an
  even grid of `points` per output revolution (quasi-static equilibria,
  `rvfmu.core.statics.quasistatic.equilibria`) and interpolated linearly to the record's
  rows.  When the ratio is a whole number (every preset) the model's TE repeats
  every output revolution (the sun turns i times, every crank z_p times), so one
  revolution of grid serves a record of many; otherwise the grid spans the
  record's range of input angles.  The grid, not the rows, sets the model's cost:
  a record of 10^5 rows costs what `points` equilibria cost.
- The input encoder is taken to read the model's theta_in (zero at the reference
  pose of docs/model.md section 2).  A bench whose zero differs shows it as a
  shift between the curves; the best shift is reported beside the figures at
  zero shift, not applied.
- The bench's TE has lost its mean (the encoders' zeros) and the orders that
  `measure` removed as runout.  The model's TE is put through the same
  projection, on the same rows with the same cos/sin columns of the encoder
  angles, so that both curves have lost the same content; what remains is
  compared: te_pp, RMS, the correlation and the difference, by angle and order.
- Direction: a record turned in the negative sense is modelled with its load
  resisting that motion (tau_load = +load) and its no-load limit approached from
  that side; quasi-static, nothing else depends on the sense.

Everything here is arrays in, a record out: no files, no CLI, no plots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.base.units import ARCSEC
from ..core.reducer.design import RVDesign
from ..core.reducer.errors import ErrorSet
from ..core.statics import metrics
from ..core.statics.quasistatic import default_points, equilibria, input_angles
from .measured import MeasuredTE

REVOLUTION = 2.0 * np.pi

# A ratio within this of a whole number repeats its TE every output revolution
# (ratios are tooth-count fractions: a non-whole one is off by 1/z_s or more).
WHOLE_RATIO = 1e-9


def periodic(design: RVDesign) -> bool:
    """True when the model's TE repeats every output revolution: the ratio is a whole number
    (the sun turns i times per output revolution, every crank z_p times)."""
    return abs(design.ratio - round(design.ratio)) < WHOLE_RATIO


@dataclass(frozen=True)
class ModelGrid:
    """The model's TE of S reducers on a grid of input angles.

    theta_in: (A,) [rad]; te_arcsec: (S, A); converged: (S,) bool; period: the input
    angle of one output revolution [rad] when the grid covers one periodic revolution,
    else None (the grid spans the angles it was made for).
    """

    theta_in: np.ndarray
    te_arcsec: np.ndarray
    converged: np.ndarray
    period: float | None

    def at(self, theta_in) -> np.ndarray:
        """(S, rows) TE [arcsec] at the input angles theta_in (rows,) [rad], linear between
        grid points (periodically when the grid is one periodic revolution)."""
        theta = np.asarray(theta_in, dtype=float)
        grid, te = self.theta_in, self.te_arcsec
        if self.period is not None:
            theta = np.mod(theta, self.period)
            grid = np.append(grid, self.period)
            te = np.concatenate([te, te[:, :1]], axis=1)
        return np.stack([np.interp(theta, grid, curve) for curve in te])


def model_grid(
    design: RVDesign,
    errors: ErrorSet,
    load: float,
    points: int,
    sense: int = 1,
    theta_range: tuple[float, float] | None = None,
) -> ModelGrid:
    """The model's TE [arcsec] of every reducer of `errors` at a resisting `load` [N*m],
    `points` per output revolution.

    sense: +1 when the input turns positive (tau_load = -load), -1 when negative
    (tau_load = +load); the no-load limit is approached from the resisting side.
    theta_range: (first, last) input angles [rad] to cover when the design is not
    periodic; a periodic design always gets one revolution from theta_in = 0.
    """
    if periodic(design) or theta_range is None:
        theta = input_angles(design, points)
        period = REVOLUTION * design.ratio if periodic(design) else None
    else:
        step = REVOLUTION * design.ratio / points
        first = np.floor(min(theta_range) / step)
        last = np.ceil(max(theta_range) / step)
        theta = step * np.arange(first, last + 1)
        period = None
    tau = -sense * float(load)
    eq = equilibria(design, errors, theta, [tau], zero_side=-sense)
    return ModelGrid(theta, eq.te[:, 0] / ARCSEC, eq.converged[:, 0].all(axis=-1), period)


def bench_columns(measured: MeasuredTE) -> np.ndarray:
    """(rows, 1 + 2 * components): the constant and the cos/sin columns of the encoder angles
    that `measure_te` fitted and removed, on the record's rows."""
    columns = [np.ones(measured.rows)]
    for c in measured.components:
        angle = measured.theta_out if c.shaft == "output" else measured.theta_in
        columns += [np.cos(c.order * angle), np.sin(c.order * angle)]
    return np.stack(columns, axis=1)


def as_bench_sees(measured: MeasuredTE, curves) -> np.ndarray:
    """(S, rows): TE curves [arcsec] on the record's rows with what the bench processing
    removed (the mean and the runout orders) removed the same way."""
    curves = np.atleast_2d(curves)
    columns = bench_columns(measured)
    coef = np.linalg.lstsq(columns, curves.T, rcond=None)[0]
    return curves - (columns @ coef).T


def even_in_output(measured: MeasuredTE, curves) -> np.ndarray:
    """(S, revolutions * points_per_revolution): curves on the record's rows resampled evenly
    in the nominal output angle over its whole revolutions, as `measure_te` resamples them
    for its spectrum (the FFT of n revolutions gives orders k / n)."""
    total = measured.revolutions * measured.points_per_revolution
    grid = measured.revolutions * REVOLUTION * np.arange(total) / total
    phi = measured.output_angle
    return np.stack([np.interp(grid, phi, c) for c in np.atleast_2d(curves)])


@dataclass(frozen=True)
class Comparison:
    """A bench record beside the model of a design at the record's load.

    Per-row arrays (rows,) [arcsec]: measured_arcsec (the record's TE without its
    runout, `MeasuredTE.te_reducer_arcsec`), model_raw_arcsec (the model's TE at the
    rows, its mean included), model_arcsec (the same with the bench's projection
    applied, `as_bench_sees`), difference_arcsec = measured - model.  orders (K,) in
    cycles per output revolution; spectrum (3, K) [arcsec]: measured, model, difference.
    points: the model's grid per output revolution; periodic: one revolution of grid
    served the whole record.  shift_deg: the output angle by which the model, delayed,
    best matches the measurement, with the correlation there (shift_correlation).
    """

    measured: MeasuredTE
    design: RVDesign
    load_Nm: float
    points: int
    periodic: bool
    converged: bool
    model_raw_arcsec: np.ndarray
    model_arcsec: np.ndarray
    orders: np.ndarray
    spectrum: np.ndarray
    shift_deg: float
    shift_correlation: float

    @property
    def measured_arcsec(self) -> np.ndarray:
        return self.measured.te_reducer_arcsec

    @property
    def difference_arcsec(self) -> np.ndarray:
        return self.measured_arcsec - self.model_arcsec

    @property
    def te_pp_arcsec(self) -> np.ndarray:
        """(2,) peak-to-peak over the record's rows: [measured, model]."""
        return metrics.te_pp(np.stack([self.measured_arcsec, self.model_arcsec]))

    @property
    def rms_arcsec(self) -> np.ndarray:
        """(2,) RMS about the mean: [measured, model]."""
        return metrics.te_rms(np.stack([self.measured_arcsec, self.model_arcsec]))

    @property
    def rms_difference_arcsec(self) -> float:
        return float(np.sqrt(np.mean(self.difference_arcsec**2)))

    @property
    def correlation(self) -> float:
        """Pearson correlation of the two curves over the rows (nan if either is flat)."""
        a, b = self.measured_arcsec, self.model_arcsec
        a, b = a - a.mean(), b - b.mean()
        norm = np.sqrt((a @ a) * (b @ b))
        return float(a @ b / norm) if norm > 0 else float("nan")

    def by_order(self, count: int = 8) -> list[tuple[float, float, float, float]]:
        """[(order, measured, model, |difference|) [arcsec]]: the orders among the `count`
        largest of either curve, by order; |difference| is the amplitude of the difference
        curve at that order (phase included, so it can exceed the two amplitudes' gap)."""
        chosen = set()
        for amplitude in self.spectrum[:2]:
            top = np.argsort(-amplitude[1:], kind="stable")[:count] + 1
            chosen.update(int(k) for k in top if amplitude[k] > metrics.NOISE_FLOOR_ARCSEC)
        return [(float(self.orders[k]), *(float(a) for a in self.spectrum[:, k])) for k in sorted(chosen)]


def compare_te(
    measured: MeasuredTE, design: RVDesign, errors: ErrorSet, load: float = 0.0, points: int | None = None
) -> Comparison:
    """The bench record `measured` beside the model of `design` with `errors` (one reducer)
    at the resisting `load` [N*m] the bench ran at; `points` per output revolution of the
    model's grid (default `default_points`, 8 per pin-passing period, as `rvte te`)."""
    if points is None:
        points = default_points(design)
    grid = model_grid(
        design,
        errors,
        load,
        points,
        measured.sense,
        (float(measured.theta_in.min()), float(measured.theta_in.max())),
    )
    raw = grid.at(measured.theta_in)[0]
    model = as_bench_sees(measured, raw)[0]
    curves = np.stack([measured.te_reducer_arcsec, model, measured.te_reducer_arcsec - model])
    even = even_in_output(measured, curves)
    bins, spectrum = metrics.order_spectrum(even)
    shift, best = _best_shift(even[0], even[1], measured.revolutions)
    return Comparison(
        measured=measured,
        design=design,
        load_Nm=float(load),
        points=int(points),
        periodic=grid.period is not None,
        converged=bool(grid.converged[0]),
        model_raw_arcsec=raw,
        model_arcsec=model,
        orders=bins / measured.revolutions,
        spectrum=spectrum,
        shift_deg=shift,
        shift_correlation=best,
    )


def _best_shift(a, b, revolutions):
    """(shift [deg of output], correlation): the circular delay of b that best matches a,
    both evenly sampled over `revolutions` output revolutions, in (-180, 180] x revolutions."""
    a, b = a - a.mean(), b - b.mean()
    norm = np.sqrt((a @ a) * (b @ b))
    if norm == 0:
        return 0.0, float("nan")
    # c[k] = sum_j a[j] b[j - k]: b delayed by k samples
    c = np.fft.irfft(np.fft.rfft(a) * np.conj(np.fft.rfft(b)), n=a.size) / norm
    k = int(np.argmax(c))
    if k > a.size // 2:
        k -= a.size
    return float(360.0 * revolutions * k / a.size), float(c[k])
