"""Manufacturing errors of docs/model.md section 4, for one reducer or a batch of them.

An `ErrorSet` holds every error of a batch of reducers as arrays with a
leading sample axis, in SI units.  Eccentricity and position errors [E, beta]
are stored as complex numbers E*exp(i*beta) in the frame that docs/model.md section 4 names
for their phase: the model turns them into the fixed frame by one complex
multiplication per pose, and a sum of two error sets is their superposition.

Files (TOML) use the names of docs/model.md section 4 with E in um and beta in degrees; a
missing key means zero.  Unknown names, wrong lengths, NaN, negative
magnitudes and negative clearances are refused with the field named, and so is
an error larger than the model can hold (`check_error_sizes`): one rule for every
error, at most ERROR_FRACTION of the length of the geometry it displaces.
`error_template_text` writes a complete file of zeros to fill in, and
`toml_text` is the one writer of such files (and of other flat TOML
documents of numbers, strings and nested lists).
"""

from __future__ import annotations

import dataclasses
import textwrap
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.checks import InputError, finite_array
from ..base.units import DEG, MM, UM
from .design import RVDesign

PHASED = (
    "sun_eccentricity",
    "sun_assembly",
    "planet_eccentricity",
    "crank_cam_eccentricity",
    "disc_crank_hole",
    "carrier_crank_hole",
    "carrier_assembly",
)
PER_TOOTH = ("pin_radial", "pin_pitch", "pin_radius", "disc_profile", "disc_pitch")
CLEARANCES = ("crank_disc_clearance", "crank_carrier_clearance", "main_bearing_clearance")
ERROR_NAMES = PHASED + PER_TOOTH + CLEARANCES

# Where the equivalent error model holds.  It takes every error as a small displacement
# about the nominal kinematics (docs/model.md section 4): the gap of every contact moves by
# the error along the nominal contact normal, the second-order part is left out.  An error
# delta moves a contact along its profile by about delta, over a tooth whose normal turns
# through its whole swing within the tooth depth; the part left out is then of relative size
# about delta / (2 x the length the error displaces).  At a tenth of that length it is 5 %:
# beyond, the first-order model is no longer the reducer.  The length is the tooth depth's
# scale of the stage the error displaces: the module m for the stage-1 mesh (tooth depth
# 2.25 m); the eccentricity e for everything of the cycloid stage (its lobes are 2e deep, and
# a crank, cam, disc hole, carrier seat or bearing clearance moves a disc centre whose
# nominal path is a circle of radius e).  A tenth is 90-175 um on the presets; real errors,
# even of a poor reducer, are a few to a few tens of um (seed 002 tables 2-4: 3-8 um).
ERROR_FRACTION = 0.1
STAGE_1_ERRORS = ("sun_eccentricity", "sun_assembly", "planet_eccentricity")


def error_shapes(design: RVDesign) -> dict:
    """Shape of one reducer's value of each error, without the trailing [E, beta] pair."""
    n_c, z_p, z_c = design.n_c, design.z_p, design.z_c
    return {
        "sun_eccentricity": (),
        "sun_assembly": (),
        "planet_eccentricity": (n_c,),
        "crank_cam_eccentricity": (n_c, 2),
        "disc_crank_hole": (2, n_c),
        "carrier_crank_hole": (n_c,),
        "carrier_assembly": (),
        "pin_radial": (z_p,),
        "pin_pitch": (z_p,),
        "pin_radius": (z_p,),
        "disc_profile": (2, z_c),
        "disc_pitch": (2, z_c),
        "crank_disc_clearance": (),
        "crank_carrier_clearance": (),
        "main_bearing_clearance": (),
    }


