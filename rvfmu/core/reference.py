"""A straightforward reference solve: one angle at a time, all unknowns, scipy.optimize.

This is the slow, obvious way to find the equilibrium of the equivalent model:
write down its energy over all unknowns and hand it to a general-purpose
minimiser.  It shares the element Jacobians with the fast solver but none of
its tricks (no condensation, no active sets, no first-contact kinematics), so
the tests use it as an independent check and the benchmark as its baseline.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from .design import RVDesign
from .equivalent import EquivalentModel
from .errors import ErrorSet
from .quasistatic import NO_LOAD_PROBE

SCALE = 1e-6  # the optimiser works in micrometres


def equilibrium_reference(model: EquivalentModel, errors: ErrorSet, sample: int, angle: int,
                          tau_load: float) -> np.ndarray:
    """Unknowns q (n,) at one (reducer, angle) under tau_load [N*m], by L-BFGS-B."""
    lin_b, brg_b, pin_b = model.offsets(errors, np.array([sample]), np.array([angle]))
    lin_rows, lin_k = model.linear_rows[angle], model.linear_k
    brg_rows, brg_k = model.bearing_rows[angle], model.bearing_k
    pin_rows, pin_k = model.pin_rows[angle], model.pin_k
    dofs = model.pin_dofs
    c_half = model.clearance_halves(errors)[sample]
    g = model.load_vector() * tau_load
    reg = 1e-8 * pin_k

    def energy(x):
        q = x * SCALE
        lin = lin_rows @ q + lin_b[0]
        e = 0.5 * np.sum(lin_k * lin * lin)
        grad = lin_rows.T @ (lin_k * lin)
        d = np.einsum("pxn,n->px", brg_rows, q) + brg_b[0]
        norm = np.linalg.norm(d, axis=1)
        over = np.maximum(norm - c_half, 0.0)
        e += 0.5 * np.sum(brg_k * over * over)
        force = d * (brg_k * over / np.maximum(norm, 1e-300))[:, None]
        grad += np.einsum("pxn,px->n", brg_rows, force)
        delta = np.maximum(np.einsum("jkx,jx->jk", pin_rows, q[dofs]) + pin_b[0], 0.0)
        e += 0.5 * pin_k * np.sum(delta * delta)
        pin_gen = pin_k * np.einsum("jk,jkx->jx", delta, pin_rows)
        np.add.at(grad, dofs, pin_gen)
        e += 0.5 * reg * q @ q - g @ q
        grad += reg * q - g
        return e, grad * SCALE

    x0 = np.zeros(model.n_dof)
    result = minimize(energy, x0, jac=True, method="L-BFGS-B",
                      options={"maxiter": 20000, "maxcor": 30, "ftol": 1e-16, "gtol": 1e-14})
    return result.x * SCALE


def te_reference(design: RVDesign, errors: ErrorSet, theta_in, tau_load: float,
                 sample: int = 0) -> np.ndarray:
    """TE [rad] at each input angle, one scipy solve per angle.

    Zero load: two probe loads and a straight line back to zero (the no-load limit).
    """
    theta_in = np.atleast_1d(theta_in)
    model = EquivalentModel(design, theta_in, flank=1 if tau_load <= 0 else -1)
    te = np.empty(theta_in.size)
    probe = NO_LOAD_PROBE * 10 * design.rated_torque
    for a in range(theta_in.size):
        if tau_load == 0.0:
            one = equilibrium_reference(model, errors, sample, a, -probe)[model.carrier_rot]
            two = equilibrium_reference(model, errors, sample, a, -2 * probe)[model.carrier_rot]
            te[a] = (2.0 * one - two) / model.scale
        else:
            te[a] = equilibrium_reference(model, errors, sample, a, tau_load)[model.carrier_rot] / model.scale
    return te
