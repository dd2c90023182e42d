"""The native reducer FMU: the quasi-static TE map stepped by compiled C, no Python at run time.

A system simulation on a controller test bench, or in a tool without Python,
wants the reducer's output angle without an interpreter in its process.  The
quasi-static model needs none at run time: a step is one interpolation in the
TE map (`rvfmu.core.steppers.te_map`), which is plain data.  So the map is solved here,
written as a binary table into the FMU's resources, and a small C library
(rvfmu/fmu/native/: model.c, the physics, knows nothing of FMI;
fmi2Functions.c, the FMI 2.0 co-simulation plumbing, over instance.c, what it
shares with the FMI 3.0 plumbing) reads it once per
instance and interpolates it operation for operation as `TEMap.evaluate_one`,
so that its outputs are the pythonfmu FMU's quasi-static ones (tested to 1e-12
rad; equal to the bit where the compiler does not fuse multiply-adds).

The native FMU has the pythonfmu FMU's inputs and outputs (same names, value
references, units and descriptions: taken from `rvfmu.fmu.slave`), and one
parameter of it, `temperature_C` (the lubricant's temperature [C], fixed, 40 by
default): the table carries the load-free friction torque at the temperatures
`te_map.DRAG_TEMPERATURES`, and initialisation reads it there (linear in the
temperature, as `TEMap.load_free_row`), or refuses a temperature outside them
with fmi2Error / fmi3Error.  No other parameter: `design_file`, `errors_file`, `map_points` and the stiffness and
error scales change the physics, and honouring them means solving the TE map
again, which needs the Python model; `model` could only be "quasistatic";
`dynamic_step` belongs to the dynamic model.  A different reducer is a
different FMU: build another.  The C sources travel in sources/ and are
declared in modelDescription.xml, so a tool that compiles source FMUs can
build the binary for its own platform.

`--fmi-version 3` builds the same FMU for FMI 3.0: fmi3Functions.c in place of
fmi2Functions.c over the same model.c and instance.c, binaries/x86_64-linux and
x86_64-windows, the description and sources/buildDescription.xml of
`rvfmu.fmu.fmi3`.

The table, resources/te_map.bin (every number little-endian; model.c reads it
and carries the same layout in a comment):

    offset               type              field
    0                    char[8]           magic b"RVTEMAP\\0"
    8                    uint32            format version, 4
    12                   uint32            A, angle points over one output revolution (>= 2)
    16                   uint32            T, torque levels (>= 2)
    20                   uint32            K, speeds of the load-free friction (>= 2)
    24                   float64           ratio i (> 0)
    32                   float64           rated torque [N*m] (> 0)
    40                   float64           momentary maximum class, x rated (limits.MOMENTARY_FACTOR)
    48                   float64           emergency-stop class, x rated (limits.EMERGENCY_FACTOR)
    56                   float64           the friction law's speed scale [rad/s at the input]
    64                   float64           allowable output speed [rad/s] (the design's)
    72                   float64           speed factor, x allowable (limits.SPEED_FACTOR)
    80                   char[64]          the design's name, UTF-8, NUL-padded (cut to 63 bytes)
    144                  uint32            M, lubricant temperatures of the load-free friction
    148                  uint32            0 (padding)
    152                  float64           the seals' torque at the output [N*m] (TEMap.seal)
    160                  float64           static friction factor (TEMap.static_friction_factor)
    168                  float64           Stribeck speed [rad/s at the input] (reducer_model)
    176                  float64[T]        torque magnitudes [N*m], ascending, the first 0
    176 + 8T             float64[2][T][A]  te [rad]: branch 0 resisting loads, 1 driving loads
    176 + 8T + 16TA      float64[2][T][A]  tau_in [N*m]
    176 + 8T + 32TA      float64[2][T][A]  the Coulomb friction torque at the output [N*m]
    176 + 8T + 48TA      float64[K]        output speeds [rad/s], ascending, the first 0
    176 + 8T + 48TA + 8K float64[M]        lubricant temperatures [C], ascending
    ... + 8M             float64[M][K]     the load-free friction torque at the output [N*m]
    176 + 8T + 48TA + 8K + 8M + 8MK        end of file: the length is checked against A, T, K, M

The load classes and the speed limit travel in the table rather than in the C
code so that `rvfmu.core.reducer.limits` and the design stay their only source (the
design's name only goes into the messages).  Version 3 added the speed limit, version 4
the temperatures and the breakaway; a table of any other version is refused.  A table that fails a check
(magic, version, sizes against the file length, finite values, ascending
levels from 0) makes fmi2Instantiate log the reason and return NULL.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import uuid
import zipfile
from datetime import datetime, timezone
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from ..core.reducer.design import RVDesign
from ..core.reducer.errors import ErrorSet, error_file_values, toml_text
from ..core.reducer.limits import EMERGENCY_FACTOR, MOMENTARY_FACTOR, SPEED_FACTOR
from ..core.steppers.reducer_model import FRICTION_SPEED_SCALE, STRIBECK_SPEED
from ..core.steppers.te_map import TEMap
from .build import complete_model_description, prepare, source_line
from .fmi3 import FMI3_SOURCE_FILES, PLATFORM_TUPLES, build_description, model_description_3
from .slave import BUNDLED_DESIGN, BUNDLED_ERRORS

NATIVE_SOURCES = Path(__file__).resolve().parent / "native"
SOURCE_FILES = ("model.c", "instance.c", "fmi2Functions.c")  # compiled; the headers beside them
HEADER_FILES = ("model.h", "instance.h")
FMI_VERSIONS = (2, 3)  # the standards a native FMU is built for
MODEL_IDENTIFIER = "RVReducer"
TABLE_NAME = "te_map.bin"
TABLE_MAGIC = b"RVTEMAP\0"
TABLE_VERSION = 4
# magic, version, A, T, K, ratio, rated, load classes, speed scale, allowable speed, speed
# factor, design name, M, padding, seals' torque, static friction factor, Stribeck speed
TABLE_HEADER = struct.Struct("<8s4I7d64s2I3d")
NAME_BYTES = 63  # of the design's name: a NUL always ends it
# The inputs and outputs in the order of their value references in fmi2Functions.c.
VARIABLES = (
    "theta_in",
    "tau_load",
    "theta_out",
    "omega_out",
    "te",
    "te_arcsec",
    "tau_in",
    "P_loss",
    "efficiency",
)
# The parameters and their value references (instance.h: TEMPERATURE_C), the slave's.
PARAMETERS = {"temperature_C": 18}
LOG_CATEGORIES = {
    "logEvents": "the table read, resets (with debug logging on)",
    "logStatusWarning": "loads above the momentary maximum class, input speeds above the allowable one",
    "logStatusError": "inputs refused (the simulation ends), tables that cannot be read",
}
# Bit-for-bit agreement with the Python interpolation wants no fused multiply-adds.
C_FLAGS = "-O2 -ffp-contract=off"
WIN64_COMPILER = "x86_64-w64-mingw32-gcc"  # Debian's mingw-w64


def build_native_fmu(
    design: RVDesign,
    errors: ErrorSet | None = None,
    output: str | Path = "RVReducer.fmu",
    points: int | None = None,
    progress=None,
    sources: dict | None = None,
    fmi_version: int = 2,
) -> Path:
    """Write the native reducer FMU for `design` and one reducer's `errors` to `output`.

    The arguments are `build.build_fmu`'s; fmi_version: 2 or 3, the standard of
    the FMU (the same model, table and behaviour in both).  binaries/<this
    platform> is compiled with fmpy's CMake builder (the C compiler directly
    where cmake is missing), binaries/win64 (FMI 3.0: x86_64-windows) with
    mingw-w64 where it is installed; `native_platforms` says which an FMU carries.
    """
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"fmi_version = {fmi_version!r}: must be 2 or 3")
    errors, output, te_map = prepare(design, errors, output, points, progress)
    with tempfile.TemporaryDirectory(prefix="rvte_native_") as tmp:
        unzipped = Path(tmp) / "fmu"
        resources, source_dir = unzipped / "resources", unzipped / "sources"
        resources.mkdir(parents=True)
        source_dir.mkdir()
        write_table(te_map, design, resources / TABLE_NAME)
        sources = sources or {}
        (resources / BUNDLED_DESIGN).write_text(
            source_line(sources.get("design")) + toml_text(design.file_values())
        )
        (resources / BUNDLED_ERRORS).write_text(
            source_line(sources.get("errors")) + toml_text(error_file_values(errors))
        )
        for name in (*source_files(fmi_version), *HEADER_FILES):
            shutil.copy2(NATIVE_SOURCES / name, source_dir / name)
        (unzipped / "modelDescription.xml").write_bytes(model_description(fmi_version))
        if fmi_version == 3:
            (source_dir / "buildDescription.xml").write_bytes(build_description(MODEL_IDENTIFIER))
        compile_binaries(unzipped, Path(tmp) / "build", fmi_version)
        output.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(output, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(unzipped.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(unzipped).as_posix())
    if fmi_version == 2:
        complete_model_description(output)  # units, default experiment, initial unknowns
    return output


def source_files(fmi_version: int = 2) -> tuple[str, ...]:
    """The C files compiled into the FMU of that FMI version (the headers beside them)."""
    return FMI3_SOURCE_FILES if fmi_version == 3 else SOURCE_FILES


def binary_folder(platform: str, fmi_version: int = 2) -> str:
    """binaries/<folder> of an fmpy platform name (linux64, win64): FMI 3.0 names platforms
    by tuple (x86_64-linux, x86_64-windows)."""
    return PLATFORM_TUPLES[platform] if fmi_version == 3 else platform


def write_table(te_map: TEMap, design: RVDesign, path: Path) -> None:
    """Write `te_map` and the limits of `design` (its load classes from the rated torque [N*m],
    its allowable output speed [rad/s]) as the table (module doc)."""
    points, levels = te_map.theta_in.size, te_map.torque_magnitude.size
    name = design.name.encode("utf-8")[:NAME_BYTES].decode("utf-8", "ignore").encode("utf-8")
    header = TABLE_HEADER.pack(
        TABLE_MAGIC,
        TABLE_VERSION,
        points,
        levels,
        te_map.drag_speed.size,
        te_map.ratio,
        design.rated_torque,
        MOMENTARY_FACTOR,
        EMERGENCY_FACTOR,
        FRICTION_SPEED_SCALE,
        design.allowable_output_speed,
        SPEED_FACTOR,
        name,
        te_map.drag_temperature.size,
        0,
        te_map.seal,
        te_map.static_friction_factor,
        STRIBECK_SPEED,
    )
    body = [
        np.ascontiguousarray(a, dtype="<f8").tobytes()
        for a in (
            te_map.torque_magnitude,
            te_map.te,
            te_map.tau_in,
            te_map.friction,
            te_map.drag_speed,
            te_map.drag_temperature,
            te_map.drag,
        )
    ]
    path.write_bytes(header + b"".join(body))


def read_table(path: str | Path) -> tuple[TEMap, float]:
    """(the TE map, the rated torque [N*m]) of a table; for checks, the FMU reads it in C.

    The table stores no angles (evenly spaced over one output revolution, the
    interpolation needs only their count): the map's theta_in is rebuilt.
    """
    data = Path(path).read_bytes()
    fields = TABLE_HEADER.unpack_from(data)
    magic, version, points, levels, speeds, ratio, rated = fields[:7]
    temperatures, seal, static = fields[13], fields[15], fields[16]
    if magic != TABLE_MAGIC or version != TABLE_VERSION:
        raise ValueError(f"{path}: not a version {TABLE_VERSION} TE map table")
    values = np.frombuffer(data, "<f8", offset=TABLE_HEADER.size).astype(float)
    cells = 2 * levels * points
    magnitude, te, tau_in, friction, drag_speed, drag_temperature, drag = np.split(
        values, np.cumsum([levels, cells, cells, cells, speeds, temperatures])
    )
    angles = np.arange(points) * (2.0 * np.pi * ratio / points)
    shape = (2, levels, points)
    return (
        TEMap(
            ratio,
            angles,
            magnitude,
            te.reshape(shape),
            tau_in.reshape(shape),
            friction.reshape(shape),
            drag_speed,
            drag.reshape(temperatures, speeds),
            drag_temperature,
            seal,
            static,
        ),
        rated,
    )


def table_limits(path: str | Path) -> dict:
    """The limits a table carries: allowable_output_speed [rad/s], speed_factor, design name."""
    fields = TABLE_HEADER.unpack_from(Path(path).read_bytes())
    return {
        "allowable_output_speed": fields[10],
        "speed_factor": fields[11],
        "design": fields[12].rstrip(b"\0").decode("utf-8"),
    }


def declared_variables() -> list[ET.Element]:
    """The pythonfmu slave's inputs and outputs and the parameters of PARAMETERS as FMI 2.0
    <ScalarVariable>s, checked to be those of the C code (instance.h) in the order of their
    value references."""
    from .slave import RVReducer

    slave = RVReducer(instance_name="native")
    declared = [
        v
        for v in slave.to_xml().find("ModelVariables")
        if v.get("causality") in ("input", "output") or v.get("name") in PARAMETERS
    ]
    names = [(v.get("name"), int(v.get("valueReference"))) for v in declared]
    if names != [(name, vr) for vr, name in enumerate(VARIABLES)] + list(PARAMETERS.items()):
        raise RuntimeError(
            f"the slave's inputs and outputs {names} are not those of "
            f"instance.h {VARIABLES}: update the C code"
        )
    return declared


def about_model() -> dict[str, str]:
    """The attributes that say what the model is, the same in both standards' descriptions."""
    from .slave import RVReducer

    return {
        "modelName": MODEL_IDENTIFIER,
        "description": f"{RVReducer.description}; native code, the TE map only",
        "author": RVReducer.author,
        "generationTool": "rvte (native FMU)",
    }


