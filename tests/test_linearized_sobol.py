"""The linearized Sobol method (tolerance/linearized.py): its error vectors, its central
differences against independent solves, exactness on a model that is linear, its check
failing where the TE is not linear (no load, a step), the comparison with Saltelli on a
small loaded study, and resuming its solves after an interruption on every backend."""

import importlib
import json

import numpy as np
import pytest
from test_hardening import run_cli
from tolerance_toy import write_study

from rvfmu.core.base.checks import InputError
from rvfmu.core.statics.quasistatic import te_curve
from tolerance import linearized, sobol
from tolerance.error_rows import clearance_components, error_set, error_vector
from tolerance.evaluate import Outputs
from tolerance.montecarlo import rows
from tolerance.sampling import errors_from_unit
from tolerance.sobol_runs import run_sobol
from tolerance.study import load_study

evaluate_module = importlib.import_module("tolerance.evaluate")
RATED = 412.0
TOLERANCES = {
    "crank_cam_eccentricity": {"position_um": 9.0},
    "disc_crank_hole": {"position_um": 7.0},
    "disc_profile": {"band_um": 8.0},
    "pin_pitch": {"cumulative_um": 8.0, "single_um": 2.5},
    "crank_disc_clearance": {"min_um": 2.0, "max_um": 28.0},
}


def loaded_study(
    folder, name="rated", load=RATED, n=256, solved_n=32, metrics=("te_pp", "rms"), tolerances=None
):
    return write_study(
        folder,
        name=name,
        tolerances=tolerances or TOLERANCES,
        study={"metrics": list(metrics), "batch_size": 32},
        operating={"points": 64, "load_Nm": load},
        sobol={"n": n, "resamples": 100, "solved_n": solved_n},
    )


def test_error_vectors_carry_every_component_and_come_back_unchanged(tmp_path):
    study = load_study(loaded_study(tmp_path))
    errors = errors_from_unit(study, rows(study, 0, 5))
    vectors = error_vector(errors)
    back = error_set(vectors, errors.take([0]))
    for name, array in errors.arrays().items():
        np.testing.assert_array_equal(getattr(back, name), array)
    sizes = sum(a[0].size * (2 if np.iscomplexobj(a) else 1) for a in errors.arrays().values())
    assert vectors.shape == (5, sizes)
    marks = clearance_components(errors.take([0]))
    assert marks.sum() == sum(
        errors.arrays()[k][0].size
        for k in ("crank_disc_clearance", "crank_carrier_clearance", "main_bearing_clearance")
    )
    assert np.all(vectors[:, marks] >= 0.0)


def test_each_slope_is_the_central_difference_of_two_independent_solves(tmp_path):
    study = load_study(loaded_study(tmp_path))
    lin = linearized.linearize(study)
    points, active, steps, like = linearized.difference_points(study)
    assert lin.solves == 2 * active.size + 1 == points.shape[0]

    def curve(v):
        return te_curve(study.design, error_set(v, like), tau_load=-RATED, points=study.points).te_arcsec[0]

    np.testing.assert_allclose(lin.te0, curve(points[0]), rtol=0, atol=1e-9)
    marks = clearance_components(like)[active]
    for j in (0, int(np.flatnonzero(marks)[0]), active.size - 1):
        up, down = points[0].copy(), points[0].copy()
        up[active[j]] += steps[j, 0]
        down[active[j]] -= steps[j, 1]
        slope = (curve(up) - curve(down)) / (steps[j, 0] + steps[j, 1])
        np.testing.assert_allclose(lin.te_slope[j], slope, rtol=1e-9, atol=1e-3)
    # the steps are the spreads of the draws, a clearance's step down stops at zero
    assert np.all(steps > 0.0) and np.all((points[0][active] - steps[:, 1])[marks] >= 0.0)


def linear_outputs(weights):
    """A reducer model that is linear in the error vector: the TE curve = weights . e."""

    def outputs(study, errors, related=None):
        te = error_vector(errors) @ weights
        return Outputs(te, {}, np.ones(errors.samples, dtype=bool))

    return outputs


def test_a_linear_model_gives_saltellis_indices_exactly(tmp_path, monkeypatch):
    path = loaded_study(tmp_path, n=128, solved_n=16)
    study = load_study(path)
    like = errors_from_unit(study, rows(study, 0, 1))
    weights = np.random.default_rng(3).normal(size=(error_vector(like).shape[1], study.points)) * 1e5
    monkeypatch.setattr(evaluate_module, "outputs", linear_outputs(weights))
    lin = run_sobol(path, method="linearized", plots=False)
    ref = run_sobol(path, method="saltelli", plots=False)
    assert lin.check.q2 == pytest.approx(1.0, abs=1e-12)
    for column in ref.analyses:
        a, b = lin.analyses[column].indices, ref.analyses[column].indices
        assert lin.analyses[column].method == "linearized"
        np.testing.assert_allclose(a.ST, b.ST, atol=1e-9)
        np.testing.assert_allclose(a.S1, b.S1, atol=1e-9)
        # the correction of a perfect linearization is zero: the intervals are those of n
        np.testing.assert_allclose(a.ST_conf, b.ST_conf, rtol=1e-6)
        assert a.order_groups() == b.order_groups()


