"""A robot joint as a system co-simulation: servo drive, RV reducer FMU, arm, run by fmpy.

The engineering question: how far from its reference does a robot arm end up
because of the reducer's transmission error, when the drive closes its loops on
the motor encoder (as robot joints do) and so cannot see it?  And how much of
that comes from the reducer's own dynamics rather than its quasi-static TE?

Three FMUs, driven by a fixed-step Gauss-Seidel master written with fmpy's FMI
2.0 API (`fmpy.fmi2.FMU2Slave`):

- `ServoDrive` (servo_drive.py): motor inertia, friction, torque limit, P
  position / PI velocity loops on the motor angle, reference = ratio * arm reference;
- `RVReducer`, the rvte reducer FMU of the RV-40E-121 with the seed 002 errors,
  its parameter `model` either "quasistatic" (theta_out = theta_in / i +
  TE(theta_in, tau_load), the TE map) or "dynamic" (the lumped-parameter model
  of docs/model.md section 7, stepped inside each communication step);
- `Arm` (arm.py): arm inertia and gravity on its link root spring.

Each 1 ms communication step, in this order (Gauss-Seidel for the drive):

    servo.theta_ref <- reference(t)          servo.tau_in   <- reducer.tau_in (previous step)
    servo.doStep
    save reducer and arm (fmi2GetFMUstate)
    repeat:   reducer.theta_in <- servo.theta_motor    reducer.tau_load <- the guess
              reducer.doStep
              arm.theta <- reducer.theta_out
              arm.doStep
              until arm.tau_load equals the guess, else restore both (fmi2SetFMUstate)
              and guess again (secant on that one scalar)

The reducer and the arm are so solved together, implicitly ("iterated"
coupling; 2 to 3 reducer steps per communication step).  The explicit
alternative (`--coupling explicit`: one step each, the reducer given the arm's
tau_load of the step before) serves the quasi-static reducer, a step behind.
It diverges with the dynamic reducer: the carrier torsion mode (565-920 Hz
on the arm's link spring, modal damping ratio 0.005-0.009) feels the link
torque held over a step as a negative damper, link stiffness x the hold's
delay, and that beats its own damping at any step above about 15-25 us
(README.md gives the numbers).  Solved together there is no delay.

The move: 0 -> 60 deg in 1.5 s (quintic, zero speed and acceleration at both
ends), then a 0.5 s hold.  It is run three times (`--runs` chooses):
"errors", the quasi-static reducer with its errors; "no-errors", the same with
`error_scale` = 0 (the error-free reducer; set before initialisation, so the
FMU solves its TE map again); "dynamic", the reducer with its errors and
`model` = "dynamic" (also set before initialisation).  Everything else is
equal, so errors - no-errors is the arm position error that the errors cause
through TE, and dynamic - errors is what the reducer's own dynamics add.

    python studies/robot_joint/run_joint.py [--points 3120] [--stop-time 2.0] [--step 1e-3]
        [--output DIR] [--runs errors no-errors dynamic] [--coupling iterated|explicit]
        [--drive-torque reducer|load] [--dynamic-step S]

The FMUs are built once into the output folder (studies/robot_joint/output/ by
default) and reused while they are newer than their sources.  The figure
`robot_joint.png` goes there too.
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import time as clock
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

import arm as arm_module  # noqa: E402  (the Arm FMU's source: its default parameters)
import servo_drive as servo_module  # noqa: E402

from rvfmu.core.base.units import ARCSEC  # noqa: E402

# The reducer before its calibration to the catalogue (rvfmu/bench/catalogue.py): every figure of
# README.md was measured on it.  The calibrated preset is softer in torsion (a series output
# compliance: 108 against 123 N*m/arcmin; 3.6x softer before the stiffnesses came from
# geometry, when the explicit coupling of README.md no longer diverged at 1 ms on it).
DESIGN = "RV-40E-121-estimate"
ERRORS_FILE = ROOT / "studies" / "seed002_errors.toml"
OUTPUT = HERE / "output"
POINTS = 3120  # TE map points per output revolution: 2 per pin-passing period (z_p * z_c = 1560)
STEP = 1e-3  # s, communication step
MOVE_DEG = 60.0  # arm move [deg]
MOVE_TIME = 1.5  # s
STOP_TIME = 2.0  # s: the move and a 0.5 s hold
NO_ERRORS = 0.0  # error_scale of the reference run: the error-free reducer
# The runs: name -> (the reducer's error_scale, its model).
RUNS = {"errors": (1.0, "quasistatic"), "no-errors": (NO_ERRORS, "quasistatic"), "dynamic": (1.0, "dynamic")}
REDUCER_MODELS = ("quasistatic", "dynamic")  # the reducer FMU's `model` values
COUPLINGS = ("explicit", "iterated")
DRIVE_TORQUES = ("reducer", "load")  # the drive's tau_in: the reducer's, or tau_load / i
# Iterated coupling: the tau_load residual [N m] at which a step is accepted.  1e-4 N m winds
# the reducer up by 3e-10 rad (6e-5 arcsec) at its softest, K ~ 3e5 N m/rad.
COUPLING_TOLERANCE = 1e-4
COUPLING_EVALUATIONS = 12  # reducer steps allowed per communication step; the secant needs 2-4

# Every parameter is set explicitly on its FMU; the values are the FMU sources' defaults,
# chosen for an RV-40E-121 joint (README.md says why).
SERVO = dict(servo_module.DEFAULTS, substeps=servo_module.DEFAULT_SUBSTEPS)
ARM = dict(arm_module.DEFAULTS, substeps=arm_module.DEFAULT_SUBSTEPS)


def reference(t, move=math.radians(MOVE_DEG), duration=MOVE_TIME):  # noqa: B008 - a float, immutable
    """Arm reference [rad] at times t [s]: quintic 0 -> move over `duration`, then held."""
    s = np.clip(np.asarray(t, float) / duration, 0.0, 1.0)
    return move * s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


# -- FMUs -------------------------------------------------------------------------------------
def _newest(paths):
    return max(p.stat().st_mtime for p in paths)


def build_fmus(output=OUTPUT, points=POINTS, log=print) -> dict:
    """Paths of the three FMUs in `output`, each built unless it is newer than its sources."""
    from pythonfmu import FmuBuilder

    from rvfmu.fmu.build import complete_model_description

    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    fmus = {}
    # the arm saves and restores its state: the iterated coupling steps it again from a saved point
    for name, script, options in (
        ("ServoDrive", HERE / "servo_drive.py", {}),
        ("Arm", HERE / "arm.py", {"canGetAndSetFMUstate": True}),
    ):
        fmu = output / f"{name}.fmu"
        if not fmu.is_file() or fmu.stat().st_mtime < script.stat().st_mtime:
            log(f"building {fmu.name}")
            FmuBuilder.build_FMU(script, dest=output, **options)
            complete_model_description(fmu)  # initial unknowns, units, default experiment
        fmus[name] = fmu
    reducer = output / f"RVReducer_{points}.fmu"
    package = ROOT / "rvfmu"
    sources = (
        [ERRORS_FILE, package / "fmu" / "slave.py", package / "fmu" / "build.py"]
        + list((package / "core").rglob("*.py"))
        + list((package / "core").rglob("*.toml"))
    )
    if not reducer.is_file() or reducer.stat().st_mtime < _newest(sources):
        from rvfmu.core.reducer.design import preset
        from rvfmu.core.reducer.errors import load_errors
        from rvfmu.fmu.build import build_fmu

        log(f"building {reducer.name} (TE map: {points} points per output revolution)")
        design = preset(DESIGN)
        build_fmu(design, load_errors(ERRORS_FILE, design), reducer, points=points)
    fmus["RVReducer"] = reducer
    return fmus


class Slave:
    """One co-simulation FMU instance through fmpy's FMI 2.0 API, variables by name."""

    def __init__(self, path, name, parameters=None):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        self.unzipped = extract(str(path))
        self.fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=self.unzipped,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate()
        for key, value in (parameters or {}).items():
            if self.types[key] == "Integer":
                self.fmu.setInteger([self.vr[key]], [int(value)])
            elif self.types[key] == "String":
                self.fmu.setString([self.vr[key]], [str(value)])
            else:
                self.fmu.setReal([self.vr[key]], [float(value)])
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()

    def set(self, **values):
        self.fmu.setReal([self.vr[k] for k in values], list(values.values()))

    def get(self, name):
        return self.fmu.getReal([self.vr[name]])[0]

    def initialized(self):
        self.fmu.exitInitializationMode()

    def step(self, time, size):
        self.fmu.doStep(currentCommunicationPoint=time, communicationStepSize=size)

    def save(self):
        """The FMU's state now (fmi2GetFMUstate); give it back to `restore`, then `free` it."""
        return self.fmu.getFMUstate()

    def restore(self, state):
        self.fmu.setFMUstate(state)

    def free(self, state):
        self.fmu.freeFMUstate(state)

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.unzipped, ignore_errors=True)


