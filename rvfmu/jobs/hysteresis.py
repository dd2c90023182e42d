"""`rvte hysteresis`: the catalogue's hysteresis loop of a reducer, with its contacts' friction.

The job over `rvfmu.core.losses.hysteresis`: the windup test swept to +-max load and back with the
input locked, the lost motion, torsional rigidity and hysteresis loss read off the loop,
the friction work of a cycle by contact; a table for people, JSON for scripts and the
loop as a figure.

The loop's width: friction shifts the loading branch to higher torques and the unloading one
to lower, by the friction torque T_f (up to 2.2 N*m at the output of RV-40E-121, 0.5 % of
rated); drawn over +-rated the two branches are one line.  What shows friction is the angle
between them at the same applied torque: theta_unloading(T) - theta_loading(T), read off the loop's
corners (`branch_angle`, `loop_width`); the frictionless path's slope times 2 T_f away from
zero, the clearance plus what friction adds at zero (there it is the hysteresis loss).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.base.checks import InputError
from ..core.base.units import ARCMIN
from ..core.losses.friction import LOSS_NAMES
from ..core.losses.hysteresis import HysteresisLoop, sweep_torques
from ..core.losses.hysteresis import hysteresis as hysteresis_loop
from ..core.statics.quasistatic import WINDUP_POSITIONS
from ..outputs import figure_file
from ..progress import counter as progress_counter


@dataclass(frozen=True)
class HysteresisReport:
    """The hysteresis loop of one reducer (`core.hysteresis.HysteresisLoop`)."""

    loop: HysteresisLoop

    def summary(self) -> str:
        """The table `rvte hysteresis` prints: design and sweep, lost motion [arcmin],
        torsional rigidity [N*m/arcmin], hysteresis loss [arcmin], friction torque [N*m], the
        loop's width [arcsec] at zero and at half the sweep (within the branches' reach), the
        friction work of a cycle [J] by contact and the warnings."""
        h, d = self.loop, self.loop.design
        top = h.tau_load[-1]
        total = sum(h.friction_work_J.values())
        # the width loaded, at half the sweep (the branches' reach ends T_f short of its end)
        half = min(0.5 * top, self.width_torques_Nm[-1])
        lines = [
            f"design             {d.name} (ratio {d.ratio:g}, rated torque {d.rated_torque:g} N*m)",
            f"loop               input locked, output swept to +-{top:g} N*m and back "
            f"({h.tau_load.size} torques, mean over the locked positions)",
            f"lost motion        {_figure(h.lost_motion_arcmin, '.3f', 'arcmin')} "
            "(the loop's middle at +-3 % rated)",
            f"torsional rigidity {_figure(h.torsional_rigidity_Nm_per_arcmin, '.1f', 'N*m/arcmin')} "
            "(the loop's middle, 50-100 % rated)",
            f"hysteresis loss    {h.hysteresis_loss_arcmin:.3f} arcmin (the loop's width at zero torque)",
            f"friction torque    {h.friction_torque.max():.3g} N*m at most at the output "
            f"(the loop's half-width in torque)",
            f"loop width         {60 * self.width_at_zero_arcmin:.3g} arcsec at zero torque, "
            f"{60 * self.width_arcmin(half)[0]:.3g} arcsec at {half:.4g} N*m (the unloading "
            "branch's angle less the loading one's)",
            f"friction work      {total:.4g} J a cycle (the loop's area {h.area_J:.4g} J):",
        ]
        for name in LOSS_NAMES:
            share = h.friction_work_J[name] / total if total > 0 else 0.0
            lines.append(f"  {name:<30} {h.friction_work_J[name]:>10.4g} J  {100 * share:>5.1f} %")
        # a loop that did not converge is refused (`core.hysteresis.check_loop`): no line here
        lines += [f"warning            {text}" for text in h.warnings]
        return "\n".join(lines)

    @property
    def width_torques_Nm(self) -> np.ndarray:
        """(K,) [N*m] ascending: zero and the corners of either branch within the torques both
        reach (`width_torques`)."""
        return width_torques(self.loop.loop)

    def width_arcmin(self, torques=None) -> np.ndarray:
        """(K,) [arcmin] the loop's width at output torques (K,) [N*m] (default
        `width_torques_Nm`): the unloading branch's angle less the loading one's."""
        torques = self.width_torques_Nm if torques is None else torques
        return loop_width(self.loop.loop, torques) / ARCMIN

    @property
    def width_at_zero_arcmin(self) -> float:
        """[arcmin] the width at zero torque: the clearance crossed plus what friction adds."""
        return float(self.width_arcmin(0.0)[0])

    @property
    def width_max_arcmin(self) -> float:
        """[arcmin] the largest width over the torques both branches reach."""
        return float(self.width_arcmin().max())

    @property
    def width_max_torque_Nm(self) -> float:
        """[N*m] the torque of the largest width (the first, if several)."""
        return float(self.width_torques_Nm[np.argmax(self.width_arcmin())])

    def to_json(self) -> dict:
        """The loop for scripts (`--json`): the figures of `summary` (a figure the sweep does
        not reach as null), friction_work_J by contact and the loop's points as
        {torque_Nm, angle_arcmin}, up the loading branch and back down the unloading one."""
        h = self.loop
        return {
            "design": h.design.name,
            "lost_motion_arcmin": _number(h.lost_motion_arcmin),
            "torsional_rigidity_Nm_per_arcmin": _number(h.torsional_rigidity_Nm_per_arcmin),
            "hysteresis_loss_arcmin": h.hysteresis_loss_arcmin,
            "width_at_zero_arcmin": self.width_at_zero_arcmin,
            "width_max_arcmin": self.width_max_arcmin,
            "width_max_torque_Nm": self.width_max_torque_Nm,
            "friction_work_J": h.friction_work_J,
            "loop": [{"torque_Nm": float(t), "angle_arcmin": float(a / ARCMIN)} for t, a in h.loop],
            "converged": h.converged,
            "warnings": list(h.warnings),
        }


def _branches(loop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The loop (2 N, 2) (torque [N*m], angle [rad]; up the loading branch, back down the
    unloading one: `core.hysteresis.HysteresisLoop.loop`) as its two branches (N, 2), each in
    ascending angle."""
    half = loop.shape[0] // 2
    return loop[:half], loop[half:][::-1]


