"""Tolerance allocation: the cost model, the least-cost core on a stack-up with a closed form,
and `allocate` / `rvte allocate` on a small reducer study."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ndtr, ndtri
from tolerance_toy import toml_value, write_study

import tolerance
from rvfmu.core.base.checks import InputError
from tolerance import cost as costs
from tolerance.least_cost import (
    CORRECTION_CONSTANT,
    CORRECTION_LOCAL,
    CORRECTION_SLOPE,
    KAPPA,
    Correction,
    Limit,
    ScaledModel,
    Verified,
    allocate_scales,
    look_confidence,
    look_sizes,
    sequential_yield,
)
from tolerance.mc_runs import run_mc
from tolerance.study import load_study
from tolerance.surrogate import Chaos


def priced_study(folder, costs_of: dict, **options):
    """`write_study` with a [tolerances.NAME.cost] table per entry of costs_of."""
    path = write_study(folder, **options)
    lines = [path.read_text()]
    for name, table in costs_of.items():
        lines.append(
            f"[tolerances.{name}.cost]\n"
            + "".join(f"{key} = {toml_value(value)}\n" for key, value in table.items())
        )
    path.write_text("".join(lines))
    return path


# -- the cost model --------------------------------------------------------------------------------


def test_reciprocal_power_cost_and_its_defaults_by_hand(tmp_path):
    model = costs.CostModel(a=1.0, b=32.0, k=2.0, tightest_um=2.0, loosest_um=8.0)
    assert model.cost(4.0) == pytest.approx(1.0 + 32.0 / 16.0)
    assert model.slope(4.0) == pytest.approx(-2.0 * 32.0 / 16.0)  # d cost / d ln t
    study = load_study(write_study(tmp_path))
    zone = study.factors[0]  # carrier_assembly, 8 um
    default = costs.resolved(zone)
    assert (default.a, default.k, default.b) == (0.0, 2.0, 8.0**2)  # one unit at 8 um (seed 002)
    assert default.cost(8.0) == pytest.approx(1.0)
    assert default.tightest_um == pytest.approx(8.0 / 10**0.4)  # two IT grades either side
    assert default.loosest_um == pytest.approx(8.0 * 10**0.4)


def test_the_allocated_number_of_each_kind_and_what_follows_it(tmp_path):
    study = load_study(
        write_study(
            tmp_path,
            tolerances={
                "disc_pitch": {"cumulative_um": 6.0, "single_um": 1.9},
                "crank_disc_clearance": {"min_um": 2.0, "max_um": 8.0},
                "pin_radial": {"band_um": 5.0},
                "carrier_assembly": {"position_um": 8.0},
            },
        )
    )
    pitch, clearance, band, zone = study.factors
    assert costs.scaled_values(pitch, 0.5) == {"cumulative_um": 3.0, "single_um": 0.95}
    assert costs.scaled_values(clearance, 0.5) == {"max_um": 4.0, "min_um": 1.0}
    assert costs.scaled_values(band, 2.0) == {"band_um": 10.0}
    assert costs.scaled_values(zone, 0.25) == {"position_um": 2.0}
    assert [costs.current_um(f) for f in study.factors] == [6.0, 8.0, 5.0, 8.0]


def test_a_cost_section_changes_no_computed_number(tmp_path):
    plain = load_study(write_study(tmp_path, name="plain"))
    priced = load_study(
        priced_study(
            tmp_path,
            {
                "carrier_assembly": {"a": 2.0, "b": 10.0, "k": 1.5, "tightest_um": 4.0, "loosest_um": 12.0},
                "crank_cam_eccentricity": {"k": 1.0},
            },
            name="priced",
        )
    )
    assert priced.inputs_hash == plain.inputs_hash
    assert priced.factors[0].cost == costs.CostModel(a=2.0, b=10.0, k=1.5, tightest_um=4.0, loosest_um=12.0)
    assert costs.resolved(priced.factors[1]).b == pytest.approx(8.0)  # 8 um ** k = 1


@pytest.mark.parametrize(
    "cost, field, words",
    [
        ({"k": -1.0}, "cost.k", "exponent must be >= 0"),
        ({"b": -2.0}, "cost.b", "must be >= 0"),
        ({"tightest_um": 6.0, "loosest_um": 5.0}, "cost.tightest_um", "must be <= loosest_um"),
        ({"tightest_um": 10.0}, "cost.tightest_um", "must be <= the current tolerance position_um"),
        ({"tightest_um": 2.0, "loosest_um": 7.0}, "cost.loosest_um", "must be >= the current"),
        ({"colour": 1}, "cost.colour", "is not a key of the cost table"),
    ],
)
def test_bad_cost_sections_are_one_line_naming_the_field(tmp_path, cost, field, words):
    path = priced_study(
        tmp_path, {"carrier_assembly": cost}, tolerances={"carrier_assembly": {"position_um": 8.0}}
    )
    with pytest.raises(InputError) as error:
        load_study(path)
    message = str(error.value)
    assert "\n" not in message and message.startswith("toy.toml: ")
    assert f"tolerances.carrier_assembly.{field} = " in message and words in message


# -- the core on an analytic stack-up ----------------------------------------------------------------


def test_chaos_evaluates_as_openturns_does():
    rng = np.random.default_rng(4)
    X = rng.uniform(-1, 1, (400, 3))
    y = 1.0 + X[:, 0] - 2.0 * X[:, 1] * X[:, 2] + 0.5 * X[:, 2] ** 2
    chaos = Chaos(X, y)
    test = rng.uniform(-1, 1, (50, 3))
    np.testing.assert_allclose(chaos(test), np.asarray(chaos.metamodel(test))[:, 0], atol=1e-12)
    np.testing.assert_allclose(
        chaos(test), 1.0 + test[:, 0] - 2.0 * test[:, 1] * test[:, 2] + 0.5 * test[:, 2] ** 2, atol=1e-9
    )


def test_the_quadratic_form_of_a_degree_2_chaos_is_its_sum_of_legendre_terms():
    """The search evaluates its chaos (degree 2) as k0 + g.x + x.Q x with two BLAS products;
    the sum over the orthonormal Legendre terms is the reference, values and gradients."""
    rng = np.random.default_rng(6)
    X = rng.uniform(-1, 1, (600, 4))
    y = 0.3 + X[:, 0] - 2.0 * X[:, 1] * X[:, 2] + 0.7 * X[:, 3] ** 2 - 0.4 * X[:, 0] * X[:, 3]
    chaos = Chaos(X, y + 0.01 * rng.standard_normal(600))
    assert chaos.quadratic is not None
    assert sum(np.count_nonzero(a) == 2 for a in chaos.alpha) >= 2  # interactions kept
    assert sum(a.max() == 2 for a in chaos.alpha) >= 1  # and a square
    test = rng.uniform(-1, 1, (200, 4))
    value, gradient = chaos.value_gradient(test)
    reference, reference_gradient = chaos.terms_value_gradient(test)
    np.testing.assert_allclose(value, reference, rtol=0, atol=1e-12)
    np.testing.assert_allclose(gradient, reference_gradient, rtol=0, atol=1e-12)
    np.testing.assert_allclose(chaos(test), chaos.terms(test), rtol=0, atol=1e-12)
    np.testing.assert_allclose(chaos(test), np.asarray(chaos.metamodel(test))[:, 0], atol=1e-12)
    cubic = Chaos(X, y + X[:, 0] ** 3, 3)  # beyond degree 2: the terms themselves
    assert cubic.quadratic is None
    np.testing.assert_allclose(cubic(test), np.asarray(cubic.metamodel(test))[:, 0], atol=1e-12)


def _central_differences(function, X, h=1e-6):
    """d function / d X by central differences: function (m, F) -> (m,), X (m, F): (m, F)."""
    return np.stack(
        [(function(X + h * e) - function(X - h * e)) / (2 * h) for e in np.eye(X.shape[1])], axis=1
    )


def test_the_gradients_the_optimisers_use_are_those_of_the_functions():
    """The chain rule through the chaos, the surrogate's probability of passing two spec
    lines, and the correction's mean, variance and planned probit equals central differences."""
    from tolerance.surrogate import Surrogate

    rng = np.random.default_rng(5)
    X = rng.uniform(-1, 1, (400, 3))
    chaos = Chaos(
        X, 1.0 + X[:, 0] - 2.0 * X[:, 1] * X[:, 2] + 0.5 * X[:, 2] ** 2 + 0.05 * rng.standard_normal(400)
    )
    inside = rng.uniform(-0.9, 0.9, (6, 3))
    value, gradient = chaos.value_gradient(inside)
    np.testing.assert_allclose(value, chaos(inside), atol=1e-12)
    np.testing.assert_allclose(gradient, _central_differences(chaos, inside), atol=1e-7)

    Z = rng.uniform(0.0, 2.0, (3000, 3))  # a metric whose spread grows with Z
    Y = np.exp(
        0.3 * Z[:, :1] + 0.2 * Z[:, 1:2] * Z[:, 2:3] + 0.1 * (1 + Z[:, :1]) * rng.standard_normal((3000, 1))
    )
    surrogate = Surrogate(Z, Y, (Limit(0, 3.0, "max"), Limit(0, 1.2, "min")))
    at = rng.uniform(0.1, 1.9, (6, 3))
    p, dp = surrogate.probability(at, gradient=True)
    np.testing.assert_allclose(p, surrogate.probability(at), rtol=1e-12)
    assert np.abs(dp).max() > 0.05  # not trivially flat
    np.testing.assert_allclose(dp, _central_differences(surrogate.probability, at), atol=1e-7)

    def surrogate_probit(S, gradient=False):  # a curved surrogate, 2 factors
        x = np.log(np.atleast_2d(S))
        z = 3.0 - 0.7 * x.sum(axis=1) - 0.2 * x[:, 0] * x[:, 1]
        return (z, np.stack([-0.7 - 0.2 * x[:, 1], -0.7 - 0.2 * x[:, 0]], axis=1)) if gradient else z

    runs = np.array([[1.0, 1.0], [1.3, 1.1], [1.1, 1.4]])
    correction = Correction(
        [_verified_at(s, surrogate_probit(s)[0] - 0.1, n=20000) for s in runs], surrogate_probit, 3.0
    )
    log_s = np.log(rng.uniform(0.8, 2.0, (5, 2)))
    z, mean, var, dz, d_mean, d_var = correction.at(np.exp(log_s), gradient=True)
    for value, gradient, k in ((mean, d_mean, 1), (var, d_var, 2)):
        np.testing.assert_allclose(value, correction.at(np.exp(log_s))[k], rtol=1e-12)
        numeric = _central_differences(lambda x: correction.at(np.exp(x))[k], log_s)
        np.testing.assert_allclose(gradient, numeric, atol=1e-7)
    planned, d_planned = correction.planned(np.exp(log_s), -KAPPA, 0.01, gradient=True)
    numeric = _central_differences(lambda x: correction.planned(np.exp(x), -KAPPA, 0.01), log_s)
    np.testing.assert_allclose(d_planned, numeric, atol=1e-7)


