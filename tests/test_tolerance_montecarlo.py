"""Monte Carlo yield: the Wilson interval, and a toy reducer whose true yield is known."""

import numpy as np
import pytest
from tolerance_toy import write_study

from tolerance import evaluate, run_mc, wilson_interval
from tolerance.study import load_study


def test_wilson_interval_by_hand():
    z = 1.959963984540054
    low, high = wilson_interval(0, 10, 0.95)
    assert low == 0.0 and high == pytest.approx(z * z / (10 + z * z))
    low, high = wilson_interval(50, 100, 0.95)
    half = z * np.sqrt(0.25 / 100 + z * z / 40000) / (1 + z * z / 100)
    assert (low, high) == pytest.approx((0.5 - half, 0.5 + half))


def test_wilson_interval_covers_the_true_yield_at_its_confidence():
    rng = np.random.default_rng(5)
    p, n, trials = 0.93, 200, 4000
    passed = rng.binomial(n, p, trials)
    covered = np.mean([lo <= p <= hi for lo, hi in (wilson_interval(k, n, 0.95) for k in passed)])
    assert 0.93 <= covered <= 0.97


def test_mc_yield_interval_covers_the_true_yield_of_a_toy_reducer(tmp_path):
    """One true-position zone (carrier assembly, uniform over a 8 um disc): te_pp grows with the
    offset r at every phase, so the true yield is the phase average of (r*/R)^2, where r* is the
    offset at which te_pp reaches the limit (uniform over the disc: P(r < r*) = (r*/R)^2).
    The estimate's 20 um tip and root clearance keeps the discs free at every offset; the
    calibrated preset's 5 um does not (a large offset preloads pins: te_pp is not monotone)."""
    toy = {"metrics": ["te_pp"], "design": "RV-40E-121-estimate"}
    path = write_study(tmp_path, tolerances={"carrier_assembly": {"position_um": 8.0}}, study=toy)
    study = load_study(path)
    radius = np.linspace(0.0, 1.0, 25)  # r / R
    phase = np.arange(16) / 16  # beta / 2 pi
    rr, pp = np.meshgrid(radius, phase)
    X = np.column_stack([rr.ravel() ** 2, pp.ravel()])  # the columns: u_radius, u_phase
    te_pp = evaluate(study, X)[0][:, 0].reshape(rr.shape)
    assert np.all(np.diff(te_pp, axis=1) > 0)  # monotone in r at every phase
    limit = float(np.median(te_pp[:, 17]))  # about r = 0.7 R
    r_star = np.array([np.interp(limit, row, radius) for row in te_pp])
    true_yield = float(np.mean(r_star**2))
    assert 0.3 < true_yield < 0.7

    changed = write_study(
        tmp_path,
        tolerances={"carrier_assembly": {"position_um": 8.0}},
        study=toy,
        spec={"te_pp_arcsec": limit},
        montecarlo={"n": 256},
    )
    result = run_mc(changed, plots=False)
    (y,) = result.analysis.yields
    assert y.n == 256 and y.method == "Wilson score"
    assert y.low <= true_yield <= y.high
    assert y.high - y.low < 0.13


def test_a_reducer_whose_solve_fails_costs_itself_not_its_batch(tmp_path, monkeypatch):
    from importlib import import_module

    from tolerance import analyze_mc, sample_mc

    evaluation = import_module("tolerance.evaluate")  # the module (the package's name is the function)

    study = load_study(write_study(tmp_path))
    X = sample_mc(study, 8)
    good_Y, good_converged = evaluate(study, X)
    real_te_curve = evaluation.te_curve
    doomed = np.abs(evaluation.errors_from_unit(study, X).carrier_assembly) > 3e-6  # (8,)
    assert 0 < doomed.sum() < 8

    def singular_for_large_offsets(design, errors, **kwargs):
        if np.any(np.abs(errors.carrier_assembly) > 3e-6):
            raise np.linalg.LinAlgError("Singular matrix")
        return real_te_curve(design, errors, **kwargs)

    monkeypatch.setattr(evaluation, "te_curve", singular_for_large_offsets)
    Y, converged = evaluate(study, X)
    assert np.all(np.isnan(Y[doomed])) and not converged[doomed].any()
    # the same reducers, to the solver's convergence (1e-14 m): alone, a reducer's Newton
    # iteration starts elsewhere (the error-free start needs NOMINAL_GUESS_MIN_SAMPLES)
    np.testing.assert_allclose(Y[~doomed], good_Y[~doomed], rtol=1e-8, atol=0.0)
    analysis = analyze_mc(study, Y, converged)
    assert analysis.failed == doomed.sum() and analysis.yields[0].n == 8 - doomed.sum()
