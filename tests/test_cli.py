"""The `rvte` command line does what the README says."""

import csv
import subprocess
import sys

import numpy as np
from conftest import ROOT

from rvfmu.core.base.units import MM
from rvfmu.core.reducer.design import preset


def rvte(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "rvfmu.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def test_te_prints_its_figures_and_writes_csv_and_plot(tmp_path):
    out_csv, out_png = tmp_path / "te.csv", tmp_path / "te.png"
    proc = rvte(
        "te",
        "RV-40E-121",
        "--errors",
        ROOT / "studies" / "seed002_errors.toml",
        "--load",
        412,
        "--points",
        1560,
        "--csv",
        out_csv,
        "--plot",
        out_png,
    )
    assert proc.returncode == 0, proc.stderr
    for word in (
        "te_pp",
        "rms",
        "mean",
        "largest orders",
        "lost motion",
        "torsional rigidity",
        "1560 per output revolution",
    ):
        assert word in proc.stdout
    assert "aliases" in proc.stdout  # 1560 points cannot resolve the pin-passing order 1560
    with out_csv.open() as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["theta_in_rad", "theta_out_rad", "te_arcsec"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (1560, 3)
    np.testing.assert_allclose(data[:, 1] - data[:, 0] / 121.0, data[:, 2] * np.pi / 180 / 3600, atol=1e-9)
    assert out_png.stat().st_size > 20_000 and out_png.read_bytes()[:4] == b"\x89PNG"
    te_pp = float(proc.stdout.split("te_pp")[1].split()[0])
    assert abs(te_pp - np.ptp(data[:, 2])) < 1e-3


def test_presets_lists_the_ratios():
    proc = rvte("presets")
    assert proc.returncode == 0
    lines = {line.split()[0]: float(line.split()[1]) for line in proc.stdout.splitlines()[1:]}
    assert lines == {"RV-40E-121": 121, "RV-40E-81": 81, "RV-20E": 53, "RV-110E": 161}


def test_profile_writes_csv_and_dxf(tmp_path):
    proc = rvte(
        "profile",
        "RV-40E-81",
        "--csv",
        tmp_path / "disc.csv",
        "--dxf",
        tmp_path / "disc.dxf",
        "--points",
        4000,
    )
    assert proc.returncode == 0, proc.stderr
    xy = np.loadtxt(tmp_path / "disc.csv", delimiter=",", skiprows=1)
    radius = np.hypot(xy[:, 0], xy[:, 1])
    # valley and tip radii of docs/model.md section 3 with the preset's modifications, in mm
    d = {k: v / MM for k, v in vars(preset("RV-40E-81")).items() if k in ("d_rp", "d_rrp")}
    assert abs(radius.min() - (66.0 + d["d_rp"] - 1.5 - 3.0 - d["d_rrp"])) < 2e-3
    assert abs(radius.max() - (66.0 + d["d_rp"] + 1.5 - 3.0 - d["d_rrp"])) < 2e-3
    assert (tmp_path / "disc.dxf").read_text().count("LWPOLYLINE") >= 1


def test_profile_without_an_output_is_a_clear_error():
    proc = rvte("profile", "RV-40E-81")
    assert proc.returncode == 2 and "--csv" in proc.stderr and "Traceback" not in proc.stderr
