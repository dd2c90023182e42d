"""`rvte simulate` against careless input: excitation amplitudes a record cannot resolve, runs
too long to compute, speeds beyond any reducer, a load step outside the run and an input that
reverses (rvfmu/core/dynamics/simulation.py, rvfmu/core/dynamics/excitations.py, rvfmu/jobs/simulate.py)."""

import json
import math
import re

import numpy as np
import pytest
from conftest import ROOT
from test_hardening import run_cli

from rvfmu import api
from rvfmu.core.base.checks import InputError
from rvfmu.core.dynamics import simulation
from rvfmu.core.dynamics.excitations import (
    MIN_PERIODS,
    RESOLUTION_BINS,
    Excitations,
    amplitude_at,
    read_amplitudes,
    record_needed,
)
from rvfmu.core.dynamics.simulation import MAX_STEPS, Sampled, simulate

SEED002 = str(ROOT / "studies" / "seed002_errors.toml")


@pytest.fixture
def no_stepping(monkeypatch):
    """Fail the test if the integration starts."""

    def refuse(*args, **kwargs):
        raise AssertionError("the run started before its input was refused")

    monkeypatch.setattr(simulation.NewmarkStepper, "starting_at", refuse)


# -- 1. amplitudes only where the record resolves them ------------------------------------------


def test_the_record_needed_is_the_periods_or_the_bins_to_the_nearest_neighbour():
    assert (MIN_PERIODS, RESOLUTION_BINS) == (4, 3)
    # 10 Hz beside 12 Hz: 3 bins of 2 Hz need 1.5 s, more than 4 periods (0.4 s)
    assert record_needed(10.0, [12.0, 30.0]) == pytest.approx(1.5)
    # 30 Hz, 18 Hz from 12: 3 / 18 = 0.167 s, more than 4 periods (0.133 s)
    assert record_needed(30.0, [10.0, 12.0]) == pytest.approx(3.0 / 18.0)
    # 100 Hz far from 400 Hz: 4 periods (0.04 s), more than 3 / 300 s
    assert record_needed(100.0, [400.0]) == pytest.approx(0.04)
    assert math.isinf(record_needed(50.0, [20.0, 50.0 * (1 + 1e-12)]))


def test_a_short_record_reports_not_resolved_and_a_long_enough_one_the_amplitude():
    """Sines of 1 and 2 at 10 and 12 Hz: 1.5 s needed by both; 1.49 s reads neither, 1.5 s
    (the rounded figure the message gives) reads both within 1 %."""
    step = 1e-3
    listed = (("a", 10.0), ("b", 12.0), ("c", 600.0))

    def rows(seconds):
        t = np.arange(int(round(seconds / step))) * step
        x = np.sin(2 * np.pi * 10.0 * t + 0.3) + 2.0 * np.sin(2 * np.pi * 12.0 * t)
        return {name: (amplitude, why) for name, _, amplitude, why in read_amplitudes(x, step, listed)}

    short = rows(1.49)
    assert short["a"] == (None, "needs \u2265 1.5 s of record")
    assert short["b"] == (None, "needs \u2265 1.5 s of record")
    assert short["c"] == (None, "above the step's Nyquist frequency 500 Hz")
    enough = rows(1.5)
    assert enough["a"][0] == pytest.approx(1.0, rel=0.01) and enough["a"][1] is None
    assert enough["b"][0] == pytest.approx(2.0, rel=0.01) and enough["b"][1] is None
    twins = read_amplitudes(np.zeros(100), step, (("p", 50.0), ("q", 50.0)))
    assert twins == [("p", 50.0, None, "coincides with q"), ("q", 50.0, None, "coincides with p")]


def test_a_run_shorter_than_the_excitations_periods_prints_no_amplitude(capsys):
    """The 0.05 s run that printed 3.61 arcsec at the crank rotation (9.01 over 1 s): each
    excitation now says how much record it needs (crank: 4 periods of 8.815 Hz = 0.454 s;
    its 2nd order: 3 bins of the 8.815 Hz to the crank = 0.341 s)."""
    args = ["simulate", "RV-40E-121", "--errors", SEED002, "--load", "206", "--duration", "0.05"]
    code, out, err = run_cli(args, capsys)
    assert code == 0 and err == ""
    needs = {
        "input rotation": "0.333",
        "input rotation x2": "0.113",
        "crank rotation": "0.454",
        "crank rotation x2": "0.341",
        "pin passing": "0.114",
        "pin passing x2": "0.0568",
        "stage-1 mesh": "0.114",
        "stage-1 mesh x2": "0.0568",
    }
    for name, seconds in needs.items():
        assert re.search(
            rf"\n  {name} +\d+\.\d\d   not resolved: needs \u2265 {seconds} s of "
            r"record\n",
            out,
        ), name
    code, out, _ = run_cli(args + ["--json"], capsys)
    rows = json.loads(out)["excitations"]
    assert [(r["name"], r["amplitude_arcsec"], r["not_resolved"]) for r in rows] == [
        (name, None, f"needs \u2265 {seconds} s of record") for name, seconds in needs.items()
    ]