# -- the co-simulation ------------------------------------------------------------------------
@dataclass(frozen=True)
class JointRun:
    """One run, every array shaped (steps + 1,) at the communication points but `evaluations`.

    name: a key of RUNS; error_scale and model: the reducer's parameters; coupling: of the
    reducer and the arm, "explicit" or "iterated"; time [s], theta_ref [rad] (arm reference),
    theta_motor [rad], tau_motor [N m], theta_out [rad] (flange), te_arcsec [arcsec]
    (reducer TE), tau_load [N m], theta_arm [rad]; evaluations: (steps,) reducer steps
    taken per communication step (1 when explicit); wall_time_s: the run's wall time [s].
    """

    name: str
    error_scale: float
    model: str
    coupling: str
    time: np.ndarray
    theta_ref: np.ndarray
    theta_motor: np.ndarray
    tau_motor: np.ndarray
    theta_out: np.ndarray
    te_arcsec: np.ndarray
    tau_load: np.ndarray
    theta_arm: np.ndarray
    evaluations: np.ndarray
    wall_time_s: float

    @property
    def arm_error_arcsec(self):
        """Arm angle minus its reference [arcsec]."""
        return (self.theta_arm - self.theta_ref) / ARCSEC

    @property
    def servo_error_arcsec(self):
        """Motor angle over the ratio minus the reference [arcsec]: what the drive sees and corrects."""
        return (self.theta_motor / SERVO["ratio"] - self.theta_ref) / ARCSEC


