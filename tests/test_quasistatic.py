"""The quasi-static TE model against invariants and independent computations."""

import numpy as np
import pytest
from conftest import ROOT, hand_pin_geometry, unit

from rvfmu.core.base.units import ARCSEC, UM
from rvfmu.core.reducer.design import PRESET_NAMES, preset
from rvfmu.core.reducer.errors import load_errors, stack, zero_errors
from rvfmu.core.reducer.profile import disc_profile
from rvfmu.core.statics.equivalent import EquivalentModel
from rvfmu.core.statics.quasistatic import (
    NO_LOAD_PROBE,
    catalogue_torques,
    default_points,
    equilibria,
    equilibrium_te,
    input_angles,
    metric_torques,
    te_curve,
    windup,
)
from rvfmu.core.statics.reference import no_load_limit_bracket, te_reference
from rvfmu.core.statics.solver import solve_pairs

POINTS = 720


def exact(design):
    return design.with_fields(d_rp=0.0, d_rrp=0.0)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_exact_geometry_gives_zero_no_load_te(name):
    curve = te_curve(exact(preset(name)), points=POINTS)
    assert np.all(curve.converged)
    assert np.max(np.abs(curve.te_arcsec)) < 0.01


def test_no_load_te_is_positively_homogeneous_in_the_errors(rv40, seed002):
    design = exact(rv40)
    both = stack([seed002, seed002.scaled(2.0)])
    te = te_curve(design, both, points=POINTS).te_arcsec
    assert np.ptp(te[0]) > 5.0  # the errors do something
    np.testing.assert_allclose(te[1], 2.0 * te[0], atol=2e-3)


def test_positive_modifications_give_the_lost_motion_of_their_clearance(rv40):
    """No errors, usual modification pair: TE at no load is the first-contact rotation.

    Independent value: each pin's gap is measured on the modified profile itself
    (closest point of the closed-form curve to the pin centre, minus the pin radius),
    and the carrier turns back until the pin with the smallest gap/closing-rate touches.
    """
    design = rv40
    assert design.d_rrp > 0 > design.d_rp
    theta_in = input_angles(design, 48)
    curve = te_curve(design, points=48)
    normal, pins, rate = hand_pin_geometry(design, theta_in)
    prof = disc_profile(design, 40000)
    profile_pts = np.stack([prof.x, prof.y], axis=-1)
    expected = np.empty(theta_in.size)
    for a, th in enumerate(theta_in):
        theta_out = th / design.ratio
        best = np.inf
        for j in range(2):
            psi = -design.z_c * theta_out + j * np.pi
            centre = design.e * unit(psi)
            rot = np.array(
                [
                    [np.cos(theta_out + j * np.pi), -np.sin(theta_out + j * np.pi)],
                    [np.sin(theta_out + j * np.pi), np.cos(theta_out + j * np.pi)],
                ]
            )
            closing = np.flatnonzero(rate[a, j] > 1e-6)
            for k in closing:
                local = rot.T @ (pins[k] - centre)  # pin centre in the disc frame
                gap = np.min(np.linalg.norm(profile_pts - local, axis=1)) - design.r_rp
                best = min(best, gap / rate[a, j, k])
        expected[a] = -best
    te = curve.te[0]
    assert np.all(te < 0)
    np.testing.assert_allclose(te, expected, rtol=2e-3, atol=2e-3 * ARCSEC)
    # nearly constant, and about an arcminute for 0.01 mm modifications
    assert np.ptp(curve.te_arcsec) < 0.02 * abs(curve.mean_arcsec[0])
    assert 30 < -curve.mean_arcsec[0] < 120


def test_single_pin_error_acts_only_where_that_pin_can_touch(rv40):
    """A pin moved into the discs changes TE only at angles where it carries load,
    and it can carry a resisting load only on the closing side of a disc (hand kinematics)."""
    design = rv40
    k = 7
    errors = zero_errors(design, 2)
    errors.pin_radial[1, k] = -5.0 * UM  # inward: into the discs
    theta_in = input_angles(design, POINTS)
    model = EquivalentModel(design, theta_in)
    sample = np.repeat([0, 1], POINTS)
    angle = np.tile(np.arange(POINTS), 2)
    eq = solve_pairs(
        model, errors, sample, angle, -design.rated_torque, no_load_probe=1e-4 * design.rated_torque
    )
    te = (eq.q[:, model.carrier_rot] / model.scale).reshape(2, POINTS)
    force = eq.pin_force[:, :, k].reshape(2, POINTS, 2)  # (sample, angle, disc)
    change = (te[1] - te[0]) / ARCSEC
    _, _, rate = hand_pin_geometry(design, theta_in)
    loaded = force > 0
    rate_k = rate[:, :, k]
    assert np.all(rate_k[loaded[0]] > 0) and np.all(rate_k[loaded[1]] > 0)
    touches = np.any(loaded, axis=(0, 2))
    assert 0.1 * POINTS < touches.sum() < 0.9 * POINTS
    assert np.max(np.abs(change[~touches])) < 1e-7
    assert np.max(np.abs(change[touches])) > 0.1


def test_loaded_te_grows_with_load_and_rigidity_is_realistic(rv40, seed002):
    design = rv40
    loads = np.array([0.0, -0.25, -0.5, -1.0]) * design.rated_torque
    theta_in = input_angles(design, 90)
    te, _, ok = equilibrium_te(design, seed002, theta_in, loads)
    assert ok.all()
    mean = te[0].mean(axis=-1)
    windup_from_no_load = mean[1:] - mean[0]
    assert np.all(np.diff(windup_from_no_load) < 0) and windup_from_no_load[0] < 0
    # pointwise too: more load, more lag, at every angle
    assert np.all(np.diff(te[0], axis=0) < 0)
    rigidity = windup(design, seed002).torsional_rigidity_Nm_per_arcmin()[0]
    print(f"RV-40E-121 torsional rigidity: {rigidity:.1f} N*m/arcmin")
    assert 30.0 < rigidity < 600.0


