"""The quasi-static Newton iteration compiled, one (reducer, angle) pair at a time.

`newton.newton` iterates a whole chunk of pairs together in numpy.  Each pair
is a small problem (six disc unknowns, a few more per bearing with
clearance), so in numpy nearly all the time is the Python cost of the many
small array operations, not arithmetic; and a chunk iterates until its
slowest pair has converged.  Here numba compiles the same iteration for one
pair, and the pairs are solved one after another, each stopping when it has
converged.  The algorithm is that of `newton.newton`, step for step: the
primal-dual first step with the guessed pins (and bearings) engaged, then
semismooth Newton steps on the true energy, a full step where it lowers the
energy and the exact line search otherwise, the same tolerances.  Every step
after the first starts where the step before landed, and a full step lands at
its trial point, whose energy the step needs anyway: there one pass over the
elements gives the energy, the gradient and the Hessian together
(`_evaluate`), the same sums in the same order, so the numbers are those of
the separate functions to the bit (tests/test_newton_kernel.py).  The two
agree to round-off (tests/test_newton_kernel.py); the numpy iteration is used
where numba is absent or switched off (RVTE_NUMBA=0, `newton_kernel.COMPILED`).

Array arguments, B pairs, nN reduced unknowns, K pins per disc, p bearings
with clearance (p may be 0):
angle: (B,) each pair's angle, indexing K, Kh: (A, nN, nN) reduced stiffness per angle, and
what the Hessian adds (the mode stiffness), and brg_rows: (A, p, 2, nN) the bearings' rows per
angle; brg_cols: (p, w) the unknowns those touch (`equivalent.touched_columns`); f: (B, nN); rows:
(B, 2, K, 3); pin_b: (B, 2, K); pin_local: (2, 3);
brg_off: (B, p, 2); c_half: (B, p); brg_law: (p, 3), each bearing's
stiffness k, roller-law constant a (0: linear) and series compliance; pin_law: (3,) the pins'
law (`pin_law.contact`: stated stiffness k, b, F*); table: (2, T) the
roller law's table (`roller_law.TABLE_E`, `TABLE_DE`);
toward: (B, p, 2); guess: (B, 2, K) bool; q: (B, nN), the start, overwritten
by the solution.
"""

from __future__ import annotations

import inspect

import numpy as np

from ..base.compiled import COMPILED, kernel  # noqa: F401 (COMPILED: whether the iteration runs compiled)
from ..laws.pin_law import contact
from ..laws.roller_law import roller_law

STALL_STEP = 1e-12  # m: a full step at most this long that changes the energy by no more than its
# round-off (the 1e-13 |E| the full step's test allows) is a stalled one; `stall_steps` of them
# in a row end a pair as converged where the caller asks for it (`solver.ReducedSystem._release`,
# its retries).  Where a stiff bearing sits exactly on its clearance circle the steps can
# alternate between its two sides just above the step tolerance (1.3e-14 m seen) to the
# iteration's limit.  Not the default: many pairs take ten and more such steps before one
# falls below the tolerance (the weak springs make the Hessians' condition about 1e9), and a
# test so near round-off would turn it into differences of up to 6e-5 arcsec.


@kernel
def _deflections(rows, pin_b, pin_local, q, out):
    """Pin deflections out (2, K) of one pair at q (nN,)."""
    for j in range(2):
        a, b, c = q[pin_local[j, 0]], q[pin_local[j, 1]], q[pin_local[j, 2]]
        for k in range(rows.shape[1]):
            out[j, k] = rows[j, k, 0] * a + rows[j, k, 1] * b + rows[j, k, 2] * c + pin_b[j, k]


@kernel
def _bearing_deflections(brg_rows, brg_cols, brg_off, q, out):
    """Bearing deflections out (p, 2) of one pair at q (nN,)."""
    for b in range(brg_rows.shape[0]):
        for x in range(2):
            s = brg_off[b, x]
            for w in range(brg_cols.shape[1]):
                i = brg_cols[b, w]
                if i < 0:
                    break
                s += brg_rows[b, x, i] * q[i]
            out[b, x] = s


