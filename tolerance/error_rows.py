"""A batch of reducers given by their error components rather than by sample rows.

A study's sample rows are points of the unit hypercube that `sampling.errors_from_unit`
turns into errors.  Some jobs choose the errors themselves (the central differences of
`tolerance.linearized`): their rows are error vectors, every component of every error of
`MODEL.md` section 4 in SI units, laid out by `error_vector`.  `ErrorRows` carries such a
batch through a backend to `evaluate.evaluate`, which then returns the model's outputs
(TE curve and scalar metrics, `evaluate.output_columns`) instead of the metrics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rvfmu.core.reducer.errors import CLEARANCES, ErrorSet


def error_vector(errors: ErrorSet) -> np.ndarray:
    """(S, P) every error component of S reducers [m]: each error's array flattened, a phased
    error as its real parts then its imaginary parts, in the order of `ErrorSet`."""
    parts = []
    for array in errors.arrays().values():
        flat = array.reshape(array.shape[0], -1)
        parts += [flat.real, flat.imag] if np.iscomplexobj(flat) else [flat]
    return np.concatenate(parts, axis=1).astype(float)


def error_set(vectors: np.ndarray, like: ErrorSet) -> ErrorSet:
    """The ErrorSet of error vectors (S, P) laid out as `error_vector` lays out `like`."""
    vectors = np.atleast_2d(vectors)
    S, start, arrays = vectors.shape[0], 0, {}
    for name, array in like.arrays().items():
        shape, size = array.shape[1:], int(np.prod(array.shape[1:], dtype=int))
        if np.iscomplexobj(array):
            values = vectors[:, start : start + size] + 1j * vectors[:, start + size : start + 2 * size]
            start += 2 * size
        else:
            values = vectors[:, start : start + size]
            start += size
        arrays[name] = np.ascontiguousarray(values).reshape((S,) + shape)
    return ErrorSet(**arrays)


def clearance_components(like: ErrorSet) -> np.ndarray:
    """(P,) bool: the components of `error_vector` that are clearances (never below zero)."""
    marks = []
    for name, array in like.arrays().items():
        size = int(np.prod(array.shape[1:], dtype=int)) * (2 if np.iscomplexobj(array) else 1)
        marks.append(np.full(size, name in CLEARANCES))
    return np.concatenate(marks)


@dataclass(frozen=True)
class ErrorRows:
    """A batch of reducers by their error vectors (S, P) [m], laid out as `like` (an ErrorSet
    of one reducer of the same design)."""

    vectors: np.ndarray
    like: ErrorSet

    @property
    def shape(self) -> tuple:
        return self.vectors.shape

    def errors(self) -> ErrorSet:
        """The rows as an ErrorSet of S reducers, each array (S, ...) [m], laid out as `like`."""
        return error_set(self.vectors, self.like)
