"""The quasi-static FMUs' lubricant temperature (`temperature_C`) and breakaway (Stribeck law).

The TE map carries the load-free friction torque (bearings' drag, churning, seals) at the
temperatures `te_map.DRAG_TEMPERATURES`; both FMUs read it at their `temperature_C` parameter
when initialisation ends (linear between the table's temperatures, its row at one of them)
and refuse a temperature outside them.  Near standstill the Coulomb contacts and the seals
break away at the design's `static_friction_factor` (`reducer_model.friction_step`).
"""

import shutil
import struct

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from test_fmu import (
    Instance,
    free_instances,  # noqa: F401 - frees every instance after a test
)
from test_fmu_native import STEP, drive, varying_run
from test_fmu_native3 import Instance3

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCSEC
from rvfmu.core.losses.friction import RPM, efficiency_map, load_free_torques
from rvfmu.core.steppers.reducer_model import (
    FRICTION_SPEED_SCALE,
    STRIBECK_SPEED,
    QuasiStaticReducer,
    friction_step,
    stribeck_decay,
)
from rvfmu.core.steppers.te_map import DRAG_TEMPERATURES, LOAD_FREE_INTERPOLATION_BOUND, TEMap
from rvfmu.fmu.api import fmu_build
from rvfmu.fmu.build import build_fmu
from rvfmu.fmu.native import TABLE_NAME, read_table

POINTS = 624  # a coarse map: the friction, not the TE, is under test
OUTPUT_RPM = 10.0  # the no-load runs' output speed [rpm]
# temperatures between the table's, none on it: where the interpolation is checked
BETWEEN = (-18.75, -11.25, 1.25, 23.75, 61.25)
BAD_TEMPERATURES = (-30.0, 100.5, float("nan"), float("inf"))
STATIC_OFFSET = 160  # the table's static friction factor (rvfmu/fmu/native.py)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, rv40, seed002):
    """{"python", "native2", "native3": (path, description)}, one build each."""
    folder = tmp_path_factory.mktemp("temperature")
    paths = {
        "python": build_fmu(rv40, seed002, folder / "python.fmu", points=POINTS),
        "native2": fmu_build(rv40, seed002, folder / "native2.fmu", points=POINTS, native=True),
        "native3": fmu_build(
            rv40, seed002, folder / "native3.fmu", points=POINTS, native=True, fmi_version=3
        ),
    }
    return {name: (path, read_model_description(str(path))) for name, path in paths.items()}


@pytest.fixture(scope="module")
def table(fmus, tmp_path_factory):
    """(the native FMU's unzipped folder, its TE map)."""
    unzipped = extract(str(fmus["native2"][0]), unzipdir=tmp_path_factory.mktemp("unzipped"))
    return unzipped, read_table(f"{unzipped}/resources/{TABLE_NAME}")[0]


@pytest.fixture(scope="module")
def static_one(table, tmp_path_factory):
    """The native FMI 2.0 FMU's folder with its table's static friction factor set to 1."""
    unzipped, _ = table
    copy = tmp_path_factory.mktemp("static_one") / "fmu"
    shutil.copytree(unzipped, copy)
    path = copy / "resources" / TABLE_NAME
    data = bytearray(path.read_bytes())
    assert struct.unpack_from("<d", data, STATIC_OFFSET)[0] == 1.25
    data[STATIC_OFFSET : STATIC_OFFSET + 8] = struct.pack("<d", 1.0)
    path.write_bytes(bytes(data))
    return str(copy)


def make(fmus, name, temperature=None, unzipped=None):
    """An initialised instance of FMU `name`, temperature_C set unless None."""
    reals = None if temperature is None else {"temperature_C": temperature}
    path, md = fmus[name]
    if name == "native3":
        return Instance3(path, md, name=name, reals=reals, unzipped=unzipped)
    if unzipped is None:
        return Instance(path, md, name=name, reals=reals)
    inst = Instance.__new__(Instance)  # Instance's start on a given folder
    inst.vr = {v.name: v.valueReference for v in md.modelVariables}
    inst.fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipped,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    inst.fmu.instantiate(loggingOn=True, callbacks=None)
    Instance.opened.append(inst.fmu)
    for key, value in (reals or {}).items():
        inst.fmu.setReal([inst.vr[key]], [value])
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    return inst


