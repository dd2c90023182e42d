"""The quasi-static TE of one reducer tabulated over input angle and output torque.

A co-simulation master asks for the output angle thousands of times per
simulated second; one contact solve per request would be far too slow, while
the quasi-static TE is a function of two variables only, periodic in the input
angle over one output revolution (i input revolutions).  So it is solved once on
a grid and interpolated: linearly and periodically in the input angle (points
dense enough to resolve the pin-passing order), linearly in the torque, with
separate branches for resisting and driving loads because the TE jumps by the
lost motion where the torque changes sign.  The torque levels reach the
momentary maximum class, 2.5x the rated torque (`limits`); beyond it the map
is extrapolated linearly from its last two levels (the FMU warns there, and
refuses loads beyond the emergency-stop class, 5x).

Friction (docs/model.md section 9) travels with the map: the Coulomb contacts'
friction torque at the output on the same grid (it is proportional to the contact
loads, which the same solves give), and the load-free torque of the bearings' drag,
the churning and the seal tabulated over output speed (DRAG_SPEEDS, linear between them,
linearly extrapolated beyond): the reducer models step both without the
physics (`reducer_model`).  The load-free torque is tabulated at DRAG_TEMPERATURES too
(the lubricant's viscosity, `lubricant.py`, moves the drag and the churning) and read
linearly in the temperature (`TEMap.load_free_row`); the seals' share of it, which breaks
away from rest (`seals.py`), and the design's `static_friction_factor` travel beside it.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from ..base.checks import InputError, integer
from ..laws.lubricant import REFERENCE_TEMPERATURE_C
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet, zero_errors
from ..statics.quasistatic import default_points, input_angles

# Torque levels as fractions of rated torque: dense near zero, where contacts and
# clearances close, sparse at high load, where the windup is nearly linear; up to the
# momentary maximum class (limits.MOMENTARY_FACTOR), beyond which a host is warned.
TORQUE_FRACTIONS = (0.0, 0.005, 0.015, 0.03, 0.06, 0.1, 0.15, 0.25, 0.35, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5)
# Output speeds [rad/s] of the load-free friction torque's table: zero, then evenly in log up
# to 30 rad/s (290 rpm, beyond any RV reducer's rating), and the kinks of Palmgren's drag
# (`friction.drag_kinks`); linear between them, the drag and the churning (which grows as
# the speed squared: 64 points read it within 1 %, 160 within 0.16 %) within 0.2 %.
DRAG_SPEEDS = np.concatenate([[0.0], np.geomspace(1e-4, 30.0, 160)])
# Lubricant temperatures [C] of the load-free table: -20 to 100 C (a robot joint's cold start
# to a hot gearbox), 40 C (the grade's temperature, `lubricant.py`) among them.  Read linearly
# in the temperature: the native FMU's C has no libm (`rvfmu/fmu/native/model.c`), so no log;
# at a fixed speed the drag is not smooth in the temperature anyway (it leaves Palmgren's
# floor where nu n = 160^1.5), so a log law gains little there.  Every 2.5 C, linear reads
# the table's load-free torque within 1.7 % of `friction.load_free_torques` (RV-20E, RV-40E,
# RV-110E, measured at a quarter, half and three quarters of every interval; every 10 C it
# was 24 %, every 5 C 6.3 %): LOAD_FREE_INTERPOLATION_BOUND.
DRAG_TEMPERATURES = tuple(-20.0 + 2.5 * k for k in range(49))
LOAD_FREE_INTERPOLATION_BOUND = 0.02


@dataclass(frozen=True)
class TEMap:
    """TE [rad] and input torque [N*m] on a grid, for one reducer.

    theta_in: (A,) input angles evenly over one output revolution [rad];
    torque_magnitude: (T,) ascending torque magnitudes [N*m], the first zero;
    te: (2, T, A), tau_in: (2, T, A) -- branch 0 resisting loads (tau_load = -magnitude,
    the zero level the no-load limit of docs/model.md section 5), branch 1 driving loads
    (tau_load = +magnitude, the zero level the limit from that side); friction (2, T, A)
    [N*m]: the Coulomb contacts' friction torque at the output (`friction.coulomb_torques`);
    drag_speed (K,) [rad/s] and drag (M, K) [N*m]: the load-free friction torque at the output
    (the bearings' drag, the churning and the seals) at output speeds from 0, ascending, and
    at the lubricant temperatures drag_temperature (M,) [C], ascending (a (K,) drag: one
    row at 40 C); seal [N*m]: the seals' share of it at the output (speed- and
    temperature-free, `seals.py`), which breaks away with the Coulomb friction at
    static_friction_factor [1] x its running torque (`reducer_model.friction_step`).
    """

    ratio: float
    theta_in: np.ndarray
    torque_magnitude: np.ndarray
    te: np.ndarray
    tau_in: np.ndarray
    friction: np.ndarray
    drag_speed: np.ndarray
    drag: np.ndarray
    drag_temperature: np.ndarray | None = None
    seal: float = 0.0
    static_friction_factor: float = 1.0

    @property
    def period(self) -> float:
        """Input angle of one output revolution [rad]."""
        return 2.0 * np.pi * self.ratio

    def evaluate(self, theta_in, tau_load):
        """(te [rad], tau_in [N*m]) at any input angles and output torques (broadcast).

        Torques beyond the grid are extrapolated linearly from its last two levels.
        """
        theta_in, tau_load = np.broadcast_arrays(np.asarray(theta_in, float), np.asarray(tau_load, float))
        A = self.theta_in.size
        position = np.mod(theta_in, self.period) / self.period * A
        i0 = np.floor(position).astype(int) % A
        i1 = (i0 + 1) % A
        wa = position - np.floor(position)
        branch = (tau_load > 0).astype(int)
        magnitude = np.abs(tau_load)
        levels = self.torque_magnitude
        j0 = np.clip(np.searchsorted(levels, magnitude, side="right") - 1, 0, levels.size - 2)
        wt = (magnitude - levels[j0]) / (levels[j0 + 1] - levels[j0])
        results = []
        for table in (self.te, self.tau_in, self.friction):
            below = (1.0 - wa) * table[branch, j0, i0] + wa * table[branch, j0, i1]
            above = (1.0 - wa) * table[branch, j0 + 1, i0] + wa * table[branch, j0 + 1, i1]
            results.append((1.0 - wt) * below + wt * above)
        return tuple(results)

    def load_free_row(self, temperature_C: float = REFERENCE_TEMPERATURE_C) -> list[float]:
        """(K,) the load-free friction torque [N*m] at the table's speeds, the lubricant at
        `temperature_C` [C]: linear between the table's temperatures, at one of them its row
        exactly.  Outside them InputError: the table says nothing there."""
        temperatures = self._drag_temperatures
        if not (math.isfinite(temperature_C) and temperatures[0] <= temperature_C <= temperatures[-1]):
            raise InputError(
                "temperature_C",
                temperature_C,
                f"must be from {temperatures[0]} to {temperatures[-1]} C (the "
                "temperatures of the TE map's load-free table)",
            )
        m = bisect.bisect_right(temperatures, temperature_C) - 1
        rows = self._drag_rows
        if temperatures[m] == temperature_C:
            return list(rows[m])
        w = (temperature_C - temperatures[m]) / (temperatures[m + 1] - temperatures[m])
        return [a + w * (b - a) for a, b in zip(rows[m], rows[m + 1])]

    def load_free(self, temperature_C: float = REFERENCE_TEMPERATURE_C):
        """The load-free friction torque at the output [N*m] as a function of the output speed
        [rad/s] (its magnitude counts), the lubricant at `temperature_C` [C] (`load_free_row`):
        linear in the table, extrapolated from its last two speeds."""
        speeds, values, last = self._drag_speeds, self.load_free_row(temperature_C), self._last_drag

        def load_free_one(omega_out: float) -> float:
            speed = -omega_out if omega_out < 0 else omega_out
            k = bisect.bisect_right(speeds, speed) - 1
            k = last if k > last else k
            w = (speed - speeds[k]) / (speeds[k + 1] - speeds[k])
            return values[k] + w * (values[k + 1] - values[k])

        return load_free_one

    def load_free_one(self, omega_out: float) -> float:
        """The load-free friction torque at the output [N*m] at an output speed [rad/s], the
        lubricant at 40 C (`load_free`)."""
        if self._reference_load_free is None:
            put = object.__setattr__
            put(self, "_reference_load_free", self.load_free(REFERENCE_TEMPERATURE_C))
        return self._reference_load_free(omega_out)

    def evaluate_one(self, theta_in: float, tau_load: float) -> tuple[float, float, float]:
        """`evaluate` for one point, in plain Python: a co-simulation step asks for one.
        (te [rad], tau_in [N*m], the Coulomb friction torque at the output [N*m])."""
        A = self._points
        position = (theta_in % self._period) * self._per_radian
        i0 = int(position)
        wa = position - i0
        i0 %= A
        i1 = i0 + 1 if i0 + 1 < A else 0
        if tau_load > 0:
            magnitude, te_rows, tau_rows, f_rows = (
                tau_load,
                self._te_rows[1],
                self._tau_rows[1],
                self._friction_rows[1],
            )
        else:
            magnitude, te_rows, tau_rows, f_rows = (
                -tau_load,
                self._te_rows[0],
                self._tau_rows[0],
                self._friction_rows[0],
            )
        levels = self._levels
        j0 = bisect.bisect_right(levels, magnitude) - 1
        j0 = 0 if j0 < 0 else (self._last_level if j0 > self._last_level else j0)
        wt = (magnitude - levels[j0]) / (levels[j0 + 1] - levels[j0])
        lo, hi = te_rows[j0], te_rows[j0 + 1]
        a = lo[i0] + wa * (lo[i1] - lo[i0])
        te = a + wt * (hi[i0] + wa * (hi[i1] - hi[i0]) - a)
        lo, hi = tau_rows[j0], tau_rows[j0 + 1]
        a = lo[i0] + wa * (lo[i1] - lo[i0])
        tau_in = a + wt * (hi[i0] + wa * (hi[i1] - hi[i0]) - a)
        lo, hi = f_rows[j0], f_rows[j0 + 1]
        a = lo[i0] + wa * (lo[i1] - lo[i0])
        return te, tau_in, a + wt * (hi[i0] + wa * (hi[i1] - hi[i0]) - a)

    def __post_init__(self):
        put = object.__setattr__
        if np.ndim(self.drag) == 1:  # one row: the load-free torque at 40 C
            put(self, "drag", np.asarray(self.drag, float)[None, :])
            if self.drag_temperature is None:
                put(self, "drag_temperature", np.array([REFERENCE_TEMPERATURE_C]))
        if self.drag_temperature is None:
            put(self, "drag_temperature", np.asarray(DRAG_TEMPERATURES, float))
        put(self, "drag_temperature", np.asarray(self.drag_temperature, float).reshape(-1))
        put(self, "seal", float(self.seal))
        put(self, "static_friction_factor", float(self.static_friction_factor))
        # Python-level views for evaluate_one: list indexing beats numpy for single items.
        put(self, "_points", int(self.theta_in.size))
        put(self, "_period", self.period)
        put(self, "_per_radian", self.theta_in.size / self.period)
        put(self, "_levels", [float(x) for x in self.torque_magnitude])
        put(self, "_last_level", len(self.torque_magnitude) - 2)
        put(self, "_te_rows", [[row.tolist() for row in branch] for branch in self.te])
        put(self, "_tau_rows", [[row.tolist() for row in branch] for branch in self.tau_in])
        put(self, "_friction_rows", [[row.tolist() for row in branch] for branch in self.friction])
        put(self, "_drag_speeds", [float(x) for x in self.drag_speed])
        put(self, "_drag_rows", [[float(x) for x in row] for row in self.drag])
        put(self, "_drag_temperatures", [float(x) for x in self.drag_temperature])
        put(self, "_last_drag", len(self.drag_speed) - 2)
        put(self, "_reference_load_free", None)

    def to_arrays(self) -> dict:
        return {
            "ratio": np.array(self.ratio),
            "theta_in": self.theta_in,
            "torque_magnitude": self.torque_magnitude,
            "te": self.te,
            "tau_in": self.tau_in,
            "friction": self.friction,
            "drag_speed": self.drag_speed,
            "drag": self.drag,
            "drag_temperature": self.drag_temperature,
            "seal": np.array(self.seal),
            "static_friction_factor": np.array(self.static_friction_factor),
        }

    @classmethod
    def from_arrays(cls, arrays) -> "TEMap":
        # a map written before the temperature table: its drag one row at 40 C, no breakaway
        extra = {
            k: (np.asarray(arrays[k], float) if k == "drag_temperature" else float(arrays[k]))
            for k in ("drag_temperature", "seal", "static_friction_factor")
            if k in arrays
        }
        try:
            te_map = cls(
                float(arrays["ratio"]),
                *(
                    np.asarray(arrays[k], float)
                    for k in (
                        "theta_in",
                        "torque_magnitude",
                        "te",
                        "tau_in",
                        "friction",
                        "drag_speed",
                        "drag",
                    )
                ),
                **extra,
            )
        except KeyError as missing:
            raise InputError("te_map", str(missing), "is missing from the TE map file") from None
        A, T = te_map.theta_in.size, te_map.torque_magnitude.size
        for name in ("te", "tau_in", "friction"):
            if getattr(te_map, name).shape != (2, T, A) or T < 2:
                raise InputError(
                    "te_map", f"{name} {getattr(te_map, name).shape}", f"must be shaped (2, {T}, {A})"
                )
        K, M = te_map.drag_speed.size, te_map.drag_temperature.size
        if (
            K < 2
            or te_map.drag.shape != (M, K)
            or te_map.drag_speed[0] != 0.0
            or not np.all(np.diff(te_map.drag_speed) > 0)
            or not np.all(np.diff(te_map.drag_temperature) > 0)
        ):
            raise InputError(
                "te_map",
                f"drag {te_map.drag.shape}",
                "must be one value per drag "
                "temperature and speed, the speeds ascending from 0, the "
                "temperatures ascending",
            )
        if not all(
            np.all(np.isfinite(getattr(te_map, k)))
            for k in (
                "te",
                "tau_in",
                "friction",
                "drag_speed",
                "drag",
                "drag_temperature",
                "seal",
                "static_friction_factor",
            )
        ):
            raise InputError("te_map", "non-finite values", "must be finite")
        return te_map


def build_te_map(
    design: RVDesign,
    errors: ErrorSet | None = None,
    points: int | None = None,
    torque_fractions=TORQUE_FRACTIONS,
    progress=None,
    drag_temperatures=DRAG_TEMPERATURES,
) -> TEMap:
    """Solve the quasi-static model on the grid (one reducer: `errors` of one sample).

    torque_fractions: magnitudes as fractions of the rated torque, ascending from 0,
    solved on both branches; points: per output revolution (default `default_points`);
    drag_temperatures: the lubricant temperatures [C] of the load-free table, ascending.
    """
    from ..losses.friction import RPM, contact_loads, coulomb_torques, drag_kinks, load_free_torques

    errors = zero_errors(design) if errors is None else errors.check(design)
    if errors.samples != 1:
        raise InputError("errors", f"{errors.samples} reducers", "a TE map is for one reducer")
    points = default_points(design) if points is None else integer("points", points, 16)
    theta_in = input_angles(design, points)
    magnitude = np.asarray(torque_fractions, float) * design.rated_torque
    te = np.empty((2, magnitude.size, points))
    tau_in, friction = np.empty_like(te), np.empty_like(te)
    for branch, (sign, side) in enumerate(((-1.0, -1), (1.0, 1))):
        tau = sign * magnitude
        loads = contact_loads(design, errors, tau, theta_in, zero_side=side, progress=progress)
        te[branch] = loads.output_angle[0]
        tau_in[branch] = loads.tau_in[0]
        friction[branch] = sum(
            coulomb_torques(
                design,
                loads.pin_force[0],
                loads.pin_slide_arm,
                loads.cam_force[0],
                loads.crank_seat_force[0],
                loads.main_force[0],
                loads.tau_in[0],
            ).values()
        )
    temperatures = np.asarray(drag_temperatures, float).reshape(-1)
    if temperatures.size < 1 or not np.all(np.diff(temperatures) > 0):
        raise InputError("drag_temperatures", list(temperatures), "must be ascending, at least one")
    # every temperature's kinks: the table is linear in the speed between them at each
    speeds = np.unique(np.concatenate([DRAG_SPEEDS, *(drag_kinks(design, t) for t in temperatures)]))
    drag = np.array([sum(load_free_torques(design, speeds / RPM, t).values()) for t in temperatures])
    free = load_free_torques(design, [0.0])
    seal = float(free["output seal"][0] + free["input seal"][0])
    return TEMap(
        design.ratio,
        theta_in,
        magnitude,
        te,
        tau_in,
        friction,
        speeds,
        drag,
        temperatures,
        seal,
        design.static_friction_factor,
    )
