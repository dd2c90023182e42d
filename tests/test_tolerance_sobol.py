"""The Sobol harness: Ishigami's analytic indices, Saltelli slicing, negative estimates, a toy ranking."""

import importlib
import json
from pathlib import Path

import numpy as np
import pytest
from tolerance_toy import write_study

from rvfmu.cli import main
from tolerance import run_sobol, sobol
from tolerance.summaries import order_text

ISHIGAMI = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[-np.pi, np.pi]] * 3}
A, B = 7.0, 0.1


def ishigami(X):
    return np.sin(X[:, 0]) + A * np.sin(X[:, 1]) ** 2 + B * X[:, 2] ** 4 * np.sin(X[:, 0])


def ishigami_indices():
    """Analytic S1 and ST of the Ishigami function (Ishigami & Homma 1990; Sobol' 1999)."""
    v1 = 0.5 * (1 + B * np.pi**4 / 5) ** 2
    v2 = A**2 / 8
    v13 = B**2 * np.pi**8 * (1 / 18 - 1 / 50)
    total = v1 + v2 + v13
    return np.array([v1, v2, 0.0]) / total, np.array([v1 + v13, v2, v13]) / total


@pytest.fixture(scope="module")
def ishigami_run():
    n = 2048
    X = sobol.sample(ISHIGAMI, n, second_order=False, seed=3)
    y = ishigami(X)
    return n, X, y, sobol.analyze(ISHIGAMI, y[:, None], ["y"], resamples=300, seed=3)["y"]


@pytest.mark.parametrize(
    "problem",
    [
        ISHIGAMI,
        {
            "num_vars": 6,
            "names": [f"x{k}" for k in range(6)],
            "bounds": [[0.0, 1.0]] * 4 + [[-2.0, 3.0]] * 2,
            "groups": ["b", "a", "b", "c", "a", "a"],
        },
    ],
    ids=["variables", "groups"],
)
@pytest.mark.parametrize("second_order", [False, True])
def test_the_saltelli_design_is_salibs_to_the_bit(problem, second_order):
    """`sobol.sample` builds SALib's design (`SALib.sample.sobol.sample`, the reference) with
    whole-array copies: the same matrix, to the bit, with groups out of order and without."""
    import warnings

    from SALib.sample import sobol as salib_sample

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        reference = salib_sample.sample(problem, 32, calc_second_order=second_order, scramble=True, seed=7)
    np.testing.assert_array_equal(sobol.sample(problem, 32, second_order, seed=7), reference)


def test_one_group_is_crossed_whole():
    """SALib drops a single group and crosses its variables one by one; the grouped design
    crosses the group whole: per base sample A, A_B = B, B."""
    one = dict(ISHIGAMI, groups=["g"] * 3)
    X = sobol.sample(one, 8, False, seed=2).reshape(8, 3, 3)
    np.testing.assert_array_equal(X[:, 1], X[:, 2])
    assert not np.any(X[:, 0] == X[:, 2])


