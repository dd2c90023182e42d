"""Group Sobol indices from a polynomial chaos: analytic Ishigami and G-function indices,
an exact linear model, a step the check refuses, several outputs, inputs refused, a fixed seed."""

import numpy as np
import openturns as ot
import pytest
from test_tolerance_sobol import A, B, ishigami_indices

from rvfmu.core.base.checks import InputError
from tolerance import chaos_sobol
from tolerance.chaos_sobol import Q2_MIN, chaos_indices, group_shares
from tolerance.surrogate import Chaos

ISHIGAMI = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[0.0, 1.0]] * 3}


def ishigami(U):
    """Ishigami's function of unit draws U (n, 3), each input uniform on [-pi, pi]."""
    X = np.pi * (2.0 * U - 1.0)
    return np.sin(X[:, 0]) + A * np.sin(X[:, 1]) ** 2 + B * X[:, 2] ** 4 * np.sin(X[:, 0])


def g_function(U, a):
    """Sobol's G-function prod_i (|4 u_i - 2| + a_i) / (1 + a_i) of unit draws U (n, d)."""
    return np.prod((np.abs(4.0 * U - 2.0) + a) / (1.0 + a), axis=1)


def g_group_indices(a, groups):
    """Analytic group indices of the G-function.

    Each factor has mean 1 and variance V_i = 1 / (3 (1 + a_i)^2), so the
    variance of the product of the factors of a set s is prod_{i in s}(1 + V_i) - 1:
    this is the closed variance V_s^c = Var(E[y | x_s]) (the factors outside s
    average to 1).  V = prod_all(1 + V_i) - 1, and for a group g:
        S1_g = (prod_{i in g}(1 + V_i) - 1) / V,
        ST_g = (V - (prod_{i not in g}(1 + V_i) - 1)) / V      (ST_g = 1 - S1 of the rest).
    """
    V = 1.0 / (3.0 * (1.0 + a) ** 2)
    total = np.prod(1.0 + V) - 1.0
    S1 = np.array([np.prod(1.0 + V[g]) - 1.0 for g in groups]) / total
    ST = np.array([total - (np.prod(1.0 + np.delete(V, g)) - 1.0) for g in groups]) / total
    return S1, ST


def _within(estimate, truth, half_width):
    """|estimate - truth| <= half-width (plus rounding, for indices that are exactly 0)."""
    assert np.all(np.abs(estimate - truth) <= half_width + 1e-12), (estimate, truth, half_width)


def test_ishigami_analytic_indices_lie_within_the_chaos_bootstrap_intervals():
    U = np.random.default_rng(1).random((200, 3))
    (result,) = chaos_indices(U, ishigami(U), ISHIGAMI, degree=8, resamples=40, seed=1)
    S1, ST = ishigami_indices()
    assert result.names == ("x1", "x2", "x3") and result.n == 200 and result.degree == 8
    assert result.q2 > 0.999 and result.checked and "passed" in result.check_text()
    _within(result.S1, S1, result.S1_conf)
    _within(result.ST, ST, result.ST_conf)
    assert np.all(result.ST_conf < 0.02)  # and the intervals are narrow
    assert result.ST_resamples.shape == (40, 3)
    assert list(result.ranking()) == [0, 1, 2]
    assert result.order_groups() == [[1], [2], [3]]  # every order settled


def test_g_function_group_indices_lie_within_the_intervals():
    """Six inputs in three groups of two; the ranking g1 > g2 > g3 is settled."""
    a = np.array([0.0, 1.0, 4.5, 9.0, 99.0, 99.0])
    problem = {
        "num_vars": 6,
        "names": [f"x{i}" for i in range(6)],
        "bounds": [[0.0, 1.0]] * 6,
        "groups": ["g1", "g1", "g2", "g2", "g3", "g3"],
    }
    U = np.random.default_rng(2).random((300, 6))
    (result,) = chaos_indices(U, g_function(U, a), problem, degree=4, resamples=30, seed=2)
    S1, ST = g_group_indices(a, [[0, 1], [2, 3], [4, 5]])
    assert result.names == ("g1", "g2", "g3") and result.checked
    _within(result.S1, S1, result.S1_conf)
    _within(result.ST, ST, result.ST_conf)
    assert result.order_groups() == [[1], [2], [3]]


