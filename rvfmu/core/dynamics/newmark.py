"""Time integration of the dynamic model: implicit Newmark-beta with Newton iterations.

Seeds 000/001 integrate with fixed steps; the average-acceleration Newmark rule
(beta = 1/4, gamma = 1/2) is unconditionally stable for linear systems and
conserves their energy, so the stiff bearing and shaft modes (kHz) neither
blow up nor damp the TE artificially, and the step only has to resolve the
frequencies of interest.  The contacts make each step nonlinear: Newton
iterations on the step's residual with the tangent stiffness and damping of
the contacts that are closed, until the displacement update is below
`TOLERANCE`, or has settled into a two-state cycle smaller than
`CYCLE_TOLERANCE` (a contact exactly at its switch, where the tangent jumps).
The loop is `kernels.newmark_steps`, compiled when numba is installed.

`static_equilibrium` gives the elastic equilibrium at a step, and `static_start`
the run's starting state: that equilibrium from the quasi-static solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..statics.equivalent import EquivalentModel
from ..statics.quasistatic import NO_LOAD_PROBE
from ..statics.solver import solve_pairs
from .kernels import newmark_steps

BETA, GAMMA = 0.25, 0.5  # average acceleration (trapezoidal rule)
TOLERANCE = 1e-13  # [m] Newton update: 1e-7 um, far below any error or deflection
CYCLE_TOLERANCE = 1e-9  # [m] a Newton two-state cycle at a contact switch this small has
# converged: 1 nm is 0.003 arcsec at the pin circle of an RV-40E
MAX_ITERATIONS = 30


@dataclass
class State:
    """q, v, a: (n,) displacement [m], velocity [m/s], acceleration [m/s^2] at one step."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray


class NewmarkStepper:
    """Fixed-step Newmark-beta over a prepared `DynamicModel`: `advance` runs to a later time
    step of the model's motion (the external forces are the model's: load and nominal
    motion), `step` one step.  The loop itself is `kernels.newmark_steps`.
    """

    def __init__(self, model, state: State, step: int = 0, beta: float = BETA, gamma: float = GAMMA):
        self.model = model
        self.state, self.k = state, step
        self.beta, self.gamma = beta, gamma
        self.iterations = 0
        self.failed_steps = 0

    @classmethod
    def starting_at(cls, model, q0, v0=None, step: int = 0, **kwargs):
        """A stepper whose initial acceleration balances the forces at q0, v0."""
        v0 = np.zeros_like(q0) if v0 is None else v0
        f, _, _ = model.forces(step, q0, v0)
        a0 = (model.external(step) - f) / model.mass
        return cls(model, State(q0.copy(), v0.copy(), a0), step, **kwargs)

    def advance(self, stop: int, q_out=None, v_out=None, power_out=None) -> State:
        """Run to time step `stop`; the states of steps k + 1 .. stop go into q_out[k + 1 ..],
        v_out[k + 1 ..] ((T, n) arrays indexed by step) when given, and the power the
        friction and the damping dissipate there into power_out[k + 1 ..] ((T, 2) [W])."""
        model = self.model
        q, v, a = (np.array(x, dtype=float) for x in (self.state.q, self.state.v, self.state.a))
        k = self.k
        while k < stop:
            g, first = model.geometry(k + 1)
            last = min(first + stop - k, g.h.size)
            qs, vs = np.empty((last, q.size)), np.empty((last, q.size))
            ps = np.empty((last, 2))
            most, failed = newmark_steps(
                model.elements,
                g,
                first,
                last,
                model.mass,
                q,
                v,
                a,
                self.beta,
                self.gamma,
                TOLERANCE,
                CYCLE_TOLERANCE,
                MAX_ITERATIONS,
                qs,
                vs,
                ps,
            )
            self.iterations = max(self.iterations, most)
            self.failed_steps += failed
            done = last - first
            if q_out is not None:
                q_out[k + 1 : k + 1 + done] = qs[first:last]
                v_out[k + 1 : k + 1 + done] = vs[first:last]
            if power_out is not None:
                power_out[k + 1 : k + 1 + done] = ps[first:last]
            k += done
        self.state, self.k = State(q, v, a), k
        return self.state

    def step(self) -> State:
        """Advance to the next time step of the model's motion."""
        return self.advance(self.k + 1)


def static_equilibrium(model, load_force, step: int = 0, q0=None) -> np.ndarray:
    """(n,) displacements where the elastic forces balance `load_force` at a step.

    Newton on f(q) = F from q0 (default: zero), with a small spring on every unknown
    in the Jacobian only (keeps a floating part's matrix regular; the solution is
    that of the true forces); at most MAX_ITERATIONS * 4 iterations.
    """
    q = np.zeros(model.n) if q0 is None else np.array(q0, dtype=float)
    zero = np.zeros(model.n)
    regular = 1e-9 * model.pin_k
    for _ in range(MAX_ITERATIONS * 4):
        f, K, _ = model.forces(step, q, zero)
        dq = np.linalg.solve(K + regular * np.eye(model.n), load_force - f)
        q += dq
        if np.max(np.abs(dq)) < TOLERANCE:
            break
    return q


def static_start(model, tau_load: float, theta_in: float = 0.0, force=None) -> np.ndarray:
    """(n,) the elastic equilibrium of a prepared model at its step 0 under tau_load [N*m]
    (force: the whole generalised load instead, e.g. with the nominal motion's), found
    from the quasi-static solution at theta_in refined with the input shaft's twist."""
    force = tau_load * model.load_vector() if force is None else force
    start = _quasi_static_start(model, model.design, model.errors, tau_load, model.flank, theta_in)
    return static_equilibrium(model, force, 0, start)


def _quasi_static_start(model, design, errors, tau_load, flank, theta_in: float = 0.0) -> np.ndarray:
    """The quasi-static equilibrium at theta_in in the dynamic model's unknowns."""
    qs_model = EquivalentModel(design, [theta_in], flank)
    eq = solve_pairs(
        qs_model, errors, [0], [0], [tau_load], no_load_probe=NO_LOAD_PROBE * design.rated_torque
    )
    q0 = np.zeros(model.n)
    for name, k in qs_model.index.items():
        q0[model.index[name]] = eq.q[0, k]
    return q0
