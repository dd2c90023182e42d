"""The dynamic model's inner loop: element forces and Newmark steps, compiled when numba is there.

A time step of the dynamic model is a few Newton iterations, each summing
some thirty springs into an 18 x 18 (two cranks) or 21 x 21 (three cranks)
system and solving it.  In numpy every one of those small operations costs a
microsecond of Python, so the run is slow however little arithmetic it does.
These two functions hold that loop; numba compiles them (`COMPILED`) when it
is installed, and without it (a host Python that lacks it, or RVTE_NUMBA=0)
they run as they are, as plain numpy: the same results, several times slower.

The element data come in two named tuples built by `DynamicModel`:
`Elements` (what does not change over the run) and `Geometry` (rows, offsets,
stiffnesses and external forces at a run of time steps, axis 0 the step).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from .compiled import COMPILED, kernel  # noqa: F401 (COMPILED: what tests and benchmarks ask)
from .pin_law import contact
from .roller_law import roller_law

Elements = namedtuple("Elements", [
    "linear_c",        # (m,) dashpots of the meshes and sun support [N s/m]
    "half_clearance",  # (nb,) free radial play of each bearing [m]
    "bearing_k",       # (nb,) [N/m]
    "bearing_c",       # (nb,) [N s/m]
    "bearing_law",     # (nb, 2): roller-law constant a (0: the linear spring bearing_k), series
                       # compliance [m/N]
    "law_table",       # (2, T): the roller law's table (roller_law.TABLE_E, TABLE_DE)
    "pin_dofs",        # (2, 3) unknowns of each disc: x, y, rotation
    "pin_law",         # (3,) the pins' law unless IMPACT (`pin_law.contact`: k [N/m], b, F*)
    "pin_c",           # pin dashpot (IMPACT: its c_max) [N s/m]
    "impact",          # True: IMPACT law, False: linear
    "impact_k",        # IMPACT stiffness [N/m^e]
    "impact_exponent",
    "impact_depth",    # IMPACT d_max [m]
    "shaft",           # index of the sun's rotation
    "shaft_k",         # input shaft stiffness over scale^2 [N/m]
    "shaft_c",         # its dashpot over scale^2 [N s/m]
])

Geometry = namedtuple("Geometry", [
    "h",               # (A,) time step into each step [s] (the run's first: 0)
    "linear_cols",     # (m, w) unknowns each mesh or support row touches (-1: none)
    "L",               # (A, m, w) their coefficients
    "linear_k", "linear_offset",           # (A, m), (A, m)
    "bearing_cols",    # (nb, w)
    "B",               # (A, nb, 2, w)
    "bearing_offset",  # (A, nb, 2)
    "P", "pin_offset",                     # (A, 2, z_p, 3), (A, 2, z_p)
    "external",                            # (A, n) load and nominal-motion forces [N]
])


def touched_columns(rows: np.ndarray) -> np.ndarray:
    """(E, w) the unknowns that element rows (A, E, ..., n) touch, at any of the A instants:
    each element joins two bodies, so a handful of the n.  Shorter lists are padded with
    -1 (`gather` gives those a zero coefficient)."""
    touched = np.any(rows != 0.0, axis=tuple(k for k in range(rows.ndim - 1) if k != 1))  # (E, n)
    cols = np.full((touched.shape[0], max(1, int(touched.sum(axis=1).max()))), -1, dtype=np.int64)
    for e, row in enumerate(touched):
        found = np.flatnonzero(row)
        cols[e, :found.size] = found
    return cols


def gather(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(A, E, ..., w) the coefficients of rows (A, E, ..., n) on the unknowns `cols` (E, w);
    zero where cols is -1."""
    A, n = rows.shape[0], rows.shape[-1]
    inner = rows.shape[2:-1]                       # () for 1-D elements, (2,) for bearings
    k = int(np.prod(inner, dtype=int))
    base = np.arange(cols.shape[0] * k).reshape((cols.shape[0],) + inner + (1,)) * n
    flat = base + np.where(cols < 0, 0, cols).reshape((cols.shape[0],) + (1,) * len(inner) + (-1,))
    out = rows.reshape(A, -1)[:, flat]
    out[:, np.broadcast_to((cols < 0).reshape(flat.shape[:1] + (1,) * len(inner) + flat.shape[-1:]),
                           flat.shape)] = 0.0
    return out


