"""The conventions of a Garmin export checked from its own data, never assumed from one file.

The family does not write one convention (docs/ingest.md, "Garmin glass-cockpit exports"): the
normal load is n - 1 on some units and n on others, the track is magnetic or true, the
variation's sign may differ, the altitude column is the altimeter's reading at its setting or a
pressure altitude, the GPS height is above the ellipsoid or above MSL.  Each function here
decides one of them from the export's own figures, states the evidence, and says when the data
contradict the built-in convention (the data win, with a warning giving the figures) or cannot
tell (the built-in convention, with a warning).  Inputs are in SI units and degrees, in the
file's row order (1 Hz rows: consecutive rows are consecutive seconds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Convention",
    "altitude_datum",
    "gps_height_datum",
    "magvar_sign_wmm",
    "normal_load_offset",
    "track_reference",
]

#: ground speed below which the aircraft stands still [m/s] (half a knot)
REST_MPS = 0.26
#: speed above which the positions' track is the aircraft's (the taxi's wander excluded) [m/s]
FAST_MPS = 25.0
#: fewest rows a decision rests on
MIN_ROWS = 20
#: smallest variation [deg] by which the GPS track tells a magnetic track from a true one
SEPARATION_DEG = 0.5


@dataclass(frozen=True)
class Convention:
    """One convention of the export as read.

    Attributes
    ----------
    quantity : what it is about (``"NormAc"``, ``"TRK"``, ...)
    reading : how the column is read (``"n - 1"``, ``"magnetic"``, ...)
    basis : ``"data"`` (decided by the figures), ``"label"`` (the export's own unit or name) or
        ``"built-in"`` (the data cannot tell)
    evidence : the figures
    warning : set when the data contradict the built-in convention or cannot tell
    """

    quantity: str
    reading: str
    basis: str
    evidence: str
    warning: str | None = None

    def text(self) -> str:
        """``reading (basis: evidence)`` for ``flightrecon info``."""
        return f"{self.reading} ({self.basis}: {self.evidence})"


def _wrap(a: np.ndarray) -> np.ndarray:
    return (np.asarray(a, float) + 180.0) % 360.0 - 180.0


def normal_load_offset(nz: np.ndarray, gs_mps: np.ndarray, roll_deg: np.ndarray,
                       builtin: float, column: str) -> tuple[float, Convention]:
    """Whether the normal load column is n (offset 0) or n - 1 (offset +1 g) from its value
    standing still (ground speed below :data:`REST_MPS`, wings level within 5 deg) or, without
    such rows, in straight flight (faster than :data:`FAST_MPS`, bank within 3 deg): the
    median is 1 g or 0 g there (within 0.2 g: the 0.01 g resolution, a sloping apron and
    the turbulence move it by a few hundredths).
    """
    nz, gs, roll = (np.asarray(x, float) for x in (nz, gs_mps, roll_deg))
    ok = np.isfinite(nz) & np.isfinite(gs) & (~np.isfinite(roll) | (np.abs(roll) < 5.0))
    where, sel = "at rest", ok & (gs < REST_MPS)
    if sel.sum() < MIN_ROWS:
        where, sel = "in straight flight", ok & (gs > FAST_MPS) & (np.abs(roll) < 3.0)
    named = {0.0: "n", 1.0: "n - 1"}
    if sel.sum() < MIN_ROWS:
        msg = (f"{column}: no {MIN_ROWS} rows at rest or in straight flight to tell n from "
               f"n - 1: read as {named[builtin]} (the built-in convention)")
        return builtin, Convention(column, named[builtin], "built-in", "no rows at rest or "
                                   "in straight flight", msg)
    m = float(np.median(nz[sel]))
    ev = f"median {m:+.3f} g over {int(sel.sum())} rows {where}"
    found = 1.0 if abs(m) < 0.2 else 0.0 if abs(m - 1.0) < 0.2 else None
    if found is None:
        msg = (f"{column}: {ev}, neither 0 g (n - 1) nor 1 g (n): read as "
               f"{named[builtin]} (the built-in convention)")
        return builtin, Convention(column, named[builtin], "built-in", ev, msg)
    warn = None if found == builtin else (
        f"{column}: {ev}: recorded as {named[found]}, not {named[builtin]} as the built-in "
        f"convention for this unit says: read as {named[found]}")
    return found, Convention(column, named[found], "data", ev, warn)


def magvar_sign_wmm(magvar_deg: np.ndarray, wmm_deg: np.ndarray, column: str
                    ) -> tuple[float | None, Convention]:
    """The sign that makes the recorded variation east positive, from the World Magnetic
    Model's declination at the same points and date (``wmm_deg``, east positive;
    :func:`flightrecon.geo.magnetic.declination_deg`).

    The model is good to about 0.5 deg: a variation within 1 deg of zero cannot tell its sign
    (``None``: the sign then costs at most twice the variation).
    """
    mv, d = np.asarray(magvar_deg, float), np.asarray(wmm_deg, float)
    ok = np.isfinite(mv) & np.isfinite(d)
    if ok.sum() < 1:
        return None, Convention(column, "east positive", "built-in", "no variation with a "
                                "position to compare with the WMM")
    dm = float(np.median(d[ok]))
    east = float(np.median(np.abs(mv[ok] - d[ok])))
    west = float(np.median(np.abs(-mv[ok] - d[ok])))
    ev = (f"WMM {dm:+.1f} deg, recorded {float(np.median(mv[ok])):+.1f} deg (median of "
          f"{int(ok.sum())} points)")
    if abs(dm) < 1.0:
        return None, Convention(column, "east positive", "built-in", ev + ": too small for "
                                "the model to tell the sign")
    sign = 1.0 if east <= west else -1.0
    off = min(east, west)
    warn = None
    if off > 1.5:
        warn = (f"{column}: {ev}: {off:.1f} deg from the model with either sign (a wrong "
                "date, position or column?)")
    elif sign < 0:
        warn = (f"{column}: {ev}: the recorded variation is west positive; read with the "
                "sign changed (true = magnetic + east variation)")
    return sign, Convention(column, "east positive" if sign > 0 else "west positive (sign "
                            "changed)", "data", ev, warn)


def _positions_track(lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    """Track [deg] of consecutive positions (central differences in row order)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    return np.degrees(np.arctan2(np.gradient(lon) * np.cos(lat), np.gradient(lat))) % 360.0


