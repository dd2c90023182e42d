"""The loss commands and calibration hardened: a hysteresis sweep too small to measure, a
loop that breaks its own invariants, speeds beyond any reducer, catalogue figures out of the
calibration's reach, and negative values after list options on the command line."""

import dataclasses
import json
import re

import numpy as np
import pytest
from test_hardening import run_cli

from rvfmu import api, cli
from rvfmu.bench import calibration_data, calibration_fit, calibration_problem, calibration_values
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import RPM
from rvfmu.core.losses import friction
from rvfmu.core.losses import hysteresis as hysteresis_module
from rvfmu.core.losses.hysteresis import AREA_TOLERANCE, MIN_SWEEP_FRACTION, check_loop, hysteresis
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.limits import SPEED_FACTOR
from rvfmu.jobs.efficiency import EfficiencyReport
from rvfmu.jobs.hysteresis import HysteresisReport


def one_line_error(code, out, err, command):
    """The CLI's refusal: status 2, one line on stderr, no numbers printed as results."""
    assert code == 2, (out, err)
    assert err.count("\n") == 1 and err.startswith(f"rvte {command}: error: "), err
    assert "Traceback" not in err and out == ""
    return err


@pytest.fixture
def no_equilibria(monkeypatch):
    """Fail the test if any equilibrium is solved: the refusal must come first."""

    def refuse(*args, **kwargs):
        raise AssertionError("equilibria solved before the input was checked")

    for target in ("rvfmu.core.losses.friction.contact_loads", "rvfmu.core.losses.hysteresis.contact_loads"):
        monkeypatch.setattr(target, refuse)


@pytest.fixture(scope="module")
def rv40():
    return preset("RV-40E-121")


@pytest.fixture(scope="module")
def rated_loop(rv40):
    return hysteresis(rv40, positions=4)


# -- 1. the hysteresis loop -------------------------------------------------------------------


def test_a_sweep_below_the_lost_motion_test_torque_is_refused(rv40, capsys, no_equilibria):
    smallest = MIN_SWEEP_FRACTION * rv40.rated_torque
    assert smallest == pytest.approx(12.36)
    for value in (1e-9, 0.5 * smallest, 12.35):
        with pytest.raises(InputError) as info:
            hysteresis(rv40, max_load=value)
        assert info.value.field == "max_load" and info.value.value == value
        assert "at least 12.36 N*m" in str(info.value) and "3 % of the rated torque" in str(info.value)
    err = one_line_error(*run_cli(["hysteresis", "RV-40E-121", "--max-load", "1e-9"], capsys), "hysteresis")
    assert "max_load = 1e-09: must be at least 12.36 N*m" in err
    with pytest.raises(InputError, match="max_load = 1e-09"):
        api.hysteresis("RV-40E-121", max_load=1e-9)


def test_the_smallest_sweep_allowed_keeps_the_loops_invariants(rv40):
    smallest = MIN_SWEEP_FRACTION * rv40.rated_torque
    h = hysteresis(rv40, max_load=smallest, positions=4)
    assert h.converged and h.tau_load[-1] == pytest.approx(smallest)
    assert 0.0 < h.friction_torque.max() <= smallest
    work = sum(h.friction_work_J.values())
    assert abs(h.area_J - work) <= AREA_TOLERANCE * work
    assert np.isfinite(h.lost_motion_arcmin)  # the sweep reaches +-3 % rated


def test_a_rated_run_keeps_the_loops_invariants_and_prints_no_warning(rated_loop):
    h = rated_loop
    assert h.converged and h.warnings == ()
    assert h.friction_torque.max() <= h.tau_load[-1] == h.design.rated_torque
    work = sum(h.friction_work_J.values())
    assert work > 0.0 and abs(h.area_J - work) <= AREA_TOLERANCE * work
    check_loop(h, h.tau_load[-1])  # passes as it is
    summary = HysteresisReport(h).summary()
    assert "warning" not in summary
    assert f"{h.friction_torque.max():.3g} N*m at most" in summary


