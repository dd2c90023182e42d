"""The figure of `rvte efficiency --plot`: the catalogue's charts against output torque and
against the lubricant's temperature (its low-temperature characteristic), their values in the
JSON, and what they must show of the load-free losses."""

import json

import numpy as np
import pytest
from test_hardening import run_cli

from rvfmu import api
from rvfmu.core.losses.friction import efficiency_map
from rvfmu.core.reducer.design import preset
from rvfmu.jobs.efficiency import CHART_LOAD_FRACTIONS, CHART_TEMPERATURES_C, EfficiencyReport
from rvfmu.plots import figure_efficiency

SPEEDS = (5.0, 15.0, 40.0)


@pytest.fixture(scope="module")
def plotted(tmp_path_factory):
    path = tmp_path_factory.mktemp("charts") / "efficiency.png"
    return api.efficiency("RV-40E-121", speeds=SPEEDS, plot_path=path), path


def test_the_charts_are_the_maps_of_the_same_reducer_at_their_torques_and_temperatures(plotted):
    report, path = plotted
    c, m = report.characteristics, report.map
    design = preset("RV-40E-121")
    assert path.read_bytes()[:4] == b"\x89PNG"
    np.testing.assert_array_equal(c.by_torque.load_Nm, design.rated_torque * np.array(CHART_LOAD_FRACTIONS))
    np.testing.assert_array_equal(c.by_torque.output_speed_rpm, SPEEDS)
    assert tuple(c.by_temperature) == CHART_TEMPERATURES_C
    # the chart's 40 C map is the report's own, solved again
    at_40 = c.by_temperature[40.0]
    np.testing.assert_array_equal(at_40.efficiency, m.efficiency)
    np.testing.assert_array_equal(at_40.no_load_running_torque_Nm, m.no_load_running_torque_Nm)
    # and the cold one that of efficiency_map at -10 C
    cold = efficiency_map(design, None, SPEEDS, m.load_Nm, temperature_C=-10.0)
    np.testing.assert_array_equal(c.by_temperature[-10.0].efficiency, cold.efficiency)


def test_the_charts_show_the_load_free_losses(plotted):
    c = plotted[0].characteristics
    # at every speed the efficiency rises with the torque: the load-free losses weigh less
    assert np.all(np.diff(c.by_torque.efficiency, axis=1) > 0.0)
    # the running torque rises as the oil cools, at every speed
    running = np.array([x.no_load_running_torque_Nm for x in c.by_temperature.values()])
    assert np.all(np.diff(running, axis=0) < 0.0)
    # and the efficiency at rated torque falls as it cools
    rated = np.array([x.efficiency[:, -1] for x in c.by_temperature.values()])
    assert np.all(np.diff(rated, axis=0) > 0.0)


def test_the_figure_has_its_five_charts_and_without_them_two(plotted):
    import matplotlib.pyplot as plt

    report = plotted[0]
    fig = figure_efficiency(report)
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == 5
    cold, running = visible[3], visible[4]
    assert [t.get_text() for t in running.get_legend().get_texts()] == [
        f"{t:g} °C" for t in CHART_TEMPERATURES_C
    ]
    assert len(visible[1].get_lines()) == len(SPEEDS) + 1  # one per speed and the rated line
    # the low-temperature characteristic: per speed, the running torque over the temperatures
    assert len(cold.get_lines()) == len(SPEEDS)
    x, y = cold.get_lines()[0].get_data()
    np.testing.assert_array_equal(x, CHART_TEMPERATURES_C)
    np.testing.assert_array_equal(
        y, [m.no_load_running_torque_Nm[0] for m in report.characteristics.by_temperature.values()]
    )
    plt.close(fig)
    fig = figure_efficiency(EfficiencyReport(report.map))
    assert len([ax for ax in fig.axes if ax.get_visible()]) == 2
    plt.close(fig)


def test_the_json_carries_the_charts_only_with_the_figure(tmp_path, capsys):
    plot = tmp_path / "e.png"
    code, out, err = run_cli(
        ["efficiency", "RV-40E-121", "--speeds", "15", "--loads", "412", "--json", "--plot", plot], capsys
    )
    assert code == 0, err
    data = json.loads(out)["characteristics"]
    assert [x["temperature_C"] for x in data["by_temperature"]] == list(CHART_TEMPERATURES_C)
    assert len(data["efficiency_by_torque"]["load_Nm"]) == len(CHART_LOAD_FRACTIONS)
    code, out, _ = run_cli(["efficiency", "RV-40E-121", "--speeds", "15", "--loads", "412", "--json"], capsys)
    assert code == 0 and "characteristics" not in json.loads(out)
