"""The shipped presets and the stiffness estimates they are built from.

Every preset loads, has the ratio and geometry of docs/model.md section 6, and each
of its stiffnesses is recomputed here from its `[sources]` table and its
geometry with rvfmu/core/laws/stiffness.py.  The stiffness formulas themselves are
checked on hand-checkable cases and against independent computations.
"""

import math
import subprocess
import sys
import tomllib
from importlib import resources

import numpy as np
import pytest

from rvfmu import api
from rvfmu.core.base.units import DEG, MM
from rvfmu.core.laws import stiffness
from rvfmu.core.reducer.design import DESIGN_FIELDS, PRESET_NAMES, design_from_file_values, preset

RATIOS = {"RV-40E-121": 121, "RV-40E-81": 81, "RV-20E": 53, "RV-110E": 161}

# docs/model.md section 6: z_s, z_pl, m (mm), z_p, z_c, R_p (mm), e (mm), cranks
TABLE = {
    "RV-40E-121": (12, 36, 1.5, 40, 39, 64.05, 1.3, 2),
    "RV-40E-81": (16, 32, 1.5, 40, 39, 66.0, 1.5, 2),
    "RV-20E": (20, 26, 1.5, 40, 39, 52.0, 0.9, 2),
}

STIFFNESS_KEYS = (
    "pin_disc_stiffness_N_per_m",
    "mesh_stiffness_N_per_m",
    "crank_disc_bearing_stiffness_N_per_m",
    "crank_carrier_bearing_stiffness_N_per_m",
    "main_bearing_stiffness_N_per_m",
    "sun_support_stiffness_N_per_m",
    "carrier_compliance_arcsec_per_Nm",
)
AGREEMENT = 0.005  # preset files carry 4 significant digits; 0.5 % catches a wrong input


def preset_file(name: str) -> dict:
    """The preset TOML as written, parsed here independently of rvfmu.core.reducer.design."""
    text = resources.files("rvfmu.core.reducer.presets").joinpath(f"{name}.toml").read_text()
    return tomllib.loads(text)


# -- the presets load, with the right ratio and geometry ------------------------------------


def test_shipped_preset_files_are_exactly_the_named_presets():
    shipped = {
        entry.name[:-5]
        for entry in resources.files("rvfmu.core.reducer.presets").iterdir()
        if entry.name.endswith(".toml") and entry.name != "catalogue.toml"
    }
    assert shipped == set(PRESET_NAMES) == set(RATIOS)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_preset_loads_with_every_field_from_its_file(name):
    # the estimate: the file's values; the preset by its name adds its [calibration]
    # (test_catalogue.py)
    design, values = preset(name + "-estimate"), preset_file(name)
    assert design.name == name + "-estimate"
    for spec in DESIGN_FIELDS:
        assert spec.file_key in values, spec.file_key  # complete: nothing from defaults
        assert getattr(design, spec.field) == pytest.approx(values[spec.file_key] * spec.scale, rel=1e-12)


@pytest.mark.parametrize("name, ratio", RATIOS.items())
def test_preset_ratio(name, ratio):
    design, values = preset(name), preset_file(name)
    assert design.ratio == pytest.approx(ratio, rel=1e-12)
    # docs/model.md section 2, from the file's own tooth counts
    assert 1 + values["z_pl"] / values["z_s"] * values["z_p"] == pytest.approx(ratio, rel=1e-12)


