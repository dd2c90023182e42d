"""TE metrics of docs/model.md section 5 on signals whose answers are known by hand."""

import numpy as np
import pytest

from rvfmu.core.statics.metrics import (
    amplitude_at_order,
    largest_orders,
    order_spectrum,
    te_mean,
    te_pp,
    te_rms,
)

N = 280  # points per revolution: a multiple of 4*7, so the sine of order 7 hits its peaks


def angles(n=N):
    """n points evenly over one revolution, the last not repeating the first."""
    return 2.0 * np.pi * np.arange(n) / n


def test_pure_sine_of_order_7():
    te = 3.0 * np.sin(7 * angles())
    orders, amplitude = order_spectrum(te)
    assert amplitude.shape == (1, N // 2 + 1)
    np.testing.assert_array_equal(orders, np.arange(N // 2 + 1))
    assert amplitude[0, 7] == pytest.approx(3.0, rel=1e-12)
    others = np.delete(amplitude[0], 7)
    assert np.max(others) < 1e-12
    assert amplitude_at_order(te, 7)[0] == pytest.approx(3.0, rel=1e-12)


def test_phase_does_not_change_the_amplitude():
    te = 3.0 * np.cos(7 * angles() + 0.9)
    assert amplitude_at_order(te, 7)[0] == pytest.approx(3.0, rel=1e-12)


def test_order_0_is_the_mean():
    te = 2.5 + 3.0 * np.sin(7 * angles())
    _, amplitude = order_spectrum(te)
    assert amplitude[0, 0] == pytest.approx(2.5, rel=1e-12)
    assert amplitude_at_order(te, 0)[0] == pytest.approx(2.5, rel=1e-12)
    assert te_mean(te)[0] == pytest.approx(2.5, rel=1e-12)
    negative = -1.5 + 0.0 * angles()
    assert te_mean(negative)[0] == pytest.approx(-1.5)
    assert amplitude_at_order(negative, 0)[0] == pytest.approx(1.5)  # an amplitude: |mean|


def test_nyquist_order_is_not_doubled():
    # 16 points: order 8 is the alternating sequence +2, -2, ...: its amplitude is 2.
    te = 2.0 * np.cos(8 * angles(16))
    np.testing.assert_allclose(te, 2.0 * (-1.0) ** np.arange(16), atol=1e-12)
    assert amplitude_at_order(te, 8)[0] == pytest.approx(2.0, rel=1e-12)


def test_te_pp_rms_mean_of_known_signals():
    te = 4.0 + 3.0 * np.sin(7 * angles())
    assert te_pp(te)[0] == pytest.approx(6.0, rel=1e-12)
    assert te_rms(te)[0] == pytest.approx(3.0 / np.sqrt(2.0), rel=1e-12)  # about the mean
    steps = np.array([0.0, 1.0, -2.0, 5.0])
    assert te_pp(steps)[0] == 7.0
    assert te_mean(steps)[0] == 1.0
    assert te_rms(steps)[0] == pytest.approx(np.sqrt((1 + 0 + 9 + 16) / 4))
    constant = np.full(N, 12.0)
    assert te_pp(constant)[0] == 0.0
    assert te_rms(constant)[0] == pytest.approx(0.0, abs=1e-12)


def test_metrics_are_per_sample():
    te = np.stack([3.0 * np.sin(7 * angles()), 1.0 + 0.5 * np.cos(2 * angles())])
    np.testing.assert_allclose(te_pp(te), [6.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(te_mean(te), [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(te_rms(te), [3.0 / np.sqrt(2), 0.5 / np.sqrt(2)], rtol=1e-12)
    np.testing.assert_allclose(amplitude_at_order(te, 7), [3.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(amplitude_at_order(te, 2), [0.0, 0.5], atol=1e-12)


def test_largest_orders_ranks_the_harmonics():
    theta = angles()
    te = (
        4.0
        + 3.0 * np.sin(7 * theta)
        + 1.5 * np.cos(2 * theta + 0.3)
        + 0.5 * np.sin(13 * theta)
        + 0.2 * np.cos(40 * theta)
    )
    orders, amplitudes = largest_orders(te, count=4)
    assert orders.shape == amplitudes.shape == (1, 4)
    np.testing.assert_array_equal(orders[0], [7, 2, 13, 40])  # the mean (order 0) left out
    np.testing.assert_allclose(amplitudes[0], [3.0, 1.5, 0.5, 0.2], rtol=1e-10)


def test_largest_orders_of_a_batch():
    theta = angles()
    te = np.stack([np.sin(3 * theta) + 2.0 * np.sin(5 * theta), 2.0 * np.sin(3 * theta) + np.sin(5 * theta)])
    orders, amplitudes = largest_orders(te, count=2)
    np.testing.assert_array_equal(orders, [[5, 3], [3, 5]])
    np.testing.assert_allclose(amplitudes, [[2.0, 1.0], [2.0, 1.0]], rtol=1e-10)


def test_amplitude_beyond_nyquist_raises():
    te = np.sin(3 * angles(16))  # Nyquist order 8
    assert amplitude_at_order(te, 8)[0] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="Nyquist order 8"):
        amplitude_at_order(te, 9)
    with pytest.raises(ValueError, match="16 points"):
        amplitude_at_order(te, 100)
    with pytest.raises(ValueError):
        amplitude_at_order(te, -1)


def test_aliasing_of_an_order_above_nyquist():
    # docs/model.md section 5: a curve sampled too coarsely aliases the ripple.  Order 13 on
    # 16 points shows up at order 16 - 13 = 3 with the same amplitude.
    te = 0.7 * np.sin(13 * angles(16))
    orders, amplitude = largest_orders(te, count=1)
    assert orders[0, 0] == 3
    assert amplitude[0, 0] == pytest.approx(0.7, rel=1e-12)
