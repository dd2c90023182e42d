"""Evaluating a sample matrix: rows of the unit hypercube -> TE metrics of the reducers they make.

This is the `evaluate(X) -> Y` of SALib's scheme for a tolerance study: one
pure function (no files, no global state) over a batch of rows, so that any
backend (in-process, worker processes, Dask workers) gives the same numbers
for the same batch.  The whole batch goes through the core model at once
(`te_curve` solves every reducer and angle together); the windup test, which
costs more, runs only if the study asks for lost motion or torsional rigidity, and then at
the six torques those two read (`metric_torques`).

Metrics (study file names, then the column that holds them and its unit):
te_pp -> te_pp_arcsec, rms -> rms_arcsec (about the mean), order_<k> ->
order_<k>_arcsec (amplitude of k cycles per output revolution), lost_motion
-> lost_motion_arcmin, torsional_rigidity -> torsional_rigidity_Nm_per_arcmin
(catalogue definitions, docs/model.md section 5), efficiency -> efficiency (forward, at
the operating load and output speed) and no_load_running_torque ->
no_load_running_torque_Nm (at the input, at the operating output speed; docs/model.md
section 9).  The friction metrics run only if the study asks for them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from rvfmu.core.losses.friction import operating_losses
from rvfmu.core.reducer.errors import ErrorSet
from rvfmu.core.statics import metrics
from rvfmu.core.statics.quasistatic import metric_torques, te_curve, windup

from .error_rows import ErrorRows
from .sampling import errors_from_unit

UNITS = {
    "te_pp": "arcsec",
    "rms": "arcsec",
    "order": "arcsec",
    "lost_motion": "arcmin",
    "torsional_rigidity": "Nm_per_arcmin",
    "efficiency": "",
    "no_load_running_torque": "Nm",
}
LOWER_LIMITED = ("torsional_rigidity", "efficiency")  # a spec on these is a minimum, else a maximum
WINDUP_METRICS = ("lost_motion", "torsional_rigidity")
FRICTION_METRICS = ("efficiency", "no_load_running_torque")
_ORDER = re.compile(r"order_([0-9]+)$")


def metric_kind(name: str) -> str | None:
    """'te_pp', 'rms', 'order', 'lost_motion', 'torsional_rigidity', 'efficiency',
    'no_load_running_torque', or None for an unknown name."""
    if name in UNITS and name != "order":
        return name
    return "order" if _ORDER.match(name) else None


def metric_order(name: str) -> int:
    """k of 'order_<k>'."""
    return int(_ORDER.match(name).group(1))


def metric_column(name: str) -> str:
    """The column (and spec key) of a metric: its name and unit, e.g. 'te_pp_arcsec'; a
    fraction has no unit ('efficiency')."""
    unit = UNITS[metric_kind(name)]
    return f"{name}_{unit}" if unit else name


RELATED_SHARE = 0.5  # of the columns a row must share with an earlier one to start from its solutions
RELATED_WINDOW = 64  # rows back that a row is compared with (Saltelli's A is G + 1 back at most)


def evaluate(study, X) -> tuple[np.ndarray, np.ndarray]:
    """Metrics of the reducers of rows X (S, D) in [0, 1).

    Returns Y (S, M) in the units of `metric_column` for the study's metrics,
    in order, and converged (S,) bool (the equilibrium converged at every
    angle).  A reducer whose solve fails outright gives NaN and False.
    X may instead be `ErrorRows` (reducers by their error vectors): Y is then
    the model's outputs, (S, C) in the columns of `output_columns`.
    """
    if isinstance(X, ErrorRows):
        errors, width, of = X.errors(), sum(map(len, output_columns(study))), _output_values
        related = None
    else:
        X = np.asarray(X, dtype=float)
        errors, width, of = errors_from_unit(study, X), len(study.metrics), _metrics
        related = related_rows(X)
    try:
        return of(study, errors, related)
    except np.linalg.LinAlgError:
        # One singular reducer must not cost the batch: solve the reducers one by one.
        Y = np.full((errors.samples, width), np.nan)
        converged = np.zeros(errors.samples, dtype=bool)
        for s in range(errors.samples):
            try:
                Y[s], converged[s] = (a[0] for a in of(study, errors.take([s])))
            except np.linalg.LinAlgError:
                pass
        return Y, converged


def output_columns(study) -> tuple[tuple, tuple]:
    """(TE columns te_00000 ..., scalar kinds) of the outputs the study's metrics are read
    from (`Outputs`): the curve at the study's points if a metric needs it, the windup pair
    and the friction pair if one of each is asked for."""
    kinds = {metric_kind(m) for m in study.metrics}
    te = (
        tuple(f"te_{k:05d}" for k in range(study.points))
        if kinds - set(WINDUP_METRICS + FRICTION_METRICS)
        else ()
    )
    return te, tuple(k for group in (WINDUP_METRICS, FRICTION_METRICS) if kinds & set(group) for k in group)


def related_rows(X) -> np.ndarray | None:
    """(S,) int: for each row of X (S, D), the row before it in X that has the most columns
    equal to its own, if at least RELATED_SHARE of them, else -1; None where no row has one.

    Saltelli's design (`sobol.sample`) builds each base sample's rows A_B^(i) from its row A
    with the columns of group i taken from B: every one shares all but a group's columns with
    its A, which comes before it.  A reducer with nearly the same errors has nearly the same
    equilibria, so its solutions start those of the other (`quasistatic.te_curve`,
    start_from).  Independent rows (a Monte Carlo sample) share no column."""
    X = np.asarray(X)
    S = X.shape[0]
    if S < 2 or X.ndim != 2 or X.shape[1] == 0:
        return None
    best, shared = np.full(S, -1), np.zeros(S, dtype=int)
    for back in range(1, min(S, RELATED_WINDOW + 1)):  # the row `back` rows before each
        common = (X[back:] == X[:-back]).sum(axis=1)
        closer = (common >= shared[back:]) & (common > 0)  # a tie: the earlier row, a base sample's first
        best[back:][closer], shared[back:][closer] = np.flatnonzero(closer), common[closer]
    related = np.where(shared >= RELATED_SHARE * X.shape[1], best, -1)
    return related if np.any(related >= 0) else None


def _output_values(study, errors: ErrorSet, related=None):
    """(S, C) the outputs in `output_columns`' order, and converged (S,)."""
    out = outputs(study, errors, related)
    parts = ([out.te_arcsec] if out.te_arcsec is not None else []) + [
        out.scalars[k][:, None] for k in output_columns(study)[1]
    ]
    return np.hstack(parts), out.converged


