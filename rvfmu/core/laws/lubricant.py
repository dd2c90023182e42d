"""The lubricant: its kinematic viscosity at any temperature, from its grade and viscosity index.

The engineering question: how thick is the oil in the bearings at the temperature the
reducer runs at?  Palmgren's load-free drag grows as (nu n)^(2/3) (`friction.py`), so a
joint started cold turns stiffly and a warm one freely.  An oil is sold by two figures, and
they fix its viscosity at every temperature:

- its ISO VG grade (ISO 3448, Table 1): the mid-point kinematic viscosity at 40 C in
  mm^2/s (= cSt), which is the grade's number from VG 10 up (VG 2, 3, 5, 7: 2.2, 3.2,
  4.6, 6.8);
- its viscosity index VI (ASTM D2270-10): how little the viscosity falls from 40 C to
  100 C against two reference oil series of VI 0 and 100.  D2270 defines VI from the
  viscosities at 40 C (U) and 100 C (Y): L(Y) and H(Y) are the 40 C viscosities of the
  VI 0 and VI 100 oils with the viscosity Y at 100 C, and
      VI = 100 (L - U) / (L - H)                               when U >= H (VI <= 100),
      VI = (10^N - 1) / 0.00715 + 100,  N = (log H - log U) / log Y   when U < H;
  L and H come from D2270's Table 1 for 2 <= Y <= 70 mm^2/s or, as here, from the
  quadratics of its Appendix X2 (Table X2.1: L = a Y^2 + b Y + c, H = d Y^2 + e Y + f on 16
  ranges of Y, the last, Y > 70, being the equations of section 5.2.1); they agree with
  Table 1 within 0.12 %.  Given U and VI, Y is the root of VI(U, Y) = VI (it rises with Y).
  D2270 defines no VI for Y < 2 mm^2/s: a grade and index that would give one are refused.
- between and beyond the two points, Walther's equation (ASTM D341-09):
      log10 log10 (nu + 0.7) = A - B log10 T,   T in K,
  through (40 C, U) and (100 C, Y).  The 0.7 form is D341's for nu >= 2 mm^2/s (below,
  the thinnest oils hot, it reads a little low: D341 adds small terms there).

A design may instead state one viscosity (`lubricant_viscosity_cSt`, > 0): it is then the
viscosity at every temperature, as before the grade was modelled (`viscosity_cSt`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..base.checks import InputError, finite_number

# ISO 3448 Table 1: grade -> mid-point kinematic viscosity at 40 C [mm^2/s].
ISO_VG_VISCOSITY = {
    2: 2.2,
    3: 3.2,
    5: 4.6,
    7: 6.8,
    10: 10.0,
    15: 15.0,
    22: 22.0,
    32: 32.0,
    46: 46.0,
    68: 68.0,
    100: 100.0,
    150: 150.0,
    220: 220.0,
    320: 320.0,
    460: 460.0,
    680: 680.0,
    1000: 1000.0,
    1500: 1500.0,
    2200: 2200.0,
    3200: 3200.0,
}
ISO_VG_GRADES = tuple(ISO_VG_VISCOSITY)
# Viscosity indices of real oils: mineral oils 80-110, synthetic (PAO, ester) 120-180, some
# polyglycols and VI-improved oils up to 250-300; 400 bounds them with room to spare.
VISCOSITY_INDEX_RANGE = (0.0, 400.0)
# Where a robot joint runs and is stored: a cold start in a freezer cell to a reducer near
# its grease's limit.  Walther's line holds over it for mineral and synthetic oils.
TEMPERATURE_RANGE_C = (-40.0, 150.0)
REFERENCE_TEMPERATURE_C = 40.0  # ISO 3448's grade temperature: nu = the grade's there
HIGH_TEMPERATURE_C = 100.0  # D2270's second point
KELVIN = 273.15  # 0 C in K
WALTHER_OFFSET = 0.7  # ASTM D341: Z = nu + 0.7 [mm^2/s], nu >= 2 mm^2/s
D2270_LEAST_Y = 2.0  # mm^2/s at 100 C: D2270 defines no VI below
# ASTM D2270-10 Table X2.1: (least Y [mm^2/s], a, b, c, d, e, f) of L = a Y^2 + b Y + c and
# H = d Y^2 + e Y + f, each row up to the next row's least Y; the last row (Y > 70) is the
# equation pair of section 5.2.1 (L = 0.8353 Y^2 + 14.67 Y - 216, H = 0.1684 Y^2 + 11.85 Y
# - 97) to more digits.
D2270_X2 = np.array(
    [
        (2.0, 1.14673, 1.7576, -0.109, 0.84155, 1.5521, -0.077),
        (3.8, 3.38095, -15.4952, 33.196, 0.78571, 1.7929, -0.183),
        (4.4, 2.5, -7.2143, 13.812, 0.82143, 1.5679, 0.119),
        (5.0, 0.101, 16.635, -45.469, 0.04985, 9.1613, -18.557),
        (6.4, 3.35714, -23.5643, 78.466, 0.22619, 7.7369, -16.656),
        (7.0, 0.01191, 21.475, -72.87, 0.79762, -0.7321, 14.61),
        (7.7, 0.41858, 16.1558, -56.04, 0.05794, 10.5156, -28.24),
        (9.0, 0.88779, 7.5527, -16.6, 0.26665, 6.7015, -10.81),
        (12.0, 0.7672, 10.7972, -38.18, 0.20073, 8.4658, -22.49),
        (15.0, 0.97305, 5.3135, -2.2, 0.28889, 5.9741, -4.93),
        (18.0, 0.97256, 5.25, -0.98, 0.24504, 7.416, -16.73),
        (22.0, 0.91413, 7.4759, -21.82, 0.20323, 9.1267, -34.23),
        (28.0, 0.87031, 9.7157, -50.77, 0.18411, 10.1015, -46.75),
        (40.0, 0.84703, 12.6752, -133.31, 0.17029, 11.4866, -80.62),
        (55.0, 0.85921, 11.1009, -83.19, 0.1713, 11.368, -76.94),
        (70.0, 0.83531, 14.6731, -216.246, 0.16841, 11.8493, -96.947),
    ]
)


def check_grade(value, field: str = "lubricant_iso_vg", where: str = "") -> int:
    """The ISO VG grade `value` as an int, or InputError naming `field` unless it is one of
    ISO 3448's grades (ISO_VG_GRADES)."""
    allowed = (
        "must be an ISO 3448 viscosity grade: one of "
        + ", ".join(str(g) for g in ISO_VG_GRADES)
        + " (mm^2/s at 40 C)"
    )
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(field, value, allowed, where)
    if not (math.isfinite(float(value)) and float(value).is_integer() and int(value) in ISO_VG_VISCOSITY):
        raise InputError(field, value, allowed, where)
    return int(value)


