"""Tests of rvfmu.core.reducer.profile: the closed-form disc profile against an
independent numerical envelope, its hand-checkable radii, symmetries and files."""

import math
import sys
from importlib import resources

import numpy as np
import pytest

from rvfmu.core.base.units import MM, UM
from rvfmu.core.reducer.design import RVDesign, preset
from rvfmu.core.reducer.profile import (
    Profile,
    _closed_form,
    disc_profile,
    disc_profile_for,
    numerical_envelope,
    profile_radius_at,
    write_profile_csv,
    write_profile_dxf,
)

# Geometry of docs/model.md section 6; the other fields only need to be plausible here.
GEOMETRY = {
    "RV-40E-121": dict(z_s=12, z_pl=36, R_p=64.05 * MM, e=1.3 * MM),
    "RV-40E-81": dict(z_s=16, z_pl=32, R_p=66.0 * MM, e=1.5 * MM),
}
OTHER_FIELDS = dict(
    m=1.5 * MM,
    pressure_angle=math.radians(20.0),
    gear_width=20 * MM,
    z_p=40,
    z_c=39,
    r_rp=3.0 * MM,
    d_rp=0.0,
    d_rrp=0.0,
    disc_width=15 * MM,
    n_c=2,
    pin_disc_stiffness=3e8,
    mesh_stiffness=4e8,
    crank_disc_bearing_stiffness=5e8,
    crank_carrier_bearing_stiffness=8e8,
    main_bearing_stiffness=2e9,
    sun_support_stiffness=1e8,
    damping_ratio=0.05,
    sun_mass=0.3,
    sun_inertia=1e-4,
    crank_mass=0.5,
    crank_inertia=3e-4,
    disc_mass=1.0,
    disc_inertia=2e-3,
    carrier_mass=3.0,
    carrier_inertia=1e-2,
    rated_torque=412.0,
    youngs_modulus=206e9,
    poisson_ratio=0.3,
)
MODIFIED = dict(d_rp=-0.01 * MM, d_rrp=+0.01 * MM)
UNMODIFIED = dict(d_rp=0.0, d_rrp=0.0)


def make_design(name, **mods):
    """The preset if its TOML is shipped, else the same geometry built directly."""
    if resources.files("rvfmu.core.reducer.presets").joinpath(f"{name}.toml").is_file():
        return preset(name).with_fields(**mods)
    return RVDesign(name=name, **{**OTHER_FIELDS, **GEOMETRY[name], **mods})


CASES = [(name, mods) for name in GEOMETRY for mods in (UNMODIFIED, MODIFIED)]
CASE_IDS = [f"{name}-{'mod' if mods['d_rrp'] else 'plain'}" for name, mods in CASES]


def valley_tip_radii(d):
    base = d.R_p + d.d_rp - d.r_rp - d.d_rrp
    return base - d.e, base + d.e


@pytest.mark.parametrize("name, mods", CASES, ids=CASE_IDS)
def test_closed_form_matches_independent_envelope(name, mods):
    d = make_design(name, **mods)
    valleys = 2 * np.pi * np.arange(d.z_c) / d.z_c
    rays = np.concatenate([np.linspace(0, 2 * np.pi, 500, endpoint=False), valleys, valleys + np.pi / d.z_c])
    angles, radius = numerical_envelope(d, rays, poses=1000)
    assert np.all(np.isfinite(radius))
    assert np.max(np.abs(radius - profile_radius_at(d, angles))) < 0.1 * UM
    # The envelope alone gives the valley and tip radii of docs/model.md section 3.
    valley, tip = valley_tip_radii(d)
    n = 500
    assert np.allclose(radius[n : n + d.z_c], valley, rtol=0, atol=0.1 * UM)
    assert np.allclose(radius[n + d.z_c :], tip, rtol=0, atol=0.1 * UM)


def test_disc_1_is_disc_0_turned_by_pi_and_conjugate():
    d = make_design("RV-40E-81", **MODIFIED)
    p0, p1 = disc_profile_for(d, 0, 2000), disc_profile_for(d, 1, 2000)
    np.testing.assert_allclose(p1.x, -p0.x, atol=1e-15)
    np.testing.assert_allclose(p1.y, -p0.y, atol=1e-15)
    # Disc 1 driven by cams at beta + theta_out + pi carves the same part, turned by pi.
    angles, radius = numerical_envelope(d, 360, poses=1000, disc=1)
    np.testing.assert_allclose(radius, profile_radius_at(d, angles - np.pi), atol=0.1 * UM)
    valley, tip = valley_tip_radii(d)

    def nearest(p, a):
        return np.hypot(p.x, p.y)[np.argmin(np.abs(np.angle(np.exp(1j * (np.arctan2(p.y, p.x) - a)))))]

    assert nearest(p1, np.pi) == pytest.approx(valley, abs=1e-9)
    assert nearest(p1, 0.0) == pytest.approx(tip, abs=1e-9)  # z_c odd: a tip faces valley 0
    with pytest.raises(ValueError, match="disc"):
        disc_profile_for(d, 2)


