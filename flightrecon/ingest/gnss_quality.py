"""GNSS fixes as receivers write them: accuracy figures and fix-quality flags.

* **Per-fix accuracy.**  ``gnss_h_sd_m`` (horizontal sd per axis), ``gnss_v_sd_m`` (vertical sd)
  and ``gnss_vel_sd_mps`` are used as given.  Where ``gnss_h_sd_m`` is absent it is derived:

  - from the HDOP: ``sd = HDOP * UERE / sqrt(2)`` with the user-equivalent range error
    ``UERE_M`` = 3 m (HDOP scales the range error into the 2-D RMS horizontal error,
    ``sqrt(sd_N^2 + sd_E^2) = HDOP * UERE``; per axis the 2-D RMS is divided by sqrt(2));
  - from the ADS-B NACp: its estimated position uncertainty ``EPU`` (RTCA DO-260B: a 95 %
    bound on the horizontal error, e.g. NACp 8: 92.6 m, 9: 30 m, 10: 10 m, 11: 3 m) over 2.448,
    the 95 % radius of a circular 2-D normal in units of its per-axis sd
    (``sqrt(-2 ln 0.05)``); NACp 0 (unknown) gives no figure.

  A fix without a figure gets the estimator's default noise.
* **Positions recorded in steps.**  An export that keeps few digits writes the latitude in
  steps (five significant digits: 0.001 deg, 111 m): the rounding error is uniform over a step,
  sd ``step / sqrt(12)`` (32 m), and dwarfs the receiver's.  A step is detected when 95 % of
  the fixes' latitudes (longitudes) are whole multiples of their smallest difference and that
  step is at least :data:`MIN_STEP_M`; the rounding sd of the coarser axis is then added, in
  quadrature, to ``gnss_h_sd_m`` (to :data:`UERE_M` where the log has no figure), and a note
  says so.  A GNSS height recorded in steps of :data:`MIN_STEP_M` or more (whole tens of feet)
  adds its own rounding to ``gnss_v_sd_m`` the same way: each axis its own.  The rounding is
  added after the analyst's options (:mod:`.gnss_use`), on top of a receiver's sd given there.
* **A fix repeated at the recorder's rate.**  A recorder sampling its GNSS faster than the
  receiver updates writes each fix several times (a 1 Hz receiver on a 10 Hz frame: runs of
  ten identical positions).  Where fixes come faster than 1.5 Hz and the median run of
  identical consecutive positions is 3 or longer, only the first of each run is kept (a
  measurement is used once); the repeats are masked and reported.
* **Fix quality** (``gnss_quality``, the NMEA GGA code): 0 (invalid), 6 (estimated / dead
  reckoning), 7 (manual input) and 8 (simulation) are not measurements of the aircraft's
  position: those fixes are masked (position, height and velocity set missing) and the masking
  is reported like a validation repair.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.ingest.gnss_use import GnssUse, apply_gnss_use
from flightrecon.ingest.validate import Provenance, Repair

__all__ = ["EPU_BY_NACP_M", "MIN_STEP_M", "UERE_M", "accuracy_from_dop", "apply_gnss_quality",
           "recording_step"]

#: user-equivalent range error used with the HDOP [m]
UERE_M = 3.0
#: estimated position uncertainty (95 % horizontal bound) per NACp 1..11 [m] (DO-260B)
EPU_BY_NACP_M = {1: 18520.0, 2: 7408.0, 3: 3704.0, 4: 1852.0, 5: 926.0, 6: 555.6, 7: 185.2,
                 8: 92.6, 9: 30.0, 10: 10.0, 11: 3.0}
#: 95 % radius of a circular 2-D normal in units of its per-axis sd
R95_PER_SD = float(np.sqrt(-2.0 * np.log(0.05)))
#: NMEA GGA fix-quality codes that are not a measured position
BAD_QUALITY = (0, 6, 7, 8)
#: a recording step of the position smaller than this is not worth a word [m]
MIN_STEP_M = 2.0
#: metres per degree of latitude (mean; enough for a rounding step)
M_PER_DEG = 111_320.0
_FIX_COLUMNS = ("gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m", "gnss_vn_mps", "gnss_ve_mps")


def accuracy_from_dop(hdop: np.ndarray | None, nacp: np.ndarray | None, n: int) -> np.ndarray:
    """Horizontal sd per axis [m] from the HDOP, else the NACp (module docstring); NaN where
    neither gives one."""
    out = np.full(n, np.nan)
    if nacp is not None:
        epu = np.full(n, np.nan)
        for k, v in EPU_BY_NACP_M.items():
            epu[np.round(nacp) == k] = v
        out = epu / R95_PER_SD
    if hdop is not None:
        sd = hdop * UERE_M / np.sqrt(2.0)
        out = np.where(np.isfinite(sd) & (hdop > 0), sd, out)
    return out


def recording_step(values: np.ndarray) -> float | None:
    """The step in which ``values`` were recorded (module docstring), or ``None`` when they
    are not whole multiples of one step (or too few to tell)."""
    v = values[np.isfinite(values)]
    u = np.unique(v)
    if u.size < 10:
        return None
    d = np.diff(u)
    step = float(d.min())
    if step <= 0.0:
        return None
    r = v / step
    on = np.abs(r - np.round(r)) < 0.01
    return step if float(on.mean()) >= 0.95 else None


def _repeated_fixes(cols: dict[str, np.ndarray], t: np.ndarray, prov: Provenance
                    ) -> tuple[list[str], list[Repair]]:
    """Mask the repeats of a fix written at the recorder's rate (module docstring)."""
    lat, lon = cols.get("gnss_lat_deg"), cols.get("gnss_lon_deg")
    if lat is None or lon is None:
        return [], []
    idx = np.flatnonzero(np.isfinite(lat) & np.isfinite(lon))
    if idx.size < 20:
        return [], []
    rate = (idx.size - 1) / max(float(t[idx[-1]] - t[idx[0]]), 1e-9)
    same = (lat[idx[1:]] == lat[idx[:-1]]) & (lon[idx[1:]] == lon[idx[:-1]])
    starts = np.flatnonzero(np.r_[True, ~same])
    runs = np.diff(np.r_[starts, idx.size])
    if rate <= 1.5 or float(np.median(runs)) < 3:
        return [], []
    repeat = np.ones(idx.size, bool)
    repeat[starts] = False
    bad = np.zeros(len(t), bool)
    bad[idx[repeat]] = True
    for c in _FIX_COLUMNS:
        if c in cols:
            v = cols[c].copy()
            v[bad] = np.nan
            cols[c] = v
    warns, repairs = [], []
    for f in np.unique(prov.src_file[bad]):
        m = bad & (prov.src_file == f)
        col = prov.source_column[int(f)].get("gnss_lat_deg", "gnss_lat_deg")
        rep = Repair(file=prov.files[int(f)], column=col, channel="gnss_lat_deg",
                     rows=tuple(int(r) for r in prov.row[m]), count=int(m.sum()),
                     action="masked", first_value=float(lat[m][0]), bound=(-90.0, 90.0),
                     t_s=tuple(float(x) for x in t[m]),
                     why=f"the same position written again at the recorder's {rate:.3g} Hz "
                         f"(median run of {float(np.median(runs)):.0f} identical fixes): "
                         "each fix used once, at its first row")
        repairs.append(rep)
        warns.append(rep.message())
    return warns, repairs


