"""flightrecon.store: per-aircraft store of Sabziev coefficients and their averages.

The Sabziev fusion fits one coefficient per axis (k1, k2, k3) on each flight that has a known
arrival point.  Sabziev (2020, Conclusions) proposes that the coefficients depend mainly on the
aircraft, so their mean over an aircraft's flights can reconstruct a flight whose arrival point
is unknown (docs/sabziev.md).  This package keeps those fits, one SQLite file for the whole
fleet, and computes the averages.

Modules
-------
records : :class:`FlightCoefficients` (one fit), :class:`AircraftStats`, :class:`FleetMean`
db : file location, identity checks, schema and migrations, transactions
stats : the averaging rule (converged fits, majority branch per axis, drift over time)
api : :class:`CoefficientStore`
adapt : :func:`from_sabziev_summary`, the record of a Sabziev method run

See docs/store.md.
"""

from flightrecon.store.adapt import from_sabziev_summary
from flightrecon.store.api import CSV_COLUMNS, CoefficientStore
from flightrecon.store.db import SCHEMA_VERSION, default_store_path
from flightrecon.store.records import (AXES, BRANCHES, NO_ROOT, AircraftStats, AxisStats,
                                       Exclusion, FleetMean, FlightCoefficients)

__all__ = [
    "AXES", "BRANCHES", "CSV_COLUMNS", "NO_ROOT", "SCHEMA_VERSION", "AircraftStats", "AxisStats",
    "CoefficientStore", "Exclusion", "FleetMean", "FlightCoefficients", "default_store_path",
    "from_sabziev_summary",
]
