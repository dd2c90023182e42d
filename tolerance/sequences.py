"""Per-tooth error sequences that realise gear tolerances (ISO 1328-1).

Pitch errors of ground teeth are not independent per tooth: the cumulative
pitch deviation along the circumference is dominated by low orders (runout of
the grinding set-up, once to three times per revolution) with a small
tooth-to-tooth scatter on top.  A sequence is built in that form, then scaled
so that its total cumulative pitch deviation (F_p, the span of the cumulative
sequence) is what was asked, and scaled down further if needed so that no
single pitch deviation (f_pt, the difference of neighbouring cumulative values,
the last tooth to the first included) exceeds its tolerance.  Both limits then
hold exactly, which is what "a part made to F_p and f_pt" means.

`cumulative_pitch_sequence` draws the shape from a numpy Generator (used once
by studies/make_seed002_errors.py); `cumulative_pitch_from_draws` builds the
same shape from given draws, which is how a tolerance study makes every row of
its sample matrix reproducible (tolerance/sampling.py).
"""

import numpy as np

LOW_ORDER_SHARE = 0.8  # of the cumulative deviation's span carried by orders 1-3
LOW_ORDERS = 3  # grinding set-up runout: once to three times per revolution
LOW_WEIGHT_MIN = 0.5  # order amplitudes are uniform in [0.5, 1] / order


def cumulative_pitch_shape(phase: np.ndarray, weight: np.ndarray, scatter: np.ndarray) -> np.ndarray:
    """Cumulative pitch sequences of unit span, tooth 0 at 0: (samples, teeth) [-].

    phase (samples, LOW_ORDERS) [rad] and weight (samples, LOW_ORDERS) [-] of the
    low orders 1..LOW_ORDERS; scatter (samples, teeth) [-], the tooth-to-tooth
    part before normalisation.  Periodic over the circumference.
    """
    teeth = scatter.shape[-1]
    k = np.arange(teeth) * 2.0 * np.pi / teeth
    orders = np.arange(1, LOW_ORDERS + 1)
    low = np.einsum("so,sok->sk", weight, np.cos(orders[None, :, None] * k + phase[..., None]))
    low = low / _span(low)
    scatter = scatter / _span(scatter)
    sequence = LOW_ORDER_SHARE * low + (1.0 - LOW_ORDER_SHARE) * scatter
    sequence = sequence - sequence[:, :1]  # tooth 0 is the reference of a cumulative pitch measurement
    return sequence / _span(sequence)


def single_pitch_deviations(cumulative: np.ndarray) -> np.ndarray:
    """Single pitch deviations f_pt,k = F_p,k - F_p,k-1 (cyclic), same shape and unit as `cumulative`."""
    return cumulative - np.roll(cumulative, 1, axis=-1)


def limit_single_pitch(cumulative: np.ndarray, single_um) -> np.ndarray:
    """Scale each sequence (samples, teeth) [um] down, if needed, so that |f_pt,k| <= single_um.

    single_um: scalar or (samples,) [um].  Scaling keeps the shape and can only
    reduce the span, so an F_p limit that held before still holds.
    """
    largest = np.abs(single_pitch_deviations(cumulative)).max(axis=-1)
    limit = np.broadcast_to(np.asarray(single_um, dtype=float), largest.shape)
    factor = np.ones_like(largest)
    over = largest > limit
    factor[over] = limit[over] / largest[over]
    return cumulative * factor[:, None]


def cumulative_pitch_from_draws(span_um, phase, weight, scatter, single_um=None) -> np.ndarray:
    """Cumulative pitch deviations (samples, teeth) [um] from given draws.

    span_um (samples,) [um]: the total cumulative pitch deviation F_p wanted;
    phase, weight, scatter: see `cumulative_pitch_shape`; single_um: the single
    pitch tolerance f_pt [um] (None: no limit beyond F_p).
    """
    sequence = np.asarray(span_um, dtype=float)[:, None] * cumulative_pitch_shape(phase, weight, scatter)
    return sequence if single_um is None else limit_single_pitch(sequence, single_um)


def cumulative_pitch_sequence(
    rng: np.random.Generator, teeth: int, total_um: float, samples: int = 1
) -> np.ndarray:
    """Cumulative pitch deviations (samples, teeth) [um] whose span is exactly `total_um`.

    Orders 1-3 with random phases and amplitudes falling as 1/order, plus
    independent tooth-to-tooth scatter; periodic over the circumference.
    """
    orders = np.arange(1, LOW_ORDERS + 1)
    phase = rng.uniform(0.0, 2.0 * np.pi, (samples, orders.size))
    weight = rng.uniform(LOW_WEIGHT_MIN, 1.0, (samples, orders.size)) / orders
    scatter = rng.standard_normal((samples, teeth))
    return cumulative_pitch_from_draws(np.full(samples, float(total_um)), phase, weight, scatter)


def profile_sequence(rng: np.random.Generator, teeth: int, total_um: float, samples: int = 1) -> np.ndarray:
    """Per-tooth normal profile deviations (samples, teeth) [um], uniform in +-total/2."""
    return rng.uniform(-0.5 * total_um, 0.5 * total_um, (samples, teeth))


def _span(values: np.ndarray) -> np.ndarray:
    """Span per row (samples, 1); a constant row keeps span 1 so that it stays constant, not NaN."""
    span = np.ptp(values, axis=-1, keepdims=True)
    return np.where(span > 0.0, span, 1.0)
