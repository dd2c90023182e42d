"""The dynamic model's inner loop: element forces and Newmark steps, compiled when numba is there.

A time step of the dynamic model is a few Newton iterations, each summing
some thirty springs into an 18 x 18 (two cranks) or 21 x 21 (three cranks)
system and solving it.  In numpy every one of those small operations costs a
microsecond of Python, so the run is slow however little arithmetic it does.
These two functions hold that loop; numba compiles them (`COMPILED`) when it
is installed, and without it (a host Python that lacks it, or RVTE_NUMBA=0)
they run as they are, as plain numpy: the same results, several times slower.
A step's Newton iteration takes three updates as a rule (some 1e-6, 1e-10 and 1e-14 m):
the third comes from the second's factors of the tangent and a residual evaluated
without one (`newmark_steps`, `forces_only`): some 30 % of the step's eliminations
and of its tangents' assembly saved.

Friction (docs/model.md section 9) rides on the same elements: every pin, bearing and
mesh has a slip, its sliding speed [m/s], the nominal kinematics' plus a row over the
unknowns' velocities, and resists it with R s(w), R its Coulomb force mu N (N the
element's own normal force) plus a drag, and s(w) = w / sqrt(w^2 + slip_scale^2) the
regularised sign of the slip.  Breakaway (`stribeck`): the Coulomb force, and a seal's drag,
times 1 + (f_s - 1) exp(-(w / v_s)^2), f_s the static friction factor (1: the law above,
to the bit), v_s the Stribeck speed; the bearings' drag and the churning are viscous and
keep their value.

The element data come in two named tuples built by `DynamicModel`:
`Elements` (what does not change over the run) and `Geometry` (rows, offsets,
stiffnesses and external forces at a run of time steps, axis 0 the step).
"""

from __future__ import annotations

import warnings
from collections import namedtuple

import numpy as np

from ..base.compiled import COMPILED, kernel
from ..laws.pin_law import contact
from ..laws.roller_law import roller_law

LINE_SEARCH_HALVINGS = 8  # a Newton update is halved at most this often (to 1/256)
REUSE_BELOW = 1e-8  # [m] a Newton update this small: the next from its factors
EXP_ZERO = 746.0  # exp(-x) is 0.0 in double precision from x = 745.14 on (below 2^-1075)

Elements = namedtuple(
    "Elements",
    [
        "linear_c",  # (m,) dashpots of the meshes and sun support [N s/m]
        "half_clearance",  # (nb,) free radial play of each bearing [m]
        "bearing_k",  # (nb,) [N/m]
        "bearing_c",  # (nb,) [N s/m]
        "bearing_law",  # (nb, 2): roller-law constant a (0: the linear spring bearing_k), series
        # compliance [m/N]
        "law_table",  # (2, T): the roller law's table (roller_law.TABLE_E, TABLE_DE)
        "pin_dofs",  # (2, 3) unknowns of each disc: x, y, rotation
        "pin_law",  # (3,) the pins' law unless IMPACT (`pin_law.contact`: k [N/m], b, F*)
        "pin_c",  # pin dashpot (IMPACT: its c_max) [N s/m]
        "impact",  # True: IMPACT law, False: linear
        "impact_k",  # IMPACT stiffness [N/m^e]
        "impact_exponent",
        "impact_depth",  # IMPACT d_max [m]
        "shaft",  # index of the sun's rotation
        "shaft_k",  # input shaft stiffness over scale^2 [N/m]
        "shaft_c",  # its dashpot over scale^2 [N s/m]
        "pin_friction",  # the pins' Coulomb coefficient: the smaller of their two contacts'
        "turn_cols",  # (E, w) unknowns the slip of each turning contact touches (bearings, meshes,
        # the seal; -1: none)
        "turn_rows",  # (E, w) their coefficients: slip speed [m/s] per unknown velocity
        "turn_source",  # (E,) the element whose normal force presses it: a bearing b (0 .. nb-1),
        # a mesh nb + e, or -1 (a load-free resistance only)
        "turn_friction",  # (E,) its Coulomb coefficient (0: none)
        "slip_scale",  # [m/s] the regularised sign's slip scale
        "line_search",  # True: Newton updates halved until the residual falls (with friction)
        "modal_c",  # (n, n) modal damping on the unknowns' velocities [N s/m]
        "static_factor",  # breakaway over running friction f_s (1: the regularised Coulomb law)
        "stribeck_speed",  # [m/s] the slip over which the friction falls from f_s x to 1 x
        "turn_breakaway",  # (E,) 1: the turning contact's drag breaks away too (a seal), 0: viscous
    ],
)

