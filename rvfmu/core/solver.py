"""Static equilibrium of the equivalent model for many (reducer, angle) pairs at once.

The equilibrium minimises a convex energy: quadratic in the linear springs,
piecewise quadratic in the unilateral pin contacts, (|d| - c)_+^2 in the
bearings with clearance, minus the work of the output torque.  A semismooth
Newton method with an exact line search on that energy finds it; which pins
touch is found by the iteration (an active-set method), never assumed.

Speed comes from structure, not from approximations:
- every unknown that only linear springs touch (the sun, and with no bearing
  clearance the cranks and the carrier) is condensed out exactly, per angle, by
  a Schur complement that all reducers of a batch share; the Newton iteration
  runs on the six disc unknowns (more when bearings have clearance);
- the no-load limit without bearing clearance needs no iteration at all: the
  linear parts take their (pre)stressed shape, then the reducer turns along its
  zero-energy mechanism mode until the first pin touches (MODEL.md section 5);
- all pairs are iterated together in numpy, pairs that have converged leave
  the batch, and the pairs come in chunks so that memory stays bounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .equivalent import EquivalentModel
from .errors import ErrorSet, zero_errors

CHUNK = 4096           # pairs per chunk: ~40 MB of work arrays
MAX_ITERATIONS = 400
STEP_TOLERANCE = 1e-14   # m: converged when a Newton step moves less (1e-8 um)
REGULARISATION = 1e-6    # relative to the pin stiffness: keeps floating parts determinate
MODE_DIRECTION_STIFFNESS = 1e-9  # relative to the pin stiffness, Hessian only: see ReducedSystem
GAP_TOLERANCE = 1e-12    # m: an interference smaller than this is contact, not preload
SHRINK_FRACTION = 0.25   # drop converged pairs from the work arrays once a quarter are done
CONTINUATION = (1e3, 1e2, 1e1, 1.0)  # no load with bearing clearance: probe multiples, large to small
CANDIDATE_MARGIN = 4     # pins per disc iterated on beyond the half that the load closes


@dataclass(frozen=True)
class Equilibrium:
    """Unknowns at equilibrium for B pairs.

    q: (B, n) displacements [m; rotations as arc length at R_p];
    pin_force: (B, 2, z_p) [N], >= 0; mesh_force: (B, n_c) [N], sun-planet mesh
    forces along their lines of action (compression positive); converged: (B,)
    bool; iterations: most used.
    """

    q: np.ndarray
    pin_force: np.ndarray
    mesh_force: np.ndarray
    converged: np.ndarray
    iterations: int


class ReducedSystem:
    """The equivalent model with its linear unknowns condensed out, per angle.

    `clearance` (nb,) bool says which bearings have a clearance somewhere in the
    batch; those stay nonlinear, the others join the linear springs.
    """

    def __init__(self, model: EquivalentModel, clearance: np.ndarray):
        self.model = model
        n = model.n_dof
        A = model.pose.theta_in.size
        self.clearance = np.asarray(clearance, dtype=bool)
        lin_b = np.flatnonzero(~self.clearance)
        # Linear rows: meshes, sun support, bearings without clearance (x and y rows).
        brg_rows = model.bearing_rows[:, lin_b].reshape(A, -1, n)
        self.rows = np.concatenate([model.linear_rows, brg_rows], axis=1)        # (A, m, n)
        self.k = np.concatenate([model.linear_k, np.repeat(model.bearing_k[lin_b], 2)])
        self.linear_bearings = lin_b
        self.nl_bearings = np.flatnonzero(self.clearance)

        touched = set(model.pin_dofs.ravel())
        for b in self.nl_bearings:
            touched |= set(np.flatnonzero(np.any(model.bearing_rows[:, b] != 0, axis=(0, 1))))
        self.N = np.array(sorted(touched))
        self.L = np.array([k for k in range(n) if k not in touched])
        N, L = self.N, self.L

        K = np.einsum("ami,m,amj->aij", self.rows, self.k, self.rows)
        g = model.load_vector()
        kll = K[:, L][:, :, L]
        # G = K_LL^-1 K_LN, H = K_LL^-1 J_L^T diag(k), gl = K_LL^-1 g_L
        rhs = np.concatenate([K[:, L][:, :, N],
                              np.swapaxes(self.rows[:, :, L], 1, 2) * self.k,
                              np.broadcast_to(g[L][None, :, None], (A, L.size, 1))], axis=2)
        sol = np.linalg.solve(kll, rhs)
        nN, m = N.size, self.k.size
        self.G, self.H, self.gl = sol[:, :, :nN], sol[:, :, nN:nN + m], sol[:, :, -1]
        knl = K[:, N][:, :, L]
        self.K_red = K[:, N][:, :, N] - knl @ self.G                               # (A, nN, nN)
        self.P = (np.swapaxes(self.rows[:, :, N], 1, 2) * self.k) - knl @ self.H   # (A, nN, m)
        self.g_red = g[N][None] - np.einsum("anl,al->an", knl, self.gl)            # (A, nN)

        # Pins in reduced coordinates: disc j's unknowns sit at pin_local[j] of N.
        position = {dof: k for k, dof in enumerate(N)}
        self.pin_local = np.array([[position[d] for d in row] for row in model.pin_dofs])
        self.brg_rows = model.bearing_rows[:, self.nl_bearings][..., N]           # (A, nbn, 2, nN)
        self.brg_k = model.bearing_k[self.nl_bearings]
        self.reg = REGULARISATION * model.pin_k

        # Mechanism mode: the carrier turning with the input held, all but the pins
        # unstrained (carrier rotation unknown = 1).  It is the null vector of K_red.
        kfull = K.copy()
        if self.nl_bearings.size:
            rows = model.bearing_rows[:, self.nl_bearings]
            kfull += np.einsum("abxi,b,abxj->aij", rows, self.brg_k, rows)
        c = model.carrier_rot
        rest = [k for k in range(n) if k != c]
        mode = np.zeros((A, n))
        mode[:, c] = 1.0
        mode[:, rest] = -np.linalg.solve(kfull[:, rest][:, :, rest], kfull[:, rest][:, :, [c]])[..., 0]
        self.mode = mode
        self.pin_rate = np.einsum("ajkx,ajx->ajk", model.pin_rows, mode[:, model.pin_dofs])
        # Candidate pins: those the load closes (about half) and a margin of the nearly
        # square ones; the others are checked after the solve and taken in if they touch.
        keep = min(model.design.z_p, model.design.z_p // 2 + CANDIDATE_MARGIN)
        self.candidates = {
            direction: np.sort(np.argsort(-self.pin_rate * direction, axis=-1)[..., :keep], axis=-1)
            for direction in (-1.0, 1.0)}
        self.candidate_rows = {
            direction: np.take_along_axis(model.pin_rows, cand[..., None], axis=2)
            for direction, cand in self.candidates.items()}
        self.candidate_products = {d: _products(rows) for d, rows in self.candidate_rows.items()}
        if not self.nl_bearings.size:
            # Shape of the linear parts with the mode held: [K_red m; m^T 0] bordered solve.
            mN = mode[:, N]
            border = np.zeros((A, nN + 1, nN + 1))
            border[:, :nN, :nN] = self.K_red
            border[:, :nN, nN] = mN
            border[:, nN, :nN] = mN
            self.free_shape = np.linalg.inv(border)[:, :nN, :nN]                   # q = -Z f
        # A weak spring on every reduced unknown keeps parts that float in a clearance
        # determinate; it leaves the mechanism mode free, so that however small the
        # load, only the pins stop the carrier.
        m_hat = mode[:, N] / np.linalg.norm(mode[:, N], axis=1, keepdims=True)
        along = m_hat[:, :, None] * m_hat[:, None, :]
        self.K_red = self.K_red + self.reg * (np.eye(nN) - along)
        # Newton directions need some stiffness along the mode before a pin touches; this
        # one enters the Hessian only (the energy and its minimiser do not see it).
        self.mode_stiffness = MODE_DIRECTION_STIFFNESS * model.pin_k * along

    # -- one chunk -------------------------------------------------------------------------
    def solve(self, errors: ErrorSet, sample, angle, tau_load, half_clearance, probe,
              first_count=None) -> Equilibrium:
        """Equilibrium of the pairs (sample[b], angle[b]) under tau_load[b] [N*m].

        tau_load == 0 gives the no-load limit from the side of the signed probe
        torque `probe` (negative: a resisting load, MODEL.md section 5; positive: a
        driving one); where it needs an elastic solve (interference, bearing
        clearance) the equilibrium under `probe` is taken back to zero load along
        its tangent.
        first_count: (B, 2) int, optional: how many pins of each disc probably touch
        (from the error-free reducer); the first guess takes that many, those the
        load closes first.
        """
        model = self.model
        B = len(angle)
        lin_b, brg_b, pin_b = model.offsets(errors, sample, angle)
        b_lin = np.concatenate([lin_b, brg_b[:, self.linear_bearings].reshape(B, -1)], axis=1)
        tau = np.array(tau_load, dtype=float)
        zero = tau == 0.0
        f0 = np.einsum("bnm,bm->bn", self.P[angle], b_lin)
        brg_off = brg_b[:, self.nl_bearings]
        c_half = half_clearance[sample][:, self.nl_bearings]
        qn = np.zeros((B, self.N.size))
        converged = np.ones(B, dtype=bool)
        iterations = 0

        elastic = ~zero
        if np.any(zero):
            if self.nl_bearings.size:
                elastic |= zero
            else:
                z = np.flatnonzero(zero)
                qz, rigid = self._first_contact(angle[z], f0[z], pin_b[z], np.sign(probe))
                qn[z] = qz
                elastic[z[~rigid]] = True
        iterations = 0
        groups = [np.flatnonzero(elastic & ~zero), np.flatnonzero(elastic & zero)]
        for group, at_zero in zip(groups, (False, True)):
            if group.size == 0:
                continue
            loads = tau[group]
            q_start = None
            if at_zero:
                # Probe torques, from large to small when parts float in bearing clearances
                # (each solve starts from the last), the last one the probe itself.
                steps = CONTINUATION if self.nl_bearings.size else (1.0,)
                for scale in steps:
                    loads = np.full(group.size, probe * scale)
                    q_start, conv, its = self._solve_group(
                        group, angle, f0, pin_b, brg_off, c_half, loads, first_count, q_start)
                    iterations += its
                # From tau = probe back to tau = 0 along the tangent at that contact state.
                a = angle[group]
                part = _Work(self, a, f0[group] - probe * self.g_red[a], model.pin_rows[a],
                             pin_b[group], brg_off[group], c_half[group])
                dq = np.linalg.solve(part.hessian(q_start, None), part.load_direction()[..., None])
                qn[group] = q_start - probe * dq[..., 0]
            else:
                qn[group], conv, its = self._solve_group(
                    group, angle, f0, pin_b, brg_off, c_half, loads, first_count, None)
                iterations += its
            converged[group] = conv
        q = np.empty((B, model.n_dof))
        q[:, self.N] = qn
        q[:, self.L] = -(np.einsum("aln,an->al", self.G[angle], qn)
                         + np.einsum("alm,am->al", self.H[angle], b_lin)) + tau[:, None] * self.gl[angle]
        delta = _pin_delta(model.pin_rows[angle], qn[:, self.pin_local], pin_b)
        n_c = model.design.n_c
        mesh = np.einsum("bmn,bn->bm", model.linear_rows[angle][:, :n_c], q) + lin_b[:, :n_c]
        return Equilibrium(q, model.pin_k * np.maximum(delta, 0.0), model.linear_k[:n_c] * mesh,
                           converged, iterations)

    def _solve_group(self, group, angle, f0, pin_b, brg_off, c_half, loads, first_count, q0):
        a = angle[group]
        f = f0[group] - loads[:, None] * self.g_red[a]
        direction = np.where(loads > 0, 1.0, -1.0)
        count = None if first_count is None else first_count[group]
        return self._elastic(a, f, pin_b[group], brg_off[group], c_half[group], direction, count, q0,
                             f_errors=f0[group])

    def _elastic(self, angle, f, pin_b, brg_off, c_half, direction, count, q0=None, f_errors=None):
        """Newton solve of the pairs on their candidate pins, then on all pins where needed.

        The first guess of the touching pins: the `count` pins of each disc that the
        turning carrier reaches first, their gaps measured once the linear parts have
        taken the shape the errors force on them (when that shape is known).
        """
        model = self.model
        forward = direction > 0
        cand = self.candidates[-1.0][angle]                                         # (B, 2, Kc)
        rows = self.candidate_rows[-1.0][angle]                                     # (B, 2, Kc, 3)
        products = self.candidate_products[-1.0][angle]                             # (B, 2, Kc, 6)
        if np.any(forward):
            cand[forward] = self.candidates[1.0][angle[forward]]
            rows[forward] = self.candidate_rows[1.0][angle[forward]]
            products[forward] = self.candidate_products[1.0][angle[forward]]
        pb = np.take_along_axis(pin_b, cand, axis=2)
        closing = np.take_along_axis(self.pin_rate[angle], cand, axis=2) * direction[:, None, None]
        if count is None:
            guess = closing > 0
        else:
            gaps = pb
            if f_errors is not None and hasattr(self, "free_shape"):
                shape = -np.einsum("bij,bj->bi", self.free_shape[angle], f_errors)
                gaps = _pin_delta(rows, shape[:, self.pin_local], pb)
            with np.errstate(divide="ignore", invalid="ignore"):
                travel = np.where(closing > 0, -gaps / closing, np.inf)
            # the `count` pins of each disc that the turning carrier reaches first
            ordered = np.sort(travel, axis=-1)
            take = np.clip(count, 1, travel.shape[-1])[..., None] - 1
            guess = travel <= np.take_along_axis(ordered, take, axis=-1)
        work = _Work(self, angle, f, rows, pb, brg_off, c_half, products)
        q, converged, iterations = _newton(work, guess, q0)
        # Any pin left out that touches at the solution: solve those pairs on all pins.
        outside = np.ones(pin_b.shape, dtype=bool)
        np.put_along_axis(outside, cand, False, axis=2)
        delta = _pin_delta(model.pin_rows[angle], q[:, self.pin_local], pin_b)
        redo = np.flatnonzero(np.any(outside & (delta > GAP_TOLERANCE), axis=(1, 2)))
        if redo.size:
            full = _Work(self, angle[redo], f[redo], model.pin_rows[angle[redo]], pin_b[redo],
                         brg_off[redo], c_half[redo])
            first = (self.pin_rate[angle[redo]] * direction[redo, None, None]) > 0
            q[redo], converged[redo], more = _newton(full, first, None if q0 is None else q0[redo])
            iterations = max(iterations, more)
        return q, converged, iterations

    def _first_contact(self, angle, f, pin_b, direction):
        """No-load limit by kinematics: (q_N (B, nN), rigid (B,) bool).

        The linear parts take the shape the errors force on them with the mechanism
        held, q0 = -Z f; then the carrier turns back along the mode m until the
        first pin closes: mu = max over closing pins of -delta0 / rate (forward, for a
        driving load, direction = +1: the min over the pins closing that way).  Where no
        such pose leaves every pin free of interference, `rigid` is False and the
        pair needs the elastic solve.
        """
        q0 = -np.einsum("bij,bj->bi", self.free_shape[angle], f)
        delta0 = _pin_delta(self.model.pin_rows[angle], q0[:, self.pin_local], pin_b)
        rate = self.pin_rate[angle]
        closing = rate * direction > 0  # closes as the carrier turns that way
        with np.errstate(divide="ignore", invalid="ignore"):
            # -direction * mu_k: the pin met first, coming from the far side, is the largest
            key = np.where(closing, direction * delta0 / rate, -np.inf)
        mu = -direction * key.max(axis=(1, 2))
        after = delta0 + rate * mu[:, None, None]
        rigid = np.isfinite(mu) & np.all(after <= GAP_TOLERANCE, axis=(1, 2))
        mu = np.where(np.isfinite(mu), mu, 0.0)
        return q0 + mu[:, None] * self.mode[angle][:, self.N], rigid


def _newton(work, first_active, q0=None):
    """Active-set Newton on the reduced energy; returns (q (B, nN), converged (B,), iterations).

    The first step solves the linear system with the guessed pins in contact at
    their real gaps (a primal-dual active-set step), so it closes those gaps in one
    go; later steps are semismooth Newton steps on the true energy.  A full step is
    taken where it lowers the true energy; elsewhere an exact line search on the
    true energy chooses the step length, so every step is a descent.
    """
    B, nN = work.f.shape
    result = np.zeros((B, nN))
    converged = np.zeros(B, dtype=bool)
    ids = np.arange(B)
    warm = q0 is not None
    q = np.zeros((B, nN)) if q0 is None else q0.copy()
    energy, _ = work.energy(q)
    smooth = work.brg_rows is None  # piecewise quadratic: a consistent active set is exact
    iterations = 0
    for iterations in range(1, MAX_ITERATIONS + 1):
        first = iterations == 1 and not warm
        guess = first_active if first else None
        grad, hess, true_grad, used = work.gradient_hessian(q, guess, bearings_engaged=first)
        step = -np.linalg.solve(hess, grad[..., None])[..., 0]
        trial, delta = work.energy(q + step)
        slope = np.einsum("bi,bi->b", true_grad, step)
        full = trial <= energy + 1e-4 * slope + 1e-13 * np.abs(energy)
        alpha = np.ones(len(q))
        if not np.all(full):
            short = np.flatnonzero(~full)
            alpha[short] = work.subset(short).line_search(q[short], step[short])
        move = alpha[:, None] * step
        move[converged[ids]] = 0.0  # pairs already done but still in the arrays stay put
        q = q + move
        energy = trial if np.all(full) else np.where(full, trial, work.energy(q)[0])
        result[ids] = q
        # Done when a full step landed where exactly the pins it assumed touch (the
        # minimiser of that piece of the energy), or when a step no longer moves.
        done = np.max(np.abs(move), axis=1) <= STEP_TOLERANCE + 1e-12 * np.max(np.abs(q), axis=1)
        if first:
            # A guessed step that does not go downhill says nothing about convergence.
            done[:] = False
        if smooth:
            consistent = np.where(used, delta >= -GAP_TOLERANCE, delta <= GAP_TOLERANCE)
            done |= full & np.all(consistent, axis=(1, 2))
        done |= converged[ids]
        converged[ids[done]] = True
        if np.all(done):
            break
        if np.count_nonzero(done) > SHRINK_FRACTION * len(done):
            keep = np.flatnonzero(~done)
            work, q, ids, energy = work.subset(keep), q[keep], ids[keep], energy[keep]
    return result, converged, iterations


class _Work:
    """Per-pair arrays of the Newton iteration, gathered once and shrunk as pairs converge.

    rows (B, 2, K, 3) and pin_b (B, 2, K) are those of the K pins per disc taken
    into the iteration (all of them, or the candidates that the load can close).
    """

    def __init__(self, system, angle, f, rows, pin_b, brg_off, c_half, products=None):
        self.system = system
        self.angle = angle
        self.rows = rows
        self.products = _products(rows) if products is None else products  # (B, 2, K, 6)
        self.K = system.K_red[angle]                          # (B, nN, nN)
        self.f, self.pin_b, self.brg_off, self.c_half = f, pin_b, brg_off, c_half
        self.brg_rows = system.brg_rows[angle] if system.brg_k.size else None

    def subset(self, keep):
        new = object.__new__(_Work)
        new.system, new.angle = self.system, self.angle[keep]
        for name in ("rows", "products", "K", "f", "pin_b", "brg_off", "c_half"):
            setattr(new, name, getattr(self, name)[keep])
        new.brg_rows = None if self.brg_rows is None else self.brg_rows[keep]
        return new

    def load_direction(self):
        """d(gradient)/d(-tau): the reduced load vector (B, nN)."""
        return self.system.g_red[self.angle]

    def _local(self, q):
        return q[:, self.system.pin_local]                    # (B, 2, 3)

    def _bearing(self, q):
        return np.einsum("bpxn,bn->bpx", self.brg_rows, q) + self.brg_off

    def delta(self, q):
        return _pin_delta(self.rows, self._local(q), self.pin_b)

    def energy(self, q):
        """(reduced energy (B,) [J] up to a constant, pin deflections (B, 2, K) [m])."""
        sys = self.system
        kq = np.matmul(self.K, q[..., None])[..., 0]
        e = np.einsum("bi,bi->b", q, 0.5 * kq + self.f)
        delta = self.delta(q)
        pos = np.maximum(delta, 0.0)
        e += 0.5 * sys.model.pin_k * np.einsum("bjk,bjk->b", pos, pos)
        if self.brg_rows is not None:
            over = np.maximum(np.linalg.norm(self._bearing(q), axis=-1) - self.c_half, 0.0)
            e += 0.5 * np.einsum("bp,p->b", over * over, sys.brg_k)
        return e, delta

    def gradient_hessian(self, q, active=None, bearings_engaged=False):
        """(gradient, Hessian, true gradient, pins taken as touching) at q.

        With `active` (B, 2, K) the gradient and Hessian are those of the energy
        with exactly those pins bonded (a primal-dual active-set step); the true
        gradient is always that of the real energy.
        """
        sys = self.system
        kp = sys.model.pin_k
        base = np.matmul(self.K, q[..., None])[..., 0] + self.f
        delta = self.delta(q)
        touching = delta > 0
        if active is None:
            # A pin exactly at contact (where an exact line search stops) counts as touching:
            # that choice of the generalised Jacobian keeps the mechanism mode held.
            active = delta > -GAP_TOLERANCE
            force = np.where(touching, delta, 0.0)
            true_force = force
        else:
            force = delta * active
            true_force = np.where(touching, delta, 0.0)
        grad = base.copy()
        gen = np.matmul(force[:, :, None, :], self.rows)[:, :, 0] * kp                # (B, 2, 3)
        hess = self.K + sys.mode_stiffness[self.angle]
        upper = np.matmul((active * kp)[:, :, None, :], self.products)[:, :, 0]      # (B, 2, 6)
        blocks = upper[..., _SYMMETRIC]                                                # (B, 2, 3, 3)
        for j in range(2):
            idx = sys.pin_local[j]
            grad[:, idx] += gen[:, j]
            hess[:, idx[:, None], idx[None, :]] += blocks[:, j]
        if true_force is force:
            true_grad = grad.copy()
        else:
            true_grad = base.copy()
            true_gen = np.matmul(true_force[:, :, None, :], self.rows)[:, :, 0] * kp
            for j in range(2):
                true_grad[:, sys.pin_local[j]] += true_gen[:, j]
        if self.brg_rows is not None:
            d = self._bearing(q)
            norm = np.linalg.norm(d, axis=-1)
            scale = np.where(norm > self.c_half, 1.0 - self.c_half / np.maximum(norm, 1e-300), 0.0)
            bforce = np.einsum("bpxn,bpx->bn", self.brg_rows, d * (scale * sys.brg_k)[..., None])
            grad += bforce
            true_grad += bforce
            if bearings_engaged:
                tangent = np.broadcast_to(np.eye(2) * sys.brg_k[:, None, None],
                                          self.brg_off.shape[:2] + (2, 2))
            else:
                tangent = _bearing_tangent(d, self.c_half, sys.brg_k)
            hess = hess + np.einsum("bpxi,bpxy,bpyj->bij", self.brg_rows, tangent, self.brg_rows,
                                    optimize=True)
        return grad, hess, true_grad, active

    def hessian(self, q, active):
        return self.gradient_hessian(q, active)[1]

    def line_search(self, q, step):
        """Exact minimiser of the energy along `step`, (B,) step lengths.

        Along the line the energy is a convex 1-D function whose derivative is
        piecewise linear in the pins (and smooth in the bearings); a safeguarded
        Newton iteration on that derivative, inside a bracket, finds its zero.
        Its pieces are computed once, so each trial costs a few elementwise operations.
        """
        sys = self.system
        k_step = np.matmul(self.K, step[..., None])[..., 0]
        quad = np.einsum("bi,bi->b", step, k_step)
        lin = np.einsum("bi,bi->b", np.matmul(self.K, q[..., None])[..., 0] + self.f,
                        step)
        delta0 = self.delta(q)
        ddelta = _pin_delta(self.rows, self._local(step), 0.0)
        kp = sys.model.pin_k
        if self.brg_rows is not None:
            d0 = self._bearing(q)
            dd = np.einsum("bpxn,bn->bpx", self.brg_rows, step)

        def slope(alpha, t):
            """(first, second) derivative of the energy along the line at alpha, pairs t."""
            a = alpha[:, None, None]
            delta = delta0[t] + a * ddelta[t]
            on = delta > 0
            d1 = quad[t] * alpha + lin[t] + kp * np.einsum("bjk,bjk->b", np.where(on, delta, 0.0), ddelta[t])
            d2 = quad[t] + kp * np.einsum("bjk,bjk->b", on * ddelta[t], ddelta[t])
            if self.brg_rows is not None:
                d = d0[t] + a * dd[t]
                scale = np.linalg.norm(d, axis=-1)
                over = np.where(scale > self.c_half[t], 1.0 - self.c_half[t] / np.maximum(scale, 1e-300), 0.0)
                force = d * (over * sys.brg_k)[..., None]
                d1 = d1 + np.einsum("bpx,bpx->b", force, dd[t])
                tangent = _bearing_tangent(d, self.c_half[t], sys.brg_k)
                d2 = d2 + np.einsum("bpx,bpxy,bpy->b", dd[t], tangent, dd[t])
            return d1, d2

        B = len(q)
        everyone = np.arange(B)
        d1_0, _ = slope(np.zeros(B), everyone)
        lo, hi = np.zeros(B), np.ones(B)
        # Bracket the zero of the derivative: grow hi until the derivative is >= 0.
        d1_hi, d2_hi = slope(hi, everyone)
        grow = np.flatnonzero(d1_hi < 0)
        for _ in range(60):
            if grow.size == 0:
                break
            lo[grow] = hi[grow]
            hi[grow] *= 4.0
            d1, d2 = slope(hi[grow], grow)
            d1_hi[grow], d2_hi[grow] = d1, d2
            grow = grow[d1 < 0]
        alpha = hi.copy()
        d1, d2 = d1_hi, d2_hi
        tolerance = 1e-12 * np.abs(d1_0) + 1e-300
        todo = np.flatnonzero((np.abs(d1) > tolerance) & (d1_0 < 0))
        alpha[d1_0 >= 0] = 0.0  # no descent left: the pair is at its minimum
        for _ in range(60):
            if todo.size == 0:
                break
            a, g1, g2 = alpha[todo], d1[todo], d2[todo]
            hi[todo] = np.where(g1 > 0, a, hi[todo])
            lo[todo] = np.where(g1 < 0, a, lo[todo])
            newton = a - g1 / np.where(g2 > 0, g2, 1.0)
            inside = (g2 > 0) & (newton > lo[todo]) & (newton < hi[todo])
            alpha[todo] = np.where(inside, newton, 0.5 * (lo[todo] + hi[todo]))
            g1, g2 = slope(alpha[todo], todo)
            d1[todo], d2[todo] = g1, g2
            settled = (np.abs(g1) <= tolerance[todo]) | (hi[todo] - lo[todo] <= 1e-15 * hi[todo])
            todo = todo[~settled]
        return alpha


_UPPER = np.triu_indices(3)                       # the six distinct entries of a 3x3 block
_SYMMETRIC = np.array([[0, 1, 2], [1, 3, 4], [2, 4, 5]])  # their places in the full block


def _products(rows):
    """The six distinct products of each pin's row with itself (..., 6), for Hessian blocks."""
    return rows[..., _UPPER[0]] * rows[..., _UPPER[1]]


