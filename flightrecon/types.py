"""Small frozen dataclasses that flow one way through the pipeline.

ingest -> :class:`Flight` -> cleaning -> :class:`CleanFlight` -> estimators -> :class:`MethodResult`
-> export.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import pandas as pd


@dataclass(frozen=True)
class Position:
    """A point on the WGS-84 ellipsoid.

    ``elev_m`` is the elevation above mean sea level for airfields and stations (the way they
    are published); code that needs ellipsoidal height says so.  ``runway_true_deg`` is, for an
    airfield, the true direction of the runway used (the take-off or landing direction, from the
    runway designator or a database; ``None`` when unknown): it fixes the heading reference
    on the ground roll (docs/joint.md).  ``threshold_lat_deg`` / ``threshold_lon_deg`` locate
    the threshold of that runway (where the take-off roll begins and the landing runway
    starts; from the aeronautical information publication or a runway database); given with
    ``runway_true_deg``, they place the start of the take-off roll and the touchdown along
    the runway (docs/joint.md).
    """

    lat_deg: float
    lon_deg: float
    elev_m: float = 0.0
    runway_true_deg: float | None = None
    threshold_lat_deg: float | None = None
    threshold_lon_deg: float | None = None

    @property
    def threshold(self) -> tuple[float, float] | None:
        """(lat, lon) of the runway threshold, or ``None`` when not given."""
        if self.threshold_lat_deg is None or self.threshold_lon_deg is None:
            return None
        return (self.threshold_lat_deg, self.threshold_lon_deg)

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.lat_deg, self.lon_deg, self.elev_m)


@dataclass(frozen=True)
class PositionFix:
    """A known position at a given time (``--fix``: a radar return, a waypoint report, a
    witness): ``t_s`` in the log's time base, latitude and longitude [deg], ``alt_msl_m`` (MSL,
    ``None`` when unknown) and ``sd_m``, the standard deviation per horizontal axis [m]."""

    t_s: float
    lat_deg: float
    lon_deg: float
    alt_msl_m: float | None = None
    sd_m: float = 100.0


@dataclass(frozen=True)
class WindLevel:
    """One level of a winds-aloft prior (``--wind``): MSL altitude [m], meteorological
    direction (where the wind blows from) [deg, 0-360), speed [m/s], standard deviation of each
    wind component [m/s]."""

    alt_msl_m: float
    from_deg: float
    speed_mps: float
    sd_mps: float = 2.0


@dataclass(frozen=True)
class IngestRecord:
    """What reading the log did and found, recorded by :func:`flightrecon.ingest.load_flight`
    for the cleaning report, the estimators, the summary and ``flightrecon info`` (JSON-ready
    entries, in the order they were made).

    Attributes
    ----------
    notes : the conversions and decisions of the reading, one sentence each
    repairs : the validation repairs (``flightrecon.ingest.validate.Repair.as_dict``: values
        outside the physical range, ...)
    door : every check of the door with its figure and verdict
        (``flightrecon.ingest.door.DoorCheck.as_dict``, docs/door.md)
    mapping, sidecar : the column-mapping and the metadata file read (``None``: none)
    derived_channels : channel -> how it was computed at ingest (not recorded); the estimators
        widen their error model for these
    ignored_columns : the log's columns mapped to no channel
    gnss_use : the analyst's GNSS options (``options``) and the fixes they removed
        (:mod:`flightrecon.ingest.gnss_use`); empty when none was given
    recorder : the variant and conventions a Garmin export shows
        (:mod:`flightrecon.ingest.garmin`); ``None`` for other logs
    """

    notes: tuple[str, ...] = ()
    repairs: tuple[dict[str, Any], ...] = ()
    door: tuple[dict[str, Any], ...] = ()
    mapping: str | None = None
    sidecar: str | None = None
    derived_channels: Mapping[str, str] = field(default_factory=dict)
    ignored_columns: tuple[str, ...] = ()
    gnss_use: Mapping[str, Any] = field(default_factory=dict)
    recorder: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class ArrivalNotEnd:
    """The evidence that the arrival given is not where the record ends (it ends in the air):
    the cleaning then drops the arrival (:mod:`flightrecon.cleaning.arrival_end`).

    Attributes
    ----------
    arrival : the arrival given
    t_end_s : time of the record's last sample [s]
    tas_mps : true airspeed over the record's last second (median) [m/s]
    height_above_field_m : pressure altitude over the last second (median) above the arrival
        field's [m]
    margin_m : the height that proves an airborne end [m]
    qnh_hpa : the QNH used for the field's pressure altitude (the arrival's, else the
        departure's; ``None``: standard atmosphere)
    """

    arrival: Position
    t_end_s: float
    tas_mps: float
    height_above_field_m: float
    margin_m: float
    qnh_hpa: float | None


@dataclass(frozen=True)
class FlightMeta:
    """Flight metadata, from the command line or a sidecar file next to the log.

    Attributes
    ----------
    epoch_utc : ISO-8601 UTC time that ``t_s = 0`` stands for (``None`` if unknown)
    departure, arrival : airfield reference or lift-off / touchdown point (MSL elevation)
    station : ground radar (angle-range measuring system) position
    gnss_lever_arm_m : GNSS antenna position in body FRD axes relative to the centre of mass
    gnss_alt_datum : ``"ellipsoid"`` or ``"msl"``
    baro_datum : ``"pressure"`` (1013.25 hPa) unless the log says otherwise
    qnh_departure_hpa, qnh_arrival_hpa : sea-level pressure at the airfields, where known
    geoid_undulation_m : ellipsoidal height minus MSL height in the area of the flight (one value
        per flight: the sidecar's or the command line's, else EGM96's at the departure or the
        first GNSS fix, :mod:`flightrecon.geo.geoid`; 0 for a flight with no position)
    geoid_model : ``"EGM96"`` when the undulation is the model's (the results' ``alt_msl_m``
        then takes the model's N at each sample), ``None`` when given
    fixes : known positions at given times (:class:`PositionFix`, ``--fix``), sorted by time
    attitude_source : what measured roll and pitch: ``"ahrs"`` (an attitude and heading
        reference that erects on the accelerometers, wrong after sustained loads), ``"inertial"``
        (an inertial reference, or the simulator's truth), ``None`` undeclared (taken as
        inertial, with a warning where the loads make it matter; docs/joint.md)
    wind_aloft : winds-aloft prior by altitude (:class:`WindLevel`, ``--wind``), sorted
    origin : origin of the output frame when no departure is given: the first GNSS fix (or radar
        plot) of the record, set by the cleaning layer (MSL elevation); never an airfield
    configuration : the aircraft configuration the flight was flown in (the sidecar's
        ``[flight] configuration``, for the coefficient store; ``None`` when not given)
    ingest : what reading the log did and found (:class:`IngestRecord`)
    arrival_not_end : why the arrival given was dropped (:class:`ArrivalNotEnd`), else ``None``
    extra : the sidecar's keys and tables this schema does not know, as read (free-form)
    """

    aircraft_id: str | None = None
    flight_id: str | None = None
    epoch_utc: str | None = None
    departure: Position | None = None
    arrival: Position | None = None
    station: Position | None = None
    gnss_lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gnss_alt_datum: str = "ellipsoid"
    baro_datum: str = "pressure"
    qnh_departure_hpa: float | None = None
    qnh_arrival_hpa: float | None = None
    geoid_undulation_m: float = 0.0
    geoid_model: str | None = None
    attitude_source: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    fixes: tuple[PositionFix, ...] = ()
    wind_aloft: tuple[WindLevel, ...] = ()
    origin: Position | None = None
    configuration: str | None = None
    ingest: IngestRecord = field(default_factory=IngestRecord)
    arrival_not_end: ArrivalNotEnd | None = None


#: the fields of :class:`FlightMeta` that are records of the processing, not the flight's
#: declared metadata (left out of :func:`declared_metadata`)
RECORD_FIELDS = ("extra", "ingest", "arrival_not_end")


def declared_metadata(meta: FlightMeta) -> dict[str, Any]:
    """``meta`` as a JSON-ready dict of the flight's metadata (the summary's ``flight``,
    ``info``'s ``metadata``): every field but the records of the processing
    (:data:`RECORD_FIELDS`), and ``configuration`` only when given."""
    d = asdict(meta)
    for name in RECORD_FIELDS:
        d.pop(name)
    if d["configuration"] is None:
        d.pop("configuration")
    return d


@dataclass(frozen=True)
class Flight:
    """A validated flight in the canonical schema (output of :mod:`flightrecon.ingest`).

    ``data`` has a ``t_s`` column, sorted strictly increasing, and canonical channel columns;
    multi-rate logs leave NaN where a channel was not sampled.  ``row`` holds the 1-based data
    row in the (first) source file, for error messages downstream.
    """

    data: pd.DataFrame
    meta: FlightMeta
    sources: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class FlightPhases:
    """Lift-off and touchdown detected in the record (times in ``t_s``; NaN if not in record).

    ``starts_airborne`` / ``ends_airborne`` say that the record is cut in the air.
    ``liftoff_velocity_ned_mps`` is the ground velocity at lift-off estimated from the ground roll.
    ``lineup_t_s`` is when the aircraft turned onto the take-off runway heading (the end of the
    taxi; the record's start when it starts lined up), ``roll_start_t_s`` when the take-off roll
    began (NaN where there is no ground roll in the record).  ``impact_t_s`` and
    ``impact_peak_load_g`` are the ground impact that ends an accident record (its first sample
    and the largest load-factor magnitude from there to the end; NaN where the record does not
    end at an impact: :mod:`flightrecon.cleaning.impact`).
    """

    liftoff_t_s: float
    touchdown_t_s: float
    starts_airborne: bool
    ends_airborne: bool
    liftoff_velocity_ned_mps: tuple[float, float, float]
    lineup_t_s: float = float("nan")
    roll_start_t_s: float = float("nan")
    impact_t_s: float = float("nan")
    impact_peak_load_g: float = float("nan")


@dataclass(frozen=True)
class CleanFlight:
    """Cleaned flight (output of :mod:`flightrecon.cleaning`).

    Attributes
    ----------
    grid : uniform time grid: ``t_s`` plus every input channel present, and for each a boolean
        ``<channel>_valid`` mask (False where a long gap was left unfilled, values NaN there).
        ``heading_deg`` and other angles are unwrapped (continuous, may leave [0, 360));
        ``roll_deg`` is wrapped to [-180, 180) (interpolated the short way across +-180 deg).
        ``<channel>_saturated`` (where a channel reached its recorder range:
        :mod:`flightrecon.cleaning.saturation`) flags the samples at the range limit.
    rate_hz : grid rate
    gnss, radar : measurements at their own times (one row per fix / plot; ``t_s`` first),
        empty DataFrames when absent
    meta : flight metadata
    report : cleaning report, one dict per action (channel, what, rows / times, why)
    phases : lift-off and touchdown
    """

    grid: pd.DataFrame
    rate_hz: float
    gnss: pd.DataFrame
    radar: pd.DataFrame
    meta: FlightMeta
    report: tuple[dict[str, Any], ...] = ()
    phases: FlightPhases | None = None


@dataclass(frozen=True)
class MethodResult:
    """One estimator's contribution to a reconstruction.

    Attributes
    ----------
    name : method name (``"sabziev"``, ``"arms"``, ``"azimuth"``, ``"sns"``, ``"joint"``)
    track : DataFrame on the output time grid, ``t_s`` plus the method's columns *with* its
        prefix (``sabziev_north_m``, ``sabziev_north_sd_m``, ...).  Positions are in the tangent
        plane at the departure airfield (north/east/up, metres).
    summary : JSON-serialisable dict for the summary file (coefficients, convergence, residuals,
        estimated corrections with their standard deviations, warnings)
    """

    name: str
    track: pd.DataFrame
    summary: dict[str, Any]
