"""Physical evidence for the door's unit checks: fits of one channel against another that
physics ties to it, each with the figures that say how far the fit can be trusted.

Every channel is used at its own sampling times (a multi-rate log has NaN where a channel was
not sampled): accelerations are integrated at the load factors' own rate, never read at points
of a coarser grid, since in turbulence point samples of a load factor alias (a 2 Hz grid made a
moderate-turbulence log's pressure altitude look 0.3 times as fast as its vertical
acceleration; issue #34).

The fits (docs/ingest.md, "The door"):

* :func:`double_integral_fit`: a height-like signal ``H`` (a pressure altitude, or the integral
  of a velocity) against the double integral ``Z`` of an acceleration.  Both are reduced by the
  same centred difference over +-``half_s`` (a mean velocity), and the change of that mean
  velocity over windows of ``window_s`` is fitted, ``dH' = s dZ' + c``: the two signals pass
  through the same linear filter, so an exact log gives ``s = 1`` whatever the filter, and a
  constant acceleration bias adds the same amount to every window (``c``).  The factor ``s``
  is the number of times the channel's values are too large.
* :func:`turn_rate_fit`: in a coordinated turn the heading turns at ``g0 tan(roll) / V``
  (``V`` the true airspeed): the factor ``median(psi_dot V / (g0 tan roll))`` is about 1 for a
  true airspeed in m/s and the unit's factor otherwise (1.94 for knots), with no GNSS.
* :func:`turn_attitude_fits`: the turns the loads show, with no GNSS and no attitude: a
  steady normal load factor ``n`` above :data:`TURN_N` is a level coordinated turn at the
  bank ``acos(1/n)`` turning at ``g0 tan(bank) / V``; the recorded roll against that bank and
  the recorded heading's rate against that turn rate are about 1 for angles in degrees and
  1/57.3 for radians in a degree column (57.3 for degrees declared as radians).
* :func:`wind_triangle_fit`: GNSS ground velocity = ``s`` x air velocity from the true
  airspeed and heading + a wind constant over each ten minutes; the turns of the flight
  separate ``s`` from the wind (a straight flight cannot: then no fit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from flightrecon.constants import G0

__all__ = [
    "Fit",
    "correlation",
    "double_integral_fit",
    "long_acceleration",
    "own_samples",
    "turn_attitude_fits",
    "turn_rate_fit",
    "vertical_acceleration",
    "wind_triangle_fit",
]

#: window over which the change of a mean velocity is fitted [s]
WINDOW_S = 20.0
#: half-width of the centred difference that makes a mean velocity of a height [s]
HALF_S = 5.0


@dataclass(frozen=True)
class Fit:
    """A factor between two channels and how well it is determined.

    Attributes
    ----------
    factor : how many times too large the tested channel's values are (1 when right)
    r : correlation of the fitted pairs (1 for a perfect linear relation)
    n_eff : number of independent pieces of evidence (windows, turns) behind the factor
    se : standard error of ``factor`` from the residual scatter and ``n_eff``
    what : what was fitted against what, in words
    r_min : the agreement ``r`` of a good fit of this kind (a correlation for the window
        fits; one less the relative scatter for the turn and wind-triangle fits)
    """

    factor: float
    r: float
    n_eff: float
    se: float
    what: str
    r_min: float = 0.95

    def good(self, n_min: float = 4.0) -> bool:
        """Whether the fit is of good quality: agreement and amount of evidence."""
        return bool(np.isfinite(self.factor) and self.r >= self.r_min
                    and self.n_eff >= n_min and np.isfinite(self.se))

    def text(self) -> str:
        """``factor 0.93 +- 0.02 (r 0.984, 74 windows)`` for messages and the door report."""
        return (f"factor {self.factor:.3g} +- {self.se:.2g} (r {self.r:.3f}, "
                f"{self.n_eff:.0f} independent {self.what})")


def own_samples(data: pd.DataFrame, name: str, min_n: int = 8
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """Times and values of ``name`` at its own samples (the rows where it is not NaN)."""
    if name not in data.columns:
        return None
    v = data[name].to_numpy(dtype=float)
    ok = np.isfinite(v)
    if ok.sum() < min_n:
        return None
    return data["t_s"].to_numpy(dtype=float)[ok], v[ok]


def _at(t: np.ndarray, s: tuple[np.ndarray, np.ndarray], angle: bool = False) -> np.ndarray:
    ts, v = s
    if angle:   # interpolate an angle through its unit vector (no jump at +-180)
        r = np.radians(v)
        return np.degrees(np.arctan2(np.interp(t, ts, np.sin(r)), np.interp(t, ts, np.cos(r))))
    return np.interp(t, ts, v)


def _loads(data: pd.DataFrame, names: tuple[str, ...]
           ) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
    """The load factors at the times of the first, others interpolated where sampled apart."""
    first = own_samples(data, names[0], min_n=32)
    if first is None:
        return None
    t = first[0]
    out = {names[0]: first[1]}
    for n in names[1:]:
        s = own_samples(data, n, min_n=32)
        if s is None:
            return None
        out[n] = s[1] if s[0].size == t.size and np.array_equal(s[0], t) else _at(t, s)
    return t, out


def vertical_acceleration(data: pd.DataFrame) -> tuple[np.ndarray, np.ndarray] | None:
    """Upward acceleration ``a_up = g0 (n_long sin th - n_lat sin phi cos th + n_norm cos phi
    cos th) - g0`` at the normal load factor's own times (attitude interpolated to them;
    docs/schema.md, "Conventions")."""
    ld = _loads(data, ("n_norm_g", "n_long_g", "n_lat_g"))
    roll, pitch = own_samples(data, "roll_deg"), own_samples(data, "pitch_deg")
    if ld is None or roll is None or pitch is None:
        return None
    t, n = ld
    phi, th = np.radians(_at(t, roll)), np.radians(_at(t, pitch))
    a = G0 * (n["n_long_g"] * np.sin(th) - n["n_lat_g"] * np.sin(phi) * np.cos(th)
              + n["n_norm_g"] * np.cos(phi) * np.cos(th)) - G0
    return t, a


def long_acceleration(data: pd.DataFrame) -> tuple[np.ndarray, np.ndarray] | None:
    """Acceleration along the body x axis less gravity's component, ``g0 (n_long - sin th)``
    (the airspeed's rate for a small angle of attack), at ``n_long_g``'s own times."""
    nl, pitch = own_samples(data, "n_long_g", min_n=32), own_samples(data, "pitch_deg")
    if nl is None or pitch is None:
        return None
    t = nl[0]
    return t, G0 * (nl[1] - np.sin(np.radians(_at(t, pitch))))


def correlation(x: np.ndarray, y: np.ndarray) -> float:
    """Pearson correlation; 0 where it is undefined (fewer than 3 pairs, a constant)."""
    if x.size < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return 0.0
    return float(np.corrcoef(x, y)[0, 1])


def _cumtrapz(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])


def _robust_line(dx: np.ndarray, dy: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``dy = s dx + c`` by least squares on the pairs whose residual from a robust start
    (median ratio) is not an outlier (a spike in a channel makes a window with no partner);
    returns ``s``, the kept mask and the residuals of the kept pairs."""
    with np.errstate(divide="ignore", invalid="ignore"):
        s0 = float(np.median(dy / dx))
    res = dy - s0 * dx
    res -= np.median(res)
    mad = 1.4826 * float(np.median(np.abs(res)))
    keep = np.abs(res) <= max(4.0 * mad, 1e-9 * (float(np.median(np.abs(dy))) + 1e-300))
    if keep.sum() < 4:
        keep = np.ones(dx.size, bool)
    A = np.column_stack([dx[keep], np.ones(int(keep.sum()))])
    coef, *_ = np.linalg.lstsq(A, dy[keep], rcond=None)
    return float(coef[0]), keep, dy[keep] - A @ coef


def double_integral_fit(acc: tuple[np.ndarray, np.ndarray],
                        y: tuple[np.ndarray, np.ndarray], *, velocity: bool,
                        min_dx: float, what: str = "windows",
                        window_s: float = WINDOW_S, half_s: float = HALF_S,
                        r_min: float = 0.95) -> Fit | None:
    """Factor of a height-like channel against the double integral of an acceleration
    (module docstring).

    Parameters
    ----------
    acc : times and values of the acceleration [m/s^2], at its own rate
    y : times and values of the tested channel at its own rate: a height [m] or, with
        ``velocity``, a velocity [m/s] (integrated once here)
    min_dx : a window is evidence when its change of mean velocity from the acceleration
        exceeds this [m/s] (quieter windows carry only noise)
    window_s, half_s : the windows' length and the centred difference's half-width [s]
    r_min : the correlation of a good fit (lower for a noisy channel such as a GNSS height)

    Returns
    -------
    Fit or None
        ``None`` with fewer than 6 informative windows.
    """
    ta, a = acc
    ty, v = y
    if ta.size < 32 or ty.size < 8:
        return None
    H = _cumtrapz(ty, v) if velocity else v
    Z = _cumtrapz(ta, _cumtrapz(ta, a))
    lo, hi = max(ta[0], ty[0]) + half_s, min(ta[-1], ty[-1]) - half_s
    if hi - lo < 3 * window_s:
        return None
    # 20 points a window, a quarter window apart: the windows scale with ``window_s`` (a time
    # base in the wrong unit is tested with windows of the same share of the record)
    tc = np.arange(lo, hi, window_s / 20.0)

    def mean_velocity(ts: np.ndarray, h: np.ndarray) -> np.ndarray:
        return (np.interp(tc + half_s, ts, h) - np.interp(tc - half_s, ts, h)) / (2 * half_s)

    vy, va = mean_velocity(ty, H), mean_velocity(ta, Z)
    # no window across a stretch where either channel was not sampled
    gap = 3.0 * max(float(np.median(np.diff(ty))), float(np.median(np.diff(ta))),
                    window_s / 40.0)
    holes = np.zeros(tc.size, bool)
    for ts in (ty, ta):
        big = np.flatnonzero(np.diff(ts) > gap)
        for i in big:
            holes |= (tc + half_s > ts[i]) & (tc - half_s < ts[i + 1])
    step = 20
    i0 = np.arange(0, tc.size - step, step // 4)
    i1 = i0 + step
    ok = ~(holes[i0] | holes[i1])
    dx, dy = (va[i1] - va[i0])[ok], (vy[i1] - vy[i0])[ok]
    use = np.abs(dx) > min_dx
    if use.sum() < 6:
        return None
    dx, dy = dx[use], dy[use]
    s, keep, res = _robust_line(dx, dy)
    n_eff = max(1.0, keep.sum() * (step // 4) / step)
    r = correlation(dx[keep], dy[keep])
    sxx = float(np.sum((dx[keep] - dx[keep].mean()) ** 2))
    sigma = float(np.std(res, ddof=min(2, res.size - 1))) if res.size > 2 else np.inf
    # overlapping windows: the scatter counts n_eff times, not once per window
    se = sigma / np.sqrt(sxx * n_eff / max(keep.sum(), 1)) if sxx > 0 else np.inf
    return Fit(s, r, n_eff, float(se), what, r_min=r_min)


def _heading_from_rates(data: pd.DataFrame) -> tuple[np.ndarray, np.ndarray] | None:
    """Heading [deg] from the body rates, ``psi_dot = (q sin phi + r cos phi) / cos theta``
    integrated from 0 (an arbitrary origin: only its rate is used), at ``r_dps``'s times."""
    q, r = own_samples(data, "q_dps", 32), own_samples(data, "r_dps", 32)
    roll, pitch = own_samples(data, "roll_deg"), own_samples(data, "pitch_deg")
    if q is None or r is None or roll is None or pitch is None:
        return None
    t = r[0]
    phi, th = np.radians(_at(t, roll)), np.radians(_at(t, pitch))
    rate = (_at(t, q) * np.sin(phi) + r[1] * np.cos(phi)) / np.maximum(np.cos(th), 0.1)
    return t, _cumtrapz(t, rate)


def turn_rate_fit(data: pd.DataFrame, half_s: float = 3.0) -> Fit | None:
    """Factor of the true airspeed from coordinated turns: ``psi_dot V / (g0 tan roll)`` over
    the seconds with at least 15 deg of roll and 2 deg/s of turn in the same sense (about 1
    for a right ``tas_mps``; the turn's slip and the wind's gusts scatter it, not bias it).
    The heading's rate comes from ``heading_deg``, or from the body rates where the log has
    no heading channel.

    ``None`` with fewer than 20 turning seconds."""
    hd = own_samples(data, "heading_deg") or _heading_from_rates(data)
    roll, tas = own_samples(data, "roll_deg"), own_samples(data, "tas_mps")
    if hd is None or roll is None or tas is None:
        return None
    th, psi = hd[0], np.unwrap(np.radians(hd[1]))
    if th[-1] - th[0] < 4 * half_s:
        return None
    tc = np.arange(th[0] + half_s, th[-1] - half_s, 1.0)
    rate = (np.interp(tc + half_s, th, psi) - np.interp(tc - half_s, th, psi)) / (2 * half_s)
    # a gap in the heading is no turn: both ends of the difference within the channel's rate
    dt_h = np.diff(th)
    gap = 3.0 * max(float(np.median(dt_h)), 0.5)
    holes = np.zeros(tc.size, bool)
    for i in np.flatnonzero(dt_h > gap):
        holes |= (tc + half_s > th[i]) & (tc - half_s < th[i + 1])
    phi = np.radians(_at(tc, roll))
    v = _at(tc, tas)
    use = (~holes & (np.abs(phi) > np.radians(15.0)) & (np.abs(rate) > np.radians(2.0))
           & (np.sign(rate) == np.sign(phi)) & (v > 1.0))
    if use.sum() < 20:
        return None
    ratio = rate[use] * v[use] / (G0 * np.tan(phi[use]))
    med = float(np.median(ratio))
    mad = 1.4826 * float(np.median(np.abs(ratio - med)))
    n_eff = use.sum() / (2 * half_s)        # seconds of turn over the difference's width
    # agreement measured as 1 - relative scatter (no correlation for a ratio)
    r = float(max(0.0, 1.0 - mad / abs(med))) if med != 0 else 0.0
    # a slipping turn and gusts scatter the ratio by 10-20 % (moderate turbulence: r 0.9)
    return Fit(med, r, float(n_eff), 1.2533 * mad / np.sqrt(max(n_eff, 1.0)),
               "turns of 6 s", r_min=0.75)


def wind_triangle_fit(data: pd.DataFrame, segment_s: float = 600.0) -> Fit | None:
    """Factor of the true airspeed from the wind triangle: ``v_gnss = s V u(psi) + w_k``, a
    wind ``w_k`` per ``segment_s`` of flight, over the GNSS velocities faster than 30 m/s;
    the factor is ``1/s``.  ``None`` unless the heading spans enough turning (in each
    segment used, the air velocity's directions must not lie on one line) and 32 fixes."""
    vn, ve = own_samples(data, "gnss_vn_mps"), own_samples(data, "gnss_ve_mps")
    hd, tas = own_samples(data, "heading_deg"), own_samples(data, "tas_mps")
    if vn is None or ve is None or hd is None or tas is None or vn[0].size != ve[0].size:
        return None
    t = vn[0]
    inside = (t >= max(hd[0][0], tas[0][0])) & (t <= min(hd[0][-1], tas[0][-1]))
    gs = np.hypot(vn[1], ve[1])
    use = inside & (gs > 30.0)
    if use.sum() < 32:
        return None
    t = t[use]
    g = np.column_stack([vn[1][use], ve[1][use]])
    psi = np.radians(_at(t, hd, angle=True))
    v = _at(t, tas)
    air = v[:, None] * np.column_stack([np.cos(psi), np.sin(psi)])
    seg = ((t - t[0]) // segment_s).astype(int)
    # a wind per segment and axis is a nuisance parameter: profiled out by centring each
    # segment's air and ground velocities (Frisch-Waugh), ``s`` is then one ratio
    xs, ys, raw = [], [], []
    for k in np.unique(seg):
        m = seg == k
        if m.sum() < 16:
            continue
        # the segment's air-velocity directions must spread across (a turn): the smallest
        # spread at least a tenth of the airspeed, else wind and factor are not separable
        d = air[m] - air[m].mean(axis=0)
        ev = np.linalg.eigvalsh(d.T @ d / m.sum())
        if np.sqrt(max(ev[0], 0.0)) < 0.1 * float(np.mean(v[m])):
            continue
        xs.append(d.ravel())
        ys.append((g[m] - g[m].mean(axis=0)).ravel())
        raw.append(g[m].ravel())
    if not xs:
        return None
    x, y = np.concatenate(xs), np.concatenate(ys)
    sxx = float(x @ x)
    s = float(x @ y) / sxx
    if s <= 0:
        return None
    sigma = float(np.std(y - s * x))
    # correlated fixes: about one independent residual per 10 s
    n_eff = x.size / 2 / 10.0
    se_s = float(np.sqrt(sigma ** 2 / sxx * 10.0))
    r = float(max(0.0, 1.0 - sigma / max(float(np.std(np.concatenate(raw))), 1e-9)))
    return Fit(1.0 / s, r, n_eff, se_s / s ** 2, "10 s of GNSS velocity", r_min=0.75)



#: a turn is a stretch of at least this many seconds [s] whose mean |roll| stays above
#: :data:`TURN_SHARE` of the record's 99th percentile, and in which the mean normal load factor
#: exceeds the wings-level one by :data:`TURN_DN` (a bank of 11 deg: the loads show a turn)
TURN_MIN_S = 6.0
#: a longer turn (a spiral, a holding) is cut into pieces of this length, each a piece of
#: evidence (the turbulence's gusts decorrelate within a few seconds) [s]
TURN_PIECE_S = 10.0
TURN_SHARE = 0.4
TURN_DN = 0.02
#: half-width of the mean over which the load factor and the roll are taken [s]
TURN_HALF_S = 2.0


def _window_mean(tc: np.ndarray, s: tuple[np.ndarray, np.ndarray], half_s: float
                 ) -> np.ndarray:
    """Mean of a channel over ``tc +- half_s`` from its own samples (trapezoidal)."""
    ts, v = s
    c = _cumtrapz(ts, v)
    return (np.interp(tc + half_s, ts, c) - np.interp(tc - half_s, ts, c)) / (2 * half_s)


def _pieces_fit(f: list[float], what: str) -> Fit | None:
    """A factor as the median of independent pieces' factors; agreement ``1 - MAD/median``."""
    x = np.asarray([v for v in f if np.isfinite(v) and v > 0])
    if x.size < 2:
        return None
    med = float(np.median(x))
    mad = 1.4826 * float(np.median(np.abs(x - med)))
    return Fit(med, float(max(0.0, 1.0 - mad / med)), float(x.size),
               1.2533 * max(mad, 1e-3 * med) / np.sqrt(x.size), what, r_min=0.75)


def _turns(tc: np.ndarray, rr: np.ndarray, air: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the turns by the recorded roll (module docstring, :data:`TURN_MIN_S`),
    a long turn cut into pieces of about :data:`TURN_PIECE_S`."""
    if air.sum() < 20:
        return []
    thr = TURN_SHARE * float(np.percentile(rr[air], 99))
    if thr <= 0:
        return []
    m = np.concatenate([[False], air & (rr >= thr), [False]]).astype(np.int8)
    d = np.diff(m)
    out = []
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        n = max(1, int((b - a) // TURN_PIECE_S))
        out += [k for k in np.array_split(np.arange(a, b), n) if k.size >= TURN_MIN_S]
    return out


def _turned(psi: tuple[np.ndarray, np.ndarray], t0: float, t1: float) -> float:
    """How far the heading (unwrapped at 360) turned from ``t0`` to ``t1``: the sum of its
    steps, less the steps ten times the median one (the wraps of a heading in another unit:
    6.28 for radians)."""
    t, h = psi
    i0, i1 = np.searchsorted(t, t0, "left"), np.searchsorted(t, t1, "right")
    if i1 - i0 < 2:
        return float(abs(np.interp(t1, t, h) - np.interp(t0, t, h)))
    d = np.diff(h[i0:i1])
    med = float(np.median(np.abs(d)))
    keep = np.abs(d) <= 10.0 * med if med > 0 else np.ones(d.size, bool)
    return float(abs(d[keep].sum()))


def turn_attitude_fits(data: pd.DataFrame, half_s: float = TURN_HALF_S) -> dict[str, Fit]:
    """The roll's and the heading's factors from the turns the loads show (module docstring).

    The turns are found by the recorded roll whatever its unit (:func:`_turns`); in each, the
    mean normal load factor over the wings-level one, ``n``, is that of a level coordinated
    turn at the bank ``acos(1/n)``:

    * roll: the mean |roll| against the bank the loads show, ``acos(1/n)`` in degrees (about
      1; 1/57.3 for radians in a degree column);
    * heading: the heading's change over the turn against ``g0 tan(acos(1/n)) T / V`` (about
      1; 1/57.3 for radians, 57.3 for degrees declared as radians).

    A climbing turn or turbulence scatters the pieces by 10-20 %; one piece per turn, or per
    :data:`TURN_PIECE_S` of a long one.  A channel with fewer than two pieces has no entry.
    """
    n, roll = own_samples(data, "n_norm_g", 32), own_samples(data, "roll_deg")
    if n is None or roll is None:
        return {}
    lo, hi = max(n[0][0], roll[0][0]) + half_s, min(n[0][-1], roll[0][-1]) - half_s
    tc = np.arange(lo, hi, 1.0)
    if tc.size < 20:
        return {}
    ns = _window_mean(tc, n, half_s)
    rr = _window_mean(tc, (roll[0], np.abs(roll[1])), half_s)
    tas = own_samples(data, "tas_mps")
    v = _at(tc, tas) if tas is not None else None
    air = (v > 30.0) if v is not None else np.ones(tc.size, bool)
    turns = _turns(tc, rr, air)
    if not turns:
        return {}
    level = air.copy()
    for k in turns:
        level[k] = False
    n0 = float(np.median(ns[level])) if level.sum() >= 10 else 1.0
    hd = own_samples(data, "heading_deg")
    psi = None if hd is None else (hd[0], np.unwrap(hd[1], period=360.0))
    f_roll, f_head = [], []
    for k in turns:
        dn = float(np.mean(ns[k])) / n0 - 1.0
        if dn < TURN_DN:
            continue
        bank_deg = float(np.degrees(np.arccos(1.0 / (1.0 + dn))))
        f_roll.append(float(np.mean(rr[k])) / bank_deg)
        if psi is None or v is None or tc[k[0]] < psi[0][0] or tc[k[-1]] > psi[0][-1]:
            continue
        expect = np.degrees(G0 * np.tan(np.radians(bank_deg)) * (tc[k[-1]] - tc[k[0]])
                            / float(np.mean(v[k])))
        if expect >= 10.0:
            f_head.append(_turned(psi, tc[k[0]], tc[k[-1]]) / expect)
    out: dict[str, Fit] = {}
    for name, f, what in (("roll_deg", f_roll, "turns (roll against the bank acos(1/n_norm))"),
                          ("heading_deg", f_head, "turns (heading change against "
                                                  "g0 tan(bank) T / V)")):
        fit = _pieces_fit(f, what)
        if fit is not None:
            out[name] = fit
    return out
