"""Giving memory back between the stages of a reconstruction.

Reading a log goes through Arrow (Parquet and CSV readers), whose allocator keeps the buffers
it freed for reuse; cleaning allocates and frees arrays of many megabytes on the C heap, which
glibc keeps when the process asked it not to trim (``flightrecon.cli.main._tune_memory``).
Neither is reused by the estimators' large arrays (those are mapped fresh), so what the first
stages freed would otherwise stay in the process for the whole run and add to its peak.
:func:`release_unused` hands it back; it changes no result.  Measured on the 10-hour benchmark
flight (docs/performance.md, "Memory").
"""

from __future__ import annotations

import sys


def release_unused() -> None:
    """Return the memory that Arrow's pool and the C heap hold free to the operating system.

    Arrow's ``release_unused`` and glibc's ``malloc_trim(0)``; each is skipped where it is not
    available (no pyarrow, not glibc).
    """
    try:
        import pyarrow as pa

        pa.default_memory_pool().release_unused()
    except Exception:  # noqa: BLE001 - an allocator without the call: nothing to release
        pass
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL("libc.so.6").malloc_trim(0)
        except (OSError, AttributeError):  # not glibc
            pass
