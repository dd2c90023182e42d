"""The hysteresis loop of the catalogue's windup test, with the contacts' friction.

The engineering question: the catalogue draws the output angle against the output torque
with the input locked, swept to +rated, back through zero to -rated and back, and reads
three figures off that loop: the lost motion (the angle span of the loop's middle between
+-3 % rated torque), the torsional rigidity (its slope between 50 % and 100 %) and the
hysteresis loss (the loop's width at zero torque).  Without friction the loop is a single
curve; friction opens it.

How: the frictionless windup (`contact_loads` at LEVELS torques from -max to +max, at the
windup test's locked positions) gives the path; between two neighbouring torques every
contact slips by what the equilibria's displacements give it (a pin: the disc's contact
point along the tangent; a bearing: the turn of its inner part against its outer; the
mesh: the carrier against the locked sun) and loses its friction force or moment (those of
`friction`, at the mean of the two torques' loads) times that slip.  The work dW of an
interval over the output's turn across it is the friction torque T_f there, which the
applied torque must exceed on the way up and fall short of on the way down: the loop's
branches are the path shifted by +-T_f (Coulomb friction switches its sense where the
sweep turns).  So the loop's area is the friction work of a full cycle, and its middle is
the frictionless windup: lost motion and rigidity read off the loop are those of
`quasistatic.windup`, the hysteresis loss is what friction adds.  First order in the
coefficients, as the efficiency (docs/model.md section 9).

What is refused rather than printed: a sweep below MIN_SWEEP_FRACTION of rated torque, the
catalogue's lost-motion test torque (3 %: the smallest torque the catalogue reads its loop
at; below it none of its figures is on the loop, and the sweep is of the size of the
bearings' load-free drag, ~0.1 N*m at the output of the presets, which the loop's shifted
branches cannot represent: at +-1e-9 N*m they printed a friction torque of 0.54 N*m, 5e8
times the sweep, from equilibria that did not converge); and any loop that breaks what the
construction needs (`check_loop`): every equilibrium converged, a friction torque no larger
than the swept torque (else the applied torque never overcomes it and the output does not
move), and an area equal to the friction work within AREA_TOLERANCE (they are equal by
construction wherever the mean output angle advances between neighbouring torques; a gap
means it went back, and the shifted path is no loop).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.checks import InputError, finite_number, integer
from ..base.units import ARCMIN
from ..laws.seals import seal_torques
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet
from ..reducer.limits import check_load
from ..statics.equivalent import EquivalentModel
from ..statics.quasistatic import (
    LOST_MOTION_FRACTION,
    NO_LOAD_PROBE,
    RIGIDITY_FRACTIONS,
    WINDUP_POSITIONS,
    windup_positions,
)
from .churning import CHURNING_NAMES
from .friction import contact_loads, coulomb_resistances, drag_moments

LEVELS = 40  # evenly spaced torques on each side of zero, up to the largest
NEAR_ZERO = NO_LOAD_PROBE  # the smallest torque of the sweep, x the largest: the clearance's edge
SMALL_LEVELS = 12  # and these, spaced evenly in log from it to 3 % of the largest
# The smallest sweep, x rated: the catalogue's lost-motion test torque (module docstring).
MIN_SWEEP_FRACTION = LOST_MOTION_FRACTION
# The loop's area against the friction work of the cycle: equal by construction, so only
# round-off may part them (below 1e-12 of the work on RV-40E-121, tests/test_friction.py);
# relative to the work or to the box the loop spans (torque span x angle span), whichever is
# larger, since the shoelace sum's round-off scales with the box (a frictionless loop: 7e-15 J).
AREA_TOLERANCE = 1e-9


@dataclass(frozen=True)
class HysteresisLoop:
    """The windup test's loop, the mean over the locked positions.

    tau_load (T,) [N*m]: the frictionless path's torques, ascending; windup (T,) [rad]: its
    output angle; friction_torque (T-1,) [N*m]: the friction torque of each interval;
    friction_work_J: {contact kind: J} of one full cycle (both sweeps); loop (2(T-1)*2, 2):
    the loop's corners (torque [N*m], angle [rad]), up the loading branch and back down
    the unloading one; the catalogue figures of the loop; warnings: texts for the report
    (a sweep above the momentary maximum torque class, `limits.check_load`).
    """

    design: RVDesign
    tau_load: np.ndarray
    windup: np.ndarray
    friction_torque: np.ndarray
    friction_work_J: dict
    loop: np.ndarray
    lost_motion_arcmin: float
    torsional_rigidity_Nm_per_arcmin: float
    hysteresis_loss_arcmin: float
    converged: bool
    warnings: tuple[str, ...] = ()

    @property
    def area_J(self) -> float:
        """The loop's area by the shoelace formula [J] (torque x angle)."""
        t, a = self.loop[:, 0], self.loop[:, 1]
        return float(0.5 * abs(np.dot(t, np.roll(a, -1)) - np.dot(a, np.roll(t, -1))))


