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
deflects u where u + C F(u) = s, Psi(s) = Phi(u) + C F(u)^2 / 2, force F(u), stiffness
F'(u) / (1 + C F'(u)).

`roller_law` finds u with no iteration loop.  In the bearing's own scale the equation has
two parameters: with xi = u / s, rho = c / s and kappa = C a s^(n-1) (the spring's
compliance over the bearing's, dimensionless), xi + kappa xi^n G(rho / xi) = 1, G(r) =
E(r) - r E'(r) / (n+1), for any s, c, a, C, and c = 0 is its row rho = 0.  The share of
the travel beyond the play that the bearing takes, eta = (u - c) / (s - c) in (0, 1], is
tabulated once on t = 1 - (1 - rho)^(1/4) (near s = c, 1 - eta grows as (1 - rho)^0.61:
in t as (1 - t)^2.4, smooth enough to interpolate) and tau = kappa / (1 + kappa), both
in [0, 1] (START_T_INTERVALS x START_TAU_INTERVALS cells, each node solved by the
reference below) and interpolated by cubic Lagrange polynomials in both: within 4e-5 of
u - c over the presets' range (kappa < 1.5; 3e-6 where s - c > 0.1 um).  One Newton
correction follows, with no test: its error is about (C F'' / (2 (1 + C F'))) e^2 for a
start e off, at most 3e-11 of u - c there (3e-13 where s - c > 0.1 um), and the energy,
force and stiffness are then those of the bearing at the corrected u (whose power u^(n-1)
comes from the start's by the binomial series of (1 - x)^(n-1), x the correction over u,
where x is below 1e-4: within round-off, and one power less of three; with the divisions by
n + 1 made products, 121 -> 105 ns a call, studies/benchmarks/bench_law_forms.py; a bearing
without play, c = 0, written out, `_tight`, 73 ns).  That keeps them
consistent: dPsi/ds = F(u) (1 + C F'(u)) du/ds, and du/ds = 1 / (1 + C F'(u)) up to the
derivative of u's error, which the table's cells make piecewise smooth, so the force is
the energy's derivative and the stiffness the force's as closely as the reference's (whose
u is at round-off) up to that derivative: central differences of the two forms differ by
at most 1e-9 of the force and of the stiffness where s - c > 0.1 um (5.3e-10 measured; the
last bits of the math library set it; closer, both are at round-off), and Gauss quadratures
of the force and the stiffness give the energy's and the force's increase within 1e-11
(tests/test_law_forms.py).  Against the reference, force,
stiffness and energy agree within 2e-10 relative wherever s - c exceeds 1e-10 m; closer
to the play, both are at the round-off of u - c (an ulp of s over s - c) and agree within
the spread the reference shows over a few ulps of its own u.

`roller_law_newton`, the reference kept for the tests and the benchmarks (RVTE_LAWS=newton,
`compiled.py`), runs Newton's method from u = s (monotone because F is convex).  Newton's
steps shrink quadratically, each about K times the square of the last, K = step / last^2;
it stops when the step it would take next, K step^2, is below SERIES_TOLERANCE s (or a
step itself is): the same u to round-off (a few 1e-15 s) as iterating until a step is
below it, one solve of F fewer in most bearings, and none of the 60 of a solve whose
steps stall at round-off.

The functions here are compiled by numba where it is installed (`compiled.kernel`) and are
called one bearing at a time; `radial_law` evaluates arrays of bearings (the compiled law
at each where numba is, else numpy; `radial_law_newton` in numpy).
"""

from __future__ import annotations

import math

import numpy as np

from ..base.compiled import COMPILED, NEWTON_LAWS, kernel
from .compliance import LINE_EXPONENT

N = LINE_EXPONENT
INTERVALS = 1024  # of the rho table
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)
SERIES_ITERATIONS = 60
SERIES_TOLERANCE = 1e-15  # of s: u's step, taken or foreseen
# the start table of eta(t, tau): 256 x 128 cells leave 4e-5 of u - c, which the one
# correction takes to 3e-11; 128 x 64 leave 1e-3, and one correction some 1e-9
START_T_INTERVALS = 256
START_TAU_INTERVALS = 128
INVERSE_N1 = 1.0 / (N + 1.0)
# (1 - x)^p = 1 - x (P1 - x (P2 - x P3)) + O(x^4), p = n - 1: the corrected u's power from the
# start's, where the correction is below SERIES_POWER_BELOW of u (the x^4 term is then below
# 3e-18, within round-off)
_P = N - 1.0
POWER_1, POWER_2, POWER_3 = _P, _P * (_P - 1.0) / 2.0, _P * (_P - 1.0) * (_P - 2.0) / 6.0
SERIES_POWER_BELOW = 1e-4


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
        de[i] = -2.0 * (N + 1.0) * np.sum(w * approach**N)
    return e, de


TABLE_E, TABLE_DE = _table()


def load_constant(
    rollers: int, roller_load_constant: float, contact_angle: float = 0.0, bearings: int = 1
) -> float:
    """a [N/m^n] of the law: `bearings` alike side by side, each of `rollers` rollers with
    Q = roller_load_constant * delta^n, at `contact_angle` [rad] to the radial plane."""
    return bearings * rollers * roller_load_constant * math.cos(contact_angle) ** (N + 1.0) / (2.0 * math.pi)


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
    return _rollers_at(table_e, table_de, s, c, a, s ** (N - 1.0))


@kernel
def _rollers_at(table_e, table_de, s, c, a, sn1):
    """`_rollers` at s > c, with s^(n-1) given (sn1)."""
    rho = c / s
    e, d1, d2 = _hermite(table_e, table_de, rho)
    asn1 = a * sn1
    rd1 = rho * d1 * INVERSE_N1
    energy = asn1 * s * s * e * INVERSE_N1
    force = asn1 * s * (e - rd1)
    stiffness = asn1 * (N * e - 2.0 * N * rd1 + rho * rho * d2 * INVERSE_N1)
    return energy, force, max(stiffness, 0.0)


@kernel
def _settled(size, last, s):
    """Whether the series Newton iteration has converged after a step of `size` [m] that
    followed one of `last` (0: none): the step, or the next one foreseen, size^3 / last^2,
    below SERIES_TOLERANCE s."""
    limit = SERIES_TOLERANCE * s
    return size <= limit or (last > 0.0 and size * size * size <= limit * last * last)


@kernel
def roller_law_newton(table_e, table_de, s, c, a, compliance):
    """`roller_law_direct` with u found by Newton's method from u = s: the reference."""
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
    return (energy + 0.5 * compliance * force * force, force, stiffness / (1.0 + compliance * stiffness))


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
    d1 = (
        (6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (6 * t - 6 * t2) * p1 + (3 * t2 - 2 * t) * m1
    ) / h
    d2 = ((12 * t - 6) * p0 + (6 * t - 4) * m0 + (6 - 12 * t) * p1 + (6 * t - 2) * m1) / (h * h)
    sn1 = s_safe ** (N - 1.0)
    energy = a * sn1 * s_safe * s_safe * e / (N + 1.0)
    force = a * sn1 * s_safe * (e - rho * d1 / (N + 1.0))
    stiffness = np.maximum(
        a * sn1 * (N * e - 2.0 * N * rho * d1 / (N + 1.0) + rho * rho * d2 / (N + 1.0)), 0.0
    )
    return (np.where(engaged, energy, 0.0), np.where(engaged, force, 0.0), np.where(engaged, stiffness, 0.0))


def _series_deflection(s, c, a, compliance):
    """u [m] with u + C F(u) = s, the reference's Newton iteration over arrays (broadcast),
    each bearing stopped where `roller_law_newton` stops it; s where s <= c."""
    s, c, a, compliance = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (s, c, a, compliance)))
    u = s.copy()
    last = np.zeros(s.shape)
    moving = s > c
    limit = SERIES_TOLERANCE * s
    for _ in range(SERIES_ITERATIONS):
        if not moving.any():
            break
        _, force, stiffness = _rollers_array(u, c, a)
        u_new = u - (u + compliance * force - s) / (1.0 + compliance * stiffness)
        u_new = np.where(u_new <= c, 0.5 * (u + c), u_new)
        size = np.abs(u_new - u)
        u = np.where(moving, u_new, u)
        settled = (size <= limit) | ((last > 0.0) & (size**3 <= limit * last * last))
        moving &= ~settled
        last = size
    return u


def _series_law(u, c, a, compliance):
    """(energy, force, stiffness) of the bearing at u with the spring in series."""
    energy, force, stiffness = _rollers_array(u, c, a)
    return (energy + 0.5 * compliance * force * force, force, stiffness / (1.0 + compliance * stiffness))


def radial_law_newton(s, c, a, compliance):
    """`roller_law_newton` over arrays (broadcast): the reference."""
    s, c, a, compliance = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (s, c, a, compliance)))
    return _series_law(_series_deflection(s, c, a, compliance), c, a, compliance)