Scratch = namedtuple(
    "Scratch",
    [
        "bearing_load",  # (nb,) each bearing's normal force [N] (for the friction it presses)
        "bearing_grad",  # (nb, 2) its gradient over the bearing's (x, y) deflection [N/m]
        "mesh_load",  # (m,) each mesh's |force| [N]
        "mesh_sign",  # (m,) and its sign
        "disc_f",
        "disc_k",
        "disc_c",  # (3,), (3, 3), (3, 3): one disc's pins over its unknowns
    ],
)

Geometry = namedtuple(
    "Geometry",
    [
        "h",  # (A,) time step into each step [s] (the run's first: 0)
        "linear_cols",  # (m, w) unknowns each mesh or support row touches (-1: none)
        "L",  # (A, m, w) their coefficients
        "linear_k",
        "linear_offset",  # (A, m), (A, m)
        "bearing_cols",  # (nb, w)
        "B",  # (A, nb, 2, w)
        "bearing_offset",  # (A, nb, 2)
        "P",
        "pin_offset",  # (A, 2, z_p, 3), (A, 2, z_p)
        "external",  # (A, n) load and nominal-motion forces [N]
        "pin_tangent",  # (A, 2, z_p, 3) each pin's slip row over its disc's unknowns
        "pin_slip",  # (A, 2, z_p) the nominal slip [m/s]
        "turn_slip",  # (A, E) the turning contacts' nominal slip [m/s]
        "turn_drag",  # (A, E) their load-free resistance [N] at the nominal speed
    ],
)


