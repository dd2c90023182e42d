"""Simulating the dynamic model: a prescribed input motion and load in, TE(t) and its spectrum out.

The run starts at rest in the elastic equilibrium under the initial load (from
the quasi-static solution, refined with the input shaft's twist), raises the
input speed over a smooth ramp (seed 004) and integrates with the Newmark
stepper.  The metrics are taken over the constant-speed part after the ramp,
where the spectrum by frequency shows the reducer's own excitations: input
rotation, crank rotation, pin passing and stage-1 mesh (docs/model.md section 7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..base.checks import InputError, finite_number, fits_in_memory, positive
from ..base.units import RPM, rad_to_arcsec
from ..laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature
from ..losses.friction import step_efficiency
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet, zero_errors
from ..reducer.limits import check_load, check_speed
from ..statics.metrics import NOISE_FLOOR_ARCSEC
from .dynamic import MESH_MODELS, DynamicModel, Motion, contact_law, ramp_motion
from .excitations import HARMONICS, Excitations, amplitude_at, read_amplitudes  # noqa: F401 (this module's face)
from .modes import modes
from .newmark import NewmarkStepper, _quasi_static_start, static_start  # noqa: F401 (as above)

STEPS_PER_PERIOD = 20  # default step: 20 per period of the fastest excitation (mesh or pin passing)
MIN_STEPS_PER_PERIOD = 8  # coarser than this misses the excitation: refused
NATURAL_STEPS_PER_PERIOD = 15  # and 15 per period of a natural frequency the excitations reach: the
# average-acceleration rule's period error (pi^2/12)(h/T)^2 < 0.4 %
METHODS = ("newmark", "Radau", "BDF")
DEFAULT_RAMP_OUTPUT_TURNS = 0.02  # start ramp: 2 % of an output revolution's time at speed, >= 0.05 s
# The longest run `simulate` starts: a million steps are 20 output revolutions of the RV-40E-121
# at 1600 rpm, and 22-40 s of stepping at the 25,000-45,000 steps/s measured on one core of a
# 2-core Xeon (seed 002's errors, 1600 and 16,900 rpm); beyond, a run is minutes to hours with
# nothing to show (1e7 rpm: 2.2 million steps, the rate falling to 2,000 steps/s at speed).
MAX_STEPS = 1_000_000
PROGRESS_STEPS = 50_000  # runs of more steps report progress: they take more than a second or two


@dataclass(frozen=True)
class Simulation:
    """A dynamic run of one reducer.

    time, theta_in, theta_out, te [rad], omega_out [rad/s], tau_in [N*m], tau_load [N*m]: (T,);
    q: (T, n) every unknown [m, rotations as arc length at R_p], names in `dofs`;
    steady: index of the first step after the start ramp; step [s]; omega_in [rad/s],
    friction_power, damper_power [W]: (T,), the power the contacts' friction and the
    elements' dashpots dissipate; drive: "ramp" (constant speed after a start ramp) or
    "sampled" (sampled input angles); warnings: texts of the inputs beyond their rated
    class (`limits.check_load`, `limits.check_speed`), for the reports to print.
    """

    design: RVDesign
    speed_rpm: float
    time: np.ndarray
    theta_in: np.ndarray
    theta_out: np.ndarray
    te: np.ndarray
    omega_out: np.ndarray
    tau_in: np.ndarray
    tau_load: np.ndarray
    q: np.ndarray
    dofs: tuple
    steady: int
    step: float
    failed_steps: int
    omega_in: np.ndarray
    friction_power: np.ndarray
    damper_power: np.ndarray
    drive: str = "ramp"
    warnings: tuple[str, ...] = ()

    @property
    def input_reverses(self) -> bool:
        """Whether the input angle goes back anywhere after the start ramp (a sampled input
        that reverses, or whose spline does between samples): the record then has no single
        speed, so no excitation frequency."""
        return bool(np.any(np.diff(self.theta_in[self.steady :]) < 0.0))

    @property
    def input_power(self) -> np.ndarray:
        """(T,) [W] the power the input shaft brings in: minus the reducer's torque on it
        (docs/model.md section 2) times its speed."""
        return -self.tau_in * self.omega_in

    @property
    def output_power(self) -> np.ndarray:
        """(T,) [W] the power the output gives the load: minus tau_load times the output speed
        (negative where the load drives)."""
        return -self.tau_load * self.omega_out

    def mean_powers(self) -> dict:
        """{"input_W", "output_W", "friction_W", "damping_W": mean over the run after the
        start ramp (trapezoid in time); "efficiency": `friction.step_efficiency` of
        those means (what the losses leave of the power that passes, forward or
        backdriving; None where no power passes)}."""
        t = self.time[self.steady :]
        span = t[-1] - t[0] if t.size > 1 else 0.0

        def mean(x):
            x = x[self.steady :]
            return float(np.sum(0.5 * np.diff(t) * (x[1:] + x[:-1])) / span) if span > 0 else float(x[0])

        out = {
            "input_W": mean(self.input_power),
            "output_W": mean(self.output_power),
            "friction_W": mean(self.friction_power),
            "damping_W": mean(self.damper_power),
        }
        passes = out["output_W"] != 0.0
        out["efficiency"] = (
            step_efficiency(out["output_W"], out["friction_W"] + out["damping_W"]) if passes else None
        )
        return out

    @property
    def te_arcsec(self) -> np.ndarray:
        return rad_to_arcsec(self.te)

    def steady_te_arcsec(self) -> np.ndarray:
        return self.te_arcsec[self.steady :]

    @property
    def te_pp_arcsec(self) -> float:
        te = self.steady_te_arcsec()
        return float(te.max() - te.min())

    def spectrum_hz(self):
        """(frequencies [Hz], amplitudes [arcsec]) of the TE after the ramp, mean removed
        (Hann window, amplitude-corrected)."""
        te = self.steady_te_arcsec()
        te = te - te.mean()
        window = np.hanning(te.size)
        amplitude = 2.0 * np.abs(np.fft.rfft(te * window)) / window.sum()
        return np.fft.rfftfreq(te.size, self.step), amplitude

    def excitation_rows(self) -> list[tuple[str, float, float | None, str | None]]:
        """[(name, frequency [Hz], TE amplitude [arcsec] or None, why it is None or None)] of
        every excitation and its 2nd harmonic at the run's speed (`Excitations`), after the
        start ramp (`read_amplitudes`): None where the record is too short to resolve it
        ("needs >= X s of record"), above the step's Nyquist frequency, and everywhere when
        the input reverses ("the input reverses": no single speed, no frequency)."""
        listed = Excitations.at(self.design, self.speed_rpm).with_harmonics()
        if self.input_reverses:
            return [(name, hz, None, "the input reverses") for name, hz in listed]
        return read_amplitudes(self.steady_te_arcsec(), self.step, listed)

    def excitation_amplitudes(self) -> list[tuple[str, float, float | None]]:
        """[(name, frequency [Hz], TE amplitude [arcsec] or None)]: `excitation_rows`
        without the reasons."""
        return [(name, hz, amplitude) for name, hz, amplitude, _ in self.excitation_rows()]

    def peaks_hz(self, count: int = 5, floor: float = NOISE_FLOOR_ARCSEC):
        """Up to `count` largest local maxima of the spectrum above `floor` arcsec: [(Hz, arcsec)]."""
        f, a = self.spectrum_hz()
        inner = np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] >= a[2:])) + 1
        inner = inner[a[inner] > floor]
        top = inner[np.argsort(-a[inner])][:count]
        return [(float(f[k]), float(a[k])) for k in top]


def default_step(design: RVDesign, speed_rpm: float, natural_hz=()) -> float:
    """[s]: STEPS_PER_PERIOD steps per period of the faster of pin passing and stage-1 mesh,
    and at least NATURAL_STEPS_PER_PERIOD per period of every natural frequency [Hz] that
    their second harmonics reach (up to twice the faster): a resonance they excite is
    resolved.  natural_hz: the linearised model's (`modes`), as `simulate` passes them."""
    ex = Excitations.at(design, speed_rpm)
    fastest = max(ex.pin_passing, ex.mesh)
    step = 1.0 / (STEPS_PER_PERIOD * fastest)
    reached = [f for f in np.asarray(natural_hz, dtype=float) if f <= 2.0 * fastest]
    if reached:
        step = min(step, 1.0 / (NATURAL_STEPS_PER_PERIOD * max(reached)))
    return step