def todays_run(te_map: TEMap, theta_in, tau_load):
    """`drive`'s outputs after each step as the quasi-static model stepped before the temperature table
    and the breakaway: the load-free torque of the map's 40 C row, Coulomb friction
    regularised over FRICTION_SPEED_SCALE, nothing more (its arithmetic, written out)."""
    row = te_map.drag[list(te_map.drag_temperature).index(40.0)]
    at_40 = TEMap(
        te_map.ratio,
        te_map.theta_in,
        te_map.torque_magnitude,
        te_map.te,
        te_map.tau_in,
        te_map.friction,
        te_map.drag_speed,
        row,
    )  # a 40 C map
    ratio, rows = te_map.ratio, []
    theta_before = 0.0
    te, _, _ = te_map.evaluate_one(0.0, 0.0)
    theta_out = 0.0 / ratio + te
    for theta, load in zip(theta_in, tau_load):
        te, tau_map, coulomb = te_map.evaluate_one(float(theta), float(load))
        out = float(theta) / ratio + te
        omega = (out - theta_out) / STEP
        omega_in = (float(theta) - theta_before) / STEP
        friction_out = coulomb + at_40.load_free_one(omega_in / ratio)
        sense = min(max(omega_in / FRICTION_SPEED_SCALE, -1.0), 1.0)
        torque = sense * (friction_out / ratio)
        p_loss = torque * omega_in
        passed = tau_map * omega_in
        if passed < 0.0:
            efficiency = -passed / (p_loss - passed)
        elif passed > 0.0:
            efficiency = (passed - p_loss) / passed if passed > p_loss else 0.0
        else:
            efficiency = 0.0
        rows.append((out, omega, te, te / ARCSEC, tau_map - torque, p_loss, efficiency))
        theta_out, theta_before = out, float(theta)
    return np.array(rows)


def constant_speed_friction(inst, omega_in, steps=5, te_map=None):
    """(tau_in [N*m], the friction torque at the input [N*m]) after `steps` steps at input speed
    `omega_in` [rad/s], no load; the friction from the map's frictionless torque if given."""
    for k in range(steps):
        inst.set(theta_in=(k + 1) * omega_in * STEP, tau_load=0.0)
        inst.step(k * STEP, STEP)
    tau_in = inst.get("tau_in")[0]
    if te_map is None:
        return tau_in, None
    _, tau_map, _ = te_map.evaluate_one(steps * omega_in * STEP, 0.0)
    return tau_in, tau_map - tau_in


# -- the table --------------------------------------------------------------------------------


def test_the_table_rows_are_the_load_free_torques_and_40_c_is_one_of_them(table, rv40):
    _, te_map = table
    assert tuple(te_map.drag_temperature) == DRAG_TEMPERATURES and 40.0 in DRAG_TEMPERATURES
    assert DRAG_TEMPERATURES[0] == -20.0 and DRAG_TEMPERATURES[-1] == 100.0
    for m in (0, DRAG_TEMPERATURES.index(40.0), len(DRAG_TEMPERATURES) - 1):
        temperature = DRAG_TEMPERATURES[m]
        exact = sum(load_free_torques(rv40, te_map.drag_speed / RPM, temperature).values())
        assert np.array_equal(te_map.drag[m], exact), temperature
        assert te_map.load_free_row(temperature) == list(te_map.drag[m])  # the row to the bit
    seals = load_free_torques(rv40, [0.0])
    assert te_map.seal == seals["output seal"][0] + seals["input seal"][0] > 0
    assert te_map.static_friction_factor == rv40.static_friction_factor == 1.25
    # the load-free torque grows as the lubricant cools (its viscosity, the drag)
    assert np.all(te_map.drag[0, 1:] > te_map.drag[-1, 1:])


