"""The dynamic model's damping law (docs/model.md section 7): every mode carries the design's
ratio, and a free decay shows it."""

import math

import numpy as np
import pytest

from rvfmu.core.dynamics.dynamic import DynamicModel, Motion
from rvfmu.core.dynamics.modes import modes
from rvfmu.core.dynamics.newmark import NewmarkStepper
from rvfmu.core.dynamics.simulation import static_start


@pytest.mark.parametrize("zeta", [0.05, 0.02])
def test_the_modes_below_2_khz_carry_the_designs_ratio(rv40, seed002, zeta):
    m = modes(rv40.with_fields(damping_ratio=zeta), seed002, load=206.0)
    low = m.frequencies_hz < 2000.0
    assert np.count_nonzero(low) >= 4
    np.testing.assert_allclose(m.damping_ratios, zeta, rtol=1e-9)


def test_the_carrier_torsion_mode_decays_by_the_printed_ratio(rv40, seed002):
    """Released from its loaded equilibrium with the carrier-torsion mode's shape as velocity,
    input held, no friction: the logarithmic decrement of that mode's coordinate over its
    first ten periods gives the damping ratio `rvte modes` prints, within 5 %."""
    load = 206.0
    m = modes(rv40, seed002, load=load)
    k = max(range(m.frequencies_hz.size), key=lambda i: m.energy_shares(i)["carrier torsion"])
    assert m.energy_shares(k)["carrier torsion"] > 0.9
    hz, phi = m.frequencies_hz[k], m.shapes[:, k]
    model = DynamicModel(rv40, seed002, contact="linear", mesh="constant", friction=False)
    step = 1.0 / (200.0 * hz)
    count = int(12.0 / (hz * step))
    t = np.arange(count) * step
    model.prepare(Motion(t, np.zeros(count), np.zeros(count), np.zeros(count), -load))
    q0 = static_start(model, -load, 0.0)
    model.set_modal_damping(q0)
    stepper = NewmarkStepper.starting_at(model, q0, 1e-4 * phi / np.max(np.abs(phi)))
    q, v = np.empty((count, model.n)), np.empty((count, model.n))
    q[0] = q0
    stepper.advance(count - 1, q, v)
    coordinate = (q - q0) @ (m.mass * phi)  # phi^T M (q - q0)
    peaks = [
        i
        for i in range(1, count - 1)
        if coordinate[i] > coordinate[i - 1] and coordinate[i] >= coordinate[i + 1]
    ]
    assert len(peaks) >= 10
    decrement = math.log(coordinate[peaks[0]] / coordinate[peaks[9]]) / 9.0
    measured = decrement / math.sqrt(4.0 * math.pi**2 + decrement**2)
    assert measured == pytest.approx(m.damping_ratios[k], rel=0.05)
    assert (t[peaks[9]] - t[peaks[0]]) / 9.0 == pytest.approx(
        1.0 / (hz * math.sqrt(1.0 - m.damping_ratios[k] ** 2)), rel=0.01
    )
