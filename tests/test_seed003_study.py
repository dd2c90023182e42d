"""studies/seed003_calibration/run_seed003.py runs end to end on a small budget."""

import subprocess
import sys

from conftest import ROOT

SCRIPT = ROOT / "studies" / "seed003_calibration" / "run_seed003.py"


def test_seed003_identification_runs_and_compares_both_starts(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--quick", "-o", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "calibration.txt").read_text()
    assert text.strip() == proc.stdout.strip()
    for name in ("R_ca", "R_b", "R_pd"):
        assert name in text
    assert "Beside seed 003" in text and "From our geometric estimate" in text
    # the three lines of the second fit: start, fitted, sigma and both sensitivities, numbers
    rows = [line.split() for line in text.splitlines()[-4:-1]]
    assert [r[0] for r in rows] == ["R_ca", "R_b", "R_pd"]
    assert all(float(x) >= 0.0 for r in rows for x in r[1:])
    assert (tmp_path / "rv20e_seed003_calibrated.toml").is_file()
    assert (tmp_path / "calibration.json").is_file()
