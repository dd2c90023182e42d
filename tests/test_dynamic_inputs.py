"""The dynamic model's drive and load in time, its compiled kernel against plain numpy, bad input."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import rad_to_arcsec
from rvfmu.core.dynamics import kernels
from rvfmu.core.dynamics.dynamic import DynamicModel, ramp_motion
from rvfmu.core.dynamics.simulation import Sampled, simulate
from rvfmu.core.statics.equivalent import EquivalentModel
from rvfmu.core.statics.quasistatic import equilibrium_te

ROOT = Path(__file__).resolve().parents[1]


def random_errors(design, seed):
    """One reducer with every error drawn at a few micrometres (complex ones in any direction)."""
    from rvfmu.core.reducer.errors import ErrorSet, zero_errors

    rng = np.random.default_rng(seed)
    arrays = {}
    for name, array in zero_errors(design).arrays().items():
        draw = rng.normal(0.0, 3e-6, array.shape)
        if np.iscomplexobj(array):
            draw = draw + 1j * rng.normal(0.0, 3e-6, array.shape)
        arrays[name] = np.abs(draw) if "clearance" in name else draw
    return ErrorSet(**arrays)


@pytest.mark.parametrize("name", ["RV-40E-121", "RV-110E", "RV-20E"])
def test_the_compiled_element_geometry_is_the_numpy_geometry(name):
    """`DynamicModel._chunk` (compiled) against `_chunk_numpy` (from EquivalentModel) at 600
    random steps (angles over many turns, speeds and accelerations of either sign, loads):
    every array of every element equal to round-off, on both flanks, with the mesh
    stiffness varying and constant, with the friction's drags and without."""
    from rvfmu.core.dynamics.dynamic import Motion
    from rvfmu.core.reducer.design import preset

    assert kernels.COMPILED, "numba is a dependency: the element geometry must compile"
    design = preset(name)
    rng = np.random.default_rng(7)
    T = 640
    motion = Motion(
        np.sort(rng.uniform(0.0, 3.0, T)),
        rng.uniform(-3e3, 3e3, T),
        rng.uniform(-300.0, 300.0, T),
        rng.uniform(-2e3, 2e3, T),
        rng.uniform(-2e3, 2e3, T),
    )
    for flank, mesh, friction in ((1, "varying", True), (-1, "constant", False)):
        model = DynamicModel(design, random_errors(design, 11), mesh=mesh, flank=flank, friction=friction)
        model.prepare(motion)
        for start, stop in ((0, 1), (3, 620)):
            compiled, reference = model._chunk(start, stop), model._chunk_numpy(start, stop)
            for field, x, y in zip(reference._fields, compiled, reference):
                assert x.shape == y.shape and x.dtype == y.dtype and x.flags.c_contiguous, field
                np.testing.assert_allclose(
                    x,
                    y,
                    rtol=0,
                    atol=1e-13 * max(np.abs(y).max(), 1e-300),
                    err_msg=f"{name} {field} flank {flank}",
                )
        drags = model._chunk(3, 620).turn_drag
        assert (np.count_nonzero(drags) > 0) == friction


def test_every_element_row_lies_on_the_unknowns_the_kernel_loops_over(rv40, seed002):
    model = DynamicModel(rv40, seed002)
    angles = np.random.default_rng(3).uniform(0.0, 2 * np.pi * rv40.ratio, 2000)
    dense = EquivalentModel(rv40, angles, 1, sun_rotation=True)
    for rows, cols in ((dense.linear_rows, model._linear_cols), (dense.bearing_rows, model._bearing_cols)):
        coefficients = kernels.gather(rows, cols)
        rebuilt = np.zeros_like(rows)
        for e in range(cols.shape[0]):
            for x, col in enumerate(cols[e]):
                if col >= 0:
                    rebuilt[:, e, ..., col] = coefficients[:, e, ..., x]
        np.testing.assert_array_equal(rebuilt, rows)


