"""The lubricant's churning (rvfmu/core/losses/churning.py): ISO/TR 14179-2's no-load loss of a
dip-lubricated gear against a hand-worked point, its place among the load-free torques, a
dry reducer unchanged to the bit, and what it does to the efficiency of every preset."""

import json

import numpy as np
import pytest
from test_hardening import run_cli

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import RPM
from rvfmu.core.laws.lubricant import viscosity_cSt
from rvfmu.core.losses import churning, friction
from rvfmu.core.losses.hysteresis import hysteresis
from rvfmu.core.reducer.design import PRESET_NAMES, load_design, preset

BASE = "RV-40E-121"


def test_the_law_at_a_hand_worked_point():
    # ISO/TR 14179-2, P = f_g nu n^3 (1.474 D^5.7 + 7.37 D^4.7 b R_f) / (A_g 1e26) kW with
    # f_g = 0.5, nu = 100 mm^2/s, n = 1000 rpm, D = 100 mm, b = 10 mm, m = 2 mm, A_g = 0.2:
    #   R_f = 7.93 - 4.648 / 2 = 5.606
    #   1.474 * 100^5.7 = 1.474 * 10^11.4 = 1.474 * 2.511886e11 = 3.702520e11
    #   7.37 * 100^4.7 * 10 * 5.606 = 413.1622 * 2.511886e9 = 1.037817e12
    #   f_g nu n^3 = 0.5 * 100 * 1e9 = 5e10;  5e10 * 1.408069e12 = 7.040346e22
    #   / (0.2 * 1e26) = 3.520173e-3 kW = 3.520173 W
    assert churning.roughness_factor(2.0) == pytest.approx(5.606, rel=1e-12)
    power = churning.gear_churning_power(0.5, 100.0, [1000.0, -1000.0, 0.0], 100.0, 10.0, 2.0)
    assert power[0] == pytest.approx(3.520173, rel=1e-6)
    assert power[1] == power[0] and power[2] == 0.0  # either sense, none at rest
    # the teeth's factor is 0 below m = 4.648 / 7.93 = 0.586 mm: a smooth disc's two faces
    assert churning.roughness_factor(0.5) == 0.0
    smooth = churning.gear_churning_power(1.0, 10.0, 100.0, 50.0, 5.0, 0.5)
    assert smooth == pytest.approx(1.474 * 10.0 * 1e6 * 50.0**5.7 / (0.2e26) * 1e3, rel=1e-12)


def test_the_presets_parts_turn_at_their_speeds_relative_to_the_housing():
    d = preset(BASE)
    # RV-40E-121 disc: lobes' outside diameter 2 (64.05 + 1.3 - 3.0) = 124.7 mm, width 10,
    # module 2 e = 2.6 mm, turning with the carrier at the output speed (their orbit is a
    # translation, outside the law); two discs.
    (disc,) = churning.churning_parts(d)["discs churning"]
    assert disc[0] == 2 and disc[4] == 1
    assert disc[1:4] == pytest.approx((124.7, 10.0, 2.6), rel=1e-12)
    planet, sun = churning.churning_parts(d)["gears churning"]
    assert planet[:2] == (2, pytest.approx(1.5 * 38)) and planet[4] == 39
    assert sun[:2] == (1, pytest.approx(1.5 * 14)) and sun[4] == pytest.approx(121.0)
    torques = churning.churning_torques(d, [15.0])
    nu = viscosity_cSt(d, 40.0)  # 100 mm^2/s: the grade's, at 40 C
    discs = 2 * churning.gear_churning_power(0.5, nu, 15.0, 124.7, 10.0, 2.6)
    assert torques["discs churning"][0] == pytest.approx(discs / (15.0 * RPM), rel=1e-12)
    gears = 2 * churning.gear_churning_power(
        0.5, nu, 39 * 15.0, 57.0, 10.0, 1.5
    ) + churning.gear_churning_power(0.5, nu, 121 * 15.0, 21.0, 10.0, 1.5)
    assert torques["gears churning"][0] == pytest.approx(gears / (15.0 * RPM), rel=1e-12)
    # they are the load-free torques' churning entries, among the loss names
    free = friction.load_free_torques(d, [15.0])
    for name in churning.CHURNING_NAMES:
        assert name in friction.LOSS_NAMES
        assert free[name][0] == torques[name][0] > 0.0


def test_churning_rises_as_the_lubricant_cools_and_with_speed():
    d = preset(BASE)
    temperatures = (80.0, 40.0, 20.0, 0.0, -10.0)
    cold = [sum(churning.churning_torques(d, [15.0], t).values())[0] for t in temperatures]
    assert np.all(np.diff(cold) > 0.0), cold
    # linear in the viscosity: -10 C against 40 C is the viscosity's ratio (53.6 for VG 100, VI 95)
    ratio = viscosity_cSt(d, -10.0) / viscosity_cSt(d, 40.0)
    assert cold[-1] / cold[1] == pytest.approx(ratio, rel=1e-12) and ratio > 10.0
    speeds = np.array([1.0, 5.0, 15.0, 30.0, 60.0])
    fast = sum(churning.churning_torques(d, speeds).values())
    assert np.all(np.diff(fast) > 0.0)
    assert fast[-1] / fast[2] == pytest.approx(16.0, rel=1e-12)  # torque ~ n^2
    assert sum(churning.churning_torques(d, [0.0]).values())[0] == 0.0  # no starting torque
    # the load-free total rises with them too (the bearings' drag and the churning)
    free = {t: sum(friction.load_free_torques(d, [15.0], t).values())[0] for t in (40.0, -10.0)}
    assert free[-10.0] > free[40.0]


