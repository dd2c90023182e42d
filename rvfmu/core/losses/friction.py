"""Friction: the power the reducer's contacts lose, its efficiency, running and starting torque.

The engineering question: how much of the motor's power reaches the output, forward and
when the load drives the motor, how much torque the motor needs to turn the unloaded
reducer, and where the power goes.  The answer is the power balance on the frictionless
equilibrium (docs/model.md section 9): the contact loads are those of the quasi-static
model without friction (`solver.solve_pairs`), the speeds those of the rigid kinematics of
section 2, and every contact loses a power >= 0:

- a pin: it turns freely in its housing groove, so the friction force at its two contacts
  is the same (its moment balance) and the smaller Coulomb limit of the two, and it slides
  where that limit is: the loss is min(mu_disc, mu_groove) * N * |v|, v the speed of the
  disc's contact point, which turns about the pitch point (|theta_out'| times its distance
  from there, `EquivalentModel.pin_slide_arm`);
- a rolling bearing: its friction moment times its parts' relative speed (z_p |theta_out'|
  for the crank bearings, |theta_out'| for the main bearings); the moment is a
  load-proportional part mu * P * d_m / 2 (SKF's constant-coefficient estimate, written on
  the pitch diameter) and Palmgren's load-free drag 1e-7 f0 (nu n)^(2/3) d_m^3 [N mm]
  (Harris & Kotzalas, Rolling Bearing Analysis), nu the lubricant's kinematic viscosity at
  its temperature (`lubricant.viscosity_cSt`: ISO VG grade and viscosity index, Walther);
- a sun-planet mesh: mu * H_V of the power it rolls, the sun torque times the sun's speed
  relative to the carrier (ISO/TR 14179-2, Ohlendorf's loss factor H_V);
- the discs and gears churning the lubricant they turn in: ISO/TR 14179-2's no-load loss
  of a dip-lubricated gear at the lubricant's fill and viscosity (`churning.py`);
- the lip seals (`seals.py`, SKF's seal frictional moment on each counterface): the output
  seal's torque times the output speed, the input seal's times the input speed, i times the
  output's.

From rest every Coulomb contact and seal first breaks away at the design's
`static_friction_factor` times its running friction (Palmgren's drag and the churning,
viscous, at theirs): the starting and backdriving torques.

Forward, P_in = P_out + sum of the losses; backdriving (the load drives the motor) the
motor receives P_out - losses, with the losses of the backdriving equilibrium.  To first
order in the coefficients this is the equilibrium with friction: what it leaves out is the
change of the contact loads that friction's own forces make, a fraction of the loss itself
(Malhotra & Parameswaran, Mech. Mach. Theory 18 (1983) 491, compute a cycloid drive's
efficiency the same way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..base.checks import InputError, finite_number, integer
from ..base.units import MM, RPM
from ..laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature, viscosity_cSt
from ..laws.seals import SEAL_NAMES, seal_torques
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet
from ..reducer.limits import check_load, check_speed
from ..statics.budget import bearing_forces
from ..statics.equivalent import EquivalentModel, dof_names
from ..statics.quasistatic import NO_LOAD_PROBE, _checked_errors
from ..statics.solver import solve_pairs
from .churning import CHURNING_NAMES, churning_torques

# Palmgren's drag: 1e-7 f0 (nu n)^(2/3) d_m^3 for nu*n >= 2000 (cSt rpm), 160e-7 f0 d_m^3
# below; the larger of the two is continuous (the branches differ by 0.8 % at 2000).
DRAG_FLOOR = 160.0
LOSS_NAMES = (
    ("pins", "crank-disc needle bearings", "crank-carrier bearings", "main bearings", "sun-planet meshes")
    + CHURNING_NAMES
    + SEAL_NAMES
)
AVERAGE_POINTS = 36  # angles over one crank turn that a loss is averaged on
DEFAULT_SPEEDS_RPM = (5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 60.0)  # the catalogue chart's range
DEFAULT_LOAD_FRACTIONS = (0.25, 0.5, 0.75, 1.0)  # x rated torque


def mesh_loss_factor(z_1: int, z_2: int, pressure_angle: float) -> tuple[float, float, float]:
    """(H_V, eps_1, eps_2) of an unshifted external spur pair with addendum = module.

    ISO/TR 14179-2: the mesh loses mu * H_V of the power it transmits,
    H_V = pi (u + 1) / (z_1 u) (1 - eps_alpha + eps_1^2 + eps_2^2), u = z_2 / z_1, with the
    addendum contact ratios eps_k = z_k / (2 pi) (tan alpha_ak - tan alpha); the module
    cancels.  (eps_1 + eps_2 is the transverse contact ratio.)
    """
    tan_alpha = math.tan(pressure_angle)
    eps = []
    for z in (z_1, z_2):
        tip_angle = math.acos(z * math.cos(pressure_angle) / (z + 2.0))
        eps.append(z / (2.0 * math.pi) * (math.tan(tip_angle) - tan_alpha))
    u = z_2 / z_1
    factor = math.pi * (u + 1.0) / (z_1 * u) * (1.0 - eps[0] - eps[1] + eps[0] ** 2 + eps[1] ** 2)
    return factor, eps[0], eps[1]


def bearing_drag_moment(f0: float, viscosity_cSt: float, speed_rpm, pitch_diameter: float):
    """Palmgren's load-free friction moment [N*m] of one rolling bearing at `speed_rpm`
    (array): 1e-7 f0 max((nu n)^(2/3), 160) d_m^3 N*mm, d_m in mm, nu in mm^2/s."""
    nu_n = viscosity_cSt * np.abs(np.asarray(speed_rpm, dtype=float))
    return 1e-7 * f0 * np.maximum(nu_n ** (2.0 / 3.0), DRAG_FLOOR) * (pitch_diameter / MM) ** 3 * 1e-3


def pitch_diameters_from_sources(values: dict) -> dict:
    """The bearings' pitch diameters of a preset file {file key: mm}, by one rule for every
    frame (no drawing gives them): a needle bearing runs on its cam, whose diameter is the
    crank's plus twice the eccentricity (the least that holds the shaft), with needles a
    third as thick as long; a tapered roller is as thick as long, on the crank's diameter;
    the main bearings run on the pin circle."""
    src = values["sources"]
    crank = src["crank_diameter_mm"]
    return {
        "needle_pitch_diameter_mm": crank + 2.0 * values["e_mm"] + values["needle_roller_length_mm"] / 3.0,
        "tapered_pitch_diameter_mm": crank + values["tapered_roller_length_mm"],
        "main_bearing_pitch_diameter_mm": 2.0 * values["R_p_mm"],
    }


@dataclass(frozen=True)
class ContactLoads:
    """Contact loads of the frictionless equilibria of S reducers at L output torques and A
    input angles.

    tau_load (L,) [N*m]; pin_force (S, L, A, 2, z_p) [N]; pin_slide_arm (A, 2, z_p) [m];
    crank_seat_force (S, L, A, n_c), cam_force (S, L, A, 2 n_c), main_force (S, L, A) [N]: the
    radial force on each crank's bearing pair, each needle bearing (crank i, disc j at
    2 i + j) and the main bearings; tau_in (S, L, A) [N*m]: the input torque without
    friction; q (S, L, A, n): the equilibria's unknowns (`EquivalentModel`); output_angle
    (S, L, A) [rad]: the output flange's (`EquivalentModel.output_angle`); converged
    (S, L, A).
    """

    tau_load: np.ndarray
    pin_force: np.ndarray
    pin_slide_arm: np.ndarray
    crank_seat_force: np.ndarray
    cam_force: np.ndarray
    main_force: np.ndarray
    tau_in: np.ndarray
    q: np.ndarray
    output_angle: np.ndarray
    converged: np.ndarray


def crank_turn_angles(design: RVDesign, points: int = AVERAGE_POINTS) -> np.ndarray:
    """(points,) input angles [rad] spread over one turn of the cranks relative to the carrier,
    the period of the bearings' loads (i/z_p input turns)."""
    points = integer("points", points, 1)
    return 2.0 * np.pi * design.ratio / design.z_p * np.arange(points) / points


