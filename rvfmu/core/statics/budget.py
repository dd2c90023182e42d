"""The compliance budget: which elastic element gives how much of the torsional windup.

The engineering question: a catalogue test winds the output up with the input
locked and reads the torsional rigidity from the slope between 50 % and 100 %
of rated torque (docs/model.md section 5).  Which parts of the reducer make
that windup, and by how much?  A stiffer needle bearing is worth buying only
if the needle bearings carry a real share of it.

The answer comes from energy, not from stiffening one element at a time (which
moves the load onto the others and so answers another question).  At
equilibrium the elements' strain energy U and the output torque's work agree
at every torque: dU = tau dtheta (the envelope theorem applied to the
potential U - tau theta, whose minimum over the unknowns is the equilibrium).
Between two torques, then, the increase of each element's strain energy over
the work of the output torque is that element's share of the windup, the
shares add up to one, and for linear elements a share is exactly the fraction
of the incremental compliance that the element contributes.  The work is
integrated along the loading path on LEVELS torques (trapezoidal rule, exact
while no contact changes between two levels); the energies are those of the
solver's own energy (`solver.py`), term by term, with the weak springs that
keep floating parts determinate apart (`regularisation`: about 1e-6 of the
work, no element's).

Positions and senses follow the catalogue test of `quasistatic.windup`: the
input locked at `positions` angles over one output revolution, the output
loaded in both senses; each element's energy increase and the work are
summed over all of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.checks import InputError, finite_number, integer
from ..base.units import ARCMIN
from ..laws.pin_law import contacts
from ..laws.roller_law import radial_law
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet
from ..reducer.limits import check_load
from .equivalent import EquivalentModel
from .newton import pin_delta
from .quasistatic import (
    NO_LOAD_PROBE,
    RIGIDITY_FRACTIONS,
    WINDUP_POSITIONS,
    _checked_errors,
    windup_positions,
)
from .solver import ReducedSystem, solve_pairs

LEVELS = 321  # torques from 50 % to 100 %: the trapezoidal work is within 1e-7 of the energy


@dataclass(frozen=True)
class Element:
    """One kind of elastic element: `count` alike in the reducer, each of `stiffness`
    [`unit`]; `share` of the windup between the budget's two torques (shares add up to 1)."""

    name: str
    count: int
    stiffness: float
    unit: str
    share: float


@dataclass(frozen=True)
class ComplianceBudget:
    """Shares of the output windup between torque_low and torque_high [N*m], one reducer.

    elements: the model's elastic elements, each with its share, the solver's weak springs
    last (their share is `regularisation` / `work`); energy: (E,) increase of
    each element's strain energy [J], regularisation: that of the solver's weak springs [J],
    and work: the output torque's work over the same loading [J], all summed over the
    positions and both senses; windup_low, windup_high:
    (2, P) output rotation [rad] at the two torques, resisting (row 0, negative torque)
    and driving (row 1) loads, at each position.
    """

    design: RVDesign
    torque_low: float
    torque_high: float
    elements: tuple[Element, ...]
    energy: np.ndarray
    regularisation: float
    work: float
    windup_low: np.ndarray
    windup_high: np.ndarray
    converged: bool

    @property
    def share_sum(self) -> float:
        """Sum of the element energies and the weak springs' over the work: 1 but for the
        integration error."""
        return float((self.energy.sum() + self.regularisation) / self.work)

    @property
    def torsional_rigidity_Nm_per_arcmin(self) -> float:
        """Torque over windup slope between the two torques, mean over positions and
        senses (the catalogue definition, `quasistatic.Windup`) [N*m/arcmin]."""
        span = self.torque_high - self.torque_low
        slope = np.abs(self.windup_high - self.windup_low).mean(axis=-1) / span  # (2,) rad/N*m
        return float(1.0 / (0.5 * slope.sum() / ARCMIN))