@dataclass(frozen=True)
class Sampled:
    """A signal given at sample times [s]: linear between samples, held beyond them.

    `checked` gives one with finite values at strictly increasing times, or an
    InputError naming the field and the first bad sample.  name: the input it came from
    (the field later errors name), "load_step" for `step`.
    """

    time: np.ndarray
    values: np.ndarray
    name: str = ""

    @classmethod
    def checked(cls, name: str, time, values, at_least: int = 2) -> "Sampled":
        t, x = np.asarray(time, dtype=float).ravel(), np.asarray(values, dtype=float).ravel()
        if t.size != x.size or t.size < at_least:
            raise InputError(
                name,
                f"{t.size} times, {x.size} values",
                f"needs at least {at_least} samples, one value per time",
            )
        for label, data in (("time", t), ("value", x)):
            bad = np.flatnonzero(~np.isfinite(data))
            if bad.size:
                raise InputError(
                    name,
                    f"{label} {data[bad[0]]} at sample {bad[0] + 1}",
                    "every sample must be a finite number",
                )
        back = np.flatnonzero(np.diff(t) <= 0.0)
        if back.size:
            raise InputError(
                name, f"time {t[back[0] + 1]:g} s at sample {back[0] + 2}", "times must increase strictly"
            )
        return cls(t, x, name)

    @classmethod
    def step(cls, before: float, at: float, after: float) -> "Sampled":
        """`before` until time `at` [s], `after` from then on (a step with a 1 ns rise)."""
        at = finite_number("load step time", at)
        return cls(np.array([at - 1e-9, at]), np.array([before, after]), "load_step")

    def at(self, time) -> np.ndarray:
        return np.interp(time, self.time, self.values)


