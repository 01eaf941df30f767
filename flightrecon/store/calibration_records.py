"""Per-aircraft sensor calibration records: one flight's estimates of the persistent sensor
errors (:class:`FlightCalibration`), the sensor changes and the fused result's types, with
the constants of the fusion rule (:mod:`flightrecon.store.calibration`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any


from flightrecon.errors import StoreError
from flightrecon.store.records import finite_number, bool_flag, check_flight_identity

#: the persistent sensor errors the joint smoother estimates (keys of its ``corrections``) that
#: belong to the aircraft: fused over its flights and, with ``--use-fleet-coefficients``, used as
#: the joint smoother's priors on a new flight
PERSISTENT: tuple[str, ...] = (
    "tas_scale", "heading_bias_deg", "roll_bias_deg", "pitch_bias_deg",
    "accel_bias_x_g", "accel_bias_y_g", "accel_bias_z_g",
    "accel_scale_x", "accel_scale_y", "accel_scale_z", "doppler_scale", "drift_bias_deg",
)
#: recorded and fused for display, never applied as priors: the pressure-altitude offset and
#: scale carry the day's QNH and atmosphere besides the static-source error (the model cannot
#: separate them), and the wind gradient is the day's weather
DAY_DEPENDENT: tuple[str, ...] = ("baro_offset_m", "baro_scale", "wind_gradient_n_per_km",
                                  "wind_gradient_e_per_km")
#: a flight whose sd is at least this fraction of its prior sd has not observed the error
UNOBSERVED_RATIO = 0.95
#: a flight this many standard deviations from the fusion of the others is an outlier
OUTLIER_Z = 4.0
#: fewest flights used before the worst can be excluded as an outlier (two others to judge it)
MIN_FLIGHTS_OUTLIER = 3
#: fewest flights for a maximum-likelihood drift (fewer: q = 0, said in the result)
MIN_FLIGHTS_DRIFT = 3
#: the sensor-change wildcard (every quantity)
ALL_QUANTITIES = "*"


@dataclass(frozen=True)
class SensorEstimate:
    """One persistent sensor error as estimated on one flight.

    Attributes
    ----------
    quantity : name (a key of the joint smoother's ``corrections``, e.g. ``tas_scale``)
    value, sd : the smoother's estimate and standard deviation, in ``unit``
    prior_mean, prior_sd : the prior the smoother used for it on that flight
    unit : unit text as the smoother reports it
    """

    quantity: str
    value: float
    sd: float
    prior_mean: float
    prior_sd: float
    unit: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.quantity, str) or not self.quantity.strip():
            raise StoreError(f"sensor estimate: quantity must be a non-empty string, "
                             f"got {self.quantity!r}")
        q = self.quantity
        for name in ("value", "sd", "prior_mean", "prior_sd"):
            object.__setattr__(self, name, finite_number(getattr(self, name), f"{q}.{name}"))
        if self.sd < 0:
            raise StoreError(f"{q}.sd: must be >= 0, got {self.sd}")
        if self.prior_sd <= 0:
            raise StoreError(f"{q}.prior_sd: must be > 0, got {self.prior_sd}")

    def data_only(self) -> tuple[float, float] | None:
        """The flight's own information with the prior divided out: ``(m_d, s_d)``, or
        ``None`` when the flight did not observe the error (sd >= UNOBSERVED_RATIO prior sd)."""
        if self.sd >= UNOBSERVED_RATIO * self.prior_sd:
            return None
        if self.sd <= 0.0:
            return self.value, 0.0
        info = 1.0 / self.sd ** 2 - 1.0 / self.prior_sd ** 2
        var = 1.0 / info
        return var * (self.value / self.sd ** 2 - self.prior_mean / self.prior_sd ** 2), \
            math.sqrt(var)


@dataclass(frozen=True, eq=False)
class FlightCalibration:
    """The joint smoother's estimates of the persistent sensor errors on one flight, with the
    conditions that make flights comparable.

    Attributes
    ----------
    aircraft_id, flight_id : identifiers; ``(aircraft_id, flight_id)`` unique in the store
    flight_date_utc : take-off time or date, UTC
    estimates : the :class:`SensorEstimate` of each quantity
    configuration : the aircraft configuration the flight was flown in (free text from the
        metadata, ``""`` when not given); only flights of the same configuration are fused
        for a target that names one
    sources : the measurement sources the smoother used (``air+baro+gnss_pos+...``)
    duration_s : length of the record [s]
    tas_range_mps : 5th and 95th percentile of the airborne true airspeed [m/s]
    alt_range_m : 5th and 95th percentile of the pressure altitude [m]
    converged : the joint smoother converged
    software_version, settings, input_hashes : provenance
    log_sha256 : SHA-256 of the flight's log (its content identity)
    recorded_at_utc : set by the store
    """

    aircraft_id: str
    flight_id: str
    flight_date_utc: str
    estimates: tuple[SensorEstimate, ...]
    configuration: str = ""
    sources: str = ""
    duration_s: float = 1.0
    tas_range_mps: tuple[float, float] = (math.nan, math.nan)
    alt_range_m: tuple[float, float] = (math.nan, math.nan)
    converged: bool = True
    software_version: str = "unknown"
    settings: dict[str, Any] = field(default_factory=dict)
    input_hashes: dict[str, Any] = field(default_factory=dict)
    log_sha256: str | None = None
    recorded_at_utc: str | None = None

    def __post_init__(self) -> None:
        check_flight_identity(self)
        set_ = object.__setattr__
        est = tuple(self.estimates)
        if not all(isinstance(e, SensorEstimate) for e in est):
            raise StoreError("estimates: expected SensorEstimate records")
        names = [e.quantity for e in est]
        if len(set(names)) != len(names):
            raise StoreError(f"estimates: a quantity appears twice in {names}")
        set_(self, "estimates", est)
        dur = finite_number(self.duration_s, "duration_s")
        if dur <= 0:
            raise StoreError(f"duration_s: must be positive, got {dur}")
        set_(self, "duration_s", dur)
        set_(self, "converged", bool_flag(self.converged, "converged"))
        for name in ("tas_range_mps", "alt_range_m"):
            r = tuple(getattr(self, name))
            if len(r) != 2:
                raise StoreError(f"{name}: expected (low, high), got {r!r}")
            set_(self, name, tuple(math.nan if x is None else float(x) for x in r))
        for name in ("configuration", "sources"):
            if not isinstance(getattr(self, name), str):
                raise StoreError(f"{name}: expected text, got {getattr(self, name)!r}")

    def estimate(self, quantity: str) -> SensorEstimate | None:
        """The estimate of ``quantity`` (``None`` if not recorded)."""
        for e in self.estimates:
            if e.quantity == quantity:
                return e
        return None

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (NaN stays NaN; the CLI maps it to null)."""
        return {
            "aircraft_id": self.aircraft_id, "flight_id": self.flight_id,
            "flight_date_utc": self.flight_date_utc, "configuration": self.configuration,
            "sources": self.sources, "duration_s": self.duration_s,
            "tas_range_mps": list(self.tas_range_mps), "alt_range_m": list(self.alt_range_m),
            "converged": self.converged, "software_version": self.software_version,
            "settings": self.settings, "input_hashes": self.input_hashes,
            "log_sha256": self.log_sha256, "recorded_at_utc": self.recorded_at_utc,
            "estimates": {e.quantity: {"value": e.value, "sd": e.sd, "prior_mean": e.prior_mean,
                                       "prior_sd": e.prior_sd, "unit": e.unit}
                          for e in self.estimates},
        }

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FlightCalibration):
            return NotImplemented

        def norm(d):
            return {k: ([None if isinstance(x, float) and math.isnan(x) else x for x in v]
                        if isinstance(v, list) else v) for k, v in d.items()}
        return norm(self.as_dict()) == norm(other.as_dict())


