"""The compliance budget (`rvte stiffness`): shares from energy, against the work and the windup."""

import json

import numpy as np
import pytest
from conftest import ROOT
from test_cli import rvte

from rvfmu import api
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCMIN, UM
from rvfmu.core.reducer.design import preset
from rvfmu.core.statics.budget import WEAK_SPRINGS, compliance_budget
from rvfmu.core.statics.quasistatic import windup


def test_shares_add_up_to_the_work_of_the_output_torque(rv40, seed002):
    """Element energies over the output torque's work, integrated independently along the
    loading path: they add up to one (dU = tau dtheta at equilibrium)."""
    budget = compliance_budget(rv40, seed002)
    assert budget.converged
    assert abs(budget.share_sum - 1.0) < 1e-6
    # the solver's weak springs hold a millionth, no element's
    assert 0.0 <= budget.regularisation / budget.work < 1e-5
    assert budget.elements[-1].name == WEAK_SPRINGS
    assert budget.elements[-1].share == pytest.approx(budget.regularisation / budget.work, rel=1e-12)
    # so the table's shares add up to one as the energies do
    assert sum(e.share for e in budget.elements) == pytest.approx(budget.share_sum, abs=1e-12)


def _with_clearances(errors):
    return errors.replace(
        crank_disc_clearance=np.array([6.0 * UM]),
        crank_carrier_clearance=np.array([4.0 * UM]),
        main_bearing_clearance=np.array([10.0 * UM]),
    )


def test_shares_add_up_with_bearing_clearances(rv40, seed002):
    budget = compliance_budget(rv40, _with_clearances(seed002))
    assert budget.converged
    assert abs(budget.share_sum - 1.0) < 1e-6


@pytest.mark.parametrize("name", ["RV-40E-121", "RV-20E"])
def test_rigidity_of_the_budget_is_the_windup_tests(name):
    design = preset(name)
    budget = compliance_budget(design)
    catalogue = windup(design).torsional_rigidity_Nm_per_arcmin()[0]
    assert budget.torsional_rigidity_Nm_per_arcmin == pytest.approx(catalogue, rel=1e-9)


def test_series_compliance_share_is_its_part_of_the_compliance():
    """A spring in series with the output carries the whole torque: its share is its
    compliance over the reducer's, c * k (closed form for springs in series)."""
    design = preset("RV-40E-121")
    budget = compliance_budget(design)
    shares = {e.name: e.share for e in budget.elements}
    assert all(e.share >= 0.0 for e in budget.elements)  # no errors: nothing unloads
    for name, compliance in (
        ("output series compliance", design.output_compliance),
        ("carrier pillars", design.carrier_compliance),
    ):
        expected = compliance / ARCMIN * budget.torsional_rigidity_Nm_per_arcmin
        assert 0.01 < expected < 0.5
        assert shares[name] == pytest.approx(expected, rel=2e-3)


def test_without_series_compliance_its_share_is_zero_and_the_rest_adds_up(rv40):
    budget = compliance_budget(rv40)
    by_name = {e.name: e for e in budget.elements}
    assert by_name["output series compliance"].share == 0.0
    assert np.isinf(by_name["output series compliance"].stiffness)
    # the crank bearings carry most of it, the pins less, the stage 1 almost nothing (its
    # compliance reaches the output divided by the second stage's ratio squared)
    crank = by_name["crank-disc needle bearings"].share + by_name["crank-carrier bearings"].share
    assert crank > 0.8
    assert 0.02 < by_name["pin-disc contacts"].share < 0.15
    assert by_name["sun-planet meshes"].share < 0.01


def test_four_times_stiffer_needle_bearings_take_a_quarter_of_their_compliance(rv40):
    """Springs in series: an element of share s made 4x stiffer keeps (s/4) / (s/4 + 1 - s)
    of the new compliance, while the load path stays the same (it nearly does here)."""
    base = {e.name: e.share for e in compliance_budget(rv40).elements}
    stiff = rv40.with_fields(crank_disc_bearing_stiffness=4.0 * rv40.crank_disc_bearing_stiffness)
    after = {e.name: e.share for e in compliance_budget(stiff).elements}
    s = base["crank-disc needle bearings"]
    assert after["crank-disc needle bearings"] == pytest.approx((s / 4) / (s / 4 + 1 - s), rel=0.02)
    assert after["pin-disc contacts"] > base["pin-disc contacts"]


def test_budget_refuses_a_bad_load_or_sample(rv40):
    with pytest.raises(InputError, match="load"):
        compliance_budget(rv40, torque=-10.0)
    with pytest.raises(InputError, match="load"):
        compliance_budget(rv40, torque=10.0 * rv40.rated_torque)
    with pytest.raises(InputError, match="sample"):
        compliance_budget(rv40, sample=3)


