"""What the TE figure shows (rvfmu/plots.py): the ripple's shape in a zoom where it matters."""

import pytest
from conftest import ROOT

from rvfmu.core.reducer.errors import load_errors
from rvfmu.core.statics.quasistatic import te_curve
from rvfmu.plots import RIPPLE_SHARE, figure_te, ripple


@pytest.fixture(scope="module")
def curves(rv40):
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", rv40)
    return {
        "nominal": te_curve(rv40, None, 0.0, 12480),
        "errors": te_curve(rv40, errors, 0.0, 12480),
        "coarse": te_curve(rv40, None, 0.0, 720),
    }


def test_the_nominal_ripple_gets_a_zoom_and_a_curve_with_errors_does_not(curves):
    """Without errors the TE is the pin-passing ripple alone (all of te_pp); with seed 002's
    errors the low orders dominate and the ripple is a few % of te_pp."""
    share, resolved = ripple(curves["nominal"])
    assert resolved and share == pytest.approx(curves["nominal"].te_pp_arcsec[0], rel=1e-3)
    assert len(figure_te(curves["nominal"]).axes) == 3
    share, resolved = ripple(curves["errors"])
    assert resolved and share < RIPPLE_SHARE * curves["errors"].te_pp_arcsec[0]
    assert len(figure_te(curves["errors"]).axes) == 2
    assert len(figure_te(curves["errors"], zoom=True).axes) == 3
    zoom = figure_te(curves["nominal"]).axes[1]
    left, right = zoom.get_xlim()
    assert right - left == pytest.approx(4 * 360.0 / 1560)  # four pin-passing periods


def test_an_unresolved_ripple_gets_no_zoom(curves):
    assert not ripple(curves["coarse"])[1]
    assert len(figure_te(curves["coarse"], zoom=True).axes) == 2
