"""Results as pandas DataFrames (issue 27): studies, the store, curves and reports.

The studies are the toy studies of tests/tolerance_toy.py (the linear RV-40E-121 at 64
points); one factor of every kind, so that every kind's columns are checked.
"""

import json
import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from tolerance_toy import DESIGN_FILE, write_study

from rvfmu import api
from rvfmu.core.base.checks import InputError
from rvfmu.core.reducer.errors import errors_from_file_values
from rvfmu.core.statics import metrics
from rvfmu.core.statics.quasistatic import te_curve
from tolerance import evaluate, load_results, montecarlo, run_mc, run_sobol
from tolerance.allocation import AllocationResult, FactorAllocation, YieldEstimate
from tolerance.frames import results_frame
from tolerance.study import load_study

ROOT = Path(__file__).resolve().parent.parent

TOLERANCES = {  # one factor of each kind but clearance: zone, pitch, band
    "crank_cam_eccentricity": {"position_um": 9.0, "distribution": "normal"},
    "pin_pitch": {"cumulative_um": 8.0, "single_um": 2.5},
    "pin_radial": {"band_um": 5.0},
}
FACTOR_COLUMNS = ["crank_cam_eccentricity_position_um", "pin_pitch_cumulative_um", "pin_radial_band_um"]
# A clearance costs the aliasing check of a run (12 480 points) ten times as much: its
# column is checked on reducers evaluated at the study's points, without a run.
CLEARANCE = {"crank_disc_clearance": {"min_um": 2.0, "max_um": 8.0}}
SPEC = {"te_pp_arcsec": 25.0, "rms_arcsec": 6.0}


@pytest.fixture(scope="module")
def mc(tmp_path_factory):
    """The toy study with every kind of factor and two spec lines: 16 reducers, 2 batches."""
    folder = tmp_path_factory.mktemp("frames")
    path = write_study(folder, name="kinds", tolerances=TOLERANCES, spec=SPEC, montecarlo={"n": 16})
    return path, run_mc(path, output=folder / "out", plots=False)


# -- Monte Carlo ------------------------------------------------------------------------------


def test_mc_frame_has_a_row_per_reducer_and_typed_columns(mc):
    _, result = mc
    df = result.to_df()
    assert list(df.columns) == FACTOR_COLUMNS + [
        "te_pp_arcsec",
        "rms_arcsec",
        "converged",
        "passed_te_pp_arcsec",
        "passed_rms_arcsec",
        "passed",
    ]
    assert df.index.name == "row" and df.index.dtype == np.int64
    np.testing.assert_array_equal(df.index, np.arange(16))
    for column in FACTOR_COLUMNS + ["te_pp_arcsec", "rms_arcsec"]:
        assert df[column].dtype == np.float64, column
    assert df["converged"].dtype == bool
    for column in ("passed_te_pp_arcsec", "passed_rms_arcsec", "passed"):
        assert df[column].dtype == "boolean", column
    np.testing.assert_array_equal(df[["te_pp_arcsec", "rms_arcsec"]].to_numpy(), result.Y)
    np.testing.assert_array_equal(df["converged"].to_numpy(), result.converged)


def test_mc_frame_checks_the_spec_as_the_yield_does(mc):
    _, result = mc
    df = result.to_df()
    te_pp_ok = result.Y[:, 0] <= SPEC["te_pp_arcsec"]
    rms_ok = result.Y[:, 1] <= SPEC["rms_arcsec"]
    np.testing.assert_array_equal(df["passed_te_pp_arcsec"].to_numpy(bool), te_pp_ok)
    np.testing.assert_array_equal(df["passed_rms_arcsec"].to_numpy(bool), rms_ok)
    np.testing.assert_array_equal(df["passed"].to_numpy(bool), te_pp_ok & rms_ok)
    yields = {y.label: y.fraction for y in result.analysis.yields}
    assert df["passed_te_pp_arcsec"].mean() == pytest.approx(yields["te_pp_arcsec <= 25"])
    assert df["passed"].mean() == pytest.approx(yields["all limits"])