def test_mirror_symmetry_of_load_reversal(rv40):
    """The error-free reducer mirrored is itself: TE(theta, T) = -TE(-theta, -T)."""
    design = rv40
    theta_in = input_angles(design, 96)
    T = 0.5 * design.rated_torque
    te, _, _ = equilibrium_te(design, zero_errors(design), theta_in, [-T, T])
    mirrored = np.roll(te[0, 1][::-1], 1)  # value at -theta_i is at index -i
    np.testing.assert_allclose(te[0, 0], -mirrored, atol=1e-6 * ARCSEC * 1e3)


def test_superposition_of_small_errors_under_load(rv40, seed002):
    design = rv40
    small_a = seed002.scaled(0.01).replace(
        disc_profile=seed002.disc_profile * 0, disc_pitch=seed002.disc_pitch * 0
    )
    small_b = zero_errors(design).replace(
        disc_pitch=seed002.disc_pitch * 0.01, disc_profile=seed002.disc_profile * 0.01
    )
    both = small_a.replace(disc_pitch=small_b.disc_pitch, disc_profile=small_b.disc_profile)
    batch = stack([zero_errors(design), small_a, small_b, both])
    te = te_curve(design, batch, tau_load=-design.rated_torque, points=POINTS).te_arcsec
    da, db, dab = te[1] - te[0], te[2] - te[0], te[3] - te[0]
    assert np.max(np.abs(da)) > 0.02 and np.max(np.abs(db)) > 0.02  # both do something
    # 3 %: where a pin hands its load over, the runs' active sets may differ at an angle
    np.testing.assert_allclose(dab, da + db, atol=0.03 * max(np.abs(dab).max(), 1e-3))


@pytest.mark.parametrize(
    "rollers, tau_fraction, clearances",
    [
        (False, 0.0, False),
        (False, -1.0, False),
        (False, -0.25, True),
        (True, 0.0, False),
        (True, -1.0, False),
        (True, -0.03, False),
        (True, 0.5, False),
        (True, -0.25, True),
        ("hertz", 0.0, False),
        ("hertz", -1.0, False),
        ("hertz", -0.03, False),
        ("hertz", 0.5, False),
        ("hertz", -0.25, True),
    ],
)
def test_agrees_with_a_straightforward_scipy_solve(
    rv40, rv40_rollers, rv40_hertz, seed002, rollers, tau_fraction, clearances
):
    """With the roller law (rollers) the reference integrates the rollers' energy over the
    loaded arc and carries the crank's bending as a spring with unknowns of its own
    (rvfmu/core/statics/reference.py); the solver tabulates the energy and eliminates the spring
    (rvfmu/core/laws/roller_law.py).  With the pins' Hertz law too ("hertz") the reference inverts
    it by scipy's Lambert W, the solver by its own Newton iteration (rvfmu/core/laws/pin_law.py).
    At no load without clearance both take the limit with the law (seed 002's errors preload
    the estimate's discs nowhere, so there it is the kinematic pose: the law must not move
    it)."""
    design = {False: rv40, True: rv40_rollers, "hertz": rv40_hertz}[rollers]
    errors = _with_clearances(seed002, 6.0, 4.0, 10.0) if clearances else seed002
    theta_in = input_angles(design, 6) + 0.3
    tau = tau_fraction * design.rated_torque
    fast, _, ok = equilibrium_te(design, errors, theta_in, [tau])
    slow = te_reference(design, errors, theta_in, tau)
    assert ok.all()
    np.testing.assert_allclose(fast[0, 0] / ARCSEC, slow / ARCSEC, atol=0.002)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_reference_models_the_output_compliance_of_every_calibrated_preset(name):
    """The calibrated presets carry a series compliance at the output; the reference holds
    it as a torsional spring to an output flange of its own, the solver adds its windup."""
    design = preset(name)
    assert design.output_compliance > 0.0
    errors = (
        load_errors(ROOT / "studies" / "seed002_errors.toml", design)
        if name == "RV-40E-121"
        else zero_errors(design)
    )
    theta_in = input_angles(design, 4) + 0.2
    tau = -design.rated_torque
    fast, _, ok = equilibrium_te(design, errors, theta_in, [tau])
    slow = te_reference(design, errors, theta_in, tau)
    assert ok.all()
    np.testing.assert_allclose(fast[0, 0] / ARCSEC, slow / ARCSEC, atol=0.01)
    # without the compliance the two differ by its windup: the reference does not ignore it
    bare = te_reference(design.with_fields(output_compliance=0.0), errors, theta_in, tau)
    np.testing.assert_allclose((slow - bare) / ARCSEC, design.output_compliance * tau / ARCSEC, atol=0.01)


def test_default_points_resolve_the_pin_passing_order(rv40):
    assert default_points(rv40) // 2 > rv40.z_p * rv40.z_c


def test_batch_of_seed002_converges_and_matches_single(rv40, seed002):
    batch = stack([seed002, zero_errors(rv40), seed002])
    curve = te_curve(rv40, batch, tau_load=-rv40.rated_torque, points=POINTS)
    single = te_curve(rv40, seed002, tau_load=-rv40.rated_torque, points=POINTS)
    assert curve.converged.all()
    np.testing.assert_allclose(curve.te[0], single.te[0], atol=1e-9 * ARCSEC)
    np.testing.assert_allclose(curve.te[2], single.te[0], atol=1e-9 * ARCSEC)
    # seed 002 magnitudes give tens of arcseconds, as the seeds report for the RV-40E
    assert 10.0 < single.te_pp_arcsec[0] < 80.0


def test_small_loads_wind_up_monotonically_at_every_angle(rv40, seed002):
    """Where the first contacts close (a few % of rated torque) the active set changes
    fastest; more resisting load must mean more lag at every angle, with pins loaded."""
    design = rv40
    theta_in = input_angles(design, 3120)
    loads = -design.rated_torque * np.array([0.0, 0.0025, 0.01, 0.03, 0.06])
    eq = equilibria(design, seed002, theta_in, loads)
    assert eq.converged.all()
    assert np.all(np.diff(eq.te[0], axis=0) < 0)
    assert np.all(eq.pin_force_max[0, 1:] > 0)
    np.testing.assert_allclose(
        eq.tau_in[0] * design.ratio, loads[:, None] * np.ones(3120), rtol=1e-3, atol=1e-9
    )