def _bearing_tangent(d, c_half, k):
    """Tangent stiffness (B, p, 2, 2) of isotropic bearings with free play c_half at deflection d."""
    norm = np.maximum(np.linalg.norm(d, axis=-1), 1e-300)
    n_hat = d / norm[..., None]
    engaged = norm > c_half
    ratio = np.where(engaged, c_half / norm, 1.0)
    tangent = ((1.0 - ratio)[..., None, None] * np.eye(2)
               + ratio[..., None, None] * n_hat[..., :, None] * n_hat[..., None, :])
    return tangent * (engaged * k)[..., None, None]


def _pin_delta(rows, q_local, offset):
    """Pin deflections (B, 2, z_p) from disc unknowns (B, 2, 3)."""
    return np.matmul(rows, q_local[..., None])[..., 0] + offset


def solve_pairs(model: EquivalentModel, errors: ErrorSet, sample, angle, tau_load,
                no_load_probe: float, progress=None, zero_side: int = -1) -> Equilibrium:
    """Equilibria of many (reducer, angle) pairs, in chunks.

    sample, angle: (B,) indices into `errors` and `model.pose`; tau_load: (B,) [N*m].
    Where tau_load is zero the result is the no-load limit of MODEL.md section 5,
    approached from a resisting load (zero_side = -1) or a driving one (+1);
    no_load_probe [N*m] > 0 is the size of the probe torque it uses where needed.
    """
    probe = no_load_probe if zero_side > 0 else -no_load_probe
    sample, angle = np.asarray(sample), np.asarray(angle)
    tau_load = np.broadcast_to(np.asarray(tau_load, dtype=float), sample.shape)
    half = model.clearance_halves(errors)
    system = ReducedSystem(model, np.any(half > 0, axis=0))
    B = sample.size
    q = np.empty((B, model.n_dof))
    pin_force = np.empty((B, 2, model.design.z_p))
    mesh_force = np.empty((B, model.design.n_c))
    converged = np.empty(B, dtype=bool)
    iterations = 0
    count = _nominal_counts(system, errors, sample, angle, tau_load, probe)
    for start in range(0, B, CHUNK):
        part = slice(start, min(start + CHUNK, B))
        eq = system.solve(errors, sample[part], angle[part], tau_load[part], half, probe,
                          None if count is None else count[part])
        q[part], pin_force[part], converged[part] = eq.q, eq.pin_force, eq.converged
        mesh_force[part] = eq.mesh_force
        iterations = max(iterations, eq.iterations)
        if progress is not None:
            progress(part.stop - part.start)
    return Equilibrium(q, pin_force, mesh_force, converged, iterations)


NOMINAL_GUESS_MIN_SAMPLES = 4  # below this, solving the error-free reducer first costs more than it saves


def _nominal_counts(system, errors, sample, angle, tau_load, probe):
    """(B, 2) pins per disc touching in the error-free reducer at each pair's angle and load."""
    if errors.samples < NOMINAL_GUESS_MIN_SAMPLES or np.all(tau_load == 0.0):
        return None
    keys, inverse = np.unique(np.stack([angle, tau_load]), axis=1, return_inverse=True)
    a_u, t_u = keys[0].astype(int), keys[1]
    nominal = zero_errors(system.model.design, 1)
    half = np.zeros((1, system.model.bearing_k.size))
    counts = np.empty((a_u.size, 2), dtype=int)
    for start in range(0, a_u.size, CHUNK):
        part = slice(start, min(start + CHUNK, a_u.size))
        eq = system.solve(nominal, np.zeros(part.stop - part.start, dtype=int), a_u[part], t_u[part],
                          half, probe)
        counts[part] = (eq.pin_force > 0).sum(axis=2)
    return counts[inverse.ravel()]