def test_a_failed_reducer_has_no_pass_and_is_left_out_of_the_yield(mc):
    path, _ = mc
    study = load_study(path)
    Y = np.array([[10.0, 2.0], [np.nan, 1.0], [40.0, 3.0], [20.0, 9.0]])
    converged = np.array([True, False, True, False])
    df = results_frame(study, np.arange(4), montecarlo.rows(study, 0, 4), Y, converged)
    assert df["passed"].isna().tolist() == [False, True, False, False]
    assert df["passed"].dropna().tolist() == [True, False, False]
    analysis = montecarlo.analyze(study, Y, converged)
    assert analysis.yields[-1].fraction == pytest.approx(1 / 3)
    assert df["passed"].mean() == pytest.approx(analysis.yields[-1].fraction)


def test_drawn_factor_values_lie_within_their_tolerances(mc):
    _, result = mc
    df = result.to_df()
    assert df["crank_cam_eccentricity_position_um"].between(0.0, 9.0).all()
    assert df["pin_pitch_cumulative_um"].between(0.0, 8.0).all()
    assert df["pin_radial_band_um"].between(0.0, 5.0).all()
    assert df[FACTOR_COLUMNS].std().gt(0).all()  # drawn, not constant


def test_factor_values_summarise_the_drawn_errors(mc):
    _, result = mc
    df = result.to_df(errors=True)
    design = result.study.design
    cams = df[[f"crank_cam_eccentricity[{i},{j}].E_um" for i in range(design.n_c) for j in range(2)]]
    np.testing.assert_allclose(df["crank_cam_eccentricity_position_um"], 2 * cams.max(axis=1), rtol=1e-12)
    pitch = df[[f"pin_pitch[{k}]_um" for k in range(design.z_p)]].to_numpy()
    np.testing.assert_allclose(df["pin_pitch_cumulative_um"], np.ptp(pitch, axis=1), rtol=1e-12)
    assert np.all(pitch[:, 0] == 0.0)  # tooth 0 is the reference of a cumulative pitch
    single = np.abs(pitch - np.roll(pitch, 1, axis=1)).max(axis=1)
    assert np.all(single <= 2.5 + 1e-9)  # f_pt holds
    radial = df[[f"pin_radial[{k}]_um" for k in range(design.z_p)]].to_numpy()
    np.testing.assert_allclose(df["pin_radial_band_um"], 2 * np.abs(radial).max(axis=1), rtol=1e-12)
    betas = df.filter(like=".beta_deg")
    assert betas.shape[1] == 2 * design.n_c and ((betas >= 0) & (betas < 360)).all().all()
    assert list(df.columns[:3]) == FACTOR_COLUMNS and list(df.columns[-6:-3]) == [
        "te_pp_arcsec",
        "rms_arcsec",
        "converged",
    ]
    assert len(df.columns) == 3 + 4 * design.n_c + 2 * design.z_p + 6


def _file_values(row, design) -> dict:
    """One reducer's drawn errors as an error file writes them (um, deg), from its frame row:
    the error columns of the fixture's factors, and the clearance's factor column if any."""
    cams = [
        [
            [row[f"crank_cam_eccentricity[{i},{j}].E_um"], row[f"crank_cam_eccentricity[{i},{j}].beta_deg"]]
            for j in range(2)
        ]
        for i in range(design.n_c)
    ]
    values = {
        "crank_cam_eccentricity": cams,
        "pin_pitch": [row[f"pin_pitch[{k}]_um"] for k in range(design.z_p)],
        "pin_radial": [row[f"pin_radial[{k}]_um"] for k in range(design.z_p)],
    }
    if "crank_disc_clearance_um" in row:
        values["crank_disc_clearance"] = row["crank_disc_clearance_um"]
    return values


def _solved_alone(study, row) -> tuple[float, float]:
    """te_pp and RMS [arcsec] of the reducer an error file of the row's values describes."""
    errors = errors_from_file_values(study.design, _file_values(row, study.design))
    curve = te_curve(study.design, errors, tau_load=-study.load_Nm, points=study.points)
    return metrics.te_pp(curve.te_arcsec)[0], metrics.te_rms(curve.te_arcsec)[0]