def sweep_torques(design: RVDesign, max_load: float, levels: int = LEVELS) -> np.ndarray:
    """Ascending torques of the sweep [N*m], the same on each side of zero: `levels` evenly
    up to max_load, SMALL_LEVELS evenly in log from NEAR_ZERO to 3 % of it (where the
    clearance closes and friction's torque is of the size of the load), and the catalogue's
    +-3 %, 50 % and 100 % of rated torque where they are within it."""
    side = np.concatenate(
        [
            max_load * np.linspace(0.0, 1.0, levels + 1)[1:],
            max_load * np.geomspace(NEAR_ZERO, LOST_MOTION_FRACTION, SMALL_LEVELS),
        ]
    )
    rated = design.rated_torque
    marks = [f * rated for f in (LOST_MOTION_FRACTION,) + RIGIDITY_FRACTIONS if f * rated <= max_load]
    side = np.unique(np.concatenate([side, marks]))
    return np.concatenate([-side[::-1], side])


def _slips(design: RVDesign, model: EquivalentModel, q: np.ndarray) -> dict:
    """{LOSS_NAMES but the seal: array} the magnitudes of every contact's slip between
    neighbouring torques at each position, q: (T, P, n): each pin's (T-1, P, 2, z_p) [m] and
    the turn [rad] of each needle bearing (T-1, P, 2 n_c; crank i, disc j at 2 i + j), each
    crank in its tapered pair (T-1, P, n_c), the carrier in its main bearings and, the sun
    being locked, against the sun (T-1, P)."""
    d, idx, scale = design, model.index, model.scale
    dq = np.diff(q, axis=0)  # (T-1, P, n)
    dofs = model.pin_dofs  # (2, 3)
    normal = model.pin_rows[..., :2]  # (P, 2, z_p, 2)
    tangent = np.stack([-normal[..., 1], normal[..., 0]], axis=-1)
    move = dq[..., dofs[:, :2]]  # (T-1, P, 2, 2)
    turn = dq[..., dofs[:, 2]] / scale  # (T-1, P, 2)
    carrier = dq[..., idx["carrier_rot"]] / scale
    crank = np.stack([dq[..., idx[f"crank{i}_rot"]] for i in range(d.n_c)], axis=-1) / scale
    return {
        "pins": np.abs(
            (tangent * move[:, :, :, None, :]).sum(axis=-1) + turn[..., None] * model.pin_tangent_lever
        ),
        "crank-disc needle bearings": np.abs(crank[..., :, None] - turn[..., None, :]).reshape(
            crank.shape[:-1] + (-1,)
        ),
        "crank-carrier bearings": np.abs(crank - carrier[..., None]),
        "main bearings": np.abs(carrier),
        "sun-planet meshes": np.abs(carrier),
    }