@pytest.mark.parametrize("zero_side", [-1, 1])
def test_no_load_limit_from_either_side_is_the_limit_of_small_loads(rv40, seed002, zero_side):
    design = rv40
    theta_in = input_angles(design, 240)
    tiny = 1e-6 * design.rated_torque * zero_side
    eq = equilibria(design, seed002, theta_in, [0.0, tiny], zero_side=zero_side)
    np.testing.assert_allclose(eq.te[0, 0], eq.te[0, 1], atol=1e-3 * ARCSEC)


def _with_clearances(errors, crank_disc, crank_carrier, main):
    return errors.replace(
        crank_disc_clearance=np.array([crank_disc * UM]),
        crank_carrier_clearance=np.array([crank_carrier * UM]),
        main_bearing_clearance=np.array([main * UM]),
    )


@pytest.mark.parametrize("zero_side", [-1, 1])
def test_no_load_limit_with_bearing_clearances_is_the_rigid_limit(rv40, seed002, zero_side):
    """docs/model.md section 5 with clearances: rigid parts turned as far as the pins and the
    clearance circles let them.  Two linear programs over all unknowns (the circles as the
    polygons around and inside them) bracket that independently of the solver; the
    weak springs must not hold the floating parts away from it."""
    errors = stack(
        [_with_clearances(zero_errors(rv40), 12.0, 8.0, 10.0), _with_clearances(seed002, 20.0, 15.0, 12.0)]
    )
    theta_in = input_angles(rv40, 16) + 0.1
    te = equilibria(rv40, errors, theta_in, [0.0], zero_side=zero_side).te[:, 0]
    model = EquivalentModel(rv40, theta_in, flank=1 if zero_side < 0 else -1)
    checked = 0
    for s in range(errors.samples):
        for a in range(theta_in.size):
            bracket = no_load_limit_bracket(model, errors, s, a, zero_side)
            if bracket is None:
                continue  # these errors preload some part at no load: the limit is elastic there
            low, high = bracket
            assert high - low < 0.01 * ARCSEC
            assert low - 0.05 * ARCSEC <= te[s, a] <= high + 0.05 * ARCSEC, (s, a)
            checked += 1
    assert checked >= 24
    # the clearances show: the error-free reducer turns back further than without them
    plain = equilibria(rv40, zero_errors(rv40), theta_in, [0.0], zero_side=zero_side).te[0, 0]
    assert np.all(zero_side * (te[0] - plain) > 1.0 * ARCSEC)


def _te_under_driving_probe_on_the_resisting_flank(design, errors, theta_in):
    """TE [arcsec] (A,) of reducer 0 under +probe on the resisting flank's energy: on one
    flank's (convex) energy a driving load can only turn the output forward, so this bounds
    the no-load TE from the resisting side from above."""
    probe = NO_LOAD_PROBE * design.rated_torque
    model = EquivalentModel(design, theta_in, flank=1)
    A = theta_in.size
    ahead = solve_pairs(
        model, errors, np.zeros(A, dtype=int), np.arange(A), np.full(A, probe), no_load_probe=probe
    )
    assert ahead.converged.all()
    return ahead.q[:, model.carrier_rot] / model.scale / ARCSEC


def test_no_load_te_with_a_preloaded_needle_bearing_lies_between_small_loads(rv40, seed002):
    """A needle clearance of 1 um with seed 002's errors preloads the discs at no load at most
    angles, and a part touching its clearance circle with hardly any force rolls around it
    at small loads: the TE moves by arcseconds between 0.01 % and 0.1 % of the rated
    torque.  Whatever the limit does there, on the energy of one flank (convex) a resisting
    load can only turn the output back and a driving one forward, so the no-load TE lies
    between TE under the probe load and under a small driving load on that flank."""
    errors = _with_clearances(seed002, 1.0, 10.0, 10.0)
    theta_in = input_angles(rv40, 400)
    probe = NO_LOAD_PROBE * rv40.rated_torque
    eq = equilibria(rv40, errors, theta_in, [-10.0 * probe, -probe, 0.0])
    assert eq.converged.all()
    te = eq.te[0] / ARCSEC
    forward = _te_under_driving_probe_on_the_resisting_flank(rv40, errors, theta_in)
    tol = 0.05
    assert np.all(te[0] <= te[1] + tol) and np.all(te[1] <= te[2] + tol)
    assert np.all(te[2] <= forward + tol)
    # the no-load TE is not the probe's: between them the output still turns by arcseconds
    assert np.max(te[2] - te[1]) > 2.0


def _complete_study_reducers(rows):
    """Reducers of the complete study's Sobol sample (studies/rv40e_121_full.toml, N = 1024),
    on RV-40E-121-estimate, the design the study ran on when these rows were picked (its
    20 um tip and root clearance; the calibrated preset's 4.8 um preloads other rows)."""
    from tolerance import sobol
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "rv40e_121_full.toml")
    X = sobol.sample(study.problem(), 1024, False, seed=study.seed)
    return preset("RV-40E-121-estimate"), errors_from_unit(study, X[rows])


def test_no_load_limit_of_ordinary_reducers_of_the_complete_study_is_the_rigid_limit():
    """Reducers whose weak springs once held the floating parts 0.9-1.7 arcsec away from the
    rigid limit (every bearing clearance in its catalogue range, no preload at no load)."""
    design, errors = _complete_study_reducers([5444, 10888])
    theta_in = input_angles(design, 60)
    te = equilibria(design, errors, theta_in, [0.0]).te[:, 0]
    model = EquivalentModel(design, theta_in, flank=1)
    for s in range(errors.samples):
        for a in range(theta_in.size):
            low, high = no_load_limit_bracket(model, errors, s, a)
            assert low - 0.1 * ARCSEC <= te[s, a] <= high + 0.1 * ARCSEC, (s, a)


