"""The tolerance studies where they broke: a Sobol study of one group, Ctrl-C in a run, files
that are not UTF-8, a Dask address that is none, text where a bool belongs, and a calibration
data file that names nothing to fit."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import psutil
import pytest
from test_hardening import run_cli
from tolerance_toy import write_study

import tolerance
from rvfmu.core.base.checks import InputError
from tolerance import run_mc, run_sobol, sobol
from tolerance.study import load_study

CLI = [sys.executable, "-c", "import sys; from rvfmu.cli import main; sys.exit(main(sys.argv[1:]))"]


def unit_problem(groups):
    """A SALib problem of len(groups) variables on [0, 1), in those groups (None: none)."""
    D = len(groups)
    problem = {"num_vars": D, "names": [f"x{i}" for i in range(D)], "bounds": [[0.0, 1.0]] * D}
    if groups is not None:
        problem["groups"] = list(groups)
    return problem


# -- 1. Sobol: the sample and the analysis agree for every number of groups -------------------

PROBLEMS = {
    "one group of 40": (["pins"] * 40, 1),
    "one variable": (["x0"], 1),
    "two groups": (["a", "a", "b", "b", "b"], 2),
    "many groups": (["a", "b", "a", "c", "d", "c"], 4),
    "each variable its own group": ([f"x{i}" for i in range(5)], 5),
    "each variable its own, other names": ([f"g{i}" for i in range(5)], 5),
}


@pytest.mark.parametrize("second_order", [False, True], ids=["first", "second order"])
@pytest.mark.parametrize("name", PROBLEMS)
def test_the_sample_has_n_times_rows_per_base_sample_rows_for_every_number_of_groups(name, second_order):
    groups, G = PROBLEMS[name]
    problem = unit_problem(groups)
    per = sobol.rows_per_base_sample(problem, second_order)
    assert per == (2 * G + 2 if second_order else G + 2)
    X = sobol.sample(problem, 8, second_order, seed=4)
    assert X.shape == (8 * per, len(groups))
    y = X @ np.arange(1.0, len(groups) + 1.0)
    ind = sobol.analyze(problem, y[:, None], ["y"], second_order, resamples=20)["y"].indices
    assert ind.n == 8 and len(ind.names) == G


def test_the_one_group_design_is_salibs_own_for_one_variable_and_ab_is_b():
    from SALib.sample import sobol as salib_sample

    one = {"num_vars": 1, "names": ["x"], "bounds": [[2.0, 5.0]]}
    for second_order in (False, True):
        ours = sobol.sample(one, 16, second_order, seed=9)
        theirs = salib_sample.sample(one, 16, calc_second_order=second_order, scramble=True, seed=9)
        assert np.array_equal(ours, theirs)
    X = sobol.sample(unit_problem(["all"] * 6), 8, seed=1).reshape(8, 3, 6)  # A, AB, B
    assert np.array_equal(X[:, 1], X[:, 2]) and not np.array_equal(X[:, 0], X[:, 2])


def test_one_group_has_s1_and_st_exactly_one_with_zero_intervals_and_a_note():
    problem = unit_problem(["pins"] * 40)
    X = sobol.sample(problem, 16, True, seed=2)
    y = np.sin(6.0 * X[:, 0]) + X[:, 1:].sum(axis=1) ** 2
    result = sobol.analyze(problem, y[:, None], ["y"], True, resamples=30)["y"]
    ind = result.indices
    assert ind.names == ("pins",) and ind.whole_input
    assert (ind.S1.tolist(), ind.ST.tolist(), ind.S1_conf.tolist(), ind.ST_conf.tolist()) == (
        [1.0],
        [1.0],
        [0.0],
        [0.0],
    )
    assert ind.flags() == [[sobol.WHOLE_INPUT_NOTE]] and "by definition" in sobol.WHOLE_INPUT_NOTE
    assert ind.order() == [] and ind.order_groups() == [[1]]
    assert result.convergence.converged and result.convergence.max_change == 0.0
    assert ind.S2.shape == (1, 1) and np.isnan(ind.S2[0, 0])


def test_a_two_group_linear_model_gives_its_analytic_indices():
    # y = x0 + 2 x1 + 3 x2 + 0.5 x3, groups {x0, x1} and {x2, x3}, each x uniform on [0, 1):
    # V = sum c^2 / 12, additive, so S1 = ST = (sum of the group's c^2) / (sum of all c^2).
    c = np.array([1.0, 2.0, 3.0, 0.5])
    problem = unit_problem(["a", "a", "b", "b"])
    X = sobol.sample(problem, 2048, seed=5)
    ind = sobol.analyze(problem, (X @ c)[:, None], ["y"], resamples=200, seed=5)["y"].indices
    exact = np.array([c[:2] @ c[:2], c[2:] @ c[2:]]) / (c @ c)  # 5/14.25, 9.25/14.25
    assert ind.names == ("a", "b") and not ind.whole_input
    np.testing.assert_array_less(np.abs(ind.S1 - exact), np.maximum(ind.S1_conf, 0.01))
    np.testing.assert_array_less(np.abs(ind.ST - exact), np.maximum(ind.ST_conf, 0.01))
    assert np.abs(ind.ST - exact).max() < 0.02


ONE_GROUP = {"pin_radial": {"band_um": 5.0}}
ALL_IN_ONE = {
    "carrier_assembly": {"position_um": 8.0, "group": "all"},
    "crank_cam_eccentricity": {"position_um": 9.0, "group": "all"},
    "pin_radial": {"band_um": 5.0, "group": "all"},
}
TWO_GROUPS = {"crank_cam_eccentricity": {"position_um": 9.0}, "pin_radial": {"band_um": 5.0}}


@pytest.mark.parametrize(
    "tolerances, second_order, G",
    [(ONE_GROUP, False, 1), (ALL_IN_ONE, True, 1), (TWO_GROUPS, False, 2)],
    ids=["pin_radial alone", "every factor in group all, second order", "two groups"],
)
def test_rvte_sobol_runs_n_times_rows_per_base_sample_evaluations(
    tolerances, second_order, G, tmp_path, capsys
):
    path = write_study(tmp_path, tolerances=tolerances, sobol={"n": 8, "resamples": 20})
    args = ["sobol", path, "--json", "--no-plots"] + (["--second-order"] if second_order else [])
    code, out, err = run_cli(args, capsys)
    assert code == 0, err
    doc = json.loads(out)
    per = 2 * G + 2 if second_order else G + 2
    problem = load_study(path).problem()
    assert sobol.rows_per_base_sample(problem, second_order) == per
    assert doc["evaluations"] == 8 * per == sobol.sample(problem, 8, second_order).shape[0]
    job = tmp_path / "toy" / "output" / f"sobol-n8{'-second-order' if second_order else ''}"
    batches = sorted(job.glob("batch-*.parquet"))
    assert batches[-1].name.startswith(f"batch-{(8 * per - 1) // 8 * 8:09d}-{8 * per:09d}-")
    assert (
        f"8 base samples, {8 * per} evaluations, {G} factors"
        in (tmp_path / "toy" / "output" / "sobol_ranking.txt").read_text()
    )
    for _column, entry in doc["metrics"].items():
        assert len(entry["groups"]) == G
        if G == 1:
            (group,) = entry["groups"]
            assert (group["S1"], group["ST"], group["S1_conf"], group["ST_conf"]) == (1, 1, 0, 0)
            assert group["notes"] == [sobol.WHOLE_INPUT_NOTE]
            assert entry["order_groups"] == [[1]] and entry["convergence"]["converged"]


def test_a_one_group_result_makes_its_frames_and_its_report(tmp_path):
    path = write_study(tmp_path, tolerances=ALL_IN_ONE, sobol={"n": 8, "resamples": 20})
    result = run_sobol(path, second_order=True, plots=True)
    frame = result.to_df()
    assert (
        frame[["factor", "rank", "S1", "ST", "S1_conf", "ST_conf"]].values.tolist()
        == [["all", 1, 1.0, 1.0, 0.0, 0.0]] * 2
    )
    assert frame["ranking_converged"].all() and not frame["order_settled"].any()
    assert len(result.to_df(second_order=True)) == 0  # one group: no pair
    assert "S1 = ST = 1 by definition" in result.table()
    report = tolerance.report(result.study.output)
    assert "by definition" in report.html.read_text()


# -- 2. Ctrl-C: one line, exit code 130, no worker left, and the next run resumes -------------


def session_processes(sid: int) -> list:
    """Processes still running in the session `sid` (the interrupted command's)."""
    alive = []
    for process in psutil.process_iter(["status"]):
        try:
            if os.getsid(process.pid) == sid and process.info["status"] != psutil.STATUS_ZOMBIE:
                alive.append(process)
        except (ProcessLookupError, PermissionError, psutil.Error):
            continue
    return alive


def interrupt_after_first_batch(args, cwd, folder, timeout=300.0):
    """Start `rvte ARGS`, press Ctrl-C once `folder` holds a batch file: SIGINT to the command's
    whole process group, as a terminal sends it.  (code, stderr, its processes left alive)."""
    proc = subprocess.Popen(
        CLI + [str(a) for a in args],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + timeout
    try:
        while not any(folder.rglob("batch-*.parquet")):
            assert proc.poll() is None, f"ended before its first batch: {proc.communicate()}"
            assert time.monotonic() < deadline, "no batch written in time"
            time.sleep(0.01)
        children = psutil.Process(proc.pid).children(recursive=True)
        clock = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
        stopped = time.monotonic() - clock
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    _, alive = psutil.wait_procs(children, timeout=5)  # the resource tracker leaves in ~1 s
    deadline = time.monotonic() + 5
    while session_processes(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    return proc.returncode, err, alive + session_processes(proc.pid), stopped


def check_interrupted(code, err, alive, stopped, folder) -> int:
    """The one line, the code, nothing left running; returns the batches the line counts."""
    assert code == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    last = err.strip().splitlines()[-1]
    kept = len(list(folder.rglob("batch-*.parquet")))
    assert last == f"interrupted: {kept} batches kept, run the same command to resume"
    assert kept >= 1
    assert alive == [], [p.pid for p in alive]
    assert stopped < 20.0
    return kept


def run_again(args, cwd):
    done = subprocess.run(CLI + [str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done


def test_ctrl_c_in_rvte_mc_is_one_line_and_the_same_command_resumes(tmp_path):
    path = write_study(tmp_path, study={"batch_size": 4}, montecarlo={"n": 32})  # 8 batches
    folder = tmp_path / "toy" / "output" / "mc"
    args = ["mc", path, "--no-plots"]
    kept = check_interrupted(*interrupt_after_first_batch(args, tmp_path, folder), folder)
    assert kept < 8
    again = run_again(args, tmp_path)
    assert f"in 8 batches of 4 ({kept} reused, {8 - kept} computed)" in again.stderr
    whole = run_mc(path, output=tmp_path / "uninterrupted", plots=False)
    resumed = tolerance.load_results(tmp_path / "toy" / "output")
    assert np.array_equal(resumed[list(whole.study.metric_columns)].to_numpy(), whole.Y)
    assert np.array_equal(resumed["converged"].to_numpy(), whole.converged)


def test_ctrl_c_in_rvte_sobol_on_processes_ends_the_workers_and_resumes(tmp_path):
    path = write_study(tmp_path, study={"batch_size": 4}, sobol={"n": 8})  # 3 groups: 10 batches
    folder = tmp_path / "toy" / "output" / "sobol-n8"
    args = ["sobol", path, "--no-plots", "--processes", "2", "--json"]
    kept = check_interrupted(*interrupt_after_first_batch(args, tmp_path, folder), folder)
    assert kept < 10
    again = run_again(args, tmp_path)
    assert f"({kept} reused, {10 - kept} computed)" in again.stderr
    whole = run_sobol(path, output=tmp_path / "uninterrupted", plots=False)
    resumed = json.loads(again.stdout)["metrics"]
    for column, analysis in whole.analyses.items():
        groups = {g["name"]: g for g in resumed[column]["groups"]}
        for g, name in enumerate(analysis.indices.names):
            assert (groups[name]["S1"], groups[name]["ST"]) == (
                analysis.indices.S1[g],
                analysis.indices.ST[g],
            )


def test_ctrl_c_in_rvte_mc_on_a_dask_local_cluster_leaves_no_process(tmp_path):
    path = write_study(tmp_path, montecarlo={"n": 64})
    folder = tmp_path / "toy" / "output" / "mc"
    check_interrupted(
        *interrupt_after_first_batch(["mc", path, "--no-plots", "--workers", "1"], tmp_path, folder), folder
    )


def test_ctrl_c_in_rvte_allocate_on_processes_counts_every_batch_kept(tmp_path):
    from test_allocate import SPEC, small_study

    path = small_study(tmp_path, spec=SPEC)
    folder = tmp_path / "small" / "output"
    check_interrupted(
        *interrupt_after_first_batch(
            ["allocate", path, "--yield", "0.95", "--processes", "2"], tmp_path, folder
        ),
        folder,
    )


# -- 3. files that are not UTF-8 ---------------------------------------------------------------

BINARY = b"\xff\xfe\x00\x81 not text \x00"


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A toy Monte Carlo output folder of one batch."""
    tmp = tmp_path_factory.mktemp("stored")
    path = write_study(tmp, montecarlo={"n": 8})
    run_mc(path, plots=False)
    return tmp / "toy" / "output"


def copy_folder(stored, tmp_path):
    import shutil

    return Path(shutil.copytree(stored, tmp_path / "copy"))


@pytest.mark.parametrize(
    "name, words",
    [
        ("study.toml", "is not a readable UTF-8 TOML study file"),
        ("inputs.json", "is not a readable UTF-8 JSON file"),
        ("manifest.json", "has an unreadable manifest.json"),
    ],
)
def test_load_results_refuses_a_binary_file_naming_it(stored, tmp_path, name, words):
    folder = copy_folder(stored, tmp_path)
    (folder / name).write_bytes(BINARY)
    with pytest.raises(InputError) as caught:
        tolerance.load_results(folder)
    message = str(caught.value)
    assert words in message and str(folder / name if name != "manifest.json" else folder) in message
    assert "\n" not in message


def test_a_copy_of_the_study_that_is_not_the_study_file_is_named(stored, tmp_path):
    from tolerance.study import study_from_store

    folder = copy_folder(stored, tmp_path)
    inputs = json.loads((folder / "inputs.json").read_text())
    study = study_from_store(folder, "toy", inputs, (folder / "study.toml").read_text())
    assert study.name == "toy" and study.spec and study.mc_n == 8
    (folder / "study.toml").write_text("study = 3\n")
    with pytest.raises(InputError, match=r"study.toml.*has study = 3 where a \[study\] table"):
        tolerance.load_results(folder)


def test_binary_study_files_are_one_line_from_every_command(stored, tmp_path, capsys):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(BINARY)
    for command in ("mc", "sobol", "allocate"):
        code, out, err = run_cli([command, binary], capsys)
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
        assert f"study = '{binary}': is not a readable UTF-8 TOML study file" in err
    folder = copy_folder(stored, tmp_path)
    (folder / "study.toml").write_bytes(BINARY)
    code, out, err = run_cli(["report", folder], capsys)
    assert code == 2 and err.count("\n") == 1 and str(folder / "study.toml") in err
    code, out, err = run_cli(["report", stored, "--study", binary, "-o", tmp_path / "r.html"], capsys)
    assert code == 2 and err.count("\n") == 1 and str(binary) in err


# -- 4. the Dask scheduler address, checked before any work -------------------------------------


@pytest.mark.parametrize(
    "address",
    ["notanaddress", "tcp://host", "tcp://host:0", "tcp://host:70000", "http://host:8786", "tcp://:8786", ""],
)
def test_a_bad_scheduler_address_is_one_line_before_any_work(address, tmp_path, capsys, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("work started before the scheduler address was checked")

    monkeypatch.setattr("tolerance.run.compute", refuse)
    monkeypatch.setattr("tolerance.sobol.sample", refuse)
    path = write_study(tmp_path)
    for command in ("mc", "sobol"):
        code, out, err = run_cli([command, path, "--scheduler", address], capsys)
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert err.startswith(f"rvte {command}: error: --scheduler = {address!r}: ")
        assert "tcp://HOST:PORT" in err and "HOST:PORT" in err and "1 to 65535" in err
    assert not (tmp_path / "toy").exists()


def test_good_scheduler_addresses_pass_the_check():
    from tolerance.backends import scheduler_address

    for address in (
        "tcp://127.0.0.1:8786",
        "localhost:8786",
        "tls://scheduler.lan:8786",
        "tcp://[::1]:8786",
        "ws://h:1",
        "inproc://10.0.0.1/123/1",
    ):
        assert scheduler_address(address) == address


# -- 5. bool keywords take a bool --------------------------------------------------------------


@pytest.fixture(scope="module")
def mc_result(stored):
    return run_mc(stored.parent.parent / "toy.toml", plots=False)


@pytest.mark.parametrize("value", ["no", "yes", 0, 1, None, [True]])
def test_errors_keywords_take_a_bool_only(mc_result, stored, value):
    from tolerance.frames import mc_frame

    calls = {
        "MCResult.to_df": lambda: mc_result.to_df(errors=value),
        "load_results": lambda: tolerance.load_results(stored, errors=value),
        "mc_frame": lambda: mc_frame(mc_result.study, mc_result.Y, mc_result.converged, value),
    }
    for name, call in calls.items():
        with pytest.raises(InputError) as caught:
            call()
        assert str(caught.value).startswith(f"errors = {value!r}: must be True or False"), name


def test_a_bool_keyword_still_takes_numpys_bool(mc_result):
    assert mc_result.to_df(errors=np.bool_(True)).shape[1] > mc_result.to_df(errors=False).shape[1]


@pytest.mark.parametrize(
    "keyword, value", [("second_order", "no"), ("plots", "no"), ("yes", "false"), ("progress", 1)]
)
def test_run_keywords_take_a_bool_before_any_work(keyword, value, tmp_path, monkeypatch):
    monkeypatch.setattr("tolerance.run.compute", lambda *a, **k: pytest.fail("work started"))
    path = write_study(tmp_path)
    with pytest.raises(InputError, match=f"^{keyword} = {value!r}: must be True or False"):
        run_sobol(path, **{keyword: value})
    if keyword != "second_order":
        with pytest.raises(InputError, match=f"^{keyword} = {value!r}: must be True or False"):
            run_mc(path, **{keyword: value})


def test_sobol_to_df_second_order_takes_a_bool(tmp_path):
    path = write_study(tmp_path, tolerances=ONE_GROUP, sobol={"n": 8, "resamples": 20})
    result = run_sobol(path, plots=False)
    with pytest.raises(InputError, match="^second_order = 'no': must be True or False"):
        result.to_df(second_order="no")
    assert isinstance(result.to_df(second_order=False), pd.DataFrame)


# -- 6. a user catalogue file: every message about its content names it ------------------------


@pytest.mark.parametrize(
    "content",
    [
        "source = 'a catalogue without figures'\n",
        "note = 'n'\n",
        "efficiency = 3\n",
        "torsional_rigidity_Nm_per_arcmin = -1.0\n",
        "torsional_rigidity_Nm_per_arcmin = 'stiff'\n",
        "rated_torque_Nm = 412.0\n",
        "torsional_rigidity_Nm_per_arcmin = 100.0\nfigure = 3\n",
        "[[running_torque]]\noutput_speed_rpm = 10.0\ninput_torque_Nm = 'a'\n",
        "[[efficiency]]\noutput_speed_rpm = 10.0\n",
    ],
    ids=[
        "no figures",
        "only a note",
        "efficiency not tables",
        "negative rigidity",
        "text rigidity",
        "only the rated torque",
        "unknown key",
        "bad running torque",
        "efficiency without its keys",
    ],
)
def test_every_message_about_a_catalogue_files_content_names_the_file(content, tmp_path, capsys):
    path = tmp_path / "frame_catalogue.toml"
    path.write_text(content)
    code, out, err = run_cli(
        ["calibrate", "RV-40E-121", path, "--target", "catalogue", "--fit", "output_stiffness"], capsys
    )
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("rvte calibrate: error: ") and "frame_catalogue.toml" in err


def test_a_toml_without_catalogue_figures_or_datasets_says_what_either_kind_needs(tmp_path, capsys):
    path = tmp_path / "frame_catalogue.toml"
    path.write_text("source = 'a catalogue without figures'\n")
    code, _, err = run_cli(
        ["calibrate", "RV-40E-121", path, "--target", "catalogue", "--fit", "output_stiffness"], capsys
    )
    assert code == 2
    assert (
        f"frame_catalogue.toml: data = '{path}': is neither a catalogue TOML (it has none of "
        "torsional_rigidity_Nm_per_arcmin, lost_motion_arcmin, [[efficiency]], "
        "[[running_torque]]) nor a data-set TOML (one or more [[dataset]] tables)"
    ) in err


def test_a_study_speed_beyond_the_allowable_limit_is_refused_and_above_it_warned(tmp_path):
    from rvfmu.core.base.checks import InputError
    from tolerance import run_mc
    from tolerance.study import load_study

    with pytest.raises(
        InputError,
        match=r"toy.toml: operating.output_speed_rpm = 200.0: is an "
        r"output speed of 200 rpm: must be within 2 x the "
        r"allowable output speed 70 rpm of RV-40E-121 linear",
    ):
        load_study(write_study(tmp_path, operating={"output_speed_rpm": 200.0}))
    path = write_study(tmp_path, operating={"output_speed_rpm": 100.0}, montecarlo={"n": 8})
    assert load_study(path).operating_warnings == [
        "operating.output_speed_rpm = 100.0 is an output speed of 100 rpm, 1.4 x the "
        "allowable output speed 70 rpm of RV-40E-121 linear: no rating covers it; treat the "
        "results with care"
    ]
    lines = []
    run_mc(path, output=tmp_path / "out", plots=False, log=lines.append)
    assert (
        sum(line.startswith("warning: ") and "allowable output speed 70 rpm" in line for line in lines) == 1
    )


@pytest.mark.parametrize(
    "error, tolerance, key, largest, limit",
    [
        ("carrier_assembly", {"position_um": 300.0}, "position_um", 150.0, 130.0),
        ("sun_eccentricity", {"position_um": 301.0}, "position_um", 150.5, 150.0),
        ("pin_radial", {"band_um": 261.0}, "band_um", 130.5, 130.0),
        ("main_bearing_clearance", {"max_um": 131.0}, "max_um", 131.0, 130.0),
    ],
)
def test_a_tolerance_that_draws_errors_beyond_the_model_is_refused_when_the_study_is_read(
    tmp_path, error, tolerance, key, largest, limit
):
    from rvfmu.core.base.checks import InputError
    from tolerance.study import load_study

    path = write_study(tmp_path, tolerances={error: tolerance})
    with pytest.raises(InputError) as caught:
        load_study(path)
    assert str(caught.value) == (
        f"toy.toml: tolerances.{error}.{key} = {tolerance[key]}: allows errors of up to "
        f"{largest:g} um, where the model takes at most {limit:g} um for {error} on RV-40E-121 "
        "linear (ERROR_FRACTION = 0.1 x the length it displaces, docs/model.md section 4)"
    )
    # at the limit the study is read
    load_study(write_study(tmp_path, tolerances={error: {key: tolerance[key] * limit / largest}}))


def test_the_traceback_of_dask_cancelling_a_future_not_yet_made_is_dropped_and_no_other():
    """distributed's `sync()` answers a Ctrl-C by a `cancel()` callback that reads a name its
    coroutine may not have set yet; tornado logs the NameError as a traceback, which the Dask
    backend drops (tolerance.backends._CancelBeforeStart).  Any other error still shows."""
    import logging

    from tolerance.backends import _CancelBeforeStart, quiet_cancel_before_start

    def record_of(source, filename):
        space = {}
        exec(compile(source, filename, "exec"), space)
        try:
            space["outer"]()
        except Exception as exc:
            return logging.LogRecord(
                "tornado.application",
                logging.ERROR,
                filename,
                1,
                "Exception in callback",
                None,
                (type(exc), exc, exc.__traceback__),
            )
        raise AssertionError("the probe raised nothing")

    unset = (
        "def outer():\n    future: int\n    def cancel():\n        if future is not None:\n"
        "            pass\n    cancel()\n"
    )
    other = "def outer():\n    def cancel():\n        raise ValueError('a real error')\n    cancel()\n"
    keep = _CancelBeforeStart()
    assert not keep.filter(record_of(unset, "/site-packages/distributed/utils.py"))
    assert keep.filter(record_of(unset, "/site-packages/other/utils.py"))  # not distributed's
    assert keep.filter(record_of(other, "/site-packages/distributed/utils.py"))  # not the NameError
    assert keep.filter(logging.LogRecord("x", logging.ERROR, "f", 1, "no exception", None, None))
    quiet_cancel_before_start()
    quiet_cancel_before_start()
    assert (
        sum(isinstance(f, _CancelBeforeStart) for f in logging.getLogger("tornado.application").filters) == 1
    )
