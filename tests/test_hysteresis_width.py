"""The hysteresis loop's width (`rvte hysteresis`): the unloading branch's angle less the
loading one's at the same torque, against closed forms on synthetic loops, against the
loop's own path and friction torques on the RV-40E-121, in the JSON and in the figure."""

import dataclasses
import json

import numpy as np
import pytest
from test_friction import NO_FRICTION
from test_hardening import run_cli

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCMIN
from rvfmu.core.losses.hysteresis import hysteresis
from rvfmu.core.reducer.design import preset
from rvfmu.jobs.hysteresis import HysteresisReport, branch_angle, loop_width, width_reach
from rvfmu.plots import INSET_FRICTION_TORQUES, figure_hysteresis


@pytest.fixture(scope="module")
def rv40_121():
    """The preset as shipped, calibrated to the catalogue: what `rvte hysteresis` runs."""
    return preset("RV-40E-121")


@pytest.fixture(scope="module")
def report(rv40_121):
    return HysteresisReport(hysteresis(rv40_121))


def closed_loop(up: np.ndarray, down: np.ndarray) -> np.ndarray:
    """A loop array (2 N, 2) as `HysteresisLoop.loop` holds it: up the loading branch, back
    down the unloading one (both given in ascending angle)."""
    return np.concatenate([up, down[::-1]])


def close_figure(fig):
    import matplotlib.pyplot as plt

    plt.close(fig)


# -- synthetic loops: the width against its closed form -----------------------------------------


def test_a_constant_angle_offset_between_the_branches_is_the_width_everywhere(report):
    """Branches on the same torques, the unloading one 0.5 arcmin above along a curved path:
    the width is 0.5 arcmin at every torque, on the corners and between them."""
    torque = np.linspace(-300.0, 300.0, 41)
    angle = (0.01 * torque + 0.3 * np.tanh(torque / 20.0)) * ARCMIN
    offset = 0.5
    loop = closed_loop(np.column_stack([torque, angle]), np.column_stack([torque, angle + offset * ARCMIN]))
    synthetic = HysteresisReport(dataclasses.replace(report.loop, loop=loop))
    queries = np.concatenate([torque, np.linspace(-299.9, 299.9, 307)])
    np.testing.assert_allclose(synthetic.width_arcmin(queries), offset, rtol=0, atol=1e-12)
    assert synthetic.width_at_zero_arcmin == pytest.approx(offset, abs=1e-12)
    np.testing.assert_array_equal(synthetic.width_torques_Nm, torque)
    assert width_reach(loop) == (-300.0, 300.0)


def test_a_linear_path_shifted_by_the_friction_torque_is_twice_it_over_the_rigidity(report):
    """The construction of `core.hysteresis` on a path theta = tau / k: branches at tau + c
    (loading) and tau - c (unloading), so the width is 2 c / k [arcmin] wherever both reach
    (-max + c to max - c), and nowhere else."""
    k, c, top = 108.0, 2.25, 412.0  # N*m/arcmin, N*m, N*m
    tau = np.linspace(-top, top, 81)
    up = np.column_stack([tau + c, tau / k * ARCMIN])
    down = np.column_stack([tau - c, tau / k * ARCMIN])
    loop = closed_loop(up, down)
    assert width_reach(loop) == pytest.approx((-top + c, top - c), abs=1e-12)
    queries = np.linspace(-top + c, top - c, 333)
    np.testing.assert_allclose(loop_width(loop, queries) / ARCMIN, 2.0 * c / k, rtol=1e-12)
    synthetic = HysteresisReport(dataclasses.replace(report.loop, loop=loop))
    assert synthetic.width_max_arcmin == pytest.approx(2.0 * c / k, rel=1e-12)