def _release_routes(study_file, reducers, points):
    """No-load TE [arcsec] (reducers, points) of a study's first Monte Carlo reducers by
    solve_pairs(clearance_release=...) with RELEASE_ROUNDS solves, and the count of solves
    (`ReducedSystem._solve_group` calls) each route made."""
    from unittest import mock

    from rvfmu.core.statics import solver
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / study_file)
    errors = errors_from_unit(study, sample(study, reducers))
    model = EquivalentModel(study.design, input_angles(study.design, points), flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(reducers), np.arange(points), indexing="ij"))
    zero = np.zeros(s.size)
    probe = NO_LOAD_PROBE * study.design.rated_torque
    solve_group = solver.ReducedSystem._solve_group

    def route(release, rounds=solver.RELEASE_ROUNDS):
        calls = []

        def counted(self, *args, **kwargs):
            calls.append(1)
            return solve_group(self, *args, **kwargs)

        with (
            mock.patch.object(solver, "RELEASE_ROUNDS", rounds),
            mock.patch.object(solver.ReducedSystem, "_solve_group", counted),
        ):
            eq = solve_pairs(model, errors, s, a, zero, no_load_probe=probe, clearance_release=release)
        assert eq.converged.all()
        return (model.output_angle(eq.q, zero) / ARCSEC).reshape(reducers, points), len(calls)

    return route


def test_with_clearances_the_weak_springs_let_go_at_the_probe_alone_as_at_both_loads():
    """docs/model.md section 5: with bearing clearances the weak springs let go by solves
    re-centred on the last solution, at the probe alone (`clearance_release="probe"`, the
    default: five solves a point); the solve at 10 probes only starts the probe's and anchors
    the chord back to zero.  The reference lets go at both loads (eight solves).  On reducers of
    the complete study the two agree within a few 1e-4 arcsec, and the default is as close as
    the reference to a release taken much further (12 solves at each load)."""
    route = _release_routes("rv40e_121_full.toml", 8, 400)
    route("probe")  # the error-free reducer's first guesses, solved once and kept for the others
    probe_alone, probe_solves = route("probe")
    both, both_solves = route("every")
    further, _ = route("every", 12)
    assert np.abs(probe_alone - both).max() <= 0.005
    assert np.abs(np.ptp(probe_alone, axis=1) - np.ptp(both, axis=1)).max() <= 0.002
    assert np.abs(probe_alone - further).max() <= np.abs(both - further).max() + 0.005
    assert probe_solves * 8 == both_solves * 5  # per chunk: 2 + 3 solves against 2 + 3 + 3
    # the clearances are there: the curves are tens of arcsec, the releases far from idle
    assert np.ptp(both, axis=1).min() > 10.0 and np.abs(both - further).max() > 1e-3


def test_without_clearances_where_the_weak_springs_let_go_changes_nothing():
    route = _release_routes("quick_mc.toml", 2, 200)
    probe_alone, _ = route("probe")
    both, _ = route("every")
    np.testing.assert_array_equal(probe_alone, both)
    with pytest.raises(ValueError, match="clearance_release 'twice'"):
        route("twice")


def test_the_roller_laws_no_load_route_from_the_kinematic_pose_solves_no_error_free_reducer(monkeypatch):
    """The error-free reducer's first guesses (`solver._nominal_guess`) start elastic solves from
    cold; the roller law's no-load route from the kinematic pose has none, so it must not pay
    for them (an elastic solve of the error-free reducer at every angle), while the reference
    route that starts with an elastic solve still takes them."""
    from rvfmu.core.statics import solver
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    errors = errors_from_unit(study, sample(study, solver.NOMINAL_GUESS_MIN_SAMPLES))
    model = EquivalentModel(study.design, input_angles(study.design, 40), flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(errors.samples), np.arange(40), indexing="ij"))
    probe = NO_LOAD_PROBE * study.design.rated_torque
    calls = []
    solve_guess = solver._solve_nominal_guess
    monkeypatch.setattr(solver, "_solve_nominal_guess", lambda *args: calls.append(1) or solve_guess(*args))
    for start, expected in (("kinematic", 0), ("elastic", 1)):
        calls.clear()
        eq = solve_pairs(model, errors, s, a, np.zeros(s.size), no_load_probe=probe, law_start=start)
        assert eq.converged.all() and len(calls) == expected, start


def _creeping_point(row, angle):
    """No-load TE [arcsec] at four angles around `angle` (of 3200) of the complete study's
    Saltelli row `row` (N = 1024), and what each solve left unconverged: a point where parts
    barely touch their clearance circles and one solve creeps to the iteration's limit."""
    from unittest import mock

    from rvfmu.core.statics import newton, solver
    from tolerance import sobol
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "rv40e_121_full.toml")
    X = sobol.sample(study.problem(), 1024, False, seed=study.seed)
    errors = errors_from_unit(study, X[[row]])
    model = EquivalentModel(
        study.design, input_angles(study.design, study.points)[angle - 2 : angle + 2], flank=1
    )
    a, zero = np.arange(4), np.zeros(4)
    solve_group = solver.ReducedSystem._solve_group

    def solve(
        max_iterations=newton.MAX_ITERATIONS, retries=solver.RELEASE_RETRIES, stall=solver.RETRY_STALL_STEPS
    ):
        left = []

        def watched(self, group, *args, centre=None, **kwargs):
            result = solve_group(self, group, *args, centre=centre, **kwargs)
            left.append(("release" if centre is not None else "solve", group[~result[1]].tolist()))
            return result

        with (
            mock.patch.object(newton, "MAX_ITERATIONS", max_iterations),
            mock.patch.object(solver, "RELEASE_RETRIES", retries),
            mock.patch.object(solver, "RETRY_STALL_STEPS", stall),
            mock.patch.object(solver.ReducedSystem, "_solve_group", watched),
        ):
            eq = solve_pairs(
                model,
                errors,
                np.zeros(4, dtype=int),
                a,
                zero,
                no_load_probe=NO_LOAD_PROBE * study.design.rated_torque,
            )
        return model.output_angle(eq.q, zero) / ARCSEC, eq.converged, [entry for entry in left if entry[1]]

    return solve


def test_a_point_whose_probe_solve_creeps_is_converged_where_its_release_is():
    """docs/model.md section 5: the probe's own solve only starts the release solves, as the
    solve at 10 probes starts the probe's.  Row 28 at angle 811: the probe's solve creeps
    to the iteration's limit (four bearings 0.01-0.5 nm beyond their circles), the release
    solves converge, and the TE is that of a run whose every solve converges (40 000
    iterations allowed)."""
    solve = _creeping_point(28, 811)
    te, converged, left = solve()
    assert left == [("solve", [2])]  # the probe's solve of the third angle, nothing else
    assert converged.all()
    reference, converged, left = solve(max_iterations=40_000)
    assert converged.all() and left == []
    np.testing.assert_allclose(te, reference, rtol=0, atol=1e-4)


