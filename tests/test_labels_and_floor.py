"""The noise floor of the order spectrum, the TE figure, human labels of the study figures,
and the S1 > ST note of the Sobol table."""

import numpy as np
import pytest
from tolerance_toy import write_study

from rvfmu.core.base.units import rad_to_arcsec
from rvfmu.core.reducer.design import preset
from rvfmu.core.statics.metrics import (
    NOISE_FLOOR_ARCSEC,
    NOISE_FLOOR_RELATIVE,
    highest_significant_order,
    largest_orders,
    noise_floor,
    significant_orders,
)
from rvfmu.core.statics.quasistatic import TECurve, input_angles
from tolerance import sobol, summaries
from tolerance.montecarlo import analyze as analyze_mc
from tolerance.study import load_study

N = 280


def angles(n=N):
    return 2.0 * np.pi * np.arange(n) / n


# -- 1. noise floor ---------------------------------------------------------------------------


def test_floor_values_and_their_ground():
    from rvfmu.core.statics import solver

    assert NOISE_FLOOR_ARCSEC == 1e-3
    # The relative floor is the solver's regularisation: finer than that the model says nothing.
    assert NOISE_FLOOR_RELATIVE == solver.REGULARISATION == 1e-6


def test_a_flat_te_has_no_significant_order():
    rng = np.random.default_rng(1)
    te = np.stack(
        [
            np.full(N, -73.2) + 1e-12 * rng.standard_normal(N),  # round-off on a windup
            np.zeros(N),
        ]
    )
    orders, amplitudes = significant_orders(te)
    assert [o.size for o in orders] == [0, 0] and [a.size for a in amplitudes] == [0, 0]
    np.testing.assert_array_equal(highest_significant_order(te), [0, 0])
    np.testing.assert_array_equal(noise_floor(te), [NOISE_FLOOR_ARCSEC] * 2)
    # largest_orders keeps its contract: always `count` orders, here round-off.
    o, a = largest_orders(te, count=5)
    assert o.shape == a.shape == (2, 5) and np.all(a < 1e-10)


def test_significant_orders_drop_those_below_the_floor():
    theta = angles()
    te = (
        4.0
        + 3.0 * np.sin(7 * theta)
        + 1.5 * np.cos(2 * theta + 0.3)
        + 2e-3 * np.sin(40 * theta)
        + 5e-4 * np.cos(90 * theta)
        + 1e-9 * np.sin(120 * theta)
    )
    orders, amplitudes = significant_orders(te, count=5)
    np.testing.assert_array_equal(orders[0], [7, 2, 40])  # 90 and 120 are below 1e-3
    np.testing.assert_allclose(amplitudes[0], [3.0, 1.5, 2e-3], rtol=1e-9)
    assert highest_significant_order(te)[0] == 40
    orders, _ = significant_orders(te, count=2)
    np.testing.assert_array_equal(orders[0], [7, 2])


def test_the_relative_floor_scales_with_the_largest_harmonic():
    theta = angles()
    # 5000" of order 1 (a deliberately huge curve): its floor is 5e-3", so 2e-3" at 40 is noise.
    te = 5000.0 * np.sin(theta) + 2e-3 * np.sin(40 * theta) + 0.01 * np.sin(60 * theta)
    assert noise_floor(te)[0] == pytest.approx(5000.0 * NOISE_FLOOR_RELATIVE)
    orders, _ = significant_orders(te)
    np.testing.assert_array_equal(orders[0], [1, 60])
    assert highest_significant_order(te)[0] == 60


def test_significant_orders_per_curve_of_a_batch():
    theta = angles()
    te = np.stack([np.sin(3 * theta) + 2.0 * np.sin(5 * theta), np.full(N, 2.0), 0.5 * np.sin(100 * theta)])
    orders, amplitudes = significant_orders(te, count=3)
    assert len(orders) == len(amplitudes) == 3
    np.testing.assert_array_equal(orders[0], [5, 3])
    assert orders[1].size == 0
    np.testing.assert_array_equal(orders[2], [100])
    np.testing.assert_array_equal(highest_significant_order(te), [5, 0, 100])


# -- 2. TE figure -----------------------------------------------------------------------------


def fake_curve(te_arcsec, design="RV-40E-121"):
    """A TECurve of one reducer whose TE is given [arcsec], on len(te_arcsec) points."""
    d = preset(design)
    te = np.atleast_2d(te_arcsec) / rad_to_arcsec(1.0)
    theta_in = input_angles(d, te.shape[-1])
    return TECurve(d, -100.0, theta_in, theta_in / d.ratio + te, te, np.ones(1, bool), np.zeros_like(te))