def model_description(fmi_version: int = 2) -> bytes:
    """modelDescription.xml: the pythonfmu slave's inputs and outputs, and temperature_C.  FMI 2.0
    without units and default experiment (`complete_model_description` adds them) and with
    the sources; FMI 3.0 complete (`rvfmu.fmu.fmi3`)."""
    declared = declared_variables()
    if fmi_version == 3:
        return model_description_3(declared, about_model(), MODEL_IDENTIFIER, LOG_CATEGORIES)
    root = ET.Element(
        "fmiModelDescription",
        fmiVersion="2.0",
        **about_model(),
        guid=f"{{{uuid.uuid4()}}}",
        generationDateAndTime=datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        variableNamingConvention="structured",
        numberOfEventIndicators="0",
    )
    cosim = ET.SubElement(
        root,
        "CoSimulation",
        modelIdentifier=MODEL_IDENTIFIER,
        canHandleVariableCommunicationStepSize="true",
        canBeInstantiatedOnlyOncePerProcess="false",
        canNotUseMemoryManagementFunctions="true",
        canGetAndSetFMUstate="true",
        canSerializeFMUstate="true",
    )
    files = ET.SubElement(cosim, "SourceFiles")
    for name in SOURCE_FILES:
        ET.SubElement(files, "File", name=name)
    categories = ET.SubElement(root, "LogCategories")
    for name, text in LOG_CATEGORIES.items():
        ET.SubElement(categories, "Category", name=name, description=text)
    variables = ET.SubElement(root, "ModelVariables")
    variables.extend(declared)
    outputs = ET.SubElement(ET.SubElement(root, "ModelStructure"), "Outputs")
    for index, variable in enumerate(declared, start=1):
        if variable.get("causality") == "output":
            ET.SubElement(outputs, "Unknown", index=str(index))
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def compile_binaries(unzipped: Path, build_dir: Path, fmi_version: int = 2) -> list[str]:
    """Compile sources/ into binaries/<platform>/; returns the platforms built (fmpy's names).

    This platform's library is built by fmpy's builder, the CMake project with
    which `fmpy compile` builds a source FMU, given C_FLAGS (only the last bit
    depends on them: the sources need no flag and no library beyond libc; for
    FMI 3.0 it reads the sources from buildDescription.xml);
    where cmake is missing, by the C compiler directly.  win64 is
    cross-compiled with mingw-w64 where it is installed.
    """
    import fmpy
    from fmpy.build import build_platform_binary

    headers = Path(fmpy.__file__).parent / "c-code"  # the FMI 2.0 and 3.0 headers fmpy ships
    unzipped, build_dir = Path(unzipped).resolve(), Path(build_dir).resolve()  # cmake wants both
    built = [fmpy.platform]
    if shutil.which("cmake"):
        build_dir.mkdir(parents=True, exist_ok=True)
        with _output_to(build_dir / "build.log") as log:
            try:
                build_platform_binary(unzipped, build_dir, cmake_options={"CMAKE_C_FLAGS:STRING": C_FLAGS})
            except subprocess.CalledProcessError as exc:
                raise RuntimeError(
                    f"compiling the native FMU failed ({exc}):\n{log.read_text()[-3000:]}"
                ) from None
    else:
        library = ".dll" if os.name == "nt" else (".dylib" if sys.platform == "darwin" else ".so")
        folder = binary_folder(fmpy.platform, fmi_version)
        _compile(
            os.environ.get("CC", "cc"),
            ["-fPIC"],
            unzipped,
            headers,
            f"binaries/{folder}/{MODEL_IDENTIFIER}{library}",
            fmi_version,
        )
    if fmpy.platform != "win64" and shutil.which(WIN64_COMPILER):
        # libgcc linked in: the DLL then needs only what every Windows has (kernel32, msvcrt)
        _compile(
            WIN64_COMPILER,
            ["-static-libgcc"],
            unzipped,
            headers,
            f"binaries/{binary_folder('win64', fmi_version)}/{MODEL_IDENTIFIER}.dll",
            fmi_version,
        )
        built.append("win64")
    return built


