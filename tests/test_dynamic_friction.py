"""Friction in the dynamic model (docs/model.md section 9): the regularised law, its tangent,
the power balance in time, agreement with the quasi-static power balance, standstill."""

import math

import numpy as np
import pytest

from rvfmu.core.dynamics.dynamic import DynamicModel, ramp_motion
from rvfmu.core.dynamics.kernels import regularised_sign
from rvfmu.core.dynamics.newmark import NewmarkStepper
from rvfmu.core.dynamics.simulation import simulate, static_start
from rvfmu.core.losses.friction import RPM, efficiency_map
from rvfmu.core.reducer.errors import zero_errors
from rvfmu.core.steppers.dynamic_reducer import DynamicReducer

FRICTIONLESS = dict(
    pin_disc_friction=0.0,
    pin_groove_friction=0.0,
    mesh_friction=0.0,
    needle_friction=0.0,
    tapered_friction=0.0,
    main_bearing_friction=0.0,
    bearing_drag_factor=0.0,
    seal_torque=0.0,
    output_seal_diameter=0.0,
    input_seal_diameter=0.0,
    lubricant_fill=0.0,
)


@pytest.fixture(scope="module")
def rv40f(rv40):
    """The estimate with the preset's bearing pitch diameters, its output seal stated at
    0.5 N*m, its input seal, lubricant fill and static friction factor the preset's: every
    kind of contact of the table resists, and every load-free loss."""
    from rvfmu.core.reducer.design import preset

    d = preset("RV-40E-121")
    return rv40.with_fields(
        needle_pitch_diameter=d.needle_pitch_diameter,
        tapered_pitch_diameter=d.tapered_pitch_diameter,
        main_bearing_pitch_diameter=d.main_bearing_pitch_diameter,
        seal_torque=0.5,
    )


def test_the_regularised_sign_is_the_sign_beyond_its_scale_and_smooth_through_zero():
    scale = 1e-5
    assert regularised_sign(0.0, scale) == (0.0, pytest.approx(1.0 / scale))
    assert regularised_sign(scale, scale)[0] == pytest.approx(1.0 / math.sqrt(2.0))
    assert regularised_sign(-1e-3, scale)[0] == pytest.approx(-1.0, abs=1e-4)
    for w in (-3e-5, -1e-6, 2e-6, 4e-5):
        s, ds = regularised_sign(w, scale)
        fd = (regularised_sign(w + 1e-11, scale)[0] - regularised_sign(w - 1e-11, scale)[0]) / 2e-11
        assert ds == pytest.approx(fd, rel=1e-5)
        assert regularised_sign(-w, scale)[0] == -s


def test_zero_coefficients_give_the_frictionless_run_to_the_bit(rv40, seed002):
    design = rv40.with_fields(**FRICTIONLESS)
    runs = [simulate(design, seed002, 1600.0, load=206.0, duration=0.01, friction=f) for f in (True, False)]
    for name in ("te", "tau_in", "q", "omega_out"):
        assert np.array_equal(getattr(runs[0], name), getattr(runs[1], name)), name
    assert not np.any(runs[0].friction_power)
    assert runs[0].mean_powers()["efficiency"] == runs[1].mean_powers()["efficiency"]


def test_the_tangent_is_the_derivative_of_the_forces_with_friction(rv40f, seed002):
    """K and C against central differences of f in q and in v, at speed and at a crawl whose
    slips sit inside the regularised sign's scale (every friction term's derivative)."""
    assert_tangents(
        DynamicModel(rv40f, seed002, mesh="varying"), (100.0, 2e-3), 1e-6, np.random.default_rng(3)
    )


