"""The reducer as a time-stepping model: input angle and output torque in, output angle out.

This is the interface that a system simulation (the FMU, or any other host)
drives.  A model is a small object with one job: `step` to the end of a
communication interval given the inputs there, returning the outputs there.
Its whole state is a small dict, so that a master can save and restore it.
Two implementations: the quasi-static TE map (`QuasiStaticReducer`, here) and
the dynamic model (`dynamic_reducer.DynamicReducer`), with the same methods;
`reducers.MODELS` names them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .te_map import TEMap


@dataclass(frozen=True)
class Outputs:
    """Outputs at one instant: theta_out [rad], omega_out [rad/s], te [rad], tau_in [N*m]."""

    theta_out: float
    omega_out: float
    te: float
    tau_in: float


class QuasiStaticReducer:
    """Static equilibrium at every instant, from a TE map.

    theta_out = theta_in / i + TE(theta_in, tau_load); omega_out is the output
    angle's change over the last step divided by its length (zero before the first
    step), so the outputs at the end of a step depend only on the inputs there and
    on the output angle at its start, whatever the step size.
    """

    name = "quasistatic"

    def __init__(self, te_map: TEMap):
        self.map = te_map
        self._evaluate_map = te_map.evaluate_one
        self._ratio = te_map.ratio
        self.time = self.theta_out = self.omega_out = 0.0

    def initialize(self, time: float, theta_in: float, tau_load: float) -> Outputs:
        te, tau_in = self._evaluate_map(theta_in, tau_load)
        self.time, self.theta_out, self.omega_out = float(time), theta_in / self._ratio + te, 0.0
        return Outputs(self.theta_out, 0.0, te, tau_in)

    def step(self, time: float, step_size: float, theta_in: float, tau_load: float) -> Outputs:
        """Outputs at time + step_size for the inputs there."""
        te, tau_in = self._evaluate_map(theta_in, tau_load)
        theta_out = theta_in / self._ratio + te
        omega = (theta_out - self.theta_out) / step_size if step_size > 0 else 0.0
        self.time, self.theta_out, self.omega_out = time + step_size, theta_out, omega
        return Outputs(theta_out, omega, te, tau_in)

    def get_state(self) -> dict:
        return {"time": self.time, "theta_out": self.theta_out, "omega_out": self.omega_out}

    def set_state(self, state: dict) -> None:
        keys = ("time", "theta_out", "omega_out")
        if set(keys) - set(state) or not all(math.isfinite(float(state[k])) for k in keys):
            raise ValueError(f"not a state of this model: {sorted(state)}")
        self.time, self.theta_out, self.omega_out = (float(state[k]) for k in keys)
