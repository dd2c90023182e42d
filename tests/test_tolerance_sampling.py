"""The statistical model of every kind of tolerance (tolerance/sampling.py, tolerance/sequences.py)."""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ndtr
from tolerance_toy import write_study

from rvfmu.core.base.units import UM
from tolerance import montecarlo, sampling, sequences
from tolerance.sampling import centred, disc_radius, fraction
from tolerance.study import Factor, load_study

ROOT = Path(__file__).resolve().parent.parent
N = 40_000
RNG = np.random.default_rng(11)
U = RNG.random(N)


def test_uniform_zone_is_uniform_over_the_disc_not_in_radius():
    r = disc_radius(U, 4.0, "uniform")
    assert r.min() >= 0 and r.max() <= 4.0
    # Uniform over the disc: P(r < R/2) is the area ratio 1/4 (uniform in radius would give 1/2).
    inner = np.mean(r < 2.0)
    assert abs(inner - 0.25) < 4 * np.sqrt(0.25 * 0.75 / N)
    assert abs(np.mean(r < 4.0 * np.sqrt(0.6)) - 0.6) < 0.01


def test_normal_zone_is_a_truncated_circular_normal():
    r = disc_radius(U, 3.0, "normal")  # 3 sigma = zone radius 3 -> sigma = 1
    assert r.max() <= 3.0
    expected = (1 - np.exp(-0.5)) / (1 - np.exp(-4.5))  # Rayleigh P(r < sigma), truncated at 3 sigma
    assert abs(np.mean(r < 1.0) - expected) < 4 * np.sqrt(expected * (1 - expected) / N)


def test_centred_values_uniform_and_normal_within_their_tolerance():
    uniform = centred(U, 2.0, "uniform")
    assert uniform.min() >= -2.0 and uniform.max() <= 2.0
    assert abs(uniform.std() - 4.0 / np.sqrt(12)) < 0.02
    normal = centred(U, 3.0, "normal")  # tolerance +-3 -> sigma 1, truncated at 3 sigma
    assert np.abs(normal).max() <= 3.0
    inside = (ndtr(1) - ndtr(-1)) / (ndtr(3) - ndtr(-3))
    assert abs(np.mean(np.abs(normal) < 1.0) - inside) < 4 * np.sqrt(inside * (1 - inside) / N)
    assert abs(normal.std() - 0.9866) < 0.015  # std of N(0,1) truncated at +-3
    assert np.isfinite(centred(np.array([0.0, 1.0]), 3.0, "normal")).all()  # u = 0 and 1 are safe


def test_magnitude_fraction_uniform_and_half_normal():
    assert abs(fraction(U, "uniform").mean() - 0.5) < 0.01
    half = fraction(U, "normal")
    assert half.min() >= 0 and half.max() <= 1.0
    assert abs(np.mean(half < 1 / 3) - (2 * ndtr(1) - 1) / (2 * ndtr(3) - 1)) < 0.01


@pytest.mark.parametrize("distribution", ["uniform", "normal"])
def test_pitch_sequences_respect_cumulative_and_single_pitch_tolerances(rv40, distribution):
    factor = Factor("disc_pitch", "pitch", distribution, cumulative_um=6.0, single_um=1.2)
    names = sampling.draw_names(factor, rv40)
    assert len(names) == 2 * (1 + 6 + rv40.z_c)
    values = sampling.factor_values(factor, rv40, RNG.random((2000, len(names)))) / UM
    assert values.shape == (2000, 2, rv40.z_c)
    span = np.ptp(values, axis=-1)
    single = np.abs(sequences.single_pitch_deviations(values)).max(axis=-1)
    assert span.max() <= 6.0 + 1e-9  # F_p
    assert single.max() <= 1.2 + 1e-9  # f_pt, to round-off
    assert np.any(np.isclose(single, 1.2))  # the single-pitch limit binds on some parts
    assert np.allclose(values[..., 0], 0.0)  # tooth 0 is the reference


def test_pitch_span_is_uniform_in_the_tolerance_without_single_limit(rv40):
    factor = Factor("pin_pitch", "pitch", "uniform", cumulative_um=8.0)
    names = sampling.draw_names(factor, rv40)
    values = sampling.factor_values(factor, rv40, RNG.random((4000, len(names)))) / UM
    span = np.ptp(values, axis=-1)
    assert span.max() <= 8.0 + 1e-9
    assert abs(np.mean(span < 4.0) - 0.5) < 0.03


def test_band_and_clearance_factors_stay_in_their_range(rv40):
    band = Factor("disc_profile", "band", "uniform", band_um=8.0)
    values = sampling.factor_values(band, rv40, RNG.random((500, 2 * rv40.z_c))) / UM
    assert values.shape == (500, 2, rv40.z_c) and np.abs(values).max() <= 4.0
    clearance = Factor("main_bearing_clearance", "clearance", "normal", min_um=2.0, max_um=10.0)
    gaps = sampling.factor_values(clearance, rv40, RNG.random((5000, 1))) / UM
    assert gaps.min() >= 2.0 and gaps.max() <= 10.0 and abs(gaps.mean() - 6.0) < 0.05


def test_rows_make_reproducible_reducers_with_the_fixed_errors_added(tmp_path, seed002):
    path = write_study(tmp_path, study={"errors": str(ROOT / "studies" / "seed002_errors.toml")})
    study = load_study(path)
    X = montecarlo.rows(study, 0, 10)
    assert np.array_equal(X[5], montecarlo.rows(study, 5, 6)[0])  # a row does not depend on n
    errors = sampling.errors_from_unit(study, X)
    again = sampling.errors_from_unit(study, X)
    for name, array in errors.arrays().items():
        assert np.array_equal(array, getattr(again, name))
    # Sources without a tolerance keep the error file's values; toleranced ones add to them.
    assert np.array_equal(errors.disc_pitch, np.repeat(seed002.disc_pitch, 10, axis=0))
    sampled = errors.carrier_assembly - seed002.carrier_assembly[0]
    assert np.all(np.abs(sampled) <= 4.0 * UM + 1e-15)
    assert not np.any(errors.sun_eccentricity)
    bare = replace(study, base_errors=None)
    assert np.allclose(sampling.errors_from_unit(bare, X).carrier_assembly, sampled, rtol=0, atol=1e-18)


def test_seed002_error_file_script_still_reproduces_the_stored_file(tmp_path):
    sys.path.insert(0, str(ROOT / "studies"))
    try:
        import make_seed002_errors
    finally:
        sys.path.pop(0)
    written = make_seed002_errors.main(tmp_path / "seed002_errors.toml")
    assert written.read_text() == (ROOT / "studies" / "seed002_errors.toml").read_text()
