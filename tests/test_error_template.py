"""The error template (`rvte errors --template DESIGN`) and the shared TOML writer.

The template is the file a user fills in: it must name every error of the
model contract (docs/model.md section 4) in its order, with zero values of the
design's shapes, and read back as the error-free reducer, bit for bit.
"""

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rvfmu.core.reducer.design import PRESET_NAMES, preset
from rvfmu.core.reducer.errors import (
    ERROR_NAMES,
    PHASED,
    error_file_values,
    error_shapes,
    error_template_text,
    load_errors,
    toml_text,
)
from rvfmu.core.statics.quasistatic import te_curve

# The error names of the contract, in the order of its section 4 table: written out here,
# not taken from the code, so that the code cannot drift from the contract unnoticed.
CONTRACT_NAMES = (
    "sun_eccentricity",
    "sun_assembly",
    "planet_eccentricity",
    "crank_cam_eccentricity",
    "disc_crank_hole",
    "carrier_crank_hole",
    "carrier_assembly",
    "pin_radial",
    "pin_pitch",
    "pin_radius",
    "disc_profile",
    "disc_pitch",
    "crank_disc_clearance",
    "crank_carrier_clearance",
    "main_bearing_clearance",
)

SEED002 = Path(__file__).resolve().parent.parent / "studies" / "seed002_errors.toml"


def _keys_in_order(text):
    return [m.group(1) for m in re.finditer(r"^([a-z_]+) = ", text, flags=re.MULTILINE)]


def _template_errors(tmp_path, name):
    """The design of preset `name` and its error template, written and loaded back."""
    design = preset(name)
    path = tmp_path / "errors.toml"
    path.write_text(error_template_text(design))
    return design, load_errors(path, design)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_template_loads_back_as_zero(tmp_path, name):
    design, errors = _template_errors(tmp_path, name)
    errors.check(design)
    assert errors.samples == 1
    shapes = error_shapes(design)
    for key, array in errors.arrays().items():
        assert array.shape == (1,) + shapes[key], key
        assert not np.any(array), key
    assert error_file_values(errors) == {}


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_template_names_every_contract_error_in_order(name):
    design = preset(name)
    text = error_template_text(design)
    assert ERROR_NAMES == CONTRACT_NAMES
    assert _keys_in_order(text) == list(CONTRACT_NAMES)
    lines = text.splitlines()
    for key in CONTRACT_NAMES:
        # a comment right above every key; the header names the design and the reference
        at = next(i for i, line in enumerate(lines) if line.startswith(f"{key} = "))
        assert lines[at - 1].startswith("#"), key
    assert design.name in lines[0]
    assert "docs/model.md section 4" in text
    assert f"z_p = {design.z_p}" in text and f"n_c = {design.n_c}" in text


def test_template_shapes_are_written_out():
    # RV-110E has three cranks: every per-crank list has three entries.
    design = preset("RV-110E")
    values = tomllib.loads(error_template_text(design))
    for key in CONTRACT_NAMES:
        shape = error_shapes(design)[key] + ((2,) if key in PHASED else ())
        assert np.shape(values[key]) == shape, key
        assert all(isinstance(v, float) for v in np.ravel(values[key]).tolist()), key
    assert max(len(line) for line in error_template_text(design).splitlines()) <= 100


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_template_errors_give_the_error_free_te_exactly(tmp_path, name):
    design, errors = _template_errors(tmp_path, name)
    with_template = te_curve(design, errors, points=64)
    error_free = te_curve(design, None, points=64)
    np.testing.assert_allclose(with_template.te, error_free.te, rtol=0.0, atol=1e-12)


def test_toml_text_round_trips_an_error_file(tmp_path):
    design = preset("RV-40E-121")
    seed = load_errors(SEED002, design)
    path = tmp_path / "copy.toml"
    path.write_text(toml_text(error_file_values(seed), header="a copy"))
    again = load_errors(path, design)
    for key, array in seed.arrays().items():
        np.testing.assert_allclose(getattr(again, key), array, rtol=0.0, atol=1e-15, err_msg=key)


def test_toml_text_values():
    text = toml_text({"name": 'a "b"', "z_p": 40, "flag": True, "x": 2.0, "y": 1e-7, "z": 3.0}, digits=6)
    assert text == 'name = "a \\"b\\""\nz_p = 40\nflag = true\nx = 2.0\ny = 1e-07\nz = 3.0\n'