@pytest.mark.parametrize(
    "change, expected",
    [
        (dict(converged=False), "did not converge"),
        ("friction above the sweep", "must be above the loop's friction torque"),
        ("work off the area", "must agree within 1e-09"),
    ],
)
def test_a_loop_that_breaks_an_invariant_is_refused(rated_loop, change, expected):
    h, top = rated_loop, rated_loop.tau_load[-1]
    if change == "friction above the sweep":
        t_f = h.friction_torque.copy()
        t_f[3] = 1.5 * top
        bad = dataclasses.replace(h, friction_torque=t_f)
    elif change == "work off the area":
        bad = dataclasses.replace(h, friction_work_J={k: 1.001 * v for k, v in h.friction_work_J.items()})
    else:
        bad = dataclasses.replace(h, **change)
    with pytest.raises(InputError) as info:
        check_loop(bad, top)
    assert info.value.field == "max_load" and info.value.value == top
    assert expected in str(info.value)
    if change == "friction above the sweep":
        assert f"{1.5 * top:.4g} N*m" in str(info.value)


def test_a_loop_that_did_not_converge_prints_no_numbers(monkeypatch, capsys):
    real = hysteresis_module.contact_loads

    def unconverged(*args, **kwargs):
        loads = real(*args, **kwargs)
        ok = loads.converged.copy()
        ok[..., 0] = False
        return dataclasses.replace(loads, converged=ok)

    monkeypatch.setattr(hysteresis_module, "contact_loads", unconverged)
    err = one_line_error(
        *run_cli(["hysteresis", "RV-40E-121", "--max-load", "206", "--json"], capsys), "hysteresis"
    )
    assert "max_load = 206.0: the sweep's equilibria did not converge" in err


def test_a_sweep_above_the_momentary_class_is_run_with_a_warning(rv40, capsys):
    code, out, err = run_cli(["hysteresis", "RV-40E-121", "--max-load", "1236"], capsys)
    assert code == 0, err
    assert re.search(r"^warning +max_load = 1236 N\*m is 3 x the rated torque", out, re.M), out


# -- 2. speeds beyond any reducer -------------------------------------------------------------


def test_a_speed_beyond_the_allowable_class_is_refused_before_any_work(rv40, capsys, no_equilibria):
    limit_rpm = SPEED_FACTOR * rv40.allowable_output_speed / RPM
    assert limit_rpm == pytest.approx(140.0)
    err = one_line_error(*run_cli(["efficiency", "RV-40E-121", "--speeds", "5,1e12"], capsys), "efficiency")
    assert "speeds = 1000000000000.0: is an output speed of 1e+12 rpm" in err
    assert "2 x the allowable output speed 70 rpm of RV-40E-121 (140 rpm out" in err
    with pytest.raises(InputError) as info:
        api.efficiency("RV-40E-121", speeds=[141.0])
    assert info.value.field == "speeds" and info.value.value == 141.0
    with pytest.raises(InputError, match="speeds = 141.0"):
        friction.efficiency_map(rv40, output_speed_rpm=[141.0])
    # the power balance on loads solved elsewhere (calibration) checks them too
    with pytest.raises(InputError, match="speeds = 1e\\+12|speeds = 1000000000000.0"):
        friction.efficiency_from_loads(rv40, None, [1e12], [100.0])
    # the studies' metrics
    with pytest.raises(InputError) as info:
        friction.operating_losses(rv40, None, 100.0, 1e12)
    assert info.value.field == "output_speed_rpm" and "140 rpm out" in str(info.value)


def test_output_speeds_warn_above_the_allowable_speed_and_refuse_what_is_not_a_speed(rv40):
    speeds, warnings = friction.output_speeds("speeds", [10.0, 70.0], rv40)
    assert speeds.tolist() == [10.0, 70.0] and warnings == ()
    speeds, warnings = friction.output_speeds("speeds", [10.0, 100.0, 140.0], rv40)
    assert len(warnings) == 2
    assert warnings[0].startswith(
        "speeds = 100.0 is an output speed of 100 rpm, 1.4 x the allowable output speed 70 rpm of RV-40E-121"
    )
    for bad, expected in (
        (-5.0, "must be positive"),
        (float("nan"), "must be finite"),
        (140.5, "must be within 2 x"),
    ):
        with pytest.raises(InputError) as info:
            friction.output_speeds("speeds", [10.0, bad], rv40)
        assert info.value.field == "speeds" and expected in str(info.value)
    with pytest.raises(InputError, match="at least one value"):
        friction.output_speeds("speeds", [], rv40)


