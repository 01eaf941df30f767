"""The physics checks of the door, one channel's unit or sampling each (module docstring of
:mod:`flightrecon.ingest.physics`: sampling, attitude in radians, time unit, pressure altitude,
GNSS height, airspeed), recording their verdicts on a :class:`flightrecon.ingest.door.Door`.
"""

from __future__ import annotations

import numpy as np

from flightrecon.constants import FOOT_M, G0
from flightrecon.ingest.evidence import (
    Fit,
    double_integral_fit,
    long_acceleration,
    own_samples,
    turn_attitude_fits,
    turn_rate_fit,
    vertical_acceleration,
    wind_triangle_fit,
)
from flightrecon.ingest.door import (
    N_MIN,
    PHYSICAL_BAND,
    SE_MARGIN,
    RECONSTRUCT_INPUTS,
    UNIT_BAND,
    DeclaredUnit,
    Door,
    candidate_units,
    certain_unit,
    nearest_unit,
    plausible_fit,
)

#: time units a time column may really be in, by their size in seconds
TIME_FACTORS = {"ms": 1e-3, "µs": 1e-6, "min": 60.0, "h": 3600.0, "cs (1/100 s)": 1e-2,
                "ds (1/10 s)": 1e-1}

#: a channel missing on more than this fraction of the rows it could have been sampled on, at
#: irregular intervals, is reported
MOSTLY_MISSING = 0.5


def check_sampling(door: Door) -> None:
    """An input channel sampled at a lower rate is regular; one mostly missing at random is
    literal NaN where the recorder should have written a value (issue #39: 90 % NaN in
    ``n_long_g`` gave a track 1.3 km off without a word)."""
    t = door.data["t_s"].to_numpy(dtype=float)
    for name in RECONSTRUCT_INPUTS + ("baro_alt_m",):
        if name not in door.data.columns:
            continue
        v = door.data[name].to_numpy(dtype=float)
        ok = np.isfinite(v)
        n = int(ok.sum())
        if n < 8:
            continue
        ts = t[ok]
        dt = np.diff(ts)
        med = float(np.median(dt))
        regular = float(np.mean(np.abs(dt - med) <= 0.1 * med + 1e-9)) if med > 0 else 1.0
        # rows of the log between this channel's first and last sample
        span = (t >= ts[0]) & (t <= ts[-1])
        missing = 1.0 - n / max(int(span.sum()), 1)
        if regular < 0.5 and missing > MOSTLY_MISSING:
            door.warn("sampling", name, missing,
                      f"{door.where(name)}: {100 * missing:.0f} % of the rows have no value, at "
                      f"irregular intervals (only {100 * regular:.0f} % of the intervals are "
                      f"the median {med:.3g} s): a channel mostly missing (literal NaN where "
                      "a value was due?); the estimators bridge the holes, at a cost")
        else:
            door.record("sampling", name, "passed", 1.0 / med if med > 0 else None,
                        f"rate (Hz): {n} samples every {med:.3g} s, {100 * regular:.0f} % of the "
                        "intervals regular")


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


def _pitch_misfits(door: Door) -> tuple[float, float] | None:
    """Median misfit of ``n_long = sin(pitch) + dV/dt / g0`` with the pitch read as radians
    and as degrees, at the longitudinal load factor's samples."""
    nl, p, tas = (own_samples(door.data, n) for n in ("n_long_g", "pitch_deg", "tas_mps"))
    if nl is None or p is None or tas is None:
        return None
    t = nl[0]
    k = 5.0
    vdot = (np.interp(t + k, *tas) - np.interp(t - k, *tas)) / (2 * k)
    inside = (t - k >= tas[0][0]) & (t + k <= tas[0][-1]) & (t >= p[0][0]) & (t <= p[0][-1])
    pv = np.interp(t, *p)
    ok = inside & (np.abs(pv) > 0.03)
    if ok.sum() < 32:
        return None
    nlv, pv, vd = nl[1][ok], pv[ok], vdot[ok] / G0
    return (float(np.median(np.abs(nlv - (np.sin(pv) + vd)))),
            float(np.median(np.abs(nlv - (np.sin(np.radians(pv)) + vd)))))