@kernel
def _radial(s, c_half, law, table):
    """(energy, force, radial stiffness, force / s) of an isotropic bearing with free play
    c_half at radial deflection s: k (s - c) outside the play for a linear one (law[1] == 0),
    the roller law (`roller_law.roller_law`) for the others; nothing inside the play."""
    if s <= c_half:
        return 0.0, 0.0, 0.0, 0.0
    if law[1] == 0.0:
        k = law[0]
        over = s - c_half
        return 0.5 * k * over * over, k * over, k, k * (1.0 - c_half / s)
    energy, force, stiffness = roller_law(table[0], table[1], s, c_half, law[1], law[2])
    return energy, force, stiffness, force / s


@kernel
def _bearing(dx, dy, c_half, law, table):
    """(fx, fy, txx, txy, tyy): force and tangent stiffness of an isotropic bearing with free
    play c_half at deflection (dx, dy) (`_radial`): F(|d|) along d, the tangent F' along d
    and F/|d| across it."""
    norm = max(np.sqrt(dx * dx + dy * dy), 1e-300)
    if norm <= c_half:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    _, force, radial, across = _radial(norm, c_half, law, table)
    nx, ny = dx / norm, dy / norm
    return (
        force * nx,
        force * ny,
        across + (radial - across) * nx * nx,
        (radial - across) * nx * ny,
        across + (radial - across) * ny * ny,
    )


@kernel
def _energy(
    K, f, rows, pin_b, pin_local, pin_law, brg_rows, brg_cols, brg_off, c_half, brg_law, table, q, delta, d
):
    """Reduced energy of one pair at q [J] (up to a constant); pin deflections into delta
    (2, K) and bearing deflections into d (p, 2)."""
    n = q.size
    e = 0.0
    for i in range(n):
        kq = 0.0
        for j in range(n):
            kq += K[i, j] * q[j]
        e += q[i] * (0.5 * kq + f[i])
    _deflections(rows, pin_b, pin_local, q, delta)
    for j in range(2):
        for k in range(delta.shape[1]):
            e += contact(delta[j, k], pin_law)[0]
    _bearing_deflections(brg_rows, brg_cols, brg_off, q, d)
    for b in range(d.shape[0]):
        e += _radial(np.sqrt(d[b, 0] ** 2 + d[b, 1] ** 2), c_half[b], brg_law[b], table)[0]
    return e


@kernel
def _add_bearing(brg_rows, cols, b, gx, gy, txx, txy, tyy, grad, hess):
    """Bearing b's force (gx, gy) into grad and its stiffness [[txx, txy], [txy, tyy]] into hess,
    over the unknowns `cols` it touches (`equivalent.touched_columns`; a row that is zero at this
    angle adds a zero)."""
    for wi in range(cols.size):
        i = cols[wi]
        if i < 0:
            break
        rx, ry = brg_rows[b, 0, i], brg_rows[b, 1, i]
        grad[i] += rx * gx + ry * gy
        ux, uy = txx * rx + txy * ry, txy * rx + tyy * ry
        for wj in range(cols.size):
            j = cols[wj]
            if j < 0:
                break
            hess[i, j] += ux * brg_rows[b, 0, j] + uy * brg_rows[b, 1, j]


