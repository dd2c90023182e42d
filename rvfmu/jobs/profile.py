"""`rvte profile`: the disc's tooth profile as CSV and DXF."""

from __future__ import annotations

from pathlib import Path

from ..outputs import output_file
from .common import NothingToWrite, resolve_design


def profile(
    design, csv_path: str | Path | None = None, dxf_path: str | Path | None = None, points: int | None = None
):
    """The disc profile of a design; writes CSV (mm) and/or DXF (mm)."""
    from ..core.reducer import profile as prof

    if csv_path is None and dxf_path is None:
        raise NothingToWrite("nothing to write: give --csv FILE and/or --dxf FILE")
    csv_path = None if csv_path is None else output_file("csv", csv_path)
    dxf_path = None if dxf_path is None else output_file("dxf", dxf_path, ("dxf",))
    design = resolve_design(design)
    points = prof.DEFAULT_POINTS if points is None else points
    if csv_path is not None:
        prof.write_profile_csv(design, csv_path, points)
    if dxf_path is not None:
        prof.write_profile_dxf(design, dxf_path, points)
    return prof.disc_profile(design, points)
