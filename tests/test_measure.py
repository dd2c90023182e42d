"""`rvte measure`: TE from a bench's encoder angles, the bench's runout removed.

Every test makes its bench record from a known reducer TE and a known runout, so
what measure finds is checked against what was put in, never against a number
it printed before.
"""

import csv
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from rvfmu import api
from rvfmu.bench.measured import measure_te
from rvfmu.cli import main
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCSEC

RATIO = 81.0
# The reducer's TE: (order per output revolution, amplitude ["], phase [rad]); 39 is the
# disc's lobe order of a 40-pin RV, 78 its second harmonic.
TE_ORDERS = ((2, 12.0, -0.4), (39, 20.0, 1.0), (78, 6.0, -2.0))
# The bench's runout, as measure reports it: A cos(k theta - phase), [", deg].
OUTPUT_RUNOUT = (15.0, 40.0)  # output encoder eccentricity, order 1 of the output
INPUT_RUNOUT = (8.0, -30.0)  # input coupling, order 1 of the input
INPUT_RPM = 600.0


def reducer_te(theta_in):
    """The reducer's TE ["] at input angles [rad]."""
    phi = theta_in / RATIO
    return sum(a * np.cos(k * phi + p) for k, a, p in TE_ORDERS)


def bench(revolutions=2.0, per_rev=2048, sense=1, noise_arcsec=0.2, seed=1, ratio=RATIO):
    """A record of `revolutions` output revolutions at INPUT_RPM, `per_rev` rows each: time [s],
    theta_in, theta_out [rad] as the encoders read them (runout and seeded noise added),
    and the reducer's TE ["] at each row."""
    rows = int(round(revolutions * per_rev)) + 1
    time = np.arange(rows) / (per_rev * INPUT_RPM / 60.0 / ratio)
    theta_in = sense * 2 * np.pi * INPUT_RPM / 60.0 * time + 0.3
    te = reducer_te(theta_in)
    theta_out = theta_in / ratio + te * ARCSEC + 0.01
    (a_out, p_out), (a_in, p_in) = OUTPUT_RUNOUT, INPUT_RUNOUT
    read_out = theta_out + ARCSEC * (
        a_out * np.cos(theta_out - np.radians(p_out)) + a_in * np.cos(theta_in - np.radians(p_in))
    )
    rng = np.random.default_rng(seed)
    noise = noise_arcsec * ARCSEC
    return dict(
        time_s=time,
        theta_in=theta_in + rng.normal(0, noise * ratio, rows),
        theta_out=read_out + rng.normal(0, noise, rows),
        te=te,
    )


def write(path, columns):
    """A CSV of {name: values} with full precision."""
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(list(columns))
        for row in zip(*columns.values()):
            writer.writerow([repr(float(v)) for v in row])
    return path


def deg_file(path, record, wrap=True, time=True):
    out = {"time_s": record["time_s"]} if time else {}
    for role in ("theta_in", "theta_out"):
        angle = np.degrees(record[role])
        out[f"{role}_deg"] = angle % 360.0 if wrap else angle
    return write(path, out)


def run(*args, capsys):
    """rvte in this process: (exit code, stdout, stderr)."""
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture(scope="module")
def record():
    return bench()


@pytest.fixture(scope="module")
def measured(record):
    return measure_te(
        record["theta_in"],
        record["theta_out"],
        RATIO,
        record["time_s"],
        remove_orders=(1,),
        remove_input_orders=(1,),
    )