def _verified_at(scales, z, n=10**7):
    """A Monte Carlo of n reducers whose yield is Phi(z) (to a reducer)."""
    passed = int(round(ndtr(z) * n))
    return Verified(np.asarray(scales, dtype=float), passed, n, 0.0, 1.0)


def test_the_correction_learns_the_surrogates_error_from_the_verified_points():
    """A surrogate that predicts 70 % of the true drop in yield (probit units): its error is
    0.3 x its predicted drop.  From four nearly noise-free Monte Carlo runs the correction
    reproduces the truth at and beside them; at twice their largest drop it has learnt most
    of the error, its spread has grown again, and the search's margin covers the rest."""

    def surrogate_probit(S):  # predicted drop 0.7 x the true one, 2 factors
        return 3.0 - 0.7 * np.log(np.atleast_2d(S)).sum(axis=1)

    def true_probit(S):
        return 3.0 - np.log(np.atleast_2d(S)).sum(axis=1)

    runs = np.array([[1.0, 1.0], [1.3, 1.1], [1.1, 1.4], [1.5, 1.5]])
    verified = [_verified_at(s, true_probit(s)[0]) for s in runs]
    correction = Correction(verified, surrogate_probit, 3.0)
    z, mean, var = correction.at(runs)
    np.testing.assert_allclose(z - mean, true_probit(runs), atol=0.01)  # the runs, corrected
    assert np.all(np.sqrt(var) < 0.01)
    between = np.array([[2.0, 1.2]])  # beside the runs: corrected to 0.02 probit
    z, mean, _ = correction.at(between)
    assert z[0] - mean[0] == pytest.approx(true_probit(between)[0], abs=0.02)
    far = np.array([[2.5, 2.5]])  # predicted drop 1.28, the runs' largest 0.57
    z, mean, var = correction.at(far)
    truth = true_probit(far)[0]
    assert z[0] - truth == pytest.approx(0.3 * 2 * np.log(2.5), rel=1e-9)  # 0.55 optimistic
    assert abs(z[0] - mean[0] - truth) < 0.25 * (z[0] - truth)  # most of it learnt
    assert z[0] - mean[0] - KAPPA * np.sqrt(var[0]) < truth  # the search's margin covers the rest
    prior = CORRECTION_CONSTANT**2 + CORRECTION_SLOPE**2 * (3.0 - z[0]) ** 2 + CORRECTION_LOCAL**2
    assert 0.05**2 < var[0] < prior  # unsure again, less than knowing nothing