def contact_loads(
    design: RVDesign,
    errors: ErrorSet | None,
    tau_load,
    theta_in,
    samples=None,
    zero_side: int = -1,
    progress=None,
) -> ContactLoads:
    """The frictionless equilibria of the reducers `samples` of `errors` (default all) at
    every (tau_load (L,), theta_in (A,)).

    A zero load is the no-load limit (docs/model.md section 5) approached from a resisting
    load (zero_side = -1, how a motor turns an unloaded reducer) or a driving one (+1).
    """
    errors = _checked_errors(design, errors)
    samples = np.arange(errors.samples) if samples is None else np.atleast_1d(samples)
    for s in samples:
        integer("sample", int(s), 0, errors.samples - 1)
    tau_load = np.atleast_1d(np.asarray(tau_load, dtype=float))
    theta_in = np.atleast_1d(np.asarray(theta_in, dtype=float))
    if tau_load.size:
        check_load("tau_load", tau_load[np.argmax(np.abs(tau_load))], design.rated_torque)
    S, L, A, n_c = samples.size, tau_load.size, theta_in.size, design.n_c
    pin = np.empty((S, L, A, 2, design.z_p))
    seat, cam = np.empty((S, L, A, n_c)), np.empty((S, L, A, 2 * n_c))
    main, tau_in = np.empty((S, L, A)), np.empty((S, L, A))
    ok = np.empty((S, L, A), dtype=bool)
    q = np.empty((S, L, A, len(dof_names(design.n_c))))
    angle = np.empty((S, L, A))
    arm = None
    zero_flank = -1 if zero_side > 0 else 1
    for flank in (1, -1):  # +1: the sun drives (a resisting load); -1: the load drives
        at_zero = (tau_load == 0.0) & (zero_flank == flank)
        loads = np.flatnonzero(((tau_load < 0.0) if flank == 1 else (tau_load > 0.0)) | at_zero)
        if loads.size == 0:
            continue
        model = EquivalentModel(design, theta_in, flank=flank)
        arm = model.pin_slide_arm
        k, t, a = (g.ravel() for g in np.meshgrid(np.arange(S), loads, np.arange(A), indexing="ij"))
        s = samples[k]
        eq = solve_pairs(
            model,
            errors,
            s,
            a,
            tau_load[t],
            progress=progress,
            no_load_probe=NO_LOAD_PROBE * design.rated_torque,
            zero_side=zero_side,
        )
        force = bearing_forces(model, errors, s, a, eq.q)  # (B, nb)
        pin[k, t, a] = eq.pin_force
        seat[k, t, a] = force[:, :n_c]
        cam[k, t, a] = force[:, n_c : 3 * n_c]
        main[k, t, a] = force[:, -1]
        tau_in[k, t, a] = -flank * design.sun_base_radius * eq.mesh_force.sum(axis=1)
        q[k, t, a] = eq.q
        angle[k, t, a] = model.output_angle(eq.q, tau_load[t])
        ok[k, t, a] = eq.converged
    if arm is None:
        arm = EquivalentModel(design, theta_in).pin_slide_arm
    return ContactLoads(tau_load, pin, arm, seat, cam, main, tau_in, q, angle, ok)