def test_the_analytic_g_function_formula_holds_for_single_inputs():
    """One input per group: the formula gives the textbook V_i / V and the product rule."""
    a = np.array([0.0, 1.0, 9.0])
    V = 1.0 / (3.0 * (1.0 + a) ** 2)
    total = np.prod(1 + V) - 1
    S1, ST = g_group_indices(a, [[0], [1], [2]])
    np.testing.assert_allclose(S1, V / total, rtol=1e-12)
    np.testing.assert_allclose(ST[0], V[0] * (1 + V[1]) * (1 + V[2]) / total, rtol=1e-12)


def test_a_linear_model_gives_its_exact_group_indices():
    """y = sum_i b_i u_i: S1 = ST = sum_{i in g} b_i^2 / sum_i b_i^2, groups not contiguous."""
    b = np.array([3.0, -1.0, 2.0, 0.5, 1.5])
    problem = {
        "num_vars": 5,
        "names": list("abcde"),
        "bounds": [[0.0, 1.0]] * 5,
        "groups": ["p", "q", "p", "r", "q"],
    }
    U = np.random.default_rng(3).random((60, 5))
    (result,) = chaos_indices(U, U @ b + 4.0, problem, degree=2, resamples=10, seed=3)
    share = np.array([b[0] ** 2 + b[2] ** 2, b[1] ** 2 + b[4] ** 2, b[3] ** 2]) / np.sum(b**2)
    np.testing.assert_allclose(result.S1, share, atol=1e-10)
    np.testing.assert_allclose(result.ST, share, atol=1e-10)
    np.testing.assert_allclose(result.ST_conf, 0.0, atol=1e-10)
    assert result.q2 > 1.0 - 1e-10 and result.checked


def test_a_step_fails_the_check_and_its_ranking_is_not_settled():
    """y = step(u0) + 0.6 u1: no polynomial of degree <= 4 follows the step (Q2 ~ 0.87).
    The bootstrap alone would settle the order; the failed check unsettles it."""
    problem = {"num_vars": 3, "names": ["s", "r", "z"], "bounds": [[0.0, 1.0]] * 3}
    U = np.random.default_rng(4).random((200, 3))
    (result,) = chaos_indices(U, (U[:, 0] > 0.5) + 0.6 * U[:, 1], problem, resamples=20, seed=4)
    assert result.degree in chaos_sobol.DEGREES
    assert result.q2 < Q2_MIN and not result.checked
    steps = result.order()
    assert all(s.difference - s.half_width > 0 for s in steps)  # what the bootstrap says
    assert not any(s.settled for s in steps)
    assert result.order_groups() == [[1, 2, 3]]
    text = result.check_text()
    assert f"Q2 {result.q2:.3f} < 0.95" in text and "FAILED" in text and "not settled" in text
    assert all(text in notes for notes in result.flags())


def test_several_outputs_at_once_share_the_resamples_and_match_single_fits():
    U = np.random.default_rng(5).random((200, 3))
    Y = np.c_[ishigami(U), 2.0 * U[:, 2] - U[:, 0], np.full(200, 3.0)]
    both = chaos_indices(U, Y, ISHIGAMI, degree=8, resamples=10, seed=5)
    assert len(both) == 3
    (alone,) = chaos_indices(U, Y[:, 1], ISHIGAMI, degree=8, resamples=10, seed=5)
    np.testing.assert_array_equal(both[1].ST, alone.ST)
    np.testing.assert_array_equal(both[1].ST_resamples, alone.ST_resamples)
    np.testing.assert_allclose(both[1].ST, [0.2, 0.0, 0.8], atol=1e-10)
    assert both[0].ST[0] > 0.5 and both[0].checked
    assert both[2].constant and both[2].order() is None


def test_a_fixed_seed_gives_the_same_intervals_and_another_seed_does_not():
    U = np.random.default_rng(6).random((120, 3))
    y = ishigami(U)
    one = chaos_indices(U, y, ISHIGAMI, degree=6, resamples=10, seed=7)[0]
    again = chaos_indices(U, y, ISHIGAMI, degree=6, resamples=10, seed=7)[0]
    other = chaos_indices(U, y, ISHIGAMI, degree=6, resamples=10, seed=8)[0]
    np.testing.assert_array_equal(one.ST_resamples, again.ST_resamples)
    np.testing.assert_array_equal(one.ST_conf, again.ST_conf)
    np.testing.assert_array_equal(one.ST, other.ST)  # the fit does not use the seed
    assert not np.array_equal(one.ST_resamples, other.ST_resamples)


