"""The quasi-static TE model: TE curves, windup, lost motion and torsional rigidity.

For each input angle the reducer is in static equilibrium under the output
torque (`solver`), with the input held at that angle; the carrier's rotation
away from theta_in / i, plus the windup tau_load x series_compliance of what the
design puts in series with the output (the carrier's pillars; the flange and
housing, calibrated), is the TE of
docs/model.md section 5.  One call evaluates a
whole batch of reducers: arrays are shaped (samples, angles).

Zero load means the no-load limit of docs/model.md section 5, not a singular solve
(`solver.solve_pairs`).  Without bearing clearances it is exact and needs no
iteration: the linear parts take the shape the errors force on them, then the
carrier turns along the zero-energy mechanism mode until the first pin
touches.  Only where that pose leaves a pin in interference, and wherever
bearings have clearance (parts float in it), is an elastic solve needed: the
equilibrium under a probe torque of NO_LOAD_PROBE times the rated torque
(with bearing clearances reached by continuation from 1000 times the probe),
taken back to zero load along its tangent.  The probe resists by default
(zero_side = -1) or drives (+1): the side the limit is approached from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..base.checks import InputError, finite_number, integer
from ..base.units import ARCMIN, rad_to_arcsec
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet, zero_errors
from ..reducer.limits import check_load
from . import metrics
from .equivalent import EquivalentModel, check_angles
from .solver import solve_pairs

# Probe torque of the elastic no-load solves, x rated torque: 0.04 N*m on an RV-40E, pin
# deflections of ~1e-3 um, small enough that its contacts are those of zero load.
NO_LOAD_PROBE = 1e-4
MODELS_KEPT = 4  # equivalent models kept for the next call (`equivalent_model`)
POINTS_PER_PIN_PASS = 8  # default sampling: 8 points per pin-passing period (order z_p*z_c)
LOST_MOTION_FRACTION = 0.03  # catalogue: windup span at +-3 % rated torque
RIGIDITY_FRACTIONS = (0.5, 1.0)  # catalogue: slope between 50 % and 100 %
WINDUP_POSITIONS = 8  # locked input positions of the windup test


def default_points(design: RVDesign) -> int:
    """Points per output revolution that resolve the pin-passing order z_p * z_c."""
    return POINTS_PER_PIN_PASS * design.z_p * design.z_c


@dataclass(frozen=True)
class TECurve:
    """TE of S reducers over one output revolution at one output torque.

    theta_in: (A,) [rad], input angles, evenly over one output revolution;
    theta_out: (S, A) [rad]; te: (S, A) [rad] = theta_out - theta_in / i;
    tau_load: [N*m] (docs/model.md section 2 sign: negative resists); converged: (S,) bool.
    """

    design: RVDesign
    tau_load: float
    theta_in: np.ndarray
    theta_out: np.ndarray
    te: np.ndarray
    converged: np.ndarray
    pin_force_max: np.ndarray | None = field(repr=False)  # (S, A) largest pin force [N]; None: not asked for

    @property
    def points(self) -> int:
        return self.theta_in.size

    @property
    def te_arcsec(self):
        return rad_to_arcsec(self.te)

    @property
    def te_pp_arcsec(self):
        return metrics.te_pp(self.te_arcsec)

    @property
    def rms_arcsec(self):
        return metrics.te_rms(self.te_arcsec)

    @property
    def mean_arcsec(self):
        return metrics.te_mean(self.te_arcsec)

    def spectrum_arcsec(self):
        """(orders (K,), amplitudes (S, K) [arcsec])."""
        return metrics.order_spectrum(self.te_arcsec)


def input_angles(design: RVDesign, points: int) -> np.ndarray:
    """(points,) input angles evenly over one output revolution, end excluded [rad]; points
    whose model would not fit in memory are refused here, before any work."""
    check_angles(design, points)
    return 2.0 * np.pi * design.ratio * np.arange(points) / points


def _checked_errors(design, errors):
    if errors is None:
        return zero_errors(design)
    return errors.check(design)


@dataclass(frozen=True)
class Equilibria:
    """Quasi-static results on a grid of (sample, load, angle), each array (S, T, A).

    te [rad]; tau_in [N*m]: torque the reducer exerts on the input shaft (flange
    convention of docs/model.md section 2, about tau_load / i); pin_force_max [N];
    converged: bool.  tau_in and pin_force_max are None where the forces were not asked for.
    """

    te: np.ndarray
    tau_in: np.ndarray | None
    pin_force_max: np.ndarray | None
    converged: np.ndarray


@lru_cache(maxsize=MODELS_KEPT)
def _equivalent_model(design: RVDesign, theta_in: bytes, flank: int) -> EquivalentModel:
    return EquivalentModel(design, np.frombuffer(theta_in), flank=flank)


def equivalent_model(design: RVDesign, theta_in: np.ndarray, flank: int) -> EquivalentModel:
    """The equivalent model of `design` at the input angles theta_in (A,) [rad] on `flank`,
    kept for the next call with the same three (a study's batches all solve the same angles):
    with it the reduced systems its solves build (`solver.reduced_system`) and the
    error-free reducer's first guess (`solver._nominal_guess`)."""
    return _equivalent_model(design, np.ascontiguousarray(theta_in, dtype=float).tobytes(), flank)


def equilibria(
    design: RVDesign,
    errors: ErrorSet,
    theta_in,
    tau_load,
    progress=None,
    zero_side: int = -1,
    forces: bool = True,
    start_from=None,
) -> Equilibria:
    """Quasi-static equilibrium at every (sample, load, angle) of the grid.

    theta_in: (A,) [rad]; tau_load: (T,) [N*m].  A zero load is the no-load limit
    approached from a resisting load (zero_side = -1, docs/model.md section 5) or from a
    driving one (zero_side = +1).  A load beyond the emergency-stop class (5x rated,
    `limits`) raises InputError; the momentary-class warning is left to the callers.
    forces: False computes no pin and mesh forces (tau_in and pin_force_max None): the TE
    alone, the same to the bit, for the callers that read nothing else (the studies, the
    windup test).
    start_from: (S,) int, optional: for each reducer, another (>= 0) whose solutions start its
    no-load solves with the roller law at the same load and angle (`solver.solve_pairs`,
    law_after), or -1.  Those reducers' solves wait for the ones they start from; one whose own
    start is another's is started as usual.  The equilibria are the same within the Newton
    tolerance: for reducers whose errors are nearly the same (Saltelli's rows that differ
    from another in one group, `tolerance.evaluate.related_rows`), in fewer steps.  Loaded
    pairs are solved as without it, to the bit.
    """
    theta_in = np.atleast_1d(np.asarray(theta_in, dtype=float))
    tau_load = np.atleast_1d(np.asarray(tau_load, dtype=float))
    if tau_load.size:
        check_load("tau_load", tau_load[np.argmax(np.abs(tau_load))], design.rated_torque)
    S, T, A = errors.samples, tau_load.size, theta_in.size
    names = ("te", "tau_in", "pin_force_max") if forces else ("te",)
    out = {name: np.empty((S, T, A)) for name in names}
    ok = np.empty((S, T, A), dtype=bool)
    probe = NO_LOAD_PROBE * design.rated_torque
    zero_flank = -1 if zero_side > 0 else 1
    started = _started_from(start_from, S)
    for flank in (1, -1):
        # flank +1: the sun drives the planets forward (resisting load); -1: the load drives
        mask = (
            (tau_load < 0) | ((tau_load == 0) & (zero_flank == 1))
            if flank == 1
            else (tau_load > 0) | ((tau_load == 0) & (zero_flank == -1))
        )
        loads = np.flatnonzero(mask)
        if loads.size == 0:
            continue
        model = equivalent_model(design, theta_in, flank)
        s, t, a = (g.ravel() for g in np.meshgrid(np.arange(S), loads, np.arange(A), indexing="ij"))
        # the starts serve the no-load solves: the pair of the same load and angle of the
        # reducer started from (pairs are numbered reducer by reducer, load by load)
        later = (started[s] >= 0) & (tau_load[t] == 0.0)
        law_after = None
        if later.any():
            law_after = np.full(s.size, -1)
            law_after[later] = np.flatnonzero(later) + (started[s[later]] - s[later]) * loads.size * A
        eq = solve_pairs(
            model,
            errors,
            s,
            a,
            tau_load[t],
            no_load_probe=probe,
            progress=progress,
            zero_side=zero_side,
            forces=forces,
            law_after=law_after,
        )
        # The output flange: the carrier's crank seats' rotation plus the series windup.
        out["te"][s, t, a] = model.output_angle(eq.q, tau_load[t])
        if forces:
            # Mesh force on the sun acts along -w at the sun's base circle.
            out["tau_in"][s, t, a] = -flank * design.sun_base_radius * eq.mesh_force.sum(axis=1)
            out["pin_force_max"][s, t, a] = eq.pin_force.max(axis=(1, 2))
        ok[s, t, a] = eq.converged
    return Equilibria(out["te"], out.get("tau_in"), out.get("pin_force_max"), ok)


def _started_from(start_from, samples: int) -> np.ndarray:
    """(S,) int: the reducer whose solutions start each reducer's no-load solves, -1 for none;
    a start that is itself started from another is dropped (those are solved first)."""
    if start_from is None:
        return np.full(samples, -1)
    started = np.asarray(start_from, dtype=int).ravel()
    if started.shape != (samples,) or np.any(started >= samples) or np.any(started == np.arange(samples)):
        raise ValueError(f"start_from: must be {samples} indices of other reducers or -1")
    started = np.where(started < 0, -1, started)
    return np.where((started >= 0) & (started[np.maximum(started, 0)] < 0), started, -1)


def equilibrium_te(
    design: RVDesign,
    errors: ErrorSet,
    theta_in,
    tau_load,
    progress=None,
    forces: bool = True,
    start_from=None,
):
    """TE [rad], largest pin force [N] (None without `forces`) and convergence at every
    (sample, load, angle), (S, T, A); start_from as `equilibria`'s."""
    eq = equilibria(design, errors, theta_in, tau_load, progress, forces=forces, start_from=start_from)
    return eq.te, eq.pin_force_max, eq.converged


def te_curve(
    design: RVDesign,
    errors: ErrorSet | None = None,
    tau_load: float = 0.0,
    points: int | None = None,
    progress=None,
    forces: bool = True,
    start_from=None,
) -> TECurve:
    """TE over one output revolution of every reducer in `errors` at output torque `tau_load`.

    tau_load [N*m] follows docs/model.md section 2: a resisting load T is tau_load = -T; 0 gives
    the no-load TE.  points: per output revolution (default `default_points`).  forces:
    False leaves the largest pin force out (pin_force_max None), for callers that read the
    TE alone (the tolerance studies): the same TE to the bit, without the pins' and meshes'
    forces at every pair.  start_from: (S,) int, optional, as `equilibria`'s: each reducer's
    no-load solves started from another's solutions (or -1), the same curves in fewer steps.
    """
    errors = _checked_errors(design, errors)
    tau_load = finite_number("tau_load", tau_load)
    points = default_points(design) if points is None else integer("points", points, 8)
    theta_in = input_angles(design, points)
    te, force, ok = equilibrium_te(
        design, errors, theta_in, [tau_load], progress, forces=forces, start_from=start_from
    )
    theta_out = theta_in / design.ratio + te[:, 0]
    force = None if force is None else force[:, 0]
    return TECurve(design, tau_load, theta_in, theta_out, te[:, 0], ok[:, 0].all(axis=-1), force)


@dataclass(frozen=True)
class Windup:
    """Output windup against output torque with the input locked (catalogue test).

    tau_load: (T,) [N*m]; theta_in: (P,) input positions [rad];
    windup: (S, T, P) [rad], output rotation from its nominal place;
    converged: (S,) bool, the equilibrium converged at every torque and position.
    """

    design: RVDesign
    tau_load: np.ndarray
    theta_in: np.ndarray
    windup: np.ndarray
    converged: np.ndarray

    def lost_motion_arcmin(self):
        """(S,) windup span at +-3 % rated torque, mean over the positions [arcmin]."""
        rated = self.design.rated_torque
        plus = self._at(LOST_MOTION_FRACTION * rated)
        minus = self._at(-LOST_MOTION_FRACTION * rated)
        return (plus - minus).mean(axis=-1) / ARCMIN

    def torsional_rigidity_Nm_per_arcmin(self):
        """(S,) torque / windup slope between 50 % and 100 % rated torque, both senses [N*m/arcmin]."""
        rated = self.design.rated_torque
        lo, hi = (f * rated for f in RIGIDITY_FRACTIONS)
        slope_plus = (self._at(hi) - self._at(lo)) / (hi - lo)
        slope_minus = (self._at(-lo) - self._at(-hi)) / (hi - lo)
        compliance = 0.5 * (slope_plus + slope_minus).mean(axis=-1)  # rad per N*m
        return 1.0 / (compliance / ARCMIN)

    def _at(self, torque):
        k = int(np.argmin(np.abs(self.tau_load - torque)))
        if not np.isclose(self.tau_load[k], torque):
            raise ValueError(f"windup was not computed at {torque} N*m")
        return self.windup[:, k]


def catalogue_torques(design: RVDesign) -> np.ndarray:
    """Output torques [N*m] of the catalogue hysteresis test, from -rated to +rated."""
    fractions = np.array(
        [
            -1.0,
            -0.75,
            -0.5,
            -0.25,
            -LOST_MOTION_FRACTION,
            -0.01,
            0.01,
            LOST_MOTION_FRACTION,
            0.25,
            0.5,
            0.75,
            1.0,
        ]
    )
    return fractions * design.rated_torque


def metric_torques(design: RVDesign) -> np.ndarray:
    """The six torques of `catalogue_torques` that lost motion and torsional rigidity read
    (+-3 %, +-50 % and +-100 % of rated) [N*m]: each torque is a separate equilibrium, so a
    windup test at these alone gives both metrics as the whole test does, at half its solves
    (the studies, the calibration)."""
    positive = np.array(sorted({LOST_MOTION_FRACTION, *RIGIDITY_FRACTIONS}))
    return np.concatenate([-positive[::-1], positive]) * design.rated_torque


def windup_positions(design: RVDesign, positions: int) -> np.ndarray:
    """(positions,) locked input angles of the windup test over one output revolution [rad],
    offset by half a pin pitch of the output so that they do not all sit on a pin."""
    return input_angles(design, positions) + np.pi * design.ratio / (design.z_p * positions)


def windup(
    design: RVDesign, errors: ErrorSet | None = None, tau_load=None, positions: int = WINDUP_POSITIONS
) -> Windup:
    """Windup curves with the input locked at `positions` angles over one output revolution."""
    errors = _checked_errors(design, errors)
    positions = integer("positions", positions, 1)
    tau_load = catalogue_torques(design) if tau_load is None else np.asarray(tau_load, dtype=float)
    if np.any(tau_load == 0.0):
        raise InputError("tau_load", 0.0, "windup needs nonzero torques (the curve has a jump at 0)")
    theta_in = windup_positions(design, positions)
    te, _, ok = equilibrium_te(design, errors, theta_in, tau_load, forces=False)
    return Windup(design, tau_load, theta_in, te, ok.all(axis=(1, 2)))