def spectrum_texts(fig):
    ax_sp = fig.axes[-1]  # the spectrum: the last panel (a zoom may sit above it)
    return ax_sp, [t.get_text() for t in ax_sp.texts]


def test_te_figure_markers_and_order_axis():
    from rvfmu.plots import figure_te

    d = preset("RV-40E-121")
    pin = d.z_p * d.z_c
    points = 8 * pin
    theta = angles(points)
    te = -20.0 + 3.0 * np.sin(d.z_p * theta) + 1.0 * np.sin(pin * theta) + 1e-11 * np.sin(3000 * theta)
    ax_sp, texts = spectrum_texts(figure_te(fake_curve(te)))
    assert any(t.startswith("crank order (z_p)") for t in texts)
    assert any(t.startswith("pin-passing order (z_p·z_c)") for t in texts)
    assert not any("crank in carrier" in t or "pin passing" in t for t in texts)
    assert ax_sp.get_xlabel() == "order [cycles per output revolution]"
    # The axis ends a little beyond the pin-passing order, far from the Nyquist order 4 * pin.
    left, right = ax_sp.get_xlim()
    assert pin < right < 2 * pin
    # Only the two orders above the floor are drawn.
    (lines,) = ax_sp.collections
    assert len(lines.get_segments()) == 2


def test_te_figure_of_a_flat_te_says_so():
    from rvfmu.plots import figure_te

    ax_sp, texts = spectrum_texts(figure_te(fake_curve(np.full(96, -73.2))))
    assert "flat TE: no order above the noise floor of 0.001″" in texts
    assert sum(len(c.get_segments()) for c in ax_sp.collections) == 0
    # Markers still shown: the crank order 40 within Nyquist 48, the pin-passing one aliased.
    assert any(t == "crank order (z_p) = 40" for t in texts)
    assert any("aliased to" in t for t in texts)
    assert ax_sp.get_xlim()[1] < 100


def test_plot_te_still_writes_the_file(tmp_path):
    from rvfmu.plots import plot_te

    path = plot_te(fake_curve(np.sin(40 * angles(480))), tmp_path / "te.png")
    assert path.is_file() and path.stat().st_size > 0


# -- 3. human labels --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "column, label",
    [
        ("te_pp_arcsec", "TE peak-to-peak [arcsec]"),
        ("rms_arcsec", "TE RMS about the mean [arcsec]"),
        ("lost_motion_arcmin", "lost motion [arcmin]"),
        ("torsional_rigidity_Nm_per_arcmin", "torsional rigidity [N·m/arcmin]"),
        ("order_40_arcsec", "TE order 40 amplitude [arcsec]"),
        ("order_1560_arcsec", "TE order 1560 amplitude [arcsec]"),
        ("something_else", "something_else"),
    ],
)
def test_column_label(column, label):
    assert summaries.column_label(column) == label


COLUMNS = (
    "te_pp_arcsec",
    "rms_arcsec",
    "lost_motion_arcmin",
    "torsional_rigidity_Nm_per_arcmin",
    "order_40_arcsec",
)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    path = write_study(
        tmp_path_factory.mktemp("labels"),
        study={"metrics": ["te_pp", "rms", "lost_motion", "torsional_rigidity", "order_40"]},
        operating={"points": 128},
        spec={"te_pp_arcsec": 30.0, "torsional_rigidity_Nm_per_arcmin": 300.0},
    )
    study = load_study(path)
    assert study.metric_columns == COLUMNS
    return study


def fake_outputs(X):
    """Five metric columns from the unit rows X: cheap, varied, no model."""
    a, b = X[:, 0], X[:, -1]
    return np.column_stack([20 + 20 * a, 5 + 4 * a * b, 1 + 0.5 * b, 350 - 100 * a * b, 2 * a + b])


def all_texts(fig):
    """Every axis label, title and legend text of a figure."""
    texts = [fig._suptitle.get_text()] if fig._suptitle else []
    for ax in fig.axes:
        texts += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
        legend = ax.get_legend()
        if legend is not None:
            texts += [t.get_text() for t in legend.get_texts()]
    return texts


def no_column_names(texts):
    for text in texts:
        for column in COLUMNS:
            assert column not in text, (column, text)


