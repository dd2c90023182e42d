"""What a tolerance costs, and which number of a tolerance an allocation changes.

The engineering question: a drawing's tolerances can be traded against each
other (tighten the one the TE is sensitive to, open the ones it is not) for
the same yield at a lower price.  That needs a price per tolerance.  The
tolerance-allocation literature models the cost of holding a tolerance t with
a *reciprocal power* law (Chase, Greenwood, Loosli and Hauglund 1990, "Least
cost tolerance allocation for mechanical assemblies with automated process
selection", Manufacturing Review 3(1); Spotts 1973 used its k = 2 case,
Speckhart 1972 the exponential law):

    cost(t) = a + b / t**k          t in um; a, b in cost units; k >= 0

`a` is what the feature costs however loose it is (it adds the same to every
allocation and never moves it), `b` how much tightening costs, and `k` how
steeply the price rises as the tolerance closes: with k = 2 halving a
tolerance quadruples its variable cost.  Chase et al. fit a, b and k to a
process's cost data; that is what a shop should do with its own.

Defaults (`DEFAULT_K`, `REFERENCE_UM`): a = 0, k = 2 (Spotts's reciprocal
square, a steep law: precision grinding gets dear fast), and b = t_ref**k, i.e.
one cost unit at the kind's reference tolerance, the tolerance the seed 002
RV-40E-121 drawing gives that kind.  So by default the drawing is taken to be
cost-balanced, every tolerance costing the same where the drawing puts it.
They are placeholders to be replaced by the shop's own numbers, and the
allocation reports which were used.

Bounds: `tightest_um` and `loosest_um`, the tightest and loosest tolerance the
process can hold (a process cannot hold less; opening further saves nothing
because another, cheaper process would take over).  Default: two ISO 286 IT
grades either side of the current tolerance (each grade is a step of
10**0.2 = 1.585, so x / 2.51 and x * 2.51).

The allocated number of each kind (`ALLOCATED`) is the one the cost and the
bounds speak of; the others of the factor follow it in proportion, so one
scale s = t / t_current describes a new tolerance completely:

- zone: `position_um`;
- band: `band_um`;
- pitch: `cumulative_um` (F_p), `single_um` (f_pt) scaled by the same s;
- clearance: `max_um`, the largest clearance, with `min_um` scaled by the same s,
  so the whole range [min, max] shrinks or opens towards zero (a tighter
  bearing clearance class: smaller and narrower together).

Every kind's errors are proportional to these numbers (tolerance/sampling.py:
the drawn values of a reducer are s times those at s = 1), which is what lets
the allocation describe a reducer by its unit draws and the scales.
"""

from __future__ import annotations

from dataclasses import dataclass

from rvfmu.core.base.checks import InputError, finite_number

ALLOCATED = {"zone": "position_um", "band": "band_um", "pitch": "cumulative_um", "clearance": "max_um"}
SCALED_WITH = {"zone": (), "band": (), "pitch": ("single_um",), "clearance": ("min_um",)}
KEYS = ("a", "b", "k", "tightest_um", "loosest_um")

DEFAULT_A = 0.0  # a fixed cost never moves an allocation
DEFAULT_K = 2.0  # Spotts 1973: reciprocal square
REFERENCE_UM = {  # one cost unit at the tolerance seed 002 gives the kind (RV-40E-121)
    "zone": 8.0,  # crank, hole and carrier positions: 7-9 um
    "band": 5.0,  # pin radial band 5 um (disc profile 8 um)
    "pitch": 8.0,  # pin F_p 8 um (disc F_p 6 um)
    "clearance": 10.0,  # illustrative bearing clearance (docs/model.md section 4)
}
BOUND_STEP = 10.0**0.4  # default bounds: two ISO 286 IT grades (x 1.585 each) either side


@dataclass(frozen=True)
class CostModel:
    """cost(t) = a + b / t**k for the allocated tolerance t [um], held within [tightest_um, loosest_um].

    tightest_um / loosest_um None: the defaults around the current tolerance
    (`resolved`).
    """

    a: float = DEFAULT_A
    b: float | None = None
    k: float = DEFAULT_K
    tightest_um: float | None = None
    loosest_um: float | None = None

    def cost(self, t_um):
        """Cost of tolerance(s) t_um [um] (same shape), in cost units."""
        return self.a + self.b / t_um**self.k

    def slope(self, t_um):
        """d cost / d ln t = -k b / t**k: what opening the tolerance by 1 % saves, x 100."""
        return -self.k * self.b / t_um**self.k


