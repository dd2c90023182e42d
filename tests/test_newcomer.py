"""Output a newcomer can follow: counts that add up, orders that are there, lines that explain
themselves, the aliasing of a coarse study measured, and the error template."""

import dataclasses

import numpy as np
import pytest
from tolerance_toy import write_study

from rvfmu import api, cli
from rvfmu.core.reducer.errors import load_errors
from rvfmu.core.statics import metrics
from tolerance import montecarlo, run_mc
from tolerance.evaluate import evaluate
from tolerance.study import load_study


@pytest.fixture(scope="module")
def toy_run(tmp_path_factory):
    """30 reducers in batches of 8 at 64 points: 32 computed, 30 analysed, the points alias."""
    folder = tmp_path_factory.mktemp("newcomer")
    path = write_study(folder, montecarlo={"n": 30})
    lines = []
    return path, run_mc(path, output=folder / "out", plots=False, log=lines.append), lines


def test_mc_counts_say_what_was_analysed_and_what_was_computed(toy_run):
    _, result, lines = toy_run
    table = result.table()
    assert (
        "30 reducers analysed (32 computed in 4 batches of 8; the rest are kept for a "
        "larger -n)" in table.splitlines()[0]
    )
    assert lines[-1].startswith("mc: 32 reducers in 4 batches of 8 (0 reused, 4 computed)")
    summary = result.to_json()
    assert (summary["n"], summary["computed_rows"], summary["batch_size"]) == (30, 32, 8)


def test_the_aliasing_check_recomputes_reducers_at_full_resolution(toy_run):
    path, result, _ = toy_run
    check = result.aliasing
    study = load_study(path)
    assert (check.points, check.full_points, check.rows) == (64, 8 * 40 * 39, 16)
    # an independent evaluation of the same reducers at 12480 points
    fine = dataclasses.replace(study, points=12480, spec=())
    Y, _ = evaluate(fine, montecarlo.rows(study, 0, 16))
    np.testing.assert_allclose(check.full, Y, rtol=1e-12)
    np.testing.assert_array_equal(check.coarse, result.Y[:16])
    change = np.abs(Y - result.Y[:16]).max(axis=0)
    np.testing.assert_allclose(check.max_change(), change)
    # the yield bound: the share of reducers within that change of the spec line
    near = np.mean(np.abs(result.Y[:, 0] - 30.0) <= change[0])
    assert check.yield_at_risk == {"te_pp_arcsec <= 30": pytest.approx(near)}
    table = result.table()
    assert (
        "aliasing check: 64 points per revolution do not resolve the pin-passing order; 16 "
        "reducers of this study recomputed at 12480 points change te_pp_arcsec by at most" in table
    )
    assert "aliasing moves the yield by at most that much" in table


def test_a_study_that_resolves_the_pin_passing_order_needs_no_aliasing_check(tmp_path):
    from tolerance import aliasing

    study = load_study(write_study(tmp_path, operating={"points": 3200}))
    assert not aliasing.aliases(study)
    assert aliasing.check(study, np.zeros((1, len(study.columns))), np.zeros((1, 2))) is None


def test_no_order_below_the_noise_floor_is_listed():
    report = api.te("RV-110E", load=500.0, points=1248)
    listed = report.summary().split("largest orders", 1)[1].splitlines()[0]
    amplitudes = [float(part.split(":")[1].strip(" \u2033")) for part in listed.split(",")]
    assert amplitudes and min(amplitudes) >= metrics.NOISE_FLOOR_ARCSEC
    assert "0.000\u2033" not in listed
    flat_curve = dataclasses.replace(report.curve, te=np.full_like(report.curve.te, 1e-4))
    flat = dataclasses.replace(report, curve=flat_curve).summary()
    assert "largest orders    none above the noise floor of 0.001\u2033 (the TE is flat)" in flat


def test_the_no_load_mean_is_explained_and_a_loaded_one_is_not():
    no_load = api.te("RV-20E", points=64).summary()
    mean_line = next(line for line in no_load.splitlines() if line.startswith("mean"))
    assert "no load: the output's turn-back from its nominal place to the first contact" in mean_line
    assert "free play" in mean_line
    loaded = api.te("RV-20E", load=50.0, points=64).summary()
    assert "turn-back" not in loaded