def test_a_discontinuous_output_fails_the_check_and_falls_back_to_saltelli(tmp_path, monkeypatch):
    path = loaded_study(tmp_path, n=64, solved_n=16)
    study = load_study(path)
    draws = error_vector(errors_from_unit(study, rows(study, 0, 4096)))
    column = int(np.argmax(draws.std(axis=0)))
    centre = draws[:, column].mean()

    def outputs(study, errors, related=None):
        step = (error_vector(errors)[:, column] > centre).astype(float)
        te = step[:, None] * np.sin(np.linspace(0, 6.28, study.points))[None] * 10.0
        return Outputs(te, {}, np.ones(errors.samples, dtype=bool))

    monkeypatch.setattr(evaluate_module, "outputs", outputs)
    result = run_sobol(path, method="linearized", plots=False)
    assert np.all(result.check.q2 < linearized.Q2_MIN)
    for analysis in result.analyses.values():
        assert analysis.method == "saltelli"
        assert analysis.check_q2 < linearized.Q2_MIN
    assert result.Y.shape[0] == 64 * sobol.rows_per_base_sample(study.problem())
    table = result.table()
    assert "te_pp_arcsec: Q2 = " in table and "FAILED" in table and "passed" not in table
    frame = result.to_df()
    assert set(frame["method"]) == {"saltelli"} and np.all(frame["check_q2"] < 0.95)


def test_at_no_load_the_check_fails_and_the_ranking_is_saltellis(tmp_path):
    path = loaded_study(tmp_path, name="noload", load=0.0, n=32, solved_n=16)
    said = []
    result = run_sobol(path, method="linearized", plots=False, log=said.append)
    assert said[0].startswith("warning: method linearized at no load")
    reference = run_sobol(path, method="saltelli", plots=False)
    assert not np.any(result.check.passed())
    for column, analysis in result.analyses.items():
        assert analysis.method == "saltelli"
        np.testing.assert_array_equal(analysis.indices.ST, reference.analyses[column].indices.ST)


def test_on_a_loaded_study_the_order_groups_are_saltellis(tmp_path):
    path = loaded_study(tmp_path, n=512, solved_n=32)
    lin = run_sobol(path, method="linearized", plots=False)
    ref = run_sobol(path, method="saltelli", plots=False)
    assert np.all(lin.check.passed())
    solved = lin.check.solves + 32 * sobol.rows_per_base_sample(load_study(path).problem())
    assert solved < ref.Y.shape[0] / 4
    for column in ("te_pp_arcsec", "rms_arcsec"):
        a, b = lin.analyses[column].indices, ref.analyses[column].indices
        assert lin.analyses[column].method == "linearized"
        # every ST within the reference's interval widened by its own
        assert np.all(np.abs(a.ST - b.ST) <= a.ST_conf + b.ST_conf)
        # the ranking's settled runs: the linearized method never claims an order the
        # reference does not settle, and the top rank is the same
        assert list(np.array(a.names)[a.ranking()][:2]) == list(np.array(b.names)[b.ranking()][:2])
        groups_a, groups_b = a.order_groups(), b.order_groups()
        for group in groups_b:
            assert any(set(group) <= set(g) for g in groups_a)


def interrupting(after):
    calls = {"n": 0}
    real = evaluate_module.outputs

    def outputs(study, errors, related=None):
        calls["n"] += 1
        if calls["n"] > after:
            raise KeyboardInterrupt
        return real(study, errors, related)

    return outputs


def test_interrupted_linearization_resumes_with_the_same_indices(tmp_path, monkeypatch):
    path = loaded_study(tmp_path, n=64, solved_n=16)
    clean = run_sobol(path, method="linearized", plots=False, output=tmp_path / "clean")
    monkeypatch.setattr(evaluate_module, "outputs", interrupting(2))
    with pytest.raises(KeyboardInterrupt):
        run_sobol(path, method="linearized", plots=False, output=tmp_path / "cut")
    monkeypatch.undo()
    study = load_study(path, tmp_path / "cut")
    kept = len(list((tmp_path / "cut" / linearized.JOB).glob("batch-*.parquet")))
    assert kept == 2
    resumed = run_sobol(path, method="linearized", plots=False, output=tmp_path / "cut")
    for column in clean.analyses:
        np.testing.assert_array_equal(resumed.analyses[column].indices.ST, clean.analyses[column].indices.ST)
    assert study.sobol_method == "saltelli"  # the file's default: the method came from the call


@pytest.mark.parametrize("backend", [{"processes": 2}, {"workers": 2}], ids=["processes", "dask"])
def test_the_linearization_resumes_on_other_backends_with_the_same_indices(tmp_path, backend):
    path = loaded_study(tmp_path, n=64, solved_n=16)
    here = run_sobol(path, method="linearized", plots=False, output=tmp_path / "here")
    # half the difference batches stored by this process, the rest on the backend
    study = load_study(path, tmp_path / "there")
    points = linearized.difference_points(study)[0]
    from tolerance.run import compute

    te_columns = evaluate_module.output_columns(study)[0]
    like = errors_from_unit(study, rows(study, 0, 1))
    compute(
        study, linearized.JOB, points.shape[0] // 2, lambda s, e: points[s:e], columns=te_columns, like=like
    )
    there = run_sobol(path, method="linearized", plots=False, output=tmp_path / "there", **backend)
    for column in here.analyses:
        np.testing.assert_array_equal(there.analyses[column].indices.ST, here.analyses[column].indices.ST)


