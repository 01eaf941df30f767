"""Records of the coefficient store: one flight's Sabziev coefficients and per-aircraft statistics.

Units: ``k1`` and ``k3`` in 1/s (along-track complementary-filter coefficients of the x and z
equations), ``k2`` in 1/s^2 (baro-inertial loop of the y equation); see docs/sabziev.md.
Times are UTC, written as ISO-8601 strings ``YYYY-MM-DDTHH:MM:SSZ`` (microseconds kept when given).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import date, datetime, timezone
from typing import Any

import numpy as np

from flightrecon.errors import StoreError

#: names of the three coefficients, in axis order (x/north, y/up, z/east in the Sabziev frame)
AXES: tuple[str, str, str] = ("k1", "k2", "k3")

#: root branches: ``negative`` is the physical one (stable filter / oscillating baro loop),
#: ``positive`` grows like exp(k T) and is reported as unphysical (docs/sabziev.md)
BRANCHES: tuple[str, str] = ("negative", "positive")
#: branch of an axis on which the solver found no root (only on a non-converged axis)
NO_ROOT = "none"


def utc_text(value: str | datetime | date, what: str) -> str:
    """Normalise a UTC time to ``YYYY-MM-DDTHH:MM:SS[.ffffff]Z``.

    Parameters
    ----------
    value
        A timezone-aware :class:`datetime`, a :class:`date` (taken as 00:00 UTC) or an ISO-8601
        string.  A string or datetime without a timezone is refused: a store shared between
        analysts in different time zones must not guess.
    what
        Field name for the error message.

    Raises
    ------
    StoreError
        Unparseable text or a time without a timezone.
    """
    if isinstance(value, str):
        text = value.strip()
        if len(text) == 10:  # a bare date YYYY-MM-DD
            try:
                value = date.fromisoformat(text)
            except ValueError as exc:
                raise StoreError(f"{what}: not an ISO-8601 date: '{value}'") from exc
        else:
            try:
                value = datetime.fromisoformat(text.replace("Z", "+00:00").replace("z", "+00:00"))
            except ValueError as exc:
                raise StoreError(f"{what}: not an ISO-8601 UTC time: '{value}'") from exc
    if isinstance(value, datetime):
        if value.tzinfo is None or value.utcoffset() is None:
            raise StoreError(f"{what}: time '{value.isoformat()}' has no timezone; give it in UTC "
                             "(suffix Z or +00:00)")
        dt = value.astimezone(timezone.utc)
    elif isinstance(value, date):
        dt = datetime(value.year, value.month, value.day, tzinfo=timezone.utc)
    else:
        raise StoreError(f"{what}: expected a date, datetime or ISO-8601 string, "
                         f"got {type(value).__name__}")
    spec = "microseconds" if dt.microsecond else "seconds"
    return dt.replace(tzinfo=None).isoformat(timespec=spec) + "Z"


def utc_days(text: str) -> float:
    """Days since 1970-01-01T00:00Z of a normalised UTC string (for the drift regression)."""
    dt = datetime.fromisoformat(text.replace("Z", "+00:00"))
    return dt.timestamp() / 86400.0


def now_utc_text() -> str:
    """The current time as a normalised UTC string."""
    return utc_text(datetime.now(timezone.utc), "now")


def _number_or_nan(x: Any, what: str) -> float:
    """``x`` as a float; None, NaN and infinities become NaN (unknown)."""
    if x is None:
        return math.nan
    try:
        v = float(x)
    except (TypeError, ValueError) as exc:
        raise StoreError(f"{what}: expected a number, got {x!r}") from exc
    return v if math.isfinite(v) else math.nan


def finite_number(x: Any, what: str) -> float:
    v = _number_or_nan(x, what)
    if not math.isfinite(v):
        raise StoreError(f"{what}: must be a finite number, got {x!r}")
    return v


def bool_flag(x: Any, what: str) -> bool:
    if not isinstance(x, (bool, int, np.bool_)) or x not in (0, 1):
        raise StoreError(f"{what}: expected True or False, got {x!r}")
    return bool(x)


def check_sha256(h: Any) -> None:
    """``None`` or 64 lower-case hex digits (a SHA-256), else StoreError."""
    if h is None:
        return
    if not (isinstance(h, str) and len(h) == 64 and all(c in "0123456789abcdef" for c in h)):
        raise StoreError(f"log_sha256: expected 64 lower-case hex digits, got {h!r}")


def check_flight_identity(record: Any) -> None:
    """The identity fields every per-flight record shares, checked and normalised in place (a
    frozen dataclass): non-empty ``aircraft_id``, ``flight_id`` and ``software_version``, UTC
    ``flight_date_utc`` (and ``recorded_at_utc`` when set), and ``log_sha256``."""
    check_sha256(record.log_sha256)
    for name in ("aircraft_id", "flight_id", "software_version"):
        v = getattr(record, name)
        if not isinstance(v, str) or not v.strip():
            raise StoreError(f"{name}: must be a non-empty string, got {v!r}")
    set_ = object.__setattr__
    set_(record, "flight_date_utc", utc_text(record.flight_date_utc, "flight_date_utc"))
    if record.recorded_at_utc is not None:
        set_(record, "recorded_at_utc", utc_text(record.recorded_at_utc, "recorded_at_utc"))


def _nan_free(d: dict[str, Any]) -> dict[str, Any]:
    """Copy of an :meth:`FlightCoefficients.as_dict` with NaN floats as None (for equality)."""
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}


@dataclass(frozen=True, eq=False)
class FlightCoefficients:
    """The Sabziev coefficients fitted on one flight of one aircraft, with their provenance.

    Validated and normalised on construction (times to UTC text, numbers to float), so a record
    read back from the store compares equal to the one written.  A fit that failed is recorded
    too (failures are reported, not hidden); the averages leave it out.

    Attributes
    ----------
    aircraft_id, flight_id : identifiers (non-empty); ``(aircraft_id, flight_id)`` is unique in
        the store and re-recording it replaces the row
    flight_date_utc : take-off time or date, UTC (see :func:`utc_text`)
    duration_s : duration T of the fitted interval (lift-off to touchdown) [s], > 0
    k1, k3 : x and z coefficients [1/s]; k2 : y coefficient [1/s^2].  Finite on a converged
        axis; NaN allowed on an axis that found no root
    branch : root branch per axis for (k1, k2, k3): ``"negative"`` or ``"positive"``, or
        ``"none"`` on an axis that did not converge and has no root
    converged : Newton-Raphson met its tolerance on every axis (``all(axis_converged)``)
    residual_m : end-point miss |s(k, T) - s_T| of the fit [m], >= 0; NaN allowed only when not
        converged
    iterations : Newton-Raphson iterations (total over the axes); ``None`` for rows migrated from
        a schema-v1 store, which did not record it
    software_version : flightrecon version that produced the fit
    settings : JSON-serialisable settings of the run
    input_hashes : JSON-serialisable {input name: SHA-256}
    axis_converged : convergence per axis for (k1, k2, k3); ``None`` means ``(converged,) * 3``
    recorded_at_utc : when the row was written (set by the store; ``None`` before recording)
    log_sha256 : SHA-256 (hex) of the flight's log, its content identity (``None``: unknown, as
        for rows upgraded from a v2 store)
    k_sd : conditioning of each root, ``50 m / |dF/dk|`` (the spread of k that 50 m of end-point
        uncertainty alone gives; docs/sabziev.md), for (k1, k2, k3); NaN where unknown (an axis
        without a root, rows upgraded from a v3 store); ``None`` means all NaN
    """

    aircraft_id: str
    flight_id: str
    flight_date_utc: str
    duration_s: float
    k1: float
    k2: float
    k3: float
    branch: tuple[str, str, str]
    converged: bool
    residual_m: float
    iterations: int | None
    software_version: str
    settings: dict[str, Any] = field(default_factory=dict)
    input_hashes: dict[str, Any] = field(default_factory=dict)
    axis_converged: tuple[bool, bool, bool] | None = None
    recorded_at_utc: str | None = None
    log_sha256: str | None = None
    k_sd: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        check_flight_identity(self)
        set_ = object.__setattr__
        sds = (math.nan,) * 3 if self.k_sd is None else tuple(self.k_sd)
        if len(sds) != 3:
            raise StoreError(f"k_sd: expected three values for (k1, k2, k3), got {sds!r}")
        sds = tuple(_number_or_nan(x, "k_sd") for x in sds)
        if any(x <= 0.0 for x in sds if math.isfinite(x)):
            raise StoreError(f"k_sd: must be positive where known, got {sds!r}")
        set_(self, "k_sd", sds)
        dur = finite_number(self.duration_s, "duration_s")
        if dur <= 0.0:
            raise StoreError(f"duration_s: must be positive, got {dur}")
        set_(self, "duration_s", dur)
        set_(self, "converged", bool_flag(self.converged, "converged"))
        if self.axis_converged is None:
            set_(self, "axis_converged", (self.converged,) * 3)
        ac = tuple(self.axis_converged)
        if len(ac) != 3:
            raise StoreError(f"axis_converged: expected three flags for (k1, k2, k3), got {ac!r}")
        ac = tuple(bool_flag(c, "axis_converged") for c in ac)
        if all(ac) != self.converged:
            raise StoreError(f"converged is {self.converged} but the axes say {ac}: a fit is "
                             "converged when every axis is")
        set_(self, "axis_converged", ac)
        br = tuple(self.branch)
        if len(br) != 3 or any(b not in BRANCHES + (NO_ROOT,) for b in br):
            raise StoreError(f"branch: expected three of {BRANCHES + (NO_ROOT,)} for (k1, k2, k3),"
                             f" got {br!r}")
        set_(self, "branch", br)
        for ax, ok, b in zip(AXES, ac, br):
            if ok:
                set_(self, ax, finite_number(getattr(self, ax), ax))
                if b == NO_ROOT:
                    raise StoreError(f"branch of {ax}: a converged axis has a root branch, "
                                     f"not '{NO_ROOT}'")
            else:
                set_(self, ax, _number_or_nan(getattr(self, ax), ax))
        res = _number_or_nan(self.residual_m, "residual_m")
        if math.isfinite(res):
            if res < 0.0:
                raise StoreError(f"residual_m: must be >= 0, got {res}")
        elif self.converged:
            raise StoreError(f"residual_m: a converged fit needs a finite residual, got {res}")
        set_(self, "residual_m", res)
        if self.iterations is not None:
            if isinstance(self.iterations, bool) or int(self.iterations) != self.iterations \
                    or self.iterations < 0:
                raise StoreError(f"iterations: expected a count >= 0, got {self.iterations!r}")
            set_(self, "iterations", int(self.iterations))
        for name in ("settings", "input_hashes"):
            if not isinstance(getattr(self, name), dict):
                got = type(getattr(self, name)).__name__
                raise StoreError(f"{name}: expected a dict, got {got}")

    @property
    def k(self) -> tuple[float, float, float]:
        """``(k1, k2, k3)``."""
        return (self.k1, self.k2, self.k3)

    def __eq__(self, other: object) -> bool:
        """Field-wise equality in which NaN equals NaN (an unknown k or residual)."""
        if not isinstance(other, FlightCoefficients):
            return NotImplemented
        return _nan_free(self.as_dict()) == _nan_free(other.as_dict())

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-serialisable except NaN values, which callers map to None)."""
        return {
            "aircraft_id": self.aircraft_id, "flight_id": self.flight_id,
            "flight_date_utc": self.flight_date_utc, "duration_s": self.duration_s,
            "k1": self.k1, "k2": self.k2, "k3": self.k3, "branch": list(self.branch),
            "converged": self.converged, "axis_converged": list(self.axis_converged or ()),
            "residual_m": self.residual_m, "iterations": self.iterations,
            "software_version": self.software_version, "settings": self.settings,
            "input_hashes": self.input_hashes, "recorded_at_utc": self.recorded_at_utc,
            "log_sha256": self.log_sha256, "k_sd": list(self.k_sd or ()),
        }