@kernel
def _gradient_hessian(
    K,
    Kh,
    f,
    rows,
    pin_b,
    pin_local,
    pin_law,
    brg_rows,
    brg_cols,
    brg_off,
    c_half,
    brg_law,
    table,
    toward,
    has_toward,
    gap_tolerance,
    q,
    guess,
    use_guess,
    engaged,
    grad,
    hess,
    true_grad,
    used,
    delta,
    d,
):
    """`newton.Work.gradient_hessian` for one pair, into grad, hess, true_grad (nN,) / (nN, nN)
    and used (2, K); delta and d are work space."""
    n = q.size
    kp = pin_law[0]
    for i in range(n):
        for j in range(n):
            hess[i, j] = K[i, j] + Kh[i, j]
    for i in range(n):
        s = f[i]
        for j in range(n):
            s += K[i, j] * q[j]
        grad[i] = s
        true_grad[i] = s
    _deflections(rows, pin_b, pin_local, q, delta)
    for j in range(2):
        loc = pin_local[j]
        for k in range(rows.shape[1]):
            dk = delta[j, k]
            _, true_force, tangent = contact(dk, pin_law)
            if use_guess:  # bonded at its real gap by the stated stiffness
                act = guess[j, k]
                force = kp * dk if act else 0.0
                tangent = kp
            else:  # at contact exactly: touching, the stated stiffness
                act = dk > -gap_tolerance
                force = true_force
                if dk <= 0.0:
                    tangent = kp
            used[j, k] = act
            if force != 0.0 or true_force != 0.0:  # an open pin adds nothing
                for x in range(3):
                    grad[loc[x]] += force * rows[j, k, x]
                    true_grad[loc[x]] += true_force * rows[j, k, x]
            if act:
                for x in range(3):
                    for y in range(3):
                        hess[loc[x], loc[y]] += tangent * rows[j, k, x] * rows[j, k, y]
    if brg_rows.shape[0] == 0:
        return
    _bearing_deflections(brg_rows, brg_cols, brg_off, q, d)
    for b in range(d.shape[0]):
        dx, dy = d[b, 0], d[b, 1]
        kb, c = brg_law[b, 0], c_half[b]
        fx, fy, txx, txy, tyy = _bearing(dx, dy, c, brg_law[b], table)  # the true bearing force
        gx, gy = fx, fy
        if engaged:
            txx, txy, tyy = kb, 0.0, kb
            if has_toward:
                gx, gy = (dx - c * toward[b, 0]) * kb, (dy - c * toward[b, 1]) * kb
        cols = brg_cols[b]
        for wi in range(cols.size):
            i = cols[wi]
            if i < 0:
                break
            true_grad[i] += brg_rows[b, 0, i] * fx + brg_rows[b, 1, i] * fy
        _add_bearing(brg_rows, cols, b, gx, gy, txx, txy, tyy, grad, hess)


@kernel
def _evaluate(
    K,
    Kt,
    f,
    rows,
    pin_b,
    pin_local,
    pin_law,
    brg_rows,
    brg_cols,
    brg_off,
    c_half,
    brg_law,
    table,
    gap_tolerance,
    q,
    grad,
    hess,
    used,
    delta,
    d,
):
    """The energy of one pair at q (returned), as `_energy` gives it, and into grad and hess its
    gradient and the iteration's Hessian there, as `_gradient_hessian` gives them with nothing
    guessed or engaged: the same sums in the same order, in one pass over the elements where
    those two make one each (every Newton step after the first is evaluated where the step
    before landed, and a full step lands at its trial point).  Kt: K + Kh, the Hessian's
    constant part, summed once per pair."""
    n = q.size
    kp = pin_law[0]
    e = 0.0
    for i in range(n):
        kq, g = 0.0, f[i]  # summed as the two functions sum them, to the bit
        for j in range(n):
            kq += K[i, j] * q[j]
            g += K[i, j] * q[j]
            hess[i, j] = Kt[i, j]
        grad[i] = g
        e += q[i] * (0.5 * kq + f[i])
    _deflections(rows, pin_b, pin_local, q, delta)
    for j in range(2):
        loc = pin_local[j]
        for k in range(rows.shape[1]):
            dk = delta[j, k]
            energy, force, tangent = contact(dk, pin_law)
            e += energy
            act = dk > -gap_tolerance
            if dk <= 0.0:
                tangent = kp
            used[j, k] = act
            if force != 0.0:  # an open pin adds nothing
                for x in range(3):
                    grad[loc[x]] += force * rows[j, k, x]
            if act:
                for x in range(3):
                    for y in range(3):
                        hess[loc[x], loc[y]] += tangent * rows[j, k, x] * rows[j, k, y]
    if brg_rows.shape[0] == 0:
        return e
    _bearing_deflections(brg_rows, brg_cols, brg_off, q, d)
    for b in range(d.shape[0]):
        dx, dy = d[b, 0], d[b, 1]
        c = c_half[b]
        # `_bearing` and the energy of `_energy` from one evaluation of the law
        s = np.sqrt(dx**2 + dy**2)
        norm = max(s, 1e-300)
        if norm <= c:
            continue  # inside its play: adds nothing
        energy, force, radial, across = _radial(norm, c, brg_law[b], table)
        if s != norm:
            energy = _radial(s, c, brg_law[b], table)[0]
        e += energy
        nx, ny = dx / norm, dy / norm
        fx, fy = force * nx, force * ny
        txx, txy, tyy = (
            across + (radial - across) * nx * nx,
            (radial - across) * nx * ny,
            across + (radial - across) * ny * ny,
        )
        _add_bearing(brg_rows, brg_cols[b], b, fx, fy, txx, txy, tyy, grad, hess)
    return e


