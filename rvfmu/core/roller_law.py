"""A roller bearing's radial law as the solvers use it: energy, force and stiffness of the
deflection of its centre, with its clearance and a linear spring in series.

`compliance.bearing_radial_force` gives the law for a load; a solver needs it the other way
round and many times per iteration: the energy of a deflection, its derivative (the force)
and its second derivative (the tangent stiffness), consistent with each other to round-off
so that the Newton iteration and its line search see one convex function.

A bearing of Z rollers, each carrying Q = K_n delta^n (Palmgren, n = 10/9), its centre
deflected by s with free play c (half the radial clearance), the rollers spread over the
circumference (the mean over cage positions, as `compliance.bearing_radial_force`):

    energy     Phi(s) = a s^(n+1) E(rho) / (n+1),          a = Z K_n / (2 pi),  rho = c / s
    force      F(s)   = a s^n (E - rho E' / (n+1))
    stiffness  F'(s)  = a s^(n-1) (n E - 2 n rho E' / (n+1) + rho^2 E'' / (n+1))
    E(rho) = 2 * integral over 0 < psi < acos(rho) of (cos psi - rho)^(n+1)

and nothing for s <= c.  E and its derivative E' = -2 (n+1) * integral of (cos psi - rho)^n
are tabulated once on rho in [0, 1] and interpolated by cubic Hermite polynomials: the
force is the exact derivative of the interpolated energy.  A tapered roller pair at
contact angle alpha (to the radial plane) has the same form with a = 2 Z K_n cos^(n+1)
alpha / (2 pi).

A linear spring of compliance C in series (the crankshaft bent and sheared at its cams
behind the needle bearing) makes the element's energy that of the pair at equilibrium: the bearing
deflects u where u + C F(u) = s (Newton's method from u = s, monotone because F is convex),
Psi(s) = Phi(u) + C F(u)^2 / 2, force F(u), stiffness F'(u) / (1 + C F'(u)).  Newton's
steps shrink quadratically, each about K times the square of the last, K = step / last^2;
it stops when the step it would take next, K step^2, is below SERIES_TOLERANCE s (or a
step itself is): the same u to round-off (a few 1e-15 s) as iterating until a step is
below it, one solve of F fewer in most bearings, and none of the 60 of a solve whose
steps stall at round-off.

The functions here are compiled by numba where it is installed (`compiled.kernel`) and are
called one bearing at a time; `radial_law` evaluates arrays of bearings in numpy.
"""

from __future__ import annotations

import math

import numpy as np

from .compliance import LINE_EXPONENT
from .compiled import kernel

N = LINE_EXPONENT
INTERVALS = 1024                  # of the rho table
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)
SERIES_ITERATIONS = 60
SERIES_TOLERANCE = 1e-15          # of s: u's step, taken or foreseen


def _table():
    """(E, E') at rho = i / INTERVALS, i = 0 .. INTERVALS."""
    rho = np.linspace(0.0, 1.0, INTERVALS + 1)
    e, de = np.zeros_like(rho), np.zeros_like(rho)
    for i, r in enumerate(rho[:-1]):
        limit = math.acos(r)
        psi = 0.5 * limit * (_NODES + 1.0)
        w = 0.5 * limit * _WEIGHTS
        approach = np.cos(psi) - r
        e[i] = 2.0 * np.sum(w * approach ** (N + 1.0))
        de[i] = -2.0 * (N + 1.0) * np.sum(w * approach ** N)
    return e, de


TABLE_E, TABLE_DE = _table()


def load_constant(rollers: int, roller_load_constant: float, contact_angle: float = 0.0,
                  bearings: int = 1) -> float:
    """a [N/m^n] of the law: `bearings` alike side by side, each of `rollers` rollers with
    Q = roller_load_constant * delta^n, at `contact_angle` [rad] to the radial plane."""
    return bearings * rollers * roller_load_constant * math.cos(contact_angle) ** (N + 1.0) \
        / (2.0 * math.pi)


