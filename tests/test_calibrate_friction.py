"""Calibrating the friction fields to efficiencies and running torques
(rvfmu/bench/calibration_problem.py, docs/model.md section 9): known coefficients come back
from the figures they made."""

import json

import numpy as np
import pytest

from rvfmu import api
from rvfmu.cli import main
from rvfmu.core.losses.friction import efficiency_map
from rvfmu.core.reducer.design import load_design


def write(path, text):
    path.write_text(text)
    return path


def catalogue_text(design, efficiency_points, running_speeds, rigidity=None):
    """A catalogue TOML of the figures `design` gives at those points (the power balance)."""
    speeds = sorted({v for v, _ in efficiency_points} | set(running_speeds))
    loads = sorted({t for _, t in efficiency_points})
    m = efficiency_map(design, None, speeds, loads)
    text = 'source = "made by the model with known coefficients"\n'
    if rigidity is not None:
        text += f"torsional_rigidity_Nm_per_arcmin = {rigidity!r}\n"
    for v, t in efficiency_points:
        eta = float(m.efficiency[speeds.index(v), loads.index(t)])
        text += (
            f"[[efficiency]]\noutput_speed_rpm = {v!r}\nload_Nm = {t!r}\nefficiency = {eta!r}\n"
            "lubricant_temperature_C = 40.0\n"
        )
    for v in running_speeds:
        torque = float(m.no_load_running_torque_Nm[speeds.index(v)])
        text += f"[[running_torque]]\noutput_speed_rpm = {v!r}\ninput_torque_Nm = {torque!r}\n"
    return text


def test_coefficients_come_back_from_the_efficiencies_and_running_torques_they_made(tmp_path):
    """The pins' coefficient sets the Coulomb losses (efficiency at load), the bearings' drag
    factor the load-free ones (running torque): both come back to 1e-4."""
    start = load_design("RV-40E-121").with_fields(pin_groove_friction=0.3)  # the disc's is the smaller
    truth = start.with_fields(pin_disc_friction=0.08, bearing_drag_factor=3.0)
    data = write(
        tmp_path / "catalogue.toml",
        catalogue_text(truth, [(5.0, 412.0), (20.0, 206.0), (40.0, 412.0)], [5.0, 40.0]),
    )
    report = api.calibrate(
        start, [data], ["pin_disc_friction", "bearing_drag_factor"], target="catalogue", maxiter=5, popsize=5
    )
    cal = report.calibration
    np.testing.assert_allclose(cal.values, [0.08, 3.0], rtol=1e-4)
    assert cal.dof == 3 and np.all(np.abs(cal.residuals_after) < 1e-6)
    assert np.all(np.abs(cal.residuals_before) > 1e-3)
    summary = report.summary()
    assert "1 - efficiency, 20 rpm 206 N*m" in summary and "running torque N*m, 40 rpm" in summary
    assert json.dumps(report.to_json(), allow_nan=False)


def test_stiffness_and_friction_figures_fit_together(tmp_path):
    """A catalogue with the rigidity and an efficiency: the pin stiffness and the mesh
    coefficient, each seen by its own figure, come back together."""
    from rvfmu.core.statics.quasistatic import windup

    start = load_design("RV-20E")
    truth = start.with_fields(pin_disc_stiffness=1.3 * start.pin_disc_stiffness, mesh_friction=0.08)
    rigidity = float(windup(truth).torsional_rigidity_Nm_per_arcmin()[0])
    data = write(
        tmp_path / "catalogue.toml",
        catalogue_text(truth, [(15.0, 167.0), (30.0, 83.5)], [], rigidity=rigidity),
    )
    cal = api.calibrate(
        start, [data], ["pin_disc_stiffness", "mesh_friction"], target="catalogue", maxiter=3, popsize=5
    ).calibration
    np.testing.assert_allclose(cal.values, [truth.pin_disc_stiffness, 0.08], rtol=2e-3)


def test_the_command_fits_a_coefficient_and_writes_it(tmp_path, capsys):
    truth = load_design("RV-20E").with_fields(mesh_friction=0.07)
    data = write(tmp_path / "c.toml", catalogue_text(truth, [(10.0, 167.0)], []))
    out = tmp_path / "fitted.toml"
    assert (
        main(
            [
                "calibrate",
                "RV-20E",
                str(data),
                "--fit",
                "mesh_friction_coefficient",
                "--maxiter",
                "2",
                "--popsize",
                "4",
                "-o",
                str(out),
                "--json",
            ]
        )
        == 0
    )
    fitted = json.loads(capsys.readouterr().out)["fitted"][0]
    assert fitted["name"] == "mesh_friction" and fitted["unit"] == "1"
    assert fitted["value"] == pytest.approx(0.07, rel=1e-4)
    assert load_design(out).mesh_friction == pytest.approx(0.07, rel=1e-4)


@pytest.mark.parametrize(
    "text, args, field",
    [
        (
            "[[efficiency]]\noutput_speed_rpm = 10\nload_Nm = 100\nefficiency = 85\n",
            ["--fit", "mesh_friction"],
            "efficiency",
        ),
        ("[[efficiency]]\noutput_speed_rpm = 10\nefficiency = 0.85\n", ["--fit", "mesh_friction"], "load_Nm"),
        (
            "[[running_torque]]\noutput_speed_rpm = 10\ninput_torque_Nm = -1\n",
            ["--fit", "mesh_friction"],
            "input_torque_Nm",
        ),
        (
            "[[running_torque]]\noutput_speed_rpm = 10\ninput_torque_Nm = 0.1\ntemperature = 40\n",
            ["--fit", "mesh_friction"],
            "temperature",
        ),
        (
            "[[running_torque]]\noutput_speed_rpm = 10\ninput_torque_Nm = 0.1\n",
            ["--fit", "seal_torque"],
            "fit",
        ),  # the design's seal torque is 0: no log start
    ],
)
def test_bad_friction_data_is_one_line_naming_the_field(tmp_path, capsys, text, args, field):
    data = write(tmp_path / "c.toml", text)
    code = main(["calibrate", "RV-20E", str(data), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "error: " in err and f" {field} = " in err, err
