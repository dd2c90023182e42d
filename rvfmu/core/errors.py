"""Manufacturing errors of MODEL.md section 4, for one reducer or a batch of them.

An `ErrorSet` holds every error of a batch of reducers as arrays with a
leading sample axis, in SI units.  Eccentricity and position errors [E, beta]
are stored as complex numbers E*exp(i*beta) in the frame that MODEL.md names
for their phase: the model turns them into the fixed frame by one complex
multiplication per pose, and a sum of two error sets is their superposition.

Files (TOML) use the names of MODEL.md with E in um and beta in degrees; a
missing key means zero.  Unknown names, wrong lengths, NaN, negative
magnitudes and negative clearances are refused with the field named.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .checks import InputError, finite_array
from .design import RVDesign
from .units import DEG, UM

PHASED = ("sun_eccentricity", "sun_assembly", "planet_eccentricity", "crank_cam_eccentricity",
          "disc_crank_hole", "carrier_crank_hole", "carrier_assembly")
PER_TOOTH = ("pin_radial", "pin_pitch", "pin_radius", "disc_profile", "disc_pitch")
CLEARANCES = ("crank_disc_clearance", "crank_carrier_clearance", "main_bearing_clearance")
ERROR_NAMES = PHASED + PER_TOOTH + CLEARANCES


def error_shapes(design: RVDesign) -> dict:
    """Shape of one reducer's value of each error, without the trailing [E, beta] pair."""
    n_c, z_p, z_c = design.n_c, design.z_p, design.z_c
    return {
        "sun_eccentricity": (), "sun_assembly": (), "planet_eccentricity": (n_c,),
        "crank_cam_eccentricity": (n_c, 2), "disc_crank_hole": (2, n_c),
        "carrier_crank_hole": (n_c,), "carrier_assembly": (),
        "pin_radial": (z_p,), "pin_pitch": (z_p,), "pin_radius": (z_p,),
        "disc_profile": (2, z_c), "disc_pitch": (2, z_c),
        "crank_disc_clearance": (), "crank_carrier_clearance": (), "main_bearing_clearance": (),
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
        return self


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
    return ErrorSet(**{name: np.concatenate([getattr(e, name) for e in error_sets])
                       for name in ERROR_NAMES})


def errors_from_file_values(design: RVDesign, values: dict, where: str = "errors") -> ErrorSet:
    """One reducer's errors from MODEL.md names in file units (um, deg)."""
    unknown = [key for key in values if key not in ERROR_NAMES]
    if unknown:
        raise InputError(unknown[0], values[unknown[0]],
                         f"is not an error name; known names: {', '.join(ERROR_NAMES)}", where)
    shapes = error_shapes(design)
    arrays = dataclasses.asdict(zero_errors(design))
    for name, raw in values.items():
        if name in PHASED:
            pairs = finite_array(name, raw, shapes[name] + (2,), where)
            magnitude, phase = pairs[..., 0], pairs[..., 1]
            if np.any(magnitude < 0):
                raise InputError(name, raw, "every magnitude E must be >= 0 um "
                                 "(turn the phase beta by 180 deg instead)", where)
            arrays[name] = (magnitude * UM * np.exp(1j * phase * DEG))[None]
        else:
            value = finite_array(name, raw, shapes[name], where)
            if name in CLEARANCES and value < 0:
                raise InputError(name, raw, "a clearance must be >= 0 um", where)
            arrays[name] = (value * UM)[None]
    return ErrorSet(**arrays)


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
