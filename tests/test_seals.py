"""The lip seals (rvfmu/core/laws/seals.py, docs/model.md section 9): SKF's seal frictional moment
against its closed form, the presets' seals, the law switched off to the bit, breakaway."""

import dataclasses

import numpy as np
import pytest

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import MM, RPM
from rvfmu.core.laws import seals
from rvfmu.core.losses import friction
from rvfmu.core.reducer.design import PRESET_NAMES, design_from_file_values, preset, preset_file

POINTS = 6  # angles over a crank turn: the losses' mean, enough for these comparisons


def test_the_law_is_skfs_closed_form_at_hand_worked_points():
    # LS row (beta 2, K_S1 0.032, K_S2 50) on a 118.1 mm counterface:
    #   118.1^2 = 13947.61; x 0.032 = 446.32352; + 50 = 496.32352 N*mm = 0.49632352 N*m
    assert seals.lip_seal_torque(118.1 * MM, 2.0, 0.032, 50.0) == pytest.approx(0.49632352, rel=1e-12)
    # RS1 deep groove ball row, D <= 62 (beta 2.25, K_S1 0.023, K_S2 2) on 14 mm:
    #   14^0.25 = sqrt(3.7416574) = 1.9343364; 14^2.25 = 196 x 1.9343364 = 379.12994;
    #   x 0.023 = 8.7199886; + 2 = 10.7199886 N*mm
    beta, k1, k2 = seals.SKF_SEAL_ROWS["RS1, deep groove ball, D <= 62"]
    assert seals.lip_seal_torque(14.0 * MM, beta, k1, k2) == pytest.approx(0.0107199886, rel=1e-7)
    # no counterface, no seal: not K_S2
    np.testing.assert_allclose(
        seals.lip_seal_torque(np.array([0.0, 14.0 * MM]), 2.0, 0.032, 50.0),
        [0.0, 0.056272],
        rtol=1e-12,
        atol=0,
    )
    assert seals.SKF_SEAL_ROWS[seals.DEFAULT_SEAL_ROW] == (2.0, 0.032, 50.0)
    assert seals.STATIC_FRICTION_FACTOR == pytest.approx(1.25, rel=1e-15)


def test_a_stated_seal_torque_overrides_the_output_seals_law():
    d = preset("RV-40E-121")
    law = seals.seal_torques(d)
    assert law["output seal"] == pytest.approx(0.49632352, rel=1e-12)  # 118.1 mm, LS row
    assert law["input seal"] == pytest.approx((0.032 * 14.0**2 + 50.0) * 1e-3, rel=1e-12)
    stated = seals.seal_torques(d.with_fields(seal_torque=2.5))
    assert stated == {"output seal": 2.5, "input seal": law["input seal"]}
    free = friction.load_free_torques(d.with_fields(seal_torque=2.5), [5.0, 60.0])
    np.testing.assert_array_equal(free["output seal"], [2.5, 2.5])
    # the input seal turns at i x the output's speed: at the output it is i x its torque
    np.testing.assert_array_equal(free["input seal"], [d.ratio * law["input seal"]] * 2)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_every_preset_has_both_seals_by_the_one_rule(name):
    values = preset_file(name)
    rule = seals.seal_diameters_from_sources(values)
    d = preset(name)
    assert d.output_seal_diameter == pytest.approx(rule["output_seal_diameter_mm"] * MM, rel=1e-12)
    assert d.input_seal_diameter == pytest.approx(rule["input_seal_diameter_mm"] * MM, rel=1e-12)
    torques = seals.seal_torques(d)
    assert torques["output seal"] > 0.3 and torques["input seal"] > 0.05  # N*m; K_S2 alone 0.05
    assert {"output seal", "input seal"} <= set(friction.LOSS_NAMES)


@pytest.fixture(scope="module")
def rv40_loads():
    design = preset("RV-40E-121")
    loads = friction.contact_loads(
        design, None, [0.0, -41.2, -412.0], friction.crank_turn_angles(design, POINTS)
    )
    back = friction.contact_loads(design, None, [41.2, 412.0], friction.crank_turn_angles(design, POINTS))
    return design, loads, back


def _maps_equal(a, b):
    for field in dataclasses.fields(friction.EfficiencyMap):
        if field.name == "design":
            continue
        x, y = getattr(a, field.name), getattr(b, field.name)
        if isinstance(x, dict):
            assert x.keys() == y.keys()
            for name in x:
                assert np.array_equal(x[name], y[name]), (field.name, name)
        else:
            assert np.array_equal(x, y), field.name


