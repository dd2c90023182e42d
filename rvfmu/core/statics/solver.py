"""Static equilibrium of the equivalent model for many (reducer, angle) pairs at once.

The equilibrium minimises a convex energy: quadratic in the linear springs,
in the unilateral pin contacts that of their law (`pin_law`: the linear spring,
piecewise quadratic, or the Hertz law), in the bearings with clearance or with
rollers that of the linear spring beyond the clearance or of the roller law
(`roller_law`), minus the work of the output torque.  An active-set
Newton method on that energy (`newton.py`) finds it; which pins touch is found
by the iteration, never assumed.

Speed comes from structure, not from approximations:
- every unknown that only linear springs touch (the sun, and with no bearing
  clearance the cranks and the carrier) is condensed out exactly, per angle, by
  a Schur complement that all reducers of a batch share; the Newton iteration
  runs on the six disc unknowns (more when bearings have clearance);
- the no-load limit without bearing clearance needs no iteration at all: the
  linear parts take their (pre)stressed shape, then the reducer turns along its
  zero-energy mechanism mode until the first pin touches (docs/model.md section 5);
  only where that leaves a pin in interference, or with bearing clearance, is
  the equilibrium under a small probe torque solved and taken back to zero (with
  the roller law and no clearance, the kinematic pose is only the start of the
  law's one solve, interference and all);
- the Newton iteration is compiled and runs pair by pair, each stopping when it
  has converged (`newton_kernel`; without numba, all pairs are iterated together
  in numpy and those that have converged leave the batch), and the pairs come
  in chunks so that memory stays bounded;
- the compiled iteration starts each pair from the solution of the same reducer at
  the previous angle (`newton.chain_links`), and a pair started from a nearby
  equilibrium takes every pin in at once: the minimiser does not depend on the
  start, the number of steps to it does (docs/model.md section 5).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from ..base.compiled import kernel
from ..laws.pin_law import contact_forces, contacts
from ..reducer.errors import ErrorSet, zero_errors
from . import newton_kernel
from .equivalent import EquivalentModel, touched_columns
from .newton import (
    CHAIN_LENGTH,
    CHUNKS_PER_THREAD,
    GAP_TOLERANCE,
    Work,
    chain_links,
    kernel_threads,
    map_chunks,
    newton,
    pin_delta,
)

CHUNK = 4096  # pairs per chunk: ~40 MB of work arrays
ANGLE_BLOCK = 512  # angles per block of `ReducedSystem`'s arrays
REGULARISATION = 1e-6  # relative to the softest element (`weak_stiffness`): keeps floating
# parts determinate
# The sun support holds the sun, always condensed out; the reduced unknowns feel it only where
# a crank floats in its bearing clearance (the cranks' turn against each other is then held by
# the sun support through the meshes), and there as about its own stiffness: the weak springs'
# share is about 0.65 x theirs over it (1.1e-3 with a sun support of 1e5 N/m, 100 um
# clearances, weak springs 164 N/m).  Counted 30 times it bounds that share near 3e-5 and
# leaves the presets' weak springs at (RV-40E-81: 4 % below) their meshes', 18-31 x stiffer
# than their sun supports; counted once, the springs get so weak (5.5 N/m on the RV-40E-121)
# that, with bearing clearance, the floating parts' no-load equilibrium is determinate to a
# few 1e-7 arcsec only.
SUN_SUPPORT_WEIGHT = 30.0
MODE_DIRECTION_STIFFNESS = 1e-9  # relative to the pin stiffness, Hessian only: see ReducedSystem
CONTINUATION = (1e1, 1.0)  # no load with bearing clearance: probe multiples, large to small
LAW_PROBE = 1e-3  # no load, no clearance, the roller law: one solve at this x probe, from the
# limit with the stated stiffnesses; the law's windup left there (it goes
# as load^0.9) is below 1e-3 arcsec on the RV-40E-121
LAW_RELEASE_ROUNDS = 1  # ... and after the one solve of the roller law at no load (a second and
# third move quick_mc's no-load TE by less than 1e-5 arcsec, none by 0.0012)
RELEASE_ROUNDS = 3  # no load with bearing clearance: solves with the weak springs re-centred,
# at the probe (CLEARANCE_RELEASES "probe"), or at each of the last two probe loads (the
# reference, "every")
RELEASE_RETRIES = 2  # ... and up to this many more where the last of them did not converge: a
# solve that creeps to the iteration's limit where parts barely touch their clearance circles
# converges when started again from where it stopped (5 of the 6 such last solves among the
# complete study's 17 408 reducers; studies/rv40e_121_full/README.md) ...
RETRY_STALL_STEPS = 10  # ... and a retry also ends where its steps have stalled this many times
# in a row (`newton_kernel.STALL_STEP`: the sixth, whose steps alternate across a stiff bearing's
# clearance circle 1.3e-14 m apart)
RELEASE_BELOW = 100.0  # loads up to this many probe torques get the same release
TANGENT_AGREEMENT = 3.0  # with bearing clearance: back to zero load along the tangent unless it turns
# the carrier this many times further than the chord through the last two
# probe loads
ZERO_RESIDUAL = 1e-3  # without: along the tangent where it lands in equilibrium (out-of-balance
# force below this share of the probe's load vector) ...
REFINEMENTS = 3  # ... elsewhere from probes 10x smaller, at most this many times, then the chord
CANDIDATE_MARGIN = 1  # pins per disc iterated on beyond the half that the load closes


def weak_stiffness(model: EquivalentModel) -> float:
    """Stiffness [N/m] of the weak spring on every reduced unknown: REGULARISATION x the
    softest elastic element that holds a reduced unknown (pins, meshes, bearings, and the
    sun support counted SUN_SUPPORT_WEIGHT times).

    The weak springs act in parallel with those elements, so their share of any deflection
    is about their stiffness over that of the elements carrying it: scaled with the softest
    of them it stays near REGULARISATION whatever the design.  (Scaled with the pin stiffness
    alone, pins of 1e15 N/m made them 1e9 N/m, stiffer than the crank bearings: they carried
    a third of the windup and nearly tripled the rigidity.)
    """
    d = model.design
    return REGULARISATION * min(
        d.pin_disc_stiffness,
        d.mesh_stiffness,
        d.crank_disc_bearing_stiffness,
        d.crank_carrier_bearing_stiffness,
        d.main_bearing_stiffness,
        SUN_SUPPORT_WEIGHT * d.sun_support_stiffness,
    )


@dataclass(frozen=True)
class Equilibrium:
    """Unknowns at equilibrium for B pairs.

    q: (B, n) displacements [m; rotations as arc length at R_p];
    pin_force: (B, 2, z_p) [N], >= 0; mesh_force: (B, n_c) [N], sun-planet mesh
    forces along their lines of action (compression positive), both None from a solve
    asked for the unknowns alone (`ReducedSystem.solve`, forces False); converged: (B,)
    bool; iterations: most used.
    """

    q: np.ndarray
    pin_force: np.ndarray | None
    mesh_force: np.ndarray | None
    converged: np.ndarray
    iterations: int


class ReducedSystem:
    """The equivalent model with its linear unknowns condensed out, per angle.

    `nonlinear` (nb,) bool says which bearings stay nonlinear (those with a clearance
    somewhere in the batch, and under load those that follow the roller law); the
    others join the linear springs with their stated stiffness.  With `rollers` False
    (the no-load limit with the stated stiffnesses, `_routes`) no bearing follows the
    roller law: the nonlinear ones are linear beyond their clearance.
    """

    # the kinematic no-load pose's first pin by the compiled `first_pin` where the iteration
    # is compiled (False: by numpy, `_first_pin_numpy`, the reference)
    compiled_first_pin = True

    def __init__(self, model: EquivalentModel, nonlinear: np.ndarray, rollers: bool = True):
        self.model = model
        n = model.n_dof
        A = model.pose.theta_in.size
        self.nonlinear = np.asarray(nonlinear, dtype=bool)
        lin_b = np.flatnonzero(~self.nonlinear)
        # Linear springs: meshes, sun support, bearings without clearance (x and y rows).
        self.k = np.concatenate([model.linear_k, np.repeat(model.bearing_k[lin_b], 2)])
        self.linear_bearings = lin_b
        self.nl_bearings = np.flatnonzero(self.nonlinear)

        touched = set(model.pin_dofs.ravel())
        for b in self.nl_bearings:
            touched |= set(np.flatnonzero(np.any(model.bearing_rows[:, b] != 0, axis=(0, 1))))
        self.N = np.array(sorted(touched))
        self.L = np.array([k for k in range(n) if k not in touched])
        # Pins in reduced coordinates: disc j's unknowns sit at pin_local[j] of N.
        position = {dof: k for k, dof in enumerate(self.N)}
        self.pin_local = np.array([[position[d] for d in row] for row in model.pin_dofs])
        self.brg_k = model.bearing_k[self.nl_bearings]
        self.brg_law_a = model.bearing_law_a[self.nl_bearings] * float(rollers)
        self.brg_law_compliance = model.bearing_law_compliance[self.nl_bearings]
        self.reg = weak_stiffness(model)

        # Every array below is made angle by angle, in blocks of ANGLE_BLOCK angles, on the
        # threads where there are enough blocks (`newton.map_chunks`): the same numbers as one
        # pass over all angles, to the bit, in about half the time on two threads (12 480
        # angles: 0.71 s in one pass, 0.64 s in blocks on one thread, 0.36 s on two;
        # bench_chunks.py).
        blocks = [slice(a, min(a + ANGLE_BLOCK, A)) for a in range(0, A, ANGLE_BLOCK)] or [slice(0, 0)]
        parts = list(map_chunks(self._angle_arrays, blocks))
        for name, first in parts[0].items():
            if isinstance(first, dict):
                joined = {key: np.concatenate([part[name][key] for part in parts]) for key in first}
            else:
                joined = np.concatenate([part[name] for part in parts])
            setattr(self, name, joined)
        # (nbn, w) the unknowns each nonlinear bearing touches, for the compiled loops
        self.brg_cols = touched_columns(self.brg_rows)

    def _angle_arrays(self, angles: slice) -> dict:
        """The system's arrays at the model's angles `angles`: {name: (a, ...) array, or a
        dict of them}."""
        model = self.model
        n = model.n_dof
        N, L, lin_b = self.N, self.L, self.linear_bearings
        A = angles.stop - angles.start
        out = {}
        brg_rows = model.bearing_rows[angles, lin_b].reshape(A, -1, n)
        rows = np.concatenate([model.linear_rows[angles], brg_rows], axis=1)  # (A, m, n)
        out["rows"] = rows

        K = np.einsum("ami,m,amj->aij", rows, self.k, rows)
        g = model.load_vector()
        kll = K[:, L][:, :, L]
        # G = K_LL^-1 K_LN, H = K_LL^-1 J_L^T diag(k), gl = K_LL^-1 g_L
        rhs = np.concatenate(
            [
                K[:, L][:, :, N],
                np.swapaxes(rows[:, :, L], 1, 2) * self.k,
                np.broadcast_to(g[L][None, :, None], (A, L.size, 1)),
            ],
            axis=2,
        )
        sol = np.linalg.solve(kll, rhs)
        nN = N.size
        G, H, gl = sol[:, :, :nN], sol[:, :, nN : nN + self.k.size], sol[:, :, -1]
        out["G"], out["H"], out["gl"] = G, H, gl
        knl = K[:, N][:, :, L]
        K_red = K[:, N][:, :, N] - knl @ G  # (A, nN, nN)
        out["P"] = (np.swapaxes(rows[:, :, N], 1, 2) * self.k) - knl @ H  # (A, nN, m)
        out["g_red"] = g[N][None] - np.einsum("anl,al->an", knl, gl)  # (A, nN)
        # (A, nbn, 2, nN) the nonlinear bearings' rows
        out["brg_rows"] = np.ascontiguousarray(model.bearing_rows[angles][:, self.nl_bearings][..., N])

        # Mechanism mode: the carrier turning with the input held, all but the pins
        # unstrained (carrier rotation unknown = 1).  It is the null vector of K_red.
        kfull = K.copy()
        if self.nl_bearings.size:
            nl_rows = model.bearing_rows[angles][:, self.nl_bearings]
            kfull += np.einsum("abxi,b,abxj->aij", nl_rows, self.brg_k, nl_rows)
        c = model.carrier_rot
        rest = [k for k in range(n) if k != c]
        mode = np.zeros((A, n))
        mode[:, c] = 1.0
        mode[:, rest] = -np.linalg.solve(kfull[:, rest][:, :, rest], kfull[:, rest][:, :, [c]])[..., 0]
        out["mode"] = mode
        # The carrier's rotation as a function of the reduced unknowns (its linear part).
        if c in N:
            carrier_row = np.zeros((A, nN))
            carrier_row[:, int(np.flatnonzero(N == c)[0])] = 1.0
        else:
            carrier_row = -G[:, int(np.flatnonzero(L == c)[0]), :]
        out["carrier_row"] = carrier_row
        pin_rows = model.pin_rows[angles]
        pin_rate = np.einsum("ajkx,ajx->ajk", pin_rows, mode[:, model.pin_dofs])
        out["pin_rate"] = pin_rate
        # Candidate pins: those the load closes (about half) and a margin of the nearly
        # square ones; the others are checked after the solve and taken in if they touch.
        keep = min(model.design.z_p, model.design.z_p // 2 + CANDIDATE_MARGIN)
        candidates = {
            direction: np.sort(np.argsort(-pin_rate * direction, axis=-1)[..., :keep], axis=-1)
            for direction in (-1.0, 1.0)
        }
        out["candidates"] = candidates
        out["candidate_rows"] = {
            direction: np.take_along_axis(pin_rows, cand[..., None], axis=2)
            for direction, cand in candidates.items()
        }
        if not self.nl_bearings.size:
            # Shape of the linear parts with the mode held: [K_red m; m^T 0] bordered solve.
            mN = mode[:, N]
            border = np.zeros((A, nN + 1, nN + 1))
            border[:, :nN, :nN] = K_red
            border[:, :nN, nN] = mN
            border[:, nN, :nN] = mN
            out["free_shape"] = np.linalg.inv(border)[:, :nN, :nN]  # q = -Z f
        # A weak spring on every reduced unknown keeps parts that float in a clearance
        # determinate; it leaves the mechanism mode free, so that however small the
        # load, only the pins stop the carrier.
        m_hat = mode[:, N] / np.linalg.norm(mode[:, N], axis=1, keepdims=True)
        along = m_hat[:, :, None] * m_hat[:, None, :]
        out["mode_unit"] = np.ascontiguousarray(m_hat)  # (A, nN)
        reg_matrix = self.reg * (np.eye(nN) - along)
        out["reg_matrix"] = reg_matrix
        out["K_red"] = K_red + reg_matrix
        # Newton directions need some stiffness along the mode before a pin touches; this
        # one enters the Hessian only (the energy and its minimiser do not see it).
        out["mode_stiffness"] = np.ascontiguousarray(MODE_DIRECTION_STIFFNESS * model.pin_k * along)
        return out

    # -- one chunk -------------------------------------------------------------------------
    def solve(
        self,
        errors: ErrorSet,
        sample,
        angle,
        tau_load,
        half_clearance,
        probe,
        first_count=None,
        bearing_direction=None,
        start=None,
        start_only=False,
        release_step=True,
        offsets=None,
        forces=True,
        clearance_release="probe",
    ) -> Equilibrium:
        """Equilibrium of the pairs (sample[b], angle[b]) under tau_load[b] [N*m].

        tau_load == 0 gives the no-load limit from the side of the signed probe
        torque `probe` (negative: a resisting load, docs/model.md section 5; positive: a
        driving one); where it needs an elastic solve (interference, bearing
        clearance) the equilibrium under `probe` (with bearing clearance reached
        by continuation over CONTINUATION x probe, the weak springs released as
        `clearance_release` says) is taken back to zero load (`_to_zero_load`).
        first_count: (B, 2) int, optional: how many pins of each disc probably touch
        (from the error-free reducer, at the load of the pair's first elastic solve:
        its own, or the first probe torque); the first guess takes that many, those
        the load closes first.  bearing_direction: (B, p, 2), optional: the unit
        direction in which each bearing with clearance is loaded there in the
        error-free reducer (zero where it carries nothing); the first step takes
        those bearings across their clearance that way (`Work.gradient_hessian`).
        start: (B, n) optional, all unknowns of each pair at a nearby equilibrium (the
        no-load limit with the stated stiffnesses): the no-load pairs of a system with
        the roller law then start there and are solved at LAW_PROBE x probe.
        start_only: the no-load pairs without bearing clearance keep their kinematic pose
        (`_first_contact`) even where it leaves a pin in interference: it is only the start
        of the roller law's solve, whose minimiser does not depend on where it starts, so
        the elastic solve with the stated stiffnesses that would remove the interference
        first is skipped (it changes the law's result by the Newton tolerance alone).
        release_step: after the roller law's no-load solve (`start`), the weak springs let
        go by one Newton step (`newton.release_step`) instead of LAW_RELEASE_ROUNDS solves.
        offsets: `model.offsets(errors, sample, angle)` when the caller has them already.
        forces: False leaves the pins' and meshes' forces out (None): a solve whose unknowns
        only start the next one.
        clearance_release: with bearing clearance, where the weak springs let go, by
        RELEASE_ROUNDS solves with them re-centred (`_release`): "probe", at the probe alone
        (the solve at 10 probes only starts the probe's and anchors the chord back to zero
        load); "every", at each of the two probe loads (the reference; docs/model.md section 5).
        """
        model = self.model
        B = len(angle)
        lin_b, brg_b, pin_b = model.offsets(errors, sample, angle) if offsets is None else offsets
        b_lin = np.concatenate([lin_b, brg_b[:, self.linear_bearings].reshape(B, -1)], axis=1)
        tau = np.array(tau_load, dtype=float)
        zero = tau == 0.0
        f0 = np.einsum("bnm,bm->bn", self.P[angle], b_lin)
        brg_off = brg_b[:, self.nl_bearings]
        c_half = half_clearance[sample][:, self.nl_bearings]
        qn = np.zeros((B, self.N.size))
        converged = np.ones(B, dtype=bool)

        elastic = ~zero
        if np.any(zero):
            if self.nl_bearings.size:
                elastic |= zero
            else:
                z = np.flatnonzero(zero)
                qz, rigid = self._first_contact(angle[z], f0[z], pin_b[z], np.sign(probe))
                qn[z] = qz
                if not start_only:
                    elastic[z[~rigid]] = True
        iterations = 0
        groups = [np.flatnonzero(elastic & ~zero), np.flatnonzero(elastic & zero)]
        for group, at_zero in zip(groups, (False, True)):
            if group.size == 0:
                continue
            loads = tau[group]
            q_start = None
            chain = chain_links(sample[group], angle[group], loads)
            if at_zero:
                # Probe torques, from large to small when parts float in bearing clearances
                # (each solve starts from the last), the last one the probe itself.
                steps = self._probe_steps()
                if start is not None:
                    steps, q_start = (LAW_PROBE,), start[group][:, self.N]
                path = []
                for k, scale in enumerate(steps):
                    loads = np.full(group.size, probe * scale)
                    cold = q_start is None
                    # the roller law's solve lets go of the weak springs by one Newton step at
                    # its end (`newton.newton`, release); rounds: solves with the springs
                    # re-centred after it
                    if start is not None:
                        step_release = release_step
                        rounds = 0 if release_step else LAW_RELEASE_ROUNDS
                    else:
                        step_release = False
                        releasing = 1 if clearance_release == "probe" else 2  # the last loads
                        rounds = RELEASE_ROUNDS if k >= len(steps) - releasing else 0
                    q_start, conv, its = self._solve_group(
                        group,
                        angle,
                        f0,
                        pin_b,
                        brg_off,
                        c_half,
                        loads,
                        first_count if cold else None,
                        bearing_direction if cold else None,
                        q_start,
                        chain=chain if cold else None,
                        every_pin=bool(self.nl_bearings.size),
                        release=step_release,
                    )
                    iterations += its
                    if self.nl_bearings.size and rounds:
                        q_start, released, its = self._release(
                            group, angle, f0, pin_b, brg_off, c_half, loads, q_start, rounds
                        )
                        # the probe's own solve only starts them, as the solve at 10 probes
                        # starts the probe's: the point is converged where its last solve is
                        conv = released
                        iterations += its
                    path.append((probe * scale, q_start))
                if start is not None:
                    # the roller law's windup vanishes as load^0.9, which a step back along
                    # the tangent would not undo: the solution at LAW_PROBE x probe is the limit
                    qn[group] = q_start
                else:
                    qn[group], refined, its = self._back_to_zero(
                        group, angle, f0, pin_b, brg_off, c_half, path[-2:]
                    )
                    conv = conv & refined
                    iterations += its
            else:
                qn[group], conv, its = self._solve_group(
                    group,
                    angle,
                    f0,
                    pin_b,
                    brg_off,
                    c_half,
                    loads,
                    first_count,
                    bearing_direction,
                    None,
                    chain=chain,
                )
                iterations += its
                # Small loads feel the weak springs too: released the same way.
                light = np.abs(loads) <= RELEASE_BELOW * abs(probe)
                if self.nl_bearings.size and np.any(light):
                    some = group[light]
                    qn[some], conv[light], its = self._release(
                        some, angle, f0, pin_b, brg_off, c_half, loads[light], qn[some]
                    )
                    iterations += its
            converged[group] = conv
        q = np.empty((B, model.n_dof))
        q[:, self.N] = qn
        q[:, self.L] = (
            -(np.einsum("aln,an->al", self.G[angle], qn) + np.einsum("alm,am->al", self.H[angle], b_lin))
            + tau[:, None] * self.gl[angle]
        )
        if not forces:
            return Equilibrium(q, None, None, converged, iterations)
        delta = pin_delta(model.pin_rows[angle], qn[:, self.pin_local], pin_b)
        n_c = model.design.n_c
        mesh = np.einsum("bmn,bn->bm", model.linear_rows[angle][:, :n_c], q) + lin_b[:, :n_c]
        return Equilibrium(
            q, pin_forces(delta, model.pin_law), model.linear_k[:n_c] * mesh, converged, iterations
        )

    def _probe_steps(self):
        """The probe multiples of the no-load solves, large to small, the probe itself last."""
        return CONTINUATION if self.nl_bearings.size else (1.0,)

    def _solve_group(
        self,
        group,
        angle,
        f0,
        pin_b,
        brg_off,
        c_half,
        loads,
        first_count,
        bearing_direction,
        q0,
        centre=None,
        chain=None,
        every_pin=False,
        release=False,
        stall=0,
    ):
        a = angle[group]
        f = f0[group] - loads[:, None] * self.g_red[a]
        if centre is not None:
            f = f - self.reg_pull(a, centre)
        direction = np.where(loads > 0, 1.0, -1.0)
        count = None if first_count is None else first_count[group]
        toward = None if bearing_direction is None else bearing_direction[group]
        return self._elastic(
            a,
            f,
            pin_b[group],
            brg_off[group],
            c_half[group],
            direction,
            count,
            q0,
            f_errors=f0[group],
            bearing_direction=toward,
            chain=chain,
            every_pin=every_pin,
            release=release,
            stall=stall,
        )

    def reg_pull(self, angle, centre):
        """(B, nN) the weak springs' force at zero displacement when centred on `centre` (B, nN):
        reg_matrix[angle] @ centre, as reg (c - m (m . c)) with m the unit mode, without
        gathering the (B, nN, nN) matrices."""
        m = self.mode_unit[angle]
        return self.reg * (centre - m * np.einsum("bi,bi->b", m, centre)[:, None])

    def _release(self, group, angle, f0, pin_b, brg_off, c_half, loads, q, rounds=RELEASE_ROUNDS):
        """The weak springs let go of the floating parts: `rounds` solves of the pairs
        `group` under `loads`, each from the last with the springs centred on it (at
        convergence they pull on nothing); a pair whose last solve did not converge gets
        up to RELEASE_RETRIES more, re-centred on where it stopped, which also end where
        their steps have stalled (RETRY_STALL_STEPS).  Each solve is a whole
        equilibrium problem, so a pair is converged when its last solve is.  Returns (q_N,
        converged, iterations)."""
        iterations = 0
        for _ in range(rounds):
            q, converged, its = self._solve_group(
                group, angle, f0, pin_b, brg_off, c_half, loads, None, None, q, centre=q
            )
            iterations += its
        for _ in range(RELEASE_RETRIES if rounds else 0):
            again = np.flatnonzero(~converged)
            if again.size == 0:
                break
            q[again], converged[again], its = self._solve_group(
                group[again],
                angle,
                f0,
                pin_b,
                brg_off,
                c_half,
                loads[again],
                None,
                None,
                q[again],
                centre=q[again],
                stall=RETRY_STALL_STEPS,
            )
            iterations += its
        return q, converged, iterations

    def _back_to_zero(self, group, angle, f0, pin_b, brg_off, c_half, path, depth=0):
        """The pairs `group` from their last probe solutions (one or two) back to zero load:
        (q_N (G, nN), converged (G,), iterations).

        Without bearing clearance, where the tangent at the smaller probe does not
        land in equilibrium (`_to_zero_load`: a contact changes between the probe
        and zero), the equilibrium is solved again at a probe ten times smaller,
        starting from the last, and the step is taken from there: at most
        REFINEMENTS times, then the chord is followed.  With bearing clearance the
        chord is followed at once where the tangent disagrees with it.
        """
        q, agree = self._to_zero_load(
            angle[group], f0[group], pin_b[group], brg_off[group], c_half[group], path
        )
        converged = np.ones(group.size, dtype=bool)
        if agree.all() or depth == REFINEMENTS or self.nl_bearings.size:
            return q, converged, 0
        sub = np.flatnonzero(~agree)
        load, q_last = path[-1]
        loads = np.full(sub.size, load / 10.0)
        q_sub, conv, iterations = self._solve_group(
            group[sub], angle, f0, pin_b, brg_off, c_half, loads, None, None, q_last[sub]
        )
        q[sub], converged[sub], its = self._back_to_zero(
            group[sub],
            angle,
            f0,
            pin_b,
            brg_off,
            c_half,
            [(load, q_last[sub]), (load / 10.0, q_sub)],
            depth + 1,
        )
        converged[sub] &= conv
        return q, converged, iterations + its

    def _to_zero_load(self, angle, f0, pin_b, brg_off, c_half, path):
        """From the smaller of two probe loads back to zero: (q_N (B, nN), agree (B,)).

        path: [(load [N*m], q_N (B, nN))], the last one or two probe loads solved, the
        smaller last (the chord needs two; without clearance the first check has one and
        only the refinements have two).  The step back
        follows the tangent at the last one: exact while no contact changes between
        it and zero (it then lands in equilibrium at zero load).  Where the Hessian
        at the probe says nothing about the way to zero, the chord through the two
        solutions is followed instead and `agree` is False:
        - without bearing clearance, where the tangent does not land in equilibrium
          (out-of-balance force above ZERO_RESIDUAL of the probe's load vector: a
          pin closes or opens on the way);
        - with bearing clearance, where the tangent turns the carrier more than
          TANGENT_AGREEMENT times as far as the chord (a part just touching its
          clearance circle with hardly any force rolls around it almost freely).
        """
        load, q = path[-1]
        rows = self.model.pin_rows[angle]
        work = Work(self, angle, f0 - load * self.g_red[angle], rows, pin_b, brg_off, c_half)
        slope = np.linalg.solve(work.hessian(q, None), work.load_direction()[..., None])[..., 0]
        tangent = -load * slope
        if len(path) > 1:
            previous_load, previous = path[-2]
            chord = (q - previous) * (load / (previous_load - load))
        else:
            chord = tangent  # nothing to fall back on: the caller refines where not agreed
        if self.nl_bearings.size:
            turn_tangent = np.einsum("bn,bn->b", self.carrier_row[angle], tangent)
            turn_chord = np.einsum("bn,bn->b", self.carrier_row[angle], chord)
            agree = np.abs(turn_tangent) <= TANGENT_AGREEMENT * np.abs(turn_chord) + 1e-13
        else:
            at_zero = Work(self, angle, f0, rows, pin_b, brg_off, c_half)
            residual = np.linalg.norm(at_zero.true_gradient(q + tangent), axis=1)
            agree = residual <= ZERO_RESIDUAL * abs(load) * np.linalg.norm(self.g_red[angle], axis=1)
        return q + np.where(agree[:, None], tangent, chord), agree

    def _elastic(
        self,
        angle,
        f,
        pin_b,
        brg_off,
        c_half,
        direction,
        count,
        q0=None,
        f_errors=None,
        bearing_direction=None,
        chain=None,
        every_pin=False,
        release=False,
        stall=0,
    ):
        """Newton solve of the pairs on their candidate pins, then on all pins where needed (on
        all pins at once with `every_pin` or a start q0); chain (B,) bool: the pairs the
        compiled iteration starts from the pair before's solution (`newton.newton`); stall:
        as `newton.newton`'s.

        The first guess of the touching pins: the `count` pins of each disc that the
        turning carrier reaches first, their gaps measured once the linear parts have
        taken the shape the errors force on them (when that shape is known); the
        bearings with clearance, across it in the direction the error-free reducer
        loads them (`bearing_direction`, when known).
        """
        model = self.model
        if release and q0 is None:
            raise ValueError("the weak springs' release step needs a start q0 near the solution")
        if q0 is not None or every_pin:
            # From a nearby equilibrium every pin: left out, the other side's pins would let
            # the discs swing away from where they touch, and the solve would take them back.
            rows = model.pin_rows[angle]
            guess = (
                None
                if q0 is not None
                else self._guess(angle, rows, pin_b, self.pin_rate[angle], direction, count, f_errors)
            )
            work = Work(self, angle, f, rows, pin_b, brg_off, c_half, bearing_direction)
            return newton(work, guess, q0, chain, release, stall)
        forward = direction > 0
        cand = self.candidates[-1.0][angle]  # (B, 2, Kc)
        rows = self.candidate_rows[-1.0][angle]  # (B, 2, Kc, 3)
        if np.any(forward):
            cand[forward] = self.candidates[1.0][angle[forward]]
            rows[forward] = self.candidate_rows[1.0][angle[forward]]
        pb = np.take_along_axis(pin_b, cand, axis=2)
        guess = self._guess(
            angle,
            rows,
            pb,
            np.take_along_axis(self.pin_rate[angle], cand, axis=2),
            direction,
            count,
            f_errors,
        )
        work = Work(self, angle, f, rows, pb, brg_off, c_half, bearing_direction)
        q, converged, iterations = newton(work, guess, q0, chain, stall=stall)
        # Any pin left out that touches at the solution: solve those pairs on all pins.
        outside = np.ones(pin_b.shape, dtype=bool)
        np.put_along_axis(outside, cand, False, axis=2)
        delta = pin_delta(model.pin_rows[angle], q[:, self.pin_local], pin_b)
        redo = np.flatnonzero(np.any(outside & (delta > GAP_TOLERANCE), axis=(1, 2)))
        if redo.size:
            full = Work(
                self,
                angle[redo],
                f[redo],
                model.pin_rows[angle[redo]],
                pin_b[redo],
                brg_off[redo],
                c_half[redo],
                bearing_direction=None if bearing_direction is None else bearing_direction[redo],
            )
            first = (self.pin_rate[angle[redo]] * direction[redo, None, None]) > 0
            q[redo], converged[redo], more = newton(
                full, first, None if q0 is None else q0[redo], stall=stall
            )
            iterations = max(iterations, more)
        return q, converged, iterations

    def _guess(self, angle, rows, pb, rate, direction, count, f_errors):
        """(B, 2, K) the pins of `rows` (offsets pb, closing rates `rate` as the carrier
        turns) guessed to touch: those the load closes, or with `count` the `count` of each
        disc that the turning carrier reaches first, their gaps measured once the linear
        parts have taken the shape the errors force on them (when that shape is known)."""
        closing = rate * direction[:, None, None]
        if count is None:
            return closing > 0
        gaps = pb
        if f_errors is not None and hasattr(self, "free_shape"):
            shape = -np.einsum("bij,bj->bi", self.free_shape[angle], f_errors)
            gaps = pin_delta(rows, shape[:, self.pin_local], pb)
        with np.errstate(divide="ignore", invalid="ignore"):
            travel = np.where(closing > 0, -gaps / closing, np.inf)
        ordered = np.sort(travel, axis=-1)
        take = np.clip(count, 1, travel.shape[-1])[..., None] - 1
        return travel <= np.take_along_axis(ordered, take, axis=-1)

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
        if newton_kernel.COMPILED and self.compiled_first_pin:
            mu, rigid = np.empty(len(angle)), np.empty(len(angle), dtype=bool)
            first_pin(
                self.model.pin_rows,
                self.pin_rate,
                np.asarray(angle, dtype=np.int64),
                np.ascontiguousarray(q0[:, self.pin_local]),
                np.ascontiguousarray(pin_b, dtype=float),
                float(direction),
                GAP_TOLERANCE,
                mu,
                rigid,
            )
        else:
            mu, rigid = self._first_pin_numpy(angle, q0, pin_b, direction)
        return q0 + mu[:, None] * self.mode[angle][:, self.N], rigid

    def _first_pin_numpy(self, angle, q0, pin_b, direction):
        """(mu (B,), rigid (B,)) of `_first_contact` as numpy arrays: the reference that
        `first_pin` is held to (tests/test_quasistatic.py) and the route without numba."""
        delta0 = pin_delta(self.model.pin_rows[angle], q0[:, self.pin_local], pin_b)
        rate = self.pin_rate[angle]
        closing = rate * direction > 0  # closes as the carrier turns that way
        with np.errstate(divide="ignore", invalid="ignore"):
            # -direction * mu_k: the pin met first, coming from the far side, is the largest
            key = np.where(closing, direction * delta0 / rate, -np.inf)
        mu = -direction * key.max(axis=(1, 2))
        after = delta0 + rate * mu[:, None, None]
        rigid = np.isfinite(mu) & np.all(after <= GAP_TOLERANCE, axis=(1, 2))
        return np.where(np.isfinite(mu), mu, 0.0), rigid


@kernel
def first_pin(pin_rows, pin_rate, angle, q_local, pin_b, direction, gap_tolerance, mu, rigid):
    """`_first_contact`'s turn of the carrier for each pair b, one pair at a time: the pins'
    deflections at the shape q_local (B, 2, 3) of the discs' unknowns, pin_rows (A, 2, z_p, 3)
    and offsets pin_b (B, 2, z_p) [m], the turn mu[b] along the mode (closing rates pin_rate
    (A, 2, z_p)) that brings the first closing pin to contact coming from the far side
    (direction +1 or -1), 0 if none closes, and rigid[b]: a pin closes and no pin is then
    in interference beyond gap_tolerance.  Without the (B, 2, z_p, 3) gathers of the numpy
    route (`ReducedSystem._first_pin_numpy`)."""
    discs, pins = pin_b.shape[1], pin_b.shape[2]
    delta = np.empty((discs, pins))  # this pair's deflections at q_local, before the turn
    for b in range(angle.size):
        a = angle[b]
        key = -np.inf
        for d in range(discs):
            for k in range(pins):
                delta[d, k] = (
                    pin_rows[a, d, k, 0] * q_local[b, d, 0]
                    + pin_rows[a, d, k, 1] * q_local[b, d, 1]
                    + pin_rows[a, d, k, 2] * q_local[b, d, 2]
                ) + pin_b[b, d, k]
                rate = pin_rate[a, d, k]
                if rate * direction > 0.0:
                    key = max(key, direction * delta[d, k] / rate)
        turn = -direction * key
        ok = np.isfinite(turn)
        if ok:
            for d in range(discs):
                for k in range(pins):
                    if not delta[d, k] + pin_rate[a, d, k] * turn <= gap_tolerance:
                        ok = False
        mu[b] = turn if np.isfinite(turn) else 0.0
        rigid[b] = ok


def pin_forces(delta, law):
    """(B, 2, z_p) [N] the pins' forces at deflections delta: the compiled law where the
    iteration is compiled (`newton_kernel.COMPILED`), else `contacts` in numpy; the two agree to
    round-off (tests/test_pin_law.py)."""
    if newton_kernel.COMPILED:
        return contact_forces(np.ascontiguousarray(delta, dtype=float), np.asarray(law, dtype=float))
    return contacts(delta, law)[1]


LAW_STARTS = ("kinematic", "elastic")
LAW_RELEASES = ("step", "solve")
CLEARANCE_RELEASES = ("probe", "every")


def solve_pairs(
    model: EquivalentModel,
    errors: ErrorSet,
    sample,
    angle,
    tau_load,
    no_load_probe: float,
    progress=None,
    zero_side: int = -1,
    law_start: str = "kinematic",
    law_release: str = "step",
    forces: bool = True,
    law_after=None,
    clearance_release: str = "probe",
) -> Equilibrium:
    """Equilibria of many (reducer, angle) pairs, in chunks.

    sample, angle: (B,) indices into `errors` and `model.pose`; tau_load: (B,) [N*m].
    Where tau_load is zero the result is the no-load limit of docs/model.md section 5,
    approached from a resisting load (zero_side = -1) or a driving one (+1);
    no_load_probe [N*m] > 0 is the size of the probe torque it uses where needed.
    A bearing with clearance in any reducer of `errors` stays nonlinear for all
    of them, so then every zero-load pair takes the probe-and-continuation route.
    law_start: where the roller law's no-load solve starts without clearance (`_routes`):
    "kinematic", the kinematic pose with the stated stiffnesses, any interference left in;
    "elastic", that pose with the interference first removed by an elastic solve with
    the stated stiffnesses (the reference: the same minimiser, within the Newton
    tolerance, at about twice the Newton steps; tests/test_law_forms.py).
    law_release: how the weak springs then let go: "step", one Newton step at the end of
    the law's solve (`newton.release_step`); "solve", LAW_RELEASE_ROUNDS solves
    (`ReducedSystem._release`, the reference).
    forces: False leaves the pins' and meshes' forces out (pin_force and mesh_force None),
    for callers that read only the unknowns (the TE, the windup): the same q to the bit.
    law_after: (B,) int, optional: for each pair, another pair of this call (>= 0) whose
    solution by the roller law at no load starts its own instead of its kinematic pose, or -1,
    e.g. the same angle of a reducer with nearly the same errors.  The energy is convex, so
    the minimiser is the same (within the Newton tolerance); a start closer to it takes fewer
    steps (`quasistatic.equilibria`, start_from).  A pair named as a start must itself start
    from its kinematic pose.  The starting pairs are solved first and the chunks of the others
    wait, each for the chunks that hold its starts, so both cores stay busy.  Other routes
    ignore it.
    clearance_release: with bearing clearance at no load, where the weak springs let go:
    "probe" (the default) or "every" (the reference), `ReducedSystem.solve`.
    """
    if clearance_release not in CLEARANCE_RELEASES:
        raise ValueError(f"clearance_release {clearance_release!r}: must be one of {CLEARANCE_RELEASES}")
    if law_start not in LAW_STARTS:
        raise ValueError(f"law_start {law_start!r}: must be one of {LAW_STARTS}")
    if law_release not in LAW_RELEASES:
        raise ValueError(f"law_release {law_release!r}: must be one of {LAW_RELEASES}")
    probe = no_load_probe if zero_side > 0 else -no_load_probe
    sample, angle = np.asarray(sample), np.asarray(angle)
    tau_load = np.broadcast_to(np.asarray(tau_load, dtype=float), sample.shape)
    half = model.clearance_halves(errors)
    clearance = np.any(half > 0, axis=0)
    B = sample.size
    law_after = _law_after(law_after, B)
    q = np.empty((B, model.n_dof))
    pin_force = np.empty((B, 2, model.design.z_p)) if forces else None
    mesh_force = np.empty((B, model.design.n_c)) if forces else None
    converged = np.empty(B, dtype=bool)
    iterations = 0
    for pairs, nonlinear, rollers, then_law in _routes(model, clearance, tau_load):
        system = reduced_system(model, nonlinear, rollers)
        law = reduced_system(model, model.bearing_law_a > 0.0, True) if then_law else None
        # the error-free reducer's first guesses serve elastic solves from a cold start, which the
        # roller law's no-load route from the kinematic pose has none of
        kinematic = law is not None and law_start == "kinematic"
        count, toward = (
            (None, None)
            if kinematic
            else _nominal_guess(system, errors, sample[pairs], angle[pairs], tau_load[pairs], probe)
        )
        starts = None
        if law is not None and law_after is not None:  # the starting pairs first
            starts = _LawStarts(pairs, law_after, model.n_dof)
            pairs = pairs[starts.order]
            count = None if count is None else count[starts.order]
            toward = None if toward is None else toward[starts.order]

        def solve_chunk(part, pairs=pairs, system=system, law=law, count=count, toward=toward, starts=starts):
            at = pairs[part]
            offsets = model.offsets(errors, sample[at], angle[at])  # the two solves' both
            eq = system.solve(
                errors,
                sample[at],
                angle[at],
                tau_load[at],
                half,
                probe,
                None if count is None else count[part],
                None if toward is None else toward[part],
                start_only=kinematic,
                offsets=offsets,
                forces=forces and law is None,  # with the law, only its solve's forces are the answer's
                clearance_release=clearance_release,
            )
            if law is not None:
                # the kinematic limit with the stated stiffnesses is within a fraction of an
                # arcsec of that with the roller law, which starts there (or where law_after says)
                start = eq.q if starts is None else starts.starts(part, eq.q)
                eq = law.solve(
                    errors,
                    sample[at],
                    angle[at],
                    tau_load[at],
                    half,
                    probe,
                    start=start,
                    release_step=law_release == "step",
                    offsets=offsets,
                    forces=forces,
                )
            return at, eq

        def chunk(part, solve_chunk=solve_chunk, starts=starts):
            if starts is None:
                return solve_chunk(part)
            solution = None
            try:
                at, eq = solve_chunk(part)
                solution = eq.q
                return at, eq
            finally:  # the chunks waiting for these solutions go on, from their own starts on a failure
                starts.solved(part, solution)

        parts = _chunks(pairs.size) if starts is None else starts.parts
        for at, eq in map_chunks(chunk, parts):
            q[at], converged[at] = eq.q, eq.converged
            if forces:
                pin_force[at], mesh_force[at] = eq.pin_force, eq.mesh_force
            iterations = max(iterations, eq.iterations)
            if progress is not None:
                progress(at.size)
    return Equilibrium(q, pin_force, mesh_force, converged, iterations)


def _law_after(law_after, pairs: int) -> np.ndarray | None:
    """`solve_pairs`' law_after checked: (B,) int, -1 where a pair starts from its kinematic pose."""
    if law_after is None:
        return None
    after = np.asarray(law_after)
    index = np.arange(pairs)
    if (
        after.shape != (pairs,)
        or not np.issubdtype(after.dtype, np.integer)
        or np.any(after >= pairs)
        or np.any(after == index)
        or np.any((after >= 0) & (after[np.maximum(after, 0)] >= 0))
    ):
        raise ValueError(
            f"law_after: must be {pairs} indices of other pairs, each of which starts from its "
            "kinematic pose (-1), or -1"
        )
    return np.where(after < 0, -1, after)


class _LawStarts:
    """Which pairs of a route start their roller law's solve from another pair's solution
    (`solve_pairs`, law_after), in the route's order with the starting pairs first (`order`),
    and those solutions as the chunks find them: a chunk waits for the chunks that hold its
    starts (`starts`), and tells the ones waiting for its own when it has them (`solved`).
    A chunk only waits for chunks before it, which the threads of `newton.map_chunks` took
    up before it (in order), so the waits end."""

    def __init__(self, pairs: np.ndarray, law_after: np.ndarray, n_dof: int):
        B = law_after.size
        position = np.full(B, -1)
        position[pairs] = np.arange(pairs.size)
        source = law_after[pairs]  # a copy (fancy indexing)
        source[position[np.maximum(source, 0)] < 0] = -1  # a start outside this route: none
        self.order = np.argsort(source >= 0, kind="stable")
        self.pairs = pairs[self.order]
        self.source = source[self.order]
        # chunks of the starting pairs, then of the others: none holds both
        first = int(np.count_nonzero(self.source < 0))
        self.parts = _chunks(first) + _chunks(pairs.size - first, first)
        position[self.pairs] = np.arange(pairs.size)
        begins = np.array([part.start for part in self.parts])
        self.source_chunk = np.searchsorted(begins, position[np.maximum(self.source, 0)], side="right") - 1
        self.solutions = np.full((B, n_dof), np.nan)
        self.ready = {part.start: threading.Event() for part in self.parts}

    def starts(self, part: slice, kinematic: np.ndarray) -> np.ndarray:
        """The starts of the chunk `part` of the route: its kinematic poses (C, n_dof), where
        given the solutions of the pairs named (waited for)."""
        source = self.source[part]
        given = source >= 0
        if not given.any():
            return kinematic
        for c in np.unique(self.source_chunk[part][given]):
            self.ready[self.parts[c].start].wait()
        start = kinematic.copy()
        found = self.solutions[source[given]]
        near = np.isfinite(found).all(axis=1)
        start[np.flatnonzero(given)[near]] = found[near]
        return start

    def solved(self, part: slice, q: np.ndarray | None) -> None:
        """The chunk `part` is done: its solutions q (C, n_dof), or None where its solve failed."""
        if q is not None:
            self.solutions[self.pairs[part]] = q
        self.ready[part.start].set()


def _chunks(size: int, begin: int = 0) -> list[slice]:
    """The chunks of the pairs begin ... begin + size - 1: at most CHUNK pairs each, as equal as
    whole warm-start chains allow (`newton.chain_links`: a chunk's chains are those of one call
    with all the pairs, so the results do not depend on the chunks), and where they run on
    threads (`newton.map_chunks`) a multiple of the threads in number, so that no thread waits
    at the end for another's last chunk (a batch of quick_mc, 46 080 pairs: 12 chunks of 3840
    instead of 11 of 4096 and one of 1024)."""
    if size <= 0:
        return []
    count = -(-size // CHUNK)
    threads = kernel_threads()
    if threads > 1 and count >= CHUNKS_PER_THREAD * threads:
        count = -(-count // threads) * threads
    per = -(-size // count)
    per = min(CHUNK, -(-per // CHAIN_LENGTH) * CHAIN_LENGTH)
    return [slice(start, min(start + per, begin + size)) for start in range(begin, begin + size, per)]


def reduced_system(model: EquivalentModel, nonlinear, rollers: bool) -> ReducedSystem:
    """`ReducedSystem(model, nonlinear, rollers)`, kept on the model for its next solves (a
    study's batches solve the same model: `quasistatic.equivalent_model`)."""
    kept = model.__dict__.setdefault("_reduced_systems", {})
    key = (np.asarray(nonlinear, dtype=bool).tobytes(), bool(rollers))
    system = kept.get(key)
    if system is None:
        system = kept[key] = ReducedSystem(model, nonlinear, rollers)
    return system


def _routes(model, clearance, tau_load):
    """[(pairs, nonlinear bearings, rollers, then_law)]: how to solve which pairs.

    The bearings with clearance are nonlinear for every pair, and under load so are
    those that follow the roller law, with their law.  At no load the limit is found
    with the stated stiffnesses first (kinematics, or the continuation with
    clearance).  Without clearance it then moves to the roller law (then_law): the
    over-constrained chain's self-stress and any preload from the errors are carried
    by the law, which a single solve at LAW_PROBE x the probe, started from the
    kinematic limit with the stated stiffnesses (pins in interference left in: the
    law's solve removes it), finds (`solve_pairs`).  With clearance the law's
    bearings stay linear beyond it at no load (docs/model.md section 6)."""
    law = model.bearing_law_a > 0.0
    if not law.any():
        return [(np.arange(tau_load.size), clearance, False, False)]
    loaded = tau_load != 0.0
    routes = [
        (np.flatnonzero(~loaded), clearance, False, not clearance.any()),
        (np.flatnonzero(loaded), clearance | law, True, False),
    ]
    return [route for route in routes if route[0].size]


NOMINAL_GUESS_MIN_SAMPLES = 4  # below this, solving the error-free reducer first costs more than it saves
NOMINAL_GUESSES_KEPT = 4  # first guesses kept per reduced system for the next batch


def _nominal_guess(system, errors, sample, angle, tau_load, probe):
    """What the error-free reducer (no clearance) does at each pair's angle and the load
    of the pair's first elastic solve (its own, or at zero load the first probe torque):
    (pins per disc touching (B, 2), unit direction of each bearing with clearance's
    deflection (B, p, 2), zero where it carries nothing), or (None, None)."""
    if errors.samples < NOMINAL_GUESS_MIN_SAMPLES:
        return None, None
    first_probe = probe * system._probe_steps()[0]
    tau_load = np.where(tau_load == 0.0, first_probe, tau_load)
    # kept on the system for the next batch of the same pairs (`reduced_system`)
    kept = system.__dict__.setdefault("_nominal_guesses", {})
    key = (np.ascontiguousarray(angle).tobytes(), tau_load.tobytes(), float(probe))
    guess = kept.get(key)  # one lookup: another thread may clear the dict meanwhile
    if guess is None:
        guess = _solve_nominal_guess(system, angle, tau_load, probe)
        if len(kept) >= NOMINAL_GUESSES_KEPT:
            kept.clear()
        kept[key] = guess
    return guess


def _solve_nominal_guess(system, angle, tau_load, probe):
    """`_nominal_guess` solved: the error-free reducer at each distinct (angle, load)."""
    keys, inverse = np.unique(np.stack([angle, tau_load]), axis=1, return_inverse=True)
    a_u, t_u = keys[0].astype(int), keys[1]
    nominal = zero_errors(system.model.design, 1)
    half = np.zeros((1, system.model.bearing_k.size))
    counts = np.empty((a_u.size, 2), dtype=int)
    toward = np.zeros((a_u.size, system.nl_bearings.size, 2))
    for start in range(0, a_u.size, CHUNK):
        part = slice(start, min(start + CHUNK, a_u.size))
        eq = system.solve(
            nominal, np.zeros(part.stop - part.start, dtype=int), a_u[part], t_u[part], half, probe
        )
        counts[part] = (eq.pin_force > 0).sum(axis=2)
        if system.nl_bearings.size:
            d = np.einsum("bpxn,bn->bpx", system.brg_rows[a_u[part]], eq.q[:, system.N])
            norm = np.linalg.norm(d, axis=-1, keepdims=True)
            toward[part] = np.where(norm > 0.0, d / np.maximum(norm, 1e-300), 0.0)
    inverse = inverse.ravel()
    return counts[inverse], (toward[inverse] if system.nl_bearings.size else None)
