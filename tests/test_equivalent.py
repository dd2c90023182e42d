"""The equivalent model's geometry against the kinematics of docs/model.md section 2, by hand."""

import numpy as np
import pytest
from conftest import hand_pin_geometry, perp, unit

from rvfmu.core.base.units import UM
from rvfmu.core.reducer.design import PRESET_NAMES, preset
from rvfmu.core.reducer.errors import zero_errors
from rvfmu.core.statics.equivalent import EquivalentModel, Pose


def hand_mechanism_mode(model):
    """Unknowns (A, n) for the carrier turning +1 rad with the input held, every part rigid."""
    d, pose = model.design, model.pose
    A = pose.theta_in.size
    q = np.zeros((A, model.n_dof))
    speed = 1.0 + d.z_s / d.z_pl  # crank turns relative to ground per carrier rad
    crank_dir = pose.theta_out[:, None] + 2 * np.pi * np.arange(d.n_c) / d.n_c
    for i in range(d.n_c):
        q[:, model.index[f"crank{i}_x"] : model.index[f"crank{i}_y"] + 1] = d.crank_circle_radius * perp(
            unit(crank_dir[:, i])
        )
        q[:, model.index[f"crank{i}_rot"]] = speed * model.scale
    for j in range(2):
        psi = pose.psi[:, j]
        q[:, model.index[f"disc{j}_x"] : model.index[f"disc{j}_y"] + 1] = d.e * speed * perp(unit(psi))
        q[:, model.index[f"disc{j}_rot"]] = model.scale
    q[:, model.index["carrier_rot"]] = model.scale
    return q


@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("flank", [1, -1])
def test_mechanism_mode_strains_nothing_but_the_pins(name, flank):
    design = preset(name)
    theta_in = np.linspace(0.0, 2 * np.pi * design.ratio, 13)
    model = EquivalentModel(design, theta_in, flank=flank)
    q = hand_mechanism_mode(model)
    np.testing.assert_allclose(np.einsum("amn,an->am", model.linear_rows, q), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("abxn,an->abx", model.bearing_rows, q), 0.0, atol=1e-12)
    pins = np.einsum("ajkx,ajx->ajk", model.pin_rows, q[:, model.pin_dofs])
    _, _, closing_rate_back = hand_pin_geometry(design, theta_in)
    np.testing.assert_allclose(pins, -closing_rate_back, atol=1e-12)


def test_nominal_pose_conventions():
    design = preset("RV-40E-121")
    pose = Pose.at(design, [0.0, 2 * np.pi * design.ratio])
    assert pose.theta_out[0] == 0.0 and pose.beta[0] == 0.0
    np.testing.assert_allclose(pose.psi[0], [0.0, np.pi])
    # one output revolution: the carrier turns once, the cranks z_p times in the carrier
    np.testing.assert_allclose(pose.theta_out[1], 2 * np.pi)
    np.testing.assert_allclose(pose.beta[1], -2 * np.pi * design.z_p)


def test_pin_zero_sits_in_valley_zero_at_start():
    """At theta_in = 0 pin 0 is fully engaged in valley 0 of disc 0: radial normal, no gap."""
    design = preset("RV-40E-121").with_fields(d_rp=0.0, d_rrp=0.0)
    model = EquivalentModel(design, [0.0])
    normal = model.pin_rows[0, 0, 0, :2]
    np.testing.assert_allclose(normal, [1.0, 0.0], atol=1e-12)
    _, _, pins = model.offsets(zero_errors(design), np.array([0]), np.array([0]))
    np.testing.assert_allclose(pins, 0.0, atol=1e-15)
    assert model._lobe[0, 0, 0] in (0, design.z_c - 1)


def test_error_offsets_are_affine_and_follow_their_frames():
    design = preset("RV-40E-121")
    theta_in = np.array([0.0, 1.0, 2.0])
    model = EquivalentModel(design, theta_in)
    errors = zero_errors(design, 3)
    errors.pin_radial[1, 0] = 2 * UM
    errors.carrier_assembly[2] = 3 * UM * np.exp(0.5j)
    s, a = np.array([0, 1, 2]), np.array([0, 0, 1])
    lin, brg, pins = model.offsets(errors, s, a)
    # an outward pin moves away from the disc: pin 0 at theta_in = 0 (radial normal) opens by 2 um
    np.testing.assert_allclose(pins[1, 0, 0] - pins[0, 0, 0], -2 * UM, atol=1e-15)
    # the carrier assembly error is a fixed-frame offset of the main bearing, any pose
    np.testing.assert_allclose(brg[2, -1], -3 * UM * np.array([np.cos(0.5), np.sin(0.5)]), atol=1e-15)
    assert np.all(lin[:2] == 0)


def test_compiled_pin_offsets_are_the_numpy_ones_to_the_bit():
    """`pin_offsets` repeats the numpy route's arithmetic pair by pair: every error that moves a
    pin's offset (pin radius, radial and pitch errors, the discs' lobe profile and pitch) drawn
    at once, for random pairs and for a whole grid of angles (a slice)."""
    from rvfmu.core.base.compiled import COMPILED

    if not COMPILED:
        pytest.skip("numba absent: the numpy route is the only one")
    design = preset("RV-40E-121")
    theta_in = np.linspace(0.0, 2 * np.pi * design.ratio, 97, endpoint=False)
    model = EquivalentModel(design, theta_in)
    rng = np.random.default_rng(45)
    errors = zero_errors(design, 5)
    for name in ("pin_radius", "pin_radial", "pin_pitch", "disc_profile", "disc_pitch"):
        values = getattr(errors, name)
        values[...] = rng.normal(0.0, 3 * UM, values.shape)
    sample, angle = rng.integers(0, 5, 700), rng.integers(0, theta_in.size, 700)
    for s, a in ((sample, angle), (np.full(theta_in.size, 3), slice(None))):
        assert model.compiled_pins
        compiled = model.offsets(errors, s, a)
        model.compiled_pins = False
        try:
            plain = model.offsets(errors, s, a)
        finally:
            model.compiled_pins = True
        for x, y in zip(compiled, plain):
            assert x.shape == y.shape and np.array_equal(x, y)
        assert np.abs(compiled[2]).max() > 1 * UM  # the errors moved the pins
