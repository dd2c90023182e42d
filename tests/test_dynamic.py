"""The dynamic model against the quasi-static one, hand-known spectra, energy and bad input."""

import math

import numpy as np
import pytest

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import rad_to_arcsec
from rvfmu.core.dynamics.dynamic import DynamicModel, Motion, mesh_stiffness_factor, ramp_motion
from rvfmu.core.dynamics.newmark import NewmarkStepper, static_equilibrium
from rvfmu.core.dynamics.simulation import Excitations, simulate
from rvfmu.core.laws.stiffness import transverse_contact_ratio
from rvfmu.core.reducer.errors import ErrorSet, zero_errors
from rvfmu.core.statics.quasistatic import equilibrium_te


def with_error(design, name, index, value):
    arrays = zero_errors(design).arrays()
    array = arrays[name].copy()
    array[(0,) + index] = value
    arrays[name] = array
    return ErrorSet(**arrays)


def spectrum(signal, step):
    signal = signal - signal.mean()
    window = np.hanning(signal.size)
    return (np.fft.rfftfreq(signal.size, step), 2.0 * np.abs(np.fft.rfft(signal * window)) / window.sum())


def test_at_slow_speed_the_dynamic_te_is_the_quasi_static_te(rv40, seed002):
    """The quasi-static TE is the frictionless reducer's (docs/model.md section 5): so is the
    dynamic run it is compared with (friction's windup: tests/test_dynamic_friction.py)."""
    sim = simulate(
        rv40, seed002, speed_rpm=5.0, load=300.0, revolutions=0.02, mesh="constant", ramp=0.5, friction=False
    )
    assert sim.failed_steps == 0
    theta = sim.theta_in[sim.steady :][::5]
    dynamic = sim.steady_te_arcsec()[::5]
    te, _, _ = equilibrium_te(rv40, seed002, theta, [-300.0])
    static = rad_to_arcsec(te[0, 0])
    pp = np.ptp(static)
    assert pp > 5.0  # a real TE curve, not a flat one
    assert np.ptp(dynamic) == pytest.approx(pp, rel=0.02)
    assert np.max(np.abs(dynamic - static)) < 0.05 * pp


@pytest.mark.parametrize("name", ["rv40_rollers", "rv40_hertz"])
def test_with_the_roller_law_the_slow_dynamic_te_is_the_quasi_static_te(request, name):
    """The crank bearings follow the roller law in both models (rvfmu/core/laws/roller_law.py), and
    in `rv40_hertz` the pins their Hertz law (rvfmu/core/laws/pin_law.py)."""
    from conftest import ROOT

    from rvfmu.core.reducer.errors import load_errors

    rv40_rollers = request.getfixturevalue(name)
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", rv40_rollers)
    sim = simulate(
        rv40_rollers,
        errors,
        speed_rpm=5.0,
        load=300.0,
        revolutions=0.02,
        mesh="constant",
        ramp=0.5,
        friction=False,
    )
    assert sim.failed_steps == 0
    theta = sim.theta_in[sim.steady :][::5]
    dynamic = sim.steady_te_arcsec()[::5]
    te, _, _ = equilibrium_te(rv40_rollers, errors, theta, [-300.0])
    static = rad_to_arcsec(te[0, 0])
    assert np.ptp(static) > 5.0
    assert np.max(np.abs(dynamic - static)) < 0.01 * np.ptp(static)
    # and the law shows: the linear bearings of the stated stiffness wind up less
    linear, _, _ = equilibrium_te(
        rv40_rollers.with_fields(needle_rollers=0, tapered_rollers=0), errors, theta, [-300.0]
    )
    assert np.mean(rad_to_arcsec(linear[0, 0]) - static) > 1.0


def test_at_a_small_load_and_slow_speed_the_dynamic_te_is_the_no_load_limit(rv40, seed002):
    small = 5e-4 * rv40.rated_torque  # 0.2 N*m
    sim = simulate(
        rv40, seed002, speed_rpm=5.0, load=small, revolutions=0.01, mesh="constant", ramp=0.5, friction=False
    )
    theta = sim.theta_in[sim.steady :][::5]
    te, _, _ = equilibrium_te(rv40, seed002, theta, [0.0])
    no_load = rad_to_arcsec(te[0, 0])
    dynamic = sim.steady_te_arcsec()[::5]
    assert np.max(np.abs(dynamic - no_load)) < 0.05 * np.ptp(no_load)


