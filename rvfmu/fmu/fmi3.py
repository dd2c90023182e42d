"""The FMI 3.0 XML of the native reducer FMU: modelDescription.xml and sources/buildDescription.xml.

The FMI 3.0 FMU is the FMI 2.0 one under the other standard's layer
(native/fmi3Functions.c instead of fmi2Functions.c, over the same model.c and
instance.c), so its description is the 2.0 one's content in 3.0's form: the
same names, value references, causalities, variabilities, units and
descriptions, each variable a scalar Float64; instantiationToken in place of
guid; <Output> and <InitialUnknown> by value reference in <ModelStructure>; the
sources declared in sources/buildDescription.xml rather than in the
description (FMI 3.0 section 2.5.1), so that a tool can compile them for its
own platform.  Only the capability flags that hold are written: the others'
defaults (false) are what this FMU does.
"""

from __future__ import annotations

import uuid
from datetime import datetime, timezone
from xml.etree import ElementTree as ET

from .build import DEFAULT_STEP, DEFAULT_STOP_TIME, VARIABLE_UNITS, unit_definitions

FMI3_SOURCE_FILES = ("model.c", "instance.c", "fmi3Functions.c")
SOURCE_LANGUAGE = "C99"
# the FMI 3.0 platform tuples of the binaries/ folders of what the FMI 2.0 FMU calls linux64, win64
PLATFORM_TUPLES = {"linux64": "x86_64-linux", "win64": "x86_64-windows", "darwin64": "x86_64-darwin"}


def model_description_3(
    declared: list[ET.Element], about: dict[str, str], model_identifier: str, log_categories: dict[str, str]
) -> bytes:
    """modelDescription.xml of FMI 3.0 from the FMI 2.0 <ScalarVariable>s `declared` (in value
    reference order); about: modelName, description, author, generationTool."""
    generated = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    root = ET.Element(
        "fmiModelDescription",
        fmiVersion="3.0",
        modelName=about["modelName"],
        instantiationToken=f"{{{uuid.uuid4()}}}",
        description=about["description"],
        author=about["author"],
        generationTool=about["generationTool"],
        generationDateAndTime=generated,
        variableNamingConvention="structured",
    )
    ET.SubElement(
        root,
        "CoSimulation",
        modelIdentifier=model_identifier,
        canHandleVariableCommunicationStepSize="true",
        canGetAndSetFMUState="true",
        canSerializeFMUState="true",
    )
    root.append(unit_definitions())
    categories = ET.SubElement(root, "LogCategories")
    for name, text in log_categories.items():
        ET.SubElement(categories, "Category", name=name, description=text)
    ET.SubElement(
        root,
        "DefaultExperiment",
        startTime="0.0",
        stopTime=str(DEFAULT_STOP_TIME),
        stepSize=str(DEFAULT_STEP),
    )
    variables = ET.SubElement(root, "ModelVariables")
    # FMI 3.0 wants the independent variable; its value reference follows the inputs' and
    # outputs' (fmi3Functions.c: TIME), the parameters' come after the pythonfmu FMU's others
    signals = sum(v.get("causality") in ("input", "output") for v in declared)
    ET.SubElement(
        variables,
        "Float64",
        name="time",
        valueReference=str(signals),
        causality="independent",
        variability="continuous",
        unit="s",
        description="simulation time [s]",
    )
    for scalar in declared:
        variables.append(float64(scalar))
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [v for v in declared if v.get("causality") == "output"]
    for variable in outputs:
        ET.SubElement(structure, "Output", valueReference=variable.get("valueReference"))
    # outputs computed at initialisation are initial unknowns (FMI 3.0 section 2.4.8)
    for variable in outputs:
        if variable.get("initial") == "calculated":
            ET.SubElement(structure, "InitialUnknown", valueReference=variable.get("valueReference"))
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def float64(scalar: ET.Element) -> ET.Element:
    """The <Float64> of an FMI 2.0 <ScalarVariable> with a <Real>, its unit from VARIABLE_UNITS."""
    real = scalar.find("Real")
    if real is None:
        raise ValueError(f"{scalar.get('name')}: only Real variables have an FMI 3.0 Float64 here")
    attributes = {
        key: scalar.get(key)
        for key in ("name", "valueReference", "description", "causality", "variability", "initial")
        if scalar.get(key) is not None
    }
    if real.get("start") is not None:
        attributes["start"] = real.get("start")
    unit = VARIABLE_UNITS.get(scalar.get("name"))
    if unit:
        attributes["unit"] = unit
    return ET.Element("Float64", **attributes)


def build_description(model_identifier: str) -> bytes:
    """sources/buildDescription.xml: one configuration, the C files and the sources folder (the
    headers model.h and instance.h; the FMI 3.0 headers are the importing tool's)."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    configuration = ET.SubElement(root, "BuildConfiguration", modelIdentifier=model_identifier)
    files = ET.SubElement(configuration, "SourceFileSet", language=SOURCE_LANGUAGE)
    for name in FMI3_SOURCE_FILES:
        ET.SubElement(files, "SourceFile", name=name)
    ET.SubElement(files, "IncludeDirectory", name=".")
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)
