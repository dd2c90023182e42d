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

Each 1 ms communication step, in this order:

    servo.theta_ref <- reference(t)          servo.tau_in   <- reducer.tau_in (previous step)
    servo.doStep
    reducer.theta_in <- servo.theta_motor    reducer.tau_load <- arm.tau_load (previous step)
    reducer.doStep
    arm.theta        <- reducer.theta_out
    arm.doStep

This explicit coupling serves the quasi-static reducer.  The dynamic reducer's
carrier torsion mode (550-870 Hz, modal damping ratio below 0.01) sits on the
arm's link spring, and a load held over the step feeds it negative damping
(link stiffness x the hold's delay) far larger than its own: the explicit
coupling diverges at any step above some 20 us (README.md gives the numbers).
So for the dynamic reducer the reducer-arm pair is solved implicitly each
step ("iterated" coupling): both FMUs are saved (fmi2GetFMUstate) and stepped
again from there (fmi2SetFMUstate) until the load torque given to the reducer
is the one the arm returns at the end of the step, by secant iterations on
that one scalar (2 to 3 reducer steps per communication step).  The drive
stays explicit.

The move: 0 -> 60 deg in 1.5 s (quintic, zero speed and acceleration at both
ends), then a 0.5 s hold.  It is run three times (`--runs` chooses):
"errors", the quasi-static reducer with its errors; "no-errors", the same with
`error_scale` = 0 (the error-free reducer; set before initialisation, so the
FMU solves its TE map again); "dynamic", the reducer with its errors and
`model` = "dynamic" (also set before initialisation).  Everything else is
equal, so errors - no-errors is the arm position error that the errors cause
through TE, and dynamic - errors is what the reducer's own dynamics add.

    python studies/robot_joint/run_joint.py [--points 3120] [--stop-time 2.0] [--output DIR]
                                            [--runs errors no-errors dynamic]

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

from rvfmu.core.units import ARCSEC  # noqa: E402

DESIGN = "RV-40E-121"
ERRORS_FILE = ROOT / "studies" / "seed002_errors.toml"
OUTPUT = HERE / "output"
POINTS = 3120            # TE map points per output revolution: 2 per pin-passing period (z_p * z_c = 1560)
STEP = 1e-3              # s, communication step
MOVE_DEG = 60.0          # arm move [deg]
MOVE_TIME = 1.5          # s
STOP_TIME = 2.0          # s: the move and a 0.5 s hold
NO_ERRORS = 0.0          # error_scale of the reference run: the error-free reducer
# The runs: name -> (the reducer's error_scale, its model).
RUNS = {"errors": (1.0, "quasistatic"), "no-errors": (NO_ERRORS, "quasistatic"),
        "dynamic": (1.0, "dynamic")}
RUNS_MODELS = ("quasistatic", "dynamic")   # the reducer FMU's `model` values
COUPLINGS = ("explicit", "iterated")
# Iterated coupling: the tau_load residual [N m] at which a step is accepted.  1e-4 N m winds
# the reducer up by 3e-10 rad (6e-5 arcsec) at its softest, K ~ 3e5 N m/rad.
COUPLING_TOLERANCE = 1e-4
COUPLING_EVALUATIONS = 12  # reducer steps allowed per communication step; the secant needs 2-4

# Every parameter is set explicitly on its FMU; the values are the FMU sources' defaults,
# chosen for an RV-40E-121 joint (README.md says why).
SERVO = dict(servo_module.DEFAULTS, substeps=servo_module.DEFAULT_SUBSTEPS)
ARM = dict(arm_module.DEFAULTS, substeps=arm_module.DEFAULT_SUBSTEPS)


def reference(t, move=math.radians(MOVE_DEG), duration=MOVE_TIME):
    """Arm reference [rad] at times t [s]: quintic 0 -> move over `duration`, then held."""
    s = np.clip(np.asarray(t, float) / duration, 0.0, 1.0)
    return move * s ** 3 * (10.0 - 15.0 * s + 6.0 * s ** 2)


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
    for name, script, options in (("ServoDrive", HERE / "servo_drive.py", {}),
                                  ("Arm", HERE / "arm.py", {"canGetAndSetFMUstate": True})):
        fmu = output / f"{name}.fmu"
        if not fmu.is_file() or fmu.stat().st_mtime < script.stat().st_mtime:
            log(f"building {fmu.name}")
            FmuBuilder.build_FMU(script, dest=output, **options)
            complete_model_description(fmu)   # initial unknowns, units, default experiment
        fmus[name] = fmu
    reducer = output / f"RVReducer_{points}.fmu"
    package = ROOT / "rvfmu"
    sources = ([ERRORS_FILE, package / "fmu" / "slave.py", package / "fmu" / "build.py"]
               + list((package / "core").rglob("*.py")) + list((package / "core").rglob("*.toml")))
    if not reducer.is_file() or reducer.stat().st_mtime < _newest(sources):
        from rvfmu.core.design import preset
        from rvfmu.core.errors import load_errors
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
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self.unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
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

    The reducer holds its input tau_load over the step and the arm answers the
    flange angle at its end with its own tau_load there; the step is accepted
    when they agree, |residual| <= COUPLING_TOLERANCE with residual(tau_load) =
    arm.tau_load - tau_load.  Both FMUs are saved first and restored before each
    further try.  Secant iterations on that scalar, from `guess` [N m] and the
    residual's slope of the last step (`slope`, None: a plain fixed-point try
    first).  Returns (tau_load [N m], slope, reducer steps taken); both FMUs are
    left at time + step.
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
                raise RuntimeError(f"the reducer-arm coupling did not converge at t = {time:.4f} s: "
                                   f"tau_load residual {r0:.3g} N m after {evaluations} reducer steps")
            # secant step; the fixed point x + r while no usable slope is known
            x1 = x0 - r0 / slope if slope is not None and slope < -1e-3 else x0 + r0
            r1 = residual(x1)
            evaluations += 1
            if x1 != x0 and r1 != r0:
                slope = (r1 - r0) / (x1 - x0)
            x0, r0 = x1, r1
        return x0 + r0, slope, evaluations
    finally:
        for slave, state in zip((reducer, arm), saved):
            slave.free(state)


