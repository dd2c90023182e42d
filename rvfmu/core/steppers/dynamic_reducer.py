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

Where numba is, a communication step is one compiled call (`communication_step`):
the element geometry of its internal steps, the Newmark steps and the means over
the step, which in Python cost a fixed tenth of a millisecond of small numpy
operations and calls around them.  Without it (or with the geometry in numpy,
`DynamicModel.compiled_geometry`) the same step runs as the Python calls it is
made of, the reference the tests hold it to.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from ..base.compiled import COMPILED, kernel
from ..dynamics.dynamic import DynamicModel, Motion, at_rest
from ..dynamics.dynamic_geometry import GeometryConstants, build_geometry
from ..dynamics.kernels import Elements, forces_only, newmark_steps, scratch
from ..dynamics.newmark import (
    BETA,
    CYCLE_TOLERANCE,
    GAMMA,
    MAX_ITERATIONS,
    TOLERANCE,
    NewmarkStepper,
    State,
    static_start,
)
from ..laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature
from ..losses.friction import step_efficiency
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet
from .reducer_model import Outputs

DEFAULT_INTERNAL_STEP = 1e-4  # [s]: 10 kHz, 25 steps per stage-1 mesh period of an RV-110E at 1600 rpm


class DynamicReducer:
    """Time-stepping dynamic model of one reducer (docs/model.md section 7)."""

    name = "dynamic"

    def __init__(
        self,
        design,
        errors: ErrorSet,
        internal_step: float = DEFAULT_INTERNAL_STEP,
        contact: str | None = None,
        mesh: str = "varying",
        temperature_C: float = REFERENCE_TEMPERATURE_C,
    ):
        if not (math.isfinite(internal_step) and internal_step > 0):
            raise ValueError(f"internal_step = {internal_step}: must be a number > 0")
        # the lubricant's [C]: the viscosity of the drag and the churning (`DynamicModel`)
        self.temperature_C = check_temperature(temperature_C)
        self.design, self.errors = design, errors
        self.internal_step = internal_step
        self.contact, self.mesh = contact, mesh
        self.model = None
        self.time = self.theta_in = self.omega_in = self.tau_load = 0.0
        self.state = None
        self._parts = None

    def _model(self, tau_load: float) -> DynamicModel:
        flank = 1 if tau_load <= 0 else -1
        if self.model is None or self.model.flank != flank:
            before = self.model
            self.model = DynamicModel(
                self.design, self.errors, self.contact, self.mesh, flank, temperature_C=self.temperature_C
            )
            if before is not None:  # the modes damped at the start stay damped alike
                self.model.elements = self.model.elements._replace(modal_c=before.elements.modal_c)
                self.model.modal_frequencies = before.modal_frequencies
                self.model.modal_shapes, self.model.floating = before.modal_shapes, before.floating
        return self.model

    def _compiled_parts(self, model: DynamicModel) -> tuple:
        """(constants, elements) of the model as plain tuples for `communication_step`, made
        again only when the model or its elements change: numba types a named tuple's fields
        one by one in Python at every call (some 10 us for the 67 constants and the 24
        elements), a plain tuple's in C (4 us)."""
        parts = self._parts
        if parts is None or parts[0] is not model or parts[1] is not model.elements:
            parts = self._parts = (model, model.elements, tuple(model.constants()), tuple(model.elements))
        return parts[2], parts[3]

    def _outputs(
        self,
        omega_in: float,
        tau_in: float,
        tau_load: float,
        torque_rate: float = 0.0,
        p_loss: float = 0.0,
        p_out: float = 0.0,
    ) -> Outputs:
        """Outputs of the flange: the carrier plus the windup of the massless series compliance
        under tau_load [N*m], changing at torque_rate [N*m/s]; p_loss and p_out [W]: the
        power dissipated and the power the output gives the load, means over the step."""
        model, s, c = self.model, self.state, self.design.series_compliance
        te = s.q[model.carrier_rot] / model.scale + c * tau_load
        omega_out = omega_in / self.design.ratio + s.v[model.carrier_rot] / model.scale + c * torque_rate
        return Outputs(
            self.theta_in / self.design.ratio + te,
            omega_out,
            te,
            tau_in,
            p_loss,
            step_efficiency(p_out, p_loss),
        )

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
        omega = (theta_in - self.theta_in) / step_size
        model = self._model(tau_load)
        if COMPILED and model.compiled_geometry:
            state = self.state
            q, v, a = state.q.copy(), state.v.copy(), state.a.copy()
            constants, elements = self._compiled_parts(model)
            tau_in, p_loss, speed = communication_step(
                constants,
                elements,
                model.mass,
                float(time),
                float(step_size),
                count,
                self.theta_in,
                omega,
                float(tau_load),
                q,
                v,
                a,
                model.sun_rot,
                model.carrier_rot,
                model.shaft_k,
                model.shaft_c,
                model.scale,
            )
            p_out = -float(tau_load) * (omega / self.design.ratio + speed)
            self.state = State(q, v, a)
            return self._advanced(time, step_size, theta_in, tau_load, omega, tau_in, p_loss, p_out)
        t = time + step_size * np.arange(count + 1) / count
        angles = self.theta_in + omega * (t - time)
        # the nominal motion's d'Alembert forces come at this constant speed (centripetal terms)
        model.prepare(Motion(t, angles, np.full(t.size, omega), np.zeros(t.size), tau_load))
        stepper = NewmarkStepper(model, self.state)
        q, v, power = (
            np.empty((count + 1, model.n)),
            np.empty((count + 1, model.n)),
            np.empty((count + 1, 2)),
        )
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
        p_out = -float(tau_load) * mean(omega / self.design.ratio + v[:, model.carrier_rot] / model.scale)
        self.state = stepper.state
        return self._advanced(time, step_size, theta_in, tau_load, omega, tau_in, p_loss, p_out)

    def _advanced(self, time, step_size, theta_in, tau_load, omega, tau_in, p_loss, p_out) -> Outputs:
        """Take the step's end as the reducer's time and inputs; its outputs."""
        self.time, self.theta_in, self.omega_in = time + step_size, float(theta_in), omega
        rate, self.tau_load = (float(tau_load) - self.tau_load) / step_size, float(tau_load)
        return self._outputs(omega, tau_in, self.tau_load, rate, p_loss, p_out)

    def get_state(self) -> dict:
        s = self.state
        return {
            "time": self.time,
            "theta_in": self.theta_in,
            "omega_in": self.omega_in,
            "tau_load": self.tau_load,
            "q": s.q.tolist(),
            "v": s.v.tolist(),
            "a": s.a.tolist(),
        }

    def set_state(self, state: dict) -> None:
        try:
            arrays = [np.asarray(state[k], dtype=float) for k in ("q", "v", "a")]
            scalars = [float(state[k]) for k in ("time", "theta_in", "omega_in", "tau_load")]
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"not a state of this model: {sorted(state)}") from None
        n = self.model.n if self.model is not None else arrays[0].size
        if any(a.shape != (n,) or not np.all(np.isfinite(a)) for a in arrays) or not all(
            math.isfinite(x) for x in scalars
        ):
            raise ValueError("not a state of this model: wrong sizes or non-finite values")
        self.time, self.theta_in, self.omega_in, self.tau_load = scalars
        self.state = State(*[a.copy() for a in arrays])


