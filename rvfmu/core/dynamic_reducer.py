"""The dynamic model as a time-stepping reducer: the FMU's `model = "dynamic"`.

A host gives the input angle and the load torque at the end of each
communication step; inside the step the input angle is taken as a straight
line from its previous value (constant speed over the step, the only motion
the host's samples define) and the load is held at its new value, and the
Newmark stepper runs internal steps of at most `internal_step` seconds.  The
outputs are those at the end of the step, but for tau_in, its mean over the
step, and p_loss and the efficiency, the power the reducer's friction and damping
dissipate over the step and what it leaves of the power that passes.  The state
is the displacements, velocities and accelerations of every unknown with the
last input angle and time: a master can save it, roll back and re-step to
the same results.
"""

from __future__ import annotations

import math

import numpy as np

from .dynamic import DynamicModel, Motion, at_rest
from .errors import ErrorSet
from .newmark import NewmarkStepper, State
from .reducer_model import Outputs, step_efficiency
from .newmark import static_start

DEFAULT_INTERNAL_STEP = 1e-4   # [s]: 10 kHz, 25 steps per stage-1 mesh period of an RV-110E at 1600 rpm


class DynamicReducer:
    """Time-stepping dynamic model of one reducer (docs/model.md section 7)."""

    name = "dynamic"

    def __init__(self, design, errors: ErrorSet, internal_step: float = DEFAULT_INTERNAL_STEP,
                 contact: str | None = None, mesh: str = "varying"):
        if not (math.isfinite(internal_step) and internal_step > 0):
            raise ValueError(f"internal_step = {internal_step}: must be a number > 0")
        self.design, self.errors = design, errors
        self.internal_step = internal_step
        self.contact, self.mesh = contact, mesh
        self.model = None
        self.time = self.theta_in = self.omega_in = self.tau_load = 0.0
        self.state = None

    def _model(self, tau_load: float) -> DynamicModel:
        flank = 1 if tau_load <= 0 else -1
        if self.model is None or self.model.flank != flank:
            before = self.model
            self.model = DynamicModel(self.design, self.errors, self.contact, self.mesh, flank)
            if before is not None:      # the modes damped at the start stay damped alike
                self.model.elements = self.model.elements._replace(modal_c=before.elements.modal_c)
                self.model.modal_frequencies = before.modal_frequencies
                self.model.modal_shapes, self.model.floating = before.modal_shapes, before.floating
        return self.model

    def _outputs(self, omega_in: float, tau_in: float, tau_load: float,
                 torque_rate: float = 0.0, p_loss: float = 0.0, p_out: float = 0.0) -> Outputs:
        """Outputs of the flange: the carrier plus the windup of the massless series compliance
        under tau_load [N*m], changing at torque_rate [N*m/s]; p_loss and p_out [W]: the
        power dissipated and the power the output gives the load, means over the step."""
        model, s, c = self.model, self.state, self.design.series_compliance
        te = s.q[model.carrier_rot] / model.scale + c * tau_load
        omega_out = omega_in / self.design.ratio + s.v[model.carrier_rot] / model.scale + c * torque_rate
        return Outputs(self.theta_in / self.design.ratio + te, omega_out, te, tau_in, p_loss,
                       step_efficiency(p_out, p_loss))

    def initialize(self, time: float, theta_in: float, tau_load: float) -> Outputs:
        """At rest in the elastic equilibrium under tau_load at theta_in."""
        model = self._model(tau_load)
        model.prepare(at_rest(theta_in, time, tau_load))
        q = static_start(model, tau_load, theta_in)
        model.set_modal_damping(q)
        self.time, self.theta_in = float(time), float(theta_in)
        self.state = State(q, np.zeros(model.n), np.zeros(model.n))
        self.omega_in, self.tau_load = 0.0, float(tau_load)
        return self._outputs(0.0, model.input_torque(q, np.zeros(model.n)), self.tau_load)

    def step(self, time: float, step_size: float, theta_in: float, tau_load: float) -> Outputs:
        """Outputs at time + step_size for the inputs there."""
        count = max(1, math.ceil(step_size / self.internal_step - 1e-9))
        t = time + step_size * np.arange(count + 1) / count
        omega = (theta_in - self.theta_in) / step_size
        angles = self.theta_in + omega * (t - time)
        model = self._model(tau_load)
        # the nominal motion's d'Alembert forces come at this constant speed (centripetal terms)
        model.prepare(Motion(t, angles, np.full(t.size, omega), np.zeros(t.size), tau_load))
        stepper = NewmarkStepper(model, self.state)
        q, v, power = (np.empty((count + 1, model.n)), np.empty((count + 1, model.n)),
                       np.empty((count + 1, 2)))
        q[0], v[0] = self.state.q, self.state.v
        power[0] = model.forces_and_powers(0, q[0], v[0])[3]
        stepper.advance(count, q, v, power)
        # tau_in over the step, its mean (trapezoid over the internal steps): what a host that
        # holds it over its next step should get; the end value alone carries the sun's ringing
        # on its shaft (kHz), sampled once per communication step
        def mean(x):
            return float(np.sum(0.5 * np.diff(t) * (x[1:] + x[:-1])) / step_size)

        tau_in = mean(model.input_torque(q.T, v.T))
        p_loss = mean(power.sum(axis=1))
        p_out = -float(tau_load) * mean(omega / self.design.ratio
                                        + v[:, model.carrier_rot] / model.scale)
        self.state = stepper.state
        self.time, self.theta_in, self.omega_in = time + step_size, float(theta_in), omega
        rate, self.tau_load = (float(tau_load) - self.tau_load) / step_size, float(tau_load)
        return self._outputs(omega, tau_in, self.tau_load, rate, p_loss, p_out)

    def get_state(self) -> dict:
        s = self.state
        return {"time": self.time, "theta_in": self.theta_in, "omega_in": self.omega_in,
                "tau_load": self.tau_load, "q": s.q.tolist(), "v": s.v.tolist(), "a": s.a.tolist()}

    def set_state(self, state: dict) -> None:
        try:
            arrays = [np.asarray(state[k], dtype=float) for k in ("q", "v", "a")]
            scalars = [float(state[k]) for k in ("time", "theta_in", "omega_in", "tau_load")]
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"not a state of this model: {sorted(state)}") from None
        n = self.model.n if self.model is not None else arrays[0].size
        if any(a.shape != (n,) or not np.all(np.isfinite(a)) for a in arrays) or \
                not all(math.isfinite(x) for x in scalars):
            raise ValueError("not a state of this model: wrong sizes or non-finite values")
        self.time, self.theta_in, self.omega_in, self.tau_load = scalars
        self.state = State(*[a.copy() for a in arrays])
