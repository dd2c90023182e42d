"""The equivalent error model: every contact of the reducer as a spring on small displacements.

The question: given the pose that the input angle sets and the manufacturing
errors, how far does every part move, and so how far does the carrier lag or
lead?  Errors are micrometres and deflections are micrometres, while the parts
are centimetres, so the directions and lever arms of every contact are those
of the exact, error-free pose (seed 003's equivalent error model R Y = P over
seed 002's degrees of freedom).  Each error enters as an equivalent
displacement along its contact normal; the model is linear in the unknowns but
for the unilateral pin contacts and the bearing clearances.

Degrees of freedom (small displacements from the nominal pose, fixed frame):
sun x, y; per crank x, y and rotation; per disc x, y and rotation; carrier x,
y and rotation.  The input angle is held (the sun does not rotate).  Every
rotation is stored as arc length at the pin circle radius R_p [m] so that all
unknowns have one unit and one size.

Nothing here is solved: `EquivalentModel` gives, for a set of input angles,
the Jacobian of every element (shared by all reducers of a batch) and, for
any (reducer, angle) pairs, the offsets that the errors put on each element.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..base.checks import fits_in_memory
from ..base.compiled import COMPILED, kernel
from ..reducer.design import RVDesign
from ..reducer.errors import CLEARANCES, ErrorSet

# Peak memory of the element geometry, measured on the RV-40E-121 and RV-110E at 12 480 angles
# (tracemalloc): the rows of the meshes and bearings plus 24 floats per angle for each (disc,
# pin) contact, its rows, gaps, levers and the temporaries that build them.
FLOATS_PER_PIN_CONTACT = 24


def geometry_bytes(design: RVDesign, angles: int, sun_rotation: bool = False) -> int:
    """Peak bytes of `EquivalentModel`'s element geometry at `angles` input angles."""
    n = len(dof_names(design.n_c, sun_rotation))
    meshes, bearings = design.n_c + 2, 3 * design.n_c + 1
    per_angle = meshes * n + 2 * bearings * n + 2 * design.z_p * FLOATS_PER_PIN_CONTACT
    return 8 * int(angles) * per_angle


def check_angles(design: RVDesign, angles: int, field: str = "points", where: str = "") -> None:
    """Refuse, before any work, a count of input angles whose geometry alone would not fit in
    memory (`checks.fits_in_memory`): what every route that sizes its angles from an input
    goes through."""
    fits_in_memory(
        field,
        angles,
        geometry_bytes(design, angles),
        f"gives {int(angles)} input angles whose element geometry alone",
        where,
    )


def dof_names(n_c: int, sun_rotation: bool = False) -> list[str]:
    """Unknowns in order; with `sun_rotation` the sun's rotation too (the dynamic model's
    input shaft twists; the quasi-static model holds the sun at its input angle)."""
    names = ["sun_x", "sun_y"] + (["sun_rot"] if sun_rotation else [])
    for i in range(n_c):
        names += [f"crank{i}_x", f"crank{i}_y", f"crank{i}_rot"]
    for j in range(2):
        names += [f"disc{j}_x", f"disc{j}_y", f"disc{j}_rot"]
    return names + ["carrier_x", "carrier_y", "carrier_rot"]


def _pair(x, y):
    """Vectors (..., 2) from their components (np.stack's work, without its overhead)."""
    x, y = np.asarray(x), np.asarray(y)
    shape = x.shape if x.shape == y.shape else np.broadcast_shapes(x.shape, y.shape)
    out = np.empty(shape + (2,))
    out[..., 0], out[..., 1] = x, y
    return out


def _perp(v):
    """k x v for vectors stored as (..., 2)."""
    return _pair(-v[..., 1], v[..., 0])


def _unit(angle):
    return _pair(np.cos(angle), np.sin(angle))


def _c2v(z):
    return _pair(z.real, z.imag)


@functools.lru_cache(maxsize=8)
def _body_dofs(names: tuple) -> dict:
    """{body: [indices of its unknowns]} for a list of unknowns named body_x, body_y, ..."""
    out = {}
    for k, name in enumerate(names):
        out.setdefault(name.rsplit("_", 1)[0], []).append(k)
    return out


