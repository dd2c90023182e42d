"""What a new user and a careless one hit: output paths checked up front, load limits,
oversized runs, and the layout (rvfmu never needs the studies package above it)."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest
from conftest import ROOT
from tolerance_toy import write_study

from rvfmu import api, cli
from rvfmu.core.base.checks import InputError
from rvfmu.core.reducer.limits import EMERGENCY_FACTOR, MOMENTARY_FACTOR, check_load
from tolerance import run_mc
from tolerance.study import load_study


def run_cli(args, capsys):
    code = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if any TE is computed or any FMU built."""

    def refuse(*args, **kwargs):
        raise AssertionError("work started before the output paths were checked")

    for target in (
        "rvfmu.jobs.te.te_curve",
        "rvfmu.jobs.te.windup",
        "rvfmu.fmu.build.build_te_map",
        "rvfmu.core.reducer.profile.disc_profile",
        "tolerance.run.compute",
    ):
        monkeypatch.setattr(target, refuse)


# -- 1. output paths are checked before any work -----------------------------------------------


@pytest.mark.parametrize(
    "args, expected",
    [
        (["te", "RV-40E-121", "--plot", "out.xyz"], "plot = 'out.xyz': must end in one of"),
        (["te", "RV-40E-121", "--plot", "{tmp}"], "is a folder: give a file name"),
        (["te", "RV-40E-121", "--csv", "{tmp}/no/such/te.csv"], "the folder '{tmp}/no/such' does not"),
        (["te", "RV-40E-121", "--csv", "{tmp}/te.csv", "--plot", "{tmp}/te.docx"], ".png"),
        (
            ["profile", "RV-40E-81", "--dxf", "{tmp}/disc.txt"],
            "dxf = '{tmp}/disc.txt': must end in one of .dxf",
        ),
        (["profile", "RV-40E-81", "--csv", "{tmp}/gone/disc.csv"], "does not exist"),
        (["fmu", "build", "RV-40E-121", "-o", "{tmp}/gone/R.fmu"], "output = '{tmp}/gone/R.fmu'"),
        (["mc", "{study}", "-o", "{study}"], "is a file: give a folder"),
        (["sobol", "{study}", "-o", "{study}/sub"], "is a file"),
    ],
)
def test_bad_output_paths_exit_2_with_one_line_before_any_work(
    args, expected, tmp_path, capsys, no_work, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    study = write_study(tmp_path)
    fill = {"tmp": str(tmp_path), "study": str(study)}
    code, out, err = run_cli([a.format(**fill) for a in args], capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith(f"rvte {args[0]}: error: ")
    assert expected.format(**fill) in err
    assert "Traceback" not in err and out == ""


def test_profile_without_an_output_says_there_is_nothing_to_write(capsys, no_work):
    code, out, err = run_cli(["profile", "RV-40E-81"], capsys)
    assert code == 2
    assert err == "rvte profile: nothing to write: give --csv FILE and/or --dxf FILE\n"


# -- 2. loads outside the model's validity ------------------------------------------------------


def test_load_limits_follow_the_catalogue_classes():
    rated = 412.0
    assert check_load("load", MOMENTARY_FACTOR * rated, rated) is None  # at the limit: fine
    assert "momentary maximum" in check_load("load", -1.01 * MOMENTARY_FACTOR * rated, rated)
    assert check_load("load", -EMERGENCY_FACTOR * rated, rated) is not None  # warned, not refused
    with pytest.raises(
        InputError,
        match=r"load = 2100.0: must be within \+-5 x the rated torque "
        r"412 N\*m \(emergency-stop class, 2060 N\*m\)",
    ):
        check_load("load", 2100.0, rated)
    with pytest.raises(InputError, match="must be finite"):
        check_load("load", float("nan"), rated)


def test_cli_refuses_a_load_beyond_the_emergency_stop_class(capsys, no_work):
    code, out, err = run_cli(["te", "RV-40E-121", "--load", "1e12"], capsys)
    assert code == 2 and out == ""
    assert err == (
        "rvte te: error: load = 1000000000000.0: must be within +-5 x the rated torque "
        "412 N*m (emergency-stop class, 2060 N*m): the small-displacement model does "
        "not hold beyond\n"
    )


def test_cli_warns_above_the_momentary_class_and_still_computes(capsys):
    code, out, err = run_cli(["te", "RV-40E-121", "--load", "1100", "--points", "64"], capsys)
    assert code == 0
    assert "warning           load = 1100 N*m is 2.7 x the rated torque 412 N*m" in out
    assert "te_pp" in out


def test_the_core_refuses_beyond_the_emergency_stop_class(rv40):
    from rvfmu.core.statics.quasistatic import te_curve

    with pytest.raises(InputError, match="tau_load = 2500.0"):
        te_curve(rv40, None, tau_load=2500.0, points=16)


def test_study_load_limits(tmp_path):
    with pytest.raises(InputError, match="operating.load_Nm = 3000.0: must be within"):
        load_study(write_study(tmp_path, name="heavy", operating={"load_Nm": 3000.0}))
    study = load_study(write_study(tmp_path, name="high", operating={"load_Nm": 1100.0}))
    assert "above the momentary maximum class" in study.load_warning
    assert load_study(write_study(tmp_path, name="fine")).load_warning is None


# -- 4. oversized runs ------------------------------------------------------------------------


def test_an_oversized_run_is_refused_after_its_first_batch(tmp_path):
    path = write_study(tmp_path)
    out = tmp_path / "huge"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "rvfmu.cli",
            "mc",
            str(path),
            "-n",
            "1073741824",
            "-o",
            str(out),
            "--no-plots",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert "mc: 1073741824 evaluations in 134217728 batches of 8 (134217728 to compute)" in proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("rvte mc: error: n = 1073741824: 1073741824 evaluations would take about ")
    assert last.endswith("give --yes to run it anyway, or ask for fewer")
    assert len(list((out / "mc").glob("batch-*.parquet"))) == 1  # the timed batch is kept


def test_a_run_above_the_free_disk_needs_yes(tmp_path, monkeypatch):
    import shutil

    from tolerance import run as run_module

    free = shutil.disk_usage(tmp_path)._replace(free=1000)  # 1 kB free: one batch fills it
    monkeypatch.setattr(run_module.shutil, "disk_usage", lambda path: free)
    path = write_study(tmp_path)
    lines = []
    with pytest.raises(
        InputError,
        match=r"^n = 32: 32 evaluations would write about .* with "
        r"1.0 kB free on the output.s disk",
    ):
        run_mc(path, output=tmp_path / "full", plots=False, log=lines.append)
    assert lines[0].startswith("mc: 32 evaluations in 4 batches of 8 (4 to compute); first batch")
    result = run_mc(path, output=tmp_path / "full", plots=False, yes=True, log=lines.append)
    assert result.Y.shape == (32, 2) and np.all(np.isfinite(result.Y))
    assert "(1 reused, 3 computed)" in lines[-1]  # the refused run's batch is kept


def test_a_sobol_n_whose_sample_cannot_fit_in_memory_is_refused_at_once(tmp_path, capsys, no_work):
    code, out, err = run_cli(["sobol", write_study(tmp_path), "-n", str(2**40), "--yes"], capsys)
    assert code == 2
    assert "sample matrix alone takes" in err and "choose a smaller n" in err


# -- 5. the layout: rvfmu never imports tolerance ------------------------------------------------


def test_rvfmu_works_with_the_tolerance_package_unimportable(tmp_path):
    script = textwrap.dedent("""
        import importlib, pkgutil, sys
        sys.modules["tolerance"] = None          # import tolerance -> ImportError
        import rvfmu
        for info in pkgutil.walk_packages(rvfmu.__path__, "rvfmu."):
            importlib.import_module(info.name)
        assert not any(name == "tolerance" or name.startswith("tolerance.")
                       for name, module in sys.modules.items() if module is not None)
        from rvfmu import api
        report = api.te("RV-40E-121", "studies/seed002_errors.toml", points=96)
        print(f"te_pp {report.curve.te_pp_arcsec[0]:.6f}")
        from rvfmu import cli
        sys.exit(cli.main(["te", "RV-40E-121", "--points", "64"]))
    """)
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    reference = api.te("RV-40E-121", ROOT / "studies/seed002_errors.toml", points=96)
    assert proc.stdout.splitlines()[0] == f"te_pp {reference.curve.te_pp_arcsec[0]:.6f}"
    assert any(line.startswith("te_pp  ") for line in proc.stdout.splitlines())
    # the CLI says in one line that the study commands are unavailable, and why
    assert "rvte: the 'studies' commands (tolerance.cli:add_study_commands) are unavailable" in proc.stderr


def test_the_study_commands_join_rvte_through_the_entry_point_group():
    from importlib import metadata

    entries = {e.name: e.value for e in metadata.entry_points(group=cli.COMMAND_GROUP)}
    assert entries["studies"] == "tolerance.cli:add_study_commands"
    commands = cli.build_parser()._subparsers._group_actions[0].choices
    assert {"te", "presets", "profile", "fmu", "mc", "sobol"} <= set(commands)


# -- 5. hostile input: a binary file, a count of points no memory holds --------------------------


@pytest.fixture
def no_solver(monkeypatch):
    """Fail the test if the quasi-static solver is called."""

    def refuse(*args, **kwargs):
        raise AssertionError("the solver ran before the input was refused")

    for target in ("rvfmu.core.statics.quasistatic.solve_pairs", "rvfmu.core.losses.friction.solve_pairs"):
        monkeypatch.setattr(target, refuse)


@pytest.mark.parametrize(
    "args, expected",
    [
        (
            ["te", "RV-40E-121", "--points", "100000000"],
            "error: points = 100000000: gives 100000000 input angles whose element geometry alone takes",
        ),
        (
            ["fmu", "build", "RV-40E-121", "--points", "100000000", "-o", "big.fmu"],
            "error: points = 100000000: gives 100000000 input angles",
        ),
        (["te", "RV-110E", "--points", "10000000000"], "error: points = 10000000000: "),
    ],
)
def test_points_no_memory_holds_are_one_line_before_the_solver(
    args, expected, tmp_path, capsys, monkeypatch, no_solver
):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(args, capsys)
    assert code == 2 and err.count("\n") == 1 and expected in err, err
    assert "choose a smaller points" in err
    assert not (tmp_path / "big.fmu").exists()


def test_a_binary_bench_file_is_one_line_naming_the_file(tmp_path, capsys, no_solver):
    data = tmp_path / "scope.csv"
    data.write_bytes(b"theta_in_deg,theta_out_deg\n" + bytes(range(128, 256)) * 4)
    for args in (
        ["measure", data, "--ratio", "121"],
        ["simulate", "RV-40E-121", "--load-csv", data],
        ["compare", "RV-40E-121", data],
    ):
        code, _, err = run_cli(args, capsys)
        assert code == 2 and err.count("\n") == 1, err
        assert f"= '{data}': is not a text (UTF-8) CSV file: byte 27 is b'\\x80'" in err, err


def test_a_study_whose_points_no_memory_holds_is_refused_when_loaded(tmp_path):
    path = write_study(tmp_path, operating={"points": 100000000})
    with pytest.raises(InputError, match=r"points = 100000000: gives 100000000 input angles"):
        load_study(path)