def _heading_misfits(door: Door) -> tuple[float, float] | None:
    """Median angle between the GNSS track and the heading read as radians, as degrees."""
    vn, ve, h = (own_samples(door.data, n) for n in ("gnss_vn_mps", "gnss_ve_mps",
                                                     "heading_deg"))
    if vn is None or ve is None or h is None or vn[0].size != ve[0].size:
        return None
    t = vn[0]
    gs = np.hypot(vn[1], ve[1])
    ok = (gs > 30.0) & (t >= h[0][0]) & (t <= h[0][-1])
    if ok.sum() < 32:
        return None
    track = np.arctan2(ve[1][ok], vn[1][ok])
    hv = np.interp(t[ok], *h)

    def misfit(psi: np.ndarray) -> float:
        return float(np.median(np.abs(np.angle(np.exp(1j * (track - psi))))))

    return misfit(hv), misfit(np.radians(hv))


#: a roll or heading factor from the turns (:func:`turn_attitude_fits`) names a unit with
#: this many pieces of turn agreeing (a circuit gives 5-11, a spiral dive 4-6; the factor is
#: 57 times off the physical band, far beyond any turn's scatter of 5-10 %)
ATTITUDE_TURNS_MIN = 4.0


def _attitude_from_turns(door: Door) -> dict[str, tuple[str | None, Fit]]:
    """Roll and heading against the turns the loads show: channel -> (the unit named with
    certainty or ``None``, the fit)."""
    out: dict[str, tuple[str | None, Fit]] = {}
    for name, fit in turn_attitude_fits(door.data).items():
        table = candidate_units("angle", door.unit_of(name, "deg").unit)
        unit = nearest_unit(fit.factor, table, UNIT_BAND)
        sure = (unit is not None and fit.good(ATTITUDE_TURNS_MIN)
                and not (fit.factor - SE_MARGIN * fit.se <= PHYSICAL_BAND[1]
                         and fit.factor + SE_MARGIN * fit.se >= PHYSICAL_BAND[0]))
        out[name] = (unit if sure else None, fit)
    return out


def _attitude_evidence(door: Door, like: dict[str, bool]
                       ) -> tuple[dict[str, tuple[str, float, str]],
                                  list[tuple[str, str, float]]]:
    """The channels the physics shows in another angle unit (channel -> unit, factor,
    evidence), and the doubts in words."""
    found: dict[str, tuple[str, float, str]] = {}
    doubts: list[tuple[str, str, float]] = []
    for name, (unit, fit) in _attitude_from_turns(door).items():
        what = "roll" if name == "roll_deg" else "heading's change"
        text = (f"the {what} is {fit.factor:.3g} times what the turns the load factors show "
                f"give ({fit.text()})")
        if unit is not None:
            found[name] = (unit, fit.factor, text)
        elif not plausible_fit(fit) and fit.good(2.0):
            # the heading's turn expected is at the recorded airspeed: both are in doubt
            both = name == "heading_deg"
            doubts.append(("heading_deg/tas_mps" if both else name,
                           f"{door.where(name)}: {text}; not certain: check its unit"
                           + (" and the airspeed's" if both else ""), fit.factor))
    rad = 1.0 / float(np.degrees(1.0))
    if like["pitch_deg"] and "pitch_deg" not in found:
        m = _pitch_misfits(door)
        if m is not None and m[0] < 0.5 * m[1] and m[1] > 0.01:
            found["pitch_deg"] = ("rad", rad, f"n_long_g fits sin(pitch) with pitch in radians "
                                  f"(median misfit {m[0]:.3f} g) and not in degrees "
                                  f"({m[1]:.3f} g)")
    if like["heading_deg"] and "heading_deg" not in found:
        m = _heading_misfits(door)
        if m is not None and m[0] < 0.35 and m[1] > 2 * m[0]:
            found["heading_deg"] = ("rad", rad, f"heading fits the GNSS track angle in radians "
                                    f"(median {np.degrees(m[0]):.0f} deg off) and not in "
                                    f"degrees ({np.degrees(m[1]):.0f} deg off)")
    return found, doubts