def test_a_release_solve_that_creeps_converges_when_started_again():
    """Row 5109 at angle 2971: the last of the release solves creeps to the iteration's
    limit; started again from where it stopped (`solver.RELEASE_RETRIES`) it converges, and
    the TE is that of a run whose every solve converges."""
    solve = _creeping_point(5109, 2971)
    te, converged, left = solve(retries=0)
    assert left == [("release", [2])] and list(converged) == [True, True, False, True]
    te, converged, left = solve()
    assert left == [("release", [2])] and converged.all()  # the retry converged
    reference, converged, left = solve(max_iterations=40_000)
    assert converged.all() and left == []
    np.testing.assert_allclose(te, reference, rtol=0, atol=1e-4)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_retried_release_solve_ends_where_its_steps_stall(compiled, monkeypatch):
    """Row 16398 at angle 2261: a stiff main bearing sits exactly on its clearance circle and
    the release solve alternates between its two sides in steps of 1.3e-14 m, just above the
    step tolerance, however often it is started again.  The retries end where ten steps in a
    row stall (`solver.RETRY_STALL_STEPS`), and the TE is that of the point's last iterate to
    round-off: the two sides are 1.3e-14 m apart.  The compiled and numpy iterations alike."""
    from rvfmu.core.statics import newton_kernel

    monkeypatch.setattr(newton_kernel, "COMPILED", compiled and newton_kernel.COMPILED)
    solve = _creeping_point(16398, 2261)
    unended, converged, left = solve(stall=0)
    assert list(converged) == [True, True, False, True]
    assert left == [("release", [2])] * 3  # the last release solve and both retries
    te, converged, left = solve()
    assert converged.all() and left == [("release", [2])]
    np.testing.assert_allclose(te, unended, rtol=0, atol=1e-9)  # 5e-12 arcsec measured


def test_no_load_te_of_a_tight_needle_reducer_has_no_spike():
    """Reducer 16594 of the complete study: needle clearance 4 um, preloaded at no load at
    some angles.  Near input angle 1199 of 3200 the tangent at the probe was nearly singular
    and sent the no-load TE 600 arcsec forward; it must stay between the probe's TE and
    that under a small driving load on the same flank."""
    design, errors = _complete_study_reducers([16594])
    theta_in = input_angles(design, 3200)[1190:1210]
    probe = NO_LOAD_PROBE * design.rated_torque
    te = equilibria(design, errors, theta_in, [-probe, 0.0]).te[0] / ARCSEC
    forward = _te_under_driving_probe_on_the_resisting_flank(design, errors, theta_in)
    assert np.all(te[0] <= te[1] + 0.05) and np.all(te[1] <= forward + 0.05)


@pytest.mark.parametrize("row, index", [(12, 10857), (9, 9587)])
def test_no_load_te_of_a_preloaded_reducer_without_bearing_clearance_is_the_limit(row, index):
    """quick_mc's reducers on the calibrated RV-40E-121: no bearing clearance, pins in
    interference at no load.  Near these angles (of 12480) the pose changes its contacts
    between the probe and zero load; the tangent at the probe sent the no-load TE of
    reducer 12 to 207 arcsec (its neighbours at -7 and +6.5) and that of reducer 9 to
    38 arcsec (the limit: 18.9).  The no-load TE must be the limit of the TE under
    resisting loads that shrink to zero (1e-3 and 1e-4 probes agree within 0.01 arcsec
    there), and lie between the probe's TE and that under a small driving load on the
    same flank.  The crank bearings are linear springs here (`linear_bearings`): this is
    the no-load route of the stated stiffnesses, which a design on the roller law also
    takes first.  The modification pair and the crank bearings' stiffnesses and the output
    compliance are those these angles were found on (the calibrated preset's of then,
    2.63867 um, 1.503e8 and 7.674e8 N/m, 0.0210337 arcsec/(N*m)): others preload other
    angles, or change the contacts at none of these."""
    from conftest import linear_bearings

    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    design = linear_bearings(study.design).with_fields(
        d_rp=-2.63867 * UM,
        d_rrp=2.63867 * UM,
        crank_disc_bearing_stiffness=1.503e8,
        crank_carrier_bearing_stiffness=7.674e8,
        output_compliance=0.0210337 * ARCSEC,
    )
    errors = errors_from_unit(study, sample(study, row + 1)[row:])
    theta_in = input_angles(design, 12480)[index - 6 : index + 7]
    probe = NO_LOAD_PROBE * design.rated_torque
    eq = equilibria(design, errors, theta_in, [-probe, -1e-3 * probe, -1e-4 * probe, 0.0])
    assert eq.converged.all()
    te = eq.te[0] / ARCSEC
    assert np.max(np.abs(te[1] - te[2])) < 0.01
    assert np.max(np.abs(te[3] - te[2])) < 0.05
    forward = _te_under_driving_probe_on_the_resisting_flank(design, errors, theta_in)
    assert np.all(te[0] <= te[3] + 0.05) and np.all(te[3] <= forward + 0.05)
    # the probe's own TE is not the limit there: the test looks where it matters
    assert np.max(np.abs(te[0] - te[3])) > 5.0


# -- the crank bearings' roller law -----------------------------------------------------------


def test_the_roller_law_winds_up_as_its_stated_stiffness_under_load_and_softer_near_zero(
    rv40, rv40_rollers, seed002
):
    """The stated stiffnesses are the laws' secants over 50-100 % of the bearing loads that
    rigid-part statics gives at rated torque: the rigidity stays within 2 % (the model's
    bearing loads carry the pins' radial forces too), while near zero load the rollers are
    softer than that secant (Q ~ delta^(10/9)): the lost motion grows."""
    linear, rollers = windup(rv40, seed002), windup(rv40_rollers, seed002)
    assert rollers.torsional_rigidity_Nm_per_arcmin()[0] == pytest.approx(
        linear.torsional_rigidity_Nm_per_arcmin()[0], rel=0.02
    )
    assert rollers.lost_motion_arcmin()[0] > linear.lost_motion_arcmin()[0] + 0.02