def coulomb_resistances(design: RVDesign, pin_force, cam_force, crank_seat_force, main_force, tau_in) -> dict:
    """{LOSS_NAMES but the seal: array} each Coulomb contact's friction, independent of how
    fast it slips, at the loads given (shapes of `ContactLoads` without the angle averaging):
    pins: the friction force of each pin (..., 2, z_p) [N], the smaller limit of its two
    contacts; each needle bearing (..., 2 n_c), each crank's tapered pair (..., n_c) and the
    main bearings (...): the load-proportional moment mu P d_m / 2 [N*m]; the meshes (...):
    mu H_V |tau_sun| [N*m], their loss over the sun's turn against the carrier."""
    d = design
    h_v = mesh_loss_factor(d.z_s, d.z_pl, d.pressure_angle)[0]
    return {
        "pins": min(d.pin_disc_friction, d.pin_groove_friction) * pin_force,
        "crank-disc needle bearings": 0.5 * d.needle_friction * d.needle_pitch_diameter * cam_force,
        "crank-carrier bearings": 0.5 * d.tapered_friction * d.tapered_pitch_diameter * crank_seat_force,
        "main bearings": 0.5 * d.main_bearing_friction * d.main_bearing_pitch_diameter * main_force,
        "sun-planet meshes": d.mesh_friction * h_v * np.abs(tau_in),
    }