def check_attitude_units(door: Door) -> None:
    """Refuse roll, pitch or heading in another angle unit than the one they are read in
    when the physics shows it with certainty: the turns the loads show (roll, heading), the
    longitudinal load (pitch), the GNSS track (heading); warn on a doubt."""
    like = {n: _radian_like(door.data[n].to_numpy(dtype=float)
                            if n in door.data.columns else None, heading=(n == "heading_deg"))
            for n in ("roll_deg", "pitch_deg", "heading_deg")}
    found, doubts = _attitude_evidence(door, like)
    check = "attitude unit"
    for name, (unit, factor, text) in list(found.items()):
        d = door.unit_of(name, "deg")
        if d.confirmed:
            contradicted(door, check, name, factor, unit, d, text)
            del found[name]
    if found:
        names = list(found)
        also = [n for n, v in like.items() if v and n not in found
                and door.unit_of(n, "deg").unit == "deg"]
        unit, factor, _ = found[names[0]]
        contradicted(door, check, names[0], factor, unit, door.unit_of(names[0], "deg"),
                     "; ".join(f"{n}: {found[n][2]}" for n in names)
                     + (f" ({', '.join(names[1:])} too)" if len(names) > 1 else "")
                     + (f"; {', '.join(also)} also never leave the radian range" if also
                        else ""))
    for name, text, factor in doubts:
        door.warn(check, name, factor, text)
    if all(like.values()):
        door.warn(check, "roll/pitch/heading", None,
                  f"{door.file()}: roll_deg, pitch_deg and heading_deg never leave +-3.2 "
                  "(heading 0..6.3) over the whole record: radians in degree columns? (likely "
                  "unit rad; nothing in the log could confirm it)")
    elif not doubts:
        door.record(check, "roll/pitch/heading", "passed", None,
                    "no channel fits another angle unit better than its own"
                    if any(like.values()) else "the attitude leaves the radian range")


# ------------------------------------------------------------------ time unit


def _time_unit(factor: float) -> str | None:
    """The time unit that explains ``factor`` (a rate measured against a wrong time base),
    or ``None``: a factor no unit explains (a frozen channel: 0) is not a unit error."""
    # within a factor of 3 (the units are 10 times apart and more; a real flight's airspeed
    # changed 0.65 times as fast as its integrated longitudinal load, angle of attack and all)
    return nearest_unit(factor, TIME_FACTORS, tol=2.0) if factor > 0 else None


def _time_unit_message(factor: float, what: str) -> str:
    unit = _time_unit(factor)
    guess = f" (likely unit: {unit})" if unit else ""
    return (f"the time stamps are in the wrong unit{guess}: {what} disagree by a factor of "
            f"{factor:.3g}; t_s must be seconds (a mapping file can convert: [time] unit)")


def check_time_unit(door: Door) -> None:
    """The time base against the airspeed's change and against the GNSS positions."""
    prov = door.prov
    col = "t_s"
    try:
        col = prov.source_column[0].get("t_s", "t_s")
    except (AttributeError, IndexError):
        pass
    acc, tas = long_acceleration(door.data), own_samples(door.data, "tas_mps")
    fit = None
    if acc is not None and tas is not None:
        span = float(door.data["t_s"].iloc[-1] - door.data["t_s"].iloc[0])
        # windows a share of the record (20 s on a 15-minute flight), so that a time base in
        # another unit is tested on the same samples as a right one
        w = span / 45.0
        fit = double_integral_fit(acc, tas, velocity=True, min_dx=3.0, window_s=w,
                                  half_s=w / 4)
    g = _gnss_speed_factor(door)
    # only a fit that explains the airspeed's changes (fit.good: a time base in another unit
    # scales them and keeps the agreement) and that the GNSS does not contradict is certain:
    # a jet whose airspeed the integrated load hardly explains (r 0.13) gave 0.0125 +- 0.019
    gnss_says_seconds = g is not None and 0.5 < g < 2.0
    if (fit is not None and fit.good(N_MIN) and not gnss_says_seconds
            and (fit.factor < 0.05 or fit.factor > 20.0) and _time_unit(fit.factor)):
        door.refuse("time unit", "t_s", fit.factor, _time_unit_message(
            fit.factor, "the airspeed's change and the integrated longitudinal load factor"),
            file=door.file(), column=col)
    if g is not None and (g < 0.05 or g > 20.0) and _time_unit(g):
        door.refuse("time unit", "t_s", g, _time_unit_message(
            g, "the ground speed implied by consecutive GNSS positions and the recorded speed"),
            file=door.file("gnss_lat_deg"), column=col)
    figs = [f for f in ((fit.factor if fit else None), g) if f is not None]
    if figs:
        door.record("time unit", "t_s", "passed", figs[0],
                    (fit.text() if fit else "") + (f"; GNSS speed factor {g:.3g}"
                                                   if g is not None else ""))
    else:
        door.record("time unit", "t_s", "skipped", None,
                    "too little airspeed change and no GNSS positions")