def assert_tangents(model, input_speeds, velocity_scale, rng):
    """K and C of `model` against central differences of its forces f in q and in v, at each
    input speed [rad/s] (under 300 N*m), from the static start moved by 1e-8 m and
    velocities of `velocity_scale` [m/s] drawn from `rng`."""
    for omega in input_speeds:
        model.prepare(ramp_motion(np.array([0.0, 1e-4]), omega, 0.0, -300.0))
        q = static_start(model, -300.0, 0.0) + 1e-8 * rng.standard_normal(model.n)
        v = velocity_scale * rng.standard_normal(model.n)
        f, K, C = model.forces(1, q, v)
        scale = np.abs(K).max()
        # the differences' rounding: |f| eps / step, where friction's C is small (at speed)
        noise = 10.0 * np.abs(f).max() * np.finfo(float).eps / 1e-9
        for k in range(model.n):
            d = np.zeros(model.n)
            d[k] = 1e-12
            dq = (model.forces(1, q + d, v)[0] - model.forces(1, q - d, v)[0]) / 2e-12
            np.testing.assert_allclose(dq, K[:, k], rtol=1e-4, atol=1e-6 * scale)
            d[k] = 1e-9  # 1e-4 of the regularised sign's slip scale
            dv = (model.forces(1, q, v + d)[0] - model.forces(1, q, v - d)[0]) / 2e-9
            np.testing.assert_allclose(dv, C[:, k], rtol=1e-4, atol=max(1e-6 * np.abs(C).max(), noise))


def test_the_working_arrays_carry_nothing_from_one_evaluation_to_the_next(rv40f, seed002):
    """The Newmark loop evaluates the forces into working arrays made once (`scratch`): after
    a loaded state, a state with every bearing inside its clearance (no normal force, so no
    Coulomb friction in them) gives what fresh arrays give, to the bit, and so does the
    loaded state after it."""
    from rvfmu.core.dynamics.kernels import element_forces, forces_into, scratch

    errors = seed002.replace(
        **{
            name: np.full_like(getattr(seed002, name), 20e-6)
            for name in ("crank_disc_clearance", "crank_carrier_clearance", "main_bearing_clearance")
        }
    )
    model = DynamicModel(rv40f, errors, mesh="varying")
    model.prepare(ramp_motion(np.array([0.0, 1e-4]), 100.0, 0.0, -300.0))
    loaded = static_start(model, -300.0, 0.0)
    v = 1e-4 * np.random.default_rng(5).standard_normal(model.n)
    g, a = model.geometry(1)
    work = scratch(model.elements, g)
    states = (loaded, np.zeros(model.n), loaded)
    kept, fresh = [], []
    for q in states:
        for out, arrays in ((kept, work), (fresh, None)):
            f, K, C = np.empty(model.n), np.empty((model.n, model.n)), np.empty((model.n, model.n))
            if arrays is None:
                powers = element_forces(model.elements, g, a, q, v, f, K, C)
            else:
                powers = forces_into(model.elements, g, a, q, v, f, K, C, arrays)
            out.append((f, K, C, powers))
    for (f1, K1, C1, p1), (f2, K2, C2, p2) in zip(kept, fresh):
        assert np.array_equal(f1, f2) and np.array_equal(K1, K2) and np.array_equal(C1, C2)
        assert p1 == p2
    # the states differ where it matters: loaded bearings rub, free ones do not
    assert kept[0][3][0] > kept[1][3][0]


