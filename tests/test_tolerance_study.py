"""Study files: what is accepted, what is refused (with the field named), and the study hash."""

from dataclasses import replace
from pathlib import Path

import pytest
from tolerance_toy import write_study

from rvfmu.cli import main
from rvfmu.core.base.checks import InputError
from tolerance.study import load_study

ROOT = Path(__file__).resolve().parent.parent


def refused(tmp_path, match, **sections):
    with pytest.raises(InputError, match=match) as info:
        load_study(write_study(tmp_path, **sections))
    return info.value


def test_shipped_studies_load_with_one_group_per_error_source():
    sobol = load_study(ROOT / "studies" / "rv40e_121_sobol.toml")
    assert sobol.groups == (
        "crank_cam_eccentricity",
        "disc_crank_hole",
        "carrier_crank_hole",
        "carrier_assembly",
        "disc_profile",
        "disc_pitch",
        "pin_radial",
        "pin_pitch",
    )
    assert sobol.points == 720 and sobol.sobol_n == 1024 and sobol.load_Nm == 0.0
    problem = sobol.problem()
    assert problem["num_vars"] == len(problem["names"]) == len(problem["groups"]) == 279
    assert sobol.output == ROOT / "studies" / "rv40e_121_sobol" / "output"
    quick = load_study(ROOT / "studies" / "quick_mc.toml")
    assert {f.distribution for f in quick.factors} == {"normal"}
    assert [str(s) for s in quick.spec] == ["te_pp_arcsec <= 60", "lost_motion_arcmin <= 2"]


def test_unknown_keys_and_sections_are_refused(tmp_path):
    refused(tmp_path, "sead.*is not a key of \\[study\\]", study={"sead": 3})
    refused(tmp_path, "load.*is not a key of \\[operating\\]", operating={"load": 3.0})
    refused(
        tmp_path,
        "posiiton_um.*known keys: position_um",
        tolerances={"carrier_assembly": {"posiiton_um": 3.0}},
    )


def test_a_factor_that_names_no_error_is_refused(tmp_path):
    error = refused(
        tmp_path, "names no error of docs/model.md", tolerances={"cam_runout": {"position_um": 3.0}}
    )
    assert error.field == "tolerances.cam_runout"


def test_negative_and_missing_tolerances_are_refused(tmp_path):
    error = refused(tmp_path, "must be >= 0", tolerances={"carrier_assembly": {"position_um": -2.0}})
    assert error.field == "tolerances.carrier_assembly.position_um" and error.value == -2.0
    refused(tmp_path, "position_um = None: is missing", tolerances={"carrier_assembly": {}})
    refused(
        tmp_path,
        "single pitch tolerance must be > 0",
        tolerances={"pin_pitch": {"cumulative_um": 8.0, "single_um": 0.0}},
    )
    refused(
        tmp_path, "must be >= min_um", tolerances={"main_bearing_clearance": {"min_um": 5.0, "max_um": 2.0}}
    )
    refused(
        tmp_path,
        "must be one of uniform, normal",
        tolerances={"pin_radial": {"band_um": 5.0, "distribution": "gauss"}},
    )
    refused(tmp_path, "must be a number", tolerances={"pin_radial": {"band_um": "5"}})


def test_metrics_spec_and_sample_counts_are_checked(tmp_path):
    refused(tmp_path, "must be te_pp, rms", study={"metrics": ["te_ppp"]})
    refused(tmp_path, "order must be from 1 to 31", study={"metrics": ["te_pp", "order_40"]})
    refused(tmp_path, "must be the column of a metric", spec={"lost_motion_arcmin": 1.0})
    refused(tmp_path, "must be a power of 2", sobol={"n": 100})
    refused(tmp_path, "must be between 0 and 1", montecarlo={"confidence": 95})
    refused(tmp_path, "study.design = None: is missing", study={"design": None})


def test_rigidity_spec_is_a_minimum(tmp_path):
    study = load_study(
        write_study(
            tmp_path,
            study={"metrics": ["te_pp", "torsional_rigidity"]},
            spec={"torsional_rigidity_Nm_per_arcmin": 350.0},
        )
    )
    (limit,) = study.spec
    assert limit.sense == "min" and bool(limit.passes(360.0)) and not limit.passes(340.0)


def test_hash_covers_what_changes_numbers_and_nothing_else(tmp_path):
    base = load_study(write_study(tmp_path))
    assert load_study(write_study(tmp_path)).inputs_hash == base.inputs_hash
    assert (
        load_study(write_study(tmp_path, spec={"te_pp_arcsec": 99.0}, montecarlo={"n": 5000})).inputs_hash
        == base.inputs_hash
    )
    changed = load_study(write_study(tmp_path, tolerances={"carrier_assembly": {"position_um": 8.5}}))
    assert changed.inputs_hash != base.inputs_hash
    assert replace(base, seed=8).inputs_hash != base.inputs_hash
    assert replace(base, load_Nm=100.0).inputs_hash != base.inputs_hash


def test_cli_reports_a_bad_study_in_one_line_with_exit_code_2(tmp_path, capsys):
    path = write_study(tmp_path, tolerances={"carrier_assembly": {"position_um": -1.0}})
    assert main(["mc", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "tolerances.carrier_assembly.position_um = -1.0" in err
    assert main(["sobol", str(tmp_path / "missing.toml")]) == 2
    assert "must be a readable study TOML file" in capsys.readouterr().err