@dataclass(frozen=True)
class _Layout:
    """The constant entries of the element rows and where the angle-dependent ones go.

    linear (m, n), bearing (nb, 2, n): the +-1 translation entries of the sun support
    and the bearings; the *_entries are flat indices into one instant's rows, raveled
    from: mesh_entries (n_c, 5) sun x, sun y, crank x, crank y, crank rotation of mesh
    i; seat_entries (n_c, 2) the carrier rotation of crank seat i (x and y rows);
    cam_crank_entries and cam_disc_entries (n_c, 2, 2) the crank and disc rotations of
    cam bearing (i, j).
    """

    linear: np.ndarray
    bearing: np.ndarray
    sun_rot: int
    mesh_entries: np.ndarray
    seat_entries: np.ndarray
    cam_crank_entries: np.ndarray
    cam_disc_entries: np.ndarray


@functools.lru_cache(maxsize=8)
def _layout(n_c: int, sun_rotation: bool) -> _Layout:
    names = dof_names(n_c, sun_rotation)
    n, body = len(names), _body_dofs(tuple(names))
    sun, car = body["sun"], body["carrier"]
    crank = [body[f"crank{i}"] for i in range(n_c)]
    disc = [body[f"disc{j}"] for j in range(2)]
    linear = np.zeros((n_c + 2, n))
    linear[n_c, sun[0]] = linear[n_c + 1, sun[1]] = 1.0  # the sun support
    mesh = [[i * n + k for k in (sun[0], sun[1], crank[i][0], crank[i][1], crank[i][2])] for i in range(n_c)]
    nb = 3 * n_c + 1
    bearing = np.zeros((nb, 2, n))

    def joins(b, inner, outer):
        """Bearing b: deflection = inner part's translation - outer part's."""
        for xy in range(2):
            if inner is not None:
                bearing[b, xy, inner[xy]] = 1.0
            if outer is not None:
                bearing[b, xy, outer[xy]] = -1.0

    def entry(b, xy, column):
        return (b * 2 + xy) * n + column

    seat, cam_crank, cam_disc = [], [], []
    for i in range(n_c):
        joins(i, crank[i], car)
        seat.append([entry(i, xy, car[2]) for xy in range(2)])
    for i in range(n_c):
        cam_crank.append([]), cam_disc.append([])
        for j in range(2):
            b = n_c + 2 * i + j
            joins(b, crank[i], disc[j])
            cam_crank[i].append([entry(b, xy, crank[i][2]) for xy in range(2)])
            cam_disc[i].append([entry(b, xy, disc[j][2]) for xy in range(2)])
    joins(nb - 1, car, None)
    return _Layout(
        linear,
        bearing,
        sun[2] if sun_rotation else -1,
        np.ravel(mesh),
        np.ravel(seat),
        np.ravel(cam_crank),
        np.ravel(cam_disc),
    )


@dataclass(frozen=True)
class Pose:
    """Nominal kinematics (docs/model.md section 2) at input angles theta_in, shape (A,)."""

    theta_in: np.ndarray
    theta_out: np.ndarray  # carrier angle, theta_in / i
    beta: np.ndarray  # crank angle relative to the carrier
    psi: np.ndarray  # (A, 2) direction of disc j's centre from the pin circle centre

    @classmethod
    def at(cls, design: RVDesign, theta_in) -> "Pose":
        theta_in = np.atleast_1d(np.asarray(theta_in, dtype=float))
        theta_out = theta_in / design.ratio
        beta = -(design.z_s / design.z_pl) * (theta_in - theta_out)
        psi = (theta_out + beta)[:, None] + np.array([0.0, np.pi])
        return cls(theta_in, theta_out, beta, psi)