def test_recovers_the_reducer_te_and_the_runout(record, measured):
    m = measured
    true = record["te"][: m.rows] - record["te"][: m.rows].mean()
    true_pp = np.ptp(record["te"])
    assert m.revolutions == 2 and m.rows_after == 0
    assert abs(m.te_pp_arcsec[1] - true_pp) < 0.02 * true_pp
    assert np.max(np.abs(m.te_reducer_arcsec - true)) < 0.02 * true_pp
    # the runout was there: the measured TE is much larger than the reducer's
    assert m.te_pp_arcsec[0] > 1.2 * true_pp
    found = {(c.shaft, c.order): c for c in m.components}
    assert set(found) == {("output", 1), ("input", 1)}
    for key, (amplitude, phase) in ((("output", 1), OUTPUT_RUNOUT), (("input", 1), INPUT_RUNOUT)):
        assert abs(found[key].amplitude_arcsec - amplitude) < 0.05 * amplitude
        assert abs((found[key].phase_deg - phase + 180) % 360 - 180) < 2.0
    # and it is what was removed, row by row
    (a_out, p_out), (a_in, p_in) = OUTPUT_RUNOUT, INPUT_RUNOUT
    runout = a_out * np.cos(m.theta_out - np.radians(p_out)) + a_in * np.cos(m.theta_in - np.radians(p_in))
    assert np.max(np.abs(m.runout_arcsec - runout)) < 0.05 * a_out
    # the spectrum by order sees the reducer's orders where they are
    reducer_orders = [order for order, _ in m.largest_orders(3)[1]]
    assert sorted(reducer_orders) == [k for k, _, _ in TE_ORDERS]


def test_keep_orders_keeps_the_output_order(record):
    m = measure_te(record["theta_in"], record["theta_out"], RATIO, keep_orders=(1,))
    assert m.components == ()
    np.testing.assert_allclose(m.te_reducer_arcsec, m.te_arcsec - m.te_arcsec.mean(), atol=1e-9)
    assert abs(m.te_pp_arcsec[0] - m.te_pp_arcsec[1]) < 1e-9


def test_wrapped_counts_deg_and_rad_give_the_same_te(tmp_path, record):
    counts = (2**20, 2**23)  # input, output encoder
    c_in, c_out = (
        np.round(record[role] / (2 * np.pi) * n) for role, n in zip(("theta_in", "theta_out"), counts)
    )
    files = {
        "counts": write(
            tmp_path / "counts.csv",
            {
                "time_s": record["time_s"],
                "theta_in_counts": c_in % counts[0],
                "theta_out_counts": c_out % counts[1],
            },
        ),
        "deg": write(
            tmp_path / "deg.csv",
            {
                "time_s": record["time_s"],
                "theta_in_deg": c_in * 360.0 / counts[0],
                "theta_out_deg": c_out * 360.0 / counts[1],
            },
        ),
        "rad": write(
            tmp_path / "rad.csv",
            {
                "time_s": record["time_s"],
                "theta_in_rad": c_in * 2 * np.pi / counts[0],
                "theta_out_rad": c_out * 2 * np.pi / counts[1],
            },
        ),
        "named": write(
            tmp_path / "named.csv",
            {"t": record["time_s"], "enc_in": c_in % counts[0], "enc_out": c_out % counts[1]},
        ),
    }
    reports = {
        "counts": api.measure(files["counts"], RATIO, counts_per_rev=counts, remove_input_orders=(1,)),
        "deg": api.measure(files["deg"], RATIO, remove_input_orders=(1,)),
        "rad": api.measure(files["rad"], RATIO, remove_input_orders=(1,)),
        "named": api.measure(
            files["named"],
            RATIO,
            columns=("enc_in", "enc_out", "t"),
            units="counts",
            counts_per_rev=counts,
            remove_input_orders=(1,),
        ),
    }
    rollovers = reports["counts"].measured.rollovers
    assert rollovers[0] > 100 and rollovers[1] == 2  # the counts did wrap, and unwrapped
    assert reports["deg"].measured.rollovers == (0, 0)
    base = reports["deg"].measured
    for name, report in reports.items():
        m = report.measured
        np.testing.assert_allclose(m.te_reducer_arcsec, base.te_reducer_arcsec, atol=1e-6, err_msg=name)
        np.testing.assert_allclose(m.te_pp_arcsec, base.te_pp_arcsec, atol=1e-6, err_msg=name)
        for c, b in zip(m.components, base.components):
            assert abs(c.amplitude_arcsec - b.amplitude_arcsec) < 1e-6
            assert abs(c.phase_deg - b.phase_deg) < 1e-6


def test_wrapped_degrees_give_the_unwrapped_te(tmp_path, record):
    wrapped = api.measure(deg_file(tmp_path / "w.csv", record, wrap=True), RATIO).measured
    plain = api.measure(deg_file(tmp_path / "p.csv", record, wrap=False), RATIO).measured
    assert wrapped.rollovers[0] == 162 and plain.rollovers == (0, 0)
    np.testing.assert_allclose(wrapped.te_reducer_arcsec, plain.te_reducer_arcsec, atol=1e-5)