def test_exact_reducer_without_errors_runs_flat_and_the_varying_mesh_shows_at_its_frequency(rv40):
    exact = rv40.with_fields(d_rp=0.0, d_rrp=0.0)
    # frictionless: the pins' friction varies with pin passing too (their sliding arms), a
    # ripple of its own (tests/test_dynamic_friction.py)
    constant = simulate(exact, None, 1600.0, load=206.0, duration=0.25, mesh="constant", friction=False)
    # arcsec: the pin-passing load sharing (0.014 arcsec quasi-static at this load) and what
    # the start leaves ringing in the lightly damped modes
    assert constant.te_pp_arcsec < 0.1
    varying = simulate(exact, None, 1600.0, load=206.0, duration=0.25, mesh="varying", friction=False)
    mesh_hz = Excitations.at(exact, 1600.0).mesh
    f, a = varying.spectrum_hz()
    below = f < 1000.0  # the excitations, not the kHz modes
    peak = f[below][np.argmax(a[below])]
    assert abs(peak - mesh_hz) <= 2 * (f[1] - f[0])
    assert varying.te_pp_arcsec > 5 * constant.te_pp_arcsec


def test_mesh_stiffness_steps_between_single_and_double_pair_contact(rv40):
    eps = transverse_contact_ratio(rv40.z_s, rv40.z_pl, rv40.m, rv40.pressure_angle)
    teeth = np.linspace(0.0, 3.0, 3001)[:-1]
    theta_in = 2 * math.pi * teeth / rv40.z_s
    factor = mesh_stiffness_factor(rv40, theta_in, np.zeros_like(theta_in))[:, 0]
    single = 1.0 / (0.75 * eps + 0.25)
    assert set(np.round(factor / single, 12)) == {1.0, 1.75}
    assert np.mean(factor == 1.75 * single) == pytest.approx(eps - 1.0, abs=2e-3)
    assert factor.mean() == pytest.approx(1.0, abs=2e-3)  # the mean is ISO's c_gamma


@pytest.fixture(scope="module")
def base(rv40):
    """The error-free RV-40E-121 at 1600 rpm and half its rated load, 0.5 s after the ramp."""
    return simulate(rv40, None, 1600.0, load=206.0, duration=0.5, mesh="constant")


def test_a_crank_cam_eccentricity_puts_its_te_at_the_crank_frequency(rv40, base):
    cam = simulate(
        rv40,
        with_error(rv40, "crank_cam_eccentricity", (0, 0), 5e-6),
        1600.0,
        load=206.0,
        duration=0.5,
        mesh="constant",
        step=base.step,
    )  # base's time grid
    f, a = spectrum(cam.steady_te_arcsec() - base.steady_te_arcsec(), cam.step)
    crank = Excitations.at(rv40, 1600.0).crank
    assert abs(f[np.argmax(a)] - crank) <= 1.5 * (f[1] - f[0])


def test_a_sun_eccentricity_turns_with_the_input_and_cancels_in_the_te(rv40, base):
    """Each planet's mesh sees the eccentricity at the input rotation frequency relative to the
    carrier; for equally spaced planets the tangential parts sum to zero (sum of t_i = 0), so
    the TE keeps only a second-order trace, far below E / r_b / i of a fixed-axis pair."""
    sun = simulate(
        rv40,
        with_error(rv40, "sun_eccentricity", (), 5e-6),
        1600.0,
        load=206.0,
        duration=0.5,
        mesh="constant",
        step=base.step,
    )
    crank = sun.dofs.index("crank0_rot")
    f, a = spectrum(sun.q[sun.steady :, crank] - base.q[base.steady :, crank], sun.step)
    ex = Excitations.at(rv40, 1600.0)
    assert abs(f[np.argmax(a)] - (ex.input - ex.output)) <= 1.5 * (f[1] - f[0])
    fixed_axis = rad_to_arcsec(5e-6 / rv40.sun_base_radius / rv40.ratio)
    change = np.ptp(sun.steady_te_arcsec() - base.steady_te_arcsec())
    assert change < 0.1 * fixed_axis


