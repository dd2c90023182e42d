"""The Newton iteration on the reduced contact problem, for many pairs at once.

One chunk of (reducer, angle) pairs, condensed to the unknowns that nonlinear
elements touch (`solver.ReducedSystem`), is iterated here: an active-set
Newton method on the convex energy, whose first step bonds the pins guessed to
touch at their real gaps (a primal-dual active-set step) and whose later steps
are semismooth Newton steps; a full step is kept where it lowers the energy,
otherwise an exact line search along it chooses the length.  Arrays are
shaped (pairs, ...) and shrink as pairs converge.

The iteration runs compiled, one pair after another (`newton_kernel`), where
numba is installed; the numpy iteration of a whole chunk here
(`newton_batched`) is the same algorithm, the reference the compiled one is
tested against, and what runs without numba.
"""

from __future__ import annotations

import threading
from functools import cached_property

import numpy as np

from ..laws.pin_law import contacts
from ..laws.roller_law import TABLE_DE, TABLE_E, radial_law
from . import newton_kernel
from .newton_kernel import STALL_STEP

MAX_ITERATIONS = 400
STEP_TOLERANCE = 1e-14  # m: converged when a Newton step moves less (1e-8 um)
GAP_TOLERANCE = 1e-12  # m: an interference smaller than this is contact, not preload
SHRINK_FRACTION = 0.25  # drop converged pairs from the work arrays once a quarter are done
MIN_PAIRS_PER_THREAD = 64  # a thread of the compiled iteration gets at least this many pairs


def newton(work, first_active, q0=None, chain=None, release=False, stall=0):
    """Active-set Newton on the reduced energy; returns (q (B, nN), converged (B,), iterations).

    Compiled one pair at a time (`newton_kernel`) when numba is there, otherwise
    the numpy iteration of the whole chunk at once (`newton_batched`): the same
    algorithm, the same results to round-off.  chain (B,) bool, optional: the compiled
    iteration starts each pair marked from the solution of the pair before it (its
    neighbouring angle: `chain_links`) instead of its own start; the energy is the same,
    so is its minimiser, and the numpy iteration, which solves the pairs together,
    ignores it.  release: the converged pairs then let go of the weak springs by one Newton
    step (`release_step`), in the compiled kernel from the Hessian it
    has factored there, in numpy from the Hessian at the solution.  stall > 0: that many
    stalled steps in a row (`newton_kernel.STALL_STEP`) also end a pair as converged.
    """
    if newton_kernel.COMPILED:
        return newton_compiled(work, first_active, q0, chain, release, stall)
    q, converged, iterations = newton_batched(work, first_active, q0, stall)
    if release:
        q = release_step(work, q)
    return q, converged, iterations


def release_step(work, q):
    """(B, nN) the pairs of `work` at their solutions q moved by one Newton step to where the
    weak springs, re-centred on q, pull on nothing.

    At the solution q of a solve with the springs centred at zero they pull with -R q (R =
    `solver.ReducedSystem.reg_matrix`, 1e-6 of the softest element); re-centred on q they pull
    on nothing there, and the step q + H(q)^-1 R q reaches the released equilibrium to second
    order in that pull.  The compiled iteration takes it at the end of each pair's solve with
    the Hessian it has factored there, for one substitution (`newton_kernel.newton_pairs`,
    release); this is the numpy iteration's.  The reference is a solve from q with the
    springs re-centred (`solver.ReducedSystem._release`), which takes this step and one more
    to find it has arrived: the step alone is within 3e-5 arcsec of it on quick_mc's
    reducers, te_pp within 2e-8 arcsec (`bench_no_load_start.py`, tests/test_law_forms.py).
    """
    sys = work.system
    m = sys.mode_unit[work.angle]
    pull = sys.reg * (q - m * np.einsum("bi,bi->b", m, q)[:, None])
    return q + np.linalg.solve(work.hessian(q, None), pull[..., None])[..., 0]


CHAIN_LENGTH = 32  # pairs per chain of warm starts; thread batches are whole chains


