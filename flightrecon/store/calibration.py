"""Per-aircraft sensor calibration: one flight's estimates of the persistent sensor errors, and
their fusion over an aircraft's flights (docs/store.md, "Sensor calibration").

The joint smoother (docs/joint.md) estimates, on every flight, the errors an aircraft carries
from flight to flight: the airspeed scale, the heading, roll and pitch biases, the accelerometer
biases and scale errors, the Doppler scale and drift-angle bias.  On a routine flight with GNSS
they are well observed; on a flight with the recorder alone nothing else pins them down.  This
module keeps each flight's estimates (:class:`FlightCalibration`) and fuses them
(:func:`fuse_quantity`, :func:`aircraft_calibration`):

1. **The flight's own information.**  A flight's estimate ``v +- s`` is the joint smoother's
   posterior under its prior ``N(m_p, s_p^2)``.  Multiplying several such posteriors would count
   the prior once per flight, so the prior is divided out first (information form):
   ``1/s_d^2 = 1/s^2 - 1/s_p^2`` and ``m_d = s_d^2 (v/s^2 - m_p/s_p^2)``.  With independent
   priors on the states and a linear-Gaussian model this is exact: the posterior marginal is the
   prior times the flight's marginal likelihood of that error.  A flight whose sd is at least
   :data:`UNOBSERVED_RATIO` of its prior's has learnt nothing about that error and is left out
   (``not observed``).
2. **Slow drift.**  The error of the aircraft is a random walk in time,
   ``x(t) = x(t_0) + w(t - t_0)`` with ``Var w = q^2 (t - t_0)`` [t in days], started at the
   earliest flight used in the population prior ``N(m_0, P_0)`` (the joint smoother's default
   prior).  ``q`` is set per aircraft and quantity (:meth:`CoefficientStore.set_drift`) or
   estimated by maximum likelihood from the flights (at least :data:`MIN_FLIGHTS_DRIFT`;
   ``q = 0`` with fewer, said in the result).
3. **Fusion at a date.**  ``x(t*)`` given every flight used is the Gaussian conditional
   (generalised least squares with the random walk's covariance
   ``C(a, b) = P_0 + q^2 (min(a, b) - t_0)``); with ``q = 0`` it is the inverse-variance
   combination of the flights and the prior.
4. **Outliers.**  Each flight is compared with the fusion of the others at its date, with the
   drift the others give (leave-one-out: a jump on the last flight is not explained away by a
   drift fitted to it): ``z = (m_d - x_hat) / sqrt(Var x_hat + s_d^2)``.  With at least
   :data:`MIN_FLIGHTS_OUTLIER` flights, the worst flight beyond :data:`OUTLIER_Z` is excluded
   (``outlier``) and the test is repeated; ``q`` is then estimated from the flights kept.
5. **Sensor changes.**  A change recorded for a quantity (or ``*``, every sensor) at a date makes
   the flights before it inapplicable to a date after it, and the flights after it
   inapplicable to a date before it.

These are pure functions on lists of records; the store calls them on the rows it reads.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightrecon.errors import StoreError
from flightrecon.store.records import _finite, _flag, check_sha256, utc_days, utc_text

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
            object.__setattr__(self, name, _finite(getattr(self, name), f"{q}.{name}"))
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
        for name in ("aircraft_id", "flight_id", "software_version"):
            v = getattr(self, name)
            if not isinstance(v, str) or not v.strip():
                raise StoreError(f"{name}: must be a non-empty string, got {v!r}")
        set_ = object.__setattr__
        set_(self, "flight_date_utc", utc_text(self.flight_date_utc, "flight_date_utc"))
        if self.recorded_at_utc is not None:
            set_(self, "recorded_at_utc", utc_text(self.recorded_at_utc, "recorded_at_utc"))
        check_sha256(self.log_sha256)
        est = tuple(self.estimates)
        if not all(isinstance(e, SensorEstimate) for e in est):
            raise StoreError("estimates: expected SensorEstimate records")
        names = [e.quantity for e in est]
        if len(set(names)) != len(names):
            raise StoreError(f"estimates: a quantity appears twice in {names}")
        set_(self, "estimates", est)
        dur = _finite(self.duration_s, "duration_s")
        if dur <= 0:
            raise StoreError(f"duration_s: must be positive, got {dur}")
        set_(self, "duration_s", dur)
        set_(self, "converged", _flag(self.converged, "converged"))
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


# -- the fusion --------------------------------------------------------------------------------

def _cov(t: np.ndarray, u: np.ndarray, P0: float, q: float, t0: float) -> np.ndarray:
    return P0 + q * q * (np.minimum.outer(t, u) - t0)


def _condition(t, y, r, ts, m0, P0, q, t0):
    """Mean and variance of x(ts) given y = x(t) + e, Var e = r (the random-walk GLS)."""
    if len(t) == 0:
        return m0, P0 + q * q * (ts - t0)
    S = _cov(t, t, P0, q, t0) + np.diag(r)
    c = _cov(t, np.array([ts]), P0, q, t0)[:, 0]
    L = np.linalg.cholesky(S)
    a = np.linalg.solve(L, c)
    b = np.linalg.solve(L, y - m0)
    return m0 + float(a @ b), max(float(P0 + q * q * (ts - t0) - a @ a), 0.0)


def _loglik(t, y, r, m0, P0, q, t0) -> float:
    S = _cov(t, t, P0, q, t0) + np.diag(r)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return -math.inf
    b = np.linalg.solve(L, y - m0)
    return float(-0.5 * (b @ b) - np.sum(np.log(np.diag(L))))


def estimate_drift(t: np.ndarray, y: np.ndarray, r: np.ndarray, m0: float, P0: float,
                   scale: float) -> float:
    """Maximum-likelihood q of the random walk [unit per sqrt(day)].

    The log-likelihood ``-1/2 (y - m0)^T S^-1 (y - m0) - 1/2 log det S`` is evaluated at q = 0
    and on a logarithmic grid from 1e-6 to 1 times ``scale`` (the prior sd) per sqrt(day), and
    refined by a golden-section search about the best grid point.
    """
    from scipy.optimize import minimize_scalar

    t0 = float(np.min(t))
    grid = scale * np.logspace(-6, 0, 49)
    cands = np.r_[0.0, grid]
    ll = np.array([_loglik(t, y, r, m0, P0, q, t0) for q in cands])
    i = int(np.argmax(ll))
    if i == 0:
        return 0.0
    lo = math.log(cands[max(i - 1, 1)])
    hi = math.log(cands[min(i + 1, len(cands) - 1)])
    if hi <= lo:
        return float(cands[i])
    res = minimize_scalar(lambda u: -_loglik(t, y, r, m0, P0, math.exp(u), t0),
                          bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
    best = math.exp(res.x)
    return best if -res.fun >= ll[i] else float(cands[i])


def applicable_window(changes: Sequence[SensorChange], quantity: str,
                      at_days: float) -> tuple[float, float, list[SensorChange]]:
    """``(start, end, changes)`` in days: the flights in ``[start, end)`` describe ``quantity``
    at ``at_days`` (the last change at or before it, the first change after it)."""
    rel = [c for c in changes if c.quantity in (quantity, ALL_QUANTITIES)]
    start, end = -math.inf, math.inf
    for c in rel:
        d = utc_days(c.change_utc)
        if d <= at_days:
            start = max(start, d)
        else:
            end = min(end, d)
    return start, end, rel


def fuse_quantity(quantity: str, records: Sequence[FlightCalibration], at_utc: str, *,
                  changes: Sequence[SensorChange] = (), drift: float | None = None,
                  configuration: str | None = None,
                  population_prior: tuple[float, float] | None = None) -> QuantityCalibration:
    """The fused calibration of ``quantity`` at ``at_utc`` (rule: module docstring).

    Parameters
    ----------
    quantity : a key of the joint smoother's corrections
    records : one aircraft's flights
    at_utc : the date of the estimate (e.g. the new flight's take-off)
    changes : the aircraft's sensor changes
    drift : q [unit per sqrt(day)] if set; ``None`` to estimate it
    configuration : only flights of this configuration (``None``: all)
    population_prior : ``(m0, sd0)``; default: the widest prior the flights were run with
    """
    at_utc = utc_text(at_utc, "at")
    at = utc_days(at_utc)
    start, end, _ = applicable_window(changes, quantity, at)
    excluded: list[CalibrationExclusion] = []
    rows = []
    unit = ""
    priors = []
    for rec in sorted(records, key=lambda r: (r.flight_date_utc, r.flight_id)):
        e = rec.estimate(quantity)
        if e is None:
            continue
        unit = unit or e.unit
        priors.append((e.prior_sd, e.prior_mean))
        d = utc_days(rec.flight_date_utc)
        if configuration is not None and rec.configuration != configuration:
            excluded.append(CalibrationExclusion(
                rec.flight_id, f"configuration '{rec.configuration}', not '{configuration}'"))
            continue
        if d < start:
            excluded.append(CalibrationExclusion(rec.flight_id, "before a sensor change"))
            continue
        if d >= end:
            excluded.append(CalibrationExclusion(rec.flight_id, "after a sensor change"))
            continue
        if not rec.converged:
            excluded.append(CalibrationExclusion(rec.flight_id, "joint smoother not converged"))
            continue
        dat = e.data_only()
        if dat is None:
            excluded.append(CalibrationExclusion(
                rec.flight_id, f"not observed (sd {e.sd:.3g} >= {UNOBSERVED_RATIO} x prior sd)"))
            continue
        rows.append((rec.flight_id, d, dat[0], max(dat[1], 1e-12 * e.prior_sd)))
    if population_prior is None:
        if not priors:
            raise StoreError(f"no flight has an estimate of '{quantity}'")
        sd0, m0 = max(priors)
    else:
        m0, sd0 = population_prior
    P0 = sd0 * sd0
    ids = [r[0] for r in rows]
    t = np.array([r[1] for r in rows], float)
    y = np.array([r[2] for r in rows], float)
    rv = np.array([r[3] for r in rows], float) ** 2

    def q_for(tt, yy, rr):
        if drift is not None:
            return float(drift), "set"
        if len(tt) < MIN_FLIGHTS_DRIFT:
            return 0.0, f"none: fewer than {MIN_FLIGHTS_DRIFT} flights to estimate it"
        return estimate_drift(tt, yy, rr, m0, P0, sd0), "estimated"

    def loo_z(tt, yy, rr):
        """Each flight against the fusion of the others, with the drift the others give."""
        z = np.zeros(len(tt))
        for i in range(len(tt)):
            k = np.arange(len(tt)) != i
            qi, _ = q_for(tt[k], yy[k], rr[k])
            t0 = float(np.min(tt))
            m, v = _condition(tt[k], yy[k], rr[k], tt[i], m0, P0, qi, t0)
            z[i] = (yy[i] - m) / math.sqrt(v + rr[i])
        return z

    keep = np.ones(len(t), bool)
    while True:
        z = loo_z(t[keep], y[keep], rv[keep]) if keep.any() else np.zeros(0)
        if keep.sum() < MIN_FLIGHTS_OUTLIER or not len(z) or np.max(np.abs(z)) <= OUTLIER_Z:
            break
        j = int(np.argmax(np.abs(z)))
        worst = int(np.flatnonzero(keep)[j])
        excluded.append(CalibrationExclusion(
            ids[worst], f"outlier: {abs(z[j]):.1f} sd from the other flights", float(z[j])))
        keep[worst] = False
    q, qsrc = q_for(t[keep], y[keep], rv[keep])
    t0 = float(min(np.min(t[keep]) if keep.any() else at, at))
    m, v = _condition(t[keep], y[keep], rv[keep], at, m0, P0, q, t0)
    return QuantityCalibration(
        quantity=quantity, unit=unit, at_utc=at_utc, n=int(keep.sum()), mean=m,
        sd=math.sqrt(v), prior_mean=m0, prior_sd=sd0, drift_sd_per_sqrt_day=q,
        drift_source=qsrc, flights=tuple(i for i, k in zip(ids, keep) if k),
        z=tuple(float(x) for x in z), excluded=tuple(excluded),
        persistent=quantity in PERSISTENT)


def aircraft_calibration(aircraft_id: str, records: Sequence[FlightCalibration],
                         at_utc: str | None = None, *, changes: Sequence[SensorChange] = (),
                         drift: Mapping[str, float] | None = None,
                         configuration: str | None = None,
                         quantities: Sequence[str] | None = None) -> AircraftCalibration:
    """The fused calibration of every recorded quantity of one aircraft at ``at_utc`` (default:
    the latest flight's date).

    Parameters
    ----------
    drift : ``{quantity: q}`` set per quantity; the others are estimated
    quantities : restrict to these (default: every quantity recorded, persistent ones first)
    """
    others = {r.aircraft_id for r in records} - {aircraft_id}
    if others:
        raise StoreError(f"calibration of aircraft '{aircraft_id}': records of other aircraft "
                         f"given: {sorted(others)}")
    if not records:
        raise StoreError(f"no sensor calibration recorded for aircraft '{aircraft_id}'")
    if at_utc is None:
        at_utc = max(r.flight_date_utc for r in records)
    at_utc = utc_text(at_utc, "at")
    names: list[str] = []
    for r in records:
        for e in r.estimates:
            if e.quantity not in names:
                names.append(e.quantity)
    order = [q for q in PERSISTENT if q in names] + [q for q in names if q not in PERSISTENT]
    if quantities is not None:
        order = [q for q in order if q in quantities]
    drift = dict(drift or {})
    out = tuple(fuse_quantity(q, records, at_utc, changes=changes, drift=drift.get(q),
                              configuration=configuration) for q in order)
    ch = tuple(c for c in changes if c.aircraft_id == aircraft_id)
    return AircraftCalibration(aircraft_id=aircraft_id, at_utc=at_utc,
                               configuration=configuration, n_flights=len(records),
                               quantities=out, changes=ch)
