"""What a calibration is fitted to, and the small TOML files that hold it.

A `DataSet` is what was measured on one reducer under one condition: a TE peak
(seed 003), a bench record (`rvfmu.bench.measured.MeasuredTE`) or a reducer's
catalogue figures (`Catalogue`: torsional rigidity, lost motion, efficiency points
and no-load running torques, each with its conditions).  Read here: a catalogue
TOML (`catalogue_dataset`), a data-set TOML of [[dataset]] tables
(`peaks_datasets`; its bench CSVs through the reader it is given) and a design's
[sources] table (`design_sources`).  The bench CSVs themselves are read by
`rvfmu.api.measure`, the calibrated design is written by `rvfmu.api.calibrate`.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.base.checks import InputError, finite_number, non_negative, positive
from ..core.reducer.design import ESTIMATE_SUFFIX, PRESET_NAMES, RVDesign, preset_file
from ..core.reducer.errors import ErrorSet, load_errors
from .measured import MeasuredTE

CATALOGUE_KEYS = ("torsional_rigidity_Nm_per_arcmin", "lost_motion_arcmin", "rated_torque_Nm")
# Friction figures of a catalogue file: arrays of tables, each with its conditions.
FRICTION_CATALOGUE_KEYS = {
    "efficiency": ("output_speed_rpm", "load_Nm", "efficiency", "lubricant_temperature_C", "note"),
    "running_torque": ("output_speed_rpm", "input_torque_Nm", "lubricant_temperature_C", "note"),
}
CATALOGUE_NOTES = ("source", "note")
DATASETS_KEYS = ("load_Nm", "errors", "error_scale", "source", "dataset")
DATASET_KEYS = ("name", "te_pp_arcsec", "data", "load_Nm", "errors", "error_scale", "note")


@dataclass(frozen=True)
class Catalogue:
    """Catalogue figures of a reducer; rated_torque_Nm: the torque the stiffness figures refer
    to (lost motion at +-3 % of it, rigidity between 50 and 100 %), None: the design's;
    efficiency: ((output speed [rpm], resisting torque [N*m], efficiency), ...), forward;
    running_torque: ((output speed [rpm], no-load running torque at the input [N*m]), ...)."""

    torsional_rigidity_Nm_per_arcmin: float | None = None
    lost_motion_arcmin: float | None = None
    rated_torque_Nm: float | None = None
    efficiency: tuple = ()
    running_torque: tuple = ()

    def figures(self) -> dict:
        """The stiffness figures given: {name: value}."""
        return {
            k: v
            for k, v in (
                ("torsional_rigidity_Nm_per_arcmin", self.torsional_rigidity_Nm_per_arcmin),
                ("lost_motion_arcmin", self.lost_motion_arcmin),
            )
            if v is not None
        }

    def labels(self) -> list[str]:
        """A name for each of `values`."""
        return (
            list(self.figures())
            + [f"1 - efficiency, {v:g} rpm {t:g} N*m" for v, t, _ in self.efficiency]
            + [f"running torque N*m, {v:g} rpm" for v, _ in self.running_torque]
        )

    def values(self) -> np.ndarray:
        """Every figure as calibration compares it: the stiffness figures, the loss share
        1 - efficiency of each efficiency point, the running torques."""
        return np.array(
            list(self.figures().values())
            + [1.0 - e for _, _, e in self.efficiency]
            + [t for _, t in self.running_torque],
            dtype=float,
        )


@dataclass(frozen=True)
class DataSet:
    """What was measured on one reducer under one condition.

    load_Nm: resisting output torque; errors: that reducer's errors (one sample), None for
    none.  One of: te_pp_arcsec (a TE peak-to-peak, as seed 003 gives them), measured (a
    bench record: its curve, or its te_pp without the runout), catalogue (figures).
    """

    name: str
    load_Nm: float = 0.0
    errors: ErrorSet | None = None
    te_pp_arcsec: float | None = None
    measured: MeasuredTE | None = None
    catalogue: Catalogue | None = None

    def target_value(self, target: str) -> np.ndarray:
        """The measured quantity this data set brings to `target`, as an array."""
        if target == "catalogue":
            return self.catalogue.values()
        if target == "curve":
            return self.measured.te_reducer_arcsec
        if self.te_pp_arcsec is not None:
            return np.array([self.te_pp_arcsec])
        return np.array([float(self.measured.te_pp_arcsec[1])])


def read_toml(field: str, path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise InputError(field, str(path), "must be an existing file")
    try:
        return tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(field, str(path), f"is not valid TOML ({exc})") from None


def is_catalogue(values: dict) -> bool:
    return (
        any(k in values for k in CATALOGUE_KEYS + tuple(FRICTION_CATALOGUE_KEYS)) and "dataset" not in values
    )


def catalogue_dataset(path, values: dict, load: float = 0.0, errors=None) -> DataSet:
    """A catalogue TOML as a data set: torsional_rigidity_Nm_per_arcmin, lost_motion_arcmin,
    optional rated_torque_Nm; [[efficiency]] tables (output_speed_rpm, load_Nm: the resisting
    torque, efficiency: forward, 0 < eta < 1) and [[running_torque]] tables (output_speed_rpm,
    input_torque_Nm: the no-load running torque at the input), each optionally with
    lubricant_temperature_C and a note; source and note: free text."""
    where = Path(path).name
    known = CATALOGUE_KEYS + tuple(FRICTION_CATALOGUE_KEYS) + CATALOGUE_NOTES
    unknown = [k for k in values if k not in known]
    if unknown:
        raise InputError(
            unknown[0], values[unknown[0]], "is not a catalogue key; known: " + ", ".join(known), where
        )
    figures = {k: positive(k, values[k], where) for k in CATALOGUE_KEYS if k in values}
    points = {}
    for key, allowed in FRICTION_CATALOGUE_KEYS.items():
        entries = values.get(key, [])
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            raise InputError(key, entries, f"must be [[{key}]] tables", where)
        rows = []
        for k, entry in enumerate(entries):
            at = f"{where} {key} {k + 1}"
            unknown = [x for x in entry if x not in allowed]
            if unknown:
                raise InputError(
                    unknown[0], entry[unknown[0]], f"is not a [[{key}]] key; known: " + ", ".join(allowed), at
                )
            needed = allowed[:3] if key == "efficiency" else allowed[:2]
            missing = [x for x in needed if x not in entry]
            if missing:
                raise InputError(missing[0], None, f"every [[{key}]] needs " + ", ".join(needed), at)
            numbers = [positive(x, entry[x], at) for x in needed]
            if key == "efficiency" and not numbers[2] < 1.0:
                raise InputError("efficiency", numbers[2], "must be below 1 (a fraction: 0.85, not 85 %)", at)
            rows.append(tuple(numbers))
        points[key] = tuple(rows)
    if not set(figures) - {"rated_torque_Nm"} and not any(points.values()):
        raise InputError(
            "data",
            str(path),
            "a catalogue file needs torsional_rigidity_Nm_per_arcmin, "
            "lost_motion_arcmin, [[efficiency]] or [[running_torque]]",
        )
    return DataSet(where, load, errors, catalogue=Catalogue(**figures, **points))


def peaks_datasets(
    path,
    values: dict,
    design: RVDesign,
    load: float = 0.0,
    errors: str | Path | ErrorSet | None = None,
    read_record=None,
) -> list[DataSet]:
    """The [[dataset]] tables of a data-set TOML, each with te_pp_arcsec (a measured TE
    peak-to-peak) or data (a bench CSV, read by read_record(path) -> MeasuredTE), and
    load_Nm, errors (an error file, relative to this file) and error_scale (x the errors),
    each defaulting to the file's top-level value, then to `load` and `errors`."""
    path = Path(path)
    where = path.name
    unknown = [k for k in values if k not in DATASETS_KEYS]
    if unknown:
        raise InputError(
            unknown[0],
            values[unknown[0]],
            "is not a data-set file key; known: " + ", ".join(DATASETS_KEYS),
            where,
        )
    entries = values.get("dataset")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise InputError(
            "data",
            str(path),
            "is neither a catalogue TOML (it has none of "
            "torsional_rigidity_Nm_per_arcmin, lost_motion_arcmin, [[efficiency]], "
            "[[running_torque]]) nor a data-set TOML (one or more [[dataset]] "
            "tables)",
            where,
        )
    top = {"load_Nm": load, "errors": errors, "error_scale": 1.0}
    for key in ("load_Nm", "error_scale"):
        if key in values:
            top[key] = finite_number(key, values[key], where)
    if "errors" in values:
        top["errors"] = path.parent / str(values["errors"])
    cache = {}
    out = []
    for k, entry in enumerate(entries):
        at = f"{where} dataset {k + 1}"
        unknown = [key for key in entry if key not in DATASET_KEYS]
        if unknown:
            raise InputError(
                unknown[0],
                entry[unknown[0]],
                "is not a [[dataset]] key; known: " + ", ".join(DATASET_KEYS),
                at,
            )
        name = str(entry.get("name", k + 1))
        load_k = non_negative("load_Nm", entry.get("load_Nm", top["load_Nm"]), at)
        scale = non_negative("error_scale", entry.get("error_scale", top["error_scale"]), at)
        source = path.parent / str(entry["errors"]) if "errors" in entry else top["errors"]
        err = None
        if isinstance(source, ErrorSet):
            err = source.check(design).scaled(scale)
        elif source is not None:
            if str(source) not in cache:
                cache[str(source)] = load_errors(source, design)
            err = cache[str(source)].scaled(scale)
        if ("te_pp_arcsec" in entry) == ("data" in entry):
            raise InputError(
                "te_pp_arcsec",
                None,
                "give either te_pp_arcsec (a measured peak) or data (a bench CSV), not both or neither",
                at,
            )
        if "data" in entry:
            if read_record is None:
                raise InputError("data", entry["data"], "bench records are read by rvfmu.api", at)
            record = read_record(path.parent / str(entry["data"]))
            out.append(DataSet(name, load_k, err, measured=record))
        else:
            out.append(
                DataSet(name, load_k, err, te_pp_arcsec=positive("te_pp_arcsec", entry["te_pp_arcsec"], at))
            )
    return out


def design_sources(spec) -> dict | None:
    """The [sources] table of a design: a preset name's, a design file's own, or (a file
    that names a preset and has none) its preset's; None when there is none."""
    text = str(spec).removesuffix(ESTIMATE_SUFFIX)
    if text in PRESET_NAMES:
        return preset_file(text).get("sources")
    path = Path(spec)
    if not path.is_file():
        return None
    try:
        values = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return None
    if isinstance(values.get("sources"), dict):
        return values["sources"]
    name = str(values.get("preset", "")).removesuffix(ESTIMATE_SUFFIX)
    return preset_file(name).get("sources") if name in PRESET_NAMES else None


__all__ = [
    "Catalogue",
    "DataSet",
    "read_toml",
    "is_catalogue",
    "catalogue_dataset",
    "peaks_datasets",
    "design_sources",
]