@kernel
def element_forces(el, g, a, q, v, f, K, C):
    """Forces of every element at step a of geometry g into f (n,), with their derivatives in
    q and v into K and C (n, n): the EOM is M q'' + f = F.  f, K, C are overwritten."""
    f[:] = 0.0
    K[:, :] = 0.0
    C[:, :] = 0.0
    # meshes and sun support: bilateral springs
    cols, L = g.linear_cols, g.L[a]
    for e in range(cols.shape[0]):
        delta, rate = g.linear_offset[a, e], 0.0
        for x in range(cols.shape[1]):
            delta += L[e, x] * q[cols[e, x]]
            rate += L[e, x] * v[cols[e, x]]
        k, c = g.linear_k[a, e], el.linear_c[e]
        force = k * delta + c * rate
        for x in range(cols.shape[1]):
            i = cols[e, x]
            f[i] += L[e, x] * force
            for y in range(cols.shape[1]):
                K[i, cols[e, y]] += k * L[e, x] * L[e, y]
                C[i, cols[e, y]] += c * L[e, x] * L[e, y]
    # bearings: 2-D springs (linear, or the roller law) with a dead zone of half the radial
    # clearance
    cols, B = g.bearing_cols, g.B[a]
    for b in range(cols.shape[0]):
        dx, dy = g.bearing_offset[a, b, 0], g.bearing_offset[a, b, 1]
        vx, vy = 0.0, 0.0
        for x in range(cols.shape[1]):
            dx += B[b, 0, x] * q[cols[b, x]]
            dy += B[b, 1, x] * q[cols[b, x]]
            vx += B[b, 0, x] * v[cols[b, x]]
            vy += B[b, 1, x] * v[cols[b, x]]
        r = np.sqrt(dx * dx + dy * dy)
        half = el.half_clearance[b]
        if half > 0.0 and r <= half:
            continue                                   # inside its play; a tight one always holds
        k, c = el.bearing_k[b], el.bearing_c[b]
        ux, uy = (dx / r, dy / r) if r > 0.0 else (0.0, 0.0)
        if el.bearing_law[b, 0] == 0.0:
            # force k (r - half) u: F' = k along u, F / r = k (1 - half / r) across it
            radial = k
            across = k * (1.0 - half / r) if half > 0.0 else k
        else:
            # the roller law (rvfmu/core/roller_law.py): F(r) along u
            _, force, radial = roller_law(el.law_table[0], el.law_table[1], r, half,
                                          el.bearing_law[b, 0], el.bearing_law[b, 1])
            across = force / r if r > 0.0 else 0.0
        fx, fy = across * dx + c * vx, across * dy + c * vy
        sxx = across + (radial - across) * ux * ux
        syy = across + (radial - across) * uy * uy
        sxy = (radial - across) * ux * uy
        for x in range(cols.shape[1]):
            i, bx, by = cols[b, x], B[b, 0, x], B[b, 1, x]
            f[i] += bx * fx + by * fy
            tx, ty = sxx * bx + sxy * by, sxy * bx + syy * by
            for y in range(cols.shape[1]):
                j, cx, cy = cols[b, y], B[b, 0, y], B[b, 1, y]
                K[i, j] += tx * cx + ty * cy
                C[i, j] += c * (bx * cx + by * cy)
    # pins: unilateral along their normals, over each disc's own three unknowns
    for j in range(2):
        dofs = el.pin_dofs[j]
        R = g.P[a, j]                                      # (z_p, 3)
        for p in range(R.shape[0]):
            delta = g.pin_offset[a, j, p]
            rate = 0.0
            for x in range(3):
                delta += R[p, x] * q[dofs[x]]
                rate += R[p, x] * v[dofs[x]]
            if delta <= 0.0:
                continue                                   # open
            if el.impact:
                s = min(delta / el.impact_depth, 1.0)
                ramp = s * s * (3.0 - 2.0 * s)             # IMPACT's cubic step of the damping
                dramp = 6.0 * s * (1.0 - s) / el.impact_depth if delta < el.impact_depth else 0.0
                e = el.impact_exponent
                normal = el.impact_k * delta ** e + el.pin_c * ramp * rate
                k = e * el.impact_k * delta ** (e - 1.0) + el.pin_c * dramp * rate
                c = el.pin_c * ramp
            else:
                _, spring, k = contact(delta, el.pin_law)
                normal = spring + el.pin_c * rate
                c = el.pin_c
            if normal <= 0.0:
                continue                                   # a separating dashpot pulls nothing
            for x in range(3):
                f[dofs[x]] += R[p, x] * normal
                for y in range(3):
                    K[dofs[x], dofs[y]] += k * R[p, x] * R[p, y]
                    C[dofs[x], dofs[y]] += c * R[p, x] * R[p, y]
    # input shaft: the sun's rotation deviation against a torsional spring to the housing
    s = el.shaft
    f[s] += el.shaft_k * q[s] + el.shaft_c * v[s]
    K[s, s] += el.shaft_k
    C[s, s] += el.shaft_c