def chain_links(sample, angle, load):
    """(B,) bool: which pairs start from the solution of the pair before them, the same
    reducer and load at the previous angle (`newton`).  Chains are cut every CHAIN_LENGTH
    pairs of the batch, so that the threads of `newton_compiled`, which split batches
    between chains, give the results of one thread to the bit."""
    link = np.zeros(len(sample), dtype=bool)
    link[1:] = (sample[1:] == sample[:-1]) & (load[1:] == load[:-1]) & (angle[1:] == angle[:-1] + 1)
    link[::CHAIN_LENGTH] = False
    return link


_THREAD = threading.local()  # .single: this thread solves a chunk of its own (`map_chunks`)
CHUNKS_PER_THREAD = 3  # chunks run on threads from this many per thread: fewer leave one
# thread idle at the end (3 chunks on 2 threads: 1.53x one thread,
# against 1.69x with each chunk's pairs split; 7 chunks: 1.85x
# against 1.59x)


def map_chunks(function, starts):
    """function(start) for each chunk start, results in order.  Where there are
    CHUNKS_PER_THREAD chunks or more for each thread `kernel_threads` allows, the chunks run
    on the threads, each chunk's compiled iteration on its own thread (`kernel_threads` gives
    1 there): the Python between the compiled calls of one chunk then runs while another's
    kernel does.  A chunk's result does not depend on the thread it ran on, so the results
    are those of one thread."""
    starts = list(starts)
    threads = kernel_threads()
    if threads <= 1 or len(starts) < CHUNKS_PER_THREAD * threads:
        yield from map(function, starts)  # few chunks: each splits its pairs instead
        return

    def alone(start):
        _THREAD.single = True
        try:
            return function(start)
        finally:
            _THREAD.single = False

    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(threads) as pool:
        yield from pool.map(alone, starts)


def kernel_threads() -> int:
    """Threads the compiled iteration splits a batch of pairs over: RVTE_THREADS if set, else
    every core in a main process and one in a worker process (a process pool's or a Dask
    worker, which run one per core already).  Each pair is solved alone, so the results do
    not depend on the count."""
    import multiprocessing
    import os

    text = os.environ.get("RVTE_THREADS", "").strip()
    if text:
        if not text.isdigit() or int(text) < 1:
            from ..base.checks import InputError

            raise InputError(
                "RVTE_THREADS",
                text,
                "must be a whole number >= 1 (the environment variable: threads of the compiled solver)",
            )
    if getattr(_THREAD, "single", False):
        return 1
    if text:
        return int(text)
    if multiprocessing.parent_process() is not None:
        return 1
    return os.cpu_count() or 1


def newton_compiled(work, first_active, q0=None, chain=None, release=False, stall=0):
    """`newton` by the compiled kernel (`newton_kernel.newton_pairs`), the pairs split over
    `kernel_threads` threads (the kernel releases the GIL) in batches of at least
    MIN_PAIRS_PER_THREAD, each a whole number of warm-start chains (`chain_links`)."""
    from .newton_kernel import newton_pairs

    B, nN = work.f.shape
    c = np.ascontiguousarray
    angle, stiffness, pairs, shared, bearings, law = _kernel_arguments(work)
    p = bearings[0].shape[1]
    toward = np.zeros((B, p, 2)) if work.toward is None else work.toward
    guess = np.zeros(work.pin_b.shape, dtype=bool) if first_active is None else first_active
    q = np.zeros((B, nN)) if q0 is None else np.array(q0, dtype=float)
    converged = np.zeros(B, dtype=bool)
    iterations = np.zeros(B, dtype=np.int64)
    toward, guess = c(toward, dtype=float), c(guess, dtype=np.bool_)
    chain = np.zeros(B, dtype=bool) if chain is None else c(chain, dtype=np.bool_)
    sys = work.system
    mode_unit = c(sys.mode_unit, dtype=float)

    def solve(lo, hi):
        newton_pairs(
            angle[lo:hi],
            *stiffness,
            *(a[lo:hi] for a in pairs),
            *shared,
            *(a[lo:hi] for a in bearings),
            *law,
            toward[lo:hi],
            work.toward is not None,
            guess[lo:hi],
            q[lo:hi],
            q0 is not None,
            chain[lo:hi],
            sys.reg if release else 0.0,
            mode_unit,
            MAX_ITERATIONS,
            STEP_TOLERANCE,
            GAP_TOLERANCE,
            converged[lo:hi],
            iterations[lo:hi],
            int(stall),
        )

    threads = min(kernel_threads(), B // MIN_PAIRS_PER_THREAD)
    if threads <= 1:
        solve(0, B)
    else:
        from concurrent.futures import ThreadPoolExecutor

        bounds = np.linspace(0, B, threads + 1).astype(int)
        bounds[1:-1] -= bounds[1:-1] % CHAIN_LENGTH
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(solve, bounds[:-1], bounds[1:]))
    return q, converged, int(iterations.max(initial=0))