def sampled_motion(time, angle: Sampled, tau_load) -> Motion:
    """The input motion through sampled input angles: a cubic spline (not-a-knot), its
    first and second derivatives the speed and acceleration, evaluated at `time`."""
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(angle.time, angle.values)
    return Motion(time, spline(time), spline(time, 1), spline(time, 2), tau_load)


def simulate(
    design: RVDesign,
    errors: ErrorSet | None = None,
    speed_rpm: float | None = 1600.0,
    load: float | Sampled = 0.0,
    duration: float | None = None,
    revolutions: float | None = None,
    contact: str | None = None,
    mesh: str = "varying",
    step: float | None = None,
    ramp: float | None = None,
    method: str = "newmark",
    progress=None,
    input_angle: Sampled | None = None,
    friction: bool = True,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
) -> Simulation:
    """Dynamic TE of one reducer at a constant input speed after a start ramp, or along
    sampled input angles.

    load: resisting output torque [N*m] (tau_load = -load), constant or `Sampled`
    over the run's time (t = 0 at the start of the ramp); duration [s] or
    revolutions (output revolutions at speed, after the ramp); step [s] (default
    `default_step`); ramp [s] (default 2 % of an output revolution, at least
    0.05 s).  input_angle: `Sampled` input angles [rad] instead of the ramp and
    constant speed (speed_rpm, duration, revolutions and ramp then come from the
    samples and must not be given).  method: "newmark" (fixed step, the default)
    or "Radau" / "BDF" (scipy's adaptive solve_ivp, the slow reference).  friction:
    False simulates the reducer without its contacts' friction and drag.  temperature_C: the
    lubricant's [C] (default 40), the viscosity of the bearings' drag and of the churning.
    progress(total, done): optional, called on runs of more than PROGRESS_STEPS steps,
    first with done = 0 before the first step.

    Refused (InputError): an input speed beyond `limits.SPEED_FACTOR` x the design's
    allowable output speed times the ratio (the sampled input's fastest between two
    samples), a load beyond the emergency-stop class, a load step (`Sampled.step`) outside
    the run, a run of more than MAX_STEPS steps, and a temperature_C outside
    `lubricant.TEMPERATURE_RANGE_C`.  Speeds and loads above their rated
    class are run and carried in `Simulation.warnings`.
    """
    errors = zero_errors(design) if errors is None else errors.check(design)
    if errors.samples != 1:
        raise InputError("errors", errors.samples, "the dynamic model simulates one reducer")
    contact = contact_law(design, contact)
    temperature_C = check_temperature(temperature_C)
    if method not in METHODS:
        raise InputError("method", method, f"must be one of {', '.join(METHODS)}")
    if mesh not in MESH_MODELS:
        raise InputError("mesh", mesh, f"must be one of {', '.join(MESH_MODELS)}")
    if duration is not None and revolutions is not None:
        raise InputError("duration", duration, "give a duration or a number of revolutions, not both")
    if not isinstance(load, Sampled):
        load = finite_number("load", load)
    loads = np.atleast_1d(load.values if isinstance(load, Sampled) else load)
    for value in loads:
        check_load("load", value, design.rated_torque)
    warnings = [check_load("load", loads[np.argmax(np.abs(loads))], design.rated_torque)]
    if input_angle is None:
        speed_rpm = positive("speed_rpm", speed_rpm)
        warnings.append(check_speed("speed_rpm", speed_rpm, speed_rpm * RPM / design.ratio, design))
        speed = speed_rpm * 2.0 * math.pi / 60.0
        out_period = 2.0 * math.pi * design.ratio / speed
        ramp = (
            max(0.05, DEFAULT_RAMP_OUTPUT_TURNS * out_period) if ramp is None else finite_number("ramp", ramp)
        )
        if ramp < 0:
            raise InputError("ramp", ramp, "must be >= 0")
        if revolutions is not None:
            length = positive("revolutions", revolutions) * out_period
        else:
            length = out_period if duration is None else positive("duration", duration)
        start, end = 0.0, ramp + length
    else:
        for name, value in (("duration", duration), ("revolutions", revolutions), ("ramp", ramp)):
            if value is not None:
                raise InputError(name, value, "the sampled input angles give the run's length; leave it out")
        start, end = float(input_angle.time[0]), float(input_angle.time[-1])
        mean = (input_angle.values[-1] - input_angle.values[0]) / (end - start)
        if not mean > 0.0:
            raise InputError(
                input_angle.name or "input",
                f"mean speed {mean:.4g} rad/s",
                "the input must turn forward (positive mean speed)",
            )
        speed_rpm, ramp = mean * 60.0 / (2.0 * math.pi), 0.0
        warnings.append(_sampled_speed_warning(design, input_angle))
    _check_load_step(load, start, end, ramp, input_angle is not None)
    finest = default_step(design, speed_rpm)
    step_given = step is not None
    if step is None:
        mean_load = float(np.mean(load.values)) if isinstance(load, Sampled) else load
        step = default_step(design, speed_rpm, modes(design, errors, mean_load).frequencies_hz)
    else:
        step = positive("step", step)
    coarsest = finest * STEPS_PER_PERIOD / MIN_STEPS_PER_PERIOD
    if step > coarsest:
        ex = Excitations.at(design, speed_rpm)
        raise InputError(
            "step",
            step,
            f"must be <= {coarsest:.3g} s: at {speed_rpm:g} rpm the "
            f"stage-1 mesh ({ex.mesh:.0f} Hz) and pin passing ({ex.pin_passing:.0f} Hz) "
            f"need at least {MIN_STEPS_PER_PERIOD} steps per period",
        )
    count = int(math.ceil((end - start) / step - 1e-9)) + 1
    if count > MAX_STEPS:
        _refuse_size(count, step, step_given, start, end, ramp, speed_rpm, duration, revolutions, input_angle)
    if input_angle is not None:
        step = (end - start) / (count - 1)  # the grid ends with the samples
    unknowns = 3 * (2 + design.n_c + 2)
    name = "input" if input_angle is not None else "revolutions" if revolutions is not None else "duration"
    fits_in_memory(
        name,
        {"input": end - start, "revolutions": revolutions}.get(name, duration),
        count * (2 * unknowns + 6) * 8,
        f"gives {count} time steps whose record alone",
    )
    time = start + np.arange(count) * step
    tau_load = -(load.at(time) if isinstance(load, Sampled) else np.full(count, load))
    if input_angle is None:
        motion = ramp_motion(time, speed, ramp, tau_load)
    else:
        motion = sampled_motion(time, input_angle, tau_load)
    drive = "ramp" if input_angle is None else "sampled"
    warnings = tuple(text for text in warnings if text)
    model = DynamicModel(
        design, errors, contact, mesh, 1 if np.mean(tau_load) <= 0 else -1, friction, temperature_C
    )
    model.prepare(motion)
    q0 = static_start(model, tau_load[0], float(motion.theta_in[0]), model.external(0))
    model.set_modal_damping(q0)
    if method != "newmark":
        return _reference(model, motion, q0, method, speed_rpm, design, ramp, step, drive, warnings)
    stepper = NewmarkStepper.starting_at(model, q0)
    q, v, power = np.empty((count, model.n)), np.empty((count, model.n)), np.empty((count, 2))
    q[0], v[0] = q0, stepper.state.v
    power[0] = model.forces_and_powers(0, q0, v[0])[3]
    report = max(1, count // 200)
    if count <= PROGRESS_STEPS:
        progress = None
    if progress is not None:
        progress(count - 1, 0)  # the bar and its total at once, before the first chunk
    while stepper.k < count - 1:
        stepper.advance(min(stepper.k + report, count - 1), q, v, power)
        if progress is not None:
            progress(count - 1, stepper.k)
    return _record(
        model, design, speed_rpm, motion, q, v, power, ramp, step, stepper.failed_steps, drive, warnings
    )


def _sampled_speed_warning(design: RVDesign, angle: Sampled) -> str | None:
    """`limits.check_speed` of the fastest input speed between two samples of `angle` (input
    angles [rad] at times [s]; either sense): its warning text or None, InputError naming the
    samples beyond the limit."""
    rates = np.diff(angle.values) / np.diff(angle.time)
    k = int(np.argmax(np.abs(rates) >= (1.0 - 1e-9) * np.abs(rates).max()))  # the first fastest
    return check_speed(
        angle.name or "input",
        f"input speed {rates[k] / RPM:.4g} rpm (its fastest, samples {k + 1} to {k + 2})",
        rates[k] / design.ratio,
        design,
    )


def _check_load_step(load, start: float, end: float, ramp: float, sampled: bool) -> None:
    """Refuse a load step (`Sampled.step`) whose time [s] lies outside the run, start..end
    [s]: it would never be applied."""
    if not (isinstance(load, Sampled) and load.name == "load_step"):
        return
    at = float(load.time[-1])
    if not start < at < end:
        span = (
            "the sampled input's times"
            if sampled
            else f"t = 0 at the start of the ramp, {ramp:.4g} s of ramp and {end - ramp:.4g} s at speed"
        )
        raise InputError(
            "load_step",
            f"{at:g}:{load.values[-1]:g}",
            f"the load would change at {at:g} s, outside the run ({start:g} to "
            f"{end:.4g} s, {span}): give a time inside it or a longer run",
        )


def _refuse_size(
    count, step, step_given, start, end, ramp, speed_rpm, duration, revolutions, input_angle
) -> None:
    """InputError for a run of `count` > MAX_STEPS time steps, naming the input that sets
    its length and how to shorten it."""
    if input_angle is not None:
        field, value = input_angle.name or "input", f"{end - start:g} s of samples"
        shorten = "give a shorter record of input angles"
    else:
        field, value = (
            ("duration", duration)
            if duration is not None
            else ("revolutions", revolutions)
            if revolutions is not None
            else ("speed_rpm", speed_rpm)
        )
        shorten = "shorten --duration (or --revolutions, default one output revolution) or lower --speed-rpm"
    if step_given:
        shorten += ", or give a larger --step"
    ramp_text = f" (the start ramp's {ramp:.3g} s included)" if ramp else ""
    raise InputError(
        field,
        value,
        f"the run of {end - start:.4g} s{ramp_text} at "
        f"{speed_rpm:.6g} rpm takes {count} time steps of {step:.3g} s, more than the "
        f"limit of {MAX_STEPS} (MAX_STEPS, about a minute of computing): {shorten}",
    )


def _reference(model, motion, q0, method, speed_rpm, design, ramp, step, drive, warnings):
    """The same run by scipy's adaptive implicit `solve_ivp` (Radau or BDF), reported at the
    Newmark steps' times: the reference the fixed-step integrator is checked against.

    Geometry is rebuilt for every time scipy asks for (a one-instant motion), so
    this is slow: for short runs and tests.
    """
    from scipy.integrate import solve_ivp

    n, M = model.n, model.mass
    columns = (motion.theta_in, motion.omega_in, motion.alpha_in, motion.tau_load)

    def instant(t):
        # the run's motion and load at t, linear between its steps
        model.prepare(Motion(np.array([t]), *(np.interp([t], motion.time, x) for x in columns)))
        return model.external(0)

    def rhs(t, y):
        F = instant(t)
        f, _, _ = model.forces(0, y[:n], y[n:])
        return np.concatenate([y[n:], (F - f) / M])

    def jacobian(t, y):
        instant(t)
        _, K, C = model.forces(0, y[:n], y[n:])
        return np.block([[np.zeros((n, n)), np.eye(n)], [-K / M[:, None], -C / M[:, None]]])

    time = motion.time
    solution = solve_ivp(
        rhs,
        (time[0], time[-1]),
        np.concatenate([q0, np.zeros(n)]),
        method=method,
        t_eval=time,
        jac=jacobian,
        rtol=1e-8,
        atol=1e-13,
    )
    if not solution.success:
        raise RuntimeError(f"solve_ivp ({method}) failed: {solution.message}")
    q, v = solution.y[:n].T, solution.y[n:].T
    model.prepare(motion)
    power = np.array([model.forces_and_powers(k, q[k], v[k])[3] for k in range(time.size)])
    return _record(model, design, speed_rpm, motion, q, v, power, ramp, step, 0, drive, warnings)


def _record(
    model,
    design,
    speed_rpm,
    motion,
    q,
    v,
    power,
    ramp,
    step,
    failed,
    drive: str,
    warnings: tuple[str, ...] = (),
) -> Simulation:
    """The run's record from the unknowns q and their rates v, (T, n), and the dissipated
    powers (T, 2) (friction, dampers), at the motion's times."""
    # the output flange: the carrier plus the windup of the massless series compliance
    te = q[:, model.carrier_rot] / model.scale + design.series_compliance * motion.tau_load
    omega_out = motion.omega_in / design.ratio + v[:, model.carrier_rot] / model.scale
    if design.series_compliance and motion.time.size > 1:
        omega_out = omega_out + design.series_compliance * np.gradient(motion.tau_load, motion.time)
    return Simulation(
        design,
        speed_rpm,
        motion.time,
        motion.theta_in,
        motion.theta_in / design.ratio + te,
        te,
        omega_out,
        model.input_torque(q.T, v.T),
        motion.tau_load,
        q,
        tuple(model.names),
        int(np.searchsorted(motion.time, motion.time[0] + ramp)),
        step,
        failed,
        motion.omega_in,
        power[:, 0],
        power[:, 1],
        drive,
        warnings,
    )