def test_a_branch_whose_torque_steps_back_is_read_where_the_output_has_got_to():
    """Loading (0, 0) -> (2, 1) -> (1, 1) -> (3, 2): past the step back the output turns on at
    once, to where the last segment climbs past 2 N*m again (angle 1.5); by hand:
    0.75 at 1.5 N*m, 1.5 at 2 N*m, 1.75 at 2.5 N*m.  Unloading (ascending angle)
    (-1, 0), (1, 1), (0, 1), (2, 2), the torque falling from the top: 1.25 at 0.5 N*m, 0.5 at
    0 N*m (where the segment from (1, 1) falls below 0 again), 0.25 at -0.5 N*m."""
    up = np.array([[0.0, 0.0], [2.0, 1.0], [1.0, 1.0], [3.0, 2.0]])
    np.testing.assert_allclose(
        branch_angle(up, np.array([1.5, 2.0, 2.5, 3.0]), True), [0.75, 1.5, 1.75, 2.0], rtol=0, atol=1e-15
    )
    down = np.array([[-1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [2.0, 2.0]])
    np.testing.assert_allclose(
        branch_angle(down, np.array([0.5, 0.0, -0.5, -1.0]), False),
        [1.25, 0.5, 0.25, 0.0],
        rtol=0,
        atol=1e-15,
    )


def test_torques_the_branches_do_not_both_reach_are_refused(report):
    lo, hi = width_reach(report.loop.loop)
    assert lo == pytest.approx(-412.0 + report.loop.friction_torque[0], abs=1e-9)
    assert hi == pytest.approx(412.0 - report.loop.friction_torque[-1], abs=1e-9)
    with pytest.raises(InputError) as err:
        report.width_arcmin([0.0, 412.0])
    assert err.value.field == "torques" and err.value.value == 412.0
    assert str(err.value) == (
        f"torques = 412.0: must be within {lo:.6g} to {hi:.6g} N*m, "
        "the torques both branches of the loop reach"
    )
    with pytest.raises(InputError, match=r"^torques = \[0.0, nan\]: must be a list of finite "):
        report.width_arcmin([0.0, float("nan")])
    with pytest.raises(InputError, match=r"^torques = 'zero': must be output torques \[N\*m\]"):
        report.width_arcmin("zero")


# -- RV-40E-121: the width the loop's friction gives -----------------------------------------------


def test_rv40_width_is_the_path_read_at_plus_and_minus_the_friction_torque(report):
    """Where an interval's shifted segments hold torque tau on both branches (tau +- T_f inside
    the interval, the neighbours' segments not reaching over it), the width there is the
    frictionless path at tau + T_f less the path at tau - T_f: 84 torques of the default
    sweep (the output seal's 0.5 N*m from its law widens T_f near zero), exact to round-off."""
    h = report.loop
    tau, path, t_f = h.tau_load, h.windup, h.friction_torque
    mid = 0.5 * (tau[1:] + tau[:-1])
    before = np.concatenate([[np.inf], t_f[:-1]])
    after = np.concatenate([t_f[1:], [np.inf]])
    held = (
        (mid - t_f >= tau[:-1])
        & (mid + t_f <= tau[1:])
        & (tau[:-1] + before <= mid)
        & (tau[1:] - after >= mid)
    )
    assert held.sum() == 84
    expected = (
        np.interp(mid[held] + t_f[held], tau, path) - np.interp(mid[held] - t_f[held], tau, path)
    ) / ARCMIN
    np.testing.assert_allclose(report.width_arcmin(mid[held]), expected, rtol=1e-12)


def test_rv40_width_is_positive_and_of_the_size_of_the_loops_friction(report):
    h = report.loop
    width = report.width_arcmin()
    assert width.shape == report.width_torques_Nm.shape and np.all(width > 0.0)
    # loaded: the path's slope (the record's rigidity, 50-100 % rated) times 2 T_f there
    for torque in (-300.0, 300.0):
        t_f = h.friction_torque[np.searchsorted(h.tau_load, torque) - 1]
        assert report.width_arcmin(torque)[0] == pytest.approx(
            2.0 * t_f / h.torsional_rigidity_Nm_per_arcmin, rel=0.02
        )
    # at zero torque: the record's hysteresis loss (the path at +-T_f across the clearance)
    assert report.width_at_zero_arcmin == pytest.approx(h.hysteresis_loss_arcmin, rel=2e-3)
    # the widest is where the branches cross the clearance, within T_f of zero
    assert report.width_max_arcmin == width.max() >= report.width_at_zero_arcmin
    assert abs(report.width_max_torque_Nm) <= h.friction_torque.max()
    # 1.35 arcsec before the output seal's law (0.496 N*m) joined the loop's friction
    assert 60.0 * report.width_arcmin(206.0)[0] == pytest.approx(1.91, abs=0.005)


def test_without_friction_the_branches_are_one_line(rv40_121):
    free = HysteresisReport(hysteresis(rv40_121.with_fields(**NO_FRICTION), positions=4))
    # the same corners on both branches: zero but for the round-off of reading them
    np.testing.assert_allclose(free.width_arcmin(), 0.0, rtol=0, atol=1e-15)
    fig = figure_hysteresis(free)
    try:
        assert fig.axes[1].child_axes == [] and fig.axes[2].get_yscale() == "linear"
    finally:
        close_figure(fig)


# -- what the engineer gets: JSON, summary, figure ----------------------------------------------


def test_json_and_summary_carry_the_width(report, capsys, tmp_path):
    plot = tmp_path / "loop.png"
    code, out, err = run_cli(["hysteresis", "RV-40E-121", "--json", "--plot", plot], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert data["width_at_zero_arcmin"] == pytest.approx(report.width_at_zero_arcmin, rel=1e-12)
    assert data["width_max_arcmin"] == pytest.approx(report.width_max_arcmin, rel=1e-12)
    assert data["width_max_torque_Nm"] == pytest.approx(report.width_max_torque_Nm, rel=1e-12)
    assert plot.read_bytes()[:4] == b"\x89PNG" and plot.stat().st_size > 20_000
    line = next(x for x in report.summary().splitlines() if x.startswith("loop width"))
    assert line == (
        f"loop width         {60 * report.width_at_zero_arcmin:.3g} arcsec at zero "
        f"torque, {60 * report.width_arcmin(206.0)[0]:.3g} arcsec at 206 N*m (the "
        "unloading branch's angle less the loading one's)"
    )


def test_the_figure_draws_the_width_and_the_branches_apart(report):
    h = report.loop
    fig = figure_hysteresis(report)
    try:
        whole, middle, width = fig.axes
        assert len(fig.axes) == 3
        # the width panel draws the record's width, in arcsec, on a log scale
        torque, arcsec = width.lines[0].get_data()
        np.testing.assert_array_equal(torque, report.width_torques_Nm)
        np.testing.assert_allclose(arcsec, 60.0 * report.width_arcmin(), rtol=1e-15)
        assert width.get_yscale() == "log" and "arcsec" in width.get_ylabel()
        # the inset: the two branches apart over +-5 friction torques at zero
        (inset,) = middle.child_axes
        assert [line.get_label() for line in inset.lines[:2]] == ["loading", "unloading"]
        mid = 0.5 * (h.tau_load[1:] + h.tau_load[:-1])
        held = float(np.interp(0.0, mid, h.friction_torque))
        assert inset.get_xlim() == pytest.approx(
            (-INSET_FRICTION_TORQUES * held, INSET_FRICTION_TORQUES * held)
        )
        half = h.loop.shape[0] // 2
        np.testing.assert_array_equal(inset.lines[0].get_xydata()[:, 0], h.loop[:half, 0])
    finally:
        close_figure(fig)
