"""The presets against the catalogue figures of their frames, and their calibration.

The question: does a preset behave like the reducer whose frame it models?  A
catalogue gives, per frame, the rated torque, the torsional rigidity and an
upper bound on the lost motion (docs/model.md section 5 defines both as the
catalogue does); our presets are built from the seeds' geometry and
stiffnesses estimated by formula, and those estimates leave out whatever is
soft outside the contacts and bearings the model has (the output flange and
carrier body in torsion, the housing and its fixing, the crank's twist), and
guess the disc's modification pair.  So a preset comes out several times
stiffer than its frame, with more lost motion.

How the gap is closed, and why so:

- Two values, two figures.  The torsional rigidity identifies a torsional
  stiffness in series with the output (`calibration_values.OUTPUT_STIFFNESS`: what the
  model does not have, lumped where a catalogue test measures it); the lost
  motion identifies the size of the modification pair
  (`calibration_values.MODIFICATION_SCALE`: the tip and root clearance that sets the
  backlash), which the seeds give only partly.  Each figure moves mostly one
  value, so the pair is identifiable; nothing else is fitted.
- The lost motion is aimed at `lost_motion_aim` x the catalogue's bound (the
  catalogue file says why): a typical reducer of the frame, inside the bound.
- The fit is `rvfmu.bench.calibration_fit` (differential evolution, then least squares)
  on the catalogue target, from the estimate: the preset file's `[calibration]`
  table records the fitted values, the figures before and after and how it was
  made; `preset(name)` applies it, `preset(name + "-estimate")` does not.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path

from ..core.base.checks import InputError
from ..core.reducer.design import ESTIMATE_SUFFIX, PRESET_NAMES, RVDesign, in_file_units, preset, preset_file
from ..core.statics.quasistatic import Windup, windup
from .calibration_data import Catalogue, DataSet
from .calibration_fit import Calibration, calibrate
from .calibration_problem import problem
from .calibration_values import MODIFICATION_SCALE, OUTPUT_STIFFNESS

CATALOGUE_FILE = "catalogue.toml"
# A calibrated preset matches its frame's rigidity when within this share of it.
RIGIDITY_TOLERANCE = 0.02
CALIBRATION_FIT = (OUTPUT_STIFFNESS, MODIFICATION_SCALE)


@dataclass(frozen=True)
class Frame:
    """A catalogue frame: rated torque [N*m], torsional rigidity [N*m/arcmin] (typical),
    lost motion and backlash bounds [arcmin], the torque of the lost-motion test [N*m]."""

    name: str
    rated_torque_Nm: float
    torsional_rigidity_Nm_per_arcmin: float
    lost_motion_max_arcmin: float
    lost_motion_torque_Nm: float
    backlash_max_arcmin: float
    source: str


def _catalogue_values() -> dict:
    text = resources.files("rvfmu.core.reducer.presets").joinpath(CATALOGUE_FILE).read_text()
    return tomllib.loads(text)


def source() -> str:
    """Where the catalogue figures come from, as the catalogue file states it."""
    return str(_catalogue_values()["source"])


def lost_motion_aim() -> float:
    """The share of the catalogue's lost-motion bound that a calibration aims at."""
    return float(_catalogue_values()["lost_motion_aim"])


def frame_of(name: str) -> Frame:
    """The catalogue frame of preset `name` (calibrated or estimate)."""
    base = str(name).removesuffix(ESTIMATE_SUFFIX)
    values = _catalogue_values()
    if base not in values["presets"]:
        raise InputError(
            "preset", name, f"has no catalogue frame; presets with one: {', '.join(values['presets'])}"
        )
    frame = values["presets"][base]
    return Frame(frame, source=source(), **values["frames"][frame])


def target(frame: Frame) -> Catalogue:
    """What a preset of `frame` is calibrated to: its rigidity, and its lost-motion bound x
    the aim, at its rated torque."""
    return Catalogue(
        torsional_rigidity_Nm_per_arcmin=frame.torsional_rigidity_Nm_per_arcmin,
        lost_motion_arcmin=lost_motion_aim() * frame.lost_motion_max_arcmin,
        rated_torque_Nm=frame.rated_torque_Nm,
    )


@dataclass(frozen=True)
class Figures:
    """A design's catalogue figures by the catalogue test (docs/model.md section 5)."""

    torsional_rigidity_Nm_per_arcmin: float
    lost_motion_arcmin: float
    converged: bool


def figures(design: RVDesign) -> Figures:
    """Torsional rigidity and lost motion of `design` without errors (`quasistatic.windup`)."""
    return figures_of(windup(design))


def figures_of(w: Windup) -> Figures:
    """The catalogue figures of a windup test (its first sample)."""
    return Figures(
        float(w.torsional_rigidity_Nm_per_arcmin()[0]), float(w.lost_motion_arcmin()[0]), bool(w.converged[0])
    )