def _start_table():
    """eta = (u - c) / (s - c) at the nodes t = i / START_T_INTERVALS, tau = j /
    START_TAU_INTERVALS, flat (row i of START_TAU_INTERVALS + 1 values of tau): solved in
    the bearing's scale, s = 1, c = rho, a = 1, C = kappa; at t = 1 (s = c) its limit 1, at
    tau = 1 (a rigid bearing, kappa infinite) its limit 0."""
    t = np.linspace(0.0, 1.0, START_T_INTERVALS + 1)[:, None]
    tau = np.linspace(0.0, 1.0, START_TAU_INTERVALS + 1)[None, :]
    inside = (t < 1.0) & (tau < 1.0)
    rho = np.where(inside, 1.0 - (1.0 - t) ** 4, 0.5)
    kappa = np.where(inside, tau / np.where(inside, 1.0 - tau, 1.0), 1.0)
    u = _series_deflection(1.0, rho, 1.0, kappa)
    eta = np.where(inside, (u - rho) / (1.0 - rho), np.where(t < 1.0, 0.0, 1.0))
    return eta.ravel()


START_ETA = _start_table()


@kernel
def _lagrange(x):
    """The four weights of cubic Lagrange interpolation through nodes -1, 0, 1, 2 at x."""
    below, above, after = x + 1.0, x - 1.0, x - 2.0
    return (
        -(1.0 / 6.0) * x * above * after,
        0.5 * below * above * after,
        -0.5 * below * x * after,
        (1.0 / 6.0) * below * x * above,
    )


