"""Sobol runs that stop themselves (`rvte sobol --rounds`, [sobol] rounds): base samples
doubled from ROUND_START until the order groups hold over two doublings, within the budget
n, every round reusing the reducers of the last, the result that of a plain run at the size
it stopped at."""

import numpy as np
import pytest
from test_hardening import run_cli
from tolerance_toy import write_study

from tolerance import sobol_runs
from tolerance.sobol_runs import run_sobol
from tolerance.study import load_study

TOLERANCES = {
    "crank_cam_eccentricity": {"position_um": 9.0},
    "disc_crank_hole": {"position_um": 7.0},
    "pin_pitch": {"cumulative_um": 8.0, "single_um": 2.5},
}


def study_file(folder, n=512, load=412.0, rounds=None, solved_n=64):
    sobol = {"n": n, "resamples": 100, "solved_n": solved_n}
    if rounds is not None:
        sobol["rounds"] = rounds
    return write_study(
        folder,
        tolerances=TOLERANCES,
        sobol=sobol,
        operating={"points": 48, "load_Nm": load},
        study={"batch_size": 64},
    )


def test_rounds_double_until_the_order_groups_hold_and_equal_a_plain_run(tmp_path):
    path = study_file(tmp_path)
    result = run_sobol(path, rounds=True, plots=False, output=tmp_path / "rounds")
    sizes = [r.size for r in result.rounds]
    assert sizes[0] == sobol_runs.ROUND_START
    assert sizes == [sobol_runs.ROUND_START * 2**k for k in range(len(sizes))]
    assert sizes[-1] <= 512
    last = result.rounds[-1]
    if last.settled:
        same = [r.order_groups for r in result.rounds[-sobol_runs.SETTLED_ROUNDS :]]
        assert all(groups == same[0] for groups in same)
        assert not any(r.settled for r in result.rounds[:-1])
    else:
        assert last.size == 512  # the budget ends a run that never settled
    assert result.n == last.size
    # the rounds share their reducers: what was solved is the last round's design
    rows = result.study.problem()["num_vars"]
    assert last.solved == result.Y.shape[0] and result.X.shape[1] == rows
    plain = run_sobol(path, last.size, plots=False, output=tmp_path / "plain")
    for column, analysis in plain.analyses.items():
        np.testing.assert_array_equal(result.analyses[column].indices.ST, analysis.indices.ST)
    table = result.table()
    assert f"round of {sobol_runs.ROUND_START} base samples" in table
    document = result.to_json()
    assert [r["size"] for r in document["rounds"]] == sizes


def test_a_budget_below_the_first_round_is_one_round_and_the_file_can_ask_for_rounds(tmp_path):
    path = study_file(tmp_path, n=32, rounds=True)
    assert load_study(path).sobol_rounds is True
    result = run_sobol(path, plots=False)
    assert [r.size for r in result.rounds] == [32] and result.n == 32


def test_rounds_of_the_linearized_method_double_its_solved_base_samples(tmp_path):
    path = study_file(tmp_path, n=512, solved_n=256)
    result = run_sobol(path, method="linearized", rounds=True, plots=False)
    assert result.n == 512
    assert [r.size for r in result.rounds][0] == sobol_runs.ROUND_START
    assert result.rounds[-1].size <= 256
    assert all(a.method == "linearized" for a in result.analyses.values())
    assert result.check.rows == 2 * result.rounds[-1].size


def test_a_bad_rounds_value_is_refused(tmp_path, capsys):
    path = study_file(tmp_path)
    path.write_text(path.read_text().replace("[sobol]\n", '[sobol]\nrounds = "yes"\n'))
    code, out, err = run_cli(["sobol", path], capsys)
    assert code == 2 and "sobol.rounds" in err and "yes" in err
    with pytest.raises(Exception, match="rounds"):
        run_sobol(study_file(tmp_path / "b"), rounds="often", plots=False)
