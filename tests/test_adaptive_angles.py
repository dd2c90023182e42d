"""te_pp from a coarse pass refined around the extremes (rvfmu/core/statics/adaptive_angles.py):
the same grid max - min as the full curve, from fewer solves, and the rule's stated limits."""

import numpy as np
import pytest
from conftest import ROOT

from rvfmu.core.base.checks import InputError
from rvfmu.core.statics.adaptive_angles import refine_extremes, te_pp_adaptive
from rvfmu.core.statics.quasistatic import te_curve
from tolerance import montecarlo
from tolerance.sampling import errors_from_unit
from tolerance.study import load_study


def table_solver(curves, calls):
    """solve(sample, index) reading the values of `curves` (S, P), recording every call."""

    def solve(sample, index):
        calls.append((sample.copy(), index.copy()))
        return curves[sample, index], np.ones(sample.size, dtype=bool)

    return solve


def test_smooth_curves_give_the_grid_extremes_from_a_fraction_of_the_points():
    P = 400
    x = 2 * np.pi * np.arange(P) / P
    curves = np.stack([np.sin(x) + 0.3 * np.cos(3 * x + 1.0), 2.0 * np.cos(2 * x + 0.4)])
    calls = []
    r = refine_extremes(table_solver(curves, calls), 2, P, stride=8, safety=2.0, pilot=4)
    np.testing.assert_array_equal(r.argmax, curves.argmax(axis=1))
    np.testing.assert_array_equal(r.argmin, curves.argmin(axis=1))
    np.testing.assert_array_equal(r.te_pp_arcsec, curves.max(axis=1) - curves.min(axis=1))
    # coarse 50 + 7 points in each of the pilot intervals, the two beside each coarse extreme
    # (the second curve has two maxima and two minima) and a few more
    assert np.all(r.solves < 0.4 * P), r.solves
    # no point is solved twice, and the count is what the record says
    s = np.concatenate([c[0] for c in calls])
    a = np.concatenate([c[1] for c in calls])
    assert len(set(zip(s.tolist(), a.tolist()))) == s.size
    np.testing.assert_array_equal(np.bincount(s, minlength=2), r.solves)
    assert r.rounds == len(calls)


def test_a_spike_narrower_than_the_stride_and_larger_than_any_excess_seen_is_missed():
    # The rule is statistical (module docstring): a one-point spike in an interval that
    # neither the pilot nor the extremes' neighbourhood refines is not found.
    P = 400
    x = 2 * np.pi * np.arange(P) / P
    curve = np.sin(x)
    # intervals of stride 8: the pilot takes 0 and 25, the extremes 11, 12, 36 and 37
    spike = 163  # inside interval 20
    curve[spike] = 5.0
    r = refine_extremes(table_solver(curve[None], []), 1, P, stride=8, safety=2.0, pilot=2)
    assert r.argmax[0] != spike
    assert r.te_max_arcsec[0] == pytest.approx(1.0, abs=1e-3)
    # with every interval in the pilot it is found
    r = refine_extremes(table_solver(curve[None], []), 1, P, stride=8, safety=2.0, pilot=50)
    assert r.argmax[0] == spike and r.solves[0] == P


@pytest.mark.parametrize(
    "field, value, allowed",
    [
        ("stride", 1, "must be from 2 to 200"),
        ("stride", 201, "must be from 2 to 200"),
        ("safety", 0.5, "must be >= 1"),
        ("safety", float("nan"), "must be finite"),
        ("pilot", -1, "must be >= 0"),
        ("points", 4, "must be >= 8"),
    ],
)
def test_bad_rule_settings_name_the_field_the_value_and_what_is_allowed(field, value, allowed):
    settings = {"points": 400, "stride": 4, "safety": 2.0, "pilot": 8, field: value}
    with pytest.raises(InputError) as caught:
        refine_extremes(lambda s, a: (np.zeros(s.size), np.ones(s.size, bool)), 1, **settings)
    message = str(caught.value)
    assert caught.value.field == field
    assert message.startswith(f"{field} = ") and allowed in message, message


@pytest.fixture(scope="module")
def full_study_reducers():
    """Three reducers drawn as studies/rv40e_121_full.toml draws them: every error source,
    the three bearing clearances included (the costly no-load route)."""
    study = load_study(ROOT / "studies" / "rv40e_121_full.toml")
    errors = errors_from_unit(study, montecarlo.rows(study, 0, 3))
    assert np.all(errors.crank_disc_clearance > 0) and np.all(errors.main_bearing_clearance > 0)
    return study.design, errors


def test_te_pp_equals_the_full_curve_on_sampled_reducers_with_clearances(full_study_reducers):
    design, errors = full_study_reducers
    # the study's 3200 points: far fewer alias so much that the rule refines every interval
    P = 3200
    full = te_curve(design, errors, tau_load=0.0, points=P)
    r = te_pp_adaptive(design, errors, tau_load=0.0, points=P)
    assert r.converged.all() and full.converged.all()
    np.testing.assert_allclose(r.te_pp_arcsec, full.te_pp_arcsec, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(r.argmax, full.te_arcsec.argmax(axis=1))
    np.testing.assert_array_equal(r.argmin, full.te_arcsec.argmin(axis=1))
    assert r.solves.sum() < errors.samples * P, r.solves
    assert np.all(r.solves >= P // 4)  # the coarse pass at least


def test_te_pp_adaptive_refuses_a_load_beyond_the_emergency_class(full_study_reducers):
    design, errors = full_study_reducers
    with pytest.raises(InputError) as caught:
        te_pp_adaptive(design, errors, tau_load=-100 * design.rated_torque, points=480)
    assert caught.value.field == "tau_load"
    assert "tau_load = " in str(caught.value)