@kernel
def _eta(i, j, x, y):
    """The table's bicubic interpolant in the cell of nodes i .. i + 1, j .. j + 1 (1 <= i <
    START_T_INTERVALS - 1, likewise j) at x, y in [-1, 2] from node i, j (numbers or arrays;
    written out, a third faster compiled than as a loop)."""
    wx0, wx1, wx2, wx3 = _lagrange(x)
    wy0, wy1, wy2, wy3 = _lagrange(y)
    row = START_TAU_INTERVALS + 1
    e = START_ETA
    k = (i - 1) * row + j
    r0 = wy0 * e[k - 1] + wy1 * e[k] + wy2 * e[k + 1] + wy3 * e[k + 2]
    k = k + row
    r1 = wy0 * e[k - 1] + wy1 * e[k] + wy2 * e[k + 1] + wy3 * e[k + 2]
    k = k + row
    r2 = wy0 * e[k - 1] + wy1 * e[k] + wy2 * e[k + 1] + wy3 * e[k + 2]
    k = k + row
    r3 = wy0 * e[k - 1] + wy1 * e[k] + wy2 * e[k + 1] + wy3 * e[k + 2]
    return wx0 * r0 + wx1 * r1 + wx2 * r2 + wx3 * r3


@kernel
def _start(s, c, a, compliance):
    """The tabulated u [m] of the bearing with its series spring at s [m] > c."""
    rho = c / s
    kappa = compliance * a * s ** (N - 1.0)
    x = (1.0 - math.sqrt(math.sqrt(1.0 - rho))) * START_T_INTERVALS
    y = kappa / (1.0 + kappa) * START_TAU_INTERVALS
    i = min(max(int(x), 1), START_T_INTERVALS - 2)
    j = min(max(int(y), 1), START_TAU_INTERVALS - 2)
    return c + _eta(i, j, x - i, y - j) * (s - c)


@kernel
def _corrected(u, un1, step):
    """(u - step, its power (u - step)^(n-1)) from u and its power un1: the binomial series of
    (1 - x)^(n-1) to x^3, x = step / u, where x is below SERIES_POWER_BELOW (within round-off),
    else the power itself."""
    x = step / u
    u -= step
    if abs(x) < SERIES_POWER_BELOW:
        return u, un1 * (1.0 - x * (POWER_1 - x * (POWER_2 - x * POWER_3)))
    return u, u ** (N - 1.0)


