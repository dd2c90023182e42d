"""numba where it is installed: `kernel` compiles a function, `COMPILED` says whether it does.

The compiled functions of the model (`statics.kernels`, `statics.newton_kernel`,
`laws.pin_law`, `laws.roller_law`, `dynamics.dynamic_geometry`, `steppers.dynamic_reducer`)
all take `kernel` from here, so that none of them has to import another to get it.  Without numba
(a host Python that lacks it, or RVTE_NUMBA=0) `kernel` returns the function as it is:
the same results, as plain numpy, several times slower.

numba keys a cached function by the file that defines it, not by the files of the
functions it calls: newton_kernel's iteration, which inlines pin_law's `contact`, would
keep the old contact after pin_law.py changed, though the two live in different rooms.  So
the cache of the whole core is one unit: `SOURCES_STAMP` holds the digest of every source
file of rvfmu/core and its rooms, and when that digest changes every cached kernel of every
room goes before any is loaded.

RVTE_LAWS=newton selects the reference forms of the pins' and the roller bearings' laws,
inverted by Newton's method (`pin_law.contact_newton`, `roller_law.roller_law_newton`),
where the default ("direct") takes their forms without an inner iteration.  The choice is
made once, at import, because numba freezes a kernel's callees when it compiles it; kernels
compiled under it are not cached, so that the cache only ever holds the default forms.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

FOLDER = Path(__file__).parents[1]  # rvfmu/core: its rooms' kernels are one cache
SOURCES_STAMP = FOLDER / "__pycache__" / "kernels.sources"


def _numba():
    if os.environ.get("RVTE_NUMBA", "1") == "0":
        return None
    try:
        import numba
    except ImportError:
        return None
    return numba


def sources_digest() -> str:
    """sha256 of the core's source files (every room's), in the order of their paths."""
    digest = hashlib.sha256()
    for path in sorted(FOLDER.rglob("*.py")):
        name = path.relative_to(FOLDER).as_posix()
        digest.update(name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _drop_stale_cache():
    digest = sources_digest()
    try:
        if SOURCES_STAMP.read_text() == digest:
            return
    except OSError:
        pass
    try:
        for path in FOLDER.rglob("__pycache__/*.nb[ic]"):
            path.unlink(missing_ok=True)
        SOURCES_STAMP.parent.mkdir(exist_ok=True)
        SOURCES_STAMP.write_text(digest)
    except OSError:  # a read-only install: numba compiles without a cache there
        pass


def _law_forms() -> bool:
    """Whether RVTE_LAWS asks for the Newton-inverted reference laws."""
    forms = os.environ.get("RVTE_LAWS", "direct")
    if forms not in ("direct", "newton"):
        from .checks import InputError

        raise InputError("RVTE_LAWS", forms, "must be 'direct' (the default) or 'newton'", "environment")
    return forms == "newton"


NEWTON_LAWS = _law_forms()
_NUMBA = _numba()
COMPILED = _NUMBA is not None
if COMPILED:
    _drop_stale_cache()


def kernel(function=None, *, inline: bool = False):
    """`function` compiled by numba (cached on disk where its folder allows), or as it is.

    `@kernel(inline=True)`: numba also writes its body into every kernel that calls it (numba's
    IR inlining, `inline="always"`), instead of a call.  For a kernel called in an inner loop
    with many arrays, as the dynamic model's forces with the model's two named tuples of
    arrays: such a call cost 1.4 us before a line of its body ran, a quarter of an evaluation
    (studies/benchmarks/bench_dynamic.py).  The arithmetic is the same, and so are the results.
    """
    if function is None:
        return lambda f: kernel(f, inline=inline)
    if _NUMBA is None:
        return function
    options = {"nogil": True, "error_model": "numpy"} | ({"inline": "always"} if inline else {})
    try:
        return _NUMBA.njit(cache=not NEWTON_LAWS, **options)(function)
    except RuntimeError:  # no writable cache location (e.g. a read-only install)
        return _NUMBA.njit(**(options | {"error_model": "python"}))(function)
