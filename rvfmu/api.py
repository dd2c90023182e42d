"""One public function per job; the `rvte` CLI is a thin layer over these.

Each function takes file paths or preset names and plain numbers, checks the
output paths before any work (`rvfmu.outputs`), runs the core, writes the
files it was asked for and returns a small record.  Each job lives in its own
module of `rvfmu.jobs` with its report; this module is their public face.
"""

from __future__ import annotations

from .core.statics.quasistatic import default_points
from .jobs.calibrate import CalibrateReport, calibrate
from .jobs.common import (
    NothingToWrite,
    read_columns,
    resolve_design,
    resolve_errors,
    write_columns,
    write_te_csv,
)
from .jobs.compare import BY_ORDER_SHOWN, CompareReport, compare
from .jobs.efficiency import EfficiencyReport, efficiency
from .jobs.hysteresis import HysteresisReport, hysteresis
from .jobs.measure import ANGLE_ROLES, ANGLE_UNITS, MeasureReport, measure
from .jobs.modes import ModesReport, modes
from .jobs.presets import CatalogueReport, PresetInfo, errors_template, presets, presets_catalogue
from .jobs.profile import profile
from .jobs.simulate import SimulationReport, simulate
from .jobs.stiffness import StiffnessReport, stiffness
from .jobs.te import HARMONICS_SHOWN, TEReport, te

__all__ = [
    "te",
    "TEReport",
    "simulate",
    "SimulationReport",
    "modes",
    "ModesReport",
    "presets",
    "PresetInfo",
    "presets_catalogue",
    "CatalogueReport",
    "profile",
    "errors_template",
    "measure",
    "MeasureReport",
    "compare",
    "CompareReport",
    "calibrate",
    "CalibrateReport",
    "stiffness",
    "StiffnessReport",
    "efficiency",
    "EfficiencyReport",
    "hysteresis",
    "HysteresisReport",
    "default_points",
    "write_te_csv",
    "write_columns",
    "read_columns",
    "resolve_design",
    "resolve_errors",
    "NothingToWrite",
    "ANGLE_UNITS",
    "ANGLE_ROLES",
    "BY_ORDER_SHOWN",
    "HARMONICS_SHOWN",
]
