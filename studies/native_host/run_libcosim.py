"""Run the reducer FMU in the Open Simulation Platform's native co-simulation engine.

libcosim (C++, through its Python binding libcosimpy) loads the FMU the way
Modelica tools and other native hosts do: it dlopens the FMU's binary, which
embeds Python.  The host must therefore make libpython loadable and tell the
embedded interpreter where its standard library and numpy/scipy are; run it as

    LD_PRELOAD=<libdir>/libpython3.11.so PYTHONHOME=<prefix> PYTHONPATH=<site-packages> \\
        python studies/native_host/run_libcosim.py RVReducer.fmu out.csv [--speed RAD_S] [--load NM] \\
            [--duration S] [--model {quasistatic,dynamic}]

(`python studies/native_host/env.py` prints those three values for this Python.)
A native FMU (`rvte fmu build --native`) embeds no Python: it runs with none of
the three, and it has no `model` parameter (it is the quasi-static TE map).
The input shaft turns at a constant speed under a constant resisting load;
the output angle, TE and input torque are written to a CSV file, one row per step.
`--model` sets the FMU's string parameter `model` before initialisation:
`quasistatic` (the TE map, the FMU's default) or `dynamic` (the dynamic model,
stepped inside each 1 ms communication step at the FMU's `dynamic_step`); an
FMU without that parameter runs only as `quasistatic`.
"""

import argparse
import csv
import os
import sys

from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

MODELS = ("quasistatic", "dynamic")  # the values of the FMU's `model` parameter


def run(
    fmu, out, speed=1600 * 2 * 3.141592653589793 / 60, load=0.0, step=1e-3, duration=0.2, model="quasistatic"
):
    execution = CosimExecution.from_step_size(step_size=int(step * 1e9))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmu), instance_name="reducer"))
    variables = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    manipulator = CosimManipulator.create_override()
    observer = CosimObserver.create_last_value()
    execution.add_manipulator(manipulator)
    execution.add_observer(observer)
    names = ["theta_out", "te_arcsec", "omega_out", "tau_in", "P_loss", "efficiency"]
    refs = [variables[n] for n in names]
    if "model" in variables:
        if not execution.string_initial_value(index, variables["model"], model):
            raise RuntimeError(f"libcosim refused the initial value model = {model!r}")
    elif model != "quasistatic":
        raise RuntimeError(f"{fmu} has no parameter `model`: it runs the quasi-static TE map only")
    execution.real_initial_value(index, variables["tau_load"], -load)
    rows = []
    steps = int(round(duration / step))
    for k in range(steps + 1):
        t = k * step
        manipulator.slave_real_values(
            index, [variables["theta_in"], variables["tau_load"]], [speed * t, -load]
        )
        if not execution.step():
            raise RuntimeError(f"libcosim step {k} failed")
        rows.append([t + step] + list(observer.last_real_values(index, refs)))
    with open(out, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["time"] + names)
        writer.writerows(rows)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fmu")
    parser.add_argument("out")
    parser.add_argument("--speed", type=float, default=1600 * 2 * 3.141592653589793 / 60)
    parser.add_argument("--load", type=float, default=0.0, help="resisting output torque [N*m]")
    parser.add_argument("--duration", type=float, default=0.2)
    parser.add_argument(
        "--model",
        choices=MODELS,
        default="quasistatic",
        help="the FMU's reducer model (default: quasistatic)",
    )
    args = parser.parse_args(argv)
    rows = run(args.fmu, args.out, args.speed, args.load, duration=args.duration, model=args.model)
    print(f"{len(rows)} steps, last te_arcsec {rows[-1][2]:.4f}")
    return 0


if __name__ == "__main__":
    code = main()
    # Everything is written.  A pythonfmu FMU embeds an interpreter inside this Python
    # process, and libcosim's release of it at interpreter exit can corrupt the heap
    # ("corrupted double-linked list", depending only on the size of the unpacked FMU:
    # one more 12-byte source file in it was enough), so the process ends here without
    # the interpreter's finalisation.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
