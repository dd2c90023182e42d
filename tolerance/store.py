"""Never lose work: a study's results, batch by batch, in its output folder.

A study of thousands of reducers runs for minutes to hours; a crash, a
kill or a lost Dask worker must cost at most the batches in flight.  Every
finished batch is written at once as one Parquet file (metric columns, the
row index and the convergence flag), first to a temporary name and then
renamed, so a killed run never leaves half a batch under a batch name.  A run
started again reads what is there and computes only the missing batches.

Nothing is mixed silently:

- `manifest.json` holds the hash of the study's inputs (`Study.inputs_hash`)
  and of the model's code (`model_fingerprint`); a folder written by another
  study, or by another version of the model, is refused with the reason.
- every batch file carries the sha256 of its own bytes in its name and, in
  its Parquet metadata, those hashes, its row range, the sha256 of the sample
  rows it was computed from and of its values; a truncated, corrupted or
  foreign batch is refused, naming the file, never skipped.  Batch files carry
  no time stamp: the same results are the same bytes, so the same file name,
  whichever backend computed them.

Layout: <output>/manifest.json, inputs.json (the hashed inputs), study.toml (the
study file as last run), and one folder per job (`mc`, `sobol-n1024`, ...)
holding `batch-<start>-<stop>-<sha256, 16 hex>.parquet` for rows [start, stop)
and, if the study aliases, `aliasing_check.json` (tolerance/aliasing.py).
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from rvfmu.core.base.checks import InputError

from .study import Study, model_fingerprint

FORMAT = "rvte-tolerance-study/1"
MANIFEST = "manifest.json"
METADATA_KEY = b"rvte"
FILE_DIGEST = 16  # hex digits of a batch file's sha256 kept in its name (64 bits: no accident)


def rows_hash(X: np.ndarray) -> str:
    """sha256 of sample rows (float64, C order)."""
    return hashlib.sha256(np.ascontiguousarray(X, dtype="<f8").tobytes()).hexdigest()


def values_hash(Y: np.ndarray, converged: np.ndarray) -> str:
    """sha256 of a batch's outputs: Y (rows, M) as float64 then converged (rows,) as bool."""
    digest = hashlib.sha256(np.ascontiguousarray(Y, dtype="<f8").tobytes())
    digest.update(np.ascontiguousarray(converged, dtype=bool).tobytes())
    return digest.hexdigest()


def open_output(study: Study, folder: Path | None = None) -> Path:
    """Create the study's output folder, or check that an existing one is this study's.

    Raises InputError if the folder belongs to another study or model version,
    or is not empty and not a study folder.
    """
    folder = Path(folder or study.output)
    manifest_path = folder / MANIFEST
    if manifest_path.exists():
        check_manifest(folder, read_manifest(folder), study)
    else:
        if folder.exists() and any(folder.iterdir()):
            raise InputError(
                "output",
                str(folder),
                f"is not empty and has no {MANIFEST}: it is not "
                "a study output folder; choose an empty or new folder",
            )
        folder.mkdir(parents=True, exist_ok=True)
        manifest = {
            "format": FORMAT,
            "study": study.name,
            "inputs_hash": study.inputs_hash,
            "model_hash": model_fingerprint(),
            "created": _now(),
            "versions": software_versions(),
        }
        _write_atomic(folder / "inputs.json", json.dumps(study.inputs(), indent=1, sort_keys=True))
        _write_atomic(manifest_path, json.dumps(manifest, indent=1))
    if study.text:
        _write_atomic(folder / "study.toml", study.text)
    return folder


def study_output_folder(path, field: str = "output_folder") -> Path:
    """`path` as an existing study output folder (one with a manifest), for reading it;
    InputError naming `field` otherwise."""
    if path is None or str(path) == "":
        raise InputError(field, path, "must be a study output folder")
    folder = Path(path)
    if not folder.is_dir():
        raise InputError(
            field, str(folder), "must be an existing study output folder (written by rvte mc or rvte sobol)"
        )
    if not (folder / MANIFEST).is_file():
        raise InputError(
            field,
            str(folder),
            f"is not a study output folder: it has no {MANIFEST} (rvte mc and rvte sobol write one)",
        )
    return folder


def read_manifest(folder: Path) -> dict:
    """The manifest of an output folder that has one; InputError if it cannot be read."""
    try:
        manifest = json.loads((Path(folder) / MANIFEST).read_text())
        if not isinstance(manifest, dict):
            raise TypeError("not a JSON object")
        missing = [key for key in ("inputs_hash", "model_hash") if key not in manifest]
        if missing:
            raise KeyError(missing[0])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(
            "output",
            str(folder),
            f"has an unreadable {MANIFEST} ({exc}); "
            "it is not a study folder this run can trust: choose another output "
            "folder or delete this one",
        ) from None
    return manifest