def test_the_drawn_values_reproduce_the_reducers(mc):
    """A row's drawn errors, read back as an error file and solved alone, give its metrics."""
    _, result = mc
    df = result.to_df(errors=True)
    rows = sorted({0, 5, int(df["te_pp_arcsec"].idxmax())})
    for r in rows:
        te_pp, rms = _solved_alone(result.study, df.loc[r])
        assert te_pp == pytest.approx(df.loc[r, "te_pp_arcsec"], rel=1e-6, abs=1e-6), r
        assert rms == pytest.approx(df.loc[r, "rms_arcsec"], rel=1e-6, abs=1e-6), r
    # ... and another row's values do not: the columns belong to their row.
    assert _solved_alone(result.study, df.loc[rows[1]])[0] != pytest.approx(
        df.loc[rows[0], "te_pp_arcsec"], rel=1e-3
    )


def test_a_clearance_is_its_own_column_and_reproduces_the_reducers(tmp_path):
    study = load_study(write_study(tmp_path, name="clear", tolerances={**TOLERANCES, **CLEARANCE}))
    X = montecarlo.rows(study, 0, 4)
    Y, converged = evaluate(study, X)
    df = results_frame(study, np.arange(4), X, Y, converged, errors=True)
    assert list(df.columns[:4]) == FACTOR_COLUMNS + ["crank_disc_clearance_um"]
    assert not any(c.startswith("crank_disc_clearance") for c in df.columns[4:])
    assert df["crank_disc_clearance_um"].between(2.0, 8.0).all()
    assert df["crank_disc_clearance_um"].nunique() == 4
    for r in (1, 3):
        te_pp, rms = _solved_alone(study, df.loc[r])
        assert te_pp == pytest.approx(df.loc[r, "te_pp_arcsec"], rel=1e-6, abs=1e-6), r
        assert rms == pytest.approx(df.loc[r, "rms_arcsec"], rel=1e-6, abs=1e-6), r


def test_mc_samples_csv_is_the_frame_written(mc):
    path, result = mc
    out = path.parent / "out"
    csv = pd.read_csv(out / "mc_samples.csv", index_col="row")
    assert (out / "mc_samples.csv").read_text().splitlines()[0] == "row,te_pp_arcsec,rms_arcsec,converged"
    df = result.to_df()
    np.testing.assert_array_equal(csv.index, df.index)
    np.testing.assert_allclose(
        csv[["te_pp_arcsec", "rms_arcsec"]], df[["te_pp_arcsec", "rms_arcsec"]], rtol=5e-6
    )
    np.testing.assert_array_equal(csv["converged"], df["converged"].astype(int))
    first = (out / "mc_samples.csv").read_text().splitlines()[1].split(",")
    assert first[1] == f"{result.Y[0, 0]:.6g}" and first[-1] in ("0", "1")


# -- the store -------------------------------------------------------------------------------


def test_load_results_equals_the_runs_frame(mc):
    path, result = mc
    out = path.parent / "out"
    pd.testing.assert_frame_equal(load_results(out), result.to_df())
    pd.testing.assert_frame_equal(load_results(out, "mc", errors=True), result.to_df(errors=True))


def test_load_results_reads_the_batches_there_are(mc, tmp_path):
    path, result = mc
    out = tmp_path / "partial"
    shutil.copytree(path.parent / "out", out)
    sorted((out / "mc").glob("batch-*.parquet"))[0].unlink()  # rows 0-7 gone
    df = load_results(out)
    np.testing.assert_array_equal(df.index, np.arange(8, 16))
    pd.testing.assert_frame_equal(df, result.to_df().iloc[8:])