def coulomb_torques(
    design: RVDesign, pin_force, pin_slide_arm, cam_force, crank_seat_force, main_force, tau_in
) -> dict:
    """{LOSS_NAMES but the seal: (...) [N*m]} the friction torque at the output of each kind
    of Coulomb contact (`coulomb_resistances` times each contact's slip per output turn:
    its sliding arm for a pin, z_p for the crank bearings, i - 1 for the meshes): the
    contact's loss is this torque times the output speed, whatever the speed."""
    r = coulomb_resistances(design, pin_force, cam_force, crank_seat_force, main_force, tau_in)
    return {
        "pins": (r["pins"] * pin_slide_arm).sum(axis=(-1, -2)),
        "crank-disc needle bearings": design.z_p * r["crank-disc needle bearings"].sum(axis=-1),
        "crank-carrier bearings": design.z_p * r["crank-carrier bearings"].sum(axis=-1),
        "main bearings": r["main bearings"],
        "sun-planet meshes": (design.ratio - 1.0) * r["sun-planet meshes"],
    }


def drag_moments(design: RVDesign, speed_rpm, temperature_C: float = REFERENCE_TEMPERATURE_C) -> dict:
    """{"crank-disc needle bearings", "crank-carrier bearings", "main bearings": array [N*m]}
    Palmgren's load-free moment of one needle bearing, of one crank's tapered pair (two
    bearings) and of the main bearings (two), each turning at `speed_rpm` against its
    outer part, in the lubricant at `temperature_C` [C] (`lubricant.viscosity_cSt`)."""
    d = design
    nu = viscosity_cSt(d, temperature_C)

    def drag(pitch_diameter):
        return bearing_drag_moment(d.bearing_drag_factor, nu, speed_rpm, pitch_diameter)

    return {
        "crank-disc needle bearings": drag(d.needle_pitch_diameter),
        "crank-carrier bearings": 2.0 * drag(d.tapered_pitch_diameter),
        "main bearings": 2.0 * drag(d.main_bearing_pitch_diameter),
    }


def load_free_torques(
    design: RVDesign, output_speed_rpm, temperature_C: float = REFERENCE_TEMPERATURE_C
) -> dict:
    """{"crank-disc needle bearings", "crank-carrier bearings", "main bearings",
    CHURNING_NAMES, "output seal", "input seal": (V,) [N*m]} the friction torque at the output
    of the bearings' drag, the churning and the seals at output speeds (V,) [rpm], the lubricant at
    `temperature_C` [C]: each bearing's Palmgren moment (`drag_moments`) times its speed
    over the output's (z_p for the crank bearings, 1 for the main bearings); the discs' and
    gears' churning power over the output speed (`churning.churning_torques`)."""
    d = design
    n_out = np.abs(np.atleast_1d(np.asarray(output_speed_rpm, dtype=float)))
    crank = drag_moments(d, d.z_p * n_out, temperature_C)
    seals = seal_torques(d)
    main = drag_moments(d, n_out, temperature_C)
    return {
        "crank-disc needle bearings": 2 * d.n_c * d.z_p * crank["crank-disc needle bearings"],
        "crank-carrier bearings": d.n_c * d.z_p * crank["crank-carrier bearings"],
        "main bearings": main["main bearings"],
        **churning_torques(d, n_out, temperature_C),
        # a seal's torque does not depend on the speed (`seals.py`); the input seal turns at
        # i x the output's speed: i x its torque at the output
        "output seal": np.full(n_out.shape, seals["output seal"]),
        "input seal": np.full(n_out.shape, d.ratio * seals["input seal"]),
    }