@dataclass(frozen=True)
class ErrorSet:
    """Errors of S reducers, SI units.

    Phased errors are complex arrays (S, *shape) = E*exp(i*beta) [m] in their own
    frame; per-tooth errors and clearances are real arrays (S, *shape) [m].
    Shapes per reducer: see `error_shapes`.
    """

    sun_eccentricity: np.ndarray
    sun_assembly: np.ndarray
    planet_eccentricity: np.ndarray
    crank_cam_eccentricity: np.ndarray
    disc_crank_hole: np.ndarray
    carrier_crank_hole: np.ndarray
    carrier_assembly: np.ndarray
    pin_radial: np.ndarray
    pin_pitch: np.ndarray
    pin_radius: np.ndarray
    disc_profile: np.ndarray
    disc_pitch: np.ndarray
    crank_disc_clearance: np.ndarray
    crank_carrier_clearance: np.ndarray
    main_bearing_clearance: np.ndarray

    @property
    def samples(self) -> int:
        return self.pin_radial.shape[0]

    def arrays(self) -> dict:
        return {name: getattr(self, name) for name in ERROR_NAMES}

    def scaled(self, factor: float) -> "ErrorSet":
        """Every error magnitude (and clearance) times `factor`; phases kept."""
        return ErrorSet(**{k: v * factor for k, v in self.arrays().items()})

    def take(self, index) -> "ErrorSet":
        """The reducers `index` (slice or integer array) of the batch."""
        index = np.atleast_1d(np.arange(self.samples)[index])
        return ErrorSet(**{k: v[index] for k, v in self.arrays().items()})

    def replace(self, **changes) -> "ErrorSet":
        return dataclasses.replace(self, **changes)

    def check(self, design: RVDesign) -> "ErrorSet":
        """Raise InputError if any array does not fit `design`; return self."""
        shapes = error_shapes(design)
        for name, array in self.arrays().items():
            expected = (self.samples,) + shapes[name]
            if array.shape != expected:
                raise InputError(name, f"array of shape {array.shape}", f"must be shaped {expected}")
            if not np.all(np.isfinite(array)):
                raise InputError(name, "array with NaN or inf", "must be finite")
        for name in CLEARANCES:
            if np.any(getattr(self, name) < 0):
                raise InputError(name, float(np.min(getattr(self, name)) / UM), "must be >= 0 um")
        check_error_sizes(design, self)
        return self


def error_limits(design: RVDesign) -> dict:
    """{error name: the largest magnitude E, |deviation| or clearance [m] the model takes}:
    ERROR_FRACTION x the module m (stage-1 errors) or x the eccentricity e (the others)."""
    return {name: ERROR_FRACTION * (design.m if name in STAGE_1_ERRORS else design.e) for name in ERROR_NAMES}


def check_error_sizes(design: RVDesign, errors: ErrorSet, where: str = "") -> None:
    """Raise InputError at the first error of `errors` larger than `error_limits(design)`,
    naming it with its index (`crank_cam_eccentricity[1][0]`), its size in um and the limit
    in um; in a batch of several reducers `where` names the reducer too."""
    limits = error_limits(design)
    for name, array in errors.arrays().items():
        size = np.abs(array)  # (S, *shape): magnitude E, |deviation|, clearance
        limit = limits[name]
        over = np.argwhere(size > limit * (1.0 + 1e-9))  # 1e-9: E at the limit, after exp(i beta)
        if not over.size:
            continue
        sample, *index = (int(i) for i in over[0])
        field = name + "".join(f"[{i}]" for i in index)
        what = (
            "its magnitude E"
            if name in PHASED
            else "a clearance"
            if name in CLEARANCES
            else "its absolute value"
        )
        length, symbol = (design.m, "module m") if name in STAGE_1_ERRORS else (design.e, "eccentricity e")
        place = f"reducer {sample} of {errors.samples}" if errors.samples > 1 else ""
        raise InputError(
            field,
            float(size[(sample, *index)] / UM),
            f"{what} must be at most {limit / UM:.4g} um, {ERROR_FRACTION:g} x the "
            f"{symbol} = {length / MM:.4g} mm of {design.name}: the equivalent error "
            "model linearises about the nominal kinematics and does not hold for "
            "an error that large (docs/model.md section 4)",
            ", ".join(w for w in (where, place) if w),
        )


def zero_errors(design: RVDesign, samples: int = 1) -> ErrorSet:
    """S reducers without any error."""
    arrays = {}
    for name, shape in error_shapes(design).items():
        dtype = complex if name in PHASED else float
        arrays[name] = np.zeros((samples,) + shape, dtype=dtype)
    return ErrorSet(**arrays)


def stack(error_sets) -> ErrorSet:
    """One batch from several error sets, in order."""
    error_sets = list(error_sets)
    return ErrorSet(**{name: np.concatenate([getattr(e, name) for e in error_sets]) for name in ERROR_NAMES})