def test_load_results_refuses_what_it_cannot_trust(mc, tmp_path):
    path, _ = mc
    with pytest.raises(InputError, match="must be an existing study output folder"):
        load_results(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="has no manifest.json"):
        load_results(tmp_path / "empty")
    other = tmp_path / "other"
    shutil.copytree(path.parent / "out", other)
    with pytest.raises(InputError, match="has no results in .*jobs there: mc"):
        load_results(other, "sobol-n16")
    with pytest.raises(InputError, match="must be mc or a Sobol job"):
        load_results(other, "allocation")
    for batch in (other / "mc").glob("batch-*.parquet"):
        batch.unlink()
    with pytest.raises(InputError, match="has no batch files") as info:
        load_results(other)
    assert str(other / "mc") in str(info.value)
    old = tmp_path / "old"
    shutil.copytree(path.parent / "out", old)
    manifest = json.loads((old / "manifest.json").read_text())
    manifest["model_hash"] = "0" * 64
    (old / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(InputError, match="computed by another version of the model") as info:
        load_results(old)
    assert info.value.value == str(old)


# -- Sobol ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sobol(tmp_path_factory):
    """The toy study's Sobol run with second order: N = 8, 3 groups, 64 rows."""
    folder = tmp_path_factory.mktemp("sobol")
    path = write_study(folder, sobol={"n": 8, "resamples": 20, "second_order": True})
    return path, run_sobol(path, output=folder / "out", plots=False)


def test_sobol_frame_is_long_ranked_and_matches_the_json(sobol):
    _, result = sobol
    df = result.to_df()
    assert list(df.columns) == [
        "metric",
        "factor",
        "rank",
        "S1",
        "S1_conf",
        "ST",
        "ST_conf",
        "S1_reported",
        "ST_reported",
        "not_converged",
        "ci_wide",
        "S1_above_ST",
        "notes",
        "ranking_converged",
        "ST_above_next",
        "ST_above_next_conf",
        "order_settled",
        "method",
        "check_q2",
    ]
    assert set(df["method"]) == {"saltelli"} and df["check_q2"].isna().all()
    groups = list(result.study.groups)
    assert len(df) == 2 * len(groups)
    assert pd.api.types.is_string_dtype(df["metric"]) and pd.api.types.is_string_dtype(df["factor"])
    assert df["rank"].dtype == np.int64
    for column in (
        "S1",
        "S1_conf",
        "ST",
        "ST_conf",
        "S1_reported",
        "ST_reported",
        "ST_above_next",
        "ST_above_next_conf",
    ):
        assert df[column].dtype == np.float64, column
    for column in ("not_converged", "ci_wide", "S1_above_ST", "ranking_converged", "order_settled"):
        assert df[column].dtype == bool, column
    document = result.to_json()["metrics"]
    for metric, table in df.groupby("metric", sort=False):
        assert sorted(table["factor"]) == sorted(groups)
        assert table["rank"].tolist() == list(range(1, len(groups) + 1))
        for item, (_, row) in zip(document[metric]["groups"], table.iterrows(), strict=True):
            assert (item["name"], item["rank"]) == (row["factor"], row["rank"])
            for key in ("S1", "S1_conf", "ST", "ST_conf", "S1_reported", "ST_reported"):
                assert row[key] == pytest.approx(item[key], abs=0, rel=1e-15), key
            assert row["notes"] == "; ".join(item["notes"])
            assert row["not_converged"] == ("not converged" in row["notes"])
            assert row["ci_wide"] == ("CI wide" in row["notes"])
            assert row["S1_above_ST"] == ("beyond their CIs" in row["notes"])
            step = item["next"]
            if step is None:  # the last rank: nothing below it
                assert row["rank"] == len(groups) and np.isnan(row["ST_above_next"])
                assert not row["order_settled"]
            else:
                assert row["ST_above_next"] == pytest.approx(step["difference"], abs=0, rel=1e-15)
                assert row["ST_above_next_conf"] == step["half_width"]
                assert row["order_settled"] == step["settled"]
        assert table["ranking_converged"].nunique() == 1
        assert table["ranking_converged"].iloc[0] == document[metric]["convergence"]["converged"]
    assert df["ci_wide"].any()  # N = 8: wide intervals, flagged


def test_sobol_second_order_frame(sobol):
    _, result = sobol
    s2 = result.to_df(second_order=True)
    assert list(s2.columns) == ["metric", "factor_a", "factor_b", "S2", "S2_conf"]
    G = len(result.study.groups)
    assert len(s2) == 2 * G * (G - 1) // 2
    document = result.to_json()["metrics"]
    for row in s2.itertuples():
        pair = document[row.metric]["S2"][f"{row.factor_a} x {row.factor_b}"]
        assert (row.S2, row.S2_conf) == pytest.approx((pair["S2"], pair["S2_conf"]))
    with pytest.raises(InputError, match="computed no second-order indices"):
        replace(result, second_order=False).to_df(second_order=True)


def test_load_results_of_a_sobol_job_gives_its_saltelli_rows(sobol):
    path, result = sobol
    df = load_results(path.parent / "out", "sobol-n8-second-order")
    np.testing.assert_array_equal(df.index, np.arange(result.X.shape[0]))
    np.testing.assert_array_equal(df[list(result.study.metric_columns)].to_numpy(), result.Y)
    expected = results_frame(
        result.study, np.arange(result.X.shape[0]), result.X, result.Y, result.computed.converged
    )
    pd.testing.assert_frame_equal(df, expected, check_exact=True)


# -- curves and reports ------------------------------------------------------------------------


def _csv_frame_equal(path, df, formats):
    """The CSV at `path` has the frame's columns, in order, and its values at their format's
    precision."""
    csv = pd.read_csv(path)
    assert list(csv.columns) == list(df.columns)
    assert path.read_bytes().split(b"\r\n")[0].decode() == ",".join(df.columns)
    for column in df.columns:
        assert df[column].dtype == np.float64, column
        digits = formats[column]
        if digits.endswith("f"):
            np.testing.assert_allclose(
                csv[column], df[column], rtol=0, atol=0.51 * 10.0 ** -int(digits[1:-1])
            )
        else:
            np.testing.assert_allclose(csv[column], df[column], rtol=10.0 ** (1 - int(digits[1:-1])))


@pytest.fixture(scope="module")
def design_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("design")
    write_study(folder)
    return folder / DESIGN_FILE


def test_te_report_frame_is_its_csv(design_file, tmp_path):
    from rvfmu.jobs.common import TE_FORMATS

    path = tmp_path / "te.csv"
    report = api.te(design_file, points=64, csv_path=path)
    df = report.to_df()
    assert list(df.columns) == ["theta_in_rad", "theta_out_rad", "te_arcsec"] and len(df) == 64
    np.testing.assert_array_equal(df["te_arcsec"], report.curve.te_arcsec[0])
    _csv_frame_equal(path, df, TE_FORMATS)


def _bench_record(path, ratio, rows_per_rev=720):
    """A bench CSV of one output revolution: time_s, theta_in_deg, theta_out_deg."""
    theta_in = np.linspace(0.0, 2 * np.pi * ratio, rows_per_rev + 1)
    theta_out = theta_in / ratio + 4.8e-6 * np.sin(3 * theta_in / ratio) + 1e-6 * np.sin(theta_in)
    pd.DataFrame(
        {
            "time_s": np.linspace(0.0, 4.0, theta_in.size),
            "theta_in_deg": np.degrees(theta_in),
            "theta_out_deg": np.degrees(theta_out),
        }
    ).to_csv(path, index=False, float_format="%.17g")
    return path


def test_measure_report_frame_is_its_csv(tmp_path):
    from rvfmu.jobs.measure import FORMATS

    data = _bench_record(tmp_path / "bench.csv", 81.0)
    report = api.measure(data, 81.0, csv_path=tmp_path / "te.csv")
    df = report.to_df()
    assert list(df.columns) == [
        "time_s",
        "theta_in_rad",
        "theta_out_rad",
        "te_arcsec",
        "runout_arcsec",
        "te_reducer_arcsec",
    ]
    assert len(df) == report.measured.rows
    np.testing.assert_array_equal(df["te_reducer_arcsec"], report.measured.te_reducer_arcsec)
    _csv_frame_equal(tmp_path / "te.csv", df, FORMATS)


def test_compare_report_frame_is_its_csv(design_file, tmp_path):
    from rvfmu.jobs.compare import FORMATS

    data = _bench_record(tmp_path / "bench.csv", 121.0)
    report = api.compare(design_file, data, points=64, csv_path=tmp_path / "cmp.csv")
    df = report.to_df()
    assert list(df.columns) == ["theta_in_rad", "te_measured_arcsec", "te_model_arcsec", "difference_arcsec"]
    np.testing.assert_allclose(
        df["difference_arcsec"], df["te_measured_arcsec"] - df["te_model_arcsec"], atol=1e-12
    )
    _csv_frame_equal(tmp_path / "cmp.csv", df, FORMATS)


def test_simulation_report_frame_is_its_csv(design_file, tmp_path):
    from rvfmu.jobs.simulate import FORMATS

    report = api.simulate(design_file, speed_rpm=1600.0, duration=0.01, csv_path=tmp_path / "sim.csv")
    df = report.to_df()
    assert list(df.columns) == ["time_s", "theta_in_rad", "theta_out_rad", "te_arcsec", "tau_in_Nm"]
    assert len(df) == report.simulation.time.size
    _csv_frame_equal(tmp_path / "sim.csv", df, FORMATS)


def test_allocation_frame_lists_factors_costs_and_yields():
    factors = (
        FactorAllocation(
            "crank_cam_eccentricity.position_um", "um", 9.0, 9.06, 4.0, 22.5, 0.79, 0.78, "none"
        ),
        FactorAllocation("pin_radial.band_um", "um", 5.0, 12.5, 2.0, 12.5, 1.6, 0.64, "upper"),
    )
    result = AllocationResult(
        "quick",
        "quick.toml",
        "quick_allocated.toml",
        0.9973,
        True,
        factors,
        2.39,
        1.42,
        YieldEstimate(1.0, 0.9996, 1.0, 10000),
        YieldEstimate(0.9987, 0.9978, 0.9992, 10000),
        "kriging",
        512,
        "Q2 0.66",
        52048,
    )
    df = result.to_df()
    assert df.index.name == "factor"
    assert df.index.tolist() == ["crank_cam_eccentricity.position_um", "pin_radial.band_um", "total"]
    assert list(df.columns) == [
        "unit",
        "current",
        "allocated",
        "lower",
        "upper",
        "binding",
        "cost_current",
        "cost_allocated",
        "yield_current",
        "yield_current_low",
        "yield_current_high",
        "yield_allocated",
        "yield_allocated_low",
        "yield_allocated_high",
    ]
    assert df.loc["pin_radial.band_um", "allocated"] == 12.5
    assert df.loc["pin_radial.band_um", "binding"] == "upper"
    assert df.loc["total", "cost_allocated"] == 1.42
    assert df.loc["total", "yield_allocated_low"] == 0.9978
    assert df.loc[:"pin_radial.band_um", "yield_allocated"].isna().all()
    assert df["cost_current"].iloc[:-1].sum() == pytest.approx(df.loc["total", "cost_current"])
    assert df["current"].dtype == np.float64 and df["yield_current"].dtype == np.float64


# -- the example ---------------------------------------------------------------------------------


def test_the_notebook_example_runs_on_a_small_study(tmp_path):
    study = write_study(tmp_path, name="small", montecarlo={"n": 16}, sobol={"n": 8, "resamples": 20})
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env.update(
        RVTE_STUDY=str(study),
        RVTE_OUTPUT=str(out),
        PYTHONPATH=os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]),
    )
    proc = subprocess.run(
        [sys.executable, str(ROOT / "studies" / "notebook_example.py")],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    figure = out / "notebook_te_pp_by_decile.png"
    assert figure.is_file() and figure.stat().st_size > 10_000
    assert f"wrote figure {figure}" in proc.stdout
    assert "decile of " in proc.stdout and "ST_conf" in proc.stdout
    assert "yield " in proc.stdout
    # The figure's factor tops the te_pp ranking of the same study.
    ranked = json.loads((out / "sobol_indices.json").read_text())["metrics"]["te_pp_arcsec"]
    top = ranked["groups"][0]["name"]
    assert f"decile of {top}_" in proc.stdout


def test_the_command_line_and_the_physics_do_not_import_pandas():
    """pandas is for results: `rvte --help` and the core model stay without it."""
    code = (
        "import sys, contextlib, io\n"
        "from rvfmu.cli import main\n"
        "import rvfmu.core.statics.quasistatic, rvfmu.core.dynamics.simulation, tolerance.evaluate\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        "    main(['--help'])\n"
        "print('pandas' in sys.modules)\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "False"
    assert not [p for p in (ROOT / "rvfmu" / "core").rglob("*.py") if "pandas" in p.read_text()]
    assert not [p for p in (ROOT / "rvfmu" / "fmu").rglob("*.py") if "pandas" in p.read_text()]