def test_the_windup_at_the_metrics_torques_gives_the_whole_tests_metrics():
    """The studies solve the windup test at the six torques lost motion and rigidity read
    (`metric_torques`): every torque is a separate equilibrium, so on reducers of the complete
    study, with every bearing clearance and the roller law of the calibrated preset, the two
    metrics equal those of all twelve catalogue torques."""
    from tolerance import sobol
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "rv40e_121_full.toml")
    X = sobol.sample(study.problem(), 64, False, seed=study.seed)
    design, errors = study.design, errors_from_unit(study, X[[3, 200, 555, 901]])
    torques = metric_torques(design)
    whole = catalogue_torques(design)
    assert torques.size == 6 and np.all(np.isin(torques, whole)) and np.all(np.diff(torques) > 0)
    assert set(np.round(np.abs(torques) / design.rated_torque, 12)) == {0.03, 0.5, 1.0}
    part, full = windup(design, errors, torques), windup(design, errors, whole)
    assert part.converged.all() and full.converged.all()
    np.testing.assert_allclose(part.lost_motion_arcmin(), full.lost_motion_arcmin(), rtol=1e-12, atol=0)
    np.testing.assert_allclose(
        part.torsional_rigidity_Nm_per_arcmin(), full.torsional_rigidity_Nm_per_arcmin(), rtol=1e-12, atol=0
    )
    # and what the metrics read is the same: the windup at each of the six is the whole test's there
    for k, torque in enumerate(torques):
        np.testing.assert_array_equal(
            part.windup[:, k], full.windup[:, int(np.flatnonzero(whole == torque)[0])]
        )


def test_with_the_roller_law_the_no_load_te_is_the_limit_of_vanishing_loads():
    """Without clearance the no-load limit moves from the stated stiffnesses to the roller
    law: the calibrated RV-40E-121 with seed 002's errors is preloaded at no load (its
    4.8 um tip clearance), and the law carries that preload differently (the no-load TE
    moves by up to about 1 arcsec).  It must be the limit of the law's TE under resisting
    loads that shrink to zero, and agree with the reference's no-load TE (its solve of all
    unknowns with the law at a load of 1e-7 x rated)."""
    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    theta_in = input_angles(design, 180)
    probe = NO_LOAD_PROBE * design.rated_torque
    law = equilibria(design, errors, theta_in, [-1e-2 * probe, 0.0]).te[0] / ARCSEC
    stated = (
        equilibria(design.with_fields(needle_rollers=0, tapered_rollers=0), errors, theta_in, [0.0]).te[0, 0]
        / ARCSEC
    )
    assert np.max(np.abs(law[1] - law[0])) < 0.002
    moved = np.argsort(-np.abs(law[1] - stated))[:3]
    assert np.all(np.abs(law[1] - stated)[moved] > 0.2)  # where the law makes a difference
    slow = te_reference(design, errors, theta_in[moved], 0.0) / ARCSEC
    np.testing.assert_allclose(law[1][moved], slow, atol=0.005)


def test_with_the_roller_law_and_clearances_the_no_load_te_is_the_rigid_limit(rv40_rollers):
    """At no load the bearings with clearance follow the roller law in the continuation;
    the limit is that of rigid parts (the linear programs of `no_load_limit_bracket`),
    whatever the law."""
    design = rv40_rollers
    errors = _with_clearances(load_errors(ROOT / "studies" / "seed002_errors.toml", design), 20.0, 15.0, 12.0)
    theta_in = input_angles(design, 16) + 0.1
    te = equilibria(design, errors, theta_in, [0.0]).te[0, 0]
    model = EquivalentModel(design, theta_in, flank=1)
    checked = 0
    for a in range(theta_in.size):
        bracket = no_load_limit_bracket(model, errors, 0, a)
        if bracket is None:
            continue  # these errors preload some part at no load: the limit is elastic there
        low, high = bracket
        assert low - 0.05 * ARCSEC <= te[a] <= high + 0.05 * ARCSEC, a
        checked += 1
    assert checked >= 12


def test_a_stated_stiffness_its_rollers_cannot_reach_is_refused(rv40, rv40_rollers):
    from rvfmu.core.base.checks import InputError

    with pytest.raises(InputError) as info:
        rv40_rollers.with_fields(crank_disc_bearing_stiffness=2e9)
    assert info.value.field == "crank_disc_bearing_stiffness_N_per_m"
    assert "secant stiffness of its rollers alone" in str(info.value)
    with pytest.raises(InputError) as info:
        rv40.with_fields(needle_rollers=12, needle_roller_length=0.0)
    assert info.value.field == "needle_roller_length_mm"
    with pytest.raises(InputError) as info:
        rv40.with_fields(tapered_rollers=14, tapered_roller_length=6e-3, tapered_contact_angle=0.0)
    assert info.value.field == "tapered_contact_angle_deg"


def _study_errors(name, rows):
    from tolerance import sobol
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / name)
    X = sobol.sample(study.problem(), 64, False, seed=study.seed)
    return study.design, errors_from_unit(study, X[rows])


@pytest.mark.parametrize("name", ["quick_mc.toml", "rv40e_121_full.toml"])
def test_the_te_without_the_forces_is_the_te_with_them_to_the_bit(name):
    """The studies ask for the TE alone (`forces=False`): the pins' and meshes' forces are left
    out after each solve, nothing else; on reducers with the roller law (quick_mc) and with every
    bearing clearance (the complete study), at no load and under load, and in the windup test."""
    design, errors = _study_errors(name, [1, 70, 333])
    theta = input_angles(design, 90)
    loads = [0.0, -0.3 * design.rated_torque, 0.05 * design.rated_torque]
    with_forces = equilibria(design, errors, theta, loads)
    without = equilibria(design, errors, theta, loads, forces=False)
    assert without.tau_in is None and without.pin_force_max is None
    assert with_forces.converged.all()
    np.testing.assert_array_equal(without.te, with_forces.te)
    np.testing.assert_array_equal(without.converged, with_forces.converged)
    assert np.ptp(with_forces.te[:, 0], axis=-1).min() > 1 * ARCSEC  # the errors make a TE
    curve = te_curve(design, errors, 0.0, 90, forces=False)
    assert curve.pin_force_max is None
    np.testing.assert_array_equal(curve.te, with_forces.te[:, 0])
    # the windup test never reads the forces: the same windup as the equilibria with them
    torques = metric_torques(design)
    wind = windup(design, errors, torques, positions=3)
    te, force, ok = equilibrium_te(design, errors, wind.theta_in, torques)
    assert force is not None
    np.testing.assert_array_equal(wind.windup, te)


