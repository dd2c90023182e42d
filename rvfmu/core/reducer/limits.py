"""Where the small-displacement model holds: output torque limits by catalogue class.

The equivalent error model linearises every contact, bearing and mesh about
the nominal kinematics: displacements must stay small against the clearances
and the tooth geometry.  That holds up to a few times the rated torque.
Catalogues of RV reducers give two classes above rated: the momentary maximum
(acceleration and deceleration peaks, about 2.5x rated) and the emergency
stop (about 5x rated, a few times in the reducer's life).  Above the first the
results are still computed but the caller is warned; above the second the
model is refused (at 1e12 N*m it would print a TE of 1e11 arcsec as a result).
"""

from __future__ import annotations

from ..base.checks import InputError, finite_number

MOMENTARY_FACTOR = 2.5  # catalogue momentary maximum torque class, x rated (accel/decel peaks)
EMERGENCY_FACTOR = 5.0  # catalogue emergency-stop torque class, x rated: beyond, refused


def check_load(field: str, torque, rated_torque: float, where: str = "") -> str | None:
    """Check an output torque [N*m] (either sign) against the limits of `rated_torque`.

    Raises InputError naming `field` above EMERGENCY_FACTOR x rated; returns a
    warning text above MOMENTARY_FACTOR x rated, else None.
    """
    torque = finite_number(field, torque, where)
    ratio = abs(torque) / rated_torque
    if ratio > EMERGENCY_FACTOR:
        raise InputError(
            field,
            torque,
            f"must be within +-{EMERGENCY_FACTOR:g} x the rated torque "
            f"{rated_torque:g} N*m (emergency-stop class, "
            f"{EMERGENCY_FACTOR * rated_torque:g} N*m): the small-displacement model "
            "does not hold beyond",
            where,
        )
    if ratio > MOMENTARY_FACTOR:
        return (
            f"{field} = {torque:g} N*m is {ratio:.2g} x the rated torque {rated_torque:g} N*m, "
            f"above the momentary maximum class ({MOMENTARY_FACTOR:g} x): the "
            "small-displacement model is stretched; treat the results with care"
        )
    return None


# Speed.  The catalogue gives each frame an allowable output speed (RV-40E: 70 rpm, at a
# rated speed of 15 rpm); beyond it the lubrication, the bearings' drag and the friction
# coefficients the losses use have no rating behind them.  Up to SPEED_FACTOR x that speed
# the model still answers (a warning is returned), beyond it the speed is refused: at
# 1e12 rpm the losses would print 1.9e18 W as a result.
SPEED_FACTOR = 2.0


def check_speed(field: str, value, output_speed: float, design, where: str = "") -> str | None:
    """Check an output speed [rad/s] (either sign) against `design.allowable_output_speed`.

    `value` is what the user gave under `field` (shown in the message, in its own unit);
    `output_speed` is the output speed it stands for.  Raises InputError beyond
    SPEED_FACTOR x the allowable speed; returns a warning text above it, else None.
    """
    from ..base.units import RPM

    output_speed = finite_number(field, output_speed, where)
    allowed = design.allowable_output_speed
    ratio = abs(output_speed) / allowed
    limit_rpm = SPEED_FACTOR * allowed / RPM
    if ratio > SPEED_FACTOR:
        raise InputError(
            field,
            value,
            f"is an output speed of {abs(output_speed) / RPM:.4g} rpm: "
            f"must be within {SPEED_FACTOR:g} x the allowable output speed "
            f"{allowed / RPM:g} rpm of {design.name} ({limit_rpm:g} rpm out, "
            f"{limit_rpm * design.ratio:.6g} rpm in)",
            where,
        )
    if ratio > 1.0:
        return (
            f"{field} = {value!r} is an output speed of {abs(output_speed) / RPM:.4g} rpm, "
            f"{ratio:.2g} x the allowable output speed {allowed / RPM:g} rpm of "
            f"{design.name}: no rating covers it; treat the results with care"
        )
    return None
