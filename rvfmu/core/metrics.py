"""TE metrics of MODEL.md section 5: peak-to-peak, RMS, mean and the order spectrum.

Every function takes TE curves shaped (samples, angles) sampled evenly over
exactly one output revolution (the last point is not a repeat of the first),
so that the discrete Fourier transform gives amplitudes by order, in cycles
per output revolution.
"""

import numpy as np


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
    """The `count` largest harmonics (order >= 1) of each curve: (orders, amplitudes), (samples, count)."""
    orders, amplitude = order_spectrum(te)
    top = np.argsort(amplitude[..., 1:], axis=-1)[..., ::-1][..., :count] + 1
    return orders[top], np.take_along_axis(amplitude, top, axis=-1)


def amplitude_at_order(te, order):
    """Amplitude of one order, (samples,)."""
    orders, amplitude = order_spectrum(te)
    if not 0 <= order < orders.size:
        raise ValueError(f"order {order} is beyond the Nyquist order {orders.size - 1} "
                         f"of {np.atleast_2d(te).shape[-1]} points per revolution")
    return amplitude[..., order]