def test_the_interpolation_in_temperature_is_within_its_stated_bound(table, rv40):
    _, te_map = table
    worst = 0.0
    for temperature in BETWEEN:
        exact = sum(load_free_torques(rv40, te_map.drag_speed / RPM, temperature).values())
        read = np.array(te_map.load_free_row(temperature))
        error = np.max(np.abs(read - exact) / exact)
        assert error <= LOAD_FREE_INTERPOLATION_BOUND, (temperature, error)
        worst = max(worst, error)
    assert worst > 1e-4  # it does interpolate: not a row of the table
    print(f"worst interpolation error at {BETWEEN} C: {worst:.3%}")


def test_a_temperature_outside_the_table_is_refused_by_the_core(table):
    _, te_map = table
    for bad in BAD_TEMPERATURES:
        with pytest.raises(InputError) as refused:
            QuasiStaticReducer(te_map, bad)
        assert str(refused.value) == (
            f"temperature_C = {bad!r}: must be from -20.0 to 100.0 C "
            "(the temperatures of the TE map's load-free table)"
        )


def test_a_map_file_from_before_the_table_reads_as_its_40_c_row_without_breakaway(table):
    _, te_map = table
    arrays = te_map.to_arrays()
    assert set(TEMap.from_arrays(arrays).to_arrays()) == set(arrays)
    old = {k: v for k, v in arrays.items() if k not in ("drag_temperature", "seal", "static_friction_factor")}
    old["drag"] = te_map.drag[DRAG_TEMPERATURES.index(40.0)]
    read = TEMap.from_arrays(old)
    assert list(read.drag_temperature) == [40.0] and read.static_friction_factor == 1.0
    assert read.load_free_row(40.0) == te_map.load_free_row(40.0)
    with pytest.raises(InputError, match="temperature_C = 41.0: must be from 40.0 to 40.0 C"):
        read.load_free_row(41.0)


# -- 40 C: today's outputs --------------------------------------------------------------------


@pytest.mark.parametrize("name", ["python", "native2", "native3"])
def test_at_40_c_every_output_is_todays_to_the_bit(fmus, table, rv40, name):
    """A run of speeds beyond the breakaway's (where it is exactly 0) and standstill, the load
    through both branches: the outputs of today's law on the 40 C row, bit for bit."""
    _, te_map = table
    theta_in, tau_load = varying_run(rv40.rated_torque, steps=1500)
    expected = todays_run(te_map, theta_in, tau_load)
    speeds = np.abs(np.diff(np.concatenate([[0.0], theta_in]))) / STEP
    assert np.all((speeds == 0.0) | (speeds > np.sqrt(40.0) * STRIBECK_SPEED))
    assert (speeds == 0.0).sum() > 100
    for temperature in (None, 40.0):  # the default, and 40 set
        got = drive(make(fmus, name, temperature), theta_in, tau_load)
        assert np.array_equal(got, expected), (name, temperature)


# -- cold: the no-load running torque rises --------------------------------------------------


@pytest.fixture(scope="module")
def running_torque(rv40, seed002):
    """{temperature: the no-load running torque at the input [N*m]} by `efficiency_map`."""
    return {
        t: efficiency_map(
            rv40, seed002, [OUTPUT_RPM], [rv40.rated_torque / 4], temperature_C=t
        ).no_load_running_torque_Nm[0]
        for t in (40.0, -10.0)
    }


@pytest.mark.parametrize("name", ["python", "native2", "native3"])
def test_at_minus_10_c_the_input_torque_rises_by_the_no_load_running_torques_difference(
    fmus, rv40, running_torque, name
):
    omega_in = OUTPUT_RPM * RPM * rv40.ratio
    warm, _ = constant_speed_friction(make(fmus, name), omega_in)
    cold, _ = constant_speed_friction(make(fmus, name, -10.0), omega_in)
    rise = warm - cold  # tau_in is the reducer's torque on the input: -friction
    expected = running_torque[-10.0] - running_torque[40.0]
    assert expected > 0.05
    assert rise == pytest.approx(expected, rel=LOAD_FREE_INTERPOLATION_BOUND), (rise, expected)


