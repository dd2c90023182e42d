"""Bad input gives one clear error naming the field, the value and what is allowed.

Checked through the Python API (design and error files, as dicts and as TOML
files) and through the `rvte` command line, where bad input must exit with
status 2 and print one line, never a traceback.
"""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rvfmu import cli
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import DEG, MM, UM
from rvfmu.core.reducer.design import (
    DESIGN_FIELDS,
    PRESET_NAMES,
    design_from_file_values,
    load_design,
    preset,
)
from rvfmu.core.reducer.errors import error_file_values, errors_from_file_values, load_errors

BASE = "RV-40E-121"  # z_p = 40, z_c = 39, n_c = 2, R_p = 64.05 mm, e = 1.3 mm
SEED002 = Path(__file__).resolve().parent.parent / "studies" / "seed002_errors.toml"


def one_line(message: str) -> bool:
    return "\n" not in message.strip()


def design_error(values: dict) -> InputError:
    with pytest.raises(InputError) as info:
        design_from_file_values(values, where="bad.toml")
    return info.value


def errors_error(values: dict) -> InputError:
    with pytest.raises(InputError) as info:
        errors_from_file_values(preset(BASE), values, where="bad_errors.toml")
    return info.value


def toml_line(key, value) -> str:
    """One TOML line; repr() of str, int and float is valid TOML (nan included)."""
    return f"{key} = {value!r}"


def complete_design_text(**changes) -> str:
    """A complete design file (no preset) of BASE with some file keys changed."""
    values = {**preset(BASE).file_values(), **changes}
    return "\n".join(toml_line(k, v) for k, v in values.items()) + "\n"


# -- design values, Python API ----------------------------------------------------------

# (overrides of the preset, field named, value as shown, what is allowed)
BAD_DESIGNS = {
    "z_c not z_p - 1": ({"z_c": 40}, "z_c", "40", "must be z_p - 1 = 39"),
    "e too large": ({"e_mm": 2.0}, "e_mm", "2.0", "must be < R_p/z_p = 1.601 mm"),
    "negative stiffness": (
        {"mesh_stiffness_N_per_m": -1.0e8},
        "mesh_stiffness_N_per_m",
        "-100000000.0",
        "must be > 0",
    ),
    "negative mass": ({"disc_mass_kg": -0.5}, "disc_mass_kg", "-0.5", "must be > 0"),
    "unknown key": ({"pin_radius_mm": 3.0}, "pin_radius_mm", "3.0", "is not a design key"),
    "NaN": ({"R_p_mm": math.nan}, "R_p_mm", "nan", "must be finite"),
    "infinity": ({"gear_width_mm": math.inf}, "gear_width_mm", "inf", "must be finite"),
    "text for a number": ({"R_p_mm": "64.05"}, "R_p_mm", "'64.05'", "must be a number"),
    "true for a number": ({"e_mm": True}, "e_mm", "True", "must be a number"),
    "fractional tooth count": ({"z_s": 12.5}, "z_s", "12.5", "must be a whole number"),
    "z_s not divisible by n_c": ({"z_s": 13}, "z_s", "13", "must be divisible by n_c = 2"),
    "odd z_p": ({"z_p": 41, "z_c": 40}, "z_p", "41", "must be even"),
    "Poisson ratio of 1": ({"poisson_ratio": 1.0}, "poisson_ratio", "1.0", "from 0 to below 1"),
}


@pytest.mark.parametrize("overrides, field, shown, allowed", BAD_DESIGNS.values(), ids=BAD_DESIGNS)
def test_bad_design_value_names_field_value_and_allowed(overrides, field, shown, allowed):
    error = design_error({"preset": BASE, **overrides})
    assert error.field == field
    message = str(error)
    assert f"{field} = {shown}: " in message
    assert allowed in message
    assert one_line(message)


def test_e_equal_to_pin_circle_limit_is_refused():
    # e must be strictly below R_p/z_p = 64.05/40 mm: at the limit the trochoid has cusps.
    error = design_error({"preset": BASE, "e_mm": 64.05 / 40})
    assert error.field == "e_mm"
    assert "R_p/z_p" in str(error)
    # Just below the limit the eccentricity check passes, but the trochoid is then so
    # sharp that the 3 mm pin undercuts the profile: that is the field named instead.
    below = design_error({"preset": BASE, "e_mm": 1.59})
    assert below.field == "r_rp_mm"
    assert "undercuts" in str(below)


def test_unknown_key_lists_the_known_keys():
    message = str(design_error({"preset": BASE, "pin_radius_mm": 3.0}))
    for spec in DESIGN_FIELDS:
        assert spec.file_key in message
    assert "bad.toml" in message  # where the key was found


