"""The cycloid disc profile (docs/model.md section 3): closed form, check and export.

Engineering question: what shape must be ground on a disc so that it meshes
with the pins of a design, including its shift (`d_rp`) and equidistant
(`d_rrp`) modifications, and how is that shape handed to CAD/CAM?

The profile is the inner envelope, in the disc frame, of a generating pin of
radius r_rp + d_rrp whose centre runs on a circle of radius R_p + d_rp.  The
closed form below (seed 004, parametric equations for x_c, y_c) is that pin-
centre trochoid offset inwards by the pin radius.  A closed form is easy to get
subtly wrong (a sign of the phase, a frame turned by a pitch, a modification
applied the wrong way), and every later result - contact, clearance, TE - rests
on it.  So `numerical_envelope` computes the same curve a second way that
shares no formula with it: it moves the disc through the kinematics of docs/model.md
section 2 and carves it with all the pins, pose by pose.  The tests require the
two to agree to 0.1 um.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.units import MM
from .design import RVDesign

DEFAULT_POINTS = 20000
"""Points on a whole profile, equally spaced along it: ~25 um apart on a ~0.5 m
profile, so a chord sags at most ~0.2 um from the curve at the sharpest lobe tip
of the presets (radius of curvature ~0.4 mm), below grinding tolerance."""

_FINE_POINTS = 1 << 16  # uniform-t sampling behind arc-length spacing and angle lookup


@dataclass(frozen=True, eq=False)
class Profile:
    """A closed disc profile in the disc frame, SI units.

    x, y: point coordinates [m], shape (points,); t: trochoid parameter [rad],
    shape (points,), rising from 0 to below 2*pi, spaced so that the points are
    equally spaced along the curve (the profile runs ~40 times faster in t at a
    valley than at a tip); the last point is not repeated.  Point t = 0 is the
    bottom of valley 0 on the +x axis (disc 0).
    """

    x: np.ndarray
    y: np.ndarray
    t: np.ndarray

    @property
    def radius(self) -> np.ndarray:
        """Distance of each point from the disc centre [m], shape (points,)."""
        return np.hypot(self.x, self.y)


def _closed_form(design: RVDesign, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Profile points (x, y) [m] of disc 0 at trochoid parameters t [rad] (any shape).

    Seed 004's x_c, y_c with the generating angle phi = -z_c*t: the trochoid
    C(t) = (R cos t - e cos z_p t, R sin t - e sin z_p t), R = R_p + d_rp,
    minus r = r_rp + d_rrp times its unit outward normal.  |C'| = R/S with
    S = (1 + K1^2 - 2 K1 cos z_c t)^(-1/2), K1 = e z_p / R.
    """
    R = design.R_p + design.d_rp
    r = design.r_rp + design.d_rrp
    e, z_p, z_c = design.e, design.z_p, design.z_c
    k1 = e * z_p / R
    s = 1.0 / np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * np.cos(z_c * t))
    radial = R - r * s
    swing = e / R * (R - z_p * r * s)
    x = radial * np.cos(t) - swing * np.cos(z_p * t)
    y = radial * np.sin(t) - swing * np.sin(z_p * t)
    return x, y


def disc_profile(design: RVDesign, points: int = DEFAULT_POINTS) -> Profile:
    """Profile of disc 0 in its own frame, `points` points, closed form [m].

    Valley m lies at disc angle 2*pi*m/z_c at radius R_p + d_rp - e - r_rp - d_rrp,
    tip m at angle (2m+1)*pi/z_c at radius R_p + d_rp + e - r_rp - d_rrp.
    """
    fine_t = np.linspace(0.0, 2.0 * np.pi, _FINE_POINTS + 1)
    fine_x, fine_y = _closed_form(design, fine_t)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(fine_x), np.diff(fine_y)))])
    t = np.interp(np.linspace(0.0, arc[-1], int(points), endpoint=False), arc, fine_t)
    x, y = _closed_form(design, t)
    return Profile(x=x, y=y, t=t)


def disc_profile_for(design: RVDesign, disc: int, points: int = DEFAULT_POINTS) -> Profile:
    """Profile of disc `disc` (0 or 1) in its own frame [m], shape (points,).

    Disc 1 is the same part as disc 0 turned by pi about its own centre
    (docs/model.md section 2), so its points are those of disc 0 negated.
    """
    if disc not in (0, 1):
        raise ValueError(f"disc = {disc!r}: must be 0 or 1")
    p = disc_profile(design, points)
    sign = 1.0 if disc == 0 else -1.0
    return Profile(x=sign * p.x, y=sign * p.y, t=p.t)


