"""The dynamic model's element geometry at a run of time steps, compiled when numba is there.

`DynamicModel._chunk` builds, for the steps of a chunk, every element's rows,
offsets and stiffness, the external forces and the nominal slips, from
`EquivalentModel` (the one implementation of the geometry, in numpy).  A long
run builds 512 steps at a time and the numpy is cheap per step; the FMU builds
the ten or so steps of one communication step at a time, and then a hundred
small numpy operations cost a fixed 0.6 ms a step, more than the Newmark steps
themselves.  `fill_geometry` computes the same quantities step by step in one
compiled loop, from the constants `geometry_constants` gathers once per model:
the same formulas in the same order (docs/model.md sections 2, 3, 7 and 9), so
that the two agree to round-off.  Without numba the model keeps the numpy
route, which also stays the reference the tests hold this one to.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from ..base.compiled import kernel
from ..laws.stiffness import transverse_contact_ratio
from ..losses.friction import DRAG_FLOOR, RPM, drag_moments
from ..statics.equivalent import _layout, _unit
from .kernels import Geometry

DOUBLE_PAIR = 1.75  # double-pair / single-pair mesh stiffness: ISO 6336-1's c_gamma = c'(0.75 eps + 0.25)

DRAG_NONE, DRAG_BEARING, DRAG_CONSTANT, DRAG_CHURNING = 0, 1, 2, 3
# a pin's disc lobe is kept from the step before while its contact point lies inside that
# lobe by more than this share of its distance from the disc centre (`_same_lobe`): some
# 1e-9 rad, where the angle atan2 gives carries a few 1e-16 rad of round-off
LOBE_MARGIN = 1e-9

GeometryConstants = namedtuple(
    "GeometryConstants",
    [
        "ratio",
        "k_beta",  # i; -z_s / z_pl: the cranks' turn per relative input turn
        "flank",
        "cos_alpha",
        "sin_alpha",
        "crank_radius",
        "r_s",
        "r_pl",
        "scale",
        "e",
        "n_c",
        "linear_template",  # (m, n) the constant entries of the mesh and support rows
        "bearing_template",  # (nb, 2, n) of the bearing rows
        "mesh_entries",
        "seat_entries",
        "cam_crank_entries",
        "cam_disc_entries",  # flat indices
        "sun_rot",
        "carrier_rot",
        "linear_cols",
        "bearing_cols",  # (m, w), (nb, w): -1 none
        "linear_k",  # (m,) [N/m]
        "varying",
        "double_pair",
        "single_pair",
        "two_pairs",  # the mesh stiffness's cycle
        "z_s",
        "pin_pos",
        "pin_radial",  # (z_p, 2) pin centres [m], their radial units
        "pitch_reach",  # z_p e: the pitch point's distance from the pin circle centre
        "r_rp",
        "d_rrp",
        "d_rp",
        "pitch_arm",
        "z_c",
        "lobe_edges",  # (z_c + 1, 2): the unit vectors of the disc's lobe edges, at
        # angles 2 pi l / z_c in the disc's frame (l = z_c: l = 0's)
        # one reducer's errors: complex ones as (..., 2) real and imaginary parts
        "sun_eccentricity",
        "planet_eccentricity",
        "sun_assembly",
        "carrier_crank_hole",
        "crank_cam_eccentricity",
        "disc_crank_hole",
        "carrier_assembly",
        "pin_radius",
        "pin_radial_error",
        "pin_pitch",
        "disc_profile",
        "disc_pitch",
        # the nominal motion
        "crank_x",
        "crank_y",
        "crank_rot",
        "disc_x",
        "disc_y",
        "disc_rot",  # (n_c,), (2,) indices
        "sun_inertia",
        "carrier_inertia",
        "crank_mass",
        "crank_inertia",
        "disc_mass",
        "disc_inertia",
        # friction
        "pin_dofs",
        "turn_cols",
        "turn_rows",
        "drag_kind",
        "drag_coefficient",
        "drag_radius",  # (E,): DRAG_*; [N*m] (bearing), [N]
        # (constant), [N*m/rpm^2] (churning); [m]
        "viscosity",  # [mm^2/s] at the model's temperature
    ],
)


def _parts(z) -> np.ndarray:
    z = np.asarray(z)
    return np.ascontiguousarray(np.stack([z.real, z.imag], axis=-1), dtype=float)


def geometry_constants(model) -> GeometryConstants:
    """The constants `fill_geometry` needs, from a `DynamicModel` (one reducer)."""
    d, err, idx = model.design, model.errors, model.index
    lay = _layout(d.n_c, True)
    eps = transverse_contact_ratio(d.z_s, d.z_pl, d.m, d.pressure_angle)
    pin_angle = 2.0 * np.pi * np.arange(d.z_p) / d.z_p
    x, y, rot = model._nominal_index
    kinds, radius = model._drag_kind, np.asarray(model._drag_radius, dtype=float)
    drag_kind = np.zeros(len(kinds), dtype=np.int64)
    coefficient = np.zeros(len(kinds))
    if model.friction:
        # Palmgren's moment on his floor: coefficient x floor
        at_floor = drag_moments(d, 0.0, model.temperature_C)
        for e, kind in enumerate(kinds):
            if kind is None or not radius[e] > 0.0:
                continue
            if kind in model.seal_torques:  # a seal: its torque over its radius
                drag_kind[e], coefficient[e] = DRAG_CONSTANT, model.seal_torques[kind] / radius[e]
            elif kind == "churning":
                drag_kind[e], coefficient[e] = DRAG_CHURNING, model._churning[e]
            else:
                drag_kind[e], coefficient[e] = DRAG_BEARING, float(at_floor[kind]) / DRAG_FLOOR
    single = 1.0 / (0.75 * eps + 0.25)
    el = model.elements
    ints = lambda v: np.ascontiguousarray(v, dtype=np.int64)  # noqa: E731
    floats = lambda v: np.ascontiguousarray(v, dtype=float)  # noqa: E731
    return GeometryConstants(
        float(d.ratio),
        float(-d.z_s / d.z_pl),
        float(model.flank),
        math.cos(d.pressure_angle),
        math.sin(d.pressure_angle),
        float(d.crank_circle_radius),
        d.m * d.z_s / 2.0,
        d.m * d.z_pl / 2.0,
        float(model.scale),
        float(d.e),
        int(d.n_c),
        floats(lay.linear),
        floats(lay.bearing),
        ints(lay.mesh_entries),
        ints(lay.seat_entries),
        ints(lay.cam_crank_entries),
        ints(lay.cam_disc_entries),
        int(idx["sun_rot"]),
        int(idx["carrier_rot"]),
        ints(model._linear_cols),
        ints(model._bearing_cols),
        floats([d.mesh_stiffness] * d.n_c + [d.sun_support_stiffness] * 2),
        model.mesh == "varying",
        0.0,
        0.0,
        float(eps - 1.0),
        int(d.z_s),
        floats(d.R_p * _unit(pin_angle)),
        floats(_unit(pin_angle)),
        float(d.z_p * d.e),
        float(d.r_rp),
        float(d.d_rrp),
        float(d.d_rp),
        float(d.R_p * d.z_c / d.z_p),
        int(d.z_c),
        floats(_unit(2.0 * np.pi * np.r_[np.arange(d.z_c), 0] / d.z_c)),
        _parts(err.sun_eccentricity[0]),
        _parts(err.planet_eccentricity[0]),
        _parts(err.sun_assembly[0]),
        _parts(err.carrier_crank_hole[0]),
        _parts(err.crank_cam_eccentricity[0]),
        _parts(err.disc_crank_hole[0]),
        _parts(err.carrier_assembly[0]),
        floats(err.pin_radius[0]),
        floats(err.pin_radial[0]),
        floats(err.pin_pitch[0]),
        floats(err.disc_profile[0]),
        floats(err.disc_pitch[0]),
        ints(x["crank"]),
        ints(y["crank"]),
        ints(rot["crank"]),
        ints(x["disc"]),
        ints(y["disc"]),
        ints(rot["disc"]),
        float(d.sun_inertia),
        float(d.carrier_inertia),
        float(d.crank_mass),
        float(d.crank_inertia),
        float(d.disc_mass),
        float(d.disc_inertia),
        ints(el.pin_dofs),
        ints(el.turn_cols),
        floats(el.turn_rows),
        drag_kind,
        coefficient,
        floats(radius),
        float(model.viscosity),
    )._replace(double_pair=DOUBLE_PAIR * single, single_pair=single)


@kernel
def _circling(nominal, force, x, y, rot, angle, radius, mass, inertia, w, acc, w_turn, a_turn, scale):
    """A body whose centre rides a circle of `radius` at `angle`, speed w and acceleration
    acc [rad/s, rad/s^2], turning at w_turn, a_turn: its nominal velocities into nominal[x],
    [y], [rot] and its d'Alembert forces (minus mass times the acceleration, radius (acc t -
    w^2 r)) into force[...]."""
    co, si = math.cos(angle), math.sin(angle)
    speed = radius * w
    nominal[x], nominal[y] = -speed * si, speed * co
    nominal[rot] = w_turn * scale
    w2, tangential = mass * radius * w**2, mass * radius * acc
    force[x], force[y] = tangential * si + w2 * co, w2 * si - tangential * co
    force[rot] = -inertia * a_turn / scale


@kernel
def _same_lobe(x, y, edges, lobe, z_c):
    """The lobe of the disc, `lobe` or a neighbour of it, in which the point (x, y) [m] of the
    disc's frame lies by more than LOBE_MARGIN of its distance from the centre, or -1 (none
    such, or lobe -1).  Inside lobe l, between the edges' unit vectors e_l and e_l+1 (lobes
    narrower than pi), both cross products e_l x p and p x e_l+1 are positive: where both
    exceed the margin, p's angle lies that far inside, and atan2's lobe is that one."""
    if lobe < 0:
        return -1
    margin = LOBE_MARGIN * (abs(x) + abs(y))
    for shift in (0, 1, -1):
        m = lobe + shift  # (lobe + shift) % z_c, without an integer division for every pin
        if m == z_c:
            m = 0
        elif m < 0:
            m = z_c - 1
        if edges[m, 0] * y - edges[m, 1] * x > margin and x * edges[m + 1, 1] - y * edges[m + 1, 0] > margin:
            return m
    return -1


@kernel
def fill_geometry(
    c,
    theta,
    omega,
    alpha,
    tau_load,
    L,
    k_lin,
    lin,
    B,
    brg,
    P,
    pins,
    external,
    tangent,
    pin_slip,
    turn_slip,
    turn_drag,
):
    """The element geometry of the steps at input angles theta (A,) [rad], speeds omega,
    accelerations alpha, under tau_load (A,) [N*m], into the arrays of `Geometry` (axis 0 the
    step; each overwritten): what `DynamicModel._chunk` builds in numpy."""
    two_pi = 2.0 * np.pi
    n_c, z_p = c.n_c, c.pin_pos.shape[0]
    rows_lin = np.empty(c.linear_template.shape)
    rows_brg = np.empty(c.bearing_template.shape)
    flat_lin = rows_lin.reshape(-1)
    flat_brg = rows_brg.reshape(-1)
    n = c.linear_template.shape[1]
    mesh_w = np.empty((n_c, 2))
    seat = np.empty((n_c, 2))
    nominal = np.empty(n)
    force = np.empty(n)
    lobes = np.full((2, z_p), -1, dtype=np.int64)  # each pin's lobe at the step before
    for t in range(theta.shape[0]):
        th_in = theta[t]
        th_out = th_in / c.ratio
        psi = th_out + c.k_beta * (th_in - th_out)  # crank angle: cam 0's direction
        # meshes: the line of action w of each, the planet's turn, the sun's turn
        rows_lin[:, :] = c.linear_template
        for i in range(n_c):
            angle = th_out + two_pi * i / n_c
            ex, ey = math.cos(angle), math.sin(angle)
            wx = c.flank * c.cos_alpha * -ey + c.sin_alpha * ex
            wy = c.flank * c.cos_alpha * ex + c.sin_alpha * ey
            mesh_w[i, 0], mesh_w[i, 1] = wx, wy
            planet = -(wx * (c.r_pl * ey) + wy * (-c.r_pl * ex)) / c.scale
            values = (wx, wy, -wx, -wy, planet)
            for k in range(5):
                flat_lin[c.mesh_entries[5 * i + k]] = values[k]
            seat[i, 0], seat[i, 1] = -(c.crank_radius * ey) / c.scale, c.crank_radius * ex / c.scale
        for i in range(n_c):
            rows_lin[i, c.sun_rot] = c.flank * c.cos_alpha * c.r_s / c.scale
        # bearings: the crank seats' and cams' turns
        rows_brg[:, :, :] = c.bearing_template
        for i in range(n_c):
            for xy in range(2):
                flat_brg[c.seat_entries[2 * i + xy]] = -seat[i, xy]
            for j in range(2):
                cx, cy = math.cos(psi + np.pi * j), math.sin(psi + np.pi * j)
                lever = (-(c.e * cy) / c.scale, c.e * cx / c.scale)
                for xy in range(2):
                    flat_brg[c.cam_crank_entries[(2 * i + j) * 2 + xy]] = lever[xy]
                    flat_brg[c.cam_disc_entries[(2 * i + j) * 2 + xy]] = -seat[i, xy]
        for e in range(c.linear_cols.shape[0]):
            for x in range(c.linear_cols.shape[1]):
                col = c.linear_cols[e, x]
                L[t, e, x] = rows_lin[e, col] if col >= 0 else 0.0
        for b in range(c.bearing_cols.shape[0]):
            for xy in range(2):
                for x in range(c.bearing_cols.shape[1]):
                    col = c.bearing_cols[b, x]
                    B[t, b, xy, x] = rows_brg[b, xy, col] if col >= 0 else 0.0
        # mesh stiffness over the cycle
        teeth = c.z_s * (th_in - th_out) / two_pi
        for e in range(c.linear_k.shape[0]):
            factor = 1.0
            if e < n_c and c.varying:
                phase = (teeth + c.z_s * e / n_c) % 1.0
                factor = c.double_pair if phase < c.two_pairs else c.single_pair
            k_lin[t, e] = c.linear_k[e] * factor
        # offsets: the errors turned with their parts
        cin, sin_ = math.cos(th_in), math.sin(th_in)
        cout, sout = math.cos(th_out), math.sin(th_out)
        ccr, scr = math.cos(psi), math.sin(psi)
        sun_re = c.sun_eccentricity[0] * cin - c.sun_eccentricity[1] * sin_
        sun_im = c.sun_eccentricity[0] * sin_ + c.sun_eccentricity[1] * cin
        for i in range(n_c):
            pe = c.planet_eccentricity[i]
            re = sun_re - (pe[0] * ccr - pe[1] * scr)
            im = sun_im - (pe[0] * scr + pe[1] * ccr)
            lin[t, i] = mesh_w[i, 0] * re + mesh_w[i, 1] * im
        lin[t, n_c], lin[t, n_c + 1] = -c.sun_assembly[0], -c.sun_assembly[1]
        for i in range(n_c):
            h = c.carrier_crank_hole[i]
            brg[t, i, 0] = -(h[0] * cout - h[1] * sout)
            brg[t, i, 1] = -(h[0] * sout + h[1] * cout)
            for j in range(2):
                cam, hole = c.crank_cam_eccentricity[i, j], c.disc_crank_hole[j, i]
                b = n_c + 2 * i + j
                brg[t, b, 0] = (cam[0] * ccr - cam[1] * scr) - (hole[0] * cout - hole[1] * sout)
                brg[t, b, 1] = (cam[0] * scr + cam[1] * ccr) - (hole[0] * sout + hole[1] * cout)
        last = c.bearing_template.shape[0] - 1
        brg[t, last, 0], brg[t, last, 1] = -c.carrier_assembly[0], -c.carrier_assembly[1]
        # the nominal motion: speeds, accelerations, the centres' circles
        w_in, a_in = omega[t], alpha[t]
        w_out, a_out = w_in / c.ratio, a_in / c.ratio
        w_psi = w_out + c.k_beta * (w_in - w_out)
        a_psi = a_out + c.k_beta * (a_in - a_out)
        nominal[:] = 0.0
        force[:] = 0.0
        nominal[c.sun_rot] = w_in * c.scale
        nominal[c.carrier_rot] = w_out * c.scale
        force[c.sun_rot] = -c.sun_inertia * a_in / c.scale
        force[c.carrier_rot] = -c.carrier_inertia * a_out / c.scale
        for i in range(n_c):
            _circling(
                nominal,
                force,
                c.crank_x[i],
                c.crank_y[i],
                c.crank_rot[i],
                th_out + two_pi * i / n_c,
                c.crank_radius,
                c.crank_mass,
                c.crank_inertia,
                w_out,
                a_out,
                w_psi,
                a_psi,
                c.scale,
            )
        for j in range(2):
            _circling(
                nominal,
                force,
                c.disc_x[j],
                c.disc_y[j],
                c.disc_rot[j],
                psi + np.pi * j,
                c.e,
                c.disc_mass,
                c.disc_inertia,
                w_psi,
                a_psi,
                w_out,
                a_out,
                c.scale,
            )
        for x in range(n):
            external[t, x] = force[x]
        external[t, c.carrier_rot] = tau_load[t] * (1.0 / c.scale) + force[c.carrier_rot]
        # pins: normal through the pitch point, lever, lobe, gap, offset, slip
        for j in range(2):
            dx, dy = math.cos(psi + np.pi * j), math.sin(psi + np.pi * j)
            px, py = c.pitch_reach * dx, c.pitch_reach * dy
            cx, cy = c.e * dx, c.e * dy
            # the disc's frame is turned by th_out + pi j: its lobe where atan2 is not needed
            cos_disc, sin_disc = math.cos(th_out), math.sin(th_out)
            if j == 1:
                cos_disc, sin_disc = -cos_disc, -sin_disc
            for k in range(z_p):
                nx, ny = c.pin_pos[k, 0] - px, c.pin_pos[k, 1] - py
                # its unit vector: 1 / sqrt(x^2 + y^2) once (hypot and two divisions took a fifth of
                # the geometry; within 1 ulp of them)
                inverse = 1.0 / math.sqrt(nx * nx + ny * ny)
                nx, ny = nx * inverse, ny * inverse
                ax = (c.pin_pos[k, 0] - c.r_rp * nx) - cx
                ay = (c.pin_pos[k, 1] - c.r_rp * ny) - cy
                lever = ax * ny - ay * nx
                P[t, j, k, 0], P[t, j, k, 1], P[t, j, k, 2] = nx, ny, lever / c.scale
                tangent[t, j, k, 0], tangent[t, j, k, 1] = -ny, nx
                tangent[t, j, k, 2] = (ax * nx + ay * ny) / c.scale
                rx, ry = c.pin_radial[k, 0], c.pin_radial[k, 1]
                radial_dot = nx * rx + ny * ry
                tangent_dot = ny * rx - nx * ry
                lobe = _same_lobe(
                    ax * cos_disc + ay * sin_disc,
                    ay * cos_disc - ax * sin_disc,
                    c.lobe_edges,
                    lobes[j, k],
                    c.z_c,
                )
                if lobe < 0:  # the first step, or a lobe edge near: atan2's own
                    disc_angle = (math.atan2(ay, ax) - th_out) - np.pi * j
                    lobe = min(int(math.floor((disc_angle % two_pi) * c.z_c / two_pi)), c.z_c - 1)
                lobes[j, k] = lobe
                gap = c.d_rrp - c.d_rp * radial_dot
                pins[t, j, k] = (
                    (
                        c.pin_radius[k]
                        - gap
                        - c.pin_radial_error[k] * radial_dot
                        - c.pin_pitch[k] * tangent_dot
                    )
                    + c.disc_profile[j, lobe]
                    + c.disc_pitch[j, lobe] * (lever / c.pitch_arm)
                )
                slip = 0.0
                for x in range(3):
                    slip += tangent[t, j, k, x] * nominal[c.pin_dofs[j, x]]
                pin_slip[t, j, k] = slip
        # turning contacts: nominal slip, load-free drag (Palmgren's moment, a seal's torque
        # or a part's churning over the arm; `DynamicModel._drag`, in the same order)
        for e in range(c.turn_cols.shape[0]):
            slip = 0.0
            for x in range(c.turn_cols.shape[1]):
                col = c.turn_cols[e, x]
                if col >= 0:
                    slip += c.turn_rows[e, x] * nominal[col]
            turn_slip[t, e] = slip
            kind, radius = c.drag_kind[e], c.drag_radius[e]
            if kind == DRAG_BEARING:
                nu_n = c.viscosity * (abs(slip) / radius / RPM)
                turn_drag[t, e] = c.drag_coefficient[e] * max(nu_n ** (2.0 / 3.0), DRAG_FLOOR) / radius
            elif kind == DRAG_CONSTANT:
                turn_drag[t, e] = c.drag_coefficient[e]
            elif kind == DRAG_CHURNING:
                speed_rpm = abs(slip) / radius / RPM
                turn_drag[t, e] = c.drag_coefficient[e] * speed_rpm * speed_rpm / radius
            else:
                turn_drag[t, e] = 0.0


@kernel
def build_geometry(c, h, theta, omega, alpha, tau_load):
    """The `Geometry` of the steps with time steps h (A,) [s] into them, at input angles theta
    (A,) [rad], speeds omega, accelerations alpha, under tau_load (A,) [N*m]: its arrays made
    and filled (`fill_geometry`) from the model's constants c."""
    A, n = theta.shape[0], c.linear_template.shape[1]
    m, nb, z_p = c.linear_cols.shape[0], c.bearing_cols.shape[0], c.pin_pos.shape[0]
    E = c.turn_cols.shape[0]
    g = Geometry(
        h,
        np.maximum(c.linear_cols, 0),
        np.empty((A, m, c.linear_cols.shape[1])),
        np.empty((A, m)),
        np.empty((A, m)),
        np.maximum(c.bearing_cols, 0),
        np.empty((A, nb, 2, c.bearing_cols.shape[1])),
        np.empty((A, nb, 2)),
        np.empty((A, 2, z_p, 3)),
        np.empty((A, 2, z_p)),
        np.empty((A, n)),
        np.empty((A, 2, z_p, 3)),
        np.empty((A, 2, z_p)),
        np.empty((A, E)),
        np.empty((A, E)),
    )
    fill_geometry(
        c,
        theta,
        omega,
        alpha,
        tau_load,
        g.L,
        g.linear_k,
        g.linear_offset,
        g.B,
        g.bearing_offset,
        g.P,
        g.pin_offset,
        g.external,
        g.pin_tangent,
        g.pin_slip,
        g.turn_slip,
        g.turn_drag,
    )
    return g
