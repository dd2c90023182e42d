"""From rows of the unit hypercube to manufacturing errors: each tolerance's statistical model.

The engineering question: a drawing gives a tolerance per error source; which
reducers does a shop that holds those tolerances actually build?  Each
tolerance of docs/model.md section 4 is one *factor* with a statistical model:

- zone (every [E, beta] error): a true-position tolerance is a disc of
  diameter `position_um` around the nominal place, so the offset is drawn
  uniformly over that disc (radius = R*sqrt(u), not R*u, which would crowd the
  centre), or from a circular normal with 3 sigma = R, truncated at R.
- pitch (`pin_pitch`, `disc_pitch`): a cumulative pitch sequence (low orders
  plus tooth-to-tooth scatter, tolerance/sequences.py) whose span F_p is drawn
  from [0, cumulative_um] and whose single pitch deviations are held within
  `single_um` (ISO 1328-1 F_p and f_pt, both exactly).
- band (`pin_radial`, `pin_radius`, `disc_profile`): every tooth's value
  independently within +-band_um/2 (for the disc profile, band_um is F_alpha).
- clearance: a radial internal clearance within [min_um, max_um].

"uniform" or "normal" is chosen per factor; normal means the tolerance is
+-3 sigma and parts beyond it are rejected at inspection (truncated normal),
so every drawn part is within its tolerance.

Every random number a factor uses is one column of the sample row, drawn in
[0, 1) by the Monte Carlo generator or by SALib's Saltelli sampler, and all
columns of a factor form one Sobol group.  The row alone fixes the reducer:
it is reproducible on any machine, and a Sobol group index measures the whole
source (its magnitude, its phases and its per-tooth pattern together), which
is what "the share of TE variance due to the cam eccentricity tolerance"
means.  The alternative, one magnitude column per factor with phases from a
seed, would make phases depend on the row index and break Saltelli's A/B
cross-sampling.  `draw_names` lists the columns of each factor in order.
"""

from __future__ import annotations

import functools

import numpy as np

from rvfmu.core.base.units import UM
from rvfmu.core.reducer.design import RVDesign
from rvfmu.core.reducer.errors import CLEARANCES, PER_TOOTH, PHASED, ErrorSet, error_shapes, zero_errors

from .sequences import LOW_ORDERS, LOW_WEIGHT_MIN, cumulative_pitch_from_draws

SAMPLING_VERSION = 1
"""Bumped whenever the map from a unit row to errors changes: it enters the study hash."""

TRUNCATION_SIGMAS = 3.0  # tolerance = +-3 sigma (process capability 1.0, 99.73 % inside)
DISTRIBUTIONS = ("uniform", "normal")

KIND_OF = {
    **{name: "zone" for name in PHASED},
    "pin_pitch": "pitch",
    "disc_pitch": "pitch",
    "pin_radial": "band",
    "pin_radius": "band",
    "disc_profile": "band",
    **{name: "clearance" for name in CLEARANCES},
}
assert set(KIND_OF) == set(PHASED + PER_TOOTH + CLEARANCES)

KEYS = {  # tolerance keys of each kind in the study file [um], required first
    "zone": ("position_um",),
    "pitch": ("cumulative_um", "single_um"),
    "band": ("band_um",),
    "clearance": ("max_um", "min_um"),
}
REQUIRED = {"zone": 1, "pitch": 1, "band": 1, "clearance": 1}  # how many of KEYS are required
DRAWS = {  # what the columns of one factor are, for the docs and the column names
    "zone": "2 per zone: radius, then phase",
    "pitch": f"per sequence: span, then weight and phase of orders 1-{LOW_ORDERS}, then one "
    "scatter value per tooth",
    "band": "1 per tooth",
    "clearance": "1",
}

_RAYLEIGH_TAIL = float(np.exp(-0.5 * TRUNCATION_SIGMAS**2))  # P(|circular normal| > 3 sigma)


# -- the distributions, each a map from u in [0, 1] ------------------------------------------


@functools.cache
def _normal() -> tuple:
    """(ndtri, P3): scipy.special's inverse normal CDF and the normal CDF at TRUNCATION_SIGMAS,
    on first use (scipy.special takes 0.2 s to import; `rvte te` draws nothing)."""
    from scipy.special import ndtr, ndtri

    return ndtri, float(ndtr(TRUNCATION_SIGMAS))


def centred(u, half_width, distribution):
    """A value in [-half_width, +half_width]: uniform, or normal with 3 sigma = half_width (truncated)."""
    u = np.clip(u, 0.0, 1.0)
    if distribution == "uniform":
        return half_width * (2.0 * u - 1.0)
    ndtri, p3 = _normal()
    return half_width / TRUNCATION_SIGMAS * ndtri((1.0 - p3) + u * (2.0 * p3 - 1.0))


