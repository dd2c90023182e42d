"""Small tolerance studies for the tests: the RV-40E-121 at few points per revolution.

These studies test the tolerance machinery (sampling, stores, resuming, backends, Sobol,
allocation, reports), not the reducer: their design is the RV-40E-121 with its crank
bearings and its pins linear springs of their stated stiffness (`LINEAR_DESIGN`), which
solves about five times faster than the preset on its contact laws.  The laws themselves
are tested in test_roller_law.py and test_pin_law.py, and the shipped preset runs through
a whole study in test_allocate_rv40e.py and in the README's quick_mc.
"""

from pathlib import Path


def toml_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


LINEAR_DESIGN = (
    'preset = "RV-40E-121"\nname = "RV-40E-121 linear"\nneedle_rollers = 0\n'
    "tapered_rollers = 0\npin_groove_clearance_mm = 0\n"
)
DESIGN_FILE = "rv40e121_linear.toml"


def write_study(
    folder, name="toy", tolerances=None, study=None, operating=None, spec=None, montecarlo=None, sobol=None
) -> Path:
    """Write a study file `name`.toml in `folder`, and the design file it names; every section
    can be overridden (None: leave out)."""
    design = Path(folder).resolve() / DESIGN_FILE  # absolute: a copied study file finds it
    design.write_text(LINEAR_DESIGN)
    sections = {
        "study": {
            "name": name,
            "design": str(design),
            "seed": 7,
            "metrics": ["te_pp", "rms"],
            "batch_size": 8,
            **(study or {}),
        },
        "operating": {"points": 64, **(operating or {})},
        "spec": {"te_pp_arcsec": 30.0} if spec is None else spec,
        "montecarlo": {"n": 32, **(montecarlo or {})},
        "sobol": {"n": 16, "resamples": 100, **(sobol or {})},
    }
    tolerances = tolerances or {
        "carrier_assembly": {"position_um": 8.0},
        "crank_cam_eccentricity": {"position_um": 9.0, "distribution": "normal"},
        "pin_radial": {"band_um": 5.0},
    }
    lines = []
    for section, values in sections.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in values.items() if v is not None]
    for error, values in tolerances.items():
        lines.append(f"[tolerances.{error}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in values.items()]
    path = Path(folder) / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path