def test_the_efficiency_report_prints_a_speed_warning(rv40, capsys):
    emap = friction.efficiency_map(rv40, output_speed_rpm=[10.0, 100.0], load_Nm=[200.0], points=4)
    assert len(emap.warnings) == 1 and "speeds = 100.0" in emap.warnings[0]
    report = EfficiencyReport(emap)
    assert re.search(r"^warning +speeds = 100.0 is an output speed of 100 rpm", report.summary(), re.M)
    assert report.to_json()["warnings"] == list(emap.warnings)
    code, out, err = run_cli(
        ["efficiency", "RV-40E-121", "--speeds", "100", "--loads", "200", "--json"], capsys
    )
    assert code == 0, err
    assert json.loads(out)["warnings"][0].startswith("speeds = 100.0 is an output speed")


def test_catalogue_friction_points_have_their_speeds_checked(tmp_path, capsys):
    data = tmp_path / "frame.toml"
    data.write_text("[[running_torque]]\noutput_speed_rpm = 1e12\ninput_torque_Nm = 0.1\n")
    out = tmp_path / "fitted.toml"
    err = one_line_error(
        *run_cli(["calibrate", "RV-40E-121", data, "--fit", "bearing_drag_factor", "-o", out], capsys),
        "calibrate",
    )
    assert "frame.toml running_torque 1: output_speed_rpm = 1000000000000.0" in err
    assert "140 rpm out" in err and not out.exists()
    data.write_text("[[running_torque]]\noutput_speed_rpm = 100\ninput_torque_Nm = 0.03\n")
    design = preset("RV-40E-121")
    problem = calibration_problem.problem(
        design,
        [calibration_data.catalogue_dataset(data, calibration_data.read_toml("data", data))],
        ["bearing_drag_factor"],
    )
    assert len(problem.warnings) == 1
    assert problem.warnings[0].startswith(
        "frame.toml running_torque 1: output_speed_rpm = 100.0 is an output speed of 100 rpm"
    )


# -- 3. calibration to figures out of reach ---------------------------------------------------


@pytest.mark.parametrize(
    "text, figure, value",
    [
        (
            "torsional_rigidity_Nm_per_arcmin = 1e9\nlost_motion_arcmin = 1e-9\n",
            "torsional_rigidity_Nm_per_arcmin",
            "1000000000.0",
        ),
        ("torsional_rigidity_Nm_per_arcmin = 1e9\n", "torsional_rigidity_Nm_per_arcmin", "1000000000.0"),
        ("lost_motion_arcmin = 1e-9\n", "lost_motion_arcmin", "1e-09"),
    ],
)
def test_a_catalogue_figure_out_of_reach_writes_nothing(tmp_path, capsys, text, figure, value):
    data = tmp_path / "absurd.toml"
    data.write_text(text)
    out = tmp_path / "calibrated.toml"
    err = one_line_error(
        *run_cli(
            [
                "calibrate",
                "RV-40E-121-estimate",
                data,
                "--fit",
                "output_stiffness,modification_scale",
                "--target",
                "catalogue",
                "-o",
                out,
            ],
            capsys,
        ),
        "calibrate",
    )
    assert not out.exists()
    assert f"error: {figure} = {value}: out of the fit's reach" in err
    # the window: 412 N*m/arcmin / and x 30, the modification scale's 0.05 to 4
    assert (
        "within the default bounds (output_stiffness 13.73 to 1.236e+04 N*m/arcmin, "
        "modification_scale 0.05 to 4 x)"
    ) in err
    low, high = (float(x) for x in re.search(r"the design gives (\S+) to (\S+);", err).groups())
    assert low < high and not low <= float(value) <= high
    with pytest.raises(InputError) as info:
        api.calibrate(
            "RV-40E-121-estimate",
            [data],
            ["output_stiffness", "modification_scale"],
            target="catalogue",
            output=out,
        )
    assert info.value.field == figure and not out.exists()