@kernel
def _tight(table_e, s, a, compliance):
    """`roller_law_direct` of a bearing without play (c = 0), written out: rho = 0 everywhere,
    so the start table's cell holds row t = 0 alone (at x = -1 its weights across the rows are
    1, 0, -0, 0) and the Hermite interpolant gives E(0) = table_e[0] with every term in rho
    zero.  The same numbers as the general path to the bit, at seven tenths of its time: the
    crank bearings of a study without clearances."""
    kappa = compliance * a * s ** (N - 1.0)
    y = kappa / (1.0 + kappa) * START_TAU_INTERVALS
    j = min(max(int(y), 1), START_TAU_INTERVALS - 2)
    wy0, wy1, wy2, wy3 = _lagrange(y - j)
    eta = START_ETA
    u = (wy0 * eta[j - 1] + wy1 * eta[j] + wy2 * eta[j + 1] + wy3 * eta[j + 2]) * s
    e = table_e[0]
    un1 = u ** (N - 1.0)
    force, stiffness = 0.0, 0.0
    if u > 0.0:
        asn1 = a * un1
        force, stiffness = asn1 * u * e, max(asn1 * (N * e), 0.0)
    u, un1 = _corrected(u, un1, (u + compliance * force - s) / (1.0 + compliance * stiffness))
    if u <= 0.0:
        return 0.0, 0.0, 0.0
    asn1 = a * un1
    energy, force, stiffness = asn1 * u * u * e * INVERSE_N1, asn1 * u * e, max(asn1 * (N * e), 0.0)
    return (energy + 0.5 * compliance * force * force, force, stiffness / (1.0 + compliance * stiffness))


@kernel
def roller_law_direct(table_e, table_de, s, c, a, compliance):
    """(energy [J], force [N], stiffness [N/m]) of a roller bearing with free play c [m],
    law constant a and a series spring of `compliance` [m/N], at centre deflection s [m]:
    u from the start table and one Newton correction (module docstring)."""
    if s <= c:
        return 0.0, 0.0, 0.0
    if compliance == 0.0:
        return _rollers(table_e, table_de, s, c, a)
    if c == 0.0:
        return _tight(table_e, s, a, compliance)
    u = _start(s, c, a, compliance)
    un1 = u ** (N - 1.0)
    force, stiffness = 0.0, 0.0
    if u > c:
        _, force, stiffness = _rollers_at(table_e, table_de, u, c, a, un1)
    u, un1 = _corrected(u, un1, (u + compliance * force - s) / (1.0 + compliance * stiffness))
    if u <= c:
        return 0.0, 0.0, 0.0
    energy, force, stiffness = _rollers_at(table_e, table_de, u, c, a, un1)
    return (energy + 0.5 * compliance * force * force, force, stiffness / (1.0 + compliance * stiffness))


@kernel
def _direct_each(table_e, table_de, s, c, a, compliance):
    """(3, M): `roller_law_direct` at each of M bearings (1-D arrays), one at a time."""
    out = np.empty((3, s.size))
    for i in range(s.size):
        out[0, i], out[1, i], out[2, i] = roller_law_direct(
            table_e, table_de, s[i], c[i], a[i], compliance[i]
        )
    return out


def radial_law_direct(s, c, a, compliance):
    """`roller_law_direct` over arrays (broadcast): (energy, force, stiffness) arrays; the
    compiled law one bearing at a time where numba is (2-3 times as fast), else in numpy
    (`_radial_numpy`)."""
    s, c, a, compliance = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (s, c, a, compliance)))
    if not COMPILED:
        return _radial_numpy(s, c, a, compliance)
    flat = (np.ascontiguousarray(v).ravel() for v in (s, c, a, compliance))
    return tuple(v.reshape(s.shape) for v in _direct_each(TABLE_E, TABLE_DE, *flat))


def _radial_numpy(s, c, a, compliance):
    """`roller_law_direct` over broadcast arrays of one shape, in numpy."""
    engaged = s > c
    s_safe = np.where(engaged, s, 1.0)
    c_safe = np.where(engaged, c, 0.0)
    rho = c_safe / s_safe
    kappa = compliance * a * s_safe ** (N - 1.0)
    x = (1.0 - np.sqrt(np.sqrt(1.0 - rho))) * START_T_INTERVALS
    y = kappa / (1.0 + kappa) * START_TAU_INTERVALS
    i = np.clip(x.astype(np.int64), 1, START_T_INTERVALS - 2)
    j = np.clip(y.astype(np.int64), 1, START_TAU_INTERVALS - 2)
    u = c_safe + _eta(i, j, x - i, y - j) * (s_safe - c_safe)
    _, force, stiffness = _rollers_array(u, c_safe, a)
    u = u - (u + compliance * force - s_safe) / (1.0 + compliance * stiffness)
    u = np.where(compliance == 0.0, s_safe, u)  # the bearing alone: u = s
    energy, force, stiffness = _series_law(u, c_safe, a, compliance)
    return (np.where(engaged, energy, 0.0), np.where(engaged, force, 0.0), np.where(engaged, stiffness, 0.0))


# the forms the solvers take (RVTE_LAWS, `compiled.py`): bound here, before any kernel that
# calls them is compiled, since numba freezes a kernel's callees
roller_law = roller_law_newton if NEWTON_LAWS else roller_law_direct
radial_law = radial_law_newton if NEWTON_LAWS else radial_law_direct