@dataclass(frozen=True)
class Exclusion:
    """A flight left out of one axis's statistics, and why (``"not converged"`` or
    ``"branch positive, majority negative"`` and the like)."""

    flight_id: str
    axis: str
    reason: str


@dataclass(frozen=True, eq=False)
class PropertyStats:
    """The candidate aircraft property behind one coefficient, averaged over the fits on the
    stable branch (:func:`flightrecon.store.stats.property_stats`; docs/store.md).

    Attributes
    ----------
    axis : ``"k1"``, ``"k2"`` or ``"k3"``
    quantity : ``"tau_s"`` (time constant ``-1/k`` of k1, k3 [s]) or ``"w_radps"`` (loop
        frequency ``sqrt(-k2)`` [rad/s])
    n : fits used (converged on the axis, on the stable branch ``negative``)
    weighted : True when every fit used carries its conditioning and the mean is weighted by
        the inverse variance of the transform; False: equal weights
    mean : weighted mean of the transform (NaN if n == 0)
    se : its standard error from the fits' conditioning, ``1 / sqrt(sum w)`` (weighted), or
        ``spread / sqrt(n)`` (equal weights; NaN if n < 2)
    spread : sample standard deviation of the transform over the fits (ddof 1; NaN if n < 2):
        the flight-to-flight spread
    chi2_dof : ``sum w (p - mean)^2 / (n - 1)`` (weighted, n >= 2; else NaN): about 1 when the
        fits scatter as their conditioning says, much larger when the flights differ more than
        their conditioning (then the transform is not one aircraft value)
    k, k_sd : the coefficient of the mean (``-1/tau`` or ``-w^2``) and the flight-to-flight
        spread carried into k to first order (``spread / tau^2`` or ``2 w spread``)
    """

    axis: str
    quantity: str
    n: int
    weighted: bool
    mean: float
    se: float
    spread: float
    chi2_dof: float
    k: float
    k_sd: float

    def __eq__(self, other: object) -> bool:
        """Field-wise equality in which NaN equals NaN (a spread unknown from one fit)."""
        if not isinstance(other, PropertyStats):
            return NotImplemented
        return _nan_free(self.__dict__) == _nan_free(other.__dict__)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True)