def _gnss_speed_factor(door: Door) -> float | None:
    s_lat, s_lon = own_samples(door.data, "gnss_lat_deg"), own_samples(door.data, "gnss_lon_deg")
    if s_lat is None or s_lon is None or len(s_lat[0]) != len(s_lon[0]):
        return None
    t, lat = s_lat
    lon = s_lon[1]
    dt = np.diff(t)
    d = _haversine(lat[:-1], lon[:-1], lat[1:], lon[1:])
    ok = dt > 0
    if ok.sum() < 8:
        return None
    tm = 0.5 * (t[1:] + t[:-1])
    vn, ve, tas = (own_samples(door.data, n) for n in ("gnss_vn_mps", "gnss_ve_mps", "tas_mps"))
    if vn is not None and ve is not None and vn[0].size == ve[0].size:
        ref = np.hypot(np.interp(tm, *vn), np.interp(tm, *ve))
    elif tas is not None:
        ref = np.interp(tm, *tas)
    else:
        return None
    use = ok & np.isfinite(ref) & (ref > 30.0)
    if use.sum() < 8:
        return None
    return float(np.median(d[use] / dt[use]) / np.median(ref[use]))


def _haversine(lat1, lon1, lat2, lon2):
    p1, p2 = np.radians(lat1), np.radians(lat2)
    dl = np.radians(lon2 - lon1)
    a = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    return 2 * 6_371_000.0 * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


# ------------------------------------------------------------------ altitudes


def contradicted(door: Door, check: str, name: str, factor: float, real: str,
                 declared: DeclaredUnit, evidence: str) -> None:
    """A unit the physics contradicts with certainty: refused (exit 5), naming the file, the
    column, where the unit comes from (the mapping's file and line, or the canonical column
    name), the factor, the likely unit and how to override; used as declared only when the
    mapping confirms it (``unit_confirmed = true``), recorded as ``overridden`` (docs/door.md).
    """
    if declared.confirmed:
        text = (f"{door.where(name)}: used in {declared.unit} as confirmed by "
                f"{declared.where} with unit_confirmed = true, against the door's evidence: "
                f"{evidence} (factor {factor:.3g}, likely unit {real})")
        door.record(check, name, "overridden", factor, text)
        door.warnings.append(text)
        return
    there = declared.table or (f"a mapping file's [channels.{name}] (column = "
                               f"\"{door.col(name)}\")")
    door.refuse(check, name, factor,
                f"{evidence}: {name} is in {real}, read as {declared.unit} (likely unit {real}; "
                f"factor {factor:.3g}; the unit {declared.unit} comes from {declared.where}). "
                f"Declare unit = \"{real}\" in {there}; if {declared.unit} is right, declare "
                f"unit = \"{declared.unit}\" with unit_confirmed = true there: it is then used "
                "as declared and the summary records the contradiction (docs/door.md)",
                file=door.file(name), column=door.col(name))