def fraction(u, distribution):
    """A magnitude fraction in [0, 1]: uniform, or |normal| with 3 sigma = 1 (half-normal, truncated)."""
    u = np.clip(u, 0.0, 1.0)
    if distribution == "uniform":
        return u
    ndtri, p3 = _normal()
    return ndtri(0.5 + u * (p3 - 0.5)) / TRUNCATION_SIGMAS


def disc_radius(u, radius, distribution):
    """Distance from the zone centre in [0, radius]: uniform over the disc (radius*sqrt(u)),
    or a circular normal with 3 sigma = radius (Rayleigh, truncated at radius)."""
    u = np.clip(u, 0.0, 1.0)
    if distribution == "uniform":
        return radius * np.sqrt(u)
    sigma = radius / TRUNCATION_SIGMAS
    return sigma * np.sqrt(-2.0 * np.log1p(-u * (1.0 - _RAYLEIGH_TAIL)))


# -- the columns of each factor ---------------------------------------------------------------


def draw_names(factor, design: RVDesign) -> tuple[str, ...]:
    """Names of the unit columns that `factor` draws, in the order they sit in a row."""
    shape = error_shapes(design)[factor.name]
    name = factor.name
    if factor.kind == "zone":
        return tuple(f"{name}{_index(i)}.{part}" for i in np.ndindex(shape) for part in ("radius", "phase"))
    if factor.kind == "pitch":
        names = []
        for lead in np.ndindex(shape[:-1]):
            base = f"{name}{_index(lead)}"
            names.append(f"{base}.span")
            for order in range(1, LOW_ORDERS + 1):
                names += [f"{base}.order{order}_weight", f"{base}.order{order}_phase"]
            names += [f"{base}.scatter[{k}]" for k in range(shape[-1])]
        return tuple(names)
    if factor.kind == "band":
        return tuple(f"{name}{_index(i)}" for i in np.ndindex(shape))
    return (name,)


def _index(index) -> str:
    return "[" + ",".join(str(i) for i in index) + "]" if index else ""


def factor_values(factor, design: RVDesign, U: np.ndarray) -> np.ndarray:
    """The error array of `factor` for S rows of its own columns U (S, n_draws), SI units.

    Returns (S, *error_shapes(design)[factor.name]): complex E*exp(i*beta) [m]
    for zones (phase in the frame docs/model.md section 4 names), real [m] otherwise.
    """
    shape = error_shapes(design)[factor.name]
    S = U.shape[0]
    dist = factor.distribution
    if factor.kind == "zone":
        pairs = U.reshape(S, -1, 2)
        r = disc_radius(pairs[..., 0], 0.5 * factor.position_um, dist)
        return (r * np.exp(2j * np.pi * pairs[..., 1]) * UM).reshape((S,) + shape)
    if factor.kind == "pitch":
        teeth = shape[-1]
        per = 1 + 2 * LOW_ORDERS + teeth
        seq = U.reshape(S, -1, per)
        lead = seq.shape[1]
        flat = seq.reshape(S * lead, per)
        orders = np.arange(1, LOW_ORDERS + 1)
        weight = (LOW_WEIGHT_MIN + (1.0 - LOW_WEIGHT_MIN) * flat[:, 1 : 1 + 2 * LOW_ORDERS : 2]) / orders
        phase = 2.0 * np.pi * flat[:, 2 : 2 + 2 * LOW_ORDERS : 2]
        scatter = centred(flat[:, 1 + 2 * LOW_ORDERS :], TRUNCATION_SIGMAS, "normal")
        span = factor.cumulative_um * fraction(flat[:, 0], dist)
        values = cumulative_pitch_from_draws(span, phase, weight, scatter, factor.single_um)
        return (values * UM).reshape((S,) + shape)
    if factor.kind == "band":
        return (centred(U, 0.5 * factor.band_um, dist) * UM).reshape((S,) + shape)
    mid = 0.5 * (factor.min_um + factor.max_um)
    half = 0.5 * (factor.max_um - factor.min_um)
    return (mid + centred(U[:, 0], half, dist)) * UM


def errors_from_unit(study, X: np.ndarray) -> ErrorSet:
    """The reducers of sample rows X (S, D) in [0, 1): the study's fixed errors plus every factor.

    D is the study's number of columns (`study.columns`); errors of sources with
    no tolerance are those of the study's error file, or zero.
    """
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != len(study.columns):
        raise ValueError(f"sample rows must be shaped (S, {len(study.columns)}), got {X.shape}")
    S = X.shape[0]
    arrays = zero_errors(study.design, S).arrays()
    for factor, start, stop in study.layout:
        arrays[factor.name] = factor_values(factor, study.design, X[:, start:stop])
    if study.base_errors is not None:
        for name, base in study.base_errors.arrays().items():
            arrays[name] = arrays[name] + base[0]
    return ErrorSet(**arrays)