def test_sampled_input_angles_reproduce_the_ramp_run(rv40, seed002):
    ramped = simulate(rv40, seed002, speed_rpm=300.0, load=200.0, duration=0.05, ramp=0.05, mesh="constant")
    samples = np.linspace(0.0, ramped.time[-1], 400)
    angles = ramp_motion(samples, 300.0 * 2 * np.pi / 60, 0.05).theta_in
    sampled = simulate(
        rv40,
        seed002,
        load=200.0,
        input_angle=Sampled.checked("input", samples, angles),
        mesh="constant",
        step=ramped.step,
    )
    assert sampled.drive == "sampled" and sampled.steady == 0
    assert sampled.time.size == ramped.time.size
    np.testing.assert_allclose(sampled.theta_in, ramped.theta_in, atol=1e-6)
    te_range = np.ptp(ramped.steady_te_arcsec())
    steady = slice(ramped.steady, None)
    assert np.max(np.abs(sampled.te_arcsec[steady] - ramped.te_arcsec[steady])) < 0.02 * te_range


def test_a_constant_sampled_load_is_the_constant_load(rv40, seed002):
    constant = simulate(rv40, seed002, speed_rpm=600.0, load=150.0, duration=0.01, ramp=0.01)
    sampled = simulate(
        rv40,
        seed002,
        speed_rpm=600.0,
        duration=0.01,
        ramp=0.01,
        load=Sampled.checked("load", [0.0, 1.0], [150.0, 150.0]),
    )
    np.testing.assert_array_equal(sampled.te, constant.te)


def test_after_a_load_step_the_te_settles_on_the_quasi_static_te_at_the_new_load(rv40, seed002):
    # slow and well damped: the step rings out, then the static windup at the new load remains
    design = rv40.with_fields(damping_ratio=0.2)
    sim = simulate(
        design,
        seed002,
        speed_rpm=10.0,
        load=Sampled.step(100.0, 0.3, 400.0),
        duration=0.5,
        ramp=0.2,
        mesh="constant",
    )
    assert sim.failed_steps == 0
    for low, high, load in ((0.25, 0.3, 100.0), (0.6, 0.7, 400.0)):
        inside = (sim.time >= low) & (sim.time < high)
        te, _, _ = equilibrium_te(design, seed002, sim.theta_in[inside][::20], [-load])
        static = rad_to_arcsec(te[0, 0])
        np.testing.assert_allclose(sim.te_arcsec[inside][::20], static, atol=0.02 * abs(static).max())
    assert np.allclose(-sim.tau_load[sim.time >= 0.3], 400.0)


@pytest.mark.parametrize(
    "time, values, message",
    [
        ([0.0, 0.1, 0.2, 0.3], [0.0, np.nan, 2.0, 3.0], "value nan at sample 2"),
        ([0.0, 0.1, np.inf, 0.3], [0.0, 1.0, 2.0, 3.0], "time inf at sample 3"),
        ([0.0, 0.1, 0.1, 0.3], [0.0, 1.0, 2.0, 3.0], "times must increase strictly"),
        ([0.0, 0.1], [0.0, 1.0], "at least 4 samples"),
    ],
)
def test_bad_sampled_input_is_refused_naming_the_sample(time, values, message):
    with pytest.raises(InputError, match=message):
        Sampled.checked("input_csv", time, values, at_least=4)