class AxisStats:
    """Statistics of one coefficient over the usable fits of one aircraft.

    Attributes
    ----------
    axis : ``"k1"``, ``"k2"`` or ``"k3"``
    branch : the majority branch used (``None`` when no fit is usable)
    n : number of fits used
    mean, median : of k over the fits used (NaN if n == 0)
    std : sample standard deviation (ddof = 1; NaN if n < 2)
    drift_per_day : least-squares slope of k against flight date [unit of k per day]
        (NaN if n < 2 or all flights on one instant)
    drift_se_per_day : its standard error, sqrt(s^2 / Sxx) with s^2 = SSR / (n - 2)
        (NaN if n < 3 or the slope is NaN)
    excluded : the fits left out, each with its reason
    prop : the transformed coefficient over the stable-branch fits (:class:`PropertyStats`):
        what the fleet mean uses
    """

    axis: str
    branch: str | None
    n: int
    mean: float
    median: float
    std: float
    drift_per_day: float
    drift_se_per_day: float
    excluded: tuple[Exclusion, ...] = ()
    prop: PropertyStats | None = None

    def excluded_counts(self) -> dict[str, int]:
        """``{reason: count}`` of the excluded fits."""
        out: dict[str, int] = {}
        for e in self.excluded:
            out[e.reason] = out.get(e.reason, 0) + 1
        return out


