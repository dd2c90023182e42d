"""Friction (`rvte efficiency`): each loss law against its closed form, the power balance,
the kinematics it rests on, and the efficiency map's physics."""

import json
import math

import numpy as np
import pytest
from conftest import ROOT, unit
from test_cli import rvte

from rvfmu import api
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import DEG, MM
from rvfmu.core.laws.stiffness import transverse_contact_ratio
from rvfmu.core.losses import friction
from rvfmu.core.losses.hysteresis import hysteresis
from rvfmu.core.reducer.design import PRESET_NAMES, preset, preset_file
from rvfmu.core.statics.equivalent import EquivalentModel
from rvfmu.core.statics.quasistatic import equilibria, te_curve, windup
from rvfmu.core.steppers.reducer_model import FRICTION_SPEED_SCALE, QuasiStaticReducer, friction_step
from rvfmu.core.steppers.te_map import build_te_map
from tolerance.evaluate import evaluate
from tolerance.sampling import errors_from_unit
from tolerance.study import load_study

FRICTION_FIELDS = (
    "pin_disc_friction",
    "pin_groove_friction",
    "mesh_friction",
    "needle_friction",
    "tapered_friction",
    "main_bearing_friction",
    "bearing_drag_factor",
    "seal_torque",
    "lubricant_fill",
    "seal_friction_K_S1",
    "seal_friction_K_S2",
)
NO_FRICTION = {name: 0.0 for name in FRICTION_FIELDS}


@pytest.fixture(scope="module")
def rv40_map():
    return friction.efficiency_map(
        preset("RV-40E-121"),
        output_speed_rpm=[5.0, 15.0, 30.0, 60.0],
        load_Nm=[103.0, 206.0, 412.0],
        points=12,
    )


# -- the laws alone ---------------------------------------------------------------------------


def test_mesh_loss_factor_by_hand():
    """H_V = pi (u+1)/(z_1 u) (1 - eps_a + eps_1^2 + eps_2^2) (ISO/TR 14179-2), the addendum
    contact ratios adding up to the path-of-contact contact ratio of the mesh stiffness."""
    h_v, eps_1, eps_2 = friction.mesh_loss_factor(20, 20, 20.0 * DEG)
    eps = transverse_contact_ratio(20, 20, 1.0 * MM, 20.0 * DEG)
    assert eps_1 + eps_2 == pytest.approx(eps, rel=1e-12)
    assert eps_1 == pytest.approx(eps_2, rel=1e-12)
    assert h_v == pytest.approx(math.pi * 2.0 / 20.0 * (1.0 - eps + 2.0 * (eps / 2.0) ** 2), rel=1e-12)
    assert h_v == pytest.approx(0.2058, abs=2e-4)
    h_v, eps_1, eps_2 = friction.mesh_loss_factor(12, 36, 20.0 * DEG)
    assert eps_1 + eps_2 == pytest.approx(transverse_contact_ratio(12, 36, 1.5 * MM, 20.0 * DEG), rel=1e-12)
    assert h_v == pytest.approx(
        math.pi * (3.0 + 1.0) / 36.0 * (1.0 - eps_1 - eps_2 + eps_1**2 + eps_2**2), rel=1e-12
    )


def test_palmgren_drag_by_hand():
    # 1e-7 f0 (nu n)^(2/3) d_m^3 N*mm: f0 = 2, nu = 100 cSt, n = 1000 rpm, d_m = 20 mm
    assert friction.bearing_drag_moment(2.0, 100.0, 1000.0, 20 * MM) == pytest.approx(
        1e-7 * 2.0 * 1e5 ** (2.0 / 3.0) * 8000.0 * 1e-3, rel=1e-12
    )
    # below nu n = 2000 Palmgren's constant 160e-7 f0 d_m^3
    assert friction.bearing_drag_moment(2.0, 100.0, 5.0, 20 * MM) == pytest.approx(
        160e-7 * 2.0 * 8000.0 * 1e-3, rel=1e-12
    )
    # continuous and rising with speed
    speeds = np.linspace(0.0, 100.0, 2001)
    drag = friction.bearing_drag_moment(2.0, 100.0, speeds, 20 * MM)
    assert np.all(np.diff(drag) >= 0.0)
    assert np.max(np.abs(np.diff(drag))) < 1e-3 * drag[-1]