def drag_kinks(design: RVDesign, temperature_C: float = REFERENCE_TEMPERATURE_C) -> np.ndarray:
    """Output speeds [rad/s] where a bearing's drag leaves Palmgren's floor for his power law,
    nu n = 160^(3/2), nu at `temperature_C` [C] (the kinks of `load_free_torques`; none
    without a lubricant)."""
    nu = viscosity_cSt(design, temperature_C)
    if not nu > 0.0:
        return np.empty(0)
    ratios = np.array([design.z_p, 1.0])  # the crank bearings' speed, the main bearings'
    return DRAG_FLOOR**1.5 / (nu * ratios) * RPM


def contact_losses(
    design: RVDesign,
    loads: ContactLoads,
    output_speed_rpm,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
    breakaway: bool = False,
) -> dict:
    """{LOSS_NAMES: (V, S, L) power [W]} lost by each kind of contact at every output speed
    (V,) [rpm], reducer and load of `loads`, averaged over its angles, the lubricant at
    `temperature_C` [C]; each >= 0.  breakaway: the Coulomb contacts and the seals at
    `static_friction_factor` x their running friction, as they start from rest (`seals.py`)."""
    w = np.abs(np.atleast_1d(np.asarray(output_speed_rpm, dtype=float))) * RPM  # (V,)
    coulomb = {
        k: v.mean(axis=-1)
        for k, v in coulomb_torques(  # (S, L)
            design,
            loads.pin_force,
            loads.pin_slide_arm,
            loads.cam_force,
            loads.crank_seat_force,
            loads.main_force,
            loads.tau_in,
        ).items()
    }
    free = load_free_torques(design, w / RPM, temperature_C)  # (V,)
    if breakaway:  # the viscous drag and churning have no breakaway: they stay
        static = design.static_friction_factor
        coulomb = {k: static * v for k, v in coulomb.items()}
        free.update({k: static * free[k] for k in SEAL_NAMES})
    shape = (w.size,) + loads.main_force.shape[:-1]  # (V, S, L)
    out = {}
    for name in LOSS_NAMES:
        torque = np.zeros(shape)
        if name in coulomb:
            torque = torque + coulomb[name][None]
        if name in free:
            torque = torque + free[name][:, None, None]
        out[name] = torque * w[:, None, None]
    return out


def output_speeds(
    field: str, output_speed_rpm, design: RVDesign, where: str = ""
) -> tuple[np.ndarray, tuple[str, ...]]:
    """(speeds (V,) [rpm], warnings) of output speeds [rpm] given under `field`: at least one,
    each finite and > 0 and within `limits.SPEED_FACTOR` x the design's allowable output
    speed (an InputError naming `field` otherwise); a warning text for each above the
    allowable speed, where the friction coefficients have no rating behind them."""
    speeds = np.atleast_1d(np.asarray(output_speed_rpm, dtype=float))
    if speeds.size == 0:
        raise InputError(field, "", "must list at least one value", where)
    warnings = []
    for v in speeds:
        if not finite_number(field, float(v), where) > 0.0:
            raise InputError(field, float(v), "must be positive (output speeds in rpm)", where)
        note = check_speed(field, float(v), float(v) * RPM, design, where)
        if note:
            warnings.append(note)
    return speeds, tuple(warnings)