def _quantised_positions(cols: dict[str, np.ndarray], rec: dict | None = None) -> list[str]:
    """Add the rounding of positions recorded in steps to ``gnss_h_sd_m`` and of heights
    recorded in steps to ``gnss_v_sd_m``, each axis its own (module docstring); returns the
    notes, and records the rounding sd added per axis in ``rec`` (``rounding_h_sd_m``,
    ``rounding_v_sd_m``)."""
    lat, lon = cols.get("gnss_lat_deg"), cols.get("gnss_lon_deg")
    if lat is None or lon is None or np.isfinite(lat).sum() < 20:
        return []
    coslat = float(np.cos(np.radians(np.nanmedian(lat))))
    notes = []
    steps = {}
    for name, v, scale in (("latitude", lat, M_PER_DEG), ("longitude", lon,
                                                          M_PER_DEG * coslat)):
        st = recording_step(v)
        if st is not None and st * scale >= MIN_STEP_M:
            steps[name] = (st, st * scale)
    if steps:
        q_m = max(m for _, m in steps.values())
        shown = "; ".join(f"{k} in steps of {st:.3g} deg ({m:.0f} m)" for k, (st, m)
                          in steps.items())
        notes.append(_add_rounding(cols, "gnss_h_sd_m", np.isfinite(lat), q_m, shown, rec))
    alt = cols.get("gnss_alt_m")
    if alt is not None and np.isfinite(alt).sum() >= 20:
        st = recording_step(alt)
        if st is not None and st >= MIN_STEP_M:
            notes.append(_add_rounding(cols, "gnss_v_sd_m", np.isfinite(alt), st,
                                       f"height in steps of {st:.3g} m", rec))
    return notes