def simulate(fmus, error_scale=1.0, points=POINTS, stop_time=STOP_TIME, step=STEP,
             model="quasistatic", coupling=None, name=None) -> JointRun:
    """Co-simulate servo -> reducer -> arm (Gauss-Seidel, fixed step) over [0, stop_time].

    model: the reducer FMU's `model`, "quasistatic" or "dynamic"; coupling of the
    reducer and the arm: "explicit" (one step each) or "iterated" (`step_iterated`);
    default explicit for the quasi-static reducer, iterated for the dynamic one.
    """
    if model not in RUNS_MODELS:
        raise ValueError(f"model = {model!r}: must be one of {', '.join(RUNS_MODELS)}")
    coupling = coupling or ("iterated" if model == "dynamic" else "explicit")
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling = {coupling!r}: must be one of {', '.join(COUPLINGS)}")
    started = clock.perf_counter()
    ratio = SERVO["ratio"]
    reducer_parameters = {}
    if model != "quasistatic":
        reducer_parameters["model"] = model
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
        record[0] = (servo.get("theta_motor"), servo.get("tau_motor"), reducer.get("theta_out"),
                     reducer.get("te_arcsec"), arm.get("tau_load"), arm.get("theta_arm"))
        evaluations = np.ones(steps, dtype=int)
        times = step * np.arange(steps + 1)
        refs = reference(times)
        slope = None
        for k in range(steps):
            t = times[k]
            servo.set(theta_ref=float(refs[k]), tau_in=reducer.get("tau_in"))
            servo.step(t, step)
            if coupling == "explicit":
                reducer.set(theta_in=servo.get("theta_motor"), tau_load=arm.get("tau_load"))
                reducer.step(t, step)
                arm.set(theta=reducer.get("theta_out"))
                arm.step(t, step)
            else:
                # first guess: tau_load extrapolated linearly from the last two points
                guess = 2.0 * record[k, 4] - record[max(k - 1, 0), 4]
                _, slope, evaluations[k] = step_iterated(reducer, arm, t, step,
                                                         servo.get("theta_motor"), guess, slope)
            record[k + 1] = (servo.get("theta_motor"), servo.get("tau_motor"),
                             reducer.get("theta_out"), reducer.get("te_arcsec"),
                             arm.get("tau_load"), arm.get("theta_arm"))
    finally:
        for slave in (servo, reducer, arm):
            slave.close()
    return JointRun(name or model, error_scale, model, coupling, times, refs, *record.T, evaluations,
                    clock.perf_counter() - started)


# -- report ------------------------------------------------------------------------------------
def summary(with_errors: JointRun, without: JointRun) -> dict:
    """Peak values of the two runs [arcsec, N m]."""
    caused = with_errors.arm_error_arcsec - without.arm_error_arcsec
    hold = with_errors.time >= min(MOVE_TIME, with_errors.time[-1])
    return {
        "peak_arm_error_with_errors_arcsec": float(np.max(np.abs(with_errors.arm_error_arcsec))),
        "peak_arm_error_without_errors_arcsec": float(np.max(np.abs(without.arm_error_arcsec))),
        "peak_te_caused_error_arcsec": float(np.max(np.abs(caused))),
        "te_caused_error_pp_arcsec": float(np.ptp(caused)),
        "te_pp_with_errors_arcsec": float(np.ptp(with_errors.te_arcsec)),
        "peak_servo_error_arcsec": float(max(np.max(np.abs(r.servo_error_arcsec))
                                             for r in (with_errors, without))),
        "final_servo_error_arcsec": float(max(abs(r.servo_error_arcsec[-1]) for r in (with_errors, without))),
        "final_arm_error_with_errors_arcsec": float(with_errors.arm_error_arcsec[-1]),
        "final_arm_error_without_errors_arcsec": float(without.arm_error_arcsec[-1]),
        "peak_motor_torque_Nm": float(max(np.max(np.abs(r.tau_motor)) for r in (with_errors, without))),
        "torque_limit_Nm": float(SERVO["torque_limit"]),
        "hold_from_s": float(with_errors.time[hold][0]),
    }


