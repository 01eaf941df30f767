"""flightrecon: post-flight reconstruction of an aircraft's trajectory from recorded data.

Units: SI inside (metres, seconds, radians in the maths); column names carry their unit
(``_m``, ``_mps``, ``_deg``, ``_g``, ``_s``).  Conventions: see ``docs/schema.md``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("flightrecon")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

from flightrecon import _numba_cache

# where the compiled kernels are cached: before any kernel module is imported (a read-only
# installation with an unwritable home must still run)
_numba_cache.configure()

__all__ = ["__version__"]