def check_baro(door: Door) -> Fit | None:
    """Pressure altitude against the integrated vertical acceleration (module docstring);
    returns the fit for the GNSS-height check."""
    name = "baro_alt_m"
    baro = own_samples(door.data, name)
    if baro is None:
        return None
    acc = vertical_acceleration(door.data)
    fit = double_integral_fit(acc, baro, velocity=False, min_dx=1.0) if acc else None
    check = "baro_alt_m unit"
    if fit is None:
        door.record(check, name, "skipped", None,
                    "too few climbs and descents (or no load factors and attitude) to fit")
        return None
    declared = door.unit_of(name, "m")
    table = candidate_units("length", declared.unit)
    unit = certain_unit(fit, table)
    evidence = (f"the pressure altitude changes {fit.factor:.2f} times as fast as the vertical "
                f"acceleration from the load factors and attitude integrates ({fit.text()})")
    if unit is not None:
        # a second witness: the GNSS height must not say the pressure altitude is right
        slope = door.gnss_baro_slope()
        if slope is not None and nearest_unit(slope[0], {"1": 1.0}, 0.3):
            door.warn(check, name, fit.factor,
                      f"{door.where(name)}: {evidence}, which suggests {unit}, but the GNSS "
                      f"height changes {slope[0]:.2f} times as fast as it (r {slope[1]:.3f}): "
                      "check the load factors and attitude, and this column's unit")
            return fit
        contradicted(door, check, name, fit.factor, unit, declared, evidence)
        return fit
    slope = door.gnss_baro_slope()
    gnss_agrees = slope is not None and slope[1] > 0.98 and nearest_unit(slope[0], {"1": 1.0}, 0.3)
    if plausible_fit(fit) and fit.good(N_MIN):
        door.record(check, name, "passed", fit.factor, fit.text())
    elif gnss_agrees and slope is not None:
        # the acceleration's fit is not decisive; a second witness is
        door.record(check, name, "passed", fit.factor,
                    f"{fit.text()}; the GNSS height changes {slope[0]:.3f} times as fast as "
                    f"it (r {slope[1]:.3f})")
    elif plausible_fit(fit):
        door.record(check, name, "skipped", fit.factor,
                    f"{fit.text()}: a fit too poor to judge (turbulence, a low rate)")
    elif fit.factor > 0 and nearest_unit(fit.factor, table, UNIT_BAND):
        door.warn(check, name, fit.factor,
                  f"{door.where(name)}: {evidence}: near the factor of "
                  f"{nearest_unit(fit.factor, table, UNIT_BAND)} read as {declared.unit}, but the "
                  "fit is not good enough to be sure: check its unit")
    elif fit.good(N_MIN):
        door.warn(check, name, fit.factor,
                  f"{door.where(name)}: {evidence} (expected about 1): check its unit and the "
                  "load factors")
    else:
        door.record(check, name, "skipped", fit.factor,
                    f"{fit.text()}: a fit too poor to judge (turbulence, a low rate)")
    return fit




def check_gnss_height(door: Door, baro_fit: Fit | None) -> None:
    """GNSS height against pressure altitude: a factor of a unit is one of them in feet; the
    vertical acceleration (fitted to each) says which."""
    check = "gnss_alt_m unit"
    slope = door.gnss_baro_slope()
    if slope is None:
        if "gnss_alt_m" in door.data.columns and "baro_alt_m" in door.data.columns:
            door.record(check, "gnss_alt_m", "skipped", None,
                        "less than 150 m of climb or descent in both heights")
        return
    f, r = slope
    gd, bd = door.unit_of("gnss_alt_m", "m"), door.unit_of("baro_alt_m", "m")
    unit = nearest_unit(f, {"ft": 1 / FOOT_M, "m": FOOT_M}, UNIT_BAND) if r > 0.98 else None
    if unit is None:
        if r > 0.98 and not nearest_unit(f, {"1": 1.0}, 0.3):
            door.warn(check, "gnss_alt_m", f,
                      f"{door.where('gnss_alt_m')}: the GNSS height changes {f:.2f} times as "
                      "fast as the pressure altitude over the flight (expected about 1): check "
                      "both units")
        else:
            door.record(check, "gnss_alt_m", "passed", f,
                        f"GNSS height against pressure altitude: slope {f:.3f}, r {r:.3f}")
        return
    acc = vertical_acceleration(door.data)
    gnss = own_samples(door.data, "gnss_alt_m")
    # a GNSS height is noisier than a pressure altitude (5 m against 1 m): r 0.77-0.84 on
    # the independent corpus, a good fit from 0.7
    g_fit = double_integral_fit(acc, gnss, velocity=False, min_dx=1.0, r_min=0.7) \
        if acc is not None and gnss is not None else None
    evidence = f"the GNSS height changes {f:.2f} times as fast as the pressure altitude (r {r:.3f})"
    baro_ok = baro_fit is not None and baro_fit.good(N_MIN) and plausible_fit(baro_fit)
    gnss_ok = g_fit is not None and g_fit.good(N_MIN) and plausible_fit(g_fit)
    if baro_ok or (g_fit is not None and g_fit.good(N_MIN) and not plausible_fit(g_fit)):
        who, dec = "gnss_alt_m", gd
        real = "ft" if f > 1 else "m"
        why = ("the pressure altitude agrees with the vertical acceleration" if baro_ok else
               f"the GNSS height disagrees with the vertical acceleration ({g_fit.text()})"
               if g_fit else "")
    elif gnss_ok:
        who, dec = "baro_alt_m", bd
        real = "ft" if f < 1 else "m"
        why = f"the GNSS height agrees with the vertical acceleration ({g_fit.text()})" \
            if g_fit else ""
    else:
        if gd.explicit or bd.explicit:
            door.warn(check, "gnss_alt_m", f,
                      f"{door.where('gnss_alt_m')}: {evidence}: one of the two heights is in "
                      "feet, as declared in the mapping; used as declared")
            return
        door.refuse(check, "gnss_alt_m", f,
                    f"GNSS height (gnss_alt_m) and pressure altitude (baro_alt_m) change by a "
                    f"factor of {f:.2f} over the flight (r {r:.3f}; expected about 1): one of "
                    "them is in feet (likely unit ft); the vertical acceleration could not tell "
                    "which (too few climbs and descents). Declare each height's unit in a "
                    "mapping file; declared units are used as declared, with a warning",
                    file=door.file("gnss_alt_m"), column=door.col("gnss_alt_m"))
        return
    contradicted(door, check, who, f, real, dec, f"{evidence}; {why}")