def plot(with_errors: JointRun, without: JointRun, path, points=POINTS) -> Path:
    """Arm error of both runs, the TE-caused error, the reducer TE and the motor torque vs time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = with_errors.time
    fig, axes = plt.subplots(4, 1, figsize=(9, 11), sharex=True, constrained_layout=True)
    ax = axes[0]
    ax.plot(t, with_errors.arm_error_arcsec, color="C3", lw=1, label="with seed 002 errors")
    ax.plot(t, without.arm_error_arcsec, color="C0", lw=1, label="without errors (error_scale 0)")
    ax.plot(t, with_errors.servo_error_arcsec, color="0.4", lw=0.8, ls="--",
            label="servo error (motor angle / i - reference)")
    ax.set_ylabel("arm angle - reference [arcsec]")
    ax.set_title(f"{DESIGN} robot joint: arm 0 -> {MOVE_DEG:g} deg in {MOVE_TIME:g} s (quintic), "
                 f"then hold", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax = axes[1]
    ax.plot(t, with_errors.arm_error_arcsec - without.arm_error_arcsec, color="C2", lw=1,
            label="arm error caused by TE (difference of the runs)")
    ax.plot(t, with_errors.te_arcsec - without.te_arcsec, color="k", lw=0.8, ls=":",
            label="difference of the reducer TE (quasi-static, at the flange)")
    ax.set_ylabel("difference [arcsec]")
    ax.legend(fontsize=8, loc="lower right")
    ax = axes[2]
    ax.plot(t, with_errors.te_arcsec, color="C3", lw=1, label="with errors")
    ax.plot(t, without.te_arcsec, color="C0", lw=1, label="without errors")
    ax.set_ylabel("reducer TE [arcsec]")
    ax.set_title(f"TE map: {points} points per output revolution "
                 f"({points / 1560:g} per pin-passing period)", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    ax = axes[3]
    ax.plot(t, with_errors.tau_motor, color="C3", lw=1, label="with errors")
    ax.plot(t, without.tau_motor, color="C0", lw=1, label="without errors")
    ax.set_ylabel("motor torque [N m]")
    ax.set_title(f"motor torque limit \u00b1{SERVO['torque_limit']:g} N m (off this scale)", fontsize=9)
    ax.set_xlabel("time [s]")
    ax.legend(fontsize=8, loc="lower right")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.axvline(MOVE_TIME, color="0.6", lw=0.8)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run_joint(output=OUTPUT, points=POINTS, stop_time=STOP_TIME, step=STEP, log=print):
    """Build (or reuse) the FMUs, run with and without errors, plot; returns (runs, summary, png)."""
    started = clock.perf_counter()
    fmus = build_fmus(output, points, log)
    runs = []
    for scale in (1.0, NO_ERRORS):
        log(f"co-simulating {stop_time:g} s at {step * 1e3:g} ms, error_scale {scale:g}"
            + ("" if scale == 1.0 else " (the reducer solves its TE map again at initialisation)"))
        runs.append(simulate(fmus, scale, points, stop_time, step))
    png = plot(*runs, Path(output) / "robot_joint.png", points)
    result = summary(*runs)
    result["wall_time_s"] = clock.perf_counter() - started
    return runs, result, png


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=POINTS,
                        help="TE map points per output revolution (default %(default)s)")
    parser.add_argument("--stop-time", type=float, default=STOP_TIME, help="s (default %(default)s)")
    parser.add_argument("--output", type=Path, default=OUTPUT, help="folder of the FMUs and the figure")
    args = parser.parse_args(argv)
    _, s, png = run_joint(args.output, args.points, args.stop_time)
    print(f"\nRV-40E-121 joint, {MOVE_DEG:g} deg move in {MOVE_TIME:g} s, {STEP * 1e3:g} ms steps, "
          f"TE map {args.points} points/rev")
    print(f"  peak arm error, with errors      {s['peak_arm_error_with_errors_arcsec']:8.1f} arcsec "
          f"(at rest after the move {s['final_arm_error_with_errors_arcsec']:+.1f})")
    print(f"  peak arm error, without errors   {s['peak_arm_error_without_errors_arcsec']:8.1f} arcsec "
          f"(at rest after the move {s['final_arm_error_without_errors_arcsec']:+.1f})")
    print(f"  peak arm error caused by TE      {s['peak_te_caused_error_arcsec']:8.1f} arcsec "
          f"(peak-to-peak {s['te_caused_error_pp_arcsec']:.1f}; reducer TE peak-to-peak "
          f"{s['te_pp_with_errors_arcsec']:.1f} over the move)")
    print(f"  peak servo error (motor side)    {s['peak_servo_error_arcsec']:8.1f} arcsec "
          f"(at the end {s['final_servo_error_arcsec']:.2f})")
    print(f"  peak motor torque                {s['peak_motor_torque_Nm']:8.2f} N m "
          f"(limit {s['torque_limit_Nm']:g})")
    print(f"  wall time {s['wall_time_s']:.1f} s; figure {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