def test_the_compiled_first_pin_is_the_numpy_one(monkeypatch):
    """`first_pin` (the kinematic no-load pose's first pin, compiled) against the numpy route
    it replaces, called on the same pairs inside a no-load TE of quick_mc's reducers: the
    same pins decide (rigid the same) and the pose agrees to round-off, which a dot product
    summed in another order leaves; the TE then agrees within the Newton tolerance."""
    from rvfmu.core.statics import newton_kernel
    from rvfmu.core.statics.solver import ReducedSystem

    if not newton_kernel.COMPILED:
        pytest.skip("numba absent: the numpy route is the only one")
    design, errors = _study_errors("quick_mc.toml", [2, 41, 300, 600])
    first_contact = ReducedSystem._first_contact
    seen = []

    def both(self, angle, f, pin_b, direction):
        compiled = first_contact(self, angle, f, pin_b, direction)
        monkeypatch.setattr(ReducedSystem, "compiled_first_pin", False)
        plain = first_contact(self, angle, f, pin_b, direction)
        monkeypatch.setattr(ReducedSystem, "compiled_first_pin", True)
        seen.append((compiled, plain))
        return compiled

    monkeypatch.setattr(ReducedSystem, "_first_contact", both)
    reference = te_curve(design, errors, 0.0, 360, forces=False)
    assert seen
    for (q, rigid), (q_plain, rigid_plain) in seen:
        np.testing.assert_array_equal(rigid, rigid_plain)
        np.testing.assert_allclose(q, q_plain, rtol=1e-13, atol=1e-13 * np.abs(q_plain).max())
    assert any(r.any() for (_, r), _ in seen) and any((~r).any() for (_, r), _ in seen)
    monkeypatch.setattr(ReducedSystem, "_first_contact", first_contact)
    monkeypatch.setattr(ReducedSystem, "compiled_first_pin", False)
    plain = te_curve(design, errors, 0.0, 360, forces=False)
    assert reference.converged.all() and plain.converged.all()
    np.testing.assert_allclose(reference.te_arcsec, plain.te_arcsec, rtol=0, atol=1e-9)


def _newton_steps(run):
    """(run()'s result, the compiled Newton iteration's steps in it, summed over its pairs)."""
    from unittest import mock

    from rvfmu.core.statics import newton_kernel

    kernel, steps = newton_kernel.newton_pairs, []
    iterations = newton_kernel.newton_pairs_argument("iterations")

    def counted(*arguments):
        kernel(*arguments)
        steps.append(int(arguments[iterations].sum()))  # the kernel's iterations (B,), filled in

    with mock.patch.object(newton_kernel, "newton_pairs", counted):
        return run(), sum(steps)


def test_a_reducer_started_from_a_near_one_reaches_the_same_curve_in_fewer_steps():
    """`te_curve(start_from=...)`: the roller law's no-load solves of a reducer start from
    another's solutions at the same angle instead of its kinematic pose.  On one base sample
    of Saltelli's design (A, the eight rows A_B^(i) that take one group's columns from B,
    then B), each A_B^(i) started from A: the same curves within the Newton tolerance
    (newton.STEP_TOLERANCE at R_p), in fewer Newton steps; the no-load route with bearing
    clearances and a loaded curve ignore the starts."""
    from rvfmu.core.statics import newton

    design, errors = _study_errors("rv40e_121_sobol.toml", list(range(10)))
    start_from = np.array([-1] + [0] * 8 + [-1])
    plain, steps = _newton_steps(lambda: te_curve(design, errors, 0.0, 120, forces=False))
    started, fewer = _newton_steps(
        lambda: te_curve(design, errors, 0.0, 120, forces=False, start_from=start_from)
    )
    assert plain.converged.all() and started.converged.all()
    bound = 2.0 * newton.STEP_TOLERANCE / design.R_p / ARCSEC
    assert np.abs(started.te_arcsec - plain.te_arcsec).max() <= bound
    assert np.array_equal(started.te_arcsec[[0, 9]], plain.te_arcsec[[0, 9]])  # solved as before
    assert fewer < 0.85 * steps, (fewer, steps)
    loaded = te_curve(design, errors, -100.0, 60, forces=False)
    same = te_curve(design, errors, -100.0, 60, forces=False, start_from=start_from)
    np.testing.assert_array_equal(same.te_arcsec, loaded.te_arcsec)


def test_the_started_reducers_chunks_wait_for_their_starts_on_threads_to_the_same_bit(monkeypatch):
    """One pass: the chunks of the reducers started from another's solutions wait for the chunks
    that hold those (`solver._LawStarts`).  With chunks of 64 pairs on two threads (23 chunks
    of sources and dependents, the threads' route of `newton.map_chunks`) the curves are those
    of the same call on one thread in chunks of 4096 pairs, to the bit, and the A and B rows
    those without starts."""
    from rvfmu.core.statics import newton, solver

    design, errors = _study_errors("rv40e_121_sobol.toml", list(range(10)))
    start_from = np.array([-1] + [0] * 8 + [-1])
    monkeypatch.setenv("RVTE_THREADS", "1")
    one = te_curve(design, errors, 0.0, 144, forces=False, start_from=start_from)
    monkeypatch.setenv("RVTE_THREADS", "2")
    monkeypatch.setattr(solver, "CHUNK", 64)
    chunked = []
    map_chunks = newton.map_chunks

    def counted(function, parts):
        parts = list(parts)
        chunked.append(len(parts))
        yield from map_chunks(function, parts)

    monkeypatch.setattr(solver, "map_chunks", counted)
    threads = te_curve(design, errors, 0.0, 144, forces=False, start_from=start_from)
    assert max(chunked) >= newton.CHUNKS_PER_THREAD * 2  # the threads' route
    np.testing.assert_array_equal(threads.te_arcsec, one.te_arcsec)
    plain = te_curve(design, errors, 0.0, 144, forces=False)
    np.testing.assert_array_equal(threads.te_arcsec[[0, 9]], plain.te_arcsec[[0, 9]])