def test_a_verification_looks_after_n_over_16_to_n_reducers_in_whole_batches():
    assert look_sizes(10_000, 64) == (640, 1280, 2560, 5056, 10_000)
    assert look_sizes(2000, 64) == (512, 1024, 2000)  # 256 is below MIN_LOOK
    assert look_sizes(512, 32) == (512,)  # one look: the Monte Carlo of n as it always was
    assert look_sizes(10_000, 64, looks=1) == (10_000,)
    assert look_sizes(10_000, 1, looks=3) == (2500, 5000, 10_000)
    assert look_confidence(0.95, 5) == pytest.approx(0.99) and look_confidence(0.95, 1) == 0.95


def binomial_model(p: float):
    """One metric, 1 for a reducer that fails (probability 1 - p), 0 for one that passes the
    spec line <= 0.5; draws number `draw` are their own, a larger n extends a smaller one."""

    def verify(s, n, draw):
        return (np.random.default_rng([5, draw]).random(n) >= p)[:, None].astype(float)

    cost = (costs.CostModel(a=0.0, b=1.0, k=1.0, tightest_um=0.5, loosest_um=2.0),)
    return ScaledModel(("x",), np.ones(1), cost, (Limit(0, 0.5, "max"),), 1, None, None, verify)


def test_a_sequential_verification_stops_at_the_first_look_clear_of_the_target():
    sizes, level = look_sizes(10_000, 64), look_confidence(0.95, 5)
    for p, meets in ((0.9999, True), (0.95, False)):
        model = binomial_model(p)
        verified, rows = sequential_yield(model, [1.0], 0.99, sizes, 1, level)
        assert rows == verified.n < 10_000 and verified.meets(0.99) is meets
        # every earlier look's interval, by its own count, straddles the target; this one does not
        for size in sizes:
            fails = int(model.verify([1.0], size, 1).sum())
            low, high = tolerance.wilson_interval(size - fails, size, level)
            assert (low >= 0.99 or high < 0.99) is (size == rows)
            if size == rows:
                assert (verified.low, verified.high) == (low, high) and verified.passed == size - fails
                break
    # near the target it takes every reducer: the last look decides
    verified, rows = sequential_yield(binomial_model(0.991), [1.0], 0.99, sizes, 1, level)
    assert rows == verified.n == 10_000


