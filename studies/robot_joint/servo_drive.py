"""A robot-joint servo drive as an FMU: motor inertia, friction, torque limit, cascaded control.

What a real robot joint does: the drive closes its loops on the *motor*
encoder.  A P position loop on the motor angle sets a velocity command, a PI
velocity loop turns it into a torque command, limited to the motor's peak
torque.  The position reference is the arm reference times the reducer ratio,
so everything the reducer adds between motor and arm (transmission error,
windup, lost motion) is invisible to the loops and shows up, uncorrected, as
arm position error.  That is why TE matters in a robot joint.

The drive receives a new arm setpoint `theta_ref` every communication step (as
a robot controller sends one every interpolation cycle).  Between setpoints it
extrapolates linearly with the rate of the last two setpoints and feeds that
rate forward to the velocity loop (velocity feed-forward, as industrial drives
do), so a moving reference gives almost no following error.

The motor shaft: J_m * d(omega)/dt = tau_motor + tau_in - b * omega, where
`tau_in` is the torque of the reducer on its input shaft (negative when the
reducer resists the motor, see docs/model.md section 2 and the reducer FMU).  It is
integrated with semi-implicit (symplectic) Euler over `substeps` sub-steps per
communication step, and the controller runs at that sub-step rate, like a
drive's fast velocity loop; `tau_in` is held over the communication step.

`ServoDriveModel` is the physics and control, plain Python that knows nothing
of FMI; `ServoDrive` is the thin pythonfmu adapter.  pythonfmu finds the class
by its `class ServoDrive(Fmi2Slave):` line, so keep that line as it is.  Slave
methods never raise: pythonfmu would report fmi2Fatal and drop the instance;
a bad input or parameter is logged and the step returns fmi2Discard.
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial, Fmi2Status

# Defaults: a ~1 kW AC servo motor on an RV-40E-121 joint (see README.md).
DEFAULTS = {
    "ratio": 121.0,  # reducer ratio i (RV-40E-121)
    "motor_inertia": 1.5e-4,  # kg m^2: rotor plus the reducer's input shaft
    "viscous_friction": 1.0e-4,  # N m s/rad: bearing and seal drag, ~0.03 N m at 3000 rpm
    "torque_limit": 9.5,  # N m: peak torque of a 1 kW, 3.2 N m rated motor
    "position_gain": 150.0,  # 1/s: position loop, a quarter of the velocity loop bandwidth
    "velocity_gain": 0.15,  # N m s/rad: velocity loop crossover kv / (J_m + J_arm / i^2)
    # = 0.15 / 2.5e-4 = 600 rad/s (95 Hz) with the 1.5 kg m^2 arm
    "velocity_integral_time": 0.008,  # s: PI zero at 125 rad/s, well below the crossover
    "velocity_feedforward": 1.0,  # fraction of the setpoint rate fed to the velocity loop
}
DEFAULT_SUBSTEPS = 20  # sub-steps per communication step: 50 us at a 1 ms step


class ServoDriveModel:
    """Motor shaft and cascaded P/PI controller; state: motor angle, speed, velocity integral.

    Angles in rad and speeds in rad/s on the motor side; the reference `theta_ref`
    is on the arm side (rad) and is multiplied by `ratio` here.
    """

    def __init__(
        self,
        ratio,
        motor_inertia,
        viscous_friction,
        torque_limit,
        position_gain,
        velocity_gain,
        velocity_integral_time,
        velocity_feedforward,
        substeps,
    ):
        positive = {
            "ratio": ratio,
            "motor_inertia": motor_inertia,
            "torque_limit": torque_limit,
            "position_gain": position_gain,
            "velocity_gain": velocity_gain,
            "velocity_integral_time": velocity_integral_time,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value}: must be a finite number > 0")
        if not (math.isfinite(viscous_friction) and viscous_friction >= 0):
            raise ValueError(f"viscous_friction = {viscous_friction}: must be a finite number >= 0")
        if not (math.isfinite(velocity_feedforward) and 0 <= velocity_feedforward <= 1):
            raise ValueError(f"velocity_feedforward = {velocity_feedforward}: must be in [0, 1]")
        if not (isinstance(substeps, int) and 1 <= substeps <= 10000):
            raise ValueError(f"substeps = {substeps}: must be an integer in [1, 10000]")
        self.i, self.J, self.b, self.limit = ratio, motor_inertia, viscous_friction, torque_limit
        self.kp, self.kv, self.ti, self.kff = (
            position_gain,
            velocity_gain,
            velocity_integral_time,
            velocity_feedforward,
        )
        self.substeps = substeps
        self.state = {}

    def initialize(self, time, theta_ref, tau_in):
        """Start at rest on the reference, holding the load: the velocity integral is preset
        to the torque that balances `tau_in`, so the run starts in static equilibrium."""
        holding = min(max(-tau_in, -self.limit), self.limit)
        self.state = {
            "time": time,
            "theta": self.i * theta_ref,
            "omega": 0.0,
            "integral": holding,
            "tau": holding,
            "ref": theta_ref,
            "ref_time": time,
            "ref_rate": 0.0,
        }
        return self.outputs()

    def step(self, time, step_size, theta_ref, tau_in):
        """Advance over [time, time + step_size] with the inputs held; outputs at the end."""
        s = self.state
        if time > s["ref_time"]:
            s["ref_rate"] = (theta_ref - s["ref"]) / (time - s["ref_time"])
        s["ref"], s["ref_time"] = theta_ref, time
        i, J, b, limit, kp, kv = self.i, self.J, self.b, self.limit, self.kp, self.kv
        dt = step_size / self.substeps
        ki_dt = kv / self.ti * dt
        ref, ref_rate = i * theta_ref, i * s["ref_rate"]
        theta, omega, integral, tau = s["theta"], s["omega"], s["integral"], s["tau"]
        for k in range(self.substeps):
            # position loop (P) -> velocity loop (PI) -> torque, at the start of the sub-step
            omega_cmd = self.kff * ref_rate + kp * (ref + ref_rate * k * dt - theta)
            error = omega_cmd - omega
            tau = kv * error + integral
            if tau > limit or tau < -limit:
                tau = limit if tau > 0 else -limit  # clamp, and hold the integral (anti-windup)
            else:
                integral += ki_dt * error
            # semi-implicit Euler: new speed first, then the angle with the new speed
            omega += dt * (tau + tau_in - b * omega) / J
            theta += dt * omega
        s.update(time=time + step_size, theta=theta, omega=omega, integral=integral, tau=tau)
        return self.outputs()

    def outputs(self):
        """(theta_motor [rad], omega_motor [rad/s], tau_motor [N m]) at the current time."""
        s = self.state
        return s["theta"], s["omega"], s["tau"]


class ServoDrive(Fmi2Slave):
    author = "rvte"
    description = (
        "Robot-joint servo drive: motor inertia, viscous friction, torque limit and a "
        "cascaded P position / PI velocity controller on the motor encoder"
    )

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_ref = 0.0
        self.tau_in = 0.0
        self.theta_motor = 0.0
        self.omega_motor = 0.0
        self.tau_motor = 0.0
        for name, value in DEFAULTS.items():
            setattr(self, name, value)
        self.substeps = DEFAULT_SUBSTEPS
        self._model = None
        self._failed = None

        cont, par = Fmi2Variability.continuous, Fmi2Variability.fixed
        for name, text in (
            ("theta_ref", "arm position reference [rad]; the motor reference is ratio times it"),
            (
                "tau_in",
                "torque of the reducer on the motor shaft [N.m], negative when it resists positive rotation",
            ),
        ):
            self.register_variable(
                Real(name, causality=Fmi2Causality.input, variability=cont, description=text)
            )
        for name, text in (
            ("theta_motor", "motor (encoder) angle [rad]"),
            ("omega_motor", "motor speed [rad/s]"),
            ("tau_motor", "motor torque of the last sub-step [N.m], within +-torque_limit"),
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
            ("ratio", "reducer ratio i [1]"),
            ("motor_inertia", "rotor inertia plus reducer input shaft [kg.m2]"),
            ("viscous_friction", "viscous friction on the motor shaft [N.m.s/rad]"),
            ("torque_limit", "peak motor torque [N.m]"),
            ("position_gain", "position loop gain [1/s]"),
            ("velocity_gain", "velocity loop proportional gain [N.m.s/rad]"),
            ("velocity_integral_time", "velocity loop integral time [s]"),
            ("velocity_feedforward", "fraction of the setpoint rate fed forward [1]"),
        ):
            self.register_variable(
                Real(name, causality=Fmi2Causality.parameter, variability=par, description=text)
            )
        self.register_variable(
            Integer(
                "substeps",
                causality=Fmi2Causality.parameter,
                variability=par,
                description="integration and control sub-steps per communication step",
            )
        )

    def exit_initialization_mode(self):
        try:
            self._model = ServoDriveModel(
                *(float(getattr(self, n)) for n in DEFAULTS), substeps=int(self.substeps)
            )
            self._check_inputs()
            self._show(self._model.initialize(0.0, self.theta_ref, self.tau_in))
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
            self._check_inputs()
            self._show(self._model.step(current_time, step_size, self.theta_ref, self.tau_in))
        except Exception as exc:  # noqa: BLE001
            self._fail(str(exc))
            return False
        return True

    def _check_inputs(self):
        for name in ("theta_ref", "tau_in"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"input {name} = {value}: must be finite")

    def _show(self, outputs):
        self.theta_motor, self.omega_motor, self.tau_motor = outputs

    def _fail(self, message):
        self._failed = message
        self.log(message, Fmi2Status.error)