def element_energies(model: EquivalentModel, errors: ErrorSet, sample, angle, q) -> dict:
    """Strain energy [J] of each kind of element at the equilibria q (B, n) of loaded pairs
    (sample[b], angle[b]): {element name: (B,)}, the terms of the solver's energy.

    The pins follow their law (`pin_law`); the bearings that have a roller law follow it;
    where the law has a spring in series (the crankshaft's part behind the needles and behind
    its tapered roller pair, `compliance.crank_split`), that spring's energy is an element of
    its own."""
    d = model.design
    n_c = d.n_c
    lin_b, brg_b, pin_b = model.offsets(errors, sample, angle)
    lin = np.einsum("bmn,bn->bm", model.linear_rows[angle], q) + lin_b
    lin_energy = 0.5 * model.linear_k * lin * lin  # (B, m)
    s, c_half = _bearing_deflections(model, errors, sample, angle, q, brg_b)
    over = np.maximum(s - c_half, 0.0)
    brg_energy = 0.5 * model.bearing_k * over * over  # (B, nb)
    series_energy = np.zeros_like(brg_energy)  # the springs in series with roller bearings
    rollers = model.bearing_law_a > 0.0
    if np.any(rollers):
        compliance = model.bearing_law_compliance[rollers]
        energy, force, _ = radial_law(
            s[:, rollers], c_half[:, rollers], model.bearing_law_a[rollers], compliance
        )
        series_energy[:, rollers] = 0.5 * compliance * force * force
        brg_energy[:, rollers] = energy - series_energy[:, rollers]
    delta = pin_delta(model.pin_rows[angle], q[:, model.pin_dofs], pin_b)
    parts = {
        "pin-disc contacts": contacts(delta, model.pin_law)[0].sum(axis=(1, 2)),
        "sun-planet meshes": lin_energy[:, :n_c].sum(axis=1),
        "sun support": lin_energy[:, n_c:].sum(axis=1),
        "crank-carrier bearings": brg_energy[:, :n_c].sum(axis=1),
        "crank-disc needle bearings": brg_energy[:, n_c : 3 * n_c].sum(axis=1),
        "main bearing": brg_energy[:, -1],
    }
    for kind, (name, _, columns) in CRANK_ROWS.items():
        if d.roller_laws.get(kind, (0.0, 0.0))[1] > 0.0:
            parts[name] = series_energy[:, columns(n_c)].sum(axis=1)
    return parts


def _bearing_deflections(model, errors, sample, angle, q, brg_b):
    """(B, nb) radial deflection of every bearing [m] and (B, nb) its free play."""
    brg = np.einsum("bpxn,bn->bpx", model.bearing_rows[angle], q) + brg_b
    return np.linalg.norm(brg, axis=-1), model.clearance_halves(errors)[sample]


def bearing_forces(model: EquivalentModel, errors: ErrorSet, sample, angle, q) -> np.ndarray:
    """(B, nb) radial force [N] on every bearing of the model (crank seats, cams, main
    bearing, in `EquivalentModel` order) at the equilibria q (B, n): the linear spring beyond
    the bearing's free play, or the roller law where the design gives the rollers."""
    _, brg_b, _ = model.offsets(errors, sample, angle)
    s, c_half = _bearing_deflections(model, errors, sample, angle, q, brg_b)
    force = model.bearing_k * np.maximum(s - c_half, 0.0)
    rollers = model.bearing_law_a > 0.0
    if np.any(rollers):
        force[:, rollers] = radial_law(
            s[:, rollers],
            c_half[:, rollers],
            model.bearing_law_a[rollers],
            model.bearing_law_compliance[rollers],
        )[1]
    return force


WEAK_SPRINGS = "weak springs (numerical)"
# The weak springs' share above which the budget says so: the table prints shares to 0.1 %.
# Scaled with the softest element (`solver.weak_stiffness`) they hold under 1e-6 on the
# presets and at most 2e-5 in the corners of the design's limits that were tried (stiffnesses
# at their bounds with 100 um clearances and errors).
WEAK_SHARE_VISIBLE = 1e-3
# The springs in series with a roller law, the crankshaft's parts (`compliance.crank_split`):
# {roller law kind: (row name, the bearing row it splits from, its bearing columns)}.
CRANK_ROWS = {
    "crank_disc": (
        "crank bending and tilt, each cam",
        "crank-disc needle bearings",
        lambda n_c: slice(n_c, 3 * n_c),
    ),
    "crank_carrier": ("crank bending, both cams alike", "crank-carrier bearings", lambda n_c: slice(0, n_c)),
}