def test_negative_sense_gives_the_same_te(record, measured):
    back = bench(sense=-1, seed=2)
    m = measure_te(back["theta_in"], back["theta_out"], RATIO, back["time_s"], remove_input_orders=(1,))
    assert m.sense == -1 and m.revolutions == 2
    assert m.measured_ratio == pytest.approx(RATIO, rel=1e-4)
    true = back["te"][: m.rows] - back["te"][: m.rows].mean()
    true_pp = np.ptp(back["te"])
    # TE = theta_out - theta_in / i in either sense: the same function of the input angle
    assert np.max(np.abs(m.te_reducer_arcsec - true)) < 0.02 * true_pp
    assert abs(m.te_pp_arcsec[1] - measured.te_pp_arcsec[1]) < 0.02 * true_pp
    for c, (amplitude, phase) in zip(m.components, (OUTPUT_RUNOUT, INPUT_RUNOUT)):
        assert abs(c.amplitude_arcsec - amplitude) < 0.05 * amplitude
        assert abs((c.phase_deg - phase + 180) % 360 - 180) < 2.0
    assert m.output_speed_hz == pytest.approx(INPUT_RPM / 60 / RATIO, rel=1e-3)


def test_a_wrong_ratio_is_refused_naming_both(tmp_path, record, capsys):
    path = deg_file(tmp_path / "b.csv", record)
    with pytest.raises(InputError) as info:
        api.measure(path, 121)
    text = str(info.value)
    assert text.startswith("ratio = 121")
    assert float(re.search(r"the data show ([0-9.]+)", text).group(1)) == pytest.approx(81, rel=1e-3)
    code, out, err = run("measure", path, "--ratio", 121, capsys=capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "ratio = 121" in err


def test_a_ratio_slightly_off_warns_of_the_ramp(tmp_path, record):
    report = api.measure(deg_file(tmp_path / "b.csv", record), 81.05)
    assert "ramp" in report.summary() and report.to_json()["warnings"]
    assert not api.measure(deg_file(tmp_path / "b.csv", record), RATIO).measured.warnings


def _lines(path):
    return path.read_text().splitlines()


def _bad(tmp_path, record, case):
    """(file, extra arguments, column, row) of one bad-data case (unequal lengths, NaN, time, too short, unknown column)."""
    path = deg_file(tmp_path / f"{case}.csv", record)
    lines = _lines(path)
    if case == "short row":  # unequal column lengths in a file
        lines[40] = ",".join(lines[40].split(",")[:2])
        column, row = "theta_out_deg", 41
    elif case == "nan":
        fields = lines[56].split(",")
        fields[2] = "nan"
        lines[56] = ",".join(fields)
        column, row = "theta_out_deg", 57
    elif case == "time":
        fields = lines[99].split(",")
        fields[0] = lines[97].split(",")[0]
        lines[99] = ",".join(fields)
        column, row = "time_s", 100
    elif case == "short record":
        lines = lines[:1500]
        column, row = "theta_out_deg", "rows 2 to 1500"
    elif case == "unknown column":
        path.write_text("\n".join(lines) + "\n")
        return path, ("--columns", "theta_in_deg,theta_output_deg"), "theta_output_deg", None
    path.write_text("\n".join(lines) + "\n")
    return path, (), column, row


@pytest.mark.parametrize("case", ["short row", "nan", "time", "short record", "unknown column"])
def test_bad_data_is_one_line_naming_column_and_row(tmp_path, record, case, capsys):
    path, extra, column, row = _bad(tmp_path, record, case)
    code, out, err = run("measure", path, "--ratio", RATIO, *extra, capsys=capsys)
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert column in err
    if isinstance(row, int):
        assert re.search(rf"\b(row|line) {row}\b", err), err
    elif row:
        assert row in err


def test_core_checks_name_column_and_row(record):
    n = record["theta_in"].size
    with pytest.raises(InputError, match=r"theta_out.*ends after row 10\b"):
        measure_te(record["theta_in"], record["theta_out"][:10], RATIO)
    theta_out = record["theta_out"].copy()
    theta_out[[7, 9]] = np.nan
    with pytest.raises(InputError, match=r"theta_out = nan: row 8 .*not: 8, 10\)"):
        measure_te(record["theta_in"], theta_out, RATIO)
    with pytest.raises(InputError, match=r"the output turns [0-9.]+ deg over rows 1 to 200"):
        measure_te(record["theta_in"][:200], record["theta_out"][:200], RATIO)
    theta_in = record["theta_in"].copy()
    theta_in[n // 2] -= 1.0
    with pytest.raises(InputError, match=rf"theta_in = 'row {n // 2 + 1}': the input turns back"):
        measure_te(theta_in, record["theta_out"], RATIO)
    with pytest.raises(InputError, match="the output turns the other way"):
        measure_te(record["theta_in"], -record["theta_out"], RATIO)
    with pytest.raises(InputError, match="remove_input_orders = 1: input order 1 is output order 81"):
        measure_te(
            record["theta_in"], record["theta_out"], RATIO, remove_orders=(1, 81), remove_input_orders=(1,)
        )
    with pytest.raises(InputError, match="keep_orders = 2"):
        measure_te(record["theta_in"], record["theta_out"], RATIO, keep_orders=(2,))


def test_rows_after_the_last_whole_revolution_are_counted():
    extra = bench(revolutions=2.5, per_rev=512)
    m = measure_te(extra["theta_in"], extra["theta_out"], RATIO)
    assert m.revolutions == 2 and m.rows_after == 256 and m.rows + m.rows_after == 1281


def test_hz_spectrum_only_with_time_and_order_one_at_the_output_speed(tmp_path, record):
    without = api.measure(deg_file(tmp_path / "n.csv", record, time=False), RATIO)
    assert without.measured.hz is None and without.to_json()["largest_lines_hz"] is None
    assert "largest lines Hz" not in without.summary() and "no spectrum in Hz" in without.summary()
    m = api.measure(deg_file(tmp_path / "t.csv", record), RATIO).measured
    speed = INPUT_RPM / 60.0 / RATIO
    assert m.output_speed_hz == pytest.approx(speed, rel=1e-6)
    # the order-1 line of the measured TE (the output encoder's eccentricity) in Hz
    low = m.hz <= 1.5 * speed
    line = m.hz[low][np.argmax(m.spectrum_hz[0][low] * (m.hz[low] > 0))]
    assert line == pytest.approx(m.output_speed_hz, rel=1e-9)
    assert abs(line - speed) < 0.5 / (m.revolutions / speed)  # within half a bin of the truth
    # the lobe order 39 sits at 39 x the output speed
    assert m.largest_lines_hz(1)[1][0][0] == pytest.approx(39 * speed, rel=1e-9)


def test_cli_json_csv_and_plot(tmp_path, record):
    path = deg_file(tmp_path / "b.csv", record)
    out_csv, out_png = tmp_path / "te.csv", tmp_path / "te.png"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "rvfmu.cli",
            "measure",
            str(path),
            "--ratio",
            "81",
            "--remove-input-orders",
            "1",
            "--csv",
            str(out_csv),
            "--plot",
            str(out_png),
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["ratio"] == 81 and summary["measured_ratio"] == pytest.approx(81, rel=1e-4)
    assert summary["te_pp_arcsec"]["measured"] > summary["te_pp_arcsec"]["without_runout"]
    assert {(c["shaft"], c["order"]) for c in summary["removed"]} == {("output", 1), ("input", 1)}
    data = np.genfromtxt(out_csv, delimiter=",", names=True)
    assert data.dtype.names == (
        "time_s",
        "theta_in_rad",
        "theta_out_rad",
        "te_arcsec",
        "runout_arcsec",
        "te_reducer_arcsec",
    )
    assert data.size == summary["rows"]["used"]
    residual = data["te_arcsec"] - data["runout_arcsec"] - data["te_reducer_arcsec"]
    assert np.ptp(residual) < 1e-5  # the fit's constant, the same on every row
    assert np.ptp(data["te_reducer_arcsec"]) == pytest.approx(
        summary["te_pp_arcsec"]["without_runout"], abs=1e-5
    )
    assert out_png.read_bytes()[:4] == b"\x89PNG"
