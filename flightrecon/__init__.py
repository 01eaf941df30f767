"""flightrecon: post-flight reconstruction of an aircraft's trajectory from recorded data.

Units: SI inside (metres, seconds, radians in the maths); column names carry their unit
(``_m``, ``_mps``, ``_deg``, ``_g``, ``_s``).  Conventions: see ``docs/schema.md``.
"""

from flightrecon import numba_cache

# where the compiled kernels are cached: before any kernel module is imported (a read-only
# installation with an unwritable home must still run)
numba_cache.configure()

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``__version__``, read from the installed package's metadata on first use
    (:mod:`importlib.metadata` costs 15-30 ms to import: a command that does not print or
    record the version does not pay it)."""
    if name != "__version__":
        raise AttributeError(f"module 'flightrecon' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("flightrecon")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        found = "0.0.0+unknown"
    globals()["__version__"] = found
    return found
