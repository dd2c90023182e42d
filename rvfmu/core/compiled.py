"""numba where it is installed: `kernel` compiles a function, `COMPILED` says whether it does.

The compiled functions of the model (`kernels`, `newton_kernel`, `roller_law`) all take
`kernel` from here, so that none of them has to import another to get it.  Without numba
(a host Python that lacks it, or RVTE_NUMBA=0) `kernel` returns the function as it is:
the same results, as plain numpy, several times slower.
"""

from __future__ import annotations

import os


def _numba():
    if os.environ.get("RVTE_NUMBA", "1") == "0":
        return None
    try:
        import numba
    except ImportError:
        return None
    return numba


_NUMBA = _numba()
COMPILED = _NUMBA is not None


def kernel(function):
    """`function` compiled by numba (cached on disk where its folder allows), or as it is."""
    if _NUMBA is None:
        return function
    try:
        return _NUMBA.njit(cache=True, nogil=True)(function)
    except RuntimeError:    # no writable cache location (e.g. a read-only install)
        return _NUMBA.njit(nogil=True)(function)
