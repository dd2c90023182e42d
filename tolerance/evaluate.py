"""Evaluating a sample matrix: rows of the unit hypercube -> TE metrics of the reducers they make.

This is the `evaluate(X) -> Y` of SALib's scheme for a tolerance study: one
pure function (no files, no global state) over a batch of rows, so that any
backend (in-process, worker processes, Dask workers) gives the same numbers
for the same batch.  The whole batch goes through the core model at once
(`te_curve` solves every reducer and angle together); the windup test, which
costs more, runs only if the study asks for lost motion or torsional rigidity.

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

import numpy as np

from rvfmu.core import metrics
from rvfmu.core.errors import ErrorSet
from rvfmu.core.friction import operating_losses
from rvfmu.core.quasistatic import te_curve, windup

from .sampling import errors_from_unit

UNITS = {"te_pp": "arcsec", "rms": "arcsec", "order": "arcsec", "lost_motion": "arcmin",
         "torsional_rigidity": "Nm_per_arcmin", "efficiency": "", "no_load_running_torque": "Nm"}
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


def evaluate(study, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Metrics of the reducers of rows X (S, D) in [0, 1).

    Returns Y (S, M) in the units of `metric_column` for the study's metrics,
    in order, and converged (S,) bool (the equilibrium converged at every
    angle).  A reducer whose solve fails outright gives NaN and False.
    """
    X = np.asarray(X, dtype=float)
    errors = errors_from_unit(study, X)
    try:
        return _metrics(study, errors)
    except np.linalg.LinAlgError:
        # One singular reducer must not cost the batch: solve the reducers one by one.
        Y = np.full((X.shape[0], len(study.metrics)), np.nan)
        converged = np.zeros(X.shape[0], dtype=bool)
        for s in range(X.shape[0]):
            try:
                Y[s], converged[s] = (a[0] for a in _metrics(study, errors.take([s])))
            except np.linalg.LinAlgError:
                pass
        return Y, converged


def _metrics(study, errors: ErrorSet):
    design = study.design
    columns = {}
    converged = np.ones(errors.samples, dtype=bool)
    needs_curve = any(metric_kind(m) not in WINDUP_METRICS + FRICTION_METRICS for m in study.metrics)
    if needs_curve:
        curve = te_curve(design, errors, tau_load=-study.load_Nm, points=study.points)
        te = curve.te_arcsec
        converged &= curve.converged
        columns["te_pp"] = metrics.te_pp(te)
        columns["rms"] = metrics.te_rms(te)
    if any(metric_kind(m) in WINDUP_METRICS for m in study.metrics):
        wind = windup(design, errors, positions=study.windup_positions)
        converged &= wind.converged
        columns["lost_motion"] = wind.lost_motion_arcmin()
        columns["torsional_rigidity"] = wind.torsional_rigidity_Nm_per_arcmin()
    if any(metric_kind(m) in FRICTION_METRICS for m in study.metrics):
        efficiency, running, ok = operating_losses(design, errors, study.load_Nm,
                                                   study.output_speed_rpm)
        converged &= ok
        columns["efficiency"], columns["no_load_running_torque"] = efficiency, running
    Y = np.empty((errors.samples, len(study.metrics)))
    for j, name in enumerate(study.metrics):
        if metric_kind(name) == "order":
            Y[:, j] = metrics.amplitude_at_order(te, metric_order(name))
        else:
            Y[:, j] = columns[name]
    return Y, converged