def test_the_looks_keep_the_error_rate_the_interval_states():
    """At a true yield equal to the target, an allocation may be found to meet it (the low end
    of its interval above the target) at most (1 - c) / 2 of the time.  Five looks at the
    plain 95 % each break that (about 6 %); at 99 % each (Bonferroni) they keep it."""
    sizes, model, repeats = look_sizes(10_000, 64), binomial_model(0.99), 2000

    def rate(level):
        return np.mean(
            [sequential_yield(model, [1.0], 0.99, sizes, d, level)[0].meets(0.99) for d in range(repeats)]
        )

    spread = 3 * np.sqrt(0.025 * 0.975 / repeats)
    assert rate(look_confidence(0.95, len(sizes))) <= 0.025 + spread
    assert rate(0.95) > 0.025 + spread


def test_linear_stack_up_recovers_the_closed_form_least_cost_allocation():
    """y = sum x_i, x_i normal with sigma t_i / 3, spec |y| <= L: yield 2 Phi(L / sigma_y) - 1.

    Minimising sum b_i t_i^-k subject to sum t_i^2 = 9 sigma_y^2 (Lagrange):
    t_i proportional to b_i^(1 / (k + 2)).
    """
    b, k, L, target = np.array([1.0, 2.0, 4.0]), 1.0, 1.13, 0.9973
    current = np.ones(3)
    models = tuple(costs.CostModel(a=0.0, b=bi, k=k, tightest_um=0.2, loosest_um=5.0) for bi in b)

    def values(U):  # each factor's error at the current tolerance
        return ndtri(np.clip(U, 1e-12, 1 - 1e-12)) * current / 3

    def evaluate(s, U, job):
        return (values(U) * s).sum(axis=1, keepdims=True)

    verifications = []

    def verify(s, n, draw):  # draws number `draw`: independent of every other number
        U = np.random.default_rng([11, draw]).random((n, 3))
        verifications.append(draw)
        return evaluate(s, U, "verify")

    model = ScaledModel(
        ("x0", "x1", "x2"),
        current,
        models,
        (Limit(0, L, "max"), Limit(0, -L, "min")),
        3,
        values,
        evaluate,
        verify,
        log_inputs=False,
        seed=3,
    )
    # one Monte Carlo of n a verification (looks=1): the search itself against the closed form.
    # With the default sequential looks it took 375 768 instead of 5 000 768 evaluations and
    # came to 10.45 and 10.40 (two seeds) against 10.33 (docs/benchmarks.md).  The surrogate's
    # yield on 2^15 draws: the scales within 1.1 % of the closed form (1.4 % on 2^16, 4.5 % on
    # the default 2^14)
    result = allocate_scales(model, target, 1_000_000, draws=2**15, looks=1)

    sigma_y = L / ndtri((1 + target) / 2)
    best = b ** (1 / (k + 2))
    best *= 3 * sigma_y / np.sqrt(np.sum(best**2))
    best_cost = np.sum(b * best**-k)
    assert result.feasible and result.allocated.estimate >= target
    assert result.current.estimate == pytest.approx(2 * ndtr(L / np.sqrt(3) * 3) - 1, abs=1e-3)
    assert model.cost(result.scales).sum() == pytest.approx(best_cost, rel=0.02)
    np.testing.assert_allclose(result.scales * current, best, rtol=0.05)
    assert result.allocated.n == 1_000_000
    assert result.allocated.low <= result.allocated.estimate <= result.allocated.high
    # the current tolerances, every round and every confirmation, each on draws of its own
    assert verifications == list(range(1 + len(result.rounds) + len(result.confirmations)))


