"""Transmission error measured on a bench with an input and an output encoder.

The question: what is the reducer's own TE, given the readings of the two
encoders of a bench run?  TE is docs/model.md section 5's
`theta_out - theta_in / i` in arcsec, whichever way the bench turns: the same
geometric error gives the same TE against the input angle in both senses (in
the negative sense a positive TE is an output that lags in the direction of
travel).  How it is computed, and why so:

- Encoders roll over at one revolution (an absolute encoder counts 0..N-1), so
  every angle is unwrapped: a step of more than half a revolution between two
  rows is a roll-over.  Rows must therefore be closer than half a revolution of
  either shaft, and the input must turn one way through the record, which also
  catches rows too far apart to unwrap.
- The encoders' zeros are arbitrary: the TE's mean over the record (a constant
  offset) is removed and reported.
- TE is taken over whole output revolutions only: te_pp and the order spectrum
  are defined over them (docs/model.md section 5), and the cos/sin columns of a
  once-per-revolution runout are orthogonal to the reducer's other orders only
  over whole revolutions (over part of one, the fit would take the reducer's TE
  with it).  The rows after the last whole revolution are left out and counted.
- A stated ratio far from the data's is a mistake (a wrong preset, a wrong
  counts per revolution), not a TE: it is refused, not turned into a TE ramp.
- The bench adds low orders of its own: an encoder mounted off-centre, or a
  coupling that bends, reads a once-per-revolution error of its shaft
  (seed 004 removes them: 46.31" measured, 23.15" for the reducer).  They are
  fitted by linear least squares on cos/sin columns of the output angle
  (orders in cycles per output revolution) and of the input angle (cycles per
  input revolution) and removed, each reported as A*cos(k*theta - phase).  The
  reducer's own content at those orders goes with them, which is why an order
  can be kept.
- The spectrum: the TE is resampled evenly in the nominal output angle
  theta_in / i (TE is a function of theta_in) over the whole revolutions; the
  FFT of n revolutions gives orders k / n.  With a time column it is also
  resampled evenly in time, for the spectrum in Hz: a vibration of the bench is
  a sharp line in Hz, a geometric error of the reducer a sharp line in order.

Everything here is arrays in, a record out: no files, no CLI, no plots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.base.checks import InputError, integer, positive
from ..core.base.units import ARCSEC, DEG
from ..core.statics import metrics

UNITS = ("deg", "rad", "counts")

# Issue 11: a stated ratio more than 1 % off the least-squares slope of theta_in against
# theta_out is an input mistake.  A TE can never move the slope that far: a 100" ripple
# moves it by ~1e-4.
RATIO_TOLERANCE = 0.01

# Below RATIO_TOLERANCE, but a ratio off by 1e-4 already adds a TE ramp of
# 1e-4 x 1 296 000" = 130" per output revolution, more than a reducer's whole te_pp;
# the record then carries a warning.  A TE of 50" moves the slope by ~1e-5 only.
RATIO_WARNING = 1e-4

REVOLUTION = 2.0 * np.pi


@dataclass(frozen=True)
class RunoutComponent:
    """One removed bench component, amplitude_arcsec * cos(order * theta - phase_deg) of TE,
    theta the angle of `shaft` ("output": cycles per output revolution, "input": per input
    revolution) as its encoder reads it."""

    shaft: str
    order: int
    amplitude_arcsec: float
    phase_deg: float


@dataclass(frozen=True)
class MeasuredTE:
    """TE of a bench record over its whole output revolutions.

    Rows are those of the whole revolutions (`rows` of them, the first labelled
    `first_row`); per-row arrays are (rows,): theta_in, theta_out [rad] unwrapped, in
    the encoders' frames; time [s] or None; te_arcsec the measured TE with its offset
    removed; runout_arcsec the removed components; te_reducer_arcsec = te_arcsec minus
    them (and the fit's constant).  Curves stacked as (2, ...) are [measured, reducer].
    orders (K,) in cycles per output revolution with spectrum (2, K) [arcsec];
    hz (K,) with spectrum_hz (2, K) [arcsec] when there is a time column, else None.
    """

    ratio: float
    measured_ratio: float
    first_row: int
    rows_total: int
    rows_after: int
    rollovers: tuple[int, int]
    sense: int
    revolutions: int
    points_per_revolution: int
    theta_in: np.ndarray
    theta_out: np.ndarray
    time: np.ndarray | None
    te_arcsec: np.ndarray
    runout_arcsec: np.ndarray
    te_reducer_arcsec: np.ndarray
    offset_arcsec: float
    components: tuple[RunoutComponent, ...]
    te_pp_by_revolution_arcsec: np.ndarray
    orders: np.ndarray
    spectrum: np.ndarray
    hz: np.ndarray | None
    spectrum_hz: np.ndarray | None
    output_speed_hz: float | None
    warnings: tuple[str, ...] = ()

    @property
    def rows(self) -> int:
        return self.te_arcsec.size

    @property
    def curves(self) -> np.ndarray:
        """(2, rows) [arcsec]: the measured TE and the reducer's, offset removed."""
        return np.stack([self.te_arcsec, self.te_reducer_arcsec])

    @property
    def te_pp_arcsec(self) -> np.ndarray:
        """(2,) peak-to-peak over the whole revolutions: [measured, reducer]."""
        return metrics.te_pp(self.curves)

    @property
    def te_rms_arcsec(self) -> np.ndarray:
        """(2,) RMS about the mean: [measured, reducer]."""
        return metrics.te_rms(self.curves)

    @property
    def output_angle(self) -> np.ndarray:
        """(rows,) nominal output angle turned since the first row, theta_in / i [rad], >= 0."""
        return self.sense * (self.theta_in - self.theta_in[0]) / self.ratio

    def largest_orders(self, count: int = 5):
        """[(order, amplitude)] * 2: the `count` largest lines (order > 0) of each curve."""
        return _largest(self.orders, self.spectrum, count)

    def largest_lines_hz(self, count: int = 5):
        """As `largest_orders`, in Hz; None without a time column."""
        return None if self.hz is None else _largest(self.hz, self.spectrum_hz, count)


def _largest(axis, amplitude, count):
    out = []
    for amp in amplitude:
        top = np.argsort(-amp[1:], kind="stable")[:count] + 1
        out.append([(float(axis[k]), float(amp[k])) for k in top])
    return out


def angle_rad(name: str, values, unit: str, counts_per_rev: float | None = None) -> np.ndarray:
    """Encoder readings `values` (rows,) in `unit` (deg, rad or counts, with counts_per_rev)
    as radians (rows,), not yet unwrapped."""
    values = np.asarray(values, dtype=float)
    if unit == "deg":
        return values * DEG
    if unit == "rad":
        return values.copy()
    if unit == "counts":
        if counts_per_rev is None:
            raise InputError(
                "counts_per_rev",
                None,
                f"column {name} is in counts: give the encoder's counts per revolution",
            )
        return values * (REVOLUTION / positive("counts_per_rev", counts_per_rev))
    raise InputError("units", unit, "must be one of " + ", ".join(UNITS))


def unwrap(angle_rad: np.ndarray) -> tuple[np.ndarray, int]:
    """(unwrapped angle (rows,) [rad], number of roll-overs): a step of more than half a
    revolution between rows is taken as a roll-over."""
    steps = np.diff(angle_rad)
    return np.unwrap(angle_rad, period=REVOLUTION), int(np.count_nonzero(np.abs(steps) > np.pi))


def check_rows(columns: dict, first_row: int = 1, time_name: str | None = None) -> int:
    """The number of rows of the columns {name: (rows,)} (None: absent), or an InputError
    naming the column and row: unequal lengths, a row that is not finite, a time (the
    column time_name) that does not increase.  Row i is labelled first_row + i."""
    given = {name: np.asarray(v, dtype=float) for name, v in columns.items() if v is not None}
    lengths = {name: v.size for name, v in given.items()}
    longest = max(lengths, key=lengths.get)
    for name, n in lengths.items():
        if n != lengths[longest]:
            raise InputError(
                name,
                f"{n} rows",
                f"ends after row {first_row + n - 1}, "
                f"{longest} after row {first_row + lengths[longest] - 1}: every "
                "column needs a value on every row",
            )
    for name, v in given.items():
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            listed = ", ".join(str(first_row + k) for k in bad[:5]) + (", ..." if bad.size > 5 else "")
            raise InputError(
                name,
                float(v[bad[0]]),
                f"row {first_row + bad[0]} is not a finite "
                f"number (rows of this column that are not: {listed}); no row is "
                "dropped silently: remove or fill them",
            )
    if time_name in given:
        v = given[time_name]
        back = np.flatnonzero(np.diff(v) <= 0.0)
        if back.size:
            k = back[0] + 1
            raise InputError(
                time_name,
                float(v[k]),
                f"row {first_row + k} is not later than row "
                f"{first_row + k - 1} ({v[k - 1]:g} s): time must increase from row "
                f"to row ({back.size} of {v.size - 1} steps do not)",
            )
    return lengths[longest]


def measure_te(
    theta_in_rad,
    theta_out_rad,
    ratio: float,
    time_s=None,
    remove_orders=(1,),
    remove_input_orders=(),
    keep_orders=(),
    names=("theta_in", "theta_out", "time_s"),
    first_row: int = 1,
    rollovers: tuple[int, int] = (0, 0),
) -> MeasuredTE:
    """TE of a bench record over its whole output revolutions, the bench's runout removed.

    theta_in_rad, theta_out_rad: (rows,) encoder angles [rad], unwrapped (`unwrap`);
    time_s: (rows,) [s] or None.  ratio: the stated ratio i.  remove_orders: orders of
    the output rotation fitted and removed (less keep_orders); remove_input_orders:
    orders of the input rotation.  names: the columns' names for messages, row i
    labelled first_row + i; rollovers: how many `unwrap` found, for the record.
    """
    ratio = positive("ratio", ratio)
    name_in, name_out, name_time = names
    check_rows({name_in: theta_in_rad, name_out: theta_out_rad, name_time: time_s}, first_row, name_time)
    theta_in = np.asarray(theta_in_rad, dtype=float)
    theta_out = np.asarray(theta_out_rad, dtype=float)
    time = None if time_s is None else np.asarray(time_s, dtype=float)
    n = theta_in.size
    if n < 3:
        raise InputError(name_in, f"{n} rows", "at least one whole output revolution of rows is needed")
    out_orders, in_orders = _orders(remove_orders, remove_input_orders, keep_orders, ratio)

    # The input turns one way: its sense, and np.interp below needs a monotonic abscissa.
    sense = 1 if theta_in[-1] > theta_in[0] else -1
    if theta_in[-1] == theta_in[0]:
        raise InputError(
            name_in,
            float(theta_in[0] / DEG),
            f"the input ends where it starts (rows {first_row} and {first_row + n - 1}): it must turn",
        )
    back = np.flatnonzero(sense * np.diff(theta_in) < 0.0)
    if back.size:
        k = back[0] + 1
        raise InputError(
            name_in,
            f"row {first_row + k}",
            f"the input turns back there by "
            f"{abs(theta_in[k] - theta_in[k - 1]) / DEG:.4g} deg after turning "
            f"{'positive' if sense > 0 else 'negative'} ({back.size} of {n - 1} "
            "steps do): it must turn one way through the record, and rows must be "
            "closer than half a revolution of either shaft for a roll-over to be told "
            "from a move",
        )
    turned_out = sense * (theta_out[-1] - theta_out[0])
    if turned_out <= 0.0:
        raise InputError(
            name_out,
            f"{sense * turned_out / DEG:.6g} deg",
            f"the output turns the "
            f"other way than the input ({sense * (theta_in[-1] - theta_in[0]) / DEG:.6g}"
            " deg): input and output turn the same way (docs/model.md section 2); "
            "negate one column if its encoder counts the other way",
        )
    phi = sense * (theta_in - theta_in[0]) / ratio  # nominal output angle turned [rad]
    # A record of n revolutions that ends a hair short of them (noise, a last row not quite
    # there) still has n: a shortfall of up to half a row's step is no missing sample.
    slack = 0.5 * phi[-1] / (n - 1)
    revolutions = int(np.floor((min(turned_out, phi[-1]) + slack) / REVOLUTION))
    if revolutions < 1:
        raise InputError(
            name_out,
            float(f"{turned_out / DEG:.6g}"),
            f"the output turns "
            f"{turned_out / DEG:.4g} deg over rows {first_row} to {first_row + n - 1}:"
            " at least one whole output revolution (360 deg) is needed, as te_pp, the "
            "order spectrum and the runout fit are defined over whole revolutions",
        )
    used = int(np.searchsorted(phi, revolutions * REVOLUTION + slack, side="right"))
    last = first_row + used - 1

    measured_ratio = _slope(theta_out[:used], theta_in[:used])
    off = measured_ratio / ratio - 1.0
    if abs(off) > RATIO_TOLERANCE:
        raise InputError(
            "ratio",
            ratio,
            f"the data show {measured_ratio:.6g} (least-squares slope "
            f"of {name_in} against {name_out}, rows {first_row} to {last}), "
            f"{100 * off:+.3g} % off; more than {100 * RATIO_TOLERANCE:g} % off is "
            "refused (it would be a TE ramp, not a TE): check the ratio, the units "
            "and the counts per revolution",
        )
    warnings = []
    if abs(off) > RATIO_WARNING:
        warnings.append(
            f"the stated ratio {ratio:g} is {100 * off:+.3g} % off the data's "
            f"{measured_ratio:.6g}: that adds a TE ramp of about "
            f"{abs(off) * REVOLUTION / ARCSEC:.3g}\u2033 per output revolution"
        )

    points = used // revolutions
    nyquist = points // 2
    for field, order, line in [("remove_orders", k, k) for k in out_orders] + [
        ("remove_input_orders", m, m * ratio) for m in in_orders
    ]:
        if line >= nyquist:
            raise InputError(
                field,
                order,
                f"is output order {line:g}, not below the Nyquist order "
                f"{nyquist} of the {points} rows per output revolution",
            )

    te_raw = (theta_out - theta_in / ratio) / ARCSEC
    offset = float(te_raw[:used].mean())
    te = te_raw - offset
    columns = [np.ones(n)]
    for k in out_orders:
        columns += [np.cos(k * theta_out), np.sin(k * theta_out)]
    for m in in_orders:
        columns += [np.cos(m * theta_in), np.sin(m * theta_in)]
    design = np.stack(columns, axis=1)  # (rows, 1 + 2 * components)
    coef = np.linalg.lstsq(design[:used], te[:used], rcond=None)[0]
    runout = design[:, 1:] @ coef[1:]
    reducer = te - coef[0] - runout
    components = tuple(
        RunoutComponent(shaft, order, float(np.hypot(a, b)), float(np.degrees(np.arctan2(b, a))))
        for (shaft, order), (a, b) in zip(
            [("output", k) for k in out_orders] + [("input", m) for m in in_orders], coef[1:].reshape(-1, 2)
        )
    )

    # Evenly over the whole revolutions (all rows bracket the last grid point).
    curves = np.stack([te, reducer])
    total = revolutions * points
    grid = revolutions * REVOLUTION * np.arange(total) / total
    bins, spectrum = metrics.order_spectrum(np.stack([np.interp(grid, phi, c) for c in curves]))
    orders = bins / revolutions
    hz = spectrum_hz = speed = None
    if time is not None:
        start, end = time[0], float(np.interp(revolutions * REVOLUTION, phi, time))
        at = start + (end - start) * np.arange(total) / total
        bins, spectrum_hz = metrics.order_spectrum(np.stack([np.interp(at, time, c) for c in curves]))
        hz = bins / (end - start)
        speed = revolutions / (end - start)

    # te_pp of each revolution: phi is sorted, so each revolution is a run of rows.
    rev = np.minimum((phi[:used] / REVOLUTION).astype(int), revolutions - 1)
    starts = np.searchsorted(rev, np.arange(revolutions))
    by_rev = np.maximum.reduceat(curves[:, :used], starts, axis=1) - np.minimum.reduceat(
        curves[:, :used], starts, axis=1
    )

    return MeasuredTE(
        ratio=ratio,
        measured_ratio=float(measured_ratio),
        first_row=first_row,
        rows_total=n,
        rows_after=n - used,
        rollovers=tuple(rollovers),
        sense=sense,
        revolutions=revolutions,
        points_per_revolution=points,
        theta_in=theta_in[:used],
        theta_out=theta_out[:used],
        time=None if time is None else time[:used],
        te_arcsec=te[:used],
        runout_arcsec=runout[:used],
        te_reducer_arcsec=reducer[:used],
        offset_arcsec=offset,
        components=components,
        te_pp_by_revolution_arcsec=by_rev,
        orders=orders,
        spectrum=spectrum,
        hz=hz,
        spectrum_hz=spectrum_hz,
        output_speed_hz=speed,
        warnings=tuple(warnings),
    )


def _slope(x, y) -> float:
    """Least-squares slope of y against x."""
    x = x - x.mean()
    return float(x @ (y - y.mean()) / (x @ x))


def _orders(remove_orders, remove_input_orders, keep_orders, ratio):
    """(output orders, input orders) to remove, checked: whole numbers >= 1, kept orders among
    the removed ones, and no input order on the same line as a removed output order."""
    out = [integer("remove_orders", k, 1) for k in remove_orders]
    inputs = sorted({integer("remove_input_orders", m, 1) for m in remove_input_orders})
    for k in keep_orders:
        if integer("keep_orders", k, 1) not in out:
            raise InputError(
                "keep_orders", k, f"keeps an order that is not removed (remove_orders = {sorted(set(out))})"
            )
    out = sorted(set(out) - {int(k) for k in keep_orders})
    for m in inputs:
        for k in out:
            if abs(m * ratio - k) < 0.5:
                raise InputError(
                    "remove_input_orders",
                    m,
                    f"input order {m} is output order "
                    f"{m * ratio:g} at ratio {ratio:g}, the same line as output order "
                    f"{k} in remove_orders: remove it once",
                )
    return tuple(out), tuple(inputs)
