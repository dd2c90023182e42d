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
loads, which the same solves give), and the load-free torque of the bearings' drag
and the seal tabulated over output speed (DRAG_SPEEDS, linear between them,
linearly extrapolated beyond): the reducer models step both without the
physics (`reducer_model`).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from .checks import InputError, integer
from .design import RVDesign
from .errors import ErrorSet, zero_errors
from .quasistatic import default_points, input_angles

# Torque levels as fractions of rated torque: dense near zero, where contacts and
# clearances close, sparse at high load, where the windup is nearly linear; up to the
# momentary maximum class (limits.MOMENTARY_FACTOR), beyond which a host is warned.
TORQUE_FRACTIONS = (0.0, 0.005, 0.015, 0.03, 0.06, 0.1, 0.15, 0.25, 0.35, 0.5, 0.75, 1.0, 1.25, 1.5,
                    2.0, 2.5)
# Output speeds [rad/s] of the load-free friction torque's table: zero, then evenly in log up
# to 30 rad/s (290 rpm, beyond any RV reducer's rating), and the kinks of Palmgren's drag
# (`friction.drag_kinks`); linear between them, the drag is read within 0.2 %.
DRAG_SPEEDS = np.concatenate([[0.0], np.geomspace(1e-4, 30.0, 64)])


@dataclass(frozen=True)
class TEMap:
    """TE [rad] and input torque [N*m] on a grid, for one reducer.

    theta_in: (A,) input angles evenly over one output revolution [rad];
    torque_magnitude: (T,) ascending torque magnitudes [N*m], the first zero;
    te: (2, T, A), tau_in: (2, T, A) -- branch 0 resisting loads (tau_load = -magnitude,
    the zero level the no-load limit of docs/model.md section 5), branch 1 driving loads
    (tau_load = +magnitude, the zero level the limit from that side); friction (2, T, A)
    [N*m]: the Coulomb contacts' friction torque at the output (`friction.coulomb_torques`);
    drag_speed (K,) [rad/s] and drag (K,) [N*m]: the load-free friction torque at the output
    (the bearings' drag and the seal) at output speeds from 0, ascending.
    """

    ratio: float
    theta_in: np.ndarray
    torque_magnitude: np.ndarray
    te: np.ndarray
    tau_in: np.ndarray
    friction: np.ndarray
    drag_speed: np.ndarray
    drag: np.ndarray

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
            at = lambda j: (1.0 - wa) * table[branch, j, i0] + wa * table[branch, j, i1]
            results.append((1.0 - wt) * at(j0) + wt * at(j0 + 1))
        return tuple(results)

    def load_free_one(self, omega_out: float) -> float:
        """The load-free friction torque at the output [N*m] at an output speed [rad/s] (its
        magnitude counts), linear in the table, extrapolated from its last two speeds."""
        speed = -omega_out if omega_out < 0 else omega_out
        speeds, values = self._drag_speeds, self._drag
        k = bisect.bisect_right(speeds, speed) - 1
        k = self._last_drag if k > self._last_drag else k
        w = (speed - speeds[k]) / (speeds[k + 1] - speeds[k])
        return values[k] + w * (values[k + 1] - values[k])

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
            magnitude, te_rows, tau_rows, f_rows = (tau_load, self._te_rows[1], self._tau_rows[1],
                                                    self._friction_rows[1])
        else:
            magnitude, te_rows, tau_rows, f_rows = (-tau_load, self._te_rows[0], self._tau_rows[0],
                                                    self._friction_rows[0])
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
        # Python-level views for evaluate_one: list indexing beats numpy for single items.
        put = object.__setattr__
        put(self, "_points", int(self.theta_in.size))
        put(self, "_period", self.period)
        put(self, "_per_radian", self.theta_in.size / self.period)
        put(self, "_levels", [float(x) for x in self.torque_magnitude])
        put(self, "_last_level", len(self.torque_magnitude) - 2)
        put(self, "_te_rows", [[row.tolist() for row in branch] for branch in self.te])
        put(self, "_tau_rows", [[row.tolist() for row in branch] for branch in self.tau_in])
        put(self, "_friction_rows", [[row.tolist() for row in branch] for branch in self.friction])
        put(self, "_drag_speeds", [float(x) for x in self.drag_speed])
        put(self, "_drag", [float(x) for x in self.drag])
        put(self, "_last_drag", len(self.drag_speed) - 2)

    def to_arrays(self) -> dict:
        return {"ratio": np.array(self.ratio), "theta_in": self.theta_in,
                "torque_magnitude": self.torque_magnitude, "te": self.te, "tau_in": self.tau_in,
                "friction": self.friction, "drag_speed": self.drag_speed, "drag": self.drag}

    @classmethod
    def from_arrays(cls, arrays) -> "TEMap":
        try:
            te_map = cls(float(arrays["ratio"]), *(np.asarray(arrays[k], float) for k in (
                "theta_in", "torque_magnitude", "te", "tau_in", "friction", "drag_speed", "drag")))
        except KeyError as missing:
            raise InputError("te_map", str(missing), "is missing from the TE map file") from None
        A, T = te_map.theta_in.size, te_map.torque_magnitude.size
        for name in ("te", "tau_in", "friction"):
            if getattr(te_map, name).shape != (2, T, A) or T < 2:
                raise InputError("te_map", f"{name} {getattr(te_map, name).shape}",
                                 f"must be shaped (2, {T}, {A})")
        K = te_map.drag_speed.size
        if K < 2 or te_map.drag.shape != (K,) or te_map.drag_speed[0] != 0.0 \
                or not np.all(np.diff(te_map.drag_speed) > 0):
            raise InputError("te_map", f"drag {te_map.drag.shape}", "must be one value per drag "
                             "speed, the speeds ascending from 0")
        if not all(np.all(np.isfinite(getattr(te_map, k))) for k in (
                "te", "tau_in", "friction", "drag_speed", "drag")):
            raise InputError("te_map", "non-finite values", "must be finite")
        return te_map


def build_te_map(design: RVDesign, errors: ErrorSet | None = None, points: int | None = None,
                 torque_fractions=TORQUE_FRACTIONS, progress=None) -> TEMap:
    """Solve the quasi-static model on the grid (one reducer: `errors` of one sample).

    torque_fractions: magnitudes as fractions of the rated torque, ascending from 0,
    solved on both branches; points: per output revolution (default `default_points`).
    """
    from .friction import RPM, coulomb_torques, contact_loads, drag_kinks, load_free_torques

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
        friction[branch] = sum(coulomb_torques(
            design, loads.pin_force[0], loads.pin_slide_arm, loads.cam_force[0],
            loads.crank_seat_force[0], loads.main_force[0], loads.tau_in[0]).values())
    speeds = np.unique(np.concatenate([DRAG_SPEEDS, drag_kinks(design)]))
    drag = sum(load_free_torques(design, speeds / RPM).values())
    return TEMap(design.ratio, theta_in, magnitude, te, tau_in, friction, speeds, drag)