def _kernel_arguments(work):
    """The arrays of `work` as the compiled kernels take them: (angle (B,), [K_red, mode
    stiffness, bearing rows] per angle and the unknowns those touch (`touched_columns`), [f,
    rows, pin_b] per pair, [pin_local, pin_law] shared, [bearing offsets, half clearances] per
    pair (p = 0 without bearings with clearance), [each bearing's (k, roller-law a, series
    compliance), the roller law's table])."""
    sys = work.system
    B, nN = work.f.shape
    c = np.ascontiguousarray
    if not sys.brg_k.size:
        brg_rows, brg_off, c_half = (
            np.zeros((sys.K_red.shape[0], 0, 2, nN)),
            np.zeros((B, 0, 2)),
            np.zeros((B, 0)),
        )
    else:
        brg_rows, brg_off, c_half = sys.brg_rows, work.brg_off, work.c_half
    return (
        c(work.angle, dtype=np.int64),
        [
            c(sys.K_red, dtype=float),
            c(sys.mode_stiffness, dtype=float),
            c(brg_rows, dtype=float),
            sys.brg_cols,
        ],
        [c(work.f, dtype=float), c(work.rows, dtype=float), c(work.pin_b, dtype=float)],
        [c(sys.pin_local, dtype=np.int64), c(sys.model.pin_law, dtype=float)],
        [c(brg_off, dtype=float), c(c_half, dtype=float)],
        [
            c(np.stack([sys.brg_k, sys.brg_law_a, sys.brg_law_compliance], axis=-1), dtype=float),
            c(np.stack([TABLE_E, TABLE_DE])),
        ],
    )


def compiled_hessians(work, q):
    """`Work.hessian(q, None)` by the compiled kernel (`newton_kernel.hessians`)."""
    from .newton_kernel import hessians

    angle, stiffness, pairs, shared, bearings, law = _kernel_arguments(work)
    out = np.empty(q.shape + q.shape[-1:])
    hessians(
        angle,
        *stiffness,
        *pairs,
        *shared,
        *bearings,
        *law,
        np.ascontiguousarray(q, dtype=float),
        GAP_TOLERANCE,
        out,
    )
    return out


