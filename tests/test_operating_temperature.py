"""The lubricant's temperature in a study: `[operating] temperature_C` for the friction metrics.

The friction metrics of a study (`efficiency`, `no_load_running_torque`) are those of
`rvfmu.core.losses.friction.operating_losses` at the study's output speed and, now, at its
lubricant temperature; the key is part of the study's identity only where a friction metric
is asked for, and a value outside the range Walther's equation is held over is refused by name.
"""

import numpy as np
import pytest
from tolerance_toy import write_study

from rvfmu.core.base.checks import InputError
from rvfmu.core.laws.lubricant import REFERENCE_TEMPERATURE_C
from rvfmu.core.losses.friction import operating_losses
from tolerance.evaluate import errors_from_unit, evaluate
from tolerance.study import load_study

FRICTION = {"metrics": ["no_load_running_torque"]}


def _study(tmp_path, name, temperature=None, study=FRICTION):
    operating = {"temperature_C": temperature} if temperature is not None else {}
    return load_study(write_study(tmp_path, name=name, study=study, operating=operating, spec={}))


def test_the_study_default_is_the_grades_temperature_and_the_results_of_before(tmp_path):
    default = _study(tmp_path, "default")
    assert default.temperature_C == REFERENCE_TEMPERATURE_C == 40.0
    X = np.random.default_rng(3).random((2, len(default.columns)))
    Y, ok = evaluate(default, X)
    errors = errors_from_unit(default, X)
    _, running, _ = operating_losses(default.design, errors, default.load_Nm, default.output_speed_rpm)
    assert ok.all()
    np.testing.assert_array_equal(Y[:, 0], running)


def test_a_cold_study_runs_its_friction_metric_at_its_temperature(tmp_path):
    warm, cold = _study(tmp_path, "warm"), _study(tmp_path, "cold", -10.0)
    X = np.random.default_rng(4).random((2, len(cold.columns)))
    Y_warm, _ = evaluate(warm, X)
    Y_cold, ok = evaluate(cold, X)
    _, running, _ = operating_losses(
        cold.design, errors_from_unit(cold, X), cold.load_Nm, cold.output_speed_rpm, temperature_C=-10.0
    )
    assert ok.all()
    np.testing.assert_array_equal(Y_cold[:, 0], running)
    # the oil is thicker in the cold: the load-free drag, and so the running torque, rises
    assert np.all(Y_cold[:, 0] > Y_warm[:, 0])


def test_the_temperature_is_part_of_the_identity_only_for_the_friction_metrics(tmp_path):
    warm, cold = _study(tmp_path, "warm"), _study(tmp_path, "cold", -10.0)
    assert warm.inputs()["operating"]["temperature_C"] == 40.0
    assert warm.inputs() != cold.inputs()
    te = {"metrics": ["te_pp"]}
    assert _study(tmp_path, "te40", study=te).inputs() == _study(tmp_path, "te0", 0.0, te).inputs()
    assert "temperature_C" not in _study(tmp_path, "te", study=te).inputs()["operating"]


@pytest.mark.parametrize("value", [200.0, -60.0, "cold"])
def test_a_temperature_outside_walthers_range_is_refused_by_name(tmp_path, value):
    with pytest.raises(InputError) as error:
        _study(tmp_path, "bad", value)
    text = str(error.value)
    assert "operating.temperature_C" in text and str(value) in text
    if not isinstance(value, str):
        assert "-40" in text and "150" in text