def errors_from_file_values(design: RVDesign, values: dict, where: str = "errors") -> ErrorSet:
    """One reducer's errors from docs/model.md section 4 names in file units (um, deg)."""
    unknown = [key for key in values if key not in ERROR_NAMES]
    if unknown:
        raise InputError(
            unknown[0],
            values[unknown[0]],
            f"is not an error name; known names: {', '.join(ERROR_NAMES)}",
            where,
        )
    shapes = error_shapes(design)
    arrays = dataclasses.asdict(zero_errors(design))
    for name, raw in values.items():
        if name in PHASED:
            pairs = finite_array(name, raw, shapes[name] + (2,), where)
            magnitude, phase = pairs[..., 0], pairs[..., 1]
            if np.any(magnitude < 0):
                raise InputError(
                    name,
                    raw,
                    "every magnitude E must be >= 0 um (turn the phase beta by 180 deg instead)",
                    where,
                )
            arrays[name] = (magnitude * UM * np.exp(1j * phase * DEG))[None]
        else:
            value = finite_array(name, raw, shapes[name], where)
            if name in CLEARANCES and value < 0:
                raise InputError(name, raw, "a clearance must be >= 0 um", where)
            arrays[name] = (value * UM)[None]
    errors = ErrorSet(**arrays)
    check_error_sizes(design, errors, where)
    return errors


def error_file_values(errors: ErrorSet, sample: int = 0) -> dict:
    """One reducer's errors as an error file writes them (um, deg), zeros left out."""
    values = {}
    for name, array in errors.arrays().items():
        value = array[sample]
        if not np.any(value):
            continue
        if name in PHASED:
            pairs = np.stack([np.abs(value) / UM, np.degrees(np.angle(value)) % 360.0], axis=-1)
            values[name] = pairs.tolist()
        else:
            values[name] = (value / UM).tolist()
    return values


def load_errors(path: str | Path, design: RVDesign) -> ErrorSet:
    """The error set of one reducer from a TOML error file."""
    path = Path(path)
    if not path.is_file():
        raise InputError("errors", str(path), "must be a readable TOML error file")
    try:
        values = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError("errors", str(path), f"is not valid TOML ({exc})") from None
    return errors_from_file_values(design, values, where=path.name)


# -- writing error files --------------------------------------------------------------------

# One short line per error of docs/model.md section 4, in its order: definition, unit, sign and
# the frame of the phase.  "{n_c}", "{z_p}", "{z_c}" are filled in from the design.
ERROR_NOTES = {
    "sun_eccentricity": "[E um, beta deg]: sun pitch circle centre off the input axis; "
    "beta in the sun frame (turns with theta_in)",
    "sun_assembly": "[E um, beta deg]: input axis off the pin circle (housing) centre; "
    "beta in the fixed frame",
    "planet_eccentricity": "{n_c} x [E um, beta deg], [crank i]: planet pitch circle centre off "
    "its crank axis; beta in the crank frame (x axis along cam 0)",
    "crank_cam_eccentricity": "{n_c} x 2 x [E um, beta deg], [crank i][disc j]: centre of cam j "
    "off its nominal place; beta in the crank frame (x along cam 0, "
    "both cams)",
    "disc_crank_hole": "2 x {n_c} x [E um, beta deg], [disc j][crank i]: position of crank hole "
    "i of disc j off nominal; beta in the disc frame (turns with theta_out)",
    "carrier_crank_hole": "{n_c} x [E um, beta deg], [crank i]: crank bearing seat i in the "
    "carrier off nominal; beta in the carrier frame",
    "carrier_assembly": "[E um, beta deg]: carrier rotation axis off the pin circle centre; "
    "beta in the fixed frame",
    "pin_radial": "{z_p} values um, [pin k]: radial offset of the pin centre, + outward",
    "pin_pitch": "{z_p} values um, [pin k]: cumulative pitch deviation (tangential offset on "
    "the pin circle, not summed again), + counter-clockwise",
    "pin_radius": "{z_p} values um, [pin k]: pin radius deviation, + larger",
    "disc_profile": "2 x {z_c} values um, [disc j][lobe m]: normal deviation of lobe m "
    "(valley m to valley m+1), + material added",
    "disc_pitch": "2 x {z_c} values um, [disc j][lobe m]: cumulative pitch deviation of lobe m, "
    "tangential at radius R_p*z_c/z_p, + counter-clockwise",
    "crank_disc_clearance": "um >= 0: radial internal clearance (ISO 5753, total travel) of "
    "every crank-disc needle bearing",
    "crank_carrier_clearance": "um >= 0: radial internal clearance (ISO 5753) of every "
    "crankshaft support bearing in the carrier",
    "main_bearing_clearance": "um >= 0: radial internal clearance (ISO 5753) of the carrier main bearings",
}

