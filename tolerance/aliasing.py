"""Does sampling the TE below the pin-passing order change a study's answers?  Measured, not assumed.

The TE of an RV reducer has content up to the pin-passing order z_p*z_c
(1560 for 40 pins): the load moves from pin to pin.  A study that samples
fewer than 2*z_p*z_c points per revolution (720 is common: 17x cheaper) folds
that ripple onto lower orders.  Whether it matters depends on the reducer
and the operating point: at no load the first contact rarely ripples at the
pin-passing order, under load it does.  So a study that aliases recomputes a
few of its own reducers at full resolution (`CHECK_ROWS`, 8 points per
pin-passing period) and reports, for every TE metric, the largest change,
and for every spec line the share of reducers that lie closer to the limit
than that change: the most the yield can move through aliasing.

The full-resolution values are kept in the job's folder of the store
(`aliasing_check.json`, keyed by the hash of the rows), so a study run again
does not recompute them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rvfmu.core.statics.quasistatic import default_points

from .evaluate import FRICTION_METRICS, WINDUP_METRICS, evaluate, metric_column, metric_kind
from .store import rows_hash

CHECK_ROWS = 16  # reducers recomputed: 16 at 12480 points cost about 4 batches of 64 at 720
FILE = "aliasing_check.json"


def aliases(study) -> bool:
    """True if the study's points per revolution do not resolve the pin-passing order."""
    return study.points // 2 <= study.design.z_p * study.design.z_c


@dataclass(frozen=True)
class AliasingCheck:
    """TE metrics of `rows` reducers at the study's points and at `full_points`.

    columns: the TE metric columns checked; coarse, full: (rows, C) values;
    yield_at_risk: {spec label: share of all analysed reducers within the
    largest change of that limit}, a bound on how far aliasing moves the yield.
    """

    points: int
    full_points: int
    columns: tuple[str, ...]
    coarse: np.ndarray
    full: np.ndarray
    yield_at_risk: dict

    @property
    def rows(self) -> int:
        return self.coarse.shape[0]

    def max_change(self) -> np.ndarray:
        """(C,) largest |full - coarse| over the rows, in the column's unit."""
        return np.max(np.abs(self.full - self.coarse), axis=0)

    def max_relative_change(self) -> np.ndarray:
        """(C,) largest |full - coarse| / |full| over the rows."""
        scale = np.maximum(np.abs(self.full), 1e-12)
        return np.max(np.abs(self.full - self.coarse) / scale, axis=0)

    def lines(self) -> list[str]:
        """The check for the printed summary: the largest change per column, in arcsec and
        %, then the yield at risk per spec line."""
        changes = ", ".join(
            f"{c} by at most {d:.3g} arcsec ({100 * r:.2g} %)"
            for c, d, r in zip(self.columns, self.max_change(), self.max_relative_change())
        )
        out = [
            f"aliasing check: {self.points} points per revolution do not resolve the "
            f"pin-passing order; {self.rows} reducers of this study recomputed at "
            f"{self.full_points} points change {changes}"
        ]
        for label, share in self.yield_at_risk.items():
            out.append(
                f"  yield {label}: {100 * share:.2f} % of the reducers lie within that "
                "change of the limit, so aliasing moves the yield by at most that much"
            )
        return out

    def to_json(self) -> dict:
        """The check for the JSON summary: points, rows, and the largest absolute and relative
        change and the yield at risk, by column or spec label."""
        return {
            "points": self.points,
            "full_points": self.full_points,
            "rows": self.rows,
            "columns": list(self.columns),
            "max_change": dict(zip(self.columns, self.max_change().tolist())),
            "max_relative_change": dict(zip(self.columns, self.max_relative_change().tolist())),
            "yield_at_risk": self.yield_at_risk,
        }


def check(
    study, X: np.ndarray, Y: np.ndarray, folder: Path | None = None, Y_all=None, spec=()
) -> AliasingCheck | None:
    """Recompute the reducers of rows X (R, D), whose study metrics are Y (R, M), at full resolution.

    None if the study does not alias or has no TE metric.  Y_all (N, M): the
    metrics of every analysed reducer, to bound the yield change of each
    `spec` limit.  The full-resolution values are cached in `folder` (the job's folder).
    """
    if not aliases(study):
        return None
    # the windup test and the friction metrics do not sample the TE curve's points
    picked = [
        j for j, m in enumerate(study.metrics) if metric_kind(m) not in WINDUP_METRICS + FRICTION_METRICS
    ]
    if not picked:
        return None
    metrics = tuple(study.metrics[j] for j in picked)
    columns = tuple(metric_column(m) for m in metrics)
    full_points = default_points(study.design)
    X = np.asarray(X, dtype=float)
    key = {"rows_sha256": rows_hash(X), "full_points": full_points, "columns": list(columns)}
    full = _cached(folder, key)
    if full is None:
        fine = replace(study, points=full_points, metrics=metrics, spec=())
        full, _ = evaluate(fine, X)
        if folder is not None:
            (Path(folder) / FILE).write_text(json.dumps({**key, "values": full.tolist()}))
    coarse = np.asarray(Y, dtype=float)[:, picked]
    result = AliasingCheck(study.points, full_points, columns, coarse, full, {})
    at_risk = {}
    if Y_all is not None:
        change = dict(zip(columns, result.max_change()))
        for limit in spec:
            if limit.column in change:
                values = Y_all[:, study.metric_columns.index(limit.column)]
                values = values[np.isfinite(values)]
                near = np.abs(values - limit.limit) <= change[limit.column]
                at_risk[str(limit)] = float(near.mean()) if values.size else 0.0
    return replace(result, yield_at_risk=at_risk)


def _cached(folder, key) -> np.ndarray | None:
    if folder is None:
        return None
    path = Path(folder) / FILE
    try:
        stored = json.loads(path.read_text())
        if all(stored.get(k) == v for k, v in key.items()):
            return np.asarray(stored["values"], dtype=float)
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return None