def newton_batched(work, first_active, q0=None, stall=0):
    """`newton` in numpy, every pair of the chunk iterated together.

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
    # piecewise quadratic (linear pins, no bearing with clearance): a consistent active set is exact
    smooth = work.brg_rows is None and work.system.model.pin_law[1] == 0.0
    stalls = np.zeros(B, dtype=int)  # stalled steps in a row (with `stall`)
    iterations = 0
    for iterations in range(1, MAX_ITERATIONS + 1):
        first = iterations == 1 and not warm
        guess = first_active if first else None
        grad, hess, true_grad, used = work.gradient_hessian(q, guess, bearings_engaged=first)
        step = -np.linalg.solve(hess, grad[..., None])[..., 0]
        trial_q = q + step
        trial, delta = work.energy(trial_q)
        slope = np.einsum("bi,bi->b", true_grad, step)
        full = trial <= energy + 1e-4 * slope + 1e-13 * np.abs(energy)
        if not first:
            # a step that no longer moves is taken whole, whatever the energy's round-off says
            # (the compiled kernel then ends the pair without evaluating its end)
            full |= np.max(np.abs(step), axis=1) <= STEP_TOLERANCE + 1e-12 * np.max(np.abs(trial_q), axis=1)
        alpha = np.ones(len(q))
        if not np.all(full):
            short = np.flatnonzero(~full)
            alpha[short] = work.subset(short).line_search(q[short], step[short])
        move = alpha[:, None] * step
        move[converged[ids]] = 0.0  # pairs already done but still in the arrays stay put
        q = q + move
        before = energy
        energy = trial if np.all(full) else np.where(full, trial, work.energy(q)[0])
        result[ids] = q
        # Done when a full step landed where exactly the pins it assumed touch (the
        # minimiser of that piece of the energy), or when a step no longer moves.
        done = np.max(np.abs(move), axis=1) <= STEP_TOLERANCE + 1e-12 * np.max(np.abs(q), axis=1)
        if first:
            # A guessed step that does not go downhill says nothing about convergence.
            done[:] = False
        elif stall:
            stalled = full & (np.max(np.abs(move), axis=1) <= STALL_STEP)
            stalled &= np.abs(trial - before) <= 1e-13 * np.abs(before)
            stalls = np.where(stalled & ~done, stalls + 1, 0)
            done |= stalls >= stall
        if smooth:
            consistent = np.where(used, delta >= -GAP_TOLERANCE, delta <= GAP_TOLERANCE)
            done |= full & np.all(consistent, axis=(1, 2))
        done |= converged[ids]
        converged[ids[done]] = True
        if np.all(done):
            break
        if np.count_nonzero(done) > SHRINK_FRACTION * len(done):
            keep = np.flatnonzero(~done)
            work, q, ids, energy, stalls = work.subset(keep), q[keep], ids[keep], energy[keep], stalls[keep]
    return result, converged, iterations


class Work:
    """Per-pair arrays of the Newton iteration, gathered once and shrunk as pairs converge.

    rows (B, 2, K, 3) and pin_b (B, 2, K) are those of the K pins per disc taken
    into the iteration (all of them, or the candidates that the load can close).
    bearing_direction (B, p, 2), optional: the unit direction in which each
    bearing with clearance is probably loaded (zero where unknown), for the first step.
    """

    def __init__(self, system, angle, f, rows, pin_b, brg_off, c_half, bearing_direction=None):
        self.system = system
        self.angle = angle
        self.rows = rows
        self.f, self.pin_b, self.brg_off, self.c_half = f, pin_b, brg_off, c_half
        self.toward = bearing_direction if system.brg_k.size else None

    def subset(self, keep):
        new = object.__new__(Work)
        new.system, new.angle = self.system, self.angle[keep]
        for name in ("rows", "f", "pin_b", "brg_off", "c_half"):
            setattr(new, name, getattr(self, name)[keep])
        for name in ("products", "K", "brg_rows"):
            if self.__dict__.get(name) is not None:
                setattr(new, name, getattr(self, name)[keep])
        new.toward = None if self.toward is None else self.toward[keep]
        return new

    @cached_property
    def brg_rows(self):
        """(B, p, 2, nN) the rows of the bearings with clearance at each pair's angle, None
        without such bearings: gathered on first use (the compiled iteration reads the
        system's, per angle)."""
        return self.system.brg_rows[self.angle] if self.system.brg_k.size else None

    @cached_property
    def K(self):
        """(B, nN, nN) each pair's reduced stiffness: gathered on first use (the compiled
        iteration reads the system's, per angle)."""
        return self.system.K_red[self.angle]

    @cached_property
    def products(self):
        """(B, 2, K, 6) the pins' row products for the Hessian blocks: made on first use, so
        that the compiled iteration, which never reads them, does not pay for them."""
        return row_products(self.rows)

    def load_direction(self):
        """d(gradient)/d(-tau): the reduced load vector (B, nN)."""
        return self.system.g_red[self.angle]

    def _local(self, q):
        return q[:, self.system.pin_local]  # (B, 2, 3)

    def _bearing(self, q):
        return np.einsum("bpxn,bn->bpx", self.brg_rows, q) + self.brg_off

    def delta(self, q):
        return pin_delta(self.rows, self._local(q), self.pin_b)

    def energy(self, q):
        """(reduced energy (B,) [J] up to a constant, pin deflections (B, 2, K) [m])."""
        sys = self.system
        kq = np.matmul(self.K, q[..., None])[..., 0]
        e = np.einsum("bi,bi->b", q, 0.5 * kq + self.f)
        delta = self.delta(q)
        e += contacts(delta, sys.model.pin_law)[0].sum(axis=(1, 2))
        if self.brg_rows is not None:
            e += bearing_law(self._bearing(q), self.c_half, sys)[0].sum(axis=1)
        return e, delta

    def true_gradient(self, q):
        """Gradient (B, nN) of the true energy at q: its out-of-balance force."""
        sys = self.system
        grad = np.matmul(self.K, q[..., None])[..., 0] + self.f
        force = contacts(self.delta(q), sys.model.pin_law)[1]
        gen = np.matmul(force[:, :, None, :], self.rows)[:, :, 0]  # (B, 2, 3)
        for j in range(2):
            grad[:, sys.pin_local[j]] += gen[:, j]
        if self.brg_rows is not None:
            grad += np.einsum(
                "bpxn,bpx->bn", self.brg_rows, bearing_law(self._bearing(q), self.c_half, sys)[1]
            )
        return grad

    def gradient_hessian(self, q, active=None, bearings_engaged=False):
        """(gradient, Hessian, true gradient, pins taken as touching) at q.

        With `active` (B, 2, K) the gradient and Hessian are those of the energy
        with exactly those pins bonded (a primal-dual active-set step); the true
        gradient is always that of the real energy.  With `bearings_engaged` every
        bearing with clearance is taken as engaged: a spring of its stiffness
        pulling it across its clearance in its `bearing_direction` where that is
        known (the bearings' own primal-dual step: from inside the clearance, one
        step lands where the loaded bearings bear), centred where it stands elsewhere.
        """
        sys = self.system
        kp = sys.model.pin_k
        base = np.matmul(self.K, q[..., None])[..., 0] + self.f
        delta = self.delta(q)
        _, law_force, law_tangent = contacts(delta, sys.model.pin_law)
        if active is None:
            # A pin exactly at contact (where an exact line search stops) counts as touching,
            # with the stated stiffness: that choice of the generalised Jacobian keeps the
            # mechanism mode held.
            active = delta > -GAP_TOLERANCE
            force = true_force = law_force
            stiffness = np.where(delta > 0.0, law_tangent, kp) * active
        else:
            # the guessed pins bonded at their real gaps by the stated stiffness
            force = kp * delta * active
            true_force = law_force
            stiffness = kp * active
        grad = base.copy()
        gen = np.matmul(force[:, :, None, :], self.rows)[:, :, 0]  # (B, 2, 3)
        hess = self.K + sys.mode_stiffness[self.angle]
        upper = np.matmul(stiffness[:, :, None, :], self.products)[:, :, 0]  # (B, 2, 6)
        blocks = upper[..., _SYMMETRIC]  # (B, 2, 3, 3)
        for j in range(2):
            idx = sys.pin_local[j]
            grad[:, idx] += gen[:, j]
            hess[:, idx[:, None], idx[None, :]] += blocks[:, j]
        if true_force is force:
            true_grad = grad.copy()
        else:
            true_grad = base.copy()
            true_gen = np.matmul(true_force[:, :, None, :], self.rows)[:, :, 0]
            for j in range(2):
                true_grad[:, sys.pin_local[j]] += true_gen[:, j]
        if self.brg_rows is not None:
            d = self._bearing(q)
            _, force, tangent = bearing_law(d, self.c_half, sys)
            bforce = np.einsum("bpxn,bpx->bn", self.brg_rows, force)
            true_grad += bforce
            if bearings_engaged and self.toward is not None:
                pull = (d - self.c_half[..., None] * self.toward) * sys.brg_k[:, None]
                bforce = np.einsum("bpxn,bpx->bn", self.brg_rows, pull)
            grad += bforce
            if bearings_engaged:
                tangent = np.broadcast_to(
                    np.eye(2) * sys.brg_k[:, None, None], self.brg_off.shape[:2] + (2, 2)
                )
            # sum over bearings and directions of row^T tangent row: one (B, nN, 2p) @ (B, 2p, nN)
            B, p, _, n = self.brg_rows.shape
            pulled = np.matmul(tangent, self.brg_rows).reshape(B, 2 * p, n)
            hess = hess + np.matmul(self.brg_rows.transpose(0, 3, 1, 2).reshape(B, n, 2 * p), pulled)
        return grad, hess, true_grad, active

    def hessian(self, q, active):
        """(B, nN, nN) the Hessian at q with the pins `active` (None: those touching),
        compiled where numba is (`newton_kernel.hessians`) and `active` is None."""
        if active is None and newton_kernel.COMPILED:
            return compiled_hessians(self, q)
        return self.gradient_hessian(q, active)[1]

    def line_search(self, q, step):
        """Exact minimiser of the energy along `step`, (B,) step lengths.

        Along the line the energy is a convex 1-D function whose derivative is
        piecewise linear in linear pins (and smooth in Hertz pins and the bearings); a safeguarded
        Newton iteration on that derivative, inside a bracket, finds its zero.
        Its pieces are computed once, so each trial costs a few elementwise operations.
        """
        sys = self.system
        k_step = np.matmul(self.K, step[..., None])[..., 0]
        quad = np.einsum("bi,bi->b", step, k_step)
        lin = np.einsum("bi,bi->b", np.matmul(self.K, q[..., None])[..., 0] + self.f, step)
        delta0 = self.delta(q)
        ddelta = pin_delta(self.rows, self._local(step), 0.0)
        law = sys.model.pin_law
        if self.brg_rows is not None:
            d0 = self._bearing(q)
            dd = np.einsum("bpxn,bn->bpx", self.brg_rows, step)

        def slope(alpha, t):
            """(first, second) derivative of the energy along the line at alpha, pairs t."""
            a = alpha[:, None, None]
            _, force, tangent = contacts(delta0[t] + a * ddelta[t], law)
            d1 = quad[t] * alpha + lin[t] + np.einsum("bjk,bjk->b", force, ddelta[t])
            d2 = quad[t] + np.einsum("bjk,bjk->b", tangent * ddelta[t], ddelta[t])
            if self.brg_rows is not None:
                d = d0[t] + a * dd[t]
                _, force, tangent = bearing_law(d, self.c_half[t], sys)
                d1 = d1 + np.einsum("bpx,bpx->b", force, dd[t])
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


_UPPER = np.triu_indices(3)  # the six distinct entries of a 3x3 block
_SYMMETRIC = np.array([[0, 1, 2], [1, 3, 4], [2, 4, 5]])  # their places in the full block


def row_products(rows):
    """The six distinct products of each pin's row with itself (..., 6), for Hessian blocks."""
    return rows[..., _UPPER[0]] * rows[..., _UPPER[1]]


def bearing_law(d, c_half, system):
    """(energy (B, p) [J], force (B, p, 2) [N], tangent stiffness (B, p, 2, 2) [N/m]) of the
    isotropic bearings of `system` (its brg_k, and brg_law_a, brg_law_compliance for those
    that follow the roller law, `roller_law`) with free play c_half at deflection d (B, p, 2).

    Radial force F(s) along d/s, s = |d|: k (s - c) outside the play for a linear bearing,
    the roller law for the others; the tangent is F'(s) along d and F(s)/s across it."""
    s = np.linalg.norm(d, axis=-1)
    over = np.maximum(s - c_half, 0.0)
    k, a = system.brg_k, system.brg_law_a
    energy, force, radial = 0.5 * k * over * over, k * over, k * (over > 0.0)
    # across: F/s, written k (1 - c/s) for a linear bearing so that it is k at s = 0, c = 0
    across = np.where(over > 0.0, k * (1.0 - c_half / np.maximum(s, 1e-300)), 0.0)
    rollers = a > 0.0
    if np.any(rollers):
        e_r, f_r, k_r = radial_law(
            s[:, rollers], c_half[:, rollers], a[rollers], system.brg_law_compliance[rollers]
        )
        energy[:, rollers], force[:, rollers], radial[:, rollers] = e_r, f_r, k_r
        across[:, rollers] = f_r / np.maximum(s[:, rollers], 1e-300)
    n_hat = d / np.maximum(s, 1e-300)[..., None]
    along = n_hat[..., :, None] * n_hat[..., None, :]
    tangent = across[..., None, None] * np.eye(2) + (radial - across)[..., None, None] * along
    return energy, force[..., None] * n_hat, tangent


def pin_delta(rows, q_local, offset):
    """Pin deflections (B, 2, z_p) from disc unknowns (B, 2, 3)."""
    return np.matmul(rows, q_local[..., None])[..., 0] + offset