def operating_losses(
    design: RVDesign,
    errors: ErrorSet | None,
    load_Nm: float,
    output_speed_rpm: float,
    points: int = AVERAGE_POINTS,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
):
    """(efficiency (S,), no-load running torque at the input (S,) [N*m]) of every reducer of
    `errors` at one operating point: a resisting load [N*m] > 0 at an output speed [rpm]
    > 0, forward (the motor drives), the lubricant at `temperature_C` [C]; the tolerance
    studies' metrics.  A speed beyond `limits.SPEED_FACTOR` x the allowable output speed
    raises InputError; the warning above 1 x is the caller's to give (`limits.check_speed`)."""
    temperature_C = check_temperature(temperature_C)
    load = finite_number("load_Nm", load_Nm)
    speed = finite_number("output_speed_rpm", output_speed_rpm)
    if not speed > 0.0:
        raise InputError("output_speed_rpm", speed, "must be a positive output speed [rpm]")
    check_speed("output_speed_rpm", speed, speed * RPM, design)
    loads = contact_loads(design, errors, [0.0, -load], crank_turn_angles(design, points))
    lost = sum(contact_losses(design, loads, [speed], temperature_C).values())[0]  # (S, 2)
    w = speed * RPM
    efficiency = load * w / (load * w + lost[:, 1]) if load > 0.0 else np.zeros(lost.shape[0])
    return efficiency, lost[:, 0] / (design.ratio * w), loads.converged.all(axis=(1, 2))


@dataclass(frozen=True)
class EfficiencyMap:
    """Efficiency of one reducer over output speeds (V,) [rpm] and resisting loads (L,) [N*m].

    temperature_C [C] and lubricant_viscosity_cSt [mm^2/s]: the lubricant's temperature and
    its viscosity there (`lubricant.viscosity_cSt`);
    efficiency, backdriving_efficiency, input_torque_Nm (the motor's torque, forward),
    loss_W (forward, total): (V, L); losses: {LOSS_NAMES: (V, L) W}, forward;
    no_load_running_torque_Nm (V,): at the input, turning the unloaded reducer;
    starting_torque_input_Nm: its limit at standstill, the Coulomb contacts and the seals
    breaking away (`contact_losses`, breakaway); backdriving_torque_output_Nm: the
    output torque that starts the unloaded reducer turning the motor.  A backdriving
    efficiency <= 0 means the load cannot drive the motor there (it is reported as 0).
    warnings: texts for the report (speeds above the allowable output speed, loads above
    the momentary maximum class: `rvfmu.core.reducer.limits`).
    """

    design: RVDesign
    output_speed_rpm: np.ndarray
    load_Nm: np.ndarray
    efficiency: np.ndarray
    backdriving_efficiency: np.ndarray
    input_torque_Nm: np.ndarray
    loss_W: np.ndarray
    losses: dict
    no_load_running_torque_Nm: np.ndarray
    starting_torque_input_Nm: float
    backdriving_torque_output_Nm: float
    converged: bool
    warnings: tuple[str, ...] = ()
    temperature_C: float = REFERENCE_TEMPERATURE_C
    lubricant_viscosity_cSt: float = math.nan


STANDSTILL_RPM = 1e-9  # a speed at which every loss is its limit at standstill


def efficiency_map(
    design: RVDesign,
    errors: ErrorSet | None = None,
    output_speed_rpm=None,
    load_Nm=None,
    points: int = AVERAGE_POINTS,
    sample: int = 0,
    progress=None,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
) -> EfficiencyMap:
    """Forward and backdriving efficiency, input torque and losses at every output speed
    [rpm] and resisting load [N*m] (defaults: those of 5 to 60 rpm within the design's
    allowable output speed; 25 % to 100 % of rated torque),
    the no-load running torque over the speeds and the starting and backdriving torques,
    each loss averaged over `points` angles of one crank turn, the lubricant at
    `temperature_C` [C] (default 40, its grade's temperature).  progress(count): optional,
    called as the (1 + 2 loads) x points equilibria are solved."""
    temperature_C = check_temperature(temperature_C)
    if output_speed_rpm is None:  # the chart's speeds the design is rated for
        output_speed_rpm = [
            v for v in DEFAULT_SPEEDS_RPM if v * RPM <= design.allowable_output_speed * (1.0 + 1e-12)
        ]
    speeds = output_speeds("speeds", output_speed_rpm, design)[0]
    loads = np.atleast_1d(
        np.asarray(
            design.rated_torque * np.array(DEFAULT_LOAD_FRACTIONS) if load_Nm is None else load_Nm,
            dtype=float,
        )
    )
    if loads.size == 0:
        raise InputError("loads", "", "must list at least one value")
    for v in loads:
        if not finite_number("loads", float(v)) > 0.0:
            raise InputError("loads", float(v), "must be positive (resisting output torques in N*m)")
    note = check_load("loads", float(loads.max()), design.rated_torque)
    theta_in = crank_turn_angles(design, points)
    forward = contact_loads(
        design, errors, np.concatenate([[0.0], -loads]), theta_in, [sample], progress=progress
    )
    backward = contact_loads(design, errors, loads, theta_in, [sample], progress=progress)
    result = efficiency_from_loads(design, forward, speeds, loads, backward, temperature_C)
    return replace(result, warnings=result.warnings + ((note,) if note else ()))