def test_a_peak_out_of_reach_writes_nothing_and_is_marked_without_a_file(tmp_path, capsys):
    """Without errors the TE peak hardly moves with the pins' stiffness: 1000 arcsec is out of
    reach, although the misfit is too flat to push the fit onto a bound."""
    data = tmp_path / "peaks.toml"
    data.write_text("load_Nm = 167.0\n[[dataset]]\nte_pp_arcsec = 1000.0\n")
    out = tmp_path / "fitted.toml"
    budget = ["--points", "64", "--maxiter", "2", "--popsize", "3"]
    err = one_line_error(
        *run_cli(["calibrate", "RV-20E", data, "--fit", "pin_disc_stiffness", *budget, "-o", out], capsys),
        "calibrate",
    )
    assert (
        "error: te_pp_arcsec of 1 = 1000.0: out of the fit's reach: within the default "
        "bounds (pin_disc_stiffness 4.235e+07 to 6.776e+08 N/m) the design gives" in err
    )
    assert not out.exists()
    code, text, err = run_cli(
        ["calibrate", "RV-20E", data, "--fit", "pin_disc_stiffness", *budget, "--json"], capsys
    )
    assert code == 0, err
    assert json.loads(text)["out_of_reach"].startswith("te_pp_arcsec of 1 = 1000.0: out of")
    report = api.calibrate("RV-20E", [data], ["pin_disc_stiffness"], points=64, maxiter=2, popsize=3)
    assert re.search(r"^warning +NOT A CALIBRATION: te_pp_arcsec of 1 = 1000.0", report.summary(), re.M)


def test_a_fit_pressed_against_a_default_bound_is_refused_and_a_given_one_is_not(rv40):
    """`out_of_reach`: the value on its default bound with the misfit still falling beyond it
    names the figure, the value, the bound and the model's figure there."""
    data = calibration_data.DataSet(
        "frame.toml", catalogue=calibration_data.Catalogue(torsional_rigidity_Nm_per_arcmin=1e9)
    )
    (p,) = calibration_values.parameters(rv40, ["output_stiffness"])
    problem = calibration_problem.Problem(rv40, (p,), (data,), "catalogue", 8)
    after = [np.array([126.2])]
    res = np.array([126.2 / 1e9 - 1.0])
    jac = np.array([[1.3e-7]])  # the rigidity rises with the stiffness
    error = calibration_fit.out_of_reach(problem, np.array([False]), np.array([True]), jac, res, after)
    assert isinstance(error, InputError)
    assert error.field == "torsional_rigidity_Nm_per_arcmin" and error.value == 1e9
    assert f"output_stiffness ends at its upper bound {p.upper:.4g} N*m/arcmin" in str(
        error
    ) and "torsional_rigidity_Nm_per_arcmin = 126.2" in str(error)
    # inside the window, pressed inward, or on bounds the user gave: no refusal
    assert (
        calibration_fit.out_of_reach(problem, np.array([False]), np.array([False]), jac, res, after) is None
    )
    assert (
        calibration_fit.out_of_reach(problem, np.array([False]), np.array([True]), -jac, res, after) is None
    )
    given = dataclasses.replace(p, bounds_given=True)
    assert (
        calibration_fit.out_of_reach(
            dataclasses.replace(problem, parameters=(given,)),
            np.array([False]),
            np.array([True]),
            jac,
            res,
            after,
        )
        is None
    )
    # the corners: the default window cannot reach 1e9, a window the user states is his
    error = calibration_fit.beyond_reach(problem)
    assert error.field == "torsional_rigidity_Nm_per_arcmin" and error.value == 1e9
    assert calibration_fit.beyond_reach(dataclasses.replace(problem, parameters=(given,))) is None


def test_a_shipped_calibration_still_runs_and_writes(tmp_path):
    """The presets' own fit (the RV-20E's frame, as `rvte calibrate` runs it) is unaffected."""
    from rvfmu.bench import catalogue

    frame = catalogue.frame_of("RV-20E")
    data = tmp_path / "frame.toml"
    data.write_text(
        f"torsional_rigidity_Nm_per_arcmin = {frame.torsional_rigidity_Nm_per_arcmin}\n"
        f"lost_motion_arcmin = {catalogue.lost_motion_aim() * frame.lost_motion_max_arcmin}\n"
    )
    out = tmp_path / "rv20.toml"
    report = api.calibrate(
        "RV-20E-estimate",
        [data],
        ["output_stiffness", "modification_scale"],
        target="catalogue",
        maxiter=6,
        popsize=6,
        output=out,
    )
    assert out.is_file() and not report.calibration.at_bound.any()
    assert report.calibration.v_index[1] < 1e-3 * report.calibration.v_index[0]


# -- 4. negative values after list options ----------------------------------------------------