def test_a_run_long_enough_reports_every_amplitude_as_before(capsys):
    """0.46 s at speed resolves all eight (the crank's 0.454 s the longest need), and each
    amplitude is the one `amplitude_at` reads from the record after the ramp, as it was
    before the rule."""
    report = api.simulate("RV-40E-121", SEED002, load=206.0, duration=0.46)
    sim = report.simulation
    te = sim.steady_te_arcsec()
    rows = sim.excitation_rows()
    assert [(name, hz) for name, hz, _, _ in rows] == list(
        Excitations.at(sim.design, 1600.0).with_harmonics()
    )
    for name, hz, amplitude, why in rows:
        assert why is None and amplitude == amplitude_at(te, sim.step, hz), name
    crank = dict((n, a) for n, _, a, _ in rows)["crank rotation"]
    assert 8.0 < crank < 10.0  # arcsec: 9.06 over a whole output revolution
    assert "not resolved" not in report.summary()
    assert re.search(r"\n  crank rotation +8\.82 +\d\.\d{4}\n", report.summary())
    assert all(
        r["not_resolved"] is None and r["amplitude_arcsec"] > 0.0 for r in report.to_json()["excitations"]
    )


# -- 2. run size --------------------------------------------------------------------------------


def test_a_run_of_too_many_steps_is_refused_in_one_line_before_it_starts(capsys, no_stepping):
    code, out, err = run_cli(["simulate", "RV-40E-121", "--speed-rpm", "16000", "--duration", "30"], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    match = re.fullmatch(
        r"rvte simulate: error: duration = 30\.0: the run of 30\.05 s \(the start "
        r"ramp's 0\.05 s included\) at 16000 rpm takes (\d+) time steps of \S+ s, "
        r"more than the limit of 1000000 \(MAX_STEPS, about a minute of "
        r"computing\): shorten --duration \(or --revolutions, default one output "
        r"revolution\) or lower --speed-rpm\n",
        err,
    )
    assert match, err
    assert int(match.group(1)) > 2_000_000  # 30.05 s at 13 us or finer


def test_the_step_limit_names_the_length_and_a_given_step(rv40, no_stepping):
    with pytest.raises(InputError, match=r"or give a larger --step$") as info:
        simulate(rv40, None, 1600.0, duration=0.1, ramp=0.05, step=1e-7)
    assert info.value.field == "duration"
    assert "takes 1500001 time steps of 1e-07 s" in str(info.value)  # 0.15 s / 1e-7 s + 1
    with pytest.raises(InputError) as info:
        simulate(rv40, None, 1600.0, revolutions=30.0)
    assert info.value.field == "revolutions" and f"limit of {MAX_STEPS}" in str(info.value)


def test_the_huge_speed_of_the_report_is_refused_at_once(capsys, no_stepping):
    code, out, err = run_cli(["simulate", "RV-40E-121", "--speed-rpm", "1e7", "--duration", "0.001"], capsys)
    assert code == 2 and out == ""
    assert err == (
        "rvte simulate: error: speed_rpm = 10000000.0: is an output speed of 8.264e+04 "
        "rpm: must be within 2 x the allowable output speed 70 rpm of RV-40E-121 "
        "(140 rpm out, 16940 rpm in)\n"
    )


def test_progress_is_reported_from_the_start_on_long_runs_only(rv40, monkeypatch):
    calls = []
    simulate(rv40, None, 1600.0, duration=0.01, progress=lambda *a: calls.append(a))
    assert calls == []  # ~1000 steps: over before a bar would show
    monkeypatch.setattr(simulation, "PROGRESS_STEPS", 100)
    sim = simulate(rv40, None, 1600.0, duration=0.01, progress=lambda *a: calls.append(a))
    total = sim.time.size - 1
    assert calls[0] == (total, 0) and calls[-1] == (total, total)
    assert [done for _, done in calls] == sorted(done for _, done in calls) and len(calls) > 100


# -- 3. speeds beyond any reducer ---------------------------------------------------------------


def test_speeds_beyond_the_allowable_class_are_refused_and_above_it_warned(capsys):
    code, out, err = run_cli(["simulate", "RV-40E-121", "--speed-rpm", "1e5"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "speed_rpm = 100000.0: is an output speed of 826.4 rpm: must be within 2 x" in err
    code, out, err = run_cli(
        ["simulate", "RV-40E-121", "--speed-rpm", "12000", "--duration", "0.005", "--load", "1100"], capsys
    )
    assert code == 0 and err == ""
    assert (
        "\nwarning           speed_rpm = 12000.0 is an output speed of 99.17 rpm, 1.4 x the "
        "allowable output speed 70 rpm of RV-40E-121: no rating covers it; treat the results "
        "with care"
    ) in out
    assert "\nwarning           load = 1100 N*m is 2.7 x the rated torque 412 N*m" in out
    code, out, _ = run_cli(["simulate", "RV-40E-121", "--duration", "0.005", "--json"], capsys)
    assert json.loads(out)["warnings"] == []


def write_angles(path, t, angles):
    path.write_text("time_s,theta_in_rad\n" + "".join(f"{a:.9g},{b:.12g}\n" for a, b in zip(t, angles)))
    return path


def test_an_input_csv_faster_than_the_limit_between_two_samples_is_refused(tmp_path, capsys, no_stepping):
    t = np.linspace(0.0, 0.05, 51)
    # 60 rad/s, then 3000 rad/s (28,648 rpm: 237 rpm out) from 0.03 s on
    angles = np.where(t < 0.03, 60.0 * t, 1.8 + 3000.0 * (t - 0.03))
    path = write_angles(tmp_path / "fast.csv", t, angles)
    code, out, err = run_cli(["simulate", "RV-40E-121", "--input-csv", path], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(
        "rvte simulate: error: input_csv = 'input speed 2.865e+04 rpm (its "
        "fastest, samples 31 to 32)': is an output speed of 236.8 rpm: must be "
        "within 2 x the allowable output speed 70 rpm of RV-40E-121"
    )


def test_an_input_csv_above_the_allowable_speed_is_run_and_warned(tmp_path):
    t = np.linspace(0.0, 0.02, 41)
    path = write_angles(tmp_path / "brisk.csv", t, 1300.0 * t)  # 12,414 rpm: 103 rpm out
    report = api.simulate("RV-40E-121", input_csv=path)
    assert report.simulation.warnings == (
        "input_csv = 'input speed 1.241e+04 rpm (its fastest, samples 1 to 2)' is an output speed "
        "of 102.6 rpm, 1.5 x the allowable output speed 70 rpm of RV-40E-121: no rating covers "
        "it; treat the results with care",
    )


# -- 4. a load step outside the run --------------------------------------------------------------


@pytest.mark.parametrize("value", ["99:100", "-0.5:100"])
def test_a_load_step_outside_the_run_is_refused(value, capsys, no_stepping):
    code, out, err = run_cli(["simulate", "RV-40E-121", "--duration", "0.05", "--load-step", value], capsys)
    at = value.split(":")[0]
    assert code == 2 and out == ""
    assert re.fullmatch(
        rf"rvte simulate: error: load_step = '{at}:100': the load would change at "
        rf"{at} s, outside the run \(0 to 0\.1407 s, t = 0 at the start of the "
        r"ramp, 0\.09075 s of ramp and 0\.05 s at speed\): give a time inside "
        r"it or a longer run\n",
        err,
    ), err


def test_the_api_refuses_a_load_step_after_the_sampled_input(tmp_path, no_stepping):
    t = np.linspace(0.0, 0.05, 51)
    path = write_angles(tmp_path / "input.csv", t, 60.0 * t)
    with pytest.raises(
        InputError,
        match=r"^load_step = '0.06:300': the load would change at "
        r"0.06 s, outside the run \(0 to 0.05 s, the sampled "
        r"input's times\)",
    ):
        api.simulate("RV-40E-121", load=100.0, load_step=(0.06, 300.0), input_csv=path)


# -- 5. an input that reverses ---------------------------------------------------------------------


def test_an_input_that_reverses_is_simulated_but_has_no_excitation_amplitudes(tmp_path, capsys):
    t = np.linspace(0.0, 0.05, 201)
    # 60 rad/s plus 0.2 rad at 100 Hz: the speed swings from -66 to 186 rad/s
    path = write_angles(tmp_path / "back.csv", t, 60.0 * t + 0.2 * np.sin(2 * np.pi * 100.0 * t))
    code, out, err = run_cli(["simulate", "RV-40E-121", "--input-csv", path, "--load", "100"], capsys)
    assert code == 0 and err == ""
    assert "mean speed 572.958 rpm (the input reverses)" in out
    assert out.count("not resolved: the input reverses\n") == 8
    code, out, _ = run_cli(["simulate", "RV-40E-121", "--input-csv", path, "--load", "100", "--json"], capsys)
    data = json.loads(out)
    assert data["input_reverses"] is True and data["failed_steps"] == 0
    assert all(
        r["amplitude_arcsec"] is None and r["not_resolved"] == "the input reverses"
        for r in data["excitations"]
    )
    assert 1.0 < data["te_pp_arcsec"] < 100.0 and np.isfinite(data["te_range_arcsec"]).all()


def test_a_forward_sampled_input_does_not_reverse(rv40):
    # 100 rad/s: input 15.92 Hz, 5.39 Hz from the crank's 2nd order (3 / 5.39 = 0.557 s), its
    # own 2nd order 15.92 Hz from it (0.189 s)
    t = np.linspace(0.0, 0.02, 21)
    sim = simulate(rv40, None, input_angle=Sampled.checked("input", t, 100.0 * t))
    assert not sim.input_reverses
    assert [why for *_, why in sim.excitation_rows()][:2] == [
        "needs \u2265 0.557 s of record",
        "needs \u2265 0.189 s of record",
    ]
