"""The load-free losses in the dynamic model (docs/model.md section 9): the lip seals, the
churning and the breakaway, each as the quasi-static power balance gives it; with none of
them switched on, the run of before to the bit; and the hysteresis loop's output seal."""

import math

import numpy as np
import pytest
from test_dynamic_friction import assert_tangents

from rvfmu.core.base.checks import InputError
from rvfmu.core.dynamics.dynamic import STRIBECK_SPEED, DynamicModel, ramp_motion
from rvfmu.core.dynamics.kernels import stribeck
from rvfmu.core.dynamics.simulation import simulate
from rvfmu.core.laws.seals import seal_torques
from rvfmu.core.losses.friction import RPM, load_free_torques
from rvfmu.core.losses.hysteresis import hysteresis
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import zero_errors
from rvfmu.core.steppers.dynamic_reducer import DynamicReducer

# the tolerance of tests/test_dynamic_friction.py's balance against the quasi-static model
BALANCE = 0.1
# every new loss switched off: no seal law, no input seal, no lubricant to churn, no breakaway
OFF = dict(output_seal_diameter=0.0, input_seal_diameter=0.0, lubricant_fill=0.0, static_friction_factor=1.0)
FRICTIONLESS = dict(
    pin_disc_friction=0.0,
    pin_groove_friction=0.0,
    mesh_friction=0.0,
    needle_friction=0.0,
    tapered_friction=0.0,
    main_bearing_friction=0.0,
    bearing_drag_factor=0.0,
    seal_torque=0.0,
    **OFF,
)
SPEED_RPM = 3000.0  # input: 24.8 rpm at the output of the RV-40E-121
PRESET = preset("RV-40E-121")  # the presets' seal diameters and fill (estimates)


@pytest.fixture(scope="module")
def bare(rv40):
    """The estimate without any friction, drag or load-free loss."""
    return rv40.with_fields(**FRICTIONLESS)


@pytest.fixture(scope="module")
def runs(bare):
    """{case: mean powers and input torque of an unloaded run at SPEED_RPM}, each run once."""
    cache = {}

    def run(case, fields, temperature_C=40.0):
        if case not in cache:
            sim = simulate(
                bare.with_fields(**fields), None, SPEED_RPM, duration=0.1, temperature_C=temperature_C
            )
            powers = sim.mean_powers()
            powers["tau_in"] = float(np.mean(sim.tau_in[sim.steady :]))
            cache[case] = powers
        return cache[case]

    return run