@kernel
def _solve_factored(L, b, x):
    """x = (L L^T)^-1 b with the Cholesky factor L (n, n) that `_solve_spd` left."""
    n = b.size
    for i in range(n):
        v = b[i]
        for k in range(i):
            v -= L[i, k] * x[k]
        x[i] = v / L[i, i]
    for i in range(n - 1, -1, -1):
        v = x[i]
        for k in range(i + 1, n):
            v -= L[k, i] * x[k]
        x[i] = v / L[i, i]


@kernel
def _solve_spd(A, b, L, x):
    """x = A^-1 b for the symmetric positive definite Hessian A (n, n) of one pair, by Cholesky
    into L (n, n); False where a pivot is not positive (the caller then solves by LU).
    LAPACK through numba costs about three times as much for these 10-20 unknowns, all of it
    call overhead."""
    n = b.size
    for j in range(n):
        pivot = A[j, j]
        for k in range(j):
            pivot -= L[j, k] * L[j, k]
        if not pivot > 0.0:
            return False
        pivot = np.sqrt(pivot)
        L[j, j] = pivot
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / pivot
    _solve_factored(L, b, x)
    return True


@kernel
def _slope(alpha, quad, lin, delta0, ddelta, pin_law, d0, dd, c_half, brg_law, table):
    """(first, second) derivative of one pair's energy along its line at alpha."""
    d1 = quad * alpha + lin
    d2 = quad
    for j in range(2):
        for k in range(delta0.shape[1]):
            _, force, tangent = contact(delta0[j, k] + alpha * ddelta[j, k], pin_law)
            d1 += force * ddelta[j, k]
            d2 += tangent * ddelta[j, k] * ddelta[j, k]
    for b in range(d0.shape[0]):
        fx, fy, txx, txy, tyy = _bearing(
            d0[b, 0] + alpha * dd[b, 0], d0[b, 1] + alpha * dd[b, 1], c_half[b], brg_law[b], table
        )
        d1 += fx * dd[b, 0] + fy * dd[b, 1]
        d2 += dd[b, 0] * (txx * dd[b, 0] + txy * dd[b, 1]) + dd[b, 1] * (txy * dd[b, 0] + tyy * dd[b, 1])
    return d1, d2


