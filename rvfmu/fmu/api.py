"""The FMU jobs as Python functions; `rvte fmu ...` wraps them."""

from __future__ import annotations

import zipfile
from pathlib import Path

from ..api import resolve_design, resolve_errors
from ..core.checks import InputError


def fmu_build(design, errors=None, output="RVReducer.fmu", points=None, progress=None) -> Path:
    """Build the reducer FMU; returns its path.  progress(total, done): optional."""
    from ..api import ProgressCounter
    from ..core.quasistatic import default_points
    from ..core.te_map import TORQUE_FRACTIONS
    from .build import build_fmu

    design = resolve_design(design)
    points = default_points(design) if points is None else points
    total = 2 * len(TORQUE_FRACTIONS) * points
    counter = None if progress is None else ProgressCounter(total, progress)
    return build_fmu(design, resolve_errors(design, errors), output, points=points, progress=counter)


def fmu_info(path) -> str:
    """A table of the FMU's variables: name, causality, variability, start, unit, description."""
    from fmpy import read_model_description

    path = Path(path)
    if not path.is_file() or not zipfile.is_zipfile(path):
        raise InputError("fmu", str(path), "must be an FMU file (a zip archive)")
    md = read_model_description(str(path))
    lines = [f"{md.modelName}  FMI {md.fmiVersion} co-simulation  ({md.generationTool})",
             f"{'name':<24} {'causality':<10} {'variability':<12} {'start':>12}  {'unit':<7} description"]
    for v in md.modelVariables:
        start = "" if v.start is None else str(v.start)
        lines.append(f"{v.name:<24} {v.causality:<10} {v.variability:<12} {start:>12}  "
                     f"{v.unit or '':<7} {v.description or ''}")
    if md.defaultExperiment is not None:
        e = md.defaultExperiment
        lines.append(f"default experiment: start {e.startTime}, stop {e.stopTime}, step {e.stepSize}")
    return "\n".join(lines)
