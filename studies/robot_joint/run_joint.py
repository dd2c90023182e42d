"""A robot joint as a system co-simulation: servo drive, RV reducer FMU, arm, run by fmpy.

The engineering question: how far from its reference does a robot arm end up
because of the reducer's transmission error, when the drive closes its loops on
the motor encoder (as robot joints do) and so cannot see it?

Three FMUs, driven by a fixed-step Gauss-Seidel master written with fmpy's FMI
2.0 API (`fmpy.fmi2.FMU2Slave`):

- `ServoDrive` (servo_drive.py): motor inertia, friction, torque limit, P
  position / PI velocity loops on the motor angle, reference = ratio * arm reference;
- `RVReducer`, the rvte reducer FMU of the RV-40E-121 with the seed 002 errors
  (quasi-static: theta_out = theta_in / i + TE(theta_in, tau_load));
- `Arm` (arm.py): arm inertia and gravity on its link root spring.

Each 1 ms communication step, in this order:

    servo.theta_ref <- reference(t)          servo.tau_in   <- reducer.tau_in (previous step)
    servo.doStep
    reducer.theta_in <- servo.theta_motor    reducer.tau_load <- arm.tau_load (previous step)
    reducer.doStep
    arm.theta        <- reducer.theta_out
    arm.doStep

The move: 0 -> 60 deg in 1.5 s (quintic, zero speed and acceleration at both
ends), then a 0.5 s hold.  It is run twice, once with the reducer's errors and
once with `error_scale` = 0 (the error-free reducer; set before initialisation,
so the FMU solves its TE map again); everything else is equal, so the difference of
the arm angles is the arm position error that the errors cause through TE.

    python studies/robot_joint/run_joint.py [--points 3120] [--stop-time 2.0] [--output DIR]

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
    for name, script in (("ServoDrive", HERE / "servo_drive.py"), ("Arm", HERE / "arm.py")):
        fmu = output / f"{name}.fmu"
        if not fmu.is_file() or fmu.stat().st_mtime < script.stat().st_mtime:
            log(f"building {fmu.name}")
            FmuBuilder.build_FMU(script, dest=output)
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

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.unzipped, ignore_errors=True)


# -- the co-simulation ------------------------------------------------------------------------
@dataclass(frozen=True)
class JointRun:
    """One run, every array shaped (steps + 1,) at the communication points.

    time [s], theta_ref [rad] (arm reference), theta_motor [rad], tau_motor [N m],
    theta_out [rad] (flange), te_arcsec [arcsec] (reducer TE), tau_load [N m],
    theta_arm [rad].
    """

    error_scale: float
    time: np.ndarray
    theta_ref: np.ndarray
    theta_motor: np.ndarray
    tau_motor: np.ndarray
    theta_out: np.ndarray
    te_arcsec: np.ndarray
    tau_load: np.ndarray
    theta_arm: np.ndarray

    @property
    def arm_error_arcsec(self):
        """Arm angle minus its reference [arcsec]."""
        return (self.theta_arm - self.theta_ref) / ARCSEC

    @property
    def servo_error_arcsec(self):
        """Motor angle over the ratio minus the reference [arcsec]: what the drive sees and corrects."""
        return (self.theta_motor / SERVO["ratio"] - self.theta_ref) / ARCSEC


def simulate(fmus, error_scale=1.0, points=POINTS, stop_time=STOP_TIME, step=STEP) -> JointRun:
    """Co-simulate servo -> reducer -> arm (Gauss-Seidel, fixed step) over [0, stop_time]."""
    ratio = SERVO["ratio"]
    reducer_parameters = {} if error_scale == 1.0 else {"error_scale": error_scale, "map_points": points}
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
        times = step * np.arange(steps + 1)
        refs = reference(times)
        for k in range(steps):
            t = times[k]
            servo.set(theta_ref=float(refs[k]), tau_in=reducer.get("tau_in"))
            servo.step(t, step)
            reducer.set(theta_in=servo.get("theta_motor"), tau_load=arm.get("tau_load"))
            reducer.step(t, step)
            arm.set(theta=reducer.get("theta_out"))
            arm.step(t, step)
            record[k + 1] = (servo.get("theta_motor"), servo.get("tau_motor"),
                             reducer.get("theta_out"), reducer.get("te_arcsec"),
                             arm.get("tau_load"), arm.get("theta_arm"))
    finally:
        for slave in (servo, reducer, arm):
            slave.close()
    return JointRun(error_scale, times, refs, *record.T)


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