@kernel
def _line_search(
    K,
    f,
    rows,
    pin_b,
    pin_local,
    pin_law,
    brg_rows,
    brg_cols,
    brg_off,
    c_half,
    brg_law,
    table,
    q,
    step,
    delta0,
    ddelta,
    d0,
    dd,
    zero_b,
    zero_d,
):
    """`newton.Work.line_search` for one pair: the exact minimiser of the energy along step."""
    n = q.size
    quad, lin = 0.0, 0.0
    for i in range(n):
        ks, kq = 0.0, 0.0
        for j in range(n):
            ks += K[i, j] * step[j]
            kq += K[i, j] * q[j]
        quad += step[i] * ks
        lin += (kq + f[i]) * step[i]
    _deflections(rows, pin_b, pin_local, q, delta0)
    _deflections(rows, zero_b, pin_local, step, ddelta)
    _bearing_deflections(brg_rows, brg_cols, brg_off, q, d0)
    _bearing_deflections(brg_rows, brg_cols, zero_d, step, dd)
    d1_0, _ = _slope(0.0, quad, lin, delta0, ddelta, pin_law, d0, dd, c_half, brg_law, table)
    lo, hi = 0.0, 1.0
    d1, d2 = _slope(hi, quad, lin, delta0, ddelta, pin_law, d0, dd, c_half, brg_law, table)
    for _ in range(60):  # bracket: grow hi until the derivative is >= 0
        if d1 >= 0.0:
            break
        lo = hi
        hi *= 4.0
        d1, d2 = _slope(hi, quad, lin, delta0, ddelta, pin_law, d0, dd, c_half, brg_law, table)
    alpha = hi
    if d1_0 >= 0.0:
        return 0.0  # no descent left: the pair is at its minimum
    tolerance = 1e-12 * abs(d1_0) + 1e-300
    if abs(d1) <= tolerance:
        return alpha
    for _ in range(60):  # safeguarded Newton on the derivative
        if d1 > 0.0:
            hi = alpha
        if d1 < 0.0:
            lo = alpha
        trial = alpha - d1 / (d2 if d2 > 0.0 else 1.0)
        if d2 > 0.0 and lo < trial < hi:
            alpha = trial
        else:
            alpha = 0.5 * (lo + hi)
        d1, d2 = _slope(alpha, quad, lin, delta0, ddelta, pin_law, d0, dd, c_half, brg_law, table)
        if abs(d1) <= tolerance or hi - lo <= 1e-15 * hi:
            break
    return alpha