def test_the_disc_slides_past_each_pin_about_its_pitch_point():
    """The disc point at a pin's contact moves, by the rigid kinematics of docs/model.md section 2
    (centre e u(psi), psi = -z_c theta_out + j pi, turning with the carrier), along the
    contact tangent at |theta_out'| times `pin_slide_arm`: a finite difference by hand."""
    d = preset("RV-40E-121")
    theta_in = np.array([0.0, 0.7, 2.3])
    model = EquivalentModel(d, theta_in)
    h = 1e-6 * d.ratio  # an output step of 1e-6 rad

    def disc_point(theta_in_now, point, theta_in_then):
        """Where the disc's material point `point` (at theta_in_then) is at theta_in_now."""
        out_then, out_now = theta_in_then / d.ratio, theta_in_now / d.ratio

        def psi(out):
            return -d.z_c * out + np.array([0.0, np.pi])

        c_then, c_now = d.e * unit(psi(out_then)), d.e * unit(psi(out_now))
        turn = out_now - out_then
        rel = point - c_then[..., None, :]
        rotated = np.stack(
            [
                math.cos(turn) * rel[..., 0] - math.sin(turn) * rel[..., 1],
                math.sin(turn) * rel[..., 0] + math.cos(turn) * rel[..., 1],
            ],
            axis=-1,
        )
        return c_now[..., None, :] + rotated

    pins = d.R_p * unit(2 * np.pi * np.arange(d.z_p) / d.z_p)
    for a, t in enumerate(theta_in):
        psi = -d.z_c * t / d.ratio + np.array([0.0, np.pi])
        pitch = d.z_p * d.e * unit(psi)
        normal = pins[None] - pitch[:, None]
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        contact = pins[None] - d.r_rp * normal  # (2, z_p, 2)
        velocity = (disc_point(t + h, contact, t) - disc_point(t - h, contact, t)) / (2e-6)
        speed = np.linalg.norm(velocity, axis=-1)
        assert speed == pytest.approx(model.pin_slide_arm[a], rel=1e-6)
        # it slides: no approach along the normal
        assert np.max(np.abs((velocity * normal).sum(axis=-1))) < 1e-6 * speed.max()


def test_the_pins_carry_the_housing_torque_with_the_lever_the_losses_use(rv40_hertz):
    """The pin forces of the frictionless equilibrium, on their normals through the pitch
    point, hold the housing's torque T (1 - 1/i): the forces and geometry the pin loss uses."""
    d = rv40_hertz
    torque = 0.6 * d.rated_torque
    loads = friction.contact_loads(d, None, [-torque], friction.crank_turn_angles(d, 6))
    assert loads.converged.all()
    model = EquivalentModel(d, friction.crank_turn_angles(d, 6))
    psi = model.pose.psi  # (A, 2)
    pin_angle = 2 * np.pi * np.arange(d.z_p) / d.z_p
    reach = model.pin_slide_arm + d.r_rp
    arm_about_centre = d.R_p * d.z_p * d.e * np.abs(np.sin(pin_angle - psi[..., None])) / reach
    held = (loads.pin_force[0, 0] * arm_about_centre).sum(axis=(1, 2))
    assert held == pytest.approx(torque * (1.0 - 1.0 / d.ratio), rel=1e-4)
    # and the frictionless input torque is T/i (to the few parts in a million that the
    # deformed pose changes the lever ratio by)
    assert np.abs(loads.tau_in[0, 0]) == pytest.approx(torque / d.ratio, rel=1e-5)


# -- the power balance ------------------------------------------------------------------------