def check_viscosity_index(value, field: str = "lubricant_viscosity_index", where: str = "") -> float:
    """The viscosity index `value` as a float, or InputError naming `field` outside
    VISCOSITY_INDEX_RANGE."""
    value = finite_number(field, value, where)
    low, high = VISCOSITY_INDEX_RANGE
    if not low <= value <= high:
        raise InputError(
            field,
            value,
            f"must be from {low:g} to {high:g}, the viscosity "
            "indices of real oils (ASTM D2270; mineral gear oils 90-100, "
            "synthetics up to about 250)",
            where,
        )
    return value


def check_temperature(value, field: str = "temperature_C", where: str = "") -> float:
    """The lubricant temperature `value` [C] as a float, or InputError naming `field`
    outside TEMPERATURE_RANGE_C."""
    value = finite_number(field, value, where)
    low, high = TEMPERATURE_RANGE_C
    if not low <= value <= high:
        raise InputError(
            field,
            value,
            f"must be from {low:g} to {high:g} C, where a reducer's "
            "oil runs and Walther's equation (ASTM D341) is held",
            where,
        )
    return value


def grade_viscosity_40(grade) -> float:
    """The mid-point kinematic viscosity [mm^2/s] at 40 C of ISO VG `grade` (ISO 3448)."""
    return ISO_VG_VISCOSITY[check_grade(grade)]


def reference_viscosities(nu_100) -> tuple[np.ndarray, np.ndarray]:
    """(L, H) [mm^2/s], each shaped like `nu_100` [mm^2/s] (>= 2): the 40 C viscosities of
    the VI 0 and VI 100 oils of ASTM D2270 whose viscosity at 100 C is nu_100 (Table X2.1's
    quadratics)."""
    y = np.asarray(nu_100, dtype=float)
    row = D2270_X2[np.clip(np.searchsorted(D2270_X2[:, 0], y, side="right") - 1, 0, None)]
    a, b, c, d, e, f = np.moveaxis(row[..., 1:], -1, 0)
    return (a * y + b) * y + c, (d * y + e) * y + f


def viscosity_index(nu_40, nu_100) -> np.ndarray:
    """ASTM D2270's viscosity index of an oil of kinematic viscosities nu_40 at 40 C and
    nu_100 >= 2 at 100 C [mm^2/s] (arrays broadcast together), unrounded."""
    u = np.asarray(nu_40, dtype=float)
    y = np.asarray(nu_100, dtype=float)
    low, high = reference_viscosities(y)
    with np.errstate(divide="ignore", invalid="ignore"):
        below = 100.0 * (low - u) / (low - high)  # U >= H, eq. (1)
        n = (np.log10(high) - np.log10(u)) / np.log10(y)  # U < H, eq. (6)
        above = (10.0**n - 1.0) / 0.00715 + 100.0  # eq. (7)
    return np.where(u >= high, below, above)