class EquivalentModel:
    """Element Jacobians at A input angles and error offsets for (reducer, angle) pairs.

    Elements, each with its stiffness:
    - `linear`: sun-planet meshes (one per crank, along the line of action of the
      loaded flank) and the sun support (x, y): bilateral springs, rows (A, m, n);
    - `bearings`: per crank its support in the carrier, per crank and disc the
      cam needle bearing, and the carrier main bearing: isotropic 2-D springs with
      a radial clearance, rows (A, nb, 2, n);
    - `pins`: pin k against disc j, unilateral along the contact normal, rows
      (A, 2, z_p, 3) over that disc's own three unknowns.
    A positive element deflection is compression (interference).
    `flank` is +1 when the sun drives the planets forward (a resisting load, or
    the no-load limit approached from one), -1 when the load drives the output
    (or the no-load limit is approached from that side).
    """

    # the pins' offsets by the compiled `pin_offsets` (False: by numpy, `_pin_offsets_numpy`)
    compiled_pins = COMPILED

    def __init__(self, design: RVDesign, theta_in, flank: int = 1, sun_rotation: bool = False):
        self.design = design
        check_angles(design, np.size(theta_in))
        self.pose = Pose.at(design, theta_in)
        self.flank = 1 if flank >= 0 else -1
        self.sun_rotation = sun_rotation
        self.names = dof_names(design.n_c, sun_rotation)
        self.n_dof = len(self.names)
        self.index = {name: k for k, name in enumerate(self.names)}
        self._bodies = _body_dofs(tuple(self.names))
        self.scale = design.R_p  # rotation unknowns are arc lengths at R_p
        self._build_geometry()

    # -- indices -------------------------------------------------------------------
    def _dofs(self, body: str) -> list[int]:
        return self._bodies[body]

    @property
    def carrier_rot(self) -> int:
        return self.index["carrier_rot"]

    @property
    def pin_dofs(self) -> np.ndarray:
        """(2, 3) unknowns of disc j: x, y, rotation."""
        return np.array([self._dofs("disc0"), self._dofs("disc1")])

    # -- geometry ------------------------------------------------------------------
    def _build_geometry(self):
        d, p = self.design, self.pose
        A, n_c = p.theta_in.size, d.n_c
        a = d.crank_circle_radius
        r_s, r_pl = d.m * d.z_s / 2.0, d.m * d.z_pl / 2.0
        crank_dir = p.theta_out[:, None] + 2.0 * np.pi * np.arange(n_c) / n_c  # (A, n_c)
        e_i, t_i = _unit(crank_dir), _perp(_unit(crank_dir))  # (A, n_c, 2)

        lay = _layout(n_c, self.sun_rotation)
        # Sun-planet meshes: compression = w . (u_sun(C) - u_planet(C)) at the pitch point C.
        alpha = d.pressure_angle
        w = self.flank * np.cos(alpha) * t_i + np.sin(alpha) * e_i  # (A, n_c, 2)
        # planet point C - O_p = -r_pl e_i turns with the crank: u = rot * k x (C - O_p)
        planet_rot = -(w * _perp(-r_pl * e_i)).sum(axis=-1) / self.scale  # (A, n_c)
        linear = np.broadcast_to(lay.linear, (A,) + lay.linear.shape).copy()  # (A, m, n)
        mesh_values = np.concatenate([w, -w, planet_rot[..., None]], axis=-1)  # (A, n_c, 5)
        linear.reshape(A, -1)[:, lay.mesh_entries] = mesh_values.reshape(A, -1)
        if self.sun_rotation:
            # sun point C - O_s = r_s e_i turns with the sun: u = rot * r_s t_i, w . t_i = flank cos
            linear[:, :n_c, lay.sun_rot] = self.flank * np.cos(alpha) * r_s / self.scale
        self.linear_rows = linear
        self.linear_k = np.array([d.mesh_stiffness] * n_c + [d.sun_support_stiffness] * 2)
        self._mesh_w = w

        # Bearings: deflection d = (inner part) - (outer part), 2-D; in order, crank i in its
        # carrier seat, cam j of crank i in hole i of disc j, the carrier main bearing.
        # A point at a e_i of a part turning about the reducer axis / a cam at e psi_j turning
        # with its crank moves by rotation * k x (point): the rows of those rotations.
        crank_seat = _perp(a * e_i) / self.scale  # (A, n_c, 2)
        psi_dir = _unit(p.psi)  # (A, 2, 2)
        cam_lever = _perp(d.e * psi_dir) / self.scale  # (A, 2, 2)
        rows = np.broadcast_to(lay.bearing, (A,) + lay.bearing.shape).copy()  # (A, nb, 2, n)
        flat = rows.reshape(A, -1)
        flat[:, lay.seat_entries] = -crank_seat.reshape(A, -1)
        flat[:, lay.cam_crank_entries] = np.broadcast_to(cam_lever[:, None], (A, n_c, 2, 2)).reshape(A, -1)
        flat[:, lay.cam_disc_entries] = np.broadcast_to(-crank_seat[:, :, None], (A, n_c, 2, 2)).reshape(
            A, -1
        )
        self.bearing_rows = rows
        self.bearing_k = np.array(
            [d.crank_carrier_bearing_stiffness] * n_c
            + [d.crank_disc_bearing_stiffness] * (2 * n_c)
            + [d.main_bearing_stiffness]
        )
        self.bearing_kind = (
            ["crank_carrier_clearance"] * n_c
            + ["crank_disc_clearance"] * (2 * n_c)
            + ["main_bearing_clearance"]
        )
        # The bearings that follow the roller law (`roller_law`): its constant a (0: the linear
        # spring bearing_k) and the compliance of the spring in series with it [m/N].
        laws = d.roller_laws
        per_bearing = (
            [laws.get("crank_carrier", (0.0, 0.0))] * n_c
            + [laws.get("crank_disc", (0.0, 0.0))] * (2 * n_c)
            + [(0.0, 0.0)]
        )
        self.bearing_law_a = np.array([law[0] for law in per_bearing])
        self.bearing_law_compliance = np.array([law[1] for law in per_bearing])

        # Pins: normal through the pitch point z_p e (cos psi, sin psi) (instant centre).
        pin_angle = 2.0 * np.pi * np.arange(d.z_p) / d.z_p
        pin_pos = d.R_p * _unit(pin_angle)  # (z_p, 2)
        pitch = d.z_p * d.e * psi_dir  # (A, 2, 2)
        centre = d.e * psi_dir
        normal = pin_pos[None, None] - pitch[:, :, None]  # (A, 2, z_p, 2)
        reach = np.hypot(normal[..., 0], normal[..., 1])  # (A, 2, z_p)
        normal /= reach[..., None]
        # The disc turns about the pitch point relative to the housing, so its contact point
        # slides past the (groove-held) pin at |theta_out'| times its distance from there.
        self.pin_slide_arm = reach - d.r_rp
        contact = pin_pos[None, None] - d.r_rp * normal
        arm = contact - centre[:, :, None]
        lever = arm[..., 0] * normal[..., 1] - arm[..., 1] * normal[..., 0]  # (A, 2, z_p)
        # a turn of the disc about its centre slides its contact point along the tangent by
        # the turn times n . (Q - C) (the hysteresis loop's pin slips)
        self.pin_tangent_lever = (arm * normal).sum(axis=-1)  # (A, 2, z_p)
        self.pin_rows = np.concatenate([normal, (lever / self.scale)[..., None]], axis=-1)
        self.pin_k = d.pin_disc_stiffness
        self.pin_law = np.array(d.pin_law, dtype=float)  # (k, b, F*): `pin_law.contact`
        radial = _unit(pin_angle)
        radial_dot = normal[..., 0] * radial[:, 0] + normal[..., 1] * radial[:, 1]  # n . e_k
        tangent_dot = normal[..., 1] * radial[:, 0] - normal[..., 0] * radial[:, 1]  # n . t_k
        # Lobe of each contact point, in the disc frame (disc 1 is disc 0 turned by pi).
        disc_angle = np.arctan2(arm[..., 1], arm[..., 0]) - p.theta_out[:, None, None]
        disc_angle -= np.array([0.0, np.pi])[None, :, None]
        self._lobe = np.floor(np.mod(disc_angle, 2.0 * np.pi) * d.z_c / (2.0 * np.pi)).astype(int)
        self._lobe = np.minimum(self._lobe, d.z_c - 1)
        # Profile modifications as gaps (docs/model.md section 3): d_rrp opens every normal, d_rp
        # moves the generating pin circle out, closing the gap by d_rp (n . e_k).
        gap = d.d_rrp - d.d_rp * radial_dot  # (A, 2, z_p)
        # Everything the error offsets need per angle, gathered in one take.
        self._pin_geometry = np.empty((A, 4, 2, d.z_p))
        for k, part in enumerate((gap, radial_dot, tangent_dot, lever)):
            self._pin_geometry[:, k] = part
        self._lobe_flat = self._lobe + d.z_c * np.arange(2)[None, :, None]

    def output_angle(self, q: np.ndarray, tau_load) -> np.ndarray:
        """The output flange's angle from its nominal place [rad] at the equilibria q (..., n)
        under tau_load (broadcast to q's leading shape): the carrier's crank seats' rotation
        plus the windup of the series compliance (the carrier's pillars, the output's)."""
        return q[..., self.carrier_rot] / self.scale + self.design.series_compliance * tau_load

    # -- loads -----------------------------------------------------------------------
    def load_vector(self) -> np.ndarray:
        """Generalised force (n,) of a unit output torque tau_load = 1 N*m."""
        g = np.zeros(self.n_dof)
        g[self.carrier_rot] = 1.0 / self.scale
        return g

    def clearance_halves(self, errors: ErrorSet) -> np.ndarray:
        """(S, nb) free radial play of each bearing [m]: half the radial clearance.

        A bearing's radial clearance is the total radial travel of one ring against
        the other (ISO 5753), so the centre moves freely within half of it.
        """
        by_kind = {name: getattr(errors, name) for name in CLEARANCES}
        return 0.5 * np.stack([by_kind[kind] for kind in self.bearing_kind], axis=1)

    # -- error offsets ---------------------------------------------------------------
    def offsets(self, errors: ErrorSet, sample, angle):
        """Offsets of every element for the pairs (errors[sample[b]], angle[b]), b < B
        (angle may be a slice of the model's angles, e.g. all of them: slice(None)).

        Returns (linear (B, m), bearings (B, nb, 2), pins (B, 2, z_p)) [m]:
        the deflection of each element with all unknowns zero.
        """
        d, p = self.design, self.pose
        th_in = p.theta_in[angle]
        th_out = p.theta_out[angle]
        crank_abs = th_out + p.beta[angle]  # crank frame: cam 0 direction
        rot_in = np.exp(1j * th_in)[:, None]
        rot_out = np.exp(1j * th_out)[:, None]
        rot_crank = np.exp(1j * crank_abs)[:, None]
        n_c = d.n_c

        # Meshes: the sun pitch centre is off by its eccentricity (turning with the sun),
        # the planet pitch centre by its eccentricity (turning with the crank).
        sun_ecc = errors.sun_eccentricity[sample][:, None] * rot_in  # (B, 1)
        planet_ecc = errors.planet_eccentricity[sample] * rot_crank  # (B, n_c)
        w = self._mesh_w[angle]  # (B, n_c, 2)
        mesh = np.einsum("bix,bix->bi", w, _c2v(sun_ecc - planet_ecc))
        assembly = _c2v(errors.sun_assembly[sample])  # (B, 2)
        linear = np.concatenate([mesh, -assembly], axis=1)

        # Bearings, in the order of _build_geometry.
        seat = errors.carrier_crank_hole[sample] * rot_out  # (B, n_c)
        cam = errors.crank_cam_eccentricity[sample] * rot_crank[..., None]  # (B, n_c, 2)
        hole = np.swapaxes(errors.disc_crank_hole[sample], 1, 2) * rot_out[..., None]  # (B, n_c, 2)
        bearings = _c2v(
            np.concatenate(
                [
                    -seat,
                    (cam - hole).reshape(len(sample), 2 * n_c),
                    -errors.carrier_assembly[sample][:, None],
                ],
                axis=1,
            )
        )

        if self.compiled_pins:
            pins = np.empty((len(sample), 2, d.z_p))
            contiguous = np.ascontiguousarray
            pin_offsets(
                self._pin_geometry,
                self._lobe_flat,
                np.arange(self._lobe_flat.shape[0])[angle],
                np.asarray(sample, dtype=np.int64),
                contiguous(errors.pin_radius, dtype=float),
                contiguous(errors.pin_radial, dtype=float),
                contiguous(errors.pin_pitch, dtype=float),
                contiguous(errors.disc_profile, dtype=float).ravel(),
                contiguous(errors.disc_pitch, dtype=float).ravel(),
                2 * d.z_c,
                d.R_p * d.z_c / d.z_p,
                pins,
            )
        else:
            pins = self._pin_offsets_numpy(errors, sample, angle)
        return linear, bearings, pins

    def _pin_offsets_numpy(self, errors: ErrorSet, sample, angle) -> np.ndarray:
        """The pins' offsets (B, 2, z_p) [m] of `offsets` as numpy arrays: the reference that
        `pin_offsets` is held to (to the bit, tests/test_equivalent.py) and the route
        without numba."""
        d = self.design
        # Pins: pin centre moved by its radial/pitch error, radius error, disc lobe
        # profile (+ material) and pitch (lobe turned about the disc centre).
        gap, nr, nt, lever = np.moveaxis(self._pin_geometry[angle], 1, 0)  # each (B, 2, z_p)
        pins = (
            errors.pin_radius[sample][:, None]
            - gap
            - errors.pin_radial[sample][:, None] * nr
            - errors.pin_pitch[sample][:, None] * nt
        )
        # Flat index of (sample, disc, lobe) into the (S, 2, z_c) lobe arrays.
        flat = self._lobe_flat[angle] + (2 * d.z_c) * np.asarray(sample)[:, None, None]
        pins += np.take(errors.disc_profile, flat)
        pins += np.take(errors.disc_pitch, flat) * (lever / (d.R_p * d.z_c / d.z_p))
        return pins


