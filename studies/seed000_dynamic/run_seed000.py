"""The operating point of seeds 000/001: the RV-110E at 1600 rpm input for one output revolution.

Seeds 000/001 simulate the RV-110E with manufacturing errors at 1600 rpm and
report a dynamic TE between -35.9 and 38.8 arcsec with spectral peaks at 260 Hz
(4.43 arcsec) and 400 Hz (0.62 arcsec).  They give no error values, so the
errors here are one reducer drawn from seed 002's tolerances
(`tolerances.toml`, written to `output/rv110e_errors.toml`); the range is a
plausibility check, not a reproduction.  The peak frequencies are kinematics
(pin passing z_p*z_c*f_out and the stage-1 mesh z_s*(f_in - f_out)) and must
match.  Nothing is tuned to the seeds' figures.

    python studies/seed000_dynamic/run_seed000.py [--load 540] [--revolutions 1]
        [--contact hertz impact]
"""

import argparse
import json
from pathlib import Path

import numpy as np

from rvfmu import api
from rvfmu.core.dynamics.excitations import Excitations
from rvfmu.core.reducer.errors import error_file_values, toml_text
from tolerance import montecarlo
from tolerance.sampling import errors_from_unit
from tolerance.study import load_study

HERE = Path(__file__).resolve().parent
SEED = {"te_min": -35.9, "te_max": 38.8, "peaks": {260.0: 4.43, 400.0: 0.62}}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--load",
        type=float,
        default=540.0,
        help="resisting output torque [N*m] (default: half of rated, moderate)",
    )
    parser.add_argument("--revolutions", type=float, default=1.0)
    parser.add_argument(
        "--contact",
        nargs="+",
        choices=("hertz", "linear", "impact"),
        default=["hertz", "impact"],
        help="pin contact laws to run (default: the preset's own, the pins' Hertz "
        "law, and IMPACT, which seeds 000/001 use; linear: the stated stiffness)",
    )
    parser.add_argument("--output", type=Path, default=HERE / "output")
    args = parser.parse_args()
    args.output.mkdir(parents=True, exist_ok=True)

    study = load_study(HERE / "tolerances.toml")
    errors = errors_from_unit(study, montecarlo.rows(study, 0, 1))
    errors_path = args.output / "rv110e_errors.toml"
    errors_path.write_text(
        toml_text(
            error_file_values(errors),
            "RV-110E: row 0 of studies/seed000_dynamic/tolerances.toml (seed 002's tolerances)",
        )
    )
    from rvfmu.progress import ProgressBar

    runs = {}
    for contact in args.contact:
        with ProgressBar(f"simulate ({contact})", unit="step") as bar:
            runs[contact] = api.simulate(
                study.design.name,
                errors_path,
                speed_rpm=1600.0,
                load=args.load,
                revolutions=args.revolutions,
                contact=contact,
                progress=bar,
                plot_path=args.output / f"rv110e_te_{contact}.png",
                csv_path=args.output / f"rv110e_te_{contact}.csv",
            )
    first = next(iter(runs.values())).simulation
    ex = Excitations.at(first.design, 1600.0)
    for contact, report in runs.items():
        print(f"-- pin contact law: {contact}")
        print(report.summary())
        print()
    width = 22
    print(f"{'':<26} {'seeds 000/001':>16}" + "".join(f"{'rvte, ' + c:>{width}}" for c in runs))
    tes = {c: r.simulation.steady_te_arcsec() for c, r in runs.items()}
    print(
        f"{'TE range [arcsec]':<26} {SEED['te_min']:>7.1f} to {SEED['te_max']:<5.1f} "
        + "".join(f"{te.min():>{width - 11}.1f} to {te.max():<7.1f}" for te in tes.values())
    )
    print(
        f"{'TE range about the mean':<26} {'':>16}"
        + "".join(
            f"{te.min() - te.mean():>{width - 11}.1f} to {te.max() - te.mean():<7.1f}" for te in tes.values()
        )
    )
    print(
        f"{'te_pp [arcsec]':<26} {SEED['te_max'] - SEED['te_min']:>16.1f}"
        + "".join(f"{np.ptp(te):>{width}.1f}" for te in tes.values())
    )
    summary = {"load_Nm": args.load, "seed": SEED, "runs": {}}
    for contact, report in runs.items():
        sim = report.simulation
        te = tes[contact]
        f, a = sim.spectrum_hz()
        summary["runs"][contact] = {
            "te_range_arcsec": [float(te.min()), float(te.max())],
            "te_pp_arcsec": float(np.ptp(te)),
            "peaks": {},
            "resolution_hz": float(f[1] - f[0]),
        }
    for (seed_hz, seed_amp), (name, hz) in zip(
        SEED["peaks"].items(), (("pin passing", ex.pin_passing), ("stage-1 mesh", ex.mesh))
    ):
        cells = ""
        for contact, report in runs.items():
            # the TE amplitude at the excitation's own frequency (docs/model.md section 7)
            amplitude = {n: a for n, _, a in report.simulation.excitation_amplitudes()}[name]
            summary["runs"][contact]["peaks"][name] = {
                "kinematic_hz": hz,
                "amplitude_arcsec": amplitude,
                "seed_hz": seed_hz,
                "seed_arcsec": seed_amp,
            }
            cells += f"{hz:>{width - 9}.1f} Hz {amplitude:>5.3f}\u2033"
        print(
            f"{name + ' peak':<26} {seed_hz:>6.0f} Hz {seed_amp:>5.2f}\u2033"
            + cells
            + f"  (kinematics {hz:.1f} Hz)"
        )
    (args.output / "comparison.json").write_text(json.dumps(summary, indent=1))
    print(f"\nwrote {args.output / 'comparison.json'}, rv110e_te_<law>.png and .csv, rv110e_errors.toml")


if __name__ == "__main__":
    main()