def hysteresis(
    design: RVDesign,
    errors: ErrorSet | None = None,
    max_load: float | None = None,
    positions: int = WINDUP_POSITIONS,
    levels: int = LEVELS,
    sample: int = 0,
    progress=None,
) -> HysteresisLoop:
    """The windup test's loop swept to +-max_load (default the rated torque) with the input
    locked at `positions` angles over one output revolution, for reducer `sample`."""
    d = design
    max_load = d.rated_torque if max_load is None else finite_number("max_load", max_load)
    if not max_load > 0.0:
        raise InputError(
            "max_load", max_load, "must be a positive torque [N*m]: the loop is swept to +-max_load"
        )
    smallest = MIN_SWEEP_FRACTION * d.rated_torque
    if max_load < smallest:
        raise InputError(
            "max_load",
            max_load,
            f"must be at least {smallest:.4g} N*m, "
            f"{100 * MIN_SWEEP_FRACTION:g} % of the rated torque {d.rated_torque:g} "
            "N*m (the catalogue's lost-motion test torque): a smaller sweep reaches "
            "none of the loop's figures and is of the size of the bearings' "
            "load-free friction, which it cannot measure",
        )
    note = check_load("max_load", max_load, d.rated_torque)
    positions, levels = integer("positions", positions, 1), integer("levels", levels, 2)
    tau = sweep_torques(d, max_load, levels)
    theta_in = windup_positions(d, positions)
    loads = contact_loads(d, errors, tau, theta_in, [sample], progress=progress)
    model = EquivalentModel(d, theta_in)
    angle = loads.output_angle[0]  # (T, P)
    slips = _slips(d, model, loads.q[0])
    mean = lambda x: 0.5 * (x[1:] + x[:-1])  # noqa: E731
    # each contact's friction at the mean of an interval's two loads; a slow test: every
    # bearing's drag at its standstill value
    resist = coulomb_resistances(
        d,
        *(
            mean(a[0])
            for a in (
                loads.pin_force,
                loads.cam_force,
                loads.crank_seat_force,
                loads.main_force,
                loads.tau_in,
            )
        ),
    )
    for name, drag in drag_moments(d, 0.0).items():
        resist[name] = resist[name] + drag
    work = {  # (T-1, P) [J]
        name: (resist[name] * slips[name]).reshape(slips[name].shape[:2] + (-1,)).sum(axis=-1)
        for name in resist
    }
    # the output seal: its running torque, the stated one or its law (`seals.seal_torques`, as
    # `friction.load_free_torques`); the input is locked, its seal does not slip
    work["output seal"] = seal_torques(d)["output seal"] * np.abs(np.diff(angle, axis=0))
    work["input seal"] = np.zeros_like(work["output seal"])
    for name in CHURNING_NAMES:  # the parts barely move in a windup test: no churning
        work[name] = np.zeros_like(work["output seal"])
    dw = sum(work.values()).mean(axis=-1)  # (T-1,)
    theta = angle.mean(axis=-1)  # (T,)
    step = np.diff(theta)
    t_f = np.where(step > 0.0, dw / np.where(step > 0.0, step, 1.0), 0.0)
    up = np.stack(
        [np.column_stack([tau[:-1] + t_f, theta[:-1]]), np.column_stack([tau[1:] + t_f, theta[1:]])], axis=1
    ).reshape(-1, 2)
    down = np.stack(
        [np.column_stack([tau[:-1] - t_f, theta[:-1]]), np.column_stack([tau[1:] - t_f, theta[1:]])], axis=1
    ).reshape(-1, 2)[::-1]
    loop = np.concatenate([up, down])

    def at(torque):
        return float(np.interp(torque, tau, theta))

    rated = d.rated_torque
    lost = (
        (at(LOST_MOTION_FRACTION * rated) - at(-LOST_MOTION_FRACTION * rated)) / ARCMIN
        if LOST_MOTION_FRACTION * rated <= max_load
        else float("nan")
    )
    lo, hi = (f * rated for f in RIGIDITY_FRACTIONS)
    rigidity = float("nan")
    if hi <= max_load:
        compliance = 0.5 * ((at(hi) - at(lo)) + (at(-lo) - at(-hi))) / (hi - lo)
        rigidity = 1.0 / (compliance / ARCMIN)
    result = HysteresisLoop(
        design=d,
        tau_load=tau,
        windup=theta,
        friction_torque=t_f,
        friction_work_J={k: 2.0 * float(v.mean(axis=-1).sum()) for k, v in work.items()},
        loop=loop,
        lost_motion_arcmin=float(lost),
        torsional_rigidity_Nm_per_arcmin=rigidity,
        hysteresis_loss_arcmin=_width_at_zero(tau, theta, t_f) / ARCMIN,
        converged=bool(loads.converged.all()),
        warnings=(note,) if note else (),
    )
    check_loop(result, max_load)
    return result


def check_loop(loop: HysteresisLoop, max_load: float) -> None:
    """Raise an InputError naming max_load [N*m] unless `loop` is one the construction gives
    (module docstring): its friction torque (T-1,) at most max_load, its area the friction
    work of the cycle within AREA_TOLERANCE (of the work or of the loop's box), every
    equilibrium converged."""
    if not loop.converged:
        raise InputError(
            "max_load",
            max_load,
            "the sweep's equilibria did not converge at some "
            "(torque, position) pairs: no loop is read off them (the design or "
            "errors leave a pose the solver cannot settle)",
        )
    top = float(loop.friction_torque.max())
    if top > max_load:
        raise InputError(
            "max_load",
            max_load,
            f"must be above the loop's friction torque "
            f"{top:.4g} N*m: a smaller sweep never overcomes the friction and the "
            "output does not turn",
        )
    work, area = sum(loop.friction_work_J.values()), loop.area_J
    box = float(np.ptp(loop.loop[:, 0]) * np.ptp(loop.loop[:, 1]))
    if abs(area - work) > AREA_TOLERANCE * max(abs(work), box):
        back = int(np.sum(np.diff(loop.windup) <= 0.0))
        raise InputError(
            "max_load",
            max_load,
            f"gives a loop of area {area:.6g} J against a "
            f"friction work of {work:.6g} J a cycle (they must agree within "
            f"{AREA_TOLERANCE:g} of the work or of the loop's box, "
            f"{max(abs(work), box):.4g} J): the mean output angle goes back over {back} "
            "intervals of the sweep, so the loop is not a result",
        )


def _width_at_zero(tau: np.ndarray, theta: np.ndarray, t_f: np.ndarray) -> float:
    """The loop's width in angle at zero applied torque [rad]: unloaded from +max the output
    rests where the frictionless path is at +T_f, from -max where it is at -T_f, T_f the
    friction torque of the interval across zero (each side's path read on its own side
    only, never across the clearance between them, and at its end below its first level)."""
    k = int(np.flatnonzero((tau[:-1] < 0.0) & (tau[1:] > 0.0))[0])
    held = t_f[k]
    upper = np.interp(held, tau[k + 1 :], theta[k + 1 :])
    lower = np.interp(-held, tau[: k + 1], theta[: k + 1])
    return float(upper - lower)
