"""Natural frequencies of the dynamic model: a hand-built torsional model, orthonormality,
energy shares and the Campbell excitation lines."""

import math
import re
from unittest import mock

import numpy as np
import pytest

from rvfmu.core.base.checks import InputError
from rvfmu.core.dynamics.dynamic import INPUT_SHAFT_FACTOR, DynamicModel, ramp_motion
from rvfmu.core.dynamics.modes import MODES_NO_LOAD_PROBE, campbell, modes
from rvfmu.core.reducer import design as design_module
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import zero_errors

# Factor on every bearing, the sun support and the pins: "rigid" against the meshes.  Stage 2
# multiplies the mesh force by about r_b,planet / e (20 on the RV-40E-121) on its way to the cam
# bearings and pins, so they are felt at the mesh some 400 times softer than they are: at 1e4
# a heavy output still sees them at 1.8 %, at 1e6 at 2e-4.
STIFF = 1e6

LABEL = re.compile(r"^(sun|carrier|crank \d|disc [01]) (translation|torsion)$")


def stiff_mechanism(design, carrier_inertia_factor=1.0, stiff=STIFF):
    """Every bearing, the sun support and the pins `stiff` times stiffer: only the meshes and the
    input shaft stay soft.  That rigid limit is no reducer (rvfmu/core/reducer/design.py refuses
    stiffnesses beyond STIFFNESS_RANGE and STIFFNESS_SPREAD): those bounds are lifted while
    this verification's design is built."""
    with (
        mock.patch.object(design_module, "STIFFNESS_RANGE", (0.0, math.inf)),
        mock.patch.object(design_module, "STIFFNESS_SPREAD", math.inf),
    ):
        return design.with_fields(
            crank_carrier_bearing_stiffness=stiff * design.crank_carrier_bearing_stiffness,
            crank_disc_bearing_stiffness=stiff * design.crank_disc_bearing_stiffness,
            main_bearing_stiffness=stiff * design.main_bearing_stiffness,
            sun_support_stiffness=stiff * design.sun_support_stiffness,
            pin_disc_stiffness=stiff * design.pin_disc_stiffness,
            carrier_inertia=carrier_inertia_factor * design.carrier_inertia,
        )


def two_inertia_frequencies(d):
    """The two torsional frequencies [Hz] of the reducer with rigid pins, bearings and sun
    support, by hand from the kinematics of docs/model.md section 2 (not from the model's code).

    Rigid bearings and pins leave two coordinates: the sun's rotation phi_s and the
    carrier's rotation phi_o (the main bearing holds the carrier's centre, the crank
    bearings put each crank axis on the carrier, the pins let each disc only turn about
    its pitch point, and the cam bearings tie cranks to discs).  Along that mechanism,
    per radian of carrier rotation (section 2: beta = -z_p theta_out):
      - each crank's axis moves a (a = m (z_s + z_pl)/2, crank circle) tangentially and
        the crank with its planet turns by 1 + beta' = 1 - z_p = -z_c rad;
      - each disc turns by 1 rad and its centre moves on its eccentric circle,
        psi = -z_c theta_out: speed z_c e;
    so the kinetic energy is 1/2 J_o phi_o'^2 with
      J_o = J_carrier + n_c (m_crank a^2 + J_crank z_c^2) + 2 (J_disc + m_disc (z_c e)^2).
    Each mesh's compression along its line of action is
      r_b,s phi_s - cos(alpha) (a phi_o + r_pl phi_crank) = r_b,s (phi_s - i phi_o),
    since phi_crank = -z_c phi_o and r_s i = r_s + r_pl z_p = a + r_pl z_c.  Referred to
    the sun, phi_r = i phi_o and J_r = J_o / i^2: the n_c meshes make one torsional spring
    k_t = n_c k_mesh r_b,s^2 between the sun and J_r, and the input shaft a spring
    k_s = 10 k_t (docs/model.md section 7) from the sun to the motor, held still.
    The two-inertia chain  ground -k_s- J_sun -k_t- J_r  has
      det [[k_s + k_t - w^2 J_sun, -k_t], [-k_t, k_t - w^2 J_r]] = 0:
      J_sun J_r w^4 - ((k_s + k_t) J_r + k_t J_sun) w^2 + k_s k_t = 0.
    Returns ((f_low, f_high) [Hz], the lowest mode's kinetic energy shares of the sun,
    all crank and the carrier torsions, J_o, k_s, k_t).
    """
    i = d.ratio
    a = d.crank_circle_radius
    r_b = d.m * d.z_s / 2.0 * math.cos(d.pressure_angle)
    k_t = d.n_c * d.mesh_stiffness * r_b**2
    k_s = INPUT_SHAFT_FACTOR * k_t
    crank_torsion = d.n_c * d.crank_inertia * d.z_c**2
    J_o = (
        d.carrier_inertia
        + d.n_c * d.crank_mass * a**2
        + crank_torsion
        + 2 * (d.disc_inertia + d.disc_mass * (d.z_c * d.e) ** 2)
    )
    J_r, J_s = J_o / i**2, d.sun_inertia
    b = (k_s + k_t) * J_r + k_t * J_s
    root = math.sqrt(b * b - 4.0 * J_s * J_r * k_s * k_t)
    w2 = np.array([(b - root), (b + root)]) / (2.0 * J_s * J_r)
    # lowest mode's shape: phi_r / phi_s from the sun's row, (k_s + k_t - w^2 J_s) / k_t
    ratio = (k_s + k_t - w2[0] * J_s) / k_t
    kinetic_s, kinetic_r = J_s, J_r * ratio**2
    shares = {
        "sun torsion": kinetic_s / (kinetic_s + kinetic_r),
        "crank torsion": kinetic_r / (kinetic_s + kinetic_r) * crank_torsion / J_o,
        "carrier torsion": kinetic_r / (kinetic_s + kinetic_r) * d.carrier_inertia / J_o,
    }
    return np.sqrt(w2) / (2.0 * math.pi), shares, J_o, k_s, k_t