def step_iterated(reducer, arm, time, step, theta_in, guess, slope=None):
    """Step the reducer and the arm over [time, time + step] together, implicitly.

    The reducer takes tau_load for the step and the arm answers the flange angle
    at its end with its own tau_load there; the step is accepted when they agree,
    |residual| <= COUPLING_TOLERANCE with residual(tau_load) = arm.tau_load - tau_load.
    Both FMUs are saved first and restored before each further try.  Secant
    iterations on that scalar, from `guess` [N m] and the residual's slope of
    the last step (`slope`, None: a plain fixed-point try first).  Returns
    (tau_load [N m], slope, reducer steps taken); both FMUs are left at
    time + step.
    """
    saved = reducer.save(), arm.save()

    def residual(tau_load, restore=True):
        if restore:
            reducer.restore(saved[0])
            arm.restore(saved[1])
        reducer.set(theta_in=theta_in, tau_load=tau_load)
        reducer.step(time, step)
        arm.set(theta=reducer.get("theta_out"))
        arm.step(time, step)
        return arm.get("tau_load") - tau_load

    try:
        x0, r0 = guess, residual(guess, restore=False)
        evaluations = 1
        while abs(r0) > COUPLING_TOLERANCE:
            if evaluations >= COUPLING_EVALUATIONS:
                raise RuntimeError(
                    f"the reducer-arm coupling did not converge at t = {time:.4f} s: "
                    f"tau_load residual {r0:.3g} N m after {evaluations} reducer steps"
                )
            # secant step; the fixed point x + r while no usable slope is known (the residual's
            # slope is the loop gain - 1, about -1 to -1.6 here: gain 0 to -0.6, so a fixed point
            # alone would converge too, more slowly)
            x1 = x0 - r0 / slope if slope is not None and abs(slope) > 1e-3 else x0 + r0
            r1 = residual(x1)
            evaluations += 1
            if x1 != x0 and r1 != r0:
                slope = (r1 - r0) / (x1 - x0)
            x0, r0 = x1, r1
        return x0 + r0, slope, evaluations
    finally:
        for slave, state in zip((reducer, arm), saved):
            slave.free(state)


