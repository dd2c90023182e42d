"""`rvte calibrate`: identifying stiffnesses from measured TE.

Every test makes its measurements with the model itself at known stiffnesses
(and seeded noise), so the fit is checked against the truth it must recover.
The budgets are small (few points per revolution, a few generations of
differential evolution): the tests are of the method, not of the optimisers'
defaults.
"""

import json
import math

import numpy as np
import pytest
from test_compare import ERRORS, POINTS, errors, record, rv20  # noqa: F401 (errors, rv20: fixtures)

from rvfmu import api
from rvfmu.bench.calibration_data import design_sources
from rvfmu.bench.calibration_values import parameters
from rvfmu.bench.compare import model_grid
from rvfmu.cli import main
from rvfmu.core.base.checks import InputError
from rvfmu.core.laws import compliance
from rvfmu.core.laws.stiffness import crank_carrier_stiffness_estimate, series
from rvfmu.core.reducer.design import load_design
from rvfmu.core.statics.quasistatic import windup

BUDGET = dict(points=POINTS, maxiter=4, popsize=5)
TRUTH = {"pin_disc_stiffness": 1.3, "crank_disc_bearing_stiffness": 0.75}  # x the preset's


@pytest.fixture(scope="module")
def truth(rv20):
    return rv20.with_fields(**{k: s * getattr(rv20, k) for k, s in TRUTH.items()})


def write(path, text):
    path.write_text(text)
    return path


def test_curves_give_back_the_stiffnesses_that_made_them(tmp_path, rv20, errors, truth):
    # two bench records of the true reducer at two loads, 0.2" of encoder noise
    for load, seed in ((50, 1), (167, 2)):
        record(tmp_path / f"r{load}.csv", truth, errors, float(load), noise_arcsec=0.2, seed=seed)
    data = write(
        tmp_path / "sets.toml",
        f'errors = "{ERRORS}"\n'
        '[[dataset]]\nname = "50 Nm"\ndata = "r50.csv"\nload_Nm = 50.0\n'
        '[[dataset]]\nname = "167 Nm"\ndata = "r167.csv"\nload_Nm = 167.0\n',
    )
    out = tmp_path / "calibrated.toml"
    # the crank-disc bearing is fitted as a linear spring (a bearing on the roller law is not);
    # the pins are linear as the truth's
    design = write(
        tmp_path / "rv20e_linear.toml",
        'preset = "RV-20E"\nname = "RV-20E"\nneedle_rollers = 0\ntapered_rollers = 0\n'
        "pin_groove_clearance_mm = 0\n",
    )
    report = api.calibrate(str(design), [data], list(TRUTH), output=out, **BUDGET)
    cal = report.calibration
    assert cal.problem.target == "curve"
    for p, value, sigma in zip(cal.problem.parameters, cal.values, cal.sigma):
        true = getattr(truth, p.field)
        assert abs(value / true - 1) < 0.05, p.name
        assert 0 < sigma < 0.05 * value, p.name
        assert abs(value - true) < 3 * sigma, (p.name, value, true, sigma)  # 1-sigma is honest
    rows = cal.misfit()
    assert all(r["misfit_after"] < r["misfit_before"] for r in rows)
    assert all(abs(r["misfit_after"] - 0.2) < 0.05 for r in rows)  # down to the noise
    # the calibrated design file is a design: rvte te reads it, with the fitted values
    design = load_design(out)
    for p, value in zip(cal.problem.parameters, cal.values):
        assert getattr(design, p.field) == pytest.approx(value, rel=1e-12)
    assert main(["te", str(out), "--points", "64"]) == 0


def test_peaks_of_data_sets_at_several_loads_give_back_the_pin_stiffness(tmp_path, rv20, errors):
    truth = rv20.with_fields(pin_disc_stiffness=0.7 * rv20.pin_disc_stiffness)
    # six loads: with three, the residual variance (two degrees of freedom) is too poor an
    # estimate of the noise for a 3-sigma statement
    loads = (25.0, 40.0, 70.0, 100.0, 130.0, 167.0)
    rng = np.random.default_rng(3)
    text = f'errors = "{ERRORS}"\n'
    for load in loads:
        peak = float(np.ptp(model_grid(truth, errors, load, POINTS).te_arcsec))
        text += (
            f'[[dataset]]\nname = "{load:g} Nm"\nload_Nm = {load}\n'
            f"te_pp_arcsec = {peak + rng.normal(0, 0.05)!r}\n"
        )
    data = write(tmp_path / "peaks.toml", text)
    cal = api.calibrate(rv20, [data], ["pin_disc_stiffness_N_per_m"], **BUDGET).calibration
    assert cal.problem.target == "peaks"
    (value,), (sigma,) = cal.values, cal.sigma
    assert abs(value / truth.pin_disc_stiffness - 1) < 0.05
    assert abs(value - truth.pin_disc_stiffness) < 3 * sigma
    v_before, v_after = cal.v_index
    assert v_after < 0.01 * v_before


def test_catalogue_rigidity_gives_back_the_pin_stiffness_with_no_variance_left(tmp_path):
    shipped = load_design("RV-20E")  # the design the calibration below starts from
    truth = shipped.with_fields(pin_disc_stiffness=1.5 * shipped.pin_disc_stiffness)
    rigidity = float(windup(truth).torsional_rigidity_Nm_per_arcmin()[0])
    data = write(
        tmp_path / "catalogue.toml",
        f"torsional_rigidity_Nm_per_arcmin = {rigidity!r}\nrated_torque_Nm = 167.0\n",
    )
    report = api.calibrate("RV-20E", [data], ["pin_disc_stiffness"], maxiter=3, popsize=5)
    cal = report.calibration
    assert cal.problem.target == "catalogue"
    assert abs(cal.values[0] / truth.pin_disc_stiffness - 1) < 0.01
    assert np.isnan(cal.sigma[0]) and cal.dof == 0  # one figure, one value: no variance left
    assert "no variance left" in report.summary()


