"""The pins' contact law as the solvers use it: energy, force and tangent stiffness of a pin
pressed by delta into its disc and its housing groove.

A pin lies in a groove of the housing and the disc's tooth presses it there: two Hertz
line contacts in series, pin-disc and pin-groove.  Radzimovsky's closed form of a line
contact's approach (`stiffness.hertz_line_contact_approach`) is linear in the load but for
a logarithm of it:

    delta_i = b_i F (2/3 + ln(4 rho_1 |rho_2| / h^2)),   h^2 = 4 F R* / (pi E* l)
            = b_i F ln(F_i* / F),   b_i = 2 (1 - nu^2) / (pi E l),
                                    F_i* = e^(2/3) pi E* l rho_1 |rho_2| / R*,

so the two contacts in series are

    delta(F) = b F ln(F* / F),   b = 2 b_i,   F* = sqrt(F_1* F_2*),

one law of two constants: softer than its secant at small loads, stiffer at large ones.
A design states one pin stiffness, the secant that every linear part of the model uses
and the catalogue's rigidity test sees (50-100 % of the largest pin force at rated
torque, `stiffness.pin_stiffness_estimate`); where it also gives the pins' groove, the
pins follow this law with F* from its geometry and b such that the law's secant over that
range is the stated stiffness.  With the estimate's own stiffness b is exactly 2 b_i.

The solvers need the law the other way round, at a deflection: with x = F / F* and
y = delta / (b F*), y = -x ln x, so v = -ln x > 1 solves v - ln v = c, c = -ln y (it is
Lambert's W_-1; `reference.py` takes scipy's), and the force is F = delta / (b v).

`contact` reads v(c) off a table, with no iteration: quintic Hermite polynomials on v and
its derivatives dv/dc = v / (v - 1), d2v/dc2 = -v / (v - 1)^3 at the nodes (each node
solved to round-off), stored as each interval's six coefficients in t and summed by
Horner's rule, FINE_INTERVALS intervals from the law's limit to c = ROOT_TABLE_END
and TAIL_INTERVALS from there to c = TAIL_END = 745, past -ln of the smallest positive
double (744.44): the table covers every deflection a double can hold, so nothing lies
beyond it (a y that underflows to 0 is read as the smallest double, a force of 1e-320 N or
less).  Its error is at most 2e-15 of v (measured against Newton's roots on a grid 100
times finer, tests/test_law_forms.py), and 4e-15 of v - 1 (the tangent's).

`contact_newton`, the reference kept for the tests and the benchmarks (RVTE_LAWS=newton,
`compiled.py`), runs Newton's method instead: it converges (the function is increasing and
convex) and stops when a step is below 1e-8 v, after which the error is below round-off
(Newton's error after a step s is at most s^2 / (2 v (v - 1))).  It starts from v(c)
tabulated once (ROOT_INTERVALS intervals from the law's limit to c = ROOT_TABLE_END) and
interpolated by cubic Hermite polynomials on its slope: within 1e-9 of v, so one step ends
it, where de Bruijn's v0 = c + ln c + ln c / c, used beyond the table, takes two for the
pin forces of a reducer (v > 8) and four near the law's limit; MAX_STEPS at most.
The law holds while F < F* e^-2 (v = 2, three orders of magnitude above any reducer's pin
force); beyond, a trial step of an iteration meets the tangent there continued linearly,
so the energy stays convex and finite.

    energy   Phi(F) = b F^2 (ln(F*/F) - 1/2) / 2 = b F^2 (v - 1/2) / 2
    tangent  dF/d delta = 1 / (b (ln(F*/F) - 1)) = 1 / (b (v - 1))

`contact` is compiled by numba where it is installed (`compiled.kernel`) and takes one pin;
`contacts` is the same in numpy for arrays (`contacts_newton` the reference's).  A law of
b = 0 is the linear spring k.
"""

from __future__ import annotations

import math

import numpy as np

from ..base.compiled import COMPILED, NEWTON_LAWS, kernel

U_LIMIT = -2.0  # ln(F / F*) where the law continues as its tangent
Y_LIMIT = -U_LIMIT * math.exp(U_LIMIT)  # delta / (b F*) there
MAX_STEPS = 6  # Newton steps on v - ln v = c at most (four reach round-off, tests)
STEP_TOLERANCE = 1e-8  # relative step after which v is at round-off
C_LIMIT = -math.log(Y_LIMIT)  # c at the law's limit, where v = 2
ROOT_TABLE_END = 40.0  # c up to which Newton starts from the table (y down to 4e-18)
ROOT_INTERVALS = 4096
# the quintic table of v(c): fine up to ROOT_TABLE_END (v's derivatives are largest near the
# law's limit), coarse beyond; 8192 and 1024 intervals put its error below 2e-15 of v, where
# 4096 and 512 leave 1e-13 (tests/test_law_forms.py measures it)
FINE_INTERVALS = 8192
TAIL_INTERVALS = 1024
TAIL_END = 745.0  # beyond -ln(5e-324) = 744.44: every positive y of a double
Y_SMALLEST = 5e-324  # the smallest positive double: where y underflows, y is read as it