def test_group_shares_agree_with_openturns_grouped_indices():
    """The numpy sums over the coefficients against FunctionalChaosSobolIndices."""
    rng = np.random.default_rng(9)
    X = 2.0 * rng.random((150, 4)) - 1.0
    y = X[:, 0] * X[:, 1] + X[:, 2] ** 2 + 0.3 * X[:, 3] + X[:, 0] * X[:, 3] ** 2
    chaos = Chaos(X, y, 3)
    groups = [[0, 3], [1], [2]]
    S1, ST, variance = group_shares(chaos.alpha, chaos.coefficients, np.array([0, 1, 2, 0]), 3)
    d = 4
    basis = ot.OrthogonalProductPolynomialFactory([ot.LegendreFactory()] * d)
    algo = ot.FunctionalChaosAlgorithm(
        ot.Sample(X),
        ot.Sample(y[:, None]),
        ot.JointDistribution([ot.Uniform(-1.0, 1.0)] * d),
        ot.FixedStrategy(basis, basis.getEnumerateFunction().getBasisSizeFromTotalDegree(3)),
        ot.LeastSquaresStrategy(
            ot.LeastSquaresMetaModelSelectionFactory(ot.LARS(), ot.CorrectedLeaveOneOut())
        ),
    )
    algo.run()
    sobol = ot.FunctionalChaosSobolIndices(algo.getResult())
    np.testing.assert_allclose(S1, [sobol.getSobolGroupedIndex(g) for g in groups], atol=1e-12)
    np.testing.assert_allclose(ST, [sobol.getSobolGroupedTotalIndex(g) for g in groups], atol=1e-12)
    assert S1.sum() <= 1.0 + 1e-12 and np.all(S1 <= ST + 1e-15)


def test_one_group_is_the_whole_input():
    problem = {"num_vars": 2, "names": ["a", "b"], "bounds": [[0.0, 1.0]] * 2, "groups": ["t", "t"]}
    U = np.random.default_rng(10).random((20, 2))
    (result,) = chaos_indices(U, U[:, 0], problem, resamples=10)
    assert result.whole_input and result.S1[0] == 1.0 and result.ST[0] == 1.0
    assert result.checked and "whole input" in result.check_text()


@pytest.mark.parametrize(
    "change, field, value, allowed",
    [
        ({"X": np.full((30, 3), 1.0)}, "X", 1.0, "unit draws must lie in [0, 1)"),
        ({"X": np.full((30, 3), np.nan)}, "X", None, "must be finite"),
        ({"Y": np.zeros(29)}, "Y", (29,), "must be shaped 30 or 30 x M"),
        ({"X": np.full((4, 3), 0.5), "Y": np.zeros(4)}, "rows of X", 4, "must be >= 5 for 3 columns"),
        ({"resamples": 5}, "resamples", 5, "must be 0 (no intervals) or >= 10"),
        ({"confidence": 1.0}, "confidence", 1.0, "must be in (0, 1)"),
        ({"degree": 0}, "degree", 0, "must be from 1 to 20"),
        ({"q2_min": 1.5}, "q2_min", 1.5, "must be in (0, 1]"),
        ({"problem": {**ISHIGAMI, "num_vars": 4}}, "problem num_vars", 4, "must equal the 3 columns"),
    ],
)
def test_bad_inputs_are_refused_naming_field_value_and_what_is_allowed(change, field, value, allowed):
    args = {"X": np.full((30, 3), 0.5), "Y": np.zeros(30), "problem": ISHIGAMI}
    args.update(change)
    X, Y, problem = args.pop("X"), args.pop("Y"), args.pop("problem")
    with pytest.raises(InputError) as error:
        chaos_indices(X, Y, problem, **args)
    message = str(error.value)
    assert error.value.field == field and message.startswith(f"chaos Sobol: {field} = ")
    assert allowed in message
    if value is not None:
        assert error.value.value == value


def test_a_degree_whose_basis_is_too_large_is_refused_before_fitting():
    """100 columns (a 15-tolerance study with phases and tooth patterns): degree 3 has
    176 851 candidate terms; degree None keeps to degree 2 (5 151)."""
    problem = {"num_vars": 100, "names": [f"c{i}" for i in range(100)], "bounds": [[0.0, 1.0]] * 100}
    U = np.full((200, 100), 0.5)
    with pytest.raises(
        InputError,
        match=r"degree = 3: gives 176851 candidate terms over 100 "
        r"columns, more than 6000",
    ):
        chaos_indices(U, np.zeros(200), problem, degree=3)