def cost_model(values, field: str, where: str = "") -> CostModel:
    """A CostModel from a [tolerances.NAME.cost] table, each key checked; `field` names the table."""
    if not isinstance(values, dict):
        raise InputError(field, values, f"must be a table with some of {', '.join(KEYS)}", where)
    for key in values:
        if key not in KEYS:
            raise InputError(
                f"{field}.{key}",
                values[key],
                f"is not a key of the cost table; known keys: {', '.join(KEYS)}",
                where,
            )
    number = {key: finite_number(f"{field}.{key}", values[key], where) for key in values}
    if number.get("k", DEFAULT_K) < 0:
        raise InputError(
            f"{field}.k",
            number["k"],
            "the exponent must be >= 0 (cost = a + b / t^k falls as the tolerance t opens)",
            where,
        )
    if number.get("b", 0.0) < 0:
        raise InputError(
            f"{field}.b", number["b"], "must be >= 0 (a tighter tolerance never costs less)", where
        )
    for key in ("tightest_um", "loosest_um"):
        if key in number and number[key] <= 0:
            raise InputError(
                f"{field}.{key}",
                number[key],
                "must be > 0 um (the cost of a zero tolerance is infinite)",
                where,
            )
    if "tightest_um" in number and "loosest_um" in number and number["tightest_um"] > number["loosest_um"]:
        raise InputError(
            f"{field}.tightest_um",
            number["tightest_um"],
            f"must be <= loosest_um = {number['loosest_um']:g}",
            where,
        )
    return CostModel(**number)


def current_um(factor) -> float:
    """The factor's allocated tolerance as the study gives it [um]."""
    return float(getattr(factor, ALLOCATED[factor.kind]))


def check_bounds(factor, field: str) -> None:
    """Raise if the factor's own cost bounds exclude its current tolerance (field: its cost table)."""
    model, current = factor.cost, current_um(factor)
    key = ALLOCATED[factor.kind]
    if model.tightest_um is not None and current < model.tightest_um:
        raise InputError(
            f"{field}.tightest_um",
            model.tightest_um,
            f"must be <= the current tolerance {key} = {current:g} um (the bounds must include it)",
        )
    if model.loosest_um is not None and current > model.loosest_um:
        raise InputError(
            f"{field}.loosest_um",
            model.loosest_um,
            f"must be >= the current tolerance {key} = {current:g} um (the bounds must include it)",
        )


def resolved(factor) -> CostModel:
    """The factor's cost model with every default filled in (b from k and the kind, the bounds).

    A factor with no cost table gets the defaults of its kind.  Default bounds
    are BOUND_STEP either side of the current tolerance, limited by an explicit
    bound on the other side.
    """
    model = factor.cost or CostModel()
    current = current_um(factor)
    k = model.k
    b = REFERENCE_UM[factor.kind] ** k if model.b is None else model.b
    tightest = model.tightest_um if model.tightest_um is not None else current / BOUND_STEP
    loosest = model.loosest_um if model.loosest_um is not None else current * BOUND_STEP
    if model.tightest_um is None and model.loosest_um is not None:
        tightest = min(tightest, loosest)
    if model.loosest_um is None and model.tightest_um is not None:
        loosest = max(loosest, tightest)
    return CostModel(a=model.a, b=b, k=k, tightest_um=tightest, loosest_um=loosest)


def scaled_values(factor, scale: float) -> dict:
    """The factor's tolerance keys at `scale` times the current allocated tolerance [um].

    The allocated key and the keys that follow it (`SCALED_WITH`) are scaled;
    a single_um that is not given stays not given.
    """
    values = {}
    for key in (ALLOCATED[factor.kind], *SCALED_WITH[factor.kind]):
        value = getattr(factor, key)
        if value is not None:
            values[key] = float(value) * scale
    return values


def file_values(model: CostModel) -> dict:
    """The [tolerances.NAME.cost] table of a resolved model, as a study file writes it."""
    return {key: getattr(model, key) for key in KEYS}


__all__ = [
    "ALLOCATED",
    "SCALED_WITH",
    "CostModel",
    "cost_model",
    "current_um",
    "check_bounds",
    "resolved",
    "scaled_values",
    "file_values",
    "REFERENCE_UM",
    "DEFAULT_K",
    "BOUND_STEP",
]