@pytest.mark.parametrize("name", TABLE)
def test_preset_geometry_is_that_of_model_md(name):
    d = preset(name)
    z_s, z_pl, m_mm, z_p, z_c, R_p_mm, e_mm, n_c = TABLE[name]
    assert (d.z_s, d.z_pl, d.z_p, d.z_c, d.n_c) == (z_s, z_pl, z_p, z_c, n_c)
    assert d.m == pytest.approx(m_mm * MM)
    assert d.R_p == pytest.approx(R_p_mm * MM)
    assert d.e == pytest.approx(e_mm * MM)
    assert d.pressure_angle == pytest.approx(20.0 * DEG)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_preset_has_the_usual_modification_pairing(name):
    # docs/model.md section 3 and the footnote of section 6: negative shift, positive equidistant;
    # the calibration scales the pair and keeps its signs and ratio.
    d = preset(name + "-estimate")
    assert d.d_rp == pytest.approx(-0.01 * MM)
    assert d.d_rrp == pytest.approx(+0.01 * MM)
    assert d.tip_root_clearance == pytest.approx(0.02 * MM)
    c = preset(name)
    assert c.d_rp < 0.0 < c.d_rrp and c.d_rrp == pytest.approx(-c.d_rp)


def test_rv110e_tooth_counts_give_the_seed_spectral_peaks():
    # The RV-110E.toml comment: at 1600 rpm input, the pin-passing frequency
    # z_p*z_c*f_out and the stage-1 mesh frequency z_s*(f_in - f_out) fall on the
    # peaks of seeds 000/001 at 260 Hz and 400 Hz.
    d = preset("RV-110E")
    f_in = 1600.0 / 60.0
    f_out = f_in / d.ratio
    assert d.ratio == 161 and d.n_c == 3
    assert d.z_p * d.z_c * f_out == pytest.approx(260.0, rel=0.01)
    assert d.z_s * (f_in - f_out) == pytest.approx(400.0, rel=0.01)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_file_values_round_trip(name):
    design = preset(name)
    again = design_from_file_values(design.file_values())
    for spec in DESIGN_FIELDS:
        assert getattr(again, spec.field) == pytest.approx(getattr(design, spec.field), rel=1e-12)