def test_with_every_new_loss_off_the_run_is_the_one_of_before(rv40, seed002):
    """The balance tests' reducer (every contact rubbing, the output seal stated at 0.5 N*m)
    with the seal law, the input seal, the churning and the breakaway off: the TE, input
    torque and friction power of the model before they came (figures of that model's run, as
    float.hex): to the last bit on the 2-core Intel Xeon that recorded them; on another CPU
    the math library's and numpy's last bits differ and the run carries them on (a 2-core AMD
    EPYC: up to 1.6e-14 of each series' largest value, 1.6e-15 of its sum), so within 1e-12
    of that value, and its sum within 1e-12 of itself."""
    d = PRESET
    design = rv40.with_fields(
        needle_pitch_diameter=d.needle_pitch_diameter,
        tapered_pitch_diameter=d.tapered_pitch_diameter,
        main_bearing_pitch_diameter=d.main_bearing_pitch_diameter,
        seal_torque=0.5,
        **OFF,
    )
    run = simulate(design, seed002, 1600.0, load=206.0, duration=0.01)
    before = {
        "te": (
            ["-0x1.7c9db478ed2a0p-11", "-0x1.69d9584d37e1fp-11", "-0x1.55b191513a973p-11"],
            "-0x1.67ade9eeec7eep-1",
        ),
        "tau_in": (
            ["-0x1.b46541d07c64ap+0", "-0x1.0a8239abfe47bp+1", "-0x1.8292ae72d83b1p+0"],
            "-0x1.16d0437d253f2p+11",
        ),
        "friction_power": (
            ["0x1.8a988079ced76p-22", "0x1.26a08681d0a0fp+4", "0x1.f19c1fdfe1205p+4"],
            "0x1.1b50fbd92cd49p+14",
        ),
    }
    for name, (points, total) in before.items():
        x = getattr(run, name)
        assert x.size == 1017, name
        recorded = np.array([float.fromhex(v) for v in points])
        np.testing.assert_allclose(x[[1, x.size // 2, -1]], recorded, rtol=0, atol=1e-12 * np.abs(x).max())
        np.testing.assert_allclose(np.sum(x), float.fromhex(total), rtol=1e-12)


@pytest.mark.parametrize(
    "case, fields, temperature_C, names",
    [
        ("output seal", dict(output_seal_diameter=PRESET.output_seal_diameter), 40.0, ("output seal",)),
        (
            "stated output seal",
            dict(output_seal_diameter=PRESET.output_seal_diameter, seal_torque=2.0),
            40.0,
            ("output seal",),
        ),
        ("input seal", dict(input_seal_diameter=PRESET.input_seal_diameter), 40.0, ("input seal",)),
        ("churning", dict(lubricant_fill=PRESET.lubricant_fill), 40.0, ("discs churning", "gears churning")),
        (
            "churning, 10 C",
            dict(lubricant_fill=PRESET.lubricant_fill),
            10.0,
            ("discs churning", "gears churning"),
        ),
    ],
)
def test_each_new_loss_alone_is_the_quasi_static_models_at_the_same_speed(
    bare, runs, case, fields, temperature_C, names
):
    """The reducer without friction but one new loss: the friction power is that loss's
    power in the quasi-static balance (`friction.load_free_torques` times the output speed)
    at the same output speed and lubricant temperature, and the input power rises by it
    (within the balance tolerance: the run's stored energy still changes a little after
    the start ramp, some mW)."""
    n_out = SPEED_RPM / bare.ratio
    free = load_free_torques(bare.with_fields(**fields), [n_out], temperature_C)
    expected = sum(float(free[name][0]) for name in names) * n_out * RPM
    assert expected > 0.3  # W: a loss to measure
    base = runs("none", {})
    assert base["friction_W"] == 0.0
    powers = runs(case, fields, temperature_C)
    assert powers["friction_W"] == pytest.approx(expected, rel=BALANCE)
    assert powers["friction_W"] == pytest.approx(expected, rel=1e-3)  # in fact
    assert powers["output_W"] == 0.0
    assert powers["input_W"] - base["input_W"] == pytest.approx(expected, rel=BALANCE)


def test_the_churning_follows_the_lubricants_viscosity_with_the_temperature(bare, runs):
    """Cold, the oil is thicker: the churning's power grows by the viscosity's ratio."""
    from rvfmu.core.laws.lubricant import viscosity_cSt

    fill = dict(lubricant_fill=PRESET.lubricant_fill)
    ratio = viscosity_cSt(bare, 10.0) / viscosity_cSt(bare, 40.0)
    assert ratio > 3.0
    cold, warm = runs("churning, 10 C", fill, 10.0), runs("churning", fill)
    assert cold["friction_W"] / warm["friction_W"] == pytest.approx(ratio, rel=0.01)


def test_the_input_seal_raises_the_input_torque_by_its_own_at_constant_speed(bare, runs):
    """tau_in is the reducer's torque on the input (docs/model.md section 2): the seal resists
    the input's turn, so it adds minus its torque, in a run and in the FMU's steps."""
    fields = dict(input_seal_diameter=PRESET.input_seal_diameter)
    seal = seal_torques(bare.with_fields(**fields))["input seal"]
    assert seal == pytest.approx(0.056272)  # N*m, SKF's law on 14 mm
    rise = runs("input seal", fields)["tau_in"] - runs("none", {})["tau_in"]
    assert rise == pytest.approx(-seal, rel=1e-3)
    speed = 600.0 * RPM
    taus = []
    for design in (bare, bare.with_fields(**fields)):
        reducer = DynamicReducer(design, zero_errors(design))
        reducer.initialize(0.0, 0.0, 0.0)
        outs = []
        for k in range(150):
            omega = speed * min(1.0, (k + 1) / 50.0)
            outs.append(reducer.step(k * 1e-3, 1e-3, reducer.theta_in + omega * 1e-3, 0.0))
        taus.append(np.mean([o.tau_in for o in outs[100:]]))
    assert taus[1] - taus[0] == pytest.approx(-seal, rel=1e-3)


def test_the_stribeck_law_is_the_coulomb_law_without_breakaway_and_smooth_with_it():
    for w in (-2e-3, -1e-9, 0.0, 3e-6, 5e-2):
        assert stribeck(w, 1.0, STRIBECK_SPEED) == (1.0, 0.0)
    assert stribeck(0.0, 1.25, STRIBECK_SPEED) == (1.25, 0.0)
    assert stribeck(STRIBECK_SPEED, 1.25, STRIBECK_SPEED)[0] == pytest.approx(1.0 + 0.25 / math.e)
    assert stribeck(-10 * STRIBECK_SPEED, 1.25, STRIBECK_SPEED)[0] == pytest.approx(1.0, abs=1e-40)
    for w in (-3 * STRIBECK_SPEED, -0.4 * STRIBECK_SPEED, 0.02 * STRIBECK_SPEED, STRIBECK_SPEED):
        g, dg = stribeck(w, 1.25, STRIBECK_SPEED)
        h = 1e-6 * STRIBECK_SPEED
        fd = (stribeck(w + h, 1.25, STRIBECK_SPEED)[0] - stribeck(w - h, 1.25, STRIBECK_SPEED)[0]) / (2 * h)
        assert dg == pytest.approx(fd, rel=1e-5)
        assert stribeck(-w, 1.25, STRIBECK_SPEED) == (g, -dg)


def test_a_seal_resists_with_its_breakaway_torque_at_a_crawl_and_its_running_one_beyond(bare):
    """The output seal alone (stated 2 N*m) on the nominal motion at output speeds whose
    carrier slips at R_p from 0 to 5 x STRIBECK_SPEED: its friction power is the running
    torque times the Stribeck law and the regularised sign, T g(w) s(w) w / R_p; f_s = 1
    gives the regularised Coulomb law.  (A run held at a slip on the law's falling slope
    sticks and slips: its mean is no test of the law.)"""
    from rvfmu.core.dynamics.dynamic import SLIP_SCALE

    torque = 2.0
    for factor in (1.0, 1.25, 3.0):
        model = DynamicModel(
            bare.with_fields(seal_torque=torque, static_friction_factor=factor), zero_errors(bare)
        )
        for fraction in (0.0, 0.02, 0.3, 1.0, 5.0):
            w = fraction * STRIBECK_SPEED  # m/s at R_p
            model.prepare(ramp_motion(np.array([0.0, 1e-3]), w / bare.R_p * bare.ratio, 0.0))
            power = model.forces_and_powers(1, np.zeros(model.n), np.zeros(model.n))[3][0]
            lift = 1.0 + (factor - 1.0) * math.exp(-(fraction**2))
            sign = w / math.sqrt(w * w + SLIP_SCALE**2)
            assert power == pytest.approx(torque / bare.R_p * lift * sign * w, rel=1e-12, abs=1e-300)


def test_the_tangent_is_the_derivative_of_the_forces_through_the_breakaway(rv40, seed002):
    """K and C against central differences of f, every contact rubbing with a breakaway of
    3 x, at input speeds whose slips lie across the Stribeck speed (the law's slope)."""
    d = PRESET
    design = rv40.with_fields(
        needle_pitch_diameter=d.needle_pitch_diameter,
        tapered_pitch_diameter=d.tapered_pitch_diameter,
        main_bearing_pitch_diameter=d.main_bearing_pitch_diameter,
        static_friction_factor=3.0,
    )
    carrier = STRIBECK_SPEED / design.R_p * design.ratio  # rad/s of input
    assert_tangents(
        DynamicModel(design, seed002, mesh="varying"),
        (0.5 * carrier, 2.0 * carrier),
        1e-5,
        np.random.default_rng(7),
    )


def test_the_hysteresis_loops_output_seal_is_its_law_or_the_stated_torque():
    """The windup test's output seal loses its running torque over the output's travel: the
    law's (0.496 N*m on the preset's 118.1 mm), a stated one instead, none without either;
    the input is locked, its seal does no work."""
    d = PRESET.with_fields(output_seal_diameter=0.0)
    work = {}
    for case, fields in (
        ("none", {}),
        ("law", dict(output_seal_diameter=0.1181)),
        ("stated", dict(output_seal_diameter=0.1181, seal_torque=1.0)),
    ):
        loop = hysteresis(d.with_fields(**fields), positions=2, levels=4)
        work[case] = loop.friction_work_J
    law = seal_torques(PRESET)["output seal"]
    assert law == pytest.approx(0.49632352)
    assert work["none"]["output seal"] == 0.0
    assert work["stated"]["output seal"] > 0.0
    assert work["law"]["output seal"] == pytest.approx(law * work["stated"]["output seal"], rel=1e-12)
    assert all(w["input seal"] == 0.0 for w in work.values())


@pytest.mark.parametrize(
    "value, allowed",
    [
        (200.0, "must be from -40 to 150 C"),
        (-60.0, "must be from -40 to 150 C"),
        (math.nan, "must be finite"),
    ],
)
def test_a_temperature_outside_the_lubricants_range_is_refused(bare, value, allowed):
    """The field, the value and what is allowed, from `simulate` and from the model."""
    for make in (
        lambda: simulate(bare, None, 600.0, duration=0.01, temperature_C=value),
        lambda: DynamicModel(bare, zero_errors(bare), temperature_C=value),
    ):
        with pytest.raises(InputError) as info:
            make()
        assert str(info.value).startswith(f"temperature_C = {value}: {allowed}")


def test_the_dynamic_reducer_and_rvte_simulate_run_at_the_lubricants_temperature(bare, capsys):
    """The FMU's dynamic model and `rvte simulate` take the lubricant's temperature: colder oil
    turns the unloaded reducer with more input torque (the drag and the churning); out of
    Walther's range it is refused by name, before any work."""
    from rvfmu import cli

    design = PRESET
    taus = {}
    for temperature in (40.0, -10.0):
        reducer = DynamicReducer(design, zero_errors(design), temperature_C=temperature)
        assert reducer.temperature_C == temperature
        reducer.initialize(0.0, 0.0, 0.0)
        speed, outs = 600.0 * RPM, []
        for k in range(150):
            omega = speed * min(1.0, (k + 1) / 50.0)
            outs.append(reducer.step(k * 1e-3, 1e-3, reducer.theta_in + omega * 1e-3, 0.0))
        taus[temperature] = np.mean([o.tau_in for o in outs[100:]])
    assert taus[-10.0] < taus[40.0] < 0.0  # the reducer resists the input, more in the cold
    with pytest.raises(InputError) as error:
        DynamicReducer(design, zero_errors(design), temperature_C=200.0)
    assert error.value.field == "temperature_C"
    code = cli.main(["simulate", "RV-40E-121", "--duration", "0.01", "--temperature", "200"])
    err = capsys.readouterr().err
    assert code == 2 and "temperature_C" in err and "200" in err and err.count("\n") == 1
