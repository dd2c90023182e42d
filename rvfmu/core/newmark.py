"""Time integration of the dynamic model: implicit Newmark-beta with Newton iterations.

Seeds 000/001 integrate with fixed steps; the average-acceleration Newmark rule
(beta = 1/4, gamma = 1/2) is unconditionally stable for linear systems and
conserves their energy, so the stiff bearing and shaft modes (kHz) neither
blow up nor damp the TE artificially, and the step only has to resolve the
frequencies of interest.  The contacts make each step nonlinear: Newton
iterations on the step's residual with the tangent stiffness and damping of
the contacts that are closed, until the displacement update is below
`TOLERANCE`.

`static_equilibrium` gives the starting state: the elastic equilibrium at the
first instant, from the quasi-static solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BETA, GAMMA = 0.25, 0.5     # average acceleration (trapezoidal rule)
TOLERANCE = 1e-13           # [m] Newton update: 1e-7 um, far below any error or deflection
MAX_ITERATIONS = 30


@dataclass
class State:
    """q, v, a: (n,) displacement [m], velocity [m/s], acceleration [m/s^2] at one step."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray


class NewmarkStepper:
    """Fixed-step Newmark-beta over a `DynamicModel`: one `step()` advances one time step.

    load(step) -> (n,) external generalised force at a step (load and nominal inertia).
    """

    def __init__(self, model, load, state: State, step: int = 0, beta: float = BETA,
                 gamma: float = GAMMA):
        self.model, self.load = model, load
        self.state, self.k = state, step
        self.beta, self.gamma = beta, gamma
        self.M = np.diag(model.mass)
        self.iterations = 0
        self.failed_steps = 0

    @classmethod
    def starting_at(cls, model, load, q0, v0=None, step: int = 0, **kwargs):
        """A stepper whose initial acceleration balances the forces at q0, v0."""
        v0 = np.zeros_like(q0) if v0 is None else v0
        f, _, _ = model.forces(step, q0, v0)
        a0 = (load(step) - f) / model.mass
        return cls(model, load, State(q0.copy(), v0.copy(), a0), step, **kwargs)

    def step(self) -> State:
        """Advance to the next time step of the model's motion."""
        model, s, k = self.model, self.state, self.k
        time = model.motion.time
        h = time[k + 1] - time[k]
        b, g = self.beta, self.gamma
        F = self.load(k + 1)
        q = s.q + h * s.v + 0.5 * h * h * s.a          # average-acceleration predictor
        converged = False
        for it in range(MAX_ITERATIONS):
            a = (q - s.q - h * s.v) / (b * h * h) - (0.5 / b - 1.0) * s.a
            v = s.v + h * ((1.0 - g) * s.a + g * a)
            f, K, C = model.forces(k + 1, q, v)
            residual = self.M @ a + f - F
            J = self.M / (b * h * h) + C * (g / (b * h)) + K
            dq = np.linalg.solve(J, -residual)
            q = q + dq
            if np.max(np.abs(dq)) < TOLERANCE:
                converged = True
                break
        self.iterations = max(self.iterations, it + 1)
        self.failed_steps += not converged
        a = (q - s.q - h * s.v) / (b * h * h) - (0.5 / b - 1.0) * s.a
        v = s.v + h * ((1.0 - g) * s.a + g * a)
        self.state, self.k = State(q, v, a), k + 1
        return self.state


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