@kernel
def _hermite(table_e, table_de, rho):
    """(E, E', E'') of the cubic Hermite interpolant at rho in [0, 1]."""
    x = rho * INTERVALS
    i = min(int(x), INTERVALS - 1)
    t = x - i
    h = 1.0 / INTERVALS
    p0, p1 = table_e[i], table_e[i + 1]
    m0, m1 = table_de[i] * h, table_de[i + 1] * h
    t2 = t * t
    t3 = t2 * t
    e = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (3 * t2 - 2 * t3) * p1 + (t3 - t2) * m1
    d1 = (6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (6 * t - 6 * t2) * p1 + (3 * t2 - 2 * t) * m1
    d2 = (12 * t - 6) * p0 + (6 * t - 4) * m0 + (6 - 12 * t) * p1 + (6 * t - 2) * m1
    return e, d1 / h, d2 / (h * h)


@kernel
def _rollers(table_e, table_de, s, c, a):
    """(energy [J], force [N], stiffness [N/m]) of the bearing alone at deflection s [m]."""
    if s <= c:
        return 0.0, 0.0, 0.0
    rho = c / s
    e, d1, d2 = _hermite(table_e, table_de, rho)
    sn1 = s ** (N - 1.0)
    energy = a * sn1 * s * s * e / (N + 1.0)
    force = a * sn1 * s * (e - rho * d1 / (N + 1.0))
    stiffness = a * sn1 * (N * e - 2.0 * N * rho * d1 / (N + 1.0) + rho * rho * d2 / (N + 1.0))
    return energy, force, max(stiffness, 0.0)


@kernel
def _settled(size, last, s):
    """Whether the series Newton iteration has converged after a step of `size` [m] that
    followed one of `last` (0: none): the step, or the next one foreseen, size^3 / last^2,
    below SERIES_TOLERANCE s."""
    limit = SERIES_TOLERANCE * s
    return size <= limit or (last > 0.0 and size * size * size <= limit * last * last)


@kernel
def roller_law(table_e, table_de, s, c, a, compliance):
    """(energy [J], force [N], stiffness [N/m]) of a roller bearing with free play c [m],
    law constant a and a series spring of `compliance` [m/N], at centre deflection s [m]."""
    if s <= c:
        return 0.0, 0.0, 0.0
    if compliance == 0.0:
        return _rollers(table_e, table_de, s, c, a)
    u = s
    last = 0.0
    for _ in range(SERIES_ITERATIONS):
        energy, force, stiffness = _rollers(table_e, table_de, u, c, a)
        step = (u + compliance * force - s) / (1.0 + compliance * stiffness)
        u_new = u - step
        if u_new <= c:
            u_new = 0.5 * (u + c)
        size = abs(u_new - u)
        u = u_new
        if _settled(size, last, s):
            break
        last = size
    energy, force, stiffness = _rollers(table_e, table_de, u, c, a)
    return (energy + 0.5 * compliance * force * force, force,
            stiffness / (1.0 + compliance * stiffness))


def _rollers_array(s, c, a):
    """`_rollers` over arrays."""
    engaged = s > c
    s_safe = np.where(engaged, s, 1.0)
    rho = np.where(engaged, c / s_safe, 0.0)
    x = rho * INTERVALS
    i = np.minimum(x.astype(int), INTERVALS - 1)
    t = x - i
    h = 1.0 / INTERVALS
    p0, p1 = TABLE_E[i], TABLE_E[i + 1]
    m0, m1 = TABLE_DE[i] * h, TABLE_DE[i + 1] * h
    t2, t3 = t * t, t * t * t
    e = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0 + (3 * t2 - 2 * t3) * p1 + (t3 - t2) * m1
    d1 = ((6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (6 * t - 6 * t2) * p1
          + (3 * t2 - 2 * t) * m1) / h
    d2 = ((12 * t - 6) * p0 + (6 * t - 4) * m0 + (6 - 12 * t) * p1 + (6 * t - 2) * m1) / (h * h)
    sn1 = s_safe ** (N - 1.0)
    energy = a * sn1 * s_safe * s_safe * e / (N + 1.0)
    force = a * sn1 * s_safe * (e - rho * d1 / (N + 1.0))
    stiffness = np.maximum(a * sn1 * (N * e - 2.0 * N * rho * d1 / (N + 1.0)
                                      + rho * rho * d2 / (N + 1.0)), 0.0)
    return (np.where(engaged, energy, 0.0), np.where(engaged, force, 0.0),
            np.where(engaged, stiffness, 0.0))


def radial_law(s, c, a, compliance):
    """`roller_law` over arrays (broadcast): (energy, force, stiffness) arrays."""
    s, c, a, compliance = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                                for v in (s, c, a, compliance)))
    u = s.copy()
    last = np.zeros(s.shape)
    moving = s > c          # each bearing stops where `roller_law` stops it
    limit = SERIES_TOLERANCE * s
    for _ in range(SERIES_ITERATIONS):
        if not moving.any():
            break
        energy, force, stiffness = _rollers_array(u, c, a)
        u_new = u - (u + compliance * force - s) / (1.0 + compliance * stiffness)
        u_new = np.where(u_new <= c, 0.5 * (u + c), u_new)
        size = np.abs(u_new - u)
        u = np.where(moving, u_new, u)
        settled = (size <= limit) | ((last > 0.0) & (size ** 3 <= limit * last * last))
        moving &= ~settled
        last = size
    energy, force, stiffness = _rollers_array(u, c, a)
    return (energy + 0.5 * compliance * force * force, force,
            stiffness / (1.0 + compliance * stiffness))
