"""Input checking shared by designs, error sets and studies.

Every bad input becomes one `InputError` whose message names the field, the
value that was given and what is allowed, so that the CLI can print it on one
line and the FMU can log it instead of crashing its host.
"""

import math
import os

import numpy as np

MEMORY_SHARE = 0.25  # one array of results may take at most this share of the machine's memory


class InputError(ValueError):
    """A design, error set or study value that the model cannot accept."""

    def __init__(self, field, value, allowed, where=""):
        self.field = field
        self.value = value
        self.allowed = allowed
        prefix = f"{where}: " if where else ""
        super().__init__(f"{prefix}{field} = {_show(value)}: {allowed}")


def _show(value):
    text = repr(value.tolist() if isinstance(value, np.ndarray) else value)
    if isinstance(value, str):  # a path or a name: cutting it would hide the file name
        return text
    return text if len(text) <= 80 else text[:77] + "..."


def finite_number(field, value, where=""):
    """Return `value` as a float, or raise if it is not a finite real number."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(field, value, "must be a number", where)
    value = float(value)
    if not math.isfinite(value):
        raise InputError(field, value, "must be finite (not NaN or inf)", where)
    return value


def positive(field, value, where=""):
    value = finite_number(field, value, where)
    if value <= 0.0:
        raise InputError(field, value, "must be > 0", where)
    return value


def non_negative(field, value, where=""):
    value = finite_number(field, value, where)
    if value < 0.0:
        raise InputError(field, value, "must be >= 0", where)
    return value


def integer(field, value, low, high=None, where=""):
    """Return `value` as an int in [low, high], or raise."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise InputError(field, value, "must be a whole number", where)
    value = int(value)
    if value < low or (high is not None and value > high):
        allowed = f"must be >= {low}" if high is None else f"must be from {low} to {high}"
        raise InputError(field, value, allowed, where)
    return value


def finite_array(field, value, shape, where=""):
    """Return `value` as a float array of exactly `shape`, all finite, or raise.

    `shape` is a tuple of ints; the message says the shape that is allowed,
    so a pin list of the wrong length names the number of pins.
    """
    try:
        raw = np.asarray(value)
        array = raw.astype(float)
    except (TypeError, ValueError):
        raw = None
    if raw is None or raw.dtype.kind not in "iuf":
        # Text ("5") and true/false would otherwise convert silently to numbers.
        raise InputError(field, value, f"must be numbers shaped {_shape_text(shape)}", where)
    if array.shape != tuple(shape):
        raise InputError(
            field, value, f"must be shaped {_shape_text(shape)}, got {_shape_text(array.shape)}", where
        )
    if not np.all(np.isfinite(array)):
        raise InputError(field, value, "must be finite (no NaN or inf)", where)
    return array


def _shape_text(shape):
    return " x ".join(str(n) for n in shape) if shape else "a scalar"


def fits_in_memory(field, value, size_bytes, what, where=""):
    """Raise if `size_bytes` (what the input `field` = `value` asks to hold) is more than
    MEMORY_SHARE of this machine's memory; `what` says what it is, e.g. "gives 1e9 steps whose
    record alone"."""
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if size_bytes > MEMORY_SHARE * memory:
        raise InputError(
            field,
            value,
            f"{what} takes {size_bytes / 1e9:.3g} GB, more than "
            f"{MEMORY_SHARE:.0%} of this machine's {memory / 1e9:.3g} GB of memory: "
            f"choose a smaller {field}",
            where,
        )