def native_platforms(fmu: str | Path) -> list[str]:
    """The platforms an FMU has binaries for (binaries/<platform>/)."""
    with zipfile.ZipFile(fmu) as archive:
        parts = [name.split("/") for name in archive.namelist()]
    return sorted({p[1] for p in parts if len(p) == 3 and p[0] == "binaries" and p[2]})


def binaries_note(fmu: str | Path) -> str:
    """One line naming the platforms an FMU carries, and how to add win64 if it is missing."""
    platforms = native_platforms(fmu)
    note = f"binaries: {', '.join(platforms) or 'none'}"
    windows = {"win64", PLATFORM_TUPLES["win64"]}
    if not windows & set(platforms):
        note += (
            f"; no win64: {WIN64_COMPILER} was not found (Debian: apt-get install "
            "mingw-w64), or a tool can compile sources/ for it"
        )
    return note


def _compile(compiler, flags, unzipped: Path, headers: Path, target: str, fmi_version: int = 2) -> None:
    """Compile sources/ into the shared library `target` (relative to `unzipped`)."""
    target = unzipped / target
    target.parent.mkdir(parents=True, exist_ok=True)
    command = [
        compiler,
        "-shared",
        *C_FLAGS.split(),
        *flags,
        f"-I{headers}",
        f"-I{unzipped / 'sources'}",
        *(str(unzipped / "sources" / f) for f in source_files(fmi_version)),
        "-o",
        str(target),
    ]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"compiling the native FMU failed: {' '.join(command)}\n{done.stderr[-3000:]}")


@contextlib.contextmanager
def _output_to(log: Path):
    """Send this process's stdout and stderr (and its children's: cmake's) to `log`."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with open(log, "w") as file:
        os.dup2(file.fileno(), 1)
        os.dup2(file.fileno(), 2)
        try:
            yield log
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            for fd, copy in zip((1, 2), saved):
                os.dup2(copy, fd)
                os.close(copy)