def test_the_seal_law_off_gives_the_results_without_seals_to_the_bit(rv40_loads):
    """Switched off by the diameters or by zero constants, and breakaway at 1: the same map,
    every figure, to the bit; the seals lose exactly nothing; and the map is the power
    balance of the other contacts alone, computed here from them."""
    design, loads, back = rv40_loads
    speeds, torques = [5.0, 15.0, 60.0], [41.2, 412.0]
    off = design.with_fields(output_seal_diameter=0.0, input_seal_diameter=0.0, static_friction_factor=1.0)
    zero = design.with_fields(seal_friction_K_S1=0.0, seal_friction_K_S2=0.0, static_friction_factor=1.0)
    maps = [friction.efficiency_from_loads(d, loads, speeds, torques, back) for d in (off, zero)]
    _maps_equal(*maps)
    for name in ("output seal", "input seal"):
        assert not np.any(maps[0].losses[name])
    lost = friction.contact_losses(off, loads, speeds)
    others = sum(v[:, 0] for k, v in lost.items() if k not in ("output seal", "input seal"))
    w = np.array(speeds)[:, None] * RPM
    p_out = np.array(torques)[None] * w
    assert np.array_equal(maps[0].efficiency, p_out / (p_out + others[:, 1:]))
    assert np.array_equal(
        maps[0].no_load_running_torque_Nm, others[:, 0] / (design.ratio * np.array(speeds) * RPM)
    )
    still = friction.contact_losses(off, loads, [friction.STANDSTILL_RPM])
    start = sum(v[0, 0, 0] for k, v in still.items() if k not in ("output seal", "input seal"))
    assert maps[0].starting_torque_input_Nm == start / (design.ratio * friction.STANDSTILL_RPM * RPM)
    # and the seals on: every loss but theirs is the same to the bit, theirs > 0
    on = friction.efficiency_from_loads(design, loads, speeds, torques, back)
    for name in friction.LOSS_NAMES:
        if name in ("output seal", "input seal"):
            assert np.all(on.losses[name] > 0.0)
        else:
            assert np.array_equal(on.losses[name], maps[0].losses[name]), name
    assert np.all(on.efficiency < maps[0].efficiency)


def test_breakaway_changes_the_starting_torque_alone(rv40_loads):
    design, loads, back = rv40_loads
    speeds, torques = [5.0, 60.0], [41.2, 412.0]
    one = friction.efficiency_from_loads(
        design.with_fields(static_friction_factor=1.0), loads, speeds, torques, back
    )
    two = friction.efficiency_from_loads(
        design.with_fields(static_friction_factor=2.0), loads, speeds, torques, back
    )
    assert np.array_equal(one.efficiency, two.efficiency)
    assert np.array_equal(one.no_load_running_torque_Nm, two.no_load_running_torque_Nm)
    # start = f (Coulomb + seals) + drag at standstill: doubling f adds (Coulomb + seals) once
    free = friction.load_free_torques(design, [friction.STANDSTILL_RPM])
    seal = free["output seal"][0] + free["input seal"][0]
    coulomb = sum(
        v.mean(axis=-1)[0, 0]
        for v in friction.coulomb_torques(
            design,
            loads.pin_force,
            loads.pin_slide_arm,
            loads.cam_force,
            loads.crank_seat_force,
            loads.main_force,
            loads.tau_in,
        ).values()
    )
    assert (two.starting_torque_input_Nm - one.starting_torque_input_Nm) * design.ratio == pytest.approx(
        coulomb + seal, rel=1e-9
    )
    assert two.backdriving_torque_output_Nm == design.ratio * two.starting_torque_input_Nm


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_the_reducer_starts_above_its_running_torque(name):
    """Each preset: the starting torque above the no-load running torque at the chart's
    lowest speed (5 rpm): the Coulomb contacts and the seals break away at 1.25 x their
    running friction, more than the bearings' drag gains from standstill to 5 rpm.  The
    churning (`churning.py`), viscous, has no breakaway: it is left out here (with it, the
    RV-110E's churning at 5 rpm is of the size of the breakaway's margin)."""
    d = preset(name).with_fields(lubricant_fill=0.0)
    low = friction.efficiency_map(d, output_speed_rpm=[5.0], load_Nm=[d.rated_torque], points=POINTS)
    assert low.starting_torque_input_Nm > 1.05 * low.no_load_running_torque_Nm[0]
    assert low.backdriving_torque_output_Nm > d.ratio * low.no_load_running_torque_Nm[0]


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_a_small_load_runs_less_efficiently_than_the_rated_one(name):
    """Each preset as shipped, at 15 rpm: the efficiency at 10 % of rated torque below that
    at rated, the load-free torques (seals, drag, churning) a larger share of a small
    load's power."""
    d = preset(name)
    rated = friction.efficiency_map(
        d, output_speed_rpm=[15.0], load_Nm=[0.1 * d.rated_torque, d.rated_torque], points=POINTS
    )
    assert rated.efficiency[0, 0] < rated.efficiency[0, 1] - 0.01


# a field's own range is checked as the file is read (the file named), a relation with the
# rest of the design as the design is built (the design named)
@pytest.mark.parametrize(
    "key, value, where, allowed",
    [
        (
            "output_seal_diameter_mm",
            200.0,
            "RV-40E-121 (modified)",
            "must be from 0 (no seal) to 192.1 mm, 1.5 x the pin circle",
        ),
        ("input_seal_diameter_mm", -1.0, "RV-40E-121 (modified)", "must be >= 0"),
        ("seal_friction_exponent", 3.5, "RV-40E-121 (modified)", "must be from 0 to 3"),
        ("seal_friction_K_S2_Nmm", float("nan"), "mine.toml", "must be finite"),
        ("static_friction_factor", 0.9, "RV-40E-121 (modified)", "must be from 1 to 3"),
        ("static_friction_factor", 3.5, "RV-40E-121 (modified)", "must be from 1 to 3"),
    ],
)
def test_a_bad_seal_field_is_refused_by_name(key, value, where, allowed):
    with pytest.raises(InputError) as info:
        design_from_file_values({"preset": "RV-40E-121", key: value}, where="mine.toml")
    text = str(info.value)
    assert info.value.field == key
    assert text.startswith(f"{where}: {key} = {value!r}: {allowed}")
