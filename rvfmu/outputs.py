"""Output paths, checked before any work starts.

A TE curve at full resolution takes seconds, an FMU build tens of seconds and
a tolerance study minutes to hours: a figure path with an extension matplotlib
cannot write, or a folder that does not exist, must be reported at once, not
after the work.  Every check raises `InputError` naming the option, the path
and what is allowed, which the CLI prints as one line with exit code 2.
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path

from .core.base.checks import InputError


@cache
def figure_formats() -> tuple[str, ...]:
    """File extensions matplotlib writes (png, pdf, svg, ...), without the dot."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(FigureCanvasBase.get_supported_filetypes()))


def output_file(field: str, path, suffixes: tuple[str, ...] | None = None) -> Path:
    """`path` as a Path if a file can be written there, else raise.

    The folder must exist and be writable, the path must not be a folder, and
    with `suffixes` (without dots) the extension must be one of them.
    """
    if path is None or str(path) == "":
        raise InputError(field, path, "must be a file path")
    path = Path(path)
    if path.is_dir():
        raise InputError(field, str(path), "is a folder: give a file name")
    if suffixes is not None and path.suffix.lower().lstrip(".") not in suffixes:
        raise InputError(field, str(path), "must end in one of ." + ", .".join(suffixes))
    folder = path.parent
    if not folder.is_dir():
        raise InputError(field, str(path), f"cannot be written: the folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise InputError(field, str(path), "cannot be written: no write permission")
    return path


def figure_file(field: str, path) -> Path:
    """`output_file` for a figure: the extension must be a format matplotlib writes."""
    return output_file(field, path, figure_formats())


def output_folder(field: str, path) -> Path:
    """`path` as a Path if a folder can be created or written there, else raise.

    A folder that does not exist yet is fine if its nearest existing parent is
    a writable folder (it is created when the results are written).
    """
    if path is None or str(path) == "":
        raise InputError(field, path, "must be a folder path")
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(field, str(path), "is a file: give a folder")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(field, str(path), f"cannot be created: {str(existing)!r} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(field, str(path), f"cannot be written: no write permission in {str(existing)!r}")
    return path