@kernel
def newton_pairs(
    angle,
    K,
    Kh,
    brg_rows,
    brg_cols,
    f,
    rows,
    pin_b,
    pin_local,
    pin_law,
    brg_off,
    c_half,
    brg_law,
    table,
    toward,
    has_toward,
    guess,
    q,
    warm,
    chain,
    release,
    mode_unit,
    max_iterations,
    step_tolerance,
    gap_tolerance,
    converged,
    iterations,
    stall_steps,
):
    """Solve every pair; q (B, nN) holds the starts and receives the solutions, converged (B,)
    bool whether each pair converged, iterations (B,) how many Newton steps it took.

    warm: every pair starts from its q (otherwise from q with the guessed pins
    bonded: the primal-dual first step); chain (B,) bool: the pair starts instead from the
    solution just found for the pair before it (its neighbouring angle, `newton.chain_links`),
    or, where that pair was itself linked, from the line through the two solutions before
    it (their linear extrapolation to its angle), except where the energy is piecewise
    quadratic (`smooth`).  release > 0: each converged pair then lets go of the weak springs
    of stiffness `release` about it (`solver.ReducedSystem.reg_matrix`, their direction
    across the unit mode mode_unit (A, n) at its angle): one Newton step, q += H^-1 R q,
    with the Hessian H already factored at the solution (`newton.release_step`).  stall_steps >
    0: that many stalled steps in a row (STALL_STEP) also end a pair as converged."""
    B, n = q.shape
    p = brg_rows.shape[1]
    Kp = rows.shape[2]
    # piecewise quadratic (no bearing with clearance, linear pins): a consistent active set is exact
    smooth = p == 0 and pin_law[1] == 0.0
    grad, true_grad, grad_next = np.empty(n), np.empty(n), np.empty(n)
    hess, hess_next = np.empty((n, n)), np.empty((n, n))
    used, used_next = np.empty((2, Kp), dtype=np.bool_), np.empty((2, Kp), dtype=np.bool_)
    delta, delta_trial, ddelta = np.empty((2, Kp)), np.empty((2, Kp)), np.empty((2, Kp))
    d, d_trial, dd = np.empty((p, 2)), np.empty((p, 2)), np.empty((p, 2))
    zero_b, zero_d = np.zeros((2, Kp)), np.zeros((p, 2))
    trial_q, step = np.empty(n), np.empty(n)
    factor, Kts = np.empty((n, n)), np.empty((n, n))
    pull = np.empty(n)
    for s in range(B):
        qs = q[s]
        # piecewise quadratic, the primal-dual first step lands at once, and where a pin ends
        # within the gap tolerance of its switch a warm start may settle on its other side
        linked = chain[s] and s > 0 and not smooth
        if linked and s > 1 and chain[s - 1]:
            # two neighbours solved: on along the line through them
            for i in range(n):
                qs[i] = 2.0 * q[s - 1, i] - q[s - 2, i]
        elif linked:
            qs[:] = q[s - 1]
        Ks, Khs, fs, rs, bs = K[angle[s]], Kh[angle[s]], f[s], rows[s], pin_b[s]
        for i in range(n):
            for j in range(n):
                Kts[i, j] = Ks[i, j] + Khs[i, j]
        Bs, os_, cs = brg_rows[angle[s]], brg_off[s], c_half[s]
        guessed = not (warm or linked)  # the first step bonds the guessed pins
        # ready: grad, hess and used hold the true gradient and Hessian at qs, evaluated with
        # its energy (`_evaluate`); every step but a guessed first one starts so
        ready = not guessed
        if ready:
            energy = _evaluate(
                Ks,
                Kts,
                fs,
                rs,
                bs,
                pin_local,
                pin_law,
                Bs,
                brg_cols,
                os_,
                cs,
                brg_law,
                table,
                gap_tolerance,
                qs,
                grad,
                hess,
                used,
                delta,
                d,
            )
        else:
            energy = _energy(
                Ks, fs, rs, bs, pin_local, pin_law, Bs, brg_cols, os_, cs, brg_law, table, qs, delta, d
            )
        done = False
        stalls = 0  # stalled steps in a row (STALL_STEP)
        it = 0
        while it < max_iterations:
            it += 1
            first = it == 1 and guessed
            if not ready:
                _gradient_hessian(
                    Ks,
                    Khs,
                    fs,
                    rs,
                    bs,
                    pin_local,
                    pin_law,
                    Bs,
                    brg_cols,
                    os_,
                    cs,
                    brg_law,
                    table,
                    toward[s],
                    has_toward,
                    gap_tolerance,
                    qs,
                    guess[s],
                    first,
                    first,
                    grad,
                    hess,
                    true_grad,
                    used,
                    delta,
                    d,
                )
            slope_grad = grad if ready else true_grad
            factored = _solve_spd(hess, grad, factor, step)
            if factored:
                for i in range(n):
                    step[i] = -step[i]
            else:
                step[:] = -np.linalg.solve(hess, grad)
            largest_step, largest_trial = 0.0, 0.0
            for i in range(n):
                trial_q[i] = qs[i] + step[i]
                largest_step = max(largest_step, abs(step[i]))
                largest_trial = max(largest_trial, abs(trial_q[i]))
            if (not first) and largest_step <= step_tolerance + 1e-12 * largest_trial:
                # the step no longer moves: taken whole, and the pair is done without the
                # evaluation at its end (which only its line search would read)
                qs[:] = trial_q
                done = True
                break
            trial = _evaluate(
                Ks,
                Kts,
                fs,
                rs,
                bs,
                pin_local,
                pin_law,
                Bs,
                brg_cols,
                os_,
                cs,
                brg_law,
                table,
                gap_tolerance,
                trial_q,
                grad_next,
                hess_next,
                used_next,
                delta_trial,
                d_trial,
            )
            slope = 0.0
            for i in range(n):
                slope += slope_grad[i] * step[i]
            full = trial <= energy + 1e-4 * slope + 1e-13 * abs(energy)
            alpha = 1.0
            if not full:
                alpha = _line_search(
                    Ks,
                    fs,
                    rs,
                    bs,
                    pin_local,
                    pin_law,
                    Bs,
                    brg_cols,
                    os_,
                    cs,
                    brg_law,
                    table,
                    qs,
                    step,
                    delta,
                    ddelta,
                    d,
                    dd,
                    zero_b,
                    zero_d,
                )
            largest_move, largest_q = 0.0, 0.0
            for i in range(n):
                qs[i] += alpha * step[i]
                largest_move = max(largest_move, abs(alpha * step[i]))
                largest_q = max(largest_q, abs(qs[i]))
            # Done when a step no longer moves (a guessed first step says nothing of that), or,
            # piecewise quadratic, when a full step landed where exactly the pins it assumed touch.
            done = (not first) and largest_move <= step_tolerance + 1e-12 * largest_q
            if stall_steps > 0 and not done:
                stalled = full and (not first) and largest_move <= STALL_STEP
                stalls = stalls + 1 if stalled and abs(trial - energy) <= 1e-13 * abs(energy) else 0
                done = stalls >= stall_steps
            if smooth and full and not done:
                consistent = True
                for j in range(2):
                    for k in range(Kp):
                        dk = delta_trial[j, k]
                        if (used[j, k] and dk < -gap_tolerance) or (not used[j, k] and dk > gap_tolerance):
                            consistent = False
                done = consistent
            if done:
                break
            if full:  # landed on the trial point: its evaluation is the next
                energy = trial
                grad, grad_next = grad_next, grad
                hess, hess_next = hess_next, hess
                used, used_next = used_next, used
            else:
                energy = _evaluate(
                    Ks,
                    Kts,
                    fs,
                    rs,
                    bs,
                    pin_local,
                    pin_law,
                    Bs,
                    brg_cols,
                    os_,
                    cs,
                    brg_law,
                    table,
                    gap_tolerance,
                    qs,
                    grad,
                    hess,
                    used,
                    delta,
                    d,
                )
            ready = True
        if release > 0.0 and done:
            m = mode_unit[angle[s]]
            along = 0.0
            for i in range(n):
                along += m[i] * qs[i]
            for i in range(n):
                pull[i] = release * (qs[i] - m[i] * along)
            if factored:
                _solve_factored(factor, pull, step)
            else:
                step[:] = np.linalg.solve(hess, pull)
            for i in range(n):
                qs[i] += step[i]
        converged[s] = done
        iterations[s] = it