def _elements(design: RVDesign, shares: dict, weak_stiffness: float) -> tuple[Element, ...]:
    """The element table: name, count, stiffness and unit of each kind, with its share; last
    the solver's weak springs (`solver.weak_stiffness`: REGULARISATION x the softest pin, mesh
    or bearing or 30 x the sun support, on every reduced unknown), whose share is the rest of
    the work, under 1e-6 of it on the presets."""
    d = design

    def per_arcmin(compliance):
        return np.inf if compliance == 0.0 else ARCMIN / compliance

    table = [
        ("pin-disc contacts", 2 * d.z_p, d.pin_disc_stiffness, "N/m"),
        ("sun-planet meshes", d.n_c, d.mesh_stiffness, "N/m"),
        ("sun support", 1, d.sun_support_stiffness, "N/m"),
        ("crank-carrier bearings", d.n_c, d.crank_carrier_bearing_stiffness, "N/m"),
        ("crank-disc needle bearings", 2 * d.n_c, d.crank_disc_bearing_stiffness, "N/m"),
        ("main bearing", 1, d.main_bearing_stiffness, "N/m"),
        ("carrier pillars", 1, per_arcmin(d.carrier_compliance), "N*m/arcmin"),
        ("output series compliance", 1, per_arcmin(d.output_compliance), "N*m/arcmin"),
    ]
    for kind, (name, bearing, _) in CRANK_ROWS.items():
        series = d.roller_laws.get(kind, (0.0, 0.0))[1]
        if series > 0.0:
            # the stated stiffness splits into the rollers' own secant and the crank's part
            at = next(k for k, row in enumerate(table) if row[0] == bearing)
            count, stated = table[at][1], table[at][2]
            table[at] = (bearing, count, 1.0 / (1.0 / stated - series), "N/m")
            table.insert(at + 1, (name, count, 1.0 / series, "N/m"))
    table.append((WEAK_SPRINGS, 1, weak_stiffness, "N/m"))
    return tuple(Element(name, count, float(k), unit, float(shares[name])) for name, count, k, unit in table)


def compliance_budget(
    design: RVDesign,
    errors: ErrorSet | None = None,
    torque: float | None = None,
    positions: int = WINDUP_POSITIONS,
    levels: int = LEVELS,
    sample: int = 0,
) -> ComplianceBudget:
    """Each element's share of the windup between 50 % and 100 % of `torque` [N*m]
    (default: the rated torque, the catalogue's range) for reducer `sample` of `errors`.

    The output torque resists (negative tau_load) and drives (positive) in turn, at
    `positions` locked input angles; `levels` torques span each range.
    """
    errors = _checked_errors(design, errors)
    torque = design.rated_torque if torque is None else finite_number("load", torque)
    if torque <= 0.0:
        raise InputError(
            "load",
            torque,
            "must be a positive torque [N*m]: the budget spans 50 % to 100 % of it, in both senses",
        )
    check_load("load", torque, design.rated_torque)
    positions = integer("positions", positions, 1)
    levels = integer("levels", levels, 2)
    sample = integer("sample", sample, 0, errors.samples - 1)
    low, high = (f * torque for f in RIGIDITY_FRACTIONS)
    magnitudes = np.linspace(low, high, levels)
    theta_in = windup_positions(design, positions)
    names, energy, work, ends, converged, weak = [], None, 0.0, [], True, 0.0
    for sense, flank in ((-1.0, 1), (1.0, -1)):
        tau = sense * magnitudes
        model = EquivalentModel(design, theta_in, flank=flank)
        t, a = (g.ravel() for g in np.meshgrid(np.arange(levels), np.arange(positions), indexing="ij"))
        s = np.full(t.size, sample)
        eq = solve_pairs(model, errors, s, a, tau[t], no_load_probe=NO_LOAD_PROBE * design.rated_torque)
        converged &= bool(eq.converged.all())
        # The weak springs of the solver's reduced system (solver.ReducedSystem), centred at
        # zero at these loads (they are released only below RELEASE_BELOW probe torques).
        system = ReducedSystem(
            model, np.any(model.clearance_halves(errors) > 0, axis=0) | (model.bearing_law_a > 0.0)
        )
        q_n = eq.q[:, system.N]
        held = 0.5 * np.einsum("bi,bij,bj->b", q_n, system.reg_matrix[a], q_n).reshape(levels, positions)
        weak += float((held[-1] - held[0]).sum())
        parts = element_energies(model, errors, s, a, eq.q)
        parts["carrier pillars"] = 0.5 * design.carrier_compliance * tau[t] ** 2
        parts["output series compliance"] = 0.5 * design.output_compliance * tau[t] ** 2
        names = list(parts)
        increase = np.array(
            [
                (p.reshape(levels, positions)[-1] - p.reshape(levels, positions)[0]).sum()
                for p in parts.values()
            ]
        )
        energy = increase if energy is None else energy + increase
        theta = model.output_angle(eq.q, tau[t]).reshape(levels, positions)
        work += float(np.sum(0.5 * (tau[1:] + tau[:-1])[:, None] * np.diff(theta, axis=0)))
        ends.append((theta[0], theta[-1]))
    shares = dict(zip(names, energy / work), **{WEAK_SPRINGS: weak / work})
    elements = _elements(design, shares, system.reg)
    return ComplianceBudget(
        design,
        low,
        high,
        elements,
        energy,
        weak,
        work,
        np.array([e[0] for e in ends]),
        np.array([e[1] for e in ends]),
        converged,
    )