NUMBERS_PER_LINE = 10  # long per-tooth lists are wrapped so that a tooth is easy to find
COMMENT_WIDTH = 92  # comment lines wrap here: readable in any editor beside the values


def error_template_text(design: RVDesign) -> str:
    """A complete, commented error file for `design`: every error of docs/model.md section 4.

    Every name appears in section-4 order under a comment line (definition, unit,
    sign, frame of the phase) with zero values shaped for the design's n_c, z_p and
    z_c; `load_errors` reads it back as the error-free reducer.
    """
    n_c, z_p, z_c = design.n_c, design.z_p, design.z_c
    name = " ".join(str(design.name).split())  # one line, whatever the design file said
    header = (
        f"Manufacturing errors of {name} (z_p = {z_p}, z_c = {z_c}, n_c = {n_c}): every\n"
        "error of docs/model.md section 4, in its order, all zero.  Fill in what you know;\n"
        "a key left out means zero.  Magnitudes and deviations in um, phases beta in deg\n"
        "in the frame named; indices start at 0.  Use: rvte te DESIGN --errors FILE"
    )
    shapes = error_shapes(design)
    values, notes = {}, {}
    for key in ERROR_NAMES:
        shape = shapes[key] + ((2,) if key in PHASED else ())
        values[key] = np.zeros(shape).tolist() if shape else 0.0
        notes[key] = ERROR_NOTES[key].format(n_c=n_c, z_p=z_p, z_c=z_c)
    return toml_text(values, header=header, notes=notes)


def toml_text(values: dict, header: str = "", notes: dict | None = None, digits: int | None = None) -> str:
    """A flat TOML document: `key = value` per entry, in the order of `values`.

    values: numbers, strings, booleans and nested lists of numbers (as
    `error_file_values` or `RVDesign.file_values` give them); header: comment
    lines at the top; notes: {key: comment}, written before that key after a
    blank line and wrapped at COMMENT_WIDTH; digits: significant digits of
    floats (None: the shortest text that reads back to the same float).  Lists
    of more than NUMBERS_PER_LINE numbers are wrapped, that many a line.
    """
    notes = notes or {}
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    for key, value in values.items():
        if key in notes:
            lines += [""] + textwrap.wrap(
                notes[key],
                COMMENT_WIDTH,
                initial_indent="# ",
                subsequent_indent="#   ",
                break_on_hyphens=False,
            )
        prefix = f"{key} = "
        lines.append(prefix + _toml_value(value, len(prefix), digits))
    return "\n".join(lines) + "\n"


_LISTS = (list, tuple, np.ndarray)


def _toml_value(value, column: int, digits: int | None) -> str:
    """TOML text of one value whose first character sits at `column` (for wrapped lines)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if not isinstance(value, (list, tuple)):
        return _toml_float(value, digits)
    if not any(isinstance(v, _LISTS) for v in value):
        items = [_toml_value(v, 0, digits) for v in value]
        rows = [
            ", ".join(items[k : k + NUMBERS_PER_LINE]) for k in range(0, len(items), NUMBERS_PER_LINE)
        ] or [""]
        return "[" + (",\n" + " " * (column + 1)).join(rows) + "]"
    items = [_toml_value(v, column + 1, digits) for v in value]
    one_line = "[" + ", ".join(items) + "]"
    # Pairs [E, beta] of a short list share a line; deeper lists give each item its own.
    flat_items = all(isinstance(v, _LISTS) and not any(isinstance(w, _LISTS) for w in v) for v in value)
    if flat_items and "\n" not in one_line and column + len(one_line) <= 100:
        return one_line
    return "[" + (",\n" + " " * (column + 1)).join(items) + "]"


def _toml_float(value, digits: int | None) -> str:
    value = float(value)
    text = repr(value) if digits is None else f"{value:.{digits}g}"
    if text in ("nan", "inf", "-inf"):
        return text
    return text if any(c in text for c in ".e") else text + ".0"  # a float stays a float
