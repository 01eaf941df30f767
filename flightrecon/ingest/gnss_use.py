"""How the analyst wants a log's GNSS fixes used: withheld, thinned, given a receiver's sd.

The analyst's word, from the command line (``reconstruct --no-gnss``, ``--withhold-gnss
START:END``, ``--gnss-interval S``, ``--gnss-sd H[:V]``), the ``load_flight`` keyword
``gnss_use`` or the sidecar's ``[gnss]`` table (docs/ingest.md, "Using the GNSS")::

    [gnss]
    withhold = false                     # true: no GNSS at all (--no-gnss)
    withhold_s = [[1512.1, 1812.1]]      # fixes withheld over these windows [s of the log]
    interval_s = 1.0                     # at most one fix per interval
    h_sd_m = 14.0                        # receiver's horizontal sd per axis [m]
    v_sd_m = 20.0                        # receiver's vertical sd [m]

Each option has one meaning; the command line wins over the sidecar option by option.  They
are applied after the fix-quality checks (:mod:`.gnss_quality`: bad fixes and a fix repeated
at the recorder's rate masked) and before the rounding of positions recorded in steps is added:

1. **Interval** ``interval_s = N``: the time axis is cut into slots ``[k N, (k + 1) N)`` of
   the log's time (seconds from the epoch; a slot starts :data:`SLOT_TOLERANCE_S` early, for
   clock values written as 4.9999999) and the first fix of each slot is kept: at most one fix
   every N s, the same fixes whatever the record's start or trim (a 10 Hz frame with
   ``N = 1``: the fixes at whole seconds).
2. **Windows** ``withhold_s``: the fixes with ``START <= t <= END`` are withheld (every GNSS
   channel of the row set missing), after the thinning, so a window does not shift the slots.
3. **Receiver's sd** ``h_sd_m`` / ``v_sd_m``: the sd of each kept fix, replacing the log's own
   figure (a per-fix column, or one derived from the HDOP / NACp: a guess of the tool's, or a
   receiver's estimate the analyst overrules; a note says which and on how many fixes).  The
   rounding of positions recorded in steps is then still added in quadrature, per axis
   (:func:`.gnss_quality.apply_gnss_quality`): the analyst gives the receiver's error, the
   tool the export's.

What was done is recorded in ``FlightMeta.ingest.gnss_use`` (counts of fixes kept,
thinned and withheld per window, the sd given and the rounding added), reported in the
summary's ``measurements`` and in the cleaning report.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from flightrecon.errors import MetadataError

__all__ = ["GnssUse", "SLOT_TOLERANCE_S", "apply_gnss_use", "gnss_use_from_table", "interval_slots",
           "parse_gnss_sd", "parse_window"]

#: a slot of ``interval_s`` starts this much early: clock values written as ``k - 1e-9``
#: (a float sum of 0.1 s steps) belong to slot ``k`` [s]
SLOT_TOLERANCE_S = 1e-3
#: largest sd the options accept [m] (the schema's range of ``gnss_h_sd_m``)
SD_MAX_M = 100_000.0
#: the GNSS channels a withheld or thinned fix loses
_FIX_CHANNELS = ("gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m", "gnss_vn_mps", "gnss_ve_mps",
                 "gnss_vd_mps", "gnss_h_sd_m", "gnss_v_sd_m", "gnss_vel_sd_mps", "gnss_hdop",
                 "gnss_nacp", "gnss_quality", "gnss_sats")
TABLE_KEYS = ("withhold", "withhold_s", "interval_s", "h_sd_m", "v_sd_m")


@dataclasses.dataclass(frozen=True)
class GnssUse:
    """How the log's GNSS fixes are used (module docstring).

    Attributes
    ----------
    withhold : use no GNSS at all (the log's channels nor a GNSS file; ``--no-gnss``)
    withhold_s : windows ``(start, end)`` [s of the log's time] whose fixes are withheld
    interval_s : keep at most one fix per slot of this length [s] (``None``: every fix)
    h_sd_m, v_sd_m : the receiver's horizontal sd per axis and vertical sd [m]
        (``None``: the log's figure, else the estimator's default)
    """

    withhold: bool = False
    withhold_s: tuple[tuple[float, float], ...] = ()
    interval_s: float | None = None
    h_sd_m: float | None = None
    v_sd_m: float | None = None

    def __post_init__(self) -> None:
        wins = tuple(_window(a, b, "withhold_s") for a, b in self.withhold_s)
        object.__setattr__(self, "withhold_s", wins)
        if self.interval_s is not None:
            object.__setattr__(self, "interval_s", _positive(self.interval_s, "interval_s",
                                                             1e6))
        for k in ("h_sd_m", "v_sd_m"):
            v = getattr(self, k)
            if v is not None:
                object.__setattr__(self, k, _positive(v, k, SD_MAX_M))

    @property
    def any(self) -> bool:
        """Whether anything beyond the default (every fix, the log's sd) is asked."""
        return self != GnssUse()

    def over(self, base: GnssUse | None) -> GnssUse:
        """These options laid over ``base`` (the sidecar's): each one given here wins; the
        windows given here replace the base's; ``withhold`` holds if either says so."""
        if base is None:
            return self
        return GnssUse(withhold=self.withhold or base.withhold,
                       withhold_s=self.withhold_s or base.withhold_s,
                       interval_s=self.interval_s if self.interval_s is not None
                       else base.interval_s,
                       h_sd_m=self.h_sd_m if self.h_sd_m is not None else base.h_sd_m,
                       v_sd_m=self.v_sd_m if self.v_sd_m is not None else base.v_sd_m)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: windows as lists."""
        d = dataclasses.asdict(self)
        d["withhold_s"] = [list(w) for w in self.withhold_s]
        return d


def _positive(v: Any, what: str, hi: float) -> float:
    if isinstance(v, bool):
        raise MetadataError(f"GNSS option {what} must be a number, got {v!r}")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise MetadataError(f"GNSS option {what} must be a number, got {v!r}") from None
    if not math.isfinite(x) or not 0.0 < x <= hi:
        raise MetadataError(f"GNSS option {what} = {v!r} must be in (0, {hi:g}]")
    return x


def _window(a: Any, b: Any, what: str) -> tuple[float, float]:
    try:
        lo, hi = float(a), float(b)
    except (TypeError, ValueError):
        raise MetadataError(f"GNSS option {what}: a window is START:END in seconds of the "
                            f"log's time, got {a!r}:{b!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
        raise MetadataError(f"GNSS option {what}: window {a!r}:{b!r} must have START < END "
                            "(finite seconds of the log's time)")
    return lo, hi


def parse_window(text: str) -> tuple[float, float]:
    """``"START:END"`` (seconds of the log's time) as a window.

    Raises
    ------
    MetadataError
        Not two numbers separated by ``:``, or ``START >= END``.
    """
    parts = str(text).split(":")
    if len(parts) != 2:
        raise MetadataError(f"--withhold-gnss: a window is START:END in seconds of the log's "
                            f"time, got '{text}'")
    return _window(parts[0].strip(), parts[1].strip(), "--withhold-gnss")


def parse_gnss_sd(text: str) -> tuple[float, float | None]:
    """``"H"`` or ``"H:V"`` (metres) as the receiver's horizontal and vertical sd.

    Raises
    ------
    MetadataError
        Not one or two positive numbers.
    """
    parts = str(text).split(":")
    if len(parts) not in (1, 2):
        raise MetadataError(f"--gnss-sd: H[:V] in metres, got '{text}'")
    h = _positive(parts[0].strip(), "--gnss-sd H", SD_MAX_M)
    v = _positive(parts[1].strip(), "--gnss-sd V", SD_MAX_M) if len(parts) == 2 else None
    return h, v


def gnss_use_from_table(t: Any, file: str) -> tuple[GnssUse, list[str]]:
    """The sidecar's ``[gnss]`` table as :class:`GnssUse`, and warnings for unknown keys.

    Raises
    ------
    MetadataError
        Not a table, or a value of the wrong type or range.
    """
    if not isinstance(t, dict):
        raise MetadataError("[gnss] must be a table", file=file)
    warns = [f"{file}: unknown key [gnss] {k} (ignored; known: {', '.join(TABLE_KEYS)})"
             for k in t if k not in TABLE_KEYS]
    withhold = t.get("withhold", False)
    if not isinstance(withhold, bool):
        raise MetadataError(f"[gnss] withhold must be true or false, got {withhold!r}",
                            file=file)
    wins = t.get("withhold_s", [])
    if not isinstance(wins, list) or not all(isinstance(w, list) and len(w) == 2
                                             for w in wins):
        raise MetadataError("[gnss] withhold_s must be a list of [start, end] pairs (seconds "
                            "of the log's time)", file=file)
    try:
        use = GnssUse(withhold=withhold, withhold_s=tuple((w[0], w[1]) for w in wins),
                      interval_s=t.get("interval_s"), h_sd_m=t.get("h_sd_m"),
                      v_sd_m=t.get("v_sd_m"))
    except MetadataError as exc:
        raise MetadataError(f"[gnss] {exc.message}", file=file) from None
    return use, warns


def interval_slots(t: np.ndarray, fix: np.ndarray, interval_s: float) -> np.ndarray:
    """The fixes kept by the interval: the first fix of each slot (module docstring, 1)."""
    idx = np.flatnonzero(fix)
    keep = np.zeros(len(t), bool)
    if not idx.size:
        return keep
    slot = np.floor((t[idx] + SLOT_TOLERANCE_S) / interval_s)
    first = np.r_[True, slot[1:] != slot[:-1]]
    keep[idx[first]] = True
    return keep


def apply_gnss_use(cols: dict[str, np.ndarray], t: np.ndarray, use: GnssUse | None,
                   had_sd: dict[str, str]) -> tuple[list[str], list[str], dict[str, Any]]:
    """Thin, withhold and give the receiver's sd to the fixes in ``cols`` (in place; module
    docstring, steps 1-3).

    Parameters
    ----------
    cols : the flight's columns by channel (``t``'s rows)
    t : time of each row [s of the log's time], sorted
    use : the options (``None`` or the default: nothing done)
    had_sd : where the log's sd came from, per sd channel (``"recorded"``, ``"HDOP"``...):
        named in the note when the user's value replaces it

    Returns
    -------
    warnings, notes, record
        ``record`` is what goes to ``FlightMeta.ingest.gnss_use`` (empty when nothing was
        asked).
    """
    if use is None or not use.any or use.withhold:
        return [], [], {}
    warns: list[str] = []
    notes: list[str] = []
    lat = cols.get("gnss_lat_deg")
    fix = np.isfinite(lat) if lat is not None else np.zeros(len(t), bool)
    rec: dict[str, Any] = {"options": use.as_dict(), "fixes_read": int(fix.sum())}
    if lat is None or not fix.any():
        warns.append("GNSS options given (" + _said(use) + ") but the log has no GNSS "
                     "position: nothing to apply them to")
        return warns, notes, rec
    drop = np.zeros(len(t), bool)
    if use.interval_s is not None:
        keep = interval_slots(t, fix, use.interval_s)
        thin = fix & ~keep
        drop |= thin
        rec["interval_dropped"] = int(thin.sum())
        notes.append(f"GNSS fixes at most every {use.interval_s:g} s (the first fix of each "
                     f"{use.interval_s:g}-s slot of the log's time): {int(keep.sum())} of "
                     f"{int(fix.sum())} kept")
    windows = []
    for a, b in use.withhold_s:
        inside = fix & ~drop & (t >= a) & (t <= b)
        windows.append({"start_s": a, "end_s": b, "fixes_withheld": int(inside.sum())})
        drop |= inside
        if not inside.any():
            warns.append(f"GNSS withheld over {a:g}..{b:g} s of the log's time: no fix lies "
                         f"there (the fixes span {t[fix][0]:g}..{t[fix][-1]:g} s)")
        else:
            notes.append(f"GNSS withheld over {a:g}..{b:g} s of the log's time: "
                         f"{int(inside.sum())} fix(es)")
    if windows:
        rec["withheld_windows"] = windows
    for c in _FIX_CHANNELS:
        if c in cols and drop.any():
            v = cols[c].astype(float, copy=True)
            v[drop] = np.nan
            cols[c] = v
    kept = fix & ~drop
    rec["fixes_used"] = int(kept.sum())
    for ch, val, what in (("gnss_h_sd_m", use.h_sd_m, "horizontal sd per axis"),
                          ("gnss_v_sd_m", use.v_sd_m, "vertical sd")):
        if val is None:
            continue
        on = kept if ch == "gnss_h_sd_m" else kept & np.isfinite(
            cols.get("gnss_alt_m", np.full(len(t), np.nan)))
        have = cols.get(ch)
        replaced = int((on & np.isfinite(have)).sum()) if have is not None else 0
        sd = np.full(len(t), np.nan) if have is None else have.astype(float, copy=True)
        sd[on] = val
        cols[ch] = sd
        rec[ch.replace("gnss_", "given_")] = val
        src = had_sd.get(ch)
        notes.append(f"{ch} = {val:g} m on {int(on.sum())} fix(es): the receiver's {what} "
                     "given by the user" + (f", in place of the log's ({src}) on {replaced}"
                                            if replaced and src else ""))
    return warns, notes, rec


def _said(use: GnssUse) -> str:
    parts = []
    if use.withhold_s:
        parts.append("withheld windows")
    if use.interval_s is not None:
        parts.append(f"interval {use.interval_s:g} s")
    if use.h_sd_m is not None or use.v_sd_m is not None:
        parts.append("receiver sd")
    return ", ".join(parts)