@kernel
def hessians(
    angle,
    K,
    Kh,
    brg_rows,
    brg_cols,
    f,
    rows,
    pin_b,
    pin_local,
    pin_law,
    brg_off,
    c_half,
    brg_law,
    table,
    q,
    gap_tolerance,
    out,
):
    """The Newton iteration's Hessian (the true contacts, none guessed) of every pair at q
    (B, nN) into out (B, nN, nN): `newton.Work.hessian` with `active` None."""
    B, n = q.shape
    p = brg_rows.shape[1]
    Kp = rows.shape[2]
    grad, true_grad = np.empty(n), np.empty(n)
    used = np.empty((2, Kp), dtype=np.bool_)
    delta, d = np.empty((2, Kp)), np.empty((p, 2))
    toward, guess, engaged = np.zeros((p, 2)), np.zeros((2, Kp), dtype=np.bool_), False
    for s in range(B):
        _gradient_hessian(
            K[angle[s]],
            Kh[angle[s]],
            f[s],
            rows[s],
            pin_b[s],
            pin_local,
            pin_law,
            brg_rows[angle[s]],
            brg_cols,
            brg_off[s],
            c_half[s],
            brg_law,
            table,
            toward,
            False,
            gap_tolerance,
            q[s],
            guess,
            False,
            engaged,
            grad,
            out[s],
            true_grad,
            used,
            delta,
            d,
        )


_NEWTON_PAIRS_PARAMETERS = tuple(inspect.signature(getattr(newton_pairs, "py_func", newton_pairs)).parameters)


def newton_pairs_argument(name: str) -> int:
    """Position of `newton_pairs`' argument `name`, for wrappers that read its arrays (the
    benchmarks' and tests' step counts read `iterations` after the call); taken from the
    kernel as defined, so a wrapper in its place does not change it."""
    return _NEWTON_PAIRS_PARAMETERS.index(name)