@kernel
def pin_offsets(
    geometry, lobe_flat, angle, sample, radius, radial, pitch_error, profile, pitch, lobes, pitch_arm, out
):
    """The pins' offsets of `EquivalentModel.offsets` for the pairs (sample[b], angle[b]) into
    out (B, 2, z_p) [m], one pair at a time, without the (B, 4, 2, z_p) gather of the numpy
    route (`_pin_offsets_numpy`), whose arithmetic it repeats operation for operation (the
    same values to the bit).  geometry (A, 4, 2, z_p): per angle the profile's gap, n . e_k,
    n . t_k and the lever of each contact; lobe_flat (A, 2, z_p): the lobe each pin meets as
    a flat index into one reducer's (2, z_c) lobe arrays, of `lobes` = 2 z_c entries;
    radius, radial, pitch_error (S, z_p): the pins' errors; profile, pitch (S * 2 z_c): the
    discs' lobe errors, flat; pitch_arm: R_p z_c / z_p [m], the lever of a lobe's pitch
    error at unit angle."""
    for b in range(angle.size):
        a, s = angle[b], sample[b]
        for disc in range(2):
            for k in range(out.shape[2]):
                value = radius[s, k] - geometry[a, 0, disc, k]
                value = value - radial[s, k] * geometry[a, 1, disc, k]
                value = value - pitch_error[s, k] * geometry[a, 2, disc, k]
                lobe = lobe_flat[a, disc, k] + lobes * s
                value = value + profile[lobe]
                out[b, disc, k] = value + pitch[lobe] * (geometry[a, 3, disc, k] / pitch_arm)


def touched_columns(rows: np.ndarray) -> np.ndarray:
    """(E, w) the unknowns that element rows (A, E, ..., n) touch, at any of the A instants:
    each element joins two bodies, so a handful of the n.  Shorter lists are padded with
    -1 (`gather` gives those a zero coefficient); no elements (E = 0) give (0, 1)."""
    touched = np.any(rows != 0.0, axis=tuple(k for k in range(rows.ndim - 1) if k != 1))  # (E, n)
    cols = np.full((touched.shape[0], max(1, int(touched.sum(axis=1).max(initial=0)))), -1, dtype=np.int64)
    for e, row in enumerate(touched):
        found = np.flatnonzero(row)
        cols[e, : found.size] = found
    return cols