@functools.lru_cache(maxsize=256)
def _nu_100(nu_40: float, index: float) -> float:
    from scipy.optimize import brentq  # here: its import takes 0.3-0.7 s, which most commands need not pay

    return float(
        brentq(
            lambda y: float(viscosity_index(nu_40, y)) - index,
            D2270_LEAST_Y,
            nu_40,
            xtol=1e-13,
            rtol=4.0 * np.finfo(float).eps,
        )
    )


def viscosity_100(grade, index, where: str = "") -> float:
    """The kinematic viscosity [mm^2/s] at 100 C of an ISO VG `grade` oil of viscosity index
    `index`: the root Y of ASTM D2270's VI(U, Y) = index, U the grade's viscosity at 40 C.
    InputError (naming lubricant_iso_vg) where the root falls below D2270's 2 mm^2/s."""
    nu_40, index = _d2270_bracket(grade, index, where)
    return _nu_100(nu_40, index)


def _d2270_bracket(grade, index, where: str) -> tuple[float, float]:
    """(U, index) of an ISO VG `grade` oil whose root Y of VI(U, Y) = index lies in D2270's
    range [2 mm^2/s, U]; InputError as `viscosity_100` says where it does not."""
    grade = check_grade(grade, where=where)
    index = check_viscosity_index(index, where=where)
    nu_40 = ISO_VG_VISCOSITY[grade]
    least = float(viscosity_index(nu_40, D2270_LEAST_Y))
    if index < least:  # the VI rises with Y: this oil would be thinner than 2 mm^2/s at 100 C
        raise InputError(
            "lubricant_iso_vg",
            grade,
            f"with lubricant_viscosity_index = {index:g} "
            f"is below {D2270_LEAST_Y:g} mm^2/s at 100 C, where ASTM D2270 defines no "
            f"viscosity index: take ISO VG {grade} only with an index of "
            f"{math.ceil(least)} or more, or a grade from 10 up",
            where,
        )
    return nu_40, index


def walther_viscosity(nu_40: float, nu_100: float, temperature_C) -> np.ndarray:
    """Kinematic viscosity [mm^2/s], shaped like `temperature_C` [C], of the oil of nu_40 at
    40 C and nu_100 at 100 C [mm^2/s]: Walther's line (ASTM D341)
    log10 log10(nu + 0.7) = A - B log10 T [K] through the two points; nu_40 exactly at 40 C."""
    t = np.asarray(temperature_C, dtype=float)
    z_40 = math.log10(math.log10(nu_40 + WALTHER_OFFSET))
    z_100 = math.log10(math.log10(nu_100 + WALTHER_OFFSET))
    log_t40 = math.log10(REFERENCE_TEMPERATURE_C + KELVIN)
    slope = (z_40 - z_100) / (math.log10(HIGH_TEMPERATURE_C + KELVIN) - log_t40)  # B
    z = z_40 - slope * (np.log10(t + KELVIN) - log_t40)
    # The grade's own figure at its own temperature, not its round trip through two logs.
    return np.where(t == REFERENCE_TEMPERATURE_C, nu_40, 10.0**10.0**z - WALTHER_OFFSET)


def grade_viscosity(grade, index, temperature_C, where: str = "") -> np.ndarray:
    """Kinematic viscosity [mm^2/s], shaped like `temperature_C` [C] (each within
    TEMPERATURE_RANGE_C), of an ISO VG `grade` oil of viscosity index `index`."""
    t = np.asarray(temperature_C, dtype=float)
    for value in t.ravel():
        check_temperature(float(value), where=where)
    return walther_viscosity(
        ISO_VG_VISCOSITY[check_grade(grade, where=where)], viscosity_100(grade, index, where), t
    )


def viscosity_cSt(design, temperature_C: float = REFERENCE_TEMPERATURE_C) -> float:
    """The kinematic viscosity [mm^2/s] of `design`'s lubricant at `temperature_C` [C]: its
    stated `lubricant_viscosity` at every temperature if > 0, else that of its ISO VG grade
    and viscosity index there (`grade_viscosity`).  At 40 C the grade's figure exactly."""
    temperature_C = check_temperature(temperature_C)
    if design.lubricant_viscosity > 0.0:
        return float(design.lubricant_viscosity)
    return float(
        grade_viscosity(design.lubricant_iso_vg, design.lubricant_viscosity_index, temperature_C, design.name)
    )


def check_lubricant(grade, index, where: str = "") -> None:
    """Refuse (InputError) a grade that is not ISO 3448's, an index outside
    VISCOSITY_INDEX_RANGE, or a pair that leaves ASTM D2270's range (`viscosity_100`).  The
    root itself waits for the first viscosity asked for: every design is checked, few need it."""
    _d2270_bracket(grade, index, where)