def test_between_the_table_temperatures_both_fmus_read_the_same_interpolation(fmus, table, rv40):
    """At -11.25 C the FMUs agree with each other (the same arithmetic) and with the core's
    load-free torque within the stated bound."""
    _, te_map = table
    omega_in = OUTPUT_RPM * RPM * rv40.ratio
    read = {
        name: constant_speed_friction(make(fmus, name, -11.25), omega_in, te_map=te_map)[1]
        for name in ("python", "native2", "native3")
    }
    assert read["native2"] == read["python"] == read["native3"]
    coulomb = te_map.evaluate_one(5 * omega_in * STEP, 0.0)[2]
    exact = (coulomb + sum(load_free_torques(rv40, [OUTPUT_RPM], -11.25).values())[0]) / rv40.ratio
    assert read["python"] == pytest.approx(exact, rel=LOAD_FREE_INTERPOLATION_BOUND)


# -- a bad temperature ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["python", "native2", "native3"])
@pytest.mark.parametrize("bad", BAD_TEMPERATURES)
def test_a_temperature_outside_the_table_is_an_error_at_initialisation(fmus, capfd, name, bad):
    message = (
        f"initialisation failed: temperature_C = {bad!r}: must be from -20.0 to 100.0 C "
        "(the temperatures of the TE map's load-free table)"
    )
    capfd.readouterr()
    if name == "python":  # logged at initialisation, the step an error
        inst = make(fmus, name, bad)
        assert message in capfd.readouterr().out
        with pytest.raises(Exception, match="status 3"):
            inst.step(0.0, STEP)
    else:  # fmi2Error / fmi3Error at once
        with pytest.raises(Exception, match="ExitInitializationMode failed with status 3"):
            make(fmus, name, bad)
    assert message in capfd.readouterr().out


@pytest.mark.parametrize("name", ["native2", "native3"])
def test_the_native_temperature_is_fixed_after_initialisation(fmus, capfd, name):
    inst = make(fmus, name, 0.0)
    assert inst.get("temperature_C") == [0.0]
    capfd.readouterr()
    with pytest.raises(Exception, match="status 3"):
        inst.set(temperature_C=50.0)
    assert (
        "is the fixed parameter temperature_C: it can be set only before initialisation ends"
    ) in capfd.readouterr().out
    assert inst.get("temperature_C") == [0.0]
    inst.fmu.reset()  # back to its start value
    assert inst.get("temperature_C") == [40.0]


def test_both_descriptions_declare_the_parameter_alike(fmus):
    found = {}
    for name, (_, md) in fmus.items():
        (variable,) = [v for v in md.modelVariables if v.name == "temperature_C"]
        found[name] = (
            variable.causality,
            variable.variability,
            variable.valueReference,
            float(variable.start),
        )
    assert found["python"] == found["native2"] == found["native3"] == ("parameter", "fixed", 18, 40.0)


# -- breakaway: the Stribeck law --------------------------------------------------------------