def _loading_envelope(branch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A loading branch (N, 2) in ascending angle as the torque the output needs to have
    reached each angle, (M,) [N*m] non-decreasing, and those angles (M,) [rad].

    Why: the friction torque changes between the sweep's intervals, so the branch's torque
    steps back at a corner where it falls (by up to 0.06 N*m on RV-40E-121); under a rising
    torque the output then goes on turning at once, to where the branch's torque rises past
    the step again.  So the torque needed is the running maximum of the branch's, with the
    point added where a segment climbs past that maximum."""
    x, y = branch[:, 0], branch[:, 1]
    need = np.maximum.accumulate(x)
    # segment j -> j+1 climbing from below the running maximum to above it
    cross = np.flatnonzero((x[:-1] < need[:-1]) & (x[1:] > need[:-1]))
    f = (need[cross] - x[cross]) / (x[cross + 1] - x[cross])
    at = y[cross] + f * (y[cross + 1] - y[cross])
    return np.insert(need, cross + 1, need[cross]), np.insert(y, cross + 1, at)


def branch_angle(branch: np.ndarray, torques: np.ndarray, loading: bool) -> np.ndarray:
    """The output angle (K,) [rad] of a branch (N, 2) (torque [N*m], angle [rad], ascending
    angle) at torques (K,) [N*m] within its reach: loading, the furthest angle whose torque
    the output has reached; unloading, by the same rule with torque and angle reversed (the
    torque falls from the top: the output stays at the smallest angle it has come back to)."""
    if not loading:
        return -branch_angle(-branch[::-1], -np.asarray(torques), True)
    need, angle = _loading_envelope(branch)
    i = np.clip(np.searchsorted(need, torques, side="right"), 1, need.size - 1)
    lo, hi = need[i - 1], need[i]
    # need[i] > torque >= need[i - 1] inside the reach; at its top end the last angle
    f = np.where(hi > lo, (torques - lo) / np.where(hi > lo, hi - lo, 1.0), 1.0)
    return angle[i - 1] + np.clip(f, 0.0, 1.0) * (angle[i] - angle[i - 1])


def width_reach(loop: np.ndarray) -> tuple[float, float]:
    """The torques [N*m] both branches of a loop (2 N, 2) reach: from the loading branch's
    start to the unloading branch's start (a loop swept to +-max: -max + T_f to max - T_f)."""
    up, down = _branches(loop)
    return (
        max(float(up[0, 0]), float(np.minimum.accumulate(down[::-1, 0])[-1])),
        min(float(np.maximum.accumulate(up[:, 0])[-1]), float(down[-1, 0])),
    )


def width_torques(loop: np.ndarray) -> np.ndarray:
    """(K,) [N*m] ascending: zero, the ends of `width_reach` and every corner torque of either
    branch of a loop (2 N, 2) within it: the width is linear in torque between them (a branch
    may step in angle at one, where its torque stepped back: `_loading_envelope`), so the
    largest width over them is the largest the loop has, steps aside."""
    lo, hi = width_reach(loop)
    up, down = _branches(loop)
    corners = np.concatenate([_loading_envelope(up)[0], -_loading_envelope(-down[::-1])[0], [0.0, lo, hi]])
    return np.unique(corners[(corners >= lo) & (corners <= hi)])


def loop_width(loop: np.ndarray, torques) -> np.ndarray:
    """(K,) [rad] the width of a loop (2 N, 2) at output torques (K,) [N*m]: the unloading
    branch's angle less the loading branch's (`branch_angle`), each piecewise linear between
    its corners.  torques outside `width_reach` raise InputError: a branch has no angle there."""
    try:
        values = np.atleast_1d(np.asarray(torques, dtype=float))
    except (TypeError, ValueError):
        raise InputError("torques", torques, "must be output torques [N*m], numbers") from None
    if values.ndim != 1 or not np.all(np.isfinite(values)):
        raise InputError("torques", torques, "must be a list of finite output torques [N*m]")
    lo, hi = width_reach(loop)
    outside = values[(values < lo) | (values > hi)]
    if outside.size:
        raise InputError(
            "torques",
            float(outside[0]),
            f"must be within {lo:.6g} to {hi:.6g} N*m, the torques both branches of the loop reach",
        )
    up, down = _branches(loop)
    return branch_angle(down, values, False) - branch_angle(up, values, True)


def _figure(value: float, spec: str, unit: str) -> str:
    """A catalogue figure, or why there is none: the sweep stops short of its torques."""
    return "not reached by the sweep" if math.isnan(value) else f"{value:{spec}} {unit}"


def _number(value: float) -> float | None:
    return None if math.isnan(value) else value


def hysteresis(
    design, errors=None, max_load: float | None = None, plot_path: str | Path | None = None, progress=None
) -> HysteresisReport:
    """The windup test's hysteresis loop of one reducer.

    design: preset name, design file or RVDesign; errors: error file or ErrorSet (default
    none); max_load [N*m]: the sweep's end (default the rated torque; at least 3 % of it,
    the catalogue's lost-motion test torque); plot_path: the loop as a figure (checked before
    any work); progress(total, done): optional, called as the equilibria are solved.  A loop
    that did not converge, or whose friction torque exceeds the sweep or whose area is not
    its friction work, raises InputError (`rvfmu.core.losses.hysteresis.check_loop`).
    """
    from .common import resolve_design, resolve_errors

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    design = resolve_design(design)
    errors = resolve_errors(design, errors)
    top = design.rated_torque if max_load is None else max_load
    total = (
        sweep_torques(design, top).size * WINDUP_POSITIONS
        if isinstance(top, (int, float)) and math.isfinite(top) and top > 0
        else 0
    )
    report = HysteresisReport(
        hysteresis_loop(design, errors, max_load, progress=progress_counter(total, progress))
    )
    if plot_path is not None:
        from ..plots import plot_hysteresis

        plot_hysteresis(report, plot_path)
    return report