def test_a_stiffness_the_data_do_not_see_is_reported_not_identifiable(tmp_path):
    # No load, no errors: the TE is that of exact rigid parts, zero (docs/model.md section 5),
    # whatever R_ca is.
    data = write(
        tmp_path / "noload.toml",
        "load_Nm = 0.0\n[[dataset]]\nte_pp_arcsec = 60.0\n[[dataset]]\nte_pp_arcsec = 61.0\n",
    )
    report = api.calibrate("RV-20E", [data], ["R_ca"], points=POINTS, maxiter=0)
    assert np.isinf(report.calibration.sigma[0])
    assert "not identifiable" in report.summary()
    assert json.dumps(report.to_json(), allow_nan=False)  # inf as text: JSON has no inf


def test_seed003_names_map_onto_the_design_and_the_bearings_sit_in_series_with_the_crank(rv20):
    sources = design_sources("RV-20E")
    ca, b, pd = parameters(rv20, ["R_ca", "R_b", "R_pd"], sources=sources)
    assert (ca.field, b.field, pd.field) == (
        "main_bearing_stiffness",
        "crank_carrier_bearing_stiffness",
        "crank_disc_bearing_stiffness",
    )
    assert ca.value == rv20.main_bearing_stiffness
    # the preset's crank-disc value is the needle bearing (Palmgren with its roller load
    # distribution, 11 rollers of 6 mm, secant between 50 % and 100 % of 167 / (2 * 2 * a))
    # in series with the crank at a cam, and its crank-carrier value the tapered roller pair
    # (13 rollers of 5 mm at 10 deg, half of 167 / (2 a) each) in series with the crank's
    # common part (13 mm, span 34 mm, cams at 13 and 21 mm: compliance.crank_split)
    a = rv20.crank_circle_radius
    needle = compliance.secant_stiffness(
        lambda f: compliance.bearing_deflection(f, 11, 6e-3), 0.5 * 167.0 / (4 * a), 167.0 / (4 * a)
    )
    pair = crank_carrier_stiffness_estimate(167.0, 2, a, 13, 5e-3, math.radians(80.0))
    influence = compliance.crank_influence(211e9, 0.29, 13e-3, 34e-3, (13e-3, 21e-3))
    each, common = compliance.crank_split(influence, 34e-3, (13e-3, 21e-3), pair)
    assert pd.value == pytest.approx(needle, rel=0.005)
    assert b.value == pytest.approx(pair, rel=0.005)
    assert pd.series_with == pytest.approx(1.0 / each, rel=0.005)
    assert b.series_with == pytest.approx(1.0 / common, rel=0.005)
    for p, value in ((pd, 1.1e10), (b, 2e9)):
        assert p.field_values(value)[p.field] == pytest.approx(series(value, p.series_with))
        assert p.field_values(p.value)[p.field] == pytest.approx(getattr(rv20, p.field))
    # without the crank's geometry neither bearing can be told from the crank
    for name in ("R_b", "R_pd"):
        with pytest.raises(InputError) as info:
            parameters(rv20, [name], sources={})
        assert info.value.field == "fit" and "crank_diameter_mm" in str(info.value)


def test_a_bearing_on_the_roller_law_is_not_fitted_as_a_spring():
    """Its stiffness comes from its rollers (rvfmu/core/laws/roller_law.py); fitting the stated
    secant would fit nothing the model uses under load."""
    from rvfmu.core.base.checks import InputError

    design = load_design("RV-20E")  # the preset as shipped: its crank bearings on the law
    for name, key in (("R_pd", "needle_rollers"), ("R_b", "tapered_rollers")):
        with pytest.raises(InputError) as info:
            parameters(design, [name], sources=design_sources("RV-20E"))
        assert info.value.field == "fit" and key in str(info.value)
    assert parameters(design, ["R_ca"])[0].field == "main_bearing_stiffness"


@pytest.mark.parametrize(
    "args, field",
    [
        (["--fit", "R_xx"], "fit"),
        (["--fit", "R_ca", "--bounds", "R_ca=-1e10:8e10"], "bounds.R_ca"),
        (["--fit", "R_ca", "--bounds", "R_ca=8e10:7e10"], "bounds.R_ca"),
        (["--fit", "R_ca", "--bounds", "R_b=1e10:2e10"], "bounds"),
        (["--fit", "R_ca", "--target", "curve"], "target"),
        (["--fit", "R_ca", "-o", "no/such/folder/x.toml"], "output"),
    ],
)
def test_bad_input_is_one_line_naming_the_field(tmp_path, capsys, args, field):
    data = write(tmp_path / "p.toml", "[[dataset]]\nte_pp_arcsec = 60.0\n")
    code = main(["calibrate", "RV-20E", str(data), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and f"error: {field} = " in err, err


def test_a_missing_data_file_is_named(tmp_path, capsys):
    code = main(["calibrate", "RV-20E", str(tmp_path / "gone.csv"), "--fit", "R_ca"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "error: data = " in err and "gone.csv" in err
