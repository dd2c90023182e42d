"""Unit conversions at the boundary (docs/model.md section 1).

Inside the code every quantity is SI (m, rad, N, N*m, kg).  Files, the CLI
and reports speak mm, um, deg and arcsec; these factors are the only place
where the two meet.  Multiply a file value by the factor to get SI, divide an
SI value by it to report.
"""

import math

MM = 1e-3
"""One millimetre in metres."""

UM = 1e-6
"""One micrometre in metres."""

DEG = math.pi / 180.0
"""One degree in radians."""

ARCMIN = DEG / 60.0
"""One arcminute in radians."""

ARCSEC = DEG / 3600.0
"""One arcsecond in radians."""

GPA = 1e9
"""One gigapascal in pascals."""

RPM = 2.0 * math.pi / 60.0
"""One revolution per minute in rad/s."""


def rad_to_arcsec(value):
    """Radians to arcseconds; works on floats and numpy arrays alike."""
    return value / ARCSEC