def check_manifest(folder: Path, manifest: dict, study: Study) -> None:
    """Refuse (InputError) an output folder of another study or of another model version.

    Nothing is written: `open_output` and `tolerance.load_results` both use it.
    """
    theirs, their_model = manifest["inputs_hash"], manifest["model_hash"]
    model = model_fingerprint()
    if theirs != study.inputs_hash:
        raise InputError(
            "output",
            str(folder),
            f"belongs to another study "
            f"({manifest.get('study', '?')!r}, inputs hash {theirs[:12]}; this "
            f"study's is {study.inputs_hash[:12]}{_differences(folder, study)}): "
            "give this study another output folder, or delete that one to start "
            "afresh",
        )
    if their_model != model:
        raise InputError(
            "output",
            str(folder),
            "was computed by another version of the model "
            f"or of the sampling (model hash {their_model[:12]}, now "
            f"{model[:12]}): its batches cannot be mixed with new ones; use "
            "another output folder or delete this one",
        )


@dataclass(frozen=True)
class BatchResult:
    """Metrics of rows [start, stop): Y (stop-start, M), converged (stop-start,)."""

    start: int
    stop: int
    Y: np.ndarray
    converged: np.ndarray


class JobStore:
    """The batch files of one job (`mc`, `sobol-n1024`, ...) of a study."""

    def __init__(self, output: Path, study: Study, job: str):
        self.study = study
        self.job = job
        self.folder = Path(output) / job
        self.folder.mkdir(parents=True, exist_ok=True)
        self.columns = study.metric_columns
        self._remove_stale_temporaries()

    def load(self, n_rows: int, rows) -> dict:
        """Verified results of the batches of rows [0, n_rows) that have a file.

        Batches are the study's batch_size rows each, at fixed boundaries (the
        last one may be shorter); files of other ranges are left alone.
        rows(start, stop) -> the sample rows of that batch, to check that the
        file was computed from them.  Returns {(start, stop): BatchResult}.
        The folder is listed once, so a job of millions of batches costs one
        listing, not one look-up per batch.
        """
        size = self.study.batch_size
        return self._read_batches(
            rows,
            lambda start, stop: start < n_rows and not start % size and stop == min(start + size, n_rows),
        )

    def load_all(self, rows) -> dict:
        """Verified results of every batch file of the job, whatever rows it has reached.

        As `load`, for the batches at the study's boundaries (start a multiple
        of batch_size, at most batch_size rows): what `tolerance.load_results`
        reads.  Returns {(start, stop): BatchResult}, maybe with gaps (batches
        not computed yet).
        """
        size = self.study.batch_size
        return self._read_batches(rows, lambda start, stop: not start % size and start < stop <= start + size)

    def _read_batches(self, rows, wanted) -> dict:
        found = {}
        for (start, stop), paths in self.files().items():
            if not wanted(start, stop):
                continue
            if len(paths) > 1:
                raise InputError(
                    "batch",
                    str(paths[1]),
                    f"is a second file for rows {start}-{stop} beside {paths[0].name}; delete one of them",
                )
            found[(start, stop)] = self.read(paths[0], start, stop, rows(start, stop))
        return found

    def files(self) -> dict:
        """{(start, stop): [paths]} of every batch file in the job's folder."""
        files = {}
        for path in sorted(self.folder.glob("batch-*-*-*.parquet")):
            parts = path.stem.split("-")
            if len(parts) == 4 and parts[1].isdigit() and parts[2].isdigit():
                files.setdefault((int(parts[1]), int(parts[2])), []).append(path)
        return files

    def read(self, path: Path, start: int, stop: int, X: np.ndarray) -> BatchResult:
        """Read one batch file and check it against this study, its range and its rows."""
        try:
            digest = hashlib.sha256(path.read_bytes()).hexdigest()[:FILE_DIGEST]
        except OSError as exc:
            raise InputError("batch", str(path), f"cannot be read ({exc})") from None
        if not path.stem.endswith(f"-{digest}"):
            raise InputError(
                "batch",
                str(path),
                "is corrupted (its content does not match the "
                "checksum in its name); delete that file and run again to recompute "
                "its batch",
            )
        try:
            table = pq.read_table(path, page_checksum_verification=True)
            meta = json.loads(table.schema.metadata[METADATA_KEY])
        except (OSError, pa.ArrowException, ValueError, KeyError, TypeError) as exc:
            raise InputError(
                "batch",
                str(path),
                f"is corrupted or truncated ({_short(exc)}); "
                "delete that file and run again to recompute its batch",
            ) from None
        if meta.get("inputs_hash") != self.study.inputs_hash or meta.get("model_hash") != model_fingerprint():
            raise InputError(
                "batch",
                str(path),
                "belongs to another study or model version; "
                "delete it (or the whole output folder) and run again",
            )
        if (meta.get("start"), meta.get("stop"), meta.get("job")) != (start, stop, self.job):
            raise InputError(
                "batch",
                str(path),
                f"holds rows {meta.get('start')}-{meta.get('stop')} "
                f"of job {meta.get('job')!r}, not what its name says; delete it",
            )
        if meta.get("rows_sha256") != rows_hash(X):
            raise InputError(
                "batch",
                str(path),
                "was computed from other sample rows than this study draws; delete it and run again",
            )
        missing = [c for c in ("row", "converged", *self.columns) if c not in table.column_names]
        if missing:
            raise InputError("batch", str(path), f"has no column {missing[0]!r}; delete it")
        row = table.column("row").to_numpy()
        Y = (
            np.column_stack([table.column(c).to_numpy().astype(float) for c in self.columns])
            if self.columns
            else np.empty((stop - start, 0))
        )
        converged = table.column("converged").to_numpy(zero_copy_only=False).astype(bool)
        if not np.array_equal(row, np.arange(start, stop)) or meta.get("values_sha256") != values_hash(
            Y, converged
        ):
            raise InputError(
                "batch",
                str(path),
                "is corrupted (its values do not match the "
                "checksum written with them); delete it and run again",
            )
        return BatchResult(start, stop, Y, converged)

    def write(self, start: int, stop: int, X: np.ndarray, Y: np.ndarray, converged: np.ndarray) -> Path:
        """Write one finished batch (atomically: temporary file, then rename)."""
        Y = np.asarray(Y, dtype=float).reshape(stop - start, len(self.columns))
        converged = np.asarray(converged, dtype=bool)
        meta = {
            "format": FORMAT,
            "job": self.job,
            "start": start,
            "stop": stop,
            "inputs_hash": self.study.inputs_hash,
            "model_hash": model_fingerprint(),
            "rows_sha256": rows_hash(X),
            "values_sha256": values_hash(Y, converged),
            "columns": list(self.columns),
        }  # no time stamp: same results, same bytes
        data = {"row": np.arange(start, stop, dtype=np.int64), "converged": converged}
        data.update({c: Y[:, j] for j, c in enumerate(self.columns)})
        table = pa.table(data).replace_schema_metadata({METADATA_KEY: json.dumps(meta)})
        temporary = self.folder / f".batch-{start:09d}-{stop:09d}.{os.getpid()}.tmp"
        pq.write_table(table, temporary, write_page_checksum=True)
        digest = hashlib.sha256(temporary.read_bytes()).hexdigest()[:FILE_DIGEST]
        path = self.folder / f"batch-{start:09d}-{stop:09d}-{digest}.parquet"
        os.replace(temporary, path)
        return path

    def _remove_stale_temporaries(self):
        """Half-written batches of killed runs (their process is gone) are deleted."""
        for temporary in self.folder.glob(".batch-*.tmp"):
            pid = temporary.name.rsplit(".", 2)[-2]
            if not pid.isdigit() or not _alive(int(pid)):
                temporary.unlink(missing_ok=True)


PACKAGES = (
    "rvte",
    "numpy",
    "scipy",
    "SALib",
    "matplotlib",
    "pyarrow",
    "pandas",
    "numba",
    "dask",
    "openturns",
)


def software_versions() -> dict:
    """{package: version} of Python and the packages that compute and store the results."""
    import platform
    from importlib import metadata

    versions = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


def _differences(folder: Path, study: Study) -> str:
    """', differing in: tolerances, seed' from the folder's inputs.json, or '' if unreadable."""
    try:
        theirs = json.loads((folder / "inputs.json").read_text())
    except (OSError, ValueError):
        return ""
    ours = json.loads(json.dumps(study.inputs()))  # the same normalisation as the file
    keys = sorted(k for k in set(theirs) | set(ours) if theirs.get(k) != ours.get(k))
    return f", differing in: {', '.join(keys)}" if keys else ""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _write_atomic(path: Path, text: str) -> None:
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    temporary.write_text(text)
    os.replace(temporary, path)


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _short(exc: Exception) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."