# -- a small reducer study -----------------------------------------------------------------------------

TOLERANCES = {
    "crank_cam_eccentricity": {"position_um": 9.0, "distribution": "normal"},
    "pin_radial": {"band_um": 5.0},
}


def small_study(folder, spec=30.0, name="small"):
    """Two factors, TE only, 64 points: a reducer model in milliseconds.  One output folder for
    every spec: the spec is not part of the study's identity, so the stored runs are shared."""
    return priced_study(
        folder,
        {"crank_cam_eccentricity": {"tightest_um": 4.0, "loosest_um": 18.0}},
        name=name,
        study={"metrics": ["te_pp"], "batch_size": 32, "output": "small/output"},
        spec={"te_pp_arcsec": spec},
        montecarlo={"n": 512},
        tolerances=TOLERANCES,
    )


SPEC = 24.0  # te_pp, arcsec: the current tolerances miss it (yield 0.92 of 512)


@pytest.fixture(scope="module")
def allocated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("allocate")
    path = small_study(folder, spec=SPEC)
    return path, tolerance.allocate(path, 0.95, progress=False)


def test_allocation_meets_its_target_in_the_verification_monte_carlo(allocated):
    path, result = allocated
    # met: the low end of the verification's 95 % interval, not only its estimate
    assert result.feasible and result.yield_allocated.low >= 0.95 > result.yield_current.estimate
    assert result.yield_allocated.n == 512  # the study's [montecarlo] n below 0.99
    low, high = tolerance.wilson_interval(round(result.yield_allocated.estimate * 512), 512, 0.95)
    assert (result.yield_allocated.low, result.yield_allocated.high) == pytest.approx((low, high))
    # the cam position decides the TE (the pin band hardly does): it is tightened, relatively,
    # more than the pin band
    cam, band = result.factors
    assert cam.allocated / cam.current < band.allocated / band.current
    # the allocated study file is ready to run: its Monte Carlo is the confirmation on fresh
    # draws (its own seed), whose yield is the one reported, and is reused
    text = Path(result.allocated_study_file).read_text()
    assert "reducers that no step of the search saw" in text and "rvte mc" in text
    mc = run_mc(result.allocated_study_file, 512, plots=False)
    assert mc.computed.computed == 0
    assert np.mean(mc.Y[:, 0] <= SPEC) == pytest.approx(result.yield_allocated.estimate)
    assert load_study(result.allocated_study_file).seed != load_study(path).seed
    allocated_study = load_study(result.allocated_study_file)
    for factor, record in zip(allocated_study.factors, result.factors):
        assert costs.current_um(factor) == pytest.approx(record.allocated, abs=1e-9)
        assert record.lower <= record.allocated <= record.upper
    assert path.read_text() == small_study(path.parent, spec=SPEC).read_text()  # never overwritten