@dataclass(frozen=True)
class PresetAgainstCatalogue:
    """One preset: its frame, its figures before (estimate) and after calibration, and
    whether the calibrated ones fall within the catalogue's; windups: the two windup tests
    (estimate, calibrated) they come from."""

    name: str
    frame: Frame
    rated_torque_Nm: float
    estimate: Figures
    calibrated: Figures
    calibration: dict | None
    windups: tuple = ()

    @property
    def rigidity_within(self) -> bool:
        c = self.frame.torsional_rigidity_Nm_per_arcmin
        return abs(self.calibrated.torsional_rigidity_Nm_per_arcmin - c) <= RIGIDITY_TOLERANCE * c

    @property
    def lost_motion_within(self) -> bool:
        return self.calibrated.lost_motion_arcmin <= self.frame.lost_motion_max_arcmin


def against_catalogue(names=PRESET_NAMES) -> list[PresetAgainstCatalogue]:
    """Every preset in `names` (base names) against its frame."""
    rows = []
    for name in names:
        tests = (windup(preset(name + ESTIMATE_SUFFIX)), windup(preset(name)))
        rows.append(
            PresetAgainstCatalogue(
                name,
                frame_of(name),
                tests[1].design.rated_torque,
                figures_of(tests[0]),
                figures_of(tests[1]),
                preset_file(name).get("calibration"),
                tests,
            )
        )
    return rows


def calibrate_preset(
    name: str, maxiter: int | None = None, popsize: int | None = None, progress=None
) -> Calibration:
    """Fit CALIBRATION_FIT of preset `name`'s estimate to its frame's catalogue `target`."""
    if name not in PRESET_NAMES:
        raise InputError("preset", name, f"must be one of {', '.join(PRESET_NAMES)}")
    design = preset(name + ESTIMATE_SUFFIX)
    frame = frame_of(name)
    data = DataSet(frame.name, catalogue=target(frame))
    options = {k: v for k, v in (("maxiter", maxiter), ("popsize", popsize)) if v is not None}
    return calibrate(problem(design, [data], CALIBRATION_FIT, "catalogue"), progress=progress, **options)


def calibration_table(cal: Calibration, frame: Frame, command: str) -> str:
    """The `[calibration]` TOML table of a preset file: what was fitted to what, the figures
    before and after, and `[calibration.fields]`, the design keys that the preset's name sets
    over the estimate's."""
    before, after = cal.before[0], cal.after[0]
    fields = cal.problem.fields_at(cal.values)
    try:
        version = metadata.version("rvte")
    except metadata.PackageNotFoundError:
        version = "not installed"
    lines = [
        "",
        "# Calibration against the catalogue figures of the frame (rvfmu/bench/catalogue.py):",
        f'# written by `{command}`.  `preset("{cal.problem.design.name.removesuffix(ESTIMATE_SUFFIX)}")` '
        "applies [calibration.fields]",
        f'# over the values above; "{cal.problem.design.name}" is the preset without them.',
        "[calibration]",
        f'frame = "{frame.name}"',
        f"source = {json.dumps(frame.source)}",
        f"catalogue_torsional_rigidity_Nm_per_arcmin = {frame.torsional_rigidity_Nm_per_arcmin!r}",
        f"catalogue_lost_motion_max_arcmin = {frame.lost_motion_max_arcmin!r}",
        f"target_lost_motion_arcmin = {cal.problem.datasets[0].catalogue.lost_motion_arcmin!r}",
        f"estimate_torsional_rigidity_Nm_per_arcmin = {float(before[0]):.6g}",
        f"estimate_lost_motion_arcmin = {float(before[1]):.6g}",
        f"calibrated_torsional_rigidity_Nm_per_arcmin = {float(after[0]):.6g}",
        f"calibrated_lost_motion_arcmin = {float(after[1]):.6g}",
    ]
    for p, v in zip(cal.problem.parameters, cal.values):
        lines.append(f"{p.name} = {float(v):.6g}    # {p.unit}")
    lines += [
        f'fit = "differential_evolution, then least_squares: {cal.evaluations} model evaluations"',
        f'rvte = "{version}"',
        "",
        "[calibration.fields]",
    ]
    lines += [f"{key} = {value:.6g}" for key, value in in_file_units(fields).items()]
    return "\n".join(lines) + "\n"


def write_calibration(path: str | Path, table: str) -> None:
    """Replace the `[calibration]` tables of the preset file at `path` (or append them)."""
    path = Path(path)
    text = path.read_text()
    marker = "\n# Calibration against the catalogue"
    head = text.split(marker, 1)[0].rstrip("\n") + "\n"
    new = head + table
    values = tomllib.loads(new)  # the file must stay a readable preset
    if not math.isfinite(sum(values["calibration"]["fields"].values())):
        raise ValueError(f"{path}: calibration fields are not finite")
    path.write_text(new)


__all__ = [
    "Frame",
    "Figures",
    "PresetAgainstCatalogue",
    "frame_of",
    "target",
    "figures",
    "figures_of",
    "against_catalogue",
    "calibrate_preset",
    "calibration_table",
    "write_calibration",
    "lost_motion_aim",
    "source",
    "RIGIDITY_TOLERANCE",
    "CALIBRATION_FIT",
]
