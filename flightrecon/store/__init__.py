"""flightrecon.store: per-aircraft store of Sabziev coefficients and sensor calibrations.

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
calibration : per-flight sensor-error estimates of the joint smoother and their fusion per
    aircraft (inverse variance, random-walk drift, outliers, sensor changes)
identity : which record a flight's log belongs to (content hash, collisions)
api : :class:`CoefficientStore`
adapt : :func:`from_sabziev_summary` and :func:`from_joint_summary`, the records of a run

See docs/store.md.
"""

from flightrecon.store.adapt import from_joint_summary, from_sabziev_summary
from flightrecon.store.api import CALIBRATION_CSV_COLUMNS, CSV_COLUMNS, CoefficientStore
from flightrecon.store.calibration import (PERSISTENT, AircraftCalibration, FlightCalibration,
                                           QuantityCalibration, SensorChange, SensorEstimate)
from flightrecon.store.identity import Identity
from flightrecon.store.db import default_store_path
from flightrecon.store.records import (AXES, BRANCHES, NO_ROOT, AircraftStats, AxisStats,
                                       Exclusion, FleetMean, FlightCoefficients, PropertyStats)
from flightrecon.store.schema import SCHEMA_VERSION

__all__ = [
    "CALIBRATION_CSV_COLUMNS", "PERSISTENT", "AircraftCalibration", "FlightCalibration",
    "Identity", "QuantityCalibration", "SensorChange", "SensorEstimate", "from_joint_summary",
    "AXES", "BRANCHES", "CSV_COLUMNS", "NO_ROOT", "SCHEMA_VERSION", "AircraftStats", "AxisStats",
    "CoefficientStore", "Exclusion", "FleetMean", "FlightCoefficients", "default_store_path",
    "from_sabziev_summary", "PropertyStats",
]
