"""A robot arm on the reducer's output flange as an FMU: flange angle in, torque on the flange out.

The arm is a rigid body of inertia J (about the horizontal joint axis, payload
included), mass m and centre of mass at l from the axis.  Angles are
counter-clockwise positive, 0 with the centre of mass level with the axis.  It
is bolted to the output flange through its link root, a torsional spring of
stiffness k with structural damping.  With `theta` the flange angle (the input)
and `theta_arm` the arm's own angle, the link twist is theta - theta_arm and

    J * d2(theta_arm)/dt2 = tau_link - m * g * l * cos(theta_arm)
    tau_load = -tau_link                                                  [N m]

`tau_load` is the torque of the arm on the flange in the sign convention of
docs/model.md section 2 (positive in the positive direction of rotation: an arm held
up against gravity gives a negative, resisting, `tau_load`); at rest it is
-m * g * l * cos(theta_arm), and in general -(J * alpha + m * g * l * cos(theta_arm)).

Why a link spring rather than a rigid arm with tau_load = -(J * alpha + m g l cos theta)
and alpha from finite differences of the flange angle: the quasi-static reducer
winds up at once under `tau_load` (its TE includes the windup, K ~ 3e5..1.2e6
N m/rad), so the flange angle of one step already answers the torque of the
step before.  A rigid inertia read through a second difference closes that
loop with a gain of about 4 J / (K h^2) ~ 5 at a 1 ms step and diverges in a
few steps, whatever the controller; filtering the difference only trades the
divergence for a lag.  A rigid body wants a torque in and an angle out; only a
spring can take an angle in.  The link root is that spring, and it is real (an
arm is softer there than the reducer).  The arm's inertia is integrated inside
the FMU, and the explicit loop through the reducer windup has the gain
(k + k2) / K, below 1 for the stiffness chosen here (see README.md).

The damping is a standard linear solid (Zener): the spring k in parallel with
a spring k2 in series with a damper c.  Unlike a dashpot across k, its
stiffness stays bounded (k + k2) at high frequency, so the loop gain above does
not grow as the communication step shrinks.  k2 and the relaxation time c / k2
are set from `link_damping_ratio` zeta: the loss factor peaks at 2 * zeta at
the arm's own frequency sqrt(k / J).

Inside a communication step the flange angle is interpolated linearly from its
value at the previous communication point to the value received, which is
taken as the value at the end of the step (in the Gauss-Seidel order
servo -> reducer -> arm the reducer has already been stepped there); the arm
is integrated with semi-implicit Euler and the damper with implicit Euler over
`substeps` sub-steps.

`ArmModel` is the physics, plain Python that knows nothing of FMI; the pythonfmu
adapter class below it is thin (pythonfmu finds it by its class line, which
must stay exactly as it is).  Slave methods never raise; a bad input is logged
and the step returns fmi2Discard.  The adapter saves and restores the model's
state with the FMU state (fmi2GetFMUstate / fmi2SetFMUstate), so that a master
can step again from a saved point, as run_joint.py's iterated coupling does.
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial, Fmi2Status

# Defaults: an 18 kg forearm-and-payload on an RV-40E joint (see README.md).
DEFAULTS = {
    "inertia": 1.5,  # kg m^2 about the joint axis (m * l^2 = 1.1 plus the link's own 0.4)
    "mass": 18.0,  # kg
    "com_distance": 0.25,  # m: gravity torque m g l = 44 N m, 11 % of the rated 412 N m
    "g": 9.81,  # m/s^2
    "link_stiffness": 1.0e5,  # N m/rad: link root and bolted flange, ~1/3 of the reducer's
    # windup stiffness; joint resonance ~35 Hz with both in series
    "link_damping_ratio": 0.05,  # structural damping of the arm on its link [1]
}
DEFAULT_SUBSTEPS = 20  # sub-steps per communication step: 50 us at 1 ms, 1/500 of a period


class ArmModel:
    """Arm inertia on a damped link spring (standard linear solid) driven by the flange angle.

    State: arm angle [rad] and speed [rad/s], damper deflection [rad], last flange
    angle [rad].  `initialize` and `step` return (tau_load [N m], theta_arm [rad],
    omega_arm [rad/s]).
    """

    def __init__(self, inertia, mass, com_distance, g, link_stiffness, link_damping_ratio, substeps):
        for name, value in (("mass", mass), ("com_distance", com_distance), ("g", g)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} = {value}: must be a finite number >= 0")
        for name, value in (("inertia", inertia), ("link_stiffness", link_stiffness)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value}: must be a finite number > 0")
        if not (math.isfinite(link_damping_ratio) and 0 < link_damping_ratio <= 0.25):
            raise ValueError(f"link_damping_ratio = {link_damping_ratio}: must be in (0, 0.25]")
        if inertia < mass * com_distance**2:
            raise ValueError(
                f"inertia = {inertia}: must be >= mass * com_distance^2 = "
                f"{mass * com_distance**2} (the centre of mass alone)"
            )
        if not (isinstance(substeps, int) and 1 <= substeps <= 10000):
            raise ValueError(f"substeps = {substeps}: must be an integer in [1, 10000]")
        self.J, self.k = inertia, link_stiffness
        # Zener loss factor k2*x / (k*(1 + x^2) + k2*x^2), x = omega * relaxation time: its peak,
        # at x = sqrt(k / (k + k2)), is k2 / (2 sqrt(k (k + k2))); set it to eta = 2 zeta.
        eta = 2.0 * link_damping_ratio
        self.k2 = 2.0 * eta * link_stiffness * (eta + math.sqrt(eta * eta + 1.0))
        self.relaxation_time = math.sqrt(self.k / (self.k + self.k2)) / math.sqrt(self.k / inertia)
        self.gravity_moment = mass * g * com_distance
        self.substeps = substeps
        self.state = {}

    def initialize(self, time, theta):
        """Start at rest in static equilibrium: the link spring k carries the gravity torque."""
        theta_arm = theta
        for _ in range(
            50
        ):  # fixed point of k (theta - theta_arm) = m g l cos(theta_arm); contracts by m g l / k
            theta_arm = theta - self.gravity_moment * math.cos(theta_arm) / self.k
        # relaxed damper: its deflection equals the twist, so the spring k2 carries nothing
        self.state = {
            "time": time,
            "theta": theta,
            "theta_arm": theta_arm,
            "omega_arm": 0.0,
            "damper": theta - theta_arm,
            "tau_load": -self.k * (theta - theta_arm),
        }
        return self.outputs()

    def step(self, time, step_size, theta):
        """Advance to time + step_size, where the flange angle is `theta`."""
        s = self.state
        J, k, k2, mgl = self.J, self.k, self.k2, self.gravity_moment
        dt = step_size / self.substeps
        relax = dt / self.relaxation_time
        omega = (theta - s["theta"]) / step_size  # flange speed over the step
        flange, arm, omega_arm, damper = s["theta"], s["theta_arm"], s["omega_arm"], s["damper"]
        for _ in range(self.substeps):
            twist = flange - arm
            link = k * twist + k2 * (twist - damper)  # torque of the flange on the arm
            omega_arm += dt * (link - mgl * math.cos(arm)) / J
            arm += dt * omega_arm
            flange += dt * omega
            # damper c * dq/dt = k2 * (twist - q), implicit Euler (unconditionally stable)
            damper = (damper + relax * (flange - arm)) / (1.0 + relax)
        twist = theta - arm
        link = k * twist + k2 * (twist - damper)  # at the end of the step
        s.update(
            time=time + step_size,
            theta=theta,
            theta_arm=arm,
            omega_arm=omega_arm,
            damper=damper,
            tau_load=-link,
        )
        return self.outputs()

    def outputs(self):
        s = self.state
        return s["tau_load"], s["theta_arm"], s["omega_arm"]


class Arm(Fmi2Slave):
    author = "rvte"
    description = (
        "Robot arm on a horizontal joint axis: inertia and gravity on a damped link "
        "spring; flange angle in, torque on the flange out"
    )

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta = 0.0
        self.tau_load = 0.0
        self.theta_arm = 0.0
        self.omega_arm = 0.0
        for name, value in DEFAULTS.items():
            setattr(self, name, value)
        self.substeps = DEFAULT_SUBSTEPS
        self._model = None
        self._failed = None

        cont, par = Fmi2Variability.continuous, Fmi2Variability.fixed
        self.register_variable(
            Real(
                "theta",
                causality=Fmi2Causality.input,
                variability=cont,
                description="output flange angle [rad], 0: centre of mass level",
            )
        )
        for name, text in (
            (
                "tau_load",
                "torque of the arm on the output flange [N.m], negative when it resists positive rotation",
            ),
            ("theta_arm", "arm angle [rad]"),
            ("omega_arm", "arm speed [rad/s]"),
        ):
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.output,
                    variability=cont,
                    initial=Fmi2Initial.calculated,
                    description=text,
                )
            )
        for name, text in (
            ("inertia", "arm inertia about the joint axis [kg.m2]"),
            ("mass", "arm mass [kg]"),
            ("com_distance", "distance of the centre of mass from the axis [m]"),
            ("g", "gravitational acceleration [m/s2]"),
            ("link_stiffness", "static torsional stiffness of the link root [N.m/rad]"),
            ("link_damping_ratio", "damping ratio of the arm on its link [1]"),
        ):
            self.register_variable(
                Real(name, causality=Fmi2Causality.parameter, variability=par, description=text)
            )
        self.register_variable(
            Integer(
                "substeps",
                causality=Fmi2Causality.parameter,
                variability=par,
                description="integration sub-steps per communication step",
            )
        )

    def exit_initialization_mode(self):
        try:
            self._model = ArmModel(*(float(getattr(self, n)) for n in DEFAULTS), substeps=int(self.substeps))
            self._check_input()
            self._show(self._model.initialize(0.0, self.theta))
        except Exception as exc:  # noqa: BLE001 -- never raise into pythonfmu (fmi2Fatal)
            self._model = None
            self._fail(f"initialisation failed: {exc}")

    def do_step(self, current_time, step_size):
        if self._model is None:
            self._fail(self._failed or "do_step before the end of initialisation")
            return False
        try:
            if not (math.isfinite(step_size) and step_size > 0):
                raise ValueError(f"communication step size = {step_size}: must be > 0")
            self._check_input()
            self._show(self._model.step(current_time, step_size, self.theta))
        except Exception as exc:  # noqa: BLE001
            self._fail(str(exc))
            return False
        return True

    # FMU state (fmi2GetFMUstate / fmi2SetFMUstate): the variables, as pythonfmu keeps them, and
    # the model's state, so that a master can step again from a saved point (run_joint.py's
    # iterated coupling does).
    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state["_arm"] = None if self._model is None else dict(self._model.state)
        return state

    def _set_fmu_state(self, state):
        state = dict(state)
        arm_state = state.pop("_arm", None)
        super()._set_fmu_state(state)
        if arm_state is not None and self._model is not None:
            self._model.state = dict(arm_state)

    def _check_input(self):
        if not math.isfinite(self.theta):
            raise ValueError(f"input theta = {self.theta}: must be finite")

    def _show(self, outputs):
        self.tau_load, self.theta_arm, self.omega_arm = outputs

    def _fail(self, message):
        self._failed = message
        self.log(message, Fmi2Status.error)
