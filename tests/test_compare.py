"""`rvte compare`: a bench record beside the model at the record's load.

The records are made by the model itself (and a known bench runout), so the
comparison must find what was put in: the same curve where the same model made
it, and exactly the difference of two models where another one did.
"""

import csv
import json

import numpy as np
import pytest
from conftest import ROOT, linear_bearings

from rvfmu import api
from rvfmu.bench.compare import as_bench_sees, model_grid
from rvfmu.cli import main
from rvfmu.core.base.units import ARCSEC
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import load_errors
from rvfmu.core.statics.quasistatic import equilibria, input_angles

ERRORS = ROOT / "studies" / "seed002_errors.toml"
POINTS = 256  # per output revolution: cheap, and the record's rows lie on the grid


@pytest.fixture(scope="module")
def rv20():
    # the identifications fit the bearings as linear springs (rvfmu/bench/calibration_values.py)
    return linear_bearings(preset("RV-20E"))


@pytest.fixture(scope="module")
def errors(rv20):
    return load_errors(ERRORS, rv20)


def record(path, design, errors, load, revolutions=1, sense=1, runout_arcsec=0.0, noise_arcsec=0.0, seed=1):
    """A bench CSV (theta_in_deg, theta_out_deg) of `revolutions` output revolutions of the
    model at a resisting `load`, POINTS rows per revolution plus the closing row; the
    output encoder reads a once-per-revolution runout and seeded noise [arcsec]."""
    one = input_angles(design, POINTS)
    te = equilibria(design, errors, one, [-sense * load], zero_side=-sense).te[0, 0]
    rows = revolutions * POINTS + 1
    theta_in = sense * 2 * np.pi * design.ratio * np.arange(rows) / POINTS
    te_rows = te[np.mod(sense * np.arange(rows), POINTS)]
    theta_out = theta_in / design.ratio + te_rows
    rng = np.random.default_rng(seed)
    read = (
        theta_out
        + ARCSEC * runout_arcsec * np.cos(theta_out - 0.7)
        + rng.normal(0.0, noise_arcsec * ARCSEC, rows)
    )
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["theta_in_deg", "theta_out_deg"])
        for a, b in zip(np.degrees(theta_in), np.degrees(read)):
            writer.writerow([repr(float(a)), repr(float(b))])
    return path


def test_the_model_against_its_own_curve_matches_with_a_runout_removed_alike(tmp_path, rv20):
    shipped = preset(rv20.name)  # the design by its name, as the command line gives it
    data = record(
        tmp_path / "bench.csv",
        shipped,
        load_errors(ERRORS, shipped),
        100.0,
        revolutions=2,
        runout_arcsec=15.0,
    )
    report = api.compare(rv20.name, data, ERRORS, load=100.0, points=POINTS)
    c = report.comparison
    assert c.measured.revolutions == 2 and c.periodic
    # The runout went out of the record, the model's own order 1 out of both alike.  What
    # is left is second order: the runout is fitted on the encoder's reading, which carries
    # the runout itself (15" x 15" / 206 265" per rad ~ 1e-3").
    assert c.correlation > 1 - 1e-8
    assert c.rms_difference_arcsec < 2e-3
    assert abs(c.te_pp_arcsec[0] - c.te_pp_arcsec[1]) < 2e-3
    # the component removed is the runout plus the reducer's own order 1, as phasors
    theta_out = c.measured.theta_in / rv20.ratio
    basis = np.column_stack([np.cos(theta_out), np.sin(theta_out), np.ones_like(theta_out)])
    a, b, _ = np.linalg.lstsq(basis, c.model_raw_arcsec, rcond=None)[0]
    expected = np.hypot(a + 15.0 * np.cos(0.7), b + 15.0 * np.sin(0.7))
    assert abs(c.measured.components[0].amplitude_arcsec - expected) < 0.01
    assert all(diff < 2e-3 for _, _, _, diff in c.by_order())
    text = report.summary()
    for word in ("te_pp", "correlation", "difference", "by order", "256 points", "linearly interpolated"):
        assert word in text


def test_a_record_turned_backwards_is_modelled_with_its_load_resisting_that_way(tmp_path, rv20, errors):
    data = record(tmp_path / "back.csv", rv20, errors, 80.0, sense=-1)
    c = api.compare(rv20, data, errors, load=80.0, points=POINTS).comparison
    assert c.measured.sense == -1
    assert c.correlation > 1 - 1e-9 and c.rms_difference_arcsec < 1e-6


def test_another_models_record_shows_exactly_the_two_models_difference(tmp_path, rv20, errors):
    softer = rv20.with_fields(pin_disc_stiffness=0.6 * rv20.pin_disc_stiffness)
    data = record(tmp_path / "soft.csv", softer, errors, 167.0)
    c = api.compare(rv20, data, errors, load=167.0, points=POINTS).comparison
    # independently: both models on the grid, the bench's projection applied to each
    theta = c.measured.theta_in
    expected = (
        as_bench_sees(c.measured, model_grid(softer, errors, 167.0, POINTS).at(theta))
        - as_bench_sees(c.measured, model_grid(rv20, errors, 167.0, POINTS).at(theta))
    )[0]
    np.testing.assert_allclose(c.difference_arcsec, expected, atol=1e-6)
    assert c.rms_difference_arcsec > 0.3 and c.correlation < 0.9999
    # the difference by order is the spectrum of the difference curve
    k = int(np.argmax(c.spectrum[2, 1:])) + 1
    assert c.spectrum[2, k] > 0.1
    assert any(order == c.orders[k] for order, *_ in c.by_order(count=40))


def test_cli_prints_json_and_writes_the_plot_and_csv(tmp_path, capsys):
    shipped = preset("RV-20E")  # the design the command line names below
    data = record(tmp_path / "bench.csv", shipped, load_errors(ERRORS, shipped), 50.0)
    png, out = tmp_path / "cmp.png", tmp_path / "cmp.csv"
    code = main(
        [
            "compare",
            "RV-20E",
            str(data),
            "--errors",
            str(ERRORS),
            "--load",
            "50",
            "--points",
            str(POINTS),
            "--plot",
            str(png),
            "--csv",
            str(out),
            "--json",
        ]
    )
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["correlation"] > 1 - 1e-9 and report["model_points_per_revolution"] == POINTS
    assert png.read_bytes()[:4] == b"\x89PNG"
    header = out.read_text().splitlines()[0]
    assert header == "theta_in_rad,te_measured_arcsec,te_model_arcsec,difference_arcsec"


@pytest.mark.parametrize(
    "args, field",
    [
        (["compare", "RV-20E", "missing.csv"], "data"),
        (["compare", "RV-20E", "{data}", "--ratio", "81"], "ratio"),
        (["compare", "RV-20E", "{data}", "--points", "3"], "points"),
        (["compare", "RV-20E", "{data}", "--load", "5000"], "load"),
    ],
)
def test_bad_input_is_one_line_naming_the_field(tmp_path, rv20, errors, capsys, args, field):
    data = record(tmp_path / "b.csv", rv20, errors, 0.0)
    code = main([a.format(data=data) for a in args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and f"error: {field} = " in err