def test_api_and_cli_list_the_presets_with_their_ratios():
    infos = {info.name: info for info in api.presets()}
    assert {name: info.ratio for name, info in infos.items()} == RATIOS
    assert all(info.source for info in infos.values())
    result = subprocess.run(
        [sys.executable, "-m", "rvfmu.cli", "presets"], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    for name, ratio in RATIOS.items():
        assert any(line.split()[:2] == [name, str(ratio)] for line in lines), name


# -- each preset stiffness recomputed from [sources] ----------------------------------------


def recomputed_stiffness(name: str, key: str) -> float:
    """The stiffness `key` of preset `name` from its geometry and [sources] [N/m]."""
    return stiffness.estimate_from_sources(preset_file(name))[key]


@pytest.mark.parametrize("key", STIFFNESS_KEYS)
@pytest.mark.parametrize("name", PRESET_NAMES)
def test_preset_stiffness_is_recomputed_from_its_sources(name, key):
    stated = preset_file(name)[key]
    assert recomputed_stiffness(name, key) == pytest.approx(stated, rel=AGREEMENT)
    # and the design carries the file value unchanged (N/m in files and in SI)
    spec = next(spec for spec in DESIGN_FIELDS if spec.file_key == key)
    assert getattr(preset(name), spec.field) == pytest.approx(stated * spec.scale, rel=1e-15)


def test_rv20e_main_bearing_is_the_identified_value_of_seed_003():
    # Seed 003 identified R_ca = 7.97e10 on the RV-20E itself: no scaling there.
    assert preset("RV-20E").main_bearing_stiffness == pytest.approx(7.97e10, rel=1e-12)


# -- the stiffness formulas by hand ---------------------------------------------------------


def test_series_by_hand():
    assert stiffness.series(2.0, 2.0) == 1.0
    assert stiffness.series(3.0, 6.0) == pytest.approx(2.0)
    assert stiffness.series(5.0) == pytest.approx(5.0)
    assert stiffness.series(1.0, 1.0, 1.0, 1.0) == pytest.approx(0.25)


def involute_contact_ratio(z_1, z_2, pressure_angle):
    """eps_alpha = [z_1 (tan a_a1 - tan a) + z_2 (tan a_a2 - tan a)] / (2 pi),
    cos a_a = z cos a / (z + 2) (addendum = module): the roll-angle form, not the
    path-of-contact form used in rvfmu."""
    total = 0.0
    for z in (z_1, z_2):
        tip_angle = math.acos(z * math.cos(pressure_angle) / (z + 2))
        total += z * (math.tan(tip_angle) - math.tan(pressure_angle))
    return total / (2.0 * math.pi)


def test_contact_ratio_of_a_20_20_pair():
    eps = stiffness.transverse_contact_ratio(20, 20, 1.0 * MM, 20.0 * DEG)
    assert eps == pytest.approx(1.557, abs=0.002)
    assert eps == pytest.approx(involute_contact_ratio(20, 20, 20.0 * DEG), rel=1e-9)


@pytest.mark.parametrize("z_1, z_2, module_mm", [(12, 36, 1.5), (16, 32, 1.5), (15, 60, 1.25), (20, 26, 3.0)])
def test_contact_ratio_agrees_with_roll_angle_form(z_1, z_2, module_mm):
    eps = stiffness.transverse_contact_ratio(z_1, z_2, module_mm * MM, 20.0 * DEG)
    assert eps == pytest.approx(involute_contact_ratio(z_1, z_2, 20.0 * DEG), rel=1e-9)
    # the module only scales the gears
    assert eps == pytest.approx(stiffness.transverse_contact_ratio(z_1, z_2, 1.0, 20.0 * DEG))


def test_iso6336_mesh_stiffness_by_hand():
    # 20/20 teeth, 20 deg, 10 mm face: q' = 0.04723 + (0.15551 + 0.25791)/20 = 0.067901,
    # c' = 0.8 * 0.975 / q' = 11.487 N/(mm um), c_gamma = c' (0.75*1.5569 + 0.25) = 16.285,
    # times 10 mm = 162.85 N/um.
    k = stiffness.iso6336_mesh_stiffness(20, 20, 2.0 * MM, 20.0 * DEG, 10.0 * MM)
    assert k == pytest.approx(162.85e6, rel=1e-3)
    # proportional to the face width
    assert stiffness.iso6336_mesh_stiffness(20, 20, 2.0 * MM, 20.0 * DEG, 20.0 * MM) == pytest.approx(
        2.0 * k, rel=1e-12
    )


def test_roller_bearing_stiffness_is_seed_003_formula():
    length, n, E, nu = 8.0 * MM, 12, 211e9, 0.29
    expected = math.pi * length * E * n / (8.0 * (1.0 - nu**2))
    assert stiffness.roller_bearing_stiffness(length, n, E, nu) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(8.685e9, rel=1e-3)  # the RV-40E needle value in its preset
    tapered = stiffness.roller_bearing_stiffness(length, n, E, nu, contact_angle=80.0 * DEG)
    assert tapered == pytest.approx(expected / math.sin(80.0 * DEG), rel=1e-12)


def test_shaft_stiffnesses_by_hand():
    # 14 mm shaft, 60 mm long, 211 GPa: I = pi d^4/64 = 1885.7 mm^4, 3EI/L^3 = 5.526e6 N/m
    assert stiffness.cantilever_stiffness(211e9, 14 * MM, 60 * MM) == pytest.approx(5.526e6, rel=1e-3)
    # the same shaft supported at both ends, loaded in the middle, is 16 times stiffer
    assert stiffness.simply_supported_beam_stiffness(211e9, 14 * MM, 60 * MM) == pytest.approx(
        16.0 * stiffness.cantilever_stiffness(211e9, 14 * MM, 60 * MM), rel=1e-12
    )


PIN = dict(length=10 * MM, radius_1=3.0 * MM, radius_2=34.4 * MM, youngs_modulus=211e9, poisson_ratio=0.29)


def test_hertz_approach_grows_with_force_and_stiffness_rises_slowly():
    forces = np.geomspace(10.0, 2000.0, 12)
    approach = np.array([stiffness.hertz_line_contact_approach(f, **PIN) for f in forces])
    secant = np.array([stiffness.hertz_line_contact_stiffness(f, **PIN) for f in forces])
    assert np.all(approach > 0) and np.all(np.diff(approach) > 0)
    assert np.all(np.diff(secant) > 0)  # the log term makes it slightly stiffening
    # nearly linear: 200 times the force, less than 1.5 times the secant stiffness
    assert 1.0 < secant[-1] / secant[0] < 1.5
    doubled = stiffness.hertz_line_contact_stiffness(800.0, **PIN) / stiffness.hertz_line_contact_stiffness(
        400.0, **PIN
    )
    assert 1.0 < doubled < 1.1
    assert secant == pytest.approx(forces / approach, rel=1e-12)


def test_hertz_approach_depends_on_force_per_length():
    one = stiffness.hertz_line_contact_approach(400.0, **PIN)
    pin_twice_as_long = {**PIN, "length": 2 * PIN["length"]}
    assert stiffness.hertz_line_contact_approach(800.0, **pin_twice_as_long) == pytest.approx(one, rel=1e-12)


def test_hertz_approach_by_hand():
    # w = 400 N / 10 mm = 40 N/mm, E* = 211e9 / (2 (1 - 0.29^2)) = 115.19 GPa,
    # R* = 3*34.4/37.4 = 2.7594 mm, b = sqrt(4 w R* / (pi E*)) = 34.93 um;
    # delta = 2 w (1 - nu^2) / (pi E) * (2/3 + ln(6 mm / b) + ln(68.8 mm / b))
    #       = 1.1054e-7 m * (0.667 + 5.146 + 7.586) = 1.4810 um,
    # a secant stiffness of 400 N / 1.481 um = 2.70e8 N/m, the RV-40E-121 preset value.
    b = math.sqrt(4 * 40e3 * (3.0 * 34.4 / 37.4 * MM) / (math.pi * 211e9 / (2 * (1 - 0.29**2))))
    assert b == pytest.approx(34.93e-6, rel=1e-3)
    assert stiffness.hertz_line_contact_approach(400.0, **PIN) == pytest.approx(1.4810e-6, rel=1e-3)
    assert stiffness.hertz_line_contact_stiffness(400.0, **PIN) == pytest.approx(2.70e8, rel=2e-3)


def test_hertz_concave_radius_smaller_than_pin_is_refused():
    with pytest.raises(ValueError):
        stiffness.hertz_line_contact_approach(400.0, **{**PIN, "radius_2": -2.0 * MM})


def test_largest_pin_force_by_hand():
    # RV-40E-121: F = 4 T / (K1 z_c R_p), K1 = e z_p / R_p, so F = 4 T / (e z_p z_c):
    # 4 * 206 / (1.3e-3 * 40 * 39) = 406.31 N with half the rated 412 N*m on one disc.
    force = stiffness.largest_pin_force(206.0, 64.05 * MM, 1.3 * MM, 40)
    assert force == pytest.approx(824.0 / (1.3e-3 * 40 * 39), rel=1e-12)
    assert force == pytest.approx(406.31, abs=0.01)
    # proportional to the torque
    assert stiffness.largest_pin_force(412.0, 64.05 * MM, 1.3 * MM, 40) == pytest.approx(2 * force)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_disc_radius_at_largest_lever_against_finite_differences(name):
    """Independent: the pin-centre path in the disc frame by finite differences."""
    d = preset(name)
    z = d.z_p
    t = np.linspace(1e-4, math.pi / (z - 1), 200001)
    x = d.R_p * np.cos(t) - d.e * np.cos(z * t)
    y = d.R_p * np.sin(t) - d.e * np.sin(z * t)
    dx, dy = np.gradient(x, t), np.gradient(y, t)
    ddx, ddy = np.gradient(dx, t), np.gradient(dy, t)
    speed = np.hypot(dx, dy)
    lever = np.abs(x * dx + y * dy) / speed  # distance from disc centre to the normal
    i = int(np.argmax(lever[5:-5])) + 5
    # Every contact normal passes through the pitch point, e*z_c from the disc centre,
    # so the largest lever is e*z_c exactly.
    assert lever[i] == pytest.approx(d.e * d.z_c, rel=1e-6)
    rho_path = speed[i] ** 3 / (dx[i] * ddy[i] - dy[i] * ddx[i])
    expected = rho_path - d.r_rp
    got = stiffness.disc_curvature_radius_at_largest_lever(d.R_p, d.r_rp, d.e, d.z_p)
    # The lever is flat at its maximum, so where exactly it is found (and the radius of
    # curvature there) moves by a few 0.1 % with the sampling; the stiffness hardly notices.
    assert got == pytest.approx(expected, rel=5e-3)


# -- the geometric estimate's compositions by hand ------------------------------------------


def test_crank_carrier_pair_is_two_bearings_at_half_the_load():
    """Contact angle 90 deg from the axis (0 to the radial plane): the pair's secant is that of
    one bearing at half the load, doubled."""
    from rvfmu.core.laws import compliance

    pair = stiffness.crank_carrier_stiffness_estimate(412.0, 2, 0.036, 14, 6 * MM, 90.0 * DEG)
    one = compliance.secant_stiffness(
        lambda f: compliance.bearing_deflection(f, 14, 6 * MM),
        0.25 * 412 / (2 * 0.036),
        0.5 * 412 / (2 * 0.036),
    )
    assert pair == pytest.approx(2.0 * one, rel=1e-9)
    # inclined rollers carry a radial load less directly
    assert stiffness.crank_carrier_stiffness_estimate(412.0, 2, 0.036, 14, 6 * MM, 80.0 * DEG) < pair


def test_pin_with_its_groove_is_softer_than_against_the_disc_alone():
    with_groove = stiffness.pin_stiffness_estimate(
        412.0, 64.05 * MM, 3 * MM, 1.3 * MM, 40, 10 * MM, 5e-3 * MM, 211e9, 0.29
    )
    force = stiffness.largest_pin_force(206.0, 64.05 * MM, 1.3 * MM, 40)
    rho = stiffness.disc_curvature_radius_at_largest_lever(64.05 * MM, 3 * MM, 1.3 * MM, 40)
    disc_only = (0.5 * force) / (
        stiffness.hertz_line_contact_approach(force, 10 * MM, 3 * MM, rho, 211e9, 0.29)
        - stiffness.hertz_line_contact_approach(0.5 * force, 10 * MM, 3 * MM, rho, 211e9, 0.29)
    )
    groove = (0.5 * force) / (
        stiffness.hertz_line_contact_approach(force, 10 * MM, 3 * MM, -3.005 * MM, 211e9, 0.29)
        - stiffness.hertz_line_contact_approach(0.5 * force, 10 * MM, 3 * MM, -3.005 * MM, 211e9, 0.29)
    )
    assert with_groove == pytest.approx(stiffness.series(disc_only, groove), rel=1e-9)
    assert 0.6 < with_groove / disc_only < 0.9


def test_carrier_compliance_of_the_rv40e_by_hand():
    """Two pillars of 18 mm (a/2) and 22 mm, clamped: 12EI/L^3 = 12*211e9*5153e-12/1.0648e-5
    = 1.2255e9 N/m, in series with kGA/L = 0.8860*81.78e9*2.545e-4/0.022 = 8.382e8: 4.977e8 N/m;
    half the torque through them at 36 mm: 0.25 / (2 * 4.977e8 * 0.036^2) = 1.938e-7 rad/N*m
    = 0.03998 arcsec/N*m."""
    c = stiffness.carrier_compliance_estimate(2, 0.036, 10 * MM, 40 * MM, 211e9, 0.29)
    assert c / (DEG / 3600) == pytest.approx(0.03998, rel=2e-3)