def test_mc_figure_labels_are_for_people(study, tmp_path):
    rng = np.random.default_rng(3)
    Y = fake_outputs(rng.random((40, len(study.columns))))
    analysis = analyze_mc(study, Y, np.ones(40, bool))
    fig = summaries.figure_mc(study, Y, analysis)
    assert len(fig.axes) == 2 * len(COLUMNS)
    for j, column in enumerate(COLUMNS):
        ax_h, ax_c = fig.axes[2 * j], fig.axes[2 * j + 1]
        assert ax_h.get_xlabel() == ax_c.get_xlabel() == summaries.column_label(column)
        assert ax_h.get_ylabel() == "reducers"
        assert summaries.column_label(column) in ax_c.get_title()
    te_pp_legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert te_pp_legend == ["spec ≤ 30 arcsec"]
    rigidity_legend = [t.get_text() for t in fig.axes[6].get_legend().get_texts()]
    assert rigidity_legend == ["spec ≥ 300 N·m/arcmin"]
    assert "yield" in fig.axes[1].get_title()
    no_column_names(all_texts(fig))
    path = summaries.plot_mc(study, Y, analysis, tmp_path / "mc.png")  # the writer still works
    assert path.is_file()


@pytest.fixture(scope="module")
def analyses(study):
    problem = study.problem()
    X = sobol.sample(problem, 16, seed=2)
    return sobol.analyze(problem, fake_outputs(X), study.metric_columns, resamples=50, seed=2)


def test_sobol_figures_labels_are_for_people(study, analyses, tmp_path):
    bars = summaries.figure_sobol(study, analyses)
    assert len(bars.axes) == len(COLUMNS)
    for ax, column in zip(bars.axes, COLUMNS):
        assert ax.get_title().startswith(summaries.column_label(column) + ":")
        assert ax.get_ylabel() == "Sobol index (share of variance)"
        assert [t.get_text() for t in ax.get_xticklabels()][0] in study.groups
    no_column_names(all_texts(bars))
    conv = summaries.figure_convergence(study, analyses)
    for ax, column in zip(conv.axes, COLUMNS):
        assert ax.get_title().startswith(summaries.column_label(column) + ":")
        assert ax.get_xlabel() == "base samples N" and ax.get_ylabel() == "total Sobol index ST"
    no_column_names(all_texts(conv))
    assert summaries.plot_sobol(study, analyses, tmp_path / "bars.png").is_file()
    assert summaries.plot_convergence(study, analyses, tmp_path / "conv.png").is_file()


def test_tables_and_json_keep_the_column_names(study, analyses):
    text = summaries.sobol_table(study, analyses, 16, 16 * 5, False)
    assert "te_pp_arcsec  (S1, ST" in text
    data = summaries.sobol_json(study, analyses, 16, 80, False, {})
    assert set(data["metrics"]) == set(COLUMNS)


# -- 4. S1 > ST -------------------------------------------------------------------------------


def test_s1_above_st_beyond_their_intervals_is_flagged():
    S1 = np.array([0.015, 0.015, 0.60, 0.30])
    S1_conf = np.array([0.005, 0.012, 0.05, 0.02])
    ST = np.array([0.004, 0.004, 0.55, 0.50])
    ST_conf = np.array([0.003, 0.003, 0.05, 0.04])
    ind = sobol.Indices(
        ("pin_radial", "within", "overlap", "fine"), 64, S1, S1_conf, ST, ST_conf, None, None, 0.95
    )
    flags = ind.flags()
    assert flags[0] == ["S1 0.015 > ST 0.004 beyond their CIs: sampling noise, raise n"]
    assert flags[1] == []  # 0.015 - 0.012 < 0.004 + 0.003: within the noise, no note
    assert flags[2] == []  # 0.60 - 0.05 < 0.55 + 0.05
    assert flags[3] == []


def test_the_sobol_table_explains_its_notes(study):
    G = len(study.groups)
    S1 = np.full(G, 0.2)
    S1[0] = 0.015
    ST = np.full(G, 0.3)
    ST[0] = 0.004
    ind = sobol.Indices(study.groups, 64, S1, np.full(G, 0.005), ST, np.full(G, 0.003), None, None, 0.95)
    conv = sobol.Convergence((16, 32, 64), np.tile(S1, (3, 1)), np.tile(ST, (3, 1)))
    analyses = {"te_pp_arcsec": sobol.SobolAnalysis("te_pp_arcsec", ind, conv)}
    text = summaries.sobol_table(study, analyses, 64, 64 * (G + 2), False)
    row = next(line for line in text.splitlines() if study.groups[0] + " " in line)
    assert "S1 0.015 > ST 0.004 beyond their CIs: sampling noise, raise n" in row
    legend = text[text.index("Notes:") :]
    assert "S1 > ST" in legend and "never exceeds ST" in legend
    assert "sampling noise around zero" in legend and "CI wide" in legend
    data = summaries.sobol_json(study, analyses, 64, 64 * (G + 2), False, {})
    assert "sampling noise, raise n" in data["metrics"]["te_pp_arcsec"]["groups"][-1]["notes"][0]