def _add_rounding(cols: dict[str, np.ndarray], ch: str, fix: np.ndarray, step_m: float,
                  shown: str, rec: dict | None) -> str:
    """``ch`` on the fixes ``fix`` with the rounding sd ``step_m / sqrt(12)`` added in
    quadrature (to :data:`UERE_M` where there is no figure); returns the note."""
    sd_round = step_m / np.sqrt(12.0)
    have = cols.get(ch)
    base = np.full(len(fix), UERE_M) if have is None else np.where(np.isfinite(have), have,
                                                                   UERE_M)
    cols[ch] = np.where(fix, np.hypot(base, sd_round), np.nan if have is None else have)
    if rec is not None:
        rec[ch.replace("gnss_", "rounding_")] = float(sd_round)
    return (f"GNSS {'positions' if ch == 'gnss_h_sd_m' else 'heights'} recorded in steps "
            f"({shown}): the rounding, sd {sd_round:.0f} m (step / sqrt(12)), added to {ch}"
            + ("" if have is not None else f" (receiver {UERE_M:g} m where none is recorded)"))


def apply_gnss_quality(cols: dict[str, np.ndarray], t: np.ndarray, prov: Provenance,
                       use: GnssUse | None = None
                       ) -> tuple[list[str], list[Repair], list[str], dict[str, Any]]:
    """Derive ``gnss_h_sd_m`` where missing, mask bad-quality and repeated fixes, apply the
    analyst's GNSS options (:func:`.gnss_use.apply_gnss_use`: interval, withheld windows,
    receiver's sd) and add the rounding of positions recorded in steps, in ``cols`` (in place;
    module docstring).

    Returns
    -------
    warnings, repairs, notes, record
        ``record``: what the options did and the rounding added per axis (empty when neither
        applies), for ``FlightMeta.ingest.gnss_use``.
    """
    warns: list[str] = []
    repairs: list[Repair] = []
    notes: list[str] = []
    n = len(t)
    had_sd: dict[str, str] = {c: "recorded" for c in ("gnss_h_sd_m", "gnss_v_sd_m")
              if c in cols and np.isfinite(cols[c]).any()}
    hdop, nacp = cols.get("gnss_hdop"), cols.get("gnss_nacp")
    if hdop is not None or nacp is not None:
        sd = accuracy_from_dop(hdop, nacp, n)
        have = cols.get("gnss_h_sd_m")
        if have is None:
            have = np.full(n, np.nan)
        fill = ~np.isfinite(have) & np.isfinite(sd)
        if fill.any():
            cols["gnss_h_sd_m"] = np.where(fill, sd, have)
            src = " and ".join(s for s, v in (("HDOP", hdop), ("NACp", nacp)) if v is not None)
            had_sd["gnss_h_sd_m"] = ("recorded and " if "gnss_h_sd_m" in had_sd else "") \
                + f"from the {src}"
            notes.append(f"gnss_h_sd_m from the {src} on {int(fill.sum())} fixes (HDOP x "
                         f"{UERE_M:g} m / sqrt(2); NACp: EPU / {R95_PER_SD:.3f})")
    q = cols.get("gnss_quality")
    if q is not None:
        bad = np.isin(np.round(q), BAD_QUALITY) & np.isfinite(q)
        if bad.any():
            for c in _FIX_COLUMNS:
                if c in cols:
                    v = cols[c].copy()
                    v[bad] = np.nan
                    cols[c] = v
            for f in np.unique(prov.src_file[bad]):
                m = bad & (prov.src_file == f)
                col = prov.source_column[int(f)].get("gnss_quality", "gnss_quality")
                codes = ", ".join(str(int(c)) for c in np.unique(np.round(q[m])))
                rep = Repair(file=prov.files[int(f)], column=col, channel="gnss_quality",
                             rows=tuple(int(r) for r in prov.row[m]), count=int(m.sum()),
                             action="masked", first_value=float(q[m][0]), bound=(0.0, 9.0),
                             t_s=tuple(float(x) for x in t[m]),
                             why=f"fix quality {codes} (0 invalid, 6 estimated, 7 manual, "
                                 "8 simulation): not a measured position")
                repairs.append(rep)
                warns.append(rep.message())
    w, r = _repeated_fixes(cols, t, prov)
    warns += w
    repairs += r
    w, nu, rec = apply_gnss_use(cols, t, use, had_sd)
    warns += w
    notes += nu
    notes += _quantised_positions(cols, rec)
    return warns, repairs, notes, rec