def _metrics(study, errors: ErrorSet, related=None):
    out = outputs(study, errors, related)
    return metrics_from(study, out.te_arcsec, out.scalars), out.converged


@dataclass(frozen=True)
class Outputs:
    """What the model gives for S reducers before the metrics are read off: te_arcsec (S, K)
    the TE curve at the study's K points (None if no metric needs it), scalars {metric
    kind: (S,)} the windup and friction metrics, converged (S,) bool."""

    te_arcsec: np.ndarray | None
    scalars: dict
    converged: np.ndarray


def outputs(study, errors: ErrorSet, related=None) -> Outputs:
    """The TE curve and the scalar metrics of the reducers `errors` (`Outputs`); related (S,)
    int, optional: the reducer whose no-load solutions start each one's (`related_rows`)."""
    design = study.design
    te_columns, kinds = output_columns(study)
    scalars = {}
    te = None
    converged = np.ones(errors.samples, dtype=bool)
    if te_columns:
        # the metrics read the TE alone: no pin and mesh forces at its pairs
        curve = te_curve(
            design, errors, tau_load=-study.load_Nm, points=study.points, forces=False, start_from=related
        )
        te = curve.te_arcsec
        converged &= curve.converged
    if "lost_motion" in kinds:
        wind = windup(design, errors, metric_torques(design), positions=study.windup_positions)
        converged &= wind.converged
        scalars["lost_motion"] = wind.lost_motion_arcmin()
        scalars["torsional_rigidity"] = wind.torsional_rigidity_Nm_per_arcmin()
    if "efficiency" in kinds:
        efficiency, running, ok = operating_losses(
            design, errors, study.load_Nm, study.output_speed_rpm, temperature_C=study.temperature_C
        )
        converged &= ok
        scalars["efficiency"], scalars["no_load_running_torque"] = efficiency, running
    return Outputs(te, scalars, converged)


def metrics_from(study, te_arcsec, scalars: dict) -> np.ndarray:
    """Y (S, M) of the study's metrics from TE curves (S, K) and scalar outputs {kind: (S,)}:
    the same columns as `evaluate`."""
    S = te_arcsec.shape[0] if te_arcsec is not None else len(next(iter(scalars.values())))
    Y = np.empty((S, len(study.metrics)))
    for j, name in enumerate(study.metrics):
        kind = metric_kind(name)
        if kind == "order":
            Y[:, j] = metrics.amplitude_at_order(te_arcsec, metric_order(name))
        elif kind == "te_pp":
            Y[:, j] = metrics.te_pp(te_arcsec)
        elif kind == "rms":
            Y[:, j] = metrics.te_rms(te_arcsec)
        else:
            Y[:, j] = scalars[kind]
    return Y