@dataclass(frozen=True)
class SensorChange:
    """A sensor change: flights before ``change_utc`` no longer describe ``quantity`` after it
    (``quantity`` ``"*"``: every sensor)."""

    aircraft_id: str
    quantity: str
    change_utc: str
    note: str = ""


@dataclass(frozen=True)
class CalibrationExclusion:
    """A flight left out of one quantity's fusion, and why."""

    flight_id: str
    reason: str
    z: float | None = None


@dataclass(frozen=True)
class QuantityCalibration:
    """The fused calibration of one sensor error of one aircraft at a date.

    Attributes
    ----------
    quantity, unit : which error, in the smoother's unit
    at_utc : the date the estimate is for
    n : flights used
    mean, sd : the fused estimate ``x(t*)`` and its standard deviation (the population prior's
        when ``n == 0``)
    prior_mean, prior_sd : the population prior (the smoother's default)
    drift_sd_per_sqrt_day : q of the random walk used
    drift_source : ``"set"``, ``"estimated"`` (maximum likelihood) or ``"none: ..."`` (q = 0)
    flights : the flight ids used, by date
    z : per flight used, its distance from the fusion of the others (sd units)
    excluded : the flights left out, with reasons
    persistent : a property of the aircraft (applied as a prior); False for day-dependent ones
    """

    quantity: str
    unit: str
    at_utc: str
    n: int
    mean: float
    sd: float
    prior_mean: float
    prior_sd: float
    drift_sd_per_sqrt_day: float
    drift_source: str
    flights: tuple[str, ...] = ()
    z: tuple[float, ...] = ()
    excluded: tuple[CalibrationExclusion, ...] = ()
    persistent: bool = True


@dataclass(frozen=True)
class AircraftCalibration:
    """An aircraft's fused calibration at a date: one :class:`QuantityCalibration` per error."""

    aircraft_id: str
    at_utc: str
    configuration: str | None
    n_flights: int
    quantities: tuple[QuantityCalibration, ...]
    changes: tuple[SensorChange, ...] = ()

    def quantity(self, name: str) -> QuantityCalibration:
        for q in self.quantities:
            if q.quantity == name:
                return q
        raise StoreError(f"aircraft '{self.aircraft_id}' has no calibration of '{name}'")

    def priors(self) -> dict[str, tuple[float, float]]:
        """``{quantity: (mean, sd)}`` of the persistent errors observed on at least one flight:
        the joint smoother's priors for a new flight of this aircraft."""
        return {q.quantity: (q.mean, q.sd) for q in self.quantities
                if q.persistent and q.n > 0 and math.isfinite(q.mean) and q.sd > 0}

    def flights_used(self) -> tuple[str, ...]:
        """Every flight used by at least one applied quantity, sorted."""
        return tuple(sorted({f for q in self.quantities if q.persistent for f in q.flights}))