def simulate(
    fmus,
    error_scale=1.0,
    points=POINTS,
    stop_time=STOP_TIME,
    step=STEP,
    model="quasistatic",
    coupling="iterated",
    name=None,
    drive_torque="reducer",
    dynamic_step=None,
) -> JointRun:
    """Co-simulate servo -> reducer -> arm (Gauss-Seidel, fixed step) over [0, stop_time].

    model: the reducer FMU's `model`, "quasistatic" or "dynamic"; coupling of the
    reducer and the arm: "iterated" (`step_iterated`) or "explicit" (one step each,
    in the order of the module docstring; it diverges with the dynamic reducer,
    which is then reported as a RuntimeError naming the time).  The drive is
    coupled explicitly either way, and its input torque is, by `drive_torque`,
    the reducer's tau_in ("reducer") or the arm's tau_load / i ("load": the
    quasi-static relation, which leaves out the dynamic reducer's input-shaft
    ringing; the two are equal with the quasi-static reducer).  dynamic_step [s]:
    the reducer FMU's `dynamic_step` (None: its default, 1e-4 s).
    """
    if model not in REDUCER_MODELS:
        raise ValueError(f"model = {model!r}: must be one of {', '.join(REDUCER_MODELS)}")
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling = {coupling!r}: must be one of {', '.join(COUPLINGS)}")
    if drive_torque not in DRIVE_TORQUES:
        raise ValueError(f"drive_torque = {drive_torque!r}: must be one of {', '.join(DRIVE_TORQUES)}")
    started = clock.perf_counter()
    ratio = SERVO["ratio"]
    reducer_parameters = {}
    if model != "quasistatic":
        reducer_parameters["model"] = model
        if dynamic_step is not None:
            reducer_parameters["dynamic_step"] = dynamic_step
    if error_scale != 1.0:
        reducer_parameters["error_scale"] = error_scale
        if model == "quasistatic":
            reducer_parameters["map_points"] = points
    servo = Slave(fmus["ServoDrive"], "servo", SERVO)
    reducer = Slave(fmus["RVReducer"], "reducer", reducer_parameters)
    arm = Slave(fmus["Arm"], "arm", ARM)
    try:
        # Initialisation as a static equilibrium, load side first: the reducer under the
        # gravity torque at the reference, the arm on the flange angle that gives, the
        # drive on the reference holding the reaction on the motor shaft.
        ref0 = float(reference(0.0))
        gravity = ARM["mass"] * ARM["g"] * ARM["com_distance"] * math.cos(ref0)
        reducer.set(theta_in=ratio * ref0, tau_load=-gravity)
        reducer.initialized()
        arm.set(theta=reducer.get("theta_out"))
        arm.initialized()
        servo.set(theta_ref=ref0, tau_in=reducer.get("tau_in"))
        servo.initialized()

        steps = int(round(stop_time / step))
        names = ("theta_motor", "tau_motor", "theta_out", "te_arcsec", "tau_load", "theta_arm")
        record = np.empty((steps + 1, len(names)))
        record[0] = (
            servo.get("theta_motor"),
            servo.get("tau_motor"),
            reducer.get("theta_out"),
            reducer.get("te_arcsec"),
            arm.get("tau_load"),
            arm.get("theta_arm"),
        )
        evaluations = np.ones(steps, dtype=int)
        times = step * np.arange(steps + 1)
        refs = reference(times)
        slope = None
        for k in range(steps):
            t = times[k]
            try:
                tau_in = reducer.get("tau_in") if drive_torque == "reducer" else record[k, 4] / ratio
                servo.set(theta_ref=float(refs[k]), tau_in=tau_in)
                servo.step(t, step)
                if coupling == "explicit":
                    reducer.set(theta_in=servo.get("theta_motor"), tau_load=arm.get("tau_load"))
                    reducer.step(t, step)
                    arm.set(theta=reducer.get("theta_out"))
                    arm.step(t, step)
                else:
                    # first guess: tau_load extrapolated linearly from the last two points
                    guess = 2.0 * record[k, 4] - record[max(k - 1, 0), 4]
                    _, slope, evaluations[k] = step_iterated(
                        reducer, arm, t, step, servo.get("theta_motor"), guess, slope
                    )
            except Exception as exc:  # an FMU refused its step (fmpy raises on fmi2Discard)
                raise RuntimeError(
                    f"{name or model} run ({model} reducer, {coupling} coupling) "
                    f"failed in the step from t = {t:.4f} s; last tau_load "
                    f"{record[k, 4]:.1f} N m: {exc}"
                ) from exc
            record[k + 1] = (
                servo.get("theta_motor"),
                servo.get("tau_motor"),
                reducer.get("theta_out"),
                reducer.get("te_arcsec"),
                arm.get("tau_load"),
                arm.get("theta_arm"),
            )
    finally:
        for slave in (servo, reducer, arm):
            slave.close()
    return JointRun(
        name or model,
        error_scale,
        model,
        coupling,
        times,
        refs,
        *record.T,
        evaluations,
        clock.perf_counter() - started,
    )