@pytest.mark.parametrize("name, mods", CASES, ids=CASE_IDS)
def test_valleys_and_tips_where_model_md_puts_them(name, mods):
    d = make_design(name, **mods)
    valley, tip = valley_tip_radii(d)
    m = np.arange(d.z_c)
    np.testing.assert_allclose(profile_radius_at(d, 2 * np.pi * m / d.z_c), valley, atol=1e-12)
    np.testing.assert_allclose(profile_radius_at(d, (2 * m + 1) * np.pi / d.z_c), tip, atol=1e-12)
    p = disc_profile(d)
    assert isinstance(p, Profile) and p.x.shape == p.y.shape == p.t.shape == (20000,)
    assert (p.x[0], p.y[0]) == pytest.approx((valley, 0.0), abs=1e-15)
    assert p.radius.min() == pytest.approx(valley, abs=1e-9)
    assert p.radius.max() == pytest.approx(tip, abs=1e-9)
    assert valley - 1e-15 <= p.radius.min() and p.radius.max() <= tip + 1e-15


@pytest.mark.parametrize("name", list(GEOMETRY))
def test_tip_and_root_clearance_is_d_rrp_minus_d_rp(name):
    plain, mod = make_design(name, **UNMODIFIED), make_design(name, **MODIFIED)
    at = np.pi * np.arange(2 * plain.z_c) / plain.z_c  # every root and tip
    clearance = profile_radius_at(plain, at) - profile_radius_at(mod, at)
    np.testing.assert_allclose(clearance, 0.02 * MM, atol=1e-12)
    assert mod.tip_root_clearance == pytest.approx(0.02 * MM)


def test_closed_form_is_the_trochoid_offset_by_the_pin():
    d = make_design("RV-40E-121", **MODIFIED)
    t = np.linspace(0, 2 * np.pi, 997)
    R, r = d.R_p + d.d_rp, d.r_rp + d.d_rrp
    cx = R * np.cos(t) - d.e * np.cos(d.z_p * t)
    cy = R * np.sin(t) - d.e * np.sin(d.z_p * t)
    tx = -R * np.sin(t) + d.e * d.z_p * np.sin(d.z_p * t)
    ty = R * np.cos(t) - d.e * d.z_p * np.cos(d.z_p * t)
    speed = np.hypot(tx, ty)
    x, y = _closed_form(d, t)
    np.testing.assert_allclose(x, cx - r * ty / speed, atol=1e-15)
    np.testing.assert_allclose(y, cy + r * tx / speed, atol=1e-15)


def test_z_c_fold_symmetry_and_even_spacing():
    d = make_design("RV-40E-81", **MODIFIED)
    a = np.linspace(0, 2 * np.pi, 1234)
    base = profile_radius_at(d, a)
    for m in (1, 7, 38):
        np.testing.assert_allclose(profile_radius_at(d, a + 2 * np.pi * m / d.z_c), base, atol=1e-12)
    p = disc_profile(d, 3900)
    # The points of lobe 0 turned by one lobe pitch lie on the profile.
    turn = np.exp(2j * np.pi / d.z_c) * (p.x + 1j * p.y)
    np.testing.assert_allclose(np.abs(turn), profile_radius_at(d, np.angle(turn)), atol=1e-12)
    step = np.hypot(np.diff(p.x), np.diff(p.y))
    assert step.max() / step.min() < 1.01  # equally spaced along the curve


def test_csv_round_trip(tmp_path):
    d = make_design("RV-40E-121", **MODIFIED)
    path = write_profile_csv(d, tmp_path / "disc.csv", points=1500)
    assert path.read_text().splitlines()[0] == "x_mm,y_mm"
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    p = disc_profile(d, 1500)
    assert data.shape == (1500, 2)
    np.testing.assert_allclose(data[:, 0], p.x / MM, atol=1e-8)
    np.testing.assert_allclose(data[:, 1], p.y / MM, atol=1e-8)


def test_dxf_readable_closed_polyline_in_mm(tmp_path):
    import ezdxf

    d = make_design("RV-40E-81", **MODIFIED)
    path = write_profile_dxf(d, tmp_path / "disc.dxf", points=2345)
    doc = ezdxf.readfile(path)
    assert doc.units == ezdxf.units.MM
    polylines = doc.modelspace().query("LWPOLYLINE")
    assert len(polylines) == 1 and polylines[0].closed
    vertices = np.array(polylines[0].get_points("xy"))
    p = disc_profile(d, 2345)
    assert vertices.shape == (2345, 2)
    np.testing.assert_allclose(vertices, np.column_stack([p.x, p.y]) / MM, atol=1e-9)


def test_dxf_without_ezdxf_says_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ezdxf", None)  # makes `import ezdxf` fail
    with pytest.raises(RuntimeError, match="pip install ezdxf"):
        write_profile_dxf(make_design("RV-40E-121"), tmp_path / "x.dxf")
