"""The RV reducer FMU slave (pythonfmu): input angle and load torque in, output angle out.

A thin adapter: it maps FMI variables onto a reducer model of
`rvfmu.core.steppers.reducer_model`, and nothing here raises: pythonfmu reports any
Python exception as fmi2Fatal, after which the instance is unusable.  Every
problem is instead logged with status fmi2Error.  A failed initialisation is
logged (fmi2ExitInitializationMode itself returns fmi2OK) and every step
after it returns fmi2Discard (do_step returns False) with the reason logged
again; a step with a bad input (not finite, a step size that is not > 0, or tau_load
beyond the emergency-stop class, 5x the rated torque, `rvfmu.core.reducer.limits`)
returns fmi2Discard the same way, and so does a step whose input angle moved
faster than SPEED_FACTOR x the design's allowable output speed allows
(`rvfmu.core.reducer.limits.check_speed`, on (theta_in - the last step's theta_in) /
step size / ratio).  After a discarded step pythonfmu (0.7.0) answers
fmi2GetBooleanStatus(fmi2Terminated) with true.  pythonfmu offers a Python
slave nothing between fmi2Discard and fmi2Fatal (any exception, after which its
instance must not even be freed) and forwards log messages only with logging
on, so on Linux the FMU's binary wraps pythonfmu's (native/pythonfmu_guard.c,
`rvfmu.fmu.build.guard_linux_binary`): a discarded step becomes fmi2Error and
ends the simulation, as docs/model.md section 8 wants of an input no retry can
make valid, and the errors and warnings logged here reach the host's logger
whatever its logging.  Above the momentary maximum class, 2.5x rated, or above
the allowable output speed, the step is computed and a warning is logged once
per instance.

The design, the error set and the quasi-static TE map are bundled in the
FMU's resources at build time; the parameters `design_file` (a preset name or
a design file) and `errors_file` replace them, and `map_points` and the scale
parameters change the grid or the physics (error_scale = 0: the error-free
reducer), in which case the TE map is solved again when initialisation ends.
`temperature_C` reads the quasi-static map's load-free friction table at that lubricant
temperature (`TEMap.load_free_row`), or sets the dynamic model's viscosity there; one
outside the range fails the initialisation as a bad parameter does.

This file is the FMU's entry module: pythonfmu copies it into the FMU and, at
build and at run time, takes the class below as the module's Fmi2Slave
subclass (the deepest one in the class hierarchy: keep it the only one).
"""

import hashlib
import math
import os
import shutil
import sys
import tempfile
import traceback
from math import isfinite
from pathlib import Path


