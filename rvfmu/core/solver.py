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
from .errors import ErrorSet

CHUNK = 4096           # pairs per chunk: ~40 MB of work arrays
MAX_ITERATIONS = 60
STEP_TOLERANCE = 1e-14   # m: converged when a Newton step moves less (1e-8 um)
REGULARISATION = 1e-8    # relative to the pin stiffness: keeps floating parts determinate
GAP_TOLERANCE = 1e-12    # m: an interference smaller than this is contact, not preload


@dataclass(frozen=True)
class Equilibrium:
    """Unknowns at equilibrium for B pairs.

    q: (B, n) displacements [m; rotations as arc length at R_p];
    pin_force: (B, 2, z_p) [N], >= 0; converged: (B,) bool; iterations: most used.
    """

    q: np.ndarray
    pin_force: np.ndarray
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
        if not self.nl_bearings.size:
            # Shape of the linear parts with the mode held: [K_red m; m^T 0] bordered solve.
            mN = mode[:, N]
            border = np.zeros((A, nN + 1, nN + 1))
            border[:, :nN, :nN] = self.K_red
            border[:, :nN, nN] = mN
            border[:, nN, :nN] = mN
            self.free_shape = np.linalg.inv(border)[:, :nN, :nN]                   # q = -Z f

    # -- one chunk -------------------------------------------------------------------------
    def solve(self, errors: ErrorSet, sample, angle, tau_load, half_clearance, probe,
              first_active=None) -> Equilibrium:
        """Equilibrium of the pairs (sample[b], angle[b]) under tau_load[b] [N*m].

        tau_load == 0 gives the no-load limit; where it needs an elastic solve
        (interference, bearing clearance) a resisting probe torque `probe` is used
        and the result taken back to zero load along its tangent.
        first_active: (B, 2, z_p) bool, optional guess of the touching pins.
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
                qz, rigid = self._first_contact(angle[z], f0[z], pin_b[z])
                qn[z] = qz
                elastic[z[~rigid]] = True
        tau_solve = np.where(zero, -probe, tau)
        todo = np.flatnonzero(elastic)
        if todo.size:
            f = f0[todo] - tau_solve[todo, None] * self.g_red[angle[todo]]
            if first_active is None:
                direction = np.where(tau_solve[todo] > 0, 1.0, -1.0)
                guess = (self.pin_rate[angle[todo]] * direction[:, None, None]) > 0
            else:
                guess = first_active[todo]
            work = _Work(self, angle[todo], f, pin_b[todo], brg_off[todo], c_half[todo])
            q_e, conv_e, iterations = _newton(work, guess)
            back = zero[todo]
            if np.any(back):
                # From tau = -probe back to tau = 0 along the tangent at that contact state.
                part = work.subset(back)
                dq = np.linalg.solve(part.hessian(q_e[back], None), part.load_direction()[..., None])
                q_e[back] += probe * dq[..., 0]
            qn[todo], converged[todo] = q_e, conv_e
        q = np.empty((B, model.n_dof))
        q[:, self.N] = qn
        q[:, self.L] = -(np.einsum("aln,an->al", self.G[angle], qn)
                         + np.einsum("alm,am->al", self.H[angle], b_lin)) + tau[:, None] * self.gl[angle]
        delta = _pin_delta(model.pin_rows[angle], qn[:, self.pin_local], pin_b)
        return Equilibrium(q, model.pin_k * np.maximum(delta, 0.0), converged, iterations)

    def _first_contact(self, angle, f, pin_b):
        """No-load limit by kinematics: (q_N (B, nN), rigid (B,) bool).

        The linear parts take the shape the errors force on them with the mechanism
        held, q0 = -Z f; then the carrier turns back along the mode m until the
        first pin closes: mu = max over closing pins of -delta0 / rate.  Where no
        such pose leaves every pin free of interference, `rigid` is False and the
        pair needs the elastic solve.
        """
        q0 = -np.einsum("bij,bj->bi", self.free_shape[angle], f)
        delta0 = _pin_delta(self.model.pin_rows[angle], q0[:, self.pin_local], pin_b)
        rate = self.pin_rate[angle]
        closing = rate < 0  # closes as the carrier turns back (mu decreasing)
        with np.errstate(divide="ignore", invalid="ignore"):
            mu_k = np.where(closing, -delta0 / rate, -np.inf)
        mu = mu_k.max(axis=(1, 2))
        after = delta0 + rate * mu[:, None, None]
        rigid = np.isfinite(mu) & np.all(after <= GAP_TOLERANCE, axis=(1, 2))
        mu = np.where(np.isfinite(mu), mu, 0.0)
        return q0 + mu[:, None] * self.mode[angle][:, self.N], rigid


def _newton(work, first_active):
    """Active-set Newton on the reduced energy; returns (q (B, nN), converged (B,), iterations).

    The first step solves the linear system with the guessed pins in contact at
    their real gaps (a primal-dual active-set step), so it closes those gaps in one
    go; later steps are semismooth Newton steps on the true energy.  Every step is
    followed by an exact line search on the true energy, which makes each one a descent.
    """
    B, nN = work.f.shape
    result = np.zeros((B, nN))
    converged = np.zeros(B, dtype=bool)
    ids = np.arange(B)
    q = np.zeros((B, nN))
    iterations = 0
    for iterations in range(1, MAX_ITERATIONS + 1):
        if iterations == 1:
            hess = work.hessian(q, first_active, bearings_engaged=True)
            step = -np.linalg.solve(hess, work.gradient(q, first_active)[..., None])[..., 0]
        else:
            hess = work.hessian(q, None)
            step = -np.linalg.solve(hess, work.gradient(q)[..., None])[..., 0]
        alpha = work.line_search(q, step)
        move = alpha[:, None] * step
        q = q + move
        result[ids] = q
        if iterations == 1:
            continue
        done = np.max(np.abs(move), axis=1) <= STEP_TOLERANCE + 1e-12 * np.max(np.abs(q), axis=1)
        converged[ids[done]] = True
        if np.all(done):
            break
        if np.any(done):
            keep = ~done
            work, q, ids = work.subset(keep), q[keep], ids[keep]
    return result, converged, iterations


class _Work:
    """Per-pair arrays of the Newton iteration, gathered once and shrunk as pairs converge."""

    def __init__(self, system, angle, f, pin_b, brg_off, c_half):
        self.system = system
        self.angle = angle
        self.rows = system.model.pin_rows[angle]             # (B, 2, z_p, 3)
        self.K = system.K_red[angle]                          # (B, nN, nN)
        self.f, self.pin_b, self.brg_off, self.c_half = f, pin_b, brg_off, c_half
        self.brg_rows = system.brg_rows[angle] if system.brg_k.size else None

    def subset(self, keep):
        new = object.__new__(_Work)
        new.system, new.angle = self.system, self.angle[keep]
        for name in ("rows", "K", "f", "pin_b", "brg_off", "c_half"):
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

    def gradient(self, q, active=None):
        """Energy gradient (B, nN); with `active`, of the energy with those pins bonded."""
        sys = self.system
        grad = np.matmul(self.K, q[..., None])[..., 0] + self.f + sys.reg * q
        delta = _pin_delta(self.rows, self._local(q), self.pin_b)
        delta = np.maximum(delta, 0.0) if active is None else delta * active
        pin_gen = np.matmul(delta[:, :, None, :], self.rows)[:, :, 0] * sys.model.pin_k
        for j in range(2):
            grad[:, sys.pin_local[j]] += pin_gen[:, j]
        if self.brg_rows is not None:
            d = self._bearing(q)
            norm = np.linalg.norm(d, axis=-1)
            scale = np.where(norm > self.c_half, 1.0 - self.c_half / np.maximum(norm, 1e-300), 0.0)
            grad += np.einsum("bpxn,bpx->bn", self.brg_rows, d * (scale * sys.brg_k)[..., None])
        return grad

    def hessian(self, q, active, bearings_engaged=False):
        sys = self.system
        hess = self.K + sys.reg * np.eye(sys.N.size)
        if active is None:
            # A pin exactly at contact (where an exact line search stops) counts as touching:
            # that choice of the generalised Jacobian keeps the mechanism mode held.
            active = _pin_delta(self.rows, self._local(q), self.pin_b) > -GAP_TOLERANCE
        weighted = self.rows * (active * sys.model.pin_k)[..., None]
        blocks = np.matmul(np.swapaxes(weighted, -1, -2), self.rows)  # (B, 2, 3, 3)
        for j in range(2):
            idx = sys.pin_local[j]
            hess[:, idx[:, None], idx[None, :]] += blocks[:, j]
        if self.brg_rows is not None:
            if bearings_engaged:
                tangent = np.broadcast_to(np.eye(2) * sys.brg_k[:, None, None],
                                          self.brg_off.shape[:2] + (2, 2))
            else:
                tangent = _bearing_tangent(self._bearing(q), self.c_half, sys.brg_k)
            hess = hess + np.einsum("bpxi,bpxy,bpyj->bij", self.brg_rows, tangent, self.brg_rows,
                                    optimize=True)
        return hess

    def line_search(self, q, step):
        """Exact minimiser of the energy along `step`, (B,) step lengths.

        Along the line the energy is a convex 1-D function whose derivative is
        piecewise linear in the pins (and smooth in the bearings); a safeguarded
        Newton iteration on that derivative, inside a bracket, finds its zero.
        Its pieces are computed once, so each trial costs a few elementwise operations.
        """
        sys = self.system
        k_step = np.matmul(self.K, step[..., None])[..., 0] + sys.reg * step
        quad = np.einsum("bi,bi->b", step, k_step)
        lin = np.einsum("bi,bi->b", np.matmul(self.K, q[..., None])[..., 0] + self.f + sys.reg * q,
                        step)
        delta0 = _pin_delta(self.rows, self._local(q), self.pin_b)
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
                no_load_probe: float, progress=None) -> Equilibrium:
    """Equilibria of many (reducer, angle) pairs, in chunks.

    sample, angle: (B,) indices into `errors` and `model.pose`; tau_load: (B,) [N*m].
    Where tau_load is zero the result is the no-load limit of MODEL.md section 5.
    """
    sample, angle = np.asarray(sample), np.asarray(angle)
    tau_load = np.broadcast_to(np.asarray(tau_load, dtype=float), sample.shape)
    half = model.clearance_halves(errors)
    system = ReducedSystem(model, np.any(half > 0, axis=0))
    B = sample.size
    q = np.empty((B, model.n_dof))
    pin_force = np.empty((B, 2, model.design.z_p))
    converged = np.empty(B, dtype=bool)
    iterations = 0
    for start in range(0, B, CHUNK):
        part = slice(start, min(start + CHUNK, B))
        eq = system.solve(errors, sample[part], angle[part], tau_load[part], half, no_load_probe)
        q[part], pin_force[part], converged[part] = eq.q, eq.pin_force, eq.converged
        iterations = max(iterations, eq.iterations)
        if progress is not None:
            progress(part.stop - part.start)
    return Equilibrium(q, pin_force, converged, iterations)
