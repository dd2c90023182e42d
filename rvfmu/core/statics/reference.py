"""A straightforward reference solve: one angle at a time, all unknowns, scipy.optimize.

This is the slow, obvious way to find the equilibrium of the equivalent model:
write down its energy over all unknowns and hand it to a general-purpose
minimiser.  It shares the element Jacobians with the fast solver but none of
its tricks (no condensation, no active sets, no first-contact kinematics), so
the tests use it as an independent check and the benchmark as its baseline.

Every element the solver has is here: the meshes, the sun support, the bearings
with their clearances, the pins, and the torsional compliance in series with the
output (`series_compliance`: the carrier's pillars and the calibrated remainder),
which the solver adds to the carrier's rotation afterwards and which this solve
carries as one more unknown, the output flange's rotation, joined to the carrier
by a torsional spring and loaded by tau_load.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ..laws.pin_law import U_LIMIT, Y_LIMIT  # where the pins' law continues as its tangent: a definition
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet
from .equivalent import EquivalentModel
from .quasistatic import NO_LOAD_PROBE
from .solver import LAW_PROBE  # the solver's small load of the law at no load: a definition, not machinery

SCALE = 1e-6  # the optimiser works in micrometres


def equilibrium_reference(
    model: EquivalentModel,
    errors: ErrorSet,
    sample: int,
    angle: int,
    tau_load: float,
    rollers: bool = True,
    weak: float = 1.0,
) -> np.ndarray:
    """Unknowns q (n + 1,) at one (reducer, angle) under tau_load [N*m], by L-BFGS-B.

    The last unknown is the output flange's rotation (arc length at R_p, as the
    carrier's): tau_load acts on it, and a torsional spring of stiffness
    1 / series_compliance joins it to the carrier (with no compliance, the flange
    is the carrier: the last unknown repeats the carrier's rotation).

    A bearing that follows the roller law (`model.bearing_law_a` > 0; with
    `rollers` False none: the linear spring of its stated stiffness, as in the first
    stage of the solver's no-load limit) has its energy integrated over its rollers
    here (Gauss-Legendre over the loaded arc, `_roller_energy`), and its series spring,
    where it has one, is a spring of its own: two more unknowns, its deflection, between
    the bearing and the part (`roller_law` instead tabulates the energy and eliminates
    the spring).

    Every unknown carries a weak spring (1e-8 x the pin stiffness, times `weak`) that
    holds the parts the load leaves free.  Below the no-load probe load it must shrink
    with the load (weak = load / probe), or it would hold the free mechanism short of
    the contacts that the load closes.
    """
    lin_b, brg_b, pin_b = model.offsets(errors, np.array([sample]), np.array([angle]))
    lin_rows, lin_k = model.linear_rows[angle], model.linear_k
    brg_rows, brg_k = model.bearing_rows[angle], model.bearing_k
    pin_rows, pin_k = model.pin_rows[angle], model.pin_k
    dofs = model.pin_dofs
    c_half = model.clearance_halves(errors)[sample]
    law = (model.bearing_law_a > 0) & rollers
    law_a, law_c = model.bearing_law_a, model.bearing_law_compliance
    springs = np.flatnonzero(law & (law_c > 0))  # bearings with a series spring
    slot = {b: k for k, b in enumerate(springs)}  # each one's two unknowns
    g = model.load_vector() * tau_load
    reg = 1e-8 * pin_k * weak
    compliance = model.design.series_compliance
    # Torsional spring N*m/rad between carrier and flange, on arc-length unknowns: k / R_p^2.
    flange_k = 0.0 if compliance == 0.0 else 1.0 / compliance / model.scale**2
    c = model.carrier_rot
    n = model.n_dof

    def energy(x):
        x = x * SCALE
        q, series = x[:n], x[n : n + 2 * springs.size].reshape(-1, 2)
        grad = np.zeros_like(x)
        e, grad[:n], grad[n : n + 2 * springs.size] = _element_energy(q, series)
        if flange_k:
            # The load acts on the flange, which the spring joins to the carrier.
            flange = x[-1]
            twist = flange - q[c]
            e += 0.5 * flange_k * twist * twist - g[c] * flange
            grad[c] -= flange_k * twist
            grad[-1] = flange_k * twist - g[c]
        else:
            e -= g @ q
            grad[:n] -= g
        return e / weak, grad * (SCALE / weak)  # energies shrink with the load: keep L-BFGS-B's scale

    def _element_energy(q, series):
        lin = lin_rows @ q + lin_b[0]
        e = 0.5 * np.sum(lin_k * lin * lin)
        grad = lin_rows.T @ (lin_k * lin)
        d = np.einsum("pxn,n->px", brg_rows, q) + brg_b[0]
        # linear bearings: k (|d| - c)_+
        norm = np.linalg.norm(d, axis=1)
        over = np.where(law, 0.0, np.maximum(norm - c_half, 0.0))
        e += 0.5 * np.sum(brg_k * over * over)
        force = d * (brg_k * over / np.maximum(norm, 1e-300))[:, None]
        # roller bearings: their rollers carry d less the series spring's deflection
        series_grad = np.zeros_like(series)
        for b in np.flatnonzero(law):
            rollers_d = d[b].copy()
            k = slot.get(b)
            if k is not None:
                rollers_d -= series[k]
                e += 0.5 * series[k] @ series[k] / law_c[b]
                series_grad[k] += series[k] / law_c[b]
            s = np.linalg.norm(rollers_d)
            energy_r, force_r = _roller_energy(s, c_half[b], law_a[b])
            e += energy_r
            pull = force_r * rollers_d / max(s, 1e-300)
            force[b] += pull
            if k is not None:
                series_grad[k] -= pull
        grad += np.einsum("pxn,px->n", brg_rows, force)
        delta = np.maximum(np.einsum("jkx,jx->jk", pin_rows, q[dofs]) + pin_b[0], 0.0)
        energy_p, force_p = _pin_energy(delta, model.pin_law)
        e += energy_p
        pin_gen = np.einsum("jk,jkx->jx", force_p, pin_rows)
        np.add.at(grad, dofs, pin_gen)
        e += 0.5 * reg * q @ q
        grad += reg * q
        return e, grad, series_grad.ravel()

    x0 = np.zeros(n + 2 * springs.size + (1 if flange_k else 0))
    result = minimize(
        energy,
        x0,
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": 20000, "maxcor": 30, "ftol": 1e-16, "gtol": 1e-14},
    )
    x = result.x * SCALE
    q = x[:n]
    return np.append(q, x[-1] if flange_k else q[c])


_ARC_NODES, _ARC_WEIGHTS = np.polynomial.legendre.leggauss(64)


def _pin_energy(delta, law):
    """(energy [J], force (..) [N]) of pins pressed by delta >= 0 (..): the linear spring k
    of law = (k, b, F*) where b = 0, else the Hertz law delta = b F ln(F*/F) inverted by
    Lambert's W (its lower branch: F = F* exp(W_-1(-delta / (b F*)))), the energy
    integrated from it, b F^2 (ln(F*/F) - 1/2) / 2; beyond F* e^-2 its tangent there."""
    from scipy.special import lambertw

    k, b, f_star = law
    if b == 0.0:
        return 0.5 * k * np.sum(delta * delta), k * delta
    y = delta / (b * f_star)
    inside = np.minimum(y, Y_LIMIT)  # the law's range: a definition, not machinery
    x = np.where(inside > 0.0, np.exp(lambertw(-np.maximum(inside, 1e-300), -1).real), 0.0)
    force = f_star * x
    with np.errstate(divide="ignore", invalid="ignore"):
        energy = np.where(x > 0.0, 0.5 * b * force * force * (np.log(1.0 / x) - 0.5), 0.0)
    over = (y - inside) * b * f_star  # beyond the law: its tangent there continued
    tangent = 1.0 / (b * (-U_LIMIT - 1.0))
    energy = energy + force * over + 0.5 * tangent * over * over
    return float(np.sum(energy)), force + tangent * over


def _roller_energy(s, c, a):
    """(energy [J], radial force [N]) of a roller bearing with law constant a and free play
    c at centre deflection s: each roller at angle psi from the load carries
    Q = K_n (s cos psi - c)^n, stores Q (s cos psi - c) / (n + 1), the rollers spread over
    the circumference (Z / (2 pi) per radian, in a): integrals over the loaded arc."""
    from ..laws.compliance import LINE_EXPONENT as n

    if s <= c:
        return 0.0, 0.0
    limit = np.arccos(c / s)
    psi = limit * _ARC_NODES  # the nodes on [-limit, limit]
    w = limit * _ARC_WEIGHTS
    approach = s * np.cos(psi) - c
    return (a * np.sum(w * approach ** (n + 1.0)) / (n + 1.0), a * np.sum(w * approach**n * np.cos(psi)))


def te_reference(
    design: RVDesign, errors: ErrorSet, theta_in, tau_load: float, sample: int = 0
) -> np.ndarray:
    """TE [rad] of the output flange at each input angle, one scipy solve per angle.

    Zero load, the no-load limit of docs/model.md section 5: where bearings follow the
    roller law and no bearing has clearance, one solve with the law under a resisting
    load of LAW_PROBE x the probe (the law's windup goes as load^0.9, which a straight
    line back to zero would not undo; what is left of it there is below 0.001 arcsec);
    otherwise, as the solver at no load with clearance, the stated stiffnesses: two
    probe loads and a straight line back to zero.
    """
    theta_in = np.atleast_1d(theta_in)
    model = EquivalentModel(design, theta_in, flank=1 if tau_load <= 0 else -1)
    te = np.empty(theta_in.size)
    # The probe of the solver's no-load solves: a larger one bends the straight line back to
    # zero where a contact changes between the two probe loads (0.03 arcsec at 10x, seed 002).
    probe = NO_LOAD_PROBE * design.rated_torque
    law = bool(np.any(model.bearing_law_a > 0)) and not np.any(model.clearance_halves(errors) > 0)
    for a in range(theta_in.size):
        if tau_load == 0.0 and law:
            te[a] = (
                equilibrium_reference(model, errors, sample, a, -LAW_PROBE * probe, weak=LAW_PROBE)[-1]
                / model.scale
            )
        elif tau_load == 0.0:
            one = equilibrium_reference(model, errors, sample, a, -probe, rollers=False)[-1]
            two = equilibrium_reference(model, errors, sample, a, -2 * probe, rollers=False)[-1]
            te[a] = (2.0 * one - two) / model.scale
        else:
            te[a] = equilibrium_reference(model, errors, sample, a, tau_load)[-1] / model.scale
    return te


POLYGON_SIDES = 512  # bearing clearance circles as polygons in the no-load limit reference


def no_load_limit_bracket(
    model: EquivalentModel,
    errors: ErrorSet,
    sample: int,
    angle: int,
    zero_side: int = -1,
    sides: int = POLYGON_SIDES,
):
    """Bounds (low, high) [rad] on the no-load TE at one (reducer, angle), or None.

    The definition of docs/model.md section 5 taken literally, with rigid parts: the
    input held, every linear element (mesh, sun support, bearing without clearance)
    at zero deflection, every pin gap >= 0, every bearing centre within its
    clearance circle; among those poses the one that turns the output furthest
    back (zero_side = -1, a resisting load going to zero; +1, a driving one: furthest
    forward; the model's flank must be the one of that side).  That is a linear objective over a convex set; with each clearance circle
    replaced by the polygon around it (a larger set) and the polygon inside it (a
    smaller one) it becomes two linear programs (scipy's HiGHS) whose optima bracket
    the limit, within c (1 - cos(pi / sides)) of play per bearing.  None where no such
    pose exists (errors that force a preload at no load: the limit is then elastic).
    """
    from scipy.optimize import linprog

    lin_b, brg_b, pin_b = model.offsets(errors, np.array([sample]), np.array([angle]))
    c_half = model.clearance_halves(errors)[sample]
    n = model.n_dof
    free = c_half > 0
    lin_rows = model.linear_rows[angle]
    held = model.bearing_rows[angle][~free].reshape(-1, n)
    a_eq = np.concatenate([lin_rows, held])
    b_eq = -np.concatenate([lin_b[0], brg_b[0][~free].ravel()]) / SCALE
    pin_rows = model.pin_rows[angle]  # (2, z_p, 3)
    a_pin = np.zeros((pin_rows.shape[0] * pin_rows.shape[1], n))
    for j, dofs in enumerate(model.pin_dofs):
        a_pin[j * pin_rows.shape[1] : (j + 1) * pin_rows.shape[1], dofs] = pin_rows[j]
    b_pin = -pin_b[0].ravel() / SCALE
    phi = 2.0 * np.pi * np.arange(sides) / sides
    u = np.stack([np.cos(phi), np.sin(phi)], axis=1)  # (M, 2)
    cost = np.zeros(n)
    cost[model.carrier_rot] = -float(zero_side)
    bounds = []
    for radius in (1.0, np.cos(np.pi / sides)):  # polygon around, inside
        a_ub, b_ub = [a_pin], [b_pin]
        for p in np.flatnonzero(free):
            rows = model.bearing_rows[angle][p]  # (2, n): d = rows q + b
            a_ub.append(u @ rows)
            b_ub.append((c_half[p] * radius - u @ brg_b[0][p]) / SCALE)
        res = linprog(
            cost,
            A_ub=np.concatenate(a_ub),
            b_ub=np.concatenate(b_ub),
            A_eq=a_eq,
            b_eq=b_eq,
            bounds=(None, None),
            method="highs",
        )
        if res.status != 0:
            return None
        bounds.append(-zero_side * res.fun * SCALE / model.scale)
    return min(bounds), max(bounds)