def test_friction_step_breakaway_by_hand():
    ratio, coulomb, free, breakaway = 121.0, 12.1, 2.42, 14.0
    # at a few speed scales the breakaway part counts (1 + 0.25 exp(-(w / w_s)^2)) times
    omega = 3 * FRICTION_SPEED_SCALE
    tau_in, _, _ = friction_step(0.0, coulomb + free, ratio, omega, breakaway, 1.25)
    decay = np.exp(-((omega / STRIBECK_SPEED) ** 2))
    assert -tau_in == pytest.approx((coulomb + free + 0.25 * decay * breakaway) / ratio, rel=1e-14)
    # f_s = 1: today's law to the bit, whatever the breakaway part
    for omega in (0.0, 1e-3, 0.03, -0.5, 2.0, 50.0):
        assert friction_step(1.5, 14.52, ratio, omega, breakaway, 1.0) == friction_step(
            1.5, 14.52, ratio, omega
        )
    # far beyond the Stribeck speed it is exactly the running friction
    assert friction_step(1.5, 14.52, ratio, 10.0, breakaway, 2.0) == friction_step(1.5, 14.52, ratio, 10.0)
    # at standstill no torque (no chatter), within the speed scale proportional to the speed
    assert friction_step(1.5, 14.52, ratio, 0.0, breakaway, 1.25)[:2] == (1.5, 0.0)
    half = friction_step(0.0, 14.52, ratio, 0.5 * FRICTION_SPEED_SCALE, breakaway, 1.25)[0]
    full = friction_step(0.0, 14.52, ratio, FRICTION_SPEED_SCALE, breakaway, 1.25)[0]
    assert half == pytest.approx(0.5 * full, rel=1e-4)


def test_stribeck_decay_is_exp_within_its_stated_error():
    x = np.concatenate([np.linspace(0.0, 40.0, 4001), [1e-300, 0.5, 0.5000001, 39.999]])
    ours = np.array([stribeck_decay(float(v)) for v in x])
    np.testing.assert_allclose(ours, np.exp(-x), rtol=1e-13, atol=0)
    assert stribeck_decay(0.0) == 1.0 and stribeck_decay(40.0000001) == 0.0
    assert STRIBECK_SPEED >= 50 * FRICTION_SPEED_SCALE


@pytest.mark.parametrize("name", ["python", "native2", "native3"])
def test_near_standstill_the_friction_exceeds_the_running_one_by_the_breakaway(fmus, table, name):
    _, te_map = table
    slow, fast = 3 * FRICTION_SPEED_SCALE, 20 * STRIBECK_SPEED
    coulomb = te_map.evaluate_one(5 * slow * STEP, 0.0)[2]
    running = (coulomb + te_map.load_free_one(slow / te_map.ratio)) / te_map.ratio
    breakaway = (coulomb + te_map.seal) / te_map.ratio
    _, friction = constant_speed_friction(make(fmus, name), slow, te_map=te_map)
    excess = (friction - running) / ((te_map.static_friction_factor - 1.0) * breakaway)
    assert excess == pytest.approx(1.0, abs=2e-3), excess  # exp(-0.03^2) = 0.9991
    assert friction > running * 1.2
    # at high speed the running friction, as today
    coulomb = te_map.evaluate_one(5 * fast * STEP, 0.0)[2]
    running = (coulomb + te_map.load_free_one(fast / te_map.ratio)) / te_map.ratio
    _, friction = constant_speed_friction(make(fmus, name), fast, te_map=te_map)
    assert friction == pytest.approx(running, rel=1e-12)


def test_the_fmus_agree_on_the_breakaway_and_a_static_factor_of_1_is_todays(fmus, table, static_one):
    _, te_map = table
    t = np.arange(400) * STEP
    speed = 0.2 * np.sin(2 * np.pi * 2.0 * t)  # through zero, within the breakaway
    theta_in = np.cumsum(speed) * STEP
    tau_load = 0.3 * te_map.torque_magnitude[-1] * np.sin(2 * np.pi * 3.0 * t)
    runs = {name: drive(make(fmus, name), theta_in, tau_load) for name in ("python", "native2", "native3")}
    assert np.array_equal(runs["native2"], runs["python"])
    assert np.array_equal(runs["native3"], runs["python"])
    today = todays_run(te_map, theta_in, tau_load)
    assert np.max(np.abs(runs["python"][:, 4] - today[:, 4])) > 1e-3  # the breakaway shows
    # the native FMU with the table's static friction factor 1: today's, to the bit
    one = drive(make(fmus, "native2", unzipped=static_one), theta_in, tau_load)
    assert np.array_equal(one, today)
