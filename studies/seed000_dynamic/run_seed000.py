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
"""

import argparse
import json
from pathlib import Path

import numpy as np

from rvfmu import api
from rvfmu.core.errors import error_file_values, toml_text
from rvfmu.core.simulation import Excitations
from tolerance import montecarlo
from tolerance.sampling import errors_from_unit
from tolerance.study import load_study

HERE = Path(__file__).resolve().parent
SEED = {"te_min": -35.9, "te_max": 38.8, "peaks": {260.0: 4.43, 400.0: 0.62}}


def amplitude_near(frequencies, amplitudes, target, width):
    near = np.abs(frequencies - target) <= width
    k = np.argmax(np.where(near, amplitudes, -1.0))
    return float(frequencies[k]), float(amplitudes[k])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--load", type=float, default=540.0,
                        help="resisting output torque [N*m] (default: half of rated, moderate)")
    parser.add_argument("--revolutions", type=float, default=1.0)
    parser.add_argument("--output", type=Path, default=HERE / "output")
    args = parser.parse_args()
    args.output.mkdir(parents=True, exist_ok=True)

    study = load_study(HERE / "tolerances.toml")
    errors = errors_from_unit(study, montecarlo.rows(study, 0, 1))
    errors_path = args.output / "rv110e_errors.toml"
    errors_path.write_text(toml_text(error_file_values(errors), "RV-110E: row 0 of "
                                     "studies/seed000_dynamic/tolerances.toml (seed 002's tolerances)"))
    from rvfmu.progress import ProgressBar

    with ProgressBar("simulate", unit="step") as bar:
        report = api.simulate("RV-110E", errors_path, speed_rpm=1600.0, load=args.load,
                              revolutions=args.revolutions, plot_path=args.output / "rv110e_te.png",
                              csv_path=args.output / "rv110e_te.csv", progress=bar)
    sim = report.simulation
    te = sim.steady_te_arcsec()
    f, a = sim.spectrum_hz()
    ex = Excitations.at(sim.design, 1600.0)
    resolution = f[1] - f[0]
    print(report.summary())
    print()
    print(f"{'':<26} {'seeds 000/001':>16} {'rvte':>22}")
    print(f"{'TE range [arcsec]':<26} {SEED['te_min']:>7.1f} to {SEED['te_max']:<5.1f} "
          f"{te.min():>10.1f} to {te.max():<7.1f}")
    print(f"{'TE range about the mean':<26} {'':>16} {te.min() - te.mean():>10.1f} to "
          f"{te.max() - te.mean():<7.1f}")
    rows = {}
    for (seed_hz, seed_amp), (name, hz) in zip(SEED["peaks"].items(),
                                               (("pin passing", ex.pin_passing),
                                                ("stage-1 mesh", ex.mesh))):
        peak_hz, peak_amp = amplitude_near(f, a, hz, 3 * resolution)
        rows[name] = {"kinematic_hz": hz, "peak_hz": peak_hz, "amplitude_arcsec": peak_amp,
                      "seed_hz": seed_hz, "seed_arcsec": seed_amp}
        print(f"{name + ' peak':<26} {seed_hz:>6.0f} Hz {seed_amp:>5.2f}\u2033 "
              f"{peak_hz:>10.1f} Hz {peak_amp:>6.3f}\u2033  (kinematics {hz:.1f} Hz)")
    summary = {"load_Nm": args.load, "te_range_arcsec": [float(te.min()), float(te.max())],
               "te_pp_arcsec": float(np.ptp(te)), "peaks": rows, "seed": SEED,
               "resolution_hz": float(resolution)}
    (args.output / "comparison.json").write_text(json.dumps(summary, indent=1))
    print(f"\nwrote {args.output / 'comparison.json'}, rv110e_te.png, rv110e_te.csv, "
          "rv110e_errors.toml")


if __name__ == "__main__":
    main()