@pytest.mark.parametrize("carrier_inertia_factor", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("load", [412.0, 0.0])
def test_frequencies_match_a_hand_built_two_inertia_torsional_model_with_stiff_bearings(
    rv40, carrier_inertia_factor, load
):
    """rvte modes frequencies match a hand-built two-inertia torsional model in the limit of
    stiff bearings (derivation in `two_inertia_frequencies`).

    With pins, bearings and sun support 1e6 times stiffer, every other mode moves above
    100 kHz; the two torsional modes of the mechanism (the output side swinging
    on the meshes, the sun on the input shaft) must be the two lowest and agree with the
    hand model within 2 % (they agree to 2e-4 or better), and so must the kinetic energy
    shares of the lowest.  The carrier 1000 times lighter or heavier changes which inertia
    dominates the output side (the cranks, spinning z_c times faster than the carrier, or
    the carrier); a heavy carrier also checks a limit: the output side becomes one inertia
    on the meshes and the shaft in series.  The hand model uses design fields only (and
    the shaft factor 10 of docs/model.md section 7), never the model's matrices.
    """
    design = stiff_mechanism(rv40, carrier_inertia_factor)
    hand, shares, J_o, k_s, k_t = two_inertia_frequencies(design)
    result = modes(design, load=load)
    assert result.dropped == 0
    assert result.frequencies_hz[:2] == pytest.approx(hand, rel=0.02)
    assert result.frequencies_hz[2] > 10.0 * hand[1]  # no third mode near them
    got = result.energy_shares(0)
    crank = sum(v for k, v in got.items() if re.fullmatch(r"crank \d torsion", k))
    assert crank == pytest.approx(shares["crank torsion"], abs=0.02)
    assert got["carrier torsion"] == pytest.approx(shares["carrier torsion"], abs=0.02)
    assert got["sun torsion"] == pytest.approx(shares["sun torsion"], abs=0.02)
    if carrier_inertia_factor > 1.0:
        # heavy output: one inertia J_o on the shaft and meshes in series, referred to the output
        series = k_s * k_t / (k_s + k_t) * design.ratio**2
        assert result.frequencies_hz[0] == pytest.approx(math.sqrt(series / J_o) / (2.0 * math.pi), rel=0.02)


def test_the_gap_to_the_hand_model_closes_as_the_stiff_elements_stiffen(rv40):
    """The hand model is the limit, not a coincidence: with a heavy carrier (where the stiff
    elements matter most) the lowest frequency's gap shrinks as 1/stiffness, 100 times from
    1e4 to 1e6, and it lies below the hand value (finite springs in series soften)."""
    gaps = []
    for stiff in (1e4, 1e6):
        design = stiff_mechanism(rv40, 1e3, stiff)
        hand = two_inertia_frequencies(design)[0][0]
        gaps.append(modes(design, load=412.0).frequencies_hz[0] / hand - 1.0)
    assert gaps[0] < gaps[1] < 0.0
    assert 50.0 < gaps[0] / gaps[1] < 200.0


@pytest.mark.parametrize("load, theta_in", [(412.0, 0.0), (0.0, 0.0), (-206.0, 1.234)])
def test_frequencies_are_positive_and_sorted_and_the_shapes_mass_orthonormal(rv40, seed002, load, theta_in):
    result = modes(rv40, seed002, load=load, theta_in=theta_in)
    f = result.frequencies_hz
    n = len(result.names)
    assert result.shapes.shape == (n, f.size)
    assert f.size == n - result.dropped
    assert np.all(f > 0.0) and np.all(np.diff(f) >= 0.0)
    gram = result.shapes.T @ (result.mass[:, None] * result.shapes)
    assert np.max(np.abs(gram - np.eye(f.size))) < 1e-8


def test_every_mode_is_a_vibration_of_the_grounded_reducer(rv40):
    """The input shaft grounds the chain: without clearances no mode is dropped, and the
    lowest is the torsional one of the loaded reducer, a few hundred Hz."""
    result = modes(rv40, load=rv40.rated_torque)
    assert result.dropped == 0 and result.frequencies_hz.size == len(result.names) == 18
    assert 100.0 < result.frequencies_hz[0] < 2000.0


def test_dominant_shares_sum_to_one_with_the_part_labels(rv40, seed002):
    result = modes(rv40, seed002, load=rv40.rated_torque)
    groups = result.groups
    assert len(groups) == 2 * (1 + rv40.n_c + 2 + 1)  # sun, cranks, discs, carrier
    for k in range(result.frequencies_hz.size):
        everything = result.dominant(k, count=len(groups))
        assert sum(share for _, share in everything) == pytest.approx(1.0, abs=1e-12)
        assert all(LABEL.match(label) for label, _ in everything)
        top = result.dominant(k)
        assert len(top) == 2 and top[0][1] >= top[1][1] >= 0.0
        assert top == everything[:2]


def test_zero_load_is_the_resisting_probe(rv40):
    probe = MODES_NO_LOAD_PROBE * rv40.rated_torque
    zero, small = modes(rv40, load=0.0), modes(rv40, load=probe)
    assert zero.tau_load == pytest.approx(-probe)
    assert zero.frequencies_hz == pytest.approx(small.frequencies_hz, rel=1e-9)


def test_a_bearing_without_clearance_and_without_deflection_keeps_its_stiffness(rv40):
    """At q = 0 without errors no bearing deflects: the tangent must still hold every bearing
    (the same K as at a tiny deflection)."""
    model = DynamicModel(rv40, zero_errors(rv40), "linear", "constant")
    model.prepare(ramp_motion(np.array([0.0]), 0.0, 0.0))
    zero = np.zeros(model.n)
    _, K0, _ = model.forces(0, zero, zero)
    tiny = 1e-15 * np.random.default_rng(1).standard_normal(model.n)
    _, K1, _ = model.forces(0, tiny, zero)
    assert np.allclose(K0, K1, rtol=0.0, atol=1e-12 * np.abs(K1).max())


def test_campbell_lines_of_the_rv110e_at_1600_rpm():
    """docs/model.md section 7: RV-110E at 1600 rpm, crank 6.6 Hz, pin passing 258.4 Hz,
    stage-1 mesh 397.5 Hz."""
    design = preset("RV-110E")
    speeds, lines = campbell(design, None, 0.0, [0.0, 800.0, 1600.0])
    assert speeds.tolist() == [0.0, 800.0, 1600.0]
    assert lines["crank rotation"][2] == pytest.approx(6.6, abs=0.05)
    assert lines["pin passing"][2] == pytest.approx(258.4, abs=0.1)
    assert lines["stage-1 mesh"][2] == pytest.approx(397.5, abs=0.1)
    assert lines["input rotation"][2] == pytest.approx(1600.0 / 60.0)
    for values in lines.values():  # straight lines through 0
        assert values[0] == 0.0 and values[2] == pytest.approx(2.0 * values[1])


def test_bad_input_is_refused(rv40):
    with pytest.raises(InputError, match="load"):
        modes(rv40, load=10.0 * rv40.rated_torque)
    with pytest.raises(InputError, match="theta_in"):
        modes(rv40, theta_in=float("nan"))
    with pytest.raises(InputError, match="speeds_rpm"):
        campbell(rv40, None, 0.0, [100.0, -1.0])