def test_a_method_the_study_or_the_command_does_not_know_is_refused(tmp_path, capsys):
    path = loaded_study(tmp_path)
    text = path.read_text().replace("[sobol]\n", '[sobol]\nmethod = "kriging"\n')
    path.write_text(text)
    with pytest.raises(InputError, match=r"sobol\.method.*kriging.*saltelli.*linearized"):
        load_study(path)
    path = loaded_study(tmp_path)
    code, out, err = run_cli(["sobol", path, "--method", "fast", "-o", tmp_path / "cli"], capsys)
    assert code == 2 and "method" in err and "fast" in err and "linearized" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "cli" / linearized.JOB).exists()
    with pytest.raises(InputError, match="solved_n"):
        run_sobol(path, method="linearized", solved_n=48, plots=False)


def test_the_json_and_the_frame_say_the_method_and_its_check(tmp_path):
    path = loaded_study(tmp_path, n=64, solved_n=16)
    result = run_sobol(path, method="linearized", plots=False)
    document = json.loads(json.dumps(result.to_json()))
    assert document["method"] == "linearized"
    assert set(document["linearized_check"]["q2"]) == {"te_pp_arcsec", "rms_arcsec"}
    metric = document["metrics"]["te_pp_arcsec"]
    assert metric["method"] == "linearized" and metric["check_q2"] >= linearized.Q2_MIN
    frame = result.to_df()
    assert set(frame["method"]) == {"linearized"}
    assert np.all(frame["check_q2"] >= linearized.Q2_MIN)


# -- the corrected estimator on functions with known indices -------------------------------


def ishigami(X, a=7.0, b=0.1):
    return np.sin(X[:, 0]) + a * np.sin(X[:, 1]) ** 2 + b * X[:, 2] ** 4 * np.sin(X[:, 0])


def test_the_corrected_estimator_finds_ishigamis_indices_from_a_cruder_function():
    a, b = 7.0, 0.1
    problem = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[-np.pi, np.pi]] * 3}
    variance = a**2 / 8 + b * np.pi**4 / 5 + b**2 * np.pi**8 / 18 + 0.5
    first = np.array([0.5 * (1 + b * np.pi**4 / 5) ** 2, a**2 / 8, 0.0]) / variance
    total = first + np.array([8 * b**2 * np.pi**8 / 225, 0.0, 8 * b**2 * np.pi**8 / 225]) / variance
    X = sobol.sample(problem, 4096, seed=11)
    m = 256 * sobol.rows_per_base_sample(problem)
    crude = ishigami(X, 6.0, 0.08)  # the "linearization": other coefficients
    result = linearized.corrected_indices(problem, crude, ishigami(X[:m]), resamples=300, seed=5)
    assert np.all(np.abs(result.ST - total) <= result.ST_conf)
    assert np.all(np.abs(result.S1 - first) <= result.S1_conf)
    # the correction is what makes it right: the crude function alone is off beyond its CI
    alone = sobol.indices(problem, crude, resamples=300, seed=5)
    assert np.any(np.abs(alone.ST - total) > alone.ST_conf)
    # and its intervals are narrower than those of the 256 solved base samples alone
    solved_only = sobol.indices(problem, ishigami(X[:m]), resamples=300, seed=5)
    assert np.all(result.ST_conf[:2] < solved_only.ST_conf[:2])


def g_function(X, a):
    return np.prod((np.abs(4 * X - 2) + a) / (1 + a), axis=1)


def test_the_corrected_estimator_finds_the_grouped_g_functions_indices():
    a = np.array([0.0, 1.0, 4.5, 9.0, 99.0, 99.0])
    groups = ["g1", "g1", "g2", "g2", "g3", "g3"]
    problem = {"num_vars": 6, "names": [f"x{i}" for i in range(6)], "bounds": [[0, 1]] * 6, "groups": groups}
    partial = (1 / 3) / (1 + a) ** 2
    variance = np.prod(1 + partial) - 1
    first, total = [], []
    for name in ("g1", "g2", "g3"):
        inside = np.array([g == name for g in groups])
        first.append((np.prod(1 + partial[inside]) - 1) / variance)
        total.append(1 - (np.prod(1 + partial[~inside]) - 1) / variance)
    X = sobol.sample(problem, 4096, seed=3)
    m = 256 * sobol.rows_per_base_sample(problem)
    crude = g_function(X, a + 0.3)
    result = linearized.corrected_indices(problem, crude, g_function(X[:m], a), resamples=300, seed=2)
    assert np.all(np.abs(result.ST - np.array(total)) <= result.ST_conf)
    assert np.all(np.abs(result.S1 - np.array(first)) <= result.S1_conf)
