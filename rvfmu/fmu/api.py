"""The FMU jobs as Python functions; `rvte fmu ...` wraps them."""

from __future__ import annotations

import zipfile
from pathlib import Path

from ..api import resolve_design, resolve_errors
from ..core.base.checks import InputError
from ..outputs import output_file
from ..progress import counter as progress_counter


def fmu_build(
    design,
    errors=None,
    output="RVReducer.fmu",
    points=None,
    progress=None,
    native: bool = False,
    fmi_version=2,
) -> Path:
    """Build the reducer FMU; returns its path.  progress(total, done): optional.

    design: a preset name, a design file or an RVDesign; errors: an error file, an
    ErrorSet or None (no errors).  The output path must end in .fmu and be
    writable (an existing file is replaced, as every output of rvte): both are
    checked before anything is built; file and preset names are recorded in
    the FMU for `fmu_info`.  native: the FMU of compiled C that needs no Python
    (`rvfmu.fmu.native`: the quasi-static model, no parameters) instead of the
    pythonfmu one.  fmi_version: 2 or 3 (as a number or its text); 3 only with
    native (pythonfmu makes FMI 2.0 FMUs only).
    """
    from ..core.statics.quasistatic import default_points
    from ..core.steppers.te_map import TORQUE_FRACTIONS

    fmi_version = check_fmi_version(fmi_version, native)
    if native:
        from functools import partial

        from .native import build_native_fmu

        build_fmu = partial(build_native_fmu, fmi_version=fmi_version)
    else:
        from .build import build_fmu

    output = fmu_output(output)
    points = default_points(resolve_design(design)) if points is None else points
    total = 2 * len(TORQUE_FRACTIONS) * points
    sources = {
        "design": design if isinstance(design, (str, Path)) else None,
        "errors": errors if isinstance(errors, (str, Path)) else None,
    }
    design = resolve_design(design)
    return build_fmu(
        design,
        resolve_errors(design, errors),
        output,
        points=points,
        progress=progress_counter(total, progress),
        sources=sources,
    )


FMI_VERSIONS = (2, 3)


def fmu_output(output) -> Path:
    """`output` as a Path if it ends in .fmu and can be written, else InputError naming
    `output` (`rvte fmu build -o`): an FMU is a zip whose importers look for the .fmu suffix,
    and writing x.fmu for x.zip would put the file where the user does not look."""
    if output is None or str(output) == "" or Path(output).suffix.lower() != ".fmu":
        raise InputError(
            "output",
            None if output is None else str(output),
            "must end in .fmu (the FMU file to write, -o/--output)",
        )
    return output_file("output", output)


def check_fmi_version(fmi_version, native: bool) -> int:
    """The FMI version as 2 or 3; InputError for anything else, and for 3 without native."""
    text = str(fmi_version).strip()
    if text not in {str(v) for v in FMI_VERSIONS} | {f"{v}.0" for v in FMI_VERSIONS}:
        raise InputError("fmi_version", fmi_version, "must be 2 or 3 (FMI 2.0 or FMI 3.0)")
    version = int(float(text))
    if version == 3 and not native:
        raise InputError(
            "fmi_version",
            fmi_version,
            "FMI 3.0 needs the native FMU (--native): the pythonfmu FMU is FMI 2.0 only",
        )
    return version


def fmu_info(path) -> str:
    """The FMU's bundled design and errors, then a table of its variables: name,
    causality, variability, start, unit, description."""
    from fmpy import read_model_description

    path = Path(path)
    if not path.is_file() or not zipfile.is_zipfile(path):
        raise InputError("fmu", str(path), "must be an FMU file (a zip archive)")
    md = read_model_description(str(path))
    lines = [
        f"{md.modelName}  FMI {md.fmiVersion} co-simulation  ({md.generationTool})",
        *_bundled(path),
        f"{'name':<24} {'causality':<10} {'variability':<12} {'start':>12}  {'unit':<7} description",
    ]
    for v in md.modelVariables:
        start = "" if v.start is None else str(v.start)
        lines.append(
            f"{v.name:<24} {v.causality:<10} {v.variability:<12} {start:>12}  "
            f"{v.unit or '':<7} {v.description or ''}"
        )
    if md.defaultExperiment is not None:
        e = md.defaultExperiment
        lines.append(f"default experiment: start {e.startTime}, stop {e.stopTime}, step {e.stepSize}")
    return "\n".join(lines)


def _bundled(path: Path) -> list[str]:
    """Lines naming the design and the error set the FMU carries (from its resources)."""
    import tomllib

    from .build import SOURCE_PREFIX
    from .slave import BUNDLED_DESIGN, BUNDLED_ERRORS

    lines = []
    with zipfile.ZipFile(path) as archive:
        names = set(archive.namelist())
        for label, name in (("design", BUNDLED_DESIGN), ("errors", BUNDLED_ERRORS)):
            member = f"resources/{name}"
            if member not in names:
                lines.append(f"{label:<8} (none bundled)")
                continue
            text = archive.read(member).decode()
            first = text.splitlines()[0] if text else ""
            source = first[len(SOURCE_PREFIX) :] if first.startswith(SOURCE_PREFIX) else ""
            values = tomllib.loads(text)
            if label == "design":
                what = (
                    f"{values.get('name', '?')} (z_s {values.get('z_s')}, z_pl "
                    f"{values.get('z_pl')}, z_p {values.get('z_p')}, rated torque "
                    f"{values.get('rated_torque_Nm')} N*m)"
                )
            else:
                nonzero = [k for k, v in values.items() if _any_nonzero(v)]
                what = (
                    f"{len(nonzero)} nonzero: {', '.join(nonzero)}"
                    if nonzero
                    else "none: the error-free reducer"
                )
            lines.append(f"{label:<8} {what}" + (f"  [from {source}]" if source else ""))
    return lines


def _any_nonzero(value) -> bool:
    if isinstance(value, list):
        return any(_any_nonzero(v) for v in value)
    return isinstance(value, (int, float)) and value != 0