def _balance(design, errors, load, step, duration=0.04, speed_rpm=1600.0):
    """Works over a run from rest [J], the input ramped to speed over 10 ms and stepped by
    Newmark at `step` (the mean mesh stiffness: its steps would do work of their own):
    {"input": the shaft's, "kinematic": the prescribed motion's on the other elements,
    "output", "friction", "damping", "stored": the change of kinetic plus elastic energy}.

    The kinematic work is what the small-displacement model adds: its element rows and
    error offsets follow the nominal input angle, so at fixed unknowns the elastic energy
    changes in time (dU/dtheta_in * omega_in, a central difference here) and the nominal
    velocities work against the element forces; an exact large-motion model has none."""
    from rvfmu.core.dynamics.dynamic import Motion

    errors = zero_errors(design) if errors is None else errors
    count = int(round(duration / step))
    t = np.arange(count) * step
    motion = ramp_motion(t, speed_rpm * RPM, 0.01, -load)
    flank = 1 if load >= 0 else -1
    model = DynamicModel(design, errors, mesh="constant", flank=flank)
    model.prepare(motion)
    q0 = static_start(model, -load, 0.0, model.external(0))
    model.set_modal_damping(q0)
    stepper = NewmarkStepper.starting_at(model, q0)
    q, v, power = np.empty((count, model.n)), np.empty((count, model.n)), np.empty((count, 2))
    q[0], v[0] = q0, 0.0
    power[0] = model.forces_and_powers(0, q0, v[0])[3]
    stepper.advance(count - 1, q, v, power)
    assert stepper.failed_steps == 0
    assert np.all(power >= 0.0)
    p_in = -model.input_torque(q.T, v.T) * motion.omega_in
    p_out = -motion.tau_load * (motion.omega_in / design.ratio + v[:, model.carrier_rot] / model.scale)
    # the prescribed motion's power on the elements but the shaft, from the frictionless twin
    energy = []
    for shift in (1e-6, -1e-6):
        twin = DynamicModel(design, errors, mesh="constant", flank=flank, friction=False)
        twin.elements = twin.elements._replace(modal_c=model.elements.modal_c)
        twin.prepare(Motion(t, motion.theta_in + shift, motion.omega_in, motion.alpha_in, motion.tau_load))
        energy.append(np.array([twin.elastic_energy(k, q[k]) for k in range(count)]))
    twin.prepare(motion)
    nominal = twin.nominal_velocities(motion.theta_in, motion.omega_in)
    el, sun = twin.elements, twin.sun_rot
    on_elements = np.empty(count)
    for k in range(count):
        f = twin.forces(k, q[k], v[k])[0]
        f[sun] -= el.shaft_k * q[k, sun] + el.shaft_c * v[k, sun]
        on_elements[k] = nominal[k] @ f
    p_kinematic = (energy[0] - energy[1]) / 2e-6 * motion.omega_in - on_elements

    def work(p):
        return float(np.sum(0.5 * step * (p[1:] + p[:-1])))

    return {
        "input": work(p_in),
        "kinematic": work(p_kinematic),
        "output": work(p_out),
        "friction": work(power[:, 0]),
        "damping": work(power[:, 1]),
        "stored": model.stored_energy(count - 1, q[-1], v[-1]) - model.stored_energy(0, q[0], v[0]),
    }


def _closing(w):
    return (w["input"] + w["kinematic"] - w["output"] - w["friction"] - w["damping"] - w["stored"]) / w[
        "input"
    ]


@pytest.mark.parametrize(
    "load, errors",
    [(0.0, False), (0.0, True), (206.0, False), (206.0, True)],
    ids=["unloaded", "unloaded, seed 002", "206 N*m", "206 N*m, seed 002"],
)
def test_the_input_work_is_the_output_the_losses_and_the_stored_energy(rv40f, seed002, load, errors):
    """To 1e-6 of the input work with the kinematic work, which stays below 2e-3 of it: the
    rows and offsets turning with the input, and the modal damping's forces on the nominal
    motion while the start ramp winds the unknowns up (docs/model.md section 9)."""
    w = _balance(rv40f, seed002 if errors else None, load, 4e-6)
    assert w["friction"] > 0.05 * w["input"] if load else w["friction"] > 0.02 * w["input"]
    assert abs(_closing(w)) < 1e-6
    assert abs(w["kinematic"]) < 2e-3 * w["input"]
    if load:
        assert w["output"] > 0.7 * w["input"]


def test_the_dynamic_losses_are_the_quasi_static_power_balance(rv40f):
    """At 600 rpm (5 rpm at the output) forward, backdriving and unloaded: the losses
    within 10 % of the quasi-static balance's (first order in the coefficients, where the
    dynamic contact forces carry friction's own share), and backdriving below forward."""
    load = 0.5 * rv40f.rated_torque
    speed = 600.0 / rv40f.ratio
    qs = efficiency_map(rv40f, None, [speed], [load], points=12)
    runs = {
        side: simulate(rv40f, None, 600.0, load=side * load, duration=0.2).mean_powers()
        for side in (1.0, -1.0)
    }
    forward, backward = runs[1.0], runs[-1.0]
    assert forward["friction_W"] == pytest.approx(qs.loss_W[0, 0], rel=0.1)
    assert forward["efficiency"] == pytest.approx(qs.efficiency[0, 0], abs=0.01)
    assert backward["output_W"] < 0.0 and backward["input_W"] < 0.0  # the motor receives
    assert backward["efficiency"] < forward["efficiency"]
    assert backward["efficiency"] == pytest.approx(qs.backdriving_efficiency[0, 0], abs=0.01)
    idle = simulate(rv40f, None, 600.0, load=0.0, duration=0.2).mean_powers()
    running = qs.no_load_running_torque_Nm[0] * 600.0 * RPM
    assert idle["input_W"] == pytest.approx(running, rel=0.1)
    assert idle["friction_W"] == pytest.approx(idle["input_W"], rel=1e-3)


