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

from ..laws.lubricant import REFERENCE_TEMPERATURE_C
from .te_map import TEMap

# The speed scale of the friction law [rad/s at the input]: friction is Coulomb's beyond it
# and proportional to the input speed within it, so that it turns continuously through zero
# (no chatter at standstill) and costs a host no event; 0.01 rad/s is 0.1 rpm at the motor.
FRICTION_SPEED_SCALE = 0.01
# The Stribeck speed of the breakaway law [rad/s at the input]: from rest the Coulomb contacts
# and the seals break away at static_friction_factor x their running friction, which decays
# as exp(-(omega_in / STRIBECK_SPEED)^2) to the running one.  Lubricated steel contacts reach
# their running friction at sliding speeds of about 0.01 m/s (the Stribeck velocity of the
# survey of Armstrong-Helouvry, Dupont and Canudas de Wit, Automatica 30(7), 1994, 1083-1138,
# whose examples run from 1e-5 to 0.1 m/s); the input seal's lip, on a 12 to 20 mm shaft,
# slides at about 0.01 m/s at 1 rad/s, the pins and bearings (turning slower than the input)
# at less.  An estimate, 100 x FRICTION_SPEED_SCALE: within that scale the law is Coulomb's
# regularised (no chatter); the breakaway only raises the torque it reaches.
STRIBECK_SPEED = 1.0
# exp(-STRIBECK_CUT) is below a double's resolution of 1: beyond it the factor is 1 exactly.
STRIBECK_CUT = 40.0


def stribeck_decay(x: float) -> float:
    """exp(-x) for 0 <= x [1], in plain arithmetic the native FMU's C repeats operation for
    operation (it needs no libm, rvfmu/fmu/native/model.c): x halved to <= 1/2 (exact), its
    Taylor series to the 16th power (truncation < 1e-17), squared back; relative error within
    about 2^n ulp, n <= 7 halvings.  0 beyond STRIBECK_CUT."""
    if x > STRIBECK_CUT:
        return 0.0
    halvings = 0
    while x > 0.5:
        x *= 0.5
        halvings += 1
    term, total = 1.0, 1.0
    for k in range(1, 17):
        term = term * (-x) / k
        total = total + term
    for _ in range(halvings):
        total = total * total
    return total


@dataclass(frozen=True)
class Outputs:
    """Outputs at one instant: theta_out [rad], omega_out [rad/s], te [rad], tau_in [N*m],
    p_loss [W] (the friction's power over the last step), efficiency [1] (over the last step:
    forward the power the frictionless reducer passes over that plus the loss, backdriving
    what is left of it after the loss; 0 where no power passes)."""

    theta_out: float
    omega_out: float
    te: float
    tau_in: float
    p_loss: float = 0.0
    efficiency: float = 0.0


def friction_step(
    tau_map: float,
    friction_out: float,
    ratio: float,
    omega_in: float,
    breakaway_out: float = 0.0,
    static_factor: float = 1.0,
):
    """(tau_in [N*m], p_loss [W], efficiency) of a step: the frictionless map's input torque
    `tau_map`, the friction torque at the output `friction_out` [N*m] (>= 0), the input speed
    over the step [rad/s].  Friction opposes the input's turning: its torque at the input
    is friction_out / i times the speed over FRICTION_SPEED_SCALE, clipped to +-1 (docs/model.md
    section 9).  Breakaway (a regularised Stribeck law): the part `breakaway_out` [N*m] of
    friction_out (the Coulomb contacts' and the seals', not the viscous drag and churning)
    counts 1 + (static_factor - 1) exp(-(omega_in / STRIBECK_SPEED)^2) times; with
    static_factor 1 friction_out is unchanged to the bit."""
    excess = static_factor - 1.0
    if excess != 0.0:
        x = omega_in / STRIBECK_SPEED
        friction_out = friction_out + excess * stribeck_decay(x * x) * breakaway_out
    sense = omega_in / FRICTION_SPEED_SCALE
    sense = 1.0 if sense > 1.0 else (-1.0 if sense < -1.0 else sense)
    torque = sense * (friction_out / ratio)
    p_loss = torque * omega_in  # >= 0
    passed = tau_map * omega_in  # the frictionless reducer's power into the input shaft
    if passed < 0.0:  # it resists the input: the motor drives
        efficiency = -passed / (p_loss - passed)
    elif passed > 0.0:  # it drives the input: the load backdrives the motor
        efficiency = (passed - p_loss) / passed if passed > p_loss else 0.0
    else:
        efficiency = 0.0
    return tau_map - torque, p_loss, efficiency


class QuasiStaticReducer:
    """Static equilibrium at every instant, from a TE map.

    theta_out = theta_in / i + TE(theta_in, tau_load); omega_out is the output
    angle's change over the last step divided by its length (zero before the first
    step), so the outputs at the end of a step depend only on the inputs there and
    on the output and input angles at its start, whatever the step size.  The input
    torque carries the friction of the map (`friction_step`) at the input speed over
    the step, the lubricant at `temperature_C` [C] (the map's load-free table read there,
    `TEMap.load_free_row`: InputError outside its temperatures), the Coulomb friction and the
    seals breaking away near standstill at the map's static_friction_factor.
    """

    name = "quasistatic"

    def __init__(self, te_map: TEMap, temperature_C: float = REFERENCE_TEMPERATURE_C):
        self.map = te_map
        self.temperature_C = float(temperature_C)
        self._evaluate_map = te_map.evaluate_one
        self._load_free = te_map.load_free(self.temperature_C)
        self._seal = te_map.seal
        self._static = te_map.static_friction_factor
        self._ratio = te_map.ratio
        self.time = self.theta_out = self.omega_out = self.theta_in = 0.0

    def initialize(self, time: float, theta_in: float, tau_load: float) -> Outputs:
        te, tau_in, _ = self._evaluate_map(theta_in, tau_load)
        self.time, self.theta_out, self.omega_out = float(time), theta_in / self._ratio + te, 0.0
        self.theta_in = theta_in
        return Outputs(self.theta_out, 0.0, te, tau_in)

    def step(self, time: float, step_size: float, theta_in: float, tau_load: float) -> Outputs:
        """Outputs at time + step_size for the inputs there."""
        te, tau_map, coulomb = self._evaluate_map(theta_in, tau_load)
        theta_out = theta_in / self._ratio + te
        if step_size > 0:
            omega = (theta_out - self.theta_out) / step_size
            omega_in = (theta_in - self.theta_in) / step_size
        else:
            omega = omega_in = 0.0
        friction_out = coulomb + self._load_free(omega_in / self._ratio)
        tau_in, p_loss, efficiency = friction_step(
            tau_map, friction_out, self._ratio, omega_in, coulomb + self._seal, self._static
        )
        self.time, self.theta_out, self.omega_out = time + step_size, theta_out, omega
        self.theta_in = theta_in
        return Outputs(theta_out, omega, te, tau_in, p_loss, efficiency)

    def get_state(self) -> dict:
        return {
            "time": self.time,
            "theta_out": self.theta_out,
            "omega_out": self.omega_out,
            "theta_in": self.theta_in,
        }

    def set_state(self, state: dict) -> None:
        keys = ("time", "theta_out", "omega_out", "theta_in")
        if set(keys) - set(state) or not all(math.isfinite(float(state[k])) for k in keys):
            raise ValueError(f"not a state of this model: {sorted(state)}")
        self.time, self.theta_out, self.omega_out, self.theta_in = (float(state[k]) for k in keys)