def test_allocation_json_has_exactly_the_schema_the_report_reads(allocated):
    path, result = allocated
    folder = path.parent / "small" / "output"
    document = json.loads((folder / "allocation.json").read_text())
    assert (folder / "mc_summary.json").is_file()  # the current tolerances: `rvte mc`'s files
    assert document == json.loads(json.dumps(result.to_json()))
    assert list(document) == [
        "study",
        "study_file",
        "allocated_study_file",
        "target_yield",
        "feasible",
        "factors",
        "total_cost",
        "yield",
        "surrogate",
        "model_evaluations",
    ]
    assert [f["name"] for f in document["factors"]] == [
        "crank_cam_eccentricity.position_um",
        "pin_radial.band_um",
    ]
    assert set(document["factors"][0]) == {
        "name",
        "unit",
        "current",
        "allocated",
        "lower",
        "upper",
        "cost_current",
        "cost_allocated",
        "binding",
    }
    assert {f["binding"] for f in document["factors"]} <= {"none", "lower", "upper"}
    assert document["factors"][0]["lower"] == 4.0 and document["factors"][0]["upper"] == 18.0
    assert set(document["yield"]) == {"current", "allocated"}
    assert set(document["yield"]["allocated"]) == {"estimate", "low", "high", "n"}
    assert set(document["surrogate"]) == {"kind", "samples", "validation"}
    assert set(document["total_cost"]) == {"current", "allocated"}
    assert isinstance(document["model_evaluations"], int) and document["model_evaluations"] > 1024


def test_an_unreachable_target_gives_the_best_yield_and_the_binding_bounds(allocated):
    path, _ = allocated
    strict = small_study(path.parent, spec=4.0, name="strict")  # same study, same output folder
    result = tolerance.allocate(strict, 0.99, n=512, progress=False)
    assert not result.feasible
    # the cam position decides the TE: it binds at its tightest; the pin band hardly moves the
    # TE (the test above), so whether its bound binds at the best yield is the surrogate's call,
    # but it is never opened beyond the current band for a target out of reach
    cam, band = result.factors
    assert cam.binding == "lower" and cam.allocated == pytest.approx(cam.lower)
    assert band.binding in ("lower", "none") and band.allocated <= band.current + 1e-9
    assert result.yield_allocated.estimate < 0.99 and result.yield_allocated.n == 512
    assert "OUT OF REACH" in result.table()


def test_rvte_allocate_prints_the_same_document_and_refuses_bad_input_in_one_line(allocated, tmp_path):
    path, result = allocated
    proc = rvte("allocate", path, "--yield", 0.95, "--json")  # everything is stored: reused
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == json.loads(json.dumps(result.to_json()))

    bad = priced_study(
        tmp_path, {"pin_radial": {"k": -2.0}}, name="bad", tolerances={"pin_radial": {"band_um": 5.0}}
    )
    proc = rvte("allocate", bad)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert "tolerances.pin_radial.cost.k = -2.0" in proc.stderr

    other = write_study(tmp_path, name="other", tolerances={"pin_radial": {"band_um": 3.0}})
    proc = rvte("allocate", other, "-o", path.parent / "small" / "output")
    assert (
        proc.returncode == 2
        and "output = " in proc.stderr
        and "belongs to another study" in proc.stderr
        and "Traceback" not in proc.stderr
    )

    proc = rvte("allocate", path, "--yield", 1.5)
    assert proc.returncode == 2 and "yield = 1.5" in proc.stderr


def test_bounds_that_exclude_the_current_tolerance_stop_allocate_before_any_work(tmp_path):
    path = priced_study(
        tmp_path, {"pin_radial": {"loosest_um": 4.0}}, tolerances={"pin_radial": {"band_um": 5.0}}
    )
    with pytest.raises(
        InputError,
        match="tolerances.pin_radial.cost.loosest_um = 4.0: must be >= the current tolerance band_um = 5",
    ):
        tolerance.allocate(path)
    assert not (tmp_path / "toy").exists()


def test_allocate_is_the_package_function_even_once_the_modules_are_imported():
    import tolerance.allocation
    import tolerance.least_cost  # noqa: F401

    assert tolerance.allocate is tolerance.allocation.allocate


def rvte(*args):
    return subprocess.run(
        [sys.executable, "-m", "rvfmu.cli", *map(str, args)], capture_output=True, text=True, timeout=600
    )