def test_friction_winds_the_output_back_by_its_own_torque(rv40f, seed002):
    """At a crawl the dynamic TE with friction is the frictionless one less the windup of the
    contacts' friction: an offset of the loaded side's sign, a small part of the windup, and
    the same curve."""
    runs = [
        simulate(
            rv40f, seed002, speed_rpm=5.0, load=300.0, revolutions=0.01, mesh="constant", ramp=0.5, friction=f
        )
        for f in (True, False)
    ]
    shift = runs[0].steady_te_arcsec() - runs[1].steady_te_arcsec()
    windup = -np.mean(runs[1].steady_te_arcsec())
    assert windup > 50.0
    assert -0.05 * windup < np.mean(shift) < 0.0
    assert np.ptp(shift) < 0.1 * np.ptp(runs[1].steady_te_arcsec())


def test_the_dynamic_fmu_model_holds_at_standstill_without_chattering(rv40f, seed002):
    """Driven at 100 rpm for 0.1 s in 1 ms steps, then held: the input torque settles to the
    frictionless -load/i without alternating, the loss decays, and the output creeps by
    less than an arcsecond as the elastic parts take over the friction's share."""
    reducer = DynamicReducer(rv40f, seed002)
    load = 200.0
    reducer.initialize(0.0, 0.0, -load)
    theta, rows = 0.0, []
    for k in range(300):
        speed = 100.0 * RPM if k < 100 else 0.0
        theta += speed * 1e-3
        out = reducer.step(k * 1e-3, 1e-3, theta, -load)
        rows.append((out.tau_in, out.te, out.p_loss, out.efficiency))
    tau, te, loss, efficiency = np.array(rows).T
    assert np.all(loss >= 0.0) and np.all((efficiency >= 0.0) & (efficiency <= 1.0))
    assert 0.8 < np.mean(efficiency[20:100]) < 0.95
    held = slice(110, None)
    assert np.all(np.diff(tau[held]) > 0.0)  # monotone: no chatter
    assert np.all(np.diff(loss[held]) < 0.0)
    assert tau[-1] == pytest.approx(-load / rv40f.ratio, rel=0.01)
    assert np.ptp(te[held]) * 206265.0 < 1.0


def test_the_dynamic_fmu_models_torque_carries_the_losses_both_ways(rv40f):
    """Forward the motor's torque exceeds the frictionless load/i, backdriving it falls short;
    P_loss is the input power less the output power over a steady stretch."""
    speed = 600.0 * RPM
    load = 0.5 * rv40f.rated_torque
    for side in (1.0, -1.0):
        reducer = DynamicReducer(rv40f, zero_errors(rv40f))
        reducer.initialize(0.0, 0.0, -side * load)
        outs = []
        for k in range(400):
            omega = speed * min(1.0, (k + 1) / 100.0)
            outs.append((omega, reducer.step(k * 1e-3, 1e-3, reducer.theta_in + omega * 1e-3, -side * load)))
        steady = outs[200:]
        tau_in = np.mean([o.tau_in for _, o in steady])
        p_in = np.mean([-o.tau_in * w for w, o in steady])
        p_out = np.mean([side * load * o.omega_out for _, o in steady])
        p_loss = np.mean([o.p_loss for _, o in steady])
        if side > 0:
            assert tau_in < -load / rv40f.ratio
        else:
            assert 0.0 < tau_in < load / rv40f.ratio
        assert p_loss == pytest.approx(p_in - p_out, rel=0.01)
