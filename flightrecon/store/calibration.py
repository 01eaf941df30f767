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
from dataclasses import dataclass

import numpy as np

from flightrecon.errors import StoreError
from flightrecon.store.calibration_records import (  # noqa: F401  (re-exported)
    ALL_QUANTITIES,
    DAY_DEPENDENT,
    MIN_FLIGHTS_DRIFT,
    MIN_FLIGHTS_OUTLIER,
    OUTLIER_Z,
    PERSISTENT,
    UNOBSERVED_RATIO,
    AircraftCalibration,
    CalibrationExclusion,
    FlightCalibration,
    QuantityCalibration,
    SensorChange,
    SensorEstimate,
)
from flightrecon.store.records import utc_days, utc_text

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
    rows, excluded, unit, priors = _usable_flights(quantity, records, start, end, configuration)
    if population_prior is None:
        if not priors:
            raise StoreError(f"no flight has an estimate of '{quantity}'")
        sd0, m0 = max(priors)
    else:
        m0, sd0 = population_prior
    rw = _RandomWalk(m0, sd0 * sd0, sd0, drift)
    ids = [r[0] for r in rows]
    t = np.array([r[1] for r in rows], float)
    y = np.array([r[2] for r in rows], float)
    rv = np.array([r[3] for r in rows], float) ** 2
    keep, z = _exclude_outliers(rw, t, y, rv, ids, excluded)
    q, qsrc = rw.q_for(t[keep], y[keep], rv[keep])
    t0 = float(min(np.min(t[keep]) if keep.any() else at, at))
    m, v = _condition(t[keep], y[keep], rv[keep], at, m0, rw.P0, q, t0)
    return QuantityCalibration(
        quantity=quantity, unit=unit, at_utc=at_utc, n=int(keep.sum()), mean=m,
        sd=math.sqrt(v), prior_mean=m0, prior_sd=sd0, drift_sd_per_sqrt_day=q,
        drift_source=qsrc, flights=tuple(i for i, k in zip(ids, keep) if k),
        z=tuple(float(x) for x in z), excluded=tuple(excluded),
        persistent=quantity in PERSISTENT)


def _usable_flights(quantity: str, records: Sequence[FlightCalibration], start: float,
                    end: float, configuration: str | None
                    ) -> tuple[list[tuple[str, float, float, float]], list[CalibrationExclusion],
                               str, list[tuple[float, float]]]:
    """Rule steps 1 and 5: each flight's own information on ``quantity`` (``(flight_id, day,
    m_d, s_d)``, by date), the flights left out and why, the unit, and every flight's prior
    ``(sd, mean)``."""
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
    return rows, excluded, unit, priors


@dataclass(frozen=True)
class _RandomWalk:
    """Rule step 2: the population prior ``N(m0, P0)`` (``sd0`` its sd, the drift search's
    scale) and the drift ``q`` if set (``None``: estimated)."""

    m0: float
    P0: float
    sd0: float
    drift: float | None

    def q_for(self, tt: np.ndarray, yy: np.ndarray, rr: np.ndarray) -> tuple[float, str]:
        """The drift and where it comes from (set, estimated, or none: too few flights)."""
        if self.drift is not None:
            return float(self.drift), "set"
        if len(tt) < MIN_FLIGHTS_DRIFT:
            return 0.0, f"none: fewer than {MIN_FLIGHTS_DRIFT} flights to estimate it"
        return estimate_drift(tt, yy, rr, self.m0, self.P0, self.sd0), "estimated"

    def loo_z(self, tt: np.ndarray, yy: np.ndarray, rr: np.ndarray) -> np.ndarray:
        """Each flight against the fusion of the others, with the drift the others give."""
        z = np.zeros(len(tt))
        for i in range(len(tt)):
            k = np.arange(len(tt)) != i
            qi, _ = self.q_for(tt[k], yy[k], rr[k])
            t0 = float(np.min(tt))
            m, v = _condition(tt[k], yy[k], rr[k], tt[i], self.m0, self.P0, qi, t0)
            z[i] = (yy[i] - m) / math.sqrt(v + rr[i])
        return z


def _exclude_outliers(rw: _RandomWalk, t: np.ndarray, y: np.ndarray, rv: np.ndarray,
                      ids: list[str], excluded: list[CalibrationExclusion]
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Rule step 4: drop the worst flight beyond :data:`OUTLIER_Z` (leave-one-out) until none
    is; returns the flights kept (mask) and the last z-scores of those kept."""
    keep = np.ones(len(t), bool)
    while True:
        z = rw.loo_z(t[keep], y[keep], rv[keep]) if keep.any() else np.zeros(0)
        if keep.sum() < MIN_FLIGHTS_OUTLIER or not len(z) or np.max(np.abs(z)) <= OUTLIER_Z:
            break
        j = int(np.argmax(np.abs(z)))
        worst = int(np.flatnonzero(keep)[j])
        excluded.append(CalibrationExclusion(
            ids[worst], f"outlier: {abs(z[j]):.1f} sd from the other flights", float(z[j])))
        keep[worst] = False
    return keep, z


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