def test_without_friction_the_efficiency_is_one_and_nothing_else_moves(rv40_hertz, seed002):
    d = rv40_hertz.with_fields(
        needle_pitch_diameter=21 * MM, tapered_pitch_diameter=22 * MM, main_bearing_pitch_diameter=128 * MM
    )
    free = d.with_fields(**NO_FRICTION)
    m = friction.efficiency_map(free, output_speed_rpm=[5.0, 60.0], load_Nm=[100.0, 400.0], points=4)
    assert np.all(m.efficiency == 1.0) and np.all(m.backdriving_efficiency == 1.0)
    assert np.all(m.loss_W == 0.0) and np.all(m.no_load_running_torque_Nm == 0.0)
    assert m.starting_torque_input_Nm == 0.0 and m.backdriving_torque_output_Nm == 0.0
    assert m.input_torque_Nm == pytest.approx(np.broadcast_to([100.0, 400.0], (2, 2)) / d.ratio, rel=1e-14)
    # the elastic model knows nothing of friction: TE at no load and under load bit for bit
    for load in (0.0, 200.0):
        with_friction = te_curve(d, seed002, tau_load=-load, points=24)
        without = te_curve(free, seed002, tau_load=-load, points=24)
        assert np.array_equal(with_friction.te, without.te)


def test_power_balance_and_each_loss_at_every_point(rv40_map):
    m = rv40_map
    w = m.output_speed_rpm[:, None] * friction.RPM
    p_out = m.load_Nm[None] * w
    p_in = m.input_torque_Nm * m.design.ratio * w
    lost = sum(m.losses.values())
    assert p_in == pytest.approx(p_out + lost, rel=1e-12)
    assert m.loss_W == pytest.approx(lost, rel=1e-12)
    for name in friction.LOSS_NAMES:
        assert np.all(m.losses[name] >= 0.0), name
    # every kind of contact the preset gives friction to loses something
    for name in friction.LOSS_NAMES[:-1]:
        assert np.all(m.losses[name] > 0.0), name
    assert m.converged


def test_backdriving_below_forward_and_running_torque_rising_with_speed(rv40_map):
    m = rv40_map
    assert np.all(m.backdriving_efficiency < m.efficiency)
    assert np.all(m.efficiency < 1.0) and np.all(m.efficiency > 0.5)
    assert np.all(np.diff(m.no_load_running_torque_Nm) > 0.0)
    # from rest the Coulomb contacts and the seals break away above their running friction
    assert m.starting_torque_input_Nm > m.no_load_running_torque_Nm[0]
    assert m.backdriving_torque_output_Nm == pytest.approx(
        m.design.ratio * m.starting_torque_input_Nm, rel=1e-12
    )


def test_load_free_losses_make_the_efficiency_rise_with_torque():
    """The drag and the seal lose the same power at any torque, so with them alone the
    efficiency rises with torque at every speed; the Coulomb losses alone grow about in
    proportion to the torque, which leaves the efficiency nearly flat (the pins that the
    load brings into contact have a longer sliding arm for their lever)."""
    d = preset("RV-40E-121")
    coulomb = {
        "pin_disc_friction",
        "pin_groove_friction",
        "mesh_friction",
        "needle_friction",
        "tapered_friction",
        "main_bearing_friction",
    }
    drag_only = d.with_fields(**{k: 0.0 for k in coulomb}, seal_torque=1.0)
    kw = dict(output_speed_rpm=[5.0, 30.0], load_Nm=[50.0, 150.0, 300.0, 412.0], points=6)
    m = friction.efficiency_map(drag_only, **kw)
    assert np.all(np.diff(m.efficiency, axis=1) > 0.0)
    m = friction.efficiency_map(
        d.with_fields(
            bearing_drag_factor=0.0, lubricant_fill=0.0, seal_friction_K_S1=0.0, seal_friction_K_S2=0.0
        ),
        **kw,
    )
    assert np.ptp(m.efficiency) < 0.01
    # at a given torque, a Coulomb loss is proportional to speed and the efficiency the same
    assert m.efficiency[0] == pytest.approx(m.efficiency[1], rel=1e-12)


def test_a_pin_loses_with_the_smaller_of_its_two_coefficients():
    d = preset("RV-40E-121")
    kw = dict(output_speed_rpm=[15.0], load_Nm=[300.0], points=4)
    base = friction.efficiency_map(d, **kw).losses["pins"]
    assert friction.efficiency_map(d.with_fields(pin_groove_friction=0.0), **kw).losses["pins"] == 0.0
    assert friction.efficiency_map(d.with_fields(pin_disc_friction=0.2), **kw).losses[
        "pins"
    ] == pytest.approx(base, rel=1e-12)
    both = friction.efficiency_map(d.with_fields(pin_disc_friction=0.1, pin_groove_friction=0.1), **kw)
    assert both.losses["pins"] == pytest.approx(2.0 * base, rel=1e-12)