def test_the_error_template_command_writes_a_file_that_loads_back_to_zero(tmp_path, capsys):
    from rvfmu.core.reducer.design import preset

    out = tmp_path / "my_errors.toml"
    assert cli.main(["errors", "--template", "RV-110E", "-o", str(out)]) == 0
    assert "wrote error template" in capsys.readouterr().out
    errors = load_errors(out, preset("RV-110E"))
    assert all(not np.any(array) for array in errors.arrays().values())
    assert cli.main(["errors", "--template", "RV-40E-121"]) == 0
    printed = capsys.readouterr().out
    assert printed.count("\npin_pitch = [") == 1 and "docs/model.md section 4" in printed
    assert cli.main(["errors", "--template", "RV-40E-121", "-o", str(tmp_path / "e.txt")]) == 2
    assert "output = " in capsys.readouterr().err


IMPORT_FIRST = """
import importlib, pkgutil, sys
import rvfmu, rvfmu.core
names = [m.name for m in pkgutil.walk_packages(rvfmu.__path__, "rvfmu.")]   # every room's modules too
failed = []
for name in names:
    for loaded in [k for k in sys.modules if k == "rvfmu" or k.startswith("rvfmu.")]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except Exception as exc:
        failed.append(f"{name}: {exc!r}")
for loaded in [k for k in sys.modules if k == "rvfmu" or k.startswith("rvfmu.")]:
    del sys.modules[loaded]
from rvfmu.core.reducer.design import preset
preset("RV-40E-121")
print(len(names), "modules;", "; ".join(failed) or "none failed")
"""


def test_every_module_imports_first_in_a_fresh_interpreter():
    """Whatever a script imports first works: a newcomer's `from rvfmu.core.reducer.design import
    preset` must not depend on another module having been imported before (an import cycle
    once broke exactly that)."""
    import os
    import subprocess
    import sys

    from conftest import ROOT

    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run(
        [sys.executable, "-c", IMPORT_FIRST], capture_output=True, text=True, env=env, cwd=ROOT, timeout=600
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("none failed"), proc.stdout
    assert int(proc.stdout.split()[0]) > 30


COMMAND_IMPORTS = """
import json, runpy, sys
unused, sys.argv = sys.argv[2:], ["rvte", *json.loads(sys.argv[1])]
try:
    runpy.run_module("rvfmu.cli", run_name="__main__")
except SystemExit as stop:
    assert not stop.code, stop.code
print(" ".join(m for m in unused if m in sys.modules) or "none")
"""

# What a command never uses, and what each would add to its start (import time here).
UNUSED_BY_TE = (
    "scipy.optimize",  # 0.3-0.7 s: only the lubricant's D2270 root, asked for by the losses
    "scipy.special",  # 0.2 s: only the studies' normal draws
    "scipy.stats",  # 1.1 s: only the Sobol analyses and the allocation
    "SALib",
    "pandas",
    "pyarrow",
    "distributed",
    "matplotlib",  # only with --plot
    "openturns",
)
UNUSED_BY_MC = ("scipy.optimize", "scipy.stats", "SALib", "distributed", "matplotlib", "openturns")


def loaded_by(args: list, unused: tuple) -> str:
    """The modules of `unused` that `rvte *args` loads in a fresh interpreter ("none")."""
    import json
    import subprocess
    import sys

    from conftest import ROOT

    proc = subprocess.run(
        [sys.executable, "-c", COMMAND_IMPORTS, json.dumps(args), *unused],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout.splitlines()[-1]


def test_the_te_command_loads_no_library_it_does_not_use():
    """`rvte te` starts in about 2 s, a third of it imports: the studies' libraries and the
    optimisers wait for the first command that needs them."""
    assert loaded_by(["te", "RV-40E-121", "--points", "36"], UNUSED_BY_TE) == "none"


def test_a_monte_carlo_loads_no_sobol_nor_plotting_library(tmp_path):
    """`rvte mc` (here without figures) needs the draws and the store, not SALib and
    scipy.stats, which the Sobol analyses import when they run."""
    path = write_study(tmp_path, montecarlo={"n": 8})
    args = ["mc", str(path), "-o", str(tmp_path / "out"), "--no-plots"]
    assert loaded_by(args, UNUSED_BY_MC) == "none"
    assert (tmp_path / "out" / "mc_summary.json").is_file()