def numerical_envelope(
    design: RVDesign, rays: int | np.ndarray = 720, poses: int = 2000, disc: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Profile radius of disc `disc` by carving it with the moving pins [m].

    Independent of the closed form: for `poses` output angles theta_out the disc
    centre is e*(cos psi_j, sin psi_j), psi_j = theta_out + beta + j*pi (for disc
    0 that is -z_c*theta_out), its rotation theta_out (docs/model.md section 2, beta
    taken at theta_in = i*theta_out); all z_p generating pins (radius
    r_rp + d_rrp, centres at radius R_p + d_rp, angles 2*pi*k/z_p) are put into
    the disc frame, and along each ray from the disc centre the nearest entry
    into any pin circle is kept (the inner envelope).  The poses span one pin
    pitch of output rotation, 2*pi/z_p: after that the set of pins seen from the
    disc repeats, so a whole revolution would add nothing.

    rays: number of equally spaced ray angles over one turn, or the disc-frame
    ray angles themselves [rad], shape (n_rays,).
    Returns (angles [rad], radius [m]), both shape (n_rays,).  The discrete
    poses leave scallops that make the radius slightly too large, by about
    (pin-centre step)^2 / (8 * pin radius): a few nm at the default settings.
    """
    angles = (
        np.linspace(0.0, 2.0 * np.pi, rays, endpoint=False)
        if np.isscalar(rays)
        else np.asarray(rays, dtype=float).ravel()
    )
    theta_out = np.linspace(0.0, 2.0 * np.pi / design.z_p, int(poses), endpoint=False)
    i = design.ratio
    beta = -(design.z_s / design.z_pl) * (i * theta_out - theta_out)
    psi = theta_out + beta + disc * np.pi
    centre = design.e * np.exp(1j * psi)  # disc centre, fixed frame, shape (poses,)
    phi_pin = 2.0 * np.pi * np.arange(design.z_p) / design.z_p
    pins = (design.R_p + design.d_rp) * np.exp(1j * phi_pin)  # shape (z_p,)
    # Pin centres in the disc frame: translate by -centre, turn by -theta_out.
    q = ((pins[None, :] - centre[:, None]) * np.exp(-1j * theta_out)[:, None]).ravel()
    rho = design.r_rp + design.d_rrp
    # Ray s*u enters circle |p - q| = rho at s = u.q - sqrt(rho^2 - |q|^2 + (u.q)^2).
    # Only circles whose centre is within the angle they subtend can be hit.
    q_angle, q_abs = np.angle(q), np.abs(q)
    half_width = np.arcsin(np.clip(rho / q_abs, 0.0, 1.0))
    radius = np.full(angles.shape, np.inf)
    chunk = max(1, 4_000_000 // q.size)
    for start in range(0, angles.size, chunk):  # chunks bound the memory, not a point loop
        a = angles[start : start + chunk, None]
        off = np.angle(np.exp(1j * (q_angle[None, :] - a)))
        proj = q_abs[None, :] * np.cos(off)
        disc = rho * rho - (q_abs * q_abs)[None, :] + proj * proj
        hit = (np.abs(off) <= half_width[None, :]) & (disc >= 0.0)
        entry = np.where(hit, proj - np.sqrt(np.where(hit, disc, 0.0)), np.inf)
        radius[start : start + chunk] = entry.min(axis=1)
    return angles, radius


def profile_radius_at(design: RVDesign, angles) -> np.ndarray:
    """Radius [m] of the closed-form disc-0 profile at disc-frame polar angles [rad].

    angles: any shape; returns the same shape.  The parameter t of each angle is
    interpolated from a fine closed-form sampling, then refined by Newton steps
    on the polar angle, so the radius is exact to rounding, not to a chord.
    """
    angles = np.asarray(angles, dtype=float)
    fine_t = np.linspace(0.0, 2.0 * np.pi, _FINE_POINTS + 1)
    polar = np.unwrap(np.arctan2(*_closed_form(design, fine_t)[::-1]))  # 0 ... 2*pi
    if np.any(np.diff(polar) <= 0.0):
        raise ValueError(f"{design.name}: profile is not star-shaped about the disc centre")
    target = np.mod(angles, 2.0 * np.pi)
    t = np.interp(target, polar, fine_t)
    h = 1e-6
    for _ in range(3):
        x, y = _closed_form(design, t)
        xp, yp = _closed_form(design, t + h)
        xm, ym = _closed_form(design, t - h)
        slope = (np.arctan2(yp, xp) - np.arctan2(ym, xm) + np.pi) % (2 * np.pi) - np.pi
        miss = (np.arctan2(y, x) - target + np.pi) % (2 * np.pi) - np.pi
        t = t - miss / (slope / (2.0 * h))
    x, y = _closed_form(design, t)
    return np.hypot(x, y)


def write_profile_csv(design: RVDesign, path: str | Path, points: int = DEFAULT_POINTS) -> Path:
    """Write the disc-0 profile as CSV, columns `x_mm,y_mm` with a header line, mm."""
    p = disc_profile(design, points)
    path = Path(path)
    np.savetxt(
        path,
        np.column_stack([p.x / MM, p.y / MM]),
        delimiter=",",
        header="x_mm,y_mm",
        comments="",
        fmt="%.9f",
    )
    return path


def write_profile_dxf(design: RVDesign, path: str | Path, points: int = DEFAULT_POINTS) -> Path:
    """Write the disc-0 profile as a closed LWPOLYLINE of `points` vertices, mm."""
    try:
        import ezdxf
    except ImportError:
        raise RuntimeError("writing DXF needs the ezdxf package: pip install ezdxf") from None
    p = disc_profile(design, points)
    doc = ezdxf.new("R2010", units=ezdxf.units.MM)
    doc.modelspace().add_lwpolyline(np.column_stack([p.x / MM, p.y / MM]).tolist(), format="xy", close=True)
    path = Path(path)
    doc.saveas(path)
    return path