def test_a_dry_reducer_is_todays_to_the_bit():
    d = preset(BASE)
    dry = d.with_fields(lubricant_fill=0.0)
    speeds, loads = [5.0, 15.0, 60.0], [0.1 * d.rated_torque, d.rated_torque]
    for t in (40.0, -10.0):
        wet_free = friction.load_free_torques(d, speeds, t)
        for name, torque in friction.load_free_torques(dry, speeds, t).items():
            if name in churning.CHURNING_NAMES:
                assert np.all(torque == 0.0), name
            else:  # the bearings' drag and the seals do not see the fill
                assert np.array_equal(torque, wet_free[name]), name
    m_dry = friction.efficiency_map(
        dry, output_speed_rpm=speeds, load_Nm=loads, points=6, temperature_C=-10.0
    )
    m_wet = friction.efficiency_map(d, output_speed_rpm=speeds, load_Nm=loads, points=6, temperature_C=-10.0)
    # the wet run with its churning taken out is the dry run, every figure to the bit: its
    # other losses, their sum, and the efficiency from them (p_out multiplied in the order
    # `friction.efficiency_from_loads` multiplies it: another order differs in the last bit)
    rest = [n for n in friction.LOSS_NAMES if n not in churning.CHURNING_NAMES]
    kept = sum(m_wet.losses[n] for n in rest)
    assert np.array_equal(m_dry.loss_W, kept)
    p_out = np.asarray(loads)[None] * (np.asarray(speeds)[:, None] * RPM)
    todays = p_out / (p_out + kept)
    assert np.array_equal(m_dry.efficiency, todays)
    for name in rest:
        assert np.array_equal(m_dry.losses[name], m_wet.losses[name]), name
    for name in churning.CHURNING_NAMES:
        assert np.all(m_dry.losses[name] == 0.0) and np.all(m_wet.losses[name] > 0.0), name
    assert m_dry.starting_torque_input_Nm == m_wet.starting_torque_input_Nm
    # the windup test does not turn the parts: its loop is the same wet or dry
    loop_dry, loop_wet = (hysteresis(x, positions=2, levels=4) for x in (dry, d))
    assert np.array_equal(loop_dry.loop, loop_wet.loop)
    assert loop_wet.friction_work_J["discs churning"] == 0.0


def test_efficiency_of_every_preset_with_its_load_free_losses():
    """The issue's shape of every RV efficiency chart, with the seals and the churning of the
    presets: at 15 rpm the efficiency at 10 % of rated torque is at least 5 percentage points
    below that at rated (8.5 to 13.3 on the presets today), and at rated torque it falls
    with speed."""
    for name in PRESET_NAMES:
        d = preset(name)
        speeds = [v for v in (5.0, 15.0, 60.0) if v * RPM <= d.allowable_output_speed]
        m = friction.efficiency_map(
            d, output_speed_rpm=speeds, load_Nm=[0.1 * d.rated_torque, d.rated_torque], points=12
        )
        light, rated = m.efficiency[speeds.index(15.0)]
        # light loads lose more of their power: the load-free losses do not shrink with it
        assert rated - light >= 0.05, (name, light, rated)
        # at rated torque the efficiency falls with speed: the churning grows as n^3
        assert np.all(np.diff(m.efficiency[:, 1]) < 0.0), (name, m.efficiency[:, 1])


@pytest.mark.parametrize("value, allowed", [(1.5, "must be from 0 to 1"), (-0.2, "must be >= 0")])
def test_a_fill_outside_0_to_1_is_refused_naming_it(tmp_path, capsys, value, allowed):
    with pytest.raises(InputError) as info:
        preset(BASE).with_fields(lubricant_fill=value)
    assert info.value.field == "lubricant_fill"
    assert f"lubricant_fill = {value}" in str(info.value) and allowed in str(info.value)
    path = tmp_path / "wet.toml"
    path.write_text(f'preset = "{BASE}"\nlubricant_fill = {value}\n')
    with pytest.raises(InputError) as info:
        load_design(path)
    assert info.value.field == "lubricant_fill" and allowed in str(info.value)
    code, out, err = run_cli(["efficiency", str(path), "--speeds", "15"], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "lubricant_fill" in err and allowed in err


def test_the_efficiency_report_lists_the_churning(capsys):
    code, out, err = run_cli(["efficiency", BASE, "--speeds", "15", "--loads", "412", "--json"], capsys)
    assert code == 0, err
    losses = json.loads(out)["map"][0]["losses_W"]
    assert losses["gears churning"] > losses["discs churning"] > 0.0