def _bundle_digest(bundle: Path) -> str:
    """A digest of the bundled rvfmu package's sources (their paths and contents)."""
    digest = hashlib.sha256()
    for path in sorted(bundle.rglob("*.py")):
        digest.update(path.relative_to(bundle).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def stable_bundle(here: Path, cache_root: Path | None = None) -> Path | None:
    """The folder, outside the host's folder of this FMU, to import the bundled rvfmu from
    (None: import it where it is).

    In an FMU this module sits in resources/ beside the rvfmu package it carries.  A host may
    delete the folder it unpacked the FMU to once a run is over and instantiate the FMU again
    in the same process (fmpy's simulate_fmu does both): the rvfmu modules of the first run
    stay imported, their files gone, and numba then finds the cached kernels of none of them
    and compiles every kernel the next run takes (84 s for the dynamic model on a 2-core AMD
    EPYC).  So the package is copied once, per digest of its sources, into the user's cache
    folder ($XDG_CACHE_HOME or ~/.cache, rvte/fmu-<digest>), with the compiled kernels it
    carries, and imported from there by every instance and process.  Where that folder
    cannot be written, the package is imported in place as before (`_search_resources_first`).
    """
    bundle = here / "rvfmu"
    if not (bundle / "core").is_dir():
        return None  # not in an FMU: the installed rvfmu
    try:  # (the digest cannot come from rvfmu's own: importing it decides where rvfmu is from)
        if cache_root is None:
            cache_root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rvte"
        target = cache_root / f"fmu-{_bundle_digest(bundle)}"
        if not (target / "rvfmu" / "core").is_dir():
            cache_root.mkdir(parents=True, exist_ok=True)
            staging = Path(tempfile.mkdtemp(prefix=f"{target.name}.", dir=cache_root))
            shutil.copytree(bundle, staging / "rvfmu")
            try:
                os.rename(staging, target)  # whole or not at all
            except OSError:  # another process made it meanwhile
                shutil.rmtree(staging, ignore_errors=True)
    except (OSError, RuntimeError):  # no writable cache folder, or no home
        return None
    return target if (target / "rvfmu" / "core").is_dir() else None


if "rvfmu" not in sys.modules:
    STABLE_BUNDLE = stable_bundle(Path(__file__).resolve().parent)
    if STABLE_BUNDLE is not None:
        sys.path.insert(0, str(STABLE_BUNDLE))
else:
    STABLE_BUNDLE = None

import numpy as np  # noqa: E402
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String  # noqa: E402
from pythonfmu.enums import Fmi2Initial, Fmi2Status  # noqa: E402

from rvfmu.core.base.checks import InputError  # noqa: E402
from rvfmu.core.base.units import ARCSEC  # noqa: E402
from rvfmu.core.laws.lubricant import REFERENCE_TEMPERATURE_C  # noqa: E402
from rvfmu.core.reducer.design import load_design  # noqa: E402
from rvfmu.core.reducer.errors import load_errors, zero_errors  # noqa: E402
from rvfmu.core.reducer.limits import MOMENTARY_FACTOR, check_load, check_speed  # noqa: E402
from rvfmu.core.steppers.dynamic_reducer import DEFAULT_INTERNAL_STEP  # noqa: E402
from rvfmu.core.steppers.reducers import MODELS  # noqa: E402
from rvfmu.core.steppers.te_map import DRAG_TEMPERATURES, TEMap, build_te_map  # noqa: E402

BUNDLED_DESIGN = "design.toml"
BUNDLED_ERRORS = "errors.toml"
BUNDLED_MAP = "te_map.npz"
SCALES = ("pin_stiffness_scale", "bearing_stiffness_scale", "mesh_stiffness_scale", "error_scale")


class FmuInputError(Exception):
    """An input or parameter the FMU cannot accept; logged, never raised to the host."""


class RVReducer(Fmi2Slave):
    """The pythonfmu slave: inputs theta_in [rad] and tau_load [N·m]; outputs theta_out [rad],
    its speed, the TE, the input torque, the friction loss and the efficiency; the variables
    and statuses of docs/model.md section 8."""

    author = "rvte"
    description = (
        "RV reducer: transmission error, lost motion and torsional windup of a "
        "two-stage planetary + cycloid reducer (quasi-static equivalent error model)"
    )

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # inputs
        self.theta_in = 0.0
        self.tau_load = 0.0
        # outputs
        self.theta_out = 0.0
        self.omega_out = 0.0
        self.te = 0.0
        self.te_arcsec = 0.0
        self.tau_in = 0.0
        self.P_loss = 0.0
        self.efficiency = 0.0
        # parameters
        self.design_file = ""
        self.errors_file = ""
        self.model = "quasistatic"
        self.pin_stiffness_scale = 1.0
        self.bearing_stiffness_scale = 1.0
        self.mesh_stiffness_scale = 1.0
        self.error_scale = 1.0
        self.map_points = 0
        self.dynamic_step = DEFAULT_INTERNAL_STEP
        self.temperature_C = REFERENCE_TEMPERATURE_C
        self._reducer = None
        self._failed = None
        self._rated_torque = self._momentary_torque = math.inf
        self._warned = set()  # the inputs whose limit warning was logged
        self._design = None
        self._last_theta_in = 0.0  # theta_in of the last step taken [rad]
        self._allowed_angle_rate = math.inf  # input speed [rad/s] without a speed warning

        cont, par = Fmi2Variability.continuous, Fmi2Variability.fixed
        for name, text in (
            ("theta_in", "input shaft (sun) angle [rad]"),
            (
                "tau_load",
                "torque of the load on the output flange [N.m], positive in the direction of rotation",
            ),
        ):
            self.register_variable(
                Real(name, causality=Fmi2Causality.input, variability=cont, description=text)
            )
        for name, text in (
            ("theta_out", "output flange (carrier) angle [rad]"),
            ("omega_out", "output speed over the last step [rad/s]"),
            ("te", "transmission error theta_out - theta_in/i [rad]"),
            ("te_arcsec", "transmission error [arcsec]"),
            ("tau_in", "torque of the reducer on the input shaft [N.m], its friction included"),
            (
                "P_loss",
                "power lost to friction over the last step [W] (model dynamic: with its damping's, the mean)",
            ),
            (
                "efficiency",
                "efficiency over the last step [1]: forward the "
                "transmitted power over it plus the loss, backdriving "
                "what is left after the loss; 0 at standstill",
            ),
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
            ("design_file", "a preset name or a design TOML path; empty: the design bundled at build"),
            ("errors_file", "an error TOML path; empty: the errors bundled at build"),
            (
                "model",
                "reducer model: quasistatic (the TE map, default) or "
                "dynamic (masses, springs and dampers in time)",
            ),
        ):
            self.register_variable(
                String(name, causality=Fmi2Causality.parameter, variability=par, description=text)
            )
        for name, text in (
            ("pin_stiffness_scale", "factor on the pin-disc contact stiffness [1]"),
            ("bearing_stiffness_scale", "factor on every bearing stiffness [1]"),
            ("mesh_stiffness_scale", "factor on the sun-planet mesh and sun support [1]"),
            (
                "error_scale",
                "factor on every manufacturing error and clearance [1]; 0: the error-free reducer",
            ),
        ):
            self.register_variable(
                Real(name, causality=Fmi2Causality.parameter, variability=par, description=text)
            )
        self.register_variable(
            Real(
                "dynamic_step",
                causality=Fmi2Causality.parameter,
                variability=par,
                description="largest internal time step of the dynamic model [s]",
            )
        )
        self.register_variable(
            Integer(
                "map_points",
                causality=Fmi2Causality.parameter,
                variability=par,
                description="TE map points per output revolution; 0: as bundled",
            )
        )
        # after every other parameter: the native FMU declares it with this value reference
        self.register_variable(
            Real(
                "temperature_C",
                causality=Fmi2Causality.parameter,
                variability=par,
                description="lubricant temperature [C] of "
                "the load-free friction (model quasistatic; the TE map's "
                f"table: {DRAG_TEMPERATURES[0]} to {DRAG_TEMPERATURES[-1]} C)",
            )
        )

        # Direct access for the calls a master makes every step.
        reals = [v for v in self.vars.values() if isinstance(v, Real)]
        self._getters = {v.value_reference: v.getter for v in reals}
        self._setters = {v.value_reference: v.setter for v in reals}

    def get_real(self, vrs):
        """The values of the Real variables with value references `vrs`, in that order (a
        direct path for the reads a master makes every step)."""
        getters = self._getters
        if all(vr in getters for vr in vrs):
            return [float(getters[vr]()) for vr in vrs]
        return super().get_real(vrs)

    def set_real(self, vrs, values):
        """Set the Real variables with value references `vrs` to `values` (same length)."""
        setters = self._setters
        if all(vr in setters for vr in vrs):
            for vr, value in zip(vrs, values):
                setters[vr](value)
        else:
            super().set_real(vrs, values)

    # -- life cycle ---------------------------------------------------------------------
    def exit_initialization_mode(self):
        """Make the reducer model from the parameters and solve its state at theta_in and
        tau_load; a failure is logged and every later step is discarded with it."""
        try:
            self._reducer = self._make_reducer()
            message = self._bad_inputs(self.theta_in, self.tau_load)
            if message:
                raise FmuInputError(message)
            self._show(self._reducer.initialize(0.0, self.theta_in, self.tau_load))
            self._last_theta_in = self.theta_in
        except Exception as exc:  # noqa: BLE001
            # pythonfmu turns any exception into fmi2Fatal (the instance is then unusable),
            # so a failure is logged here and every step then returns fmi2Discard with it.
            self._reducer = None
            self._fail(f"initialisation failed: {_describe(exc)}")

    def do_step(self, current_time, step_size):
        """Advance by `step_size` [s] to the current inputs; False (fmi2Discard, the reason
        logged) for a bad input or a step after a failed initialisation."""
        if self._reducer is None:
            self._fail(self._failed or "do_step before the end of initialisation")
            return False
        theta_in, tau_load = self.theta_in, self.tau_load
        if not (
            isfinite(theta_in)
            and step_size > 0.0
            and abs(tau_load) <= self._momentary_torque
            and abs(theta_in - self._last_theta_in) <= self._allowed_angle_rate * step_size
        ):
            # False for NaN: checked in full
            message = (
                self._bad_inputs(theta_in, tau_load)
                if step_size > 0.0
                else f"communication step size = {step_size}: must be a number > 0"
            )
            if not message:
                message = self._bad_speed(theta_in, step_size)
            if message:
                self._fail(message)
                return False
        try:
            out = self._reducer.step(current_time, step_size, theta_in, tau_load)
        except Exception as exc:  # noqa: BLE001
            self._fail(_describe(exc))
            return False
        self._show(out)
        self._last_theta_in = theta_in
        return True

    # -- state ----------------------------------------------------------------------------
    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state["_reducer"] = None if self._reducer is None else self._reducer.get_state()
        state["_last_theta_in"] = self._last_theta_in
        return state

    def _set_fmu_state(self, state):
        state = dict(state)
        reducer_state = state.pop("_reducer", None)
        self._last_theta_in = state.pop("_last_theta_in", self._last_theta_in)
        super()._set_fmu_state(state)
        if reducer_state is not None and self._reducer is not None:
            self._reducer.set_state(reducer_state)

    # -- helpers --------------------------------------------------------------------------
    def _bad_inputs(self, theta_in, tau_load):
        """The message for the first input the model cannot take, or None.

        tau_load beyond the emergency-stop class is refused; beyond the momentary
        maximum class a warning is logged once per instance (rvfmu.core.reducer.limits).
        """
        for name, value in (("theta_in", theta_in), ("tau_load", tau_load)):
            if not isfinite(value):
                return f"input {name} = {value}: must be finite"
        return self._limited("tau_load", lambda: check_load("tau_load", tau_load, self._rated_torque))

    def _bad_speed(self, theta_in, step_size):
        """The message if the output speed the step implies is beyond the design's limit, or
        None (a warning is logged once per instance above the allowable speed)."""
        design = self._design
        output_speed = (theta_in - self._last_theta_in) / step_size / design.ratio
        return self._limited("theta_in", lambda: check_speed("theta_in", theta_in, output_speed, design))

    def _limited(self, name, check):
        """The message if `check()` (a rvfmu.core.reducer.limits check of input `name`) refuses the
        input, or None; the warning it returns is logged once per instance and input."""
        try:
            warning = check()
        except InputError as exc:
            return f"input {exc}"
        if warning and name not in self._warned:
            self._warned.add(name)
            self.log(f"input {warning}", Fmi2Status.warning)
        return None

    def _make_reducer(self):
        if self.model not in MODELS:
            raise FmuInputError(f"model = {self.model!r}: must be one of {', '.join(MODELS)}")
        if not (math.isfinite(self.dynamic_step) and self.dynamic_step > 0):
            raise FmuInputError(f"dynamic_step = {self.dynamic_step}: must be a finite number > 0")
        resources = Path(self.resources) if self.resources else Path(".")
        if STABLE_BUNDLE is None:  # imported in place: find the modules in this instance's copy
            _search_resources_first(resources)
        design = load_design(self.design_file or resources / BUNDLED_DESIGN)
        if self.errors_file:
            errors = load_errors(self.errors_file, design)
        elif (resources / BUNDLED_ERRORS).is_file():
            errors = load_errors(resources / BUNDLED_ERRORS, design)
        else:
            errors = zero_errors(design)
        scales = {name: getattr(self, name) for name in SCALES}
        for name, value in scales.items():
            if name == "error_scale" and math.isfinite(value) and value == 0.0:
                continue  # no errors at all: the exact reducer
            if not (math.isfinite(value) and value > 0):
                allowed = ">= 0 (0: no errors)" if name == "error_scale" else "> 0"
                raise FmuInputError(f"{name} = {value}: must be a finite number {allowed}")
        if self.map_points < 0:
            raise FmuInputError(f"map_points = {self.map_points}: must be >= 0")
        bundled = (
            not self.design_file
            and not self.errors_file
            and self.map_points == 0
            and all(v == 1.0 for v in scales.values())
            and (resources / BUNDLED_MAP).is_file()
        )
        self._rated_torque = design.rated_torque
        self._momentary_torque = MOMENTARY_FACTOR * design.rated_torque
        self._design = design
        self._allowed_angle_rate = design.allowable_output_speed * design.ratio
        scaled_design = _scaled(design, scales)
        # the scaled errors are checked again: error_scale may carry them past the model's limits
        scaled_errors = errors.scaled(scales["error_scale"]).check(scaled_design)
        if self.model == "dynamic":
            return MODELS["dynamic"](
                scaled_design,
                scaled_errors,
                internal_step=self.dynamic_step,
                temperature_C=self.temperature_C,
            )
        if bundled:
            with np.load(resources / BUNDLED_MAP) as arrays:
                te_map = TEMap.from_arrays(arrays)
        else:
            self.log("solving the quasi-static TE map for the changed parameters", Fmi2Status.ok)
            te_map = build_te_map(scaled_design, scaled_errors, points=self.map_points or None)
        # the map's load-free table read at the temperature; InputError outside its range
        return MODELS[self.model](te_map, temperature_C=self.temperature_C)

    def _show(self, outputs):
        self.theta_out = outputs.theta_out
        self.omega_out = outputs.omega_out
        self.te = outputs.te
        self.te_arcsec = outputs.te / ARCSEC
        self.tau_in = outputs.tau_in
        self.P_loss = outputs.p_loss
        self.efficiency = outputs.efficiency

    def _fail(self, message):
        self._failed = message
        self.log(message, Fmi2Status.error)


def _search_resources_first(resources: Path) -> None:
    """Make every rvfmu package already imported look for its modules in this instance's
    resources first.

    A host may run the FMU again in the same process after deleting the folder of its first
    run (fmpy's simulate_fmu does): the rvfmu packages imported then still search that folder,
    and a module the first run did not import (the dynamic model's, after a quasi-static run)
    was not found.
    """
    for name, module in list(sys.modules.items()):
        if (name == "rvfmu" or name.startswith("rvfmu.")) and hasattr(module, "__path__"):
            folder = str(resources.joinpath(*name.split(".")))
            if Path(folder).is_dir() and folder not in module.__path__:
                module.__path__.insert(0, folder)


def _scaled(design, scales):
    """The design with the stiffness scale parameters applied."""
    bearing, mesh = scales["bearing_stiffness_scale"], scales["mesh_stiffness_scale"]
    return design.with_fields(
        pin_disc_stiffness=design.pin_disc_stiffness * scales["pin_stiffness_scale"],
        crank_disc_bearing_stiffness=design.crank_disc_bearing_stiffness * bearing,
        crank_carrier_bearing_stiffness=design.crank_carrier_bearing_stiffness * bearing,
        main_bearing_stiffness=design.main_bearing_stiffness * bearing,
        mesh_stiffness=design.mesh_stiffness * mesh,
        sun_support_stiffness=design.sun_support_stiffness * mesh,
    )


def _describe(exc):
    if isinstance(exc, (InputError, FmuInputError, ValueError, OSError)):
        return str(exc)
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()