@kernel
def newmark_steps(el, g, first, stop, mass, q, v, a, beta, gamma, tolerance, cycle_tolerance,
                  max_iterations, out_q, out_v):
    """Advance the state (q, v, a), given at the step before `first`, through steps first..stop-1
    of g by the Newmark rule with Newton iterations; q, v, a are updated in place and the
    state after each step is written to out_q[k], out_v[k].

    A step has converged when the Newton update is below `tolerance`, or when the
    iterations have settled into a two-state cycle whose update is below
    `cycle_tolerance`: a contact sits exactly at its switch (a pin at zero force,
    or its dashpot at the point of pulling), where the tangent jumps and Newton
    alternates between the two sides.  Returns (most Newton iterations in one
    step, steps that did not converge)."""
    n = q.size
    f = np.empty(n)
    K = np.empty((n, n))
    C = np.empty((n, n))
    M = np.diag(mass)
    most, failed = 0, 0
    for k in range(first, stop):
        h = g.h[k]
        q_old, v_old, a_old = q.copy(), v.copy(), a.copy()
        q[:] = q_old + h * v_old + 0.5 * h * h * a_old     # average-acceleration predictor
        converged = False
        it = 0
        last, before = np.inf, np.inf
        while it < max_iterations:
            it += 1
            a[:] = (q - q_old - h * v_old) / (beta * h * h) - (0.5 / beta - 1.0) * a_old
            v[:] = v_old + h * ((1.0 - gamma) * a_old + gamma * a)
            element_forces(el, g, k, q, v, f, K, C)
            residual = mass * a + f - g.external[k]
            J = M / (beta * h * h) + C * (gamma / (beta * h)) + K
            dq = np.linalg.solve(J, -residual)
            q += dq
            size = np.max(np.abs(dq))
            if size < tolerance or (size < cycle_tolerance and abs(size - before) <= 1e-3 * size):
                converged = True
                break
            last, before = size, last
        most = max(most, it)
        failed += 0 if converged else 1
        a[:] = (q - q_old - h * v_old) / (beta * h * h) - (0.5 / beta - 1.0) * a_old
        v[:] = v_old + h * ((1.0 - gamma) * a_old + gamma * a)
        out_q[k] = q
        out_v[k] = v
    return most, failed
