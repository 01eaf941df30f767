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
* **Fix quality** (``gnss_quality``, the NMEA GGA code): 0 (invalid), 6 (estimated / dead
  reckoning), 7 (manual input) and 8 (simulation) are not measurements of the aircraft's
  position: those fixes are masked (position, height and velocity set missing) and the masking
  is reported like a validation repair.
"""

from __future__ import annotations

import numpy as np

from flightrecon.ingest.validate import Provenance, Repair

__all__ = ["EPU_BY_NACP_M", "UERE_M", "accuracy_from_dop", "apply_gnss_quality"]

#: user-equivalent range error used with the HDOP [m]
UERE_M = 3.0
#: estimated position uncertainty (95 % horizontal bound) per NACp 1..11 [m] (DO-260B)
EPU_BY_NACP_M = {1: 18520.0, 2: 7408.0, 3: 3704.0, 4: 1852.0, 5: 926.0, 6: 555.6, 7: 185.2,
                 8: 92.6, 9: 30.0, 10: 10.0, 11: 3.0}
#: 95 % radius of a circular 2-D normal in units of its per-axis sd
R95_PER_SD = float(np.sqrt(-2.0 * np.log(0.05)))
#: NMEA GGA fix-quality codes that are not a measured position
BAD_QUALITY = (0, 6, 7, 8)
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


def apply_gnss_quality(cols: dict[str, np.ndarray], t: np.ndarray, prov: Provenance
                       ) -> tuple[list[str], list[Repair], list[str]]:
    """Derive ``gnss_h_sd_m`` where missing and mask bad-quality fixes, in ``cols`` (in place).

    Returns
    -------
    warnings, repairs, notes
    """
    warns: list[str] = []
    repairs: list[Repair] = []
    notes: list[str] = []
    n = len(t)
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
    return warns, repairs, notes