# -- report ------------------------------------------------------------------------------------
def motor_work(run) -> float:
    """The work the motor does on its shaft over the run [J]: its torque times its turn,
    by the trapezoidal rule over the communication points."""
    return float(np.sum(0.5 * (run.tau_motor[1:] + run.tau_motor[:-1]) * np.diff(run.theta_motor)))


def summary(runs: dict) -> dict:
    """Peak values of the runs [arcsec, N m]; runs: name -> JointRun, any of RUNS.

    "runs": name -> the run's own figures ("final_...": at the last time, end_time_s);
    "te_caused" (errors - no-errors) and "dynamics_caused" (dynamic - errors, its
    peak and rms over the move, t <= MOVE_TIME) when both runs are there; the
    peaks of the servo error and the motor torque over all runs.
    """

    def during(run):  # the samples of the move, t <= MOVE_TIME
        return run.time <= MOVE_TIME + 1e-9

    out = {"runs": {}}
    for name, run in runs.items():
        out["runs"][name] = {
            "model": run.model,
            "peak_arm_error_arcsec": float(np.max(np.abs(run.arm_error_arcsec))),
            "final_arm_error_arcsec": float(run.arm_error_arcsec[-1]),
            "te_pp_arcsec": float(np.ptp(run.te_arcsec)),
            "peak_servo_error_arcsec": float(np.max(np.abs(run.servo_error_arcsec))),
            "peak_motor_torque_Nm": float(np.max(np.abs(run.tau_motor))),
            "motor_work_J": motor_work(run),
            "reducer_steps_per_step": float(np.mean(run.evaluations)),
            "wall_time_s": run.wall_time_s,
        }
    if "errors" in runs and "no-errors" in runs:
        caused = runs["errors"].arm_error_arcsec - runs["no-errors"].arm_error_arcsec
        out["te_caused"] = {"peak_arcsec": float(np.max(np.abs(caused))), "pp_arcsec": float(np.ptp(caused))}
    if "errors" in runs and "dynamic" in runs:
        quasi, dynamic = runs["errors"], runs["dynamic"]
        caused = dynamic.arm_error_arcsec - quasi.arm_error_arcsec
        move = during(quasi)
        out["dynamics_caused"] = {
            "peak_arcsec": float(np.max(np.abs(caused[move]))),
            "rms_arcsec": float(np.sqrt(np.mean(caused[move] ** 2))),
            "final_arcsec": float(caused[-1]),
            "peak_te_difference_arcsec": float(np.max(np.abs(dynamic.te_arcsec - quasi.te_arcsec))),
            "final_te_difference_arcsec": float(dynamic.te_arcsec[-1] - quasi.te_arcsec[-1]),
        }
    every = list(runs.values())
    out["peak_servo_error_arcsec"] = max(r["peak_servo_error_arcsec"] for r in out["runs"].values())
    out["final_servo_error_arcsec"] = float(max(abs(r.servo_error_arcsec[-1]) for r in every))
    out["peak_motor_torque_Nm"] = max(r["peak_motor_torque_Nm"] for r in out["runs"].values())
    out["torque_limit_Nm"] = float(SERVO["torque_limit"])
    out["end_time_s"] = float(every[0].time[-1])
    return out


STYLES = {
    "errors": dict(color="C3", label="quasi-static, seed 002 errors"),
    "no-errors": dict(color="C0", label="quasi-static, without errors (error_scale 0)"),
    "dynamic": dict(color="C1", label="dynamic, seed 002 errors"),
}