def test_a_failed_chunk_lets_the_chunks_waiting_for_its_starts_go_on(monkeypatch):
    """A chunk whose solve raises still tells the chunks waiting for its solutions that it is
    done (they start from their own kinematic poses): the call raises, it does not hang."""
    import threading
    import time

    from rvfmu.core.statics import solver

    design, errors = _study_errors("rv40e_121_sobol.toml", list(range(10)))
    monkeypatch.setenv("RVTE_THREADS", "2")
    monkeypatch.setattr(solver, "CHUNK", 64)
    solve, failed = solver.ReducedSystem.solve, []

    def failing(self, *arguments, **options):
        # the law's solve of the chunk that holds both A's (0) and B's (9) last pairs, after the
        # other thread has gone on to the chunks that wait for it
        if options.get("start") is not None and 0 in arguments[1] and 9 in arguments[1]:
            time.sleep(1.0)
            failed.append(True)
            raise np.linalg.LinAlgError("a singular Hessian")
        return solve(self, *arguments, **options)

    monkeypatch.setattr(solver.ReducedSystem, "solve", failing)
    raised = []

    def run():
        try:
            te_curve(design, errors, 0.0, 144, forces=False, start_from=np.array([-1] + [0] * 8 + [-1]))
        except np.linalg.LinAlgError as error:
            raised.append(error)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(300)
    assert not thread.is_alive() and failed and raised


def test_law_after_names_other_pairs_that_start_from_their_kinematic_pose():
    from rvfmu.core.statics.solver import _law_after

    np.testing.assert_array_equal(_law_after([-1, 0, 0, -3], 4), [-1, 0, 0, -1])
    assert _law_after(None, 4) is None
    for bad in ([-1, 1, -1], [-1, 3, -1], [-1, 0, 1], [-1, 0], [-1.0, 0.0, 0.0]):
        with pytest.raises(ValueError, match="law_after"):
            _law_after(np.array(bad), 3)


def test_a_start_from_itself_or_out_of_range_is_refused_and_a_chained_one_dropped():
    design, errors = _study_errors("rv40e_121_sobol.toml", [0, 1, 2])
    for bad in ([0, -1, -1], [-1, 3, -1], [-1, 0]):
        with pytest.raises(ValueError, match="start_from"):
            te_curve(design, errors, 0.0, 16, forces=False, start_from=bad)
    # 2 starts from 1, which starts from 0: 2 is solved from its kinematic pose, with 0 and 1
    from rvfmu.core.statics.quasistatic import _started_from

    np.testing.assert_array_equal(_started_from([-1, 0, 1], 3), [-1, 0, -1])


@pytest.mark.parametrize("threads", ["1", "2"])
def test_chunks_are_even_whole_chains_and_on_threads_a_multiple_of_them(monkeypatch, threads):
    """`solver._chunks`: the pairs cut into chunks of at most CHUNK, each but the last a whole
    number of warm-start chains (the results then do not depend on the chunks), as even as
    that allows; on two threads, where the chunks run on the threads, an even number of them."""
    from rvfmu.core.statics import newton, solver

    monkeypatch.setenv("RVTE_THREADS", threads)
    for size, begin in ((46080, 0), (4096 * 11 + 1024, 7), (5000, 3), (31, 0), (4096, 0), (0, 0)):
        parts = solver._chunks(size, begin)
        covered = np.concatenate([np.arange(p.start, p.stop) for p in parts] + [np.arange(0)])
        np.testing.assert_array_equal(covered, np.arange(begin, begin + size))
        lengths = [p.stop - p.start for p in parts]
        assert all(0 < n <= solver.CHUNK for n in lengths)
        assert all(n % newton.CHAIN_LENGTH == 0 for n in lengths[:-1])
        assert len(parts) == -(-size // solver.CHUNK) or threads == "2"
        if threads == "2" and len(parts) >= newton.CHUNKS_PER_THREAD * 2:
            assert len(parts) % 2 == 0
            assert max(lengths) - min(lengths) < 2 * newton.CHAIN_LENGTH
    monkeypatch.setenv("RVTE_THREADS", "2")
    assert [p.stop - p.start for p in solver._chunks(46080)] == [3840] * 12  # a batch of quick_mc


@pytest.mark.parametrize("name", ["quick_mc.toml", "rv40e_121_full.toml"])
def test_the_reduced_system_made_by_blocks_of_angles_is_that_of_one_pass_to_the_bit(monkeypatch, name):
    """`ReducedSystem` makes its arrays in blocks of ANGLE_BLOCK angles, on the threads where there
    are enough blocks: every array equals that of one pass over all the angles, to the bit,
    without bearing clearance (the kinematic and the roller law's systems) and with it."""
    from rvfmu.core.statics import solver
    from tolerance.study import load_study

    design = load_study(ROOT / "studies" / name).design
    model = EquivalentModel(design, input_angles(design, 150), flank=1)
    systems = {
        "kinematic": (np.zeros(model.bearing_k.size, dtype=bool), False),
        "roller law": (model.bearing_law_a > 0.0, True),
        "clearances": (np.ones(model.bearing_k.size, dtype=bool), False),
    }
    for label, (nonlinear, rollers) in systems.items():
        monkeypatch.setattr(solver, "ANGLE_BLOCK", 10**9)
        one = vars(solver.ReducedSystem(model, nonlinear, rollers))
        # 10 blocks alone, 10 on the threads (`newton.map_chunks`), 5 blocks on one of two threads
        for threads, block in (("1", 16), ("2", 16), ("2", 37)):
            monkeypatch.setenv("RVTE_THREADS", threads)
            monkeypatch.setattr(solver, "ANGLE_BLOCK", block)
            blocks = vars(solver.ReducedSystem(model, nonlinear, rollers))
            assert blocks.keys() == one.keys()
            for key, value in one.items():
                if isinstance(value, dict):
                    for k in value:
                        np.testing.assert_array_equal(blocks[key][k], value[k], err_msg=f"{label} {key}")
                elif isinstance(value, np.ndarray):
                    assert blocks[key].shape == value.shape and blocks[key].dtype == value.dtype
                    np.testing.assert_array_equal(blocks[key], value, err_msg=f"{label} {key}")