# -- the presets' geometry and the job --------------------------------------------------------


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_preset_pitch_diameters_follow_their_rule(name):
    stated = preset_file(name)
    for key, value in friction.pitch_diameters_from_sources(stated).items():
        assert stated[key] == pytest.approx(value, rel=5e-4), key


def test_efficiency_job_json_and_plot(tmp_path):
    plot = tmp_path / "efficiency.png"
    proc = rvte(
        "efficiency",
        "RV-40E-121",
        "--errors",
        ROOT / "studies" / "seed002_errors.toml",
        "--speeds",
        "5,30",
        "--loads",
        "200,412",
        "--json",
        "--plot",
        plot,
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert {
        "map",
        "no_load_running_torque",
        "starting_torque_input_Nm",
        "backdriving_torque_output_Nm",
    } <= set(data)
    assert len(data["map"]) == 4 and len(data["no_load_running_torque"]) == 2
    for point in data["map"]:
        assert {
            "output_speed_rpm",
            "load_Nm",
            "efficiency",
            "backdriving_efficiency",
            "input_torque_Nm",
        } <= set(point)
        assert 0.0 < point["backdriving_efficiency"] < point["efficiency"] < 1.0
    report = api.efficiency(
        "RV-40E-121", ROOT / "studies" / "seed002_errors.toml", speeds=[5, 30], loads=[200, 412]
    )
    assert data["map"][-1]["efficiency"] == pytest.approx(float(report.map.efficiency[-1, -1]), rel=1e-12)
    assert plot.read_bytes()[:4] == b"\x89PNG"


def test_efficiency_command_checks_its_inputs_first(tmp_path):
    proc = rvte("efficiency", "RV-40E-121", "--plot", tmp_path / "missing" / "e.png")
    assert proc.returncode == 2 and "plot" in proc.stderr and "does not exist" in proc.stderr
    proc = rvte("efficiency", "RV-40E-121", "--speeds", "5,x")
    assert proc.returncode == 2 and "--speeds" in proc.stderr
    proc = rvte("efficiency", "RV-40E-121", "--loads", "-5")
    assert proc.returncode == 2 and "loads = -5" in proc.stderr
    proc = rvte("efficiency", "RV-40E-121", "--loads", "5000")
    assert proc.returncode == 2 and "loads" in proc.stderr
    with pytest.raises(InputError, match="speeds"):
        friction.efficiency_map(preset("RV-40E-121"), output_speed_rpm=[])
    with pytest.raises(InputError, match="pin_disc_friction_coefficient"):
        preset("RV-40E-121").with_fields(pin_disc_friction=-0.1)


# -- the hysteresis loop ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def rv40_loop():
    return hysteresis(preset("RV-40E-121"), positions=4)


def test_the_loop_reads_the_windup_tests_figures_and_its_area_is_the_friction_work(rv40_loop):
    h = rv40_loop
    assert h.converged
    wind = windup(h.design, positions=4)
    assert h.lost_motion_arcmin == pytest.approx(wind.lost_motion_arcmin()[0], rel=1e-9)
    assert h.torsional_rigidity_Nm_per_arcmin == pytest.approx(
        wind.torsional_rigidity_Nm_per_arcmin()[0], rel=1e-9
    )
    work = sum(h.friction_work_J.values())
    assert work > 0.0 and h.area_J == pytest.approx(work, rel=1e-9)
    assert all(v >= 0.0 for v in h.friction_work_J.values())
    assert np.all(h.friction_torque >= 0.0)
    # the loading branch lies right of the frictionless path, the unloading one left of it
    half = h.loop.shape[0] // 2
    up, down = h.loop[:half], h.loop[half:][::-1]
    assert np.all(up[:, 0] >= down[:, 0]) and np.array_equal(up[:, 1], down[:, 1])


def test_friction_opens_the_loop_in_proportion_to_the_coefficients(rv40_loop):
    """Without friction the loop closes (its width at zero torque is the clearance the output
    crosses there); the Coulomb work is linear in the coefficients."""
    d = rv40_loop.design
    free = hysteresis(d.with_fields(**NO_FRICTION), positions=4)
    assert np.all(free.friction_torque == 0.0)
    # the two branches are the same path: the shoelace sum cancels to round-off
    assert free.area_J <= 1e-9 * rv40_loop.area_J
    assert rv40_loop.hysteresis_loss_arcmin > free.hysteresis_loss_arcmin > 0.0
    coulomb = d.with_fields(bearing_drag_factor=0.0)
    doubled = coulomb.with_fields(
        **{k: 2.0 * getattr(coulomb, k) for k in FRICTION_FIELDS if k != "bearing_drag_factor"}
    )
    once, twice = (hysteresis(x, positions=4) for x in (coulomb, doubled))
    for name in friction.LOSS_NAMES:
        assert twice.friction_work_J[name] == pytest.approx(
            2.0 * once.friction_work_J[name], rel=1e-12, abs=1e-18
        ), name


def test_hysteresis_job_json_plot_and_errors(tmp_path):
    plot = tmp_path / "loop.png"
    proc = rvte("hysteresis", "RV-40E-121", "--max-load", "206", "--json", "--plot", plot)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert {"lost_motion_arcmin", "hysteresis_loss_arcmin", "friction_work_J", "loop"} <= set(data)
    # 206 N*m is half the rated torque: no rigidity over 50-100 % of rated
    assert data["torsional_rigidity_Nm_per_arcmin"] is None
    assert plot.read_bytes()[:4] == b"\x89PNG"
    proc = rvte("hysteresis", "RV-40E-121", "--max-load", "0")
    assert proc.returncode == 2 and "max_load = 0" in proc.stderr
    proc = rvte("hysteresis", "RV-40E-121", "--plot", tmp_path / "missing" / "l.png")
    assert proc.returncode == 2 and "does not exist" in proc.stderr


# -- the study metrics ------------------------------------------------------------------------

STUDY = """
[study]
design = "RV-40E-121"
seed = 7
metrics = {metrics}
batch_size = 4

[operating]
load_Nm = {load}
points = 72
{speed}

[spec]
{spec}

[tolerances.crank_cam_eccentricity]
position_um = 9.0
"""


def study_file(
    tmp_path,
    metrics='["efficiency", "no_load_running_torque"]',
    load=300.0,
    speed="output_speed_rpm = 30.0",
    spec="efficiency = 0.9",
):
    path = tmp_path / "fric.toml"
    path.write_text(STUDY.format(metrics=metrics, load=load, speed=speed, spec=spec))
    return path


def test_study_metrics_are_the_efficiency_maps(tmp_path):
    study = load_study(study_file(tmp_path))
    assert study.metric_columns == ("efficiency", "no_load_running_torque_Nm")
    assert study.spec[0].sense == "min"
    X = np.random.default_rng(3).random((3, len(study.columns)))
    Y, converged = evaluate(study, X)
    assert converged.all()
    errors = errors_from_unit(study, X)
    for s in range(3):
        m = friction.efficiency_map(study.design, errors, output_speed_rpm=[30.0], load_Nm=[300.0], sample=s)
        assert Y[s, 0] == pytest.approx(m.efficiency[0, 0], rel=1e-12)
        assert Y[s, 1] == pytest.approx(m.no_load_running_torque_Nm[0], rel=1e-12)
    # the output speed is part of the identity only where a friction metric is asked for
    assert study.inputs()["operating"]["output_speed_rpm"] == 30.0
    te_only = load_study(study_file(tmp_path, metrics='["te_pp"]', spec=""))
    assert "output_speed_rpm" not in te_only.inputs()["operating"]


def test_study_friction_metrics_check_their_operating_point(tmp_path):
    with pytest.raises(InputError, match="operating.load_Nm = 0.0.*efficiency"):
        load_study(study_file(tmp_path, load=0.0))
    with pytest.raises(InputError, match="operating.output_speed_rpm = -5"):
        load_study(study_file(tmp_path, speed="output_speed_rpm = -5.0"))
    # the running torque alone is fine without a load
    assert (
        load_study(study_file(tmp_path, metrics='["no_load_running_torque"]', load=0.0, spec="")).load_Nm
        == 0.0
    )


# -- the FMUs' friction ---------------------------------------------------------------------


def test_the_te_map_carries_the_friction_of_the_same_solves(seed002):
    """The map's TE and input torque are the quasi-static model's to the bit (the same solves
    give the friction table), its Coulomb table is `coulomb_torques` of those equilibria, and
    its load-free table is Palmgren's drag and the seal within the table's interpolation."""
    d = preset("RV-40E-121")
    te_map = build_te_map(d, seed002, points=48, torque_fractions=(0.0, 0.5, 1.0))
    for branch, (sign, side) in enumerate(((-1.0, -1), (1.0, 1))):
        eq = equilibria(d, seed002, te_map.theta_in, sign * te_map.torque_magnitude, zero_side=side)
        assert np.array_equal(te_map.te[branch], eq.te[0])
        assert np.array_equal(te_map.tau_in[branch], eq.tau_in[0])
    m = friction.efficiency_map(d, seed002, output_speed_rpm=[7.0], load_Nm=[0.5 * d.rated_torque], points=6)
    # the map's Coulomb torque, averaged over its angles, is the efficiency map's loss / speed
    coulomb = m.loss_W[0, 0] / (7.0 * friction.RPM) - sum(friction.load_free_torques(d, [7.0]).values())[0]
    assert te_map.friction[0, 1].mean() == pytest.approx(coulomb, rel=0.05)
    speeds = np.geomspace(1e-3, 20.0, 50)
    exact = sum(friction.load_free_torques(d, speeds / friction.RPM).values())
    table = [te_map.load_free_one(w) for w in speeds]
    assert table == pytest.approx(exact, rel=2e-3)
    assert te_map.load_free_one(-3.0) == te_map.load_free_one(3.0)


def test_without_friction_the_reducer_models_input_torque_is_the_maps(seed002):
    d = preset("RV-40E-121").with_fields(**NO_FRICTION)
    te_map = build_te_map(d, seed002, points=48, torque_fractions=(0.0, 0.5, 1.0, 2.5))
    assert not te_map.friction.any() and not te_map.drag.any()
    model = QuasiStaticReducer(te_map)
    model.initialize(0.0, 0.0, -100.0)
    for k in range(1, 200):
        theta, load = 0.37 * k - 3.0, 150.0 * (k % 5 - 2)
        out = model.step((k - 1) * 1e-3, 1e-3, theta, load)
        assert out.tau_in == te_map.evaluate_one(theta, load)[1] and out.p_loss == 0.0
        assert out.efficiency in (0.0, 1.0)


def test_friction_step_by_hand():
    """Coulomb beyond the speed scale, proportional within it; efficiency both ways."""
    scale = FRICTION_SPEED_SCALE
    tau_in, p_loss, eta = friction_step(-2.0, 12.1, 121.0, 5.0)  # driving forward
    assert tau_in == pytest.approx(-2.1) and p_loss == pytest.approx(0.5)
    assert eta == pytest.approx(10.0 / 10.5)
    tau_in, p_loss, eta = friction_step(2.0, 12.1, 121.0, 5.0)  # backdriven
    assert tau_in == pytest.approx(1.9) and eta == pytest.approx(9.5 / 10.0)
    tau_in, p_loss, eta = friction_step(2.0, 12.1, 121.0, -0.5 * scale)  # within the scale
    assert tau_in == pytest.approx(2.05) and p_loss == pytest.approx(0.05 * 0.5 * scale)
    assert friction_step(0.05, 12.1, 121.0, 5.0)[2] == 0.0  # cannot backdrive
    assert friction_step(2.0, 12.1, 121.0, 0.0) == (2.0, 0.0, 0.0)  # standstill


def test_the_jobs_report_progress_to_their_total():
    for job, kwargs in (
        (api.efficiency, dict(speeds=[5.0], loads=[100.0, 200.0])),
        (api.hysteresis, dict(max_load=103.0)),
    ):
        seen = []
        job("RV-40E-121", progress=lambda total, done: seen.append((total, done)), **kwargs)
        assert seen and seen[-1][0] == seen[-1][1]
        assert all(b[1] > a[1] for a, b in zip(seen, seen[1:]))
