"""Magnetic declination from the World Magnetic Model (pygeomag) and magnetic -> true heading.

Declination D is the angle from true north to magnetic north, positive east, so
``true = magnetic + D`` (NOAA/BGS, *The US/UK World Magnetic Model*, technical reports, section
"Magnetic declination").  The model is chosen by date: WMM2010, WMM2015v2, WMM2020, WMM2025, each
valid for five years from its epoch; a date outside 2010-2030 uses the nearest model beyond its
life span, and :func:`declination_deg` says so in its returned note.
"""

from __future__ import annotations

from datetime import UTC, datetime
from functools import lru_cache

import numpy as np

__all__ = ["decimal_year", "declination_deg", "magnetic_to_true", "model_for_year"]

_MODELS = ((2010.0, "WMM_2010.COF"), (2015.0, "WMM_2015v2.COF"), (2020.0, "WMM_2020.COF"),
           (2025.0, "WMM_2025.COF"))
LIFE_SPAN_YEARS = 5.0


def decimal_year(epoch_utc: str, t_s=0.0):
    """Decimal year of ``epoch_utc`` (ISO-8601, UTC) plus ``t_s`` seconds (array-like).

    Exact to the second: year + (time - 1 Jan) / (1 Jan next year - 1 Jan).
    """
    s = epoch_utc.strip()
    dt = datetime.fromisoformat(s[:-1] + "+00:00" if s.endswith(("Z", "z")) else s)
    if dt.tzinfo is not None:
        dt = dt.astimezone(UTC).replace(tzinfo=None)
    ts = np.asarray(t_s, dtype=np.float64)
    t = np.datetime64(dt, "ns") + np.round(ts * 1e9).astype("timedelta64[ns]")
    y = t.astype("datetime64[Y]")
    start = y.astype("datetime64[ns]")
    end = (y + 1).astype("datetime64[ns]")
    frac = (t - start).astype(np.float64) / (end - start).astype(np.float64)
    out = y.astype(np.int64) + 1970 + frac
    return out if np.ndim(out) else float(out)


def model_for_year(year: float) -> tuple[str, bool]:
    """WMM coefficient file for ``year`` and whether ``year`` lies inside its life span."""
    chosen = _MODELS[0]
    for m in _MODELS:
        if year >= m[0]:
            chosen = m
    inside = chosen[0] <= year < chosen[0] + LIFE_SPAN_YEARS
    return chosen[1], inside


@lru_cache(maxsize=8)
def _geomag(cof: str):
    from pygeomag import GeoMag

    return GeoMag(coefficients_file=f"wmm/{cof}")


def declination_deg(lat_deg, lon_deg, alt_m, year: float) -> tuple[np.ndarray, str | None]:
    """WMM declination [deg, + east] at points (arrays broadcast) at decimal ``year``.

    Parameters
    ----------
    lat_deg, lon_deg : geodetic latitude and longitude [deg]
    alt_m : height [m] (the model takes MSL or ellipsoidal height; at aircraft altitudes the
        difference changes D by far less than the model's 0.3 deg uncertainty)
    year : decimal year (:func:`decimal_year`)

    Returns
    -------
    D : declination [deg], shape of the broadcast inputs
    note : ``None``, or a sentence saying the date is outside the model's life span

    Notes
    -----
    pygeomag evaluates one point per call (pure Python, about a millisecond); callers evaluate a
    few dozen points along the flight and interpolate in time (declination changes by a fraction
    of a degree per 100 km away from the poles).
    """
    cof, inside = model_for_year(year)
    gm = _geomag(cof)
    lat, lon, alt = np.broadcast_arrays(np.asarray(lat_deg, float), np.asarray(lon_deg, float),
                                        np.asarray(alt_m, float))
    lon = np.where(lon > 180.0, lon - 360.0, lon)
    out = np.empty(lat.shape)
    for idx in np.ndindex(lat.shape):
        out[idx] = gm.calculate(glat=float(lat[idx]), glon=float(lon[idx]),
                                alt=float(alt[idx]) / 1000.0, time=float(year),
                                allow_date_outside_lifespan=True).d
    note = None if inside else (f"date {year:.2f} outside the life span of {cof}: "
                                "declination extrapolated")
    return out, note


def magnetic_to_true(heading_mag_deg, declination) -> np.ndarray:
    """True heading [deg, in [0, 360)] = magnetic heading + declination (east positive)."""
    return np.mod(np.asarray(heading_mag_deg, float) + np.asarray(declination, float), 360.0)