def plot(runs: dict, path, points=POINTS) -> Path:
    """Arm error of the runs, what the TE and the reducer's dynamics cause, the reducer TE and
    the motor torque vs time; runs: name -> JointRun, any of RUNS."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(9, 12), sharex=True, constrained_layout=True)
    ax = axes[0]
    for name, run in runs.items():
        ax.plot(run.time, run.arm_error_arcsec, lw=1, **STYLES[name])
    first = next(iter(runs.values()))
    ax.plot(
        first.time,
        first.servo_error_arcsec,
        color="0.4",
        lw=0.8,
        ls="--",
        label=f"servo error (motor angle / i - reference), {first.name}",
    )
    ax.set_ylabel("arm angle - reference [arcsec]")
    ax.set_title(
        f"{DESIGN} robot joint: arm 0 -> {MOVE_DEG:g} deg in {MOVE_TIME:g} s (quintic), then hold",
        fontsize=10,
    )
    ax.legend(fontsize=8, loc="lower right")
    ax = axes[1]
    if "errors" in runs and "no-errors" in runs:
        a, b = runs["errors"], runs["no-errors"]
        ax.plot(
            a.time,
            a.arm_error_arcsec - b.arm_error_arcsec,
            color="C2",
            lw=1,
            label="caused by TE: errors - no-errors (quasi-static)",
        )
        ax.plot(
            a.time,
            a.te_arcsec - b.te_arcsec,
            color="k",
            lw=0.8,
            ls=":",
            label="difference of the reducer TE (quasi-static, at the flange)",
        )
    if "errors" in runs and "dynamic" in runs:
        a, b = runs["dynamic"], runs["errors"]
        ax.plot(
            a.time,
            a.arm_error_arcsec - b.arm_error_arcsec,
            color="C1",
            lw=1,
            label="from the reducer's dynamics: dynamic - quasi-static (both with errors)",
        )
    ax.set_ylabel("arm error difference [arcsec]")
    ax.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, frameon=False)
    ax = axes[2]
    for name, run in runs.items():  # the dynamic TE carries kHz ringing: thinner, drawn first
        ax.plot(
            run.time,
            run.te_arcsec,
            lw=0.6 if run.model == "dynamic" else 1,
            zorder=1 if run.model == "dynamic" else 2,
            **STYLES[name],
        )
    ax.set_ylabel("reducer TE [arcsec]")
    ax.set_title(
        f"TE map: {points} points per output revolution ({points / 1560:g} per pin-passing period)",
        fontsize=9,
    )
    ax.legend(fontsize=8, loc="lower right")
    ax = axes[3]
    for name, run in runs.items():
        ax.plot(
            run.time,
            run.tau_motor,
            lw=0.6 if run.model == "dynamic" else 1,
            zorder=1 if run.model == "dynamic" else 2,
            **STYLES[name],
        )
    ax.set_ylabel("motor torque [N m]")
    ax.set_title(f"motor torque limit \u00b1{SERVO['torque_limit']:g} N m (off this scale)", fontsize=9)
    ax.set_xlabel("time [s]")
    ax.legend(fontsize=8, loc="upper right")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.axvline(MOVE_TIME, color="0.6", lw=0.8)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run_joint(
    output=OUTPUT,
    points=POINTS,
    stop_time=STOP_TIME,
    step=STEP,
    runs=tuple(RUNS),
    coupling="iterated",
    drive_torque="reducer",
    dynamic_step=None,
    log=print,
):
    """Build (or reuse) the FMUs, do the runs named (keys of RUNS, done in RUNS' order), plot;
    returns (runs: name -> JointRun, summary, png).  coupling, drive_torque, dynamic_step:
    as `simulate` takes them, the same for every run."""
    unknown = [name for name in runs if name not in RUNS]
    if unknown or not runs:
        raise ValueError(f"runs = {list(runs)}: each must be one of {', '.join(RUNS)}")
    started = clock.perf_counter()
    fmus = build_fmus(output, points, log)
    done = {}
    for name in (name for name in RUNS if name in runs):
        scale, model = RUNS[name]
        log(
            f"co-simulating {stop_time:g} s at {step * 1e3:g} ms: {name} (model {model}, "
            f"error_scale {scale:g}, {coupling} coupling)"
            + (
                " (the reducer solves its TE map again at initialisation)"
                if scale != 1.0 and model == "quasistatic"
                else ""
            )
        )
        done[name] = simulate(
            fmus, scale, points, stop_time, step, model, coupling, name, drive_torque, dynamic_step
        )
    png = plot(done, Path(output) / "robot_joint.png", points)
    result = summary(done)
    result["options"] = {
        "points": points,
        "step_s": step,
        "coupling": coupling,
        "drive_torque": drive_torque,
        "dynamic_step_s": dynamic_step,
    }
    result["wall_time_s"] = clock.perf_counter() - started
    return done, result, png


def report(s) -> str:
    """The summary of `run_joint` as printed: a table of the runs, then the differences."""
    o = s["options"]
    drive = "reducer.tau_in" if o["drive_torque"] == "reducer" else "arm.tau_load / i"
    lines = [
        f"{DESIGN} joint, {MOVE_DEG:g} deg move in {MOVE_TIME:g} s, "
        f"{o['step_s'] * 1e3:g} ms steps, TE map {o['points']} points/rev",
        f"reducer and arm coupled {o['coupling']}; drive torque input {drive}"
        + ("" if o["dynamic_step_s"] is None else f"; dynamic_step {o['dynamic_step_s']:g} s"),
        "  run        reducer       arm error [arcsec]   TE p-p    servo error  motor torque"
        "  motor work  reducer steps  wall",
        f"                           peak  at t = {s['end_time_s']:<4g} s  [arcsec]  peak [arcsec]"
        "  peak [N m]         [J]     per step    [s]",
    ]
    for name, r in s["runs"].items():
        lines.append(
            f"  {name:<10} {r['model']:<12} {r['peak_arm_error_arcsec']:6.1f} "
            f"{r['final_arm_error_arcsec']:+11.1f}  {r['te_pp_arcsec']:10.1f} "
            f"{r['peak_servo_error_arcsec']:11.1f} {r['peak_motor_torque_Nm']:12.2f} "
            f"{r['motor_work_J']:11.2f} {r['reducer_steps_per_step']:12.2f} "
            f"{r['wall_time_s']:7.1f}"
        )
    if "te_caused" in s:
        c = s["te_caused"]
        lines.append(
            f"  arm error caused by TE (errors - no-errors): peak {c['peak_arcsec']:.1f} "
            f"arcsec (peak-to-peak {c['pp_arcsec']:.1f})"
        )
    if "dynamics_caused" in s:
        c = s["dynamics_caused"]
        lines.append(
            f"  arm error from the reducer's dynamics (dynamic - errors): peak "
            f"{c['peak_arcsec']:.1f} arcsec during the move (rms {c['rms_arcsec']:.1f}), "
            f"at t = {s['end_time_s']:g} s {c['final_arcsec']:+.2f}"
        )
        lines.append(
            f"  reducer TE, dynamic - quasi-static: peak "
            f"{c['peak_te_difference_arcsec']:.1f} arcsec, "
            f"at t = {s['end_time_s']:g} s {c['final_te_difference_arcsec']:+.2f}"
        )
    lines.append(
        f"  servo error at the end {s['final_servo_error_arcsec']:.2f} arcsec; "
        f"motor torque limit {s['torque_limit_Nm']:g} N m"
    )
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--points", type=int, default=POINTS, help="TE map points per output revolution (default %(default)s)"
    )
    parser.add_argument("--stop-time", type=float, default=STOP_TIME, help="s (default %(default)s)")
    parser.add_argument(
        "--step",
        type=float,
        default=STEP,
        help="communication step [s] (default %(default)s); the drive and the arm keep 20 sub-steps per step",
    )
    parser.add_argument("--output", type=Path, default=OUTPUT, help="folder of the FMUs and the figure")
    parser.add_argument(
        "--runs", nargs="+", choices=tuple(RUNS), default=tuple(RUNS), help="which runs to do (default: all)"
    )
    parser.add_argument(
        "--coupling",
        choices=COUPLINGS,
        default="iterated",
        help="of the reducer and the arm (default %(default)s; explicit diverges "
        "with the dynamic reducer, README.md says why)",
    )
    parser.add_argument(
        "--drive-torque",
        choices=DRIVE_TORQUES,
        default="reducer",
        help="the drive's input torque: the reducer's tau_in (default) or the arm's tau_load / i",
    )
    parser.add_argument(
        "--dynamic-step",
        type=float,
        default=None,
        help="the dynamic reducer's largest internal step [s] (default: the FMU's, 1e-4)",
    )
    args = parser.parse_args(argv)
    _, s, png = run_joint(
        args.output,
        args.points,
        args.stop_time,
        args.step,
        runs=args.runs,
        coupling=args.coupling,
        drive_torque=args.drive_torque,
        dynamic_step=args.dynamic_step,
    )
    print()
    print(report(s))
    print(f"  wall time {s['wall_time_s']:.1f} s; figure {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