def test_unknown_preset_lists_the_presets():
    error = design_error({"preset": "RV-40E-122"})
    assert error.field == "preset"
    assert "preset = 'RV-40E-122': " in str(error)
    for name in PRESET_NAMES:
        assert name in str(error)


def test_missing_key_without_preset_is_named():
    values = preset(BASE).file_values()
    del values["disc_width_mm"]
    error = design_error(values)
    assert error.field == "disc_width_mm"
    assert "missing" in str(error)


def test_load_design_missing_file(tmp_path):
    path = tmp_path / "no_such_design.toml"
    with pytest.raises(InputError) as info:
        load_design(path)
    assert info.value.field == "design"
    assert str(path) in str(info.value)
    assert "neither a preset" in str(info.value)


def test_load_design_unknown_preset_name():
    with pytest.raises(InputError) as info:
        load_design("RV-40E-122")
    assert info.value.field == "design"
    assert "'RV-40E-122'" in str(info.value)
    assert "RV-40E-121" in str(info.value)


def test_load_design_invalid_toml(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text('preset = "RV-40E-121"\nR_p_mm = = 64\n')
    with pytest.raises(InputError) as info:
        load_design(path)
    assert info.value.field == "design"
    assert "not valid TOML" in str(info.value)
    assert one_line(str(info.value))


def test_load_design_complete_file_with_bad_z_c(tmp_path):
    path = tmp_path / "complete.toml"
    path.write_text(complete_design_text(z_c=38))
    with pytest.raises(InputError) as info:
        load_design(path)
    assert info.value.field == "z_c"
    assert "z_c = 38: must be z_p - 1 = 39" in str(info.value)


def test_load_design_nan_in_file(tmp_path):
    path = tmp_path / "nan.toml"
    path.write_text('preset = "RV-40E-121"\nr_rp_mm = nan\n')
    with pytest.raises(InputError) as info:
        load_design(path)
    assert info.value.field == "r_rp_mm"
    assert "nan.toml: r_rp_mm = nan: must be finite" in str(info.value)


def test_complete_design_file_loads_as_the_preset(tmp_path):
    path = tmp_path / "complete.toml"
    path.write_text(complete_design_text())
    loaded, reference = load_design(path), preset(BASE)
    for spec in DESIGN_FIELDS:
        assert getattr(loaded, spec.field) == pytest.approx(getattr(reference, spec.field), rel=1e-12)


def test_preset_override_gives_overridden_value_in_si(tmp_path):
    path = tmp_path / "override.toml"
    path.write_text('preset = "RV-40E-121"\nd_rp_mm = 0.0\nd_rrp_mm = 0.02\n')
    design, base = load_design(path), preset(BASE)
    assert base.d_rp < 0.0  # so the override really changes it
    assert design.d_rp == 0.0
    assert design.d_rrp == pytest.approx(0.02 * MM, rel=1e-12)  # 2e-5 m
    assert design.tip_root_clearance == pytest.approx(0.02 * MM, rel=1e-12)
    assert design.name == "RV-40E-121 (modified)"
    for spec in DESIGN_FIELDS:
        if spec.field not in ("d_rp", "d_rrp"):
            assert getattr(design, spec.field) == getattr(base, spec.field), spec.field


# -- error values, Python API -------------------------------------------------------------

CAM_OK = [[[3.5, 30.0], [4.0, 140.0]], [[3.0, 195.0], [4.5, 85.0]]]  # [crank i][disc j]

# (error values, field named, text in the message)
BAD_ERRORS = {
    "unknown name": ({"pin_wobble": [1.0] * 40}, "pin_wobble", "is not an error name"),
    "pin list of 39": ({"pin_radial": [1.0] * 39}, "pin_radial", "must be shaped 40, got 39"),
    "pin list of 41": ({"pin_pitch": [1.0] * 41}, "pin_pitch", "must be shaped 40, got 41"),
    "NaN in a list": ({"pin_radius": [0.0] * 20 + [math.nan] + [0.0] * 19}, "pin_radius", "must be finite"),
    "negative magnitude": (
        {"carrier_assembly": [-2.0, 30.0]},
        "carrier_assembly",
        "magnitude E must be >= 0",
    ),
    "negative magnitude deep": (
        {"crank_cam_eccentricity": [[[3.5, 30.0], [4.0, 140.0]], [[-3.0, 195.0], [4.5, 85.0]]]},
        "crank_cam_eccentricity",
        "magnitude E must be >= 0",
    ),
    "negative clearance": ({"crank_disc_clearance": -1.0}, "crank_disc_clearance", "must be >= 0"),
    "cam nesting too flat": (
        {"crank_cam_eccentricity": CAM_OK[0]},
        "crank_cam_eccentricity",
        "must be shaped 2 x 2 x 2, got 2 x 2",
    ),
    "cam nesting swapped": (
        {"crank_cam_eccentricity": [[3.5, 30.0, 4.0, 140.0], [3.0, 195.0, 4.5, 85.0]]},
        "crank_cam_eccentricity",
        "must be shaped 2 x 2 x 2, got 2 x 4",
    ),
    "cam pair incomplete": (
        {"crank_cam_eccentricity": [[[3.5, 30.0], [4.0, 140.0]], [[3.0, 195.0], [4.5]]]},
        "crank_cam_eccentricity",
        "must be numbers shaped 2 x 2 x 2",
    ),
    "clearance as a list": (
        {"main_bearing_clearance": [5.0]},
        "main_bearing_clearance",
        "must be shaped a scalar",
    ),
    "clearance as text": ({"crank_disc_clearance": "5"}, "crank_disc_clearance", "must be numbers"),
    "pins as true/false": ({"pin_radial": [True] * 40}, "pin_radial", "must be numbers"),
    "disc lobes of z_p": (
        {"disc_profile": [[0.0] * 40, [0.0] * 40]},
        "disc_profile",
        "must be shaped 2 x 39, got 2 x 40",
    ),
}


@pytest.mark.parametrize("values, field, allowed", BAD_ERRORS.values(), ids=BAD_ERRORS)
def test_bad_error_value_names_field_and_allowed(values, field, allowed):
    error = errors_error(values)
    assert error.field == field
    message = str(error)
    assert message.startswith(f"bad_errors.toml: {field} = ")
    assert allowed in message
    assert one_line(message)


def test_wrong_pin_count_message_names_40():
    message = str(errors_error({"pin_pitch": [0.0, 1.2, 2.3]}))
    assert "40" in message
    assert "got 3" in message


def test_good_error_values_convert_to_si():
    errors = errors_from_file_values(
        preset(BASE),
        {
            "carrier_assembly": [4.0, 30.0],
            "crank_cam_eccentricity": CAM_OK,
            "pin_pitch": [0.5 * k for k in range(40)],
            "crank_disc_clearance": 5.0,
        },
    )
    assert errors.carrier_assembly[0] == pytest.approx(4.0 * UM * np.exp(1j * 30.0 * DEG))
    # [crank i][disc j]: crank 1, disc 0 is [3.0, 195.0]
    assert errors.crank_cam_eccentricity[0, 1, 0] == pytest.approx(3.0 * UM * np.exp(1j * 195.0 * DEG))
    assert errors.pin_pitch[0, 39] == pytest.approx(19.5 * UM)
    assert errors.crank_disc_clearance[0] == pytest.approx(5.0 * UM)
    assert not np.any(errors.pin_radial)  # a missing key means zero


def test_load_errors_nan_inside_a_toml_list(tmp_path):
    path = tmp_path / "nan_errors.toml"
    pins = ["0.0"] * 40
    pins[7] = "nan"
    path.write_text(f"pin_radial = [{', '.join(pins)}]\n")
    with pytest.raises(InputError) as info:
        load_errors(path, preset(BASE))
    assert info.value.field == "pin_radial"
    assert "nan_errors.toml: pin_radial = " in str(info.value)
    assert "must be finite" in str(info.value)


def test_load_errors_missing_and_invalid_files(tmp_path):
    with pytest.raises(InputError) as info:
        load_errors(tmp_path / "absent.toml", preset(BASE))
    assert info.value.field == "errors"
    assert "absent.toml" in str(info.value)
    broken = tmp_path / "broken.toml"
    broken.write_text("pin_radial = [1.0, 2.0\n")
    with pytest.raises(InputError) as info:
        load_errors(broken, preset(BASE))
    assert info.value.field == "errors"
    assert "not valid TOML" in str(info.value)


def test_shipped_seed002_error_file_loads_and_round_trips():
    design = preset(BASE)
    errors = load_errors(SEED002, design)
    # Table 2: crank 0, disc 1 = [4.0 um, 140 deg]
    assert errors.crank_cam_eccentricity[0, 0, 1] == pytest.approx(4.0 * UM * np.exp(1j * 140.0 * DEG))
    again = errors_from_file_values(design, error_file_values(errors))
    for name, array in errors.arrays().items():
        np.testing.assert_allclose(getattr(again, name), array, rtol=0, atol=1e-15, err_msg=name)


def test_error_file_lengths_follow_the_design():
    # RV-110E has 3 cranks: the cam table of a 2-crank reducer does not fit it.
    with pytest.raises(InputError) as info:
        errors_from_file_values(preset("RV-110E"), {"crank_cam_eccentricity": CAM_OK})
    assert "must be shaped 3 x 2 x 2, got 2 x 2 x 2" in str(info.value)


# -- the command line ---------------------------------------------------------------------


def run_rvte(*args) -> subprocess.CompletedProcess:
    # A bad input must stop before any solve; the timeout only guards a regression.
    return subprocess.run(
        [sys.executable, "-m", "rvfmu.cli", *map(str, args)], capture_output=True, text=True, timeout=120
    )


def assert_clean_failure(result, *expected):
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("rvte te: error: ")
    for text in expected:
        assert text in lines[0]
    assert result.stdout == ""


BAD_DESIGN_FILES = {
    "z_c": ('preset = "RV-40E-121"\nz_c = 40\n', ["z_c = 40", "z_p - 1"]),
    "e": ('preset = "RV-40E-121"\ne_mm = 1.65\n', ["e_mm = 1.65", "R_p/z_p"]),
    "negative stiffness": (
        'preset = "RV-40E-121"\npin_disc_stiffness_N_per_m = -2.7e8\n',
        ["pin_disc_stiffness_N_per_m = -270000000.0", "> 0"],
    ),
    "unknown key": ('preset = "RV-40E-121"\nR_pin_mm = 64.05\n', ["R_pin_mm = 64.05", "not a design key"]),
    "NaN": ('preset = "RV-40E-121"\nR_p_mm = nan\n', ["R_p_mm = nan", "finite"]),
    "text": ('preset = "RV-40E-121"\ne_mm = "1.3"\n', ["e_mm = '1.3'", "must be a number"]),
    "z_s": ('preset = "RV-40E-121"\nz_s = 13\n', ["z_s = 13", "n_c = 2"]),
    "invalid TOML": ('preset = "RV-40E-121"\ne_mm 1.3\n', ["design = ", "not valid TOML"]),
    "unknown preset": ('preset = "RV-40E-999"\n', ["preset = 'RV-40E-999'", "RV-40E-121"]),
}


@pytest.mark.parametrize("text, expected", BAD_DESIGN_FILES.values(), ids=BAD_DESIGN_FILES)
def test_cli_bad_design_file_exits_2_with_one_line(tmp_path, text, expected):
    path = tmp_path / "design.toml"
    path.write_text(text)
    assert_clean_failure(run_rvte("te", path), *expected)


def test_cli_missing_design_file(tmp_path):
    path = tmp_path / "nowhere.toml"
    assert_clean_failure(run_rvte("te", path), "design = ", "nowhere.toml", "neither a preset")


def test_cli_unknown_preset_name():
    assert_clean_failure(run_rvte("te", "RV-41E"), "design = 'RV-41E'", "RV-40E-121")


BAD_ERROR_FILES = {
    "unknown name": ("pin_wobble = 1.0\n", ["pin_wobble = 1.0", "not an error name"]),
    "short pin list": ("pin_pitch = [0.0, 1.2, 2.3]\n", ["pin_pitch = ", "shaped 40, got 3"]),
    "NaN in list": ("carrier_assembly = [4.0, nan]\n", ["carrier_assembly = ", "finite"]),
    "negative clearance": ("main_bearing_clearance = -3.0\n", ["main_bearing_clearance = -3.0", ">= 0"]),
    "cam nesting": (
        "crank_cam_eccentricity = [[3.5, 30.0], [4.0, 140.0]]\n",
        ["crank_cam_eccentricity = ", "2 x 2 x 2"],
    ),
}


@pytest.mark.parametrize("text, expected", BAD_ERROR_FILES.values(), ids=BAD_ERROR_FILES)
def test_cli_bad_errors_file_exits_2_with_one_line(tmp_path, text, expected):
    path = tmp_path / "errors.toml"
    path.write_text(text)
    assert_clean_failure(run_rvte("te", BASE, "--errors", path), "errors.toml: ", *expected)


@pytest.mark.parametrize("load", ["nan", "inf", "-inf"])
def test_cli_non_finite_load_exits_2(load):
    assert_clean_failure(run_rvte("te", BASE, f"--load={load}"), f"load = {float(load)!r}", "finite")


def test_cli_main_returns_2_in_process(tmp_path, capsys):
    path = tmp_path / "design.toml"
    path.write_text('preset = "RV-20E"\nn_c = 4\n')
    assert cli.main(["te", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip() == ("rvte te: error: RV-20E (modified): n_c = 4: must be 2 or 3 crankshafts")
