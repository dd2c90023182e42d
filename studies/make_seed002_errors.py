"""Write studies/seed002_errors.toml: seed 002's error set for the RV-40E-121.

Seed 002 tables 2-3 give every eccentricity and position error as (E um, beta deg);
table 4 gives tolerances of the per-tooth errors (disc profile 8 um and total
cumulative pitch 6 um; pin profile 5 um and total cumulative pitch 8 um).  This
script draws one per-tooth sequence that realises each of those tolerances, with a
fixed seed, once; the stored file is what the project uses.  Run it again only to
regenerate the file on purpose:  python studies/make_seed002_errors.py
"""

from pathlib import Path

import numpy as np

from tolerance.sequences import cumulative_pitch_sequence, profile_sequence

SEED = 2002
Z_P, Z_C = 40, 39


def main(path=Path(__file__).with_name("seed002_errors.toml")):  # noqa: B008 - a Path is immutable
    rng = np.random.default_rng(SEED)
    disc_profile = profile_sequence(rng, Z_C, 8.0, samples=2)
    disc_pitch = cumulative_pitch_sequence(rng, Z_C, 6.0, samples=2)
    pin_radial = profile_sequence(rng, Z_P, 5.0)[0]
    pin_pitch = cumulative_pitch_sequence(rng, Z_P, 8.0)[0]

    def row(values):
        return "[" + ", ".join(f"{v:.3f}" for v in values) + "]"

    text = f"""# Seed 002 error set of the RV-40E-121 (docs/model.md section 4 names and units: um, deg).
# Tables 2 and 3 verbatim; table 4's tolerances realised as per-tooth sequences drawn
# once by studies/make_seed002_errors.py (seed {SEED}) and stored here.
# Seed 002 neglects the stage-1 errors and gives no clearances: they are zero here.

# Table 2: crank shaft cam eccentric error, [crank i][disc j] = [E, beta]
crank_cam_eccentricity = [[[3.5, 30.0], [4.0, 140.0]],
                          [[3.0, 195.0], [4.5, 85.0]]]
# Table 2: cycloid crank shaft hole eccentric error, [disc j][crank i]
disc_crank_hole = [[[3.5, 40.0], [3.5, 215.0]],
                   [[3.0, 130.0], [3.0, 130.0]]]
# Table 3: planet carrier crank shaft hole eccentric error, [crank i]; assembling error
carrier_crank_hole = [[3.5, 195.0], [3.0, 75.0]]
carrier_assembly = [4.0, 30.0]

# Table 4, cycloid: profile error 8 um (per lobe, uniform in +-4 um), total cumulative
# pitch error 6 um (span of each disc's cumulative sequence).  [disc j][lobe m]
disc_profile = [{row(disc_profile[0])},
                {row(disc_profile[1])}]
disc_pitch = [{row(disc_pitch[0])},
              {row(disc_pitch[1])}]

# Table 4, pin gear: profile error 5 um (radial pin position, uniform in +-2.5 um, as
# E_Rk of seeds 000/002), total cumulative pitch error 8 um.  [pin k]
pin_radial = {row(pin_radial)}
pin_pitch = {row(pin_pitch)}
"""
    path.write_text(text)
    return path


if __name__ == "__main__":
    print(f"wrote {main()}")
