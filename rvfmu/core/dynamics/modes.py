"""Natural frequencies and mode shapes of the dynamic model, and the lines of a Campbell diagram.

The question: at which frequencies does the reducer resonate, and which part
moves in each mode, so that one can tell whether an excitation (crank
rotation, pin passing, stage-1 mesh; docs/model.md section 7) runs into one?

`modes` linearises the dynamic model (`rvfmu/core/dynamics/dynamic.py`) at its loaded
static equilibrium at one input angle: the input shaft holds the sun's
rotation through its torsional spring, the load acts on the carrier, and the
contacts that are closed there (pins, bearings outside their clearance) give
the tangent stiffness K.  The undamped modes solve

    K phi = w^2 M phi,        M the model's diagonal mass matrix,

with K symmetrised.  The unknowns are those of the dynamic model
(docs/model.md section 7): translations in m with masses in kg, rotations as
arc length at R_p with the inertias divided by R_p^2, so that phi^T M phi is
twice the kinetic energy per unit modal velocity whatever the unknown.

The frequencies depend on the load and the input angle only through the
contact state: which pins touch (and along which normals, set by the angle)
and how far each bearing with clearance has taken it up.  They do not depend
on the speed: the model is planar with no gyroscopic terms, its elements are
linear in the small displacements and the varying mesh stiffness is replaced
by its mean (`mesh = "constant"`).  The one way speed enters is the
centripetal load of the discs and cranks (d'Alembert forces of a few N at
1600 rpm), which can shift a contact state near zero load; these modes are
those of the reducer at rest.  A Campbell diagram therefore draws them as
horizontal lines against the excitation lines of `campbell`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..base.checks import InputError, finite_number
from ..reducer.design import RVDesign
from ..reducer.errors import ErrorSet, zero_errors
from ..reducer.limits import check_load
from .dynamic import DynamicModel, at_rest
from .excitations import Excitations
from .newmark import static_start

# Resisting probe torque at zero load, x rated torque (0.41 N*m on an RV-40E): enough to close
# the pin contacts on the resisting side, far too small to change their stiffness.
MODES_NO_LOAD_PROBE = 1e-3


@dataclass(frozen=True, eq=False)
class Modes:
    """Undamped modes of one reducer linearised at its static equilibrium.

    frequencies_hz: (N,) ascending [Hz]; shapes: (n, N) mode shapes, column k of
    mode k, mass-normalised (shapes.T @ diag(mass) @ shapes = I) in the dynamic
    model's unknowns (rotations as arc length at R_p); names: (n,) the unknowns;
    mass: (n,) the diagonal mass matrix [kg; rotations inertia / R_p^2];
    tau_load [N*m] and theta_in [rad]: where the model was linearised;
    dropped: how many rigid-body modes (below `dynamic.FLOATING_HZ`) were dropped;
    damping_ratios: (N,) each mode's ratio under the dynamic model's damping C at that
    equilibrium, phi^T C phi / (2 w) (`DynamicModel.set_modal_damping`).
    """

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    names: tuple
    mass: np.ndarray
    tau_load: float = 0.0
    theta_in: float = 0.0
    dropped: int = 0
    damping_ratios: np.ndarray | None = None

    @property
    def groups(self) -> dict:
        """Part label -> indices of its unknowns, in the order of the unknowns:
        "sun translation", "sun torsion", "crank i translation", "crank i torsion",
        "disc j translation", "disc j torsion", "carrier translation", "carrier torsion"."""
        out: dict = {}
        for k, name in enumerate(self.names):
            body, direction = name.rsplit("_", 1)
            label = f"{_body_label(body)} {'torsion' if direction == 'rot' else 'translation'}"
            out.setdefault(label, []).append(k)
        return out

    def energy_shares(self, k: int) -> dict:
        """Part label -> its fraction of mode k's kinetic energy (the fractions sum to 1)."""
        phi = self.shapes[:, k]
        energy = self.mass * phi * phi
        total = energy.sum()
        return {label: float(energy[idx].sum() / total) for label, idx in self.groups.items()}

    def dominant(self, k: int, count: int = 2) -> list:
        """The `count` parts with the largest share of mode k's kinetic energy:
        [(part label, share)], largest first, e.g. [("carrier torsion", 0.74), ...]."""
        shares = sorted(self.energy_shares(k).items(), key=lambda item: -item[1])
        return shares[:count]

    def table(self, count: int | None = None, parts: int = 2) -> list:
        """[(mode, frequency [Hz], dominant parts)] of the lowest `count` modes (all by default)."""
        last = self.frequencies_hz.size if count is None else min(count, self.frequencies_hz.size)
        return [(k, float(self.frequencies_hz[k]), self.dominant(k, parts)) for k in range(last)]


