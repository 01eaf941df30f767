"""Units and time base checked against physics, before any estimator runs.

Range checks (:mod:`flightrecon.ingest.validate`) catch values no aircraft can have; they
cannot catch a plausible number in the wrong unit: roll in radians in a ``_deg`` column never
leaves +-3.2 "degrees", a time column in milliseconds makes every rate 1000 times too small, a
GNSS height in feet is only 3.28 times too large.  Each check here compares two channels that
physics ties together and names the channel and the likely unit when they disagree by a factor
that a unit mix-up explains (docs/ingest.md, "Repaired, warned, refused"):

* **time unit**: the airspeed's rate of change against the longitudinal specific force,
  ``dV/dt = g0 (n_long - sin(pitch))`` (body x axis, small angle of attack), and the ground
  speed implied by consecutive GNSS positions against the recorded speeds; a factor near
  1/1000 means milliseconds, 60 minutes, and so on;
* **attitude in radians**: roll, pitch and heading that never leave +-3.2 (0..6.3 for heading)
  are tested against ``n_long = sin(pitch) + dV/dt / g0`` (pitch) and against the GNSS track
  angle (heading within a drift angle of the track); a channel that fits as radians and not
  as degrees is refused; all three in the radian range with nothing to test them against is
  a warning;
* **pressure altitude**: the vertical velocity from ``baro_alt_m`` changes as the vertical
  acceleration from the load factors and attitude integrates,
  ``a_up = g0 (n_long sin(theta) - n_lat sin(phi) cos(theta) + n_norm cos(phi) cos(theta)) - g0``
  (docs/schema.md, "Conventions": ``a_NED = C_nb g0 [n_long, n_lat, -n_norm] + [0, 0, g]``); a factor near 3.28 is
  a feet column declared in metres, near 0.305 the reverse;
* **airspeed unit**: the true airspeed against the GNSS ground speed (a ratio near 1.94 is
  knots in a m/s column, near 3.6 km/h);
* **GNSS height against pressure altitude**: over the climbs and descents of a flight the two
  change together (within the temperature's +-20 %); a factor near 3.28 (or 0.305) is one of
  them in feet, and the vertical-acceleration check above says which.

A log too short to reconstruct is refused by :func:`check_reconstructable` with the minimum.

Factors are least-squares fits over windows (so a sensor bias, a constant per window, drops
out) and every verdict needs enough informative samples; with too few the check is skipped.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.constants import G0
from flightrecon.errors import ValidationError

__all__ = [
    "MIN_DURATION_S",
    "MIN_INPUT_SAMPLES",
    "check_physics",
    "check_reconstructable",
]

#: a reconstruction needs at least this much record and this many samples of each input
MIN_DURATION_S = 30.0
MIN_INPUT_SAMPLES = 16
#: input channels the estimators need (the joint smoother's inputs)
RECONSTRUCT_INPUTS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg",
                      "heading_deg", "tas_mps")

FT = 0.3048
#: candidate unit factors: name -> factor by which the channel's values are too large
_LENGTH_FACTORS = {"ft (declared m)": 1 / FT, "m (declared ft)": FT}
_TIME_FACTORS = {"ms": 1e-3, "µs": 1e-6, "min": 60.0, "h": 3600.0, "cs (1/100 s)": 1e-2,
                 "ds (1/10 s)": 1e-1}
WINDOW_S = 20.0
MAX_GRID = 200_000


def _samples(data: pd.DataFrame, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    if name not in data.columns:
        return None
    v = data[name].to_numpy(dtype=float)
    ok = ~np.isnan(v)
    if ok.sum() < 8:
        return None
    return data["t_s"].to_numpy(dtype=float)[ok], v[ok]


def _on(t_grid: np.ndarray, s: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray | None:
    if s is None:
        return None
    t, v = s
    return np.interp(t_grid, t, v, left=np.nan, right=np.nan)


def _grid(data: pd.DataFrame) -> np.ndarray | None:
    t = data["t_s"].to_numpy(dtype=float)
    if t.size < 8:
        return None
    t0, t1 = float(np.nanmin(t)), float(np.nanmax(t))
    if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
        return None
    n = int(min(MAX_GRID, max(64, (t1 - t0) * 2.0)))
    return np.linspace(t0, t1, n)


def _window_factor(t: np.ndarray, y: np.ndarray, a: np.ndarray, min_dx: float,
                   min_windows: int = 6) -> float | None:
    """Least-squares factor s in ``dy = s dx + c`` over windows of :data:`WINDOW_S` seconds of
    the grid, ``dy`` the change of the velocity ``y`` and ``dx`` the integral of the
    acceleration ``a`` over the window (``c`` absorbs a constant bias).  ``None`` without
    enough informative windows (|dx| > ``min_dx``)."""
    ok = np.isfinite(y) & np.isfinite(a)
    if ok.sum() < 16:
        return None
    dt = np.diff(t)
    ai = np.where(np.isfinite(a), a, 0.0)
    X = np.concatenate([[0.0], np.cumsum(0.5 * (ai[1:] + ai[:-1]) * dt)])
    step = max(1, round(WINDOW_S / float(np.median(dt))))
    i0 = np.arange(0, t.size - step, max(1, step // 4))
    i1 = i0 + step
    good = ok[i0] & ok[i1]
    # no unsampled stretch inside a window (cheap test: the ends and the middle)
    good &= ok[(i0 + i1) // 2]
    dx = X[i1] - X[i0]
    dy = y[i1] - y[i0]
    use = good & (np.abs(dx) > min_dx)
    if use.sum() < min_windows:
        return None
    dx, dy = dx[use], dy[use]
    # a robust start (the median ratio), then least squares on the windows whose residual is
    # not an outlier: a spike in a load factor integrates to a large dx with no dy, and must
    # not pull the factor
    s0 = float(np.median(dy / dx))
    res = dy - s0 * dx
    res -= np.median(res)
    mad = 1.4826 * float(np.median(np.abs(res)))
    keep = np.abs(res) <= max(3.0 * mad, 1e-9 * float(np.median(np.abs(dy)) + 1e-300))
    if keep.sum() < min_windows:
        return s0
    A = np.column_stack([dx[keep], np.ones(int(keep.sum()))])
    coef, *_ = np.linalg.lstsq(A, dy[keep], rcond=None)
    return float(coef[0])


def _nearest(factor: float, table: dict[str, float], tol: float = 0.25) -> str | None:
    """The entry of ``table`` within ``tol`` (relative, in log) of ``factor``."""
    if not np.isfinite(factor) or factor <= 0:
        return None
    best, err = None, np.inf
    for name, f in table.items():
        e = abs(np.log(factor / f))
        if e < err:
            best, err = name, e
    return best if err < np.log(1 + tol) else None


def _smooth_velocity(t: np.ndarray, h: np.ndarray, half_s: float = 5.0) -> np.ndarray:
    """Velocity of ``h`` by a centred difference over +-``half_s`` seconds (grid ``t``)."""
    dt = float(np.median(np.diff(t)))
    k = max(1, round(half_s / dt))
    v = np.full(h.size, np.nan)
    if h.size > 2 * k:
        v[k:-k] = (h[2 * k:] - h[:-2 * k]) / (t[2 * k:] - t[:-2 * k])
    return v


def _col(prov, name: str) -> str:
    try:
        return prov.source_column[0].get(name, name)
    except (AttributeError, IndexError):
        return name


def _file(prov, name: str | None = None) -> str:
    """The file a channel came from (the log unless only a companion file has it)."""
    try:
        if name is not None:
            for i, cols in enumerate(prov.source_column):
                if name in cols:
                    return prov.files[i]
        return prov.files[0]
    except (AttributeError, IndexError):
        return "the log"


def check_physics(data: pd.DataFrame, prov) -> list[str]:
    """Run every check of the module docstring on a merged, canonical flight table.

    Parameters
    ----------
    data : ``t_s`` and canonical channels in SI units (NaN where not sampled)
    prov : :class:`flightrecon.ingest.validate.Provenance` (files and source columns)

    Returns
    -------
    warnings : suspicions that cannot be confirmed from the data

    Raises
    ------
    ValidationError
        A unit mix-up the physics confirms, naming the file, the column and the likely unit.
    """
    warns: list[str] = []
    tg = _grid(data)
    if tg is None:
        return warns
    ch = {name: _on(tg, _samples(data, name)) for name in
          ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
           "tas_mps", "baro_alt_m", "gnss_alt_m", "gnss_vn_mps", "gnss_ve_mps")}
    rad = _check_attitude_units(data, prov, tg, ch, warns)
    _check_time_unit(data, prov, tg, ch, rad)
    baro_factor = _check_baro_against_acceleration(prov, tg, ch, rad, warns)
    _check_gnss_height(data, prov, baro_factor)
    _check_airspeed_unit(prov, ch)
    return warns


# ------------------------------------------------------------------ attitude


def _radian_like(v: np.ndarray | None, heading: bool = False) -> bool:
    if v is None:
        return False
    f = v[np.isfinite(v)]
    if f.size < 8:
        return False
    if heading:
        return bool(f.min() >= -0.01 and f.max() <= 2 * np.pi + 0.01)
    return bool(np.abs(f).max() <= 3.2)


def _check_attitude_units(data, prov, tg, ch, warns) -> bool:
    """Refuse attitude in radians in ``_deg`` columns (module docstring); returns whether the
    pitch is known to be in radians (for the checks that use it: never, since it raises)."""
    like = {n: _radian_like(ch[n], heading=(n == "heading_deg"))
            for n in ("roll_deg", "pitch_deg", "heading_deg")}
    if not any(like.values()):
        return False
    confirmed: list[str] = []
    evidence: list[str] = []
    # pitch: n_long = sin(pitch) + dV/dt / g0 (exact at rest, small angle of attack in flight)
    if like["pitch_deg"] and ch["n_long_g"] is not None and ch["tas_mps"] is not None:
        vdot = _smooth_velocity(tg, ch["tas_mps"])
        p = ch["pitch_deg"]
        ok = np.isfinite(p) & np.isfinite(ch["n_long_g"]) & np.isfinite(vdot) \
            & (np.abs(p) > 0.03)
        if ok.sum() >= 32:
            nl, pv, vd = ch["n_long_g"][ok], p[ok], vdot[ok] / G0
            mis_rad = float(np.median(np.abs(nl - (np.sin(pv) + vd))))
            mis_deg = float(np.median(np.abs(nl - (np.sin(np.radians(pv)) + vd))))
            if mis_rad < 0.5 * mis_deg and mis_deg > 0.01:
                confirmed.append("pitch_deg")
                evidence.append(f"n_long_g fits sin(pitch) with pitch in radians (median misfit "
                                f"{mis_rad:.3f} g) and not in degrees ({mis_deg:.3f} g)")
    # heading: within a drift angle of the GNSS track angle
    if like["heading_deg"] and ch["gnss_vn_mps"] is not None and ch["gnss_ve_mps"] is not None:
        vn, ve, h = ch["gnss_vn_mps"], ch["gnss_ve_mps"], ch["heading_deg"]
        gs = np.hypot(vn, ve)
        ok = np.isfinite(gs) & (gs > 30.0) & np.isfinite(h)
        if ok.sum() >= 32:
            track = np.arctan2(ve[ok], vn[ok])

            def misfit(psi):
                return float(np.median(np.abs(np.angle(np.exp(1j * (track - psi))))))

            m_rad, m_deg = misfit(h[ok]), misfit(np.radians(h[ok]))
            if m_rad < 0.35 and m_deg > 2 * m_rad:
                confirmed.append("heading_deg")
                evidence.append(f"heading fits the GNSS track angle in radians (median "
                                f"{np.degrees(m_rad):.0f} deg off) and not in degrees "
                                f"({np.degrees(m_deg):.0f} deg off)")
    if confirmed:
        also = [n for n, v in like.items() if v and n not in confirmed]
        names = confirmed + also
        raise ValidationError(
            f"{', '.join(names)} look like radians recorded in degree columns (likely unit "
            f"rad): {'; '.join(evidence)}"
            + (f"; {', '.join(also)} also never leave the radian range" if also else "")
            + ". Declare unit = \"rad\" in a mapping file (docs/ingest.md)",
            file=_file(prov, names[0]), column=_col(prov, names[0]))
    if all(like.values()):
        warns.append(f"{_file(prov)}: roll_deg, pitch_deg and heading_deg never leave +-3.2 "
                     "(heading 0..6.3) over the whole record: radians in degree columns? "
                     "(likely unit rad; nothing in the log could confirm it)")
    return False


# ------------------------------------------------------------------ time unit


def _time_unit(factor: float) -> str | None:
    """The time unit that explains ``factor`` (a rate measured against a wrong time base),
    or ``None``: a factor no unit explains (a frozen channel: 0) is not a unit error."""
    return _nearest(factor, _TIME_FACTORS, tol=0.5) if factor > 0 else None


def _time_unit_message(factor: float, what: str) -> str:
    unit = _time_unit(factor)
    guess = f" (likely unit: {unit})" if unit else ""
    return (f"the time stamps are in the wrong unit{guess}: {what} disagree by a factor of "
            f"{factor:.3g}; t_s must be seconds (a mapping file can convert: [time] unit)")


def _check_time_unit(data, prov, tg, ch, rad) -> None:
    col = _col(prov, "t_s") if "t_s" in (prov.source_column[0] if prov else {}) else "t_s"
    # 1. airspeed rate against the longitudinal specific force
    if ch["tas_mps"] is not None and ch["n_long_g"] is not None and ch["pitch_deg"] is not None:
        a = G0 * (ch["n_long_g"] - np.sin(np.radians(ch["pitch_deg"])))
        f = _window_factor(tg, ch["tas_mps"], a, min_dx=3.0)
        if f is not None and (f < 0.05 or f > 20.0) and _time_unit(f):
            raise ValidationError(_time_unit_message(
                f, "the airspeed's change and the integrated longitudinal load factor"),
                file=_file(prov), column=col)
    # 2. GNSS positions against the recorded speeds
    s_lat, s_lon = _samples(data, "gnss_lat_deg"), _samples(data, "gnss_lon_deg")
    if s_lat is None or s_lon is None or len(s_lat[0]) != len(s_lon[0]):
        return
    t, lat = s_lat
    lon = s_lon[1]
    dt = np.diff(t)
    d = _haversine(lat[:-1], lon[:-1], lat[1:], lon[1:])
    ok = dt > 0
    if ok.sum() < 8:
        return
    tm = 0.5 * (t[1:] + t[:-1])
    ref = None
    for n in ("gnss_vn_mps",):
        if ch[n] is not None and ch["gnss_ve_mps"] is not None:
            ref = np.hypot(np.interp(tm, tg, ch["gnss_vn_mps"]),
                           np.interp(tm, tg, ch["gnss_ve_mps"]))
    if ref is None and ch["tas_mps"] is not None:
        ref = np.interp(tm, tg, np.nan_to_num(ch["tas_mps"], nan=0.0))
    if ref is None:
        return
    use = ok & np.isfinite(ref) & (ref > 30.0)
    if use.sum() < 8:
        return
    f = float(np.median(d[use] / dt[use]) / np.median(ref[use]))
    if (f < 0.05 or f > 20.0) and _time_unit(f):
        raise ValidationError(_time_unit_message(
            f, "the ground speed implied by consecutive GNSS positions and the recorded speed"),
            file=_file(prov, "gnss_lat_deg"), column=col)


def _haversine(lat1, lon1, lat2, lon2):
    p1, p2 = np.radians(lat1), np.radians(lat2)
    dl = np.radians(lon2 - lon1)
    a = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    return 2 * 6_371_000.0 * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


# ------------------------------------------------------------------ altitudes


def _vertical_acceleration(ch) -> np.ndarray | None:
    need = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg")
    if any(ch[n] is None for n in need):
        return None
    phi, th = np.radians(ch["roll_deg"]), np.radians(ch["pitch_deg"])
    return G0 * (ch["n_long_g"] * np.sin(th) - ch["n_lat_g"] * np.sin(phi) * np.cos(th)
                 + ch["n_norm_g"] * np.cos(phi) * np.cos(th)) - G0


def _check_baro_against_acceleration(prov, tg, ch, rad, warns) -> float | None:
    """Factor between the pressure altitude's vertical velocity changes and the integrated
    vertical acceleration; raise where it is a feet/metres mix-up."""
    if ch["baro_alt_m"] is None:
        return None
    a = _vertical_acceleration(ch)
    if a is None:
        return None
    vz = _smooth_velocity(tg, ch["baro_alt_m"])
    f = _window_factor(tg, vz, a, min_dx=2.0)
    if f is None:
        return None
    unit = _nearest(f, _LENGTH_FACTORS, tol=0.3)
    if unit is not None:
        real = "ft" if unit.startswith("ft") else "m"
        declared = "m" if real == "ft" else "ft"
        raise ValidationError(
            f"the pressure altitude changes {f:.2f} times as fast as the vertical acceleration "
            f"from the load factors and attitude integrates: it is in {real}, declared in "
            f"{declared} (likely unit {real}; set unit = \"{real}\" for baro_alt_m in a mapping "
            "file)", file=_file(prov, "baro_alt_m"), column=_col(prov, "baro_alt_m"))
    if f < 0.5 or f > 2.0:
        warns.append(f"{_file(prov, 'baro_alt_m')}: column '{_col(prov, 'baro_alt_m')}': the "
                     f"pressure altitude's rate changes {f:.2f} times as fast as the vertical "
                     "acceleration integrates (expected about 1): check its unit")
    return f


def _check_gnss_height(data, prov, baro_factor: float | None) -> None:
    sg, sb = _samples(data, "gnss_alt_m"), _samples(data, "baro_alt_m")
    if sg is None or sb is None:
        return
    t, g = sg
    b = np.interp(t, sb[0], sb[1], left=np.nan, right=np.nan)
    ok = np.isfinite(b) & np.isfinite(g)
    if ok.sum() < 16 or np.ptp(b[ok]) < 150.0:
        return
    slope = float(np.polyfit(b[ok], g[ok], 1)[0])
    unit = _nearest(slope, _LENGTH_FACTORS, tol=0.3)
    if unit is None:
        return
    baro_ok = baro_factor is not None and 0.7 < baro_factor < 1.4
    baro_bad = baro_factor is not None and _nearest(baro_factor, _LENGTH_FACTORS, 0.3)
    if baro_ok:
        who, real = "gnss_alt_m", ("ft" if unit.startswith("ft") else "m (declared ft)")
        why = "the pressure altitude agrees with the vertical acceleration"
    elif baro_bad:
        who, real = "baro_alt_m", ("ft" if unit.startswith("m") else "m (declared ft)")
        why = "the pressure altitude disagrees with the vertical acceleration"
    else:
        raise ValidationError(
            f"GNSS height (gnss_alt_m) and pressure altitude (baro_alt_m) change by a factor of "
            f"{slope:.2f} over the flight (expected about 1): one of them is in feet (likely "
            "unit ft); the vertical acceleration could not tell which (too few climbs and "
            "descents)", file=_file(prov, "gnss_alt_m"), column=_col(prov, "gnss_alt_m"))
    raise ValidationError(
        f"GNSS height changes {slope:.2f} times as fast as the pressure altitude over the "
        f"flight (expected about 1; {why}): {who} is in {real} (likely unit "
        f"{real.split()[0]}; set it in a mapping file)", file=_file(prov, who),
        column=_col(prov, who))


# ------------------------------------------------------------------ airspeed


def _check_airspeed_unit(prov, ch) -> None:
    """True airspeed against the GNSS ground speed: over a flight the wind changes their
    ratio by tens of per cent at most; a ratio near 1.94 is knots in a m/s column, 3.6 km/h."""
    if ch["tas_mps"] is None or ch["gnss_vn_mps"] is None or ch["gnss_ve_mps"] is None:
        return
    gs = np.hypot(ch["gnss_vn_mps"], ch["gnss_ve_mps"])
    tas = ch["tas_mps"]
    ok = np.isfinite(gs) & np.isfinite(tas) & (gs > 30.0)
    if ok.sum() < 32:
        return
    ratio = float(np.median(tas[ok]) / np.median(gs[ok]))
    table = {"kt": 3600 / 1852, "km/h": 3.6}
    unit = _nearest(ratio, table, tol=0.2)
    if unit is not None:
        raise ValidationError(
            f"the true airspeed is {ratio:.2f} times the GNSS ground speed over the flight "
            f"(wind changes that ratio by tens of per cent at most): it is in {unit}, not m/s "
            f"(likely unit {unit}; set it in a mapping file)",
            file=_file(prov, "tas_mps"), column=_col(prov, "tas_mps"))


# ------------------------------------------------------------------ length of the record


def check_reconstructable(flight) -> None:
    """Refuse a log too short to reconstruct, stating the minimum.

    A reconstruction needs :data:`MIN_DURATION_S` seconds of record and
    :data:`MIN_INPUT_SAMPLES` samples of each input channel it has: below that the take-off
    roll, the sensor biases and the filters' start-up cannot be told apart (a 10-row airborne
    log gave a track 9.9 km off).
    """
    d = flight.data
    file = flight.sources[0] if flight.sources else "the log"
    t = d["t_s"].to_numpy(dtype=float) if "t_s" in d.columns else np.array([])
    dur = float(t.max() - t.min()) if t.size else 0.0
    short = {c: int(d[c].notna().sum()) for c in RECONSTRUCT_INPUTS if c in d.columns
             and int(d[c].notna().sum()) < MIN_INPUT_SAMPLES}
    if dur < MIN_DURATION_S or short:
        what = f"{len(d)} rows over {dur:.3g} s"
        if short:
            what += "; " + ", ".join(f"{c} {n} samples" for c, n in short.items())
        raise ValidationError(
            f"the log is too short to reconstruct ({what}): the minimum is "
            f"{MIN_DURATION_S:g} s of record and {MIN_INPUT_SAMPLES} samples of each input "
            "channel", file=file)