# ------------------------------------------------------------------ airspeed


def _fit_name(f: Fit) -> str:
    return ("heading against the loads' turns" if "bank" in f.what else
            "turns" if "turn" in f.what else "wind triangle")


def check_airspeed(door: Door) -> None:
    """True airspeed against coordinated turns and the GNSS wind triangle (module docstring):
    certain when a good fit names a unit and no other witness contradicts it."""
    name, check = "tas_mps", "tas_mps unit"
    if own_samples(door.data, name) is None:
        return
    declared = door.unit_of(name, "m/s")
    table = candidate_units("speed", declared.unit)
    # the heading's turns against the loads' turn rate at the recorded airspeed: the heading
    # in degrees (the attitude check has passed it) leaves the airspeed's factor (issue #50:
    # an ED-112 spiral dive at 1 Hz, its roll-based turns too few, gave 1.82 for knots)
    loads = turn_attitude_fits(door.data).get("heading_deg")
    fits = [f for f in (turn_rate_fit(door.data), wind_triangle_fit(door.data), loads)
            if f is not None]
    if not fits:
        door.record(check, name, "skipped", None, "no coordinated turn and no GNSS velocity "
                    "through a turn")
        return
    units = [certain_unit(f, table) for f in fits]
    # the loads' turns are the coarser witness (the bank from the load factor: 2.15 for knots
    # on a JSBSim circuit, nearer mph's 2.24): it names the unit only where the others do not
    named = {u for f, u in zip(fits, units) if u is not None and f is not loads} or (
        {units[-1]} if loads is not None and units[-1] is not None else set())
    plausible = [f for f in fits if plausible_fit(f) and f.good(N_MIN)]
    evidence = "; ".join(f"{_fit_name(f)}: {f.text()}" for f in fits)
    if len(named) == 1 and not plausible:
        unit = named.pop()
        text = (f"the true airspeed is {fits[units.index(unit)].factor:.2f} times what the "
                f"physics gives ({evidence})")
        contradicted(door, check, name, fits[units.index(unit)].factor, unit, declared, text)
        return
    worst = max(fits, key=lambda f: abs(np.log(max(f.factor, 1e-9))))
    suspect = nearest_unit(worst.factor, table, UNIT_BAND)
    if suspect and not plausible:
        door.warn(check, name, worst.factor,
                  f"{door.where(name)}: the true airspeed disagrees with the physics by a "
                  f"factor near {suspect} read as {declared.unit} ({evidence}); not certain: "
                  "check its unit")
    elif not plausible_fit(worst) and worst.good(N_MIN):
        door.warn(check, name, worst.factor,
                  f"{door.where(name)}: the true airspeed disagrees with the physics "
                  f"({evidence}; expected about 1): check its unit and scale")
    else:
        door.record(check, name, "passed", fits[0].factor, evidence)
