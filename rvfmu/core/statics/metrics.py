"""TE metrics of docs/model.md section 5: peak-to-peak, RMS, mean and the order spectrum.

Every function takes TE curves shaped (samples, angles) sampled evenly over
exactly one output revolution (the last point is not a repeat of the first),
so that the discrete Fourier transform gives amplitudes by order, in cycles
per output revolution.

Which orders are there: a computed TE carries every order up to Nyquist, most
of them round-off (about 1e-12 arcsec).  An order is significant only above
the curve's noise floor (`noise_floor`): the larger of NOISE_FLOOR_ARCSEC and
NOISE_FLOOR_RELATIVE times the curve's largest harmonic.  `significant_orders`
and `highest_significant_order` list and bound the orders that are there; a
curve with none has a flat TE.
"""

import numpy as np

# Noise floor of the order spectrum (amplitudes in arcsec).
# Absolute part: 1e-3 arcsec is below the count of the finest angle encoders
# (29 bits: 2.4e-3 arcsec per count; their accuracy is about +-1 arcsec) and below
# the last digit that the reports print (0.001").
NOISE_FLOOR_ARCSEC = 1e-3
# Relative part, x the curve's largest harmonic: the solver's coarsest deliberate
# approximation.  Its convergence is far finer: a Newton step of less than
# newton.STEP_TOLERANCE = 1e-14 m + 1e-12 |q| ends the iteration (~1e-8 arcsec at the pin
# circle), gaps are resolved to newton.GAP_TOLERANCE = 1e-12 m (~3e-6 arcsec), and the
# orders that are not there come out at ~1e-12 arcsec (round-off of the windup).  But
# every reduced unknown carries a spring of solver.REGULARISATION = 1e-6 x the softest
# element (solver.weak_stiffness), which moves every deflection, and so every harmonic and its products, by
# up to ~1e-6 of the TE variation: an order smaller than 1e-6 x the largest one cannot
# be told from that.  The larger of the two floors is used.
NOISE_FLOOR_RELATIVE = 1e-6


def te_pp(te):
    """Peak-to-peak over the revolution, (samples,), in the unit of `te`."""
    te = np.atleast_2d(te)
    return te.max(axis=-1) - te.min(axis=-1)


def te_mean(te):
    return np.atleast_2d(te).mean(axis=-1)


def te_rms(te):
    """RMS about the mean, (samples,)."""
    te = np.atleast_2d(te)
    return np.sqrt(np.mean((te - te.mean(axis=-1, keepdims=True)) ** 2, axis=-1))


def order_spectrum(te):
    """Single-sided amplitude by order: (orders (K,), amplitudes (samples, K)).

    Order k is k cycles per output revolution; amplitude is that of the sine
    (half the peak-to-peak of the harmonic).  Order 0 is the mean.
    """
    te = np.atleast_2d(te)
    n = te.shape[-1]
    spectrum = np.fft.rfft(te, axis=-1) / n
    amplitude = np.abs(spectrum)
    amplitude[..., 1:] *= 2.0
    if n % 2 == 0:
        amplitude[..., -1] /= 2.0  # Nyquist bin is not doubled
    return np.arange(amplitude.shape[-1]), amplitude


def largest_orders(te, count=5):
    """The `count` largest harmonics (order >= 1) of each curve: (orders, amplitudes), (samples, count).

    Always `count` of them, however small: on a flat TE they are round-off.  To
    report or plot the orders that are there, use `significant_orders`.
    """
    orders, amplitude = order_spectrum(te)
    top = np.argsort(amplitude[..., 1:], axis=-1)[..., ::-1][..., :count] + 1
    return orders[top], np.take_along_axis(amplitude, top, axis=-1)


def amplitude_at_order(te, order):
    """Amplitude of one order, (samples,)."""
    orders, amplitude = order_spectrum(te)
    if not 0 <= order < orders.size:
        raise ValueError(
            f"order {order} is beyond the Nyquist order {orders.size - 1} "
            f"of {np.atleast_2d(te).shape[-1]} points per revolution"
        )
    return amplitude[..., order]


def noise_floor(te_arcsec):
    """(samples,) amplitude [arcsec] at or below which an order of each curve is noise.

    max(NOISE_FLOOR_ARCSEC, NOISE_FLOOR_RELATIVE x the curve's largest harmonic
    (order >= 1)); te_arcsec: (samples, angles) or (angles,) in arcsec.
    """
    return _floor(order_spectrum(te_arcsec)[1])


def _floor(amplitude):
    """(samples,) noise floor of amplitudes (samples, K) by order [arcsec]."""
    largest = np.max(amplitude[..., 1:], axis=-1, initial=0.0)
    return np.maximum(NOISE_FLOOR_ARCSEC, NOISE_FLOOR_RELATIVE * largest)


def significant_spectrum(te_arcsec):
    """(orders (K,), amplitudes (samples, K) [arcsec], significant (samples, K) bool).

    significant: order >= 1 with an amplitude above the curve's `noise_floor`
    (order 0, the mean, is never an order of the ripple).
    """
    orders, amplitude = order_spectrum(te_arcsec)
    significant = amplitude > _floor(amplitude)[..., None]
    significant[..., 0] = False
    return orders, amplitude, significant


def significant_orders(te_arcsec, count=5):
    """Up to `count` largest orders (>= 1) of each curve above its noise floor.

    Returns (orders, amplitudes): two lists with one array per curve (samples),
    int orders and amplitudes [arcsec], largest first (ties: lower order first),
    each of length <= count; an empty array means a flat TE (no order above
    the floor).  te_arcsec: (samples, angles) or (angles,) in arcsec.
    """
    orders, amplitude, significant = significant_spectrum(te_arcsec)
    out_orders, out_amplitudes = [], []
    for amp, keep in zip(amplitude, significant):
        there = np.flatnonzero(keep)
        top = there[np.argsort(-amp[there], kind="stable")][:count]
        out_orders.append(orders[top])
        out_amplitudes.append(amp[top])
    return out_orders, out_amplitudes


def highest_significant_order(te_arcsec):
    """(samples,) int: the highest order above each curve's noise floor, 0 for a flat TE."""
    orders, _, significant = significant_spectrum(te_arcsec)
    return np.max(np.where(significant, orders, 0), axis=-1)
