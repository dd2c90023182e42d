"""The dynamic model: the reducer's lumped masses, springs and dampers in the time domain.

The question the quasi-static model cannot answer: what TE does the reducer
show while it turns at speed, with its own inertias, near its resonances and
under a load step?  Seeds 000-002 answer it with a lumped-parameter model:
every part a rigid body in the plane, every mesh, bearing and pin contact a
spring with a damper, integrated in time (seed 002, eqs. (1)-(5)).

This model uses the same elements, gaps and error displacements as the
quasi-static one (`EquivalentModel`: one implementation of the geometry), over
its unknowns plus the sun's rotation: the input shaft is stiff but not rigid,
so the sun follows the prescribed input angle through `INPUT_SHAFT_FACTOR`
times the torsional mesh stiffness, and the shaft's twist gives the input
torque.  Unknowns are small displacements from the nominal kinematics of
docs/model.md section 2 (rotations as arc length at R_p, as in the quasi-static
model); the nominal motion itself enters as d'Alembert forces: every body's
nominal acceleration (centripetal terms of the cranks and discs, and the
angular accelerations during a speed ramp) times its mass.

    M q'' + C(q) q' + f(q, t) = F_load(t) + F_nominal(t)

- Pin-disc contacts are unilateral: a spring-damper, its spring the stated
  stiffness (`linear`) or the Hertz law of the pin between its disc and its groove
  (`hertz`, `pin_law`: the quasi-static model's law where the design gives the
  groove; the default follows the design), or the IMPACT law of seeds
  000/001/004 (k delta^e with the damping ramped from 0 to c_max over the
  penetration d_max); bearing clearances are dead zones; the
  sun-planet meshes are bilateral springs on the loaded flank.
- The mesh stiffness varies over the mesh cycle (`mesh_stiffness_factor`):
  single pair c' and double pair 1.75 c', whose mean over the cycle is ISO
  6336-1's c_gamma = c' (0.75 eps_alpha + 0.25), the preset's mesh stiffness.
- Damping: modal, the design's ratio zeta on every mode of the model linearised
  at the run's starting equilibrium (`set_modal_damping`):
  C = M Phi diag(2 zeta w_k) Phi^T M, Phi the mass-normalised shapes; the
  IMPACT law keeps its own contact damping besides.
- Friction (docs/model.md section 9), at the contacts and with the coefficients of
  the quasi-static power balance (`friction.py`): each contact resists its slip w
  (its sliding speed [m/s]: the nominal kinematics' plus the unknowns') with
  R w / sqrt(w^2 + SLIP_SCALE^2), R = mu N + drag, N its own normal force.  A pin
  slides along its tangent (the smaller coefficient of its two contacts); a bearing's
  slip is its parts' relative turn at its pitch radius (its drag Palmgren's moment at
  the nominal speed); a mesh's is H_V times the sun's base-circle speed against the
  carrier (its loss mu H_V |tau_sun| times that speed); the output seal's, the
  carrier's at R_p.
- The load-free losses, those of the quasi-static model (`friction.load_free_torques`), each
  a resistance at the contact's nominal speed: the output seal's torque on the carrier
  (`seals.seal_torques`: a stated `seal_torque` > 0, else its law), the input seal's on the
  sun's turn at its counterface radius (through the shaft, the input torque carries it),
  and the churning of the lubricant (`churning.py`, ISO/TR 14179-2), each part's torque
  c n^2 at its own speed n on its own turn: the sun's on the sun, the planets' on their
  cranks, the discs' on the discs.  The lubricant is at the model's `temperature_C` (40 C
  by default).
- Breakaway: the Coulomb contacts and the seals resist with their running R times the
  regularised Stribeck law 1 + (f_s - 1) exp(-(w / STRIBECK_SPEED)^2), f_s the design's
  `static_friction_factor` (`seals.py`): f_s at rest, the running friction beyond a few
  STRIBECK_SPEED; f_s = 1 is the regularised Coulomb law itself.  Palmgren's drag and the
  churning are viscous: no breakaway.

Nothing here integrates: `DynamicModel` gives the mass matrix, the loads and
the element forces with their tangent stiffness and damping at a time step;
the integrators (`newmark.py`) and `simulate` (`simulation.py`) drive it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..base.compiled import COMPILED
from ..laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature, viscosity_cSt
from ..laws.pin_law import contacts
from ..laws.roller_law import TABLE_DE, TABLE_E, radial_law
from ..laws.seals import SEAL_NAMES, seal_torques
from ..laws.stiffness import transverse_contact_ratio
from ..losses.churning import churning_parts, gear_churning_power
from ..losses.friction import RPM, drag_moments, mesh_loss_factor
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet
from ..statics.equivalent import EquivalentModel, touched_columns
from .dynamic_geometry import DOUBLE_PAIR, build_geometry, geometry_constants
from .kernels import Elements, Geometry, element_forces, gather

INPUT_SHAFT_FACTOR = 10.0  # input shaft torsional stiffness / torsional mesh stiffness at the sun
IMPACT_EXPONENT = 1.5  # IMPACT law exponent e (Hertz-like, seeds 000/001)
IMPACT_PENETRATION = 1e-6  # d_max [m]: the damping reaches c_max over 1 um of penetration
CHUNK = 512  # time steps whose geometry is built at once
FLOATING_HZ = 1e-3  # a mode below this is a part floating in a clearance: not damped
SLIP_SCALE = 1e-5  # [m/s] friction's regularised sign: a contact slipping at 10 um/s
# carries 71 % of its Coulomb force, at 0.1 mm/s 99.5 %
# [m/s] the Stribeck speed: below it the friction rises toward its breakaway value.  An
# estimate inside the 1e-5 to 1e-1 m/s of lubricated contacts (Armstrong-Helouvry, Dupont,
# Canudas de Wit, Automatica 30 (1994) 1083), the same 0.01 m/s the quasi-static map's step
# takes (`reducer_model.STRIBECK_SPEED`); 1000 x SLIP_SCALE, so the regularisation does not
# hide the peak.  1 mm/s (the LuGre model's example, Canudas de Wit et al., IEEE Trans.
# Autom. Control 40 (1995) 419), tried first, puts a lightly loaded reducer at a crawl on the
# law's falling slope: the robot joint's arm, stopping after its move, then sticks and slips
# and the iterated coupling of studies/robot_joint fails to converge at t = 1.536 s.
STRIBECK_SPEED = 1e-2
SEALS = SEAL_NAMES
CONTACT_LAWS = ("linear", "hertz", "impact")
MESH_MODELS = ("varying", "constant")


@dataclass(frozen=True)
class Motion:
    """Prescribed input angle [rad], speed [rad/s] and acceleration [rad/s^2], and the load
    torque tau_load [N*m] (docs/model.md section 2 sign; default zero) at times t, each (T,)."""

    time: np.ndarray
    theta_in: np.ndarray
    omega_in: np.ndarray
    alpha_in: np.ndarray
    tau_load: np.ndarray | None = None

    def __post_init__(self):
        load = (
            np.zeros(self.time.size)
            if self.tau_load is None
            else np.broadcast_to(np.asarray(self.tau_load, dtype=float), self.time.shape).copy()
        )
        object.__setattr__(self, "tau_load", load)


def at_rest(theta_in: float, time: float = 0.0, tau_load: float = 0.0) -> Motion:
    """One instant at input angle theta_in [rad], speed and acceleration zero, under tau_load."""
    return Motion(
        np.array([float(time)]),
        np.array([float(theta_in)]),
        np.zeros(1),
        np.zeros(1),
        np.array([float(tau_load)]),
    )


def ramp_motion(time, speed: float, ramp: float, tau_load=0.0) -> Motion:
    """Input speed raised smoothly from 0 to `speed` [rad/s] over `ramp` [s] (half a cosine,
    as seed 004's start ramp), then constant; theta_in(0) = 0.  tau_load: [N*m], a constant
    or one value per time."""
    t = np.asarray(time, dtype=float)
    if ramp <= 0.0:
        return Motion(t, speed * t, np.full_like(t, speed), np.zeros_like(t), tau_load)
    inside = t < ramp
    x = np.minimum(t, ramp)
    theta = 0.5 * speed * (x - ramp / math.pi * np.sin(math.pi * x / ramp)) + speed * np.maximum(
        t - ramp, 0.0
    )
    omega = np.where(inside, 0.5 * speed * (1.0 - np.cos(math.pi * x / ramp)), speed)
    alpha = np.where(inside, 0.5 * speed * math.pi / ramp * np.sin(math.pi * x / ramp), 0.0)
    return Motion(t, theta, omega, alpha, tau_load)


def mesh_stiffness_factor(design: RVDesign, theta_in, theta_out, model: str = "varying"):
    """(T, n_c) mesh stiffness over its mean (ISO c_gamma): 1 for `constant`; for `varying`
    single-pair and double-pair levels by the position in the mesh cycle.

    The cycle position is the count of sun teeth passed relative to the carrier,
    z_s (theta_in - theta_out) / 2 pi; planet i is shifted by i z_s / n_c teeth.
    The first eps_alpha - 1 of each cycle has two pairs in contact.
    """
    theta_in = np.atleast_1d(np.asarray(theta_in, dtype=float))
    if model == "constant":
        return np.ones((theta_in.size, design.n_c))
    eps = transverse_contact_ratio(design.z_s, design.z_pl, design.m, design.pressure_angle)
    teeth = design.z_s * (theta_in - np.asarray(theta_out, dtype=float)) / (2.0 * math.pi)
    phase = np.mod(teeth[:, None] + design.z_s * np.arange(design.n_c) / design.n_c, 1.0)
    single = 1.0 / (0.75 * eps + 0.25)
    return np.where(phase < eps - 1.0, DOUBLE_PAIR * single, single)


def contact_law(design: RVDesign, contact: str | None) -> str:
    """The pin contact law of a dynamic run: `contact` checked, or by default the design's own
    ("hertz" where it gives the pins' groove, else "linear")."""
    from ..base.checks import InputError

    if contact is None:
        return "hertz" if design.pin_law[1] > 0.0 else "linear"
    if contact not in CONTACT_LAWS:
        raise InputError("contact", contact, f"must be one of {', '.join(CONTACT_LAWS)}")
    if contact == "hertz" and design.pin_law[1] == 0.0:
        raise InputError(
            "contact",
            contact,
            "needs the pins' groove: the design's pin_groove_clearance_mm must be > 0",
            design.name,
        )
    return contact


class DynamicModel:
    """Masses, loads and element forces of one reducer over a prescribed input motion.

    errors: one reducer (an ErrorSet of one sample); tau_load: [N*m] constant or a
    function of time (docs/model.md section 2 sign); flank: the loaded flank of the
    meshes (+1: the sun drives, -1: the load drives; default from the load's sign);
    friction: False leaves out the contacts' friction and drag (a frictionless reducer);
    temperature_C: the lubricant's [C] (the viscosity of the bearings' drag and the churning).
    """

    compiled_geometry = True  # False: the element geometry in numpy (`_chunk_numpy`) even with numba

    def __init__(
        self,
        design: RVDesign,
        errors: ErrorSet,
        contact: str | None = None,
        mesh: str = "varying",
        flank: int = 1,
        friction: bool = True,
        temperature_C: float = REFERENCE_TEMPERATURE_C,
    ):
        if errors.samples != 1:
            raise ValueError("the dynamic model simulates one reducer at a time")
        contact = contact_law(design, contact)
        self.temperature_C = check_temperature(temperature_C)
        self.viscosity = viscosity_cSt(design, self.temperature_C)  # [mm^2/s]
        self.seal_torques = seal_torques(design)  # [N*m]
        self.design, self.errors = design, errors
        self.contact, self.mesh, self.flank = contact, mesh, flank
        # a few generic input angles, to find which unknowns each element touches
        probe = EquivalentModel(
            design, 2.0 * math.pi * np.sqrt([2.0, 3.0, 5.0, 7.0, 11.0]), flank, sun_rotation=True
        )
        self._linear_cols = touched_columns(probe.linear_rows)
        self._bearing_cols = touched_columns(probe.bearing_rows)
        self.names, self.n = probe.names, probe.n_dof
        self.index = probe.index
        self.scale = probe.scale
        self.carrier_rot, self.sun_rot = probe.index["carrier_rot"], probe.index["sun_rot"]
        self.pin_dofs = probe.pin_dofs
        self.bearing_k = probe.bearing_k
        self.half_clearance = probe.clearance_halves(errors)[0]
        self.mass = self._mass_diagonal()
        r_b = design.sun_base_radius
        self.shaft_k = INPUT_SHAFT_FACTOR * design.n_c * design.mesh_stiffness * r_b**2  # N*m/rad
        # Damping is modal (`set_modal_damping`): the element dashpots are none, but IMPACT's,
        # whose law carries its own (c_max = 2 zeta sqrt(k m_disc), ramped over d_max)
        n_c = design.n_c
        self.linear_c = np.zeros(n_c + 2)
        self.bearing_c = np.zeros(self.bearing_k.size)
        self.pin_k = design.pin_disc_stiffness
        self.pin_c = (
            2 * design.damping_ratio * math.sqrt(self.pin_k * design.disc_mass)
            if contact == "impact"
            else 0.0
        )
        self.shaft_c = 0.0
        # IMPACT: k delta^e equals the linear law at the pin deflection under rated torque
        self.impact_k = self.pin_k * self._rated_pin_deflection() ** (1.0 - IMPACT_EXPONENT)
        self.friction = bool(friction)
        turning = self._turning_contacts(probe)
        s2 = self.scale**2
        self.elements = Elements(
            self.linear_c,
            np.ascontiguousarray(self.half_clearance, dtype=float),
            self.bearing_k,
            self.bearing_c,
            np.ascontiguousarray(np.stack([probe.bearing_law_a, probe.bearing_law_compliance], axis=-1)),
            np.ascontiguousarray(np.stack([TABLE_E, TABLE_DE])),
            np.asarray(self.pin_dofs, dtype=np.int64),
            np.array(design.pin_law if contact == "hertz" else (self.pin_k, 0.0, 0.0), dtype=float),
            float(self.pin_c),
            contact == "impact",
            float(self.impact_k),
            IMPACT_EXPONENT,
            IMPACT_PENETRATION,
            int(self.sun_rot),
            self.shaft_k / s2,
            self.shaft_c / s2,
            min(design.pin_disc_friction, design.pin_groove_friction) if friction else 0.0,
            turning["cols"],
            turning["rows"],
            turning["source"],
            turning["friction"] if friction else np.zeros(turning["friction"].size),
            SLIP_SCALE,
            friction and self._resists(turning),
            np.zeros((self.n, self.n)),
            float(design.static_friction_factor) if friction else 1.0,
            STRIBECK_SPEED,
            np.array([1.0 if kind in SEALS else 0.0 for kind in turning["kind"]]),
        )
        self.modal_frequencies, self.modal_shapes = np.empty(0), np.empty((self.n, 0))
        self.floating = 0
        self._drag_radius, self._drag_kind = turning["radius"], turning["kind"]
        self._churning = turning["churning"]
        counts = {"crank": design.n_c, "disc": 2}
        self._nominal_index = tuple(
            {body: [self.index[f"{body}{k}_{axis}"] for k in range(count)] for body, count in counts.items()}
            for axis in ("x", "y", "rot")
        )
        self._geometry = None
        self._constants = None

    # -- constant parts --------------------------------------------------------------
    def set_modal_damping(self, q: np.ndarray, step: int = 0) -> None:
        """Damp every mode of the model linearised at the state q (at rest) by the design's
        ratio: K the tangent stiffness there (symmetrised), K phi = w^2 M phi, and
        C = M Phi diag(2 zeta w) Phi^T M on the unknowns' velocities, kept for the run (the
        Newmark step and the FMU apply the same matrix).  A part floating in a clearance
        (below FLOATING_HZ) is left undamped; `modal_frequencies` [rad/s] and `modal_shapes`
        (n, N) (mass-normalised, ascending) are the modes damped, `floating` how many
        were not (what `modes.modes` reports)."""
        from scipy.linalg import eigh

        self.elements = self.elements._replace(modal_c=np.zeros((self.n, self.n)))
        _, K, _ = self.forces(step, np.asarray(q, dtype=float), np.zeros(self.n))
        w2, shapes = eigh(0.5 * (K + K.T), np.diag(self.mass))
        w = np.sqrt(np.maximum(w2, 0.0))
        keep = w / (2.0 * math.pi) >= FLOATING_HZ
        weighted = self.mass[:, None] * shapes[:, keep]  # M Phi
        modal = (weighted * (2.0 * self.design.damping_ratio * w[keep])) @ weighted.T
        self.elements = self.elements._replace(modal_c=np.ascontiguousarray(0.5 * (modal + modal.T)))
        self.modal_frequencies, self.modal_shapes = w[keep], shapes[:, keep]
        self.floating = int(np.count_nonzero(~keep))

    def _resists(self, turning: dict) -> bool:
        """Whether any contact has friction or drag (with none, the run is the frictionless
        one to the bit)."""
        d = self.design
        pins = min(d.pin_disc_friction, d.pin_groove_friction) > 0.0
        drag = (
            d.bearing_drag_factor > 0.0
            and self.viscosity > 0.0
            and any(
                r > 0.0
                for r, kind in zip(turning["radius"], turning["kind"])
                if kind not in (None, "churning") + SEALS
            )
        )
        seals = any(
            r > 0.0 and self.seal_torques[kind] > 0.0
            for r, kind in zip(turning["radius"], turning["kind"])
            if kind in SEALS
        )
        return bool(
            pins
            or np.any(turning["friction"] * np.abs(turning["rows"]).sum(axis=1) > 0.0)
            or drag
            or seals
            or np.any(turning["churning"] > 0.0)
        )

    def _turning_contacts(self, probe) -> dict:
        """The contacts whose slip is a turn: each crank's bearing pair in the carrier, each
        needle bearing, the main bearings, each sun-planet mesh, the output seal, the input
        seal, and the churning of each disc, each crank and the sun, in that order.  {"cols"
        (E, 2), "rows" (E, 2): the slip [m/s] per unknown velocity; "source" (E,): the
        element pressing it (`Elements.turn_source`); "friction" (E,); "radius" (E,) [m]:
        the arm its drag moment acts at (0: no drag); "kind": the `friction.drag_moments`
        key of its drag, a seal's name (`SEALS`), "churning" or None; "churning" (E,)
        [N*m/rpm^2]: a churning drag's torque over the square of its speed}."""
        d, idx, s = self.design, self.index, self.scale
        nb = self.bearing_k.size
        carrier = idx["carrier_rot"]
        cols, rows, source, mu, radius, kind, churn = [], [], [], [], [], [], []

        def add(c, r, src, coefficient, arm, drag, churning=0.0):
            cols.append(c + [-1] * (2 - len(c)))
            rows.append(r + [0.0] * (2 - len(r)))
            source.append(src)
            mu.append(coefficient)
            radius.append(arm)
            kind.append(drag)
            churn.append(churning)

        r = 0.5 * d.tapered_pitch_diameter
        for i in range(d.n_c):
            add(
                [idx[f"crank{i}_rot"], carrier],
                [r / s, -r / s],
                i,
                d.tapered_friction,
                r,
                "crank-carrier bearings",
            )
        r = 0.5 * d.needle_pitch_diameter
        for i in range(d.n_c):
            for j in range(2):
                add(
                    [idx[f"crank{i}_rot"], idx[f"disc{j}_rot"]],
                    [r / s, -r / s],
                    d.n_c + 2 * i + j,
                    d.needle_friction,
                    r,
                    "crank-disc needle bearings",
                )
        r = 0.5 * d.main_bearing_pitch_diameter
        add([carrier], [r / s], nb - 1, d.main_bearing_friction, r, "main bearings")
        arm = mesh_loss_factor(d.z_s, d.z_pl, d.pressure_angle)[0] * d.sun_base_radius
        for i in range(d.n_c):
            add([idx["sun_rot"], carrier], [arm / s, -arm / s], nb + i, d.mesh_friction, 0.0, None)
        add([carrier], [1.0], -1, 0.0, s, "output seal")
        r = 0.5 * d.input_seal_diameter  # the lip slides on the shaft at its radius
        add([idx["sun_rot"]], [r / s], -1, 0.0, r, "input seal")
        # churning: a drag on each part's turn, its slip at R_p (`_churning_coefficients`)
        churning = self._churning_coefficients()
        for body, turns in (
            ("disc", [f"disc{j}_rot" for j in range(2)]),
            ("crank", [f"crank{i}_rot" for i in range(d.n_c)]),
            ("sun", ["sun_rot"]),
        ):
            for name in turns:
                add([idx[name]], [1.0], -1, 0.0, s, "churning", churning[body])
        return {
            "cols": np.array(cols, dtype=np.int64),
            "rows": np.array(rows),
            "source": np.array(source, dtype=np.int64),
            "friction": np.array(mu),
            "radius": np.array(radius),
            "kind": kind,
            "churning": np.array(churn),
        }

    def _churning_coefficients(self) -> dict:
        """{"disc", "crank", "sun": [N*m/rpm^2]} the churning torque on each disc, crank and
        the sun over the square of its speed against the housing [rpm], from
        `churning.churning_parts` and `gear_churning_power` (ISO/TR 14179-2: the power grows
        as n^3, so the torque at the part's own speed is P(1 rpm) / (1 rpm) x n^2).  Each
        part goes to the bodies that turn at its speed, shared evenly: the output's (the
        discs, which turn with the carrier), the cranks' (the planets) or the input's (the
        sun).  All zero without a fill or without friction."""
        d = self.design
        out = {"disc": 0.0, "crank": 0.0, "sun": 0.0}
        if not self.friction or d.lubricant_fill == 0.0:
            return out
        bodies = {1.0: ("disc", 2), float(d.z_c): ("crank", d.n_c), float(d.ratio): ("sun", 1)}
        for parts in churning_parts(d).values():
            for count, diameter, width, module, ratio in parts:
                if float(ratio) not in bodies:
                    raise ValueError(
                        f"a churning part turns at {ratio:g} x the output's speed: "
                        "the dynamic model carries those at the discs' (1), the "
                        f"cranks' ({d.z_c}) and the input's ({d.ratio:g})"
                    )
                body, share = bodies[float(ratio)]
                out[body] += (
                    count
                    * float(
                        gear_churning_power(d.lubricant_fill, self.viscosity, 1.0, diameter, width, module)
                    )
                    / RPM
                    / share
                )
        return out

    def _bodies(self) -> dict:
        """{body: (mass [kg], inertia [kg m^2])} of the sun, a crank, a disc and the carrier."""
        d = self.design
        return {
            "sun": (d.sun_mass, d.sun_inertia),
            "crank": (d.crank_mass, d.crank_inertia),
            "disc": (d.disc_mass, d.disc_inertia),
            "carrier": (d.carrier_mass, d.carrier_inertia),
        }

    def _mass_diagonal(self) -> np.ndarray:
        s2 = self.design.R_p**2
        values = self._bodies()
        out = np.empty(self.n)
        for k, name in enumerate(self.names):
            body = name.split("_")[0].rstrip("0123456789")
            mass, inertia = values[body]
            out[k] = inertia / s2 if name.endswith("_rot") else mass
        return out

    def _rated_pin_deflection(self) -> float:
        from ..laws.stiffness import largest_pin_force

        force = largest_pin_force(
            0.5 * self.design.rated_torque, self.design.R_p, self.design.e, self.design.z_p
        )
        return force / self.pin_k

    # -- per step ----------------------------------------------------------------------
    def prepare(self, motion: Motion) -> None:
        """Keep the motion; element geometry is built chunk by chunk as steps ask for it."""
        self.motion = motion
        self._geometry = None

    def geometry(self, step: int):
        """(Geometry of the chunk holding time step `step`, the step's index in it)."""
        g = self._geometry
        if g is None or not self._start <= step < self._start + g.h.size:
            g = self._geometry = self._chunk(step, min(step + CHUNK, self.motion.time.size))
            self._start = step
        return g, step - self._start

    def _chunk(self, start: int, stop: int) -> Geometry:
        """Rows, offsets, mesh stiffnesses and external forces of every element at steps
        start..stop-1 of the motion: compiled (`dynamic_geometry`) where numba is and
        `compiled_geometry` is on, else in numpy (`_chunk_numpy`, the reference)."""
        if not (COMPILED and self.compiled_geometry):
            return self._chunk_numpy(start, stop)
        m = self.motion
        return build_geometry(
            self.constants(),
            self._steps(start, stop),
            *(np.ascontiguousarray(x[start:stop]) for x in (m.theta_in, m.omega_in, m.alpha_in, m.tau_load)),
        )

    def constants(self):
        """The constants of the compiled element geometry (`geometry_constants`), gathered
        once per model."""
        if self._constants is None:
            self._constants = geometry_constants(self)
        return self._constants

    def _steps(self, start: int, stop: int) -> np.ndarray:
        """(stop - start,) the time step into each of the motion's steps start..stop-1 [s]
        (the run's first: 0)."""
        m = self.motion
        return np.diff(m.time[start - 1 : stop]) if start else np.diff(m.time[:stop], prepend=m.time[0])

    def _chunk_numpy(self, start: int, stop: int) -> Geometry:
        """`_chunk` in numpy, from `EquivalentModel`."""
        m = self.motion
        theta = m.theta_in[start:stop]
        model = EquivalentModel(self.design, theta, self.flank, sun_rotation=True)
        A = stop - start
        lin, brg, pins = model.offsets(self.errors, np.zeros(A, dtype=int), slice(None))
        factor = mesh_stiffness_factor(self.design, theta, theta / self.design.ratio, self.mesh)
        k_lin = np.tile(model.linear_k, (A, 1))
        k_lin[:, : self.design.n_c] *= factor
        external = m.tau_load[start:stop, None] * self.load_vector() + self.nominal_forces(
            theta, m.omega_in[start:stop], m.alpha_in[start:stop]
        )
        h = self._steps(start, stop)
        L = gather(model.linear_rows, self._linear_cols)
        B = gather(model.bearing_rows, self._bearing_cols)
        # friction: each pin slips along its tangent (the disc's point turning about the disc's
        # centre by n . (Q - C)), each turning contact as its rows say; nominal slips are the
        # rows times the nominal velocities
        normal = model.pin_rows[..., :2]
        tangent = np.concatenate(
            [-normal[..., 1:], normal[..., :1], (model.pin_tangent_lever / self.scale)[..., None]], axis=-1
        )
        nominal = self.nominal_velocities(theta, m.omega_in[start:stop])
        pin_slip = np.einsum("ajpx,ajx->ajp", tangent, nominal[:, self.pin_dofs])
        el = self.elements
        turn_slip = np.einsum(
            "ex,aex->ae", el.turn_rows, nominal[:, np.maximum(el.turn_cols, 0)] * (el.turn_cols >= 0)
        )
        turn_drag = self._drag(turn_slip)
        # every array C-contiguous: the compiled kernels then see one type signature, the
        # one `compile_kernels` compiles and the FMU bundles, whatever the chunk's length
        parts = (
            h,
            np.maximum(self._linear_cols, 0),
            L,
            k_lin,
            lin,
            np.maximum(self._bearing_cols, 0),
            B,
            brg,
            model.pin_rows,
            pins,
            external,
            tangent,
            pin_slip,
            turn_slip,
            turn_drag,
        )
        return Geometry(*(np.ascontiguousarray(x) for x in parts))

    def _drag(self, turn_slip: np.ndarray) -> np.ndarray:
        """(A, E) load-free resistance [N] of the turning contacts at their nominal slips
        (A, E): a bearing's Palmgren moment at its speed over its pitch radius, a seal's
        torque over its radius, a part's churning c n^2 at its speed n [rpm] over its arm;
        zero without friction.  (`dynamic_geometry.fill_geometry` computes the same, in the
        same order.)"""
        drag = np.zeros(turn_slip.shape)
        if not self.friction:
            return drag
        radius = np.asarray(self._drag_radius, dtype=float)
        for kind in set(self._drag_kind) - {None}:
            cols = [e for e, k in enumerate(self._drag_kind) if k == kind and radius[e] > 0.0]
            if not cols:
                continue
            if kind in SEALS:
                drag[:, cols] = self.seal_torques[kind] / radius[cols]
            elif kind == "churning":
                speed_rpm = np.abs(turn_slip[:, cols]) / radius[cols] / RPM
                drag[:, cols] = self._churning[cols] * speed_rpm * speed_rpm / radius[cols]
            else:  # one Palmgren moment per kind, over all its contacts and steps
                speed_rpm = np.abs(turn_slip[:, cols]) / radius[cols] / RPM
                drag[:, cols] = drag_moments(self.design, speed_rpm, self.temperature_C)[kind] / radius[cols]
        return drag

    def external(self, step: int) -> np.ndarray:
        """(n,) external generalised force at a step [N]: the load torque on the carrier and
        the nominal motion's d'Alembert forces."""
        g, a = self.geometry(step)
        return g.external[a]

    def _nominal_motion(self, theta_in, omega_in, alpha_in):
        """The nominal motion (docs/model.md section 2) at each instant: ({"in", "out",
        "crank"}: (speed [rad/s], acceleration [rad/s^2]) of the input, of the output (the
        carrier and the discs' turn) and of the cranks' turn; ((body, radius [m], angle (A,
        count) [rad], speed, acceleration) of the circles the crank and disc centres ride:
        crank c at theta_out + 2 pi c / n_c, disc j at psi + j pi))."""
        d, i = self.design, self.design.ratio
        th_in, w_in, a_in = (np.asarray(x, dtype=float) for x in (theta_in, omega_in, alpha_in))
        th_out, w_out, a_out = th_in / i, w_in / i, a_in / i
        k_beta = -d.z_s / d.z_pl
        w_psi = w_out + k_beta * (w_in - w_out)
        a_psi = a_out + k_beta * (a_in - a_out)
        psi = th_out + k_beta * (th_in - th_out)
        turns = {"in": (w_in, a_in), "out": (w_out, a_out), "crank": (w_psi, a_psi)}
        circles = (
            (
                "crank",
                d.crank_circle_radius,
                th_out[:, None] + 2 * math.pi * np.arange(d.n_c) / d.n_c,
                w_out,
                a_out,
            ),
            ("disc", d.e, psi[:, None] + math.pi * np.arange(2), w_psi, a_psi),
        )
        return turns, circles

    def nominal_velocities(self, theta_in, omega_in) -> np.ndarray:
        """(A, n) velocities of the nominal motion [m/s, rotations as arc length at R_p]:
        every body's rigid-kinematics velocity (docs/model.md section 2) at each instant."""
        theta_in = np.atleast_1d(np.asarray(theta_in, dtype=float))
        omega_in = np.broadcast_to(np.asarray(omega_in, dtype=float), theta_in.shape)
        turns, circles = self._nominal_motion(theta_in, omega_in, np.zeros(theta_in.shape))
        out = np.zeros((theta_in.size, self.n))
        idx, s = self.index, self.scale
        out[:, idx["sun_rot"]] = turns["in"][0] * s
        out[:, idx["carrier_rot"]] = turns["out"][0] * s
        x, y, rot = self._nominal_index
        for body, radius, angle, w, _ in circles:
            speed = (radius * w)[:, None]
            out[:, x[body]] = -speed * np.sin(angle)
            out[:, y[body]] = speed * np.cos(angle)
        out[:, rot["crank"]] = (turns["crank"][0] * s)[:, None]
        out[:, rot["disc"]] = (turns["out"][0] * s)[:, None]
        return out

    def nominal_forces(self, theta_in, omega_in, alpha_in) -> np.ndarray:
        """(A, n) d'Alembert forces of the nominal motion [N]: minus mass times the nominal
        acceleration of every body (docs/model.md section 2 kinematics) at each instant."""
        d = self.design
        turns, circles = self._nominal_motion(theta_in, omega_in, alpha_in)
        f = np.zeros((turns["in"][0].size, self.n))
        idx, s = self.index, self.scale
        f[:, idx["sun_rot"]] = -d.sun_inertia * turns["in"][1] / s
        f[:, idx["carrier_rot"]] = -d.carrier_inertia * turns["out"][1] / s
        # each centre's acceleration on its circle: radius (acc t - w^2 r), r and t the radial
        # and tangential units
        x, y, rot = self._nominal_index
        for body, radius, angle, w, acc in circles:
            mass = d.crank_mass if body == "crank" else d.disc_mass
            c, sn = np.cos(angle), np.sin(angle)
            w2, acc = (mass * radius * w**2)[:, None], (mass * radius * acc)[:, None]
            f[:, x[body]] = acc * sn + w2 * c
            f[:, y[body]] = w2 * sn - acc * c
        f[:, rot["crank"]] = (-d.crank_inertia * turns["crank"][1] / s)[:, None]
        f[:, rot["disc"]] = (-d.disc_inertia * turns["out"][1] / s)[:, None]
        return f

    def forces(self, step: int, q: np.ndarray, v: np.ndarray):
        """Internal forces at a step: (f (n,), K (n, n), C (n, n)).

        f is what the elements push back with (the EOM is M a + f = F); K and C are
        its derivatives in q and v (tangent stiffness and damping).  The input shaft
        ties the sun's rotation to the prescribed angle.
        """
        f, K, C, _ = self.forces_and_powers(step, q, v)
        return f, K, C

    def forces_and_powers(self, step: int, q: np.ndarray, v: np.ndarray):
        """`forces` and the powers (friction, dampers) [W] the elements dissipate there."""
        g, a = self.geometry(step)
        f, K, C = np.empty(self.n), np.empty((self.n, self.n)), np.empty((self.n, self.n))
        powers = element_forces(
            self.elements,
            g,
            a,
            np.ascontiguousarray(q, dtype=float),
            np.ascontiguousarray(v, dtype=float),
            f,
            K,
            C,
        )
        return f, K, C, powers

    def energy(self, step: int, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic energy of the unknowns' velocities plus the elastic energy [J] at a step
        (the linear or Hertz pin law, not IMPACT's; for energy checks)."""
        return float(0.5 * np.sum(self.mass * v * v) + self.elastic_energy(step, q))

    def stored_energy(self, step: int, q: np.ndarray, v: np.ndarray) -> float:
        """The reducer's kinetic energy in its whole motion (nominal plus the unknowns') plus
        its elastic energy [J] at a step: what the power balance's storage term counts."""
        m = self.motion
        speed = self.nominal_velocities(m.theta_in[step], m.omega_in[step])[0] + v
        return float(0.5 * np.sum(self.mass * speed * speed) + self.elastic_energy(step, q))

    def elastic_energy(self, step: int, q: np.ndarray) -> float:
        """Elastic energy [J] of every element at a step (as `energy`)."""
        g, a = self.geometry(step)
        delta = np.sum(g.L[a] * q[g.linear_cols], axis=-1) + g.linear_offset[a]
        elastic = 0.5 * np.sum(g.linear_k[a] * delta**2)
        d = np.sum(g.B[a] * q[g.bearing_cols][:, None, :], axis=-1) + g.bearing_offset[a]
        r = np.sqrt((d**2).sum(axis=1))
        stretch = np.maximum(r - self.half_clearance, 0.0)
        law = self.elements.bearing_law
        rollers = law[:, 0] > 0.0
        elastic += 0.5 * np.sum((self.bearing_k * stretch**2)[~rollers])
        elastic += np.sum(
            radial_law(r[rollers], self.half_clearance[rollers], law[rollers, 0], law[rollers, 1])[0]
        )
        for j in range(2):
            pin = g.P[a, j] @ q[self.pin_dofs[j]] + g.pin_offset[a, j]
            elastic += float(np.sum(contacts(pin, self.elements.pin_law)[0]))
        elastic += 0.5 * self.shaft_k * (q[self.sun_rot] / self.scale) ** 2
        return float(elastic)

    def input_torque(self, q, v) -> float:
        """Torque of the reducer on the input shaft [N*m] (docs/model.md section 2): the shaft's twist."""
        k = self.sun_rot
        return (self.shaft_k * q[k] + self.shaft_c * v[k]) / self.scale

    def load_vector(self) -> np.ndarray:
        """(n,) generalised force of tau_load = 1 N*m on the carrier."""
        g = np.zeros(self.n)
        g[self.carrier_rot] = 1.0 / self.scale
        return g