def _body_label(body: str) -> str:
    """The label of a body in the unknowns' names: crank0 -> "crank 0", sun -> "sun"."""
    stem = body.rstrip("0123456789")
    return body if stem == body else f"{stem} {body[len(stem) :]}"


def _one_reducer(design: RVDesign, errors: ErrorSet | None) -> ErrorSet:
    errors = zero_errors(design) if errors is None else errors.check(design)
    if errors.samples != 1:
        raise InputError("errors", errors.samples, "the modes are those of one reducer")
    return errors


def modes(
    design: RVDesign, errors: ErrorSet | None = None, load: float = 0.0, theta_in: float = 0.0
) -> Modes:
    """Natural frequencies and mass-normalised mode shapes of one reducer.

    The dynamic model (contact "linear", mesh "constant": the mean mesh stiffness)
    is linearised at its static equilibrium at input angle `theta_in` [rad] under a
    resisting output torque `load` [N*m] (tau_load = -load; a negative load drives).
    A zero load uses a small resisting probe instead, MODES_NO_LOAD_PROBE x the
    rated torque (0.41 N*m on an RV-40E): at exactly zero load the pin contacts
    of a modified profile are open or just touching, and an open contact has no
    stiffness; the probe closes those of the resisting side, as the no-load
    limit of docs/model.md section 5 does, without deflecting them noticeably.

    The equilibrium is found from the quasi-static solution (the sun held at
    theta_in), refined with the input shaft's twist; the tangent stiffness K
    there (zero velocity) with the diagonal mass matrix M gives K phi = w^2 M phi
    (scipy.linalg.eigh, K symmetrised); each mode's damping ratio is that of the
    dynamic model's damping there (modal: the design's ratio).  The input shaft's torsional spring
    grounds the chain, so with the pins in contact there is no rigid-body mode;
    a part inside a bearing clearance, though, is held by no spring in the
    linearisation and would float: such zero-frequency modes (below `dynamic.FLOATING_HZ`)
    are dropped and counted in `Modes.dropped`.
    """
    errors = _one_reducer(design, errors)
    load = finite_number("load", load)
    check_load("load", load, design.rated_torque)
    theta_in = finite_number("theta_in", theta_in)
    tau_load = -load if load != 0.0 else -MODES_NO_LOAD_PROBE * design.rated_torque
    flank = 1 if tau_load <= 0 else -1
    model = DynamicModel(design, errors, contact="linear", mesh="constant", flank=flank, friction=False)
    model.prepare(at_rest(theta_in))
    q = static_start(model, tau_load, theta_in)
    model.set_modal_damping(q)  # the eigenproblem, and the damping it sets
    _, _, C = model.forces(0, q, np.zeros(model.n))
    shapes, frequencies = model.modal_shapes, model.modal_frequencies / (2.0 * math.pi)
    ratios = np.einsum("ik,ij,jk->k", shapes, C, shapes) / (4.0 * math.pi * frequencies)
    return Modes(
        frequencies,
        shapes,
        tuple(model.names),
        model.mass.copy(),
        float(tau_load),
        theta_in,
        model.floating,
        ratios,
    )


def campbell(design: RVDesign, errors: ErrorSet | None, load: float, speeds_rpm):
    """The excitation lines of a Campbell diagram: (speeds [rpm] (S,), {name: (S,) [Hz]}).

    Names: "input rotation", "output rotation", "crank rotation", "pin passing",
    "stage-1 mesh" (docs/model.md section 7, `Excitations`).  The lines are
    kinematic: errors and load do not move them (they are checked, as the
    diagram's modes are taken with them).  The natural frequencies of this model
    do not depend on the speed (no gyroscopic terms, linear elements, mean mesh
    stiffness; see the module docstring), so `modes(design, errors, load)` gives
    the horizontal lines to draw against these.
    """
    _one_reducer(design, errors)
    check_load("load", finite_number("load", load), design.rated_torque)
    try:
        speeds = np.atleast_1d(np.asarray(speeds_rpm, dtype=float))
    except (TypeError, ValueError):
        speeds = np.array([np.nan])
    if speeds.ndim != 1 or speeds.size == 0 or not np.all(np.isfinite(speeds)) or np.any(speeds < 0):
        raise InputError("speeds_rpm", speeds_rpm, "must be finite input speeds >= 0 [rpm]")
    lines = [Excitations.at(design, s) for s in speeds]
    excitations = {
        "input rotation": np.array([x.input for x in lines]),
        "output rotation": np.array([x.output for x in lines]),
        "crank rotation": np.array([x.crank for x in lines]),
        "pin passing": np.array([x.pin_passing for x in lines]),
        "stage-1 mesh": np.array([x.mesh for x in lines]),
    }
    return speeds, excitations
