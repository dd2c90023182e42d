"""What every job shares: the design and errors it is given, the CSV files it reads and
writes, the JSON it prints."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..core.base.checks import InputError
from ..core.reducer.design import RVDesign, load_design
from ..core.reducer.errors import ErrorSet, load_errors, zero_errors
from ..core.statics.quasistatic import TECurve


class NothingToWrite(InputError):
    """A job that writes files was given none to write."""

    def __init__(self, message):
        ValueError.__init__(self, message)
        self.field, self.value, self.allowed = "output", None, message


def resolve_design(design: str | Path | RVDesign) -> RVDesign:
    """The design a job is given: an RVDesign as it is, else a preset name or the path of a
    design TOML file loaded (`rvfmu.core.reducer.design.load_design`; InputError if it is neither)."""
    return design if isinstance(design, RVDesign) else load_design(design)


def resolve_errors(design: RVDesign, errors: str | Path | ErrorSet | None) -> ErrorSet:
    """The errors a job is given, for `design`: None gives one reducer without any error, an
    ErrorSet is checked against the design's shapes (InputError if one does not fit), a path
    is read as a TOML error file (`rvfmu.core.reducer.errors.load_errors`, values in um and deg)."""
    if errors is None:
        return zero_errors(design)
    if isinstance(errors, ErrorSet):
        return errors.check(design)
    return load_errors(errors, design)


def write_frame(path: str | Path, frame, formats: dict) -> Path:
    """Write a DataFrame as CSV: a header of its column names, then one line per row, each
    column in its format spec ({name: spec}, e.g. ".12g"), comma-separated, CRLF line ends.

    The one CSV writer of the jobs: a report's file is its `to_df()` written here, so
    the file and the DataFrame a script gets cannot drift apart.
    """
    import pandas as pd

    path = Path(path)
    text = pd.DataFrame(
        {name: [format(value, formats[name]) for value in frame[name].to_numpy()] for name in frame.columns},
        columns=frame.columns,
    )
    text.to_csv(path, index=False, lineterminator="\r\n")
    return path


def columns_frame(columns: dict):
    """A pandas DataFrame of equal-length columns {name: values}, in that order (pandas is
    imported here, on first use, so that `rvte --help` does not pay for it)."""
    import pandas as pd

    return pd.DataFrame({name: np.asarray(values) for name, values in columns.items()})


def write_columns(path: str | Path, columns: dict) -> Path:
    """A CSV of equal-length columns: {name: (values, format spec)}, a header of the names."""
    return write_frame(
        path,
        columns_frame({name: values for name, (values, _) in columns.items()}),
        {name: spec for name, (_, spec) in columns.items()},
    )


def read_columns(field: str, path: str | Path, names: tuple[str, ...]) -> list[np.ndarray]:
    """The columns `names` of a CSV file with a header row, as float arrays; an InputError
    naming the field, the file and the row for a missing file, column or non-number."""
    rows = _csv_rows(field, path)
    header = [name.strip() for name in rows[0]] if rows else []
    missing = [name for name in names if name not in header]
    if missing:
        raise InputError(
            field,
            str(path),
            f"needs a header row with the columns {', '.join(names)} (missing: {', '.join(missing)})",
        )
    out = []
    for name in names:
        k = header.index(name)
        values = []
        for line, row in enumerate(rows[1:], start=2):
            try:
                values.append(float(row[k]))
            except (IndexError, ValueError):
                text = row[k] if k < len(row) else "nothing"
                raise InputError(
                    field,
                    f"{text!r} in column {name} on line {line} of {path}",
                    "every entry must be a number",
                ) from None
        out.append(np.array(values))
    return out


TE_FORMATS = {"theta_in_rad": ".12g", "theta_out_rad": ".12g", "te_arcsec": ".6f"}


def te_frame(curve: TECurve, sample: int = 0):
    """One reducer's TE curve as a DataFrame (points rows): theta_in_rad, theta_out_rad,
    te_arcsec (names of docs/model.md section 5), the columns of its CSV."""
    return columns_frame(
        {
            "theta_in_rad": curve.theta_in,
            "theta_out_rad": curve.theta_out[sample],
            "te_arcsec": curve.te_arcsec[sample],
        }
    )


def write_te_csv(curve: TECurve, path: str | Path, sample: int = 0) -> Path:
    """Columns theta_in_rad, theta_out_rad, te_arcsec (names of docs/model.md section 5)."""
    return write_frame(path, te_frame(curve, sample), TE_FORMATS)


def _csv_header(field: str, path: str | Path) -> list[str]:
    rows = _csv_rows(field, path, header_only=True)
    return [name.strip() for name in rows[0]] if rows else []


def _csv_rows(field: str, path: str | Path, header_only: bool = False) -> list[list[str]]:
    """The non-empty rows of a CSV file (only the first with header_only), or an InputError
    naming the field and the file when it is missing or not text (UTF-8)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(field, str(path), "must be an existing CSV file")
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = csv.reader(line for line in handle if line.strip())
            return [next(rows, [])] if header_only else list(rows)
    except UnicodeDecodeError as exc:
        raise InputError(
            field,
            str(path),
            f"is not a text (UTF-8) CSV file: byte {exc.start} is {exc.object[exc.start : exc.start + 1]!r}",
        ) from None


def _json_safe(value):
    """`value` with every float that is not finite as text ("inf", "nan"): JSON has neither."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else str(float(value))
    return value


def _design_ratio(design: RVDesign, ratio) -> float:
    """The design's ratio, or a stated one that must agree with it."""
    if ratio is None:
        return design.ratio
    from ..core.base.checks import positive

    ratio = positive("ratio", ratio)
    if abs(ratio / design.ratio - 1.0) > 1e-9:
        raise InputError(
            "ratio",
            ratio,
            f"the design {design.name} has ratio {design.ratio:g}: "
            "leave --ratio out (it is taken from the design) or give that",
        )
    return design.ratio