def test_ishigami_analytic_indices_lie_within_the_bootstrap_intervals(ishigami_run):
    n, X, y, result = ishigami_run
    S1, ST = ishigami_indices()
    ind = result.indices
    assert ind.n == n and ind.names == ("x1", "x2", "x3")
    np.testing.assert_array_less(np.abs(ind.S1 - S1), ind.S1_conf)
    np.testing.assert_array_less(np.abs(ind.ST - ST), ind.ST_conf)
    assert list(ind.ranking()) == [0, 1, 2]
    assert result.convergence.n == (n // 4, n // 2, n) and result.convergence.converged


def test_negative_estimates_are_reported_as_zero_and_flagged():
    values = np.array([-0.02, -0.30, 0.50, 1.04])
    conf = np.array([0.05, 0.10, 0.02, 0.20])
    ind = sobol.Indices(("a", "b", "c", "d"), 64, values, conf, np.abs(values), conf, None, None, 0.95)
    np.testing.assert_array_equal(ind.S1_reported, [0.0, 0.0, 0.5, 1.0])
    flags = ind.flags()
    assert flags[0] == ["S1 -0.020 < 0 within its CI: reported as 0"]
    assert flags[1][0] == "S1 -0.300 < 0 beyond its CI: not converged, raise n"
    assert flags[2] == []
    assert "S1 1.040 > 1: reported as 1" in flags[3] and "S1 CI wide (+-0.20)" in flags[3]


def test_convergence_slices_whole_base_samples(ishigami_run):
    """The first n/4 base samples of the Saltelli matrix are the matrix of n/4 (same scrambling)."""
    n, X, y, result = ishigami_run
    per = sobol.rows_per_base_sample(ISHIGAMI, second_order=False)
    assert per == 5 and X.shape == (n * per, 3)
    quarter = sobol.sample(ISHIGAMI, n // 4, second_order=False, seed=3)
    np.testing.assert_array_equal(quarter, X[: n // 4 * per])
    alone = sobol.indices(ISHIGAMI, ishigami(quarter), resamples=300, seed=3)
    np.testing.assert_allclose(result.convergence.ST[0], alone.ST, rtol=1e-12)


def test_second_order_indices_of_ishigami():
    n = 1024
    X = sobol.sample(ISHIGAMI, n, second_order=True, seed=5)
    assert X.shape == (n * 8, 3)
    ind = sobol.indices(ISHIGAMI, ishigami(X), second_order=True, resamples=200, seed=5)
    S1, ST = ishigami_indices()
    s13 = ST[2]  # x3 acts only with x1
    assert abs(ind.S2[0, 2] - s13) < ind.S2_conf[0, 2]
    assert abs(ind.S2[0, 1]) < ind.S2_conf[0, 1]


def test_a_constant_output_gives_zero_indices_not_nan():
    X = sobol.sample(ISHIGAMI, 16, seed=1)
    ind = sobol.indices(ISHIGAMI, np.ones(X.shape[0]))
    assert ind.constant and not ind.ST.any()
    assert ind.order() is None and ind.order_groups() is None


LINEAR = {"num_vars": 4, "names": ["a", "b", "c", "d"], "bounds": [[0.0, 1.0]] * 4}
SLOPES = np.array([4.0, 2.0, 2.0, 1.0])


def test_the_order_of_neighbouring_ranks_is_settled_where_their_st_differ():
    # y = sum(k_i x_i), x_i uniform and independent: ST_i = k_i^2 / sum(k^2) = 0.64, 0.16,
    # 0.16, 0.04.  b and c explain the same share: their order is not settled, whatever n.
    X = sobol.sample(LINEAR, 1024, seed=2)
    ind = sobol.indices(LINEAR, X @ SLOPES, resamples=300, seed=2)
    np.testing.assert_allclose(ind.ST, SLOPES**2 / np.sum(SLOPES**2), atol=0.01)
    ranked = [ind.names[g] for g in ind.ranking()]
    assert ranked[0] == "a" and set(ranked[1:3]) == {"b", "c"} and ranked[3] == "d"
    steps = ind.order()
    assert [(s.upper, s.lower) for s in steps] == list(zip(ind.ranking()[:-1], ind.ranking()[1:]))
    assert [s.settled for s in steps] == [True, False, True]
    assert ind.order_groups() == [[1], [2, 3], [4]]
    assert order_text(ind.order_groups()) == "1 | 2-3 | 4"
    tie = steps[1]
    assert abs(tie.difference) < tie.half_width and 0.3 < tie.kept < 0.7
    assert steps[0].kept == 1.0 and steps[2].kept == 1.0
    # the order is judged by the difference's own interval, narrower than the two intervals
    # together: the estimates move together
    for s in steps:
        assert s.half_width < ind.ST_conf[s.upper] + ind.ST_conf[s.lower]


def test_the_interval_of_an_st_difference_is_that_of_the_same_resamples(ishigami_run):
    # Jansen's ST on the standardised output, by hand, over the base samples SALib's bootstrap
    # draws (SALib 1.6: default_rng(seed).integers(n, size=(n, resamples)), seed = ours + 1):
    # each difference over the same resampled rows gives the interval, to round-off (an
    # interval from the two spreads alone, as if the estimates were independent, differs by
    # 0.7 % and 7 % here).
    n, X, y, result = ishigami_run
    ind = result.indices
    Y = ((y - y.mean()) / y.std()).reshape(n, 5)
    A, AB, B = Y[:, 0], Y[:, 1:4], Y[:, 4]
    rows = np.random.default_rng(3 + 1).integers(n, size=(n, 300))
    boots = np.stack(
        [
            0.5 * np.mean((A[rows] - AB[rows, g]) ** 2, axis=0) / np.var(np.r_[A[rows], B[rows]], axis=0)
            for g in range(3)
        ],
        axis=1,
    )
    np.testing.assert_allclose(boots, ind.ST_resamples, rtol=1e-10)
    steps = ind.order()
    assert [(s.upper, s.lower) for s in steps] == [(0, 1), (1, 2)]
    for s in steps:
        spread = boots[:, s.upper] - boots[:, s.lower]
        assert s.difference == pytest.approx(ind.ST[s.upper] - ind.ST[s.lower], rel=1e-14)
        assert s.half_width == pytest.approx(1.959964 * spread.std(ddof=1), rel=1e-6)
        assert s.kept == np.mean(spread > 0)
    assert ind.order_groups() == [[1], [2], [3]]


def test_indices_without_resamples_say_nothing_of_the_order():
    ind = sobol.Indices(
        ("a", "b"),
        64,
        np.array([0.5, 0.2]),
        np.full(2, 0.05),
        np.array([0.6, 0.3]),
        np.full(2, 0.05),
        None,
        None,
        0.95,
    )
    assert ind.order() is None and ind.order_groups() is None


@pytest.fixture(scope="module")
def toy_sobol(tmp_path_factory):
    """A toy reducer with one obviously dominant tolerance: a 20 um cam zone against sub-um ones."""
    folder = tmp_path_factory.mktemp("sobol")
    path = write_study(
        folder,
        tolerances={
            "pin_radial": {"band_um": 0.2},
            "crank_cam_eccentricity": {"position_um": 20.0},
            "disc_profile": {"band_um": 0.2, "group": "disc"},
            "disc_pitch": {"cumulative_um": 0.2, "group": "disc"},
        },
        sobol={"n": 32},
    )
    return path, run_sobol(path)


def test_toy_reducer_ranks_the_dominant_tolerance_first(toy_sobol):
    path, result = toy_sobol
    assert result.study.groups == ("pin_radial", "crank_cam_eccentricity", "disc")
    assert result.X.shape == (32 * 5, len(result.study.columns))
    for column in ("te_pp_arcsec", "rms_arcsec"):
        ind = result.analyses[column].indices
        first = ind.names[ind.ranking()[0]]
        assert first == "crank_cam_eccentricity"
        assert ind.ST_reported[1] > 0.8
    out = result.study.output
    for name in ("sobol_indices.json", "sobol_ranking.txt", "sobol_bars.png", "sobol_convergence.png"):
        assert (out / name).is_file()
    text = (out / "sobol_ranking.txt").read_text()
    assert "crank_cam_eccentricity" in text.split("\n")[5]
    for column in ("te_pp_arcsec", "rms_arcsec"):
        groups = result.analyses[column].indices.order_groups()
        assert groups[0] == [1]  # the dominant tolerance is told apart
        assert f"  order: {order_text(groups)}  (ranks joined by '-'" in text


def test_sobol_cli_json_is_machine_readable(toy_sobol, capsys):
    path, result = toy_sobol
    assert main(["sobol", str(path), "--json", "--no-plots"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert "sobol-n32: 160 reducers in 20 batches of 8 (20 reused, 0 computed)" in captured.err
    ranking = data["metrics"]["te_pp_arcsec"]["groups"]
    assert ranking[0]["name"] == "crank_cam_eccentricity" and ranking[0]["rank"] == 1
    assert set(ranking[0]) >= {"S1", "S1_conf", "ST", "ST_conf", "S1_reported", "ST_reported", "notes"}
    assert ranking[0]["next"]["factor"] == ranking[1]["name"] and ranking[0]["next"]["settled"]
    assert ranking[0]["next"]["difference"] > ranking[0]["next"]["half_width"] > 0
    assert ranking[-1]["next"] is None
    assert data["metrics"]["te_pp_arcsec"]["order_groups"][0] == [1]
    assert data["n"] == 32 and data["evaluations"] == 160
    assert data["metrics"]["te_pp_arcsec"]["convergence"]["n"] == [8, 16, 32]
    assert Path(data["output"]) == result.study.output


def test_raising_n_reuses_the_smaller_run_and_matches_a_fresh_run(toy_sobol, tmp_path, capsys):
    """n = 64 after n = 32: the first 160 reducers are copied, not recomputed, and every
    row equals that of a run at n = 64 in an empty folder."""
    path, small = toy_sobol
    assert main(["sobol", str(path), "-n", "64", "--json", "--no-plots"]) == 0
    err = capsys.readouterr().err
    assert "sobol-n64: 320 reducers in 40 batches of 8 (20 reused, 20 computed)" in err
    raised = run_sobol(path, n=64, plots=False)
    fresh = run_sobol(path, n=64, output=tmp_path / "fresh", plots=False)
    assert fresh.computed.computed == 40
    np.testing.assert_array_equal(raised.Y, fresh.Y)
    np.testing.assert_array_equal(raised.Y[:160], small.Y)


def test_batches_that_fail_the_store_checks_are_not_reused(toy_sobol, tmp_path):
    """A smaller run's folder holding files of another job is refused by the store's checks:
    the larger run computes those rows itself, and gets the same numbers."""
    path, small = toy_sobol
    out = tmp_path / "other"
    run_sobol(path, n=16, output=out, plots=False)
    (out / "sobol-n16").rename(out / "sobol-n8")  # files that say job sobol-n16, in sobol-n8
    result = run_sobol(path, n=32, output=out, plots=False)
    assert result.computed.computed == 20
    np.testing.assert_array_equal(result.Y, small.Y)


def test_lowering_n_reuses_the_first_rows_of_a_larger_run(toy_sobol, tmp_path):
    path, small = toy_sobol
    out = tmp_path / "down"
    run_sobol(path, n=32, output=out, plots=False)
    lower = run_sobol(path, n=16, output=out, plots=False)
    assert lower.computed.computed == 0 and lower.computed.reused == 10
    np.testing.assert_array_equal(lower.Y, small.Y[:80])


def test_saltelli_rows_start_from_their_base_sample_and_monte_carlo_rows_from_none():
    """`evaluate.related_rows`: each row A_B^(i) of Saltelli's design shares all but group i's
    columns with its A, the row before it that it starts from; A and B start from none, nor
    does any row of a Monte Carlo sample (independent rows share no column).  A batch that
    begins inside a base sample starts its A_B^(i) rows from the first of them."""
    from tolerance.evaluate import related_rows

    problem = {
        "num_vars": 8,
        "names": [f"x{i}" for i in range(8)],
        "groups": ["a", "a", "b", "b", "c", "c", "d", "d"],
        "bounds": [[0.0, 1.0]] * 8,
    }
    X = sobol.sample(problem, 8, False, seed=3)
    per = sobol.rows_per_base_sample(problem, False)  # A, four A_B^(i), B
    related = related_rows(X)
    for k in range(0, X.shape[0], per):
        np.testing.assert_array_equal(related[k : k + per], [-1, k, k, k, k, -1])
    # without its A: the rows A_B^(3) and A_B^(4) share half their columns with A_B^(2)
    np.testing.assert_array_equal(related_rows(X[2:per]), [-1, 0, 0, -1])
    assert related_rows(np.random.default_rng(1).random((16, 8))) is None


def test_a_saltelli_batch_gives_the_metrics_of_its_rows_solved_from_their_own_starts(monkeypatch):
    """`evaluate` on one base sample of the Sobol study's design (no load, the roller law):
    its rows A_B^(i) solved from A's solutions give the metrics of the same rows solved each
    from its kinematic pose (the relation switched off), within 1e-7 arcsec."""
    evaluate_module = importlib.import_module(
        "tolerance.evaluate"
    )  # the package's `evaluate` is the function
    from tolerance.study import load_study

    study = load_study(Path(__file__).resolve().parents[1] / "studies" / "rv40e_121_sobol.toml")
    X = sobol.sample(study.problem(), 8, False, seed=study.seed)[:10]
    assert evaluate_module.related_rows(X) is not None
    Y, converged = evaluate_module.evaluate(study, X)
    monkeypatch.setattr(evaluate_module, "RELATED_SHARE", 2.0)  # no row shares twice its columns
    assert evaluate_module.related_rows(X) is None
    Y_own, converged_own = evaluate_module.evaluate(study, X)
    assert converged.all() and converged_own.all()
    np.testing.assert_allclose(Y, Y_own, rtol=0, atol=1e-7)
    assert np.all(Y[:, 0] > 1.0)  # te_pp: curves of some arcsec, not a trivial agreement