def efficiency_from_loads(
    design: RVDesign,
    forward: ContactLoads,
    output_speed_rpm,
    load_Nm,
    backward: ContactLoads | None = None,
    temperature_C: float = REFERENCE_TEMPERATURE_C,
) -> EfficiencyMap:
    """`efficiency_map` from its contact loads: `forward` (one reducer) at the torques
    [0, -load_Nm...], `backward` at +load_Nm (None: the backdriving efficiency is nan), the
    lubricant at `temperature_C` [C].  The loads do not depend on the friction fields (nor
    on the temperature), so a calibration of those solves them once.  The speeds are
    checked as `output_speeds` checks them (field "speeds")."""
    temperature_C = check_temperature(temperature_C)
    speeds, warnings = output_speeds("speeds", output_speed_rpm, design)
    loads = np.atleast_1d(np.asarray(load_Nm, dtype=float))
    lost = {k: v[:, 0] for k, v in contact_losses(design, forward, speeds, temperature_C).items()}
    total = sum(lost.values())  # (V, 1 + L)
    w = speeds[:, None] * RPM
    p_out = loads[None] * w
    p_in = p_out + total[:, 1:]
    if backward is None:
        back = np.full(p_out.shape, np.nan)
    else:
        total_back = sum(contact_losses(design, backward, speeds, temperature_C).values())[:, 0]  # (V, L)
        back = np.maximum(1.0 - total_back / p_out, 0.0)
    standstill = sum(
        contact_losses(design, forward, [STANDSTILL_RPM], temperature_C, breakaway=True).values()
    )[0, 0, 0]
    start = standstill / (design.ratio * STANDSTILL_RPM * RPM)
    return EfficiencyMap(
        design=design,
        output_speed_rpm=speeds,
        load_Nm=loads,
        efficiency=p_out / p_in,
        backdriving_efficiency=back,
        input_torque_Nm=p_in / (design.ratio * w),
        loss_W=total[:, 1:],
        losses={k: v[:, 1:] for k, v in lost.items()},
        no_load_running_torque_Nm=total[:, 0] / (design.ratio * speeds * RPM),
        starting_torque_input_Nm=float(start),
        backdriving_torque_output_Nm=float(design.ratio * start),
        converged=bool(forward.converged.all() and (backward is None or backward.converged.all())),
        warnings=warnings,
        temperature_C=temperature_C,
        lubricant_viscosity_cSt=viscosity_cSt(design, temperature_C),
    )


def step_efficiency(p_out: float, p_loss: float) -> float:
    """The efficiency of a step from the power the output gives the load p_out [W] and the
    power dissipated p_loss [W] (means over the step): forward (p_out > 0) p_out over
    p_out + p_loss, backdriving (the load drives, p_out < 0) what the loss leaves of the
    load's power, at least 0; 0 where no power passes.  The kinetic and elastic energy the
    step stores or gives back counts for neither, so it stays within [0, 1]."""
    if p_out > 0.0:
        return p_out / (p_out + p_loss)
    if p_out < 0.0:
        return max(-p_out - p_loss, 0.0) / -p_out
    return 0.0