@dataclass(frozen=True)
class AircraftStats:
    """Per-axis statistics of one aircraft's recorded fits (see :mod:`flightrecon.store.stats`)."""

    aircraft_id: str
    n_flights: int
    axes: tuple[AxisStats, AxisStats, AxisStats]

    def axis(self, name: str) -> AxisStats:
        """The statistics of ``"k1"``, ``"k2"`` or ``"k3"``."""
        if name not in AXES:
            raise StoreError(f"unknown coefficient '{name}', expected one of {AXES}")
        return self.axes[AXES.index(name)]


@dataclass(frozen=True)
class FleetMean:
    """Averaged coefficients of one aircraft for the initial-value mode of the Sabziev method.

    ``k`` are the per-axis coefficients of the weighted mean time constant (k1, k3) or loop
    frequency (k2) over the fits on the stable branch (:class:`PropertyStats`), ``sd`` the
    flight-to-flight spread carried into k (NaN when an axis has one fit), ``n`` the fits used
    per axis and ``branch`` the branch each mean was taken on (``"negative"``).  An axis without
    enough fits (allowed with ``fleet_mean(..., allow_missing=True)``) has ``k`` and ``sd`` NaN,
    ``branch`` ``"none"``, and is named in ``missing``.
    """

    aircraft_id: str
    k: tuple[float, float, float]
    sd: tuple[float, float, float]
    n: tuple[int, int, int]
    branch: tuple[str, str, str]
    missing: tuple[str, ...] = ()
