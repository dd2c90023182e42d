"""Build the reducer FMU: solve its TE map, bundle code and data, complete the XML.

`build_fmu` does the work behind `rvte fmu build` (`rvfmu.fmu.api.fmu_build`
checks the output path and resolves the inputs first).  The FMU carries the
physics core (`rvfmu.core`, numpy; only the reference solver, which the FMU
never imports, needs scipy) in its resources, so it runs in any Python 3.11+
with numpy, rvte installed or not.  Where the host's Python also has numba,
the dynamic model runs its compiled kernels: their numba cache files are
bundled too, so a host on the same kind of CPU does not compile them again.
pythonfmu provides the FMI binary and embeds its own Python package.  pythonfmu writes neither unit definitions nor
units on the variables, so the model description is completed here.

On Linux the FMU's binaries/linux64/ library is wrapped (`guard_linux_binary`,
native/pythonfmu_guard.c): pythonfmu's own library moves beside it as
libpythonfmu-export.so, and a small C library in its place passes every call
through, except that a refused step returns fmi2Error rather than fmi2Discard
and the slave's warnings and errors reach the host's logger whatever its
logging (docs/model.md section 8).  Without a C compiler (or built elsewhere
than on Linux) the FMU keeps pythonfmu's library as it is; binaries/win64 is
always pythonfmu's.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from ..core.reducer.design import RVDesign
from ..core.reducer.errors import ErrorSet, error_file_values, toml_text, zero_errors
from ..core.steppers.dynamic_reducer import compile_kernels
from ..core.steppers.te_map import build_te_map
from .slave import BUNDLED_DESIGN, BUNDLED_ERRORS, BUNDLED_MAP

PACKAGE = Path(__file__).resolve().parent.parent  # the rvfmu package
MODULE_NAME = "rvreducer_fmu"  # the FMU's entry module
UNITS = {  # unit name -> (base unit exponents, factor)
    "rad": ({"rad": "1"}, None),
    "rad/s": ({"rad": "1", "s": "-1"}, None),
    "arcsec": ({"rad": "1"}, "4.84813681109536e-06"),
    "N.m": ({"kg": "1", "m": "2", "s": "-2"}, None),
    "1": ({}, None),
    "s": ({"s": "1"}, None),
    "W": ({"kg": "1", "m": "2", "s": "-3"}, None),
}
VARIABLE_UNITS = {
    "theta_in": "rad",
    "tau_load": "N.m",
    "theta_out": "rad",
    "omega_out": "rad/s",
    "te": "rad",
    "te_arcsec": "arcsec",
    "tau_in": "N.m",
    "pin_stiffness_scale": "1",
    "bearing_stiffness_scale": "1",
    "mesh_stiffness_scale": "1",
    "error_scale": "1",
    "dynamic_step": "s",
    "P_loss": "W",
    "efficiency": "1",
}
DEFAULT_STOP_TIME = 1.0
DEFAULT_STEP = 1e-3
GUARD_SOURCE = PACKAGE / "fmu" / "native" / "pythonfmu_guard.c"
PYTHONFMU_LIBRARY = "libpythonfmu-export.so"  # pythonfmu's Linux library, beside the guard


def build_fmu(
    design: RVDesign,
    errors: ErrorSet | None = None,
    output: str | Path = "RVReducer.fmu",
    points: int | None = None,
    progress=None,
    sources: dict | None = None,
) -> Path:
    """Write the reducer FMU for `design` and one reducer's `errors` to `output`.

    output: a path ending in .fmu (else ValueError); points: TE map points per
    output revolution (default `default_points`); progress(count): the solver's
    per-chunk counts (`rvfmu.progress.ProgressCounter`), optional.
    sources: {"design": ..., "errors": ...}, where they came from (a preset name,
    a file path), recorded in the bundled files for `rvte fmu info`.
    """
    from pythonfmu import FmuBuilder

    errors, output, te_map = prepare(design, errors, output, points, progress)
    with tempfile.TemporaryDirectory(prefix="rvte_fmu_") as tmp:
        tmp = Path(tmp)
        package = tmp / "rvfmu"
        shutil.copytree(
            PACKAGE / "core", package / "core", ignore=shutil.ignore_patterns("__pycache__", "*.pyc")
        )
        (package / "__init__.py").write_text((PACKAGE / "__init__.py").read_text())
        sources = sources or {}
        (tmp / BUNDLED_DESIGN).write_text(
            source_line(sources.get("design")) + toml_text(design.file_values())
        )
        (tmp / BUNDLED_ERRORS).write_text(
            source_line(sources.get("errors")) + toml_text(error_file_values(errors))
        )
        np.savez(tmp / BUNDLED_MAP, **te_map.to_arrays())
        script = tmp / "src" / f"{MODULE_NAME}.py"
        script.parent.mkdir()
        shutil.copy2(PACKAGE / "fmu" / "slave.py", script)
        output.parent.mkdir(parents=True, exist_ok=True)
        built = FmuBuilder.build_FMU(
            script,
            dest=output,
            project_files=[package, tmp / BUNDLED_DESIGN, tmp / BUNDLED_ERRORS, tmp / BUNDLED_MAP],
            canGetAndSetFMUstate=True,
            canSerializeFMUstate=True,
            canHandleVariableCommunicationStepSize=True,
            needsExecutionTool=True,
        )
    complete_model_description(Path(built))
    guard_linux_binary(Path(built))
    # the compiled dynamic-model kernels (numba's cache files, keyed by the source's content;
    # pythonfmu leaves __pycache__ folders out), those its dynamic model runs for this design
    # and these errors: a host with numba loads them instead of compiling on its first dynamic
    # initialisation and step
    with zipfile.ZipFile(built, "a", zipfile.ZIP_DEFLATED) as archive:
        for path in compile_kernels(design, errors):
            archive.write(path, f"resources/rvfmu/{path.resolve().relative_to(PACKAGE).as_posix()}")
    return Path(built)


def guard_linux_binary(fmu: Path) -> bool:
    """Wrap the FMU's binaries/linux64/ library in native/pythonfmu_guard.c (module doc); True
    if it was, False where it cannot be (not Linux, no C compiler: the FMU keeps pythonfmu's
    library as it is)."""
    import fmpy

    compiler = os.environ.get("CC", "cc")
    if not sys.platform.startswith("linux") or not shutil.which(compiler):
        return False
    with zipfile.ZipFile(fmu) as archive:
        entries = {info.filename: archive.read(info.filename) for info in archive.infolist()}
    binaries = [name for name in entries if name.startswith("binaries/linux64/") and name.endswith(".so")]
    if len(binaries) != 1:
        raise RuntimeError(f"{fmu}: expected one library in binaries/linux64/, found {binaries}")
    library = entries[binaries[0]]
    with tempfile.TemporaryDirectory(prefix="rvte_guard_") as tmp:
        guard = Path(tmp) / "guard.so"
        # the guard opens pythonfmu's library by its path at run time (native/pythonfmu_guard.c)
        command = [
            compiler,
            "-std=c99",
            "-O2",
            "-shared",
            "-fPIC",
            f"-I{Path(fmpy.__file__).parent / 'c-code'}",
            str(GUARD_SOURCE),
            "-o",
            str(guard),
            f'-DPYTHONFMU_LIBRARY="{PYTHONFMU_LIBRARY}"',
            "-ldl",
            "-lpthread",
        ]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(
                f"compiling the FMU's guard failed: {' '.join(command)}\n{done.stderr[-3000:]}"
            )
        entries[f"binaries/linux64/{PYTHONFMU_LIBRARY}"] = library
        entries[binaries[0]] = guard.read_bytes()
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    return True


def prepare(design: RVDesign, errors: ErrorSet | None, output, points, progress):
    """(errors, output path, TE map): what every FMU build starts from.  The output path
    must end in .fmu (checked before the map is solved; never renamed behind the caller's
    back: `rvfmu.fmu.api.fmu_output` says so to the user first)."""
    output = Path(output)
    if output.suffix.lower() != ".fmu":
        raise ValueError(f"output = {str(output)!r}: must end in .fmu")
    errors = zero_errors(design) if errors is None else errors.check(design)
    return errors, output, build_te_map(design, errors, points=points, progress=progress)


def complete_model_description(fmu: Path) -> None:
    """Add unit definitions, variable units and a default experiment to the FMU's XML."""
    with zipfile.ZipFile(fmu) as archive:
        entries = {info.filename: archive.read(info.filename) for info in archive.infolist()}
    root = ET.fromstring(entries["modelDescription.xml"])
    units = unit_definitions()
    # The schema orders the children: CoSimulation, UnitDefinitions, ..., DefaultExperiment, ...
    children = list(root)
    position = next(i for i, child in enumerate(children) if child.tag == "CoSimulation") + 1
    root.insert(position, units)
    if root.find("DefaultExperiment") is None:
        experiment = ET.Element(
            "DefaultExperiment", startTime="0.0", stopTime=str(DEFAULT_STOP_TIME), stepSize=str(DEFAULT_STEP)
        )
        after = [
            i
            for i, child in enumerate(list(root))
            if child.tag in ("CoSimulation", "UnitDefinitions", "TypeDefinitions", "LogCategories")
        ]
        root.insert(max(after) + 1, experiment)
    for variable in root.iter("ScalarVariable"):
        unit = VARIABLE_UNITS.get(variable.get("name"))
        real = variable.find("Real")
        if unit and real is not None:
            real.set("unit", unit)
    # Outputs computed at initialisation are initial unknowns (FMI 2.0 section 2.2.8).
    structure = root.find("ModelStructure")
    if structure is not None and structure.find("InitialUnknowns") is None:
        unknowns = ET.Element("InitialUnknowns")
        for index, variable in enumerate(root.iter("ScalarVariable"), start=1):
            if variable.get("causality") == "output" and variable.get("initial") == "calculated":
                ET.SubElement(unknowns, "Unknown", index=str(index))
        if len(unknowns):
            after = [i for i, child in enumerate(list(structure)) if child.tag in ("Outputs", "Derivatives")]
            structure.insert(max(after) + 1 if after else 0, unknowns)
    entries["modelDescription.xml"] = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)


def unit_definitions() -> ET.Element:
    """<UnitDefinitions> of every unit in UNITS (the same element in FMI 2.0 and 3.0)."""
    units = ET.Element("UnitDefinitions")
    for name, (base, factor) in UNITS.items():
        unit = ET.SubElement(units, "Unit", name=name)
        attributes = dict(base)
        if factor:
            attributes["factor"] = factor
        ET.SubElement(unit, "BaseUnit", **attributes)
    return units


SOURCE_PREFIX = "# source: "


def source_line(source) -> str:
    """The first line of a bundled design or error file naming where it came from
    (`# source: NAME`, read back by `fmu_info`), or "" when it came from no file."""
    return f"{SOURCE_PREFIX}{source}\n" if source else ""