def test_a_sampled_input_that_does_not_turn_forward_is_refused(rv40):
    backwards = Sampled.checked("input", [0.0, 0.1, 0.2, 0.3], [0.0, -1.0, -2.0, -3.0])
    with pytest.raises(InputError, match="positive mean speed"):
        simulate(rv40, input_angle=backwards)
    forward = Sampled.checked("input", [0.0, 0.1, 0.2, 0.3], [0.0, 1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="duration"):
        simulate(rv40, input_angle=forward, duration=1.0)


def rvte(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "rvfmu.cli", *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


def test_cli_runs_sampled_input_and_a_load_step_and_refuses_bad_files(tmp_path):
    angles = tmp_path / "input.csv"
    t = np.linspace(0.0, 0.05, 51)
    angles.write_text("time_s,theta_in_rad\n" + "".join(f"{a:.6g},{60.0 * a:.9g}\n" for a in t))
    proc = rvte(
        "simulate",
        "RV-40E-121",
        "--input-csv",
        str(angles),
        "--load",
        "100",
        "--load-step",
        "0.02:300",
        "--json",
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["drive"] == "sampled" and summary["load_Nm"] == [100.0, 300.0]
    assert summary["speed_rpm"] == pytest.approx(60.0 * 60 / (2 * np.pi))
    bad = tmp_path / "bad.csv"
    for text, message in (
        ("time_s,theta_in_rad\n0,0\n0.01,nan\n0.02,1\n0.03,2\n", "nan at sample 2"),
        ("time_s,angle\n0,0\n", "missing: theta_in_rad"),
        ("time_s,theta_in_rad\n0,0\n0.01,x\n", "'x' in column theta_in_rad on line 3"),
    ):
        bad.write_text(text)
        proc = rvte("simulate", "RV-40E-121", "--input-csv", str(bad))
        assert proc.returncode == 2 and message in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1
    proc = rvte("simulate", "RV-40E-121", "--load-csv", str(tmp_path / "absent.csv"))
    assert proc.returncode == 2 and "load_csv" in proc.stderr and "existing CSV" in proc.stderr


def test_the_compiled_kernel_and_plain_numpy_give_the_same_run(rv40, seed002):
    assert kernels.COMPILED, "numba is a dependency: the compiled kernel must be the one in use"
    compiled = simulate(
        rv40, seed002, speed_rpm=1600.0, load=206.0, duration=0.005, ramp=0.005, contact="impact"
    )
    script = (
        "import sys, numpy as np\n"
        "from rvfmu.core.dynamics import kernels\n"
        "from rvfmu.core.reducer.design import preset\n"
        "from rvfmu.core.reducer.errors import load_errors\n"
        "from rvfmu.core.dynamics.simulation import simulate\n"
        "assert not kernels.COMPILED\n"
        f"d = preset({rv40.name!r}).with_fields(needle_rollers={rv40.needle_rollers}, "
        f"tapered_rollers={rv40.tapered_rollers})\n"
        "e = load_errors(sys.argv[1], d)\n"
        "s = simulate(d, e, speed_rpm=1600.0, load=206.0, duration=0.005, ramp=0.005,"
        " contact='impact')\n"
        "np.save(sys.argv[2], s.te)\n"
    )
    out = Path(os.environ.get("TMPDIR", "/tmp")) / f"plain_te_{os.getpid()}.npy"
    env = dict(os.environ, RVTE_NUMBA="0")
    proc = subprocess.run(
        [sys.executable, "-c", script, str(ROOT / "studies" / "seed002_errors.toml"), str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    plain = np.load(out)
    out.unlink()
    np.testing.assert_allclose(plain, compiled.te, rtol=0, atol=1e-9 * np.ptp(compiled.te))


def test_the_default_step_resolves_the_excitations_and_the_modes_they_reach(rv40):
    from rvfmu.core.dynamics.simulation import (
        NATURAL_STEPS_PER_PERIOD,
        STEPS_PER_PERIOD,
        Excitations,
        default_step,
    )

    ex = Excitations.at(rv40, 1600.0)
    fastest = max(ex.pin_passing, ex.mesh)
    assert default_step(rv40, 1600.0) == pytest.approx(1.0 / (STEPS_PER_PERIOD * fastest))
    # a mode just below twice the fastest excitation sets the step; one above it does not
    reached = 1.9 * fastest
    assert default_step(rv40, 1600.0, [100.0, reached]) == pytest.approx(
        1.0 / (NATURAL_STEPS_PER_PERIOD * reached)
    )
    assert default_step(rv40, 1600.0, [100.0, 2.1 * fastest]) == default_step(rv40, 1600.0)


def test_the_output_speed_integrates_to_the_output_angle(rv40, seed002):
    # average acceleration: q_{n+1} - q_n = h (v_n + v_{n+1}) / 2 exactly, and the nominal
    # angle is linear at constant speed, so the trapezoid of omega_out is theta_out's change
    sim = simulate(rv40, seed002, speed_rpm=1600.0, load=206.0, duration=0.05, ramp=0.02)
    w, th = sim.omega_out[sim.steady :], sim.theta_out[sim.steady :]
    travelled = np.cumsum(0.5 * sim.step * (w[1:] + w[:-1]))
    np.testing.assert_allclose(travelled, th[1:] - th[0], rtol=0, atol=1e-9 * (th[-1] - th[0]))
    ripple = w - 1600.0 * 2 * np.pi / 60 / rv40.ratio
    assert 0.0 < np.abs(ripple).max() < 0.05 * 1600.0 * 2 * np.pi / 60 / rv40.ratio