@pytest.mark.parametrize("rollers", [False, True], ids=["linear bearings", "roller law"])
def test_newmark_conserves_energy_without_damping_load_or_input_motion(rv40, rv40_rollers, seed002, rollers):
    design = (rv40_rollers if rollers else rv40).with_fields(damping_ratio=0.0)
    model = DynamicModel(design, seed002, contact="linear", mesh="constant", friction=False)
    steps = 4000
    time = np.arange(steps) * 2e-6
    model.prepare(Motion(time, np.zeros(steps), np.zeros(steps), np.zeros(steps)))
    # released from its equilibrium under rated load: free vibration with pins opening and closing
    q0 = static_equilibrium(model, -design.rated_torque * model.load_vector(), 0)
    stepper = NewmarkStepper.starting_at(model, q0)
    energies = [model.energy(0, q0, np.zeros(model.n))]
    for _ in range(steps - 1):
        state = stepper.step()
        energies.append(model.energy(stepper.k, state.q, state.v))
    energies = np.array(energies)
    assert energies[0] > 0
    assert np.max(np.abs(energies / energies[0] - 1.0)) < 0.01  # stated tolerance: 1 %


def test_ramp_motion_is_smooth_and_reaches_speed():
    t = np.linspace(0.0, 0.2, 2001)
    m = ramp_motion(t, 100.0, 0.1)
    assert m.omega_in[0] == 0.0 and m.alpha_in[0] == 0.0 and m.omega_in[-1] == 100.0
    np.testing.assert_allclose(np.gradient(m.theta_in, t), m.omega_in, atol=0.05)
    assert m.theta_in[-1] == pytest.approx(100.0 * 0.05 + 100.0 * 0.1)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"duration": -1.0}, "duration"),
        ({"speed_rpm": 0.0}, "speed_rpm"),
        ({"speed_rpm": float("nan")}, "speed_rpm"),
        ({"step": 0.0}, "step"),
        ({"step": 1e-2}, "step"),
        ({"load": 5000.0}, "load"),
        ({"contact": "soft"}, "contact"),
        ({"duration": 1.0, "revolutions": 1.0}, "duration"),
        ({"duration": 1e6}, "duration"),  # 6.9e9 steps: more than the memory holds
        ({"duration": None, "revolutions": 1e5}, "revolutions"),
    ],
)
def test_bad_simulation_input_is_refused_naming_the_field(rv40, changes, field):
    options = {"speed_rpm": 1600.0, "duration": 0.01, **changes}
    with pytest.raises(InputError) as info:
        simulate(rv40, None, **options)
    assert info.value.field == field