def track_reference(trk_deg: np.ndarray, var_deg: np.ndarray, lat_deg: np.ndarray,
                    lon_deg: np.ndarray, gs_mps: np.ndarray, builtin: str, column: str
                    ) -> tuple[str, float | None, Convention]:
    """Whether the recorded track is true or magnetic, against the track of consecutive GPS
    positions above :data:`FAST_MPS`: of ``TRK``, ``TRK + var`` and ``TRK - var`` (``var`` the
    recorded variation, else the WMM's) the one whose median difference is nearest zero.

    Both tracks are the GPS's, so they agree to about 0.1 deg with no drift angle between
    them: the data tell when the hypotheses are :data:`SEPARATION_DEG` apart or more (the
    variation's size) and the nearest is within a quarter of that (and 1.5 deg) of zero.

    Returns ``(reference, variation sign or None, convention)``; the sign (+1: east positive)
    when the track is magnetic.
    """
    trk, var, gs = (np.asarray(x, float) for x in (trk_deg, var_deg, gs_mps))
    ptrk = _positions_track(np.asarray(lat_deg, float), np.asarray(lon_deg, float))
    ok = np.isfinite(trk) & np.isfinite(var) & np.isfinite(ptrk) & (gs > FAST_MPS)
    if ok.sum() < MIN_ROWS:
        msg = (f"{column}: fewer than {MIN_ROWS} fast rows with positions to tell a true "
               f"from a magnetic track: read as {builtin} (the built-in convention)")
        return builtin, None, Convention(column, builtin, "built-in", "too few fast rows", msg)
    hyp = {"true": 0.0, "magnetic": 1.0, "magnetic, variation west positive": -1.0}
    med = {k: float(np.median(_wrap(trk[ok] + s * var[ok] - ptrk[ok]))) for k, s in hyp.items()}
    best = min(med, key=lambda k: abs(med[k]))
    sep = float(np.median(np.abs(var[ok])))
    ev = (f"median difference from the track of consecutive GPS positions over "
          f"{int(ok.sum())} rows faster than {FAST_MPS:.0f} m/s: TRK {med['true']:+.2f} deg, "
          f"TRK + variation {med['magnetic']:+.2f} deg")
    if sep < SEPARATION_DEG or abs(med[best]) > min(1.5, 0.25 * sep):
        msg = (f"{column}: {ev}: the variation ({sep:.1f} deg) is too small or the track too "
               f"far off to tell true from magnetic: read as {builtin} (the built-in "
               "convention)")
        return builtin, None, Convention(column, builtin, "built-in", ev, msg)
    ref = "true" if best == "true" else "magnetic"
    sign = None if ref == "true" else hyp[best]
    warn = None
    if ref != builtin:
        warn = (f"{column}: {ev}: the track is {ref}, not {builtin} as the built-in "
                f"convention for this unit says: read as {ref}")
    return ref, sign, Convention(column, best, "data", ev, warn)