def test_negative_values_are_joined_to_the_option_that_takes_them():
    parser = cli.build_parser()
    assert cli.negative_values(
        parser, ["efficiency", "RV-40E-121", "--speeds", "-5,10", "--json", "--loads", "-1e3"]
    ) == ["efficiency", "RV-40E-121", "--speeds=-5,10", "--json", "--loads=-1e3"]
    # flags take no value; "--" ends the options; other sub-commands are looked up as theirs
    assert cli.negative_values(parser, ["stiffness", "X", "--json", "-5"]) == [
        "stiffness",
        "X",
        "--json",
        "-5",
    ]
    assert cli.negative_values(parser, ["te", "--", "--load", "-5,1"]) == ["te", "--", "--load", "-5,1"]
    assert cli.negative_values(parser, ["fmu", "build", "X", "--points", "-8"]) == [
        "fmu",
        "build",
        "X",
        "--points=-8",
    ]
    assert cli.negative_values(parser, ["te", "X", "--load", "-x"]) == ["te", "X", "--load", "-x"]
    # an abbreviation argparse accepts is joined too, and parsed as the option it stands for
    argv = cli.negative_values(parser, ["efficiency", "X", "--speed", "-5,10"])
    assert argv == ["efficiency", "X", "--speed=-5,10"]
    assert parser.parse_args(argv).speeds == (-5.0, 10.0)
    args = parser.parse_args(
        cli.negative_values(parser, ["simulate", "X", "--load-step", "-0.1:-400", "--load", "-1e3"])
    )
    assert args.load_step == (-0.1, -400.0) and args.load == -1000.0


@pytest.mark.parametrize(
    "args, expected",
    [
        (["efficiency", "RV-40E-121", "--speeds", "-5,10"], "speeds = -5.0: must be positive"),
        (["efficiency", "RV-40E-121", "--loads", "-5,10"], "loads = -5.0: must be positive"),
        (
            ["measure", "{rec}", "--ratio", "121", "--remove-orders", "-1,2"],
            "remove_orders = -1: must be >= 1",
        ),
        (
            ["measure", "{rec}", "--ratio", "121", "--remove-input-orders", "-1,2"],
            "remove_input_orders = -1: must be >= 1",
        ),
        (["measure", "{rec}", "--ratio", "121", "--keep-orders", "-1"], "keep_orders = -1: must be >= 1"),
        (
            ["measure", "{counts}", "--ratio", "121", "--counts-per-rev", "-4096,4096"],
            "counts_per_rev = -4096.0: must be > 0",
        ),
        (
            ["simulate", "RV-40E-121", "--load-step", "-0.1:400"],
            "load_step = '-0.1:400': the load would change at -0.1 s, outside the run",
        ),
        (["te", "RV-40E-121", "--load", "-1e4"], "load = -10000.0: must be within +-5 x"),
        (["hysteresis", "RV-40E-121", "--max-load", "-1e3"], "max_load = -1000.0: must be a positive"),
    ],
)
def test_a_negative_first_value_reaches_the_check_of_its_field(args, expected, tmp_path, capsys):
    n = 2000
    turn = np.linspace(0.0, 121 * 360.0, n)
    rec, counts = tmp_path / "rec.csv", tmp_path / "counts.csv"
    rec.write_text("theta_in_deg,theta_out_deg\n" + "".join(f"{a:.12g},{a / 121:.12g}\n" for a in turn))
    counts.write_text(
        "theta_in_counts,theta_out_counts\n"
        + "".join(f"{a * 4096 / 360:.0f},{a * 4096 / 360 / 121:.0f}\n" for a in turn)
    )
    code, out, err = run_cli([a.format(rec=rec, counts=counts) for a in args], capsys)
    err = one_line_error(code, out, err, args[0])
    assert "expected one argument" not in err and expected in err


def test_the_default_speeds_stay_within_each_presets_allowable_speed():
    from rvfmu.core.base.units import RPM
    from rvfmu.core.losses.friction import DEFAULT_SPEEDS_RPM
    from rvfmu.core.reducer.design import preset

    for name in ("RV-110E", "RV-40E-121"):
        report = api.efficiency(name, loads=[preset(name).rated_torque])
        allowed = preset(name).allowable_output_speed / RPM
        assert list(report.map.output_speed_rpm) == [v for v in DEFAULT_SPEEDS_RPM if v <= allowed]
        assert report.map.warnings == ()
