"""The time stamps of Garmin exports whose 1 Hz rows carry a jittering whole-second clock.

Older G1000 software (the Cessna 172S export of software 10.01 read for issue #49) stamps each
row with a whole second of a clock that does not keep step with the rows: on that export 728
stamps repeat the one before and 776 seconds are skipped (12 more steps of 3 s), 3966 rows over
4038 s of stamps.  The rows themselves are regular: the GPS position moves by the ground
speed times 1.00 s from one row to the next (median 0.999 over the rows faster than 30 m/s,
whatever the stamps' step, 0, 1 or 2 s), and by 1.92 times that across the 12 steps of 3 s (a
row lost there).  The stamps are the jittering part: read as they are, the repeated ones are
refused as ambiguous, and any re-timing that follows them puts the GPS fixes 1.8 % slower
than the ground speed they record (the smoother's GNSS clock offset 1.2 s, and no convergence).

:func:`regular_rows` re-times such rows at their own period: the GPS motion's (step / ground
speed) where the export has one, else the stamps' mean; a row lost where the motion spans two
periods (else at a step of 3 s); each
run between real gaps (a step back or longer than :data:`GAP_S`) placed on its stamps on
average.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GAP_S", "motion_period_s", "motion_rows", "regular_rows"]

#: repeated stamps, as a share of the rows, from which the re-timing is considered (below it
#: the time-order repair of :mod:`.timestamps` deals with a few repeats)
MIN_REPEATS = 0.01
#: a step longer than this [s] is a real gap: a new run starts on its stamp
GAP_S = 3
#: speed above which one row's GPS motion measures the period [m/s]
FAST_MPS = 30.0
#: fewest fast rows the motion's period rests on
MIN_FAST_ROWS = 100


def motion_period_s(lat_deg: np.ndarray, lon_deg: np.ndarray, gs_mps: np.ndarray
                    ) -> float | None:
    """The rows' period [s] from the GPS motion: the median of (distance between consecutive
    positions) / (their mean ground speed) over consecutive rows faster than
    :data:`FAST_MPS` (spherical earth: the ratio is what counts); ``None`` with fewer than
    :data:`MIN_FAST_ROWS` such rows or a figure outside 0.5-2 s."""
    lat, lon, gs = (np.asarray(x, float) for x in (lat_deg, lon_deg, gs_mps))
    r = 6_371_000.0
    dn = np.diff(np.radians(lat)) * r
    de = np.diff(np.radians(lon)) * r * np.cos(np.radians(lat[1:]))
    g = 0.5 * (gs[1:] + gs[:-1])
    ok = np.isfinite(dn) & np.isfinite(de) & (g > FAST_MPS)
    if ok.sum() < MIN_FAST_ROWS:
        return None
    p = float(np.median(np.hypot(dn[ok], de[ok]) / g[ok]))
    return p if 0.5 < p < 2.0 else None


def motion_rows(lat_deg: np.ndarray, lon_deg: np.ndarray, gs_mps: np.ndarray,
                period_s: float) -> np.ndarray:
    """Rows' periods between consecutive rows by the GPS motion (step / (ground speed x
    period): 1 from one row to the next, 2 across a lost row), NaN below :data:`FAST_MPS`."""
    lat, lon, gs = (np.asarray(x, float) for x in (lat_deg, lon_deg, gs_mps))
    r = 6_371_000.0
    dn = np.diff(np.radians(lat)) * r
    de = np.diff(np.radians(lon)) * r * np.cos(np.radians(lat[1:]))
    g = 0.5 * (gs[1:] + gs[:-1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(g > FAST_MPS, np.hypot(dn, de) / (g * period_s), np.nan)


def regular_rows(t_ns: np.ndarray, period_s: float | None = None,
                 rows_between: np.ndarray | None = None) -> tuple[np.ndarray, str | None]:
    """Times [ns] of rows (in file order) re-timed when their stamps are whole seconds that
    jitter about a regular 1 Hz series (module docstring), and the sentence saying so; the
    times unchanged and ``None`` otherwise.

    Applied when the stamps are whole seconds, their median step is 1 s, at least
    :data:`MIN_REPEATS` of them repeat the one before without the next one skipping a second
    at once (that pattern alone the time-order repair of :mod:`.timestamps` re-times onto the
    missing stamp, exactly), and the skipped seconds (steps of 2-3 s)
    number at least half the repeats (the lost seconds come back: a regular series, not a
    coarse clock).  ``period_s``: the rows' period measured otherwise
    (:func:`motion_period_s`); default the stamps' mean step within the runs.  A row is lost
    where the stamps step by :data:`GAP_S` s or, where ``rows_between`` (:func:`motion_rows`)
    is known, where the motion spans two periods or more and the stamps step by 2 s or more.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    if t.size < 10 or np.any(t % 1_000_000_000):
        return t, None
    s = (t // 1_000_000_000).astype(np.float64)
    d = np.diff(s)
    repeats = int((d == 0).sum())
    skipped = int(((d >= 2) & (d <= GAP_S)).sum())
    # a repeat followed at once by a skip (t, t, t + 2) is the time-order repair's to re-time
    # onto the missing stamp (:mod:`.timestamps`); the rest call for the rows' period
    unpaired = repeats - int(((d[:-1] == 0) & (d[1:] == 2)).sum())
    if np.median(d) != 1.0 or unpaired < MIN_REPEATS * t.size or skipped < 0.5 * repeats:
        return t, None
    inside = (d >= 0) & (d <= GAP_S)
    lost = (d == GAP_S).astype(float)            # a step of 3 s: one row lost
    if rows_between is not None:
        m = np.asarray(rows_between, float)
        lost = np.where(np.isfinite(m), ((m >= 1.5) & (d >= 2)).astype(float), lost)
    stamps_period = float(d[inside].sum() / (inside.sum() + lost.sum()))
    period = period_s if period_s is not None else stamps_period
    out = np.empty(s.size)
    cuts = np.concatenate(([0], np.flatnonzero(~inside) + 1, [s.size]))
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        k = np.concatenate(([0.0], np.cumsum(1.0 + lost[a:b - 1])))
        x = k * period
        out[a:b] = x + float(np.mean(s[a:b] + 0.5 - x))
    dev = out - s - 0.5
    source = (f"the GPS motion's ({period:.4f} s: position step / ground speed)"
              if period_s is not None else "the stamps' mean")
    note = (f"the rows' whole-second stamps jitter ({repeats} repeated, {skipped} skipped; "
            f"{t.size} rows over {s[-1] - s[0]:.0f} s of stamps, {int(lost.sum())} row(s) "
            f"lost where the GPS moved two periods or the stamps stepped {GAP_S} s): re-timed "
            f"at the rows' period, {source}; the stamps' mean is {stamps_period:.4f} s; each run of rows placed on its stamps on average "
            f"(at most {np.abs(dev).max():.1f} s from a row's stamp)")
    return np.round(out * 1e9).astype(np.int64), note
