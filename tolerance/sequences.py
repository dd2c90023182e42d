"""Per-tooth error sequences that realise gear tolerances.

Pitch errors of ground teeth are not independent per tooth: the cumulative
pitch deviation along the circumference is dominated by low orders (runout of
the grinding set-up, once and twice per revolution) with a small tooth-to-tooth
scatter on top.  A sequence is drawn in that form and then scaled so that its
total cumulative pitch deviation (ISO 1328-1 F_p, the span of the cumulative
sequence) equals the tolerance exactly, which is what "a reducer made to that
tolerance" means when a table gives a single value.
"""

import numpy as np

LOW_ORDER_SHARE = 0.8   # of the cumulative deviation's amplitude carried by orders 1-3


def cumulative_pitch_sequence(rng: np.random.Generator, teeth: int, total_um: float,
                              samples: int = 1) -> np.ndarray:
    """Cumulative pitch deviations (samples, teeth) [um] whose span is exactly `total_um`.

    Orders 1-3 with random phases and amplitudes falling as 1/order, plus
    independent tooth-to-tooth scatter; periodic over the circumference.
    """
    k = np.arange(teeth) * 2.0 * np.pi / teeth
    orders = np.arange(1, 4)
    phase = rng.uniform(0.0, 2.0 * np.pi, (samples, orders.size))
    weight = rng.uniform(0.5, 1.0, (samples, orders.size)) / orders
    low = np.einsum("so,sok->sk", weight, np.cos(orders[None, :, None] * k + phase[..., None]))
    low /= np.ptp(low, axis=1, keepdims=True)
    scatter = rng.standard_normal((samples, teeth))
    scatter /= np.ptp(scatter, axis=1, keepdims=True)
    sequence = LOW_ORDER_SHARE * low + (1.0 - LOW_ORDER_SHARE) * scatter
    sequence -= sequence[:, :1]  # tooth 0 is the reference of a cumulative pitch measurement
    return total_um * sequence / np.ptp(sequence, axis=1, keepdims=True)


def profile_sequence(rng: np.random.Generator, teeth: int, total_um: float,
                     samples: int = 1) -> np.ndarray:
    """Per-tooth normal profile deviations (samples, teeth) [um], uniform in +-total/2."""
    return rng.uniform(-0.5 * total_um, 0.5 * total_um, (samples, teeth))