def law_constants(pin_radius, disc_radius, groove_radius, width, youngs_modulus, poisson_ratio):
    """(b0 [m/N], F* [N]) of the pin-disc and pin-groove Hertz line contacts in series, each
    Radzimovsky's; radii [m] signed as `stiffness.hertz_line_contact_approach` takes them (a
    concave surface negative)."""
    e_star = youngs_modulus / (2.0 * (1.0 - poisson_ratio**2))
    b_i = 2.0 * (1.0 - poisson_ratio**2) / (math.pi * youngs_modulus * width)
    logs = []
    for other in (disc_radius, groove_radius):
        r_star = 1.0 / (1.0 / pin_radius + 1.0 / other)
        if r_star <= 0:
            raise ValueError("the concave radius must be larger than the convex one")
        logs.append(2.0 / 3.0 + math.log(math.pi * e_star * width * pin_radius * abs(other) / r_star))
    return 2.0 * b_i, math.exp(0.5 * (logs[0] + logs[1]))


def approach(force, b, f_star):
    """delta [m] of the law at `force` [N] (array or number; below F* e^-2)."""
    force = np.asarray(force, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(force > 0.0, b * force * np.log(f_star / np.maximum(force, 1e-300)), 0.0)


def scaled_law(stated, f_star, low, high):
    """b [m/N] of the law delta = b F ln(F*/F) whose secant between the forces `low` and
    `high` [N] is `stated` [N/m]."""
    spread = (high * math.log(f_star / high) - low * math.log(f_star / low)) / (high - low)
    return 1.0 / (stated * spread)


def _de_bruijn(c):
    """de Bruijn's start for v - ln v = c (arrays or numbers, c > 1)."""
    log_c = np.log(c)
    return c + log_c + log_c / c


def _newton_roots(c):
    """v with v - ln v = c (arrays, c >= C_LIMIT) to round-off: Newton's method from de
    Bruijn's start, run until it no longer moves."""
    v = _de_bruijn(c)
    for _ in range(100):
        v_new = v - (v - np.log(v) - c) * v / (v - 1.0)
        if np.array_equal(v_new, v):
            break
        v = v_new
    return v


def _root_table():
    """(v, dv/dc) at c = C_LIMIT .. ROOT_TABLE_END, ROOT_INTERVALS + 1 nodes: Newton's method
    from de Bruijn's start, run until it no longer moves."""
    v = _newton_roots(np.linspace(C_LIMIT, ROOT_TABLE_END, ROOT_INTERVALS + 1))
    v[0] = 2.0  # the law's limit exactly: 2 - ln 2 = C_LIMIT
    return v, v / (v - 1.0)


ROOT_V, ROOT_DV = _root_table()
_ROOT_STEP = (ROOT_TABLE_END - C_LIMIT) / ROOT_INTERVALS


@kernel
def _hermite(t, i):
    """The table's cubic Hermite interpolant at t in [0, 1] of interval i (numbers or arrays)."""
    t2 = t * t
    t3 = t2 * t
    return (
        (2 * t3 - 3 * t2 + 1) * ROOT_V[i]
        + (t3 - 2 * t2 + t) * _ROOT_STEP * ROOT_DV[i]
        + (3 * t2 - 2 * t3) * ROOT_V[i + 1]
        + (t3 - t2) * _ROOT_STEP * ROOT_DV[i + 1]
    )


def _table_start(c):
    """The tabulated v(c) (arrays, C_LIMIT <= c < ROOT_TABLE_END)."""
    x = np.maximum(c - C_LIMIT, 0.0) / _ROOT_STEP
    i = np.minimum(x.astype(np.int64), ROOT_INTERVALS - 1)
    return _hermite(x - i, i)


@kernel
def _start(c):
    """Newton's start for v - ln v = c: the table (`_table_start`), de Bruijn's beyond."""
    if c >= ROOT_TABLE_END:
        log_c = math.log(c)
        return c + log_c + log_c / c
    x = max(c - C_LIMIT, 0.0) / _ROOT_STEP
    i = min(int(x), ROOT_INTERVALS - 1)
    return _hermite(x - i, i)


@kernel
def _root(c):
    """v = ln(F* / F) with v - ln v = c, for c >= -ln Y_LIMIT."""
    v = _start(c)
    for _ in range(MAX_STEPS):
        step = (v - math.log(v) - c) * v / (v - 1.0)
        v -= step
        if abs(step) < STEP_TOLERANCE * v:
            break
    return v


def _quintic_table(start, end, intervals):
    """(intervals, 6): the monomial coefficients in t of the quintic Hermite polynomial on
    each interval of c from `start` to `end` (t in [0, 1] across it), through v, dv/dc and
    d2v/dc2 at its ends; summed in extended precision (np.longdouble where it is longer)."""
    v = _newton_roots(np.linspace(start, end, intervals + 1))
    if start == C_LIMIT:
        v[0] = 2.0  # the law's limit exactly
    step = (end - start) / intervals
    v = v.astype(np.longdouble)
    p, m, q = v, step * v / (v - 1.0), -step * step * v / (v - 1.0) ** 3
    p0, m0, q0, p1, m1, q1 = p[:-1], m[:-1], q[:-1], p[1:], m[1:], q[1:]
    return np.stack(
        [
            p0,
            m0,
            0.5 * q0,
            10.0 * (p1 - p0) - 6.0 * m0 - 4.0 * m1 - 1.5 * q0 + 0.5 * q1,
            15.0 * (p0 - p1) + 8.0 * m0 + 7.0 * m1 + 1.5 * q0 - q1,
            6.0 * (p1 - p0) - 3.0 * (m0 + m1) - 0.5 * (q0 - q1),
        ],
        axis=1,
    ).astype(float)


# rows 0 .. FINE_INTERVALS - 1 the fine intervals, then the tail's; numpy gathers each
# coefficient apart from its own contiguous column (twice as fast as gathering rows)
INVERSE_COEFFS = np.concatenate(
    [
        _quintic_table(C_LIMIT, ROOT_TABLE_END, FINE_INTERVALS),
        _quintic_table(ROOT_TABLE_END, TAIL_END, TAIL_INTERVALS),
    ]
)
_COLUMNS = tuple(np.ascontiguousarray(column) for column in INVERSE_COEFFS.T)
_FINE_SCALE = FINE_INTERVALS / (ROOT_TABLE_END - C_LIMIT)  # intervals per unit of c
_TAIL_SCALE = TAIL_INTERVALS / (TAIL_END - ROOT_TABLE_END)


@kernel
def _inverse(c):
    """v with v - ln v = c for C_LIMIT <= c <= TAIL_END, read off the quintic table."""
    if c < ROOT_TABLE_END:
        x = max(c - C_LIMIT, 0.0) * _FINE_SCALE
        i = min(int(x), FINE_INTERVALS - 1)
        row = i
    else:
        x = (c - ROOT_TABLE_END) * _TAIL_SCALE
        i = min(int(x), TAIL_INTERVALS - 1)
        row = FINE_INTERVALS + i
    t = x - i
    a = INVERSE_COEFFS
    return a[row, 0] + t * (a[row, 1] + t * (a[row, 2] + t * (a[row, 3] + t * (a[row, 4] + t * a[row, 5]))))


def _inverse_numpy(c):
    """`_inverse` over an array of c, in numpy."""
    x = np.maximum(c - C_LIMIT, 0.0) * _FINE_SCALE
    row = np.minimum(x.astype(np.int64), FINE_INTERVALS - 1)
    t = x - row
    tail = c >= ROOT_TABLE_END
    if tail.any():  # deflections below some 1e-20 m: rare, so apart
        x_tail = (c[tail] - ROOT_TABLE_END) * _TAIL_SCALE
        i_tail = np.minimum(x_tail.astype(np.int64), TAIL_INTERVALS - 1)
        t[tail] = x_tail - i_tail
        row[tail] = FINE_INTERVALS + i_tail
    a = _COLUMNS
    return a[0][row] + t * (a[1][row] + t * (a[2][row] + t * (a[3][row] + t * (a[4][row] + t * a[5][row]))))


@kernel
def _inverse_each(c):
    """`_inverse` over a 1-D array of c, one at a time (compiled: twice as fast as numpy)."""
    out = np.empty(c.size)
    for i in range(c.size):
        out[i] = _inverse(c[i])
    return out


def _inverse_array(c):
    """`_inverse` over an array of c: compiled where numba is, else in numpy."""
    if COMPILED:
        flat = np.ascontiguousarray(c, dtype=float).ravel()
        return _inverse_each(flat).reshape(np.shape(c))
    return _inverse_numpy(c)


@kernel
def _at_root(delta, b, v):
    """(energy, force, tangent) of the law at delta [m] where v = ln(F* / F)."""
    force = delta / (b * v)
    return 0.5 * b * force * force * (v - 0.5), force, 1.0 / (b * (v - 1.0))


@kernel
def _tangent_continued(y, b, f_star):
    """(energy, force, tangent) beyond the law's range, y > Y_LIMIT: its tangent continued."""
    f_limit = f_star * math.exp(U_LIMIT)
    tangent = 1.0 / (b * (-U_LIMIT - 1.0))
    over = (y - Y_LIMIT) * b * f_star
    energy = 0.5 * b * f_limit * f_limit * (-U_LIMIT - 0.5)
    return energy + f_limit * over + 0.5 * tangent * over * over, f_limit + tangent * over, tangent


@kernel
def contact_direct(delta, law):
    """(energy [J], force [N], tangent stiffness [N/m]) of one pin pressed by delta [m];
    law = (k, b, F*): b = 0 the linear spring k, else the Hertz law above, v read off the
    quintic table (`_inverse`).  Nothing for delta <= 0."""
    if delta <= 0.0:
        return 0.0, 0.0, 0.0
    b = law[1]
    if b == 0.0:
        return 0.5 * law[0] * delta * delta, law[0] * delta, law[0]
    y = delta / (b * law[2])
    if y <= Y_LIMIT:
        return _at_root(delta, b, _inverse(-math.log(max(y, Y_SMALLEST))))
    return _tangent_continued(y, b, law[2])


@kernel
def contact_newton(delta, law):
    """`contact_direct` with v found by Newton's method (`_root`): the reference."""
    if delta <= 0.0:
        return 0.0, 0.0, 0.0
    b = law[1]
    if b == 0.0:
        return 0.5 * law[0] * delta * delta, law[0] * delta, law[0]
    y = delta / (b * law[2])
    if y <= Y_LIMIT:
        return _at_root(delta, b, _root(-math.log(y)))
    return _tangent_continued(y, b, law[2])


# the form the solvers take (RVTE_LAWS, `compiled.py`): bound here, before any kernel that
# calls it is compiled, since numba freezes a kernel's callees
contact = contact_newton if NEWTON_LAWS else contact_direct


@kernel
def contact_forces(delta, law):
    """`contact`'s force for a C-contiguous array of deflections, of the same shape: what
    `contacts(delta, law)[1]` gives, compiled (the equilibria's pin forces)."""
    flat = delta.ravel()
    out = np.empty(flat.size)
    for i in range(flat.size):
        out[i] = contact(flat[i], law)[1]
    return out.reshape(delta.shape)


def _newton_array(c):
    """Newton's v(c) over an array, as `_root` (from the cubic table, de Bruijn's beyond)."""
    on_table = c < ROOT_TABLE_END
    v = np.where(on_table, _table_start(np.where(on_table, c, C_LIMIT)), _de_bruijn(c))
    for _ in range(MAX_STEPS):
        step = (v - np.log(v) - c) * v / (v - 1.0)
        v = v - step
        if np.all(np.abs(step) < STEP_TOLERANCE * v):
            break
    return v


def _contacts(delta, law, roots, smallest):
    """`contact` for an array of deflections with v(c) from `roots`; y at least `smallest`."""
    delta = np.asarray(delta, dtype=float)
    k, b, f_star = (float(v) for v in law)
    pos = np.maximum(delta, 0.0)
    if b == 0.0:
        on = delta > 0.0
        return 0.5 * k * pos * pos, k * pos, np.where(on, k, 0.0)
    y = pos / (b * f_star)
    inside = (pos > 0.0) & (np.maximum(y, smallest) > 0.0) & (y <= Y_LIMIT)
    c = -np.log(np.where(inside, np.maximum(y, smallest), 0.5 * Y_LIMIT))
    v = roots(c)
    force = np.where(inside, pos / (b * v), 0.0)
    energy = 0.5 * b * force * force * (v - 0.5)
    tangent = np.where(inside, 1.0 / (b * (v - 1.0)), 0.0)
    beyond = y > Y_LIMIT
    if beyond.any():  # past the law's range (none in a converged pose): its tangent continued
        f_limit = f_star * math.exp(U_LIMIT)
        t_limit = 1.0 / (b * (-U_LIMIT - 1.0))
        over = (y - Y_LIMIT) * b * f_star
        e_limit = 0.5 * b * f_limit * f_limit * (-U_LIMIT - 0.5)
        energy = np.where(beyond, e_limit + f_limit * over + 0.5 * t_limit * over * over, energy)
        force = np.where(beyond, f_limit + t_limit * over, force)
        tangent = np.where(beyond, t_limit, tangent)
    return np.asarray(energy), force, tangent


def contacts_direct(delta, law):
    """`contact_direct` for an array of deflections: (energy, force, tangent), each delta's
    shape."""
    return _contacts(delta, law, _inverse_array, Y_SMALLEST)


def contacts_newton(delta, law):
    """`contact_newton` for an array of deflections: the reference."""
    return _contacts(delta, law, _newton_array, 0.0)


contacts = contacts_newton if NEWTON_LAWS else contacts_direct