def test_stiffness_job_json_and_plot(tmp_path):
    plot = tmp_path / "budget.png"
    proc = rvte(
        "stiffness",
        "RV-40E-121",
        "--errors",
        ROOT / "studies" / "seed002_errors.toml",
        "--json",
        "--plot",
        plot,
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert {"torsional_rigidity_Nm_per_arcmin", "lost_motion_arcmin", "elements"} <= set(data)
    assert sum(e["share"] for e in data["elements"]) == pytest.approx(1.0, abs=1e-6)
    for element in data["elements"]:
        assert set(element) == {"name", "count", "stiffness", "unit", "share"}
    report = api.stiffness("RV-40E-121", ROOT / "studies" / "seed002_errors.toml")
    assert data["torsional_rigidity_Nm_per_arcmin"] == pytest.approx(
        report.torsional_rigidity_Nm_per_arcmin, rel=1e-12
    )
    assert plot.read_bytes()[:4] == b"\x89PNG"


def test_stiffness_command_checks_its_inputs_first(tmp_path):
    proc = rvte("stiffness", "RV-40E-121", "--plot", tmp_path / "missing" / "b.png")
    assert proc.returncode == 2 and "plot" in proc.stderr and "does not exist" in proc.stderr
    proc = rvte("stiffness", "RV-40E-121", "--load", "0")
    assert proc.returncode == 2 and "load = 0" in proc.stderr
    proc = rvte("stiffness", "RV-40E-121")
    assert proc.returncode == 0 and "compliance budget" in proc.stdout and "sum" in proc.stdout


def test_stiffness_prints_the_frames_catalogue_figures_beside_the_models():
    """A preset (estimate or calibrated) is shown beside its frame's catalogue rigidity and
    lost-motion bound (rvfmu/core/reducer/presets/catalogue.toml: RV-40E, 108 N*m/arcmin, at
    most 1 arcmin); a design of another name has no frame, and says so."""
    import dataclasses

    report = api.stiffness("RV-40E-121-estimate")
    assert report.catalogue.name == "RV-40E"
    table = report.summary()
    assert "catalogue 108)" in table and "catalogue at most 1)" in table
    assert "RV-40E frame, Nabtesco" in table
    data = report.to_json()["catalogue"]
    assert data["frame"] == "RV-40E" and data["torsional_rigidity_Nm_per_arcmin"] == 108
    assert data["lost_motion_max_arcmin"] == 1.0
    own = api.stiffness(dataclasses.replace(preset("RV-40E-121"), name="bench-reducer-7"))
    assert own.catalogue is None and own.to_json()["catalogue"] is None
    assert "catalogue          none: the design is no preset" in own.summary()
    assert "catalogue 108" not in own.summary()
    # the model's own figures do not depend on the name
    assert own.torsional_rigidity_Nm_per_arcmin == pytest.approx(
        api.stiffness("RV-40E-121").torsional_rigidity_Nm_per_arcmin, rel=1e-12
    )


@pytest.mark.parametrize("clearances", [False, True], ids=["tight", "clearances"])
def test_with_the_roller_law_shares_still_add_up_and_the_crank_has_rows_of_its_own(
    rv40_rollers, seed002, clearances
):
    """The roller law's energy is the integral of its force (rvfmu/core/laws/roller_law.py): the
    shares add up to one as with linear springs, the rigidity is the windup test's, and
    the springs in series with the needles and with the tapered roller pairs (the
    crankshaft's two parts, compliance.crank_split) are rows of their own: each with its
    bearing's own secant makes the stated stiffness in series."""
    errors = _with_clearances(seed002) if clearances else seed002
    budget = compliance_budget(rv40_rollers, errors)
    assert budget.converged
    assert abs(budget.share_sum - 1.0) < 1e-6
    assert budget.torsional_rigidity_Nm_per_arcmin == pytest.approx(
        windup(rv40_rollers, errors).torsional_rigidity_Nm_per_arcmin()[0], rel=1e-9
    )
    rows = {e.name: e for e in budget.elements}
    for crank, bearing, stated in (
        (
            "crank bending and tilt, each cam",
            "crank-disc needle bearings",
            rv40_rollers.crank_disc_bearing_stiffness,
        ),
        (
            "crank bending, both cams alike",
            "crank-carrier bearings",
            rv40_rollers.crank_carrier_bearing_stiffness,
        ),
    ):
        assert 1.0 / rows[crank].stiffness + 1.0 / rows[bearing].stiffness == pytest.approx(
            1.0 / stated, rel=1e-12
        )
        assert rows[crank].share > 0.05 and rows[bearing].share > 0.05
        assert rows[crank].count == rows[bearing].count


def _crank_torsion_against_the_mesh(design, sources):
    """k_mesh / k_torsion: the crank's torsion (not an element of the model) as a spring along
    the line of action, G J / (L r_b^2), L = crank span + gear width (more than the length
    between the cams and the planet), over the mesh's stiffness."""
    from rvfmu.core.laws.compliance import shaft_torsion_stiffness, shear_modulus

    d, span = sources["crank_diameter_mm"] * 1e-3, sources["crank_span_mm"] * 1e-3
    g = shear_modulus(design.youngs_modulus, design.poisson_ratio)
    torsion = shaft_torsion_stiffness(g, d, span + design.gear_width) / design.planet_base_radius**2
    return design.mesh_stiffness / torsion


def test_the_crank_torsion_left_out_would_take_under_two_percent():
    """The crank's torsion between its cams and its planet carries the crank's torque, which
    the locked input reacts at the mesh: it is a spring in series with the mesh, so its share
    would be the mesh's times k_mesh / k_torsion (the same force in both).  Largest on the
    RV-110E; under 2 % there (docs/model.md section 6)."""
    from rvfmu.core.reducer.design import PRESET_NAMES, preset_file

    ratios = {
        n: _crank_torsion_against_the_mesh(preset(n + "-estimate"), preset_file(n)["sources"])
        for n in PRESET_NAMES
    }
    assert max(ratios, key=ratios.get) == "RV-110E"
    assert all(r > 1.0 for r in ratios.values())  # softer than the mesh it is in series with
    budget = compliance_budget(preset("RV-110E-estimate"), positions=2, levels=9)
    mesh = next(e.share for e in budget.elements if e.name == "sun-planet meshes")
    assert 0.0 < mesh * ratios["RV-110E"] < 0.02
