"""What every room of the core uses: unit conversions (`units`), input checks and the error
they raise (`checks`), and numba's `kernel` with the cache that spans the whole core
(`compiled`).

May import: nothing of rvfmu.
"""