def test_rvte_simulate_prints_writes_and_speaks_json(tmp_path, capsys):
    import json
    import re

    from rvfmu import cli

    csv_path, plot = tmp_path / "sim.csv", tmp_path / "sim.png"
    assert (
        cli.main(
            [
                "simulate",
                "RV-40E-121",
                "--load",
                "206",
                "--duration",
                "0.05",
                "--csv",
                str(csv_path),
                "--plot",
                str(plot),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "at constant speed (after the start ramp)" in out and "te_pp" in out
    # 0.05 s at speed is too short to resolve the mesh from pin passing, 26 Hz away (0.114 s)
    assert (
        re.search(r"\n  stage-1 mesh +317\.36   not resolved: needs \u2265 0\.114 s of record\n", out)
        and plot.stat().st_size > 0
    )
    rows = np.loadtxt(csv_path, delimiter=",", skiprows=1)
    header = csv_path.read_text().splitlines()[0]
    assert header == "time_s,theta_in_rad,theta_out_rad,te_arcsec,tau_in_Nm"
    np.testing.assert_allclose(rad_to_arcsec(rows[:, 2] - rows[:, 1] / 121.0), rows[:, 3], atol=2e-6)
    assert cli.main(["simulate", "RV-40E-121", "--duration", "0.05", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["te_pp_arcsec"] == pytest.approx(data["te_range_arcsec"][1] - data["te_range_arcsec"][0])
    assert all(len(peak) == 2 for peak in data["peaks"])
    assert cli.main(["simulate", "RV-40E-121", "--step", "-1"]) == 2
    assert capsys.readouterr().err == "rvte simulate: error: step = -1.0: must be > 0\n"


def test_newmark_agrees_with_scipys_adaptive_bdf_on_a_short_run(rv40, seed002):
    """A hard start (1600 rpm in 4 ms) and 4 ms at speed: inertia, contacts, friction and
    errors all act.  Newmark at an eighth of the default step against solve_ivp (BDF, rtol
    1e-8): tau_in carries the input shaft's ringing (kHz), whose phase a quarter of the step
    no longer holds to 2 % once the mesh friction acts on the sun."""
    from rvfmu.core.dynamics.simulation import default_step

    options = dict(
        speed_rpm=1600.0,
        load=206.0,
        duration=0.004,
        mesh="constant",
        ramp=0.004,
        step=default_step(rv40, 1600.0) / 8,
    )
    newmark = simulate(rv40, seed002, **options)
    reference = simulate(rv40, seed002, method="BDF", **options)
    span = np.ptp(reference.te_arcsec)
    assert span > 3.0  # arcsec: the start moves the output
    assert np.max(np.abs(newmark.te_arcsec - reference.te_arcsec)) < 0.02 * span
    np.testing.assert_allclose(newmark.tau_in, reference.tau_in, atol=0.02 * np.ptp(reference.tau_in))


def test_rvte_modes_lists_modes_beside_the_excitations(tmp_path, capsys):
    import json

    from rvfmu import cli
    from rvfmu.core.dynamics.modes import modes

    plot = tmp_path / "campbell.png"
    assert cli.main(["modes", "RV-40E-121", "--load", "412", "--count", "4", "--plot", str(plot)]) == 0
    out = capsys.readouterr().out.splitlines()
    reference = modes(preset_rv40(), None, load=412.0)
    first = out[2].split()
    assert first[0] == "1" and float(first[1]) == pytest.approx(reference.frequencies_hz[0], abs=0.05)
    assert "torsion" in out[2] and "%" in out[2]
    assert out[6].startswith("excitations at 1600 rpm: input rotation 26.7 Hz, crank rotation 8.8 Hz")
    assert plot.stat().st_size > 0
    assert cli.main(["modes", "RV-40E-121", "--load", "412", "--count", "3", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["modes"]) == 3 and data["excitations_hz"]["stage-1 mesh"] == pytest.approx(
        317.355, abs=1e-3
    )
    assert cli.main(["modes", "RV-40E-121", "--count", "0"]) == 2
    assert "count = 0: must be >= 1" in capsys.readouterr().err


def preset_rv40():
    from rvfmu.core.reducer.design import preset

    return preset("RV-40E-121")


@pytest.mark.parametrize("contact, rollers", [("linear", False), ("impact", False), ("linear", True)])
def test_tangent_stiffness_and_damping_are_the_derivatives_of_the_forces(
    rv40, rv40_rollers, seed002, contact, rollers
):
    from rvfmu.core.dynamics.simulation import _quasi_static_start

    design = rv40_rollers if rollers else rv40
    model = DynamicModel(design, seed002, contact=contact, mesh="varying")
    model.prepare(ramp_motion(np.array([0.0, 1e-4]), 100.0, 0.0))
    q = _quasi_static_start(model, design, seed002, -300.0, 1)
    model.set_modal_damping(q)
    rng = np.random.default_rng(3)
    v = rng.normal(0.0, 1e-4, model.n)
    f, K, C = model.forces(1, q, v)
    for k in rng.choice(model.n, 6, replace=False):
        dq = np.zeros(model.n)
        dq[k] = 1e-11
        df = (model.forces(1, q + dq, v)[0] - model.forces(1, q - dq, v)[0]) / 2e-11
        np.testing.assert_allclose(df, K[:, k], rtol=1e-4, atol=1e-6 * np.abs(K).max())
        dv = dq * 1e3
        dfv = (model.forces(1, q, v + dv)[0] - model.forces(1, q, v - dv)[0]) / 2e-8
        np.testing.assert_allclose(dfv, C[:, k], rtol=1e-4, atol=1e-6 * np.abs(C).max())


def test_the_impact_law_meets_the_linear_law_at_the_rated_pin_deflection(rv40):
    from rvfmu.core.dynamics.dynamic import IMPACT_EXPONENT

    model = DynamicModel(rv40, zero_errors(rv40), contact="impact")
    reference = model._rated_pin_deflection()
    assert model.impact_k * reference**IMPACT_EXPONENT == pytest.approx(model.pin_k * reference)
    assert 1e-6 < reference < 1e-5  # m: a few micrometres under rated torque