def gather(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(A, E, ..., w) the coefficients of rows (A, E, ..., n) on the unknowns `cols` (E, w);
    zero where cols is -1."""
    A, n = rows.shape[0], rows.shape[-1]
    inner = rows.shape[2:-1]  # () for 1-D elements, (2,) for bearings
    k = int(np.prod(inner, dtype=int))
    base = np.arange(cols.shape[0] * k).reshape((cols.shape[0],) + inner + (1,)) * n
    flat = base + np.where(cols < 0, 0, cols).reshape((cols.shape[0],) + (1,) * len(inner) + (-1,))
    out = rows.reshape(A, -1)[:, flat]
    out[
        :,
        np.broadcast_to((cols < 0).reshape(flat.shape[:1] + (1,) * len(inner) + flat.shape[-1:]), flat.shape),
    ] = 0.0
    return out


@kernel
def regularised_sign(w, scale):
    """(s, ds/dw) of the slip w [m/s]: w / sqrt(w^2 + scale^2), the sign of w smoothed over
    `scale` (the exact sign for scale = 0 and w != 0)."""
    root = np.sqrt(w * w + scale * scale)
    if root == 0.0:
        return 0.0, 0.0
    return w / root, scale * scale / (root * root * root)


@kernel
def stribeck(w, factor, speed):
    """(g, dg/dw) of the slip w [m/s]: the friction over its running value, the Stribeck law
    g = 1 + (factor - 1) exp(-(w / speed)^2): `factor` at rest, 1 beyond a few `speed`;
    exactly (1, 0) for factor = 1."""
    if factor == 1.0:
        return 1.0, 0.0
    x = w / speed
    # beyond EXP_ZERO the exponential is 0.0 in double precision: not called there (a fast slip's
    # usual case), the same numbers to the bit
    bump = (factor - 1.0) * (np.exp(-x * x) if x * x < EXP_ZERO else 0.0)
    return 1.0 + bump, -2.0 * x / speed * bump


@kernel
def scratch(el, g):
    """The working arrays of `forces_into` for the elements el and geometry g: made once for
    a run of steps instead of at every evaluation."""
    nb, m = el.bearing_k.shape[0], g.linear_cols.shape[0]
    return Scratch(
        np.zeros(nb),
        np.zeros((nb, 2)),
        np.zeros(m),
        np.zeros(m),
        np.zeros(3),
        np.zeros((3, 3)),
        np.zeros((3, 3)),
    )


@kernel
def element_forces(el, g, a, q, v, f, K, C):
    """Forces of every element at step a of geometry g into f (n,), with their derivatives in
    q and v into K and C (n, n): the EOM is M q'' + f = F.  f, K, C are overwritten.
    Returns (friction power, damper power) [W]: what the contacts' friction and the
    damping (dashpots and the modal matrix) dissipate at this state (each >= 0)."""
    return forces_into(el, g, a, q, v, f, K, C, scratch(el, g))


@kernel
def forces_into(el, g, a, q, v, f, K, C, work):
    """`element_forces` with its working arrays `work` (`scratch`) given."""
    return forces_only(el, g, a, q, v, f, K, C, work, True)


@kernel(inline=True)
def forces_only(el, g, a, q, v, f, K, C, work, tangent):
    """`forces_into`, K and C only where `tangent` is True: else they are left as they are
    and the forces f and the powers are those it gives, to the bit (a residual whose
    tangent is not wanted: `newmark_steps` reusing an earlier one's elimination)."""
    f[:] = 0.0
    if tangent:
        K[:, :] = 0.0
        C[:, :] = 0.0
    friction_power, damper_power = 0.0, 0.0
    nb = el.bearing_k.shape[0]
    # each element's normal force and its gradient over the element's own unknowns (for the
    # friction it presses): bearings along (x, y), meshes signed by their force
    bearing_load, bearing_grad = work.bearing_load, work.bearing_grad
    mesh_load, mesh_sign = work.mesh_load, work.mesh_sign
    bearing_load[:] = 0.0
    bearing_grad[:, :] = 0.0
    # meshes and sun support: bilateral springs
    cols, L = g.linear_cols, g.L[a]
    for e in range(cols.shape[0]):
        delta, rate = g.linear_offset[a, e], 0.0
        for x in range(cols.shape[1]):
            delta += L[e, x] * q[cols[e, x]]
            rate += L[e, x] * v[cols[e, x]]
        k, c = g.linear_k[a, e], el.linear_c[e]
        force = k * delta + c * rate
        damper_power += c * rate * rate
        mesh_load[e] = abs(force)
        mesh_sign[e] = 1.0 if force >= 0.0 else -1.0
        for x in range(cols.shape[1]):
            if L[e, x] == 0.0:
                continue  # a padding column (`touched_columns`): adds nothing
            i = cols[e, x]
            f[i] += L[e, x] * force
            if not tangent:
                continue
            for y in range(cols.shape[1]):
                if L[e, y] != 0.0:
                    K[i, cols[e, y]] += k * L[e, x] * L[e, y]
                    if c != 0.0:  # the elements' dashpots are none but IMPACT's (modal damping)
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
            continue  # inside its play; a tight one always holds
        k, c = el.bearing_k[b], el.bearing_c[b]
        ux, uy = (dx / r, dy / r) if r > 0.0 else (0.0, 0.0)
        if el.bearing_law[b, 0] == 0.0:
            # force k (r - half) u: F' = k along u, F / r = k (1 - half / r) across it
            radial = k
            across = k * (1.0 - half / r) if half > 0.0 else k
        else:
            # the roller law (rvfmu/core/laws/roller_law.py): F(r) along u
            _, force, radial = roller_law(
                el.law_table[0], el.law_table[1], r, half, el.bearing_law[b, 0], el.bearing_law[b, 1]
            )
            across = force / r if r > 0.0 else 0.0
        fx, fy = across * dx + c * vx, across * dy + c * vy
        damper_power += c * (vx * vx + vy * vy)
        bearing_load[b] = across * r
        bearing_grad[b, 0], bearing_grad[b, 1] = radial * ux, radial * uy
        sxx = across + (radial - across) * ux * ux
        syy = across + (radial - across) * uy * uy
        sxy = (radial - across) * ux * uy
        for x in range(cols.shape[1]):
            i, bx, by = cols[b, x], B[b, 0, x], B[b, 1, x]
            if bx == 0.0 and by == 0.0:
                continue  # a padding column: adds nothing
            f[i] += bx * fx + by * fy
            if not tangent:
                continue
            tx, ty = sxx * bx + sxy * by, sxy * bx + syy * by
            for y in range(cols.shape[1]):
                j, cx, cy = cols[b, y], B[b, 0, y], B[b, 1, y]
                if cx == 0.0 and cy == 0.0:
                    continue
                K[i, j] += tx * cx + ty * cy
                if c != 0.0:
                    C[i, j] += c * (bx * cx + by * cy)
    # pins: unilateral along their normals, over each disc's own three unknowns; each disc's
    # pins are summed over its three unknowns first (`work.disc_*`), then added in once
    mu = el.pin_friction
    df, dk, dc = work.disc_f, work.disc_k, work.disc_c
    for j in range(2):
        dofs = el.pin_dofs[j]
        q0, q1, q2 = q[dofs[0]], q[dofs[1]], q[dofs[2]]
        v0, v1, v2 = v[dofs[0]], v[dofs[1]], v[dofs[2]]
        R, T = g.P[a, j], g.pin_tangent[a, j]  # (z_p, 3) normal and slip rows
        df[:] = 0.0
        dk[:, :] = 0.0
        dc[:, :] = 0.0
        for p in range(R.shape[0]):
            delta = g.pin_offset[a, j, p] + R[p, 0] * q0 + R[p, 1] * q1 + R[p, 2] * q2
            if delta <= 0.0:
                continue  # open
            rate = R[p, 0] * v0 + R[p, 1] * v1 + R[p, 2] * v2
            if el.impact:
                s = min(delta / el.impact_depth, 1.0)
                ramp = s * s * (3.0 - 2.0 * s)  # IMPACT's cubic step of the damping
                dramp = 6.0 * s * (1.0 - s) / el.impact_depth if delta < el.impact_depth else 0.0
                e = el.impact_exponent
                normal = el.impact_k * delta**e + el.pin_c * ramp * rate
                k = e * el.impact_k * delta ** (e - 1.0) + el.pin_c * dramp * rate
                c = el.pin_c * ramp
            else:
                _, spring, k = contact(delta, el.pin_law)
                normal = spring + el.pin_c * rate
                c = el.pin_c
            if normal <= 0.0:
                continue  # a separating dashpot pulls nothing
            damper_power += c * rate * rate
            if mu == 0.0:
                for x in range(3):
                    df[x] += R[p, x] * normal
                    if not tangent:
                        continue
                    for y in range(3):
                        dk[x, y] += k * R[p, x] * R[p, y]
                        dc[x, y] += c * R[p, x] * R[p, y]
                continue
            # friction along the tangent: mu g(w) N s(w), w the disc's slip past the pin
            w = g.pin_slip[a, j, p] + T[p, 0] * v0 + T[p, 1] * v1 + T[p, 2] * v2
            sign, dsign = regularised_sign(w, el.slip_scale)
            lift, dlift = stribeck(w, el.static_factor, el.stribeck_speed)
            mu_w = mu * lift
            resist = mu_w * normal
            friction_power += resist * sign * w
            slide = resist * dsign
            if dlift != 0.0:
                slide += mu * normal * dlift * sign
            for x in range(3):
                df[x] += R[p, x] * normal + T[p, x] * resist * sign
                if not tangent:
                    continue
                kx = k * R[p, x] + mu_w * sign * k * T[p, x]
                cx = c * R[p, x] + mu_w * sign * c * T[p, x]
                for y in range(3):
                    dk[x, y] += kx * R[p, y]
                    dc[x, y] += cx * R[p, y] + slide * T[p, x] * T[p, y]
        for x in range(3):
            f[dofs[x]] += df[x]
            if not tangent:
                continue
            for y in range(3):
                K[dofs[x], dofs[y]] += dk[x, y]
                C[dofs[x], dofs[y]] += dc[x, y]
    # input shaft: the sun's rotation deviation against a torsional spring to the housing
    s = el.shaft
    f[s] += el.shaft_k * q[s] + el.shaft_c * v[s]
    if tangent:
        K[s, s] += el.shaft_k
        C[s, s] += el.shaft_c
    damper_power += el.shaft_c * v[s] * v[s]
    # modal damping (DynamicModel.set_modal_damping): a constant matrix on the velocities
    for i in range(el.modal_c.shape[0]):
        force = 0.0
        for j in range(el.modal_c.shape[1]):
            force += el.modal_c[i, j] * v[j]
        if tangent:
            for j in range(el.modal_c.shape[1]):
                C[i, j] += el.modal_c[i, j]
        f[i] += force
        damper_power += v[i] * force
    # turning contacts: bearings, meshes, the seals and the churning parts resist their slip
    # with R s(w), R = mu N + drag, the breakaway's g(w) on mu N and a seal's drag; N's
    # gradient reaches the unknowns of the element that presses them
    cols, S = el.turn_cols, el.turn_rows
    for e in range(cols.shape[0]):
        drag, mu, source = g.turn_drag[a, e], el.turn_friction[e], el.turn_source[e]
        normal = 0.0
        if source >= nb:
            normal = mesh_load[source - nb]
        elif source >= 0:
            normal = bearing_load[source]
        resist = mu * normal + drag
        if resist == 0.0:
            continue
        w = g.turn_slip[a, e]
        for x in range(cols.shape[1]):
            if cols[e, x] >= 0:
                w += S[e, x] * v[cols[e, x]]
        sign, dsign = regularised_sign(w, el.slip_scale)
        slide, mu_w = resist * dsign, mu
        if el.static_factor != 1.0:
            lift, dlift = stribeck(w, el.static_factor, el.stribeck_speed)
            static = mu * normal + el.turn_breakaway[e] * drag  # what breaks away
            resist += (lift - 1.0) * static
            slide = resist * dsign + dlift * static * sign
            mu_w = mu * lift
        friction_power += resist * sign * w
        for x in range(cols.shape[1]):
            i = cols[e, x]
            if i < 0:
                continue
            f[i] += S[e, x] * resist * sign
            if not tangent:
                continue
            for y in range(cols.shape[1]):
                if cols[e, y] >= 0:
                    C[i, cols[e, y]] += slide * S[e, x] * S[e, y]
            if mu == 0.0 or normal == 0.0:
                continue
            scale = mu_w * sign * S[e, x]
            if source >= nb:  # N = |k delta + c rate| of mesh m
                m = source - nb
                for y in range(g.linear_cols.shape[1]):
                    j = g.linear_cols[m, y]
                    K[i, j] += scale * mesh_sign[m] * g.linear_k[a, m] * L[m, y]
                    C[i, j] += scale * mesh_sign[m] * el.linear_c[m] * L[m, y]
            else:  # N = F(r) of bearing `source`'s spring
                for y in range(g.bearing_cols.shape[1]):
                    j = g.bearing_cols[source, y]
                    K[i, j] += scale * (
                        bearing_grad[source, 0] * B[source, 0, y] + bearing_grad[source, 1] * B[source, 1, y]
                    )
    return friction_power, damper_power


@kernel
def _newmark_residual(el, g, k, q, v, a, q_old, v_old, a_old, h, beta, gamma, mass, f, K, C, residual, work):
    """The Newmark rule's acceleration and velocity at displacement q into a, v, the element
    forces into f, K, C (`forces_into`, working arrays `work`) and the step's residual
    M a + f - F into residual; returns the (friction, damper) powers."""
    return _residual(
        el, g, k, q, v, a, q_old, v_old, a_old, h, beta, gamma, mass, f, K, C, residual, work, True
    )


@kernel(inline=True)
def _residual(el, g, k, q, v, a, q_old, v_old, a_old, h, beta, gamma, mass, f, K, C, residual, work, tangent):
    """`_newmark_residual`, with K and C only where `tangent` is True (`forces_only`)."""
    for i in range(q.size):
        a[i] = (q[i] - q_old[i] - h * v_old[i]) / (beta * h * h) - (0.5 / beta - 1.0) * a_old[i]
        v[i] = v_old[i] + h * ((1.0 - gamma) * a_old[i] + gamma * a[i])
    powers = forces_only(el, g, k, q, v, f, K, C, work, tangent)
    for i in range(q.size):
        residual[i] = mass[i] * a[i] + f[i] - g.external[k, i]
    return powers


@kernel
def factor_in_place(A, pivots):
    """Gaussian elimination with partial pivoting kept for later right-hand sides
    (`solve_factored`): A becomes its LU factors (the multipliers below the diagonal, each
    in the row where it was used), pivots (n,) the row swapped into each column's place.
    False where a pivot is zero (A singular).  For the 18-21 unknowns of a step this costs
    about half of a LAPACK call through numba, which copies both arrays first; the
    elimination that solved in place (tests/test_dynamic_step_speed.py keeps it) gives the
    same x to the bit."""
    n = A.shape[0]
    for c in range(n):
        pivot, big = c, abs(A[c, c])
        for r in range(c + 1, n):
            if abs(A[r, c]) > big:
                pivot, big = r, abs(A[r, c])
        pivots[c] = pivot
        if big == 0.0:
            return False
        if pivot != c:
            for j in range(c, n):
                A[c, j], A[pivot, j] = A[pivot, j], A[c, j]
        for r in range(c + 1, n):
            m = A[r, c] / A[c, c]
            A[r, c] = m
            if m != 0.0:
                for j in range(c + 1, n):
                    A[r, j] -= m * A[c, j]
    return True


@kernel
def solve_factored(A, pivots, x):
    """x <- A^-1 x from the factors of `factor_in_place` (A, pivots unchanged)."""
    n = x.size
    for c in range(n):
        p = pivots[c]
        if p != c:
            x[c], x[p] = x[p], x[c]
        for r in range(c + 1, n):
            m = A[r, c]
            if m != 0.0:
                x[r] -= m * x[c]
    for r in range(n - 1, -1, -1):
        value = x[r]
        for j in range(r + 1, n):
            value -= A[r, j] * x[j]
        x[r] = value / A[r, r]


def _factor_numpy(A, pivots):
    """`factor_in_place` by LAPACK (getrf, whose pivots are the same swaps), for the plain
    numpy run."""
    from scipy.linalg import lu_factor

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a singular A is told by its zero pivot
        lu, swaps = lu_factor(A, check_finite=False)
    A[:, :] = lu
    pivots[:] = swaps
    return bool(np.all(np.diag(lu) != 0.0))


def _solve_factored_numpy(A, pivots, x):
    """`solve_factored` by LAPACK (getrs) on `_factor_numpy`'s factors."""
    from scipy.linalg import lu_solve

    x[:] = lu_solve((A, pivots), x, check_finite=False)


factor_step = factor_in_place if COMPILED else _factor_numpy
solve_factors = solve_factored if COMPILED else _solve_factored_numpy


@kernel
def _norm(x):
    """The Euclidean norm of x (n,), summed in order (what np.sqrt(np.sum(x * x)) gives, without
    its temporary array)."""
    total = 0.0
    for i in range(x.size):
        total += x[i] * x[i]
    return np.sqrt(total)


@kernel
def newmark_steps(
    el,
    g,
    first,
    stop,
    mass,
    q,
    v,
    a,
    beta,
    gamma,
    tolerance,
    cycle_tolerance,
    max_iterations,
    out_q,
    out_v,
    out_power,
):
    """Advance the state (q, v, a), given at the step before `first`, through steps first..stop-1
    of g by the Newmark rule with Newton iterations; q, v, a are updated in place and the
    state after each step is written to out_q[k], out_v[k], the power its friction and
    damping dissipate to out_power[k] ((friction, dampers) [W], at the last iteration's
    state: within the update's tolerance of the step's).

    A step has converged when the Newton update is below `tolerance`, or when the
    iterations have settled into a two-state cycle whose update is below
    `cycle_tolerance`: a contact sits exactly at its switch (a pin at zero force,
    or its dashpot at the point of pulling), where the tangent jumps and Newton
    alternates between the two sides.  With friction (`Elements.line_search`) each
    Newton update is halved until the step's residual falls (at most LINE_SEARCH_HALVINGS
    times): the regularised sign is a sigmoid over a slip of a few um/s, and a full
    Newton update from outside it overshoots to the other side and back.

    An update below REUSE_BELOW (Newton's quadratic phase) is followed by one from the same
    factors (`solve_factored`), at the residual alone (`forces_only`): the tangent there
    differs from the last one's by that update's share of the deflections, 1e-4 or less,
    and so does the next update from its Newton value, itself some 1e-14 m (a few
    1e-18 m apart).  Where that update is not yet below the tolerance (a contact switched),
    the next is Newton's again.  Returns (most Newton iterations in one step, steps that did
    not converge)."""
    n = q.size
    f, residual, dq, start = np.empty(n), np.zeros(n), np.empty(n), np.empty(n)
    q_old, v_old, a_old = np.empty(n), np.empty(n), np.empty(n)
    K, C, J = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    pivots = np.empty(n, dtype=np.int64)
    work = scratch(el, g)
    most, failed = 0, 0
    powers = (0.0, 0.0)
    for k in range(first, stop):
        h = g.h[k]
        ka, kc = 1.0 / (beta * h * h), gamma / (beta * h)
        for i in range(n):
            q_old[i], v_old[i], a_old[i] = q[i], v[i], a[i]
            q[i] = q_old[i] + h * v_old[i] + 0.5 * h * h * a_old[i]  # average-acceleration predictor
        converged = False
        it = 0
        last, before = np.inf, np.inf
        evaluated = False
        reuse = False  # this update from the last one's factors
        while it < max_iterations:
            it += 1
            if not evaluated:
                powers = _residual(
                    el,
                    g,
                    k,
                    q,
                    v,
                    a,
                    q_old,
                    v_old,
                    a_old,
                    h,
                    beta,
                    gamma,
                    mass,
                    f,
                    K,
                    C,
                    residual,
                    work,
                    not reuse,
                )
            for i in range(n):
                dq[i] = -residual[i]
            if reuse:
                solve_factors(J, pivots, dq)
            else:
                for i in range(n):  # J = K + kc C + ka M, as (C kc) + K: no temporaries
                    for j in range(n):
                        J[i, j] = C[i, j] * kc + K[i, j]
                    J[i, i] += mass[i] * ka
                if not factor_step(J, pivots):
                    break  # a singular tangent: the step fails
                solve_factors(J, pivots, dq)
            size = 0.0
            for i in range(n):
                size = max(size, abs(dq[i]))
            # the next update from these factors: after a small Newton update, not after one
            # from old factors (an update not yet converged after it needs a new tangent)
            reuse_next = not reuse and size < REUSE_BELOW
            if el.line_search and size >= tolerance:
                # (an update below the tolerance has converged: no line search, whose residual
                # could no longer fall below round-off and would halve it eight times for nothing)
                norm = _norm(residual)
                start[:] = q
                fraction = 1.0
                for _ in range(LINE_SEARCH_HALVINGS + 1):
                    for i in range(n):
                        q[i] = start[i] + fraction * dq[i]
                    powers = _residual(
                        el,
                        g,
                        k,
                        q,
                        v,
                        a,
                        q_old,
                        v_old,
                        a_old,
                        h,
                        beta,
                        gamma,
                        mass,
                        f,
                        K,
                        C,
                        residual,
                        work,
                        not reuse_next,
                    )
                    if _norm(residual) < norm:
                        break
                    fraction *= 0.5
                size *= fraction
                evaluated = True
            else:
                for i in range(n):
                    q[i] += dq[i]
                evaluated = False
            reuse = reuse_next
            if size < tolerance or (size < cycle_tolerance and abs(size - before) <= 1e-3 * size):
                converged = True
                break
            last, before = size, last
        most = max(most, it)
        failed += 0 if converged else 1
        for i in range(n):
            a[i] = (q[i] - q_old[i] - h * v_old[i]) * ka - (0.5 / beta - 1.0) * a_old[i]
            v[i] = v_old[i] + h * ((1.0 - gamma) * a_old[i] + gamma * a[i])
        out_q[k] = q
        out_v[k] = v
        out_power[k, 0], out_power[k, 1] = powers
    return most, failed