def altitude_datum(alt_m: np.ndarray, alt_p_m: np.ndarray, msl_m: np.ndarray,
                   gs_mps: np.ndarray, builtin: str, column: str) -> tuple[str, Convention]:
    """Whether the altitude column is the altimeter's reading at the recorded setting
    (``"indicated"``: QNH, near the GPS's MSL height on the ground) or already a pressure
    altitude (``"pressure"``), from the rows at rest: ``alt_m`` read as recorded and
    ``alt_p_m`` the pressure altitude it gives if it were indicated at the setting, each
    against the GPS MSL height ``msl_m``.

    The two readings differ by about 8.3 m per hPa of the setting from 1013.25 hPa: below 15 m
    (a setting within 2 hPa of standard) the data cannot tell, and it matters by that much at
    most.  The reading nearer the GPS, by at least half their difference, wins.
    """
    a, p, msl, gs = (np.asarray(x, float) for x in (alt_m, alt_p_m, msl_m, gs_mps))
    ok = np.isfinite(a) & np.isfinite(p) & np.isfinite(msl)
    sel, where = ok & (gs < REST_MPS), "at rest"
    if sel.sum() < MIN_ROWS:
        sel, where = ok, "over the record"
    if sel.sum() < MIN_ROWS:
        msg = (f"{column}: no GPS MSL height to check the altitude's datum against: read as "
               f"{builtin} (the built-in convention)")
        return builtin, Convention(column, builtin, "built-in", "no AltMSL rows", msg)
    d = float(np.median(a[sel] - p[sel]))
    r_ind = float(np.median(a[sel] - msl[sel]))
    r_p = float(np.median(p[sel] - msl[sel]))
    ev = (f"{where} ({int(sel.sum())} rows) against AltMSL: as the altimeter's reading at "
          f"the setting {r_ind:+.1f} m, as a pressure altitude {r_p:+.1f} m")
    if abs(d) < 15.0 or min(abs(r_ind), abs(r_p)) > abs(abs(r_ind) - abs(r_p)):
        msg = (f"{column}: {ev}: the data cannot tell the datum (the two readings differ by "
               f"{abs(d):.0f} m): read as {builtin} (the built-in convention)")
        return builtin, Convention(column, builtin, "built-in", ev, msg)
    found = "indicated" if abs(r_ind) < abs(r_p) else "pressure"
    what = "an indicated altitude" if found == "indicated" else "a pressure altitude"
    warn = None if found == builtin else (
        f"{column}: {ev}: the column is {what}, not {builtin} as the built-in convention "
        "says: read so")
    return found, Convention(column, found, "data", ev, warn)


def gps_height_datum(alt_gps_m: np.ndarray, alt_msl_m: np.ndarray | None, label: str,
                     column: str) -> tuple[str, float | None, Convention]:
    """Whether the GPS height is above the ellipsoid or MSL, from ``AltGPS - AltMSL`` (the
    geoid undulation, constant within a few metres over a flight, when AltGPS is ellipsoidal;
    zero when it is MSL); without AltMSL from the unit's label (``wgs``: ellipsoid, ``msl``).

    Returns ``(datum, undulation [m] or None, convention)``.
    """
    g = np.asarray(alt_gps_m, float)
    lab = label.lower()
    by_label = "ellipsoid" if "wgs" in lab else "msl" if "msl" in lab else None
    if alt_msl_m is None or (ok := np.isfinite(g) & np.isfinite(alt_msl_m)).sum() < MIN_ROWS:
        if by_label is None:
            msg = (f"{column}: no AltMSL to tell the GPS height's datum and the unit "
                   f"'{label}' does not say: read as above MSL")
            return "msl", None, Convention(column, "msl", "built-in", "no AltMSL", msg)
        return by_label, None, Convention(column, by_label, "label", f"unit '{label}'")
    n = np.asarray(g[ok] - np.asarray(alt_msl_m, float)[ok])
    med = float(np.median(n))
    spread = float(np.percentile(n, 75) - np.percentile(n, 25))
    ev = f"AltGPS - AltMSL median {med:+.1f} m (interquartile {spread:.1f} m, {n.size} rows)"
    found = "msl" if abs(med) < 1.5 else "ellipsoid"
    warn = None
    if spread > 5.0 or abs(med) > 110.0:
        warn = f"{column}: {ev}: not a geoid undulation; datum read as {found}"
    elif by_label is not None and found != by_label:
        warn = (f"{column}: {ev}: the GPS height is above the {found}, not the "
                f"{by_label} its unit '{label}' says: read as {found}")
    return found, (med if found == "ellipsoid" else None), Convention(column, found, "data",
                                                                      ev, warn)