@kernel
def communication_step(
    constants,
    elements,
    mass,
    time,
    step_size,
    count,
    theta_start,
    omega,
    tau_load,
    q,
    v,
    a,
    sun_rot,
    carrier_rot,
    shaft_k,
    shaft_c,
    scale,
):
    """One communication step of `DynamicReducer.step` in one call: count internal steps
    from time to time + step_size [s], the input angle from theta_start [rad] at omega
    [rad/s], under tau_load [N*m]; the element geometry from the model's constants
    (`geometry_constants`), the elements and the masses, the state q, v, a updated in
    place.  The constants and the elements come as plain tuples of their fields
    (`DynamicReducer._compiled_parts`) and are named again here.  Returns the means over the
    step (trapezoids over the internal steps, as the Python route takes them) of the input
    torque [N*m], of the dissipated power [W] and of the carrier's speed deviation [rad/s]."""
    c, el = GeometryConstants(*constants), Elements(*elements)
    A = count + 1
    t, h = np.empty(A), np.empty(A)
    theta, speed, alpha, load = np.empty(A), np.full(A, omega), np.zeros(A), np.full(A, tau_load)
    for i in range(A):
        t[i] = time + step_size * float(i) / count
        theta[i] = theta_start + omega * (t[i] - time)
        h[i] = t[i] - t[i - 1] if i else 0.0
    g = build_geometry(c, h, theta, speed, alpha, load)
    n = q.size
    out_q, out_v, power = np.empty((A, n)), np.empty((A, n)), np.empty((A, 2))
    out_q[0], out_v[0] = q, v
    # the powers at the step's start: the forces alone, their tangent not wanted (the same
    # powers as `element_forces`, to the bit)
    f, unused = np.empty(n), np.empty((0, 0))
    power[0, 0], power[0, 1] = forces_only(el, g, 0, q, v, f, unused, unused, scratch(el, g), False)
    newmark_steps(
        el,
        g,
        1,
        A,
        mass,
        q,
        v,
        a,
        BETA,
        GAMMA,
        TOLERANCE,
        CYCLE_TOLERANCE,
        MAX_ITERATIONS,
        out_q,
        out_v,
        power,
    )
    torque, loss, turn = 0.0, 0.0, 0.0
    for i in range(count):
        w = 0.5 * (t[i + 1] - t[i])
        torque += w * (
            (shaft_k * out_q[i + 1, sun_rot] + shaft_c * out_v[i + 1, sun_rot]) / scale
            + (shaft_k * out_q[i, sun_rot] + shaft_c * out_v[i, sun_rot]) / scale
        )
        loss += w * (power[i + 1, 0] + power[i + 1, 1] + power[i, 0] + power[i, 1])
        turn += w * (out_v[i + 1, carrier_rot] / scale + out_v[i, carrier_rot] / scale)
    return torque / step_size, loss / step_size, turn / step_size


