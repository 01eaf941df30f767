"""flightrecon: post-flight reconstruction of an aircraft's trajectory from recorded data.

Units: SI inside (metres, seconds, radians in the maths); column names carry their unit
(``_m``, ``_mps``, ``_deg``, ``_g``, ``_s``).  Conventions: see ``docs/schema.md``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("flightrecon")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