def compile_kernels(design: RVDesign | None = None, errors: ErrorSet | None = None) -> list:
    """Compile the kernels the dynamic model runs (numba, `kernels.COMPILED`) for the types a
    run gives them, unless numba's disk cache already holds them, and return the cache files
    and the stamp of the sources they were compiled from ([] without numba).  The FMU bundles
    these files: the same sources in its resources then load them instead of compiling on a
    host's first dynamic step.  The run: a few Newmark steps with each contact law, and the
    FMU's dynamic model (`DynamicReducer`) of `design` with `errors` (default: the RV-20E
    without errors) initialised under both signs of load and at none, whose elastic
    equilibrium takes the quasi-static Newton kernels (and at no load the kinematic pose's,
    `solver.first_pin`; the error offsets' `equivalent.pin_offsets` in both), and stepped."""
    from pathlib import Path

    from ..base.compiled import SOURCES_STAMP
    from ..dynamics import dynamic_geometry, kernels
    from ..dynamics.dynamic import ramp_motion
    from ..laws import pin_law, roller_law
    from ..reducer.design import preset
    from ..reducer.errors import zero_errors
    from ..statics import equivalent, newton_kernel, solver

    if not kernels.COMPILED:
        return []
    small = preset("RV-20E")
    for contact in ("linear", "impact"):  # hertz passes the same types as linear
        model = DynamicModel(small, zero_errors(small), contact)
        model.prepare(ramp_motion(np.array([0.0, 1e-4]), 10.0, 0.0))
        NewmarkStepper.starting_at(model, np.zeros(model.n)).advance(1)
    design = small if design is None else design
    errors = zero_errors(design) if errors is None else errors
    for load in (-0.1, 0.0, 0.1):
        reducer = DynamicReducer(design, errors)
        reducer.initialize(0.0, 0.0, load * design.rated_torque)
        reducer.step(0.0, 1e-3, 1e-3, load * design.rated_torque)
    files = []
    # every kernel this process has compiled or loaded from the cache: those called from
    # Python (a kernel's callees are in its own cache files)
    modules = (
        kernels,
        dynamic_geometry,
        sys.modules[__name__],
        newton_kernel,
        equivalent,
        solver,
        pin_law,
        roller_law,
    )
    for module in modules:
        folder = Path(module.__file__).parent / "__pycache__"
        kernels_here = {id(f): f for f in vars(module).values() if hasattr(f, "py_func")}
        for function in kernels_here.values():  # once each: some have two names
            if function.signatures and function.py_func.__module__ == module.__name__:
                code = function.py_func.__code__  # numba names its files by module, name and line
                files += folder.glob(
                    f"{Path(code.co_filename).stem}.{function.__name__}-{code.co_firstlineno}.*.nb[ic]"
                )
    # the stamp is missing where the cache folder cannot be written, and then so are the kernels
    return sorted(files) + ([SOURCES_STAMP] if files and SOURCES_STAMP.is_file() else [])
